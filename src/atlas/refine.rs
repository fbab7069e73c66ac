//! Longest-edge bisection of the inner edges of a coarse patch (thesis ch. 2
//! §5.1, after Rivara 1997).
//!
//! A coarse CAD triangulation may have no interior vertex at all (a cylinder
//! side made of long slivers), and then even a one-to-one map is too rough
//! to mesh with. Each pass tags the inner edges (edges whose two triangles
//! are in the patch) longer than the target length, and splits them at their
//! midpoint from the longest to the shortest; each split replaces the two
//! triangles of the edge by four, so the mesh stays conforming and the
//! geometry is unchanged. Patch boundary edges are never split, so
//! neighbouring patches still match. Passes repeat until no inner edge is
//! longer than the target or `max_passes` is reached.

use crate::geom::Vec3;
use crate::mesh::{EdgeId, Topology, TriMesh, VertexId};
use std::collections::HashMap;

/// A refined patch mesh: new vertices are appended after the original ones.
#[derive(Debug, Clone)]
pub struct Refinement {
    /// The refined mesh (original vertices keep their indices).
    pub mesh: TriMesh,
    /// For each refined triangle, the original triangle it lies in.
    pub source_face: Vec<u32>,
    /// Number of edge bisections performed.
    pub n_bisections: usize,
}

/// Bisect inner edges longer than `target_length`, longest first, for up to
/// `max_passes` passes, stopping before the mesh exceeds `max_faces` triangles.
pub fn bisect_inner_edges(mesh: &TriMesh, target_length: f64, max_passes: usize, max_faces: usize) -> Refinement {
    let mut out = Refinement { mesh: mesh.clone(), source_face: (0..mesh.n_faces() as u32).collect(), n_bisections: 0 };
    for _ in 0..max_passes {
        let topo = Topology::new(&out.mesh);
        let mut tagged: Vec<(f64, [VertexId; 2])> = (0..topo.n_edges())
            .filter(|&e| topo.edge_valence(EdgeId::new(e)) == 2)
            .map(|e| {
                let [a, b] = topo.edges[e];
                ((out.mesh.positions[b.idx()] - out.mesh.positions[a.idx()]).norm(), [a, b])
            })
            .filter(|(l, _)| *l > target_length)
            .collect();
        if tagged.is_empty() {
            break;
        }
        tagged.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let mut faces_of_edge = edge_face_map(&out.mesh);
        for (_, [a, b]) in tagged {
            if out.mesh.n_faces() + 2 > max_faces {
                return out;
            }
            split_edge(&mut out, &mut faces_of_edge, a, b);
        }
        debug_assert!(out.mesh.validate().is_ok());
    }
    out
}

/// Triangles of an edge: up to two (patches are manifold), `NONE` when absent.
type EdgeFaces = [u32; 2];
const NONE: u32 = u32::MAX;

/// Add triangle `f` to the incidences of edge `k`.
fn attach(map: &mut HashMap<(u32, u32), EdgeFaces>, k: (u32, u32), f: u32) {
    let slot = map.entry(k).or_insert([NONE, NONE]);
    if slot[0] == NONE { slot[0] = f } else { slot[1] = f }
}

/// Map from sorted vertex pair to the (up to two) triangles using it.
fn edge_face_map(mesh: &TriMesh) -> HashMap<(u32, u32), EdgeFaces> {
    let mut map = HashMap::with_capacity(3 * mesh.n_faces() / 2);
    for (f, t) in mesh.triangles.iter().enumerate() {
        for i in 0..3 {
            attach(&mut map, key(t[i], t[(i + 1) % 3]), f as u32);
        }
    }
    map
}

#[inline]
fn key(a: VertexId, b: VertexId) -> (u32, u32) {
    (a.0.min(b.0), a.0.max(b.0))
}

