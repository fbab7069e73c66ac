//! The embedded job store: SQLite (WAL mode, `synchronous = FULL`).
//!
//! One table `jobs`; `seq` (an autoincrement rowid) orders jobs by arrival and
//! is the pagination cursor. JSON columns hold params, summary, per-stage
//! seconds and artifacts. Every state transition is a single `UPDATE … WHERE
//! state = …`, so concurrent transitions (a worker claiming a job while a
//! client cancels it) cannot both win; a worker's writes are fenced by its
//! lease (`lease_owner`, `attempts`), see [`super::store`]. Lease times are
//! this machine's clock, which every process sharing the file shares. The
//! connection sits behind a mutex: statements are short, and the async
//! layer calls them on blocking threads.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

use rusqlite::{Connection, OptionalExtension, Row, params};

use super::model::{Artifact, JobError, JobId, JobPage, JobRecord, JobState, now_ms};
use super::store::{
    COLUMNS, Heartbeat, JobStore, Lease, NewRow, ProgressRow, QueueHead, RawRow, Reaped, Recovery, StoreError, as_i64,
    json, lease_ms, parse_id, reap_decision,
};

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
CREATE TABLE IF NOT EXISTS workers (
    name          TEXT    PRIMARY KEY,
    memory_budget INTEGER NOT NULL,
    last_seen_ms  INTEGER NOT NULL
);
";

/// Indexes over added columns (created after the columns exist).
const ADDED_INDEXES: &str = "CREATE INDEX IF NOT EXISTS jobs_by_tenant ON jobs(tenant, seq);";

/// Columns added after the first schema: `(name, declaration)`, added by
/// [`add_missing_columns`] to databases that lack them. `tenant`: the
/// submitting tenant, NULL for jobs made without authentication;
/// `lease_owner`, `lease_until_ms`, `cancel_requested`: the lease of a
/// running job and a client's cancel request (read at the heartbeat).
const ADDED_COLUMNS: &[(&str, &str)] = &[
    ("memory_estimate_bytes", "INTEGER NOT NULL DEFAULT 0"),
    ("crashes", "INTEGER NOT NULL DEFAULT 0"),
    ("tenant", "TEXT"),
    ("lease_owner", "TEXT"),
    ("lease_until_ms", "INTEGER"),
    ("cancel_requested", "INTEGER NOT NULL DEFAULT 0"),
];

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

/// Reads one row in [`COLUMNS`] order.
fn read_row(r: &Row<'_>) -> rusqlite::Result<RawRow> {
    Ok(RawRow {
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
        cancel_requested: r.get(20)?,
    })
}

/// The SQL condition "running under lease ?1 (id), ?2 (attempt), ?3 (owner)".
const FENCE: &str = "id = ?1 AND attempts = ?2 AND lease_owner = ?3 AND state = 'running'";

/// `(id, attempts, crashes, lease_owner, lease_until_ms)` of a running job.
type RunningRow = (String, i64, i64, Option<String>, Option<i64>);

/// The SQLite job store.
pub struct SqliteStore {
    conn: Mutex<Connection>,
}

impl SqliteStore {
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

    /// Runs `sql` with the lease fence as `?1..?3` and `rest` after it;
    /// returns whether a row changed.
    fn fenced(&self, sql: &str, lease: &Lease, rest: &[&dyn rusqlite::ToSql]) -> Result<bool, StoreError> {
        let id = lease.id.to_string();
        let attempt = i64::from(lease.attempt);
        let owner: &str = &lease.owner;
        let mut all: Vec<&dyn rusqlite::ToSql> = vec![&id, &attempt, &owner];
        all.extend_from_slice(rest);
        Ok(self.conn().execute(sql, all.as_slice())? == 1)
    }
}

