//! The runner: a dispatcher thread that claims queued jobs from the store and
//! runs them on a rayon pool of `workers` threads, a watchdog for the per-job
//! time limit, the heartbeat (progress, lease renewal, cancel requests) and
//! the end-of-job bookkeeping.
//!
//! Concurrency is bounded by claiming at most `workers` jobs at a time; the
//! queue itself is the `queued` rows of the store, so it survives restarts
//! and is shared by every worker process on the same store. Every job runs
//! inside `catch_unwind`: a panic fails that job only.
//!
//! Each attempt writes its artifacts to its own directory `out/<attempt>/`,
//! so a late attempt whose lease was lost (a paused or partitioned worker)
//! cannot overwrite the files of the attempt that replaced it; the winning
//! attempt's record names its directory (`attempts`), and losers' are removed.
//!
//! Memory admission: a job starts only when its peak-memory estimate fits
//! beside the estimates of the running jobs within the memory budget (a job
//! starts anyway when nothing runs: it was admitted at submission). The
//! queue is strict FIFO: when the oldest queued job does not fit, nothing
//! younger starts before it, so a large job waits for the running ones to
//! end but is never overtaken forever by a stream of small ones. A job that
//! crashed the process before runs alone: it starts only when nothing runs,
//! and nothing starts beside it.
//!
//! Lock order: `running` before the store's connection. The dispatcher claims
//! a job and registers it in `running` under one lock, so a concurrent cancel
//! or delete sees the job either queued (in the store) or running (in the map).

use std::collections::{BTreeMap, HashMap};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use tracing::{error, info, warn};

use crate::failure::FailureKind;
use crate::pipeline::media_type_for;
use crate::progress::{Progress, ProgressSink};

use super::artifact_store::{ArtifactLocation, ArtifactStore};
use super::executor::{ExecError, Executor, JobInput, JobOutcome};
use super::metrics::Metrics;
use super::model::{Artifact, JobError, JobId, JobRecord, JobState};
use super::storage;
use super::store::{Heartbeat, JobStore, Lease, ProgressRow, QueueHead, StoreError, StoreLocation};
use super::worker_name::WorkerName;

/// Settings of the job service.
#[derive(Debug, Clone)]
pub struct JobsConfig {
    /// Directory for the database, uploads and artifacts.
    pub data_dir: PathBuf,
    /// Jobs run at the same time. Default 1.
    pub workers: usize,
    /// Threads of the numerical (rayon) pool that the running jobs share:
    /// a job's parallel loops use every thread not busy with another job.
    /// 0 = one per core. At least `workers`. Default 0.
    pub threads: usize,
    /// Most jobs waiting in the queue; submissions beyond get 429. Default 64.
    pub max_queued: usize,
    /// Wall-time limit of one job attempt. Default 1 h.
    pub job_timeout: Duration,
    /// Times a job may be interrupted by a crash before it is failed. Default 3.
    pub max_attempts: u32,
    /// Server-wide triangle cap, applied on top of each job's own. Default 5e6.
    pub max_triangles: usize,
    /// Server-wide cap on the frames stage's `max_tets`, applied on top of
    /// each job's own (the volume mesher's memory follows it). Default 2e6.
    pub max_tets: usize,
    /// Bytes the estimated peak memory of the running jobs may add up to; a
    /// job estimated above it is refused at submission. Default: unlimited
    /// (the CLI sets a fraction of physical memory).
    pub memory_budget: u64,
    /// Least time between two progress writes to the store. Default 250 ms.
    pub progress_interval: Duration,
    /// Stored-bytes and per-tenant limits at submission. Default: none.
    pub quotas: super::quota::Quotas,
    /// Expiry of finished jobs. Default: kept forever.
    pub retention: super::retention::Retention,
    /// Where the job records live. Default: SQLite in `data_dir`.
    pub store: StoreLocation,
    /// Whether this process claims and runs jobs (false: API only). Default true.
    pub run_jobs: bool,
    /// Lease of a claimed job, renewed by its heartbeats; a job whose lease
    /// expires is taken by another worker. Default 30 s.
    pub lease: Duration,
    /// Interval between two heartbeats of a running job (at most a third of
    /// the lease). Default 3 s.
    pub heartbeat: Duration,
    /// Interval between two looks at the queue when nothing woke the
    /// dispatcher (a submission on this process, a job's end or a
    /// PostgreSQL notification wakes it at once). Default 100 ms.
    pub poll_interval: Duration,
    /// Where uploads and artifacts are kept for good. Default: the data directory.
    pub artifacts: ArtifactLocation,
    /// With an S3 artifact store: whether a job's local files stay after it
    /// ends (a process that also serves downloads keeps them, so it does not
    /// remove a file it may be serving; a `worker` drops them). Default true.
    pub keep_local_copies: bool,
}

