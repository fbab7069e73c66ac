//! The real server as a child process, and small helpers shared by the
//! hostile-client tests.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// `../shared/data/<rel>` next to the repository.
pub fn shared_data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data").join(rel)
}

/// The job and artifact stores of the test matrix for a server on
/// `data_dir`: with `MESHATLAS_TEST_MATRIX=postgres` (`.ci/run` runs the
/// suite a second time so, beside `.ci/services.sh`'s servers), `--store`
/// a fresh PostgreSQL database and
/// `--artifacts` a fresh prefix of the S3 test bucket, the same pair again
/// for a server restarted on the same directory; otherwise none (the
/// embedded default). Nothing when `extra` names its own store.
fn matrix_args(data_dir: &Path, extra: &[&str]) -> Vec<String> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static STORES: OnceLock<Mutex<HashMap<PathBuf, Vec<String>>>> = OnceLock::new();
    if std::env::var("MESHATLAS_TEST_MATRIX").as_deref() != Ok("postgres") || extra.contains(&"--store") {
        return Vec::new();
    }
    let mut stores = STORES.get_or_init(Default::default).lock().unwrap_or_else(|p| p.into_inner());
    stores
        .entry(data_dir.to_path_buf())
        .or_insert_with(|| {
            let admin =
                std::env::var("MESHATLAS_TEST_PG_URL").expect("the PostgreSQL matrix needs MESHATLAS_TEST_PG_URL");
            let bucket = std::env::var("MESHATLAS_TEST_S3_BUCKET").expect("the PostgreSQL matrix needs the S3 bucket");
            let db = meshatlas::jobs::pg_store::create_test_database(&admin);
            let artifacts = format!("s3://{bucket}/t_{}", uuid::Uuid::new_v4().simple());
            vec!["--store".into(), db, "--artifacts".into(), artifacts]
        })
        .clone()
}

/// A `meshatlas serve` child on `127.0.0.1:0`; killed (SIGKILL) on drop.
pub struct Server {
    pub child: Child,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// `127.0.0.1:PORT`.
    pub addr: String,
    /// The data directory (kept alive for the server's lifetime unless the
    /// caller passed its own).
    pub data_dir: PathBuf,
    _tmp: Option<tempfile::TempDir>,
    pub client: reqwest::Client,
    /// Where the child's stderr (the log) goes.
    pub log_path: PathBuf,
}

impl Server {
    /// Starts the binary with a fresh data directory and `extra` flags.
    pub fn start(extra: &[&str]) -> Server {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("data");
        let mut s = Self::start_in(&dir, extra, &[]);
        s._tmp = Some(tmp);
        s
    }

    /// Starts the binary on `data_dir` with `extra` flags and environment.
    pub fn start_in(data_dir: &Path, extra: &[&str], env: &[(&str, &str)]) -> Server {
        Self::try_start_in(data_dir, extra, env)
            .unwrap_or_else(|(code, log)| panic!("meshatlas serve exited with {code:?} before listening; log:\n{log}"))
    }

    /// Like [`Server::start_in`], but a process that exits before it listens
    /// gives its exit code and log (for flag-validation tests).
    pub fn try_start_in(
        data_dir: &Path,
        extra: &[&str],
        env: &[(&str, &str)],
    ) -> Result<Server, (Option<i32>, String)> {
        std::fs::create_dir_all(data_dir).unwrap();
        let log_path = data_dir.with_extension("log");
        let log = std::fs::File::create(&log_path).unwrap();
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshatlas"));
        cmd.args(["serve", "--addr", "127.0.0.1:0"])
            .arg("--data-dir")
            .arg(data_dir)
            .args(matrix_args(data_dir, extra))
            .args(extra)
            .env("MESHATLAS_LOG", "info")
            .stdout(Stdio::piped())
            .stderr(log);
        for (k, v) in env {
            cmd.env(k, v);
        }
        let mut child = cmd.spawn().expect("start meshatlas serve");
        let stdout = child.stdout.take().unwrap();
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let Some(addr) = line.trim().strip_prefix("listening on ").map(str::to_string) else {
            let code = child.wait().ok().and_then(|s| s.code());
            return Err((code, std::fs::read_to_string(&log_path).unwrap_or_default()));
        };
        Ok(Server {
            child,
            base: format!("http://{addr}"),
            addr,
            data_dir: data_dir.to_path_buf(),
            _tmp: None,
            client: identity_client(),
            log_path,
        })
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The server's log so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.log_path).unwrap_or_default()
    }

    /// Sends `sig` (e.g. "TERM", "HUP") to the server.
    pub fn signal(&self, sig: &str) {
        let ok = Command::new("kill").args([&format!("-{sig}"), &self.pid().to_string()]).status().unwrap();
        assert!(ok.success());
    }

