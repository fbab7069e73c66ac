//! Step 5a of the quads stage (owner: smoothing helper). PLACEHOLDER on
//! the `quads` branch only: replaced before the branch is merged.

use serde::Serialize;

use super::projection::SurfaceProjector;
use super::surface_mesh::QuadMesh;

/// What cleanup did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct CleanupStats {
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// Removes valence-2 vertices and 3-3 diamonds from `mesh`.
pub fn clean_up(mesh: &mut QuadMesh, projector: &SurfaceProjector) -> CleanupStats {
    let _ = (mesh, projector);
    CleanupStats::default()
}
