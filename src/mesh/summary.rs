//! Topological summary of a triangle mesh: counts, Euler characteristic and
//! genus per component.
//!
//! Per edge-connected component `i`: `χᵢ = Vᵢ − Eᵢ + Fᵢ` (a vertex pinching
//! two components counts in both), `bᵢ` boundary loops (connected pieces of
//! its boundary-edge graph) and, for manifold components, genus
//! `gᵢ = (2 − χᵢ − bᵢ) / 2`. The mesh χ is `Σ χᵢ` minus the extra counts of
//! pinched vertices, i.e. `V − E + F` of the whole mesh.

use super::VertexId;
use super::components::{Components, DisjointSets, connected_components, nonmanifold_vertices};
use super::{EdgeId, Topology, TriMesh};
use serde::Serialize;

/// Topology of one edge-connected component.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ComponentSummary {
    /// Triangles in the component.
    pub n_faces: usize,
    /// Distinct vertices used by its triangles.
    pub n_vertices: usize,
    /// Distinct edges of its triangles.
    pub n_edges: usize,
    /// Connected pieces of its boundary-edge graph.
    pub n_boundary_loops: usize,
    /// `V − E + F` of the component.
    pub euler_characteristic: i64,
    /// `(2 − χ − b) / 2` when the component is a manifold, else `None`.
    pub genus: Option<i64>,
    /// No boundary and no non-manifold edge.
    pub closed: bool,
}

/// Topology of the whole mesh.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct TopologySummary {
    /// Vertices used by triangles.
    pub n_vertices: usize,
    /// Distinct edges.
    pub n_edges: usize,
    /// Triangles.
    pub n_faces: usize,
    /// Edges with one triangle.
    pub n_boundary_edges: usize,
    /// Edges with three or more triangles.
    pub n_nonmanifold_edges: usize,
    /// Vertices whose triangles form more than one fan.
    pub n_nonmanifold_vertices: usize,
    /// Connected pieces of the boundary-edge graph.
    pub n_boundary_loops: usize,
    /// `V − E + F` of the mesh (vertices counted once).
    pub euler_characteristic: i64,
    /// Per-component details, in order of each component's first triangle.
    pub components: Vec<ComponentSummary>,
}

impl TopologySummary {
    /// Number of edge-connected components.
    pub fn n_components(&self) -> usize {
        self.components.len()
    }

    /// Sum of component genera, when every component is a manifold.
    pub fn genus(&self) -> Option<i64> {
        self.components.iter().map(|c| c.genus).sum()
    }

    /// True when every component is closed.
    pub fn is_closed(&self) -> bool {
        self.components.iter().all(|c| c.closed)
    }
}

/// Summarize the topology of `mesh`.
pub fn topology_summary(mesh: &TriMesh, topo: &Topology) -> TopologySummary {
    topology_summary_of(mesh, topo, &connected_components(topo), &nonmanifold_vertices(mesh, topo))
}

/// [`topology_summary`] with the edge-connected components of `topo` and
/// its non-manifold vertices already known: repair computes them once,
/// side by side, for orientation and summary (flipping triangles changes
/// neither).
pub fn topology_summary_of(
    mesh: &TriMesh,
    topo: &Topology,
    comps: &Components,
    nm_vertices: &[VertexId],
) -> TopologySummary {
    let k = comps.n_components;
    let mut vertex_is_nm = vec![false; mesh.n_vertices()];
    for v in nm_vertices {
        vertex_is_nm[v.idx()] = true;
    }

    let mut per = vec![(0usize, 0usize, 0usize, 0usize, false, false); k]; // F, V, E, bnd edges, nm, has_bnd
    for &c in &comps.component_per_face {
        per[c as usize].0 += 1;
    }
    for (v, c) in vertex_component_pairs(topo, comps, mesh.n_vertices()) {
        per[c as usize].1 += 1;
        if vertex_is_nm[v as usize] {
            per[c as usize].4 = true;
        }
    }
    let mut bnd_sets = DisjointSets::new(mesh.n_vertices());
    for e in 0..topo.n_edges() {
        let e = EdgeId::new(e);
        let c = comps.component_per_face[topo.edge_faces(e)[0].idx()] as usize;
        per[c].2 += 1;
        match topo.edge_valence(e) {
            1 => {
                per[c].3 += 1;
                per[c].5 = true;
                let [a, b] = topo.edges[e.idx()];
                bnd_sets.union(a.0, b.0);
            }
            2 => {}
            _ => per[c].4 = true,
        }
    }
    // Boundary loops per component: distinct roots of boundary vertices.
    let mut roots_per_comp: Vec<Vec<u32>> = vec![Vec::new(); k];
    for e in 0..topo.n_edges() {
        let e = EdgeId::new(e);
        if topo.is_boundary_edge(e) {
            let c = comps.component_per_face[topo.edge_faces(e)[0].idx()] as usize;
            let r = bnd_sets.find(topo.edges[e.idx()][0].0);
            roots_per_comp[c].push(r);
        }
    }
    let components: Vec<ComponentSummary> = per
        .iter()
        .zip(roots_per_comp.iter_mut())
        .map(|(&(f, v, e, _nb, nm, has_bnd), roots)| {
            roots.sort_unstable();
            roots.dedup();
            let chi = v as i64 - e as i64 + f as i64;
            let b = roots.len() as i64;
            let two_g = 2 - chi - b;
            ComponentSummary {
                n_faces: f,
                n_vertices: v,
                n_edges: e,
                n_boundary_loops: roots.len(),
                euler_characteristic: chi,
                genus: (!nm && two_g >= 0 && two_g % 2 == 0).then_some(two_g / 2),
                closed: !has_bnd && !nm,
            }
        })
        .collect();
    let used = (0..mesh.n_vertices()).filter(|&v| !topo.vertex_faces(VertexId::new(v)).is_empty()).count();
    TopologySummary {
        n_vertices: used,
        n_edges: topo.n_edges(),
        n_faces: mesh.n_faces(),
        n_boundary_edges: topo.n_boundary_edges(),
        n_nonmanifold_edges: topo.n_nonmanifold_edges(),
        n_nonmanifold_vertices: nm_vertices.len(),
        n_boundary_loops: super::boundary::boundary_components(topo),
        euler_characteristic: used as i64 - topo.n_edges() as i64 + mesh.n_faces() as i64,
        components,
    }
}

