//! Boundary loops: closed chains of boundary edges (edges with one triangle).
//!
//! A loop is returned as its vertex cycle (first vertex not repeated),
//! oriented like the triangles along it: the interior is on the left when
//! walking the loop with the normal pointing up. At a vertex where several
//! boundary chains meet (a pinch), the walk takes the unused boundary edge
//! that continues the current triangle fan; the number of loops then counts
//! the cycles, while [`boundary_components`] counts connected pieces of the
//! boundary-edge graph (the two agree on manifold meshes).

use super::components::DisjointSets;
use super::{EdgeId, Topology, TriMesh, VertexId};

/// One boundary loop.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundaryLoop {
    /// Vertices in walking order (interior on the left).
    pub vertices: Vec<VertexId>,
    /// Edges in walking order: `edges[i]` joins `vertices[i]` and `vertices[i+1]`.
    pub edges: Vec<EdgeId>,
}

impl BoundaryLoop {
    /// Length of the loop in 3D.
    pub fn length(&self, mesh: &TriMesh) -> f64 {
        let n = self.vertices.len();
        (0..n).map(|i| (mesh.position(self.vertices[(i + 1) % n]) - mesh.position(self.vertices[i])).norm()).sum()
    }
}

/// All boundary loops of the mesh, in order of their smallest edge id.
pub fn boundary_loops(mesh: &TriMesh, topo: &Topology) -> Vec<BoundaryLoop> {
    boundary_loops_where(mesh, topo, |e| topo.is_boundary_edge(e))
}

/// Loops formed by the edges selected by `is_cut` (each selected edge must
/// have exactly one triangle on the side being bounded, e.g. patch borders).
/// Edge direction is taken from the (first) triangle owning it.
pub fn boundary_loops_where(mesh: &TriMesh, topo: &Topology, is_cut: impl Fn(EdgeId) -> bool) -> Vec<BoundaryLoop> {
    // Directed boundary half-edges a→b as their owning triangle traverses them.
    let mut outgoing: std::collections::HashMap<VertexId, Vec<(VertexId, EdgeId)>> = Default::default();
    let mut order = Vec::new();
    for e in 0..topo.n_edges() {
        let e = EdgeId::new(e);
        if !is_cut(e) {
            continue;
        }
        let f = topo.edge_faces(e)[0];
        let i = topo.local_edge(f, e).expect("edge of its own face");
        let t = mesh.triangles[f.idx()];
        let (a, b) = (t[i], t[(i + 1) % 3]);
        outgoing.entry(a).or_default().push((b, e));
        order.push(e);
    }
    let mut used = std::collections::HashSet::new();
    let mut loops = Vec::new();
    for &start in &order {
        if used.contains(&start) {
            continue;
        }
        let f = topo.edge_faces(start)[0];
        let i = topo.local_edge(f, start).expect("edge of its own face");
        let t = mesh.triangles[f.idx()];
        let (first, mut cur) = (t[i], t[(i + 1) % 3]);
        used.insert(start);
        let mut vertices = vec![first];
        let mut edges = vec![start];
        while cur != first {
            let next = outgoing.get(&cur).and_then(|outs| outs.iter().find(|(_, e)| !used.contains(e)).copied());
            let Some((to, e)) = next else { break };
            used.insert(e);
            vertices.push(cur);
            edges.push(e);
            cur = to;
        }
        loops.push(BoundaryLoop { vertices, edges });
    }
    loops
}

/// One connected piece of the boundary-edge graph: what repair's
/// `n_boundary_loops` and the frames stage's open-surface error count as a
/// boundary loop. It needs no orientation, so it is the same on
/// non-orientable surfaces (a Möbius strip has one), and an edge shared by
/// three or more triangles is non-manifold, not boundary.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundaryPiece {
    /// Its boundary edges, by increasing id.
    pub edges: Vec<EdgeId>,
    /// Its vertices, in order of first appearance along `edges`.
    pub vertices: Vec<VertexId>,
}

impl BoundaryPiece {
    /// Total length of its edges in 3D.
    pub fn length(&self, mesh: &TriMesh, topo: &Topology) -> f64 {
        self.edges
            .iter()
            .map(|e| {
                let [a, b] = topo.edges[e.idx()];
                (mesh.position(b) - mesh.position(a)).norm()
            })
            .sum()
    }
}

