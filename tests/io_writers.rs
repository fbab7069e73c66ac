//! Cross-reading of every writer by independent implementations: meshio
//! (all formats), Gmsh 4.15 (MSH 4.1 and 2.2, including remeshing discrete
//! atlases from their `$Parametrizations` in a fresh process) and VTK's own
//! XML reader (VTU).
//!
//! The tests run `python3` as a subprocess and fail, never skip, when it or a
//! module is missing: `.ci/run` installs gmsh, meshio and vtk.

use meshatlas::geom::{Vec2, Vec3};
use meshatlas::io::msh22::write::write_msh22;
use meshatlas::io::msh41::discrete::{DiscreteModelBuilder, PatchUv};
use meshatlas::io::msh41::model::{DataView, MshModel, PhysicalName};
use meshatlas::io::msh41::write::{Msh41Options, write_msh41};
use meshatlas::io::stl_write::write_stl_binary;
use meshatlas::io::vtu::{
    CellBlock, DataArray, DataValues, VtuCompression, VtuEncoding, VtuHeaderType, VtuMesh, VtuOptions, write_vtu,
};
use meshatlas::mesh::{FaceId, TetMesh, TriMesh, VertexId, fixtures};
mod common;

use common::{path_str, python};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------
// Running Python

/// A fresh directory for one test's files.
fn scratch(name: &str) -> PathBuf {
    common::scratch("io_writers", name)
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().expect("array").iter().map(|x| x.as_f64().expect("number")).collect()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "lengths differ");
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn flat(points: &[Vec3]) -> Vec<f64> {
    points.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

// ---------------------------------------------------------------------------
// Python readers

/// meshio: points, cells per block, point/cell data flattened.
const MESHIO_READ: &str = r#"
m = meshio.read(sys.argv[1])
out = {"points": m.points.ravel().tolist(),
       "cells": [[c.type, np.asarray(c.data).ravel().tolist()] for c in m.cells],
       "point_data": {k: np.asarray(v).ravel().tolist() for k, v in m.point_data.items()},
       "cell_data": {k: [np.asarray(b).ravel().tolist() for b in v] for k, v in m.cell_data.items()}}
print(json.dumps(out))
"#;

/// Gmsh: entities, nodes, elements per dimension, views with their data.
const GMSH_READ: &str = r#"
gmsh.initialize(["-noenv"]); gmsh.option.setNumber("General.Terminal", 0)
gmsh.logger.start()
gmsh.open(sys.argv[1])
tags, coords, _ = gmsh.model.mesh.getNodes()
order = np.argsort(tags)
els = {}
for d in range(4):
    types, etags, enodes = gmsh.model.mesh.getElements(d)
    els[d] = [[int(t), np.asarray(e).tolist(), np.asarray(n).tolist()] for t, e, n in zip(types, etags, enodes)]
views = []
for v in gmsh.view.getTags():
    steps = int(gmsh.option.getNumber(f"View[{gmsh.view.getIndex(v)}].NbTimeStep"))
    for step in range(steps):
        kind, vtags, data, time, nc = gmsh.view.getModelData(v, step)
        if len(vtags): break
    name = gmsh.option.getString(f"View[{gmsh.view.getIndex(v)}].Name")
    views.append({"name": name, "kind": kind, "tags": np.asarray(vtags).tolist(),
                  "data": np.concatenate([np.ravel(d) for d in data]).tolist(), "time": time, "nc": nc})
errors = [l for l in gmsh.logger.get() if l.startswith("Error")]
print(json.dumps({"entities": gmsh.model.getEntities(), "node_tags": np.asarray(tags)[order].tolist(),
                  "coords": np.asarray(coords).reshape(-1, 3)[order].ravel().tolist(),
                  "elements": els, "views": views, "errors": errors,
                  "physical_groups": gmsh.model.getPhysicalGroups()}))
gmsh.finalize()
"#;

/// Check what meshio read against what was written (values to 1e-12).
fn check_meshio(
    file: &Path,
    points: &[Vec3],
    cells: &[(&str, Vec<u64>)],
    point_data: &[(&str, Vec<f64>)],
    cell_data: &[(&str, Vec<f64>)],
) {
    let r = python(MESHIO_READ, &[path_str(file)]);
    let what = file.display();
    assert!(max_abs_diff(&floats(&r["points"]), &flat(points)) < 1e-12, "{what}: points differ");
    let got = r["cells"].as_array().unwrap();
    assert_eq!(got.len(), cells.len(), "{what}: cell blocks {got:?}");
    for ((ty, ids), g) in cells.iter().zip(got) {
        assert_eq!(g[0].as_str(), Some(*ty), "{what}: cell type");
        let g_ids: Vec<u64> = g[1].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect();
        assert_eq!(&g_ids, ids, "{what}: {ty} connectivity");
    }
    for (name, values) in point_data {
        let g = floats(&r["point_data"][*name]);
        assert!(max_abs_diff(&g, values) < 1e-12, "{what}: point data {name}");
    }
    for (name, values) in cell_data {
        let g: Vec<f64> = r["cell_data"][*name]
            .as_array()
            .unwrap_or_else(|| panic!("{what}: no cell data {name}"))
            .iter()
            .flat_map(floats)
            .collect();
        assert!(max_abs_diff(&g, values) < 1e-12, "{what}: cell data {name}");
    }
}

// ---------------------------------------------------------------------------
// Fixtures

/// `[0, n]³` cubes split into 6 positive tetrahedra each (Kuhn subdivision).
fn tet_block(n: usize) -> TetMesh {
    let id = |i: usize, j: usize, k: usize| VertexId::new((k * (n + 1) + j) * (n + 1) + i);
    let mut positions = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                positions.push(Vec3::new(i as f64, j as f64, k as f64) / n as f64);
            }
        }
    }
    let mut tets = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for perm in [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
                    let mut c = [i, j, k];
                    let mut tet = [id(i, j, k); 4];
                    for (s, &axis) in perm.iter().enumerate() {
                        c[axis] += 1;
                        tet[s + 1] = id(c[0], c[1], c[2]);
                    }
                    tets.push(tet);
                }
            }
        }
    }
    let mut m = TetMesh { positions, tets };
    m.orient_positive();
    m.validate().expect("valid tet block");
    m
}

