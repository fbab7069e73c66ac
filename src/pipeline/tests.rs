//! Pipeline tests on a fixture written as OBJ (no stages selected).

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use super::*;
use crate::failure::FailureKind;
use crate::progress::{Progress, ProgressSink};

fn write_obj(path: &std::path::Path, mesh: &crate::mesh::TriMesh) {
    let mut s = String::new();
    for p in &mesh.positions {
        s.push_str(&format!("v {:?} {:?} {:?}\n", p.x, p.y, p.z));
    }
    for t in &mesh.triangles {
        s.push_str(&format!("f {} {} {}\n", t[0].idx() + 1, t[1].idx() + 1, t[2].idx() + 1));
    }
    std::fs::write(path, s).unwrap();
}

struct Record(Mutex<Vec<(String, f64)>>);
impl ProgressSink for Record {
    fn report(&self, stage: &str, fraction: f64) {
        self.0.lock().unwrap().push((stage.to_string(), fraction));
    }
}

#[test]
fn no_stage_run_writes_mesh_vtu_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("sphere.obj");
    write_obj(&input, &crate::mesh::fixtures::icosphere(2));
    let out = dir.path().join("out");
    let rec = Arc::new(Record(Mutex::new(Vec::new())));
    let progress = Progress::new(rec.clone(), Arc::new(AtomicBool::new(false)));
    let report = run_pipeline(&input, None, &PipelineParams::default(), &out, &progress).unwrap();
    assert_eq!((report.input.n_triangles, report.input.n_vertices), (320, 162));
    assert_eq!(report.input.name, "sphere.obj");
    assert_eq!(report.input.format, "obj");
    let steps: Vec<&str> = report.timings.iter().map(|t| t.step.as_str()).collect();
    assert_eq!(steps, ["load", "repair", "write", "preview", "glb", "sync"]);
    assert!(report.timings.iter().all(|t| t.seconds >= 0.0));
    let names: Vec<&str> = report.artifacts.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["mesh.msh", "mesh.vtu", "preview.png", "surface.glb"]);
    assert!(report.previews.iter().all(|p| p.error.is_none()), "{:?}", report.previews);
    for a in &report.artifacts {
        assert_eq!(std::fs::metadata(out.join(&a.name)).unwrap().len(), a.bytes);
    }
    let on_disk: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join(REPORT_NAME)).unwrap()).unwrap();
    assert_eq!(on_disk, serde_json::to_value(&report).unwrap());
    // Progress: load then write, never decreasing, ending at 1.
    let got = rec.0.lock().unwrap().clone();
    assert_eq!(got.first().map(|g| g.0.as_str()), Some("load"));
    assert_eq!(got.last().map(|g| (g.0.as_str(), g.1)), Some(("write", 1.0)));
    assert!(got.windows(2).all(|w| w[1].1 >= w[0].1), "{got:?}");
    // The written mesh reads back with the same counts.
    let back = crate::io::load_path(&out.join("mesh.msh"), None, &crate::io::LoadOptions::default()).unwrap();
    assert_eq!((back.surface.n_faces(), back.surface.n_vertices()), (320, 162));
}

#[test]
fn cancel_and_bad_input_are_reported_with_their_kind() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("t.obj");
    write_obj(&input, &crate::mesh::fixtures::tetrahedron());
    let cancel = Arc::new(AtomicBool::new(true));
    let p = Progress::new(Arc::new(Record(Mutex::new(Vec::new()))), cancel);
    let e = run_pipeline(&input, None, &PipelineParams::default(), &dir.path().join("o"), &p).unwrap_err();
    assert!(matches!(e, PipelineError::Cancelled));
    // Not a failure: the runner records it as cancelled before asking for a kind.
    assert_eq!(e.kind(), FailureKind::InternalError);
    let empty = dir.path().join("empty.stl");
    std::fs::write(&empty, b"").unwrap();
    let e =
        run_pipeline(&empty, None, &PipelineParams::default(), &dir.path().join("o2"), &Progress::none()).unwrap_err();
    assert_eq!(e.kind(), FailureKind::EmptyFile, "{e}");
}
