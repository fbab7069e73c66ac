//! Step 7a of the quads stage (owner: output helper). PLACEHOLDER on the
//! `quads` branch only: replaced before the branch is merged.

use super::surface_mesh::QuadMesh;
use crate::mesh::TriMesh;

/// Shape and topology measures of a quad mesh.
#[derive(Debug, Clone, Default)]
pub struct QuadQuality {
    /// Scaled Jacobian of each quad (minimum over its corners).
    pub scaled_jacobian: Vec<f64>,
    /// Largest corner-angle deviation from 90° of each quad, degrees.
    pub max_angle_deviation: Vec<f64>,
    /// Number of edges at each vertex (0 for order-2 edge and face nodes).
    pub valence: Vec<u32>,
}

/// The measures of `mesh` on `surface`.
pub fn quad_quality(mesh: &QuadMesh, surface: &TriMesh) -> QuadQuality {
    let _ = (mesh, surface);
    QuadQuality::default()
}
