//! The distributed job store: PostgreSQL through `tokio-postgres` and a
//! `deadpool-postgres` connection pool.
//!
//! Same table and contract as [`super::sqlite_store`], with these
//! differences:
//! - times (`created_ms`, lease expiries, …) come from the database's clock,
//!   so machines with skewed clocks agree on when a lease expires;
//! - a claim skips a row another worker is claiming (`FOR UPDATE SKIP
//!   LOCKED`) instead of waiting for it;
//! - the queue-length check and the insert of a submission hold a
//!   transaction-scoped advisory lock, so API replicas cannot overfill it;
//! - an insert `NOTIFY`s channel [`CHANNEL`], which wakes idle workers
//!   ([`PgStore::listen`]); workers poll as well, since a notification is
//!   lost when nobody listens;
//! - migrations are numbered ([`MIGRATIONS`]) and applied under an advisory
//!   lock, so processes starting at once apply each exactly once.
//!
//! The store is called from blocking threads, as the SQLite one: each call
//! runs on this store's own small tokio runtime and the caller waits for
//! the answer on a channel, which works from any thread.

use std::collections::BTreeMap;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use deadpool_postgres::{Pool, PoolConfig, Runtime, Timeouts};

use super::blocking_runtime::BlockingRuntime;
use tokio_postgres::NoTls;
use tokio_postgres::types::ToSql;

use super::model::{Artifact, JobError, JobId, JobPage, JobRecord, JobState};
use super::store::{
    COLUMNS, Heartbeat, JobStore, Lease, NewRow, ProgressRow, QueueHead, RawRow, Reaped, Recovery, StoreError, as_i64,
    json, lease_ms, parse_id, reap_decision,
};

/// The channel an insert notifies and idle workers listen on.
pub const CHANNEL: &str = "meshatlas_jobs";

/// Key of the advisory lock held while migrating.
const MIGRATION_LOCK: i64 = 0x6d65_7368_6174_6c01;
/// Key of the advisory lock held by the queue-length check and insert.
const QUEUE_LOCK: i64 = 0x6d65_7368_6174_6c02;

/// The database clock in milliseconds since the Unix epoch.
const NOW_MS: &str = "(extract(epoch from clock_timestamp()) * 1000)::bigint";

/// Numbered schema changes, applied in order, each once.
const MIGRATIONS: &[(i32, &str)] = &[
    (
        1,
        "CREATE TABLE jobs (
        seq                   BIGSERIAL PRIMARY KEY,
        id                    TEXT NOT NULL UNIQUE,
        state                 TEXT NOT NULL,
        created_ms            BIGINT NOT NULL,
        started_ms            BIGINT,
        finished_ms           BIGINT,
        input_name            TEXT NOT NULL,
        input_bytes           BIGINT NOT NULL,
        format                TEXT,
        params                TEXT NOT NULL,
        stage                 TEXT,
        progress              DOUBLE PRECISION NOT NULL DEFAULT 0,
        stage_seconds         TEXT NOT NULL DEFAULT '{}',
        summary               TEXT,
        error_kind            TEXT,
        error_detail          TEXT,
        artifacts             TEXT NOT NULL DEFAULT '[]',
        artifact_bytes        BIGINT NOT NULL DEFAULT 0,
        attempts              BIGINT NOT NULL DEFAULT 0,
        memory_estimate_bytes BIGINT NOT NULL DEFAULT 0,
        crashes               BIGINT NOT NULL DEFAULT 0,
        tenant                TEXT,
        lease_owner           TEXT,
        lease_until_ms        BIGINT,
        cancel_requested      BOOLEAN NOT NULL DEFAULT false
    );
    CREATE INDEX jobs_by_state ON jobs (state, seq);
    CREATE INDEX jobs_by_tenant ON jobs (tenant, seq);",
    ),
    (
        2,
        "CREATE TABLE workers (
        name          TEXT PRIMARY KEY,
        memory_budget BIGINT NOT NULL,
        last_seen_ms  BIGINT NOT NULL
    );",
    ),
];

