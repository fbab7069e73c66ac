//! `surface.glb` of a pipeline run opens in a glTF reader (the `gltf`
//! crate) with the atlas patches as vertex colours and the crossfield
//! singularities as a point primitive, and passes the Khronos glTF
//! validator (npm `gltf-validator`, through `tests/browser/validate_gltf.js`;
//! required with `CI` set, skipped with a reason otherwise).

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use meshatlas::io::stl_write::write_stl_binary;
use meshatlas::mesh::fixtures;
use meshatlas::pipeline::{parse_params, run_pipeline};
use meshatlas::progress::Progress;

/// Runs the pipeline with `stages` on `mesh` (as STL) and returns the output directory.
fn run(mesh: &meshatlas::mesh::TriMesh, stages: &str, dir: &Path) -> meshatlas::pipeline::PipelineReport {
    let input = dir.join("in.stl");
    let mut bytes = Vec::new();
    write_stl_binary(&mut bytes, mesh).unwrap();
    std::fs::write(&input, bytes).unwrap();
    let params = parse_params(format!(r#"{{"stages": {stages}}}"#).as_bytes()).unwrap();
    run_pipeline(&input, None, &params, &dir.join("out"), &Progress::none()).expect("pipeline")
}

/// The Khronos validator's verdict on `glb`, or `None` when node or the
/// validator is not installed (outside CI).
fn khronos_validator(glb: &Path) -> Option<serde_json::Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser/validate_gltf.js");
    let modules = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser/node_modules/gltf-validator");
    let ci = std::env::var_os("CI").is_some();
    if !modules.is_dir() {
        assert!(!ci, "CI: {} is missing (npm ci in tests/browser)", modules.display());
        eprintln!("skipped the Khronos validator: {} is missing", modules.display());
        return None;
    }
    let out = match Command::new("node").arg(&script).arg(glb).output() {
        Ok(out) => out,
        Err(e) => {
            assert!(!ci, "CI: cannot run node: {e}");
            eprintln!("skipped the Khronos validator: cannot run node: {e}");
            return None;
        }
    };
    assert!(out.status.code().is_some_and(|c| c <= 1), "validator: {}", String::from_utf8_lossy(&out.stderr));
    Some(serde_json::from_slice(&out.stdout).expect("validator JSON report"))
}

#[test]
fn the_cube_glb_has_six_patch_colours_eight_singular_points_and_validates() {
    let dir = tempfile::tempdir().unwrap();
    let report = run(&fixtures::cube(6), r#"["atlas", "crossfield"]"#, dir.path());
    let n_singular = report.stages.crossfield.as_ref().unwrap().n_singularities;
    assert_eq!(n_singular, 8, "a cube's crossfield has one +1/4 singularity per corner");
    let glb = dir.path().join("out/surface.glb");
    assert!(report.artifacts.iter().any(|a| a.name == "surface.glb" && a.media_type == "model/gltf-binary"));

    let bytes = std::fs::read(&glb).unwrap();
    let gltf = gltf::Gltf::from_slice(&bytes).expect("the gltf crate reads surface.glb");
    let blob = gltf.blob.clone().expect("binary chunk");
    let mesh = gltf.meshes().next().expect("one mesh");
    let prims: Vec<_> = mesh.primitives().collect();
    assert_eq!(prims.len(), 2);
    assert_eq!(prims[0].mode(), gltf::mesh::Mode::Triangles);
    assert_eq!(prims[1].mode(), gltf::mesh::Mode::Points);

    let tri = prims[0].reader(|_| Some(&blob[..]));
    let n_indices = tri.read_indices().unwrap().into_u32().count();
    let n_triangles = report.stages.atlas.as_ref().unwrap().n_triangles;
    assert_eq!(n_indices, 3 * n_triangles, "the atlas triangulation, whole");
    let colours: BTreeSet<[u8; 4]> = tri.read_colors(0).unwrap().into_rgba_u8().collect();
    assert_eq!(colours.len(), 6, "one colour per patch: {colours:?}");
    let positions: Vec<[f32; 3]> = tri.read_positions().unwrap().collect();
    // The node's translation is the box centre: the cube [-1, 1]³ is centred already.
    let node = gltf.nodes().next().unwrap();
    let t = node.transform().decomposed().0;
    assert!(t.iter().all(|x| x.abs() < 1e-9), "{t:?}");
    assert!(positions.iter().all(|p| p.iter().all(|x| x.abs() <= 1.0 + 1e-6)));
    assert!(positions.iter().any(|p| (p[0] - 1.0).abs() < 1e-6 && (p[1] - 1.0).abs() < 1e-6));

    let pts = prims[1].reader(|_| Some(&blob[..]));
    let corners: Vec<[f32; 3]> = pts.read_positions().unwrap().collect();
    assert_eq!(corners.len(), 8);
    for p in &corners {
        assert!(p.iter().all(|x| (x.abs() - 1.0).abs() < 1e-3), "a singularity at a cube corner: {p:?}");
    }

    if let Some(verdict) = khronos_validator(&glb) {
        let issues = &verdict["issues"];
        assert_eq!(issues["numErrors"], 0, "{verdict:#}");
        assert_eq!(issues["numWarnings"], 0, "{verdict:#}");
        assert_eq!(verdict["info"]["totalTriangleCount"], n_triangles);
    }
}

#[test]
fn without_the_atlas_the_glb_is_the_repaired_surface_in_one_colour() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = fixtures::icosphere(2);
    let report = run(&sphere, "[]", dir.path());
    let bytes = std::fs::read(dir.path().join("out/surface.glb")).unwrap();
    let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = gltf.blob.clone().unwrap();
    let prims: Vec<_> = gltf.meshes().next().unwrap().primitives().collect();
    assert_eq!(prims.len(), 1, "no singularities, no point primitive");
    let r = prims[0].reader(|_| Some(&blob[..]));
    assert_eq!(r.read_indices().unwrap().into_u32().count(), 3 * report.input.n_triangles);
    assert_eq!(r.read_positions().unwrap().count(), report.input.n_vertices);
    if let Some(verdict) = khronos_validator(&dir.path().join("out/surface.glb")) {
        assert_eq!(verdict["issues"]["numErrors"], 0, "{verdict:#}");
    }
}

#[test]
fn previews_off_writes_no_png_and_no_glb() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.stl");
    let mut bytes = Vec::new();
    write_stl_binary(&mut bytes, &fixtures::cube(2)).unwrap();
    std::fs::write(&input, bytes).unwrap();
    let params = parse_params(br#"{"stages": ["atlas"], "output": {"previews": false}}"#).unwrap();
    let report = run_pipeline(&input, None, &params, &dir.path().join("out"), &Progress::none()).unwrap();
    assert!(report.previews.is_empty());
    assert!(report.artifacts.iter().all(|a| !a.name.ends_with(".png") && !a.name.ends_with(".glb")));
    let sized = parse_params(br#"{"output": {"preview_size": [640, 480]}}"#).unwrap();
    assert_eq!((sized.output.preview_size.width, sized.output.preview_size.height), (640, 480));
    let err = parse_params(br#"{"output": {"preview_size": [10, 480]}}"#).unwrap_err();
    assert!(err.to_string().contains("preview_size"), "{err}");
}
