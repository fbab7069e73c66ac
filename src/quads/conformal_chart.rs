//! Charts in which a patch is triangulated when the atlas' disk map
//! distorts it: the patch's own plane when it is planar, otherwise its
//! least-squares conformal map (LSCM, Lévy et al. 2002) with a free
//! boundary.
//!
//! Why. The atlas maps every patch onto the unit disk (mean value map with
//! the outer loop on the circle, thesis ch. 2). That map is one-to-one but
//! not conformal: a thin strip (the wall of an engraved letter, a quarter of
//! the quad size high and fifty times as long) is squeezed into a disk, and
//! the Delaunay triangulation of its boundary points in `(u, v)` joins
//! points of opposite ends of the strip, which land in 3D as folded
//! triangles. A conformal chart keeps angles, so a triangulation that is
//! Delaunay in it is close to one on the surface: the strip becomes a long
//! rectangle and its triangles a ladder.
//!
//! Math. With `φₘ` the barycentric functions of a triangle in its own plane
//! (gradients `∇φₘ`, area `A`), the map `(u, v)` is conformal on the
//! triangle when `∇v = R ∇u` (`R` the rotation by +90° in the triangle's
//! plane, oriented by its normal). LSCM minimizes
//! `Σ_T A_T |Σₘ (vₘ ∇φₘ − uₘ R∇φₘ)|²`, a quadratic form in `(u, v)` that
//! is positive definite once two vertices are pinned (here the two boundary
//! vertices farthest apart, fixing translation, rotation and scale). The
//! normal equations are solved by a sparse Cholesky factorization. LSCM is
//! not one-to-one in general; the chart is kept only when every triangle is
//! counter-clockwise and no two boundary edges meet.

use crate::atlas::verify::sigma_ratio;
use crate::atlas::{Atlas, AtlasPatch};
use crate::geom::{Vec2, Vec3, barycentric_gradients, meeting_segments, orient2d};
use crate::linalg::{CholeskySolver, Triplets};

/// Largest distance of a patch vertex from the patch's plane, as a
/// fraction of the patch's extent, for the patch to count as planar.
pub const PLANAR_TOLERANCE: f64 = 1e-6;

/// A patch's chart is replaced when the area-weighted mean of its
/// triangles' σ2/σ1 (1 for a conformal map) is below this.
pub const MIN_MEAN_SIGMA_RATIO: f64 = 0.6;

/// A least-squares conformal chart is used only when the ratio of the
/// 95th to the 5th percentile of its triangles' area scale (chart area over
/// surface area) is at most this: LSCM keeps angles but can shrink a part
/// of the patch by orders of magnitude (a tube's end), and a triangulation
/// that is Delaunay in `(u, v)` is close to one on the surface only where
/// the scale varies slowly.
pub const MAX_AREA_SPREAD: f64 = 10.0;

/// The chart the quads stage triangulates `patch` in: the atlas' own when
/// it is close to conformal, else [`planar_chart`] or [`lscm_chart`] when
/// they are one-to-one and more conformal; `None` keeps the atlas' chart.
pub fn better_chart(atlas: &Atlas, patch: &AtlasPatch) -> Option<AtlasPatch> {
    let own = mean_sigma_ratio(atlas, patch, &patch.uv);
    if own >= MIN_MEAN_SIGMA_RATIO {
        return None;
    }
    let chart = planar_chart(atlas, patch)
        .or_else(|| lscm_chart(atlas, patch).filter(|c| area_spread(atlas, patch, &c.uv) <= MAX_AREA_SPREAD))?;
    (mean_sigma_ratio(atlas, patch, &chart.uv) > own).then_some(chart)
}

/// Ratio of the 95th to the 5th percentile over the patch's triangles of
/// the area scale of the chart `uv` (chart area over surface area).
pub fn area_spread(atlas: &Atlas, patch: &AtlasPatch, uv: &[Vec2]) -> f64 {
    let mut scale: Vec<f64> = patch
        .triangles
        .iter()
        .filter_map(|t| {
            let p = t.map(|l| position(atlas, patch, l));
            let area = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
            (area > 0.0).then(|| orient2d(&uv[t[0] as usize], &uv[t[1] as usize], &uv[t[2] as usize]) / area)
        })
        .collect();
    if scale.is_empty() {
        return 1.0;
    }
    scale.sort_by(f64::total_cmp);
    let k = scale.len() / 20;
    scale[scale.len() - 1 - k] / scale[k]
}

