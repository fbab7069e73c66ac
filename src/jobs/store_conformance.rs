//! What every [`JobStore`] must do, as test functions over `&dyn JobStore`:
//! the SQLite store runs them in its unit tests, the PostgreSQL store
//! against a real server when `MESHATLAS_TEST_PG_URL` is set (CI).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use crate::failure::FailureKind;

use super::model::{Artifact, JobError, JobId, JobPage, JobRecord, JobState, now_ms};
use super::store::{Heartbeat, JobStore, Lease, NewRow};

const LONG: Duration = Duration::from_secs(60);

/// Inserts a queued job of `bytes` by `tenant` into a queue of `max`.
pub fn insert_as(s: &dyn JobStore, max: usize, tenant: Option<&str>, bytes: u64) -> Option<JobRecord> {
    let params = serde_json::json!({"stages": []});
    let new = NewRow {
        id: JobId::random(),
        input_name: "a.stl",
        input_bytes: bytes,
        format: Some("stl"),
        params: &params,
        memory_estimate_bytes: bytes,
        tenant,
    };
    s.insert_queued(&new, max).unwrap()
}

/// Inserts a queued job into a queue of `max`.
pub fn insert(s: &dyn JobStore, max: usize) -> Option<JobRecord> {
    insert_as(s, max, None, 10)
}

/// Claims the oldest queued job for `owner`; returns its record and lease.
pub fn claim_next(s: &dyn JobStore, owner: &str, lease: Duration) -> Option<(JobRecord, Lease)> {
    let head = s.queue_head(u64::MAX).unwrap()?;
    let rec = s.claim(head.id, owner, lease).unwrap()?;
    let l = Lease { id: rec.id, attempt: rec.attempts, owner: Arc::from(owner) };
    Some((rec, l))
}

/// Queue limit, claim, progress, success, cancel and delete.
pub fn lifecycle_and_queue_limit(s: &dyn JobStore) {
    let a = insert(s, 2).unwrap();
    assert_eq!(a.state, JobState::Queued);
    assert_eq!(a.format.as_deref(), Some("stl"));
    let b = insert(s, 2).unwrap();
    assert!(insert(s, 2).is_none(), "third job must be refused by a queue of 2");
    let (claimed, lease) = claim_next(s, "w1", LONG).unwrap();
    assert_eq!((claimed.id, claimed.state, claimed.attempts), (a.id, JobState::Running, 1));
    assert!(insert(s, 2).is_some(), "claiming frees a queue slot");
    let secs = BTreeMap::from([("load".to_string(), 0.5)]);
    let row = ("load".to_string(), 0.25, secs.clone());
    assert_eq!(s.heartbeat(&lease, LONG, Some(&row)).unwrap(), Heartbeat::Held { cancel_requested: false });
    let got = s.get(a.id).unwrap().unwrap();
    assert_eq!((got.stage.as_deref(), got.progress), (Some("load"), 0.25));
    let art = vec![Artifact { name: "report.json".into(), bytes: 3, media_type: "application/json".into() }];
    assert!(s.finish_succeeded(&lease, &serde_json::json!({"x": 1}), &secs, &art).unwrap());
    let got = s.get(a.id).unwrap().unwrap();
    assert_eq!(got.state, JobState::Succeeded);
    assert_eq!(got.artifacts, art);
    assert_eq!(got.summary, Some(serde_json::json!({"x": 1})));
    assert_eq!(s.heartbeat(&lease, LONG, None).unwrap(), Heartbeat::Lost, "a finished job holds no lease");
    assert!(!s.cancel_queued(a.id).unwrap());
    assert!(s.cancel_queued(b.id).unwrap());
    assert_eq!(s.get(b.id).unwrap().unwrap().state, JobState::Cancelled);
    assert!(s.delete(b.id).unwrap());
    assert!(s.get(b.id).unwrap().is_none());
    assert!(!s.delete(b.id).unwrap());
}

/// A failure's kind and detail come back as stored.
pub fn failure_kinds_round_trip(s: &dyn JobStore) {
    insert(s, 10).unwrap();
    let (a, lease) = claim_next(s, "w1", LONG).unwrap();
    let e = JobError::new(FailureKind::InvalidTargetSize, "no interior lattice point");
    assert!(s.finish_failed(&lease, &e, &BTreeMap::new()).unwrap());
    assert_eq!(s.get(a.id).unwrap().unwrap().error, Some(e));
}