impl JobsConfig {
    /// Defaults with the given data directory.
    pub fn new(data_dir: impl Into<PathBuf>) -> Self {
        let data_dir = data_dir.into();
        Self {
            data_dir: data_dir.clone(),
            workers: 1,
            threads: 0,
            max_queued: 64,
            job_timeout: Duration::from_secs(3600),
            max_attempts: 3,
            max_triangles: 5_000_000,
            max_tets: 2_000_000,
            memory_budget: u64::MAX,
            progress_interval: Duration::from_millis(250),
            quotas: Default::default(),
            retention: Default::default(),
            store: StoreLocation::Sqlite(data_dir.clone()),
            run_jobs: true,
            lease: Duration::from_secs(30),
            heartbeat: Duration::from_secs(3),
            poll_interval: Duration::from_millis(100),
            artifacts: ArtifactLocation::Local,
            keep_local_copies: true,
        }
    }

    /// Directory of one job (input and `out/`).
    pub fn job_dir(&self, id: JobId) -> PathBuf {
        self.data_dir.join("jobs").join(id.to_string())
    }

    /// Directory of every attempt's artifacts of a job.
    pub fn out_root(&self, id: JobId) -> PathBuf {
        self.job_dir(id).join("out")
    }

    /// Directory of the artifacts of one attempt of a job.
    pub fn attempt_dir(&self, id: JobId, attempt: u32) -> PathBuf {
        self.out_root(id).join(attempt.to_string())
    }

    /// The file of artifact `name` of a job that ended in `attempt`; jobs
    /// stored before attempts had directories have it directly in `out/`.
    pub fn artifact_path(&self, id: JobId, attempt: u32, name: &str) -> PathBuf {
        let dir = self.attempt_dir(id, attempt);
        if dir.is_dir() { dir.join(name) } else { self.out_root(id).join(name) }
    }

    /// The stored upload of a job: `input/<name>` in its directory, under
    /// the (sanitized) client file name so reports show it.
    pub fn input_path(&self, id: JobId, input_name: &str) -> PathBuf {
        self.data_dir.join(Self::input_key(id, input_name))
    }

    /// The artifact-store key of a job's upload (its path under the data directory).
    pub fn input_key(id: JobId, input_name: &str) -> String {
        format!("jobs/{id}/input/{}", super::model::sanitize_file_name(input_name))
    }

    /// The artifact-store key of every object of a job.
    pub fn job_key(id: JobId) -> String {
        format!("jobs/{id}/")
    }

    /// The artifact-store key of the directory of one attempt's artifacts.
    pub fn attempt_key(id: JobId, attempt: u32) -> String {
        format!("jobs/{id}/out/{attempt}")
    }
}

/// Why a running job was asked to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum StopReason {
    /// A client cancelled it; the record stays, state `cancelled`.
    Cancel,
    /// A client deleted it; the record and files go.
    Delete,
    /// It exceeded the time limit; state `failed`, kind `time-limit-exceeded`.
    Timeout,
    /// The server is shutting down; the job goes back to the queue.
    Shutdown,
    /// Its lease was lost (deleted, or taken by another worker after it
    /// expired): nothing may be written, its attempt's files go.
    LeaseLost,
}

/// Progress of a running job as last reported (newer than the store).
#[derive(Debug, Clone)]
pub(crate) struct Live {
    pub stage: String,
    pub fraction: f64,
    pub stage_seconds: BTreeMap<String, f64>,
    stage_started: Instant,
    last_write: Option<Instant>,
}

