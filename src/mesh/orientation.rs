//! Consistent orientation of triangles, per edge-connected component.
//!
//! Two triangles sharing an interior edge agree when they traverse it in
//! opposite directions. A breadth-first walk across interior (valence-2)
//! edges assigns each triangle a flip bit; per component the smaller set is
//! flipped, so the count reported is the fewest flips that make the
//! component consistent. A component whose walk finds a contradiction is
//! non-orientable (a Möbius band); it is left as the walk made it and
//! reported. A component with no inconsistent interior edge (checked first,
//! on the pool) needs no walk. Closed, orientable components with negative
//! enclosed volume are then reversed as a whole so normals point outward.

use super::components::{Components, connected_components};
use super::{EdgeId, FaceId, Topology, TriMesh};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::VecDeque;

/// What [`orient_consistently`] changed.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct OrientationReport {
    /// Triangles flipped to agree with their neighbours.
    pub n_triangles_flipped: usize,
    /// Components that cannot be oriented (contain a Möbius-like strip).
    pub n_nonorientable_components: usize,
    /// Closed components reversed as a whole so their normals point outward.
    pub n_components_reversed_outward: usize,
}

/// Orient every component consistently and closed ones outward; keeps
/// `topo` in step with `mesh`.
pub fn orient_consistently(mesh: &mut TriMesh, topo: &mut Topology) -> OrientationReport {
    let comps = connected_components(topo);
    orient_components(mesh, topo, &comps)
}

/// [`orient_consistently`] with the edge-connected components already
/// known (`comps` of `topo`), so that a caller who also summarises the
/// topology computes them once: flipping triangles changes no component.
pub fn orient_components(mesh: &mut TriMesh, topo: &mut Topology, comps: &Components) -> OrientationReport {
    let mut report = OrientationReport::default();
    let needs_walk = components_with_inconsistent_edges(mesh, topo, comps);
    let mut flip = vec![false; mesh.n_faces()];
    let mut seen = vec![false; mesh.n_faces()];
    for (c, faces) in comps.faces_per_component().into_iter().enumerate() {
        // A component without an inconsistent edge walks to no flip: skipped.
        if needs_walk[c] {
            let walk = walk_flip_bits(mesh, topo, &faces, &mut flip, &mut seen);
            let n_flip = faces.iter().filter(|f| flip[f.idx()]).count();
            let invert = 2 * n_flip > faces.len();
            for f in &faces {
                if flip[f.idx()] != invert {
                    mesh.flip_face(*f);
                    topo.flip_face(*f);
                    report.n_triangles_flipped += 1;
                }
            }
            if !walk {
                report.n_nonorientable_components += 1;
                continue;
            }
        }
        if is_closed(topo, &faces) && component_volume(mesh, &faces) < 0.0 {
            for f in &faces {
                mesh.flip_face(*f);
                topo.flip_face(*f);
            }
            report.n_components_reversed_outward += 1;
        }
    }
    debug_assert!(mesh.validate().is_ok());
    debug_assert!(topo.validate(mesh).is_ok());
    report
}

/// Per component, true when one of its interior edges is traversed in the
/// same direction by both its triangles; edges checked on the pool. Most
/// uploads are consistent already, and this check costs one pass where
/// the breadth-first walk costs a queue and random access per triangle.
fn components_with_inconsistent_edges(mesh: &TriMesh, topo: &Topology, comps: &Components) -> Vec<bool> {
    let faces: Vec<FaceId> = (0..topo.n_edges())
        .into_par_iter()
        .filter_map(|e| inconsistent_edge_face(mesh, topo, EdgeId::new(e)))
        .collect();
    let mut needs = vec![false; comps.n_components];
    for f in faces {
        needs[comps.component_per_face[f.idx()] as usize] = true;
    }
    needs
}

/// Breadth-first walk over the interior edges of one component (`faces`,
/// increasing ids) from its first triangle, setting `flip` so that every
/// triangle agrees with the one it was reached from; returns false when
/// the walk meets a contradiction (non-orientable).
fn walk_flip_bits(mesh: &TriMesh, topo: &Topology, faces: &[FaceId], flip: &mut [bool], seen: &mut [bool]) -> bool {
    let mut consistent = true;
    let mut queue = VecDeque::new();
    seen[faces[0].idx()] = true;
    queue.push_back(faces[0]);
    while let Some(f) = queue.pop_front() {
        for i in 0..3 {
            let Some(g) = topo.face_across(f, i) else {
                continue;
            };
            let same_dir = traverses_same_direction(mesh, topo, f, i, g);
            let want = flip[f.idx()] ^ same_dir;
            if seen[g.idx()] {
                consistent &= flip[g.idx()] == want;
            } else {
                seen[g.idx()] = true;
                flip[g.idx()] = want;
                queue.push_back(g);
            }
        }
    }
    consistent
}

