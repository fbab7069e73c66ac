//! Feature edges, corners and feature curves (thesis ch. 2 §4.1).
//!
//! An edge is a feature edge when it is a boundary edge (one triangle), a
//! non-manifold edge (three or more), or when the dihedral angle between the
//! unit normals of its two triangles exceeds `feature_angle_deg` (the angle
//! between normals: 0° for a flat fold, 90° for a cube edge). A corner is a
//! vertex where a number of feature edges other than 2 meets. Feature curves
//! are maximal chains of feature edges between corners; a closed chain
//! without a corner gets one artificial corner (its smallest vertex id) so
//! every curve has end points, as MSH `$Entities` requires. Model faces are
//! the triangles connected without crossing a feature edge.

use crate::geom::angle_between;
use crate::mesh::components::{Components, face_components};
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh, VertexId};
use serde::Serialize;

/// A maximal chain of feature edges between two corners (or a closed loop).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FeatureCurve {
    /// Vertices along the curve; for a closed curve the first is repeated at the end.
    pub vertices: Vec<VertexId>,
    /// Edges along the curve: `edges[i]` joins `vertices[i]` and `vertices[i+1]`.
    pub edges: Vec<EdgeId>,
}

impl FeatureCurve {
    /// True when the curve starts and ends at the same corner.
    pub fn is_closed(&self) -> bool {
        self.vertices.first() == self.vertices.last()
    }
}

/// Why each feature edge was selected, and the curves they form.
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// Per edge: true for feature edges.
    pub is_feature_edge: Vec<bool>,
    /// Feature edges selected by the dihedral angle.
    pub n_sharp_edges: usize,
    /// Boundary edges.
    pub n_boundary_edges: usize,
    /// Non-manifold edges.
    pub n_nonmanifold_edges: usize,
    /// Corners: end points of feature curves, sorted.
    pub corners: Vec<VertexId>,
    /// Feature curves, in order of their first edge id.
    pub curves: Vec<FeatureCurve>,
    /// Per edge: the curve it belongs to (`u32::MAX` for non-feature edges).
    pub curve_per_edge: Vec<u32>,
    /// Per edge: a crease inside a model face that the atlas cut its
    /// patches along ([`super::creases`]); empty before the atlas sets it.
    pub is_cut_crease: Vec<bool>,
}

/// Detect feature edges, corners and curves of `mesh`.
pub fn detect_features(mesh: &TriMesh, topo: &Topology, feature_angle_deg: f64) -> Features {
    let threshold = feature_angle_deg.to_radians();
    let mut is_feature_edge = vec![false; topo.n_edges()];
    let (mut n_sharp, mut n_bnd, mut n_nm) = (0, 0, 0);
    for (e, flag) in is_feature_edge.iter_mut().enumerate() {
        match topo.edge_faces(EdgeId::new(e)) {
            [_] => {
                n_bnd += 1;
                *flag = true;
            }
            [f, g] => {
                if dihedral_angle(mesh, *f, *g) > threshold {
                    n_sharp += 1;
                    *flag = true;
                }
            }
            _ => {
                n_nm += 1;
                *flag = true;
            }
        }
    }
    let (corners, curves, curve_per_edge) = edge_chains(topo, &is_feature_edge);
    Features {
        is_feature_edge,
        n_sharp_edges: n_sharp,
        n_boundary_edges: n_bnd,
        n_nonmanifold_edges: n_nm,
        corners,
        curves,
        curve_per_edge,
        is_cut_crease: Vec::new(),
    }
}

/// Angle between the unit normals of triangles `f` and `g` (0 when either is degenerate).
pub fn dihedral_angle(mesh: &TriMesh, f: FaceId, g: FaceId) -> f64 {
    let (a, b) = (mesh.face_area_vector(f), mesh.face_area_vector(g));
    if a.norm_squared() == 0.0 || b.norm_squared() == 0.0 {
        return 0.0;
    }
    angle_between(&a, &b)
}

/// Model faces: triangles connected without crossing a feature edge.
pub fn model_faces(topo: &Topology, features: &Features) -> Components {
    face_components(topo, |e| features.is_feature_edge[e.idx()])
}

/// Corners, chains and the chain of each edge, for the edges flagged in
/// `is_feature` (feature edges here, patch borders for the atlas curves).
pub(crate) fn edge_chains(topo: &Topology, is_feature: &[bool]) -> (Vec<VertexId>, Vec<FeatureCurve>, Vec<u32>) {
    edge_chains_with_corners(topo, is_feature, &[])
}

