//! The lattice spacing of each part of the surface ([`super::parts`]):
//! explicit, or chosen so that every part's volume is within a tolerance of
//! its enclosed volume while the whole mesh stays within a tet budget.
//!
//! **Volume error model.** Isosurface stuffing puts every boundary vertex on
//! the surface; the volume it misses (chords across curved and creased
//! regions, dropped boundary slivers whose four vertices were warped onto
//! the surface) is measured to fall with the square of the spacing relative
//! to the part's thickness: `e ≈ −K (h A / V)²`, with `A` the area, `V` the
//! volume and `t = 2 V / A` the characteristic thickness
//! ([`super::parts::SurfacePart::thickness`]), on balls, cubes, a torus,
//! ellipsoids, rods, disks and slabs alike (`docs/decisions.md`). The
//! volume-to-area ratio is the thickness measure because it is what the
//! error scales with: the misses are spread over the surface, so a thin fin
//! on a big body costs its own area, which `A / V` counts; a low quantile
//! of inward ray depths would refine the whole part for a fin of
//! negligible volume, and ray samples cost a BVH query each and are noisy
//! on coarse or self-touching surfaces. `V / A` is exact, one pass, and
//! defined for any closed surface. [`VOLUME_ERROR_COEFFICIENT`] is `K`.
//!
//! **Tet count** of a part at spacing `h`: `12 V / h³` lattice tets plus the
//! split boundary cells, at most [`BOUNDARY_TETS_PER_AREA`]` · A / h²`; the
//! lattice over the part's box has `Π (e_k / h + 4)` cells, allowed
//! [`LATTICE_CELLS_PER_TET`] per tet of the budget (the mesher's memory).
//! The *cost* of a part is the larger of its tets and its cells over
//! [`LATTICE_CELLS_PER_TET`].
//!
//! **Default sizes.** Each part wants the finer of its accuracy size
//! `h_acc = (V / A) √(tol / K)` and the mean edge length of its triangles (the
//! surface's own detail). The budget is `min(default_max_tets, max_tets)`,
//! shared by water filling in two rounds: first the accuracy sizes (parts
//! are capped at a common cost level, the largest first, until the sum
//! fits), then what is left goes towards the edge-length sizes the same
//! way. A part whose accuracy size does not fit is coarser than `h_acc`,
//! and the report says so.

use super::error::FramesError;
use super::parts::SurfacePart;

/// `K` of the error model `|e| ≈ K (h A / V)²` (dimensionless): the largest
/// measured `|e| / (h A / V)²` was 0.034 (a cube, `h A / V` from 1/8 to 1,
/// `docs/decisions.md`), rounded up, so `h_acc` aims below the tolerance.
pub const VOLUME_ERROR_COEFFICIENT: f64 = 0.04;

/// Boundary tets per `A / h²` beyond `12 V / h³` (the largest measured over
/// the same shapes and spacings was 3.5, a slab), so that the estimate
/// bounds the count the mesher produces.
pub const BOUNDARY_TETS_PER_AREA: f64 = 4.0;

/// Lattice cells allowed per tet of the budget: the lattice covers the
/// part's bounding box, which can be much larger than its volume (a thin
/// diagonal rod); 4 cells (about 80 bytes of lattice data) per allowed tet
/// bound the memory of the mesher.
pub const LATTICE_CELLS_PER_TET: f64 = 4.0;

/// Most lattice cells of one part whatever the budget: the mesher numbers
/// lattice vertices (about 2 per cell) with `u32`.
pub const MAX_LATTICE_CELLS: f64 = (u32::MAX / 4) as f64;

/// What the spacing of the parts depends on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizingParams {
    /// The user's spacing for every part, or `None` for the default sizes.
    pub target_size: Option<f64>,
    /// Hard limit of the estimated cost (tets, or lattice cells over
    /// [`LATTICE_CELLS_PER_TET`]) of the whole mesh.
    pub max_tets: usize,
    /// Budget of the default sizes (capped by `max_tets`).
    pub default_max_tets: usize,
    /// Relative volume error each part's accuracy size aims at.
    pub volume_tolerance: f64,
}

/// The spacing chosen for one part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartSpacing {
    /// Lattice spacing used, model units.
    pub spacing: f64,
    /// The accuracy size `h_acc` of the part (module docs), model units.
    pub accurate_spacing: f64,
    /// Estimated tets at `spacing` (module docs).
    pub estimated_tets: f64,
    /// A default spacing coarser than wanted because of the budget.
    pub capped: bool,
}

