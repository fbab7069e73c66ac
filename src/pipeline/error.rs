//! Errors of a pipeline run, each with a stable `kind` the job service
//! stores and the HTTP layer maps to a problem type.

use std::path::PathBuf;

use crate::io::{IoError, WriteError};
use crate::progress::Cancelled;

/// Why a pipeline run stopped.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The input could not be read or repaired (the reader says where).
    #[error(transparent)]
    Load(#[from] IoError),
    /// The progress handle was cancelled.
    #[error("cancelled")]
    Cancelled,
    /// A stage could not handle this input.
    #[error("stage `{stage}`: {message}")]
    Stage {
        /// Stage name.
        stage: &'static str,
        /// What went wrong, in terms of the input.
        message: String,
        /// Stable failure kind (`stage-failed`, `no-valid-map`, …).
        kind: &'static str,
    },
    /// An output file could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The writer's error.
        source: WriteError,
    },
}

impl From<Cancelled> for PipelineError {
    fn from(_: Cancelled) -> Self {
        PipelineError::Cancelled
    }
}

impl PipelineError {
    /// A failure of stage `stage` with the stable `kind` and a message for the user.
    pub fn stage(stage: &'static str, kind: &'static str, message: impl Into<String>) -> Self {
        PipelineError::Stage { stage, message: message.into(), kind }
    }

    /// Stable machine-readable kind: the reader's kind for load errors
    /// (`parse-error`, `too-many-triangles`, …), `cancelled`, `stage-failed`,
    /// or `write-failed`.
    pub fn kind(&self) -> &'static str {
        match self {
            PipelineError::Load(e) => e.kind(),
            PipelineError::Cancelled => "cancelled",
            PipelineError::Stage { kind, .. } => kind,
            PipelineError::Write { .. } => "write-failed",
        }
    }
}
