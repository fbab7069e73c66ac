//! Durable job records in SQLite (WAL mode, `synchronous = FULL`).
//!
//! One table `jobs`; `seq` (an autoincrement rowid) orders jobs by arrival and
//! is the pagination cursor. JSON columns hold params, summary, per-stage
//! seconds and artifacts. Every state transition is a single `UPDATE … WHERE
//! state = …`, so concurrent transitions (a worker claiming a job while a
//! client cancels it) cannot both win. The connection sits behind a mutex:
//! statements are short, and the async layer calls them on blocking threads.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Mutex, MutexGuard};

use rusqlite::{Connection, OptionalExtension, Row, params};

use crate::failure::FailureKind;

use super::model::{Artifact, JobError, JobId, JobPage, JobRecord, JobState, now_ms};

/// Errors of the job store.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// SQLite failed (disk full, corrupt file, locked database, …).
    #[error("job database: {0}")]
    Sqlite(#[from] rusqlite::Error),
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

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS jobs (
    seq           INTEGER PRIMARY KEY AUTOINCREMENT,
    id            TEXT    NOT NULL UNIQUE,
    state         TEXT    NOT NULL,
    created_ms    INTEGER NOT NULL,
    started_ms    INTEGER,
    finished_ms   INTEGER,
    input_name    TEXT    NOT NULL,
    input_bytes   INTEGER NOT NULL,
    format        TEXT,
    params        TEXT    NOT NULL,
    stage         TEXT,
    progress      REAL    NOT NULL DEFAULT 0,
    stage_seconds TEXT    NOT NULL DEFAULT '{}',
    summary       TEXT,
    error_kind    TEXT,
    error_detail  TEXT,
    artifacts     TEXT    NOT NULL DEFAULT '[]',
    attempts      INTEGER NOT NULL DEFAULT 0
);
CREATE INDEX IF NOT EXISTS jobs_by_state ON jobs(state, seq);
";

/// Columns added after the first schema, with their declarations; a
/// database that lacks one (per `PRAGMA table_info`) gets it on open.
/// `tenant`: the submitting tenant, NULL for jobs made without authentication.
/// Indexes over added columns (created after the columns exist).
const ADDED_INDEXES: &str = "CREATE INDEX IF NOT EXISTS jobs_by_tenant ON jobs(tenant, seq);";

/// Adds the [`ADDED_COLUMNS`] an existing database lacks, and their indexes.
fn add_missing_columns(conn: &Connection) -> Result<(), StoreError> {
    let present: Vec<String> = {
        let mut stmt = conn.prepare("PRAGMA table_info(jobs)")?;
        stmt.query_map([], |r| r.get::<_, String>(1))?.collect::<Result<_, _>>()?
    };
    for (name, decl) in ADDED_COLUMNS {
        if !present.iter().any(|p| p == name) {
            conn.execute_batch(&format!("ALTER TABLE jobs ADD COLUMN {name} {decl}"))?;
        }
    }
    conn.execute_batch(ADDED_INDEXES)?;
    Ok(())
}

const COLUMNS: &str = "seq, id, state, created_ms, started_ms, finished_ms, input_name, input_bytes, format, params, \
                       stage, progress, stage_seconds, summary, error_kind, error_detail, artifacts, attempts, \
                       memory_estimate_bytes, crashes";

/// Columns added after the first schema: `(name, declaration)`, added by
/// [`add_missing_columns`] to databases that lack them.
const ADDED_COLUMNS: &[(&str, &str)] = &[
    ("memory_estimate_bytes", "INTEGER NOT NULL DEFAULT 0"),
    ("crashes", "INTEGER NOT NULL DEFAULT 0"),
    ("tenant", "TEXT"),
];

/// Outcome of recovering jobs left `running` by a crash.
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

/// The oldest queued job, as the dispatcher needs it to decide whether it
/// may start now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QueueHead {
    /// The job.
    pub id: JobId,
    /// Its peak-memory estimate in bytes.
    pub memory_estimate_bytes: u64,
    /// Times the process died while it ran.
    pub crashes: u32,
}

