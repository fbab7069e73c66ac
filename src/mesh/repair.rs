//! Turn a triangle soup (as read from a file) into a valid, consistently
//! oriented [`TriMesh`], counting every change.
//!
//! Steps, in order:
//! 1. drop vertices no triangle references (counted as unreferenced);
//! 2. weld exactly ([`super::weld`]);
//! 3. remove **degenerate** triangles: a repeated vertex index (often
//!    created by the weld), then **duplicate** triangles: same three
//!    vertices as an earlier triangle in any order or orientation (the
//!    first is kept);
//! 4. weld by tolerance the vertices of open edges and short edges
//!    ([`super::weld::weld_by_tolerance`]; it needs step 3, as a duplicate
//!    makes the open edges of a crack look shared), then step 3 again when
//!    it joined any;
//! 5. resolve **zero-area** triangles (definition below) without opening
//!    the surface ([`super::degenerate`]): a needle's vanishing edge is
//!    collapsed, a cap's long edge flipped; only a triangle neither applies
//!    to (long edge on the boundary or non-manifold) is removed; duplicates
//!    a collapse or flip made are removed;
//! 6. drop vertices left unreferenced by 3–5 (same counter as step 1);
//! 7. orient each edge-connected component consistently and closed ones
//!    outward ([`super::orientation::orient_consistently`]);
//! 8. flip the long edge of every **folded cap**, a thin triangle lying
//!    folded over its three neighbours ([`super::folds`]);
//! 9. count — but keep — non-manifold edges and vertices, components,
//!    boundary loops, χ and genus ([`super::summary::topology_summary`]).
//!
//! **Zero area.** A triangle has zero area when its height over its longest
//! edge is at most `1e-12 · D`, `D` the bounding-box diagonal of the welded
//! mesh: `|(b − a) × (c − a)| ≤ 1e-12 · D · ℓmax`. That is about 10⁴ ulps of
//! `f64` at model scale and five orders of magnitude below the resolution of
//! the `f32` coordinates of binary STL, so only triangles that are collinear
//! up to round-off go. Valid slivers stay: the thinnest triangles of the
//! corpus (angles down to 0.004°) have heights of 4.5·10⁻⁷ · D
//! (`fault_ridgecrest_2019.obj`), 4.4·10⁻⁶ · D (`featuretype.stl`) and
//! more, five orders of magnitude above the threshold; no corpus file loses
//! a triangle to this rule. Area is not compared to an absolute or mean-area
//! threshold because real meshes mix triangle sizes over many orders of
//! magnitude.
//!
//! Nothing is removed silently: every removal is a count in [`RepairReport`].