/// A job a worker is running.
pub(crate) struct RunningJob {
    /// The lease it runs under.
    pub lease: Lease,
    /// When its last heartbeat was written.
    last_beat: Mutex<Instant>,
    /// Its end is being written: a heartbeat that then finds the lease gone
    /// has met the end's own write (or a fenced-out one, which the end
    /// handles), and must not stop or report anything.
    ending: AtomicBool,
    pub cancel: Arc<AtomicBool>,
    reason: Mutex<Option<StopReason>>,
    deadline: Instant,
    pub live: Mutex<Live>,
    /// Its peak-memory estimate, counted against the budget while it runs.
    memory_estimate: u64,
    /// It crashed the process before: nothing runs beside it.
    alone: bool,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl RunningJob {
    /// Seconds since its last heartbeat was written (or since it started).
    pub fn since_last_beat(&self) -> f64 {
        lock(&self.last_beat).elapsed().as_secs_f64()
    }

    fn new(lease: Lease, timeout: Duration, memory_estimate: u64, alone: bool) -> Self {
        let now = Instant::now();
        Self {
            lease,
            last_beat: Mutex::new(now),
            ending: AtomicBool::new(false),
            memory_estimate,
            alone,
            cancel: Arc::new(AtomicBool::new(false)),
            reason: Mutex::new(None),
            deadline: now + timeout,
            live: Mutex::new(Live {
                stage: String::new(),
                fraction: 0.0,
                stage_seconds: BTreeMap::new(),
                stage_started: now,
                last_write: None,
            }),
        }
    }

    /// Asks the job to stop; the first reason wins.
    pub fn stop(&self, why: StopReason) {
        let mut r = lock(&self.reason);
        if r.is_none() {
            *r = Some(why);
        }
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// Why the job was asked to stop, if it was.
    pub fn reason(&self) -> Option<StopReason> {
        *lock(&self.reason)
    }

    /// Per-stage seconds including the stage still running.
    pub fn stage_seconds_now(&self) -> BTreeMap<String, f64> {
        let live = lock(&self.live);
        let mut secs = live.stage_seconds.clone();
        if !live.stage.is_empty() {
            *secs.entry(live.stage.clone()).or_default() += live.stage_started.elapsed().as_secs_f64();
        }
        secs
    }
}

/// State shared by the service handle, the dispatcher and the workers.
pub(crate) struct Inner {
    pub config: JobsConfig,
    pub store: Box<dyn JobStore>,
    /// Where uploads and artifacts are kept for good.
    pub artifacts: Arc<dyn ArtifactStore>,
    /// The name this process holds leases under.
    pub name: WorkerName,
    pub executor: Arc<dyn Executor>,
    pub pool: rayon::ThreadPool,
    pub running: Mutex<HashMap<JobId, Arc<RunningJob>>>,
    pub wake: Condvar,
    pub shutdown: AtomicBool,
    pub metrics: Metrics,
    /// Jobs whose end could not be written yet (storage faults).
    pub unrecorded: Mutex<Vec<storage::Unrecorded>>,
    /// Progress reports waiting for the progress writer.
    pub progress: PendingProgress,
}

/// Progress handed from the jobs' threads to the heartbeat thread
/// ([`heartbeat_loop`]): a commit syncs the database to disk, which here
/// takes milliseconds to a tenth of a second, and a job must not wait for
/// it between two steps. Readers of a running job on this process see its
/// live progress from memory anyway; the stored row is for other processes
/// and restarts.
#[derive(Default)]
pub(crate) struct PendingProgress {
    rows: Mutex<HashMap<JobId, ProgressRow>>,
    wake: Condvar,
}

impl PendingProgress {
    /// Records `row` as job `id`'s latest progress and wakes the writer.
    fn push(&self, id: JobId, row: ProgressRow) {
        lock(&self.rows).insert(id, row);
        self.wake.notify_one();
    }
}

/// The heartbeat: until shutdown, writes every running job's latest
/// progress as it comes and otherwise renews its lease every
/// `config.heartbeat`; a heartbeat that finds the lease lost stops the job
/// ([`StopReason::LeaseLost`]), one that finds a cancel request (made on
/// any process) cancels it.
pub(crate) fn heartbeat_loop(inner: Arc<Inner>) {
    let pending = &inner.progress;
    let mut registered = Instant::now();
    while !inner.shutdown.load(Ordering::Relaxed) {
        if registered.elapsed() >= inner.config.heartbeat {
            // The worker's own heartbeat: alive, with this budget.
            if let Err(e) = inner.store.register_worker(inner.name.as_str(), inner.config.memory_budget) {
                warn!(error = %e, "cannot renew this worker's registration");
            }
            registered = Instant::now();
        }
        let mut rows = {
            let mut rows = lock(&pending.rows);
            if rows.is_empty() {
                rows = match pending.wake.wait_timeout(rows, Duration::from_millis(100)) {
                    Ok((g, _)) => g,
                    Err(p) => p.into_inner().0,
                };
            }
            std::mem::take(&mut *rows)
        };
        let jobs: Vec<Arc<RunningJob>> = inner.running().values().cloned().collect();
        for job in jobs {
            let row = rows.remove(&job.lease.id);
            let due = lock(&job.last_beat).elapsed() >= inner.config.heartbeat;
            if row.is_some() || due {
                beat(&inner, &job, row.as_ref());
            }
        }
    }
}

/// One heartbeat of `job`, acting on what it learns.
fn beat(inner: &Inner, job: &RunningJob, row: Option<&ProgressRow>) {
    let start = Instant::now();
    let written = inner.store.heartbeat(&job.lease, inner.config.lease, row);
    inner.metrics.heartbeat_written(start.elapsed().as_secs_f64());
    match written {
        Ok(Heartbeat::Held { cancel_requested }) => {
            *lock(&job.last_beat) = Instant::now();
            if cancel_requested && job.reason().is_none() {
                info!(job = %job.lease.id, "cancel requested through the store; stopping the job");
                job.stop(StopReason::Cancel);
            }
        }
        Ok(Heartbeat::Lost) if job.ending.load(Ordering::Relaxed) => {}
        Ok(Heartbeat::Lost) => {
            if job.reason().is_none() {
                warn!(job = %job.lease.id, attempt = job.lease.attempt, "the job's lease is lost; stopping it");
            }
            job.stop(StopReason::LeaseLost);
        }
        Err(e) => warn!(job = %job.lease.id, error = %e, "cannot write the heartbeat"),
    }
}

impl Inner {
    pub fn running(&self) -> MutexGuard<'_, HashMap<JobId, Arc<RunningJob>>> {
        lock(&self.running)
    }
}

/// Puts back the jobs whose lease expired or whose owner is a dead process
/// of this machine, logging what it did.
pub(crate) fn reap(inner: &Inner) {
    match inner.store.reap_expired(inner.config.max_attempts, &|owner| inner.name.is_dead(owner)) {
        Ok(r) if r.requeued.is_empty() && r.failed.is_empty() && r.crashed.is_empty() => {}
        Ok(r) => {
            inner.metrics.leases_expired(r.requeued.len() + r.failed.len() + r.crashed.len());
            warn!(
                requeued = r.requeued.len(),
                failed = r.failed.len(),
                crashed = r.crashed.len(),
                "took back jobs whose worker stopped holding them"
            );
        }
        Err(e) => error!(error = %e, "cannot look for expired leases"),
    }
}

/// The dispatcher loop: enforce time limits, take back jobs whose lease
/// expired (every heartbeat interval), start queued jobs while workers are
/// free, sleep until woken (submit, job end, notification) or the poll
/// interval passes.
pub(crate) fn dispatch_loop(inner: Arc<Inner>) {
    let mut running = inner.running();
    let mut last_reap = Instant::now();
    loop {
        if inner.shutdown.load(Ordering::Relaxed) {
            return;
        }
        if last_reap.elapsed() >= inner.config.heartbeat {
            drop(running);
            reap(&inner);
            last_reap = Instant::now();
            running = inner.running();
        }
        let now = Instant::now();
        for (id, job) in running.iter() {
            if now >= job.deadline && job.reason().is_none() {
                warn!(job = %id, "job exceeded its time limit; stopping it");
                job.stop(StopReason::Timeout);
            }
        }
        while running.len() < inner.config.workers {
            let head = match inner.store.queue_head(inner.config.memory_budget) {
                Ok(Some(head)) => head,
                Ok(None) => break,
                Err(e) => {
                    error!(error = %e, "cannot read the queue");
                    break;
                }
            };
            if !may_start(&running, head, inner.config.memory_budget) {
                break;
            }
            match inner.store.claim(head.id, inner.name.as_str(), inner.config.lease) {
                Ok(Some(rec)) => {
                    if head.crashes > 0 {
                        warn!(job = %rec.id, crashes = head.crashes, "running alone a job that crashed the server");
                    }
                    inner.metrics.job_claimed();
                    let lease = Lease { id: rec.id, attempt: rec.attempts, owner: inner.name.shared() };
                    let job = Arc::new(RunningJob::new(
                        lease,
                        inner.config.job_timeout,
                        head.memory_estimate_bytes,
                        head.crashes > 0,
                    ));
                    running.insert(rec.id, job.clone());
                    let inner2 = inner.clone();
                    inner.pool.spawn(move || run_job(&inner2, rec, &job));
                }
                // Cancelled, deleted or claimed elsewhere since it was read: look again.
                Ok(None) => {}
                Err(e) => {
                    error!(error = %e, "cannot claim the next job");
                    break;
                }
            }
        }
        running = match inner.wake.wait_timeout(running, inner.config.poll_interval) {
            Ok((g, _)) => g,
            Err(p) => p.into_inner().0,
        };
    }
}

/// Whether the queue's oldest job may start beside the `running` ones: not
/// beside a job that runs alone, alone itself when it crashed the process
/// before, and only when its estimate fits the `budget` beside theirs.
/// Anything may start when nothing runs.
fn may_start(running: &HashMap<JobId, Arc<RunningJob>>, head: QueueHead, budget: u64) -> bool {
    if running.is_empty() {
        return true;
    }
    if head.crashes > 0 || running.values().any(|j| j.alone) {
        return false;
    }
    let used = running.values().fold(0u64, |sum, j| sum.saturating_add(j.memory_estimate));
    used.saturating_add(head.memory_estimate_bytes) <= budget
}

/// Persists progress of one job, throttled.
struct JobSink {
    inner: Arc<Inner>,
    id: JobId,
    job: Arc<RunningJob>,
}

impl ProgressSink for JobSink {
    fn report(&self, stage: &str, fraction: f64) {
        let now = Instant::now();
        let write = {
            let mut live = lock(&self.job.live);
            let mut force = false;
            if live.stage != stage {
                if !live.stage.is_empty() {
                    let spent = now.duration_since(live.stage_started).as_secs_f64();
                    let prev = live.stage.clone();
                    *live.stage_seconds.entry(prev).or_default() += spent;
                }
                live.stage = stage.to_string();
                live.stage_started = now;
                force = true;
            }
            live.fraction = fraction;
            let due = live.last_write.is_none_or(|t| now.duration_since(t) >= self.inner.config.progress_interval);
            if force || due {
                live.last_write = Some(now);
                Some((live.stage.clone(), live.fraction, live.stage_seconds.clone()))
            } else {
                None
            }
        };
        if let Some(row) = write {
            self.inner.progress.push(self.id, row);
        }
    }
}

/// Checks the outcome's artifacts against the files in `out_dir` (sizes
/// from disk) and adds files the executor wrote but did not list.
fn artifacts_on_disk(out_dir: &Path, listed: &[Artifact]) -> std::io::Result<Vec<Artifact>> {
    let mut by_name: BTreeMap<String, Artifact> = BTreeMap::new();
    for entry in std::fs::read_dir(out_dir)? {
        let entry = entry?;
        let meta = entry.metadata()?;
        let Some(name) = entry.file_name().to_str().map(str::to_string) else { continue };
        if !meta.is_file() {
            continue;
        }
        let media_type = listed
            .iter()
            .find(|a| a.name == name)
            .map(|a| a.media_type.clone())
            .unwrap_or_else(|| media_type_for(&name).to_string());
        by_name.insert(name.clone(), Artifact { name, bytes: meta.len(), media_type });
    }
    for a in listed {
        if !by_name.contains_key(&a.name) {
            warn!(artifact = %a.name, "executor listed an artifact it did not write");
        }
    }
    Ok(by_name.into_values().collect())
}

/// Text of a caught panic payload.
pub(crate) fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "non-string panic payload".to_string()
    }
}

