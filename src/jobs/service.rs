//! [`JobService`]: the async face of the job machinery used by the HTTP
//! layer. Every store or file operation runs on tokio's blocking pool, and
//! numerical work runs on the rayon pool, so the async runtime never blocks.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use tracing::{info, warn};

use super::artifact_store::ArtifactStore;
use super::executor::Executor;
use super::metrics::{Gauges, Metrics};
use super::model::{JobId, JobPage, JobRecord, JobState, NewJob};
use super::runner::{Inner, JobsConfig, StopReason, dispatch_loop, panic_message, remove_job_dir};
use super::store::{JobStore, NewRow, StoreError, StoreLocation};
use super::worker_name::WorkerName;

/// Age below which a job directory without a record, or a file in `tmp/`,
/// may still belong to a submission in progress on another process sharing
/// the data directory, so start-up cleaning leaves it.
const IN_FLIGHT_AGE: Duration = Duration::from_secs(600);
/// Lifetime of a presigned artifact URL (`?redirect=1`), seconds.
pub const PRESIGNED_URL_SECS: u64 = 300;

/// The artifact `name` a finished job lists: the job's attempt count, the
/// artifact and its key in the artifact store.
fn listed_artifact(inner: &Inner, id: JobId, name: String) -> Result<(u32, super::model::Artifact, String), JobsError> {
    let rec = inner.store.get(id)?.ok_or(JobsError::NotFound(id))?;
    let art = rec.artifacts.iter().find(|a| a.name == name).cloned().ok_or(JobsError::ArtifactNotFound { id, name })?;
    let key = format!("{}/{}", JobsConfig::attempt_key(id, rec.attempts), art.name);
    Ok((rec.attempts, art, key))
}

/// How long cancel and delete wait for a running job to stop before they
/// answer that the stop is pending (the stages check for cancellation
/// every few milliseconds, so a second is ample).
pub const STOP_WAIT: Duration = Duration::from_secs(1);

/// Errors of the job service.
#[derive(Debug, thiserror::Error)]
pub enum JobsError {
    /// The job store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A file operation in the data directory failed.
    #[error("{what}: {source}")]
    Io {
        /// What was being done, with the path.
        what: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The queue already holds the configured maximum of jobs.
    #[error("the job queue is full ({max_queued} jobs waiting); retry later")]
    QueueFull {
        /// The configured queue length.
        max_queued: usize,
    },
    /// The job's estimated peak memory exceeds the server's budget.
    #[error(
        "the job's estimated peak memory of {estimated_bytes} bytes exceeds this server's memory budget of \
         {budget_bytes} bytes; lower its sizes (fewer triangles, a smaller frames.max_tets) or its stages"
    )]
    MemoryBudgetExceeded {
        /// The estimate.
        estimated_bytes: u64,
        /// The budget (`--memory-budget`).
        budget_bytes: u64,
    },
    /// The tenant already has its maximum of queued jobs.
    #[error("this tenant already has {max_queued} queued jobs; retry later")]
    TenantQueueFull {
        /// The per-tenant queue length.
        max_queued: usize,
    },
    /// Storing the upload would exceed a stored-bytes quota.
    #[error("the {} storage quota of {max_bytes} bytes would be exceeded", if *tenant { "tenant's" } else { "server's" })]
    QuotaExceeded {
        /// The tenant's quota (true) or the server-wide one (false).
        tenant: bool,
        /// The quota in bytes.
        max_bytes: u64,
    },
    /// No job with this id.
    #[error("job {0} does not exist")]
    NotFound(JobId),
    /// The job has no artifact of this name.
    #[error("job {id} has no artifact named `{name}`")]
    ArtifactNotFound {
        /// The job.
        id: JobId,
        /// The requested name.
        name: String,
    },
    /// The artifact store (an S3 bucket) failed.
    #[error(transparent)]
    Artifacts(#[from] super::artifact_store::ArtifactError),
    /// A worker or blocking task failed unexpectedly.
    #[error("internal error: {0}")]
    Internal(String),
}