fn node_tags_1based(n: usize) -> Vec<f64> {
    (1..=n).map(|t| t as f64).collect()
}

// ---------------------------------------------------------------------------
// MSH 4.1 and 2.2 plain meshes

fn surface_model_with_views(mesh: &TriMesh) -> MshModel {
    let mut m = MshModel::from_surface(mesh);
    m.surfaces[0].physical_tags = vec![5];
    m.physical_names.push(PhysicalName { dim: 2, tag: 5, name: "skin".into() });
    m.node_data.push(DataView::contiguous("normal", 3, flat(&mesh.positions), 1));
    m.node_data.push(DataView {
        time: 1.5,
        step: 1,
        ..DataView::contiguous("tensor", 9, (0..9 * mesh.n_vertices()).map(|i| i as f64 * 0.25 - 3.0).collect(), 1)
    });
    m.element_data.push(DataView::contiguous(
        "area",
        1,
        (0..mesh.n_faces()).map(|f| mesh.face_area(FaceId::new(f))).collect(),
        1,
    ));
    m
}

fn check_gmsh_plain(file: &Path, model: &MshModel, dim: u8) {
    let r = python(GMSH_READ, &[path_str(file)]);
    let what = file.display();
    assert_eq!(r["errors"], json!([]), "{what}: gmsh errors");
    assert_eq!(r["entities"], json!([[dim, 1]]), "{what}");
    let positions: Vec<Vec3> = model.node_blocks[0].positions.clone();
    assert!(max_abs_diff(&floats(&r["coords"]), &flat(&positions)) < 1e-12, "{what}: coordinates");
    assert_eq!(floats(&r["node_tags"]), node_tags_1based(positions.len()));
    let els = r["elements"][dim.to_string()].as_array().unwrap();
    assert_eq!(els.len(), 1);
    let code = model.element_blocks[0].element_type.gmsh_code();
    assert_eq!(els[0][0], json!(code));
    let nodes: Vec<u64> = els[0][2].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect();
    assert_eq!(nodes, model.element_blocks[0].nodes, "{what}: connectivity");
    let views = r["views"].as_array().unwrap();
    let written: Vec<&DataView> = model.node_data.iter().chain(&model.element_data).collect();
    assert_eq!(views.len(), written.len(), "{what}: views");
    for (v, w) in views.iter().zip(written) {
        assert_eq!(v["name"], json!(w.name));
        assert_eq!(v["nc"], json!(w.n_components));
        assert_eq!(v["time"].as_f64(), Some(w.time));
        assert_eq!(floats(&v["tags"]), w.tags.iter().map(|&t| t as f64).collect::<Vec<_>>());
        assert!(max_abs_diff(&floats(&v["data"]), &w.values) < 1e-12, "{what}: view {} values", w.name);
    }
}

#[test]
fn msh41_surface_ascii_and_binary_read_by_meshio_and_gmsh() {
    let dir = scratch("msh41_surface");
    let mesh = fixtures::icosphere(2);
    let model = surface_model_with_views(&mesh);
    for binary in [false, true] {
        let file = dir.join(if binary { "surface_bin.msh" } else { "surface.msh" });
        write_msh41(std::fs::File::create(&file).unwrap(), &model, &Msh41Options { binary }).unwrap();
        let tris: Vec<u64> = mesh.triangles.iter().flatten().map(|v| u64::from(v.0)).collect();
        check_meshio(
            &file,
            &mesh.positions,
            &[("triangle", tris)],
            &[("normal", model.node_data[0].values.clone()), ("tensor", model.node_data[1].values.clone())],
            &[("area", model.element_data[0].values.clone())],
        );
        check_gmsh_plain(&file, &model, 2);
        let r = python(GMSH_READ, &[path_str(&file)]);
        assert_eq!(r["physical_groups"], json!([[2, 5]]));
    }
}

#[test]
fn default_msh_is_ascii_below_the_threshold_and_binary_from_it_on_and_both_are_read() {
    use meshatlas::io::msh_output::{AUTO_BINARY_MIN_ELEMENTS, OutputOptions, write_msh};
    let dir = scratch("msh41_threshold");
    // cube(n) has 12 n² triangles: 99372 and 101568 lie on either side.
    for (n, binary) in [(91, false), (92, true)] {
        let mesh = fixtures::cube(n);
        assert_eq!(mesh.n_faces() >= AUTO_BINARY_MIN_ELEMENTS, binary);
        let mut model = MshModel::from_surface(&mesh);
        model.element_data.push(DataView::contiguous(
            "area",
            1,
            (0..mesh.n_faces()).map(|f| mesh.face_area(FaceId::new(f))).collect(),
            1,
        ));
        let file = dir.join(format!("cube_{n}.msh"));
        write_msh(std::fs::File::create(&file).unwrap(), &model, &OutputOptions::default()).unwrap();
        let head = std::fs::read(&file).unwrap()[..20].to_vec();
        let expected: &[u8] = if binary { b"$MeshFormat\n4.1 1 8\n" } else { b"$MeshFormat\n4.1 0 8\n" };
        assert!(head.starts_with(expected), "cube({n}): {:?}", String::from_utf8_lossy(&head));
        let tris: Vec<u64> = mesh.triangles.iter().flatten().map(|v| u64::from(v.0)).collect();
        check_meshio(
            &file,
            &mesh.positions,
            &[("triangle", tris)],
            &[],
            &[("area", model.element_data[0].values.clone())],
        );
        check_gmsh_plain(&file, &model, 2);
    }
}

#[test]
fn msh41_volume_read_by_meshio_and_gmsh() {
    let dir = scratch("msh41_volume");
    let mesh = tet_block(3);
    let mut model = MshModel::from_volume(&mesh);
    model.element_data.push(DataView::contiguous(
        "q",
        3,
        (0..3 * mesh.n_tets()).map(|i| (i as f64).sqrt()).collect(),
        1,
    ));
    let file = dir.join("volume.msh");
    write_msh41(std::fs::File::create(&file).unwrap(), &model, &Msh41Options::default()).unwrap();
    let tets: Vec<u64> = mesh.tets.iter().flatten().map(|v| u64::from(v.0)).collect();
    check_meshio(&file, &mesh.positions, &[("tetra", tets)], &[], &[("q", model.element_data[0].values.clone())]);
    check_gmsh_plain(&file, &model, 3);
}