use super::components::{connected_components, nonmanifold_vertices};
use super::degenerate::resolve_zero_area_triangles;
use super::equal_keys::first_index_of_equal_key;
use super::folds::unfold_caps;
use super::orientation::orient_components;
use super::summary::{TopologySummary, topology_summary_of};
use super::weld::{weld_by_tolerance, weld_exact};
use super::{MeshError, Topology, TriMesh};
use crate::geom::{BoundingBox, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// Height over the longest edge, relative to the model diagonal, at or
/// below which a triangle counts as zero-area (see the module doc).
pub const ZERO_AREA_RELATIVE_HEIGHT: f64 = 1e-12;

/// What loading and repair did to a mesh. All counts refer to the surface
/// unless named otherwise.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct RepairReport {
    /// Vertices as read (STL: three corners per facet; MSH: all nodes).
    pub n_input_vertices: usize,
    /// Triangles as read, after fan triangulation (MSH volume-only: boundary faces of the tets).
    pub n_input_triangles: usize,
    /// Vertices merged because their coordinates were bitwise equal.
    pub n_vertices_welded_exact: usize,
    /// Further vertices merged by the tolerance weld.
    pub n_vertices_welded_tolerance: usize,
    /// Absolute weld tolerance used (relative tolerance × bounding-box diagonal); 0 = exact only.
    pub weld_tolerance_abs: f64,
    /// True when the tolerance weld exceeded its work bound (vertices packed
    /// far denser than the tolerance) and only the exact weld was applied.
    pub tolerance_weld_abandoned: bool,
    /// Vanishing edges of zero-area "needle" triangles collapsed (step 4).
    pub n_zero_area_edges_collapsed: usize,
    /// Triangles dropped by those collapses: each needle and its neighbour
    /// across the vanishing edge (the surface stays closed).
    pub n_triangles_removed_by_collapse: usize,
    /// Long edges of zero-area "cap" triangles flipped (the cap and its
    /// neighbour replaced by two valid triangles).
    pub n_zero_area_edges_flipped: usize,
    /// Long edges of "folded caps" flipped after orientation: thin triangles
    /// facing against all three neighbours ([`super::folds`]; the cap and
    /// its neighbour replaced by two triangles facing like the surface).
    pub n_folded_caps_flipped: usize,
    /// Zero-area triangles that could be neither collapsed nor flipped (long
    /// edge on the boundary or non-manifold) and were removed.
    pub n_zero_area_triangles_removed: usize,
    /// Triangles removed because they use a vertex twice (after welding).
    pub n_degenerate_triangles_removed: usize,
    /// Triangles removed because an earlier triangle has the same three vertices.
    pub n_duplicate_triangles_removed: usize,
    /// Vertices dropped because no kept element uses them (in the file, or after removals).
    pub n_unreferenced_vertices_dropped: usize,
    /// Triangles flipped to agree with their neighbours.
    pub n_triangles_flipped: usize,
    /// Closed components reversed as a whole so their normals point outward.
    pub n_components_reversed_outward: usize,
    /// Components that cannot be oriented consistently (Möbius-like).
    pub n_nonorientable_components: usize,
    /// Edges shared by three or more triangles (kept).
    pub n_nonmanifold_edges: usize,
    /// Vertices whose triangles form more than one fan (kept).
    pub n_nonmanifold_vertices: usize,
    /// Edge-connected components.
    pub n_components: usize,
    /// Connected pieces of the boundary-edge graph.
    pub n_boundary_loops: usize,
    /// Euler characteristic `V − E + F` of the repaired surface.
    pub euler_characteristic: i64,
    /// Sum of component genera, when every component is a manifold.
    pub genus: Option<i64>,
    /// True when every component is closed (no boundary, no non-manifold edge).
    pub closed: bool,
    /// Elements not kept, by type name (e.g. "Line 2", "Quadrilateral 4", "line").
    pub skipped_elements: BTreeMap<String, usize>,
    /// Polygons with more than three vertices split into triangle fans.
    pub n_polygons_fan_triangulated: usize,
    /// Tetrahedra kept in the volume mesh (MSH only).
    pub n_tets: usize,
    /// Tetrahedra whose corners were reordered to give them positive volume.
    pub n_tets_reoriented: usize,
    /// Tetrahedra removed because they repeat a node or have zero volume.
    pub n_degenerate_tets_removed: usize,
    /// True when the surface is the boundary of the tetrahedra (the file had no triangles).
    pub surface_from_volume_boundary: bool,
    /// Topology of the repaired surface per component (always present after loading).
    pub topology: Option<TopologySummary>,
}

