//! Hostile request contents (issue 11, items 2, 5, 8 and 10): multipart
//! framing that is not counted against the upload limit (part headers,
//! preamble), client values that forge log lines, parameters that are not a
//! JSON object, and Range headers the server should ignore rather than
//! refuse.

use std::time::Duration;

use serde_json::Value;

use crate::common::{Server, is_final, shared_data};

/// Boundary of the hand-made multipart bodies.
const BOUNDARY: &str = "hostileBOUNDARY0123";

/// A small valid STL body (the bundled tiny sphere).
fn tiny_stl() -> Vec<u8> {
    std::fs::read(shared_data("gmsh/sphere_tiny.stl")).unwrap()
}

/// A hand-made multipart body: `preamble`, a `file` part with `extra_headers`
/// (each line without CRLF) and `file`, a `params` part, the close delimiter.
fn multipart_body(preamble: &[u8], extra_headers: &[String], file: &[u8], params: &str) -> Vec<u8> {
    let mut b = preamble.to_vec();
    b.extend_from_slice(format!("--{BOUNDARY}\r\n").as_bytes());
    b.extend_from_slice(b"Content-Disposition: form-data; name=\"file\"; filename=\"m.stl\"\r\n");
    for h in extra_headers {
        b.extend_from_slice(h.as_bytes());
        b.extend_from_slice(b"\r\n");
    }
    b.extend_from_slice(b"\r\n");
    b.extend_from_slice(file);
    b.extend_from_slice(format!("\r\n--{BOUNDARY}\r\n").as_bytes());
    b.extend_from_slice(b"Content-Disposition: form-data; name=\"params\"\r\n\r\n");
    b.extend_from_slice(params.as_bytes());
    b.extend_from_slice(format!("\r\n--{BOUNDARY}--\r\n").as_bytes());
    b
}

/// POSTs `body` as `multipart/form-data` with [`BOUNDARY`].
async fn post_multipart(s: &Server, body: reqwest::Body) -> reqwest::Result<reqwest::Response> {
    s.client
        .post(s.url("/v1/jobs"))
        .header("content-type", format!("multipart/form-data; boundary={BOUNDARY}"))
        .body(body)
        .timeout(Duration::from_secs(90))
        .send()
        .await
}

/// Asserts a problem+json answer of `status` and `kind`; returns the body.
async fn expect_problem(r: reqwest::Response, status: u16, kind: &str) -> Value {
    assert_eq!(r.status().as_u16(), status, "unexpected status");
    let ct = r.headers().get("content-type").map(|v| v.to_str().unwrap().to_string());
    assert_eq!(ct.as_deref(), Some("application/problem+json"));
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["type"], format!("urn:meshatlas:problem:{kind}"), "{body:#}");
    body
}

