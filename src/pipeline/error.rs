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
    /// `storage-full` / `storage-unavailable` ([`storage_kind`]) or
    /// `write-failed`.
    pub fn kind(&self) -> &'static str {
        match self {
            PipelineError::Load(e) => e.kind(),
            PipelineError::Cancelled => "cancelled",
            PipelineError::Stage { kind, .. } => kind,
            PipelineError::Write { source: WriteError::Io(e), .. } => storage_kind(e).unwrap_or("write-failed"),
            PipelineError::Write { .. } => "write-failed",
        }
    }
}

/// The failure kind of an I/O error caused by the storage rather than the
/// data: `storage-full` for a full disk or an exhausted quota (`ENOSPC`,
/// `EDQUOT`), `storage-unavailable` for a read-only file system (`EROFS`);
/// `None` for other errors.
pub fn storage_kind(e: &std::io::Error) -> Option<&'static str> {
    use std::io::ErrorKind;
    match e.kind() {
        ErrorKind::StorageFull | ErrorKind::QuotaExceeded => Some("storage-full"),
        ErrorKind::ReadOnlyFilesystem => Some("storage-unavailable"),
        _ => None,
    }
}