/// Clean a triangle soup into a valid mesh (steps in the module doc).
///
/// `tolerance_rel` is the weld tolerance relative to the bounding-box
/// diagonal (0 = exact weld only). The result may have no triangles when
/// every triangle was removed; the report says why.
///
/// # Errors
/// A triangle index out of range, or counts that do not fit 32-bit ids.
pub fn repair_triangle_soup(
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    tolerance_rel: f64,
) -> Result<(TriMesh, RepairReport), MeshError> {
    let mut report = RepairReport {
        n_input_vertices: positions.len(),
        n_input_triangles: triangles.len(),
        ..RepairReport::default()
    };
    super::trimesh::check_count("vertex", positions.len())?;
    super::trimesh::check_count("triangle", triangles.len())?;
    let n_in = positions.len();
    if let Some(f) = triangles.par_iter().position_first(|t| t.iter().any(|&v| v as usize >= n_in)) {
        let vertex = triangles[f].into_iter().find(|&v| v as usize >= n_in).unwrap_or(u32::MAX);
        return Err(MeshError::VertexOutOfRange { element: f, vertex, n_vertices: n_in });
    }

    let (positions, mut triangles, n_dropped) = drop_unreferenced(positions, triangles);
    report.n_unreferenced_vertices_dropped += n_dropped;

    let (exact_index, positions) = weld_exact(&positions);
    report.n_vertices_welded_exact = n_in - n_dropped - positions.len();
    triangles.par_iter_mut().for_each(|t| *t = t.map(|v| exact_index[v as usize]));
    drop(exact_index);
    remove_degenerate_and_duplicates(&mut triangles, &mut report);

    let weld = weld_by_tolerance(positions, &triangles, tolerance_rel);
    report.n_vertices_welded_tolerance = weld.n_welded;
    report.weld_tolerance_abs = weld.tolerance;
    report.tolerance_weld_abandoned = weld.abandoned;
    if weld.n_welded > 0 {
        triangles.par_iter_mut().for_each(|t| *t = t.map(|v| weld.new_index[v as usize]));
        remove_degenerate_and_duplicates(&mut triangles, &mut report);
    }
    let positions = weld.positions;

    let diagonal = BoundingBox::of_points(&positions).map_or(0.0, |b| b.diagonal());
    let zero_area = resolve_zero_area_triangles(&positions, &mut triangles, diagonal);
    report.n_zero_area_edges_collapsed = zero_area.n_needle_edges_collapsed;
    report.n_triangles_removed_by_collapse = zero_area.n_triangles_removed_by_collapse;
    report.n_zero_area_edges_flipped = zero_area.n_cap_edges_flipped;
    report.n_zero_area_triangles_removed = zero_area.n_removed;
    if zero_area.n_needle_edges_collapsed + zero_area.n_cap_edges_flipped > 0 {
        // A collapse or flip can make a triangle repeat another.
        report.n_duplicate_triangles_removed += remove_duplicates(&mut triangles);
    }

    let (positions, triangles, n_orphans) = drop_unreferenced(positions, triangles);
    report.n_unreferenced_vertices_dropped += n_orphans;

    let mut mesh = TriMesh::from_raw(positions, &triangles);
    debug_assert!(mesh.validate().is_ok());
    if mesh.n_faces() == 0 {
        return Ok((mesh, report));
    }

    let mut topo = Topology::new(&mesh);
    // One component labelling and one non-manifold vertex list serve
    // orientation and summary (flips change neither); independent, so built
    // side by side.
    let (comps, nm_vertices) = rayon::join(|| connected_components(&topo), || nonmanifold_vertices(&mesh, &topo));
    let orientation = orient_components(&mut mesh, &mut topo, &comps);
    debug_assert!(mesh.validate().is_ok());
    report.n_triangles_flipped = orientation.n_triangles_flipped;
    report.n_components_reversed_outward = orientation.n_components_reversed_outward;
    report.n_nonorientable_components = orientation.n_nonorientable_components;
    report.n_folded_caps_flipped = unfold_caps(&mut mesh, &topo);
    let nm_vertices = if report.n_folded_caps_flipped > 0 {
        // The flips keep every face's edge-connected component (four outer
        // edges for two triangles) but change the edges and the fans.
        topo = Topology::new(&mesh);
        nonmanifold_vertices(&mesh, &topo)
    } else {
        nm_vertices
    };

    let summary = topology_summary_of(&mesh, &topo, &comps, &nm_vertices);
    report.n_nonmanifold_edges = summary.n_nonmanifold_edges;
    report.n_nonmanifold_vertices = summary.n_nonmanifold_vertices;
    report.n_components = summary.n_components();
    report.n_boundary_loops = summary.n_boundary_loops;
    report.euler_characteristic = summary.euler_characteristic;
    report.genus = summary.genus();
    report.closed = summary.is_closed();
    report.topology = Some(summary);
    Ok((mesh, report))
}

