//! The quads stage on the real inputs of `../shared/data/corpus` and
//! `../shared/data/gmsh` through the real binary (`meshatlas run --stages
//! quads`): the stage asserts its own checks (0 triangles, no inverted or
//! degenerate quad, coverage, valence identity, conformity; a failed check
//! is an error), so a run that succeeds has passed them; this test adds the
//! report's counts and independent readers: Gmsh must open `quads.msh` and
//! rate every quad with `minSICN > 0`, meshio must read every quad of
//! `quads.msh` and `quads.vtu`, and VTK every quad of `quads.vtu`. And the
//! output bytes do not depend on the thread count (`RAYON_NUM_THREADS` = 1
//! and 2).
//!
//! Every file of both folders is listed in [`INPUTS`] and run (the long ones
//! by a test of their own, which runs beside the others). A file added to a
//! folder without an entry fails [`every_input_file_is_listed`].

mod common;

use common::{path_str, python, scratch, shared_data};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// What this test does with an input file.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Plan {
    /// Run in CI.
    Run,
    /// Run in CI by its own test, beside the others, for its run time.
    Long(&'static str),
}

/// Every input file (folder relative to `../shared/data`, name) and its plan.
const INPUTS: &[(&str, &str, Plan)] = &[
    ("gmsh", "cylinder_44.stl", Plan::Run),
    ("gmsh", "disk_tiny.stl", Plan::Run),
    ("gmsh", "sphere_tiny.stl", Plan::Run),
    ("gmsh", "disk_3k.stl", Plan::Run),
    ("gmsh", "sphere_3k.stl", Plan::Run),
    ("gmsh", "torus_20k.stl", Plan::Run),
    ("corpus", "cylinder_coarse.stl", Plan::Run),
    ("corpus", "gmsh_object.stl", Plan::Run),
    ("corpus", "spot.obj", Plan::Run),
    ("corpus", "gmsh_terrain.stl", Plan::Run),
    ("corpus", "gmsh_aorta2.stl", Plan::Run),
    ("corpus", "aorta_closed.stl", Plan::Run),
    ("corpus", "gmsh_t13.stl", Plan::Run),
    ("corpus", "gmsh_lever.stl", Plan::Run),
    ("corpus", "plate_holes.stl", Plan::Run),
    ("corpus", "featuretype.stl", Plan::Run),
    ("corpus", "fandisk.obj", Plan::Run),
    ("corpus", "cow.obj", Plan::Run),
    ("corpus", "camelhead.obj", Plan::Run),
    ("corpus", "fault_santa_monica_bay.obj", Plan::Run),
    ("corpus", "fault_opal_mound.obj", Plan::Run),
    ("corpus", "fault_ridgecrest_2019.obj", Plan::Run),
    ("corpus", "bunny.obj", Plan::Long("28,569 quads: 12 s in a release build")),
    ("corpus", "adis16480.stl", Plan::Long("34,000 quads (its pins and small holes follow their curvature)")),
];

/// The issue's benchmark inputs, on which midpoint subdivision must not be
/// used (issue 13: "0 triangles, with subdivision used on none of these
/// inputs"), and the CAD parts whose free triangles strips now join.
/// fandisk was subdivided whole until recombination took poor pairs in a
/// face the candidates could not pair; featuretype (57 faces) and gmsh_t13
/// (11) until strips that relaxing folded were rescued and the quads of
/// undone strips were opened again.
const NEVER_SUBDIVIDED: &[&str] = &[
    "sphere_3k.stl",
    "disk_3k.stl",
    "torus_20k.stl",
    "fandisk.obj",
    "cylinder_coarse.stl",
    "gmsh_terrain.stl",
    "featuretype.stl",
    "gmsh_t13.stl",
];