#[test]
fn msh22_surface_and_volume_read_by_meshio_and_gmsh() {
    let dir = scratch("msh22");
    let mesh = fixtures::torus(1.0, 0.3, 16, 8);
    let model = surface_model_with_views(&mesh);
    let file = dir.join("surface22.msh");
    write_msh22(std::fs::File::create(&file).unwrap(), &model).unwrap();
    let tris: Vec<u64> = mesh.triangles.iter().flatten().map(|v| u64::from(v.0)).collect();
    check_meshio(
        &file,
        &mesh.positions,
        &[("triangle", tris)],
        &[("normal", model.node_data[0].values.clone())],
        &[
            ("area", model.element_data[0].values.clone()),
            ("gmsh:physical", vec![5.0; mesh.n_faces()]),
            ("gmsh:geometrical", vec![1.0; mesh.n_faces()]),
        ],
    );
    check_gmsh_plain(&file, &model, 2);

    let vol = tet_block(2);
    let mut vmodel = MshModel::from_volume(&vol);
    vmodel.volumes[0].physical_tags = vec![3];
    vmodel.node_data.push(DataView::contiguous("u", 1, (0..vol.n_vertices()).map(|i| i as f64 / 7.0).collect(), 1));
    let file = dir.join("volume22.msh");
    write_msh22(std::fs::File::create(&file).unwrap(), &vmodel).unwrap();
    let tets: Vec<u64> = vol.tets.iter().flatten().map(|v| u64::from(v.0)).collect();
    check_meshio(
        &file,
        &vol.positions,
        &[("tetra", tets)],
        &[("u", vmodel.node_data[0].values.clone())],
        &[("gmsh:physical", vec![3.0; vol.n_tets()])],
    );
    check_gmsh_plain(&file, &vmodel, 3);
}

// ---------------------------------------------------------------------------
// VTU

/// Points of a tet block with every cell kind and typed data of 1, 3, 4, 9 components.
struct MixedVtu {
    tets: TetMesh,
    vertices: Vec<VertexId>,
    lines: Vec<[VertexId; 2]>,
    triangles: Vec<[VertexId; 3]>,
}

impl MixedVtu {
    fn new() -> Self {
        let tets = tet_block(2);
        let vertices = vec![VertexId(0), VertexId(26)];
        let lines = vec![[VertexId(0), VertexId(1)], [VertexId(1), VertexId(2)]];
        let triangles = vec![[VertexId(0), VertexId(1), VertexId(4)], [VertexId(1), VertexId(5), VertexId(4)]];
        Self { tets, vertices, lines, triangles }
    }

    fn n_cells(&self) -> usize {
        self.vertices.len() + self.lines.len() + self.triangles.len() + self.tets.n_tets()
    }

    fn mesh(&self) -> VtuMesh<'_> {
        let n = self.tets.n_vertices();
        let nc = self.n_cells();
        VtuMesh {
            points: &self.tets.positions,
            cells: vec![
                CellBlock::Vertices(&self.vertices),
                CellBlock::Lines(&self.lines),
                CellBlock::Triangles(&self.triangles),
                CellBlock::Tetrahedra(&self.tets.tets),
            ],
            point_data: vec![
                DataArray::f64("scalar", 1, (0..n).map(|i| (i as f64).sin()).collect::<Vec<_>>()),
                DataArray::vectors("vector", &self.tets.positions),
                DataArray::f64("quaternion", 4, (0..4 * n).map(|i| i as f64 / 3.0).collect::<Vec<_>>()),
                DataArray::f64("tensor", 9, (0..9 * n).map(|i| 1.0 / (i as f64 + 1.0)).collect::<Vec<_>>()),
                DataArray {
                    name: "f32".into(),
                    n_components: 1,
                    values: DataValues::Float32((0..n).map(|i| i as f32 * 0.5).collect::<Vec<_>>().into()),
                },
            ],
            cell_data: vec![
                DataArray::i32("patch", (0..nc as i32).map(|i| i - 5).collect::<Vec<_>>()),
                DataArray::u8("flag", (0..nc).map(|i| (i % 3) as u8).collect::<Vec<_>>()),
                DataArray {
                    name: "big".into(),
                    n_components: 1,
                    values: DataValues::Int64((0..nc as i64).map(|i| i << 40).collect::<Vec<_>>().into()),
                },
            ],
        }
    }

    /// Point data values as f64 (what a reader should return).
    fn point_values(&self) -> Vec<(&'static str, Vec<f64>)> {
        let m = self.mesh();
        ["scalar", "vector", "quaternion", "tensor", "f32"]
            .iter()
            .zip(&m.point_data)
            .map(|(n, a)| (*n, values_f64(&a.values)))
            .collect()
    }

    /// Cell data values as f64, all blocks concatenated.
    fn cell_values(&self) -> Vec<(&'static str, Vec<f64>)> {
        let m = self.mesh();
        ["patch", "flag", "big"].iter().zip(&m.cell_data).map(|(n, a)| (*n, values_f64(&a.values))).collect()
    }
}

fn values_f64(v: &DataValues<'_>) -> Vec<f64> {
    match v {
        DataValues::Float64(x) => x.to_vec(),
        DataValues::Float32(x) => x.iter().map(|&y| f64::from(y)).collect(),
        DataValues::Int32(x) => x.iter().map(|&y| f64::from(y)).collect(),
        DataValues::Int64(x) => x.iter().map(|&y| y as f64).collect(),
        DataValues::UInt8(x) => x.iter().map(|&y| f64::from(y)).collect(),
        DataValues::UInt32(x) => x.iter().map(|&y| f64::from(y)).collect(),
    }
}

fn ids(cells: &[VertexId]) -> Vec<u64> {
    cells.iter().map(|v| u64::from(v.0)).collect()
}