/// Every (vertex, component) incidence once, in vertex order: the distinct
/// components among the triangles around each vertex (one, except at a
/// vertex pinching components). Read from the vertex–triangle lists of
/// `topo`, chunk by chunk on the pool, so no sort of all pairs is needed;
/// the order does not depend on the thread count.
fn vertex_component_pairs(topo: &Topology, comps: &Components, n_vertices: usize) -> Vec<(u32, u32)> {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 14;
    let chunks: Vec<Vec<(u32, u32)>> = (0..n_vertices.div_ceil(CHUNK))
        .into_par_iter()
        .map(|i| {
            let mut out = Vec::with_capacity(CHUNK);
            let mut distinct: Vec<u32> = Vec::new();
            for v in i * CHUNK..((i + 1) * CHUNK).min(n_vertices) {
                let faces = topo.vertex_faces(VertexId::new(v));
                let Some(first) = faces.first() else { continue };
                let c0 = comps.component_per_face[first.idx()];
                if faces.iter().all(|f| comps.component_per_face[f.idx()] == c0) {
                    out.push((v as u32, c0));
                    continue;
                }
                distinct.clear();
                distinct.extend(faces.iter().map(|f| comps.component_per_face[f.idx()]));
                distinct.sort_unstable();
                distinct.dedup();
                out.extend(distinct.iter().map(|&c| (v as u32, c)));
            }
            out
        })
        .collect();
    chunks.concat()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    fn summary(m: &TriMesh) -> TopologySummary {
        topology_summary(m, &Topology::new(m))
    }

    #[test]
    fn known_surfaces() {
        let s = summary(&fixtures::icosphere(2));
        assert_eq!((s.euler_characteristic, s.genus(), s.is_closed()), (2, Some(0), true));
        let s = summary(&fixtures::torus(1.0, 0.4, 24, 12));
        assert_eq!((s.euler_characteristic, s.genus(), s.n_boundary_loops), (0, Some(1), 0));
        let s = summary(&fixtures::disk(5));
        assert_eq!((s.euler_characteristic, s.genus(), s.n_boundary_loops), (1, Some(0), 1));
        let s = summary(&fixtures::annulus(0.3, 1.0, 20, 3));
        assert_eq!((s.euler_characteristic, s.genus(), s.n_boundary_loops), (0, Some(0), 2));
        let s = summary(&fixtures::cube(3));
        assert_eq!((s.euler_characteristic, s.genus(), s.n_components()), (2, Some(0), 1));
    }

    #[test]
    fn pinched_vertex_has_no_genus() {
        // Two cones sharing their apex: one non-manifold vertex, two components.
        let a = fixtures::tetrahedron();
        let mut m = a.clone();
        let n = m.positions.len() as u32;
        m.positions.extend(a.positions.iter().map(|p| -p));
        // Share vertex 0 (the origin of the fixture) between both copies.
        m.triangles
            .extend(a.triangles.iter().map(|t| t.map(|v| if v.0 == 0 { v } else { super::super::VertexId(v.0 + n) })));
        let s = summary(&m);
        assert_eq!(s.n_nonmanifold_vertices, 1);
        assert_eq!(s.components.len(), 2);
        assert!(s.components.iter().all(|c| c.genus.is_none()));
    }
}
