//! The job model: ids, states, records, errors and artifacts.
//!
//! A job is created `queued`, becomes `running` when a worker claims it and
//! ends `succeeded`, `failed` or `cancelled`. A job interrupted by a crash
//! goes back to `queued` at the next start (its `attempts` counter keeps the
//! number of times a worker claimed it), and is failed with kind
//! `interrupted` once it has been claimed `max_attempts` times.
//!
//! Times are stored as Unix milliseconds and shown as RFC 3339 UTC strings.

use std::collections::BTreeMap;
use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::failure::FailureKind;

/// An unguessable job id: a random (version 4) UUID, 122 random bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JobId(uuid::Uuid);

impl JobId {
    /// A fresh random id.
    pub fn random() -> Self {
        Self(uuid::Uuid::new_v4())
    }
}

impl fmt::Display for JobId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0.hyphenated())
    }
}

/// The text is not a job id (a hyphenated UUID).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{0}` is not a job id (expected a UUID such as 3f2b8c1e-0a4d-4e5f-9b6a-1c2d3e4f5a6b)")]
pub struct BadJobId(pub String);

impl FromStr for JobId {
    type Err = BadJobId;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        uuid::Uuid::try_parse(s).map(JobId).map_err(|_| BadJobId(s.chars().take(64).collect()))
    }
}

impl Serialize for JobId {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Lifecycle state of a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobState {
    /// Accepted and waiting for a worker.
    Queued,
    /// A worker is running the pipeline.
    Running,
    /// Finished; artifacts are available.
    Succeeded,
    /// Finished with an error (see [`JobRecord::error`]).
    Failed,
    /// Cancelled by a client before it finished.
    Cancelled,
}

impl JobState {
    /// Every state, in lifecycle order (used for metrics).
    pub const ALL: [JobState; 5] =
        [JobState::Queued, JobState::Running, JobState::Succeeded, JobState::Failed, JobState::Cancelled];

    /// The lowercase name used in JSON, SQL and metrics.
    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }

    /// Parses [`JobState::as_str`] output.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|st| st.as_str() == s)
    }

    /// True for states a job never leaves.
    pub fn is_final(self) -> bool {
        matches!(self, JobState::Succeeded | JobState::Failed | JobState::Cancelled)
    }
}

/// Why a job failed: a stable [`FailureKind`] (e.g. `parse-error`,
/// `too-many-triangles`, `time-limit-exceeded`, `interrupted`) and a
/// human-readable detail. The HTTP layer turns it into problem+json.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct JobError {
    /// Stable failure kind (stored by its id; an unknown stored id reads
    /// back as `internal-error`).
    pub kind: FailureKind,
    /// What went wrong and, where possible, how to fix the input.
    pub detail: String,
}

impl JobError {
    /// A failure of `kind` with `detail`.
    pub fn new(kind: FailureKind, detail: impl Into<String>) -> Self {
        Self { kind, detail: detail.into() }
    }
}

/// A file produced by a job, downloadable by name.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Artifact {
    /// File name inside the job's output directory (no path separators).
    pub name: String,
    /// Size in bytes.
    pub bytes: u64,
    /// Media type served as `Content-Type`.
    pub media_type: String,
}

/// Everything the store keeps about a job.
#[derive(Debug, Clone, PartialEq)]
pub struct JobRecord {
    /// The job id.
    pub id: JobId,
    /// Insertion order (newest has the largest), used as pagination cursor.
    pub seq: i64,
    /// Lifecycle state.
    pub state: JobState,
    /// Creation time, Unix milliseconds.
    pub created_ms: i64,
    /// Time the last attempt started, Unix milliseconds.
    pub started_ms: Option<i64>,
    /// Time the job reached a final state, Unix milliseconds.
    pub finished_ms: Option<i64>,
    /// Client-side name of the uploaded file (or `upload`).
    pub input_name: String,
    /// Size of the upload in bytes.
    pub input_bytes: u64,
    /// Input format name (`stl`, `obj`, `ply`, `msh`) when known at upload.
    pub format: Option<String>,
    /// Validated pipeline parameters as JSON.
    pub params: serde_json::Value,
    /// Stage currently running (or the last one reported).
    pub stage: Option<String>,
    /// Overall fraction done in `[0, 1]`.
    pub progress: f64,
    /// Wall seconds per finished stage.
    pub stage_seconds: BTreeMap<String, f64>,
    /// The pipeline summary (repair report, stage summaries), when succeeded.
    pub summary: Option<serde_json::Value>,
    /// Why the job failed, when failed.
    pub error: Option<JobError>,
    /// Files produced, when succeeded.
    pub artifacts: Vec<Artifact>,
    /// Number of times a worker claimed the job.
    pub attempts: u32,
    /// Estimated peak memory of the job in bytes (0 for jobs stored before
    /// estimates existed).
    pub memory_estimate_bytes: u64,
    /// Times the server process died while the job ran (start-up recovery
    /// counts them; a graceful shutdown is not a crash).
    pub crashes: u32,
    /// A stop (cancel or delete) was asked and the job has not stopped yet
    /// (live, not stored).
    pub stop_requested: bool,
    /// Why a queued job cannot start now, when the reason is not just the
    /// jobs ahead of it (no live worker, or none with a large enough
    /// memory budget); computed when read, not stored.
    pub status_message: Option<String>,
}