/// Runs one claimed job on a worker thread and records how it ended.
fn run_job(inner: &Arc<Inner>, rec: JobRecord, job: &Arc<RunningJob>) {
    let span = tracing::info_span!("job", id = %rec.id, attempt = rec.attempts);
    let _enter = span.enter();
    let started = Instant::now();
    info!(input = %rec.input_name, bytes = rec.input_bytes, "job started");
    let out_dir = inner.config.attempt_dir(rec.id, rec.attempts);
    remove_other_attempts(&inner.config, rec.id, rec.attempts);
    let prepared = std::fs::remove_dir_all(&out_dir)
        .or_else(|e| if e.kind() == std::io::ErrorKind::NotFound { Ok(()) } else { Err(e) })
        .and_then(|()| std::fs::create_dir_all(&out_dir));
    let result = match prepared {
        Err(e) => {
            error!(error = %e, dir = %out_dir.display(), "cannot prepare the output directory");
            let err = match crate::pipeline::error::storage_kind(&e) {
                Some(kind) => storage::artifact_failure(kind),
                None => JobError::new(FailureKind::InternalError, "the server could not store the job's files"),
            };
            Ok(Err(ExecError::Failed(err)))
        }
        Ok(()) => match fetch_input(inner, &rec) {
            Err(err) => Ok(Err(ExecError::Failed(err))),
            Ok(()) => {
                let input = JobInput {
                    id: rec.id,
                    input: inner.config.input_path(rec.id, &rec.input_name),
                    input_name: rec.input_name.clone(),
                    format: rec.format.clone(),
                    params: rec.params.clone(),
                    out_dir: out_dir.clone(),
                    max_triangles: inner.config.max_triangles,
                    max_tets: inner.config.max_tets,
                };
                let sink = Arc::new(JobSink { inner: inner.clone(), id: rec.id, job: job.clone() });
                let progress = Progress::new(sink, job.cancel.clone());
                let executor = inner.executor.clone();
                std::panic::catch_unwind(AssertUnwindSafe(|| executor.execute(&input, &progress)))
            }
        },
    };
    let live_seconds = job.stage_seconds_now();
    job.ending.store(true, Ordering::Relaxed);
    let final_state = record_result(inner, job, result, &out_dir, live_seconds, started);
    if let Some(state) = final_state {
        info!(state = state.as_str(), seconds = started.elapsed().as_secs_f64(), "job finished");
    }
    if !inner.artifacts.is_local() && !inner.config.keep_local_copies {
        // The bucket holds what was recorded; this worker's copy was scratch.
        remove_job_dir(&inner.config, rec.id);
    }
    inner.running().remove(&rec.id);
    inner.wake.notify_all();
}

