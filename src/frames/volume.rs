//! The tetrahedral mesh of the volume enclosed by a closed surface, and
//! measures of its quality and fidelity.
//!
//! Method: isosurface stuffing on a BCC lattice ([`super::stuffing`]) with
//! the exact crossing-parity inside test of a triangle BVH. Chosen because
//! it is robust for any closed triangulation (no surface recovery, no
//! Delaunay predicates), runs in time linear in the output, and puts every
//! boundary vertex exactly on the input surface (cut points are segment–
//! triangle intersections, warped lattice vertices are moved onto them), so
//! the boundary follows the surface to round-off at its vertices, and to
//! `O(h²·curvature)` in between; sharp edges and corners of the input are
//! cut by chords of size `O(h)`.
//!
//! Size: the lattice spacing `h` is `target_size` when given, else the
//! mean edge length of the surface; with `V` the enclosed volume the count
//! is about `12 V / h³` tetrahedra (12 BCC tets of volume `h³/12` per
//! cube), and a default size is enlarged until the estimate fits
//! `max_tets`.

use super::bvh::TriangleBvh;
use super::error::{FramesError, OpenLoop};
use super::stuffing::{StuffedVolume, StuffingParams, isosurface_stuffing_cancellable};
use crate::fem::tet_p1::tet_p1_gradients;
use crate::geom::Vec3;
use crate::mesh::boundary::boundary_pieces;
use crate::mesh::{TetMesh, Topology, TriMesh};
use crate::progress::Progress;
use rayon::prelude::*;
use serde::Serialize;

/// What the volume step did, for the report.
#[derive(Debug, Clone, Default, Serialize)]
pub struct VolumeReport {
    /// `"stuffed"` (isosurface stuffing) or `"uploaded"`.
    pub source: String,
    /// Lattice spacing used (model units); 0 for an uploaded mesh.
    pub spacing: f64,
    /// The default size was enlarged to respect `max_tets`.
    pub spacing_capped: bool,
    /// Tetrahedra.
    pub n_tets: usize,
    /// Vertices.
    pub n_vertices: usize,
    /// Vertices on the boundary of the tetrahedral mesh.
    pub n_boundary_vertices: usize,
    /// Lattice vertices warped onto the surface.
    pub n_warped: usize,
    /// Cut points (surface crossings) kept as vertices.
    pub n_cut_points: usize,
    /// Prisms cut around a Steiner point.
    pub n_steiner: usize,
    /// Sign-changing lattice edges resolved by the round-off fallback.
    pub n_cut_fallbacks: usize,
    /// Lattice rows recast after an ambiguous crossing.
    pub n_recast_rows: usize,
    /// Smallest dihedral angle, degrees.
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle, degrees.
    pub max_dihedral_deg: f64,
    /// Volume of the tetrahedral mesh.
    pub volume: f64,
    /// Volume enclosed by the surface (divergence theorem, |·|).
    pub enclosed_volume: f64,
    /// `(volume − enclosed_volume) / enclosed_volume`.
    pub volume_relative_error: f64,
    /// Largest distance from a boundary vertex to the input surface.
    pub max_boundary_vertex_distance: f64,
    /// Things the user should know (e.g. volume lost in thin parts).
    pub warnings: Vec<String>,
}

/// The boundary loops of `surface` if it is open, as an error.
///
/// # Errors
/// [`FramesError::EmptySurface`] or [`FramesError::OpenSurface`].
pub fn check_closed(surface: &TriMesh) -> Result<(), FramesError> {
    if surface.triangles.is_empty() {
        return Err(FramesError::EmptySurface);
    }
    let topo = Topology::new(surface);
    // The same pieces repair counts as `n_boundary_loops`.
    let pieces = boundary_pieces(&topo);
    if pieces.is_empty() {
        return Ok(());
    }
    Err(FramesError::OpenSurface {
        loops: pieces
            .iter()
            .map(|l| OpenLoop {
                n_edges: l.edges.len(),
                first_vertices: l.vertices.iter().take(5).map(|v| v.0).collect(),
                length: l.length(surface, &topo),
            })
            .collect(),
        n_nonmanifold_edges: topo.n_nonmanifold_edges(),
    })
}