/// 3D position of local vertex `l` of `patch`.
fn position(atlas: &Atlas, patch: &AtlasPatch, l: u32) -> Vec3 {
    atlas.mesh.positions[patch.vertices[l as usize].idx()]
}

/// Area-weighted mean over the patch's triangles of σ2/σ1 of the map from
/// `uv` to the surface.
pub fn mean_sigma_ratio(atlas: &Atlas, patch: &AtlasPatch, uv: &[Vec2]) -> f64 {
    let (mut sum, mut area) = (0.0, 0.0);
    for t in &patch.triangles {
        let p = t.map(|l| position(atlas, patch, l));
        let a = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
        sum += a * sigma_ratio(p, t.map(|l| uv[l as usize]));
        area += a;
    }
    if area > 0.0 { sum / area } else { 1.0 }
}

/// `patch` with its `(u, v)` replaced by the orthogonal projection onto its
/// plane, when all its vertices lie in one plane (within
/// [`PLANAR_TOLERANCE`]) and the chart is one-to-one
/// ([`finish_chart`]); `None` otherwise. A planar patch's plane is an
/// isometric chart.
pub fn planar_chart(atlas: &Atlas, patch: &AtlasPatch) -> Option<AtlasPatch> {
    let n_local = patch.vertices.len() as u32;
    let pos = |l: u32| position(atlas, patch, l);
    let mut normal = Vec3::zeros();
    for t in &patch.triangles {
        normal += (pos(t[1]) - pos(t[0])).cross(&(pos(t[2]) - pos(t[0])));
    }
    let n = normal.try_normalize(0.0)?;
    let centre = (0..n_local).map(pos).sum::<Vec3>() / f64::from(n_local.max(1));
    let extent = (0..n_local).map(|l| (pos(l) - centre).norm()).fold(0.0, f64::max);
    if !(extent > 0.0) || (0..n_local).any(|l| (pos(l) - centre).dot(&n).abs() > PLANAR_TOLERANCE * extent) {
        return None;
    }
    let seed = if n.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
    let e1 = n.cross(&seed).normalize();
    let e2 = n.cross(&e1);
    let uv = (0..n_local).map(|l| Vec2::new((pos(l) - centre).dot(&e1), (pos(l) - centre).dot(&e2))).collect();
    finish_chart(atlas, patch, uv)
}

/// Boundary edges of the patch (local vertex pairs, in triangle order):
/// the edges used by one triangle.
fn boundary_edges(patch: &AtlasPatch) -> Vec<[u32; 2]> {
    let mut uses: std::collections::HashMap<[u32; 2], u32> = std::collections::HashMap::new();
    for t in &patch.triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            *uses.entry([a.min(b), a.max(b)]).or_insert(0) += 1;
        }
    }
    let mut out = Vec::new();
    for t in &patch.triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            if uses[&[a.min(b), a.max(b)]] == 1 {
                out.push([a, b]);
            }
        }
    }
    out
}

/// Gradients of the three barycentric functions of the 3D triangle `p` in
/// its plane, rotated by +90° too (`R∇φ = n̂ × ∇φ`), and its area.
fn triangle_gradients(p: &[Vec3; 3]) -> Option<([Vec3; 3], [Vec3; 3], f64)> {
    let normal = (p[1] - p[0]).cross(&(p[2] - p[0]));
    let twice_area = normal.norm();
    if !(twice_area > 0.0) {
        return None;
    }
    let n = normal / twice_area;
    let grad = barycentric_gradients(p, &n, 0.5 * twice_area);
    let rotated = grad.map(|g| n.cross(&g));
    Some((grad, rotated, 0.5 * twice_area))
}

/// The two boundary vertices farthest apart (approximately: the farthest
/// from the first boundary vertex, then the farthest from that one).
fn pins(atlas: &Atlas, patch: &AtlasPatch, boundary: &[[u32; 2]]) -> Option<[u32; 2]> {
    let farthest = |from: u32| {
        let x = position(atlas, patch, from);
        boundary
            .iter()
            .map(|e| e[0])
            .max_by(|&a, &b| {
                (position(atlas, patch, a) - x)
                    .norm_squared()
                    .total_cmp(&(position(atlas, patch, b) - x).norm_squared())
                    .then(b.cmp(&a))
            })
            .unwrap_or(from)
    };
    let a = farthest(boundary.first()?[0]);
    let b = farthest(a);
    (a != b).then_some([a, b])
}

