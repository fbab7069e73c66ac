//! Progress reporting and cooperative cancellation for long computations.
//!
//! The numerical core receives a [`Progress`] handle. It reports the current
//! stage and a fraction in `[0, 1]` through it, and polls
//! [`Progress::check`] between units of work so that a cancelled job stops
//! within a fraction of a second. The handle is cheap to clone and
//! `Send + Sync`; it knows nothing of threads, tasks or HTTP: whoever creates
//! it decides what a report means (a database row, a terminal bar, nothing).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Receives progress reports. Implemented by the job runner and the CLI.
pub trait ProgressSink: Send + Sync {
    /// Called with the stage name and the overall fraction done in `[0, 1]`.
    fn report(&self, stage: &str, fraction: f64);
}

/// The computation was cancelled by its owner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("cancelled")]
pub struct Cancelled;

/// Handle passed down to every stage: reports progress, carries the cancel flag.
///
/// A handle maps its local fraction range `[0, 1]` onto a sub-range
/// `[lo, hi]` of the overall job, so nested steps can report locally.
#[derive(Clone)]
pub struct Progress {
    sink: Option<Arc<dyn ProgressSink>>,
    cancel: Arc<AtomicBool>,
    stage: Arc<str>,
    lo: f64,
    hi: f64,
}

impl Default for Progress {
    fn default() -> Self {
        Self::none()
    }
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Progress")
            .field("stage", &self.stage)
            .field("lo", &self.lo)
            .field("hi", &self.hi)
            .field("cancelled", &self.is_cancelled())
            .finish()
    }
}

impl Progress {
    /// A handle that reports nowhere and is never cancelled (tests, library use).
    pub fn none() -> Self {
        Self { sink: None, cancel: Arc::new(AtomicBool::new(false)), stage: Arc::from(""), lo: 0.0, hi: 1.0 }
    }

    /// A handle reporting to `sink`, cancelled when `cancel` becomes true.
    pub fn new(sink: Arc<dyn ProgressSink>, cancel: Arc<AtomicBool>) -> Self {
        Self { sink: Some(sink), cancel, stage: Arc::from(""), lo: 0.0, hi: 1.0 }
    }

    /// A child handle for stage `name` covering the local range `[lo, hi]`
    /// of this handle. Reports `0` for the child immediately.
    pub fn stage(&self, name: &str, lo: f64, hi: f64) -> Progress {
        let child = Progress {
            sink: self.sink.clone(),
            cancel: self.cancel.clone(),
            stage: Arc::from(name),
            lo: self.map(lo),
            hi: self.map(hi),
        };
        child.set(0.0);
        child
    }

    /// A child handle for the local range `[lo, hi]`, same stage name.
    pub fn sub(&self, lo: f64, hi: f64) -> Progress {
        Progress {
            sink: self.sink.clone(),
            cancel: self.cancel.clone(),
            stage: self.stage.clone(),
            lo: self.map(lo),
            hi: self.map(hi),
        }
    }

    /// Report that the local fraction `f` (clamped to `[0, 1]`) is done.
    pub fn set(&self, f: f64) {
        if let Some(s) = &self.sink {
            s.report(&self.stage, self.map(f));
        }
    }

    /// The name of the stage this handle reports for.
    pub fn stage_name(&self) -> &str {
        &self.stage
    }

    /// True once the owner asked to cancel.
    pub fn is_cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// `Err(Cancelled)` once the owner asked to cancel; call between units of work.
    ///
    /// # Errors
    /// [`Cancelled`] when the cancel flag is set.
    pub fn check(&self) -> Result<(), Cancelled> {
        if self.is_cancelled() { Err(Cancelled) } else { Ok(()) }
    }

    /// The flag this handle polls, for owners that need to set it.
    pub fn cancel_flag(&self) -> Arc<AtomicBool> {
        self.cancel.clone()
    }

    fn map(&self, f: f64) -> f64 {
        let f = if f.is_nan() { 0.0 } else { f.clamp(0.0, 1.0) };
        self.lo + (self.hi - self.lo) * f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    struct Record(Mutex<Vec<(String, f64)>>);
    impl ProgressSink for Record {
        fn report(&self, stage: &str, fraction: f64) {
            self.0.lock().unwrap().push((stage.to_string(), fraction));
        }
    }

    #[test]
    fn nested_ranges_map_to_overall_fraction() {
        let rec = Arc::new(Record(Mutex::new(Vec::new())));
        let cancel = Arc::new(AtomicBool::new(false));
        let p = Progress::new(rec.clone(), cancel.clone());
        let s = p.stage("atlas", 0.5, 1.0);
        s.sub(0.0, 0.5).set(1.0);
        s.set(2.0);
        let got = rec.0.lock().unwrap().clone();
        assert_eq!(got, vec![("atlas".into(), 0.5), ("atlas".into(), 0.75), ("atlas".into(), 1.0)]);
        assert!(s.check().is_ok());
        cancel.store(true, Ordering::Relaxed);
        assert_eq!(s.check(), Err(Cancelled));
    }
}
