//! The real pipeline behind the API: every input format, artifacts read
//! back, reader failures and the triangle cap as job errors.

use std::sync::Arc;

use meshatlas::io::{LoadOptions, load_path};
use meshatlas::jobs::pipeline_executor::PipelineExecutor;
use serde_json::Value;

use crate::common::{Server, expect_problem};
use crate::errors::urlenc;
use crate::fixtures::{self, N_TRIANGLES, N_VERTICES};

async fn download(s: &Server, job: &Value, name: &str) -> Vec<u8> {
    let art = job["artifacts"].as_array().unwrap().iter().find(|a| a["name"] == name);
    let art = art.unwrap_or_else(|| panic!("no artifact {name} in {job:#}"));
    let r = s.client.get(s.url(art["url"].as_str().unwrap())).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], art["media_type"].as_str().unwrap());
    let bytes = r.bytes().await.unwrap().to_vec();
    assert_eq!(bytes.len() as u64, art["bytes"].as_u64().unwrap());
    bytes
}

fn meshio_triangles(path: &std::path::Path) -> Option<usize> {
    let out = std::process::Command::new("python3")
        .args(["-c", "import sys, meshio; m = meshio.read(sys.argv[1]); print(sum(len(c.data) for c in m.cells if c.type == 'triangle'))"])
        .arg(path)
        .output()
        .ok()?;
    if !out.status.success() {
        panic!("meshio cannot read {}: {}", path.display(), String::from_utf8_lossy(&out.stderr));
    }
    String::from_utf8_lossy(&out.stdout).trim().parse().ok()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_format_runs_and_its_artifacts_read_back() {
    let s = Server::start(Arc::new(PipelineExecutor), |c, _| c.workers = 2).await;
    let m = fixtures::mesh();
    let cases: Vec<(&str, String, &str, Vec<u8>)> = vec![
        ("stl-ascii", "?filename=a.stl".into(), "application/octet-stream", fixtures::stl_ascii(&m)),
        ("stl-binary", "".into(), "model/stl", fixtures::stl_binary(&m)),
        ("stl-binary-sniffed", "".into(), "application/octet-stream", fixtures::stl_binary(&m)),
        ("obj", "?filename=sphere.obj".into(), "application/octet-stream", fixtures::obj(&m)),
        ("ply-ascii", "?format=ply".into(), "application/octet-stream", fixtures::ply_ascii(&m)),
        ("ply-binary", "".into(), "application/octet-stream", fixtures::ply_binary_le(&m)),
        ("msh22", "?filename=s.msh".into(), "application/octet-stream", fixtures::msh22(&m)),
        ("msh41", "".into(), "application/octet-stream", fixtures::msh41(&m)),
    ];
    let mut jobs = Vec::new();
    for (name, q, ct, body) in cases {
        let j = s.submit_ok(&q, ct, body).await;
        jobs.push((name, j["id"].as_str().unwrap().to_string()));
    }
    let dir = tempfile::tempdir().unwrap();
    for (name, id) in jobs {
        let job = s.wait_final(&id).await;
        assert_eq!(job["state"], "succeeded", "{name}: {job:#}");
        let summary = &job["summary"];
        assert_eq!(summary["input"]["n_triangles"], N_TRIANGLES, "{name}");
        assert_eq!(summary["input"]["n_vertices"], N_VERTICES, "{name}");
        assert!(summary["repair"].is_object(), "{name}");
        for step in ["load", "write"] {
            assert!(job["stage_seconds"][step].as_f64().is_some_and(|t| t >= 0.0), "{name}: {step}");
        }
        let report: Value = serde_json::from_slice(&download(&s, &job, "report.json").await).unwrap();
        assert_eq!(&report, summary, "{name}: report.json is the summary");
        let msh = dir.path().join(format!("{name}.msh"));
        std::fs::write(&msh, download(&s, &job, "mesh.msh").await).unwrap();
        let back = load_path(&msh, None, &LoadOptions::default()).unwrap();
        assert_eq!((back.surface.n_vertices(), back.surface.n_faces()), (N_VERTICES, N_TRIANGLES), "{name}");
        let vtu = dir.path().join(format!("{name}.vtu"));
        std::fs::write(&vtu, download(&s, &job, "mesh.vtu").await).unwrap();
        if let Some(n) = meshio_triangles(&vtu) {
            assert_eq!(n, N_TRIANGLES, "{name}: meshio reads mesh.vtu");
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gmsh_written_parametric_msh41_and_a_corpus_stl_run_like_a_local_load() {
    let s = Server::start(Arc::new(PipelineExecutor), |_, _| {}).await;
    for rel in ["gmsh/sphere_tiny_atlas.msh", "corpus/cylinder_coarse.stl"] {
        let path = fixtures::shared_data(rel);
        let local = load_path(&path, None, &LoadOptions::default()).unwrap();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let form = reqwest::multipart::Form::new()
            .part("file", reqwest::multipart::Part::bytes(std::fs::read(&path).unwrap()).file_name(name));
        let r = s.client.post(s.url("/v1/jobs")).multipart(form).send().await.unwrap();
        assert_eq!(r.status(), 202, "{rel}");
        let job: Value = r.json().await.unwrap();
        let done = s.wait_final(job["id"].as_str().unwrap()).await;
        assert_eq!(done["state"], "succeeded", "{rel}: {done:#}");
        assert_eq!(done["summary"]["input"]["n_triangles"], local.surface.n_faces(), "{rel}");
        assert_eq!(done["summary"]["input"]["n_vertices"], local.surface.n_vertices(), "{rel}");
        assert_eq!(done["summary"]["repair"], serde_json::to_value(&local.repair).unwrap(), "{rel}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reader_failures_and_caps_fail_the_job_with_their_kind() {
    let s = Server::start(Arc::new(PipelineExecutor), |c, _| c.max_triangles = 50).await;
    let m = fixtures::mesh();
    // Truncated binary STL: the job fails with the reader's kind.
    let mut trunc = fixtures::stl_binary(&m);
    trunc.truncate(84 + 50 * 10 + 7);
    let j = s.submit_ok("?format=stl", "application/octet-stream", trunc).await;
    let done = s.wait_final(j["id"].as_str().unwrap()).await;
    assert_eq!(done["state"], "failed");
    assert_eq!(done["error"]["type"], "urn:meshatlas:problem:truncated", "{done:#}");
    assert_eq!(done["error"]["status"], 422);
    // A line that does not parse.
    let bad = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n".to_vec();
    let j = s.submit_ok("?format=obj", "application/octet-stream", bad).await;
    let done = s.wait_final(j["id"].as_str().unwrap()).await;
    assert_eq!(done["state"], "failed");
    assert_eq!(done["error"]["type"], "urn:meshatlas:problem:parse-error", "{done:#}");
    // 80 triangles over the server cap of 50.
    let j = s.submit_ok("?format=stl", "application/octet-stream", fixtures::stl_ascii(&m)).await;
    let done = s.wait_final(j["id"].as_str().unwrap()).await;
    assert_eq!(done["error"]["type"], "urn:meshatlas:problem:too-many-triangles", "{done:#}");
    assert_eq!(done["error"]["status"], 422);
    // The job's own cap, when smaller, applies too.
    let q = format!("?format=stl&params={}", urlenc(r#"{"load":{"max_triangles":10}}"#));
    let j = s.submit_ok(&q, "application/octet-stream", fixtures::stl_ascii(&m)).await;
    assert_eq!(j["params"]["load"]["max_triangles"], 10);
    let done = s.wait_final(j["id"].as_str().unwrap()).await;
    assert_eq!(done["error"]["type"], "urn:meshatlas:problem:too-many-triangles", "{done:#}");
    // Nested unknown parameter: named with its path.
    let q = format!("?params={}", urlenc(r#"{"load":{"wobble":1}}"#));
    let r = s.submit_raw(&q, "application/octet-stream", fixtures::stl_ascii(&m)).await;
    let body = expect_problem(r, 422, "invalid-params").await;
    assert_eq!(body["field"], "load.wobble");
    // Content that is no mesh format at all, named by nothing: accepted (the spec
    // cannot say which bytes are a mesh), then the job's reader names the defect.
    let j = s.submit_ok("", "application/octet-stream", b"\x00\x01garbage that is no mesh".to_vec()).await;
    assert_eq!(j["input"]["format"], serde_json::Value::Null, "{j:#}");
    let done = s.wait_final(j["id"].as_str().unwrap()).await;
    assert_eq!(done["state"], "failed", "{done:#}");
    assert_eq!(done["error"]["type"], "urn:meshatlas:problem:unknown-format", "{done:#}");
}
