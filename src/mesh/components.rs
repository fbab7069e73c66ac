//! Connected components of triangles (through shared edges) and of vertices.
//!
//! Two triangles are connected when they share an edge, whatever its valence;
//! a pinched vertex alone does not connect (that is a non-manifold vertex).
//! Components are numbered by their smallest triangle id, so the numbering
//! is deterministic. Union–find with path halving, near `O(n)`.

use super::{EdgeId, FaceId, Topology, TriMesh, VertexId};

/// Disjoint-set forest over `0..n` (union by size, path halving).
#[derive(Debug, Clone)]
pub struct DisjointSets {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl DisjointSets {
    /// `n` singletons.
    pub fn new(n: usize) -> Self {
        Self { parent: (0..n as u32).collect(), size: vec![1; n] }
    }

    /// Representative of the set containing `x`.
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let p = self.parent[x as usize];
            self.parent[x as usize] = self.parent[p as usize];
            x = self.parent[x as usize];
        }
        x
    }

    /// Merge the sets of `a` and `b`; returns false when already merged.
    pub fn union(&mut self, a: u32, b: u32) -> bool {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return false;
        }
        if self.size[a as usize] < self.size[b as usize] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b as usize] = a;
        self.size[a as usize] += self.size[b as usize];
        true
    }

    /// Dense labels `0..k` in order of first appearance, and `k`.
    pub fn labels(&mut self) -> (Vec<u32>, usize) {
        let n = self.parent.len();
        let mut label_of_root = vec![u32::MAX; n];
        let mut labels = vec![0; n];
        let mut k = 0u32;
        for x in 0..n as u32 {
            let r = self.find(x) as usize;
            if label_of_root[r] == u32::MAX {
                label_of_root[r] = k;
                k += 1;
            }
            labels[x as usize] = label_of_root[r];
        }
        (labels, k as usize)
    }
}

/// Edge-connected components of triangles.
#[derive(Debug, Clone, PartialEq)]
pub struct Components {
    /// Component label of each triangle, `0..n_components`.
    pub component_per_face: Vec<u32>,
    /// Number of components.
    pub n_components: usize,
}

impl Components {
    /// Triangles of each component, in increasing id order.
    pub fn faces_per_component(&self) -> Vec<Vec<FaceId>> {
        let mut out = vec![Vec::new(); self.n_components];
        for (f, &c) in self.component_per_face.iter().enumerate() {
            out[c as usize].push(FaceId::new(f));
        }
        out
    }
}

/// Label triangles by edge-connected component, optionally not crossing the
/// edges for which `blocked` is true (used to cut model faces along features).
pub fn face_components(topo: &Topology, blocked: impl Fn(EdgeId) -> bool) -> Components {
    let mut sets = DisjointSets::new(topo.face_edges.len());
    for e in 0..topo.n_edges() {
        let e = EdgeId::new(e);
        if blocked(e) {
            continue;
        }
        let faces = topo.edge_faces(e);
        for w in faces.windows(2) {
            sets.union(w[0].0, w[1].0);
        }
    }
    let (component_per_face, n_components) = sets.labels();
    Components { component_per_face, n_components }
}

/// Edge-connected components of the whole mesh.
pub fn connected_components(topo: &Topology) -> Components {
    face_components(topo, |_| false)
}

/// Vertices used by at least one triangle.
pub fn referenced_vertices(mesh: &TriMesh) -> Vec<bool> {
    let mut used = vec![false; mesh.n_vertices()];
    for t in &mesh.triangles {
        for v in t {
            used[v.idx()] = true;
        }
    }
    used
}

/// Non-manifold vertices: vertices whose incident triangles form more than
/// one fan (triangles around the vertex connected through edges at the vertex).
/// Returns the vertices, sorted.
pub fn nonmanifold_vertices(mesh: &TriMesh, topo: &Topology) -> Vec<VertexId> {
    use rayon::prelude::*;
    let flags: Vec<bool> = (0..mesh.n_vertices())
        .into_par_iter()
        .map_init(Vec::new, |parent, v| count_fans(mesh, topo, VertexId::new(v), parent) > 1)
        .collect();
    flags.iter().enumerate().filter(|(_, f)| **f).map(|(v, _)| VertexId::new(v)).collect()
}

/// True when one of `candidates` has more than one fan of triangles.
pub fn any_nonmanifold_vertex(mesh: &TriMesh, topo: &Topology, candidates: impl IntoIterator<Item = VertexId>) -> bool {
    let mut parent = Vec::new();
    candidates.into_iter().any(|v| count_fans(mesh, topo, v, &mut parent) > 1)
}

