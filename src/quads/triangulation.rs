//! Step 3 of the quads stage (owner: insertion helper). PLACEHOLDER on the
//! `quads` branch only: replaced before the branch is merged.

use serde::Serialize;

use super::error::QuadsError;
use super::model::QuadModel;
use super::surface_mesh::SurfaceTriangulation;
use crate::atlas::Atlas;
use crate::crossfield::Crossfield;
use crate::mesh::{Topology, TriMesh};
use crate::progress::Progress;

/// What the triangulation step did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct TriangulationStats {
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// Points on `surface` aligned with `field` at edge length `size`,
/// triangulated (see the module documentation of [`super`]).
///
/// # Errors
/// [`QuadsError::Triangulation`], [`QuadsError::Cancelled`].
pub fn surface_triangulation(
    surface: &TriMesh,
    topo: &Topology,
    atlas: &Atlas,
    field: &Crossfield,
    model: &QuadModel,
    size: f64,
    progress: &Progress,
) -> Result<(SurfaceTriangulation, TriangulationStats), QuadsError> {
    let _ = (surface, topo, atlas, field, model, size, progress);
    Err(QuadsError::Triangulation { patch: 0, reason: "placeholder".into() })
}
