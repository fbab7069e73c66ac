//! Queue throughput and time-to-start, embedded against PostgreSQL + S3.
//!
//! `cargo bench --bench queue -- [--pg URL] [--s3 BUCKET] [--jobs N] [--large FILE]`
//!
//! A burst of N small jobs (default 200; the 80-triangle icosphere, no
//! stage) is posted as fast as one client can, then polled to the end. For
//! each configuration it prints jobs per minute (first POST to last end) and
//! the p50 / p99 time to start (the job's `started_at` minus `created_at`):
//! - `embedded, 1 worker` / `embedded, 3 workers`: `serve --workers 1|3`
//!   on SQLite;
//! - `postgres, 1 worker` / `postgres, 3 workers`: one `serve --no-worker`
//!   and 1 or 3 `worker` processes on a fresh database of the server at
//!   `--pg` (or `$MESHATLAS_TEST_PG_URL`; `source .ci/services.sh &&
//!   start_postgres` starts one), skipped without it. With `--s3 BUCKET`
//!   (or `$MESHATLAS_TEST_S3_BUCKET`, with the `AWS_*` variables of
//!   `.ci/services.sh`'s `start_s3`) the artifacts go to a fresh prefix of
//!   that bucket and every process has a data directory of its own, as on
//!   separate machines; without it they share one data directory.
//!
//! With `--large FILE` one job with stages atlas and crossfield runs on the
//! embedded default and on PostgreSQL, and the overhead of the distributed
//! path (POST to `succeeded`) is printed.

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// A child process and its base URL; killed on drop.
struct Proc {
    child: Child,
    base: String,
}

