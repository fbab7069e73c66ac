//! Step 4 of the quads stage (owner: recombination helper). PLACEHOLDER on
//! the `quads` branch only: replaced before the branch is merged.

use serde::Serialize;

use super::error::QuadsError;
use super::surface_mesh::{QuadMesh, SurfaceTriangulation};
use crate::progress::Progress;

/// What recombination did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct RecombineStats {
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// All-quad mesh from the triangles of `tri`.
///
/// # Errors
/// [`QuadsError::Cancelled`].
pub fn recombine(tri: SurfaceTriangulation, progress: &Progress) -> Result<(QuadMesh, RecombineStats), QuadsError> {
    let _ = (tri, progress);
    Err(QuadsError::CheckFailed { check: "placeholder", detail: String::new() })
}
