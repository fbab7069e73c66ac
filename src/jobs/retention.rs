//! Retention: finished jobs (succeeded, failed, cancelled) whose end is
//! older than `--retention` are deleted, record and files, by a sweep that
//! runs at start-up and then every [`Retention::sweep_interval`].
//!
//! Queued and running jobs never expire. There is no eviction under quota
//! pressure: a full quota refuses new uploads (507) until jobs expire or
//! clients delete them, so a result is never removed before its time.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use tracing::{error, info};

use super::model::now_ms;
use super::runner::{Inner, remove_job_dir};

/// When finished jobs expire.
#[derive(Debug, Clone)]
pub struct Retention {
    /// Age (since the job finished) after which a finished job is deleted;
    /// `None` keeps jobs forever (the default).
    pub max_age: Option<Duration>,
    /// Time between two sweeps. Default 60 s.
    pub sweep_interval: Duration,
}

impl Default for Retention {
    fn default() -> Self {
        Self { max_age: None, sweep_interval: Duration::from_secs(60) }
    }
}

/// Parses a retention such as `7d`, `12h`, `30m`, `45s` or `3600` (seconds).
///
/// # Errors
/// A message when the text is not a positive whole number with an optional
/// unit, or overflows.
pub fn parse_retention(text: &str) -> Result<Duration, String> {
    let t = text.trim();
    let (digits, unit) = match t.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((i, _)) => t.split_at(i),
        None => (t, "s"),
    };
    let scale: u64 = match unit {
        "s" => 1,
        "m" => 60,
        "h" => 3600,
        "d" => 86_400,
        _ => return Err(format!("retention `{t}`: expected a number with unit s, m, h or d (e.g. 7d, 12h)")),
    };
    let n: u64 = digits.parse().map_err(|_| format!("retention `{t}`: expected a whole number before the unit"))?;
    let secs = n.checked_mul(scale).ok_or_else(|| format!("retention `{t}` is too long"))?;
    if secs == 0 {
        return Err(format!("retention `{t}` must be positive"));
    }
    Ok(Duration::from_secs(secs))
}

/// Deletes every finished job that ended more than `max_age` ago; returns
/// how many went.
fn sweep(inner: &Inner, max_age: Duration) -> usize {
    let cutoff = now_ms().saturating_sub(i64::try_from(max_age.as_millis()).unwrap_or(i64::MAX));
    let ids = match inner.store.finished_before(cutoff) {
        Ok(ids) => ids,
        Err(e) => {
            error!(error = %e, "retention sweep cannot list expired jobs");
            return 0;
        }
    };
    let mut n = 0;
    for id in ids {
        match inner.store.delete_if_final(id) {
            Ok(true) => {
                remove_job_dir(&inner.config, id);
                if let Err(e) = inner.artifacts.delete_prefix(&super::runner::JobsConfig::job_key(id), None) {
                    error!(job = %id, error = %e, "retention sweep cannot remove the job's objects");
                }
                n += 1;
            }
            Ok(false) => {}
            Err(e) => error!(job = %id, error = %e, "retention sweep cannot delete an expired job"),
        }
    }
    n
}

/// The sweep loop: sweeps at once, then every interval, until shutdown.
pub(crate) fn retention_loop(inner: Arc<Inner>, max_age: Duration) {
    let interval = inner.config.retention.sweep_interval;
    loop {
        let n = sweep(&inner, max_age);
        if n > 0 {
            info!(expired = n, "retention sweep deleted finished jobs");
        }
        let start = Instant::now();
        while start.elapsed() < interval {
            if inner.shutdown.load(Ordering::Relaxed) {
                return;
            }
            std::thread::sleep(interval.min(Duration::from_millis(50)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retention_units() {
        assert_eq!(parse_retention("7d"), Ok(Duration::from_secs(7 * 86_400)));
        assert_eq!(parse_retention("12h"), Ok(Duration::from_secs(12 * 3600)));
        assert_eq!(parse_retention("30m"), Ok(Duration::from_secs(1800)));
        assert_eq!(parse_retention("45s"), Ok(Duration::from_secs(45)));
        assert_eq!(parse_retention("3600"), Ok(Duration::from_secs(3600)));
        for bad in ["", "0", "0s", "7x", "d", "-1d", "1.5h", "99999999999999999999d", "7 d"] {
            assert!(parse_retention(bad).is_err(), "accepted `{bad}`");
        }
    }
}
