//! The distributed path with real processes: API replicas (`serve
//! --no-worker`) and workers (`worker`) on one PostgreSQL database (started
//! by `.ci/run`, URL in `MESHATLAS_TEST_PG_URL`) and one data directory.
//! Leases are 2 s with a heartbeat every 0.5 s, so expiry takes seconds.

#[path = "../api/fixtures.rs"]
#[allow(dead_code)]
mod fixtures;

mod cluster;
#[path = "../common/mod.rs"]
mod shared;

use std::time::{Duration, Instant};

use cluster::{Artifacts, Cluster, is_final};
use serde_json::Value;

/// The names and bytes of a finished job's artifacts, downloaded through `api`.
async fn artifacts(c: &Cluster, api: &cluster::Proc, job: &Value) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for a in job["artifacts"].as_array().unwrap() {
        let name = a["name"].as_str().unwrap().to_string();
        let r = c.client.get(format!("{}/v1/jobs/{}/artifacts/{name}", api.base, job["id"].as_str().unwrap()));
        let resp = r.send().await.unwrap();
        assert_eq!(resp.status(), 200, "{name}");
        out.push((name, resp.bytes().await.unwrap().to_vec()));
    }
    out
}

async fn sixty_jobs_over_two_apis_and_three_workers_each_run_once(c: Cluster) {
    let apis = [c.api(&["--max-queued", "1000"]), c.api(&["--max-queued", "1000"])];
    let workers = [c.worker(&[]), c.worker(&[]), c.worker(&[])];
    let mut ids = Vec::new();
    for i in 0..60 {
        ids.push(c.submit(&apis[i % 2]).await);
    }
    for (i, id) in ids.iter().enumerate() {
        let j = c.wait_for(&apis[(i + 1) % 2], id, is_final).await;
        assert_eq!((j["state"].as_str(), j["attempts"].as_u64()), (Some("succeeded"), Some(1)), "{j:#}");
    }
    // Both APIs list all 60 and serve the same bytes.
    for api in &apis {
        let list: Value =
            c.client.get(format!("{}/v1/jobs?limit=100", api.base)).send().await.unwrap().json().await.unwrap();
        assert_eq!(list["jobs"].as_array().unwrap().len(), 60);
    }
    let j = c.job(&apis[0], &ids[7]).await;
    let (a, b) = (artifacts(&c, &apis[0], &j).await, artifacts(&c, &apis[1], &j).await);
    assert!(a.iter().any(|(n, _)| n == "mesh.msh"), "{a:?}");
    assert_eq!(a, b);
    // Each job was claimed exactly once, and every worker took some.
    let mut claims = Vec::new();
    for w in &workers {
        claims.push(w.metric(&c.client, "meshatlas_claims_total").await);
    }
    assert_eq!(claims.iter().sum::<f64>(), 60.0, "{claims:?}");
    assert!(claims.iter().all(|&n| n > 0.0), "every worker takes part: {claims:?}");
}

async fn a_killed_workers_job_is_rerun_by_another_worker(c: Cluster) {
    let api = c.api(&[]);
    let slow = c.worker(&["--test-job-delay-ms", "20000"]);
    let id = c.submit(&api).await;
    c.wait_for(&api, &id, |j| j["state"] == "running" && j["stage"] == "delay").await;
    let other = c.worker(&[]);
    let t = Instant::now();
    slow.kill9();
    let j = c.wait_for(&api, &id, is_final).await;
    assert_eq!((j["state"].as_str(), j["attempts"].as_u64()), (Some("succeeded"), Some(2)), "{j:#}");
    assert!(t.elapsed() < Duration::from_secs(10), "rerun took {:?}", t.elapsed());
    assert_eq!(other.metric(&c.client, "meshatlas_lease_expiries_total").await, 1.0);
}