/// Lattice cells allowed per requested tetrahedron: the lattice covers the
/// bounding box, which can be much larger than the volume (a thin diagonal
/// rod, far-apart parts); 4 cells (about 80 bytes of lattice data) per
/// allowed tet bounds the memory of the mesher.
pub const LATTICE_CELLS_PER_TET: f64 = 4.0;

/// Most lattice cells whatever `max_tets`: the mesher numbers lattice
/// vertices (about 2 per cell) with `u32`.
pub const MAX_LATTICE_CELLS: f64 = (u32::MAX / 4) as f64;

/// The lattice spacing for `surface`: `target_size` if given (error if it
/// would exceed `max_tets`), else the mean edge length, enlarged until both
/// the estimated tet count `12 V / h³` fits `max_tets` and the lattice over
/// the bounding box has at most [`LATTICE_CELLS_PER_TET`]` · max_tets`
/// cells. Returns `(spacing, capped)`.
///
/// # Errors
/// [`FramesError::InvalidOption`] for a non-positive size,
/// [`FramesError::TooManyTets`] for an explicit size that is too small.
pub fn lattice_spacing(
    surface: &TriMesh,
    target_size: Option<f64>,
    max_tets: usize,
) -> Result<(f64, bool), FramesError> {
    let volume = surface.signed_volume().abs();
    let ext = surface.bounding_box().map_or(Vec3::zeros(), |b| b.max - b.min);
    let tets = |h: f64| 12.0 * volume / (h * h * h);
    let cells = |h: f64| (ext.x / h + 4.0) * (ext.y / h + 4.0) * (ext.z / h + 4.0);
    let max_cells = (LATTICE_CELLS_PER_TET * max_tets as f64).min(MAX_LATTICE_CELLS);
    // Both counts decrease with h: the cap is the largest of the two limits.
    let fits = |h: f64| tets(h) <= max_tets as f64 && cells(h) <= max_cells;
    if let Some(h) = target_size {
        if !(h > 0.0) || !h.is_finite() {
            return Err(FramesError::InvalidOption {
                name: "target_size",
                reason: format!("must be a positive length, got {h}"),
            });
        }
        if !fits(h) {
            let estimated = tets(h).max(cells(h) / LATTICE_CELLS_PER_TET);
            return Err(FramesError::TooManyTets {
                target_size: h,
                estimated_tets: estimated.min(u64::MAX as f64) as u64,
                max_tets,
            });
        }
        return Ok((h, false));
    }
    let diag = ext.norm();
    let mut h = surface.mean_edge_length();
    if !(h > 0.0) {
        h = diag / 20.0;
    }
    if !(h > 0.0) {
        return Ok((1.0, false));
    }
    if fits(h) {
        return Ok((h, false));
    }
    // Smallest h that fits: the volume bound in closed form, then doubling
    // and bisection for the lattice bound.
    let mut lo = h;
    let mut hi = h.max((12.0 * volume / max_tets as f64).cbrt());
    while !fits(hi) {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if fits(mid) { hi = mid } else { lo = mid }
    }
    Ok((hi, true))
}

/// Tetrahedralize the volume enclosed by the closed `surface` with lattice
/// spacing `spacing` and the warp thresholds `alpha_long`, `alpha_short`.
///
/// # Errors
/// [`FramesError::NoInterior`] when nothing fits inside;
/// [`FramesError::InvalidVolume`] if the result fails validation (a bug).
pub fn tetrahedralize_enclosed_volume(
    surface: &TriMesh,
    spacing: f64,
    alpha_long: f64,
    alpha_short: f64,
) -> Result<(StuffedVolume, VolumeReport), FramesError> {
    tetrahedralize_enclosed_volume_cancellable(surface, spacing, alpha_long, alpha_short, &Progress::none())
}

