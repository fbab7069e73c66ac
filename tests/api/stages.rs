//! The three stages through the API: one job runs atlas, crossfield and
//! frames on a closed surface; the job resource shows their summaries and
//! timings, and every named artifact downloads and reads back. Stage
//! failures on bad input are problem+json with the stage's kind.

use std::sync::Arc;

use meshatlas::jobs::pipeline_executor::PipelineExecutor;
use serde_json::Value;

use crate::common::Server;
use crate::errors::urlenc;
use crate::fixtures;

const ARTIFACTS: &[&str] = &[
    "mesh.msh",
    "mesh.vtu",
    "report.json",
    "atlas.msh",
    "atlas.vtu",
    "atlas_uv.vtu",
    "crossfield.vtu",
    "crossfield.msh",
    "singularities.json",
    "frames.vtu",
    "frames_singular.vtu",
];

async fn download(s: &Server, job: &Value, name: &str) -> Vec<u8> {
    let art = job["artifacts"].as_array().unwrap().iter().find(|a| a["name"] == name);
    let art = art.unwrap_or_else(|| panic!("no artifact {name} in {job:#}"));
    let r = s.client.get(s.url(art["url"].as_str().unwrap())).send().await.unwrap();
    assert_eq!(r.status(), 200, "{name}");
    r.bytes().await.unwrap().to_vec()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn all_three_stages_run_in_one_job() {
    let s = Server::start(Arc::new(PipelineExecutor), |c, _| c.workers = 1).await;
    let mesh = meshatlas::mesh::fixtures::icosphere(3);
    let q = format!(
        "?filename=ball.stl&params={}",
        urlenc(r#"{"stages":["frames","atlas","crossfield"],"frames":{"target_size":0.2}}"#)
    );
    let job = s.submit_ok(&q, "application/octet-stream", fixtures::stl_binary(&mesh)).await;
    let job = s.wait_final(job["id"].as_str().unwrap()).await;
    assert_eq!(job["state"], "succeeded", "{job:#}");
    for stage in ["atlas", "crossfield", "frames"] {
        assert!(job["summary"]["stages"][stage].is_object(), "no {stage} summary: {job:#}");
        assert!(job["stage_seconds"][stage].as_f64().is_some(), "no {stage} timing: {job:#}");
    }
    assert!(job["summary"]["stages"]["atlas"]["n_patches"].as_u64().unwrap() >= 2);
    let sing: Value = serde_json::from_slice(&download(&s, &job, "singularities.json").await).unwrap();
    assert_eq!(sing["euler_characteristic"], 2);
    assert_eq!(sing["singularities"].as_array().unwrap().len(), 8, "{sing:#}");
    let dir = tempfile::tempdir().unwrap();
    for name in ARTIFACTS {
        let bytes = download(&s, &job, name).await;
        assert!(!bytes.is_empty(), "{name} is empty");
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    // meshio reads every mesh artifact.
    let paths: Vec<String> = ARTIFACTS
        .iter()
        .filter(|n| n.ends_with(".vtu") || n.ends_with(".msh"))
        .map(|n| dir.path().join(n).to_string_lossy().into_owned())
        .collect();
    let out = std::process::Command::new("python3")
        .args(["-c", "import sys, meshio\nfor p in sys.argv[1:]:\n    m = meshio.read(p)\n    assert len(m.points) > 0, p\nprint('ok')"])
        .args(&paths)
        .output()
        .expect("python3 (run .ci/run)");
    assert!(out.status.success(), "meshio: {}", String::from_utf8_lossy(&out.stderr));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_on_an_open_surface_fail_with_open_surface() {
    let s = Server::start(Arc::new(PipelineExecutor), |c, _| c.workers = 1).await;
    let mesh = meshatlas::mesh::fixtures::disk(4);
    let q = "?filename=disk.stl&stages=frames";
    let job = s.submit_ok(q, "application/octet-stream", fixtures::stl_binary(&mesh)).await;
    let job = s.wait_final(job["id"].as_str().unwrap()).await;
    assert_eq!(job["state"], "failed", "{job:#}");
    assert_eq!(job["error"]["type"], "urn:meshatlas:problem:open-surface", "{job:#}");
    assert!(job["error"]["detail"].as_str().unwrap().contains("boundary loop"), "{job:#}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stage_options_are_validated_at_submission() {
    let s = Server::start(Arc::new(PipelineExecutor), |_, _| {}).await;
    for (params, field) in [
        (r#"{"atlas":{"feature_angle_deg":400}}"#, "atlas.feature_angle_deg"),
        (r#"{"crossfield":{"symmetry":5}}"#, "crossfield.symmetry"),
        (r#"{"atlas":{"wobble":1}}"#, "atlas.wobble"),
        (r#"{"frames":{"tau_shrink":2}}"#, "frames.tau_shrink"),
        (r#"{"quads":{"order":3}}"#, "quads.order"),
        (r#"{"quads":{"size":-1}}"#, "quads.size"),
        (r#"{"quads":{"sise":1}}"#, "quads.sise"),
    ] {
        let q = format!("?params={}", urlenc(params));
        let r = s.submit_raw(&q, "application/octet-stream", b"solid x\nendsolid x\n".to_vec()).await;
        let body = crate::common::expect_problem(r, 422, "invalid-params").await;
        assert_eq!(body["field"], field, "{params}: {body:#}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn output_options_choose_the_msh_version_of_the_mesh_artifacts() {
    let s = Server::start(Arc::new(PipelineExecutor), |c, _| c.workers = 1).await;
    let mesh = meshatlas::mesh::fixtures::icosphere(2);
    let params = r#"{"stages":["crossfield"],"output":{"msh_version":"2.2"}}"#;
    let q = format!("?filename=ball.stl&params={}", urlenc(params));
    let job = s.submit_ok(&q, "application/octet-stream", fixtures::stl_binary(&mesh)).await;
    let job = s.wait_final(job["id"].as_str().unwrap()).await;
    assert_eq!(job["state"], "succeeded", "{job:#}");
    for name in ["mesh.msh", "crossfield.msh"] {
        let bytes = download(&s, &job, name).await;
        assert!(bytes.starts_with(b"$MeshFormat\n2.2 0 8\n"), "{name}: {:?}", String::from_utf8_lossy(&bytes[..30]));
    }
    // Binary output exists for MSH 4.1 only: the combination is refused at submission.
    let bad = format!("?params={}", urlenc(r#"{"output":{"msh_version":"2.2","msh_binary":true}}"#));
    let r = s.submit_raw(&bad, "application/octet-stream", fixtures::stl_binary(&mesh)).await;
    assert_eq!(r.status(), 422);
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["field"], "output.msh_binary", "{body}");
}
