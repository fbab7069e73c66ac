//! The job store: the durable job records, which are also the queue.
//!
//! [`JobStore`] is what the service, the dispatcher and the workers need of
//! it; two implementations exist, chosen by URL ([`StoreLocation`]):
//! - [`super::sqlite_store::SqliteStore`] (`sqlite://DIR`, the embedded
//!   default): one SQLite file in WAL mode;
//! - [`super::pg_store::PgStore`] (`postgres://…`): PostgreSQL, shared by
//!   any number of API and worker processes on any machines.
//!
//! **Leases and fencing.** A worker claims a job with a lease (its
//! [`Lease::owner`] name and an expiry); its heartbeats renew the lease,
//! store progress and read the cancel flag. The attempt number together
//! with the owner is the fencing token: every write a worker makes about
//! its job names its [`Lease`] and changes nothing when the job is no longer
//! running under that lease (it expired and another worker took the job,
//! or a client deleted it). A job whose lease expired goes back to the
//! queue ([`JobStore::reap_expired`]) and, after `max_attempts` claims or
//! [`MAX_CRASHES`] expiries, fails.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use crate::failure::FailureKind;

use super::model::{Artifact, JobError, JobId, JobPage, JobRecord, JobState};

/// Errors of the job store.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// SQLite failed (disk full, corrupt file, locked database, …).
    #[error("job database: {0}")]
    Sqlite(#[from] rusqlite::Error),
    /// PostgreSQL failed or could not be reached.
    #[error("job database (PostgreSQL): {0}")]
    Postgres(String),
    /// A JSON column could not be encoded or decoded.
    #[error("job database JSON column `{column}`: {source}")]
    Json {
        /// Column name.
        column: &'static str,
        /// The serde error.
        source: serde_json::Error,
    },
    /// A row holds a value this version does not understand.
    #[error("job database row {id}: {what}")]
    Corrupt {
        /// Job id (text) of the row.
        id: String,
        /// What is wrong.
        what: String,
    },
}

/// Where the job records live: `sqlite://DIR` (the file `DIR/meshatlas.sqlite3`)
/// or a `postgres://` / `postgresql://` connection URL.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StoreLocation {
    /// The embedded SQLite database in this directory.
    Sqlite(std::path::PathBuf),
    /// A PostgreSQL database (libpq-style URL).
    Postgres(String),
}

impl StoreLocation {
    /// Parses `--store`: `sqlite://DIR`, `postgres://…` or `postgresql://…`.
    ///
    /// # Errors
    /// A message naming the accepted schemes.
    pub fn parse(text: &str) -> Result<Self, String> {
        if let Some(dir) = text.strip_prefix("sqlite://") {
            if dir.is_empty() {
                return Err("sqlite:// needs a directory, e.g. sqlite://./data".into());
            }
            return Ok(Self::Sqlite(dir.into()));
        }
        if text.starts_with("postgres://") || text.starts_with("postgresql://") {
            return Ok(Self::Postgres(text.to_string()));
        }
        Err(format!("unsupported job store `{text}`: use sqlite://DIR or postgres://USER@HOST:PORT/DB"))
    }

    /// The URL with any password replaced by `***`, for logs.
    pub fn redacted(&self) -> String {
        match self {
            Self::Sqlite(dir) => format!("sqlite://{}", dir.display()),
            Self::Postgres(url) => redact_password(url),
        }
    }
}

/// `scheme://user:secret@host…` → `scheme://user:***@host…`.
fn redact_password(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else { return url.to_string() };
    let Some((userinfo, host)) = rest.split_once('@') else { return url.to_string() };
    match userinfo.split_once(':') {
        Some((user, _)) => format!("{scheme}://{user}:***@{host}"),
        None => url.to_string(),
    }
}

/// A worker's hold on a running job: the job, the attempt it claimed and
/// the worker's name. Every write about the job names it (fencing).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Lease {
    /// The job.
    pub id: JobId,
    /// The attempt number the claim gave (1 for the first run).
    pub attempt: u32,
    /// The claiming worker ([`OwnerName`]).
    pub owner: Arc<str>,
}

/// What a heartbeat learned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Heartbeat {
    /// The lease was renewed; `cancel_requested` says whether a client asked
    /// (on any API process) to cancel the job.
    Held {
        /// A cancel was requested.
        cancel_requested: bool,
    },
    /// The job is no longer running under this lease (deleted, or claimed
    /// again after the lease expired): the worker must stop and discard.
    Lost,
}

/// Progress a heartbeat stores: stage, fraction, seconds per stage.
pub type ProgressRow = (String, f64, BTreeMap<String, f64>);