const ENCODINGS: [(VtuEncoding, VtuHeaderType, VtuCompression, &str); 8] = [
    (VtuEncoding::Ascii, VtuHeaderType::UInt64, VtuCompression::None, "ascii"),
    (VtuEncoding::Base64, VtuHeaderType::UInt64, VtuCompression::None, "base64_64"),
    (VtuEncoding::Base64, VtuHeaderType::UInt32, VtuCompression::None, "base64_32"),
    (VtuEncoding::Raw, VtuHeaderType::UInt64, VtuCompression::None, "raw"),
    (VtuEncoding::Raw, VtuHeaderType::UInt32, VtuCompression::None, "raw_32"),
    (VtuEncoding::Raw, VtuHeaderType::UInt64, VtuCompression::Zlib, "raw_zlib"),
    (VtuEncoding::Raw, VtuHeaderType::UInt32, VtuCompression::Zlib, "raw_zlib_32"),
    (VtuEncoding::Base64, VtuHeaderType::UInt64, VtuCompression::Zlib, "base64_zlib"),
];

fn write_mixed(dir: &Path, fixture: &MixedVtu) -> Vec<PathBuf> {
    ENCODINGS
        .iter()
        .map(|&(encoding, header_type, compression, name)| {
            let file = dir.join(format!("mixed_{name}.vtu"));
            let opts = VtuOptions { encoding, header_type, compression };
            write_vtu(std::fs::File::create(&file).unwrap(), &fixture.mesh(), &opts).unwrap();
            file
        })
        .collect()
}

#[test]
fn vtu_every_encoding_read_by_meshio() {
    let dir = scratch("vtu_meshio");
    let fx = MixedVtu::new();
    for file in write_mixed(&dir, &fx) {
        let r = python(MESHIO_READ, &[path_str(&file)]);
        let what = file.display();
        assert!(max_abs_diff(&floats(&r["points"]), &flat(&fx.tets.positions)) < 1e-12, "{what}");
        let blocks: Vec<(String, Vec<u64>)> = r["cells"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| {
                (
                    c[0].as_str().unwrap().to_string(),
                    c[1].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect(),
                )
            })
            .collect();
        let expected = vec![
            ("vertex".to_string(), ids(&fx.vertices)),
            ("line".to_string(), ids(fx.lines.as_flattened())),
            ("triangle".to_string(), ids(fx.triangles.as_flattened())),
            ("tetra".to_string(), ids(fx.tets.tets.as_flattened())),
        ];
        assert_eq!(blocks, expected, "{what}: cells");
        for (name, values) in fx.point_values() {
            assert!(max_abs_diff(&floats(&r["point_data"][name]), &values) < 1e-12, "{what}: point data {name}");
        }
        for (name, values) in fx.cell_values() {
            let got: Vec<f64> = r["cell_data"][name].as_array().unwrap().iter().flat_map(floats).collect();
            assert!(max_abs_diff(&got, &values) < 1e-12, "{what}: cell data {name}");
        }
    }
}

#[test]
fn vtu_every_encoding_read_by_vtk_xml_reader() {
    let dir = scratch("vtu_vtk");
    let fx = MixedVtu::new();
    let script = r#"
try:
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
    from vtkmodules.vtkCommonCore import vtkFileOutputWindow, vtkOutputWindow
    from vtkmodules.util.numpy_support import vtk_to_numpy
except ImportError as e:
    sys.stderr.write(f"missing Python module vtk ({e}): pip install vtk, or run .ci/run\n"); sys.exit(3)
log = sys.argv[2]
w = vtkFileOutputWindow(); w.SetFileName(log); vtkOutputWindow.SetInstance(w)
r = vtkXMLUnstructuredGridReader(); r.SetFileName(sys.argv[1]); r.Update()
g = r.GetOutput()
def arrays(d):
    return {d.GetArrayName(i): vtk_to_numpy(d.GetArray(i)).ravel().astype(float).tolist() for i in range(d.GetNumberOfArrays())}
import os
print(json.dumps({"error": r.GetErrorCode(), "log": open(log).read() if os.path.exists(log) else "",
   "points": vtk_to_numpy(g.GetPoints().GetData()).ravel().tolist(),
   "types": [g.GetCellType(i) for i in range(g.GetNumberOfCells())],
   "conn": [[g.GetCell(i).GetPointId(k) for k in range(g.GetCell(i).GetNumberOfPoints())] for i in range(g.GetNumberOfCells())],
   "point_data": arrays(g.GetPointData()), "cell_data": arrays(g.GetCellData())}))
"#;
    for file in write_mixed(&dir, &fx) {
        let log = file.with_extension("log");
        let r = python(script, &[path_str(&file), path_str(&log)]);
        let what = file.display();
        assert_eq!(r["error"], json!(0), "{what}: {}", r["log"]);
        assert_eq!(r["log"], json!(""), "{what}: VTK complained");
        assert!(max_abs_diff(&floats(&r["points"]), &flat(&fx.tets.positions)) < 1e-12, "{what}");
        let mut types = vec![1; fx.vertices.len()];
        types.extend(vec![3; fx.lines.len()]);
        types.extend(vec![5; fx.triangles.len()]);
        types.extend(vec![10; fx.tets.n_tets()]);
        assert_eq!(r["types"], json!(types), "{what}");
        let conn: Vec<Vec<u32>> = fx
            .vertices
            .iter()
            .map(|v| vec![v.0])
            .chain(fx.lines.iter().map(|c| c.map(|v| v.0).to_vec()))
            .chain(fx.triangles.iter().map(|c| c.map(|v| v.0).to_vec()))
            .chain(fx.tets.tets.iter().map(|c| c.map(|v| v.0).to_vec()))
            .collect();
        assert_eq!(r["conn"], json!(conn), "{what}");
        for (name, values) in fx.point_values().into_iter().chain(fx.cell_values()) {
            let got = r["point_data"]
                .get(name)
                .or_else(|| r["cell_data"].get(name))
                .unwrap_or_else(|| panic!("{what}: no array {name}"));
            assert!(max_abs_diff(&floats(got), &values) < 1e-12, "{what}: {name}");
        }
    }
}