/// Estimated tets of `part` at spacing `h`: `12 V / h³ + β A / h²`.
pub fn estimated_tets(part: &SurfacePart, h: f64) -> f64 {
    12.0 * part.enclosed_volume / (h * h * h) + BOUNDARY_TETS_PER_AREA * part.area / (h * h)
}

/// Lattice cells over the box of `part` at spacing `h`.
pub fn lattice_cells(part: &SurfacePart, h: f64) -> f64 {
    let e = part.bounds.max - part.bounds.min;
    (e.x / h + 4.0) * (e.y / h + 4.0) * (e.z / h + 4.0)
}

/// Cost of `part` at spacing `h` against the budget: the larger of its
/// estimated tets and its lattice cells over [`LATTICE_CELLS_PER_TET`].
pub fn part_cost(part: &SurfacePart, h: f64) -> f64 {
    estimated_tets(part, h).max(lattice_cells(part, h) / LATTICE_CELLS_PER_TET)
}

/// The accuracy size `h_acc = (V / A) √(tol / K)` of `part` (module docs):
/// the spacing at which the error model meets `volume_tolerance`; 0 for a
/// part without volume.
pub fn accurate_spacing(part: &SurfacePart, volume_tolerance: f64) -> f64 {
    0.5 * part.thickness() * (volume_tolerance / VOLUME_ERROR_COEFFICIENT).sqrt()
}

/// The spacing of every part (module docs).
///
/// # Errors
/// [`FramesError::InvalidOption`] for a non-positive `target_size`,
/// [`FramesError::TooManyTets`] when an explicit size exceeds `max_tets`
/// (or one part's lattice exceeds [`MAX_LATTICE_CELLS`]).
pub fn part_spacings(parts: &[SurfacePart], params: &SizingParams) -> Result<Vec<PartSpacing>, FramesError> {
    let acc: Vec<f64> = parts.iter().map(|p| accurate_spacing(p, params.volume_tolerance)).collect();
    if let Some(h) = params.target_size {
        return explicit_spacings(parts, &acc, h, params.max_tets);
    }
    let budget = params.default_max_tets.min(params.max_tets) as f64;
    let coarsest: Vec<f64> = parts.iter().map(coarsest_spacing).collect();
    let finest: Vec<f64> = parts.iter().map(|p| finest_spacing(p, budget)).collect();
    let clamp = |h: f64, i: usize| if h > 0.0 { h.clamp(finest[i], coarsest[i]) } else { coarsest[i] };
    let floor: Vec<f64> = parts.iter().enumerate().map(|(i, p)| part_cost(p, coarsest[i])).collect();
    // Round 1: the accuracy sizes.
    let want_acc: Vec<f64> = parts.iter().enumerate().map(|(i, p)| part_cost(p, clamp(acc[i], i))).collect();
    let round1 = water_fill(&floor, &want_acc, budget);
    // Round 2: towards the finer of accuracy and edge-length sizes.
    let want_fine: Vec<f64> = parts
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let edge = p.surface.mean_edge_length();
            let h = if acc[i] > 0.0 && edge > 0.0 { acc[i].min(edge) } else { acc[i].max(edge) };
            part_cost(p, clamp(h, i)).max(round1[i])
        })
        .collect();
    let costs = water_fill(&round1, &want_fine, budget);
    Ok(parts
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let h = spacing_for_cost(p, costs[i], finest[i], coarsest[i]);
            PartSpacing {
                spacing: h,
                accurate_spacing: acc[i],
                estimated_tets: estimated_tets(p, h),
                capped: costs[i] < want_fine[i] * (1.0 - 1e-9),
            }
        })
        .collect())
}

