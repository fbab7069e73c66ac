//! Edge topology of a triangle mesh: edges, edge → triangles, vertex → triangles.
//!
//! Edges are unordered vertex pairs stored as `[min, max]`, numbered in
//! lexicographic order so the numbering is deterministic. Local edge `i` of a
//! triangle goes from corner `i` to corner `(i + 1) % 3`. An edge with one
//! incident triangle is a boundary edge, with two an interior (manifold) edge,
//! with three or more a non-manifold edge. Incidences are stored as
//! compressed rows (CSR): building costs one sort of the `3·n_faces`
//! half-edges, `O(n log n)`, and no allocation per element.

use super::{EdgeId, FaceId, MeshError, TriMesh, VertexId};

/// Edges and incidences derived from a [`TriMesh`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Topology {
    /// Endpoints of each edge, `[min, max]`.
    pub edges: Vec<[VertexId; 2]>,
    /// For each triangle, its three edges: local edge `i` joins corners `i` and `i+1`.
    pub face_edges: Vec<[EdgeId; 3]>,
    edge_face_offsets: Vec<u32>,
    edge_faces: Vec<FaceId>,
    vertex_face_offsets: Vec<u32>,
    vertex_faces: Vec<FaceId>,
}

/// Half-edge record used while building: sorted endpoints, owning face, local index.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct HalfEdgeKey {
    lo: u32,
    hi: u32,
    face: u32,
    local: u8,
}

/// Every half-edge of `mesh` as a key, sorted by `(lo, hi, face, local)`:
/// a counting sort on `lo` (one bucket per vertex), then a sort of each
/// bucket, which holds a vertex's few outgoing edges. Why not one
/// comparison sort: `perf` put the parallel sort of the 3·F keys at 11 % of
/// a whole atlas run (topologies are built for the input, every patch and
/// the result); this is linear and cache-friendly, and gives the same
/// order, so edge numbering is unchanged.
fn sorted_half_edges(mesh: &TriMesh) -> Vec<HalfEdgeKey> {
    let key = |f: usize, i: usize| {
        let t = &mesh.triangles[f];
        let (a, b) = (t[i].0, t[(i + 1) % 3].0);
        HalfEdgeKey { lo: a.min(b), hi: a.max(b), face: f as u32, local: i as u8 }
    };
    let mut next = vec![0usize; mesh.n_vertices() + 1];
    for t in &mesh.triangles {
        for i in 0..3 {
            next[t[i].0.min(t[(i + 1) % 3].0) as usize + 1] += 1;
        }
    }
    for v in 0..mesh.n_vertices() {
        next[v + 1] += next[v];
    }
    let start = next.clone();
    let mut keys = vec![HalfEdgeKey { lo: 0, hi: 0, face: 0, local: 0 }; 3 * mesh.n_faces()];
    for f in 0..mesh.n_faces() {
        for i in 0..3 {
            let k = key(f, i);
            keys[next[k.lo as usize]] = k;
            next[k.lo as usize] += 1;
        }
    }
    for v in 0..mesh.n_vertices() {
        keys[start[v]..start[v + 1]].sort_unstable();
    }
    keys
}

impl Topology {
    /// Build the topology of `mesh` (which must satisfy [`TriMesh::validate`]).
    pub fn new(mesh: &TriMesh) -> Self {
        let n_f = mesh.n_faces();
        // The edge table and the vertex–triangle lists are independent passes
        // over the triangles: build them side by side on the pool.
        let (keys, (vertex_face_offsets, vertex_faces)) =
            rayon::join(|| sorted_half_edges(mesh), || vertex_face_csr(mesh));

        let mut edges = Vec::with_capacity(keys.len() / 2 + 1);
        let mut face_edges = vec![[EdgeId(0); 3]; n_f];
        let mut edge_face_offsets = Vec::with_capacity(keys.len() / 2 + 2);
        let mut edge_faces = Vec::with_capacity(keys.len());
        for (k, key) in keys.iter().enumerate() {
            if k == 0 || (keys[k - 1].lo, keys[k - 1].hi) != (key.lo, key.hi) {
                edge_face_offsets.push(edge_faces.len() as u32);
                edges.push([VertexId(key.lo), VertexId(key.hi)]);
            }
            let e = EdgeId::new(edges.len() - 1);
            face_edges[key.face as usize][key.local as usize] = e;
            edge_faces.push(FaceId(key.face));
        }
        edge_face_offsets.push(edge_faces.len() as u32);
        let topo = Self { edges, face_edges, edge_face_offsets, edge_faces, vertex_face_offsets, vertex_faces };
        debug_assert!(topo.validate(mesh).is_ok());
        topo
    }