#[test]
fn stl_binary_read_by_meshio() {
    let dir = scratch("stl");
    let mesh = fixtures::torus(2.0, 0.5, 24, 12);
    let file = dir.join("torus.stl");
    write_stl_binary(std::fs::File::create(&file).unwrap(), &mesh).unwrap();
    let r = python(MESHIO_READ, &[path_str(&file)]);
    let pts = floats(&r["points"]);
    let cells = &r["cells"][0];
    assert_eq!(cells[0], json!("triangle"));
    let ids: Vec<usize> = cells[1].as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as usize).collect();
    assert_eq!(ids.len(), 3 * mesh.n_faces());
    // Every corner comes back as the f32-rounded input corner.
    for (f, tri) in ids.chunks_exact(3).enumerate() {
        for (k, &i) in tri.iter().enumerate() {
            let expected = mesh.corners(FaceId::new(f))[k].map(|c| f64::from(c as f32));
            let got = Vec3::new(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
            assert!((got - expected).norm() < 1e-12, "triangle {f} corner {k}");
        }
    }
}

// ---------------------------------------------------------------------------
// Discrete atlases remeshed by Gmsh

/// The disk fixture lifted to the unit upper hemisphere: the point at radius
/// `r`, angle `φ` goes to polar angle `θ = r π/2`; `(u, v)` = the disk point.
/// Returns the mesh, the boundary ring (angle order) and `(u, v)` per vertex.
fn hemisphere(n_rings: usize) -> (TriMesh, Vec<VertexId>, Vec<Vec2>) {
    let disk = fixtures::disk(n_rings);
    let uv: Vec<Vec2> = disk.positions.iter().map(|p| p.xy()).collect();
    let positions = uv
        .iter()
        .map(|q| {
            let (r, phi) = (q.norm(), q.y.atan2(q.x));
            let theta = r * std::f64::consts::FRAC_PI_2;
            Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
        })
        .collect();
    let ring = (0..disk.n_vertices()).filter(|&v| (uv[v].norm() - 1.0).abs() < 1e-12).map(VertexId::new).collect();
    (TriMesh { positions, triangles: disk.triangles }, ring, uv)
}

/// The largest circumradius of the triangles: every point of a triangle
/// inscribed in the unit sphere has `|p| ≥ sqrt(1 − ρ²)`.
fn max_circumradius(mesh: &TriMesh) -> f64 {
    (0..mesh.n_faces())
        .map(|f| {
            let [a, b, c] = mesh.corners(FaceId::new(f));
            let (la, lb, lc) = ((b - c).norm(), (c - a).norm(), (a - b).norm());
            la * lb * lc / (4.0 * mesh.face_area(FaceId::new(f)))
        })
        .fold(0.0, f64::max)
}

/// Gmsh in a fresh process: open, check the stored maps reproduce the given
/// `(surface, u, v, x, y, z)` samples, clear, remesh with `Mesh.MeshSizeMax`,
/// and report nodes, triangles per surface, edge use counts and the log.
const GMSH_REMESH: &str = r#"
f, h, samples = sys.argv[1], float(sys.argv[2]), json.load(open(sys.argv[3]))
gmsh.initialize(["-noenv"]); gmsh.option.setNumber("General.Terminal", 0)
gmsh.logger.start()
gmsh.open(f)
entities = gmsh.model.getEntities()
boundaries = {f"{d},{t}": [list(x) for x in gmsh.model.getBoundary([(d, t)], combined=False, oriented=False)]
              for d, t in entities if d > 0}
map_error, round_trip = 0.0, 0.0
for s, u, v, x, y, z in samples:
    p = gmsh.model.getValue(2, int(s), [u, v])
    map_error = max(map_error, float(np.abs(np.array(p) - [x, y, z]).max()))
    q = gmsh.model.getValue(2, int(s), gmsh.model.getParametrization(2, int(s), [x, y, z]))
    round_trip = max(round_trip, float(np.abs(np.array(q) - [x, y, z]).max()))
gmsh.model.mesh.clear()
gmsh.option.setNumber("Mesh.MeshSizeMax", h)
gmsh.model.mesh.generate(2)
tags, coords, _ = gmsh.model.mesh.getNodes()
tri = {}
edges = {}
for d, t in gmsh.model.getEntities(2):
    types, etags, enodes = gmsh.model.mesh.getElements(2, t)
    n = 0
    for ty, nodes in zip(types, enodes):
        if ty == 2:
            nodes = np.asarray(nodes).reshape(-1, 3)
            n += len(nodes)
            for a, b, c in nodes.tolist():
                for e in ((a, b), (b, c), (c, a)):
                    k = (min(e), max(e)); edges[k] = edges.get(k, 0) + 1
    tri[str(t)] = n
uses = {}
for c in edges.values(): uses[str(c)] = uses.get(str(c), 0) + 1
print(json.dumps({"entities": entities, "boundaries": boundaries, "map_error": map_error, "round_trip": round_trip,
                  "coords": np.asarray(coords).ravel().tolist(), "triangles": tri, "edge_uses": uses,
                  "log": [l for l in gmsh.logger.get() if l.startswith(("Error", "Warning"))]}))
gmsh.finalize()
"#;

/// What Gmsh does with a stored surface map.
#[derive(Clone, Copy, PartialEq)]
enum StoredMap {
    /// Curved patch: Gmsh keeps our `(u, v)` exactly.
    Kept,
    /// Planar patch: Gmsh replaces our map by its own plane projection on load.
    ReplacedByPlane,
}

/// Write `model`, remesh it in Gmsh, return the report.
fn remesh(dir: &Path, name: &str, model: &MshModel, h: f64, samples: &[[f64; 6]], stored: StoredMap) -> Value {
    let file = dir.join(format!("{name}.msh"));
    write_msh41(std::fs::File::create(&file).unwrap(), model, &Msh41Options::default()).unwrap();
    let samples_file = dir.join(format!("{name}_samples.json"));
    std::fs::write(&samples_file, serde_json::to_string(samples).unwrap()).unwrap();
    let r = python(GMSH_REMESH, &[path_str(&file), &h.to_string(), path_str(&samples_file)]);
    let errors: Vec<&Value> =
        r["log"].as_array().unwrap().iter().filter(|l| l.as_str().unwrap().starts_with("Error")).collect();
    assert!(errors.is_empty(), "{name}: gmsh errors {errors:?}");
    let map_error = r["map_error"].as_f64().unwrap();
    match stored {
        StoredMap::Kept => assert!(map_error < 1e-12, "{name}: stored map does not reproduce xyz: {map_error}"),
        StoredMap::ReplacedByPlane => assert!(map_error > 1e-6, "{name}: Gmsh kept the map of a planar patch"),
    }
    assert!(r["round_trip"].as_f64().unwrap() < 1e-9, "{name}: Gmsh's map does not invert: {}", r["round_trip"]);
    r
}