/// Every part at the user's spacing `h`, refused when the total cost
/// exceeds `max_tets` or one lattice is too large to number.
fn explicit_spacings(
    parts: &[SurfacePart],
    acc: &[f64],
    h: f64,
    max_tets: usize,
) -> Result<Vec<PartSpacing>, FramesError> {
    if !(h > 0.0 && h.is_finite()) {
        return Err(FramesError::InvalidOption {
            name: "target_size",
            reason: format!("must be a positive length, got {h}"),
        });
    }
    let total: f64 = parts.iter().map(|p| part_cost(p, h)).sum();
    if total > max_tets as f64 || parts.iter().any(|p| lattice_cells(p, h) > MAX_LATTICE_CELLS) {
        return Err(FramesError::TooManyTets {
            target_size: h,
            estimated_tets: total.min(u64::MAX as f64) as u64,
            max_tets,
        });
    }
    Ok(parts
        .iter()
        .zip(acc)
        .map(|(p, &a)| PartSpacing {
            spacing: h,
            accurate_spacing: a,
            estimated_tets: estimated_tets(p, h),
            capped: false,
        })
        .collect())
}

/// A spacing at which `part` is one lattice cell across (it holds no tet
/// then; the coarsest size worth considering).
fn coarsest_spacing(part: &SurfacePart) -> f64 {
    let d = (part.bounds.max - part.bounds.min).norm();
    if d > 0.0 { d } else { 1.0 }
}

/// The spacing below which `part` alone exceeds `budget` or its lattice
/// cannot be numbered (bisection on the decreasing cost).
fn finest_spacing(part: &SurfacePart, budget: f64) -> f64 {
    let hi = coarsest_spacing(part);
    let fits = |h: f64| part_cost(part, h) <= budget && lattice_cells(part, h) <= MAX_LATTICE_CELLS;
    if !fits(hi) {
        return hi;
    }
    let mut lo = hi;
    while fits(lo) && lo > hi * 1e-12 {
        lo *= 0.5;
    }
    bisect_spacing(lo, hi, fits)
}

/// Smallest spacing in `[lo, hi]` for which `fits` holds, given that it
/// holds at `hi` and fits is monotone (60 bisection steps in `log h`).
fn bisect_spacing(mut lo: f64, mut hi: f64, fits: impl Fn(f64) -> bool) -> f64 {
    for _ in 0..60 {
        let mid = (lo * hi).sqrt();
        if fits(mid) { hi = mid } else { lo = mid }
    }
    hi
}

/// The spacing at which `part` costs `cost`, within `[finest, coarsest]`.
fn spacing_for_cost(part: &SurfacePart, cost: f64, finest: f64, coarsest: f64) -> f64 {
    if part_cost(part, finest) <= cost * (1.0 + 1e-12) {
        return finest;
    }
    bisect_spacing(finest, coarsest, |h| part_cost(part, h) <= cost * (1.0 + 1e-12))
}

