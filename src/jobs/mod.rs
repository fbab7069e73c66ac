//! Durable jobs: model, SQLite store, runner bridging tokio and the rayon pool.
//!
//! - [`model`]: ids (random UUID v4), states, records, errors, artifacts.
//! - [`store`]: the job records ([`JobStore`]), which are also the queue;
//!   [`sqlite_store`] (embedded) and [`pg_store`] (PostgreSQL) keep them,
//!   with leases held under a [`worker_name`].
//! - [`runner`]: dispatcher thread, rayon workers, time limit, progress.
//! - [`service`]: [`JobService`], the async API the HTTP layer calls.
//! - [`executor`]: what a worker runs ([`Executor`]); the service runs
//!   [`pipeline_executor::PipelineExecutor`], tests inject fakes.
//! - [`metrics`]: Prometheus text.
//! - [`memory`]: the memory budget (`--memory-budget` sizes, default).
//! - [`quota`]: stored-bytes and per-tenant admission limits.
//! - [`retention`]: expiry of finished jobs.
//!
//! This is the only module that touches both rayon and tokio: numerical work
//! runs on the rayon pool, store and file operations on tokio's blocking
//! pool, and the async side only awaits.

pub mod artifact_store;
pub mod blocking_runtime;
pub mod executor;
pub mod memory;
pub mod metrics;
pub mod model;
pub mod pg_store;
pub mod pipeline_executor;
pub mod quota;
pub mod retention;
pub mod runner;
pub mod service;
pub mod sqlite_store;
pub mod storage;
pub mod store;
#[cfg(test)]
mod store_conformance;
pub mod worker_name;

pub use executor::{Delayed, ExecError, Executor, JobInput, JobOutcome, Stalled};
pub use model::{Artifact, JobError, JobId, JobPage, JobRecord, JobState, NewJob};
pub use quota::Quotas;
pub use retention::{Retention, parse_retention};
pub use runner::JobsConfig;
pub use service::{Deletion, JobService, JobsError};
pub use sqlite_store::SqliteStore;
pub use store::{JobStore, Lease, StoreError, StoreLocation};

/// Installs a panic hook that logs panics through `tracing` (with the
/// current job span, so the log names the job) instead of printing to
/// stderr. Jobs also run inside `catch_unwind`, so a panic fails the job and
/// the process carries on.
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = runner::panic_message(info.payload());
        let location = info.location().map(|l| format!("{}:{}", l.file(), l.line())).unwrap_or_default();
        tracing::error!(panic = %msg, %location, "panic");
    }));
}

#[cfg(test)]
mod tests;