/// The SQL condition "running under lease $1 (id), $2 (attempt), $3 (owner)".
const FENCE: &str = "id = $1 AND attempts = $2 AND lease_owner = $3 AND state = 'running'";

fn pg(e: impl std::fmt::Display) -> StoreError {
    StoreError::Postgres(e.to_string())
}

/// Reads one row in [`COLUMNS`] order.
fn read_row(r: &tokio_postgres::Row) -> Result<RawRow, StoreError> {
    let raw = || -> Result<RawRow, tokio_postgres::Error> {
        Ok(RawRow {
            seq: r.try_get(0)?,
            id: r.try_get(1)?,
            state: r.try_get(2)?,
            created_ms: r.try_get(3)?,
            started_ms: r.try_get(4)?,
            finished_ms: r.try_get(5)?,
            input_name: r.try_get(6)?,
            input_bytes: r.try_get(7)?,
            format: r.try_get(8)?,
            params: r.try_get(9)?,
            stage: r.try_get(10)?,
            progress: r.try_get(11)?,
            stage_seconds: r.try_get(12)?,
            summary: r.try_get(13)?,
            error_kind: r.try_get(14)?,
            error_detail: r.try_get(15)?,
            artifacts: r.try_get(16)?,
            attempts: r.try_get(17)?,
            memory_estimate_bytes: r.try_get(18)?,
            crashes: r.try_get(19)?,
            cancel_requested: r.try_get(20)?,
        })
    };
    raw().map_err(pg)
}

/// The PostgreSQL job store.
pub struct PgStore {
    pool: Pool,
    url: String,
    rt: BlockingRuntime,
}

/// A parameter list of owned values, moved into a query's future.
type Params = Vec<Box<dyn ToSql + Sync + Send>>;

fn refs(p: &Params) -> Vec<&(dyn ToSql + Sync)> {
    p.iter().map(|b| &**b as &(dyn ToSql + Sync)).collect()
}

impl PgStore {
    /// Connects to `url` (libpq style, e.g. `postgres://user@host:5432/db`)
    /// and applies the pending migrations.
    ///
    /// # Errors
    /// [`StoreError::Postgres`] when the server cannot be reached or a
    /// migration fails.
    pub fn connect(url: &str) -> Result<Self, StoreError> {
        let rt = BlockingRuntime::new("meshatlas-postgres")
            .map_err(|e| pg(format!("cannot start the database runtime: {e}")))?;
        let mut cfg = deadpool_postgres::Config::new();
        cfg.url = Some(url.to_string());
        cfg.connect_timeout = Some(Duration::from_secs(5));
        cfg.application_name = Some("meshatlas".into());
        let timeouts = Timeouts {
            wait: Some(Duration::from_secs(10)),
            create: Some(Duration::from_secs(5)),
            recycle: Some(Duration::from_secs(5)),
        };
        cfg.pool = Some(PoolConfig { timeouts, ..PoolConfig::new(8) });
        let pool = {
            let _guard = rt.handle().map(tokio::runtime::Handle::enter);
            cfg.create_pool(Some(Runtime::Tokio1), NoTls).map_err(pg)?
        };
        let store = Self { pool, url: url.to_string(), rt };
        store.run(|pool| async move { migrate(&pool).await })?;
        Ok(store)
    }

    /// Runs the future `f` makes from the pool on the store's runtime and
    /// waits for its result (from any thread, async or not).
    fn run<T, F>(&self, f: impl FnOnce(Pool) -> F) -> Result<T, StoreError>
    where
        T: Send + 'static,
        F: Future<Output = Result<T, StoreError>> + Send + 'static,
    {
        self.rt.run(f(self.pool.clone())).ok_or_else(|| pg("the database task stopped"))?
    }

    /// Runs one statement with `params`; returns the rows changed.
    fn execute(&self, sql: String, params: Params) -> Result<u64, StoreError> {
        self.run(move |pool| async move {
            let client = pool.get().await.map_err(pg)?;
            client.execute(sql.as_str(), &refs(&params)).await.map_err(pg)
        })
    }