/// Makes sure this machine has the job's upload (fetched from the artifact
/// store when the data directory lacks it).
fn fetch_input(inner: &Inner, rec: &JobRecord) -> Result<(), JobError> {
    let key = JobsConfig::input_key(rec.id, &rec.input_name);
    match inner.artifacts.fetch(&inner.config.data_dir, &key) {
        Ok(true) => Ok(()),
        Ok(false) => {
            error!(key = %key, "the job's upload is missing from the artifact store");
            Err(JobError::new(FailureKind::InternalError, "the server lost the job's upload"))
        }
        Err(e) => {
            error!(error = %e, "cannot fetch the job's upload");
            Err(storage::artifact_failure(FailureKind::StorageUnavailable))
        }
    }
}

/// Puts every artifact of the attempt of `lease` into the artifact store,
/// under the attempt's key.
fn upload_artifacts(
    inner: &Inner,
    lease: &Lease,
    artifacts: &[Artifact],
) -> Result<(), super::artifact_store::ArtifactError> {
    let dir = JobsConfig::attempt_key(lease.id, lease.attempt);
    for a in artifacts {
        inner.artifacts.put(&inner.config.data_dir, &format!("{dir}/{}", a.name))?;
    }
    Ok(())
}

/// Removes a job's objects from the artifact store (all of them, or one
/// attempt's), logging a failure: the record is what counts, and a sweep of
/// the bucket can remove what is left.
fn delete_objects(inner: &Inner, prefix: &str, keep: Option<&str>) {
    if let Err(e) = inner.artifacts.delete_prefix(prefix, keep) {
        warn!(prefix, error = %e, "cannot remove objects from the artifact store");
    }
}