/// The widest subdivision scope (`none` < `triangles` < `faces` <
/// `faces_with_neighbours`) some inputs may use at their default size. In
/// adis16480 and the faults the free triangles are split alone and the
/// midpoints they leave joined through strips; each used to subdivide the
/// whole part at half the size asked (adis16480 went from 133,970 quads to
/// 34,000), and bunny's, since the worst quads are raised by max-min
/// moves, from 118,391 to 28,569. gmsh_lever splits its faces holding free
/// triangles alone: the strips a narrower split needs do not join. cow
/// splits the free triangles of 6 model faces alone.
const SUBDIVISION_SCOPE_AT_MOST: &[(&str, &str)] = &[
    ("adis16480.stl", "triangles"),
    ("fault_ridgecrest_2019.obj", "triangles"),
    ("fault_santa_monica_bay.obj", "triangles"),
    ("gmsh_lever.stl", "faces"),
    ("bunny.obj", "triangles"),
    ("cow.obj", "triangles"),
];

/// Subdivision scopes, narrowest first.
const SCOPES: &[&str] = &["none", "triangles", "faces", "faces_with_neighbours"];

/// Input formats the folders hold; other files (notes, atlases) are not inputs.
const INPUT_EXTENSIONS: &[&str] = &["stl", "obj", "ply"];

fn input_path(folder: &str, name: &str) -> PathBuf {
    shared_data().join(folder).join(name)
}

/// `meshatlas run --stages quads` on `input` into `out` with
/// `RAYON_NUM_THREADS = threads`: the report, or stderr as the error.
fn run_quads(input: &Path, out: &Path, threads: usize) -> Result<Value, String> {
    run_quads_with(input, out, threads, &[])
}

/// [`run_quads`] with `extra` arguments (`--params FILE`, say).
fn run_quads_with(input: &Path, out: &Path, threads: usize, extra: &[&str]) -> Result<Value, String> {
    let o = Command::new(env!("CARGO_BIN_EXE_meshatlas"))
        .env("RAYON_NUM_THREADS", threads.to_string())
        .arg("run")
        .arg(input)
        .arg("--stages")
        .arg("quads")
        .arg("--out")
        .arg(out)
        .arg("--json")
        .args(extra)
        .output()
        .expect("run meshatlas");
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).into_owned());
    }
    serde_json::from_slice(&o.stdout).map_err(|e| format!("bad report JSON: {e}"))
}

/// The three readers a user opens the artifacts with, on each output
/// directory: Gmsh opens `quads.msh` and rates its 2D elements (the count
/// rated and the smallest `minSICN`); meshio reads `quads.msh` and
/// `quads.vtu` (their quad cells counted); VTK's XML reader, what ParaView
/// uses, reads `quads.vtu` (its cell count, error code and anything it
/// logged, into the log file given first).
const READERS: &str = r#"
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
from vtkmodules.vtkCommonCore import vtkFileOutputWindow, vtkOutputWindow
import os
log = sys.argv[1]
w = vtkFileOutputWindow(); w.SetFileName(log); vtkOutputWindow.SetInstance(w)
gmsh.initialize(["-nt", "1"])
gmsh.option.setNumber("General.Terminal", 0)
def quads(path):
    return sum(len(c.data) for c in meshio.read(path).cells if c.type in ("quad", "quad9"))
out = {}
for d in sys.argv[2:]:
    msh, vtu = os.path.join(d, "quads.msh"), os.path.join(d, "quads.vtu")
    gmsh.clear()
    gmsh.open(msh)
    sicn = []
    for (_, s) in gmsh.model.getEntities(2):
        _, tags, _ = gmsh.model.mesh.getElements(2, s)
        for tg in tags:
            sicn.extend(gmsh.model.mesh.getElementQualities(list(tg), "minSICN"))
    r = vtkXMLUnstructuredGridReader(); r.SetFileName(vtu); r.Update()
    out[d] = {"n_rated": len(sicn), "min_sicn": min(sicn) if sicn else None,
              "meshio_msh_quads": quads(msh), "meshio_vtu_quads": quads(vtu),
              "vtk_error": r.GetErrorCode(), "vtk_cells": r.GetOutput().GetNumberOfCells()}
