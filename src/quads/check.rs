//! Step 7b of the quads stage (owner: output helper). PLACEHOLDER on the
//! `quads` branch only: replaced before the branch is merged.

use super::error::QuadsError;
use super::model::QuadModel;
use super::quality::QuadQuality;
use super::surface_mesh::QuadMesh;
use crate::mesh::{Topology, TriMesh};

/// Asserts what every output must satisfy.
///
/// # Errors
/// [`QuadsError::CheckFailed`] naming the check.
pub fn check_quad_mesh(
    mesh: &QuadMesh,
    quality: &QuadQuality,
    surface: &TriMesh,
    topo: &Topology,
    model: &QuadModel,
) -> Result<(), QuadsError> {
    let _ = (mesh, quality, surface, topo, model);
    Ok(())
}