    /// Number of vertices of the mesh the topology was built from.
    pub fn n_vertices(&self) -> usize {
        self.vertex_face_offsets.len().saturating_sub(1)
    }

    /// Number of edges.
    #[inline]
    pub fn n_edges(&self) -> usize {
        self.edges.len()
    }

    /// Triangles incident to edge `e` (one for boundary, two for interior edges).
    #[inline]
    pub fn edge_faces(&self, e: EdgeId) -> &[FaceId] {
        let (a, b) = (self.edge_face_offsets[e.idx()], self.edge_face_offsets[e.idx() + 1]);
        &self.edge_faces[a as usize..b as usize]
    }

    /// Number of triangles incident to edge `e`.
    #[inline]
    pub fn edge_valence(&self, e: EdgeId) -> usize {
        (self.edge_face_offsets[e.idx() + 1] - self.edge_face_offsets[e.idx()]) as usize
    }

    /// True when exactly one triangle uses edge `e`.
    #[inline]
    pub fn is_boundary_edge(&self, e: EdgeId) -> bool {
        self.edge_valence(e) == 1
    }

    /// True when three or more triangles share edge `e`.
    #[inline]
    pub fn is_nonmanifold_edge(&self, e: EdgeId) -> bool {
        self.edge_valence(e) > 2
    }

    /// Triangles incident to vertex `v`, in increasing id order.
    #[inline]
    pub fn vertex_faces(&self, v: VertexId) -> &[FaceId] {
        let (a, b) = (self.vertex_face_offsets[v.idx()], self.vertex_face_offsets[v.idx() + 1]);
        &self.vertex_faces[a as usize..b as usize]
    }

    /// The edge joining `a` and `b`, if any (`O(valence)` lookup).
    pub fn edge_between(&self, a: VertexId, b: VertexId) -> Option<EdgeId> {
        let key = [a.min(b), a.max(b)];
        self.vertex_faces(a).iter().flat_map(|f| self.face_edges[f.idx()]).find(|e| self.edges[e.idx()] == key)
    }

    /// The triangle across local edge `i` of `f`, when that edge is interior (valence 2).
    #[inline]
    pub fn face_across(&self, f: FaceId, i: usize) -> Option<FaceId> {
        let e = self.face_edges[f.idx()][i];
        match self.edge_faces(e) {
            [a, b] => Some(if *a == f { *b } else { *a }),
            _ => None,
        }
    }

    /// Local index (0..3) of edge `e` in triangle `f`, if `f` contains it.
    #[inline]
    pub fn local_edge(&self, f: FaceId, e: EdgeId) -> Option<usize> {
        self.face_edges[f.idx()].iter().position(|&x| x == e)
    }

    /// Keep `face_edges` in step after [`TriMesh::flip_face`] swapped corners 1 and 2.
    pub fn flip_face(&mut self, f: FaceId) {
        self.face_edges[f.idx()].swap(0, 2);
    }

    /// Number of boundary edges.
    pub fn n_boundary_edges(&self) -> usize {
        (0..self.n_edges()).filter(|&e| self.is_boundary_edge(EdgeId::new(e))).count()
    }

    /// Number of non-manifold edges (three or more triangles).
    pub fn n_nonmanifold_edges(&self) -> usize {
        (0..self.n_edges()).filter(|&e| self.is_nonmanifold_edge(EdgeId::new(e))).count()
    }