impl Proc {
    fn start(args: &[&str], data: &Path) -> Proc {
        let mut child = Command::new(env!("CARGO_BIN_EXE_meshatlas"))
            .args(args)
            .args(["--addr", "127.0.0.1:0", "--max-queued", "100000"].iter().filter(|_| args[0] == "serve"))
            .args(["--addr", "127.0.0.1:0"].iter().filter(|_| args[0] == "worker"))
            .arg("--data-dir")
            .arg(data)
            .env("MESHATLAS_LOG", "warn")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start meshatlas");
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let addr = line.trim().strip_prefix("listening on ").unwrap_or_else(|| panic!("unexpected line {line:?}"));
        Proc { child, base: format!("http://{addr}") }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The stores of one distributed configuration: a fresh database and,
/// when a bucket is given, a fresh prefix of it.
struct Distributed {
    store: String,
    artifacts: Option<String>,
    /// The shared data directory when there is no bucket.
    shared: tempfile::TempDir,
    /// Per-process data directories (S3 only), kept until the end.
    own: std::cell::RefCell<Vec<tempfile::TempDir>>,
}

impl Distributed {
    fn new(pg: &str, bucket: Option<&str>) -> Distributed {
        Distributed {
            store: meshatlas::jobs::pg_store::create_test_database(pg),
            artifacts: bucket.map(|b| format!("s3://{b}/bench_{}", uuid::Uuid::new_v4().simple())),
            shared: tempfile::tempdir().unwrap(),
            own: Default::default(),
        }
    }

    /// Starts `role` (`serve --no-worker` or `worker`) on these stores.
    fn start(&self, role: &[&str]) -> Proc {
        let mut args: Vec<&str> = role.to_vec();
        args.extend(["--store", &self.store]);
        let Some(artifacts) = &self.artifacts else { return Proc::start(&args, self.shared.path()) };
        args.extend(["--artifacts", artifacts]);
        let dir = tempfile::tempdir().unwrap();
        let p = Proc::start(&args, dir.path());
        self.own.borrow_mut().push(dir);
        p
    }

    fn label(&self) -> &'static str {
        if self.artifacts.is_some() { "postgres+s3" } else { "postgres" }
    }
}

/// An 80-triangle icosphere as binary STL (the library's writer).
fn small_stl() -> Vec<u8> {
    let mut out = Vec::new();
    meshatlas::io::stl_write::write_stl_binary(&mut out, &meshatlas::mesh::fixtures::icosphere(1)).expect("write STL");
    out
}

/// Milliseconds of an RFC 3339 UTC timestamp as the API writes it
/// (`YYYY-MM-DDTHH:MM:SS.mmmZ`), from the start of its day (the bench's
/// jobs start and end within minutes; a midnight crossing shows as a
/// negative time and is reported).
fn ms_of_day(t: &str) -> Option<f64> {
    let time = t.split('T').nth(1)?.trim_end_matches('Z');
    let mut parts = time.split(':');
    let (h, m, s): (f64, f64, f64) =
        (parts.next()?.parse().ok()?, parts.next()?.parse().ok()?, parts.next()?.parse().ok()?);
    Some(((h * 60.0 + m) * 60.0 + s) * 1000.0)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Posts `n` jobs to `api`, waits for all; prints one row.
async fn burst(label: &str, api: &Proc, n: usize, body: &[u8]) {
    let client = reqwest::Client::new();
    let start = Instant::now();
    let mut ids = Vec::with_capacity(n);
    for _ in 0..n {
        let r = client
            .post(format!("{}/v1/jobs?format=stl&params=%7B%22stages%22%3A%5B%5D%7D", api.base))
            .body(body.to_vec())
            .send()
            .await
            .expect("POST");
        assert_eq!(r.status(), 202, "{}", r.text().await.unwrap_or_default());
        ids.push(r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string());
    }
    let posted = start.elapsed().as_secs_f64();
    let mut waits = Vec::with_capacity(n);
    for id in &ids {
        loop {
            let j: Value = client.get(format!("{}/v1/jobs/{id}", api.base)).send().await.unwrap().json().await.unwrap();
            match j["state"].as_str() {
                Some("succeeded") => {
                    let (c, s) =
                        (j["created_at"].as_str().and_then(ms_of_day), j["started_at"].as_str().and_then(ms_of_day));
                    if let (Some(c), Some(s)) = (c, s) {
                        waits.push((s - c) / 1000.0);
                    }
                    break;
                }
                Some("failed" | "cancelled") => panic!("job {id} ended {j}"),
                _ => tokio::time::sleep(Duration::from_millis(5)).await,
            }
        }
    }
    let total = start.elapsed().as_secs_f64();
    waits.sort_by(f64::total_cmp);
    println!(
        "{label:<24} {n:>5} {posted:>9.2} {total:>9.2} {:>10.0} {:>9.3} {:>9.3}",
        n as f64 / total * 60.0,
        percentile(&waits, 0.5),
        percentile(&waits, 0.99)
    );
}

/// One large job through `api`: seconds from POST to `succeeded`.
async fn large_job(api: &Proc, file: &Path) -> f64 {
    let client = reqwest::Client::new();
    let body = std::fs::read(file).expect("read --large");
    let start = Instant::now();
    let r = client
        .post(format!("{}/v1/jobs?format=stl&stages=atlas,crossfield", api.base))
        .body(body)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 202);
    let id = r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string();
    loop {
        let j: Value = client.get(format!("{}/v1/jobs/{id}", api.base)).send().await.unwrap().json().await.unwrap();
        match j["state"].as_str() {
            Some("succeeded") => return start.elapsed().as_secs_f64(),
            Some("failed" | "cancelled") => panic!("large job ended {j}"),
            _ => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    let value = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1)).cloned();
    let n: usize = value("--jobs").map_or(200, |v| v.parse().expect("--jobs N"));
    let pg = value("--pg").or_else(|| std::env::var("MESHATLAS_TEST_PG_URL").ok());
    let bucket = value("--s3").or_else(|| std::env::var("MESHATLAS_TEST_S3_BUCKET").ok());
    let large = value("--large").map(PathBuf::from);
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    let body = small_stl();
    println!(
        "{:<24} {:>5} {:>9} {:>9} {:>10} {:>9} {:>9}",
        "configuration", "jobs", "posted s", "total s", "jobs/min", "p50 wait", "p99 wait"
    );
    for workers in ["1", "3"] {
        let dir = tempfile::tempdir().unwrap();
        let api = Proc::start(&["serve", "--workers", workers], dir.path());
        rt.block_on(burst(&format!("embedded, {workers} worker(s)"), &api, n, &body));
    }
    let Some(pg) = pg else {
        println!("postgres: skipped (give --pg URL or set MESHATLAS_TEST_PG_URL)");
        return;
    };
    for workers in [1, 3] {
        let d = Distributed::new(&pg, bucket.as_deref());
        let api = d.start(&["serve", "--no-worker"]);
        let _ws: Vec<Proc> = (0..workers).map(|_| d.start(&["worker"])).collect();
        rt.block_on(burst(&format!("{}, {workers} worker(s)", d.label()), &api, n, &body));
    }
    if let Some(file) = large {
        let dir = tempfile::tempdir().unwrap();
        let api = Proc::start(&["serve"], dir.path());
        let embedded = rt.block_on(large_job(&api, &file));
        drop(api);
        let d = Distributed::new(&pg, bucket.as_deref());
        let api = d.start(&["serve", "--no-worker"]);
        let worker = d.start(&["worker"]);
        let distributed = rt.block_on(large_job(&api, &file));
        drop(worker);
        println!(
            "large job {}: embedded {embedded:.2} s, {} {distributed:.2} s, overhead {:+.1} %",
            file.display(),
            d.label(),
            (distributed / embedded - 1.0) * 100.0
        );
    }
}