impl JobStore for SqliteStore {
    fn insert_queued(&self, new: &NewRow<'_>, max_queued: usize) -> Result<Option<JobRecord>, StoreError> {
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
                new.id.to_string(),
                now_ms(),
                new.input_name,
                as_i64(new.input_bytes),
                new.format,
                json("params", new.params)?,
                as_i64(new.memory_estimate_bytes),
                new.tenant
            ],
        )?;
        // Read back inside the transaction: the record as inserted (queued),
        // even when the dispatcher claims the job right after the commit.
        let raw = tx.query_row(&format!("SELECT {COLUMNS} FROM jobs WHERE id = ?1"), [new.id.to_string()], read_row)?;
        tx.commit()?;
        raw.into_record().map(Some)
    }

    fn get(&self, id: JobId) -> Result<Option<JobRecord>, StoreError> {
        let raw = self
            .conn()
            .query_row(&format!("SELECT {COLUMNS} FROM jobs WHERE id = ?1"), [id.to_string()], read_row)
            .optional()?;
        raw.map(RawRow::into_record).transpose()
    }

    fn list(&self, limit: usize, before: Option<i64>, tenant: Option<&str>) -> Result<JobPage, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT {COLUMNS} FROM jobs WHERE seq < ?1 AND (?3 IS NULL OR tenant = ?3) ORDER BY seq DESC LIMIT ?2"
        ))?;
        let take = i64::try_from(limit.saturating_add(1)).unwrap_or(i64::MAX);
        let raws = stmt
            .query_map(params![before.unwrap_or(i64::MAX), take, tenant], read_row)?
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

    fn queue_head(&self, max_estimate: u64) -> Result<Option<QueueHead>, StoreError> {
        let row: Option<(String, i64, i64)> = self
            .conn()
            .query_row(
                "SELECT id, memory_estimate_bytes, crashes FROM jobs \
                 WHERE state = 'queued' AND memory_estimate_bytes <= ?1 ORDER BY seq LIMIT 1",
                [as_i64(max_estimate)],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
            )
            .optional()?;
        row.map(|(id, bytes, crashes)| {
            Ok(QueueHead {
                id: parse_id(id)?,
                memory_estimate_bytes: u64::try_from(bytes).unwrap_or(0),
                crashes: u32::try_from(crashes).unwrap_or(0),
            })
        })
        .transpose()
    }

    fn claim(&self, id: JobId, owner: &str, lease: Duration) -> Result<Option<JobRecord>, StoreError> {
        let now = now_ms();
        let n = self.conn().execute(
            "UPDATE jobs SET state = 'running', attempts = attempts + 1, started_ms = ?2, stage = NULL, \
             progress = 0, stage_seconds = '{}', lease_owner = ?3, lease_until_ms = ?4, cancel_requested = 0 \
             WHERE id = ?1 AND state = 'queued'",
            params![id.to_string(), now, owner, now.saturating_add(lease_ms(lease))],
        )?;
        if n == 1 { self.get(id) } else { Ok(None) }
    }

    fn heartbeat(
        &self,
        lease: &Lease,
        lease_for: Duration,
        progress: Option<&ProgressRow>,
    ) -> Result<Heartbeat, StoreError> {
        let until = now_ms().saturating_add(lease_ms(lease_for));
        let conn = self.conn();
        let flag: Option<bool> = match progress {
            Some((stage, fraction, secs)) => conn
                .query_row(
                    &format!(
                        "UPDATE jobs SET lease_until_ms = ?4, stage = ?5, progress = ?6, stage_seconds = ?7 \
                         WHERE {FENCE} RETURNING cancel_requested"
                    ),
                    params![
                        lease.id.to_string(),
                        i64::from(lease.attempt),
                        &*lease.owner,
                        until,
                        stage,
                        fraction,
                        json("stage_seconds", secs)?
                    ],
                    |r| r.get(0),
                )
                .optional()?,
            None => conn
                .query_row(
                    &format!("UPDATE jobs SET lease_until_ms = ?4 WHERE {FENCE} RETURNING cancel_requested"),
                    params![lease.id.to_string(), i64::from(lease.attempt), &*lease.owner, until],
                    |r| r.get(0),
                )
                .optional()?,
        };
        Ok(match flag {
            Some(cancel_requested) => Heartbeat::Held { cancel_requested },
            None => Heartbeat::Lost,
        })
    }

    fn finish_succeeded(
        &self,
        lease: &Lease,
        summary: &serde_json::Value,
        stage_seconds: &BTreeMap<String, f64>,
        artifacts: &[Artifact],
    ) -> Result<bool, StoreError> {
        self.fenced(
            &format!(
                "UPDATE jobs SET state = 'succeeded', finished_ms = ?4, progress = 1, summary = ?5, \
                 stage_seconds = ?6, artifacts = ?7, lease_until_ms = NULL WHERE {FENCE}"
            ),
            lease,
            &[
                &now_ms(),
                &json("summary", summary)?,
                &json("stage_seconds", stage_seconds)?,
                &json("artifacts", &artifacts)?,
            ],
        )
    }

    fn finish_failed(
        &self,
        lease: &Lease,
        error: &JobError,
        stage_seconds: &BTreeMap<String, f64>,
    ) -> Result<bool, StoreError> {
        self.fenced(
            &format!(
                "UPDATE jobs SET state = 'failed', finished_ms = ?4, error_kind = ?5, error_detail = ?6, \
                 stage_seconds = ?7, lease_until_ms = NULL WHERE {FENCE}"
            ),
            lease,
            &[&now_ms(), &error.kind.as_str(), &error.detail, &json("stage_seconds", stage_seconds)?],
        )
    }

    fn finish_cancelled(&self, lease: &Lease) -> Result<bool, StoreError> {
        self.fenced(
            &format!("UPDATE jobs SET state = 'cancelled', finished_ms = ?4, lease_until_ms = NULL WHERE {FENCE}"),
            lease,
            &[&now_ms()],
        )
    }

    fn cancel_queued(&self, id: JobId) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "UPDATE jobs SET state = 'cancelled', finished_ms = ?2 WHERE id = ?1 AND state = 'queued'",
            params![id.to_string(), now_ms()],
        )?;
        Ok(n == 1)
    }

    fn request_cancel(&self, id: JobId) -> Result<bool, StoreError> {
        let n = self
            .conn()
            .execute("UPDATE jobs SET cancel_requested = 1 WHERE id = ?1 AND state = 'running'", [id.to_string()])?;
        Ok(n == 1)
    }

    fn requeue(&self, lease: &Lease) -> Result<bool, StoreError> {
        self.fenced(
            &format!(
                "UPDATE jobs SET state = 'queued', stage = NULL, progress = 0, attempts = max(attempts - 1, 0), \
                 lease_owner = NULL, lease_until_ms = NULL WHERE {FENCE}"
            ),
            lease,
            &[],
        )
    }

    fn delete(&self, id: JobId) -> Result<bool, StoreError> {
        Ok(self.conn().execute("DELETE FROM jobs WHERE id = ?1", [id.to_string()])? == 1)
    }

    fn reap_expired(&self, max_attempts: u32, is_dead: &dyn Fn(&str) -> bool) -> Result<Recovery, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let mut rec = Recovery::default();
        let now = now_ms();
        let rows: Vec<RunningRow> = {
            let mut stmt = tx.prepare(
                "SELECT id, attempts, crashes, lease_owner, lease_until_ms FROM jobs WHERE state = 'running' \
                 ORDER BY seq",
            )?;
            stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?)))?
                .collect::<Result<_, _>>()?
        };
        for (id, attempts, crashes, owner, until) in rows {
            // A row from before leases has no owner: its process is gone.
            let died = owner.as_deref().is_none_or(is_dead);
            if !died && until.is_some_and(|t| t >= now) {
                continue;
            }
            let crashes = crashes + i64::from(died);
            let job = parse_id(id.clone())?;
            match reap_decision(attempts, crashes, max_attempts, died) {
                Reaped::Requeue => {
                    tx.execute(
                        "UPDATE jobs SET state = 'queued', stage = NULL, progress = 0, stage_seconds = '{}', \
                         crashes = ?2, lease_owner = NULL, lease_until_ms = NULL WHERE id = ?1",
                        params![id, crashes],
                    )?;
                    rec.requeued.push(job);
                }
                Reaped::Fail(kind, detail) => {
                    tx.execute(
                        "UPDATE jobs SET state = 'failed', finished_ms = ?2, error_kind = ?3, error_detail = ?4, \
                         crashes = ?5, lease_until_ms = NULL WHERE id = ?1",
                        params![id, now, kind.as_str(), detail, crashes],
                    )?;
                    if kind == crate::failure::FailureKind::CrashedServer {
                        rec.crashed.push(job);
                    } else {
                        rec.failed.push(job);
                    }
                }
            }
        }
        tx.commit()?;
        Ok(rec)
    }

    fn count_by_state(&self) -> Result<BTreeMap<JobState, u64>, StoreError> {
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

    fn queued_count(&self) -> Result<usize, StoreError> {
        let n: i64 = self.conn().query_row("SELECT count(*) FROM jobs WHERE state = 'queued'", [], |r| r.get(0))?;
        Ok(usize::try_from(n).unwrap_or(0))
    }

    fn owner(&self, id: JobId) -> Result<Option<Option<String>>, StoreError> {
        Ok(self.conn().query_row("SELECT tenant FROM jobs WHERE id = ?1", [id.to_string()], |r| r.get(0)).optional()?)
    }

    fn queued_count_of(&self, tenant: &str) -> Result<usize, StoreError> {
        let n: i64 = self.conn().query_row(
            "SELECT count(*) FROM jobs WHERE state = 'queued' AND tenant = ?1",
            [tenant],
            |r| r.get(0),
        )?;
        Ok(usize::try_from(n).unwrap_or(0))
    }

    fn stored_bytes(&self, tenant: Option<&str>) -> Result<u64, StoreError> {
        let n: i64 = self.conn().query_row(
            "SELECT coalesce(sum(input_bytes), 0) + coalesce(sum( \
                 (SELECT sum(json_extract(a.value, '$.bytes')) FROM json_each(jobs.artifacts) AS a)), 0) \
             FROM jobs WHERE ?1 IS NULL OR tenant = ?1",
            [tenant],
            |r| r.get(0),
        )?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    fn finished_before(&self, cutoff_ms: i64) -> Result<Vec<JobId>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(
            "SELECT id FROM jobs WHERE state IN ('succeeded', 'failed', 'cancelled') AND finished_ms < ?1 \
             ORDER BY finished_ms",
        )?;
        let ids = stmt.query_map([cutoff_ms], |r| r.get::<_, String>(0))?.collect::<Result<Vec<_>, _>>()?;
        ids.into_iter().map(parse_id).collect()
    }

    fn delete_if_final(&self, id: JobId) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "DELETE FROM jobs WHERE id = ?1 AND state IN ('succeeded', 'failed', 'cancelled')",
            [id.to_string()],
        )?;
        Ok(n == 1)
    }

    /// Rewrites the database's `user_version` in a transaction: one page, cheap.
    fn probe_write(&self) -> Result<(), StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let v: i64 = tx.query_row("PRAGMA user_version", [], |r| r.get(0))?;
        tx.pragma_update(None, "user_version", v)?;
        tx.commit()?;
        Ok(())
    }

    fn all_ids(&self) -> Result<Vec<String>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare("SELECT id FROM jobs")?;
        let ids = stmt.query_map([], |r| r.get::<_, String>(0))?.collect::<Result<Vec<_>, _>>()?;
        Ok(ids)
    }

    fn register_worker(&self, name: &str, memory_budget: u64) -> Result<(), StoreError> {
        let now = now_ms();
        let conn = self.conn();
        conn.execute(
            "INSERT INTO workers (name, memory_budget, last_seen_ms) VALUES (?1, ?2, ?3) ON CONFLICT(name) \
             DO UPDATE SET memory_budget = excluded.memory_budget, last_seen_ms = excluded.last_seen_ms",
            params![name, as_i64(memory_budget), now],
        )?;
        conn.execute("DELETE FROM workers WHERE last_seen_ms < ?1", [now - 86_400_000])?;
        Ok(())
    }

    fn largest_worker_budget(&self, within: Duration) -> Result<Option<u64>, StoreError> {
        let since = now_ms().saturating_sub(lease_ms(within));
        let max: Option<i64> =
            self.conn()
                .query_row("SELECT max(memory_budget) FROM workers WHERE last_seen_ms >= ?1", [since], |r| r.get(0))?;
        Ok(max.map(|b| u64::try_from(b).unwrap_or(0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::failure::FailureKind;
    use crate::jobs::store_conformance as conformance;

    #[test]
    fn conforms_to_the_job_store_contract() {
        conformance::run_all(&|| Box::new(SqliteStore::open_in_memory().unwrap()));
    }

    #[test]
    fn the_contract_holds_on_a_file_too() {
        let dir = tempfile::tempdir().unwrap();
        let n = std::sync::atomic::AtomicUsize::new(0);
        conformance::run_all(&|| {
            let i = n.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            Box::new(SqliteStore::open(&dir.path().join(format!("{i}.sqlite3"))).unwrap())
        });
    }

    #[test]
    fn unknown_stored_kinds_read_as_internal_error() {
        let s = SqliteStore::open_in_memory().unwrap();
        let a = conformance::insert(&s, 10).unwrap();
        // Kinds an older version stored (`write-failed`, `io`) or a newer one may store.
        for old in ["write-failed", "io", "kind-from-the-future"] {
            s.conn()
                .execute(
                    "UPDATE jobs SET error_kind = ?2, error_detail = 'd', state = 'failed' WHERE id = ?1",
                    params![a.id.to_string(), old],
                )
                .unwrap();
            let got = s.get(a.id).unwrap().unwrap().error.unwrap();
            assert_eq!(got, JobError::new(FailureKind::InternalError, "d"), "{old}");
        }
    }

    #[test]
    fn a_database_from_before_the_added_columns_is_migrated_and_its_running_jobs_reaped() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.sqlite3");
        let (queued, running) = (JobId::random(), JobId::random());
        {
            let conn = Connection::open(&path).unwrap();
            conn.execute_batch(SCHEMA).unwrap(); // the first schema: no added columns
            for (id, state) in [(queued, "queued"), (running, "running")] {
                conn.execute(
                    "INSERT INTO jobs (id, state, created_ms, input_name, input_bytes, params, attempts) \
                     VALUES (?1, ?2, 0, 'a.stl', 1, '{}', 1)",
                    params![id.to_string(), state],
                )
                .unwrap();
            }
        }
        let s = SqliteStore::open(&path).unwrap();
        let head = s.queue_head(u64::MAX).unwrap().unwrap();
        assert_eq!((head.id, head.memory_estimate_bytes, head.crashes), (queued, 0, 0));
        assert_eq!(s.owner(queued).unwrap(), Some(None), "an old job has no tenant");
        assert!(s.list(10, None, Some("a")).unwrap().jobs.is_empty(), "an old job belongs to no tenant");
        // A running row from before leases has no owner: its process is gone.
        assert_eq!(s.reap_expired(3, &|_: &str| false).unwrap().requeued, vec![running]);
        drop(s);
        let s = SqliteStore::open(&path).unwrap();
        assert_eq!(s.queued_count().unwrap(), 2);
    }

    #[test]
    fn survives_reopen_of_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("jobs.sqlite3");
        let id = {
            let s = SqliteStore::open(&path).unwrap();
            conformance::insert(&s, 10).unwrap().id
        };
        let s = SqliteStore::open(&path).unwrap();
        assert_eq!(s.get(id).unwrap().unwrap().state, JobState::Queued);
        assert_eq!(s.queued_count().unwrap(), 1);
    }
}
