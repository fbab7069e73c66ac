//! Limits of the HTTP layer (issue 11, items 4, 9, 11 and 13): header and
//! body timeouts, a bounded graceful shutdown, problem+json for what the
//! HTTP parser rejects, no `100 Continue` before an early 413, and serve
//! flags validated before anything listens.
//!
//! Timeouts are set through `MESHATLAS_*` environment variables rather than
//! flags, so that a binary without them runs these tests and fails on the
//! defect itself instead of on an unknown flag.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::common::{Server, raw_body, raw_exchange, raw_header, raw_status, shared_data};

/// A server with a fresh data directory, `extra` flags and `env`.
fn start_with_env(extra: &[&str], env: &[(&str, &str)]) -> (Server, tempfile::TempDir) {
    let tmp = tempfile::tempdir().unwrap();
    let server = Server::start_in(&tmp.path().join("data"), extra, env);
    (server, tmp)
}

/// Reads from `s` until the peer closes (true) or `limit` passes (false);
/// what arrived is appended to `out`.
fn read_until_closed(s: &mut TcpStream, limit: Duration, out: &mut Vec<u8>) -> bool {
    s.set_read_timeout(Some(Duration::from_millis(100))).unwrap();
    let start = Instant::now();
    let mut buf = [0u8; 8192];
    while start.elapsed() < limit {
        match s.read(&mut buf) {
            Ok(0) => return true,
            Ok(n) => out.extend_from_slice(&buf[..n]),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(_) => return true,
        }
    }
    false
}

/// True when the connection is closed by the server: a read gives EOF or an
/// error without waiting (nothing arrives on a live, idle connection).
fn is_closed(s: &mut TcpStream) -> bool {
    let mut out = Vec::new();
    s.set_nonblocking(true).unwrap();
    let mut buf = [0u8; 4096];
    let closed = loop {
        match s.read(&mut buf) {
            Ok(0) => break true,
            Ok(n) => out.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break false,
            Err(_) => break true,
        }
    };
    s.set_nonblocking(false).unwrap();
    closed || raw_status(&out) == 408
}

/// The problem+json body of a raw answer, after checking its media type.
fn raw_problem(answer: &[u8]) -> Value {
    let ct = raw_header(answer, "content-type");
    assert_eq!(ct.as_deref(), Some("application/problem+json"), "{}", String::from_utf8_lossy(answer));
    serde_json::from_slice(&raw_body(answer)).unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(answer)))
}

#[test]
fn headers_trickled_a_line_per_half_second_are_cut_off_after_the_header_timeout() {
    let (server, _tmp) = start_with_env(&[], &[("MESHATLAS_HEADER_TIMEOUT_SECS", "2")]);
    let mut s = TcpStream::connect(&server.addr).unwrap();
    let start = Instant::now();
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n").unwrap();
    let mut cut_after = None;
    for i in 0..40 {
        std::thread::sleep(Duration::from_millis(500));
        if s.write_all(format!("X-Slow-{i}: y\r\n").as_bytes()).is_err() || is_closed(&mut s) {
            cut_after = Some(start.elapsed());
            break;
        }
    }
    let cut_after = cut_after.expect("headers trickled for 20 s were still being read");
    assert!(cut_after < Duration::from_secs(10), "cut off only after {cut_after:?}");
    assert!(cut_after >= Duration::from_millis(1500), "cut off before the timeout: {cut_after:?}");
}

#[test]
fn an_idle_keep_alive_connection_is_closed_after_the_header_timeout() {
    let (server, _tmp) = start_with_env(&[], &[("MESHATLAS_HEADER_TIMEOUT_SECS", "2")]);
    let mut s = TcpStream::connect(&server.addr).unwrap();
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    let mut out = Vec::new();
    let closed = read_until_closed(&mut s, Duration::from_secs(12), &mut out);
    assert_eq!(raw_status(&out), 200, "{}", String::from_utf8_lossy(&out));
    assert!(closed, "an idle keep-alive connection stayed open for 12 s");
}

