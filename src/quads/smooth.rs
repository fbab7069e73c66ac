//! Step 5b of the quads stage (owner: smoothing helper). PLACEHOLDER on
//! the `quads` branch only: replaced before the branch is merged.

use serde::Serialize;

use super::error::QuadsError;
use super::projection::SurfaceProjector;
use super::surface_mesh::QuadMesh;
use crate::progress::Progress;

/// What smoothing did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct SmoothStats {
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// Projects every vertex onto the input, then smooths `iterations` sweeps.
///
/// # Errors
/// [`QuadsError::Cancelled`].
pub fn smooth(
    mesh: &mut QuadMesh,
    projector: &SurfaceProjector,
    iterations: usize,
    progress: &Progress,
) -> Result<SmoothStats, QuadsError> {
    let _ = (mesh, projector, iterations, progress);
    Ok(SmoothStats::default())
}
