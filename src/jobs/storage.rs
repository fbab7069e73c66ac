//! Storage faults: telling a full or read-only data directory apart from
//! other failures, so that clients get `507` (request errors) or a job the
//! kinds `storage-full` / `storage-unavailable` instead of an internal error,
//! and `/healthz` can say the store does not write.
//!
//! A job whose end cannot be written is retried with backoff for
//! [`RECORD_RETRY`]; after that it waits in the runner's unrecorded list
//! ([`Unrecorded`]), which a background thread flushes every
//! [`FLUSH_INTERVAL`], recording the job `failed` with the storage kind once
//! the store writes again (or `cancelled` / deleted if a client asked so
//! meanwhile).

use std::path::Path;
use std::time::Duration;

use rusqlite::ErrorCode;

use super::model::JobError;
use super::service::JobsError;
use super::store::StoreError;
use crate::failure::FailureKind;
use crate::pipeline::error::storage_kind;

/// How long a worker retries recording a job's end before handing it to
/// the unrecorded list.
pub const RECORD_RETRY: Duration = Duration::from_secs(60);
/// First pause between two record attempts (doubled up to [`MAX_BACKOFF`]).
pub const FIRST_BACKOFF: Duration = Duration::from_millis(50);
/// Longest pause between two record attempts.
pub const MAX_BACKOFF: Duration = Duration::from_secs(2);
/// Pause between two flushes of the unrecorded list.
pub const FLUSH_INTERVAL: Duration = Duration::from_millis(500);

/// The storage kind of a store error: `storage-full` for `SQLITE_FULL`,
/// `storage-unavailable` for a read-only database or an I/O error, and for
/// a PostgreSQL server that fails or cannot be reached.
pub fn store_error_kind(e: &StoreError) -> Option<FailureKind> {
    match e {
        StoreError::Postgres(_) => Some(FailureKind::StorageUnavailable),
        StoreError::Sqlite(rusqlite::Error::SqliteFailure(f, _)) => match f.code {
            ErrorCode::DiskFull => Some(FailureKind::StorageFull),
            ErrorCode::ReadOnly | ErrorCode::SystemIoFailure | ErrorCode::CannotOpen => {
                Some(FailureKind::StorageUnavailable)
            }
            _ => None,
        },
        _ => None,
    }
}

/// The storage kind of a job-service error ([`storage_kind`] for file
/// errors, [`store_error_kind`] for the database).
pub fn jobs_error_kind(e: &JobsError) -> Option<FailureKind> {
    match e {
        JobsError::Io { source, .. } => storage_kind(source),
        JobsError::Store(s) => store_error_kind(s),
        JobsError::Artifacts(_) => Some(FailureKind::StorageUnavailable),
        _ => None,
    }
}

/// The job failure recorded for a job whose end could not be stored
/// (`kind` is `storage-full` or `storage-unavailable`).
pub fn unrecorded_failure(kind: FailureKind) -> JobError {
    let what = if kind == FailureKind::StorageFull { "was full" } else { "did not accept writes" };
    JobError::new(
        kind,
        format!("the job's result could not be stored because the server's storage {what}; submit the job again"),
    )
}

/// The failure recorded for a job whose files could not be written
/// (`kind` is `storage-full` or `storage-unavailable`).
pub fn artifact_failure(kind: FailureKind) -> JobError {
    let what = if kind == FailureKind::StorageFull { "is full" } else { "does not accept writes" };
    JobError::new(kind, format!("the job's files could not be written because the server's storage {what}"))
}

/// A job whose end is not yet in the store.
#[derive(Debug, Clone)]
pub struct Unrecorded {
    /// The job and the lease it ran under.
    pub lease: super::store::Lease,
    /// The failure to record (a storage kind).
    pub error: JobError,
    /// Per-stage seconds to record with it.
    pub stage_seconds: std::collections::BTreeMap<String, f64>,
    /// A client cancelled it meanwhile: record `cancelled` instead.
    pub cancel: bool,
    /// A client deleted it meanwhile: remove record and files instead.
    pub delete: bool,
}

/// Makes what was written to `file` durable, and reports a failed write.
///
/// Why not `sync_all` alone: a `tokio::fs::File` answers `write_all` once
/// the bytes are handed to its background write, and keeps that write's
/// error for the next write or `flush`; `sync_all` drops it. The last
/// chunk's `ENOSPC` was lost that way, and a full disk accepted an upload
/// it had not stored.
///
/// # Errors
/// The first failed write, or the failed sync.
pub async fn flush_and_sync(file: &mut tokio::fs::File) -> std::io::Result<()> {
    tokio::io::AsyncWriteExt::flush(file).await?;
    file.sync_all().await
}

/// Checks that the data directory takes a small file (created, written,
/// synced and removed in `tmp/`).
///
/// # Errors
/// A sentence naming what failed, with the storage kind when known.
pub fn probe_data_dir(data_dir: &Path) -> Result<(), String> {
    use std::io::Write;
    let path = data_dir.join("tmp").join(format!("healthz-{}.probe", uuid::Uuid::new_v4().simple()));
    let result = std::fs::File::create(&path).and_then(|mut f| {
        f.write_all(b"meshatlas health probe\n")?;
        f.sync_all()
    });
    let _ = std::fs::remove_file(&path);
    result.map_err(|e| {
        let kind = storage_kind(&e).map(|k| format!(" ({k})")).unwrap_or_default();
        format!("the data directory does not take a file{kind}: {e}")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_and_read_only_errors_have_storage_kinds() {
        let os = |code| std::io::Error::from_raw_os_error(code);
        assert_eq!(storage_kind(&os(28)), Some(FailureKind::StorageFull)); // ENOSPC
        assert_eq!(storage_kind(&os(122)), Some(FailureKind::StorageFull)); // EDQUOT
        assert_eq!(storage_kind(&os(30)), Some(FailureKind::StorageUnavailable)); // EROFS
        assert_eq!(storage_kind(&os(2)), None); // ENOENT
        let sqlite = |code| StoreError::Sqlite(rusqlite::Error::SqliteFailure(rusqlite::ffi::Error::new(code), None));
        assert_eq!(store_error_kind(&sqlite(rusqlite::ffi::SQLITE_FULL)), Some(FailureKind::StorageFull));
        assert_eq!(store_error_kind(&sqlite(rusqlite::ffi::SQLITE_READONLY)), Some(FailureKind::StorageUnavailable));
        assert_eq!(store_error_kind(&sqlite(rusqlite::ffi::SQLITE_CONSTRAINT)), None);
        let e = JobsError::Io { what: "x".into(), source: os(28) };
        assert_eq!(jobs_error_kind(&e), Some(FailureKind::StorageFull));
    }

    #[test]
    fn probe_fails_without_a_tmp_directory_and_passes_with_one() {
        let dir = tempfile::tempdir().unwrap();
        assert!(probe_data_dir(dir.path()).is_err());
        std::fs::create_dir(dir.path().join("tmp")).unwrap();
        probe_data_dir(dir.path()).unwrap();
        assert_eq!(std::fs::read_dir(dir.path().join("tmp")).unwrap().count(), 0, "the probe file is removed");
    }
}