/// A job to insert as queued.
#[derive(Debug, Clone)]
pub struct NewRow<'a> {
    /// Its id.
    pub id: JobId,
    /// The sanitized upload name.
    pub input_name: &'a str,
    /// Upload size.
    pub input_bytes: u64,
    /// Declared format, if any.
    pub format: Option<&'a str>,
    /// Validated parameters.
    pub params: &'a serde_json::Value,
    /// Its peak-memory estimate.
    pub memory_estimate_bytes: u64,
    /// The submitting tenant (`None` without authentication).
    pub tenant: Option<&'a str>,
}

/// Outcome of putting back jobs whose worker stopped holding them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Recovery {
    /// Jobs put back in the queue.
    pub requeued: Vec<JobId>,
    /// Jobs failed because they were interrupted `max_attempts` times.
    pub failed: Vec<JobId>,
    /// Jobs failed with kind `crashed-server`: the process died under them
    /// twice.
    pub crashed: Vec<JobId>,
}

/// Crashes after which a job is failed instead of being retried.
pub const MAX_CRASHES: i64 = 2;

/// The oldest queued job a worker may take, as the dispatcher needs it to
/// decide whether it may start now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QueueHead {
    /// The job.
    pub id: JobId,
    /// Its peak-memory estimate in bytes.
    pub memory_estimate_bytes: u64,
    /// Times the process died while it ran.
    pub crashes: u32,
}

/// What happens to a job whose worker is gone, by its counts so far.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reaped {
    /// Back to the queue.
    Requeue,
    /// Failed with this kind and detail.
    Fail(FailureKind, String),
}

/// Decides the fate of a job whose lease expired (or whose worker is known
/// dead) after `attempts` claims and `crashes` deaths of the process that ran
/// it (this one counted when `died`): failed `interrupted` at `max_attempts`
/// claims, failed `crashed-server` at [`MAX_CRASHES`] (the process died under
/// it twice: likely out of memory), requeued otherwise. Only a death proven
/// on this host counts as a crash: a lease that merely lapsed (a paused or
/// partitioned worker, or one on another machine) is an interruption, retried
/// up to `max_attempts`.
pub fn reap_decision(attempts: i64, crashes: i64, max_attempts: u32, died: bool) -> Reaped {
    if attempts >= i64::from(max_attempts) {
        Reaped::Fail(
            FailureKind::Interrupted,
            format!(
                "the server stopped while this job was running, {attempts} times; \
                 it is not retried again (the input may be too large for this server)"
            ),
        )
    } else if died && crashes >= MAX_CRASHES {
        Reaped::Fail(
            FailureKind::CrashedServer,
            format!(
                "the server process stopped while this job was running, twice ({crashes} times, \
                 the last time after running it alone); it likely ran out of memory, so it is not \
                 retried: lower its sizes (triangles, frames.max_tets or frames.target_size)"
            ),
        )
    } else {
        Reaped::Requeue
    }
}

/// The durable job records: every operation is one atomic statement or
/// transaction, so concurrent transitions (a worker claiming a job while a
/// client cancels it) cannot both win. Calls block; the async layer makes
/// them on blocking threads.
pub trait JobStore: Send + Sync {
    /// Inserts a queued job unless `max_queued` jobs are already queued;
    /// returns the record as inserted (state `queued`), `None` when full.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn insert_queued(&self, new: &NewRow<'_>, max_queued: usize) -> Result<Option<JobRecord>, StoreError>;

    /// The job with `id`, if it exists.
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable row.
    fn get(&self, id: JobId) -> Result<Option<JobRecord>, StoreError>;

    /// Up to `limit` jobs with `seq < before` (all when `None`), newest
    /// first; only `tenant`'s jobs when a tenant is given.
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable row.
    fn list(&self, limit: usize, before: Option<i64>, tenant: Option<&str>) -> Result<JobPage, StoreError>;

    /// The oldest queued job whose estimate is at most `max_estimate` (the
    /// asking worker's whole budget: larger jobs are left to larger workers).
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable id.
    fn queue_head(&self, max_estimate: u64) -> Result<Option<QueueHead>, StoreError>;

    /// Claims the queued job `id` for `owner` with a lease of `lease`:
    /// marks it running, counts the attempt. `None` when it is no longer
    /// queued (cancelled, deleted or claimed by another worker meanwhile).
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable row.
    fn claim(&self, id: JobId, owner: &str, lease: Duration) -> Result<Option<JobRecord>, StoreError>;