/// [`edge_chains`] with the vertices flagged in `forced` (indexed by
/// vertex; shorter means unflagged) made corners too, so that a chain is
/// split there although the vertex continues it.
pub(crate) fn edge_chains_with_corners(
    topo: &Topology,
    is_feature: &[bool],
    forced: &[bool],
) -> (Vec<VertexId>, Vec<FeatureCurve>, Vec<u32>) {
    // Feature edges incident to each vertex, as CSR.
    let n_v = topo.n_vertices();
    let mut offsets = vec![0u32; n_v + 1];
    for (e, _) in is_feature.iter().enumerate().filter(|(_, f)| **f) {
        for v in topo.edges[e] {
            offsets[v.idx() + 1] += 1;
        }
    }
    for i in 0..n_v {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut incident = vec![EdgeId(0); offsets[n_v] as usize];
    for (e, _) in is_feature.iter().enumerate().filter(|(_, f)| **f) {
        for v in topo.edges[e] {
            incident[fill[v.idx()] as usize] = EdgeId::new(e);
            fill[v.idx()] += 1;
        }
    }
    let degree = |v: VertexId| (offsets[v.idx() + 1] - offsets[v.idx()]) as usize;
    let mut is_corner: Vec<bool> = (0..n_v)
        .map(|v| {
            let d = degree(VertexId::new(v));
            d != 0 && (d != 2 || forced.get(v).copied().unwrap_or(false))
        })
        .collect();

    let mut curve_per_edge = vec![u32::MAX; topo.n_edges()];
    let mut curves = Vec::new();
    // Open chains start at corners; then remaining closed loops get an artificial corner.
    for pass in 0..2 {
        for e0 in 0..topo.n_edges() {
            if !is_feature[e0] || curve_per_edge[e0] != u32::MAX {
                continue;
            }
            let [a, b] = topo.edges[e0];
            let start = match pass {
                0 if is_corner[a.idx()] => a,
                0 if is_corner[b.idx()] => b,
                0 => continue,
                _ => {
                    is_corner[a.idx()] = true;
                    a
                }
            };
            let id = curves.len() as u32;
            let mut vertices = vec![start];
            let mut edges = Vec::new();
            let (mut v, mut e) = (start, EdgeId::new(e0));
            loop {
                curve_per_edge[e.idx()] = id;
                edges.push(e);
                let [p, q] = topo.edges[e.idx()];
                v = if p == v { q } else { p };
                vertices.push(v);
                if is_corner[v.idx()] {
                    break;
                }
                let around = &incident[offsets[v.idx()] as usize..offsets[v.idx() + 1] as usize];
                match around.iter().find(|&&x| curve_per_edge[x.idx()] == u32::MAX) {
                    Some(&next) => e = next,
                    None => break,
                }
            }
            curves.push(FeatureCurve { vertices, edges });
        }
    }
    let corners = (0..n_v).filter(|&v| is_corner[v]).map(VertexId::new).collect();
    (corners, curves, curve_per_edge)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn cube_has_12_curves_8_corners_6_faces() {
        let m = fixtures::cube(3);
        let t = Topology::new(&m);
        let f = detect_features(&m, &t, 40.0);
        assert_eq!(f.n_sharp_edges, 12 * 3);
        assert_eq!(f.corners.len(), 8);
        assert_eq!(f.curves.len(), 12);
        assert!(f.curves.iter().all(|c| c.edges.len() == 3 && !c.is_closed()));
        assert_eq!(model_faces(&t, &f).n_components, 6);
        // Turning features off leaves one model face.
        let none = detect_features(&m, &t, 180.0);
        assert!(none.curves.is_empty() && none.corners.is_empty());
        assert_eq!(model_faces(&t, &none).n_components, 1);
    }

    #[test]
    fn disk_boundary_is_one_closed_curve_with_one_corner() {
        let m = fixtures::disk(4);
        let t = Topology::new(&m);
        let f = detect_features(&m, &t, 40.0);
        assert_eq!(f.n_boundary_edges, 24);
        assert_eq!(f.curves.len(), 1);
        assert!(f.curves[0].is_closed());
        assert_eq!(f.curves[0].edges.len(), 24);
        assert_eq!(f.corners.len(), 1);
        assert!(f.curve_per_edge.iter().filter(|&&c| c == 0).count() == 24);
    }

    #[test]
    fn smooth_sphere_has_no_features() {
        let m = fixtures::icosphere(3);
        let t = Topology::new(&m);
        let f = detect_features(&m, &t, 40.0);
        assert!(f.is_feature_edge.iter().all(|x| !x));
    }
}