/// The connected pieces of the boundary-edge graph (edges with one
/// triangle), in order of their smallest edge id.
pub fn boundary_pieces(topo: &Topology) -> Vec<BoundaryPiece> {
    let mut sets = DisjointSets::new(topo.vertex_count_hint());
    let boundary: Vec<EdgeId> = (0..topo.n_edges()).map(EdgeId::new).filter(|&e| topo.is_boundary_edge(e)).collect();
    for &e in &boundary {
        let [a, b] = topo.edges[e.idx()];
        sets.union(a.0, b.0);
    }
    let mut piece_of_root: std::collections::HashMap<u32, usize> = Default::default();
    let mut pieces: Vec<BoundaryPiece> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for &e in &boundary {
        let [a, b] = topo.edges[e.idx()];
        let root = sets.find(a.0);
        let k = *piece_of_root.entry(root).or_insert_with(|| {
            pieces.push(BoundaryPiece { edges: Vec::new(), vertices: Vec::new() });
            pieces.len() - 1
        });
        pieces[k].edges.push(e);
        for v in [a, b] {
            if seen.insert(v) {
                pieces[k].vertices.push(v);
            }
        }
    }
    pieces
}

/// Number of connected pieces of the boundary-edge graph ([`boundary_pieces`]).
pub fn boundary_components(topo: &Topology) -> usize {
    boundary_pieces(topo).len()
}

impl Topology {
    /// One more than the largest vertex id used by an edge (0 when no edges).
    pub(crate) fn vertex_count_hint(&self) -> usize {
        self.edges.iter().map(|e| e[1].idx() + 1).max().unwrap_or(0)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn disk_has_one_ccw_loop() {
        let m = fixtures::disk(4);
        let t = Topology::new(&m);
        let loops = boundary_loops(&m, &t);
        assert_eq!(loops.len(), 1);
        assert_eq!(loops[0].vertices.len(), 24);
        // Counter-clockwise in the plane: positive signed area.
        let vs = &loops[0].vertices;
        let area: f64 = (0..vs.len())
            .map(|i| {
                let (p, q) = (m.position(vs[i]), m.position(vs[(i + 1) % vs.len()]));
                p.x * q.y - q.x * p.y
            })
            .sum();
        assert!(area > 0.0);
        assert!((loops[0].length(&m) - 2.0 * std::f64::consts::PI).abs() < 0.05);
        assert_eq!(boundary_components(&t), 1);
    }

    #[test]
    fn closed_surface_has_no_loop() {
        let m = fixtures::icosphere(1);
        let t = Topology::new(&m);
        assert!(boundary_loops(&m, &t).is_empty());
        assert_eq!(boundary_components(&t), 0);
    }

    /// Three triangles on the edge (0, 1): that edge is non-manifold, the
    /// other six are boundary and form one piece.
    pub(crate) fn fin() -> TriMesh {
        let p = |x: f64, y: f64, z: f64| crate::geom::Vec3::new(x, y, z);
        let positions = vec![p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.5, 1.0, 0.0), p(0.5, -1.0, 0.0), p(0.5, 0.0, 1.0)];
        TriMesh::from_raw(positions, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    }

    /// A Möbius strip of `n` quads (two triangles each), half-twisted.
    pub(crate) fn moebius(n: u32) -> TriMesh {
        let mut positions = Vec::new();
        for i in 0..n {
            let t = std::f64::consts::TAU * f64::from(i) / f64::from(n);
            for s in [-0.3, 0.3] {
                let r = 1.0 + s * (t / 2.0).cos();
                positions.push(crate::geom::Vec3::new(r * t.cos(), r * t.sin(), s * (t / 2.0).sin()));
            }
        }
        let mut tris = Vec::new();
        for i in 0..n {
            let (a, b) = (2 * i, 2 * i + 1);
            // The last quad joins the first with its sides swapped (the half twist).
            let (c, d) = if i + 1 == n { (1, 0) } else { (2 * i + 2, 2 * i + 3) };
            tris.push([a, c, b]);
            tris.push([b, c, d]);
        }
        TriMesh::from_raw(positions, &tris)
    }

    #[test]
    fn fin_has_one_boundary_piece_and_a_nonmanifold_edge() {
        let m = fin();
        let t = Topology::new(&m);
        assert_eq!(t.n_nonmanifold_edges(), 1);
        let pieces = boundary_pieces(&t);
        assert_eq!(pieces.len(), 1);
        assert_eq!(pieces[0].edges.len(), 6);
        assert_eq!(boundary_components(&t), 1);
    }

    #[test]
    fn moebius_strip_has_one_boundary_loop() {
        let m = moebius(12);
        let t = Topology::new(&m);
        let pieces = boundary_pieces(&t);
        assert_eq!(pieces.len(), 1, "{pieces:?}");
        assert_eq!(pieces[0].edges.len(), 24);
        assert_eq!(pieces[0].vertices.len(), 24);
    }

    #[test]
    fn annulus_has_two_loops() {
        let m = fixtures::annulus(0.5, 1.0, 24, 3);
        let t = Topology::new(&m);
        assert_eq!(boundary_loops(&m, &t).len(), 2);
        assert_eq!(boundary_components(&t), 2);
    }
}