fn io_err(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> JobsError {
    let what = what.into();
    move |source| JobsError::Io { what, source }
}

/// What [`JobService::delete`] did.
#[derive(Debug, Clone, Default)]
pub struct Deletion {
    /// The job as it was, when it was still running after the wait: its
    /// record is gone, its files go when it stops.
    pub pending: Option<JobRecord>,
    /// Paths (relative to the data directory) that could not be removed.
    pub not_removed: Vec<String>,
}

/// Threads of the numerical pool: `asked`, or one per core when 0, and never
/// fewer than the jobs that run at once (each job holds one thread while it
/// runs; its parallel loops borrow the idle ones).
fn pool_threads(asked: usize, workers: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    if asked == 0 { cores } else { asked }.max(workers)
}

/// Handle to the durable job service; cheap to clone.
#[derive(Clone)]
pub struct JobService {
    inner: Arc<Inner>,
    /// Held from the quota check to the insert of a submission, so two
    /// concurrent uploads cannot both take the last free quota.
    admission: Arc<Mutex<()>>,
}

impl JobService {
    /// Opens the store in `config.data_dir`, recovers jobs interrupted by a
    /// crash, removes orphaned files and starts the dispatcher and workers.
    ///
    /// # Errors
    /// [`JobsError`] when the data directory or database cannot be opened.
    pub fn start(config: JobsConfig, executor: Arc<dyn Executor>) -> Result<Self, JobsError> {
        let jobs_dir = config.data_dir.join("jobs");
        std::fs::create_dir_all(&jobs_dir).map_err(io_err(format!("cannot create {}", jobs_dir.display())))?;
        let tmp = config.data_dir.join("tmp");
        std::fs::create_dir_all(&tmp).map_err(io_err(format!("cannot create {}", tmp.display())))?;
        remove_old_entries(&tmp, IN_FLIGHT_AGE, |_| true).map_err(io_err(format!("cannot clean {}", tmp.display())))?;
        let store = open_store(&config.store)?;
        let artifacts = super::artifact_store::open(&config.artifacts)?;
        let name = WorkerName::of_this_process();
        let recovery = store.reap_expired(config.max_attempts, &|owner| name.is_dead(owner))?;
        if !recovery.requeued.is_empty() || !recovery.failed.is_empty() || !recovery.crashed.is_empty() {
            warn!(
                requeued = recovery.requeued.len(),
                failed = recovery.failed.len(),
                crashed = recovery.crashed.len(),
                "recovered interrupted jobs"
            );
        }
        remove_orphans(&*store, &jobs_dir)?;
        remove_orphan_objects(&*store, &*artifacts, IN_FLIGHT_AGE);
        let workers = config.workers.max(1);
        let threads = pool_threads(config.threads, workers);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("meshatlas-worker-{i}"))
            .panic_handler(|p| tracing::error!(panic = %panic_message(p.as_ref()), "panic escaped a job"))
            .build()
            .map_err(|e| JobsError::Internal(format!("cannot build the worker pool: {e}")))?;
        let inner = Arc::new(Inner {
            config: JobsConfig { workers, threads, ..config },
            store,
            artifacts,
            name,
            executor,
            pool,
            running: Mutex::new(Default::default()),
            wake: Condvar::new(),
            shutdown: AtomicBool::new(false),
            metrics: Metrics::default(),
            unrecorded: Mutex::new(Vec::new()),
            progress: Default::default(),
        });
        if inner.config.run_jobs {
            start_worker_threads(&inner)?;
        }
        if let Some(max_age) = inner.config.retention.max_age {
            let r = inner.clone();
            std::thread::Builder::new()
                .name("meshatlas-retention".into())
                .spawn(move || super::retention::retention_loop(r, max_age))
                .map_err(|e| JobsError::Internal(format!("cannot start the retention sweep: {e}")))?;
        }
        info!(
            data_dir = %inner.config.data_dir.display(),
            store = %inner.config.store.redacted(),
            name = inner.name.as_str(),
            run_jobs = inner.config.run_jobs,
            workers,
            threads,
            "job service started"
        );
        Ok(Self { inner, admission: Arc::new(Mutex::new(())) })
    }

    /// The configuration in force.
    pub fn config(&self) -> &JobsConfig {
        &self.inner.config
    }

    async fn blocking<T: Send + 'static>(
        &self,
        f: impl FnOnce(&Arc<Inner>) -> Result<T, JobsError> + Send + 'static,
    ) -> Result<T, JobsError> {
        let inner = self.inner.clone();
        tokio::task::spawn_blocking(move || f(&inner))
            .await
            .map_err(|e| JobsError::Internal(format!("blocking task failed: {e}")))?
    }

    /// A fresh path under the data directory to stream an upload into.
    pub fn upload_path(&self) -> PathBuf {
        self.inner.config.data_dir.join("tmp").join(format!("upload-{}.part", uuid::Uuid::new_v4().simple()))
    }

    /// A transfer of job `id`'s input, named `input_name` by the client,
    /// straight into the artifact store while the upload arrives; `None`
    /// when the data directory is the store. [`NewJob::input_stored`] then
    /// tells [`JobService::submit`] not to put the file a second time.
    pub fn stream_input(&self, id: JobId, input_name: &str) -> Option<super::artifact_store::StreamingPut> {
        self.inner.artifacts.stream_put(&JobsConfig::input_key(id, input_name))
    }

    /// Removes, in the background, the objects an upload of job `id` put
    /// into the artifact store before the submission was refused (the
    /// start-up sweep of orphans is the backstop when this fails).
    pub fn forget_streamed_input(&self, id: JobId) {
        let inner = self.inner.clone();
        if let Ok(rt) = tokio::runtime::Handle::try_current() {
            rt.spawn_blocking(move || forget_upload(&inner, id));
        } else {
            forget_upload(&inner, id);
        }
    }

    /// True when the queue can take another job (checked before an upload is
    /// read; [`JobService::submit`] checks again atomically).
    ///
    /// # Errors
    /// [`JobsError::Store`] on database failure.
    pub async fn has_queue_room(&self) -> Result<bool, JobsError> {
        self.blocking(|i| Ok(i.store.queued_count()? < i.config.max_queued)).await
    }

    /// Checks the stored-bytes and per-tenant limits for an upload of
    /// `incoming` bytes by `tenant` (before it is read;
    /// [`JobService::submit`] checks again with the real size).
    ///
    /// # Errors
    /// [`JobsError::TenantQueueFull`], [`JobsError::QuotaExceeded`], or
    /// [`JobsError::Store`] on database failure.
    pub async fn check_admission(&self, tenant: Option<String>, incoming: u64) -> Result<(), JobsError> {
        self.blocking(move |i| super::quota::check_admission(&*i.store, &i.config.quotas, tenant.as_deref(), incoming))
            .await
    }

    /// Succeeds when `tenant` (`None`: authentication off) may see job `id`;
    /// a job of another tenant is [`JobsError::NotFound`], like a missing one.
    ///
    /// # Errors
    /// [`JobsError::NotFound`], or [`JobsError::Store`] on database failure.
    pub async fn check_visible(&self, id: JobId, tenant: Option<String>) -> Result<(), JobsError> {
        let Some(tenant) = tenant else { return Ok(()) };
        self.blocking(move |inner| match inner.store.owner(id)? {
            Some(Some(owner)) if owner == tenant => Ok(()),
            _ => Err(JobsError::NotFound(id)),
        })
        .await
    }

    /// Moves the upload into a new job directory and queues the job.
    ///
    /// # Errors
    /// [`JobsError::QueueFull`] when the queue is full,
    /// [`JobsError::TenantQueueFull`]/[`JobsError::QuotaExceeded`] over a
    /// limit (the upload is removed), [`JobsError::Io`]/[`JobsError::Store`]
    /// on storage failure.
    pub async fn submit(&self, new: NewJob) -> Result<JobRecord, JobsError> {
        let admission = self.admission.clone();
        self.blocking(move |inner| {
            let _admitted = admission.lock().unwrap_or_else(|p| p.into_inner());
            let quotas = &inner.config.quotas;
            let id = new.id;
            if let Err(e) = super::quota::check_admission(&*inner.store, quotas, new.tenant.as_deref(), new.input_bytes)
            {
                let _ = std::fs::remove_file(&new.upload_path);
                if new.input_stored {
                    forget_upload(inner, id);
                }
                return Err(e);
            }
            let dir = inner.config.job_dir(id);
            let input_name = super::model::sanitize_file_name(&new.input_name);
            let input_path = inner.config.input_path(id, &input_name);
            let cleanup = |inner: &Inner| {
                let _ = std::fs::remove_file(&new.upload_path);
                remove_job_dir(&inner.config, id);
                if new.input_stored {
                    forget_upload(inner, id);
                }
            };
            let estimate = match memory_estimate(&inner.config, &new) {
                Ok(bytes) if bytes <= inner.config.memory_budget => bytes,
                Ok(bytes) => {
                    cleanup(inner);
                    return Err(JobsError::MemoryBudgetExceeded {
                        estimated_bytes: bytes,
                        budget_bytes: inner.config.memory_budget,
                    });
                }
                Err(e) => {
                    cleanup(inner);
                    return Err(e);
                }
            };
            let moved = std::fs::create_dir_all(dir.join("input"))
                .and_then(|()| std::fs::rename(&new.upload_path, &input_path))
                .map_err(io_err(format!("cannot store the upload in {}", dir.display())));
            if let Err(e) = moved {
                cleanup(inner);
                return Err(e);
            }
            let row = NewRow {
                id,
                input_name: &input_name,
                input_bytes: new.input_bytes,
                format: new.format.as_deref(),
                params: &new.params,
                memory_estimate_bytes: estimate,
                tenant: new.tenant.as_deref(),
            };
            if !new.input_stored
                && let Err(e) = inner.artifacts.put(&inner.config.data_dir, &JobsConfig::input_key(id, &input_name))
            {
                cleanup(inner);
                return Err(e.into());
            }
            let rec = inner.store.insert_queued(&row, inner.config.max_queued);
            if !inner.artifacts.is_local() && !inner.config.run_jobs && matches!(rec, Ok(Some(_))) {
                // The bucket has it; the worker that claims the job fetches it.
                remove_job_dir(&inner.config, id);
            }
            match rec {
                Ok(Some(rec)) => {
                    inner.wake.notify_all();
                    info!(job = %id, input = %input_name, bytes = new.input_bytes, "job queued");
                    Ok(rec)
                }
                Ok(None) => {
                    cleanup(inner);
                    forget_upload(inner, id);
                    Err(JobsError::QueueFull { max_queued: inner.config.max_queued })
                }
                Err(e) => {
                    cleanup(inner);
                    forget_upload(inner, id);
                    Err(e.into())
                }
            }
        })
        .await
    }

    /// The job with `id`, with live progress for a running job.
    ///
    /// # Errors
    /// [`JobsError::NotFound`], or [`JobsError::Store`] on database failure.
    pub async fn get(&self, id: JobId) -> Result<JobRecord, JobsError> {
        self.blocking(move |inner| get_live(inner, id)).await
    }

    /// Up to `limit` jobs older than `cursor`, newest first; only
    /// `tenant`'s jobs when a tenant is given.
    ///
    /// # Errors
    /// [`JobsError::Store`] on database failure.
    pub async fn list(&self, limit: usize, cursor: Option<i64>, tenant: Option<String>) -> Result<JobPage, JobsError> {
        self.blocking(move |inner| {
            let mut page = inner.store.list(limit, cursor, tenant.as_deref())?;
            {
                let running = inner.running();
                for rec in &mut page.jobs {
                    if let Some(job) = running.get(&rec.id) {
                        overlay_live(rec, job);
                    }
                }
            }
            annotate_queued(inner, &mut page.jobs)?;
            Ok(page)
        })
        .await
    }

    /// Asks a job to stop for `why`. A job running here is told at once; one
    /// running on another worker learns it at its next heartbeat (a cancel
    /// flag, or for a delete its record gone); a queued job is cancelled (or
    /// deleted) directly in the store.
    fn stop(inner: &Inner, id: JobId, why: StopReason) -> Result<Where, JobsError> {
        let running = inner.running();
        if let Some(job) = running.get(&id) {
            job.stop(why);
            return Ok(Where::Here);
        }
        drop(running);
        if super::runner::stop_unrecorded(inner, id, why) {
            return Ok(Where::Stopped);
        }
        let rec = inner.store.get(id)?.ok_or(JobsError::NotFound(id))?;
        match why {
            StopReason::Delete => {
                if !inner.store.delete(id)? {
                    return Err(JobsError::NotFound(id));
                }
                if rec.state == JobState::Running {
                    return Ok(Where::Elsewhere(Box::new(rec)));
                }
            }
            _ => {
                if !inner.store.cancel_queued(id)? && inner.store.request_cancel(id)? {
                    return Ok(Where::Elsewhere(Box::new(rec)));
                }
            }
        }
        Ok(Where::Stopped)
    }

    /// Waits up to [`STOP_WAIT`] for job `id` to stop: here, until it leaves
    /// the running map; elsewhere, until its record leaves `running`.
    async fn wait_stopped(&self, id: JobId, at: &Where) {
        let start = Instant::now();
        while start.elapsed() < STOP_WAIT {
            let stopped = match at {
                Where::Here => !self.inner.running().contains_key(&id),
                Where::Elsewhere(_) => self
                    .blocking(move |inner| Ok(inner.store.get(id)?.is_none_or(|r| r.state != JobState::Running)))
                    .await
                    .unwrap_or(true),
                Where::Stopped => true,
            };
            if stopped {
                return;
            }
            tokio::time::sleep(Duration::from_millis(if matches!(at, Where::Here) { 10 } else { 100 })).await;
        }
    }

    /// Cancels a queued or running job (a running one stops at its next
    /// progress check, or its worker's next heartbeat when it runs on
    /// another process; waited for up to [`STOP_WAIT`]). A finished job is
    /// left as it is. Returns the job as it is afterwards: still `running`
    /// with `stop_requested` when it did not stop within the wait.
    ///
    /// # Errors
    /// [`JobsError::NotFound`], or [`JobsError::Store`] on database failure.
    pub async fn cancel(&self, id: JobId) -> Result<JobRecord, JobsError> {
        let at = self.blocking(move |inner| Self::stop(inner, id, StopReason::Cancel)).await?;
        self.wait_stopped(id, &at).await;
        info!(job = %id, "job cancelled");
        let mut rec = self.get(id).await?;
        if matches!(at, Where::Elsewhere(_)) && rec.state == JobState::Running {
            rec.stop_requested = true;
        }
        Ok(rec)
    }

    /// Cancels the job if needed and removes its record and files. Returns
    /// what happened: the job as it was when it had not stopped within
    /// [`STOP_WAIT`] (its files go when it stops), and the paths (relative to
    /// the data directory) that could not be removed.
    ///
    /// # Errors
    /// [`JobsError::NotFound`], or storage errors.
    pub async fn delete(&self, id: JobId) -> Result<Deletion, JobsError> {
        let at = self.blocking(move |inner| Self::stop(inner, id, StopReason::Delete)).await?;
        let mut pending = None;
        match &at {
            Where::Here => {
                self.wait_stopped(id, &at).await;
                if self.inner.running().contains_key(&id) {
                    pending = self.get(id).await.ok();
                    info!(job = %id, "job deletion pending: it has not stopped yet");
                }
                self.blocking(move |inner| {
                    inner.store.delete(id)?;
                    Ok(())
                })
                .await?;
            }
            // Its record is gone: the worker's next heartbeat stops it, and
            // the worker removes what it writes after the files below go.
            Where::Elsewhere(rec) => {
                let mut rec = (**rec).clone();
                rec.stop_requested = true;
                pending = Some(rec);
            }
            Where::Stopped => {}
        }
        let mut not_removed = Vec::new();
        if !matches!(at, Where::Here) || pending.is_none() {
            not_removed = self
                .blocking(move |inner| {
                    inner.artifacts.delete_prefix(&JobsConfig::job_key(id), None)?;
                    Ok(super::runner::remove_job_dir_reporting(&inner.config, id))
                })
                .await?;
        }
        info!(job = %id, not_removed = not_removed.len(), "job deleted");
        Ok(Deletion { pending, not_removed })
    }

    /// Path of a finished job's artifact, if the job lists it.
    ///
    /// # Errors
    /// [`JobsError::NotFound`], [`JobsError::ArtifactNotFound`] or storage errors.
    pub async fn artifact(&self, id: JobId, name: String) -> Result<(PathBuf, super::model::Artifact), JobsError> {
        self.blocking(move |inner| {
            let (attempts, art, key) = listed_artifact(inner, id, name)?;
            // With S3, fetched into this machine's data directory on first use, then served as a file.
            if !inner.artifacts.is_local() && !inner.artifacts.fetch(&inner.config.data_dir, &key)? {
                return Err(JobsError::Internal(format!("artifact {key} is missing from the artifact store")));
            }
            Ok((inner.config.artifact_path(id, attempts, &art.name), art))
        })
        .await
    }

    /// A presigned URL of a finished job's artifact, valid for
    /// [`PRESIGNED_URL_SECS`], or `None` when the artifact store has no URLs
    /// (the data directory: the API serves the file).
    ///
    /// # Errors
    /// [`JobsError::NotFound`], [`JobsError::ArtifactNotFound`] or storage errors.
    pub async fn artifact_url(&self, id: JobId, name: String) -> Result<Option<String>, JobsError> {
        self.blocking(move |inner| {
            let (_, art, key) = listed_artifact(inner, id, name)?;
            let expires = std::time::Duration::from_secs(PRESIGNED_URL_SECS);
            Ok(inner.artifacts.presigned_get(&key, &art.name, &art.media_type, expires)?)
        })
        .await
    }

    /// Prometheus text of the service metrics.
    ///
    /// # Errors
    /// [`JobsError::Store`] on database failure.
    pub async fn metrics_text(&self) -> Result<String, JobsError> {
        self.blocking(|inner| {
            let jobs_by_state = inner.store.count_by_state()?;
            // One lock of the running jobs (a second one in this expression would deadlock).
            let (workers_busy, heartbeat_age_seconds) = {
                let running = inner.running();
                (running.len() as u64, running.values().map(|j| j.since_last_beat()).fold(0.0, f64::max))
            };
            let g = Gauges {
                queue_depth: jobs_by_state.get(&JobState::Queued).copied().unwrap_or(0),
                jobs_by_state,
                workers_busy,
                heartbeat_age_seconds,
                workers: if inner.config.run_jobs { inner.config.workers as u64 } else { 0 },
            };
            Ok(inner.metrics.render(&g))
        })
        .await
    }

    /// Checks that the store answers.
    ///
    /// # Errors
    /// [`JobsError::Store`] when it does not.
    pub async fn health(&self) -> Result<(), JobsError> {
        self.blocking(|inner| {
            inner.store.queued_count()?;
            Ok(())
        })
        .await
    }

    /// Checks that the data directory and the database take a write (a small
    /// file in `tmp/`, a one-page database transaction). Returns what failed
    /// (empty when both write).
    pub async fn storage_problems(&self) -> Vec<String> {
        let probed = self.blocking(|inner| {
            let mut problems = Vec::new();
            if let Err(e) = super::storage::probe_data_dir(&inner.config.data_dir) {
                problems.push(e);
            }
            if let Err(e) = inner.artifacts.probe() {
                problems.push(format!("the artifact store does not take a write: {e}"));
            }
            if let Err(e) = inner.store.probe_write() {
                let kind = super::storage::store_error_kind(&e).map(|k| format!(" ({k})")).unwrap_or_default();
                problems.push(format!("the job database does not take a write{kind}: {e}"));
            }
            Ok(problems)
        });
        probed.await.unwrap_or_else(|e| vec![e.to_string()])
    }

    /// Stops the dispatcher and asks running jobs to stop; they go back to
    /// the queue (not counted as an attempt). Waits up to `wait` for them.
    pub async fn shutdown(&self, wait: Duration) {
        self.inner.shutdown.store(true, Ordering::Relaxed);
        self.inner.wake.notify_all();
        for job in self.inner.running().values() {
            job.stop(StopReason::Shutdown);
        }
        let start = Instant::now();
        while start.elapsed() < wait && !self.inner.running().is_empty() {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        info!(still_running = self.inner.running().len(), "job service stopped");
    }
}

