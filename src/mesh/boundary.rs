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
        (0..n)
            .map(|i| {
                (mesh.position(self.vertices[(i + 1) % n]) - mesh.position(self.vertices[i])).norm()
            })
            .sum()
    }
}

/// All boundary loops of the mesh, in order of their smallest edge id.
pub fn boundary_loops(mesh: &TriMesh, topo: &Topology) -> Vec<BoundaryLoop> {
    boundary_loops_where(mesh, topo, |e| topo.is_boundary_edge(e))
}

/// Loops formed by the edges selected by `is_cut` (each selected edge must
/// have exactly one triangle on the side being bounded, e.g. patch borders).
/// Edge direction is taken from the (first) triangle owning it.
pub fn boundary_loops_where(
    mesh: &TriMesh,
    topo: &Topology,
    is_cut: impl Fn(EdgeId) -> bool,
) -> Vec<BoundaryLoop> {
    // Directed boundary half-edges a→b as their owning triangle traverses them.
    let mut outgoing: std::collections::HashMap<VertexId, Vec<(VertexId, EdgeId)>> =
        Default::default();
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
            let next = outgoing
                .get(&cur)
                .and_then(|outs| outs.iter().find(|(_, e)| !used.contains(e)).copied());
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

/// Number of connected pieces of the boundary-edge graph.
pub fn boundary_components(topo: &Topology) -> usize {
    let mut sets = DisjointSets::new(topo.vertex_count_hint());
    let mut touched = Vec::new();
    for e in 0..topo.n_edges() {
        let e = EdgeId::new(e);
        if topo.is_boundary_edge(e) {
            let [a, b] = topo.edges[e.idx()];
            sets.union(a.0, b.0);
            touched.push(a.0);
        }
    }
    let mut roots: Vec<u32> = touched.into_iter().map(|v| sets.find(v)).collect();
    roots.sort_unstable();
    roots.dedup();
    roots.len()
}

impl Topology {
    /// One more than the largest vertex id used by an edge (0 when no edges).
    pub(crate) fn vertex_count_hint(&self) -> usize {
        self.edges.iter().map(|e| e[1].idx() + 1).max().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
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

    #[test]
    fn annulus_has_two_loops() {
        let m = fixtures::annulus(0.5, 1.0, 24, 3);
        let t = Topology::new(&m);
        assert_eq!(boundary_loops(&m, &t).len(), 2);
        assert_eq!(boundary_components(&t), 2);
    }
}
