//! `quads.msh` and `quads.vtu` (owner: output helper). PLACEHOLDER on the
//! `quads` branch only: replaced before the branch is merged.

use std::io::Write;

use super::model::QuadModel;
use super::quality::QuadQuality;
use super::surface_mesh::QuadMesh;
use crate::io::WriteError;
use crate::io::msh_output::OutputOptions;

/// Writes `quads.msh`.
///
/// # Errors
/// [`WriteError`] from the sink.
pub fn write_quads_msh(
    mesh: &QuadMesh,
    model: &QuadModel,
    w: impl Write,
    opts: &OutputOptions,
) -> Result<(), WriteError> {
    let _ = (mesh, model, w, opts);
    Ok(())
}

/// Writes `quads.vtu`.
///
/// # Errors
/// [`WriteError`] from the sink.
pub fn write_quads_vtu(mesh: &QuadMesh, quality: &QuadQuality, w: impl Write) -> Result<(), WriteError> {
    let _ = (mesh, quality, w);
    Ok(())
}