/// The peak-memory estimate of a submitted job: its stored parameters with
/// the server's caps applied, and the sizes scanned from its upload.
fn memory_estimate(config: &JobsConfig, new: &NewJob) -> Result<u64, JobsError> {
    let mut params: crate::pipeline::PipelineParams = serde_json::from_value(new.params.clone())
        .map_err(|e| JobsError::Internal(format!("validated parameters do not parse: {e}")))?;
    params.load.max_triangles = params.load.max_triangles.min(config.max_triangles);
    params.frames.max_tets = params.frames.max_tets.min(config.max_tets);
    let format = new.format.as_deref().and_then(crate::io::Format::from_name).unwrap_or(crate::io::Format::Stl);
    let sizes = crate::io::scan_input_sizes(&new.upload_path, format)
        .map_err(io_err(format!("cannot read the upload {}", new.upload_path.display())))?;
    Ok(crate::pipeline::peak_memory_estimate(&sizes, &params).peak)
}

fn overlay_live(rec: &mut JobRecord, job: &super::runner::RunningJob) {
    rec.stop_requested = job.reason().is_some();
    let secs = job.stage_seconds_now();
    let live = job.live.lock().unwrap_or_else(|p| p.into_inner());
    if !live.stage.is_empty() {
        rec.stage = Some(live.stage.clone());
        rec.progress = live.fraction;
    }
    rec.stage_seconds = secs;
}