/// `patch` with its `(u, v)` replaced by its least-squares conformal map
/// (module documentation), when that map is one-to-one; `None` otherwise.
pub fn lscm_chart(atlas: &Atlas, patch: &AtlasPatch) -> Option<AtlasPatch> {
    let n = patch.vertices.len();
    let boundary = boundary_edges(patch);
    let [pa, pb] = pins(atlas, patch, &boundary)?;
    let d = (position(atlas, patch, pb) - position(atlas, patch, pa)).norm();
    // Unknown k < n is u_k, k ≥ n is v_{k−n}; pinned ones are known.
    let mut known: Vec<Option<f64>> = vec![None; 2 * n];
    known[pa as usize] = Some(0.0);
    known[n + pa as usize] = Some(0.0);
    known[pb as usize] = Some(d);
    known[n + pb as usize] = Some(0.0);
    let mut column = vec![usize::MAX; 2 * n];
    let mut n_free = 0;
    for (k, c) in column.iter_mut().enumerate() {
        if known[k].is_none() {
            *c = n_free;
            n_free += 1;
        }
    }
    let mut triplets = Triplets::new(n_free, n_free);
    let mut rhs = vec![0.0; n_free];
    for t in &patch.triangles {
        let p = t.map(|l| position(atlas, patch, l));
        let Some((grad, rotated, area)) = triangle_gradients(&p) else { continue };
        // Residual Σₘ (vₘ ∇φₘ − uₘ R∇φₘ), one row per 3D component.
        for axis in 0..3 {
            let row: [(usize, f64); 6] = std::array::from_fn(|i| {
                let m = i % 3;
                if i < 3 { (t[m] as usize, -rotated[m][axis]) } else { (n + t[m] as usize, grad[m][axis]) }
            });
            for &(a, ca) in &row {
                if known[a].is_some() {
                    continue;
                }
                for &(b, cb) in &row {
                    match known[b] {
                        Some(x) => rhs[column[a]] -= area * ca * cb * x,
                        None => triplets.push(column[a], column[b], area * ca * cb),
                    }
                }
            }
        }
    }
    let matrix = triplets.to_matrix().ok()?;
    let solver = CholeskySolver::new(&matrix).ok()?;
    let mut columns = vec![rhs];
    solver.solve_columns(&mut columns).ok()?;
    let x = &columns[0];
    let value = |k: usize| known[k].unwrap_or_else(|| x[column[k]]);
    let uv = (0..n).map(|l| Vec2::new(value(l), value(n + l))).collect();
    finish_chart(atlas, patch, uv)
}