/// Number of jobs the server has recorded.
async fn job_count(s: &Server) -> usize {
    let list: Value = s.client.get(s.url("/v1/jobs?limit=100")).send().await.unwrap().json().await.unwrap();
    list["jobs"].as_array().map_or(0, Vec::len)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_part_header_block_over_8_kib_is_rejected() {
    let s = Server::start(&["--max-upload-bytes", "1048576"]);
    let junk = format!("X-Junk: {}", "a".repeat(64 * 1024));
    let body = multipart_body(b"", &[junk], &tiny_stl(), r#"{"stages": []}"#);
    let r = post_multipart(&s, body.into()).await.unwrap();
    let p = expect_problem(r, 400, "invalid-multipart").await;
    assert!(p["detail"].as_str().unwrap().contains("headers exceed 8192 bytes"), "{p:#}");
    // Many short header lines count as much as one long one.
    let lines: Vec<String> = (0..400).map(|i| format!("X-Junk-{i}: {}", "b".repeat(40))).collect();
    let body = multipart_body(b"", &lines, &tiny_stl(), r#"{"stages": []}"#);
    let r = post_multipart(&s, body.into()).await.unwrap();
    expect_problem(r, 400, "invalid-multipart").await;
    // Ordinary headers still pass.
    let ok = vec!["Content-Type: model/stl".to_string(), format!("X-Note: {}", "c".repeat(1000))];
    let body = multipart_body(b"", &ok, &tiny_stl(), r#"{"stages": []}"#);
    let r = post_multipart(&s, body.into()).await.unwrap();
    assert_eq!(r.status(), 202, "{}", r.text().await.unwrap());
    assert_eq!(job_count(&s).await, 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_preamble_over_8_kib_is_rejected() {
    let s = Server::start(&["--max-upload-bytes", "1048576"]);
    let preamble = vec![b'p'; 64 * 1024];
    let body = multipart_body(&preamble, &[], &tiny_stl(), r#"{"stages": []}"#);
    let r = post_multipart(&s, body.into()).await.unwrap();
    let p = expect_problem(r, 400, "invalid-multipart").await;
    assert!(p["detail"].as_str().unwrap().contains("preamble"), "{p:#}");
    // A short preamble (allowed by RFC 2046, ignored) still passes.
    let body = multipart_body(b"this is a preamble\r\n", &[], &tiny_stl(), r#"{"stages": []}"#);
    let r = post_multipart(&s, body.into()).await.unwrap();
    assert_eq!(r.status(), 202, "{}", r.text().await.unwrap());
    assert_eq!(job_count(&s).await, 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn multipart_parts_keep_their_own_limits() {
    // Not a defect of issue 11: the limits that held must still hold with the new parser.
    let s = Server::start(&["--max-upload-bytes", "1048576"]);
    let big = vec![b'a'; 1024 * 1024 + 1];
    let r = post_multipart(&s, multipart_body(b"", &[], &big, "{}").into()).await.unwrap();
    expect_problem(r, 413, "upload-too-large").await;
    // The same without Content-Length (chunked): the file part's own limit answers.
    let chunked = generated_body(multipart_body(b"", &[], &big, "{}"), b'x', 0, Vec::new());
    let r = post_multipart(&s, chunked).await.unwrap();
    expect_problem(r, 413, "upload-too-large").await;
    let params = format!("{{\"stages\": [], \"x\": \"{}\"}}", "p".repeat(70 * 1024));
    let r = post_multipart(&s, multipart_body(b"", &[], &tiny_stl(), &params).into()).await.unwrap();
    expect_problem(r, 422, "invalid-params").await;
    // (A declared Content-Length over the limit is refused early, so the body as a whole stays under it.)
    let exact = vec![b'a'; 1024 * 1024 - 2048];
    let r = post_multipart(&s, multipart_body(b"", &[], &exact, r#"{"stages": []}"#).into()).await.unwrap();
    assert_eq!(r.status(), 202, "a file just under the limit fits");
    let r = s
        .client
        .post(s.url("/v1/jobs"))
        .header("content-type", "multipart/form-data")
        .body(multipart_body(b"", &[], &tiny_stl(), "{}"))
        .send()
        .await
        .unwrap();
    expect_problem(r, 400, "invalid-multipart").await;
    assert!(s.tmp_files().is_empty(), "{:?}", s.tmp_files());
}

/// Streams `prefix` followed by `n_chunks` chunks of 64 KiB of `fill`
/// (generated, never held whole in memory), then `suffix`.
fn generated_body(prefix: Vec<u8>, fill: u8, n_chunks: usize, suffix: Vec<u8>) -> reqwest::Body {
    let chunks = std::iter::once(prefix)
        .chain((0..n_chunks).map(move |_| vec![fill; 64 * 1024]))
        .chain(std::iter::once(suffix))
        .map(Ok::<Vec<u8>, std::io::Error>);
    reqwest::Body::wrap_stream(futures_util::stream::iter(chunks))
}

/// Sends a 200 MB framing attack to a server with a 1 MiB upload limit and
/// checks it is refused without the server's memory growing with it.
async fn refused_with_small_memory(prefix: Vec<u8>, suffix: Vec<u8>, cause: &str) {
    let s = Server::start(&["--max-upload-bytes", "1048576"]);
    let start_kib = s.rss_kib();
    let result = post_multipart(&s, generated_body(prefix, b'j', 200 * 16, suffix)).await;
    // The server may answer and close before the client has sent it all.
    if let Ok(r) = result {
        let status = r.status().as_u16();
        assert!(status == 400 || status == 413, "the upload was not refused: {status} {}", r.text().await.unwrap());
    }
    let peak_kib = s.peak_rss_kib();
    assert!(peak_kib < start_kib + 100 * 1024, "peak RSS {peak_kib} KiB from {start_kib} KiB at start");
    assert_eq!(job_count(&s).await, 0);
    let log = s.log();
    assert!(log.contains("invalid-multipart") && log.contains(cause), "the log names no cause `{cause}`:\n{log}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_200_mb_part_header_is_refused_without_buffering_it() {
    let prefix =
        format!("--{BOUNDARY}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"m.stl\"\r\nX-Junk: ");
    let suffix = format!("\r\n\r\nsolid x\r\n--{BOUNDARY}--\r\n");
    refused_with_small_memory(prefix.into_bytes(), suffix.into_bytes(), "headers exceed").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_200_mb_preamble_is_refused_without_buffering_it() {
    let suffix = format!(
        "\r\n--{BOUNDARY}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"m.stl\"\r\n\r\n\
         solid x\r\n--{BOUNDARY}--\r\n"
    );
    refused_with_small_memory(Vec::new(), suffix.into_bytes(), "preamble").await;
}

/// The text a forged log line would start with.
const FORGED: &str = "2026-01-01T00:00:00.000000Z ERROR meshatlas: FORGED";

/// Percent-encodes every byte that is not unreserved.
fn urlenc(s: &str) -> String {
    s.bytes()
        .map(|b| {
            if b.is_ascii_alphanumeric() || b"-_.~".contains(&b) {
                (b as char).to_string()
            } else {
                format!("%{b:02X}")
            }
        })
        .collect()
}

/// True when `line` starts like `2026-12-01T18:55:50.123456Z`.
fn starts_with_timestamp(line: &str) -> bool {
    let b = line.as_bytes();
    b.len() > 20
        && b[..4].iter().all(u8::is_ascii_digit)
        && b[4] == b'-'
        && b[7] == b'-'
        && b[10] == b'T'
        && b[13] == b':'
        && line.contains('Z')
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn client_values_cannot_forge_log_lines() {
    let s = Server::start(&[]);
    let evil = format!("1\n{FORGED}");
    // The cursor of a list request.
    let r = s.client.get(s.url(&format!("/v1/jobs?cursor={}", urlenc(&evil)))).send().await.unwrap();
    assert_eq!(r.status(), 400);
    // The format of a raw upload.
    let r = s
        .client
        .post(s.url(&format!("/v1/jobs?format={}", urlenc(&evil))))
        .header("content-type", "application/octet-stream")
        .body(tiny_stl())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 400);
    // The stages shorthand.
    let r = s
        .client
        .post(s.url(&format!("/v1/jobs?stages={}", urlenc(&evil))))
        .header("content-type", "application/octet-stream")
        .body(tiny_stl())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    // An unknown params key, in a multipart part and in the query.
    let params = serde_json::json!({ evil.clone(): 1 }).to_string();
    let r = s.submit_bytes("m.stl", tiny_stl(), Some(&params)).await;
    assert_eq!(r.status(), 422);
    let r = s
        .client
        .post(s.url(&format!("/v1/jobs?params={}", urlenc(&params))))
        .header("content-type", "application/octet-stream")
        .body(tiny_stl())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    // A path (the request span logs it).
    let r = s.client.get(s.url("/v1/jobs/%0A2026-01-01T00:00:00.000000Z%20ERROR%20FORGED")).send().await.unwrap();
    assert_eq!(r.status(), 404);
    tokio::time::sleep(Duration::from_millis(200)).await;
    let log = s.log();
    assert!(log.contains("FORGED"), "the values were not logged at all:\n{log}");
    for line in log.lines().filter(|l| !l.trim().is_empty()) {
        assert!(!line.contains(FORGED) || !line.starts_with("2026-01-01"), "forged log line: {line:?}\n{log}");
        assert!(starts_with_timestamp(line), "log line without a timestamp: {line:?}\n{log}");
    }
}

/// Submits `params` as a multipart part and as `?params=`; both answers.
async fn submit_params_both_ways(s: &Server, params: &str) -> [reqwest::Response; 2] {
    let part = s.submit_bytes("m.stl", tiny_stl(), Some(params)).await;
    let query = s
        .client
        .post(s.url(&format!("/v1/jobs?params={}", urlenc(params))))
        .header("content-type", "application/octet-stream")
        .body(tiny_stl())
        .send()
        .await
        .unwrap();
    [part, query]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn params_that_are_not_a_json_object_are_rejected() {
    let s = Server::start(&[]);
    for (params, got) in [
        (r#"[["crossfield"]]"#, "an array"),
        ("[]", "an array"),
        ("  [ ]  ", "an array"),
        ("7", "a number"),
        ("\"atlas\"", "a string"),
        ("null", "null"),
        ("true", "a boolean"),
    ] {
        for r in submit_params_both_ways(&s, params).await {
            let p = expect_problem(r, 422, "invalid-params").await;
            let detail = p["detail"].as_str().unwrap();
            assert!(detail.contains("must be a JSON object") && detail.contains(got), "{params}: {p:#}");
        }
    }
    for r in submit_params_both_ways(&s, "[\"crossfield\"").await {
        expect_problem(r, 400, "invalid-json").await;
    }
    assert_eq!(job_count(&s).await, 0, "no job may have been queued");
}

/// A finished job's `mesh.msh`: its URL and its bytes.
async fn finished_artifact(s: &Server) -> (String, Vec<u8>) {
    let r = s.submit_bytes("sphere_tiny.stl", tiny_stl(), Some(r#"{"stages": []}"#)).await;
    assert_eq!(r.status(), 202);
    let job: Value = r.json().await.unwrap();
    let done = s.wait_final(job["id"].as_str().unwrap(), Duration::from_secs(30)).await;
    assert!(is_final(&done) && done["state"] == "succeeded", "{done:#}");
    let art = done["artifacts"].as_array().unwrap().iter().find(|a| a["name"] == "mesh.msh").expect("mesh.msh");
    let url = s.url(art["url"].as_str().unwrap());
    let r = s.client.get(&url).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers().get("accept-ranges").map(|v| v.to_str().unwrap()), Some("bytes"));
    let full = r.bytes().await.unwrap().to_vec();
    assert!(full.len() > 100);
    (url, full)
}

/// GETs `url` with extra `headers`.
async fn get_with(s: &Server, url: &str, headers: &[(&str, &str)]) -> reqwest::Response {
    let mut req = s.client.get(url);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    req.send().await.unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unsupported_or_invalid_ranges_are_ignored() {
    let s = Server::start(&[]);
    let (url, full) = finished_artifact(&s).await;
    for range in ["bytes=0-9,20-29", "items=0-5", "bytes=abc", "bytes=9-5", "bytes=", "bytes=1-2-3", "0-5"] {
        let r = get_with(&s, &url, &[("range", range)]).await;
        assert_eq!(r.status(), 200, "Range: {range}");
        assert!(r.headers().get("content-range").is_none(), "Range: {range}");
        assert_eq!(r.bytes().await.unwrap().to_vec(), full, "Range: {range}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn single_ranges_are_served_and_unsatisfiable_ones_explained() {
    let s = Server::start(&[]);
    let (url, full) = finished_artifact(&s).await;
    let len = full.len();
    for (range, from, to) in
        [("bytes=0-9", 0, 9), ("bytes=10-", 10, len - 1), ("bytes=-10", len - 10, len - 1), ("Bytes=3-4", 3, 4)]
    {
        let r = get_with(&s, &url, &[("range", range)]).await;
        assert_eq!(r.status(), 206, "Range: {range}");
        assert_eq!(r.headers()["content-range"], format!("bytes {from}-{to}/{len}").as_str(), "Range: {range}");
        assert_eq!(r.bytes().await.unwrap().to_vec(), full[from..=to].to_vec(), "Range: {range}");
    }
    let r = get_with(&s, &url, &[("range", "bytes=999999999-")]).await;
    assert_eq!(
        r.headers().get("content-range").map(|v| v.to_str().unwrap().to_string()),
        Some(format!("bytes */{len}"))
    );
    let p = expect_problem(r, 416, "range-not-satisfiable").await;
    assert!(p["detail"].as_str().unwrap().contains(&len.to_string()), "{p:#}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn if_range_with_a_stale_validator_gives_the_whole_file() {
    let s = Server::start(&[]);
    let (url, full) = finished_artifact(&s).await;
    let head = get_with(&s, &url, &[]).await;
    let etag = head.headers()["etag"].to_str().unwrap().to_string();
    let r = get_with(&s, &url, &[("range", "bytes=0-9"), ("if-range", &etag)]).await;
    assert_eq!(r.status(), 206);
    assert_eq!(r.bytes().await.unwrap().to_vec(), full[..10].to_vec());
    for stale in ["\"0.00000000-0\"", "W/\"0.00000000-0\"", "Tue, 01 Jan 2000 00:00:00 GMT"] {
        let r = get_with(&s, &url, &[("range", "bytes=0-9"), ("if-range", stale)]).await;
        assert_eq!(r.status(), 200, "If-Range: {stale}");
        assert_eq!(r.bytes().await.unwrap().to_vec(), full, "If-Range: {stale}");
    }
}