fn get_live(inner: &Inner, id: JobId) -> Result<JobRecord, JobsError> {
    let mut rec = inner.store.get(id)?.ok_or(JobsError::NotFound(id))?;
    if rec.state == JobState::Running
        && let Some(job) = inner.running().get(&id)
    {
        overlay_live(&mut rec, job);
    }
    annotate_queued(inner, std::slice::from_mut(&mut rec))?;
    Ok(rec)
}

/// Sets the [`JobRecord::status_message`] of the queued jobs among `recs`:
/// no worker seen within a lease period, or an estimate above the largest
/// live worker's budget (asked of the store once, and only when a job is
/// queued).
fn annotate_queued(inner: &Inner, recs: &mut [JobRecord]) -> Result<(), JobsError> {
    if !recs.iter().any(|r| r.state == JobState::Queued) {
        return Ok(());
    }
    let within = inner.config.lease;
    let largest = inner.store.largest_worker_budget(within)?;
    for rec in recs.iter_mut().filter(|r| r.state == JobState::Queued) {
        rec.status_message = match largest {
            None => {
                Some(format!("no worker has been seen in the last {} s; the job waits for one", within.as_secs_f64()))
            }
            Some(b) if rec.memory_estimate_bytes > b => Some(format!(
                "the job's estimated peak memory of {} bytes exceeds the memory budget of every live worker \
                 (the largest is {b} bytes); it waits for a worker with a larger --memory-budget",
                rec.memory_estimate_bytes
            )),
            Some(_) => None,
        };
    }
    Ok(())
}