/// Samples `(surface, u, v, x, y, z)` of every `step`-th vertex of a patch map.
fn samples(surface: i32, mesh: &TriMesh, uv: &PatchUv, step: usize) -> Vec<[f64; 6]> {
    uv.vertices
        .iter()
        .zip(&uv.uv)
        .step_by(step)
        .map(|(v, q)| {
            let p = mesh.positions[v.idx()];
            [f64::from(surface), q.x, q.y, p.x, p.y, p.z]
        })
        .collect()
}

/// Expected triangle count for area `a` at size `h` (equilateral triangles).
fn expected_triangles(area: f64, h: f64) -> f64 {
    area / (3f64.sqrt() / 4.0 * h * h)
}

fn coords(r: &Value) -> Vec<Vec3> {
    floats(&r["coords"]).chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
}

#[test]
fn atlas_curved_patch_with_corner_and_closed_curve_is_remeshed_by_gmsh() {
    let dir = scratch("atlas_hemisphere");
    let (mesh, ring, uv) = hemisphere(8);
    let mut b = DiscreteModelBuilder::new(&mesh);
    let corner = b.add_corner(ring[0]).unwrap();
    let mut chain = ring.clone();
    chain.push(ring[0]);
    let curve = b.add_curve(chain).unwrap();
    let all: Vec<VertexId> = (0..mesh.n_vertices()).map(VertexId::new).collect();
    let map = PatchUv { vertices: all, uv, curvature: vec![] };
    let surface = b.add_patch((0..mesh.n_faces()).map(FaceId::new).collect(), vec![curve], Some(map.clone())).unwrap();
    let model = b.build().unwrap();
    assert_eq!((corner, curve, surface), (1, 1, 1));

    let h = 0.1;
    let r = remesh(&dir, "hemisphere", &model, h, &samples(1, &mesh, &map, 7), StoredMap::Kept);
    assert_eq!(r["entities"], json!([[0, 1], [1, 1], [2, 1]]));
    assert_eq!(r["boundaries"]["1,1"], json!([[0, 1], [0, 1]]));
    assert_eq!(r["boundaries"]["2,1"], json!([[1, 1]]));
    let n_tri = r["triangles"]["1"].as_f64().unwrap();
    let expected = expected_triangles(2.0 * std::f64::consts::PI, h);
    assert!(n_tri > 0.5 * expected && n_tri < 2.0 * expected, "{n_tri} triangles, expected about {expected}");
    let inner = (1.0 - max_circumradius(&mesh).powi(2)).sqrt();
    for p in coords(&r) {
        assert!(p.norm() <= 1.0 + 1e-9 && p.norm() >= inner - 1e-9, "node {p:?} off the input surface");
        assert!(p.z >= -1e-9, "node {p:?} below the hemisphere");
    }
    // One boundary loop: edges used once lie on the curve, all others twice.
    let uses = &r["edge_uses"];
    assert!(
        uses["1"].as_u64().unwrap() > 0 && uses.as_object().unwrap().keys().all(|k| k == "1" || k == "2"),
        "{uses}"
    );
}

/// The unit sphere as two hemispheres sharing the equator: upper cap as in
/// [`hemisphere`], lower cap mirrored (`z → −z`, triangles reversed, `v → −v`
/// so both maps keep counter-clockwise `(u, v)` triangles).
fn two_caps(n_rings: usize) -> (TriMesh, Vec<VertexId>, [PatchUv; 2], usize) {
    let (top, ring, uv) = hemisphere(n_rings);
    let n = top.n_vertices();
    let on_ring: Vec<bool> = (0..n).map(|v| ring.contains(&VertexId::new(v))).collect();
    let mut positions = top.positions.clone();
    let mut lower_id = vec![VertexId(0); n];
    for v in 0..n {
        lower_id[v] = if on_ring[v] {
            VertexId::new(v)
        } else {
            let p = top.positions[v];
            positions.push(Vec3::new(p.x, p.y, -p.z));
            VertexId::new(positions.len() - 1)
        };
    }
    let mut triangles = top.triangles.clone();
    triangles.extend(top.triangles.iter().map(|t| [lower_id[t[0].idx()], lower_id[t[2].idx()], lower_id[t[1].idx()]]));
    let upper = PatchUv { vertices: (0..n).map(VertexId::new).collect(), uv: uv.clone(), curvature: vec![] };
    let lower = PatchUv {
        vertices: lower_id.clone(),
        uv: uv.iter().map(|q| Vec2::new(q.x, -q.y)).collect(),
        curvature: vec![],
    };
    let n_top_faces = top.n_faces();
    (TriMesh { positions, triangles }, ring, [upper, lower], n_top_faces)
}

#[test]
fn atlas_sphere_of_two_caps_sharing_a_curve_is_remeshed_watertight() {
    let dir = scratch("atlas_two_caps");
    let (mesh, ring, [upper, lower], n_top) = two_caps(8);
    mesh.validate().unwrap();
    assert!(mesh.signed_volume() > 0.0);
    let mut b = DiscreteModelBuilder::new(&mesh);
    b.add_corner(ring[0]).unwrap();
    let mut chain = ring.clone();
    chain.push(ring[0]);
    let curve = b.add_curve(chain).unwrap();
    b.add_patch((0..n_top).map(FaceId::new).collect(), vec![curve], Some(upper.clone())).unwrap();
    b.add_patch((n_top..mesh.n_faces()).map(FaceId::new).collect(), vec![curve], Some(lower.clone())).unwrap();
    let model = b.build().unwrap();
    let mut s = samples(1, &mesh, &upper, 5);
    s.extend(samples(2, &mesh, &lower, 5));

    let h = 0.15;
    let r = remesh(&dir, "two_caps", &model, h, &s, StoredMap::Kept);
    assert_eq!(r["entities"], json!([[0, 1], [1, 1], [2, 1], [2, 2]]));
    assert_eq!(r["boundaries"]["2,1"], json!([[1, 1]]));
    assert_eq!(r["boundaries"]["2,2"], json!([[1, 1]]));
    let expected = expected_triangles(2.0 * std::f64::consts::PI, h);
    for patch in ["1", "2"] {
        let n = r["triangles"][patch].as_f64().unwrap();
        assert!(n > 0.5 * expected && n < 2.0 * expected, "patch {patch}: {n} triangles, expected about {expected}");
    }
    let inner = (1.0 - max_circumradius(&mesh).powi(2)).sqrt();
    for p in coords(&r) {
        assert!(p.norm() <= 1.0 + 1e-9 && p.norm() >= inner - 1e-9, "node {p:?} off the input surface");
    }
    // Watertight: both caps were meshed on the same curve nodes.
    assert_eq!(r["edge_uses"], json!({"2": r["edge_uses"]["2"]}), "every edge must be shared by exactly two triangles");
}