    /// Renews `lease` for another `lease_for`, storing `progress` if given.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn heartbeat(
        &self,
        lease: &Lease,
        lease_for: Duration,
        progress: Option<&ProgressRow>,
    ) -> Result<Heartbeat, StoreError>;

    /// Marks the job running under `lease` succeeded. False when it no
    /// longer runs under it (deleted, or taken by another attempt).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn finish_succeeded(
        &self,
        lease: &Lease,
        summary: &serde_json::Value,
        stage_seconds: &BTreeMap<String, f64>,
        artifacts: &[Artifact],
    ) -> Result<bool, StoreError>;

    /// Marks the job running under `lease` failed. False when it no longer
    /// runs under it.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn finish_failed(
        &self,
        lease: &Lease,
        error: &JobError,
        stage_seconds: &BTreeMap<String, f64>,
    ) -> Result<bool, StoreError>;

    /// Marks the job running under `lease` cancelled (it stopped at a
    /// client's request). False when it no longer runs under it.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn finish_cancelled(&self, lease: &Lease) -> Result<bool, StoreError>;

    /// Cancels a queued job. Returns whether it was queued.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn cancel_queued(&self, id: JobId) -> Result<bool, StoreError>;

    /// Sets the cancel flag of a running job, which its worker reads at its
    /// next heartbeat. Returns whether the job was running.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn request_cancel(&self, id: JobId) -> Result<bool, StoreError>;

    /// Puts the job running under `lease` back in the queue without counting
    /// the attempt (graceful shutdown of its worker).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn requeue(&self, lease: &Lease) -> Result<bool, StoreError>;

    /// Deletes the record. Returns whether it existed.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn delete(&self, id: JobId) -> Result<bool, StoreError>;

    /// Puts back every running job whose lease has expired or whose owner
    /// `is_dead` says is gone: each counts a crash and is requeued or failed
    /// by [`reap_decision`].
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn reap_expired(&self, max_attempts: u32, is_dead: &dyn Fn(&str) -> bool) -> Result<Recovery, StoreError>;

    /// Number of jobs per state (states with no job are 0).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn count_by_state(&self) -> Result<BTreeMap<JobState, u64>, StoreError>;

    /// Number of queued jobs.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn queued_count(&self) -> Result<usize, StoreError>;

    /// The tenant of job `id`: `None` when there is no such job,
    /// `Some(None)` for a job made without authentication.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn owner(&self, id: JobId) -> Result<Option<Option<String>>, StoreError>;

    /// Number of queued jobs of `tenant`.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn queued_count_of(&self, tenant: &str) -> Result<usize, StoreError>;

    /// Bytes of uploads plus listed artifacts of every job (of `tenant`'s
    /// jobs only when a tenant is given).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn stored_bytes(&self, tenant: Option<&str>) -> Result<u64, StoreError>;

    /// Ids of finished jobs that ended before `cutoff_ms`, oldest first.
    ///
    /// # Errors
    /// [`StoreError`] on database failure or a corrupt id.
    fn finished_before(&self, cutoff_ms: i64) -> Result<Vec<JobId>, StoreError>;

    /// Deletes the record if the job is finished. Returns whether it was.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn delete_if_final(&self, id: JobId) -> Result<bool, StoreError>;

    /// Checks that the database takes a write.
    ///
    /// # Errors
    /// [`StoreError`] when the write fails (disk full, read-only, unreachable).
    fn probe_write(&self) -> Result<(), StoreError>;

    /// Ids of every job (for cleaning orphaned directories at start-up).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn all_ids(&self) -> Result<Vec<String>, StoreError>;

    /// Records that the worker `name` is alive with `memory_budget`, and
    /// forgets workers not seen for a day.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn register_worker(&self, name: &str, memory_budget: u64) -> Result<(), StoreError>;

    /// The largest memory budget among the workers seen within `within`;
    /// `None` when no worker was.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    fn largest_worker_budget(&self, within: Duration) -> Result<Option<u64>, StoreError>;

    /// Calls `wake` whenever a job is queued or put back by any process
    /// (PostgreSQL notifications). The default does nothing: a submission
    /// on this process wakes its dispatcher directly, and dispatchers poll.
    fn wake_on_new_jobs(&self, wake: Arc<dyn Fn() + Send + Sync>) {
        drop(wake);
    }
}

/// Raw column values of one row, read the same way by both stores and
/// decoded in [`RawRow::into_record`]. Column order is [`COLUMNS`].
pub(crate) struct RawRow {
    pub seq: i64,
    pub id: String,
    pub state: String,
    pub created_ms: i64,
    pub started_ms: Option<i64>,
    pub finished_ms: Option<i64>,
    pub input_name: String,
    pub input_bytes: i64,
    pub format: Option<String>,
    pub params: String,
    pub stage: Option<String>,
    pub progress: f64,
    pub stage_seconds: String,
    pub summary: Option<String>,
    pub error_kind: Option<String>,
    pub error_detail: Option<String>,
    pub artifacts: String,
    pub attempts: i64,
    pub memory_estimate_bytes: i64,
    pub crashes: i64,
    pub cancel_requested: bool,
}