/// How a job ended, as it is to be written to the store.
enum Ending {
    /// Deleted by a client: nothing to write (record and files go).
    Deleted,
    /// Its lease was lost: nothing may be written; its attempt's files go.
    Abandoned,
    /// Server shutdown: back to the queue.
    Requeue,
    /// Cancelled by a client.
    Cancelled,
    /// Failed with this error.
    Failed(JobError, BTreeMap<String, f64>),
    /// Succeeded with this summary, timings and artifacts.
    Succeeded(serde_json::Value, BTreeMap<String, f64>, Vec<Artifact>),
}

/// Stores the end of a job; returns its final state (`None` when it was
/// deleted or put back in the queue). Metrics are counted before the final
/// state is stored, so a client that sees the state also sees the metrics.
/// A store that does not write is retried (see [`record_ending`]).
fn record_result(
    inner: &Arc<Inner>,
    job: &RunningJob,
    result: std::thread::Result<Result<JobOutcome, ExecError>>,
    out_dir: &Path,
    live_seconds: BTreeMap<String, f64>,
    started: Instant,
) -> Option<JobState> {
    let ending = ending_of(inner, job.reason(), result, out_dir, live_seconds);
    let state = match &ending {
        Ending::Cancelled => Some(JobState::Cancelled),
        Ending::Failed(..) => Some(JobState::Failed),
        Ending::Succeeded(..) => Some(JobState::Succeeded),
        Ending::Deleted | Ending::Abandoned | Ending::Requeue => None,
    };
    if let (Some(state), Ending::Failed(_, secs) | Ending::Succeeded(_, secs, _)) = (state, &ending) {
        inner.metrics.job_finished(state, started.elapsed().as_secs_f64(), secs);
    } else if let Some(state) = state {
        inner.metrics.job_finished(state, started.elapsed().as_secs_f64(), &job.stage_seconds_now());
    }
    record_ending(inner, job, ending)
}

/// Decides how a job ended from its stop reason and its executor's result.
/// A time-limited job's partial artifacts are removed here; a job whose
/// files could not be written (full or read-only storage) fails with the
/// storage kind.
fn ending_of(
    inner: &Arc<Inner>,
    reason: Option<StopReason>,
    result: std::thread::Result<Result<JobOutcome, ExecError>>,
    out_dir: &Path,
    live_seconds: BTreeMap<String, f64>,
) -> Ending {
    match (reason, result) {
        (Some(StopReason::Delete), _) => Ending::Deleted,
        (Some(StopReason::LeaseLost), _) => Ending::Abandoned,
        (Some(StopReason::Shutdown), _) => Ending::Requeue,
        (Some(StopReason::Cancel), _) => Ending::Cancelled,
        (_, Err(payload)) => {
            inner.metrics.job_panicked();
            error!(panic = %panic_message(payload.as_ref()), "job panicked");
            Ending::Failed(
                JobError::new(
                    FailureKind::InternalError,
                    "the job stopped because of an internal error; it has been logged",
                ),
                live_seconds,
            )
        }
        (Some(StopReason::Timeout), Ok(Err(_))) => {
            remove_partial_artifacts(out_dir);
            let limit = inner.config.job_timeout.as_secs_f64();
            Ending::Failed(
                JobError::new(
                    FailureKind::TimeLimitExceeded,
                    format!("the job ran longer than the server's limit of {limit} s and was stopped"),
                ),
                live_seconds,
            )
        }
        (_, Ok(Err(ExecError::Failed(e)))) => {
            info!(kind = %e.kind, detail = %e.detail, "job failed");
            let e = if matches!(e.kind, FailureKind::StorageFull | FailureKind::StorageUnavailable) {
                storage::artifact_failure(e.kind)
            } else {
                e
            };
            Ending::Failed(e, live_seconds)
        }
        (None, Ok(Err(ExecError::Cancelled))) => Ending::Failed(
            JobError::new(FailureKind::InternalError, "the job stopped without being asked to"),
            live_seconds,
        ),
        (_, Ok(Ok(outcome))) => match artifacts_on_disk(out_dir, &outcome.artifacts) {
            Ok(artifacts) => {
                let mut secs = outcome.stage_seconds.clone();
                for (k, v) in live_seconds {
                    secs.entry(k).or_insert(v);
                }
                Ending::Succeeded(outcome.summary, secs, artifacts)
            }
            Err(e) => {
                error!(error = %e, "cannot list the job's artifacts");
                let err = match crate::pipeline::error::storage_kind(&e) {
                    Some(kind) => storage::artifact_failure(kind),
                    None => JobError::new(FailureKind::InternalError, "the server could not list the job's files"),
                };
                Ending::Failed(err, live_seconds)
            }
        },
    }
}

