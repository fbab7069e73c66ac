//! The quads stage through the real binary (`meshatlas run --stages quads`):
//! the atlas and the crossfield are added and named in `stages_added`,
//! `report.json` carries `stages.quads`, and the artifacts `quads.msh` and
//! `quads.vtu` open in Gmsh (positive `minSICN` on every quad), meshio and
//! VTK. Known answers from the issue: a unit square has no irregular vertex
//! and a minimum scaled Jacobian ≥ 0.95; a sphere at most 10 irregular
//! vertices and none of valence ≥ 6. A size asking for too many quads fails
//! with the frames stage's `invalid-target-size`.

mod common;

use common::{path_str, python, scratch};
use meshatlas::mesh::{TriMesh, fixtures};
use serde_json::{Value, json};
use std::path::Path;
use std::process::Command;

fn write_obj(path: &Path, mesh: &TriMesh) {
    let mut s = String::new();
    for p in &mesh.positions {
        s.push_str(&format!("v {:?} {:?} {:?}\n", p.x, p.y, p.z));
    }
    for t in &mesh.triangles {
        s.push_str(&format!("f {} {} {}\n", t[0].idx() + 1, t[1].idx() + 1, t[2].idx() + 1));
    }
    std::fs::write(path, s).unwrap();
}

/// Runs `meshatlas run` on `mesh` with `params`; the exit status, the
/// report (or stderr) and the output directory.
fn run(name: &str, mesh: &TriMesh, params: &str) -> (bool, Value, std::path::PathBuf, String) {
    let dir = scratch("quads_stage", name);
    let input = dir.join(format!("{name}.obj"));
    write_obj(&input, mesh);
    let p = dir.join("params.json");
    std::fs::write(&p, params).unwrap();
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_meshatlas"))
        .arg("run")
        .arg(&input)
        .arg("--out")
        .arg(&out)
        .arg("--params")
        .arg(&p)
        .arg("--json")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    let report = if o.status.success() { serde_json::from_slice(&o.stdout).unwrap() } else { Value::Null };
    (o.status.success(), report, out, stderr)
}

const TOOLS: &str = r#"
msh, vtu, log = sys.argv[1], sys.argv[2], sys.argv[3]
gmsh.initialize(["-nt", "1"])
gmsh.option.setNumber("General.Terminal", 0)
gmsh.open(msh)
sicn, types = [], set()
for (_, s) in gmsh.model.getEntities(2):
    t, tags, _ = gmsh.model.mesh.getElements(2, s)
    types.update(int(x) for x in t)
    for tg in tags:
        sicn.extend(gmsh.model.mesh.getElementQualities(list(tg), "minSICN"))
ent = [len(gmsh.model.getEntities(d)) for d in range(3)]
gmsh.finalize()
m1, m2 = meshio.read(msh), meshio.read(vtu)
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
from vtkmodules.vtkCommonCore import vtkFileOutputWindow, vtkOutputWindow
import os
w = vtkFileOutputWindow(); w.SetFileName(log); vtkOutputWindow.SetInstance(w)
r = vtkXMLUnstructuredGridReader(); r.SetFileName(vtu); r.Update()
g = r.GetOutput()
print(json.dumps({"n_rated": len(sicn), "min_sicn": min(sicn), "types": sorted(types), "entities": ent,
    "meshio_msh": {c.type: len(c.data) for c in m1.cells}, "meshio_vtu": {c.type: len(c.data) for c in m2.cells},
    "vtk_error": r.GetErrorCode(), "vtk_log": open(log).read() if os.path.exists(log) else "",
    "vtk_types": sorted(set(g.GetCellType(i) for i in range(g.GetNumberOfCells()))), "vtk_cells": g.GetNumberOfCells()}))
"#;

/// Every quad of the artifacts in `out` is rated positive by Gmsh, and
/// meshio and VTK read them; the tools' answers.
fn open_artifacts(out: &Path, n_quads: u64) -> Value {
    let log = out.join("vtk.log");
    let r = python(TOOLS, &[path_str(&out.join("quads.msh")), path_str(&out.join("quads.vtu")), path_str(&log)]);
    assert_eq!(r["n_rated"], json!(n_quads), "{r}");
    assert!(r["min_sicn"].as_f64().unwrap() > 0.0, "an inverted quad: {r}");
    assert_eq!((&r["vtk_error"], &r["vtk_log"]), (&json!(0), &json!("")), "{r}");
    assert_eq!(r["vtk_cells"], json!(n_quads), "{r}");
    r
}

/// The common assertions on a successful run.
fn quads_report(report: &Value) -> &Value {
    assert_eq!(report["stages_added"], json!(["atlas", "crossfield"]), "{report:#}");
    let names: Vec<&str> =
        report["artifacts"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
    assert!(names.contains(&"quads.msh") && names.contains(&"quads.vtu"), "{names:?}");
    assert!(report["timings"].as_array().unwrap().iter().any(|t| t["step"] == "quads"), "{report:#}");
    let q = &report["stages"]["quads"];
    assert_eq!((&q["n_triangles"], &q["n_inverted"]), (&json!(0), &json!(0)), "{q:#}");
    assert!(q["scaled_jacobian_min"].as_f64().unwrap() > 0.0, "{q:#}");
    q
}

#[test]
fn a_unit_square_is_a_regular_grid() {
    let (ok, report, out, stderr) =
        run("square", &fixtures::square(16), r#"{"stages": ["quads"], "quads": {"size": 0.1}}"#);
    assert!(ok, "{stderr}");
    let q = quads_report(&report);
    assert_eq!(q["n_irregular_vertices"], json!(0), "{q:#}");
    assert!(q["scaled_jacobian_min"].as_f64().unwrap() >= 0.95, "{q:#}");
    let r = open_artifacts(&out, q["n_quads"].as_u64().unwrap());
    assert_eq!((&r["types"], &r["vtk_types"], &r["entities"][2]), (&json!([3]), &json!([9]), &json!(1)), "{r}");
}

#[test]
fn a_sphere_at_order_2_gives_9_node_quads_that_every_reader_opens() {
    // The sphere's irregular-vertex bound (≤ 10) is the known answer in
    // tests/quads_known_answers.rs, not yet met (issue 13).
    let params = r#"{"stages": ["quads"], "quads": {"order": 2}}"#;
    let (ok, report, out, stderr) = run("sphere", &fixtures::icosphere(3), params);
    assert!(ok, "{stderr}");
    let q = quads_report(&report);
    assert_eq!(q["order"], json!(2));
    let r = open_artifacts(&out, q["n_quads"].as_u64().unwrap());
    assert_eq!((&r["types"], &r["vtk_types"]), (&json!([10]), &json!([28])), "{r}");
    assert!(r["meshio_vtu"]["quad9"].as_u64().is_some(), "{r}");
}

#[test]
fn a_size_asking_for_too_many_quads_is_an_invalid_target_size() {
    // Rejected before any quad is placed (10^12 quads of the unit square).
    let (ok, _, _, stderr) = run("too_many", &fixtures::square(4), r#"{"stages": ["quads"], "quads": {"size": 1e-6}}"#);
    assert!(!ok);
    assert!(stderr.contains("invalid-target-size") && stderr.contains("quads"), "{stderr}");
}
