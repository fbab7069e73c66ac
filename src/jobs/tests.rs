//! Job machinery tests with injected executors (no meshes involved).

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use super::store::{JobStore, NewRow};
use super::*;
use crate::failure::FailureKind;
use crate::progress::Progress;

fn config(dir: &std::path::Path) -> JobsConfig {
    JobsConfig { progress_interval: Duration::from_millis(10), ..JobsConfig::new(dir) }
}

async fn submit(svc: &JobService) -> Result<JobRecord, JobsError> {
    let path = svc.upload_path();
    std::fs::write(&path, b"solid x\nendsolid x\n").unwrap();
    svc.submit(NewJob {
        id: JobId::random(),
        upload_path: path,
        input_stored: false,
        input_name: "x.stl".into(),
        input_bytes: 19,
        format: Some("stl".into()),
        params: serde_json::json!({}),
        tenant: None,
    })
    .await
}

async fn wait_for(svc: &JobService, id: JobId, pred: impl Fn(&JobRecord) -> bool) -> JobRecord {
    let start = Instant::now();
    loop {
        let rec = svc.get(id).await.unwrap();
        if pred(&rec) {
            return rec;
        }
        assert!(start.elapsed() < Duration::from_secs(10), "timed out; job is {rec:?}");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// Waits (polling the cancel flag) up to 30 s; returns Cancelled when asked.
fn wait_for_cancel(p: &Progress) -> Result<JobOutcome, ExecError> {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(30) {
        p.check().map_err(|_| ExecError::Cancelled)?;
        std::thread::sleep(Duration::from_millis(5));
    }
    Err(ExecError::Failed(JobError::new(FailureKind::InternalError, "never cancelled")))
}

#[tokio::test]
async fn a_job_runs_writes_artifacts_and_reports_timings() {
    let dir = tempfile::tempdir().unwrap();
    let exec = |job: &JobInput, p: &Progress| -> Result<JobOutcome, ExecError> {
        let input = std::fs::read(&job.input)
            .map_err(|e| ExecError::Failed(JobError::new(FailureKind::InternalError, e.to_string())))?;
        p.stage("copy", 0.0, 1.0).set(1.0);
        std::fs::write(job.out_dir.join("copy.stl"), &input).unwrap();
        Ok(JobOutcome {
            summary: serde_json::json!({"bytes": input.len()}),
            stage_seconds: [("copy".to_string(), 0.001)].into(),
            artifacts: vec![],
        })
    };
    let svc = JobService::start(config(dir.path()), Arc::new(exec)).unwrap();
    let rec = submit(&svc).await.unwrap();
    assert_eq!(rec.state, JobState::Queued);
    let done = wait_for(&svc, rec.id, |r| r.state.is_final()).await;
    assert_eq!(done.state, JobState::Succeeded, "{done:?}");
    assert_eq!(done.summary, Some(serde_json::json!({"bytes": 19})));
    assert_eq!(done.stage_seconds.get("copy"), Some(&0.001));
    assert_eq!(done.attempts, 1);
    assert_eq!(done.progress, 1.0);
    assert_eq!(done.artifacts, vec![Artifact { name: "copy.stl".into(), bytes: 19, media_type: "model/stl".into() }]);
    let (path, _) = svc.artifact(rec.id, "copy.stl".into()).await.unwrap();
    assert_eq!(std::fs::read(path).unwrap(), b"solid x\nendsolid x\n");
    assert!(matches!(svc.artifact(rec.id, "../input".into()).await, Err(JobsError::ArtifactNotFound { .. })));
    let metrics = svc.metrics_text().await.unwrap();
    assert!(metrics.contains("meshatlas_jobs{state=\"succeeded\"} 1"), "{metrics}");
    assert!(metrics.contains("meshatlas_stage_duration_seconds_count{stage=\"copy\"} 1"), "{metrics}");
}

#[tokio::test]
async fn failures_and_panics_fail_only_their_job() {
    let dir = tempfile::tempdir().unwrap();
    let n = Arc::new(AtomicUsize::new(0));
    let n2 = n.clone();
    let exec = move |_: &JobInput, _: &Progress| -> Result<JobOutcome, ExecError> {
        match n2.fetch_add(1, Ordering::SeqCst) {
            0 => Err(ExecError::Failed(JobError::new(FailureKind::ParseError, "line 3: expected `vertex`"))),
            1 => panic!("boom in a job"),
            _ => Ok(JobOutcome::default()),
        }
    };
    let svc = JobService::start(config(dir.path()), Arc::new(exec)).unwrap();
    let a = submit(&svc).await.unwrap();
    let b = submit(&svc).await.unwrap();
    let c = submit(&svc).await.unwrap();
    let a = wait_for(&svc, a.id, |r| r.state.is_final()).await;
    let b = wait_for(&svc, b.id, |r| r.state.is_final()).await;
    let c = wait_for(&svc, c.id, |r| r.state.is_final()).await;
    assert_eq!(a.state, JobState::Failed);
    assert_eq!(a.error, Some(JobError::new(FailureKind::ParseError, "line 3: expected `vertex`")));
    assert_eq!(b.state, JobState::Failed);
    assert_eq!(b.error.as_ref().unwrap().kind, FailureKind::InternalError);
    assert!(!b.error.unwrap().detail.contains("boom"), "panic text must not reach clients");
    assert_eq!(c.state, JobState::Succeeded);
    assert!(svc.metrics_text().await.unwrap().contains("meshatlas_job_panics_total 1"));
}

#[tokio::test]
async fn cancel_stops_a_running_job_within_a_second_and_progress_is_visible() {
    let dir = tempfile::tempdir().unwrap();
    let exec = |_: &JobInput, p: &Progress| {
        p.stage("spin", 0.2, 0.8).set(0.5);
        wait_for_cancel(p)
    };
    let svc = JobService::start(config(dir.path()), Arc::new(exec)).unwrap();
    let rec = submit(&svc).await.unwrap();
    let running = wait_for(&svc, rec.id, |r| r.state == JobState::Running && r.progress > 0.25).await;
    assert_eq!(running.stage.as_deref(), Some("spin"));
    assert!((running.progress - 0.5).abs() < 1e-12, "{}", running.progress);
    assert!(running.stage_seconds.contains_key("spin"));
    let t = Instant::now();
    let after = svc.cancel(rec.id).await.unwrap();
    assert!(t.elapsed() < Duration::from_secs(1), "cancel took {:?}", t.elapsed());
    assert_eq!(after.state, JobState::Cancelled);
    // A queued job is cancelled without running; unknown ids are reported.
    assert!(matches!(svc.cancel(JobId::random()).await, Err(JobsError::NotFound(_))));
}

#[tokio::test]
async fn delete_removes_a_running_job_and_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let exec = |_: &JobInput, p: &Progress| wait_for_cancel(p);
    let svc = JobService::start(config(dir.path()), Arc::new(exec)).unwrap();
    let a = submit(&svc).await.unwrap();
    let b = submit(&svc).await.unwrap();
    wait_for(&svc, a.id, |r| r.state == JobState::Running).await;
    assert!(svc.config().job_dir(a.id).exists());
    let t = Instant::now();
    svc.delete(a.id).await.unwrap();
    assert!(t.elapsed() < Duration::from_secs(1));
    assert!(matches!(svc.get(a.id).await, Err(JobsError::NotFound(_))));
    assert!(!svc.config().job_dir(a.id).exists());
    // b was queued behind a and now runs; delete it too.
    wait_for(&svc, b.id, |r| r.state == JobState::Running).await;
    svc.delete(b.id).await.unwrap();
    assert!(matches!(svc.delete(b.id).await, Err(JobsError::NotFound(_))));
    assert!(svc.list(10, None, None).await.unwrap().jobs.is_empty());
}

#[tokio::test]
async fn the_time_limit_fails_a_job_with_a_clear_reason() {
    let dir = tempfile::tempdir().unwrap();
    let exec = |_: &JobInput, p: &Progress| wait_for_cancel(p);
    let cfg = JobsConfig { job_timeout: Duration::from_millis(200), ..config(dir.path()) };
    let svc = JobService::start(cfg, Arc::new(exec)).unwrap();
    let rec = submit(&svc).await.unwrap();
    let done = wait_for(&svc, rec.id, |r| r.state.is_final()).await;
    assert_eq!(done.state, JobState::Failed);
    let e = done.error.unwrap();
    assert_eq!(e.kind, FailureKind::TimeLimitExceeded);
    assert!(e.detail.contains("0.2 s"), "{}", e.detail);
}

#[tokio::test]
async fn the_queue_is_bounded_and_workers_bound_concurrency() {
    let dir = tempfile::tempdir().unwrap();
    let now = Arc::new(AtomicUsize::new(0));
    let peak = Arc::new(AtomicUsize::new(0));
    let (n2, p2) = (now.clone(), peak.clone());
    let exec = move |_: &JobInput, _: &Progress| {
        let k = n2.fetch_add(1, Ordering::SeqCst) + 1;
        p2.fetch_max(k, Ordering::SeqCst);
        std::thread::sleep(Duration::from_millis(30));
        n2.fetch_sub(1, Ordering::SeqCst);
        Ok(JobOutcome::default())
    };
    let cfg = JobsConfig { workers: 2, max_queued: 8, ..config(dir.path()) };
    let svc = JobService::start(cfg, Arc::new(exec)).unwrap();
    let mut ids = Vec::new();
    let mut refused = 0;
    for _ in 0..20 {
        match submit(&svc).await {
            Ok(r) => ids.push(r.id),
            Err(JobsError::QueueFull { max_queued: 8 }) => refused += 1,
            Err(e) => panic!("{e}"),
        }
    }
    assert!(refused > 0, "20 instant submissions must overflow a queue of 8");
    for id in &ids {
        assert_eq!(wait_for(&svc, *id, |r| r.state.is_final()).await.state, JobState::Succeeded);
    }
    assert!(peak.load(Ordering::SeqCst) <= 2, "peak concurrency {}", peak.load(Ordering::SeqCst));
    let leftovers = std::fs::read_dir(dir.path().join("tmp")).unwrap().count();
    assert_eq!(leftovers, 0, "refused uploads must be removed");
}

#[tokio::test]
async fn a_restart_requeues_the_interrupted_job() {
    let dir = tempfile::tempdir().unwrap();
    // Simulate a crash: mark a job running in the store, as a killed worker would leave it.
    let id = {
        let store = SqliteStore::open(&dir.path().join("meshatlas.sqlite3")).unwrap();
        let id = JobId::random();
        let cfg = config(dir.path());
        std::fs::create_dir_all(cfg.input_path(id, "x.stl").parent().unwrap()).unwrap();
        std::fs::write(cfg.input_path(id, "x.stl"), b"x").unwrap();
        let params = serde_json::json!({});
        let row = NewRow {
            id,
            input_name: "x.stl",
            input_bytes: 1,
            format: None,
            params: &params,
            memory_estimate_bytes: 0,
            tenant: None,
        };
        store.insert_queued(&row, 10).unwrap();
        // Claimed by a process of this host that is gone (PID above Linux's pid_max), lease still live.
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap().trim().to_string();
        store.claim(id, &format!("{host}/4194304/gone"), Duration::from_secs(3600)).unwrap().unwrap();
        // An orphaned directory old enough not to be a submission in progress, and a young one.
        for (name, age) in [("not-a-job", 3600), ("in-flight", 0)] {
            let d = dir.path().join("jobs").join(name);
            std::fs::create_dir_all(&d).unwrap();
            let t = std::time::SystemTime::now() - Duration::from_secs(age);
            std::fs::File::open(&d).unwrap().set_modified(t).unwrap();
        }
        id
    };
    let exec = |_: &JobInput, _: &Progress| Ok(JobOutcome::default());
    let svc = JobService::start(config(dir.path()), Arc::new(exec)).unwrap();
    let done = wait_for(&svc, id, |r| r.state.is_final()).await;
    assert_eq!((done.state, done.attempts), (JobState::Succeeded, 2));
    assert!(!dir.path().join("jobs/not-a-job").exists(), "orphaned directories are removed");
    assert!(dir.path().join("jobs/in-flight").exists(), "a young directory may be a submission in progress");
}

#[tokio::test]
async fn shutdown_puts_the_running_job_back_without_counting_the_attempt() {
    let dir = tempfile::tempdir().unwrap();
    let exec = |_: &JobInput, p: &Progress| wait_for_cancel(p);
    let svc = JobService::start(config(dir.path()), Arc::new(exec)).unwrap();
    let rec = submit(&svc).await.unwrap();
    wait_for(&svc, rec.id, |r| r.state == JobState::Running).await;
    svc.shutdown(Duration::from_secs(5)).await;
    drop(svc);
    let quick = |_: &JobInput, _: &Progress| Ok(JobOutcome::default());
    let svc = JobService::start(config(dir.path()), Arc::new(quick)).unwrap();
    let done = wait_for(&svc, rec.id, |r| r.state.is_final()).await;
    assert_eq!((done.state, done.attempts), (JobState::Succeeded, 1));
}

/// Like [`submit`], as `tenant`.
async fn submit_as(svc: &JobService, tenant: &str) -> Result<JobRecord, JobsError> {
    let path = svc.upload_path();
    std::fs::write(&path, b"solid x\nendsolid x\n").unwrap();
    let new = NewJob {
        id: JobId::random(),
        upload_path: path,
        input_stored: false,
        input_name: "x.stl".into(),
        input_bytes: 19,
        format: Some("stl".into()),
        params: serde_json::json!({}),
        tenant: Some(tenant.to_string()),
    };
    svc.submit(new).await
}

#[tokio::test]
async fn concurrent_submissions_never_exceed_the_stored_bytes_quota() {
    let dir = tempfile::tempdir().unwrap();
    let exec = |_: &JobInput, p: &Progress| wait_for_cancel(p);
    let quotas = Quotas { max_stored_bytes: Some(3 * 19), ..Default::default() };
    let svc = JobService::start(JobsConfig { quotas, ..config(dir.path()) }, Arc::new(exec)).unwrap();
    let tasks: Vec<_> = (0..12)
        .map(|i| {
            let svc = svc.clone();
            tokio::spawn(async move { submit_as(&svc, if i % 2 == 0 { "a" } else { "b" }).await })
        })
        .collect();
    let mut accepted = 0;
    for t in tasks {
        match t.await.unwrap() {
            Ok(_) => accepted += 1,
            Err(JobsError::QuotaExceeded { tenant: false, max_bytes: 57 }) => {}
            Err(e) => panic!("{e}"),
        }
    }
    assert_eq!(accepted, 3, "a quota of three uploads admitted {accepted}");
    assert_eq!(std::fs::read_dir(dir.path().join("tmp")).unwrap().count(), 0, "refused uploads must be removed");
}

#[tokio::test]
async fn a_tenant_sees_only_its_jobs_and_a_foreign_id_is_not_found() {
    let dir = tempfile::tempdir().unwrap();
    let exec = |_: &JobInput, p: &Progress| wait_for_cancel(p);
    let quotas = Quotas { tenant_max_queued: Some(1), ..Default::default() };
    let cfg = JobsConfig { quotas, workers: 1, ..config(dir.path()) };
    let svc = JobService::start(cfg, Arc::new(exec)).unwrap();
    let a = submit_as(&svc, "a").await.unwrap();
    wait_for(&svc, a.id, |r| r.state == JobState::Running).await;
    let a2 = submit_as(&svc, "a").await.unwrap();
    assert!(matches!(submit_as(&svc, "a").await, Err(JobsError::TenantQueueFull { max_queued: 1 })));
    let b = submit_as(&svc, "b").await.unwrap();
    assert!(svc.check_visible(a.id, Some("a".into())).await.is_ok());
    assert!(svc.check_visible(a.id, None).await.is_ok(), "without authentication every job is visible");
    assert!(matches!(svc.check_visible(a.id, Some("b".into())).await, Err(JobsError::NotFound(id)) if id == a.id));
    assert!(matches!(svc.check_visible(JobId::random(), Some("b".into())).await, Err(JobsError::NotFound(_))));
    let ids = |p: JobPage| p.jobs.iter().map(|j| j.id).collect::<Vec<_>>();
    assert_eq!(ids(svc.list(10, None, Some("a".into())).await.unwrap()), vec![a2.id, a.id]);
    assert_eq!(ids(svc.list(10, None, Some("b".into())).await.unwrap()), vec![b.id]);
    assert_eq!(svc.list(10, None, None).await.unwrap().jobs.len(), 3);
}

/// The numerical pool is separate from the number of jobs at a time: one
/// job alone sees every thread (the service's parallel loops are not
/// limited to one core by `workers = 1`).
#[tokio::test]
async fn one_job_at_a_time_still_gets_every_pool_thread() {
    for (threads, expected) in [(2, 2), (3, 3), (0, std::thread::available_parallelism().unwrap().get())] {
        let dir = tempfile::tempdir().unwrap();
        let exec = |_: &JobInput, _: &Progress| -> Result<JobOutcome, ExecError> {
            // What a parallel loop inside the job may use.
            let seen = rayon::current_num_threads();
            let distinct: std::collections::HashSet<_> =
                rayon::broadcast(|_| std::thread::current().id()).into_iter().collect();
            Ok(JobOutcome {
                summary: serde_json::json!({"threads": seen, "distinct": distinct.len()}),
                stage_seconds: Default::default(),
                artifacts: vec![],
            })
        };
        let cfg = JobsConfig { workers: 1, threads, ..config(dir.path()) };
        let svc = JobService::start(cfg, Arc::new(exec)).unwrap();
        assert_eq!(svc.config().threads, expected);
        let rec = submit(&svc).await.unwrap();
        let done = wait_for(&svc, rec.id, |r| r.state.is_final()).await;
        assert_eq!(done.state, JobState::Succeeded, "{done:?}");
        let summary = done.summary.unwrap();
        assert_eq!(summary["threads"], expected, "threads = {threads}");
        assert_eq!(summary["distinct"], expected, "threads = {threads}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_finish_after_the_lease_was_taken_over_writes_nothing_and_removes_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let (go_tx, go_rx) = std::sync::mpsc::channel::<()>();
    let go_rx = std::sync::Mutex::new(go_rx);
    let exec = move |job: &JobInput, _: &Progress| -> Result<JobOutcome, ExecError> {
        go_rx.lock().unwrap().recv().unwrap();
        std::fs::write(job.out_dir.join("late.msh"), b"late").unwrap();
        Ok(JobOutcome::default())
    };
    // Heartbeats rarer than the test, so the finish, not a heartbeat, meets the fence.
    let cfg =
        JobsConfig { heartbeat: Duration::from_secs(3600), lease: Duration::from_secs(3 * 3600), ..config(dir.path()) };
    let svc = JobService::start(cfg.clone(), Arc::new(exec)).unwrap();
    let rec = submit(&svc).await.unwrap();
    wait_for(&svc, rec.id, |r| r.state == JobState::Running).await;
    // Another process takes the job over (as after an expired lease): attempt 2, another owner.
    let other = SqliteStore::open(&dir.path().join("meshatlas.sqlite3")).unwrap();
    assert_eq!(other.reap_expired(3, &|_: &str| true).unwrap().requeued, vec![rec.id]);
    other.claim(rec.id, "other-host/1/x", Duration::from_secs(3600)).unwrap().unwrap();
    go_tx.send(()).unwrap();
    let attempt1 = cfg.attempt_dir(rec.id, 1);
    let start = Instant::now();
    while attempt1.exists() && start.elapsed() < Duration::from_secs(10) {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(!attempt1.exists(), "the fenced-out attempt's files are removed");
    let j = other.get(rec.id).unwrap().unwrap();
    assert_eq!((j.state, j.attempts, j.artifacts.len()), (JobState::Running, 2, 0), "the record is the new attempt's");
    assert!(cfg.input_path(rec.id, "x.stl").exists(), "the job's input stays for the new attempt");
}
