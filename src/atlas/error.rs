//! Errors of the atlas stage.

use crate::linalg::LinalgError;
use crate::progress::Cancelled;
use thiserror::Error;

/// Why the atlas could not be built. A broken map is never returned.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AtlasError {
    /// The input has no triangle.
    #[error("the mesh has no triangles")]
    EmptyMesh,
    /// METIS failed to bisect a patch.
    #[error("partitioning patch of {n_faces} triangles failed: {message}")]
    Partition { n_faces: usize, message: String },
    /// A patch could not be given a one-to-one map even after splitting.
    #[error(
        "patch of {n_faces} triangles around ({x:.6e}, {y:.6e}, {z:.6e}) has no valid parameterization \
         after {attempts} splits: {reason}"
    )]
    NoValidMap { n_faces: usize, x: f64, y: f64, z: f64, attempts: usize, reason: String },
    /// A sparse solve failed.
    #[error("linear solve failed: {0}")]
    Linalg(#[from] LinalgError),
    /// An option is out of range.
    #[error("invalid atlas option {name}: {reason}")]
    InvalidOption { name: &'static str, reason: String },
    /// The job was cancelled.
    #[error("cancelled")]
    Cancelled,
}

impl From<Cancelled> for AtlasError {
    fn from(_: Cancelled) -> Self {
        AtlasError::Cancelled
    }
}
