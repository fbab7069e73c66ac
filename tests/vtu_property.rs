//! Property test of the VTU writer against two independent readers: many
//! files with random point and cell counts, random array sets, both header
//! types and every encoding, each read back by meshio and by VTK's XML
//! reader (what ParaView uses), plain and zlib-compressed.
//!
//! meshio reads a raw appended block by converting it to base64 array by
//! array, rewriting each `offset` attribute as it goes and looking the next
//! array up by its raw offset; a rewritten offset that equals a pending raw
//! offset makes it find the wrong array. Half of the files are chosen so
//! that this collision would happen if the appended arrays were laid out in
//! document order (as the writer once did), so the test fails on that
//! layout. Files without cells are read by VTK only (meshio cannot read
//! them, not even its own).

use std::path::Path;

use meshatlas::geom::Vec3;
use meshatlas::io::vtu::{
    CellBlock, DataArray, DataValues, VtuCompression, VtuEncoding, VtuHeaderType, VtuMesh, VtuOptions, write_vtu,
};
use meshatlas::mesh::VertexId;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde_json::{Value, json};

mod common;

use common::{path_str, python};

/// The kinds of data array a file may carry.
#[derive(Clone, Copy, Debug)]
enum Kind {
    F64,
    F64x3,
    F32,
    I32,
    U8,
}

impl Kind {
    const ALL: [Kind; 5] = [Kind::F64, Kind::F64x3, Kind::F32, Kind::I32, Kind::U8];

    /// Bytes per tuple.
    fn tuple_bytes(self) -> usize {
        match self {
            Kind::F64 => 8,
            Kind::F64x3 => 24,
            Kind::F32 | Kind::I32 => 4,
            Kind::U8 => 1,
        }
    }
}

/// The sizes of one random file.
#[derive(Clone, Debug)]
struct Config {
    n_points: usize,
    n_triangles: usize,
    point_arrays: Vec<Kind>,
    cell_arrays: Vec<Kind>,
    header64: bool,
}

impl Config {
    fn random(rng: &mut StdRng) -> Self {
        let arrays = |rng: &mut StdRng| -> Vec<Kind> {
            (0..rng.random_range(0..4)).map(|_| Kind::ALL[rng.random_range(0..Kind::ALL.len())]).collect()
        };
        Config {
            n_points: rng.random_range(3..3000),
            n_triangles: rng.random_range(1..4000),
            point_arrays: arrays(rng),
            cell_arrays: arrays(rng),
            header64: rng.random_bool(0.7),
        }
    }

    /// Bytes of each binary array in document order (point data, cell
    /// data, points, connectivity, offsets, types), without headers.
    fn array_bytes(&self) -> Vec<usize> {
        let mut v: Vec<usize> = self.point_arrays.iter().map(|k| k.tuple_bytes() * self.n_points).collect();
        v.extend(self.cell_arrays.iter().map(|k| k.tuple_bytes() * self.n_triangles));
        v.extend([24 * self.n_points, 12 * self.n_triangles, 4 * self.n_triangles, self.n_triangles]);
        v
    }

    /// Whether meshio would look up the wrong array if the appended block
    /// held the arrays in document order.
    fn collides_in_document_order(&self) -> bool {
        let header = if self.header64 { 8 } else { 4 };
        let (mut raw, mut b64) = (Vec::new(), Vec::new());
        let (mut r, mut b) = (0usize, 0usize);
        for n in self.array_bytes() {
            raw.push(r);
            b64.push(b);
            r += n + header;
            b += 4 * (n + header).div_ceil(3);
        }
        (1..raw.len()).any(|j| raw[j + 1..].contains(&b64[j]))
    }
}

/// The arrays of one file, owned.
struct Data {
    points: Vec<Vec3>,
    triangles: Vec<[VertexId; 3]>,
    point_data: Vec<DataArray<'static>>,
    cell_data: Vec<DataArray<'static>>,
}

fn values(rng: &mut StdRng, kind: Kind, name: String, n: usize) -> DataArray<'static> {
    match kind {
        Kind::F64 => DataArray::f64(name, 1, (0..n).map(|_| rng.random_range(-1e3..1e3)).collect::<Vec<_>>()),
        Kind::F64x3 => DataArray::f64(name, 3, (0..3 * n).map(|_| rng.random_range(-1.0..1.0)).collect::<Vec<_>>()),
        Kind::F32 => DataArray {
            name,
            n_components: 1,
            values: DataValues::Float32((0..n).map(|_| rng.random_range(-10.0f32..10.0)).collect::<Vec<_>>().into()),
        },
        Kind::I32 => DataArray::i32(name, (0..n).map(|_| rng.random_range(-50_000..50_000)).collect::<Vec<_>>()),
        Kind::U8 => DataArray::u8(name, (0..n).map(|_| rng.random::<u8>()).collect::<Vec<_>>()),
    }
}