/// The SQLite job store.
pub struct Store {
    conn: Mutex<Connection>,
}

fn json<T: serde::Serialize>(column: &'static str, v: &T) -> Result<String, StoreError> {
    serde_json::to_string(v).map_err(|source| StoreError::Json { column, source })
}

fn from_json<T: serde::de::DeserializeOwned>(column: &'static str, s: &str) -> Result<T, StoreError> {
    serde_json::from_str(s).map_err(|source| StoreError::Json { column, source })
}

/// Raw column values of one row, decoded in [`RawRow::into_record`].
struct RawRow {
    seq: i64,
    id: String,
    state: String,
    created_ms: i64,
    started_ms: Option<i64>,
    finished_ms: Option<i64>,
    input_name: String,
    input_bytes: i64,
    format: Option<String>,
    params: String,
    stage: Option<String>,
    progress: f64,
    stage_seconds: String,
    summary: Option<String>,
    error_kind: Option<String>,
    error_detail: Option<String>,
    artifacts: String,
    attempts: i64,
    memory_estimate_bytes: i64,
    crashes: i64,
}

impl RawRow {
    fn read(r: &Row<'_>) -> rusqlite::Result<Self> {
        Ok(Self {
            seq: r.get(0)?,
            id: r.get(1)?,
            state: r.get(2)?,
            created_ms: r.get(3)?,
            started_ms: r.get(4)?,
            finished_ms: r.get(5)?,
            input_name: r.get(6)?,
            input_bytes: r.get(7)?,
            format: r.get(8)?,
            params: r.get(9)?,
            stage: r.get(10)?,
            progress: r.get(11)?,
            stage_seconds: r.get(12)?,
            summary: r.get(13)?,
            error_kind: r.get(14)?,
            error_detail: r.get(15)?,
            artifacts: r.get(16)?,
            attempts: r.get(17)?,
            memory_estimate_bytes: r.get(18)?,
            crashes: r.get(19)?,
        })
    }

    fn into_record(self) -> Result<JobRecord, StoreError> {
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
            stop_requested: false,
        })
    }
}

