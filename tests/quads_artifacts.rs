//! `quads.msh` and `quads.vtu` read by independent tools, on quad meshes
//! built in code (the cells of fixture surfaces merged into quads,
//! [`meshatlas::quads::fixtures`]): Gmsh opens `quads.msh` (every MSH
//! variant), finds the model's corners, curves and faces, its quadrangles on
//! the faces and lines on the curves, and a positive `minSICN` on every
//! quad; meshio reads both files; VTK reads `quads.vtu` without complaint
//! and finds VTK_QUAD (9) or VTK_BIQUADRATIC_QUAD (28) cells with the
//! quality arrays. The known answers are the fixtures' own counts.

mod common;

use common::{path_str, python, scratch};
use meshatlas::atlas::features::detect_features;
use meshatlas::io::msh_output::{MshVersion, OutputOptions};
use meshatlas::mesh::{Topology, TriMesh, fixtures};
use meshatlas::quads::fixtures::{add_midpoint_nodes, quads_from_triangle_pairs};
use meshatlas::quads::quality::quad_quality;
use meshatlas::quads::{QuadMesh, QuadModel, quad_model, write_quads_msh, write_quads_vtu};
use serde_json::json;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

const GMSH: &str = r#"
gmsh.initialize(["-nt", "1"])
gmsh.option.setNumber("General.Terminal", 0)
gmsh.open(sys.argv[1])
ent = [len(gmsh.model.getEntities(d)) for d in range(3)]
elements = {}
sicn = []
for d in range(3):
    for (_, t) in gmsh.model.getEntities(d):
        types, etags, _ = gmsh.model.mesh.getElements(d, t)
        for ty, tags in zip(types, etags):
            key = f"{d}:{ty}"
            elements[key] = elements.get(key, 0) + len(tags)
            if d == 2:
                sicn.extend(gmsh.model.mesh.getElementQualities(list(tags), "minSICN"))
bounds = [len(gmsh.model.getBoundary([(2, t)], combined=False, oriented=False)) for (_, t) in gmsh.model.getEntities(2)]
curve_bounds = [len(gmsh.model.getBoundary([(1, t)], combined=False, oriented=False)) for (_, t) in gmsh.model.getEntities(1)]
nodes, _, _ = gmsh.model.mesh.getNodes()
print(json.dumps({"entities": ent, "elements": elements, "min_sicn": min(sicn), "n_quads_rated": len(sicn),
                  "surface_bounds": bounds, "curve_bounds": curve_bounds, "n_nodes": len(nodes)}))
gmsh.finalize()
"#;

const MESHIO: &str = r#"
out = {}
for p in sys.argv[1:]:
    m = meshio.read(p)
    cells = {}
    for c in m.cells:
        cells[c.type] = cells.get(c.type, 0) + len(c.data)
    out[p] = {"points": len(m.points), "cells": cells,
              "cell_data": sorted(m.cell_data.keys()), "point_data": sorted(m.point_data.keys())}
print(json.dumps(out))
"#;

const VTK: &str = r#"
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
from vtkmodules.vtkCommonCore import vtkFileOutputWindow, vtkOutputWindow
from vtkmodules.util.numpy_support import vtk_to_numpy
import os
log = sys.argv[2]
w = vtkFileOutputWindow(); w.SetFileName(log); vtkOutputWindow.SetInstance(w)
r = vtkXMLUnstructuredGridReader(); r.SetFileName(sys.argv[1]); r.Update()
g = r.GetOutput()
def arrays(d):
    return {d.GetArrayName(i): vtk_to_numpy(d.GetArray(i)).ravel().astype(float).tolist() for i in range(d.GetNumberOfArrays())}
print(json.dumps({"error": r.GetErrorCode(), "log": open(log).read() if os.path.exists(log) else "",
   "n_points": g.GetNumberOfPoints(), "types": sorted(set(g.GetCellType(i) for i in range(g.GetNumberOfCells()))),
   "n_cells": g.GetNumberOfCells(), "point_data": arrays(g.GetPointData()), "cell_data": arrays(g.GetCellData())}))