/// True when triangle `g` traverses local edge `i` of `f` in the same direction as `f`.
fn traverses_same_direction(mesh: &TriMesh, topo: &Topology, f: FaceId, i: usize, g: FaceId) -> bool {
    let e = topo.face_edges[f.idx()][i];
    let j = topo.local_edge(g, e).expect("neighbour shares the edge");
    mesh.triangles[f.idx()][i] == mesh.triangles[g.idx()][j]
}

/// True when every edge of these triangles has exactly two triangles.
fn is_closed(topo: &Topology, faces: &[FaceId]) -> bool {
    faces.par_iter().all(|f| topo.face_edges[f.idx()].iter().all(|&e| topo.edge_valence(e) == 2))
}

/// Signed volume enclosed by the given triangles, summed in fixed chunks
/// on the pool and then in chunk order, so the value (and the sign that
/// decides a reversal) does not depend on the thread count.
fn component_volume(mesh: &TriMesh, faces: &[FaceId]) -> f64 {
    let chunk_sums: Vec<f64> = faces
        .par_chunks(1 << 14)
        .map(|chunk| {
            chunk
                .iter()
                .map(|f| {
                    let [a, b, c] = mesh.corners(*f);
                    a.dot(&b.cross(&c)) / 6.0
                })
                .sum()
        })
        .collect();
    chunk_sums.iter().sum()
}

/// One triangle of interior edge `e` when both its triangles traverse it
/// in the same direction; `None` for a consistent, boundary or
/// non-manifold edge.
fn inconsistent_edge_face(mesh: &TriMesh, topo: &Topology, e: EdgeId) -> Option<FaceId> {
    let [f, g] = topo.edge_faces(e) else { return None };
    let i = topo.local_edge(*f, e).expect("own edge");
    traverses_same_direction(mesh, topo, *f, i, *g).then_some(*f)
}

/// Number of interior edges whose two triangles traverse them in the same direction.
pub fn n_inconsistent_edges(mesh: &TriMesh, topo: &Topology) -> usize {
    (0..topo.n_edges()).filter(|&e| inconsistent_edge_face(mesh, topo, EdgeId::new(e)).is_some()).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn flips_the_minority_and_orients_outward() {
        let mut m = fixtures::icosphere(2);
        let n = m.n_faces();
        for f in [3usize, 7, 11] {
            m.flip_face(FaceId::new(f));
        }
        let mut t = Topology::new(&m);
        assert!(n_inconsistent_edges(&m, &t) > 0);
        let r = orient_consistently(&mut m, &mut t);
        assert_eq!(r.n_triangles_flipped, 3);
        assert_eq!(r.n_components_reversed_outward, 0);
        assert_eq!(n_inconsistent_edges(&m, &t), 0);
        assert!(m.signed_volume() > 0.0);

        // Reverse everything: consistent but inward, reversed as a whole.
        for f in 0..n {
            m.flip_face(FaceId::new(f));
        }
        let mut t = Topology::new(&m);
        let r = orient_consistently(&mut m, &mut t);
        assert_eq!(r.n_triangles_flipped, 0);
        assert_eq!(r.n_components_reversed_outward, 1);
        assert!(m.signed_volume() > 0.0);
    }

    #[test]
    fn only_the_component_with_a_disagreement_is_walked() {
        let one = fixtures::icosphere(2);
        let n = one.n_faces();
        let shift = crate::geom::Vec3::new(5.0, 0.0, 0.0);
        let positions = one.positions.iter().copied().chain(one.positions.iter().map(|p| *p + shift)).collect();
        let nv = one.n_vertices() as u32;
        let triangles: Vec<[u32; 3]> = one
            .triangles
            .iter()
            .map(|t| t.map(|v| v.0))
            .chain(one.triangles.iter().map(|t| [t[0].0 + nv, t[2].0 + nv, t[1].0 + nv]))
            .collect();
        // First copy: outward with two triangles flipped; second: consistent but inward.
        let mut m = TriMesh::from_raw(positions, &triangles);
        m.flip_face(FaceId::new(5));
        m.flip_face(FaceId::new(9));
        let mut t = Topology::new(&m);
        let r = orient_consistently(&mut m, &mut t);
        assert_eq!(r.n_triangles_flipped, 2);
        assert_eq!(r.n_components_reversed_outward, 1);
        assert_eq!(n_inconsistent_edges(&m, &t), 0);
        let volume = |faces: std::ops::Range<usize>| component_volume(&m, &faces.map(FaceId::new).collect::<Vec<_>>());
        assert!(volume(0..n) > 0.0 && volume(n..2 * n) > 0.0);
    }

    #[test]
    fn mobius_band_is_nonorientable() {
        let mut m = fixtures::mobius_band(24);
        let mut t = Topology::new(&m);
        let r = orient_consistently(&mut m, &mut t);
        assert_eq!(r.n_nonorientable_components, 1);
    }
}