/// True when walking around `v` across its edges, from the first of its
/// triangles `faces`, comes back to it through interior edges after visiting
/// every one of them: the triangles then form exactly one fan. `O(d)` with no
/// search, the case of almost every vertex of a closed surface; any other
/// case (a boundary or non-manifold edge, a second fan) answers `false` and
/// is counted by the union–find of [`count_fans`].
fn is_one_closed_fan(mesh: &TriMesh, topo: &Topology, v: VertexId, faces: &[FaceId]) -> bool {
    let edges_at_v = |f: FaceId| {
        let (t, fe) = (mesh.triangles[f.idx()], topo.face_edges[f.idx()]);
        let mut at = (0..3).filter(|&k| t[k] == v || t[(k + 1) % 3] == v).map(|k| fe[k]);
        Some([at.next()?, at.next()?])
    };
    let start = faces[0];
    let Some([_, mut e]) = edges_at_v(start) else { return false };
    let (mut f, mut visited) = (start, 1);
    loop {
        let g = match topo.edge_faces(e) {
            [a, b] if *a == f => *b,
            [a, b] if *b == f => *a,
            _ => return false,
        };
        if g == start {
            return visited == faces.len();
        }
        visited += 1;
        if visited > faces.len() {
            return false;
        }
        let Some([x, y]) = edges_at_v(g) else { return false };
        e = if x == e { y } else { x };
        f = g;
    }
}

/// Number of fans of the triangles around `v`: a union–find over the
/// triangles of the one-ring, in the reusable buffer `parent` (no allocation
/// per vertex once the buffer has grown to the largest valence). `vertex_faces`
/// is sorted, so finding a neighbour triangle is a binary search: `O(d log d)`
/// for valence `d`, also for hostile fans of huge valence.
fn count_fans(mesh: &TriMesh, topo: &Topology, v: VertexId, parent: &mut Vec<u32>) -> usize {
    let faces = topo.vertex_faces(v);
    if faces.len() < 2 {
        return faces.len();
    }
    if is_one_closed_fan(mesh, topo, v, faces) {
        return 1;
    }
    union_fans(mesh, topo, v, faces, parent)
}

/// Representative of `x` in the union–find forest `parent` (path halving).
fn root(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        parent[x as usize] = parent[parent[x as usize] as usize];
        x = parent[x as usize];
    }
    x
}

/// Joins in `parent` (one entry per triangle of `faces`, the sorted
/// triangles around `v`) the triangles that share an edge at `v`; returns
/// the number of fans.
fn union_fans(mesh: &TriMesh, topo: &Topology, v: VertexId, faces: &[FaceId], parent: &mut Vec<u32>) -> usize {
    parent.clear();
    parent.extend(0..faces.len() as u32);
    let mut n_fans = faces.len();
    for (i, &f) in faces.iter().enumerate() {
        let t = mesh.triangles[f.idx()];
        for k in 0..3 {
            if t[k] != v && t[(k + 1) % 3] != v {
                continue;
            }
            for g in topo.edge_faces(topo.face_edges[f.idx()][k]) {
                if let Ok(j) = faces.binary_search(g) {
                    let (a, b) = (root(parent, i as u32), root(parent, j as u32));
                    if a != b {
                        parent[a as usize] = b;
                        n_fans -= 1;
                    }
                }
            }
        }
    }
    n_fans
}

/// The fan of each triangle around `v` (in the order of
/// `topo.vertex_faces(v)`), as the index of one triangle of the fan: two
/// triangles are in one fan when a path of triangles sharing edges at `v`
/// joins them.
pub fn fan_of_each_face(mesh: &TriMesh, topo: &Topology, v: VertexId) -> Vec<u32> {
    let mut parent = Vec::new();
    union_fans(mesh, topo, v, topo.vertex_faces(v), &mut parent);
    (0..parent.len() as u32).map(|i| root(&mut parent, i)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use crate::mesh::fixtures;

    #[test]
    fn two_tetrahedra_are_two_components() {
        let a = fixtures::tetrahedron();
        let mut m = a.clone();
        let n = m.positions.len() as u32;
        m.positions.extend(a.positions.iter().map(|p| p + Vec3::new(5.0, 0.0, 0.0)));
        m.triangles.extend(a.triangles.iter().map(|t| t.map(|v| VertexId(v.0 + n))));
        let t = Topology::new(&m);
        let c = connected_components(&t);
        assert_eq!(c.n_components, 2);
        assert_eq!(c.faces_per_component()[1].len(), 4);
    }

    #[test]
    fn pinched_vertex_is_nonmanifold_and_splits_components() {
        // Two triangles touching only at vertex 0.
        let m = TriMesh::from_raw(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(-1.0, 0.0, 0.0),
                Vec3::new(-1.0, -1.0, 0.0),
            ],
            &[[0, 1, 2], [0, 3, 4]],
        );
        let t = Topology::new(&m);
        assert_eq!(nonmanifold_vertices(&m, &t), vec![VertexId(0)]);
        assert_eq!(connected_components(&t).n_components, 2);
    }

    #[test]
    fn blocked_edges_cut_components() {
        let m = fixtures::square(2);
        let t = Topology::new(&m);
        let c = face_components(&t, |e| {
            let [a, b] = t.edges[e.idx()];
            (m.position(a).x - 0.5).abs() < 1e-12 && (m.position(b).x - 0.5).abs() < 1e-12
        });
        assert_eq!(c.n_components, 2);
        assert!(nonmanifold_vertices(&m, &t).is_empty());
    }
}
