//! Errors of a pipeline run, each with a stable [`FailureKind`] the job
//! service stores and the HTTP layer maps to a problem type.

use std::path::PathBuf;

use crate::failure::FailureKind;
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
        kind: FailureKind,
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
    pub fn stage(stage: &'static str, kind: FailureKind, message: impl Into<String>) -> Self {
        PipelineError::Stage { stage, message: message.into(), kind }
    }

    /// Stable failure kind: the reader's kind for load errors
    /// (`parse-error`, `too-many-triangles`, …), the stage's kind,
    /// `storage-full` / `storage-unavailable` ([`storage_kind`]) for a write
    /// the storage refused, and `internal-error` for any other write error
    /// and for `Cancelled` (not a failure: the job runner records a
    /// cancelled run as cancelled or timed out before it asks for a kind).
    pub fn kind(&self) -> FailureKind {
        match self {
            PipelineError::Load(e) => e.kind(),
            PipelineError::Cancelled => FailureKind::InternalError,
            PipelineError::Stage { kind, .. } => *kind,
            PipelineError::Write { source: WriteError::Io(e), .. } => {
                storage_kind(e).unwrap_or(FailureKind::InternalError)
            }
            PipelineError::Write { .. } => FailureKind::InternalError,
        }
    }
}

/// The failure kind of an I/O error caused by the storage rather than the
/// data: `storage-full` for a full disk or an exhausted quota (`ENOSPC`,
/// `EDQUOT`), `storage-unavailable` for a read-only file system (`EROFS`);
/// `None` for other errors.
pub fn storage_kind(e: &std::io::Error) -> Option<FailureKind> {
    use std::io::ErrorKind;
    match e.kind() {
        ErrorKind::StorageFull | ErrorKind::QuotaExceeded => Some(FailureKind::StorageFull),
        ErrorKind::ReadOnlyFilesystem => Some(FailureKind::StorageUnavailable),
        _ => None,
    }
}
