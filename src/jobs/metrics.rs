//! Prometheus metrics of the job service, rendered in the text exposition
//! format 0.0.4.
//!
//! Gauges (`meshatlas_jobs{state}`, `meshatlas_queue_depth`,
//! `meshatlas_workers_busy`) are read from the store when scraped, so they
//! survive restarts; `meshatlas_heartbeat_age_seconds` from the jobs this
//! process runs. Counters and histograms (`meshatlas_jobs_finished_total`,
//! `meshatlas_stage_duration_seconds`, `meshatlas_job_duration_seconds`,
//! `meshatlas_heartbeat_write_seconds`) live in memory and restart at zero,
//! as Prometheus counters may.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::Mutex;

use super::model::JobState;

/// Upper bounds (seconds) of the duration histogram buckets.
pub const DURATION_BUCKETS: [f64; 12] = [0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 300.0];

/// A cumulative histogram with [`DURATION_BUCKETS`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Histogram {
    /// Observations per bucket (not cumulative; the renderer accumulates).
    pub counts: [u64; DURATION_BUCKETS.len()],
    /// Observations above the last bound.
    pub overflow: u64,
    /// Sum of observed values.
    pub sum: f64,
}

impl Histogram {
    /// Adds one observation.
    pub fn observe(&mut self, v: f64) {
        let v = if v.is_finite() { v.max(0.0) } else { 0.0 };
        match DURATION_BUCKETS.iter().position(|&b| v <= b) {
            Some(i) => self.counts[i] += 1,
            None => self.overflow += 1,
        }
        self.sum += v;
    }

    /// Total number of observations.
    pub fn count(&self) -> u64 {
        self.counts.iter().sum::<u64>() + self.overflow
    }

    fn render(&self, out: &mut String, name: &str, labels: &str) {
        let sep = if labels.is_empty() { "" } else { "," };
        let mut cum = 0;
        for (b, c) in DURATION_BUCKETS.iter().zip(self.counts) {
            cum += c;
            let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"{b}\"}} {cum}");
        }
        let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"+Inf\"}} {}", self.count());
        let braces = if labels.is_empty() { String::new() } else { format!("{{{labels}}}") };
        let _ = writeln!(out, "{name}_sum{braces} {}", self.sum);
        let _ = writeln!(out, "{name}_count{braces} {}", self.count());
    }
}

/// In-memory counters and histograms.
#[derive(Debug, Default)]
pub struct Metrics {
    inner: Mutex<Counters>,
}

#[derive(Debug, Default)]
struct Counters {
    finished: BTreeMap<&'static str, u64>,
    stage: BTreeMap<String, Histogram>,
    job: Histogram,
    panics: u64,
    claims: u64,
    leases_expired: u64,
    /// Wall seconds of each heartbeat write of this process.
    heartbeat: Histogram,
}

/// Values read from the store at scrape time.
#[derive(Debug, Clone, Default)]
pub struct Gauges {
    /// Jobs per state.
    pub jobs_by_state: BTreeMap<JobState, u64>,
    /// Jobs waiting for a worker.
    pub queue_depth: u64,
    /// Workers running a job now.
    pub workers_busy: u64,
    /// Configured number of workers.
    pub workers: u64,
    /// Seconds since the oldest last heartbeat among the jobs this process
    /// runs (0 when it runs none): near the heartbeat interval when healthy,
    /// near the lease when the store is slow to take heartbeats.
    pub heartbeat_age_seconds: f64,
}

/// Escapes a Prometheus label value.
fn label(v: &str) -> String {
    v.replace('\\', "\\\\").replace('"', "\\\"").replace('\n', "\\n")
}

impl Metrics {
    fn lock(&self) -> std::sync::MutexGuard<'_, Counters> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Records a job reaching a final state after `seconds` of running, with
    /// its per-stage wall seconds.
    pub fn job_finished(&self, state: JobState, seconds: f64, stages: &BTreeMap<String, f64>) {
        let mut c = self.lock();
        *c.finished.entry(state.as_str()).or_default() += 1;
        c.job.observe(seconds);
        for (name, s) in stages {
            c.stage.entry(name.clone()).or_default().observe(*s);
        }
    }

    /// Records a panic caught in a job.
    pub fn job_panicked(&self) {
        self.lock().panics += 1;
    }

    /// Records a job claimed by this process.
    pub fn job_claimed(&self) {
        self.lock().claims += 1;
    }

    /// Records one heartbeat write that took `seconds`.
    pub fn heartbeat_written(&self, seconds: f64) {
        self.lock().heartbeat.observe(seconds);
    }

    /// Records `n` jobs this process took back after their lease expired.
    pub fn leases_expired(&self, n: usize) {
        self.lock().leases_expired += n as u64;
    }

