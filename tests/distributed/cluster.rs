//! A cluster of real `meshatlas` processes on one PostgreSQL database: API
//! processes (`serve --no-worker`) and workers (`worker`), each a child
//! process on a loopback port. Artifacts are either one data directory
//! shared by all ([`Artifacts::SharedDir`]) or an S3 bucket
//! ([`Artifacts::S3`], the SeaweedFS `.ci/run` starts), each process then
//! with a data directory of its own.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// Lease and heartbeat of the test clusters (seconds): short, so expiry
/// tests take seconds.
pub const LEASE: &str = "2";
pub const HEARTBEAT: &str = "0.5";

/// One child process and the base URL it listens on.
pub struct Proc {
    pub child: Child,
    pub base: String,
}

impl Proc {
    fn spawn(role: &[&str], store: &str, artifacts: &str, data: &Path, extra: &[&str]) -> Proc {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshatlas"));
        cmd.args(role)
            .args(["--addr", "127.0.0.1:0", "--store", store, "--lease-secs", LEASE, "--heartbeat-secs", HEARTBEAT])
            .args(["--artifacts", artifacts])
            .arg("--data-dir")
            .arg(data)
            .args(extra)
            .env("MESHATLAS_LOG", "warn")
            .stderr(Stdio::inherit());
        let (child, base) = crate::shared::spawn_listening(cmd);
        Proc { child, base }
    }

    /// Sends `signal` (e.g. `-STOP`) to the process.
    pub fn signal(&self, signal: &str) {
        let pid = self.child.id().to_string();
        assert!(Command::new("kill").args([signal, &pid]).status().unwrap().success());
    }

    /// SIGKILL and reap.
    pub fn kill9(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    /// The value of the unlabelled metric `name` on this process's /metrics.
    pub async fn metric(&self, client: &reqwest::Client, name: &str) -> f64 {
        let text = client.get(format!("{}/metrics", self.base)).send().await.unwrap().text().await.unwrap();
        text.lines()
            .find_map(|l| l.strip_prefix(name).and_then(|v| v.strip_prefix(' ')))
            .unwrap_or_else(|| panic!("no metric {name}"))
            .trim()
            .parse()
            .unwrap()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Where a cluster keeps artifacts.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Artifacts {
    /// One data directory for every process.
    SharedDir,
    /// A fresh prefix of the test bucket; a data directory per process.
    S3,
}

/// A test's database, artifact store and data directories.
pub struct Cluster {
    pub store: String,
    pub artifacts: Artifacts,
    /// `--artifacts` of every process.
    artifacts_url: String,
    root: tempfile::TempDir,
    procs: std::sync::atomic::AtomicUsize,
    pub client: reqwest::Client,
}

impl Cluster {
    /// A new database and artifact store, or `None` without the servers.
    pub fn new(artifacts: Artifacts) -> Option<Cluster> {
        let artifacts_url = match artifacts {
            Artifacts::SharedDir => "file://".to_string(),
            Artifacts::S3 => {
                let Ok(_) = std::env::var("MESHATLAS_TEST_S3_ENDPOINT") else {
                    assert!(std::env::var_os("CI").is_none(), "CI must set MESHATLAS_TEST_S3_ENDPOINT (see .ci/run)");
                    eprintln!("MESHATLAS_TEST_S3_ENDPOINT is unset: S3 cluster tests skipped");
                    return None;
                };
                let bucket = std::env::var("MESHATLAS_TEST_S3_BUCKET").unwrap_or_else(|_| "meshatlas".into());
                format!("s3://{bucket}/t_{}", uuid::Uuid::new_v4().simple())
            }
        };
        let store = meshatlas::jobs::pg_store::test_database()?;
        let root = tempfile::tempdir().unwrap();
        Some(Cluster {
            store,
            artifacts,
            artifacts_url,
            root,
            procs: Default::default(),
            client: reqwest::Client::new(),
        })
    }

    /// The data directory of the next process: the shared one, or a new one with S3.
    fn data_dir(&self) -> PathBuf {
        let dir = match self.artifacts {
            Artifacts::SharedDir => self.root.path().join("shared"),
            Artifacts::S3 => {
                let n = self.procs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                self.root.path().join(format!("p{n}"))
            }
        };
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// `meshatlas serve --no-worker`.
    pub fn api(&self, extra: &[&str]) -> Proc {
        Proc::spawn(&["serve", "--no-worker"], &self.store, &self.artifacts_url, &self.data_dir(), extra)
    }

    /// `meshatlas worker`.
    pub fn worker(&self, extra: &[&str]) -> Proc {
        Proc::spawn(&["worker"], &self.store, &self.artifacts_url, &self.data_dir(), extra)
    }

    /// Whether any copy of the file `key` (`jobs/<id>/…`) is left: in the
    /// shared directory, or in the bucket.
    pub fn stored(&self, key: &str) -> bool {
        match self.artifacts {
            Artifacts::SharedDir => self.root.path().join("shared").join(key).exists(),
            Artifacts::S3 => {
                use meshatlas::jobs::artifact_store::{ArtifactLocation, open};
                let url = &self.artifacts_url;
                let store = open(&ArtifactLocation::parse(url).unwrap()).unwrap();
                let probe = tempfile::tempdir().unwrap();
                store.fetch(probe.path(), key).unwrap()
            }
        }
    }

    /// The job directories (`<id>`) that have objects in the bucket (S3
    /// only), read a second after the last write (S3 keeps times to the
    /// second) so that every object written so far is listed.
    pub fn bucket_job_dirs(&self) -> Vec<String> {
        use meshatlas::jobs::artifact_store::{ArtifactLocation, open};
        assert_eq!(self.artifacts, Artifacts::S3);
        std::thread::sleep(Duration::from_millis(1100));
        let store = open(&ArtifactLocation::parse(&self.artifacts_url).unwrap()).unwrap();
        store.job_dirs_older_than(Duration::ZERO).unwrap()
    }

    /// Submits the test mesh through `api`; returns the job id.
    pub async fn submit(&self, api: &Proc) -> String {
        let r = self
            .client
            .post(format!("{}/v1/jobs?format=stl", api.base))
            .body(crate::fixtures::stl_ascii(&crate::fixtures::mesh()))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 202);
        r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string()
    }

    pub async fn job(&self, api: &Proc, id: &str) -> Value {
        self.client.get(format!("{}/v1/jobs/{id}", api.base)).send().await.unwrap().json().await.unwrap()
    }

    /// Polls `api` until job `id` satisfies `pred` (60 s at most).
    pub async fn wait_for(&self, api: &Proc, id: &str, pred: impl Fn(&Value) -> bool) -> Value {
        let start = Instant::now();
        loop {
            let j = self.job(api, id).await;
            if pred(&j) {
                return j;
            }
            assert!(start.elapsed() < Duration::from_secs(60), "timed out: {j:#}");
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
    }
}

pub fn is_final(j: &Value) -> bool {
    matches!(j["state"].as_str(), Some("succeeded" | "failed" | "cancelled"))
}
