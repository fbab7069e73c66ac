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
//! Parts and size: the surface is split into parts ([`super::parts`]: one
//! connected component, or several whose boxes overlap), each stuffed on its
//! own lattice at its own spacing ([`super::sizing`]: `target_size` when
//! given, else from the part's thickness and edge length within a tet
//! budget), so a small or thin part is not lost at the spacing of a large
//! one and far-apart parts do not pay for the lattice between them. The
//! report measures every part's volume against the volume it encloses.

use super::bvh::TriangleBvh;
use super::error::{FramesError, OpenLoop};
use super::parts::{SurfacePart, closed_parts};
use super::sizing::{PartSpacing, SizingParams, accurate_spacing, estimated_tets, part_spacings};
use super::stuffing::{NO_TRIANGLE, StuffedVolume, StuffingParams, isosurface_stuffing_cancellable};
use crate::fem::tet_p1::tet_p1_gradients;
use crate::geom::Vec3;
use crate::mesh::boundary::boundary_pieces;
use crate::mesh::{TetMesh, Topology, TriMesh, VertexId};
use crate::progress::Progress;
use rayon::prelude::*;
use serde::Serialize;

/// What the volume step did, for the report.
#[derive(Debug, Clone, Default, Serialize)]
pub struct VolumeReport {
    /// `"stuffed"` (isosurface stuffing) or `"uploaded"`.
    pub source: String,
    /// Smallest lattice spacing over the parts (model units); 0 for an
    /// uploaded mesh.
    pub spacing: f64,
    /// Some part's default size was enlarged to respect the tet budget.
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
    /// Parts meshed separately (0 for an uploaded mesh).
    pub n_parts: usize,
    /// Parts whose relative volume error exceeds the volume tolerance.
    pub n_parts_outside_tolerance: usize,
    /// The part relative volume error of largest magnitude.
    pub max_part_relative_error: f64,
    /// Per part: enclosed and meshed volume, relative error, spacing used
    /// (the first [`MAX_REPORTED_PARTS`]).
    pub parts: Vec<PartVolume>,
    /// Things the user should know (e.g. volume lost in thin parts).
    pub warnings: Vec<String>,
}

/// Most parts listed one by one in [`VolumeReport::parts`] (a scan can hold
/// thousands of floating shells); the counts and the worst error cover all.
pub const MAX_REPORTED_PARTS: usize = 1000;

/// The volume of one part ([`super::parts`]) of the surface: what it
/// encloses and what its tetrahedra hold.
#[derive(Debug, Clone, Default, Serialize)]
pub struct PartVolume {
    /// Index of the part (order of its smallest component).
    pub part: usize,
    /// Connected components of the surface it holds (one, unless their
    /// bounding boxes overlap: nested shells, interlocked rings).
    pub components: Vec<u32>,
    /// Triangles of the part.
    pub n_triangles: usize,
    /// Enclosed volume of its surface by the divergence theorem (cavities
    /// subtracted), model units cubed.
    pub enclosed_volume: f64,
    /// Volume of its tetrahedra.
    pub volume: f64,
    /// `(volume − enclosed_volume) / enclosed_volume` (−1 when no tet fits).
    pub relative_error: f64,
    /// Lattice spacing used, model units.
    pub target_size: f64,
    /// Spacing the volume tolerance asks for (`tol · t / 2C`,
    /// [`super::sizing`]).
    pub accurate_size: f64,
    /// Characteristic thickness `2 V / A`, model units.
    pub thickness: f64,
    /// Tetrahedra.
    pub n_tets: usize,
    /// `|relative_error|` is within the volume tolerance.
    pub within_tolerance: bool,
    /// A default spacing coarser than wanted because of the tet budget.
    pub capped: bool,
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

/// Warp thresholds of isosurface stuffing, fractions of the edge length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarpThresholds {
    /// On long lattice edges (Labelle & Shewchuk: 0.24999).
    pub alpha_long: f64,
    /// On short lattice edges (Labelle & Shewchuk: 0.41189).
    pub alpha_short: f64,
}

