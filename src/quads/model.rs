//! The model a quad mesh is classified on: the feature corners, the feature
//! curves and the model faces bounded by them (thesis ch. 2 §4.1). The
//! seams the atlas cut to get disks are not part of it: the mesh crosses
//! them.
//!
//! Only the feature curves that separate two model faces (or lie on the
//! boundary, or on a non-manifold edge) are kept. A crease that fades out
//! inside a face (fandisk's) or a closed crease that does not disconnect it
//! has the same model face on both sides: it bounds nothing, the atlas has
//! no reason to cut along it (its patches are cut from model faces), so no
//! atlas curve carries it, and the quads cross it like a seam.

use crate::atlas::features::{Features, edge_chains, model_faces};
use crate::mesh::{EdgeId, Topology, VertexId};

/// Corners, curves and faces of the feature model of a surface.
#[derive(Debug, Clone)]
pub struct QuadModel {
    /// Corner vertices (of the repaired surface), sorted; model corner `i`
    /// is `corners[i]`.
    pub corners: Vec<VertexId>,
    /// Feature curves as chains of surface vertices and edges (a closed
    /// curve repeats its first vertex at the end); model curve `i` is
    /// `features.curves[i]`.
    pub features: Features,
    /// Model face of each surface triangle.
    pub face_per_triangle: Vec<u32>,
    /// Number of model faces.
    pub n_faces: usize,
    /// For each curve, the model faces on either side (one for a boundary
    /// curve, more for a non-manifold one), sorted and deduplicated.
    pub faces_per_curve: Vec<Vec<u32>>,
}

impl QuadModel {
    /// Model corner index of surface vertex `v`, if it is a corner.
    pub fn corner_of(&self, v: VertexId) -> Option<u32> {
        self.corners.binary_search(&v).ok().map(|i| i as u32)
    }
}

/// The feature model of a surface with feature edges `features` (as the
/// atlas detected them), keeping the separating curves only (module
/// documentation).
pub fn quad_model(topo: &Topology, features: &Features) -> QuadModel {
    let faces = model_faces(topo, features);
    let features = separating_features(topo, features, &faces.component_per_face);
    let features = &features;
    let faces_per_curve = features
        .curves
        .iter()
        .map(|c| {
            let mut f: Vec<u32> = c
                .edges
                .iter()
                .flat_map(|&e| topo.edge_faces(e).iter().map(|t| faces.component_per_face[t.idx()]))
                .collect();
            f.sort_unstable();
            f.dedup();
            f
        })
        .collect();
    QuadModel {
        corners: features.corners.clone(),
        features: features.clone(),
        face_per_triangle: faces.component_per_face,
        n_faces: faces.n_components,
        faces_per_curve,
    }
}

/// The features of `features` without the edges whose two triangles lie in
/// the same model face (`face_per_triangle`), curves and corners rebuilt.
/// Dropping them leaves the model faces unchanged: they separate nothing.
fn separating_features(topo: &Topology, features: &Features, face_per_triangle: &[u32]) -> Features {
    let separates = |e: usize| match topo.edge_faces(EdgeId::new(e)) {
        [f, g] => face_per_triangle[f.idx()] != face_per_triangle[g.idx()],
        _ => true,
    };
    let is_feature_edge: Vec<bool> =
        features.is_feature_edge.iter().enumerate().map(|(e, &flag)| flag && separates(e)).collect();
    if is_feature_edge == features.is_feature_edge {
        return features.clone();
    }
    let (corners, curves, curve_per_edge) = edge_chains(topo, &is_feature_edge);
    Features { is_feature_edge, corners, curves, curve_per_edge, ..features.clone() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::features::detect_features;
    use crate::mesh::fixtures;

    #[test]
    fn a_cube_has_8_corners_12_curves_and_6_faces() {
        let mesh = fixtures::cube(4);
        let topo = Topology::new(&mesh);
        let model = quad_model(&topo, &detect_features(&mesh, &topo, 30.0));
        assert_eq!(model.corners.len(), 8);
        assert_eq!(model.features.curves.len(), 12);
        assert_eq!(model.n_faces, 6);
        assert!(model.faces_per_curve.iter().all(|f| f.len() == 2));
    }

    /// A crease that ends inside a face separates nothing: one model face,
    /// no curve inside it, the boundary one closed curve.
    #[test]
    fn a_crease_ending_inside_a_face_is_not_a_model_curve() {
        // A fan of 8 triangles around the origin with its first rim vertex
        // lifted to z = 0.8: the spoke to it folds by 64°, its neighbours by
        // 49°, the other spokes are flat; at 55° only the first spoke is a
        // crease, from the rim to the centre.
        let mut positions = vec![crate::geom::Vec3::zeros()];
        for k in 0..8 {
            let a = std::f64::consts::TAU * f64::from(k) / 8.0;
            positions.push(crate::geom::Vec3::new(a.cos(), a.sin(), if k == 0 { 0.8 } else { 0.0 }));
        }
        let triangles =
            (0..8).map(|k| [VertexId::new(0), VertexId::new(1 + k), VertexId::new(1 + (k + 1) % 8)]).collect();
        let mesh = crate::mesh::TriMesh { positions, triangles };
        let topo = Topology::new(&mesh);
        let features = detect_features(&mesh, &topo, 55.0);
        let inside = |c: &crate::atlas::features::FeatureCurve| c.edges.iter().any(|&e| !topo.is_boundary_edge(e));
        assert!(features.curves.iter().any(inside), "the fixture has no interior crease");
        let model = quad_model(&topo, &features);
        assert_eq!(model.n_faces, 1);
        assert!(!model.features.curves.iter().any(inside));
        assert_eq!(model.features.curves.len(), 1, "the boundary loop stays one curve");
        assert!(model.features.curves[0].is_closed());
    }
}
