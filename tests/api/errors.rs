//! Every error path answers problem+json with a stable type and a request id.

use std::sync::Arc;

use crate::common::{Server, copy_exec, expect_problem, spin_exec};
use meshatlas::failure::FailureKind;
use meshatlas::jobs::{ExecError, JobError, JobInput, JobOutcome};
use meshatlas::progress::Progress;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unknown_routes_methods_and_ids_are_404_405_problems() {
    let s = Server::start(copy_exec(), |_, _| {}).await;
    let r = s.client.get(s.url("/v2/nothing")).send().await.unwrap();
    expect_problem(r, 404, "not-found").await;
    let r = s.client.put(s.url("/v1/jobs")).send().await.unwrap();
    let allow = r.headers().get("allow").map(|v| v.to_str().unwrap().to_string());
    expect_problem(r, 405, "method-not-allowed").await;
    assert!(allow.is_some_and(|a| a.contains("POST")), "405 keeps the Allow header");
    let r = s.client.get(s.url("/v1/jobs/not-a-uuid")).send().await.unwrap();
    expect_problem(r, 404, "job-not-found").await;
    let missing = uuid_like();
    let r = s.client.get(s.url(&format!("/v1/jobs/{missing}"))).send().await.unwrap();
    let body = expect_problem(r, 404, "job-not-found").await;
    assert!(body["detail"].as_str().unwrap().contains(&missing));
    let r = s.client.delete(s.url(&format!("/v1/jobs/{missing}"))).send().await.unwrap();
    expect_problem(r, 404, "job-not-found").await;
    let r = s.client.post(s.url(&format!("/v1/jobs/{missing}/cancel"))).send().await.unwrap();
    expect_problem(r, 404, "job-not-found").await;
    let r = s.client.get(s.url(&format!("/v1/jobs/{missing}/artifacts/mesh.msh"))).send().await.unwrap();
    expect_problem(r, 404, "job-not-found").await;
}