async fn a_paused_workers_late_attempt_never_replaces_the_new_one(c: Cluster) {
    let api = c.api(&[]);
    // The first worker waits 2.5 s before the pipeline; it is paused inside that wait.
    let paused = c.worker(&["--test-job-delay-ms", "2500"]);
    let id = c.submit(&api).await;
    c.wait_for(&api, &id, |j| j["state"] == "running" && j["stage"] == "delay").await;
    paused.signal("-STOP");
    let t = Instant::now();
    let other = c.worker(&[]);
    let j = c.wait_for(&api, &id, is_final).await;
    assert_eq!((j["state"].as_str(), j["attempts"].as_u64()), (Some("succeeded"), Some(2)), "{j:#}");
    assert!(t.elapsed() >= Duration::from_millis(1500), "the lease (2 s) must expire first: {:?}", t.elapsed());
    let before = artifacts(&c, &api, &j).await;
    // Resumed past its delay, the old attempt runs the pipeline at once and
    // tries to finish; its lease is gone, so nothing of it may land.
    paused.signal("-CONT");
    let attempt1 = format!("jobs/{id}/out/1/report.json");
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(5) {
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let after = c.job(&api, &id).await;
    assert_eq!((after["state"].as_str(), after["attempts"].as_u64()), (Some("succeeded"), Some(2)), "{after:#}");
    assert_eq!(after["artifacts"], j["artifacts"]);
    assert_eq!(artifacts(&c, &api, &after).await, before, "the late attempt changed the artifacts");
    assert!(!c.stored(&attempt1), "the late attempt's files are removed");
    assert!(c.stored(&format!("jobs/{id}/out/2/report.json")), "the winner's files stay");
    drop(other);
}

async fn cancel_and_delete_through_one_api_stop_a_job_running_behind_another(c: Cluster) {
    let (a, b) = (c.api(&[]), c.api(&[]));
    let w = c.worker(&["--test-job-delay-ms", "30000", "--workers", "2"]);
    let (x, y) = (c.submit(&b).await, c.submit(&b).await);
    for id in [&x, &y] {
        c.wait_for(&b, id, |j| j["state"] == "running").await;
    }
    let t = Instant::now();
    let r = c.client.post(format!("{}/v1/jobs/{x}/cancel", a.base)).send().await.unwrap();
    assert!(r.status() == 202 || r.status() == 200, "{}", r.status());
    let j = c.wait_for(&b, &x, is_final).await;
    assert_eq!(j["state"], "cancelled");
    let bound = Duration::from_secs_f64(cluster::HEARTBEAT.parse::<f64>().unwrap() + 1.0);
    assert!(t.elapsed() <= bound, "cancel took {:?} (bound {bound:?})", t.elapsed());

    let input = c.job(&b, &y).await["input"]["name"].as_str().unwrap().to_string();
    let input_key = format!("jobs/{y}/input/{input}");
    assert!(c.stored(&input_key), "the upload is stored");
    let t = Instant::now();
    let r = c.client.delete(format!("{}/v1/jobs/{y}", a.base)).send().await.unwrap();
    assert!(r.status() == 202 || r.status() == 204, "{}", r.status());
    assert_eq!(c.client.get(format!("{}/v1/jobs/{y}", b.base)).send().await.unwrap().status(), 404);
    loop {
        if w.metric(&c.client, "meshatlas_workers_busy").await == 0.0 {
            break;
        }
        assert!(t.elapsed() <= bound, "the deleted job still runs after {:?}", t.elapsed());
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let start = Instant::now();
    while c.stored(&input_key) && start.elapsed() < Duration::from_secs(5) {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(!c.stored(&input_key), "the deleted job's files are removed");
}

async fn restarting_every_process_at_once_loses_no_job_and_finishes_each_once(c: Cluster) {
    let slow = ["--test-job-delay-ms", "400", "--workers", "2"];
    let apis = [c.api(&["--max-queued", "100"]), c.api(&["--max-queued", "100"])];
    let workers = [c.worker(&slow), c.worker(&slow)];
    let mut ids = Vec::new();
    for i in 0..20 {
        ids.push(c.submit(&apis[i % 2]).await);
    }
    c.wait_for(&apis[0], &ids[0], |j| j["state"] != "queued").await;
    for p in apis.into_iter().chain(workers) {
        p.kill9();
    }
    let apis = [c.api(&["--max-queued", "100"]), c.api(&["--max-queued", "100"])];
    let _workers = [c.worker(&[]), c.worker(&[])];
    for (i, id) in ids.iter().enumerate() {
        let j = c.wait_for(&apis[i % 2], id, is_final).await;
        assert_eq!(j["state"], "succeeded", "{j:#}");
        assert!(j["attempts"].as_u64().unwrap() <= 2, "{j:#}");
    }
    let list: Value =
        c.client.get(format!("{}/v1/jobs?limit=100", apis[1].base)).send().await.unwrap().json().await.unwrap();
    let listed = list["jobs"].as_array().unwrap();
    assert_eq!(listed.len(), 20, "every accepted job is there, once");
    assert!(listed.iter().all(|j| j["state"] == "succeeded"));
}

async fn a_worker_with_a_small_budget_leaves_a_large_job_to_a_larger_one(c: Cluster) {
    let api = c.api(&[]);
    let id = c.submit(&api).await;
    let alone = c.job(&api, &id).await;
    let msg = alone["status_message"].as_str().unwrap_or_default();
    assert!(msg.contains("no worker has been seen"), "{alone:#}");
    let small = c.worker(&["--memory-budget", "1KiB"]);
    let estimate = c.job(&api, &id).await["memory_estimate_bytes"].as_u64().unwrap();
    assert!(estimate > 1024, "the test job must not fit 1 KiB (estimate {estimate})");
    tokio::time::sleep(Duration::from_secs(2)).await;
    let waiting = c.job(&api, &id).await;
    assert_eq!(waiting["state"], "queued", "the small worker must leave it");
    let msg = waiting["status_message"].as_str().unwrap_or_default();
    assert!(
        msg.contains("exceeds the memory budget of every live worker") && msg.contains("1024 bytes"),
        "{waiting:#}"
    );
    let large = c.worker(&["--memory-budget", "4GiB"]);
    let j = c.wait_for(&api, &id, is_final).await;
    assert_eq!(j["state"], "succeeded", "{j:#}");
    assert!(j["status_message"].is_null(), "{j:#}");
    assert_eq!(small.metric(&c.client, "meshatlas_claims_total").await, 0.0);
    assert_eq!(large.metric(&c.client, "meshatlas_claims_total").await, 1.0);
}

async fn redirect_one_hands_out_a_presigned_url_with_s3_and_the_file_without(c: Cluster) {
    let (api, worker) = (c.api(&[]), c.worker(&[]));
    let id = c.submit(&api).await;
    let j = c.wait_for(&api, &id, is_final).await;
    assert_eq!(j["state"], "succeeded", "{j:#}");
    // The worker timed its heartbeat writes (progress goes out through them).
    assert!(worker.metric(&c.client, "meshatlas_heartbeat_write_seconds_count").await > 0.0);
    assert_eq!(worker.metric(&c.client, "meshatlas_heartbeat_age_seconds").await, 0.0, "it runs nothing now");
    let url = format!("{}/v1/jobs/{id}/artifacts/mesh.vtu", api.base);
    let direct = c.client.get(&url).send().await.unwrap().bytes().await.unwrap();
    let no_follow = reqwest::Client::builder().redirect(reqwest::redirect::Policy::none()).build().unwrap();
    let r = no_follow.get(format!("{url}?redirect=1")).send().await.unwrap();
    if c.artifacts == Artifacts::S3 {
        assert_eq!(r.status(), 307);
        assert_eq!(r.headers()["cache-control"], "no-store");
        let location = r.headers()["location"].to_str().unwrap().to_string();
        assert!(location.contains("X-Amz-Signature="), "{location}");
        // The bucket itself answers, without the API's token or cookies.
        let got = reqwest::get(&location).await.unwrap();
        assert_eq!(got.status(), 200, "{location}");
        assert_eq!(got.headers()["content-type"], "application/vnd.vtk.vtu+xml");
        assert_eq!(got.headers()["content-disposition"], "attachment; filename=\"mesh.vtu\"");
        assert_eq!(got.bytes().await.unwrap(), direct);
    } else {
        assert_eq!(r.status(), 200, "no URL of its own: the file is served");
        assert_eq!(r.bytes().await.unwrap(), direct);
    }
    let bad = c.client.get(format!("{url}?redirect=yes")).send().await.unwrap();
    assert_eq!(bad.status(), 400);
}

/// Uploads stream into the bucket as they arrive. One the API refuses after
/// reading it (an empty body; a `params` part that is not JSON, after a file
/// part larger than one multipart part) or that the client cuts off
/// half-way leaves no object and no job; an accepted one is in the bucket
/// when the 202 comes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn s3_uploads_refused_or_cut_off_leave_no_object() {
    let Some(c) = Cluster::new(Artifacts::S3) else { return };
    let api = c.api(&[]);
    let r = c.client.post(format!("{}/v1/jobs?format=stl", api.base)).body(Vec::new()).send().await.unwrap();
    assert_eq!(r.status(), 400, "{}", r.text().await.unwrap());
    let big = vec![b'x'; 11 << 20];
    let form = reqwest::multipart::Form::new()
        .part("file", reqwest::multipart::Part::bytes(big.clone()).file_name("big.stl"))
        .text("params", "{not json");
    let r = c.client.post(format!("{}/v1/jobs", api.base)).multipart(form).send().await.unwrap();
    assert_eq!(r.status(), 400);
    assert!(r.text().await.unwrap().contains("urn:meshatlas:problem:invalid-json"));
    {
        use tokio::io::AsyncWriteExt;
        let addr = api.base.trim_start_matches("http://").to_string();
        let mut tcp = tokio::net::TcpStream::connect(&addr).await.unwrap();
        let head =
            format!("POST /v1/jobs?format=stl HTTP/1.1\r\nHost: {addr}\r\nContent-Length: {}\r\n\r\n", 3 * big.len());
        tcp.write_all(head.as_bytes()).await.unwrap();
        tcp.write_all(&big).await.unwrap();
        tcp.flush().await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    assert_eq!(c.bucket_job_dirs(), Vec::<String>::new(), "objects of refused or cut-off uploads");
    let listed: Value = c.client.get(format!("{}/v1/jobs", api.base)).send().await.unwrap().json().await.unwrap();
    assert_eq!(listed["jobs"].as_array().map(Vec::len), Some(0), "{listed:#}");
    let id = c.submit(&api).await;
    assert!(c.stored(&format!("jobs/{id}/input/upload")), "the accepted upload is in the bucket");
}

/// Each scenario twice: artifacts in one shared data directory, and in an
/// S3 bucket with a data directory per process.
macro_rules! on_both_artifact_stores {
    ($($name:ident),* $(,)?) => {
        mod shared_dir {
            $(
                #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
                async fn $name() {
                    let Some(c) = super::Cluster::new(super::Artifacts::SharedDir) else { return };
                    super::$name(c).await;
                }
            )*
        }
        mod s3 {
            $(
                #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
                async fn $name() {
                    let Some(c) = super::Cluster::new(super::Artifacts::S3) else { return };
                    super::$name(c).await;
                }
            )*
        }
    };
}

on_both_artifact_stores!(
    sixty_jobs_over_two_apis_and_three_workers_each_run_once,
    a_killed_workers_job_is_rerun_by_another_worker,
    a_paused_workers_late_attempt_never_replaces_the_new_one,
    cancel_and_delete_through_one_api_stop_a_job_running_behind_another,
    restarting_every_process_at_once_loses_no_job_and_finishes_each_once,
    a_worker_with_a_small_budget_leaves_a_large_job_to_a_larger_one,
    redirect_one_hands_out_a_presigned_url_with_s3_and_the_file_without,
);