fn data(rng: &mut StdRng, c: &Config) -> Data {
    let points = (0..c.n_points)
        .map(|_| Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
        .collect();
    let n = c.n_points as u32;
    let triangles = (0..c.n_triangles)
        .map(|_| [VertexId(rng.random_range(0..n)), VertexId(rng.random_range(0..n)), VertexId(rng.random_range(0..n))])
        .collect();
    let point_data =
        c.point_arrays.iter().enumerate().map(|(i, &k)| values(rng, k, format!("p{i}"), c.n_points)).collect();
    let cell_data =
        c.cell_arrays.iter().enumerate().map(|(i, &k)| values(rng, k, format!("c{i}"), c.n_triangles)).collect();
    Data { points, triangles, point_data, cell_data }
}

/// Sum of an array's values as f64 (a cheap fingerprint that catches a
/// wrong or shifted array).
fn sum(v: &DataValues<'_>) -> (usize, f64) {
    match v {
        DataValues::Float64(x) => (x.len(), x.iter().sum()),
        DataValues::Float32(x) => (x.len(), x.iter().map(|&y| f64::from(y)).sum()),
        DataValues::Int32(x) => (x.len(), x.iter().map(|&y| f64::from(y)).sum()),
        DataValues::Int64(x) => (x.len(), x.iter().map(|&y| y as f64).sum()),
        DataValues::UInt8(x) => (x.len(), x.iter().map(|&y| f64::from(y)).sum()),
        DataValues::UInt32(x) => (x.len(), x.iter().map(|&y| f64::from(y)).sum()),
    }
}

/// What a reader must find in a file.
fn expected(d: &Data) -> Value {
    let arrays: serde_json::Map<String, Value> = d
        .point_data
        .iter()
        .chain(&d.cell_data)
        .map(|a| {
            let (n, s) = sum(&a.values);
            (a.name.clone(), json!([n, s]))
        })
        .collect();
    let coord_sum: f64 = d.points.iter().map(|p| p.x + p.y + p.z).sum();
    let conn_sum: u64 = d.triangles.iter().flatten().map(|v| u64::from(v.0)).sum();
    json!({"n_points": d.points.len(), "n_cells": d.triangles.len(), "coord_sum": coord_sum,
           "conn_sum": conn_sum, "arrays": arrays})
}

/// Reads every file with meshio and VTK; prints one JSON object per file.
const READ_BOTH: &str = r#"
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
from vtkmodules.vtkCommonCore import vtkFileOutputWindow, vtkOutputWindow
from vtkmodules.util.numpy_support import vtk_to_numpy
files = json.load(open(sys.argv[1]))
w = vtkFileOutputWindow(); w.SetFileName(sys.argv[2]); vtkOutputWindow.SetInstance(w)
def summary(n_points, n_cells, coords, conn, arrays):
    return {"n_points": int(n_points), "n_cells": int(n_cells), "coord_sum": float(np.sum(coords)),
            "conn_sum": int(np.sum(conn)),
            "arrays": {k: [int(np.asarray(v).size), float(np.sum(np.asarray(v, dtype=float)))] for k, v in arrays.items()}}
out = {}
for f in files:
    r = {}
    try:
        m = meshio.read(f)
        arrays = dict(m.point_data)
        arrays.update({k: np.concatenate([np.ravel(b) for b in v]) for k, v in m.cell_data.items()})
        conn = np.concatenate([np.ravel(c.data) for c in m.cells])
        r["meshio"] = summary(len(m.points), sum(len(c.data) for c in m.cells), m.points, conn, arrays)
    except Exception as e:
        r["meshio"] = {"error": f"{type(e).__name__}: {e}"}
    g = vtkXMLUnstructuredGridReader(); g.SetFileName(f); g.Update()
    u = g.GetOutput()
    if g.GetErrorCode() != 0 or u.GetPoints() is None:
        r["vtk"] = {"error": f"error code {g.GetErrorCode()}"}
    else:
        arrays = {}
        for d in (u.GetPointData(), u.GetCellData()):
            for i in range(d.GetNumberOfArrays()):
                arrays[d.GetArrayName(i)] = vtk_to_numpy(d.GetArray(i))
        conn = vtk_to_numpy(u.GetCells().GetConnectivityArray())
        r["vtk"] = summary(u.GetNumberOfPoints(), u.GetNumberOfCells(), vtk_to_numpy(u.GetPoints().GetData()), conn, arrays)
    out[f] = r
print(json.dumps(out))
"#;

/// Whether `got` (one reader's summary) matches `want`.
fn matches(got: &Value, want: &Value) -> Result<(), String> {
    if let Some(e) = got.get("error") {
        return Err(e.to_string());
    }
    for key in ["n_points", "n_cells", "conn_sum"] {
        if got[key] != want[key] {
            return Err(format!("{key}: {} != {}", got[key], want[key]));
        }
    }
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * (1.0 + b.abs());
    if !close(got["coord_sum"].as_f64().unwrap_or(f64::NAN), want["coord_sum"].as_f64().unwrap()) {
        return Err(format!("coordinates: {} != {}", got["coord_sum"], want["coord_sum"]));
    }
    for (name, w) in want["arrays"].as_object().unwrap() {
        let g = &got["arrays"][name];
        let ok = g[0] == w[0] && close(g[1].as_f64().unwrap_or(f64::NAN), w[1].as_f64().unwrap());
        if !ok {
            return Err(format!("array {name}: [len, sum] {g} != {w}"));
        }
    }
    Ok(())
}

#[test]
fn random_vtus_are_read_by_meshio_and_vtk() {
    let dir = common::scratch("vtu_property", "random");
    let mut rng = StdRng::seed_from_u64(0x7674_7521);
    // Files that would collide in document order, then unconstrained ones.
    let mut configs: Vec<Config> = Vec::new();
    while configs.len() < 12 {
        let c = Config::random(&mut rng);
        if c.collides_in_document_order() {
            configs.push(c);
        }
    }
    configs.extend((0..12).map(|_| Config::random(&mut rng)));
    // Files without cells (e.g. `frames_singular.vtu` of a cube): VTK reads
    // them; meshio cannot (not even its own), as the README says.
    let n_with_cells = configs.len();
    configs.extend((0..3).map(|_| Config { n_triangles: 0, cell_arrays: Vec::new(), ..Config::random(&mut rng) }));
    let mut files = Vec::new();
    let mut want = serde_json::Map::new();
    for (i, c) in configs.iter().enumerate() {
        let d = data(&mut rng, c);
        let mesh = VtuMesh {
            points: &d.points,
            cells: vec![CellBlock::Triangles(&d.triangles)],
            point_data: d.point_data.clone(),
            cell_data: d.cell_data.clone(),
        };
        // Raw (the default and the case meshio mishandled) for every file,
        // base64 and ASCII for a few.
        let (raw, zlib) = (VtuEncoding::Raw, VtuCompression::Zlib);
        let none = VtuCompression::None;
        let variants: &[(VtuEncoding, VtuCompression)] = if i % 6 == 0 {
            &[
                (raw, none),
                (raw, zlib),
                (VtuEncoding::Base64, none),
                (VtuEncoding::Base64, zlib),
                (VtuEncoding::Ascii, none),
            ]
        } else {
            &[(raw, none), (raw, zlib)]
        };
        for &(encoding, compression) in variants {
            let header_type = if c.header64 { VtuHeaderType::UInt64 } else { VtuHeaderType::UInt32 };
            let file = dir.join(format!("f{i:02}_{encoding:?}_{compression:?}.vtu"));
            let opts = VtuOptions { encoding, header_type, compression };
            write_vtu(std::fs::File::create(&file).unwrap(), &mesh, &opts).unwrap();
            want.insert(path_str(&file).to_string(), expected(&d));
            files.push(path_str(&file).to_string());
        }
    }
    let list = dir.join("files.json");
    std::fs::write(&list, serde_json::to_vec(&files).unwrap()).unwrap();
    let log = dir.join("vtk.log");
    let got = python(READ_BOTH, &[path_str(&list), path_str(&log)]);
    let mut failures = Vec::new();
    for (file, w) in &want {
        let readers: &[&str] = if w["n_cells"] == 0 { &["vtk"] } else { &["meshio", "vtk"] };
        for &reader in readers {
            if let Err(e) = matches(&got[file][reader], w) {
                let name = Path::new(file).file_name().unwrap().to_string_lossy().to_string();
                failures.push(format!("{reader} {name}: {e}"));
            }
        }
    }
    assert!(want.values().filter(|w| w["n_cells"] == 0).count() >= configs.len() - n_with_cells);
    assert!(failures.is_empty(), "{} of {} reads failed:\n{}", failures.len(), 2 * want.len(), failures.join("\n"));
}