/// Writes `ending` to the store once, fenced by `lease`; the final state,
/// `None` when there is none (deleted, abandoned, requeued, or the job no
/// longer runs under this lease). A fenced write that changes nothing
/// removes this attempt's files, or the whole job's when its record is gone.
fn write_ending(inner: &Inner, lease: &Lease, ending: &Ending) -> Result<Option<JobState>, StoreError> {
    let store = &inner.store;
    let written = match ending {
        Ending::Deleted => {
            remove_job_dir(&inner.config, lease.id);
            delete_objects(inner, &JobsConfig::job_key(lease.id), None);
            return Ok(None);
        }
        Ending::Abandoned => false,
        Ending::Requeue => {
            store.requeue(lease)?;
            return Ok(None);
        }
        Ending::Cancelled => store.finish_cancelled(lease)?,
        Ending::Failed(e, secs) => store.finish_failed(lease, e, secs)?,
        Ending::Succeeded(summary, secs, artifacts) => {
            // Uploaded before the record lists them; a failed upload fails the job.
            if let Err(e) = upload_artifacts(inner, lease, artifacts) {
                error!(error = %e, "cannot store the job's artifacts");
                let failed = Ending::Failed(storage::artifact_failure(FailureKind::StorageUnavailable), secs.clone());
                return write_ending(inner, lease, &failed);
            }
            store.finish_succeeded(lease, summary, secs, artifacts)?
        }
    };
    if written {
        if matches!(ending, Ending::Succeeded(..)) {
            remove_other_attempts(&inner.config, lease.id, lease.attempt);
            let keep = JobsConfig::attempt_key(lease.id, lease.attempt);
            delete_objects(inner, &format!("jobs/{}/out/", lease.id), Some(&keep));
        }
        return Ok(Some(match ending {
            Ending::Cancelled => JobState::Cancelled,
            Ending::Failed(..) => JobState::Failed,
            _ => JobState::Succeeded,
        }));
    }
    if store.get(lease.id)?.is_none() {
        remove_job_dir(&inner.config, lease.id);
        delete_objects(inner, &JobsConfig::job_key(lease.id), None);
    } else {
        info!(attempt = lease.attempt, "another attempt holds the job; this attempt's files are removed");
        remove_partial_artifacts(&inner.config.attempt_dir(lease.id, lease.attempt));
        delete_objects(inner, &format!("{}/", JobsConfig::attempt_key(lease.id, lease.attempt)), None);
    }
    Ok(None)
}

/// Writes `ending`, retrying with backoff for [`storage::RECORD_RETRY`]
/// while the store fails (a full or read-only disk); a cancel or delete
/// that arrives meanwhile replaces the ending. A job still unrecorded then
/// goes to the unrecorded list, to be failed with the storage kind by
/// [`flush_unrecorded`] once the store writes again.
fn record_ending(inner: &Inner, job: &RunningJob, mut ending: Ending) -> Option<JobState> {
    let start = Instant::now();
    let mut pause = storage::FIRST_BACKOFF;
    loop {
        match (job.reason(), &ending) {
            (_, Ending::Deleted | Ending::Abandoned | Ending::Requeue) => {}
            (Some(StopReason::Delete), _) => ending = Ending::Deleted,
            (Some(StopReason::LeaseLost), _) => ending = Ending::Abandoned,
            (Some(StopReason::Cancel), _) => ending = Ending::Cancelled,
            _ => {}
        }
        let err = match write_ending(inner, &job.lease, &ending) {
            Ok(state) => return state,
            Err(e) => e,
        };
        if matches!(ending, Ending::Requeue) && inner.shutdown.load(Ordering::Relaxed) {
            // Left `running`: its lease expires and a worker takes it back.
            error!(error = %err, "cannot put the job back in the queue");
            return None;
        }
        if start.elapsed() >= storage::RECORD_RETRY || inner.shutdown.load(Ordering::Relaxed) {
            let kind = storage::store_error_kind(&err).unwrap_or(FailureKind::StorageUnavailable);
            error!(error = %err, kind = kind.as_str(), "cannot record the end of the job; it waits in the unrecorded list");
            let secs = match &ending {
                Ending::Failed(_, s) | Ending::Succeeded(_, s, _) => s.clone(),
                _ => job.stage_seconds_now(),
            };
            lock(&inner.unrecorded).push(storage::Unrecorded {
                lease: job.lease.clone(),
                error: storage::unrecorded_failure(kind),
                stage_seconds: secs,
                cancel: matches!(ending, Ending::Cancelled),
                delete: matches!(ending, Ending::Deleted),
            });
            return None;
        }
        warn!(error = %err, retry_in_ms = pause.as_millis() as u64, "cannot record the end of the job; retrying");
        std::thread::sleep(pause);
        pause = (pause * 2).min(storage::MAX_BACKOFF);
    }
}