/// [`tetrahedralize_enclosed_volume`], checking `progress` for
/// cancellation inside the mesher and between the quality measures.
///
/// # Errors
/// As [`tetrahedralize_enclosed_volume`], and [`FramesError::Cancelled`].
pub fn tetrahedralize_enclosed_volume_cancellable(
    surface: &TriMesh,
    spacing: f64,
    alpha_long: f64,
    alpha_short: f64,
    progress: &Progress,
) -> Result<(StuffedVolume, VolumeReport), FramesError> {
    let bvh = TriangleBvh::new(surface);
    progress.check()?;
    let stuffed = isosurface_stuffing_cancellable(
        surface,
        &bvh,
        &StuffingParams::new(spacing, alpha_long, alpha_short),
        progress,
    )?;
    let enclosed = surface.signed_volume().abs();
    if stuffed.mesh.tets.is_empty() {
        return Err(FramesError::NoInterior { spacing, volume: enclosed });
    }
    progress.check()?;
    stuffed.mesh.validate()?;
    progress.check()?;
    let boundary = boundary_vertices(&stuffed.mesh);
    progress.check()?;
    let max_dist = boundary
        .par_iter()
        .enumerate()
        .filter(|(_, b)| **b)
        .map(|(v, _)| bvh.closest_point(&stuffed.mesh.positions[v]).map_or(0.0, |c| c.0))
        .reduce(|| 0.0, f64::max);
    progress.check()?;
    let (min_d, max_d) = dihedral_angle_range(&stuffed.mesh);
    let volume = stuffed.mesh.volume();
    let relative_error = if enclosed > 0.0 { (volume - enclosed) / enclosed } else { 0.0 };
    let mut warnings = Vec::new();
    if relative_error < -0.05 {
        warnings.push(format!(
            "the volume mesh holds {:.1}% less than the enclosed volume: parts thinner than about two lattice spacings ({:.4e}) are not resolved; use a smaller target_size",
            -100.0 * relative_error,
            2.0 * spacing
        ));
    }
    let report = VolumeReport {
        source: "stuffed".into(),
        spacing,
        spacing_capped: false,
        n_tets: stuffed.mesh.n_tets(),
        n_vertices: stuffed.mesh.n_vertices(),
        n_boundary_vertices: boundary.iter().filter(|b| **b).count(),
        n_warped: stuffed.n_warped,
        n_cut_points: stuffed.n_cut_points,
        n_steiner: stuffed.n_steiner,
        n_cut_fallbacks: stuffed.n_cut_fallbacks,
        n_recast_rows: stuffed.n_recast_rows,
        min_dihedral_deg: min_d,
        max_dihedral_deg: max_d,
        volume,
        enclosed_volume: enclosed,
        volume_relative_error: relative_error,
        max_boundary_vertex_distance: max_dist,
        warnings,
    };
    Ok((stuffed, report))
}

/// Faces of `mesh` that belong to exactly one tet, oriented outward
/// (positively oriented tets assumed), as vertex triples.
pub fn tet_boundary_faces(mesh: &TetMesh) -> Vec<[u32; 3]> {
    // Outward faces of a positive tet [a, b, c, d].
    const FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut keyed: Vec<([u32; 3], [u32; 3])> = Vec::with_capacity(mesh.tets.len() * 4);
    for t in &mesh.tets {
        for f in FACES {
            let tri = f.map(|i| t[i].0);
            let mut key = tri;
            key.sort_unstable();
            keyed.push((key, tri));
        }
    }
    keyed.par_sort_unstable_by(|a, b| a.0.cmp(&b.0));
    let mut out = Vec::new();
    let mut i = 0;
    while i < keyed.len() {
        let mut j = i + 1;
        while j < keyed.len() && keyed[j].0 == keyed[i].0 {
            j += 1;
        }
        if j - i == 1 {
            out.push(keyed[i].1);
        }
        i = j;
    }
    out
}