/// Tetrahedralize the volume enclosed by the closed `surface`, part by part
/// ([`super::parts`]) at the spacings of [`part_spacings`]. The mesh made
/// is held to the limit the sizes were chosen for (`max_tets` for an
/// explicit size, the default budget `min(default_max_tets, max_tets)`
/// otherwise): when the estimate was low, default sizes are recomputed
/// with the budget lowered by the overshoot (at most twice, then
/// `max_tets` is the limit) and an explicit size is refused.
///
/// # Errors
/// As [`part_spacings`] and [`tetrahedralize_parts_cancellable`], and
/// [`FramesError::TooManyTets`] when the mesh exceeds its limit.
pub fn enclosed_volume_mesh(
    surface: &TriMesh,
    sizing: &SizingParams,
    warp: WarpThresholds,
    progress: &Progress,
) -> Result<(StuffedVolume, VolumeReport), FramesError> {
    let parts = closed_parts(surface);
    progress.check()?;
    let mut sizing = *sizing;
    let budget = sizing.default_max_tets.min(sizing.max_tets);
    let mut attempt = 0;
    loop {
        let spacings = part_spacings(&parts, &sizing)?;
        let (stuffed, rep) =
            tetrahedralize_parts_cancellable(surface, &parts, &spacings, warp, sizing.volume_tolerance, progress)?;
        let n = stuffed.mesh.n_tets();
        let retry = sizing.target_size.is_none() && attempt < 2;
        let limit = if retry { budget } else { sizing.max_tets };
        if n <= limit {
            return Ok((stuffed, rep));
        }
        if !retry {
            return Err(FramesError::TooManyTets {
                target_size: rep.spacing,
                estimated_tets: n as u64,
                max_tets: sizing.max_tets,
            });
        }
        attempt += 1;
        let lowered = sizing.default_max_tets.min(sizing.max_tets) as f64 * 0.95 * budget as f64 / n as f64;
        sizing.default_max_tets = (lowered as usize).max(1);
    }
}

/// Tetrahedralize the volume enclosed by the closed `surface` with the
/// same lattice spacing `spacing` in every part and the warp thresholds
/// `alpha_long`, `alpha_short` (no tet limit).
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
    let parts = closed_parts(surface);
    let spacings: Vec<PartSpacing> = parts
        .iter()
        .map(|p| PartSpacing {
            spacing,
            accurate_spacing: accurate_spacing(p, DEFAULT_VOLUME_TOLERANCE),
            estimated_tets: estimated_tets(p, spacing),
            capped: false,
        })
        .collect();
    let warp = WarpThresholds { alpha_long, alpha_short };
    tetrahedralize_parts_cancellable(surface, &parts, &spacings, warp, DEFAULT_VOLUME_TOLERANCE, &Progress::none())
}

/// Volume tolerance of [`tetrahedralize_enclosed_volume`]'s report (the
/// frames option's default).
pub const DEFAULT_VOLUME_TOLERANCE: f64 = 0.01;

/// Stuff every part of `surface` at its spacing, merge the meshes (parts
/// are disjoint), and measure the result against the surface, per part and
/// in total. `surface_triangle_per_vertex` of the result names triangles of
/// `surface`. Progress is shared by the parts in proportion to their
/// estimated tets; cancellation is checked inside the mesher.
///
/// # Errors
/// [`FramesError::NoInterior`] when no tet fits in any part;
/// [`FramesError::InvalidVolume`] if the result fails validation (a bug);
/// [`FramesError::Cancelled`].
pub fn tetrahedralize_parts_cancellable(
    surface: &TriMesh,
    parts: &[SurfacePart],
    spacings: &[PartSpacing],
    warp: WarpThresholds,
    volume_tolerance: f64,
    progress: &Progress,
) -> Result<(StuffedVolume, VolumeReport), FramesError> {
    let mesher = progress.sub(0.0, 0.8);
    let total_est: f64 = spacings.iter().map(|s| s.estimated_tets.max(1.0)).sum();
    let mut done = 0.0;
    let mut merged: Option<StuffedVolume> = None;
    let mut part_reports = Vec::with_capacity(parts.len());
    for (i, (part, s)) in parts.iter().zip(spacings).enumerate() {
        let w = s.estimated_tets.max(1.0) / total_est;
        let sub = mesher.sub(done, done + w);
        done += w;
        let bvh = TriangleBvh::new(&part.surface);
        progress.check()?;
        let params = StuffingParams::new(s.spacing, warp.alpha_long, warp.alpha_short);
        let mut stuffed = isosurface_stuffing_cancellable(&part.surface, &bvh, &params, &sub)?;
        part_reports.push(part_volume(i, part, s, &stuffed.mesh, volume_tolerance));
        for t in &mut stuffed.surface_triangle_per_vertex {
            if *t != NO_TRIANGLE {
                *t = part.triangle_ids[*t as usize];
            }
        }
        merged = Some(match merged {
            None => stuffed,
            Some(acc) => append_stuffed(acc, stuffed),
        });
    }
    let spacing = spacings.iter().map(|s| s.spacing).fold(f64::INFINITY, f64::min);
    let enclosed: f64 = parts.iter().map(|p| p.enclosed_volume).sum();
    let stuffed = merged.unwrap_or_else(|| StuffedVolume {
        mesh: TetMesh::default(),
        surface_triangle_per_vertex: Vec::new(),
        n_warped: 0,
        n_cut_points: 0,
        n_steiner: 0,
        n_cut_fallbacks: 0,
        n_recast_rows: 0,
    });
    if stuffed.mesh.tets.is_empty() {
        return Err(FramesError::NoInterior { spacing, volume: enclosed });
    }
    let report = measured_volume_report(surface, &stuffed, spacing, enclosed, part_reports, progress)?;
    progress.set(1.0);
    Ok((stuffed, report))
}