/// A job to insert: the upload has already been written to `upload_path`.
#[derive(Debug, Clone)]
pub struct NewJob {
    /// The job's id, chosen before the upload so that it can stream to
    /// its key in the artifact store ([`JobId::random`] otherwise).
    pub id: JobId,
    /// Temporary file holding the upload; moved into the job directory.
    pub upload_path: PathBuf,
    /// The upload is already in the artifact store under the job's input
    /// key (streamed there as it arrived).
    pub input_stored: bool,
    /// Client-side file name (or `upload`).
    pub input_name: String,
    /// Upload size in bytes.
    pub input_bytes: u64,
    /// Input format name when known (`stl`, `obj`, `ply`, `msh`).
    pub format: Option<String>,
    /// Validated pipeline parameters as JSON.
    pub params: serde_json::Value,
    /// The submitting tenant (`None` without authentication).
    pub tenant: Option<String>,
}

/// One page of jobs, newest first.
#[derive(Debug, Clone)]
pub struct JobPage {
    /// The jobs of this page.
    pub jobs: Vec<JobRecord>,
    /// Cursor for the next (older) page, if there is one.
    pub next_cursor: Option<i64>,
}

/// A safe file name from a client-supplied one: the last path component,
/// characters other than ASCII letters, digits, `.`, `-`, `_` replaced by
/// `_`, no leading dot, at most 100 characters; `upload` when nothing is left.
pub fn sanitize_file_name(name: &str) -> String {
    let last = name.rsplit(['/', '\\']).next().unwrap_or("");
    let mut out: String =
        last.chars().map(|c| if c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_') { c } else { '_' }).collect();
    while out.starts_with('.') {
        out.remove(0);
    }
    // Keep the extension when truncating.
    if out.len() > 100 {
        let ext = out.rsplit_once('.').map(|(_, e)| e.to_string()).filter(|e| e.len() <= 10);
        out.truncate(if ext.is_some() { 89 } else { 100 });
        if let Some(e) = ext {
            out.push('.');
            out.push_str(&e);
        }
    }
    if out.is_empty() || out.chars().all(|c| c == '_') { "upload".to_string() } else { out }
}

/// Current time in Unix milliseconds.
pub fn now_ms() -> i64 {
    let d = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    i64::try_from(d.as_millis()).unwrap_or(i64::MAX)
}

/// Formats Unix milliseconds as RFC 3339 UTC (`2026-11-22T17:49:03.120Z`).
///
/// Civil date from days since the epoch by Howard Hinnant's algorithm
/// (proleptic Gregorian calendar).
pub fn rfc3339(ms: i64) -> String {
    let secs = ms.div_euclid(1000);
    let millis = ms.rem_euclid(1000);
    let days = secs.div_euclid(86_400);
    let sod = secs.rem_euclid(86_400);
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{millis:03}Z", sod / 3600, (sod % 3600) / 60, sod % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rfc3339_matches_known_instants() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000Z");
        // 2000-02-29T12:34:56.789Z (leap day) = 951827696789 ms
        assert_eq!(rfc3339(951_827_696_789), "2000-02-29T12:34:56.789Z");
        // 2026-11-22T00:00:00Z = 1795305600 s
        assert_eq!(rfc3339(1_795_305_600_000), "2026-11-22T00:00:00.000Z");
        assert_eq!(rfc3339(-1), "1969-12-31T23:59:59.999Z");
    }

    #[test]
    fn job_ids_round_trip_and_reject_garbage() {
        let id = JobId::random();
        assert_eq!(id.to_string().parse::<JobId>(), Ok(id));
        assert_ne!(JobId::random(), JobId::random());
        assert!("../etc/passwd".parse::<JobId>().is_err());
        assert!("".parse::<JobId>().is_err());
    }

    #[test]
    fn file_names_are_sanitized() {
        assert_eq!(sanitize_file_name("bunny.stl"), "bunny.stl");
        assert_eq!(sanitize_file_name("../../etc/passwd"), "passwd");
        assert_eq!(sanitize_file_name("C:\\x\\my mesh (1).obj"), "my_mesh__1_.obj");
        assert_eq!(sanitize_file_name(".hidden"), "hidden");
        assert_eq!(sanitize_file_name(""), "upload");
        assert_eq!(sanitize_file_name(".."), "upload");
        let long = format!("{}.ply", "a".repeat(300));
        let s = sanitize_file_name(&long);
        assert!(s.len() <= 100 && s.ends_with(".ply"), "{s}");
    }

    #[test]
    fn states_round_trip() {
        for s in JobState::ALL {
            assert_eq!(JobState::parse(s.as_str()), Some(s));
            assert_eq!(serde_json::to_value(s).unwrap(), serde_json::Value::String(s.as_str().into()));
        }
        assert!(JobState::Failed.is_final() && !JobState::Running.is_final());
    }
}