/// Water filling: per item `clamp(level, floor_i, want_i)` with the largest
/// common `level` whose sum fits `budget` (the floors alone when even they
/// do not fit). Items wanting less than the level get what they want; the
/// largest wants are cut first.
pub fn water_fill(floor: &[f64], want: &[f64], budget: f64) -> Vec<f64> {
    let at = |level: f64| -> Vec<f64> { floor.iter().zip(want).map(|(&f, &w)| level.min(w).max(f)).collect() };
    let sum = |level: f64| at(level).iter().sum::<f64>();
    let top = want.iter().copied().fold(0.0, f64::max);
    if sum(top) <= budget {
        return at(top);
    }
    let (mut lo, mut hi) = (0.0, top);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if sum(mid) <= budget { lo = mid } else { hi = mid }
    }
    at(lo)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::parts::closed_parts;
    use crate::geom::Vec3;
    use crate::mesh::{TriMesh, VertexId, fixtures};

    fn part_of(mesh: &TriMesh) -> SurfacePart {
        closed_parts(mesh).remove(0)
    }

    #[test]
    fn water_filling_cuts_the_largest_wants_first() {
        let got = water_fill(&[0.0, 0.0, 0.0], &[10.0, 100.0, 1000.0], 310.0);
        assert!((got[0] - 10.0).abs() < 1e-9 && (got[1] - 100.0).abs() < 1e-9 && (got[2] - 200.0).abs() < 1e-6);
        assert_eq!(water_fill(&[1.0, 1.0], &[2.0, 3.0], 100.0), vec![2.0, 3.0]);
        // Floors are kept even above the budget.
        assert_eq!(water_fill(&[5.0, 5.0], &[6.0, 6.0], 4.0), vec![5.0, 5.0]);
    }

    #[test]
    fn accuracy_size_follows_thickness() {
        // Cube [-1, 1]³: V / A = 8 / 24; at tol = K / 4, h = V / (2 A).
        let cube = part_of(&fixtures::cube(2));
        let h = accurate_spacing(&cube, VOLUME_ERROR_COEFFICIENT / 4.0);
        assert!((h - 1.0 / 6.0).abs() < 1e-15, "{h}");
        // The same cube flattened to 2 × 2 × 0.2: V / A = 0.8 / 9.6, a
        // quarter of the cube's, so a quarter of its spacing.
        let mut slab = fixtures::cube(2);
        for p in &mut slab.positions {
            p.z *= 0.1;
        }
        let slab = part_of(&slab);
        let ratio = accurate_spacing(&slab, VOLUME_ERROR_COEFFICIENT / 4.0) / h;
        assert!((ratio - 0.25).abs() < 1e-12, "{ratio}");
    }

    #[test]
    fn default_sizes_respect_the_budget_and_explicit_sizes_the_limit() {
        let mut two = fixtures::icosphere(3);
        let n = two.positions.len() as u32;
        two.positions.extend(fixtures::icosphere(1).positions.iter().map(|p| p * 0.1 + Vec3::new(1000.0, 0.0, 0.0)));
        let tris: Vec<_> = fixtures::icosphere(1).triangles.iter().map(|t| t.map(|v| VertexId(v.0 + n))).collect();
        two.triangles.extend(tris);
        let parts = closed_parts(&two);
        assert_eq!(parts.len(), 2);
        let params =
            SizingParams { target_size: None, max_tets: 2_000_000, default_max_tets: 300_000, volume_tolerance: 0.01 };
        let s = part_spacings(&parts, &params).unwrap();
        // Each part at the finer of accuracy and edge length, both fit: the
        // small ball (radius 0.1) much finer than the big one.
        assert!(s.iter().all(|x| !x.capped && x.spacing <= x.accurate_spacing * (1.0 + 1e-9)), "{s:?}");
        assert!(s[1].spacing < s[0].spacing / 5.0, "{s:?}");
        let total: f64 = parts.iter().zip(&s).map(|(p, x)| part_cost(p, x.spacing)).sum();
        assert!(total <= 300_000.0 * (1.0 + 1e-6), "{total}");
        // A budget between the accuracy sizes and the edge-length sizes: the
        // big ball (finer edges than its accuracy size needs) gives up part
        // of its refinement, the small ball keeps its size.
        let c0 = part_cost(&parts[0], s[0].spacing);
        let c0_acc = part_cost(&parts[0], s[0].accurate_spacing);
        let c1 = part_cost(&parts[1], s[1].spacing);
        assert!(c0 > 1.2 * c0_acc, "{c0} {c0_acc}");
        let budget = c1 + 0.5 * (c0 + c0_acc);
        let tight = SizingParams { default_max_tets: budget as usize, ..params };
        let t = part_spacings(&parts, &tight).unwrap();
        let total: f64 = parts.iter().zip(&t).map(|(p, x)| part_cost(p, x.spacing)).sum();
        assert!(total <= budget * (1.0 + 1e-6), "{total}");
        assert!(t[0].capped && t[0].spacing > s[0].spacing && t[0].spacing < s[0].accurate_spacing, "{t:?}");
        assert!(!t[1].capped && (t[1].spacing - s[1].spacing).abs() < 1e-9 * s[1].spacing, "{t:?}");
        // max_tets caps the default budget too.
        let low = SizingParams { max_tets: 5_000, ..params };
        let total: f64 =
            parts.iter().zip(&part_spacings(&parts, &low).unwrap()).map(|(p, x)| part_cost(p, x.spacing)).sum();
        assert!(total <= 5_000.0 * (1.0 + 1e-6), "{total}");
        // Explicit sizes apply to every part, and are refused above max_tets.
        let e = part_spacings(&parts, &SizingParams { target_size: Some(0.05), ..params }).unwrap();
        assert!(e.iter().all(|x| x.spacing == 0.05 && !x.capped));
        assert!(matches!(
            part_spacings(&parts, &SizingParams { target_size: Some(0.01), max_tets: 1000, ..params }),
            Err(FramesError::TooManyTets { .. })
        ));
        assert!(matches!(
            part_spacings(&parts, &SizingParams { target_size: Some(-1.0), ..params }),
            Err(FramesError::InvalidOption { .. })
        ));
    }
}