#[test]
fn a_half_sent_body_is_dropped_after_the_idle_timeout_and_its_part_file_removed() {
    let (server, _tmp) = start_with_env(&[], &[("MESHATLAS_BODY_IDLE_TIMEOUT_SECS", "2")]);
    let mut s = TcpStream::connect(&server.addr).unwrap();
    s.write_all(
        b"POST /v1/jobs?format=stl HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\n\
          Content-Length: 1000000\r\n\r\n",
    )
    .unwrap();
    s.write_all(&vec![b'x'; 100_000]).unwrap();
    let start = Instant::now();
    while server.tmp_files().is_empty() {
        assert!(start.elapsed() < Duration::from_secs(10), "no upload file appeared in tmp/");
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut out = Vec::new();
    let closed = read_until_closed(&mut s, Duration::from_secs(12), &mut out);
    let waited = start.elapsed();
    assert!(closed && waited < Duration::from_secs(10), "a stalled upload was held for {waited:?}");
    assert_eq!(raw_status(&out), 408, "{}", String::from_utf8_lossy(&out));
    assert_eq!(raw_problem(&out)["type"], "urn:meshatlas:problem:upload-timeout");
    let start = Instant::now();
    while !server.tmp_files().is_empty() {
        assert!(start.elapsed() < Duration::from_secs(5), "left in tmp/: {:?}", server.tmp_files());
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_half_sent_multipart_upload_is_dropped_after_the_idle_timeout_and_its_part_file_removed() {
    let (server, _tmp) = start_with_env(&[], &[("MESHATLAS_BODY_IDLE_TIMEOUT_SECS", "2")]);
    let mut s = TcpStream::connect(&server.addr).unwrap();
    s.write_all(
        b"POST /v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: multipart/form-data; boundary=XYZ\r\n\
          Content-Length: 1000000\r\n\r\n--XYZ\r\nContent-Disposition: form-data; name=\"file\"; \
          filename=\"a.stl\"\r\n\r\n",
    )
    .unwrap();
    s.write_all(&vec![b'x'; 100_000]).unwrap();
    let start = Instant::now();
    while server.tmp_files().is_empty() {
        assert!(start.elapsed() < Duration::from_secs(10), "no upload file appeared in tmp/");
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut out = Vec::new();
    let closed = read_until_closed(&mut s, Duration::from_secs(12), &mut out);
    assert!(closed, "a stalled multipart upload was held for {:?}", start.elapsed());
    assert_eq!(raw_status(&out), 408, "{}", String::from_utf8_lossy(&out));
    assert_eq!(raw_problem(&out)["type"], "urn:meshatlas:problem:upload-timeout");
    let start = Instant::now();
    while !server.tmp_files().is_empty() {
        assert!(start.elapsed() < Duration::from_secs(5), "left in tmp/: {:?}", server.tmp_files());
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_with_a_half_sent_upload_open_exits_within_the_grace_and_requeues_the_running_job() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("data");
    let env = [("MESHATLAS_SHUTDOWN_GRACE_SECS", "2"), ("MESHATLAS_BODY_IDLE_TIMEOUT_SECS", "120")];
    let mut server = Server::start_in(&dir, &["--test-job-delay-ms", "30000"], &env);
    let stl = std::fs::read(shared_data("gmsh/sphere_tiny.stl")).unwrap();
    let r = server.client.post(server.url("/v1/jobs?format=stl")).body(stl).send().await.unwrap();
    assert_eq!(r.status(), 202);
    let id = r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string();
    server.wait_for(&id, Duration::from_secs(20), |j| j["state"] == "running").await;

    let mut s = TcpStream::connect(&server.addr).unwrap();
    s.write_all(
        b"POST /v1/jobs?format=stl HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\n\
          Content-Length: 1000000\r\n\r\n",
    )
    .unwrap();
    s.write_all(&vec![b'x'; 10_000]).unwrap();
    let start = Instant::now();
    while server.tmp_files().is_empty() {
        assert!(start.elapsed() < Duration::from_secs(10), "no upload file appeared in tmp/");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }

    server.signal("TERM");
    let t = Instant::now();
    let status = server.wait_exit(Duration::from_secs(10));
    let status =
        status.unwrap_or_else(|| panic!("still running 10 s after SIGTERM (grace 2 s); log:\n{}", server.log()));
    assert!(status.success(), "exit status {status} after SIGTERM");
    assert!(t.elapsed() >= Duration::from_millis(1500), "the grace was not given: exited after {:?}", t.elapsed());
    assert!(server.tmp_files().is_empty(), "left in tmp/: {:?}", server.tmp_files());
    drop(s);

    let again = Server::start_in(&dir, &[], &[]);
    let j = again.wait_final(&id, Duration::from_secs(60)).await;
    assert_eq!(j["state"], "succeeded", "{j:#}");
    assert_eq!(j["attempts"], 1, "the shutdown counted as an attempt: {j:#}");
}

#[test]
fn a_100_kb_url_answers_414_problem_json() {
    let server = Server::start(&[]);
    let req = format!("GET /v1/jobs?cursor={} HTTP/1.1\r\nHost: x\r\n\r\n", "a".repeat(100_000));
    let answer = raw_exchange(&server.addr, req.as_bytes(), Duration::from_secs(5));
    assert_eq!(raw_status(&answer), 414, "{}", String::from_utf8_lossy(&answer));
    let p = raw_problem(&answer);
    assert_eq!(p["type"], "urn:meshatlas:problem:uri-too-long");
    assert_eq!(p["status"], 414);
}

#[test]
fn a_request_with_120_headers_answers_431_problem_json() {
    let server = Server::start(&[]);
    let mut req = String::from("GET /healthz HTTP/1.1\r\nHost: x\r\n");
    for i in 0..120 {
        req.push_str(&format!("X-Many-{i}: v\r\n"));
    }
    req.push_str("\r\n");
    let answer = raw_exchange(&server.addr, req.as_bytes(), Duration::from_secs(5));
    assert_eq!(raw_status(&answer), 431, "{}", String::from_utf8_lossy(&answer));
    let p = raw_problem(&answer);
    assert_eq!(p["type"], "urn:meshatlas:problem:headers-too-large");
    assert_eq!(p["status"], 431);
}

#[test]
fn control_bytes_in_content_type_answer_400_problem_json() {
    let server = Server::start(&[]);
    let req = b"POST /v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: model/\x01stl\r\nContent-Length: 3\r\n\r\nabc";
    let answer = raw_exchange(&server.addr, req, Duration::from_secs(5));
    assert_eq!(raw_status(&answer), 400, "{}", String::from_utf8_lossy(&answer));
    let p = raw_problem(&answer);
    assert_eq!(p["type"], "urn:meshatlas:problem:bad-request");
    assert_eq!(p["status"], 400);
    // The server still answers on a new connection afterwards.
    let ok = raw_exchange(
        &server.addr,
        b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
        Duration::from_secs(5),
    );
    assert_eq!(raw_status(&ok), 200, "{}", String::from_utf8_lossy(&ok));
}

#[test]
fn expect_100_continue_with_an_oversized_length_gets_413_without_100_continue() {
    let server = Server::start(&["--max-upload-bytes", "1048576"]);
    let req = b"POST /v1/jobs?format=stl HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\n\
                Content-Length: 10000000000\r\nExpect: 100-continue\r\n\r\n";
    let answer = raw_exchange(&server.addr, req, Duration::from_secs(4));
    let text = String::from_utf8_lossy(&answer);
    assert_eq!(raw_status(&answer), 413, "first answer: {text}");
    assert!(!text.contains("100 Continue"), "{text}");
    assert_eq!(raw_problem(&answer)["type"], "urn:meshatlas:problem:upload-too-large");
}

/// Runs `meshatlas serve` with `args` (plus a data directory, and
/// `--addr 127.0.0.1:0` unless `args` names one); its exit code and stderr.
/// A server that starts listening is killed and reported as `None`.
fn serve_exit(args: &[&str], data_dir: &Path) -> (Option<i32>, String, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshatlas"));
    cmd.arg("serve").arg("--data-dir").arg(data_dir);
    if !args.iter().any(|a| a.starts_with("--addr")) {
        cmd.args(["--addr", "127.0.0.1:0"]);
    }
    let mut child = cmd.args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut line = String::new();
    let _ = BufReader::new(child.stdout.take().unwrap()).read_line(&mut line);
    if line.starts_with("listening on") {
        let _ = child.kill();
    }
    let out = child.wait_with_output().unwrap();
    (out.status.code(), line, String::from_utf8_lossy(&out.stderr).to_string())
}

#[test]
fn bad_serve_flags_exit_with_a_usage_error_naming_the_flag() {
    let tmp = tempfile::tempdir().unwrap();
    let cases: &[(&str, &str)] = &[
        ("--job-timeout-secs", "1e300"),
        ("--job-timeout-secs", "inf"),
        ("--job-timeout-secs", "NaN"),
        ("--job-timeout-secs", "0"),
        ("--job-timeout-secs", "-5"),
        ("--max-triangles", "0"),
        ("--max-triangles", "-1"),
        ("--workers", "0"),
        ("--workers", "5000"),
        ("--max-queued", "0"),
        ("--max-upload-bytes", "0"),
        ("--max-attempts", "0"),
        ("--max-attempts", "1e3"),
        ("--retry-after-secs", "99999999999"),
        ("--addr", "not an address"),
        ("--addr", "127.0.0.1:99999"),
        ("--header-timeout-secs", "0"),
        ("--header-timeout-secs", "1e9"),
        ("--body-idle-timeout-secs", "0"),
        ("--shutdown-grace-secs", "99999999"),
    ];
    let mut failures = Vec::new();
    for (i, (flag, value)) in cases.iter().enumerate() {
        let dir = tmp.path().join(format!("d{i}"));
        let arg = format!("{flag}={value}");
        let (code, stdout, stderr) = serve_exit(&[&arg], &dir);
        let ok = code.is_some_and(|c| c != 0 && c != 101)
            && !stdout.contains("listening on")
            && !stderr.contains("panicked")
            && stderr.contains(flag);
        if !ok {
            failures.push(format!("{flag} {value}: exit {code:?}, stdout {stdout:?}, stderr {stderr:?}"));
        }
    }
    assert!(failures.is_empty(), "accepted or badly reported:\n{}", failures.join("\n"));
}
