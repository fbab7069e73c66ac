//! A patch: a set of triangles of the atlas mesh extracted as its own local
//! mesh, and the test of whether it can be parameterized on the unit disk.
//!
//! A patch is parameterizable (thesis ch. 2 §3) when it is a topological
//! disk, possibly with holes: one edge-connected component, manifold (no
//! non-manifold edge or vertex), consistently oriented, genus 0
//! (`χ = 2 − b`) with at least one boundary loop `b ≥ 1`, and boundary loops
//! that are simple and pairwise disjoint (every boundary vertex has exactly
//! two boundary edges), so that the outer loop can be laid on the unit circle.

use crate::mesh::boundary::{BoundaryLoop, boundary_loops};
use crate::mesh::components::{any_nonmanifold_vertex, nonmanifold_vertices};
use crate::mesh::orientation::n_inconsistent_edges;
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh, VertexId};
use serde::Serialize;

/// Local copy of a patch: compact vertex numbering and its own topology.
#[derive(Debug, Clone)]
pub struct PatchMesh {
    /// Global (atlas mesh) vertex of each local vertex.
    pub global_vertices: Vec<VertexId>,
    /// Global (atlas mesh) triangle of each local triangle.
    pub global_faces: Vec<FaceId>,
    /// The local mesh.
    pub mesh: TriMesh,
    /// Topology of the local mesh.
    pub topo: Topology,
}

/// Why a patch cannot be parameterized as it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PatchDefect {
    /// More than one edge-connected component.
    Disconnected,
    /// A non-manifold edge or vertex.
    NonManifold,
    /// Triangles disagree on orientation.
    NotOrientable,
    /// No boundary loop (closed surface).
    Closed,
    /// Genus above zero.
    Genus,
    /// Two boundary loops touch, or one touches itself.
    PinchedBoundary,
}

impl PatchMesh {
    /// The whole of `mesh` as one patch, reusing its topology `topo` (a
    /// copy instead of a renumbering and a new topology: the first patch of
    /// a closed surface without features is the whole input, and this runs
    /// before anything can run in parallel). `None` when some vertex has no triangle: then local
    /// and global numberings differ and [`PatchMesh::extract`] is needed.
    pub fn whole(mesh: &TriMesh, topo: &Topology) -> Option<Self> {
        let n_v = mesh.n_vertices();
        if (0..n_v).any(|v| topo.vertex_faces(VertexId::new(v)).is_empty()) {
            return None;
        }
        Some(Self {
            global_vertices: (0..n_v).map(VertexId::new).collect(),
            global_faces: (0..mesh.n_faces()).map(FaceId::new).collect(),
            mesh: mesh.clone(),
            topo: topo.clone(),
        })
    }

    /// Extract the triangles `faces` of `mesh` as a local mesh.
    pub fn extract(mesh: &TriMesh, faces: &[FaceId]) -> Self {
        let mut global_vertices = Vec::with_capacity(faces.len() / 2 + 3);
        let mut triangles = Vec::with_capacity(faces.len());
        if faces.len() * 16 >= mesh.n_vertices() {
            // Large patch: a dense map over the mesh vertices is cheapest.
            let mut local_of = vec![u32::MAX; mesh.n_vertices()];
            for &f in faces {
                triangles.push(mesh.triangles[f.idx()].map(|v| {
                    if local_of[v.idx()] == u32::MAX {
                        local_of[v.idx()] = global_vertices.len() as u32;
                        global_vertices.push(v);
                    }
                    VertexId(local_of[v.idx()])
                }));
            }
        } else {
            let mut local_of = std::collections::HashMap::with_capacity(faces.len());
            for &f in faces {
                triangles.push(mesh.triangles[f.idx()].map(|v| {
                    *local_of.entry(v).or_insert_with(|| {
                        global_vertices.push(v);
                        VertexId::new(global_vertices.len() - 1)
                    })
                }));
            }
        }
        let positions = global_vertices.iter().map(|v| mesh.positions[v.idx()]).collect();
        let local = TriMesh { positions, triangles };
        debug_assert!(local.validate().is_ok());
        let topo = Topology::new(&local);
        Self { global_vertices, global_faces: faces.to_vec(), mesh: local, topo }
    }

    /// Number of triangles.
    pub fn n_faces(&self) -> usize {
        self.mesh.n_faces()
    }

    /// Local vertices that lie on a boundary edge.
    pub fn boundary_vertex_flags(&self) -> Vec<bool> {
        let mut on = vec![false; self.mesh.n_vertices()];
        for e in 0..self.topo.n_edges() {
            if self.topo.edge_valence(EdgeId::new(e)) != 2 {
                for v in self.topo.edges[e] {
                    on[v.idx()] = true;
                }
            }
        }
        on
    }

    /// Number of vertices not on the boundary.
    pub fn n_interior_vertices(&self) -> usize {
        self.boundary_vertex_flags().iter().filter(|b| !**b).count()
    }

    /// The first reason this patch cannot be parameterized, or `None`.
    pub fn defect(&self) -> Option<PatchDefect> {
        self.defect_with(false)
    }