"#;

/// The quad mesh of a fixture's cells and its feature model.
fn quads_of(surface: &TriMesh) -> (QuadMesh, QuadModel) {
    let topo = Topology::new(surface);
    let model = quad_model(surface, &topo, &detect_features(surface, &topo, 30.0));
    (quads_from_triangle_pairs(surface, &topo, &model), model)
}

/// Writes `quads.msh` (with `opts`) and `quads.vtu` into `dir`.
fn write(
    dir: &Path,
    mesh: &QuadMesh,
    model: &QuadModel,
    surface: &TriMesh,
    opts: &OutputOptions,
) -> (PathBuf, PathBuf) {
    let (msh, vtu) = (dir.join("quads.msh"), dir.join("quads.vtu"));
    write_quads_msh(mesh, model, BufWriter::new(File::create(&msh).unwrap()), opts).unwrap();
    write_quads_vtu(mesh, &quad_quality(mesh, surface), BufWriter::new(File::create(&vtu).unwrap())).unwrap();
    (msh, vtu)
}

#[test]
fn gmsh_opens_the_cube_in_every_msh_variant_with_its_model_and_no_inverted_quad() {
    let surface = fixtures::cube(3);
    let (mesh, model) = quads_of(&surface);
    for (name, opts) in [
        ("ascii", OutputOptions { msh_binary: Some(false), ..Default::default() }),
        ("binary", OutputOptions { msh_binary: Some(true), ..Default::default() }),
        ("msh22", OutputOptions { msh_version: MshVersion::V22, msh_binary: None, ..Default::default() }),
    ] {
        let dir = scratch("quads_artifacts", &format!("cube_{name}"));
        let (msh, _) = write(&dir, &mesh, &model, &surface, &opts);
        let r = python(GMSH, &[path_str(&msh)]);
        assert_eq!(r["n_quads_rated"], json!(54), "{name}: {r}");
        assert!(r["min_sicn"].as_f64().unwrap() > 0.99, "{name}: a square grid has SICN 1: {r}");
        assert_eq!(r["n_nodes"], json!(56), "{name}: 6·3² + 2 vertices: {r}");
        assert_eq!(r["elements"]["2:3"], json!(54), "{name}: {r}");
        assert_eq!(r["elements"]["1:1"], json!(36), "{name}: 12 curves of 3 edges: {r}");
        if opts.msh_version == MshVersion::V41 {
            // $Entities: 8 corners, 12 curves, 6 faces; each face bounded by 4 curves, each curve by 2 corners.
            assert_eq!(r["entities"], json!([8, 12, 6]), "{name}: {r}");
            assert_eq!(r["surface_bounds"], json!(vec![4; 6]), "{name}: {r}");
            assert_eq!(r["curve_bounds"], json!(vec![2; 12]), "{name}: {r}");
            assert_eq!(r["elements"]["0:15"], json!(8), "{name}: {r}");
        }
    }
}

#[test]
fn gmsh_rates_every_quad_of_a_cylinder_and_an_order_2_square_positive() {
    let cylinder = fixtures::cylinder(1.0, 2.0, 16, 4);
    let (mesh, model) = quads_of(&cylinder);
    let dir = scratch("quads_artifacts", "cylinder");
    let (msh, _) = write(&dir, &mesh, &model, &cylinder, &OutputOptions::default());
    let r = python(GMSH, &[path_str(&msh)]);
    assert_eq!(r["elements"]["2:3"], json!(64), "{r}");
    // Two boundary circles (closed curves through one corner each) of 16 lines.
    assert_eq!(r["elements"]["1:1"], json!(32), "{r}");
    assert_eq!(r["entities"], json!([2, 2, 1]), "{r}");
    assert!(r["min_sicn"].as_f64().unwrap() > 0.9, "{r}");

    let square = fixtures::square_structured(3);
    let (mut mesh, model) = quads_of(&square);
    add_midpoint_nodes(&mut mesh);
    let dir = scratch("quads_artifacts", "square_order2");
    let (msh, _) = write(&dir, &mesh, &model, &square, &OutputOptions::default());
    let r = python(GMSH, &[path_str(&msh)]);
    assert_eq!(r["elements"]["2:10"], json!(9), "9-node quadrangles: {r}");
    assert_eq!(r["elements"]["1:8"], json!(12), "3-node lines: {r}");
    assert_eq!(r["n_nodes"], json!(49), "a 7 × 7 lattice of nodes: {r}");
    assert!(r["min_sicn"].as_f64().unwrap() > 0.99, "{r}");
}