#[test]
fn atlas_patch_with_a_hole_is_remeshed_by_gmsh() {
    // An open cylinder: one curved patch bounded by two closed curves, mapped
    // to the annulus 0.5 <= |(u, v)| <= 1 (bottom ring outside, top ring inside).
    let dir = scratch("atlas_cylinder");
    let (radius, height, n_around, n_height) = (1.0, 1.5, 32, 8);
    let mesh = fixtures::cylinder(radius, height, n_around, n_height);
    let ring = |k: usize| -> Vec<VertexId> { (0..n_around).map(|j| VertexId::new(k * n_around + j)).collect() };
    let mut b = DiscreteModelBuilder::new(&mesh);
    let mut curves = Vec::new();
    for k in [0, n_height] {
        let r = ring(k);
        b.add_corner(r[0]).unwrap();
        let mut chain = r.clone();
        chain.push(r[0]);
        curves.push(b.add_curve(chain).unwrap());
    }
    let all: Vec<VertexId> = (0..mesh.n_vertices()).map(VertexId::new).collect();
    let uv = all
        .iter()
        .map(|v| {
            let p = mesh.positions[v.idx()];
            let rho = 1.0 - 0.5 * p.z / height;
            Vec2::new(p.x, p.y) * (rho / radius)
        })
        .collect();
    let map = PatchUv { vertices: all, uv, curvature: vec![] };
    b.add_patch((0..mesh.n_faces()).map(FaceId::new).collect(), curves, Some(map.clone())).unwrap();
    let model = b.build().unwrap();

    let h = 0.15;
    let r = remesh(&dir, "cylinder", &model, h, &samples(1, &mesh, &map, 5), StoredMap::Kept);
    assert_eq!(r["entities"], json!([[0, 1], [0, 2], [1, 1], [1, 2], [2, 1]]));
    assert_eq!(r["boundaries"]["2,1"], json!([[1, 1], [1, 2]]));
    let n = r["triangles"]["1"].as_f64().unwrap();
    let expected = expected_triangles(std::f64::consts::TAU * radius * height, h);
    assert!(n > 0.5 * expected && n < 2.0 * expected, "{n} triangles, expected about {expected}");
    let inner = radius * (std::f64::consts::PI / n_around as f64).cos();
    for p in coords(&r) {
        let rho = p.xy().norm();
        assert!(
            rho <= radius + 1e-9 && rho >= inner - 1e-9 && p.z > -1e-9 && p.z < height + 1e-9,
            "node {p:?} off the cylinder"
        );
    }
    let uses = &r["edge_uses"];
    assert!(
        uses["1"].as_u64().unwrap() > 0 && uses.as_object().unwrap().keys().all(|k| k == "1" || k == "2"),
        "{uses}"
    );
}

/// `fixtures::cube(n)` as 6 planar patches, 12 edge curves and 8 corners.
fn cube_atlas(n: usize) -> (TriMesh, MshModel, Vec<[f64; 6]>) {
    let mesh = fixtures::cube(n);
    let on = |x: f64| (x.abs() - 1.0).abs() < 1e-12;
    let corners: Vec<VertexId> =
        (0..mesh.n_vertices()).filter(|&v| mesh.positions[v].iter().all(|&c| on(c))).map(VertexId::new).collect();
    let mut b = DiscreteModelBuilder::new(&mesh);
    for &c in &corners {
        b.add_corner(c).unwrap();
    }
    // Edge curves: vertices with two coordinates at ±1, sorted along the third.
    let mut curve_keys = Vec::new();
    for free in 0..3 {
        for s1 in [-1.0, 1.0] {
            for s2 in [-1.0, 1.0] {
                let (a1, a2) = ((free + 1) % 3, (free + 2) % 3);
                let mut chain: Vec<VertexId> = (0..mesh.n_vertices())
                    .filter(|&v| {
                        let p = mesh.positions[v];
                        (p[a1] - s1).abs() < 1e-12 && (p[a2] - s2).abs() < 1e-12
                    })
                    .map(VertexId::new)
                    .collect();
                chain.sort_by(|x, y| mesh.positions[x.idx()][free].total_cmp(&mesh.positions[y.idx()][free]));
                let tag = b.add_curve(chain).unwrap();
                curve_keys.push((tag, [(a1, s1), (a2, s2)]));
            }
        }
    }
    let mut all_samples = Vec::new();
    for axis in 0..3 {
        for side in [-1.0, 1.0] {
            let faces: Vec<FaceId> = (0..mesh.n_faces())
                .map(FaceId::new)
                .filter(|&f| mesh.corners(f).iter().all(|p| (p[axis] - side).abs() < 1e-12))
                .collect();
            let boundary: Vec<i32> =
                curve_keys.iter().filter(|(_, k)| k.contains(&(axis, side))).map(|(t, _)| *t).collect();
            let mut vertices: Vec<VertexId> = faces.iter().flat_map(|&f| mesh.triangles[f.idx()]).collect();
            vertices.sort_unstable();
            vertices.dedup();
            let (a, c) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut uv: Vec<Vec2> =
                vertices.iter().map(|v| Vec2::new(mesh.positions[v.idx()][a], mesh.positions[v.idx()][c])).collect();
            // Keep the (u, v) triangles counter-clockwise.
            let [p, q, r] = mesh.triangles[faces[0].idx()].map(|v| uv[vertices.binary_search(&v).unwrap()]);
            if meshatlas::geom::orient2d(&p, &q, &r) < 0.0 {
                uv.iter_mut().for_each(|w| w.x = -w.x);
            }
            let map = PatchUv { vertices, uv, curvature: vec![] };
            let tag = b.add_patch(faces, boundary, Some(map.clone())).unwrap();
            all_samples.extend(samples(tag, &mesh, &map, 3));
        }
    }
    let model = b.build().unwrap();
    (mesh, model, all_samples)
}