/// The columns [`RawRow`] reads, in its field order.
pub(crate) const COLUMNS: &str = "seq, id, state, created_ms, started_ms, finished_ms, input_name, input_bytes, format, \
                                  params, stage, progress, stage_seconds, summary, error_kind, error_detail, \
                                  artifacts, attempts, memory_estimate_bytes, crashes, cancel_requested";

/// JSON text of a column value.
pub(crate) fn json<T: serde::Serialize>(column: &'static str, v: &T) -> Result<String, StoreError> {
    serde_json::to_string(v).map_err(|source| StoreError::Json { column, source })
}

fn from_json<T: serde::de::DeserializeOwned>(column: &'static str, s: &str) -> Result<T, StoreError> {
    serde_json::from_str(s).map_err(|source| StoreError::Json { column, source })
}

/// Parses a stored job id.
pub(crate) fn parse_id(id: String) -> Result<JobId, StoreError> {
    id.parse::<JobId>().map_err(|e| StoreError::Corrupt { id, what: e.to_string() })
}

impl RawRow {
    /// Decodes the row into a record.
    pub(crate) fn into_record(self) -> Result<JobRecord, StoreError> {
        let corrupt = |what: String| StoreError::Corrupt { id: self.id.clone(), what };
        let id = self.id.parse::<JobId>().map_err(|e| corrupt(e.to_string()))?;
        let state = JobState::parse(&self.state).ok_or_else(|| corrupt(format!("unknown state `{}`", self.state)))?;
        let error = match (self.error_kind, self.error_detail) {
            (Some(kind), detail) => {
                Some(JobError { kind: FailureKind::from_stored(&kind), detail: detail.unwrap_or_default() })
            }
            (None, _) => None,
        };
        Ok(JobRecord {
            id,
            seq: self.seq,
            state,
            created_ms: self.created_ms,
            started_ms: self.started_ms,
            finished_ms: self.finished_ms,
            input_name: self.input_name,
            input_bytes: u64::try_from(self.input_bytes).unwrap_or(0),
            format: self.format,
            params: from_json("params", &self.params)?,
            stage: self.stage,
            progress: self.progress,
            stage_seconds: from_json("stage_seconds", &self.stage_seconds)?,
            summary: self.summary.as_deref().map(|s| from_json("summary", s)).transpose()?,
            error,
            artifacts: from_json("artifacts", &self.artifacts)?,
            attempts: u32::try_from(self.attempts).unwrap_or(0),
            memory_estimate_bytes: u64::try_from(self.memory_estimate_bytes).unwrap_or(0),
            crashes: u32::try_from(self.crashes).unwrap_or(0),
            stop_requested: self.cancel_requested && state == JobState::Running,
            status_message: None,
        })
    }
}

/// Milliseconds of a lease duration, for SQL arithmetic.
pub(crate) fn lease_ms(d: Duration) -> i64 {
    i64::try_from(d.as_millis()).unwrap_or(i64::MAX)
}

/// Saturating `u64` → `i64` for byte counts stored in signed columns.
pub(crate) fn as_i64(v: u64) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn store_urls_parse_and_passwords_are_redacted() {
        assert_eq!(StoreLocation::parse("sqlite://./data").unwrap(), StoreLocation::Sqlite("./data".into()));
        let pg = StoreLocation::parse("postgres://u:pw@db:5432/x").unwrap();
        assert_eq!(pg.redacted(), "postgres://u:***@db:5432/x");
        assert_eq!(StoreLocation::parse("postgresql://db/x").unwrap().redacted(), "postgresql://db/x");
        assert!(StoreLocation::parse("sqlite://").is_err());
        assert!(StoreLocation::parse("mysql://db").unwrap_err().contains("sqlite://DIR"));
    }

    #[test]
    fn reaping_requeues_then_fails_at_max_attempts_or_the_second_crash() {
        assert_eq!(reap_decision(1, 1, 3, true), Reaped::Requeue);
        assert!(matches!(reap_decision(3, 1, 3, true), Reaped::Fail(FailureKind::Interrupted, _)));
        assert!(matches!(reap_decision(2, 2, 3, true), Reaped::Fail(FailureKind::CrashedServer, _)));
        assert!(matches!(reap_decision(1, 1, 1, true), Reaped::Fail(FailureKind::Interrupted, _)));
        // A lapsed lease without a proven death is retried up to max_attempts.
        assert_eq!(reap_decision(2, 2, 3, false), Reaped::Requeue);
        assert!(matches!(reap_decision(3, 2, 3, false), Reaped::Fail(FailureKind::Interrupted, _)));
    }
}