/// Removes from the artifact store the upload of a submission that was
/// refused after it was stored (no row refers to it).
fn forget_upload(inner: &Inner, id: JobId) {
    if let Err(e) = inner.artifacts.delete_prefix(&JobsConfig::job_key(id), None) {
        warn!(job = %id, error = %e, "cannot remove the upload of a refused job from the artifact store");
    }
}

/// Where a job that was asked to stop was running.
enum Where {
    /// On this process.
    Here,
    /// On another worker (the record as it was before the request).
    Elsewhere(Box<JobRecord>),
    /// Nowhere: it was queued, finished or unrecorded, and is handled.
    Stopped,
}

/// Opens the job store at `location`.
fn open_store(location: &StoreLocation) -> Result<Box<dyn JobStore>, JobsError> {
    Ok(match location {
        StoreLocation::Sqlite(dir) => {
            std::fs::create_dir_all(dir).map_err(io_err(format!("cannot create {}", dir.display())))?;
            Box::new(super::sqlite_store::SqliteStore::open(&dir.join("meshatlas.sqlite3"))?)
        }
        StoreLocation::Postgres(url) => Box::new(super::pg_store::PgStore::connect(url)?),
    })
}

/// Starts the threads of a process that runs jobs: heartbeat, recorder and
/// dispatcher; with PostgreSQL also the listener that wakes the dispatcher.
fn start_worker_threads(inner: &Arc<Inner>) -> Result<(), JobsError> {
    let spawn = |name: &str, f: Box<dyn FnOnce() + Send>| {
        std::thread::Builder::new()
            .name(format!("meshatlas-{name}"))
            .spawn(f)
            .map(drop)
            .map_err(|e| JobsError::Internal(format!("cannot start the {name} thread: {e}")))
    };
    // Registered before the first request can ask whether a worker is alive.
    if let Err(e) = inner.store.register_worker(inner.name.as_str(), inner.config.memory_budget) {
        warn!(error = %e, "cannot register this worker in the store");
    }
    let (h, r, d) = (inner.clone(), inner.clone(), inner.clone());
    spawn("heartbeat", Box::new(move || super::runner::heartbeat_loop(h)))?;
    spawn("recorder", Box::new(move || super::runner::recorder_loop(r)))?;
    spawn("dispatcher", Box::new(move || dispatch_loop(d)))?;
    let weak = Arc::downgrade(inner);
    inner.store.wake_on_new_jobs(Arc::new(move || {
        if let Some(i) = weak.upgrade() {
            i.wake.notify_all();
        }
    }));
    Ok(())
}