/// Newest first, `limit` per page, a cursor to the next.
pub fn list_is_newest_first_and_paginates(s: &dyn JobStore) {
    let ids: Vec<JobId> = (0..5).map(|_| insert(s, 100).unwrap().id).collect();
    let p1 = s.list(2, None, None).unwrap();
    assert_eq!(p1.jobs.iter().map(|j| j.id).collect::<Vec<_>>(), vec![ids[4], ids[3]]);
    let p2 = s.list(2, p1.next_cursor, None).unwrap();
    assert_eq!(p2.jobs.iter().map(|j| j.id).collect::<Vec<_>>(), vec![ids[2], ids[1]]);
    let p3 = s.list(2, p2.next_cursor, None).unwrap();
    assert_eq!(p3.jobs.iter().map(|j| j.id).collect::<Vec<_>>(), vec![ids[0]]);
    assert_eq!(p3.next_cursor, None);
}

/// A live lease is not reaped; an expired one (or a dead owner) is. Only an
/// owner proven dead counts a crash; the second crash or `max_attempts`
/// claims fail the job, and a lease that merely lapsed is retried up to
/// `max_attempts` (a paused or remote worker is not a crashed server).
pub fn reaping_follows_leases_and_counts_crashes(s: &dyn JobStore) {
    let never = |_: &str| false;
    let a = insert(s, 10).unwrap();
    let (c, _) = claim_next(s, "w1", LONG).unwrap();
    assert_eq!((c.id, c.attempts, c.crashes), (a.id, 1, 0));
    assert_eq!(s.reap_expired(3, &never).unwrap().requeued, vec![], "a live lease is not reaped");
    assert_eq!(s.reap_expired(3, &|o: &str| o == "w1").unwrap().requeued, vec![a.id], "a dead owner is reaped");
    let head = s.queue_head(u64::MAX).unwrap().unwrap();
    assert_eq!((head.id, head.crashes), (a.id, 1));
    let (c, _) = claim_next(s, "w2", Duration::from_millis(1)).unwrap();
    assert_eq!((c.attempts, c.crashes), (2, 1));
    std::thread::sleep(Duration::from_millis(30));
    let rec = s.reap_expired(3, &never).unwrap();
    assert_eq!(rec.requeued, vec![a.id], "a lapsed lease is an interruption, not a second crash");
    assert_eq!(s.get(a.id).unwrap().unwrap().crashes, 1);
    claim_next(s, "w3", LONG).unwrap();
    let rec = s.reap_expired(5, &|o: &str| o == "w3").unwrap();
    assert_eq!(rec.crashed, vec![a.id], "second proven death");
    let j = s.get(a.id).unwrap().unwrap();
    assert_eq!((j.state, j.crashes), (JobState::Failed, 2));
    assert_eq!(j.error.unwrap().kind, FailureKind::CrashedServer);
    // Leases that lapse without a death: interrupted at max_attempts, never crashed-server.
    let b = insert(s, 10).unwrap();
    for attempt in 1..=3 {
        let (c, _) = claim_next(s, &format!("p{attempt}"), Duration::from_millis(1)).unwrap();
        assert_eq!((c.id, c.attempts), (b.id, attempt));
        std::thread::sleep(Duration::from_millis(30));
        let rec = s.reap_expired(3, &never).unwrap();
        if attempt < 3 {
            assert_eq!(rec.requeued, vec![b.id]);
        } else {
            assert_eq!(rec.failed, vec![b.id]);
        }
    }
    let j = s.get(b.id).unwrap().unwrap();
    assert_eq!((j.crashes, j.error.unwrap().kind), (0, FailureKind::Interrupted));
    // max_attempts 1: the first interruption already fails it.
    let d = insert(s, 10).unwrap();
    claim_next(s, "w4", Duration::from_millis(1)).unwrap();
    std::thread::sleep(Duration::from_millis(30));
    assert_eq!(s.reap_expired(1, &never).unwrap().failed, vec![d.id]);
    assert_eq!(s.get(d.id).unwrap().unwrap().error.unwrap().kind, FailureKind::Interrupted);
    assert_eq!(s.count_by_state().unwrap()[&JobState::Failed], 3);
    assert!(s.claim(d.id, "w5", LONG).unwrap().is_none(), "a failed job cannot be claimed");
}