gmsh.finalize()
out["vtk_log"] = open(log).read() if os.path.exists(log) else ""
print(json.dumps(out))
"#;

/// One run of the stage a check makes: a label for the messages, the
/// input, the scratch directory name and extra command-line arguments.
struct QuadsRun {
    label: String,
    input: PathBuf,
    name: String,
    extra: Vec<String>,
}

/// Runs every file of `plan` and asserts the report's counts and Gmsh's
/// rating ([`check_runs`]).
fn check_inputs(suite: &str, keep: impl Fn(&Plan) -> bool) {
    let runs = INPUTS
        .iter()
        .filter(|x| keep(&x.2))
        .map(|&(folder, name, plan)| QuadsRun {
            label: format!("{name} ({plan:?})"),
            input: input_path(folder, name),
            name: name.to_string(),
            extra: Vec::new(),
        })
        .collect();
    check_runs(suite, runs);
}

/// Runs each of `runs` and asserts its report's counts (quads, no
/// triangle, no inverted quad, no subdivision on [`NEVER_SUBDIVIDED`], its
/// scope within [`SUBDIVISION_SCOPE_AT_MOST`]) and
/// the readers' view of its artifacts ([`READERS`]: Gmsh rates every quad
/// of `quads.msh` with min SICN > 0; meshio finds every quad in
/// `quads.msh` and `quads.vtu`, VTK in `quads.vtu` without an error); all
/// failures are collected, then reported together.
fn check_runs(suite: &str, runs: Vec<QuadsRun>) {
    let mut failures = Vec::new();
    let mut rated = Vec::new();
    for run in &runs {
        let out = scratch(suite, &run.name);
        let extra: Vec<&str> = run.extra.iter().map(String::as_str).collect();
        match run_quads_with(&run.input, &out, 2, &extra) {
            Err(e) => failures.push(format!("{}: the stage failed: {}", run.label, e.trim())),
            Ok(report) => {
                let q = &report["stages"]["quads"];
                let n_quads = q["n_quads"].as_u64().unwrap_or(0);
                if n_quads == 0 || q["n_triangles"] != 0 || q["n_inverted"] != 0 {
                    failures.push(format!(
                        "{}: {} quads, {} triangles, {} inverted",
                        run.label, q["n_quads"], q["n_triangles"], q["n_inverted"]
                    ));
                }
                let subdivided = &q["recombination"]["n_subdivided_faces"];
                if NEVER_SUBDIVIDED.contains(&run.name.as_str()) && *subdivided != 0 {
                    failures.push(format!("{}: {subdivided} model faces midpoint-subdivided", run.label));
                }
                let scope = q["recombination"]["subdivision_scope"].as_str().unwrap_or("missing");
                let rank = |s: &str| SCOPES.iter().position(|&t| t == s).unwrap_or(SCOPES.len());
                let widest = SUBDIVISION_SCOPE_AT_MOST.iter().find(|(n, _)| *n == run.name).map(|&(_, w)| w);
                if let Some(widest) = widest
                    && rank(scope) > rank(widest)
                {
                    failures.push(format!("{}: subdivision scope {scope}, wider than {widest}", run.label));
                }
                rated.push((&run.label, out, n_quads));
            }
        }
    }
    if !rated.is_empty() {
        let log = scratch(suite, "vtk_log").join("vtk.log");
        let mut args = vec![path_str(&log)];
        args.extend(rated.iter().map(|(_, dir, _)| path_str(dir)));
        let r = python(READERS, &args);
        for (label, dir, n_quads) in &rated {
            let g = &r[path_str(dir)];
            let min = g["min_sicn"].as_f64();
            if g["n_rated"].as_u64() != Some(*n_quads) || !min.is_some_and(|m| m > 0.0) {
                failures.push(format!("{label}: Gmsh rated {} of {n_quads} quads, min SICN {:?}", g["n_rated"], min));
            }
            for key in ["meshio_msh_quads", "meshio_vtu_quads", "vtk_cells"] {
                if g[key].as_u64() != Some(*n_quads) {
                    failures.push(format!("{label}: {key} {} of {n_quads}", g[key]));
                }
            }
            if g["vtk_error"] != 0 {
                failures.push(format!("{label}: VTK error code {}", g["vtk_error"]));
            }
        }
        if r["vtk_log"] != "" {
            failures.push(format!("VTK logged: {}", r["vtk_log"]));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_input_file_is_listed() {
    for folder in ["corpus", "gmsh"] {
        let dir = shared_data().join(folder);
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
            .filter(|n| n.rsplit_once('.').is_some_and(|(_, ext)| INPUT_EXTENSIONS.contains(&ext)))
            .collect();
        names.sort();
        for n in &names {
            assert!(INPUTS.iter().any(|(f, name, _)| *f == folder && name == n), "{folder}/{n} is not in INPUTS");
        }
        for (f, name, _) in INPUTS.iter().filter(|(f, _, _)| *f == folder) {
            assert!(names.iter().any(|n| n == name), "{f}/{name} is in INPUTS but not in the folder");
        }
    }
}

#[test]
fn the_quads_stage_passes_its_checks_and_gmsh_on_the_corpus() {
    check_inputs("quads_corpus", |p| *p == Plan::Run);
}

#[test]
fn the_quads_stage_passes_its_checks_and_gmsh_on_the_long_inputs() {
    check_inputs("quads_corpus_long", |p| matches!(p, Plan::Long(_)));
}

/// adis16480 (a CAD part with chamfers 0.2 mm wide along its edges, cut by
/// the atlas into strips one triangle wide, and pins of radius 0.2 mm)
/// passed only at its default size: at 0.6 and 0.7 times it, folded strip
/// triangles at a chamfer's reflex corner needed more rings of
/// re-triangulation than the sliver step grew (28 and 57 inverted quads);
/// at 1.2 and 2 times it, the pins got under 6 edges per turn (17 and 85
/// inverted quads). Every size must pass the stage's checks and Gmsh's
/// rating.
#[test]
fn adis16480_passes_from_0_6_to_2_times_its_default_size() {
    let suite = "quads_corpus_sizes";
    let default_size = 0.003_245_278_572_259_251_6;
    let runs = [0.6, 0.7, 1.2, 2.0]
        .into_iter()
        .map(|factor| {
            let params = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("{suite}.adis16480.{factor}.json"));
            std::fs::write(&params, format!(r#"{{"quads":{{"size":{}}}}}"#, factor * default_size)).unwrap();
            QuadsRun {
                label: format!("adis16480 at {factor}× its default size"),
                input: input_path("corpus", "adis16480.stl"),
                name: format!("adis16480.{factor}"),
                extra: vec!["--params".to_string(), path_str(&params).to_string()],
            }
        })
        .collect();
    check_runs(suite, runs);
}

#[test]
fn quads_artifacts_do_not_depend_on_the_thread_count() {
    // A closed surface with feature curves and several patches, and one
    // with singularities and no feature.
    for (folder, name) in [("corpus", "gmsh_object.stl"), ("gmsh", "sphere_3k.stl")] {
        let input = input_path(folder, name);
        let dirs: Vec<PathBuf> = [1, 2]
            .into_iter()
            .map(|threads| {
                let out = scratch("quads_corpus_threads", &format!("{name}.{threads}"));
                run_quads(&input, &out, threads).unwrap_or_else(|e| panic!("{name}, {threads} threads: {e}"));
                out
            })
            .collect();
        for artifact in ["quads.msh", "quads.vtu"] {
            let bytes: Vec<Vec<u8>> = dirs.iter().map(|d| std::fs::read(d.join(artifact)).unwrap()).collect();
            assert!(!bytes[0].is_empty(), "{name}: empty {artifact}");
            assert!(bytes[0] == bytes[1], "{name}: {artifact} differs between 1 and 2 threads");
        }
    }
}