    /// As [`Self::defect`], for a piece of a surface known to have no
    /// non-manifold vertex. A vertex without boundary edges in the piece
    /// has all the triangles of its (single) fan in the piece, so only
    /// boundary vertices can be pinched and only they are checked: the full
    /// check visits every fan, and repeated at every split level it was a
    /// visible part of a large atlas (`docs/decisions.md`).
    pub fn defect_of_manifold_piece(&self) -> Option<PatchDefect> {
        self.defect_with(true)
    }

    /// The checks of [`Self::defect`]; `boundary_fans_only` restricts the
    /// non-manifold vertex test to boundary vertices.
    fn defect_with(&self, boundary_fans_only: bool) -> Option<PatchDefect> {
        let topo = &self.topo;
        // Cheapest checks first: a closed face (no boundary edge) is the
        // common case for the first generation and needs no further pass.
        let mut boundary_degree = vec![0u32; self.mesh.n_vertices()];
        let mut n_boundary_edges = 0;
        for e in 0..topo.n_edges() {
            if topo.is_boundary_edge(EdgeId::new(e)) {
                n_boundary_edges += 1;
                for v in topo.edges[e] {
                    boundary_degree[v.idx()] += 1;
                }
            }
        }
        if topo.n_nonmanifold_edges() > 0 {
            return Some(PatchDefect::NonManifold);
        }
        if n_boundary_edges == 0 {
            return Some(PatchDefect::Closed);
        }
        if crate::mesh::components::connected_components(topo).n_components != 1 {
            return Some(PatchDefect::Disconnected);
        }
        let pinched = if boundary_fans_only {
            let on_boundary = (0..self.mesh.n_vertices()).filter(|&v| boundary_degree[v] > 0);
            any_nonmanifold_vertex(&self.mesh, topo, on_boundary.map(VertexId::new))
        } else {
            !nonmanifold_vertices(&self.mesh, topo).is_empty()
        };
        if pinched {
            return Some(PatchDefect::NonManifold);
        }
        if n_inconsistent_edges(&self.mesh, topo) > 0 {
            return Some(PatchDefect::NotOrientable);
        }
        if boundary_degree.iter().any(|&d| d != 0 && d != 2) {
            return Some(PatchDefect::PinchedBoundary);
        }
        let loops = boundary_loops(&self.mesh, topo).len() as i64;
        let chi = self.mesh.n_vertices() as i64 - topo.n_edges() as i64 + self.mesh.n_faces() as i64;
        if chi != 2 - loops {
            return Some(PatchDefect::Genus);
        }
        None
    }

    /// Boundary loops, longest (in 3D length) first.
    pub fn loops_longest_first(&self) -> Vec<BoundaryLoop> {
        let mut loops = boundary_loops(&self.mesh, &self.topo);
        let mut keyed: Vec<(f64, BoundaryLoop)> = loops.drain(..).map(|l| (l.length(&self.mesh), l)).collect();
        keyed.sort_by(|a, b| b.0.total_cmp(&a.0));
        keyed.into_iter().map(|(_, l)| l).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    fn all_faces(m: &TriMesh) -> Vec<FaceId> {
        (0..m.n_faces()).map(FaceId::new).collect()
    }

    #[test]
    fn disk_and_annulus_qualify() {
        for m in [fixtures::disk(4), fixtures::annulus(0.3, 1.0, 24, 3), fixtures::square(3), fixtures::l_shape(2)] {
            let p = PatchMesh::extract(&m, &all_faces(&m));
            assert_eq!(p.defect(), None);
        }
    }

    #[test]
    fn closed_and_higher_genus_do_not() {
        let s = fixtures::icosphere(1);
        assert_eq!(PatchMesh::extract(&s, &all_faces(&s)).defect(), Some(PatchDefect::Closed));
        // A torus with one triangle removed: one boundary loop, genus 1.
        let t = fixtures::torus(1.0, 0.4, 16, 8);
        let faces: Vec<FaceId> = (1..t.n_faces()).map(FaceId::new).collect();
        assert_eq!(PatchMesh::extract(&t, &faces).defect(), Some(PatchDefect::Genus));
        let band = fixtures::mobius_band(16);
        assert_eq!(PatchMesh::extract(&band, &all_faces(&band)).defect(), Some(PatchDefect::NotOrientable));
    }

    #[test]
    fn two_separate_triangles_are_disconnected() {
        let m = fixtures::square(2);
        let p = PatchMesh::extract(&m, &[FaceId(0), FaceId(7)]);
        assert_eq!(p.defect(), Some(PatchDefect::Disconnected));
        assert_eq!(p.mesh.n_vertices(), 5);
        assert_eq!(p.global_faces, vec![FaceId(0), FaceId(7)]);
    }

    #[test]
    fn boundary_touching_itself_is_nonmanifold() {
        // 3×3 grid without cells (0,0) and (1,1): a ring of 7 cells whose hole
        // touches the outer boundary at one vertex.
        let m = fixtures::square(3);
        let faces: Vec<FaceId> = (0..m.n_faces()).filter(|f| ![0, 1, 8, 9].contains(f)).map(FaceId::new).collect();
        let p = PatchMesh::extract(&m, &faces);
        assert_eq!(p.defect(), Some(PatchDefect::NonManifold));
        assert_eq!(p.defect_of_manifold_piece(), Some(PatchDefect::NonManifold));
        assert_eq!(p.n_interior_vertices(), 0);
    }
}