/// The attempt and owner fence every worker write: after the job was taken
/// again, the old attempt's heartbeat is lost and its finish changes nothing.
pub fn a_stale_attempt_is_fenced_out(s: &dyn JobStore) {
    let a = insert(s, 10).unwrap();
    let (_, old) = claim_next(s, "w1", Duration::from_millis(1)).unwrap();
    std::thread::sleep(Duration::from_millis(30));
    assert_eq!(s.reap_expired(3, &|_: &str| false).unwrap().requeued, vec![a.id]);
    let (_, new) = claim_next(s, "w2", LONG).unwrap();
    assert_eq!(new.attempt, 2);
    assert_eq!(s.heartbeat(&old, LONG, None).unwrap(), Heartbeat::Lost);
    let art = vec![Artifact { name: "late.msh".into(), bytes: 1, media_type: "model/x".into() }];
    assert!(!s.finish_succeeded(&old, &serde_json::json!({}), &BTreeMap::new(), &art).unwrap());
    let e = JobError::new(FailureKind::InternalError, "late");
    assert!(!s.finish_failed(&old, &e, &BTreeMap::new()).unwrap());
    assert!(!s.finish_cancelled(&old).unwrap());
    assert!(!s.requeue(&old).unwrap());
    // Same attempt number, another owner: fenced too.
    let other = Lease { owner: Arc::from("w3"), ..new.clone() };
    assert_eq!(s.heartbeat(&other, LONG, None).unwrap(), Heartbeat::Lost);
    assert!(s.finish_succeeded(&new, &serde_json::json!({}), &BTreeMap::new(), &[]).unwrap());
    let j = s.get(a.id).unwrap().unwrap();
    assert_eq!((j.state, j.attempts, j.artifacts.len()), (JobState::Succeeded, 2, 0));
}

/// A cancel request reaches the worker's next heartbeat; the worker then
/// records the cancel. A graceful requeue does not count the attempt.
pub fn cancel_requests_reach_the_heartbeat_and_requeue_keeps_the_count(s: &dyn JobStore) {
    let a = insert(s, 10).unwrap();
    assert!(!s.request_cancel(a.id).unwrap(), "a queued job is cancelled directly, not flagged");
    let (_, lease) = claim_next(s, "w1", LONG).unwrap();
    assert!(s.request_cancel(a.id).unwrap());
    assert!(s.get(a.id).unwrap().unwrap().stop_requested);
    assert_eq!(s.heartbeat(&lease, LONG, None).unwrap(), Heartbeat::Held { cancel_requested: true });
    assert!(s.finish_cancelled(&lease).unwrap());
    assert_eq!(s.get(a.id).unwrap().unwrap().state, JobState::Cancelled);
    let b = insert(s, 10).unwrap();
    let (_, lease) = claim_next(s, "w1", LONG).unwrap();
    assert!(s.requeue(&lease).unwrap());
    let (c, _) = claim_next(s, "w2", LONG).unwrap();
    assert_eq!((c.id, c.attempts, c.stop_requested), (b.id, 1, false), "requeued, attempt not counted, flag clear");
    assert!(s.delete(b.id).unwrap());
    assert_eq!(s.heartbeat(&lease, LONG, None).unwrap(), Heartbeat::Lost, "a deleted job's lease is lost");
}

/// The queue head skips jobs larger than the asking worker's budget.
pub fn the_queue_head_skips_jobs_above_the_budget(s: &dyn JobStore) {
    let big = insert_as(s, 10, None, 1000).unwrap();
    let small = insert_as(s, 10, None, 10).unwrap();
    assert_eq!(s.queue_head(u64::MAX).unwrap().unwrap().id, big.id);
    assert_eq!(s.queue_head(999).unwrap().unwrap().id, small.id);
    assert!(s.queue_head(9).unwrap().is_none());
}