/// Tries once to record every job of the unrecorded list (`failed` with its
/// storage kind, or as the client asked meanwhile); keeps those the store
/// still refuses. Called by the recorder thread.
pub(crate) fn flush_unrecorded(inner: &Inner) {
    let pending: Vec<storage::Unrecorded> = std::mem::take(&mut *lock(&inner.unrecorded));
    let mut keep = Vec::new();
    for u in pending {
        let ending = if u.delete {
            Ending::Deleted
        } else if u.cancel {
            Ending::Cancelled
        } else {
            Ending::Failed(u.error.clone(), u.stage_seconds.clone())
        };
        let id = u.lease.id;
        let written = match ending {
            Ending::Deleted => inner.store.delete(id).map(|_| remove_job_dir(&inner.config, id)),
            ref e => write_ending(inner, &u.lease, e).map(|_| ()),
        };
        match written {
            Ok(()) => {
                info!(job = %id, kind = %u.error.kind, "recorded the end of a job that could not be stored before")
            }
            Err(_) => keep.push(u),
        }
    }
    lock(&inner.unrecorded).extend(keep);
}

/// Marks a job of the unrecorded list for cancellation or deletion and
/// tries to record it at once. Returns false when the job is not in the list.
pub(crate) fn stop_unrecorded(inner: &Inner, id: JobId, why: StopReason) -> bool {
    {
        let mut list = lock(&inner.unrecorded);
        let Some(u) = list.iter_mut().find(|u| u.lease.id == id) else { return false };
        match why {
            StopReason::Delete => u.delete = true,
            StopReason::Cancel => u.cancel = true,
            _ => {}
        }
    }
    flush_unrecorded(inner);
    true
}

/// The recorder thread: flushes the unrecorded list until shutdown.
pub(crate) fn recorder_loop(inner: Arc<Inner>) {
    while !inner.shutdown.load(Ordering::Relaxed) {
        std::thread::sleep(storage::FLUSH_INTERVAL);
        if !lock(&inner.unrecorded).is_empty() {
            flush_unrecorded(&inner);
        }
    }
}

/// Removes the files a stopped job left in its output directory (a job
/// failed by the time limit keeps no partial artifacts).
fn remove_partial_artifacts(out_dir: &Path) {
    if let Err(e) = std::fs::remove_dir_all(out_dir)
        && e.kind() != std::io::ErrorKind::NotFound
    {
        warn!(dir = %out_dir.display(), error = %e, "cannot remove the partial artifacts of a stopped job");
    }
}

/// Removes the artifact directories of a job's attempts other than `keep`
/// (and artifacts stored directly in `out/` before attempts had directories).
fn remove_other_attempts(config: &JobsConfig, id: JobId, keep: u32) {
    let Ok(entries) = std::fs::read_dir(config.out_root(id)) else { return };
    let keep = keep.to_string();
    for entry in entries.flatten() {
        if entry.file_name().to_str() == Some(keep.as_str()) {
            continue;
        }
        let path = entry.path();
        let removed = if path.is_dir() { std::fs::remove_dir_all(&path) } else { std::fs::remove_file(&path) };
        if let Err(e) = removed
            && e.kind() != std::io::ErrorKind::NotFound
        {
            warn!(path = %path.display(), error = %e, "cannot remove another attempt's artifacts");
        }
    }
}

/// Removes a job's directory, logging failures other than "not there".
pub(crate) fn remove_job_dir(config: &JobsConfig, id: JobId) {
    let dir = config.job_dir(id);
    if let Err(e) = std::fs::remove_dir_all(&dir)
        && e.kind() != std::io::ErrorKind::NotFound
    {
        warn!(dir = %dir.display(), error = %e, "cannot remove job directory");
    }
}

/// Removes a job's directory like [`remove_job_dir`]; returns what is left
/// of it (paths relative to the data directory, at most 100).
pub(crate) fn remove_job_dir_reporting(config: &JobsConfig, id: JobId) -> Vec<String> {
    remove_job_dir(config, id);
    let mut left = Vec::new();
    let mut stack = vec![config.job_dir(id)];
    while let Some(p) = stack.pop() {
        if left.len() >= 100 || std::fs::symlink_metadata(&p).is_err() {
            continue;
        }
        if let Ok(rel) = p.strip_prefix(&config.data_dir) {
            left.push(rel.to_string_lossy().into_owned());
        }
        if let Ok(rd) = std::fs::read_dir(&p) {
            stack.extend(rd.flatten().map(|e| e.path()));
        }
    }
    left.sort();
    left
}