#[test]
fn meshio_reads_both_files_and_vtk_finds_quads_with_their_arrays() {
    let surface = fixtures::cube(2);
    let (mesh, model) = quads_of(&surface);
    let dir = scratch("quads_artifacts", "meshio_vtk");
    let (msh, vtu) = write(&dir, &mesh, &model, &surface, &OutputOptions::default());
    let r = python(MESHIO, &[path_str(&msh), path_str(&vtu)]);
    let m = &r[path_str(&msh)];
    assert_eq!(m["points"], json!(26), "{r}");
    assert_eq!(m["cells"]["quad"], json!(24), "{r}");
    assert_eq!(m["cells"]["line"], json!(24), "{r}");
    let v = &r[path_str(&vtu)];
    assert_eq!(v["cells"], json!({"quad": 24}), "{r}");
    assert_eq!(v["cell_data"], json!(["max_angle_deviation", "model_face", "scaled_jacobian"]), "{r}");
    assert_eq!(v["point_data"], json!(["irregular", "valence"]), "{r}");

    let log = dir.join("vtk.log");
    let r = python(VTK, &[path_str(&vtu), path_str(&log)]);
    assert_eq!((&r["error"], &r["log"]), (&json!(0), &json!("")), "{r}");
    assert_eq!((&r["n_points"], &r["n_cells"], &r["types"]), (&json!(26), &json!(24), &json!([9])), "{r}");
    let valence = r["point_data"]["valence"].as_array().unwrap();
    // A cube's 8 corners have 3 edges, its other 18 vertices 4.
    assert_eq!(valence.iter().filter(|v| v.as_f64() == Some(3.0)).count(), 8, "{r}");
    assert_eq!(valence.iter().filter(|v| v.as_f64() == Some(4.0)).count(), 18, "{r}");
    let irregular: f64 = r["point_data"]["irregular"].as_array().unwrap().iter().filter_map(|v| v.as_f64()).sum();
    assert_eq!(irregular, 8.0, "{r}");
    assert!(
        r["cell_data"]["scaled_jacobian"].as_array().unwrap().iter().all(|j| (j.as_f64().unwrap() - 1.0).abs() < 1e-12)
    );
    let faces: Vec<f64> = r["cell_data"]["model_face"].as_array().unwrap().iter().filter_map(|v| v.as_f64()).collect();
    for f in 0..6 {
        assert_eq!(faces.iter().filter(|&&g| g == f as f64).count(), 4, "face {f}: {r}");
    }

    // Order 2: VTK_BIQUADRATIC_QUAD, read by both tools.
    let square = fixtures::square_structured(2);
    let (mut mesh, model) = quads_of(&square);
    add_midpoint_nodes(&mut mesh);
    let (msh, vtu) = write(&dir, &mesh, &model, &square, &OutputOptions::default());
    let r = python(VTK, &[path_str(&vtu), path_str(&log)]);
    assert_eq!((&r["error"], &r["n_points"], &r["types"]), (&json!(0), &json!(25), &json!([28])), "{r}");
    let r = python(MESHIO, &[path_str(&msh), path_str(&vtu)]);
    assert_eq!(r[path_str(&msh)]["cells"]["quad9"], json!(4), "{r}");
    assert_eq!(r[path_str(&vtu)]["cells"], json!({"quad9": 4}), "{r}");
}
