//! The browser pages' negotiation and access: `GET /v1/jobs/{id}` answers
//! JSON to API clients and the static HTML shell to a browser, and with
//! tokens the shell is public while the JSON still needs a token.

use std::sync::Arc;

use meshatlas::http::auth::Auth;
use meshatlas::http::{AppState, HttpLimits};
use meshatlas::jobs::{JobService, JobsConfig};
use serde_json::Value;

use crate::common::{Server, copy_exec};

/// What Chrome sends on navigation.
const BROWSER_ACCEPT: &str =
    "text/html,application/xhtml+xml,application/xml;q=0.9,image/avif,image/webp,image/apng,*/*;q=0.8";
const TOKEN: &str = "page-test-token-0123456789";

/// GET `path` with `accept` (none when `None`) and `token`; status, headers and body.
async fn get(
    client: &reqwest::Client,
    url: &str,
    accept: Option<&str>,
    token: Option<&str>,
) -> (u16, reqwest::header::HeaderMap, Vec<u8>) {
    let mut req = client.get(url);
    if let Some(a) = accept {
        req = req.header("accept", a);
    }
    if let Some(t) = token {
        req = req.bearer_auth(t);
    }
    let resp = req.send().await.unwrap();
    let status = resp.status().as_u16();
    let headers = resp.headers().clone();
    (status, headers, resp.bytes().await.unwrap().to_vec())
}

fn header<'a>(h: &'a reqwest::header::HeaderMap, name: &str) -> &'a str {
    h.get(name).and_then(|v| v.to_str().ok()).unwrap_or("")
}

/// Asserts an answer is the HTML shell with its security headers.
fn assert_shell(status: u16, h: &reqwest::header::HeaderMap, body: &[u8], what: &str) {
    assert_eq!(status, 200, "{what}");
    assert_eq!(header(h, "content-type"), "text/html; charset=utf-8", "{what}");
    assert_eq!(header(h, "vary"), "accept", "{what}");
    assert!(header(h, "content-security-policy").starts_with("default-src 'self'"), "{what}");
    assert_eq!(header(h, "x-content-type-options"), "nosniff", "{what}");
    let text = String::from_utf8_lossy(body);
    assert!(text.starts_with("<!doctype html>") && text.contains("src=\"/ui/app.js\""), "{what}: {text}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn json_clients_keep_the_json_answer() {
    let s = Server::start(copy_exec(), |_, _| {}).await;
    let job = s.submit_ok("?filename=a.stl", "application/octet-stream", b"solid x\nendsolid x\n".to_vec()).await;
    let url = s.url(job["url"].as_str().unwrap());
    for accept in
        [None, Some("application/json"), Some("*/*"), Some("application/json, text/html"), Some("text/*;q=0.5, */*")]
    {
        let (status, h, body) = get(&s.client, &url, accept, None).await;
        assert_eq!(status, 200, "{accept:?}");
        assert_eq!(header(&h, "content-type"), "application/json", "{accept:?}");
        assert_eq!(header(&h, "vary"), "accept", "{accept:?}");
        let v: Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(v["id"], job["id"], "{accept:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_browser_gets_the_same_html_shell_for_every_job_path() {
    let s = Server::start(copy_exec(), |_, _| {}).await;
    let job = s.submit_ok("?filename=a.stl", "application/octet-stream", b"solid x\nendsolid x\n".to_vec()).await;
    let url = s.url(job["url"].as_str().unwrap());
    let (status, h, shell) = get(&s.client, &url, Some(BROWSER_ACCEPT), None).await;
    assert_shell(status, &h, &shell, "job page");
    let missing = s.url("/v1/jobs/3f2b8c1e-0a4d-4e5f-9b6a-1c2d3e4f5a6b");
    let (status, h, other) = get(&s.client, &missing, Some("text/html"), None).await;
    assert_shell(status, &h, &other, "unknown job");
    assert_eq!(shell, other, "the shell carries no job data");
    let (status, h, index) = get(&s.client, &s.url("/"), Some(BROWSER_ACCEPT), None).await;
    assert_shell(status, &h, &index, "start page");
    assert_eq!(index, shell);
    // Without an HTML Accept the unknown job is still the JSON 404.
    let (status, h, _) = get(&s.client, &missing, None, None).await;
    assert_eq!((status, header(&h, "content-type")), (404, "application/problem+json"));
    for (path, ct) in [("/ui/app.js", "text/javascript; charset=utf-8"), ("/ui/app.css", "text/css; charset=utf-8")] {
        let (status, h, body) = get(&s.client, &s.url(path), None, None).await;
        assert_eq!((status, header(&h, "content-type")), (200, ct), "{path}");
        assert!(!body.is_empty());
    }
}

/// A server like [`Server::start`] (same store matrix) but with one token (tenant `t`).
async fn start_with_token() -> (String, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let tokens = dir.path().join("tokens.txt");
    std::fs::write(&tokens, format!("{TOKEN} t\n")).unwrap();
    let mut cfg = JobsConfig::new(dir.path().join("data"));
    if let Some(url) = crate::common::matrix_database() {
        cfg.store = meshatlas::jobs::StoreLocation::Postgres(url);
        cfg.artifacts = crate::common::matrix_bucket();
    }
    let jobs = JobService::start(cfg, copy_exec()).unwrap();
    let auth = Some(Arc::new(Auth::load(&tokens, false).unwrap()));
    let state = AppState { jobs, limits: Arc::new(HttpLimits::default()), auth };
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    tokio::spawn(meshatlas::http::serve(listener, state, std::future::pending()));
    (base, dir)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_tokens_the_shell_is_public_and_the_json_needs_a_token() {
    let (base, _dir) = start_with_token().await;
    let client = reqwest::Client::new();
    let form = reqwest::multipart::Form::new()
        .part("file", reqwest::multipart::Part::bytes(b"solid x\nendsolid x\n".to_vec()).file_name("a.stl"));
    let resp = client.post(format!("{base}/v1/jobs")).bearer_auth(TOKEN).multipart(form).send().await.unwrap();
    assert_eq!(resp.status(), 202);
    let job: Value = resp.json().await.unwrap();
    let url = format!("{base}{}", job["url"].as_str().unwrap());

    let (status, h, _) = get(&client, &url, Some("application/json"), None).await;
    assert_eq!(status, 401, "JSON without a token");
    assert!(header(&h, "www-authenticate").starts_with("Bearer"));
    let (status, _, _) = get(&client, &url, Some("application/json"), Some(TOKEN)).await;
    assert_eq!(status, 200, "JSON with the token");
    for (what, page, accept) in
        [("job page", url.as_str(), BROWSER_ACCEPT), ("start page", &format!("{base}/"), BROWSER_ACCEPT)]
    {
        let (status, h, body) = get(&client, page, Some(accept), None).await;
        assert_shell(status, &h, &body, what);
    }
    let (status, _, _) = get(&client, &format!("{base}/ui/app.js"), None, None).await;
    assert_eq!(status, 200, "the script is public");
    // Only the shell: the list and the artifacts need the token even from a browser.
    for path in ["/v1/jobs".to_string(), format!("{}/artifacts/copy.bin", job["url"].as_str().unwrap())] {
        let (status, _, _) = get(&client, &format!("{base}{path}"), Some(BROWSER_ACCEPT), None).await;
        assert_eq!(status, 401, "{path}");
    }
}