impl Store {
    /// Opens (creating if needed) the database at `path` in WAL mode.
    ///
    /// # Errors
    /// [`StoreError::Sqlite`] when the file cannot be opened or migrated.
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        let conn = Connection::open(path)?;
        conn.pragma_update(None, "journal_mode", "WAL")?;
        conn.pragma_update(None, "synchronous", "FULL")?;
        conn.busy_timeout(std::time::Duration::from_secs(5))?;
        conn.execute_batch(SCHEMA)?;
        add_missing_columns(&conn)?;
        Ok(Self { conn: Mutex::new(conn) })
    }

    /// An in-memory store (tests).
    ///
    /// # Errors
    /// [`StoreError::Sqlite`] if SQLite cannot create the schema.
    pub fn open_in_memory() -> Result<Self, StoreError> {
        let conn = Connection::open_in_memory()?;
        conn.execute_batch(SCHEMA)?;
        add_missing_columns(&conn)?;
        Ok(Self { conn: Mutex::new(conn) })
    }

    fn conn(&self) -> MutexGuard<'_, Connection> {
        // A panic while holding the lock cannot leave SQLite inconsistent
        // (statements are atomic), so a poisoned lock is still usable.
        self.conn.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Inserts a queued job, unless `max_queued` jobs are already queued.
    /// Returns the record as inserted (state `queued`, whatever a worker
    /// does right after), `None` when the queue is full.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    #[allow(clippy::too_many_arguments)]
    pub fn insert_queued(
        &self,
        id: JobId,
        input_name: &str,
        input_bytes: u64,
        format: Option<&str>,
        params: &serde_json::Value,
        memory_estimate_bytes: u64,
        max_queued: usize,
        tenant: Option<&str>,
    ) -> Result<Option<JobRecord>, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let queued: i64 = tx.query_row("SELECT count(*) FROM jobs WHERE state = 'queued'", [], |r| r.get(0))?;
        if usize::try_from(queued).unwrap_or(usize::MAX) >= max_queued {
            return Ok(None);
        }
        tx.execute(
            "INSERT INTO jobs (id, state, created_ms, input_name, input_bytes, format, params, \
             memory_estimate_bytes, tenant) \
             VALUES (?1, 'queued', ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
            params![
                id.to_string(),
                now_ms(),
                input_name,
                i64::try_from(input_bytes).unwrap_or(i64::MAX),
                format,
                json("params", params)?,
                i64::try_from(memory_estimate_bytes).unwrap_or(i64::MAX),
                tenant
            ],
        )?;
        // Read back inside the transaction: the record as inserted (queued),
        // even when the dispatcher claims the job right after the commit.
        let raw = tx.query_row(&format!("SELECT {COLUMNS} FROM jobs WHERE id = ?1"), [id.to_string()], RawRow::read)?;
        tx.commit()?;
        raw.into_record().map(Some)
    }

    /// The job with `id`, if it exists.
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable row.
    pub fn get(&self, id: JobId) -> Result<Option<JobRecord>, StoreError> {
        let raw = self
            .conn()
            .query_row(&format!("SELECT {COLUMNS} FROM jobs WHERE id = ?1"), [id.to_string()], RawRow::read)
            .optional()?;
        raw.map(RawRow::into_record).transpose()
    }

    /// Up to `limit` jobs with `seq < before` (all when `None`), newest
    /// first; only `tenant`'s jobs when a tenant is given.
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable row.
    pub fn list(&self, limit: usize, before: Option<i64>, tenant: Option<&str>) -> Result<JobPage, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT {COLUMNS} FROM jobs WHERE seq < ?1 AND (?3 IS NULL OR tenant = ?3) ORDER BY seq DESC LIMIT ?2"
        ))?;
        let take = i64::try_from(limit.saturating_add(1)).unwrap_or(i64::MAX);
        let raws = stmt
            .query_map(params![before.unwrap_or(i64::MAX), take, tenant], RawRow::read)?
            .collect::<Result<Vec<_>, _>>()?;
        drop(stmt);
        drop(conn);
        let mut jobs = raws.into_iter().map(RawRow::into_record).collect::<Result<Vec<_>, _>>()?;
        let next_cursor = if jobs.len() > limit {
            jobs.truncate(limit);
            jobs.last().map(|j| j.seq)
        } else {
            None
        };
        Ok(JobPage { jobs, next_cursor })
    }

    /// Claims the oldest queued job: marks it running, counts the attempt.
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable row.
    pub fn claim_next(&self) -> Result<Option<JobRecord>, StoreError> {
        let id: Option<String> = {
            let conn = self.conn();
            conn.query_row(
                "UPDATE jobs SET state = 'running', attempts = attempts + 1, started_ms = ?1, stage = NULL, \
                 progress = 0, stage_seconds = '{}' \
                 WHERE seq = (SELECT seq FROM jobs WHERE state = 'queued' ORDER BY seq LIMIT 1) RETURNING id",
                [now_ms()],
                |r| r.get(0),
            )
            .optional()?
        };
        match id {
            Some(id) => {
                let id = id.parse::<JobId>().map_err(|e| StoreError::Corrupt { id, what: e.to_string() })?;
                self.get(id)
            }
            None => Ok(None),
        }
    }

    /// The oldest queued job, without claiming it.
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable id.
    pub fn queue_head(&self) -> Result<Option<QueueHead>, StoreError> {
        let row: Option<(String, i64, i64)> = self
            .conn()
            .query_row(
                "SELECT id, memory_estimate_bytes, crashes FROM jobs WHERE state = 'queued' ORDER BY seq LIMIT 1",
                [],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
            )
            .optional()?;
        row.map(|(id, bytes, crashes)| {
            let job = id.parse::<JobId>().map_err(|e| StoreError::Corrupt { id, what: e.to_string() })?;
            Ok(QueueHead {
                id: job,
                memory_estimate_bytes: u64::try_from(bytes).unwrap_or(0),
                crashes: u32::try_from(crashes).unwrap_or(0),
            })
        })
        .transpose()
    }

    /// Claims the queued job `id`: marks it running, counts the attempt.
    /// `None` when it is no longer queued (cancelled or deleted meanwhile).
    ///
    /// # Errors
    /// [`StoreError`] on database failure or an undecodable row.
    pub fn claim(&self, id: JobId) -> Result<Option<JobRecord>, StoreError> {
        let n = self.conn().execute(
            "UPDATE jobs SET state = 'running', attempts = attempts + 1, started_ms = ?2, stage = NULL, \
             progress = 0, stage_seconds = '{}' WHERE id = ?1 AND state = 'queued'",
            params![id.to_string(), now_ms()],
        )?;
        if n == 1 { self.get(id) } else { Ok(None) }
    }

    /// Records progress of a running job.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn set_progress(
        &self,
        id: JobId,
        stage: &str,
        progress: f64,
        stage_seconds: &BTreeMap<String, f64>,
    ) -> Result<(), StoreError> {
        self.conn().execute(
            "UPDATE jobs SET stage = ?2, progress = ?3, stage_seconds = ?4 WHERE id = ?1 AND state = 'running'",
            params![id.to_string(), stage, progress, json("stage_seconds", stage_seconds)?],
        )?;
        Ok(())
    }

    /// Marks a running job succeeded with its summary, timings and artifacts.
    /// Returns false if the job was not running (deleted meanwhile).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn finish_succeeded(
        &self,
        id: JobId,
        summary: &serde_json::Value,
        stage_seconds: &BTreeMap<String, f64>,
        artifacts: &[Artifact],
    ) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "UPDATE jobs SET state = 'succeeded', finished_ms = ?2, progress = 1, summary = ?3, stage_seconds = ?4, \
             artifacts = ?5 WHERE id = ?1 AND state = 'running'",
            params![
                id.to_string(),
                now_ms(),
                json("summary", summary)?,
                json("stage_seconds", stage_seconds)?,
                json("artifacts", &artifacts)?
            ],
        )?;
        Ok(n == 1)
    }

    /// Marks a queued or running job failed. Returns false if it was in
    /// neither state.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn finish_failed(
        &self,
        id: JobId,
        error: &JobError,
        stage_seconds: &BTreeMap<String, f64>,
    ) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "UPDATE jobs SET state = 'failed', finished_ms = ?2, error_kind = ?3, error_detail = ?4, \
             stage_seconds = ?5 WHERE id = ?1 AND state IN ('queued', 'running')",
            params![id.to_string(), now_ms(), error.kind.as_str(), error.detail, json("stage_seconds", stage_seconds)?],
        )?;
        Ok(n == 1)
    }

    /// Marks a job cancelled if it is in `from` state. Returns whether it was.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn cancel_if(&self, id: JobId, from: JobState) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "UPDATE jobs SET state = 'cancelled', finished_ms = ?2 WHERE id = ?1 AND state = ?3",
            params![id.to_string(), now_ms(), from.as_str()],
        )?;
        Ok(n == 1)
    }

    /// Puts a running job back in the queue (graceful shutdown).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn requeue(&self, id: JobId) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "UPDATE jobs SET state = 'queued', stage = NULL, progress = 0, attempts = max(attempts - 1, 0) \
             WHERE id = ?1 AND state = 'running'",
            [id.to_string()],
        )?;
        Ok(n == 1)
    }

    /// Deletes the record. Returns whether it existed.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn delete(&self, id: JobId) -> Result<bool, StoreError> {
        Ok(self.conn().execute("DELETE FROM jobs WHERE id = ?1", [id.to_string()])? == 1)
    }

    /// After a crash: every `running` job counts a crash and goes back to
    /// `queued`; it is failed instead with kind `interrupted` once claimed
    /// `max_attempts` times, or with kind `crashed-server` at its
    /// [`MAX_CRASHES`]th crash (the process died under it twice: likely out
    /// of memory).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn recover_interrupted(&self, max_attempts: u32) -> Result<Recovery, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let mut rec = Recovery::default();
        {
            let mut stmt = tx.prepare("SELECT id, attempts, crashes FROM jobs WHERE state = 'running' ORDER BY seq")?;
            let rows =
                stmt.query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)?, r.get::<_, i64>(2)?)))?;
            for row in rows {
                let (id, attempts, crashes) = row?;
                let crashes = crashes + 1;
                tx.execute("UPDATE jobs SET crashes = ?2 WHERE id = ?1", params![id, crashes])?;
                let job =
                    id.parse::<JobId>().map_err(|e| StoreError::Corrupt { id: id.clone(), what: e.to_string() })?;
                if attempts >= i64::from(max_attempts) {
                    tx.execute(
                        "UPDATE jobs SET state = 'failed', finished_ms = ?2, error_kind = ?4, \
                         error_detail = ?3 WHERE id = ?1",
                        params![
                            id,
                            now_ms(),
                            format!(
                                "the server stopped while this job was running, {attempts} times; \
                                 it is not retried again (the input may be too large for this server)"
                            ),
                            FailureKind::Interrupted.as_str(),
                        ],
                    )?;
                    rec.failed.push(job);
                } else if crashes >= MAX_CRASHES {
                    tx.execute(
                        "UPDATE jobs SET state = 'failed', finished_ms = ?2, error_kind = ?4, \
                         error_detail = ?3 WHERE id = ?1",
                        params![
                            id,
                            now_ms(),
                            format!(
                                "the server process stopped while this job was running, twice ({crashes} times, \
                                 the last time after running it alone); it likely ran out of memory, so it is not \
                                 retried: lower its sizes (triangles, frames.max_tets or frames.target_size)"
                            ),
                            FailureKind::CrashedServer.as_str(),
                        ],
                    )?;
                    rec.crashed.push(job);
                } else {
                    tx.execute(
                        "UPDATE jobs SET state = 'queued', stage = NULL, progress = 0, stage_seconds = '{}' \
                         WHERE id = ?1",
                        [&id],
                    )?;
                    rec.requeued.push(job);
                }
            }
        }
        tx.commit()?;
        Ok(rec)
    }

    /// Number of jobs per state (states with no job are 0).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn count_by_state(&self) -> Result<BTreeMap<JobState, u64>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare("SELECT state, count(*) FROM jobs GROUP BY state")?;
        let mut out: BTreeMap<JobState, u64> = JobState::ALL.into_iter().map(|s| (s, 0)).collect();
        let rows = stmt.query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)?)))?;
        for row in rows {
            let (state, n) = row?;
            if let Some(s) = JobState::parse(&state) {
                out.insert(s, u64::try_from(n).unwrap_or(0));
            }
        }
        Ok(out)
    }

    /// Number of queued jobs.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn queued_count(&self) -> Result<usize, StoreError> {
        let n: i64 = self.conn().query_row("SELECT count(*) FROM jobs WHERE state = 'queued'", [], |r| r.get(0))?;
        Ok(usize::try_from(n).unwrap_or(0))
    }

    /// The tenant of job `id`: `None` when there is no such job,
    /// `Some(None)` for a job made without authentication.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn owner(&self, id: JobId) -> Result<Option<Option<String>>, StoreError> {
        Ok(self.conn().query_row("SELECT tenant FROM jobs WHERE id = ?1", [id.to_string()], |r| r.get(0)).optional()?)
    }

    /// Number of queued jobs of `tenant`.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn queued_count_of(&self, tenant: &str) -> Result<usize, StoreError> {
        let n: i64 = self.conn().query_row(
            "SELECT count(*) FROM jobs WHERE state = 'queued' AND tenant = ?1",
            [tenant],
            |r| r.get(0),
        )?;
        Ok(usize::try_from(n).unwrap_or(0))
    }

    /// Bytes of uploads plus listed artifacts of every job (of `tenant`'s
    /// jobs only when a tenant is given).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn stored_bytes(&self, tenant: Option<&str>) -> Result<u64, StoreError> {
        let n: i64 = self.conn().query_row(
            "SELECT coalesce(sum(input_bytes), 0) + coalesce(sum( \
                 (SELECT sum(json_extract(a.value, '$.bytes')) FROM json_each(jobs.artifacts) AS a)), 0) \
             FROM jobs WHERE ?1 IS NULL OR tenant = ?1",
            [tenant],
            |r| r.get(0),
        )?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    /// Ids of finished jobs (succeeded, failed, cancelled) that ended before
    /// `cutoff_ms`, oldest first.
    ///
    /// # Errors
    /// [`StoreError`] on database failure or a corrupt id.
    pub fn finished_before(&self, cutoff_ms: i64) -> Result<Vec<JobId>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(
            "SELECT id FROM jobs WHERE state IN ('succeeded', 'failed', 'cancelled') AND finished_ms < ?1 \
             ORDER BY finished_ms",
        )?;
        let ids = stmt.query_map([cutoff_ms], |r| r.get::<_, String>(0))?.collect::<Result<Vec<_>, _>>()?;
        ids.into_iter()
            .map(|id| id.parse::<JobId>().map_err(|e| StoreError::Corrupt { id, what: e.to_string() }))
            .collect()
    }

    /// Deletes the record if the job is finished. Returns whether it was.
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn delete_if_final(&self, id: JobId) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "DELETE FROM jobs WHERE id = ?1 AND state IN ('succeeded', 'failed', 'cancelled')",
            [id.to_string()],
        )?;
        Ok(n == 1)
    }

    /// Checks that the database takes a write (rewrites its `user_version`
    /// in a transaction: one page, cheap).
    ///
    /// # Errors
    /// [`StoreError::Sqlite`] when the write fails (disk full, read-only).
    pub fn probe_write(&self) -> Result<(), StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let v: i64 = tx.query_row("PRAGMA user_version", [], |r| r.get(0))?;
        tx.pragma_update(None, "user_version", v)?;
        tx.commit()?;
        Ok(())
    }

    /// Ids of every job (for cleaning orphaned directories at start-up).
    ///
    /// # Errors
    /// [`StoreError`] on database failure.
    pub fn all_ids(&self) -> Result<Vec<String>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare("SELECT id FROM jobs")?;
        let ids = stmt.query_map([], |r| r.get::<_, String>(0))?.collect::<Result<Vec<_>, _>>()?;
        Ok(ids)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn insert(store: &Store, max: usize) -> Option<JobRecord> {
        store
            .insert_queued(JobId::random(), "a.stl", 10, Some("stl"), &serde_json::json!({"stages": []}), 0, max, None)
            .unwrap()
    }

    #[test]
    fn lifecycle_and_queue_limit() {
        let s = Store::open_in_memory().unwrap();
        let a = insert(&s, 2).unwrap();
        assert_eq!(a.state, JobState::Queued);
        assert_eq!(a.format.as_deref(), Some("stl"));
        let b = insert(&s, 2).unwrap();
        assert!(insert(&s, 2).is_none(), "third job must be refused by a queue of 2");
        let claimed = s.claim_next().unwrap().unwrap();
        assert_eq!((claimed.id, claimed.state, claimed.attempts), (a.id, JobState::Running, 1));
        assert!(insert(&s, 2).is_some(), "claiming frees a queue slot");
        let secs = BTreeMap::from([("load".to_string(), 0.5)]);
        s.set_progress(a.id, "load", 0.25, &secs).unwrap();
        let got = s.get(a.id).unwrap().unwrap();
        assert_eq!((got.stage.as_deref(), got.progress), (Some("load"), 0.25));
        let art = vec![Artifact { name: "report.json".into(), bytes: 3, media_type: "application/json".into() }];
        assert!(s.finish_succeeded(a.id, &serde_json::json!({"x": 1}), &secs, &art).unwrap());
        let got = s.get(a.id).unwrap().unwrap();
        assert_eq!(got.state, JobState::Succeeded);
        assert_eq!(got.artifacts, art);
        assert_eq!(got.summary, Some(serde_json::json!({"x": 1})));
        assert!(!s.cancel_if(a.id, JobState::Queued).unwrap());
        assert!(s.cancel_if(b.id, JobState::Queued).unwrap());
        assert_eq!(s.get(b.id).unwrap().unwrap().state, JobState::Cancelled);
        assert!(s.delete(b.id).unwrap());
        assert!(s.get(b.id).unwrap().is_none());
        assert!(!s.delete(b.id).unwrap());
    }

    #[test]
    fn failure_kinds_round_trip_and_unknown_stored_kinds_read_as_internal_error() {
        let s = Store::open_in_memory().unwrap();
        let a = insert(&s, 10).unwrap();
        s.claim(a.id).unwrap().unwrap();
        let e = JobError::new(FailureKind::InvalidTargetSize, "no interior lattice point");
        assert!(s.finish_failed(a.id, &e, &BTreeMap::new()).unwrap());
        assert_eq!(s.get(a.id).unwrap().unwrap().error, Some(e));
        // Kinds an older version stored (`write-failed`, `io`) or a newer one may store.
        for old in ["write-failed", "io", "kind-from-the-future"] {
            s.conn().execute("UPDATE jobs SET error_kind = ?2 WHERE id = ?1", params![a.id.to_string(), old]).unwrap();
            let got = s.get(a.id).unwrap().unwrap().error.unwrap();
            assert_eq!(got, JobError::new(FailureKind::InternalError, "no interior lattice point"), "{old}");
        }
    }

    #[test]
    fn list_is_newest_first_and_paginates() {
        let s = Store::open_in_memory().unwrap();
        let ids: Vec<JobId> = (0..5).map(|_| insert(&s, 100).unwrap().id).collect();
        let p1 = s.list(2, None, None).unwrap();
        assert_eq!(p1.jobs.iter().map(|j| j.id).collect::<Vec<_>>(), vec![ids[4], ids[3]]);
        let p2 = s.list(2, p1.next_cursor, None).unwrap();
        assert_eq!(p2.jobs.iter().map(|j| j.id).collect::<Vec<_>>(), vec![ids[2], ids[1]]);
        let p3 = s.list(2, p2.next_cursor, None).unwrap();
        assert_eq!(p3.jobs.iter().map(|j| j.id).collect::<Vec<_>>(), vec![ids[0]]);
        assert_eq!(p3.next_cursor, None);
    }

    #[test]
    fn recovery_counts_crashes_and_fails_at_the_second_or_after_max_attempts() {
        let s = Store::open_in_memory().unwrap();
        let a = insert(&s, 10).unwrap();
        let c = s.claim_next().unwrap().unwrap();
        assert_eq!((c.id, c.attempts, c.crashes), (a.id, 1, 0));
        assert_eq!(s.recover_interrupted(3).unwrap().requeued, vec![a.id]);
        let head = s.queue_head().unwrap().unwrap();
        assert_eq!((head.id, head.crashes), (a.id, 1));
        let c = s.claim(a.id).unwrap().unwrap();
        assert_eq!((c.attempts, c.crashes), (2, 1));
        let rec = s.recover_interrupted(3).unwrap();
        assert_eq!(rec.crashed, vec![a.id]);
        let j = s.get(a.id).unwrap().unwrap();
        assert_eq!((j.state, j.crashes), (JobState::Failed, 2));
        assert_eq!(j.error.unwrap().kind, FailureKind::CrashedServer);
        // --max-attempts 1: the first interruption already fails it.
        let b = insert(&s, 10).unwrap();
        s.claim(b.id).unwrap().unwrap();
        assert_eq!(s.recover_interrupted(1).unwrap().failed, vec![b.id]);
        assert_eq!(s.get(b.id).unwrap().unwrap().error.unwrap().kind, FailureKind::Interrupted);
        assert_eq!(s.count_by_state().unwrap()[&JobState::Failed], 2);
        assert!(s.claim(b.id).unwrap().is_none(), "a failed job cannot be claimed");
    }

    #[test]
    fn a_database_from_before_the_added_columns_is_migrated() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.sqlite3");
        {
            let conn = Connection::open(&path).unwrap();
            conn.execute_batch(SCHEMA).unwrap(); // the first schema: no added columns
            conn.execute(
                "INSERT INTO jobs (id, state, created_ms, input_name, input_bytes, params) \
                 VALUES (?1, 'queued', 0, 'a.stl', 1, '{}')",
                [JobId::random().to_string()],
            )
            .unwrap();
        }
        let s = Store::open(&path).unwrap();
        let head = s.queue_head().unwrap().unwrap();
        assert_eq!((head.memory_estimate_bytes, head.crashes), (0, 0));
        drop(s);
        let s = Store::open(&path).unwrap();
        assert_eq!(s.queued_count().unwrap(), 1);
    }

    #[test]
    fn an_old_database_gets_the_tenant_column_and_keeps_its_jobs() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("jobs.sqlite3");
        {
            let conn = Connection::open(&path).unwrap();
            conn.execute_batch(SCHEMA).unwrap();
            conn.execute(
                "INSERT INTO jobs (id, state, created_ms, input_name, input_bytes, params) \
                 VALUES (?1, 'queued', 1, 'old.stl', 7, '{}')",
                [JobId::random().to_string()],
            )
            .unwrap();
        }
        let s = Store::open(&path).unwrap();
        let page = s.list(10, None, None).unwrap();
        assert_eq!(page.jobs.len(), 1);
        assert_eq!(s.owner(page.jobs[0].id).unwrap(), Some(None), "an old job has no tenant");
        assert!(s.list(10, None, Some("a")).unwrap().jobs.is_empty(), "an old job belongs to no tenant");
        drop(s);
        Store::open(&path).unwrap();
    }

    #[test]
    fn tenants_scope_lists_counts_and_stored_bytes() {
        let s = Store::open_in_memory().unwrap();
        let params = serde_json::json!({});
        let add = |t: Option<&str>, bytes: u64| {
            s.insert_queued(JobId::random(), "a.stl", bytes, None, &params, 0, 100, t).unwrap().unwrap().id
        };
        let a1 = add(Some("a"), 100);
        let b1 = add(Some("b"), 10);
        let a2 = add(Some("a"), 1000);
        let anon = add(None, 1);
        let ids = |p: JobPage| p.jobs.iter().map(|j| j.id).collect::<Vec<_>>();
        assert_eq!(ids(s.list(10, None, Some("a")).unwrap()), vec![a2, a1]);
        assert_eq!(ids(s.list(10, None, Some("b")).unwrap()), vec![b1]);
        assert_eq!(ids(s.list(10, None, None).unwrap()), vec![anon, a2, b1, a1]);
        assert_eq!(s.owner(a1).unwrap(), Some(Some("a".to_string())));
        assert_eq!(s.owner(JobId::random()).unwrap(), None);
        assert_eq!(s.queued_count_of("a").unwrap(), 2);
        assert_eq!(s.stored_bytes(Some("a")).unwrap(), 1100);
        assert_eq!(s.stored_bytes(None).unwrap(), 1111);
        let claimed = s.claim_next().unwrap().unwrap();
        assert_eq!(claimed.id, a1);
        let art = vec![
            Artifact { name: "x".into(), bytes: 5, media_type: "t".into() },
            Artifact { name: "y".into(), bytes: 7, media_type: "t".into() },
        ];
        s.finish_succeeded(a1, &serde_json::json!({}), &BTreeMap::new(), &art).unwrap();
        assert_eq!(s.stored_bytes(Some("a")).unwrap(), 1112);
        assert_eq!(s.queued_count_of("a").unwrap(), 1);
        assert_eq!(s.finished_before(now_ms() + 1).unwrap(), vec![a1]);
        assert!(s.finished_before(now_ms() - 60_000).unwrap().is_empty());
        assert!(!s.delete_if_final(a2).unwrap(), "a queued job is not deleted");
        assert!(s.delete_if_final(a1).unwrap());
        assert_eq!(s.stored_bytes(None).unwrap(), 1011);
    }

    #[test]
    fn survives_reopen_of_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("jobs.sqlite3");
        let id = {
            let s = Store::open(&path).unwrap();
            insert(&s, 10).unwrap().id
        };
        let s = Store::open(&path).unwrap();
        assert_eq!(s.get(id).unwrap().unwrap().state, JobState::Queued);
        assert_eq!(s.queued_count().unwrap(), 1);
    }
}