#[test]
fn atlas_cube_of_six_patches_twelve_curves_eight_points_is_remeshed_watertight() {
    let dir = scratch("atlas_cube");
    let (_, model, s) = cube_atlas(4);
    assert_eq!((model.points.len(), model.curves.len(), model.surfaces.len()), (8, 12, 6));
    let h = 0.2;
    let r = remesh(&dir, "cube", &model, h, &s, StoredMap::ReplacedByPlane);
    let ents = r["entities"].as_array().unwrap();
    assert_eq!(ents.len(), 8 + 12 + 6);
    for f in 1..=6 {
        assert_eq!(r["boundaries"][format!("2,{f}")].as_array().unwrap().len(), 4, "face {f}");
        let n = r["triangles"][f.to_string()].as_f64().unwrap();
        let expected = expected_triangles(4.0, h);
        assert!(n > 0.5 * expected && n < 2.0 * expected, "face {f}: {n} triangles, expected about {expected}");
    }
    for p in coords(&r) {
        let m = p.iter().fold(0.0f64, |a, c| a.max(c.abs()));
        assert!((m - 1.0).abs() < 1e-9, "node {p:?} off the cube");
    }
    assert_eq!(r["edge_uses"], json!({"2": r["edge_uses"]["2"]}), "every edge must be shared by exactly two triangles");
}

/// Entity kinds and boundary sizes of a [`GMSH_REMESH`] report, sorted, so
/// that models with other tags compare equal.
fn layout(r: &Value) -> Vec<String> {
    let mut s: Vec<String> = r["entities"].as_array().unwrap().iter().map(|e| format!("dim {}", e[0])).collect();
    for (k, b) in r["boundaries"].as_object().unwrap() {
        s.push(format!("dim {} bounded by {}", &k[..1], b.as_array().unwrap().len()));
    }
    s.sort();
    s
}

/// Remesh one of Gmsh's own atlases in `shared/data/gmsh/`.
fn remesh_reference(dir: &Path, name: &str, h: f64) -> Value {
    let reference = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/gmsh").join(name);
    assert!(reference.exists(), "missing {} (the shared/ data must sit beside the repository)", reference.display());
    let empty = dir.join("none.json");
    std::fs::write(&empty, "[]").unwrap();
    python(GMSH_REMESH, &[path_str(&reference), &h.to_string(), path_str(&empty)])
}

/// Our disk and two-cap sphere atlases and Gmsh's own `disk_tiny_atlas.msh`
/// and `sphere_tiny_atlas.msh` answer Gmsh's queries alike: same entity
/// kinds and boundary relations, and a remesh that works.
#[test]
fn atlas_layout_matches_the_files_gmsh_writes() {
    let dir = scratch("atlas_vs_gmsh");
    let disk = fixtures::disk(4);
    let ring: Vec<VertexId> =
        (0..disk.n_vertices()).filter(|&v| (disk.positions[v].norm() - 1.0).abs() < 1e-12).map(VertexId::new).collect();
    let mut b = DiscreteModelBuilder::new(&disk);
    b.add_corner(ring[5]).unwrap();
    let chain: Vec<VertexId> = ring[5..].iter().chain(&ring[..=5]).copied().collect();
    let curve = b.add_curve(chain).unwrap();
    let all: Vec<VertexId> = (0..disk.n_vertices()).map(VertexId::new).collect();
    // A rotated (u, v) map: Gmsh replaces it anyway, the disk being planar.
    let uv = all.iter().map(|v| {
        let p = disk.positions[v.idx()];
        Vec2::new(0.6 * p.x - 0.8 * p.y, 0.8 * p.x + 0.6 * p.y)
    });
    let map = PatchUv { vertices: all.clone(), uv: uv.collect(), curvature: vec![] };
    b.add_patch((0..disk.n_faces()).map(FaceId::new).collect(), vec![curve], Some(map.clone())).unwrap();
    let ours = remesh(&dir, "disk", &b.build().unwrap(), 0.2, &samples(1, &disk, &map, 3), StoredMap::ReplacedByPlane);
    let theirs = remesh_reference(&dir, "disk_tiny_atlas.msh", 0.2);
    assert_eq!(layout(&ours), layout(&theirs), "ours {ours} vs Gmsh's {theirs}");
    for r in [&ours, &theirs] {
        let n = r["triangles"]["2"].as_f64().or(r["triangles"]["1"].as_f64()).unwrap();
        assert!(n > 0.5 * expected_triangles(std::f64::consts::PI, 0.2), "{r}");
        // Gmsh's file comes from an STL, so its points carry f32 rounding.
        assert!(coords(r).iter().all(|p| p.z.abs() < 1e-9 && p.xy().norm() < 1.0 + 1e-6));
    }

    let (mesh, ring, [upper, lower], n_top) = two_caps(4);
    let mut b = DiscreteModelBuilder::new(&mesh);
    b.add_corner(ring[0]).unwrap();
    let chain: Vec<VertexId> = ring.iter().chain(&ring[..1]).copied().collect();
    let curve = b.add_curve(chain).unwrap();
    b.add_patch((0..n_top).map(FaceId::new).collect(), vec![curve], Some(upper)).unwrap();
    b.add_patch((n_top..mesh.n_faces()).map(FaceId::new).collect(), vec![curve], Some(lower)).unwrap();
    let ours = remesh(&dir, "sphere", &b.build().unwrap(), 0.3, &[], StoredMap::Kept);
    let theirs = remesh_reference(&dir, "sphere_tiny_atlas.msh", 0.3);
    assert_eq!(layout(&ours), layout(&theirs), "ours {ours} vs Gmsh's {theirs}");
    for r in [&ours, &theirs] {
        assert_eq!(r["edge_uses"], json!({"2": r["edge_uses"]["2"]}), "not watertight: {r}");
        assert!(coords(r).iter().all(|p| (p.norm() - 1.0).abs() < 0.1), "{r}");
    }
}