/// Tenants scope listing, queue counts and stored bytes; retention finds
/// finished jobs by their end time.
pub fn tenants_scope_lists_counts_and_stored_bytes(s: &dyn JobStore) {
    let add = |t: Option<&str>, bytes: u64| insert_as(s, 100, t, bytes).unwrap().id;
    let a1 = add(Some("a"), 100);
    let b1 = add(Some("b"), 10);
    let a2 = add(Some("a"), 1000);
    let anon = add(None, 1);
    let ids = |p: JobPage| p.jobs.iter().map(|j| j.id).collect::<Vec<_>>();
    assert_eq!(ids(s.list(10, None, Some("a")).unwrap()), vec![a2, a1]);
    assert_eq!(ids(s.list(10, None, Some("b")).unwrap()), vec![b1]);
    assert_eq!(ids(s.list(10, None, None).unwrap()), vec![anon, a2, b1, a1]);
    assert_eq!(s.owner(a1).unwrap(), Some(Some("a".to_string())));
    assert_eq!(s.owner(anon).unwrap(), Some(None));
    assert_eq!(s.owner(JobId::random()).unwrap(), None);
    assert_eq!(s.queued_count_of("a").unwrap(), 2);
    assert_eq!(s.stored_bytes(Some("a")).unwrap(), 1100);
    assert_eq!(s.stored_bytes(None).unwrap(), 1111);
    let (claimed, lease) = claim_next(s, "w", LONG).unwrap();
    assert_eq!(claimed.id, a1);
    let art = vec![
        Artifact { name: "x".into(), bytes: 5, media_type: "t".into() },
        Artifact { name: "y".into(), bytes: 7, media_type: "t".into() },
    ];
    s.finish_succeeded(&lease, &serde_json::json!({}), &BTreeMap::new(), &art).unwrap();
    assert_eq!(s.stored_bytes(Some("a")).unwrap(), 1112);
    assert_eq!(s.queued_count_of("a").unwrap(), 1);
    assert_eq!(s.queued_count().unwrap(), 3);
    assert_eq!(s.finished_before(now_ms() + 1).unwrap(), vec![a1]);
    assert!(s.finished_before(now_ms() - 60_000).unwrap().is_empty());
    assert!(!s.delete_if_final(a2).unwrap(), "a queued job is not deleted");
    assert!(s.delete_if_final(a1).unwrap());
    assert_eq!(s.stored_bytes(None).unwrap(), 1011);
    assert_eq!(s.all_ids().unwrap().len(), 3);
    s.probe_write().unwrap();
}

/// Two workers racing for one job: exactly one claim wins.
pub fn one_claim_wins_a_race(s: &dyn JobStore) {
    let a = insert(s, 10).unwrap();
    let wins: usize = std::thread::scope(|sc| {
        let hs: Vec<_> = (0..4)
            .map(|w| sc.spawn(move || usize::from(s.claim(a.id, &format!("w{w}"), LONG).unwrap().is_some())))
            .collect();
        hs.into_iter().map(|h| h.join().unwrap()).sum()
    });
    assert_eq!(wins, 1);
}

/// Workers register their budgets; only recently seen ones count.
pub fn workers_register_their_budgets(s: &dyn JobStore) {
    assert_eq!(s.largest_worker_budget(LONG).unwrap(), None, "no worker yet");
    s.register_worker("a", 100).unwrap();
    s.register_worker("b", 300).unwrap();
    s.register_worker("a", 200).unwrap();
    assert_eq!(s.largest_worker_budget(LONG).unwrap(), Some(300));
    // b is last seen 200 ms before a; the window reaches back past a's
    // registration by half that gap, so a slow write or query on a busy
    // host (a file-backed store under CI load took over 20 ms) does not
    // push a out of it nor b into it.
    std::thread::sleep(Duration::from_millis(200));
    let before_a = std::time::Instant::now();
    s.register_worker("a", 200).unwrap();
    let window = before_a.elapsed() + Duration::from_millis(100);
    assert_eq!(s.largest_worker_budget(window).unwrap(), Some(200), "b was not seen lately");
}

/// Every conformance test, each on a fresh store from `fresh`.
pub fn run_all(fresh: &dyn Fn() -> Box<dyn JobStore>) {
    lifecycle_and_queue_limit(&*fresh());
    failure_kinds_round_trip(&*fresh());
    list_is_newest_first_and_paginates(&*fresh());
    reaping_follows_leases_and_counts_crashes(&*fresh());
    a_stale_attempt_is_fenced_out(&*fresh());
    cancel_requests_reach_the_heartbeat_and_requeue_keeps_the_count(&*fresh());
    the_queue_head_skips_jobs_above_the_budget(&*fresh());
    tenants_scope_lists_counts_and_stored_bytes(&*fresh());
    one_claim_wins_a_race(&*fresh());
    workers_register_their_budgets(&*fresh());
}
