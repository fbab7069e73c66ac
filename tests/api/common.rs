//! Test server and helpers.

use std::sync::Arc;
use std::time::{Duration, Instant};

use meshatlas::failure::FailureKind;
use meshatlas::http::{AppState, HttpLimits};
use meshatlas::jobs::{ExecError, Executor, JobError, JobInput, JobOutcome, JobService, JobsConfig};
use meshatlas::progress::Progress;
use serde_json::Value;

/// A server on 127.0.0.1:<random port> with its own data directory.
pub struct Server {
    pub base: String,
    pub client: reqwest::Client,
    #[allow(dead_code)]
    pub jobs: JobService,
    pub dir: tempfile::TempDir,
}

impl Server {
    /// Starts a server running `exec`, after `tweak` adjusts the defaults.
    pub async fn start(exec: Arc<dyn Executor>, tweak: impl FnOnce(&mut JobsConfig, &mut HttpLimits)) -> Server {
        let dir = tempfile::tempdir().unwrap();
        let mut cfg = JobsConfig { progress_interval: Duration::from_millis(10), ..JobsConfig::new(dir.path()) };
        if let Some(url) = matrix_database() {
            cfg.store = meshatlas::jobs::StoreLocation::Postgres(url);
            cfg.artifacts = matrix_bucket();
        }
        let mut limits = HttpLimits::default();
        tweak(&mut cfg, &mut limits);
        let jobs = JobService::start(cfg, exec).unwrap();
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let state = AppState { jobs: jobs.clone(), limits: Arc::new(limits), auth: None };
        tokio::spawn(meshatlas::http::serve(listener, state, std::future::pending()));
        // Identity bytes: no automatic `Accept-Encoding: gzip` (the gzip encoding is tested in `tests/hostile`).
        let client = reqwest::Client::builder().no_gzip().build().unwrap();
        Server { base: format!("http://{addr}"), client, jobs, dir }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// Submits `body` raw to `POST /v1/jobs{query}` and returns the response.
    pub async fn submit_raw(&self, query: &str, content_type: &str, body: Vec<u8>) -> reqwest::Response {
        self.client
            .post(self.url(&format!("/v1/jobs{query}")))
            .header("content-type", content_type)
            .body(body)
            .send()
            .await
            .unwrap()
    }

    /// Submits and expects 202; returns the job JSON.
    pub async fn submit_ok(&self, query: &str, content_type: &str, body: Vec<u8>) -> Value {
        let resp = self.submit_raw(query, content_type, body).await;
        let status = resp.status();
        let loc = resp.headers().get("location").map(|v| v.to_str().unwrap().to_string());
        let json: Value = resp.json().await.unwrap();
        assert_eq!(status, 202, "{json}");
        assert_eq!(loc.as_deref(), json["url"].as_str());
        json
    }

    pub async fn get_job(&self, id: &str) -> Value {
        let resp = self.client.get(self.url(&format!("/v1/jobs/{id}"))).send().await.unwrap();
        assert_eq!(resp.status(), 200);
        resp.json().await.unwrap()
    }

    /// Polls until the job reaches a final state (or `pred` holds).
    pub async fn wait_until(&self, id: &str, pred: impl Fn(&Value) -> bool) -> Value {
        let start = Instant::now();
        loop {
            let job = self.get_job(id).await;
            if pred(&job) {
                return job;
            }
            assert!(start.elapsed() < Duration::from_secs(60), "timed out waiting; job: {job:#}");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    pub async fn wait_final(&self, id: &str) -> Value {
        self.wait_until(id, |j| matches!(j["state"].as_str(), Some("succeeded" | "failed" | "cancelled"))).await
    }
}

/// The job store of the test matrix: with `MESHATLAS_TEST_MATRIX=postgres`
/// (`.ci/run` runs this suite a second time so) every server of the suite
/// keeps its jobs in a fresh PostgreSQL database on `MESHATLAS_TEST_PG_URL`;
/// otherwise `None`, the embedded SQLite default.
pub fn matrix_database() -> Option<String> {
    match std::env::var("MESHATLAS_TEST_MATRIX").as_deref() {
        Ok("postgres") => {
            let admin = std::env::var("MESHATLAS_TEST_PG_URL")
                .expect("MESHATLAS_TEST_MATRIX=postgres needs MESHATLAS_TEST_PG_URL");
            Some(meshatlas::jobs::pg_store::create_test_database(&admin))
        }
        Ok("") | Ok("sqlite") | Err(_) => None,
        Ok(other) => panic!("MESHATLAS_TEST_MATRIX must be sqlite or postgres, not {other}"),
    }
}

/// The artifact store of the PostgreSQL matrix: a fresh prefix of the S3
/// test bucket (`MESHATLAS_TEST_S3_BUCKET`, endpoint and keys from the
/// `AWS_*` variables `.ci/services.sh` exports).
pub fn matrix_bucket() -> meshatlas::jobs::artifact_store::ArtifactLocation {
    meshatlas::jobs::artifact_store::ArtifactLocation::parse(&matrix_bucket_url()).unwrap()
}

/// [`matrix_bucket`] as an `--artifacts` URL.
pub fn matrix_bucket_url() -> String {
    let bucket =
        std::env::var("MESHATLAS_TEST_S3_BUCKET").expect("MESHATLAS_TEST_MATRIX=postgres needs the S3 test bucket");
    format!("s3://{bucket}/t_{}", uuid::Uuid::new_v4().simple())
}

/// Checks a problem+json response: status, type kind, request id in body
/// and header. Returns the body.
pub async fn expect_problem(resp: reqwest::Response, status: u16, kind: &str) -> Value {
    assert_eq!(resp.status().as_u16(), status, "unexpected status");
    let ct = resp.headers().get("content-type").map(|v| v.to_str().unwrap().to_string());
    assert_eq!(ct.as_deref(), Some("application/problem+json"));
    let header_id = resp.headers().get("x-request-id").map(|v| v.to_str().unwrap().to_string());
    let body: Value = resp.json().await.unwrap();
    assert_eq!(body["type"], format!("urn:meshatlas:problem:{kind}"), "{body:#}");
    assert_eq!(body["status"], status);
    assert!(body["title"].as_str().is_some_and(|t| !t.is_empty()));
    assert!(body["detail"].as_str().is_some_and(|t| !t.is_empty()));
    let id = body["request_id"].as_str().expect("request_id in body");
    assert_eq!(Some(id), header_id.as_deref());
    body
}

/// Executor that copies the input to `copy.bin` and reports its size.
pub fn copy_exec() -> Arc<dyn Executor> {
    Arc::new(|job: &JobInput, p: &Progress| -> Result<JobOutcome, ExecError> {
        let bytes = std::fs::read(&job.input)
            .map_err(|e| ExecError::Failed(JobError::new(FailureKind::InternalError, e.to_string())))?;
        let s = p.stage("copy", 0.0, 1.0);
        std::fs::write(job.out_dir.join("copy.bin"), &bytes).unwrap();
        s.set(1.0);
        Ok(JobOutcome {
            summary: serde_json::json!({"bytes": bytes.len(), "params": job.params, "format": job.format}),
            stage_seconds: [("copy".to_string(), 0.0)].into(),
            artifacts: vec![],
        })
    })
}

/// Executor that reports stage `spin` at 50 % and waits for cancellation.
pub fn spin_exec() -> Arc<dyn Executor> {
    Arc::new(|_: &JobInput, p: &Progress| -> Result<JobOutcome, ExecError> {
        p.stage("spin", 0.0, 1.0).set(0.5);
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(30) {
            p.check().map_err(|_| ExecError::Cancelled)?;
            std::thread::sleep(Duration::from_millis(5));
        }
        Err(ExecError::Failed(JobError::new(FailureKind::InternalError, "never cancelled")))
    })
}
