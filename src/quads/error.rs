//! Why the quads stage could not produce a mesh.

use crate::progress::Cancelled;

/// Why a quad mesh could not be built.
#[derive(Debug, thiserror::Error)]
pub enum QuadsError {
    /// An option is out of range.
    #[error("invalid quads option {name}: {reason}")]
    InvalidOption { name: &'static str, reason: String },
    /// The target size asks for more quads than the stage allows.
    #[error("quads.size {size} asks for about {estimated} quads, more than the limit {limit}")]
    TooManyQuads { size: f64, estimated: u64, limit: u64 },
    /// A patch could not be triangulated in its `(u, v)` plane.
    #[error("patch {patch}: {reason}")]
    Triangulation { patch: usize, reason: String },
    /// A check every output must pass failed (inverted quad, uncovered model
    /// face, valence identity, conformity): a bug, reported with its detail.
    #[error("quad mesh check `{check}` failed: {detail}")]
    CheckFailed { check: &'static str, detail: String },
    /// The computation was cancelled.
    #[error("cancelled")]
    Cancelled(#[from] Cancelled),
}
