//! Step 6 of the quads stage (owner: smoothing helper). PLACEHOLDER on the
//! `quads` branch only: replaced before the branch is merged.

use super::projection::SurfaceProjector;
use super::surface_mesh::QuadMesh;

/// Adds the edge and centre nodes of 9-node quadrangles, on the input.
pub fn add_high_order_nodes(mesh: &mut QuadMesh, projector: &SurfaceProjector) {
    let _ = (mesh, projector);
}