/// Split edge `ab` at its midpoint, replacing its two triangles by four.
fn split_edge(out: &mut Refinement, faces_of_edge: &mut HashMap<(u32, u32), EdgeFaces>, a: VertexId, b: VertexId) {
    let Some(&faces) = faces_of_edge.get(&key(a, b)) else {
        return;
    };
    if faces.contains(&NONE) {
        return;
    }
    let pa: Vec3 = out.mesh.positions[a.idx()];
    let pb: Vec3 = out.mesh.positions[b.idx()];
    out.mesh.positions.push((pa + pb) * 0.5);
    let m = VertexId::new(out.mesh.positions.len() - 1);
    faces_of_edge.remove(&key(a, b));
    for f in faces {
        let t = out.mesh.triangles[f as usize];
        // Rotate so the split edge is local edge 0: t = [p, q, r] with {p, q} = {a, b}.
        let i = (0..3).find(|&i| key(t[i], t[(i + 1) % 3]) == key(a, b)).expect("face has the edge");
        let (p, q, r) = (t[i], t[(i + 1) % 3], t[(i + 2) % 3]);
        let g = out.mesh.triangles.len() as u32;
        out.mesh.triangles[f as usize] = [p, m, r];
        out.mesh.triangles.push([m, q, r]);
        out.source_face.push(out.source_face[f as usize]);
        // Update incidences: (q, r) moves from f to g; new edges (p, m), (m, q), (m, r).
        if let Some(list) = faces_of_edge.get_mut(&key(q, r)) {
            for x in list.iter_mut() {
                if *x == f {
                    *x = g;
                }
            }
        }
        attach(faces_of_edge, key(p, m), f);
        attach(faces_of_edge, key(m, q), g);
        attach(faces_of_edge, key(m, r), f);
        attach(faces_of_edge, key(m, r), g);
    }
    out.n_bisections += 1;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;
    use crate::mesh::orientation::n_inconsistent_edges;

    #[test]
    fn bisection_keeps_geometry_boundary_and_orientation() {
        let m = fixtures::square(1); // two triangles, one inner edge (the diagonal)
        let r = bisect_inner_edges(&m, 0.3, 5, 10_000);
        assert!(r.mesh.validate().is_ok());
        assert!(r.n_bisections > 0);
        assert!((r.mesh.area() - 1.0).abs() < 1e-14);
        let t = Topology::new(&r.mesh);
        assert_eq!(n_inconsistent_edges(&r.mesh, &t), 0);
        // The four sides are never split: still exactly 4 boundary edges.
        assert_eq!(t.n_boundary_edges(), 4);
        // Every inner edge is short now, or the passes ran out.
        let longest_inner = (0..t.n_edges())
            .filter(|&e| t.edge_valence(EdgeId::new(e)) == 2)
            .map(|e| (r.mesh.positions[t.edges[e][1].idx()] - r.mesh.positions[t.edges[e][0].idx()]).norm())
            .fold(0.0, f64::max);
        assert!(longest_inner <= 0.3 + 1e-12 || r.n_bisections >= 5);
        assert_eq!(r.source_face.len(), r.mesh.n_faces());
        assert!(r.source_face.iter().all(|&s| s < 2));
        // Each refined triangle lies in its source triangle (same normal, inside bbox).
        for (f, &s) in r.source_face.iter().enumerate() {
            let c = r.mesh.corners(crate::mesh::FaceId::new(f));
            let centroid = (c[0] + c[1] + c[2]) / 3.0;
            let in_lower = centroid.y <= centroid.x + 1e-12; // source 0 is below the diagonal
            assert_eq!(in_lower, s == 0);
        }
    }

    #[test]
    fn coarse_cylinder_side_gains_interior_vertices() {
        let m = fixtures::cylinder(1.0, 4.0, 12, 1); // one layer of long triangles
        let r = bisect_inner_edges(&m, 0.6, 5, 100_000);
        let t = Topology::new(&r.mesh);
        let mut on_boundary = vec![false; r.mesh.n_vertices()];
        for e in 0..t.n_edges() {
            if t.is_boundary_edge(EdgeId::new(e)) {
                t.edges[e].iter().for_each(|v| on_boundary[v.idx()] = true);
            }
        }
        assert!(on_boundary.iter().filter(|b| !**b).count() > 10);
        assert!((r.mesh.area() - m.area()).abs() < 1e-12);
    }
}