/// `true` for vertices on the boundary of the tetrahedral mesh.
pub fn boundary_vertices(mesh: &TetMesh) -> Vec<bool> {
    boundary_vertices_of_faces(mesh.n_vertices(), &tet_boundary_faces(mesh))
}

/// `true` for the vertices of the given boundary faces.
pub fn boundary_vertices_of_faces(n_vertices: usize, faces: &[[u32; 3]]) -> Vec<bool> {
    let mut b = vec![false; n_vertices];
    for f in faces {
        for &v in f {
            b[v as usize] = true;
        }
    }
    b
}

/// Smallest and largest dihedral angle over all tets, in degrees.
pub fn dihedral_angle_range(mesh: &TetMesh) -> (f64, f64) {
    mesh.tets
        .par_iter()
        .map(|t| {
            let p = t.map(|v| mesh.positions[v.idx()]);
            let (g, vol) = tet_p1_gradients(&p);
            if !(vol > 0.0) {
                return (0.0, 180.0);
            }
            // ∇φ_k is normal to the face opposite k, pointing inward; the
            // dihedral angle at the edge opposite to (k, l) is π − ∠(∇φ_k, ∇φ_l).
            let mut lo = f64::INFINITY;
            let mut hi = 0.0f64;
            for k in 0..4 {
                for l in k + 1..4 {
                    let c = g[k].dot(&g[l]) / (g[k].norm() * g[l].norm());
                    let ang = 180.0 - c.clamp(-1.0, 1.0).acos().to_degrees();
                    lo = lo.min(ang);
                    hi = hi.max(ang);
                }
            }
            (lo, hi)
        })
        .reduce(|| (f64::INFINITY, 0.0), |a, b| (a.0.min(b.0), a.1.max(b.1)))
}

