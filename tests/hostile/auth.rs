//! Authentication and tenancy (issue 11): bearer tokens on every `/v1`
//! route, jobs scoped to the submitting tenant, per-tenant and server-wide
//! limits, token reload on SIGHUP, refusal to listen beyond loopback without
//! authentication, and retention of finished jobs.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::common::{Server, raw_exchange, raw_status, shared_data};

const TOKEN_A: &str = "tok-alpha-0123456789abcdef";
const TOKEN_B: &str = "tok-bravo-0123456789abcdef";
const TOKEN_C: &str = "tok-charlie-0123456789abcdef";

/// Writes a token file (`token tenant` lines) next to the data directory.
fn token_file(dir: &Path, lines: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("tokens.txt");
    std::fs::write(&path, lines).unwrap();
    path
}

/// A server with tenants `a` (TOKEN_A) and `b` (TOKEN_B) and `extra` flags.
fn start_with_tokens(extra: &[&str]) -> (Server, tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let tokens = token_file(tmp.path(), &format!("# test tenants\n{TOKEN_A} a\n\n{TOKEN_B}   b\n"));
    let mut args = vec!["--auth-tokens", tokens.to_str().unwrap()];
    args.extend_from_slice(extra);
    let server = Server::start_in(&tmp.path().join("data"), &args, &[]);
    (server, tmp, tokens)
}

/// `method path` with `token` (if any); status, headers and JSON body.
async fn call(s: &Server, method: &str, path: &str, token: Option<&str>) -> (u16, reqwest::header::HeaderMap, Value) {
    let method = reqwest::Method::from_bytes(method.as_bytes()).unwrap();
    let mut req = s.client.request(method, s.url(path));
    if let Some(t) = token {
        req = req.bearer_auth(t);
    }
    let resp = req.send().await.unwrap();
    let status = resp.status().as_u16();
    let headers = resp.headers().clone();
    let bytes = resp.bytes().await.unwrap();
    (status, headers, serde_json::from_slice(&bytes).unwrap_or(Value::Null))
}

/// Multipart upload of `sphere_tiny.stl` as `token`'s tenant.
async fn submit_as(s: &Server, token: &str) -> (u16, reqwest::header::HeaderMap, Value) {
    let bytes = std::fs::read(shared_data("gmsh/sphere_tiny.stl")).unwrap();
    let form = reqwest::multipart::Form::new()
        .part("file", reqwest::multipart::Part::bytes(bytes).file_name("sphere_tiny.stl"));
    let resp = s.client.post(s.url("/v1/jobs")).bearer_auth(token).multipart(form).send().await.unwrap();
    let status = resp.status().as_u16();
    let headers = resp.headers().clone();
    (status, headers, resp.json().await.unwrap_or(Value::Null))
}

/// Submits as `token` and expects 202; the job id.
async fn submit_ok(s: &Server, token: &str) -> String {
    let (status, _, body) = submit_as(s, token).await;
    assert_eq!(status, 202, "{body}");
    body["id"].as_str().unwrap().to_string()
}