/// Removes the entries of `dir` older than `age` (by modification time)
/// for which `pick` holds.
fn remove_old_entries(dir: &std::path::Path, age: Duration, pick: impl Fn(&str) -> bool) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)?.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let old = entry.metadata().and_then(|m| m.modified()).is_ok_and(|t| t.elapsed().is_ok_and(|e| e >= age));
        if old && pick(&name) {
            warn!(path = %entry.path().display(), "removing a leftover entry");
            let path = entry.path();
            let _ = if path.is_dir() { std::fs::remove_dir_all(&path) } else { std::fs::remove_file(&path) };
        }
    }
    Ok(())
}

/// Removes the objects of job directories in the artifact store that no
/// record names and that nothing has written to for `age` (an upload whose
/// API died between the bucket and the row). A younger one may be a
/// submission in flight on another API. Failures are logged: the sweep runs
/// again at the next start.
fn remove_orphan_objects(store: &dyn JobStore, artifacts: &dyn ArtifactStore, age: Duration) {
    let swept = (|| -> Result<usize, JobsError> {
        let known: std::collections::HashSet<String> = store.all_ids()?.into_iter().collect();
        let orphans: Vec<String> =
            artifacts.job_dirs_older_than(age)?.into_iter().filter(|id| !known.contains(id)).collect();
        for id in &orphans {
            artifacts.delete_prefix(&format!("jobs/{id}/"), None)?;
        }
        Ok(orphans.len())
    })();
    match swept {
        Ok(0) => {}
        Ok(n) => info!(orphans = n, "removed artifact-store objects of jobs without a record"),
        Err(e) => warn!(error = %e, "cannot sweep the artifact store for orphaned objects"),
    }
}