/// Area-weighted outward normals of the boundary faces (from
/// [`tet_boundary_faces`]) at each vertex (zero for interior vertices) and,
/// per vertex, the largest angle (radians) between one incident face normal
/// and that average.
pub fn boundary_vertex_normals(mesh: &TetMesh, faces: &[[u32; 3]]) -> (Vec<Vec3>, Vec<f64>) {
    let n = mesh.n_vertices();
    let mut normal = vec![Vec3::zeros(); n];
    let face_normals: Vec<Vec3> = faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| mesh.positions[v as usize]);
            (b - a).cross(&(c - a)) * 0.5
        })
        .collect();
    for (f, an) in faces.iter().zip(&face_normals) {
        for &v in f {
            normal[v as usize] += an;
        }
    }
    for v in normal.iter_mut() {
        let l = v.norm();
        if l > 0.0 {
            *v /= l;
        }
    }
    let mut spread = vec![0.0f64; n];
    for (f, an) in faces.iter().zip(&face_normals) {
        let l = an.norm();
        if !(l > 0.0) {
            continue;
        }
        let u = an / l;
        for &v in f {
            let c = u.dot(&normal[v as usize]).clamp(-1.0, 1.0);
            spread[v as usize] = spread[v as usize].max(c.acos());
        }
    }
    (normal, spread)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn open_surface_names_its_loops() {
        let cyl = fixtures::cylinder(1.0, 2.0, 16, 4);
        match check_closed(&cyl) {
            Err(FramesError::OpenSurface { loops, n_nonmanifold_edges: 0 }) => {
                assert_eq!(loops.len(), 2);
                assert!(
                    loops.iter().all(|l| l.n_edges == 16
                        && (l.length - 16.0 * 2.0 * (std::f64::consts::PI / 16.0).sin()).abs() < 1e-9)
                );
                let msg = FramesError::OpenSurface { loops, n_nonmanifold_edges: 0 }.to_string();
                assert!(msg.contains("2 boundary loop") && msg.contains("16 edges"), "{msg}");
            }
            other => panic!("expected OpenSurface, got {other:?}"),
        }
        assert!(check_closed(&fixtures::icosphere(1)).is_ok());
        assert_eq!(check_closed(&TriMesh::default()), Err(FramesError::EmptySurface));
    }

    #[test]
    fn open_surface_counts_loops_like_repair_on_fin_and_moebius() {
        use crate::mesh::boundary::tests::{fin, moebius};
        for (m, nm) in [(fin(), 1), (moebius(12), 0)] {
            let repair = crate::mesh::summary::topology_summary(&m, &Topology::new(&m)).n_boundary_loops;
            match check_closed(&m) {
                Err(FramesError::OpenSurface { loops, n_nonmanifold_edges }) => {
                    assert_eq!((loops.len(), repair, n_nonmanifold_edges), (1, 1, nm));
                    let msg = FramesError::OpenSurface { loops, n_nonmanifold_edges }.to_string();
                    assert!(msg.contains("1 boundary loop"), "{msg}");
                    assert_eq!(msg.contains("non-manifold"), nm > 0, "{msg}");
                }
                other => panic!("expected OpenSurface, got {other:?}"),
            }
        }
    }

    #[test]
    fn spacing_defaults_and_caps() {
        let cube = fixtures::cube(4); // edge 2, volume 8
        let (h, capped) = lattice_spacing(&cube, None, 1_000_000).unwrap();
        assert!(!capped && (h - cube.mean_edge_length()).abs() < 1e-15);
        let (h, capped) = lattice_spacing(&cube, None, 100).unwrap();
        let cells = (2.0 / h + 4.0).powi(3);
        assert!(capped && 12.0 * 8.0 / h.powi(3) <= 100.0 && cells <= 400.0 * (1.0 + 1e-9));
        assert!((12.0 * 8.0 / h.powi(3) - 100.0).abs() < 1e-6 || (cells - 400.0).abs() < 1e-6);
        // Far-apart parts: the lattice over the bounding box is the limit.
        let mut two = fixtures::icosphere(1);
        let n = two.positions.len() as u32;
        two.positions.extend(fixtures::icosphere(1).positions.iter().map(|p| p + Vec3::new(1000.0, 0.0, 0.0)));
        let tris: Vec<_> = two.triangles.iter().map(|t| t.map(|v| crate::mesh::VertexId(v.0 + n))).collect();
        two.triangles.extend(tris);
        let (h, capped) = lattice_spacing(&two, None, 10_000).unwrap();
        assert!(capped && (1000.0 / h + 4.0) * (2.0 / h + 4.0).powi(2) <= 40_000.0 * (1.0 + 1e-9));
        assert!(matches!(lattice_spacing(&two, Some(0.05), 10_000), Err(FramesError::TooManyTets { .. })));
        assert!(matches!(lattice_spacing(&cube, Some(0.01), 1000), Err(FramesError::TooManyTets { .. })));
        assert!(matches!(lattice_spacing(&cube, Some(-1.0), 1000), Err(FramesError::InvalidOption { .. })));
    }

    #[test]
    fn stuffed_ball_follows_the_sphere() {
        let sphere = fixtures::icosphere(3);
        let (vol, rep) = tetrahedralize_enclosed_volume(&sphere, 0.2, 0.24999, 0.41189).unwrap();
        assert!(vol.mesh.validate().is_ok());
        assert!(rep.max_boundary_vertex_distance < 1e-12, "{}", rep.max_boundary_vertex_distance);
        assert!(rep.volume_relative_error.abs() < 0.03, "{}", rep.volume_relative_error);
        assert!(rep.min_dihedral_deg > 5.0, "min dihedral {}", rep.min_dihedral_deg);
        // Every boundary vertex lies on a surface triangle.
        let b = boundary_vertices(&vol.mesh);
        assert!(
            b.iter()
                .enumerate()
                .all(|(v, &is_b)| !is_b || vol.surface_triangle_per_vertex[v] != super::super::stuffing::NO_TRIANGLE)
        );
    }
}
