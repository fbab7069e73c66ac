//! Durability with the real binary: SIGKILL mid-job, restart, nothing lost;
//! a job interrupted `--max-attempts` times is failed with a clear reason;
//! SIGTERM puts the running job back in the queue without counting an attempt.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::fixtures;

/// A `meshatlas serve` child process on a free loopback port.
struct Proc {
    child: Child,
    base: String,
}

impl Proc {
    fn start(data_dir: &Path, extra: &[&str]) -> Proc {
        // One database per data directory in the PostgreSQL matrix, kept in it across restarts.
        let matrix_file = data_dir.join("matrix-store");
        if !matrix_file.exists()
            && let Some(url) = crate::common::matrix_database()
        {
            std::fs::write(&matrix_file, format!("{url}\n{}", crate::common::matrix_bucket_url())).unwrap();
        }
        let matrix = std::fs::read_to_string(&matrix_file).ok();
        let (store, artifacts) = match matrix.as_deref().and_then(|s| s.split_once('\n')) {
            Some((s, a)) => (Some(s), Some(a)),
            None => (None, None),
        };
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshatlas"));
        cmd.args(["serve", "--addr", "127.0.0.1:0", "--workers", "1"])
            .arg("--data-dir")
            .arg(data_dir)
            .args(store.iter().flat_map(|url| ["--store", url]))
            .args(artifacts.iter().flat_map(|url| ["--artifacts", url]))
            .args(extra)
            .env("MESHATLAS_LOG", "warn")
            .stderr(Stdio::inherit());
        let (child, base) = crate::shared::spawn_listening(cmd);
        Proc { child, base }
    }

    fn kill9(mut self) {
        self.child.kill().unwrap(); // SIGKILL on Unix
        self.child.wait().unwrap();
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

async fn job(client: &reqwest::Client, base: &str, id: &str) -> Value {
    client.get(format!("{base}/v1/jobs/{id}")).send().await.unwrap().json().await.unwrap()
}

async fn wait_for(client: &reqwest::Client, base: &str, id: &str, pred: impl Fn(&Value) -> bool) -> Value {
    let start = Instant::now();
    loop {
        let j = job(client, base, id).await;
        if pred(&j) {
            return j;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "timed out: {j:#}");
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
}

fn is_final(j: &Value) -> bool {
    matches!(j["state"].as_str(), Some("succeeded" | "failed" | "cancelled"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kill9_mid_job_loses_nothing_and_repeated_interruption_fails_the_job() {
    let dir = tempfile::tempdir().unwrap();
    let client = reqwest::Client::new();
    let stl = fixtures::stl_ascii(&fixtures::mesh());
    let slow = ["--test-job-delay-ms", "20000", "--max-attempts", "2"];

    let a = Proc::start(dir.path(), &slow);
    let mut ids = Vec::new();
    for _ in 0..3 {
        let r = client.post(format!("{}/v1/jobs?format=stl", a.base)).body(stl.clone()).send().await.unwrap();
        assert_eq!(r.status(), 202);
        ids.push(r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string());
    }
    let running = wait_for(&client, &a.base, &ids[0], |j| j["state"] == "running" && j["stage"] == "delay").await;
    assert_eq!(running["attempts"], 1);
    a.kill9();

    // Restart: all jobs listed; the interrupted one runs again (attempt 2).
    let b = Proc::start(dir.path(), &slow);
    let list: Value = client.get(format!("{}/v1/jobs", b.base)).send().await.unwrap().json().await.unwrap();
    let listed: Vec<&str> = list["jobs"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap()).collect();
    assert_eq!(listed, ids.iter().rev().map(String::as_str).collect::<Vec<_>>());
    let again = wait_for(&client, &b.base, &ids[0], |j| j["state"] == "running" && j["stage"] == "delay").await;
    assert_eq!(again["attempts"], 2);
    assert_eq!(job(&client, &b.base, &ids[1]).await["state"], "queued");
    b.kill9();

    // Second interruption with --max-attempts 2: failed with a clear reason; the others run.
    let c = Proc::start(dir.path(), &["--max-attempts", "2"]);
    let first = wait_for(&client, &c.base, &ids[0], is_final).await;
    assert_eq!(first["state"], "failed");
    assert_eq!(first["error"]["type"], "urn:meshatlas:problem:interrupted");
    assert!(first["error"]["detail"].as_str().unwrap().contains("2 times"), "{first:#}");
    for id in &ids[1..] {
        let j = wait_for(&client, &c.base, id, is_final).await;
        assert_eq!(j["state"], "succeeded", "{j:#}");
        assert_eq!(j["attempts"], 1);
        let names: Vec<&str> = j["artifacts"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
        assert!(names.contains(&"mesh.msh") && names.contains(&"report.json"), "{names:?}");
    }
    drop(c);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_requeues_the_running_job_without_counting_an_attempt() {
    let dir = tempfile::tempdir().unwrap();
    let client = reqwest::Client::new();
    let a = Proc::start(dir.path(), &["--test-job-delay-ms", "20000"]);
    let r = client
        .post(format!("{}/v1/jobs?format=stl", a.base))
        .body(fixtures::stl_ascii(&fixtures::mesh()))
        .send()
        .await
        .unwrap();
    let id = r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string();
    wait_for(&client, &a.base, &id, |j| j["state"] == "running").await;
    let pid = a.child.id().to_string();
    let t = Instant::now();
    assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
    let mut a = a;
    let status = a.child.wait().unwrap();
    assert!(status.success(), "graceful exit, got {status}");
    assert!(t.elapsed() < Duration::from_secs(5), "shutdown took {:?}", t.elapsed());
    let b = Proc::start(dir.path(), &[]);
    let j = wait_for(&client, &b.base, &id, is_final).await;
    assert_eq!(j["state"], "succeeded", "{j:#}");
    assert_eq!(j["attempts"], 1);
}
