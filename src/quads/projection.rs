//! Projection onto the input surface (owner: smoothing helper).
//! PLACEHOLDER on the `quads` branch only: replaced before the branch is merged.

use super::model::QuadModel;
use crate::mesh::{Topology, TriMesh};

/// Projects points onto the input surface, its curves and corners.
pub struct SurfaceProjector<'a> {
    /// The input surface.
    pub surface: &'a TriMesh,
    /// Its topology.
    pub topo: &'a Topology,
    /// Its feature model.
    pub model: &'a QuadModel,
}

impl<'a> SurfaceProjector<'a> {
    /// A projector onto `surface`.
    pub fn new(surface: &'a TriMesh, topo: &'a Topology, model: &'a QuadModel) -> Self {
        Self { surface, topo, model }
    }
}