/// Remove triangles that use a vertex twice, then those that repeat an
/// earlier one, adding both counts to `report`.
fn remove_degenerate_and_duplicates(triangles: &mut Vec<[u32; 3]>, report: &mut RepairReport) {
    let before = triangles.len();
    triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0]);
    report.n_degenerate_triangles_removed += before - triangles.len();
    report.n_duplicate_triangles_removed += remove_duplicates(triangles);
}

/// Remove triangles whose vertex set repeats an earlier one (the first is
/// kept, order preserved); returns how many. Equal sorted triples are
/// grouped on the pool ([`first_index_of_equal_key`]).
fn remove_duplicates(triangles: &mut Vec<[u32; 3]>) -> usize {
    let key = |f: usize| {
        let mut k = triangles[f];
        k.sort_unstable();
        k
    };
    let first = first_index_of_equal_key(triangles.len(), key);
    let before = triangles.len();
    if first.iter().enumerate().all(|(f, &g)| g as usize == f) {
        return 0;
    }
    let mut f = 0;
    triangles.retain(|_| {
        f += 1;
        first[f - 1] as usize == f - 1
    });
    before - triangles.len()
}

/// Drop vertices no triangle uses, renumbering the rest in order; returns
/// the compacted data and the number dropped.
fn drop_unreferenced(positions: Vec<Vec3>, mut triangles: Vec<[u32; 3]>) -> (Vec<Vec3>, Vec<[u32; 3]>, usize) {
    let mesh = TriMesh { positions, triangles: Vec::new() };
    let mut used = vec![false; mesh.n_vertices()];
    for t in &triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let n_used = used.iter().filter(|&&u| u).count();
    if n_used == mesh.n_vertices() {
        return (mesh.positions, triangles, 0);
    }
    let mut new_id = vec![u32::MAX; mesh.n_vertices()];
    let mut positions = Vec::with_capacity(n_used);
    for (v, &u) in used.iter().enumerate() {
        if u {
            new_id[v] = positions.len() as u32;
            positions.push(mesh.positions[v]);
        }
    }
    for t in &mut triangles {
        *t = t.map(|v| new_id[v as usize]);
    }
    let dropped = mesh.n_vertices() - n_used;
    (positions, triangles, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    /// Explode a mesh into a soup: three corners per triangle.
    fn soup(m: &TriMesh) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        let mut t = Vec::new();
        for tri in &m.triangles {
            let base = p.len() as u32;
            p.extend(tri.iter().map(|v| m.positions[v.idx()]));
            t.push([base, base + 1, base + 2]);
        }
        (p, t)
    }

    #[test]
    fn soup_of_a_sphere_welds_back() {
        let m = fixtures::icosphere(2);
        let (p, t) = soup(&m);
        let (r, rep) = repair_triangle_soup(p, t, 0.0).unwrap();
        assert_eq!(r.n_vertices(), m.n_vertices());
        assert_eq!(r.n_faces(), m.n_faces());
        assert_eq!(rep.n_vertices_welded_exact, 3 * m.n_faces() - m.n_vertices());
        assert_eq!((rep.n_components, rep.euler_characteristic, rep.genus, rep.closed), (1, 2, Some(0), true));
        assert_eq!(rep.n_triangles_flipped, 0);
        assert!(r.signed_volume() > 0.0);
    }

    #[test]
    fn counts_every_removal() {
        let m = fixtures::square(2); // 9 vertices, 8 triangles
        let mut p = m.positions.clone();
        let mut t: Vec<[u32; 3]> = m.triangles.iter().map(|t| t.map(|v| v.0)).collect();
        p.push(Vec3::new(5.0, 5.0, 5.0)); // 9: unreferenced
        p.push(Vec3::new(1.0 + 1e-9, 1.0, 0.0)); // 10: welds to the corner (1,1) by tolerance
        p.push(Vec3::new(0.25, 0.0, 0.0)); // 11: on the edge (0,0)-(0.5,0): collinear
        t.push([0, 1, 1]); // degenerate
        t.push([0, 11, 1]); // zero area (collinear)
        t.push(t[0]); // duplicate
        t.push([t[1][0], t[1][2], t[1][1]]); // duplicate with opposite orientation
        let corner = m.positions.iter().position(|q| *q == Vec3::new(1.0, 1.0, 0.0)).unwrap() as u32;
        let tri_with_corner = *t.iter().find(|t| t.contains(&corner)).unwrap();
        t.push(tri_with_corner.map(|v| if v == corner { 10 } else { v })); // duplicate after weld
        let (r, rep) = repair_triangle_soup(p, t, 1e-6).unwrap();
        assert_eq!(r.n_faces(), 8);
        assert_eq!(r.n_vertices(), 9);
        assert_eq!(rep.n_unreferenced_vertices_dropped, 2, "{rep:?}"); // 9, and 11 after its triangle went
        assert_eq!(rep.n_vertices_welded_tolerance, 1);
        assert_eq!(rep.n_degenerate_triangles_removed, 1);
        assert_eq!(rep.n_zero_area_triangles_removed, 1);
        assert_eq!(rep.n_duplicate_triangles_removed, 3);
        assert_eq!((rep.n_boundary_loops, rep.euler_characteristic, rep.genus), (1, 1, Some(0)));
        assert_eq!(rep.n_input_triangles, 13);
        assert_eq!(rep.n_input_vertices, 12);
    }

    /// A closed icosphere with a cap (a T-junction closed by a collinear
    /// triangle) and two needles (a vertex doubled 1e-14 away, the seams of
    /// its split fan filled by slivers with a vanishing edge).
    fn sphere_with_cap_and_needles() -> (TriMesh, Vec<Vec3>, Vec<[u32; 3]>) {
        let m = fixtures::icosphere(2);
        let mut p = m.positions.clone();
        let mut t: Vec<[u32; 3]> = m.triangles.iter().map(|t| t.map(|v| v.0)).collect();
        let [a, b, c] = t[0];
        let mid = p.len() as u32;
        p.push((p[a as usize] + p[b as usize]) / 2.0);
        t[0] = [a, mid, c];
        t.push([mid, b, c]);
        t.push([a, b, mid]); // the cap: pairs b→a of the neighbour, m→b and a→m
        let f = t.iter().position(|tri| !tri.iter().any(|v| [a, b, c].contains(v))).unwrap();
        let [v, x, y] = t[f];
        let v2 = p.len() as u32;
        p.push(p[v as usize] + Vec3::new(1e-14, 0.0, 0.0));
        t[f] = [v2, x, y];
        t.push([v, x, v2]);
        t.push([v, v2, y]);
        (m, p, t)
    }

    #[test]
    fn zero_area_triangles_are_resolved_without_opening_a_closed_surface() {
        let (m, p, t) = sphere_with_cap_and_needles();
        let n_in = t.len();
        let (r, rep) = repair_triangle_soup(p, t, 0.0).unwrap();
        assert_eq!((rep.closed, rep.n_boundary_loops, rep.euler_characteristic), (true, 0, 2), "{rep:?}");
        assert_eq!(rep.n_zero_area_edges_flipped, 1);
        assert_eq!((rep.n_zero_area_edges_collapsed, rep.n_triangles_removed_by_collapse), (1, 2));
        assert_eq!(rep.n_zero_area_triangles_removed, 0);
        // Only the two needles went (collapsed away); the cap was replaced.
        assert_eq!(r.n_faces(), n_in - 2);
        assert_eq!(r.n_faces(), m.n_faces() + 2);
        assert_eq!(r.n_vertices(), m.n_vertices() + 1);
        let diagonal = BoundingBox::of_points(&r.positions).unwrap().diagonal();
        let tris: Vec<[u32; 3]> = r.triangles.iter().map(|t| t.map(|v| v.0)).collect();
        assert!(tris.iter().all(|t| !super::super::degenerate::is_zero_area(&r.positions, t, diagonal)));
        assert!(r.signed_volume() > 0.0);
    }

    /// The repaired mesh and report of a large soup (above the grouping's
    /// partitioning threshold, with duplicates, degenerate triangles and a
    /// tolerance weld) are the same on one and two threads.
    #[test]
    fn repair_does_not_depend_on_the_thread_count() {
        let mut m = fixtures::cube(40);
        for p in &mut m.positions {
            *p = p.normalize();
        }
        let (mut p, mut t) = soup(&m);
        for k in 0..500 {
            t.push(t[k * 7]); // duplicate
            t.push([t[k][0], t[k][0], t[k][1]]); // degenerate
            let v = t[k * 11][0] as usize;
            p[v] += Vec3::new(1e-9, 0.0, 0.0); // welds by tolerance
        }
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| repair_triangle_soup(p.clone(), t.clone(), 1e-6).unwrap())
        };
        let (one, rep_one) = run(1);
        let (two, rep_two) = run(2);
        assert_eq!(one.positions, two.positions);
        assert_eq!(one.triangles, two.triangles);
        assert_eq!(rep_one, rep_two);
        assert_eq!((one.n_faces(), one.n_vertices()), (m.n_faces(), m.n_vertices()));
        assert_eq!((rep_one.n_duplicate_triangles_removed, rep_one.n_degenerate_triangles_removed), (500, 500));
        assert_eq!((rep_one.closed, rep_one.euler_characteristic), (true, 2));
    }

    #[test]
    fn thin_slivers_are_kept() {
        // Angle of about 0.001 degrees at the apex side: height 1e-5 of the edge.
        let p = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.5, 1e-8, 0.0)];
        let (r, rep) = repair_triangle_soup(p, vec![[0, 1, 2]], 1e-6).unwrap();
        assert_eq!((r.n_faces(), rep.n_zero_area_triangles_removed), (1, 0));
    }

    #[test]
    fn flipped_and_inward_components_are_fixed() {
        let mut m = fixtures::icosphere(1);
        for f in 0..m.n_faces() {
            m.flip_face(crate::mesh::FaceId::new(f));
        }
        m.flip_face(crate::mesh::FaceId::new(0));
        let t: Vec<[u32; 3]> = m.triangles.iter().map(|t| t.map(|v| v.0)).collect();
        let (r, rep) = repair_triangle_soup(m.positions.clone(), t, 1e-6).unwrap();
        assert_eq!((rep.n_triangles_flipped, rep.n_components_reversed_outward), (1, 1));
        assert!(r.signed_volume() > 0.0);
    }

    #[test]
    fn out_of_range_is_an_error_and_all_removed_is_empty() {
        let p = vec![Vec3::zeros(), Vec3::x()];
        assert!(matches!(
            repair_triangle_soup(p.clone(), vec![[0, 1, 2]], 0.0),
            Err(MeshError::VertexOutOfRange { .. })
        ));
        let (r, rep) = repair_triangle_soup(p, vec![[0, 1, 1]], 0.0).unwrap();
        assert_eq!((r.n_faces(), r.n_vertices(), rep.n_degenerate_triangles_removed), (0, 0, 1));
    }
}