/// Polls the job as `token` until it is succeeded, failed or cancelled.
async fn wait_final_as(s: &Server, token: &str, id: &str) -> Value {
    let start = Instant::now();
    loop {
        let (status, _, j) = call(s, "GET", &format!("/v1/jobs/{id}"), Some(token)).await;
        assert_eq!(status, 200, "{j}");
        if crate::common::is_final(&j) {
            return j;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "job never finished: {j}");
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
}

/// Polls the job as `token` until its state is `state`.
async fn wait_state_as(s: &Server, token: &str, id: &str, state: &str) {
    let start = Instant::now();
    loop {
        let (_, _, j) = call(s, "GET", &format!("/v1/jobs/{id}"), Some(token)).await;
        if j["state"] == state {
            return;
        }
        assert!(start.elapsed() < Duration::from_secs(20), "job never reached {state}: {j}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

fn assert_unauthorized(status: u16, headers: &reqwest::header::HeaderMap, body: &Value, wrong_token: bool, what: &str) {
    assert_eq!(status, 401, "{what}: {body}");
    assert_eq!(body["type"], "urn:meshatlas:problem:unauthorized", "{what}: {body}");
    assert!(body["request_id"].is_string(), "{what}: {body}");
    let ct = headers.get("content-type").and_then(|v| v.to_str().ok()).unwrap_or("");
    assert!(ct.starts_with("application/problem+json"), "{what}: content-type {ct}");
    let challenge = headers.get("www-authenticate").and_then(|v| v.to_str().ok()).unwrap_or("");
    assert!(challenge.starts_with("Bearer realm=\"meshatlas\""), "{what}: WWW-Authenticate `{challenge}`");
    assert_eq!(challenge.contains("error=\"invalid_token\""), wrong_token, "{what}: WWW-Authenticate `{challenge}`");
}

/// Every `/v1` route (with a syntactically valid id) as (method, path).
fn v1_routes() -> Vec<(&'static str, String)> {
    let id = "3f2b8c1e-0a4d-4e5f-9b6a-1c2d3e4f5a6b";
    vec![
        ("POST", "/v1/jobs".to_string()),
        ("GET", "/v1/jobs".to_string()),
        ("GET", format!("/v1/jobs/{id}")),
        ("DELETE", format!("/v1/jobs/{id}")),
        ("POST", format!("/v1/jobs/{id}/cancel")),
        ("GET", format!("/v1/jobs/{id}/artifacts/report.json")),
        ("GET", "/v1/no-such-route".to_string()),
    ]
}

#[tokio::test]
async fn every_v1_route_answers_401_with_a_bearer_challenge_without_a_valid_token() {
    let (s, _tmp, _) = start_with_tokens(&[]);
    for (method, path) in v1_routes() {
        let (st, h, b) = call(&s, method, &path, None).await;
        assert_unauthorized(st, &h, &b, false, &format!("{method} {path} without a token"));
        let (st, h, b) = call(&s, method, &path, Some("not-a-token-of-this-server")).await;
        assert_unauthorized(st, &h, &b, true, &format!("{method} {path} with a wrong token"));
        // Another scheme is no bearer token at all.
        let resp = s.client.request(reqwest::Method::GET, s.url(&path)).basic_auth("a", Some(TOKEN_A)).send().await;
        assert_eq!(resp.unwrap().status(), 401, "{method} {path} with Basic auth");
    }
    let (st, _, b) = call(&s, "GET", "/v1/jobs", Some(TOKEN_A)).await;
    assert_eq!(st, 200, "a valid token lists jobs: {b}");
    let (st, _, b) = call(&s, "GET", "/healthz", None).await;
    assert_eq!((st, &b["status"]), (200, &Value::from("ok")), "/healthz stays open: {b}");
    let (st, _, _) = call(&s, "GET", "/metrics", None).await;
    assert_eq!(st, 200, "/metrics is open without --metrics-auth");
    assert!(!s.log().contains(TOKEN_A), "a token reached the log");
}

#[tokio::test]
async fn metrics_auth_protects_metrics() {
    let (s, _tmp, _) = start_with_tokens(&["--metrics-auth"]);
    let (st, h, b) = call(&s, "GET", "/metrics", None).await;
    assert_unauthorized(st, &h, &b, false, "/metrics without a token");
    let (st, _, _) = call(&s, "GET", "/metrics", Some(TOKEN_B)).await;
    assert_eq!(st, 200);
    let (st, _, _) = call(&s, "GET", "/healthz", None).await;
    assert_eq!(st, 200);
}

#[tokio::test]
async fn a_tenant_cannot_see_or_touch_another_tenants_jobs() {
    let (s, _tmp, _) = start_with_tokens(&[]);
    let a1 = submit_ok(&s, TOKEN_A).await;
    let a2 = submit_ok(&s, TOKEN_A).await;
    let b1 = submit_ok(&s, TOKEN_B).await;
    let done = wait_final_as(&s, TOKEN_A, &a1).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    wait_final_as(&s, TOKEN_A, &a2).await;
    wait_final_as(&s, TOKEN_B, &b1).await;
    let artifact = done["artifacts"][0]["name"].as_str().unwrap().to_string();

    // A foreign id answers exactly like a missing one.
    let missing = "3f2b8c1e-0a4d-4e5f-9b6a-1c2d3e4f5a6b";
    let (_, _, missing_body) = call(&s, "GET", &format!("/v1/jobs/{missing}"), Some(TOKEN_B)).await;
    let shape = |v: &Value| {
        let mut keys: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        keys.sort();
        (keys, v["type"].clone(), v["title"].clone(), v["status"].clone())
    };
    for (method, path) in [
        ("GET", format!("/v1/jobs/{a1}")),
        ("GET", format!("/v1/jobs/{a1}/artifacts/{artifact}")),
        ("POST", format!("/v1/jobs/{a1}/cancel")),
        ("DELETE", format!("/v1/jobs/{a1}")),
    ] {
        let (st, _, body) = call(&s, method, &path, Some(TOKEN_B)).await;
        assert_eq!(st, 404, "tenant b on {method} {path}: {body}");
        assert_eq!(shape(&body), shape(&missing_body), "{method} {path}: {body} vs {missing_body}");
        assert_eq!(
            body["detail"].as_str().unwrap().replace(&a1, missing),
            missing_body["detail"].as_str().unwrap(),
            "the detail tells nothing more than for a missing job"
        );
    }
    // Tenant a's job is untouched, and a still downloads its artifact.
    let (st, _, j) = call(&s, "GET", &format!("/v1/jobs/{a1}"), Some(TOKEN_A)).await;
    assert_eq!((st, &j["state"]), (200, &Value::from("succeeded")), "{j}");
    let resp = s.client.get(s.url(&format!("/v1/jobs/{a1}/artifacts/{artifact}"))).bearer_auth(TOKEN_A).send().await;
    assert_eq!(resp.unwrap().status(), 200);

    let ids = |page: &Value| -> Vec<String> {
        page["jobs"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap().to_string()).collect()
    };
    let (_, _, page_a) = call(&s, "GET", "/v1/jobs", Some(TOKEN_A)).await;
    assert_eq!(ids(&page_a), vec![a2.clone(), a1.clone()], "{page_a}");
    let (_, _, page_b) = call(&s, "GET", "/v1/jobs", Some(TOKEN_B)).await;
    assert_eq!(ids(&page_b), vec![b1.clone()], "{page_b}");
    // Pagination stays inside the tenant.
    let (_, _, p1) = call(&s, "GET", "/v1/jobs?limit=1", Some(TOKEN_A)).await;
    assert_eq!(ids(&p1), vec![a2.clone()]);
    let cursor = p1["next_cursor"].as_str().unwrap();
    let (_, _, p2) = call(&s, "GET", &format!("/v1/jobs?limit=1&cursor={cursor}"), Some(TOKEN_A)).await;
    assert_eq!(ids(&p2), vec![a1.clone()]);
    assert!(p2["next_cursor"].is_null(), "{p2}");

    // The owner can delete its own job.
    let (st, _, _) = call(&s, "DELETE", &format!("/v1/jobs/{a1}"), Some(TOKEN_A)).await;
    assert_eq!(st, 204);
}

#[tokio::test]
async fn sighup_reloads_the_token_file_and_keeps_the_old_tokens_when_it_is_bad() {
    let (mut s, _tmp, tokens) = start_with_tokens(&[]);
    assert_eq!(call(&s, "GET", "/v1/jobs", Some(TOKEN_B)).await.0, 200);
    assert_eq!(call(&s, "GET", "/v1/jobs", Some(TOKEN_C)).await.0, 401);
    std::fs::write(&tokens, format!("{TOKEN_A} a\n{TOKEN_C} c\n")).unwrap();
    s.signal("HUP");
    let start = Instant::now();
    while call(&s, "GET", "/v1/jobs", Some(TOKEN_C)).await.0 != 200 {
        assert!(start.elapsed() < Duration::from_secs(10), "the new token never became valid");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(call(&s, "GET", "/v1/jobs", Some(TOKEN_B)).await.0, 401, "the removed token still works");
    assert_eq!(call(&s, "GET", "/v1/jobs", Some(TOKEN_A)).await.0, 200);

    // A bad file on reload keeps the tokens in force and logs the error.
    std::fs::write(&tokens, format!("{TOKEN_B} b\nshort x\n")).unwrap();
    s.signal("HUP");
    let start = Instant::now();
    while !s.log().contains("line 2") {
        assert!(start.elapsed() < Duration::from_secs(10), "the bad reload was not logged:\n{}", s.log());
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(call(&s, "GET", "/v1/jobs", Some(TOKEN_C)).await.0, 200, "a bad reload dropped the tokens");
    assert_eq!(call(&s, "GET", "/v1/jobs", Some(TOKEN_B)).await.0, 401);
    assert!(s.child.try_wait().unwrap().is_none(), "the server died on SIGHUP");
}

#[test]
fn malformed_token_files_refuse_to_start_naming_the_line() {
    let cases = [
        ("short", format!("{TOKEN_A} a\nshort-token b\n"), "line 2"),
        ("duplicate", format!("# c\n{TOKEN_A} a\n{TOKEN_A} b\n"), "line 3"),
        ("three fields", format!("{TOKEN_A} a extra\n"), "line 1"),
        ("no tenant", format!("\n{TOKEN_A}\n"), "line 2"),
        ("bad tenant", format!("{TOKEN_A} a/b\n"), "line 1"),
        ("no tokens", "# nothing\n\n".to_string(), "no token"),
    ];
    for (what, text, needle) in cases {
        let tmp = tempfile::tempdir().unwrap();
        let tokens = token_file(tmp.path(), &text);
        let res = Server::try_start_in(&tmp.path().join("data"), &["--auth-tokens", tokens.to_str().unwrap()], &[]);
        let Err((code, log)) = res else { panic!("{what}: the server started with a bad token file") };
        assert!(code.is_some_and(|c| c != 0), "{what}: exit code {code:?}");
        assert!(log.contains(needle), "{what}: the message does not say `{needle}`:\n{log}");
        assert!(!log.contains(TOKEN_A), "{what}: the message shows a token:\n{log}");
    }
    // A missing file is an error too.
    let tmp = tempfile::tempdir().unwrap();
    let res = Server::try_start_in(&tmp.path().join("data"), &["--auth-tokens", "/nonexistent/tokens.txt"], &[]);
    assert!(res.is_err(), "started with a missing token file");
}

/// Starts `meshatlas serve` with exactly `args`; the child and the
/// `listening on` address, or the exit code and stderr.
/// Starts the binary with `args`; the data directory lives as long as the
/// returned `TempDir`.
fn spawn_serve(args: &[&str]) -> Result<(Child, String, tempfile::TempDir), (Option<i32>, String)> {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let log_path = tmp.path().join("log");
    let mut child = Command::new(env!("CARGO_BIN_EXE_meshatlas"))
        .arg("serve")
        .arg("--data-dir")
        .arg(&data)
        .args(args)
        .env("MESHATLAS_LOG", "info")
        .env_remove("MESHATLAS_AUTH_TOKENS")
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&log_path).unwrap())
        .spawn()
        .unwrap();
    let mut line = String::new();
    let _ = BufReader::new(child.stdout.take().unwrap()).read_line(&mut line);
    match line.trim().strip_prefix("listening on ") {
        Some(addr) => Ok((child, addr.to_string(), tmp)),
        None => {
            let code = child.wait().ok().and_then(|s| s.code());
            Err((code, std::fs::read_to_string(&log_path).unwrap_or_default()))
        }
    }
}

#[test]
fn a_non_loopback_address_without_auth_refuses_to_start_unless_insecure_no_auth() {
    // Binding 0.0.0.0 only listens; the test talks to it over 127.0.0.1.
    for addr in ["0.0.0.0:0", "[::]:0"] {
        match spawn_serve(&["--addr", addr]) {
            Ok((mut child, _, _dir)) => {
                let _ = child.kill();
                panic!("listened on {addr} without authentication");
            }
            Err((code, log)) => {
                assert!(code.is_some_and(|c| c != 0), "{addr}: exit code {code:?}");
                assert!(log.contains("--insecure-no-auth") && log.contains("--auth-tokens"), "{addr}: {log}");
            }
        }
    }
    let (mut child, addr, _dir) =
        spawn_serve(&["--addr", "0.0.0.0:0", "--insecure-no-auth"]).expect("--insecure-no-auth");
    let port = addr.rsplit(':').next().unwrap();
    let answer = raw_exchange(
        &format!("127.0.0.1:{port}"),
        b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
        Duration::from_secs(10),
    );
    let _ = child.kill();
    let _ = child.wait();
    assert_eq!(raw_status(&answer), 200, "{}", String::from_utf8_lossy(&answer));
    // Loopback needs neither.
    let (mut child, _, _dir2) = spawn_serve(&["--addr", "127.0.0.1:0"]).expect("loopback without auth");
    let _ = child.kill();
    let _ = child.wait();
}

#[tokio::test]
async fn a_tenant_with_n_queued_jobs_gets_429_and_others_still_submit() {
    let (s, _tmp, _) = start_with_tokens(&["--tenant-max-queued", "2", "--test-job-delay-ms", "60000"]);
    let first = submit_ok(&s, TOKEN_A).await;
    wait_state_as(&s, TOKEN_A, &first, "running").await;
    submit_ok(&s, TOKEN_A).await;
    submit_ok(&s, TOKEN_A).await;
    let (st, h, body) = submit_as(&s, TOKEN_A).await;
    assert_eq!(st, 429, "{body}");
    assert_eq!(body["type"], "urn:meshatlas:problem:tenant-queue-full", "{body}");
    assert!(h.get("retry-after").is_some(), "no Retry-After");
    assert_eq!(body["max_queued"], 2, "{body}");
    submit_ok(&s, TOKEN_B).await;
}

#[tokio::test]
async fn the_stored_bytes_quota_answers_507_and_retention_frees_it() {
    let size = std::fs::metadata(shared_data("gmsh/sphere_tiny.stl")).unwrap().len();
    let quota = (size + size / 2).to_string();
    let (s, _tmp, _) =
        start_with_tokens(&["--max-stored-bytes", &quota, "--retention", "8s", "--test-retention-sweep-ms", "200"]);
    let first = submit_ok(&s, TOKEN_A).await;
    let (st, _, body) = submit_as(&s, TOKEN_B).await;
    assert_eq!(st, 507, "{body}");
    assert_eq!(body["type"], "urn:meshatlas:problem:insufficient-storage", "{body}");
    assert_eq!(body["max_stored_bytes"].as_u64(), Some(size + size / 2), "{body}");
    // A declared Content-Length beyond the quota is refused before the body is sent.
    let head = format!(
        "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {TOKEN_B}\r\n\
         Content-Type: model/stl\r\nContent-Length: 100000000\r\n\r\n"
    );
    let answer = raw_exchange(&s.addr, head.as_bytes(), Duration::from_secs(5));
    assert_eq!(raw_status(&answer), 507, "{}", String::from_utf8_lossy(&answer));

    // The finished job expires after the retention, and its space with it.
    let done = wait_final_as(&s, TOKEN_A, &first).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let start = Instant::now();
    loop {
        let (st, _, _) = call(&s, "GET", &format!("/v1/jobs/{first}"), Some(TOKEN_A)).await;
        if st == 404 {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "the finished job never expired");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // The record goes first, then the files.
    let start = Instant::now();
    while s.data_dir.join("jobs").join(&first).exists() {
        assert!(start.elapsed() < Duration::from_secs(5), "the expired job's files are still there");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    submit_ok(&s, TOKEN_B).await;
}

#[tokio::test]
async fn the_tenant_stored_bytes_quota_answers_507_for_that_tenant_only() {
    let size = std::fs::metadata(shared_data("gmsh/sphere_tiny.stl")).unwrap().len();
    let quota = (size + size / 2).to_string();
    let (s, _tmp, _) = start_with_tokens(&["--tenant-max-stored-bytes", &quota, "--test-job-delay-ms", "60000"]);
    submit_ok(&s, TOKEN_A).await;
    let (st, _, body) = submit_as(&s, TOKEN_A).await;
    assert_eq!(st, 507, "{body}");
    assert_eq!(body["type"], "urn:meshatlas:problem:insufficient-storage", "{body}");
    submit_ok(&s, TOKEN_B).await;
}

#[tokio::test]
async fn retention_keeps_unfinished_jobs_and_expires_cancelled_ones() {
    let (s, _tmp, _) =
        start_with_tokens(&["--retention", "1s", "--test-retention-sweep-ms", "100", "--test-job-delay-ms", "60000"]);
    let running = submit_ok(&s, TOKEN_A).await;
    wait_state_as(&s, TOKEN_A, &running, "running").await;
    let queued = submit_ok(&s, TOKEN_A).await;
    let cancelled = submit_ok(&s, TOKEN_A).await;
    let (st, _, _) = call(&s, "POST", &format!("/v1/jobs/{cancelled}/cancel"), Some(TOKEN_A)).await;
    assert_eq!(st, 200);
    let start = Instant::now();
    while call(&s, "GET", &format!("/v1/jobs/{cancelled}"), Some(TOKEN_A)).await.0 != 404 {
        assert!(start.elapsed() < Duration::from_secs(15), "the cancelled job never expired");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    tokio::time::sleep(Duration::from_millis(1500)).await;
    for id in [&running, &queued] {
        let (st, _, j) = call(&s, "GET", &format!("/v1/jobs/{id}"), Some(TOKEN_A)).await;
        assert_eq!(st, 200, "an unfinished job expired: {j}");
    }
}

#[test]
fn auth_and_limit_flags_are_validated() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    for (args, needle) in [
        (vec!["--metrics-auth"], "--auth-tokens"),
        (vec!["--tenant-max-queued", "3"], "--auth-tokens"),
        (vec!["--retention", "7x"], "retention"),
        (vec!["--retention", "0s"], "retention"),
    ] {
        let res = Server::try_start_in(&data, &args, &[]);
        let Err((code, log)) = res else { panic!("{args:?} was accepted") };
        assert!(code.is_some_and(|c| c != 0), "{args:?}: exit {code:?}");
        assert!(log.contains(needle), "{args:?}: {log}");
    }
    for retention in ["7d", "12h", "30m", "45s", "3600"] {
        assert!(Server::try_start_in(&data, &["--retention", retention], &[]).is_ok(), "--retention {retention}");
    }
}