    /// Renders every metric in the Prometheus text format.
    pub fn render(&self, g: &Gauges) -> String {
        let c = self.lock();
        let mut out = String::new();
        out.push_str("# HELP meshatlas_jobs Jobs in the store by state.\n# TYPE meshatlas_jobs gauge\n");
        for s in JobState::ALL {
            let n = g.jobs_by_state.get(&s).copied().unwrap_or(0);
            let _ = writeln!(out, "meshatlas_jobs{{state=\"{}\"}} {n}", s.as_str());
        }
        out.push_str("# HELP meshatlas_queue_depth Jobs waiting for a worker.\n# TYPE meshatlas_queue_depth gauge\n");
        let _ = writeln!(out, "meshatlas_queue_depth {}", g.queue_depth);
        out.push_str("# HELP meshatlas_workers_busy Workers running a job.\n# TYPE meshatlas_workers_busy gauge\n");
        let _ = writeln!(out, "meshatlas_workers_busy {}", g.workers_busy);
        out.push_str("# HELP meshatlas_workers Configured workers.\n# TYPE meshatlas_workers gauge\n");
        let _ = writeln!(out, "meshatlas_workers {}", g.workers);
        out.push_str(
            "# HELP meshatlas_jobs_finished_total Jobs that reached a final state since start.\n\
             # TYPE meshatlas_jobs_finished_total counter\n",
        );
        for s in [JobState::Succeeded, JobState::Failed, JobState::Cancelled] {
            let n = c.finished.get(s.as_str()).copied().unwrap_or(0);
            let _ = writeln!(out, "meshatlas_jobs_finished_total{{state=\"{}\"}} {n}", s.as_str());
        }
        out.push_str(
            "# HELP meshatlas_job_panics_total Panics caught in jobs since start.\n\
             # TYPE meshatlas_job_panics_total counter\n",
        );
        let _ = writeln!(out, "meshatlas_job_panics_total {}", c.panics);
        out.push_str(
            "# HELP meshatlas_claims_total Jobs this process claimed since start.\n\
             # TYPE meshatlas_claims_total counter\n",
        );
        let _ = writeln!(out, "meshatlas_claims_total {}", c.claims);
        out.push_str(
            "# HELP meshatlas_lease_expiries_total Jobs this process took back after their worker's lease expired.\n\
             # TYPE meshatlas_lease_expiries_total counter\n",
        );
        let _ = writeln!(out, "meshatlas_lease_expiries_total {}", c.leases_expired);
        out.push_str(
            "# HELP meshatlas_job_duration_seconds Wall time of finished jobs.\n\
             # TYPE meshatlas_job_duration_seconds histogram\n",
        );
        c.job.render(&mut out, "meshatlas_job_duration_seconds", "");
        out.push_str(
            "# HELP meshatlas_heartbeat_age_seconds Seconds since the oldest last heartbeat of the jobs this \
             process runs.\n# TYPE meshatlas_heartbeat_age_seconds gauge\n",
        );
        let _ = writeln!(out, "meshatlas_heartbeat_age_seconds {}", g.heartbeat_age_seconds);
        out.push_str(
            "# HELP meshatlas_heartbeat_write_seconds Wall time of this process's heartbeat writes to the store.\n\
             # TYPE meshatlas_heartbeat_write_seconds histogram\n",
        );
        c.heartbeat.render(&mut out, "meshatlas_heartbeat_write_seconds", "");
        out.push_str(
            "# HELP meshatlas_stage_duration_seconds Wall time per pipeline stage.\n\
             # TYPE meshatlas_stage_duration_seconds histogram\n",
        );
        for (name, h) in &c.stage {
            h.render(&mut out, "meshatlas_stage_duration_seconds", &format!("stage=\"{}\"", label(name)));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_buckets_are_cumulative() {
        let m = Metrics::default();
        let stages = BTreeMap::from([("load".to_string(), 0.07), ("write".to_string(), 1000.0)]);
        m.job_finished(JobState::Succeeded, 0.3, &stages);
        m.job_finished(JobState::Failed, 0.003, &BTreeMap::new());
        let g = Gauges { queue_depth: 4, ..Default::default() };
        let text = m.render(&g);
        assert!(text.contains("meshatlas_queue_depth 4\n"), "{text}");
        assert!(text.contains("meshatlas_jobs_finished_total{state=\"failed\"} 1\n"));
        assert!(text.contains("meshatlas_stage_duration_seconds_bucket{stage=\"load\",le=\"0.05\"} 0\n"));
        assert!(text.contains("meshatlas_stage_duration_seconds_bucket{stage=\"load\",le=\"0.1\"} 1\n"));
        assert!(text.contains("meshatlas_stage_duration_seconds_bucket{stage=\"write\",le=\"300\"} 0\n"));
        assert!(text.contains("meshatlas_stage_duration_seconds_bucket{stage=\"write\",le=\"+Inf\"} 1\n"));
        assert!(text.contains("meshatlas_job_duration_seconds_bucket{le=\"0.01\"} 1\n"));
        assert!(text.contains("meshatlas_job_duration_seconds_count 2\n"));
        assert!(text.contains("meshatlas_jobs{state=\"queued\"} 0\n"));
        m.heartbeat_written(0.003);
        let text = m.render(&Gauges { heartbeat_age_seconds: 1.5, ..Default::default() });
        assert!(text.contains("meshatlas_heartbeat_age_seconds 1.5\n"), "{text}");
        assert!(text.contains("meshatlas_heartbeat_write_seconds_bucket{le=\"0.01\"} 1\n"), "{text}");
    }
}