/// `patch` with `uv` as its chart, centred and scaled into the unit disk
/// like the atlas' maps and mirrored if needed so its triangles are
/// counter-clockwise, when every triangle then is and no two boundary
/// edges meet (a one-to-one chart); `None` otherwise.
fn finish_chart(atlas: &Atlas, patch: &AtlasPatch, mut uv: Vec<Vec2>) -> Option<AtlasPatch> {
    if uv.is_empty() || uv.iter().any(|p| !p.x.is_finite() || !p.y.is_finite()) {
        return None;
    }
    let signed = |uv: &[Vec2], t: &[u32; 3]| orient2d(&uv[t[0] as usize], &uv[t[1] as usize], &uv[t[2] as usize]);
    let total: f64 = patch.triangles.iter().map(|t| signed(&uv, t)).sum();
    if total < 0.0 {
        uv.iter_mut().for_each(|p| p.y = -p.y);
    }
    let centre = uv.iter().sum::<Vec2>() / uv.len() as f64;
    let radius = uv.iter().map(|p| (p - centre).norm()).fold(0.0, f64::max);
    if !(radius > 0.0) {
        return None;
    }
    uv.iter_mut().for_each(|p| *p = (*p - centre) / radius);
    let boundary: Vec<[usize; 2]> = boundary_edges(patch).iter().map(|e| e.map(|v| v as usize)).collect();
    if !patch.triangles.iter().all(|t| signed(&uv, t) > 0.0) || !meeting_segments(&uv, &boundary).is_empty() {
        return None;
    }
    let sigma_ratio = patch
        .triangles
        .iter()
        .map(|t| sigma_ratio(t.map(|l| position(atlas, patch, l)), t.map(|l| uv[l as usize])))
        .collect();
    Some(AtlasPatch { uv, sigma_ratio, ..patch.clone() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::{AtlasOptions, build_atlas};
    use crate::mesh::TriMesh;
    use crate::mesh::fixtures::{placed, square_structured};
    use crate::progress::Progress;

    fn atlas_of(mesh: &TriMesh) -> Atlas {
        build_atlas(mesh, &AtlasOptions::default(), &Progress::none()).expect("atlas")
    }

    /// Every edge of every triangle has the same length ratio chart / 3D
    /// (within `tol`, relative): the chart is an isometry up to scale.
    fn assert_similar(atlas: &Atlas, patch: &AtlasPatch, tol: f64) {
        let mut ratios = Vec::new();
        for t in &patch.triangles {
            for i in 0..3 {
                let (a, b) = (t[i], t[(i + 1) % 3]);
                let d3 = (position(atlas, patch, b) - position(atlas, patch, a)).norm();
                ratios.push((patch.uv[b as usize] - patch.uv[a as usize]).norm() / d3);
            }
        }
        let (lo, hi) = ratios.iter().fold((f64::INFINITY, 0.0f64), |(l, h), &r| (l.min(r), h.max(r)));
        assert!(hi / lo - 1.0 < tol, "edge length ratios {lo} .. {hi}");
    }

    #[test]
    fn a_long_flat_strip_gets_its_plane_as_chart() {
        // 40 × 1: the atlas' disk map squeezes it (mean σ2/σ1 far below 1).
        let mesh = placed(&square_structured(8), Vec3::new(40.0, 1.0, 1.0), Vec3::zeros());
        let atlas = atlas_of(&mesh);
        let mut replaced = 0;
        for patch in &atlas.patches {
            let Some(chart) = better_chart(&atlas, patch) else { continue };
            replaced += 1;
            assert_similar(&atlas, &chart, 1e-9);
            assert!((mean_sigma_ratio(&atlas, patch, &chart.uv) - 1.0).abs() < 1e-9);
            assert!(chart.uv.iter().all(|p| p.norm() <= 1.0 + 1e-12), "inside the unit disk");
        }
        assert!(replaced > 0, "some patch of the strip was replaced");
    }

    #[test]
    fn a_bent_strip_gets_its_developed_rectangle_by_lscm() {
        // A 0.2-wide strip rolled onto half a cylinder of radius 1: every
        // grid cell is a planar rectangle, so the surface develops exactly
        // onto a π × 0.2 rectangle and LSCM must find it (up to similarity).
        let flat = square_structured(12);
        let mut mesh = flat.clone();
        for p in &mut mesh.positions {
            let (s, h) = (p.x * std::f64::consts::PI, p.y * 0.2);
            *p = Vec3::new(s.cos(), s.sin(), h);
        }
        let atlas = atlas_of(&mesh);
        for patch in &atlas.patches {
            assert!(planar_chart(&atlas, patch).is_none() || patch.triangles.len() < 3);
            let chart = lscm_chart(&atlas, patch).expect("a developable strip has a one-to-one LSCM");
            assert_similar(&atlas, &chart, 1e-6);
            assert!(area_spread(&atlas, patch, &chart.uv) < 1.0 + 1e-6);
        }
    }

    #[test]
    fn a_folded_chart_is_refused() {
        let mesh = square_structured(4);
        let atlas = atlas_of(&mesh);
        let patch = &atlas.patches[0];
        let mut uv = patch.uv.clone();
        // Move one interior vertex far outside: its triangles turn over.
        let inner = (0..uv.len()).find(|&l| uv[l].norm() < 0.5).expect("an interior vertex");
        uv[inner] = Vec2::new(5.0, 5.0);
        assert!(finish_chart(&atlas, patch, uv).is_none());
        // A mirror image is turned back, not refused.
        let mirrored: Vec<Vec2> = patch.uv.iter().map(|p| Vec2::new(p.x, -p.y)).collect();
        let chart = finish_chart(&atlas, patch, mirrored).expect("mirrored chart");
        assert!(patch.triangles.iter().all(|t| orient2d(
            &chart.uv[t[0] as usize],
            &chart.uv[t[1] as usize],
            &chart.uv[t[2] as usize]
        ) > 0.0));
    }
}