/// The report entry of part `index` meshed as `mesh` at `spacing`.
fn part_volume(index: usize, part: &SurfacePart, spacing: &PartSpacing, mesh: &TetMesh, tol: f64) -> PartVolume {
    let volume = mesh.volume();
    let v0 = part.enclosed_volume;
    let relative_error = if v0 > 0.0 { (volume - v0) / v0 } else { 0.0 };
    PartVolume {
        part: index,
        components: part.components.clone(),
        n_triangles: part.surface.n_faces(),
        enclosed_volume: v0,
        volume,
        relative_error,
        target_size: spacing.spacing,
        accurate_size: spacing.accurate_spacing,
        thickness: part.thickness(),
        n_tets: mesh.n_tets(),
        within_tolerance: relative_error.abs() <= tol,
        capped: spacing.capped,
    }
}

/// `a` followed by `b` (vertex ids of `b` shifted), counters added.
fn append_stuffed(mut a: StuffedVolume, b: StuffedVolume) -> StuffedVolume {
    let offset = a.mesh.positions.len() as u32;
    a.mesh.positions.extend(b.mesh.positions);
    a.mesh.tets.extend(b.mesh.tets.into_iter().map(|t| t.map(|v| VertexId(v.0 + offset))));
    a.surface_triangle_per_vertex.extend(b.surface_triangle_per_vertex);
    a.n_warped += b.n_warped;
    a.n_cut_points += b.n_cut_points;
    a.n_steiner += b.n_steiner;
    a.n_cut_fallbacks += b.n_cut_fallbacks;
    a.n_recast_rows += b.n_recast_rows;
    a
}

/// Validate the stuffed mesh and measure it: boundary vertices' distance
/// to `surface`, dihedral angles, volume against `enclosed`, the parts
/// (listed up to [`MAX_REPORTED_PARTS`]) and the warnings.
fn measured_volume_report(
    surface: &TriMesh,
    stuffed: &StuffedVolume,
    spacing: f64,
    enclosed: f64,
    parts: Vec<PartVolume>,
    progress: &Progress,
) -> Result<VolumeReport, FramesError> {
    progress.check()?;
    stuffed.mesh.validate()?;
    progress.check()?;
    let bvh = TriangleBvh::new(surface);
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
    let warnings = volume_warnings(relative_error, spacing, &parts);
    let worst = parts.iter().max_by(|a, b| a.relative_error.abs().total_cmp(&b.relative_error.abs()));
    Ok(VolumeReport {
        source: "stuffed".into(),
        spacing,
        spacing_capped: parts.iter().any(|p| p.capped),
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
        n_parts: parts.len(),
        n_parts_outside_tolerance: parts.iter().filter(|p| !p.within_tolerance).count(),
        max_part_relative_error: worst.map_or(0.0, |p| p.relative_error),
        parts: parts.into_iter().take(MAX_REPORTED_PARTS).collect(),
        warnings,
    })
}

/// The warnings of the volume report: volume lost in thin parts (whole
/// mesh below −5 %), and parts whose volume misses the tolerance.
fn volume_warnings(relative_error: f64, spacing: f64, parts: &[PartVolume]) -> Vec<String> {
    let mut warnings = Vec::new();
    if relative_error < -0.05 {
        warnings.push(format!(
            "the volume mesh holds {:.1}% less than the enclosed volume: parts thinner than about two lattice spacings ({:.4e}) are not resolved; use a smaller target_size",
            -100.0 * relative_error,
            2.0 * spacing
        ));
    }
    let off: Vec<&PartVolume> = parts.iter().filter(|p| !p.within_tolerance).collect();
    if let Some(w) = off.iter().max_by(|a, b| a.relative_error.abs().total_cmp(&b.relative_error.abs())) {
        let why = if off.iter().any(|p| p.capped) {
            "the tet budget (frames.default_max_tets, frames.max_tets) does not allow the spacing the tolerance needs"
        } else {
            "the spacing is coarser than the tolerance needs (frames.target_size)"
        };
        warnings.push(format!(
            "{} of {} parts differ from their enclosed volume by more than the volume tolerance (worst: part {} with components {:?}, {:+.2}% at spacing {:.4e}, wanted {:.4e}): {why}",
            off.len(),
            parts.len(),
            w.part,
            &w.components[..w.components.len().min(5)],
            100.0 * w.relative_error,
            w.target_size,
            w.accurate_size
        ));
    }
    warnings
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