/// Removes job directories with no record (a crash between file and row)
/// once they are older than [`IN_FLIGHT_AGE`]: a younger one may be a
/// submission another process is making.
fn remove_orphans(store: &dyn JobStore, jobs_dir: &std::path::Path) -> Result<(), JobsError> {
    let known: std::collections::HashSet<String> = store.all_ids()?.into_iter().collect();
    remove_old_entries(jobs_dir, IN_FLIGHT_AGE, |name| !known.contains(name))
        .map_err(io_err(format!("cannot read {}", jobs_dir.display())))
}

#[cfg(test)]
mod orphan_tests {
    use std::path::Path;

    use super::super::artifact_store::ArtifactError;
    use super::super::sqlite_store::SqliteStore;
    use super::*;

    /// An artifact store that lists fixed job directories and records deletions.
    struct Listed {
        dirs: Vec<String>,
        deleted: Mutex<Vec<String>>,
    }

    impl ArtifactStore for Listed {
        fn put(&self, _: &Path, _: &str) -> Result<(), ArtifactError> {
            Ok(())
        }
        fn fetch(&self, _: &Path, _: &str) -> Result<bool, ArtifactError> {
            Ok(false)
        }
        fn delete_prefix(&self, prefix: &str, _: Option<&str>) -> Result<(), ArtifactError> {
            self.deleted.lock().unwrap().push(prefix.to_string());
            Ok(())
        }
        fn is_local(&self) -> bool {
            false
        }
        fn probe(&self) -> Result<(), ArtifactError> {
            Ok(())
        }
        fn job_dirs_older_than(&self, _: Duration) -> Result<Vec<String>, ArtifactError> {
            Ok(self.dirs.clone())
        }
    }

    #[test]
    fn only_objects_of_jobs_without_a_record_are_swept() {
        let store = SqliteStore::open_in_memory().unwrap();
        let params = serde_json::json!({});
        let known = JobId::random();
        let row = NewRow {
            id: known,
            input_name: "a.stl",
            input_bytes: 1,
            format: Some("stl"),
            params: &params,
            memory_estimate_bytes: 1,
            tenant: None,
        };
        store.insert_queued(&row, 10).unwrap().unwrap();
        let orphan = JobId::random();
        let artifacts = Listed { dirs: vec![known.to_string(), orphan.to_string()], deleted: Mutex::default() };
        remove_orphan_objects(&store, &artifacts, IN_FLIGHT_AGE);
        assert_eq!(*artifacts.deleted.lock().unwrap(), [format!("jobs/{orphan}/")]);
    }
}
