//! What a worker runs for a job: the [`Executor`] trait and its inputs and
//! outputs.
//!
//! The runner knows nothing of meshes: it hands an executor the job's input
//! file, parameters and output directory, and gets back a summary, per-stage
//! wall seconds and the artifacts written. The service uses the pipeline
//! executor (`super::pipeline_executor`); tests inject executors that sleep,
//! panic or wait for cancellation.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use crate::progress::Progress;

use super::model::{Artifact, JobError, JobId};

/// What an executor is given.
#[derive(Debug, Clone)]
pub struct JobInput {
    /// The job id (for logs).
    pub id: JobId,
    /// The uploaded file.
    pub input: PathBuf,
    /// Client-side name of the upload (for reports).
    pub input_name: String,
    /// Format name given or detected at upload (`stl`, `obj`, `ply`, `msh`), or
    /// `None` to sniff.
    pub format: Option<String>,
    /// Validated pipeline parameters (JSON).
    pub params: serde_json::Value,
    /// Directory to write artifacts into (exists and is empty).
    pub out_dir: PathBuf,
    /// Server-wide cap on triangles; the executor applies the smaller of this
    /// and the job's own cap.
    pub max_triangles: usize,
    /// Server-wide cap on the frames stage's `max_tets`; the executor applies
    /// the smaller of this and the job's own.
    pub max_tets: usize,
}

/// What a successful execution returns.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JobOutcome {
    /// JSON summary shown in the job resource (repair report, stage summaries).
    pub summary: serde_json::Value,
    /// Wall seconds per stage, in the order run (names as in the report).
    pub stage_seconds: BTreeMap<String, f64>,
    /// Files written into `out_dir`.
    pub artifacts: Vec<Artifact>,
}

/// Why an execution did not produce an outcome.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ExecError {
    /// The progress handle was cancelled and the executor stopped.
    #[error("cancelled")]
    Cancelled,
    /// The job failed; the error says why (stable kind + detail).
    #[error("{}: {}", .0.kind, .0.detail)]
    Failed(JobError),
}

/// Runs one job synchronously on a worker thread.
pub trait Executor: Send + Sync + 'static {
    /// Runs the job, reporting through `progress` and polling
    /// `progress.check()` often enough to stop within a fraction of a second
    /// of a cancel.
    ///
    /// # Errors
    /// [`ExecError::Cancelled`] after a cancel, [`ExecError::Failed`] otherwise.
    fn execute(&self, job: &JobInput, progress: &Progress) -> Result<JobOutcome, ExecError>;
}

impl<F> Executor for F
where
    F: Fn(&JobInput, &Progress) -> Result<JobOutcome, ExecError> + Send + Sync + 'static,
{
    fn execute(&self, job: &JobInput, progress: &Progress) -> Result<JobOutcome, ExecError> {
        self(job, progress)
    }
}

/// Wraps an executor with a cancellable delay before it runs, reported as
/// stage `delay`. Used by the restart-durability test (hidden CLI flag) to
/// make small jobs slow enough to be killed mid-run.
pub struct Delayed<E> {
    /// The executor run after the delay.
    pub inner: E,
    /// How long to wait first.
    pub delay: Duration,
}

impl<E: Executor> Executor for Delayed<E> {
    fn execute(&self, job: &JobInput, progress: &Progress) -> Result<JobOutcome, ExecError> {
        let p = progress.stage("delay", 0.0, 0.1);
        let start = std::time::Instant::now();
        while start.elapsed() < self.delay {
            p.check().map_err(|_| ExecError::Cancelled)?;
            p.set(start.elapsed().as_secs_f64() / self.delay.as_secs_f64().max(1e-9));
            std::thread::sleep(Duration::from_millis(20).min(self.delay));
        }
        let waited = start.elapsed().as_secs_f64();
        let mut out = self.inner.execute(job, &progress.sub(0.1, 1.0))?;
        out.stage_seconds.insert("delay".to_string(), waited);
        Ok(out)
    }
}

/// Wraps an executor with a delay that ignores cancellation, reported as
/// stage `stall`: a stage that cannot stop at once. Used by the tests of
/// cancel/delete answering 202 while the stop is pending (hidden CLI flag).
pub struct Stalled<E> {
    /// The executor run after the stall (it sees a cancel then).
    pub inner: E,
    /// How long to ignore cancellation first.
    pub stall: Duration,
}

impl<E: Executor> Executor for Stalled<E> {
    fn execute(&self, job: &JobInput, progress: &Progress) -> Result<JobOutcome, ExecError> {
        progress.stage("stall", 0.0, 0.0);
        std::thread::sleep(self.stall);
        self.inner.execute(job, progress)
    }
}
