//! The model a quad mesh is classified on: the feature corners, the feature
//! curves and the model faces bounded by them (thesis ch. 2 §4.1). The
//! seams the atlas cut to get disks are not part of it: the mesh crosses
//! them.

use crate::atlas::features::{Features, model_faces};
use crate::mesh::{Topology, VertexId};

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
/// atlas detected them).
pub fn quad_model(topo: &Topology, features: &Features) -> QuadModel {
    let faces = model_faces(topo, features);
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
}