    /// Check that this topology describes `mesh`.
    ///
    /// # Errors
    /// [`MeshError::Inconsistent`] naming the first disagreement.
    pub fn validate(&self, mesh: &TriMesh) -> Result<(), MeshError> {
        let bad = |s: String| Err(MeshError::Inconsistent(s));
        if self.face_edges.len() != mesh.n_faces() {
            return bad(format!("{} face edge rows for {} triangles", self.face_edges.len(), mesh.n_faces()));
        }
        if self.vertex_face_offsets.len() != mesh.n_vertices() + 1 {
            return bad("vertex-face rows do not match the vertex count".into());
        }
        for (f, t) in mesh.triangles.iter().enumerate() {
            for i in 0..3 {
                let e = self.face_edges[f][i];
                let (a, b) = (t[i], t[(i + 1) % 3]);
                if self.edges.get(e.idx()) != Some(&[a.min(b), a.max(b)]) {
                    return bad(format!("triangle {f} local edge {i} is not edge {e}"));
                }
                if !self.edge_faces(e).contains(&FaceId::new(f)) {
                    return bad(format!("edge {e} does not list triangle {f}"));
                }
                if !self.vertex_faces(t[i]).contains(&FaceId::new(f)) {
                    return bad(format!("vertex {} does not list triangle {f}", t[i]));
                }
            }
        }
        if self.edge_faces.len() != 3 * mesh.n_faces() || self.vertex_faces.len() != 3 * mesh.n_faces() {
            return bad("incidence counts differ from 3 per triangle".into());
        }
        Ok(())
    }
}

/// Vertex → triangle incidences as CSR (counting sort, `O(n)`).
fn vertex_face_csr(mesh: &TriMesh) -> (Vec<u32>, Vec<FaceId>) {
    let mut offsets = vec![0u32; mesh.n_vertices() + 1];
    for t in &mesh.triangles {
        for v in t {
            offsets[v.idx() + 1] += 1;
        }
    }
    for i in 0..mesh.n_vertices() {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut faces = vec![FaceId(0); 3 * mesh.n_faces()];
    for (f, t) in mesh.triangles.iter().enumerate() {
        for v in t {
            faces[fill[v.idx()] as usize] = FaceId::new(f);
            fill[v.idx()] += 1;
        }
    }
    (offsets, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn bucketed_half_edges_are_in_full_key_order() {
        for m in [fixtures::torus(1.0, 0.4, 12, 7), fixtures::disk(5), fixtures::mobius_band(8)] {
            let keys = sorted_half_edges(&m);
            let mut sorted = keys.clone();
            sorted.sort_unstable();
            assert!(keys == sorted);
            assert_eq!(keys.len(), 3 * m.n_faces());
        }
    }

    #[test]
    fn tetrahedron_surface_is_closed_and_manifold() {
        let m = fixtures::tetrahedron();
        let t = Topology::new(&m);
        assert_eq!(t.n_edges(), 6);
        assert_eq!(t.n_boundary_edges(), 0);
        assert_eq!(t.n_nonmanifold_edges(), 0);
        for v in 0..4 {
            assert_eq!(t.vertex_faces(VertexId(v)).len(), 3);
        }
        assert!(t.validate(&m).is_ok());
    }

    #[test]
    fn square_has_boundary_and_one_interior_edge() {
        let m = fixtures::square(1);
        let t = Topology::new(&m);
        assert_eq!(t.n_edges(), 5);
        assert_eq!(t.n_boundary_edges(), 4);
        let e = (0..5).map(EdgeId::new).find(|&e| t.edge_valence(e) == 2).unwrap();
        let [a, b] = t.edges[e.idx()];
        assert_eq!(t.edge_between(b, a), Some(e));
        let f = t.edge_faces(e)[0];
        let i = t.local_edge(f, e).unwrap();
        assert_eq!(t.face_across(f, i), Some(t.edge_faces(e)[1]));
    }

    #[test]
    fn three_triangles_on_one_edge_are_nonmanifold() {
        let m = TriMesh::from_raw(
            vec![
                crate::geom::Vec3::new(0.0, 0.0, 0.0),
                crate::geom::Vec3::new(1.0, 0.0, 0.0),
                crate::geom::Vec3::new(0.0, 1.0, 0.0),
                crate::geom::Vec3::new(0.0, -1.0, 0.0),
                crate::geom::Vec3::new(0.0, 0.0, 1.0),
            ],
            &[[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        );
        let t = Topology::new(&m);
        assert_eq!(t.n_nonmanifold_edges(), 1);
        assert_eq!(t.n_boundary_edges(), 6);
    }

    #[test]
    fn flip_keeps_face_edges_consistent() {
        let mut m = fixtures::square(2);
        let mut t = Topology::new(&m);
        m.flip_face(FaceId(3));
        t.flip_face(FaceId(3));
        assert!(t.validate(&m).is_ok());
    }
}