fn uuid_like() -> String {
    "0b6f2a57-7d3c-4e8a-9f10-2b3c4d5e6f70".to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_request_id_is_echoed() {
    let s = Server::start(copy_exec(), |_, _| {}).await;
    let r = s.client.get(s.url("/nope")).header("x-request-id", "trace-42.a").send().await.unwrap();
    let body = expect_problem(r, 404, "not-found").await;
    assert_eq!(body["request_id"], "trace-42.a");
    // Success responses carry one too.
    let r = s.client.get(s.url("/healthz")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert!(r.headers().get("x-request-id").is_some());
    // An unsafe client id is replaced.
    let r = s.client.get(s.url("/nope")).header("x-request-id", "a b<script>").send().await.unwrap();
    let body = expect_problem(r, 404, "not-found").await;
    assert_ne!(body["request_id"], "a b<script>");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_uploads_get_immediate_4xx() {
    let s = Server::start(copy_exec(), |_, l| l.max_upload_bytes = 1000).await;
    // Empty body.
    let r = s.submit_raw("", "application/octet-stream", vec![]).await;
    expect_problem(r, 400, "empty-file").await;
    // Too large, declared by Content-Length.
    let r = s.submit_raw("", "application/octet-stream", vec![b'x'; 5000]).await;
    let body = expect_problem(r, 413, "upload-too-large").await;
    assert_eq!(body["max_bytes"], 1000);
    // Too large, chunked (no Content-Length): caught while streaming.
    let chunks: Vec<Result<Vec<u8>, std::io::Error>> = (0..10).map(|_| Ok(vec![b'y'; 300])).collect();
    let r = s
        .client
        .post(s.url("/v1/jobs"))
        .header("content-type", "application/octet-stream")
        .body(reqwest::Body::wrap_stream(futures_util::stream::iter(chunks)))
        .send()
        .await
        .unwrap();
    expect_problem(r, 413, "upload-too-large").await;
    // Not a mesh media type.
    let r = s.submit_raw("", "image/png", b"\x89PNG....".to_vec()).await;
    expect_problem(r, 415, "unsupported-media-type").await;
    // Unknown explicit format, unknown query parameter.
    let r = s.submit_raw("?format=dwg", "application/octet-stream", b"solid".to_vec()).await;
    let body = expect_problem(r, 400, "invalid-query").await;
    assert_eq!(body["field"], "format");
    let r = s.submit_raw("?colour=red", "application/octet-stream", b"solid".to_vec()).await;
    expect_problem(r, 400, "invalid-query").await;
    // Nothing was left behind in the upload area.
    assert_eq!(std::fs::read_dir(s.dir.path().join("tmp")).unwrap().count(), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_params_name_the_field() {
    let s = Server::start(copy_exec(), |_, _| {}).await;
    let q = format!("?params={}", urlenc(r#"{"stages":[],"wobble":1}"#));
    let r = s.submit_raw(&q, "application/octet-stream", b"solid x".to_vec()).await;
    let body = expect_problem(r, 422, "invalid-params").await;
    assert_eq!(body["field"], "wobble");
    let q = format!("?params={}", urlenc("{not json"));
    let r = s.submit_raw(&q, "application/octet-stream", b"solid x".to_vec()).await;
    expect_problem(r, 400, "invalid-json").await;
    let r = s.submit_raw("?stages=smoothing", "application/octet-stream", b"solid x".to_vec()).await;
    let body = expect_problem(r, 422, "invalid-params").await;
    assert_eq!(body["field"], "stages[0]");
    // Multipart: params part with an unknown field; unknown part; no file part.
    let form = reqwest::multipart::Form::new()
        .part("file", reqwest::multipart::Part::bytes(b"solid x".to_vec()).file_name("x.stl"))
        .text("params", r#"{"stagez": []}"#);
    let r = s.client.post(s.url("/v1/jobs")).multipart(form).send().await.unwrap();
    let body = expect_problem(r, 422, "invalid-params").await;
    assert_eq!(body["field"], "stagez");
    let form = reqwest::multipart::Form::new()
        .part("file", reqwest::multipart::Part::bytes(b"solid x".to_vec()).file_name("x.stl"))
        .text("colour", "red");
    let r = s.client.post(s.url("/v1/jobs")).multipart(form).send().await.unwrap();
    let body = expect_problem(r, 400, "invalid-multipart").await;
    assert_eq!(body["part"], "colour");
    let form = reqwest::multipart::Form::new().text("params", "{}");
    let r = s.client.post(s.url("/v1/jobs")).multipart(form).send().await.unwrap();
    expect_problem(r, 400, "missing-file").await;
    // List query validation.
    let r = s.client.get(s.url("/v1/jobs?limit=0")).send().await.unwrap();
    let body = expect_problem(r, 400, "invalid-query").await;
    assert_eq!(body["field"], "limit");
    let r = s.client.get(s.url("/v1/jobs?cursor=abc")).send().await.unwrap();
    expect_problem(r, 400, "invalid-query").await;
    // The cursor is exactly the spec's `^[0-9]{0,18}$`: no sign, no spaces, no 19th digit.
    for bad in ["%2B5", "-1", "%205", "1234567890123456789"] {
        let r = s.client.get(s.url(&format!("/v1/jobs?cursor={bad}"))).send().await.unwrap();
        let body = expect_problem(r, 400, "invalid-query").await;
        assert_eq!(body["field"], "cursor", "{bad}");
    }
    for good in ["", "0", "123456789012345678"] {
        let r = s.client.get(s.url(&format!("/v1/jobs?cursor={good}"))).send().await.unwrap();
        assert_eq!(r.status(), 200, "cursor `{good}`");
    }
    // The two combinations the spec states in prose (JSON Schema cannot span two
    // parts of a request): parameters given twice, stages given twice.
    let form = reqwest::multipart::Form::new()
        .part("file", reqwest::multipart::Part::bytes(b"solid x".to_vec()).file_name("x.stl"))
        .text("params", "{}");
    let r = s.client.post(s.url(&format!("/v1/jobs?params={}", urlenc("{}")))).multipart(form).send().await.unwrap();
    let body = expect_problem(r, 400, "bad-request").await;
    assert!(body["detail"].as_str().unwrap().contains("parameters given twice"), "{body}");
    let q = format!("?stages=atlas&params={}", urlenc(r#"{"stages":[]}"#));
    let r = s.submit_raw(&q, "application/octet-stream", b"solid x".to_vec()).await;
    let body = expect_problem(r, 400, "bad-request").await;
    assert!(body["detail"].as_str().unwrap().contains("stages given twice"), "{body}");
    // `?stages=` is names between single commas, verbatim: an empty item or a
    // padded name is an unknown stage, named by its index.
    for (bad, field) in [("atlas,,crossfield", "stages[1]"), ("%20atlas", "stages[0]"), ("atlas,", "stages[1]")] {
        let r = s.submit_raw(&format!("?stages={bad}"), "application/octet-stream", b"solid x".to_vec()).await;
        let body = expect_problem(r, 422, "invalid-params").await;
        assert_eq!(body["field"], field, "{bad}");
    }
}

pub fn urlenc(s: &str) -> String {
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_queue_answers_429_with_retry_after() {
    let s = Server::start(spin_exec(), |c, l| {
        c.workers = 1;
        c.max_queued = 1;
        l.retry_after_secs = 7;
    })
    .await;
    let a = s.submit_ok("?format=stl", "application/octet-stream", b"solid a".to_vec()).await;
    let a_id = a["id"].as_str().unwrap().to_string();
    s.wait_until(&a_id, |j| j["state"] == "running").await;
    let _b = s.submit_ok("?format=stl", "application/octet-stream", b"solid b".to_vec()).await;
    let r = s.submit_raw("", "application/octet-stream", b"solid c".to_vec()).await;
    let retry = r.headers().get("retry-after").map(|v| v.to_str().unwrap().to_string());
    let body = expect_problem(r, 429, "queue-full").await;
    assert_eq!(retry.as_deref(), Some("7"));
    assert_eq!(body["max_queued"], 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn server_errors_are_generic_and_job_failures_are_problems() {
    let exec = Arc::new(|job: &JobInput, _: &Progress| -> Result<JobOutcome, ExecError> {
        if std::fs::read(&job.input).unwrap() == b"big" {
            return Err(ExecError::Failed(JobError::new(FailureKind::TooManyTriangles, "9 triangles, the cap is 4")));
        }
        std::fs::write(job.out_dir.join("a.json"), b"{}").unwrap();
        Ok(JobOutcome::default())
    });
    let s = Server::start(exec, |_, _| {}).await;
    let job = s.submit_ok("?format=stl", "application/octet-stream", b"big".to_vec()).await;
    let done = s.wait_final(job["id"].as_str().unwrap()).await;
    assert_eq!(done["state"], "failed");
    assert_eq!(done["error"]["type"], "urn:meshatlas:problem:too-many-triangles");
    assert_eq!(done["error"]["status"], 422);
    assert_eq!(done["error"]["detail"], "9 triangles, the cap is 4");
    assert!(done["artifacts"].as_array().unwrap().is_empty());
    // An artifact whose file vanished from disk is a server error: generic body.
    let job = s.submit_ok("?format=stl", "application/octet-stream", b"ok".to_vec()).await;
    let id = job["id"].as_str().unwrap();
    let done = s.wait_final(id).await;
    assert_eq!(done["state"], "succeeded");
    // The file is in the data directory, and (PostgreSQL matrix) an object in the bucket too.
    std::fs::remove_file(s.dir.path().join("jobs").join(id).join("out/1/a.json")).unwrap();
    let artifacts = &s.jobs.config().artifacts;
    if *artifacts != meshatlas::jobs::artifact_store::ArtifactLocation::Local {
        let bucket = meshatlas::jobs::artifact_store::open(artifacts).unwrap();
        bucket.delete_prefix(&format!("jobs/{id}/out/1/"), None).unwrap();
    }
    let r = s.client.get(s.url(&format!("/v1/jobs/{id}/artifacts/a.json"))).send().await.unwrap();
    let body = expect_problem(r, 500, "internal-error").await;
    assert!(!body["detail"].as_str().unwrap().contains("a.json"), "no internals in 5xx: {body}");
    let r = s.client.get(s.url(&format!("/v1/jobs/{id}/artifacts/nope.txt"))).send().await.unwrap();
    expect_problem(r, 404, "artifact-not-found").await;
}