    /// Runs one query with `params`; returns its rows.
    fn query(&self, sql: String, params: Params) -> Result<Vec<tokio_postgres::Row>, StoreError> {
        self.run(move |pool| async move {
            let client = pool.get().await.map_err(pg)?;
            client.query(sql.as_str(), &refs(&params)).await.map_err(pg)
        })
    }

    /// The first value of the one row `sql` returns.
    fn scalar_i64(&self, sql: &str, params: Params) -> Result<i64, StoreError> {
        let rows = self.query(sql.to_string(), params)?;
        rows.first().ok_or_else(|| pg("no row"))?.try_get(0).map_err(pg)
    }

    /// Runs `sql` with the lease fence as `$1..$3` and `rest` after it;
    /// returns whether a row changed.
    fn fenced(&self, sql: String, lease: &Lease, rest: Params) -> Result<bool, StoreError> {
        let mut all: Params =
            vec![Box::new(lease.id.to_string()), Box::new(i64::from(lease.attempt)), Box::new(lease.owner.to_string())];
        all.extend(rest);
        Ok(self.execute(sql, all)? == 1)
    }

    /// Listens on [`CHANNEL`] on a dedicated connection and calls `wake` on
    /// every notification, until the store is dropped; reconnects after a
    /// lost connection (the caller polls meanwhile).
    pub fn listen(&self, wake: Arc<dyn Fn() + Send + Sync>) {
        let Some(rt) = self.rt.handle() else { return };
        let url = self.url.clone();
        rt.spawn(async move {
            loop {
                if let Err(e) = listen_once(&url, &wake).await {
                    tracing::warn!(error = %e, "job notifications lost; reconnecting in 1 s (workers poll meanwhile)");
                }
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
        });
    }
}

/// One listening connection: `LISTEN`, then `wake` per notification until
/// the connection ends.
async fn listen_once(url: &str, wake: &Arc<dyn Fn() + Send + Sync>) -> Result<(), tokio_postgres::Error> {
    let (client, mut conn) = tokio_postgres::connect(url, NoTls).await?;
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    let driver = tokio::spawn(async move {
        let mut messages = futures_util::stream::poll_fn(move |cx| conn.poll_message(cx));
        while let Some(m) = futures_util::StreamExt::next(&mut messages).await {
            match m {
                Ok(tokio_postgres::AsyncMessage::Notification(_)) => {
                    let _ = tx.send(());
                }
                Ok(_) => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    });
    client.batch_execute(&format!("LISTEN {CHANNEL}")).await?;
    while rx.recv().await.is_some() {
        wake();
    }
    drop(client);
    driver.await.unwrap_or(Ok(()))
}

/// Applies the [`MIGRATIONS`] the database lacks, under [`MIGRATION_LOCK`].
async fn migrate(pool: &Pool) -> Result<(), StoreError> {
    let mut client = pool.get().await.map_err(pg)?;
    let tx = client.transaction().await.map_err(pg)?;
    tx.execute("SELECT pg_advisory_xact_lock($1)", &[&MIGRATION_LOCK]).await.map_err(pg)?;
    tx.batch_execute(
        "CREATE TABLE IF NOT EXISTS meshatlas_migrations (version INT PRIMARY KEY, applied_ms BIGINT NOT NULL)",
    )
    .await
    .map_err(pg)?;
    let row = tx.query_one("SELECT coalesce(max(version), 0) FROM meshatlas_migrations", &[]).await.map_err(pg)?;
    let have: i32 = row.try_get(0).map_err(pg)?;
    for (version, sql) in MIGRATIONS.iter().filter(|(v, _)| *v > have) {
        tx.batch_execute(sql).await.map_err(|e| pg(format!("migration {version}: {e}")))?;
        tx.execute(&format!("INSERT INTO meshatlas_migrations VALUES ($1, {NOW_MS})"), &[version]).await.map_err(pg)?;
        tracing::info!(version, "applied job database migration");
    }
    tx.commit().await.map_err(pg)
}

fn ids_of(rows: &[tokio_postgres::Row]) -> Result<Vec<JobId>, StoreError> {
    rows.iter().map(|r| parse_id(r.try_get(0).map_err(pg)?)).collect()
}

impl JobStore for PgStore {
    fn insert_queued(&self, new: &NewRow<'_>, max_queued: usize) -> Result<Option<JobRecord>, StoreError> {
        let p: Params = vec![
            Box::new(new.id.to_string()),
            Box::new(new.input_name.to_string()),
            Box::new(as_i64(new.input_bytes)),
            Box::new(new.format.map(str::to_string)),
            Box::new(json("params", new.params)?),
            Box::new(as_i64(new.memory_estimate_bytes)),
            Box::new(new.tenant.map(str::to_string)),
        ];
        let max = i64::try_from(max_queued).unwrap_or(i64::MAX);
        let row = self.run(move |pool| async move {
            let mut client = pool.get().await.map_err(pg)?;
            let tx = client.transaction().await.map_err(pg)?;
            tx.execute("SELECT pg_advisory_xact_lock($1)", &[&QUEUE_LOCK]).await.map_err(pg)?;
            let queued: i64 = tx
                .query_one("SELECT count(*) FROM jobs WHERE state = 'queued'", &[])
                .await
                .and_then(|r| r.try_get(0))
                .map_err(pg)?;
            if queued >= max {
                return Ok(None);
            }
            let sql = format!(
                "INSERT INTO jobs (id, state, created_ms, input_name, input_bytes, format, params, \
                 memory_estimate_bytes, tenant) VALUES ($1, 'queued', {NOW_MS}, $2, $3, $4, $5, $6, $7) \
                 RETURNING {COLUMNS}"
            );
            let row = tx.query_one(sql.as_str(), &refs(&p)).await.map_err(pg)?;
            tx.execute("SELECT pg_notify($1, '')", &[&CHANNEL]).await.map_err(pg)?;
            tx.commit().await.map_err(pg)?;
            Ok(Some(read_row(&row)?))
        })?;
        row.map(RawRow::into_record).transpose()
    }

    fn get(&self, id: JobId) -> Result<Option<JobRecord>, StoreError> {
        let rows = self.query(format!("SELECT {COLUMNS} FROM jobs WHERE id = $1"), vec![Box::new(id.to_string())])?;
        rows.first().map(|r| read_row(r)?.into_record()).transpose()
    }

    fn list(&self, limit: usize, before: Option<i64>, tenant: Option<&str>) -> Result<JobPage, StoreError> {
        let take = i64::try_from(limit.saturating_add(1)).unwrap_or(i64::MAX);
        let rows = self.query(
            format!(
                "SELECT {COLUMNS} FROM jobs WHERE seq < $1 AND ($3::text IS NULL OR tenant = $3) \
                 ORDER BY seq DESC LIMIT $2"
            ),
            vec![Box::new(before.unwrap_or(i64::MAX)), Box::new(take), Box::new(tenant.map(str::to_string))],
        )?;
        let mut jobs = rows.iter().map(|r| read_row(r)?.into_record()).collect::<Result<Vec<_>, _>>()?;
        let next_cursor = if jobs.len() > limit {
            jobs.truncate(limit);
            jobs.last().map(|j| j.seq)
        } else {
            None
        };
        Ok(JobPage { jobs, next_cursor })
    }

    fn queue_head(&self, max_estimate: u64) -> Result<Option<QueueHead>, StoreError> {
        let rows = self.query(
            "SELECT id, memory_estimate_bytes, crashes FROM jobs \
             WHERE state = 'queued' AND memory_estimate_bytes <= $1 ORDER BY seq LIMIT 1"
                .into(),
            vec![Box::new(as_i64(max_estimate))],
        )?;
        rows.first()
            .map(|r| {
                let (id, bytes, crashes): (String, i64, i64) =
                    (r.try_get(0).map_err(pg)?, r.try_get(1).map_err(pg)?, r.try_get(2).map_err(pg)?);
                Ok(QueueHead {
                    id: parse_id(id)?,
                    memory_estimate_bytes: u64::try_from(bytes).unwrap_or(0),
                    crashes: u32::try_from(crashes).unwrap_or(0),
                })
            })
            .transpose()
    }

    fn claim(&self, id: JobId, owner: &str, lease: Duration) -> Result<Option<JobRecord>, StoreError> {
        let rows = self.query(
            format!(
                "UPDATE jobs SET state = 'running', attempts = attempts + 1, started_ms = {NOW_MS}, stage = NULL, \
                 progress = 0, stage_seconds = '{{}}', lease_owner = $2, lease_until_ms = {NOW_MS} + $3, \
                 cancel_requested = false \
                 WHERE id = (SELECT id FROM jobs WHERE id = $1 AND state = 'queued' FOR UPDATE SKIP LOCKED) \
                 RETURNING {COLUMNS}"
            ),
            vec![Box::new(id.to_string()), Box::new(owner.to_string()), Box::new(lease_ms(lease))],
        )?;
        rows.first().map(|r| read_row(r)?.into_record()).transpose()
    }

    fn heartbeat(
        &self,
        lease: &Lease,
        lease_for: Duration,
        progress: Option<&ProgressRow>,
    ) -> Result<Heartbeat, StoreError> {
        let mut p: Params = vec![
            Box::new(lease.id.to_string()),
            Box::new(i64::from(lease.attempt)),
            Box::new(lease.owner.to_string()),
            Box::new(lease_ms(lease_for)),
        ];
        let sql = match progress {
            Some((stage, fraction, secs)) => {
                p.push(Box::new(stage.clone()));
                p.push(Box::new(*fraction));
                p.push(Box::new(json("stage_seconds", secs)?));
                format!(
                    "UPDATE jobs SET lease_until_ms = {NOW_MS} + $4, stage = $5, progress = $6, stage_seconds = $7 \
                     WHERE {FENCE} RETURNING cancel_requested"
                )
            }
            None => format!("UPDATE jobs SET lease_until_ms = {NOW_MS} + $4 WHERE {FENCE} RETURNING cancel_requested"),
        };
        let rows = self.query(sql, p)?;
        Ok(match rows.first() {
            Some(r) => Heartbeat::Held { cancel_requested: r.try_get(0).map_err(pg)? },
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
        let bytes = artifacts.iter().fold(0u64, |s, a| s.saturating_add(a.bytes));
        self.fenced(
            format!(
                "UPDATE jobs SET state = 'succeeded', finished_ms = {NOW_MS}, progress = 1, summary = $4, \
                 stage_seconds = $5, artifacts = $6, artifact_bytes = $7, lease_until_ms = NULL WHERE {FENCE}"
            ),
            lease,
            vec![
                Box::new(json("summary", summary)?),
                Box::new(json("stage_seconds", stage_seconds)?),
                Box::new(json("artifacts", &artifacts)?),
                Box::new(as_i64(bytes)),
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
            format!(
                "UPDATE jobs SET state = 'failed', finished_ms = {NOW_MS}, error_kind = $4, error_detail = $5, \
                 stage_seconds = $6, lease_until_ms = NULL WHERE {FENCE}"
            ),
            lease,
            vec![
                Box::new(error.kind.as_str().to_string()),
                Box::new(error.detail.clone()),
                Box::new(json("stage_seconds", stage_seconds)?),
            ],
        )
    }

    fn finish_cancelled(&self, lease: &Lease) -> Result<bool, StoreError> {
        self.fenced(
            format!("UPDATE jobs SET state = 'cancelled', finished_ms = {NOW_MS}, lease_until_ms = NULL WHERE {FENCE}"),
            lease,
            vec![],
        )
    }

    fn cancel_queued(&self, id: JobId) -> Result<bool, StoreError> {
        let n = self.execute(
            format!("UPDATE jobs SET state = 'cancelled', finished_ms = {NOW_MS} WHERE id = $1 AND state = 'queued'"),
            vec![Box::new(id.to_string())],
        )?;
        Ok(n == 1)
    }

    fn request_cancel(&self, id: JobId) -> Result<bool, StoreError> {
        let n = self.execute(
            "UPDATE jobs SET cancel_requested = true WHERE id = $1 AND state = 'running'".into(),
            vec![Box::new(id.to_string())],
        )?;
        Ok(n == 1)
    }

    fn requeue(&self, lease: &Lease) -> Result<bool, StoreError> {
        self.fenced(
            format!(
                "UPDATE jobs SET state = 'queued', stage = NULL, progress = 0, attempts = greatest(attempts - 1, 0), \
                 lease_owner = NULL, lease_until_ms = NULL WHERE {FENCE}"
            ),
            lease,
            vec![],
        )
    }

    fn delete(&self, id: JobId) -> Result<bool, StoreError> {
        Ok(self.execute("DELETE FROM jobs WHERE id = $1".into(), vec![Box::new(id.to_string())])? == 1)
    }

    fn reap_expired(&self, max_attempts: u32, is_dead: &dyn Fn(&str) -> bool) -> Result<Recovery, StoreError> {
        // Candidates first (no lock held while `is_dead` looks at processes),
        // then each one re-checked and changed under its row lock.
        let rows = self.query(
            format!(
                "SELECT id, lease_owner, coalesce(lease_until_ms < {NOW_MS}, true) FROM jobs \
                 WHERE state = 'running' ORDER BY seq"
            ),
            vec![],
        )?;
        let mut gone = Vec::new();
        for r in &rows {
            let id: String = r.try_get(0).map_err(pg)?;
            let owner: Option<String> = r.try_get(1).map_err(pg)?;
            let expired: bool = r.try_get(2).map_err(pg)?;
            let died = owner.as_deref().is_none_or(is_dead);
            if expired || died {
                gone.push((id, owner, died));
            }
        }
        let mut rec = Recovery::default();
        for (id, owner, died) in gone {
            let job = parse_id(id.clone())?;
            let reaped = self.run(move |pool| async move {
                let mut client = pool.get().await.map_err(pg)?;
                let tx = client.transaction().await.map_err(pg)?;
                let row = tx
                    .query_opt(
                        &format!(
                            "SELECT attempts, crashes FROM jobs WHERE id = $1 AND state = 'running' \
                             AND lease_owner IS NOT DISTINCT FROM $2 \
                             AND ($3 OR coalesce(lease_until_ms < {NOW_MS}, true)) FOR UPDATE SKIP LOCKED"
                        ),
                        &[&id, &owner, &died],
                    )
                    .await
                    .map_err(pg)?;
                let Some(row) = row else { return Ok(None) };
                let (attempts, crashes): (i64, i64) =
                    (row.try_get(0).map_err(pg)?, row.try_get::<_, i64>(1).map_err(pg)? + i64::from(died));
                let decision = reap_decision(attempts, crashes, max_attempts, died);
                match &decision {
                    Reaped::Requeue => {
                        tx.execute(
                            "UPDATE jobs SET state = 'queued', stage = NULL, progress = 0, stage_seconds = '{}', \
                             crashes = $2, lease_owner = NULL, lease_until_ms = NULL WHERE id = $1",
                            &[&id, &crashes],
                        )
                        .await
                        .map_err(pg)?;
                        tx.execute("SELECT pg_notify($1, '')", &[&CHANNEL]).await.map_err(pg)?;
                    }
                    Reaped::Fail(kind, detail) => {
                        tx.execute(
                            &format!(
                                "UPDATE jobs SET state = 'failed', finished_ms = {NOW_MS}, error_kind = $2, \
                                 error_detail = $3, crashes = $4, lease_until_ms = NULL WHERE id = $1"
                            ),
                            &[&id, &kind.as_str(), detail, &crashes],
                        )
                        .await
                        .map_err(pg)?;
                    }
                }
                tx.commit().await.map_err(pg)?;
                Ok(Some(decision))
            })?;
            match reaped {
                Some(Reaped::Requeue) => rec.requeued.push(job),
                Some(Reaped::Fail(crate::failure::FailureKind::CrashedServer, _)) => rec.crashed.push(job),
                Some(Reaped::Fail(..)) => rec.failed.push(job),
                None => {}
            }
        }
        Ok(rec)
    }

    fn count_by_state(&self) -> Result<BTreeMap<JobState, u64>, StoreError> {
        let rows = self.query("SELECT state, count(*) FROM jobs GROUP BY state".into(), vec![])?;
        let mut out: BTreeMap<JobState, u64> = JobState::ALL.into_iter().map(|s| (s, 0)).collect();
        for r in &rows {
            let (state, n): (String, i64) = (r.try_get(0).map_err(pg)?, r.try_get(1).map_err(pg)?);
            if let Some(s) = JobState::parse(&state) {
                out.insert(s, u64::try_from(n).unwrap_or(0));
            }
        }
        Ok(out)
    }

    fn queued_count(&self) -> Result<usize, StoreError> {
        let n = self.scalar_i64("SELECT count(*) FROM jobs WHERE state = 'queued'", vec![])?;
        Ok(usize::try_from(n).unwrap_or(0))
    }

    fn owner(&self, id: JobId) -> Result<Option<Option<String>>, StoreError> {
        let rows = self.query("SELECT tenant FROM jobs WHERE id = $1".into(), vec![Box::new(id.to_string())])?;
        rows.first().map(|r| r.try_get(0).map_err(pg)).transpose()
    }

    fn queued_count_of(&self, tenant: &str) -> Result<usize, StoreError> {
        let n = self.scalar_i64(
            "SELECT count(*) FROM jobs WHERE state = 'queued' AND tenant = $1",
            vec![Box::new(tenant.to_string())],
        )?;
        Ok(usize::try_from(n).unwrap_or(0))
    }

    fn stored_bytes(&self, tenant: Option<&str>) -> Result<u64, StoreError> {
        let n = self.scalar_i64(
            "SELECT (coalesce(sum(input_bytes), 0) + coalesce(sum(artifact_bytes), 0))::bigint FROM jobs \
             WHERE $1::text IS NULL OR tenant = $1",
            vec![Box::new(tenant.map(str::to_string))],
        )?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    fn finished_before(&self, cutoff_ms: i64) -> Result<Vec<JobId>, StoreError> {
        let rows = self.query(
            "SELECT id FROM jobs WHERE state IN ('succeeded', 'failed', 'cancelled') AND finished_ms < $1 \
             ORDER BY finished_ms"
                .into(),
            vec![Box::new(cutoff_ms)],
        )?;
        ids_of(&rows)
    }

    fn delete_if_final(&self, id: JobId) -> Result<bool, StoreError> {
        let n = self.execute(
            "DELETE FROM jobs WHERE id = $1 AND state IN ('succeeded', 'failed', 'cancelled')".into(),
            vec![Box::new(id.to_string())],
        )?;
        Ok(n == 1)
    }

    /// A write that changes nothing: a transaction that takes and releases
    /// the migration table's lock (fails on a read-only or unreachable server).
    fn probe_write(&self) -> Result<(), StoreError> {
        self.execute("UPDATE meshatlas_migrations SET version = version WHERE version = 0".into(), vec![]).map(|_| ())
    }

    fn all_ids(&self) -> Result<Vec<String>, StoreError> {
        let rows = self.query("SELECT id FROM jobs".into(), vec![])?;
        rows.iter().map(|r| r.try_get(0).map_err(pg)).collect()
    }

    fn register_worker(&self, name: &str, memory_budget: u64) -> Result<(), StoreError> {
        self.execute(
            format!(
                "INSERT INTO workers (name, memory_budget, last_seen_ms) VALUES ($1, $2, {NOW_MS}) \
                 ON CONFLICT (name) DO UPDATE SET memory_budget = excluded.memory_budget, \
                 last_seen_ms = excluded.last_seen_ms"
            ),
            vec![Box::new(name.to_string()), Box::new(as_i64(memory_budget))],
        )?;
        self.execute(format!("DELETE FROM workers WHERE last_seen_ms < {NOW_MS} - 86400000"), vec![])?;
        Ok(())
    }

    fn largest_worker_budget(&self, within: Duration) -> Result<Option<u64>, StoreError> {
        let rows = self.query(
            format!("SELECT max(memory_budget) FROM workers WHERE last_seen_ms >= {NOW_MS} - $1"),
            vec![Box::new(lease_ms(within))],
        )?;
        let max: Option<i64> = rows.first().map(|r| r.try_get(0)).transpose().map_err(pg)?.flatten();
        Ok(max.map(|b| u64::try_from(b).unwrap_or(0)))
    }

    fn wake_on_new_jobs(&self, wake: Arc<dyn Fn() + Send + Sync>) {
        self.listen(wake);
    }
}

/// Creates a database with a random name on the server of `admin_url` and
/// returns its URL (tests: one database per test).
///
/// # Panics
/// When the server refuses.
#[doc(hidden)]
pub fn create_test_database(admin_url: &str) -> String {
    let name = format!("t_{}", uuid::Uuid::new_v4().simple());
    let url = admin_url.to_string();
    let sql = format!("CREATE DATABASE {name}");
    // On a thread of its own: the caller may be async code.
    std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
        rt.block_on(async move {
            let (client, conn) = tokio_postgres::connect(&url, NoTls).await.expect("connect to MESHATLAS_TEST_PG_URL");
            tokio::spawn(conn);
            client.batch_execute(&sql).await.expect("create a test database");
        });
    })
    .join()
    .expect("create a test database");
    match admin_url.rsplit_once('/') {
        Some((server, _)) if server.contains("//") && !server.ends_with('/') => format!("{server}/{name}"),
        _ => format!("{admin_url}/{name}"),
    }
}

/// A fresh database on the server at `MESHATLAS_TEST_PG_URL` (`.ci/run`
/// starts one), for tests; `None` (the test is skipped, with a note) when
/// the variable is unset outside CI. In CI (`CI` set) an unset variable
/// fails the test, so CI cannot pass by skipping.
///
/// # Panics
/// In CI without the variable, or when the server refuses.
#[doc(hidden)]
pub fn test_database() -> Option<String> {
    let Ok(admin) = std::env::var("MESHATLAS_TEST_PG_URL") else {
        assert!(std::env::var_os("CI").is_none(), "CI must set MESHATLAS_TEST_PG_URL (see .ci/run)");
        eprintln!("MESHATLAS_TEST_PG_URL is unset: PostgreSQL tests skipped (source .ci/services.sh; start_postgres)");
        return None;
    };
    Some(create_test_database(&admin))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::store_conformance as conformance;

    #[test]
    fn conforms_to_the_job_store_contract() {
        let Some(_) = test_database() else { return };
        conformance::run_all(&|| Box::new(PgStore::connect(&test_database().unwrap()).unwrap()));
    }

    #[test]
    fn processes_that_start_at_once_migrate_once() {
        let Some(url) = test_database() else { return };
        let stores: Vec<PgStore> = std::thread::scope(|s| {
            let hs: Vec<_> = (0..4).map(|_| s.spawn(|| PgStore::connect(&url).unwrap())).collect();
            hs.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let n = stores[0].scalar_i64("SELECT count(*) FROM meshatlas_migrations", vec![]).unwrap();
        assert_eq!(n, MIGRATIONS.len() as i64);
    }

    #[test]
    fn an_insert_wakes_a_listener() {
        let Some(url) = test_database() else { return };
        let s = PgStore::connect(&url).unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        let tx = std::sync::Mutex::new(tx);
        s.listen(Arc::new(move || {
            let _ = tx.lock().unwrap().send(());
        }));
        // The listener connects asynchronously: insert until one is heard.
        let heard = (0..50).any(|_| {
            conformance::insert(&s, 100).unwrap();
            rx.recv_timeout(Duration::from_millis(100)).is_ok()
        });
        assert!(heard, "no notification within 5 s");
    }

    #[test]
    fn an_unreachable_server_is_a_clear_error() {
        let err = PgStore::connect("postgres://nobody@127.0.0.1:1/none").err().unwrap();
        assert!(err.to_string().contains("PostgreSQL"), "{err}");
    }
}