    /// Waits up to `limit` for the process to exit; its exit status.
    pub fn wait_exit(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let start = Instant::now();
        while start.elapsed() < limit {
            if let Some(s) = self.child.try_wait().unwrap() {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }

    /// Resident set size of the server in KiB (Linux `VmRSS`).
    pub fn rss_kib(&self) -> u64 {
        proc_status_kib(self.pid(), "VmRSS:")
    }

    /// Peak resident set size of the server in KiB (Linux `VmHWM`).
    pub fn peak_rss_kib(&self) -> u64 {
        proc_status_kib(self.pid(), "VmHWM:")
    }

    /// Multipart upload of `file` (with file name `name`) and optional params.
    pub async fn submit_file(&self, path: &Path, params: Option<&str>) -> reqwest::Response {
        let bytes = std::fs::read(path).unwrap();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        self.submit_bytes(&name, bytes, params).await
    }

    /// Multipart upload of `bytes` as a file named `name`.
    pub async fn submit_bytes(&self, name: &str, bytes: Vec<u8>, params: Option<&str>) -> reqwest::Response {
        let mut form = reqwest::multipart::Form::new()
            .part("file", reqwest::multipart::Part::bytes(bytes).file_name(name.to_string()));
        if let Some(p) = params {
            form = form.text("params", p.to_string());
        }
        self.client.post(self.url("/v1/jobs")).multipart(form).send().await.unwrap()
    }

    /// GET `/v1/jobs/{id}` as JSON.
    pub async fn job(&self, id: &str) -> Value {
        self.client.get(self.url(&format!("/v1/jobs/{id}"))).send().await.unwrap().json().await.unwrap()
    }

    /// Polls the job until `pred` holds (panics after `limit`).
    pub async fn wait_for(&self, id: &str, limit: Duration, pred: impl Fn(&Value) -> bool) -> Value {
        let start = Instant::now();
        loop {
            let j = self.job(id).await;
            if pred(&j) {
                return j;
            }
            assert!(start.elapsed() < limit, "timed out after {limit:?}: {j:#}");
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
    }

    /// Polls until the job is succeeded, failed or cancelled.
    pub async fn wait_final(&self, id: &str, limit: Duration) -> Value {
        self.wait_for(id, limit, is_final).await
    }

    /// Opens a raw TCP connection to the server.
    pub fn tcp(&self) -> TcpStream {
        let s = TcpStream::connect(&self.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        s
    }

    /// Files left in the data directory's `tmp/`.
    pub fn tmp_files(&self) -> Vec<PathBuf> {
        match std::fs::read_dir(self.data_dir.join("tmp")) {
            Ok(rd) => rd.filter_map(|e| e.ok().map(|e| e.path())).collect(),
            Err(_) => Vec::new(),
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn proc_status_kib(pid: u32, key: &str) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with(key))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// True for succeeded, failed and cancelled.
pub fn is_final(j: &Value) -> bool {
    matches!(j["state"].as_str(), Some("succeeded" | "failed" | "cancelled"))
}

/// Writes `request` on a fresh connection and reads the whole answer until
/// the server closes it or `limit` passes (what arrived by then).
pub fn raw_exchange(addr: &str, request: &[u8], limit: Duration) -> Vec<u8> {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let _ = s.write_all(request);
    let start = Instant::now();
    let mut out = Vec::new();
    let mut buf = [0u8; 8192];
    while start.elapsed() < limit {
        match s.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => out.extend_from_slice(&buf[..n]),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(_) => break,
        }
    }
    out
}

/// The status code of a raw HTTP/1.1 answer (0 when there is none).
pub fn raw_status(answer: &[u8]) -> u16 {
    let text = String::from_utf8_lossy(answer);
    text.split_whitespace().nth(1).and_then(|s| s.parse().ok()).unwrap_or(0)
}

/// Header `name` (lowercase) of a raw HTTP/1.1 answer.
pub fn raw_header(answer: &[u8], name: &str) -> Option<String> {
    let text = String::from_utf8_lossy(answer);
    let head = text.split("\r\n\r\n").next()?;
    head.lines().skip(1).find_map(|l| {
        let (k, v) = l.split_once(':')?;
        (k.trim().eq_ignore_ascii_case(name)).then(|| v.trim().to_string())
    })
}

/// The body of a raw HTTP/1.1 answer (after the first blank line).
pub fn raw_body(answer: &[u8]) -> Vec<u8> {
    match answer.windows(4).position(|w| w == b"\r\n\r\n") {
        Some(i) => answer[i + 4..].to_vec(),
        None => Vec::new(),
    }
}

impl Server {
    /// Like [`Server::start`], but the binary runs under `wrapper` (e.g.
    /// `["prlimit", "--as=3000000000", "--"]`, which execs it in place, so
    /// [`Server::pid`] is still the server's).
    pub fn start_wrapped(wrapper: &[&str], extra: &[&str]) -> Server {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("data");
        std::fs::create_dir_all(&dir).unwrap();
        let log_path = dir.with_extension("log");
        let log = std::fs::File::create(&log_path).unwrap();
        let (program, pre) = wrapper.split_first().expect("a wrapper command");
        let mut child = Command::new(program)
            .args(pre)
            .arg(env!("CARGO_BIN_EXE_meshatlas"))
            .args(["serve", "--addr", "127.0.0.1:0"])
            .arg("--data-dir")
            .arg(&dir)
            .args(matrix_args(&dir, extra))
            .args(extra)
            .env("MESHATLAS_LOG", "info")
            .stdout(Stdio::piped())
            .stderr(log)
            .spawn()
            .expect("start the wrapped meshatlas serve");
        let stdout = child.stdout.take().unwrap();
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let Some(addr) = line.trim().strip_prefix("listening on ").map(str::to_string) else {
            let code = child.wait().ok().and_then(|s| s.code());
            panic!(
                "wrapped server exited with {code:?}; log:\n{}",
                std::fs::read_to_string(&log_path).unwrap_or_default()
            );
        };
        Server {
            child,
            base: format!("http://{addr}"),
            addr,
            data_dir: dir,
            _tmp: Some(tmp),
            client: identity_client(),
            log_path,
        }
    }
}

/// A reqwest client that asks for identity bytes (no automatic
/// `Accept-Encoding: gzip`), so headers and ranges are those of the files;
/// `downloads.rs` tests the gzip encoding with clients of its own.
pub fn identity_client() -> reqwest::Client {
    reqwest::Client::builder().no_gzip().build().unwrap()
}
