//! Cross-reading: files written by Gmsh (MSH 2.2 and 4.1, ASCII and binary,
//! parametric and partitioned, surfaces and tetrahedra) and by meshio (PLY,
//! STL, OBJ, MSH) load with the node and element counts their writer
//! reports, and the shared Gmsh-written atlases load. Then robustness: truncated,
//! bit-flipped and random inputs never panic or hang. The generator is a
//! Python script run with `python3` (gmsh and meshio must be installed).
//!
//! `perf_binary_stl_2m_triangles` (ignored) measures reading and welding a
//! 2M-triangle binary STL: `cargo test --release --test io_readers perf -- --ignored --nocapture`.

use meshatlas::failure::FailureKind;
use meshatlas::geom::Vec3;
use meshatlas::io::{Format, LoadOptions, load_bytes, load_path, load_reader};
use meshatlas::mesh::{TriMesh, fixtures};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Writes the test files and `manifest.json` (file, writer, nodes, elements
/// per type, expected closedness / genus / enclosed volume). Gmsh counts are
/// taken by reading each written file back with Gmsh.
const GENERATOR: &str = r#"import gmsh, json, sys, os
import numpy as np
import meshio
out = sys.argv[1]
manifest = []

def counts_of_file(f):
    """Nodes and elements per type name as Gmsh reports them after reading `f` back."""
    gmsh.clear()
    gmsh.open(f)
    types, tags, _ = gmsh.model.mesh.getElements()
    c = {}
    for t, tg in zip(types, tags):
        name = gmsh.model.mesh.getElementProperties(t)[0]
        c[name] = c.get(name, 0) + len(tg)
    ntags, _, _ = gmsh.model.mesh.getNodes()
    return len(set(ntags.tolist())), c

def write_all(model_fn, stem, expect, versions=("2.2", "4.1"), param_versions=("4.1",), partition=0):
    files = []
    for ver in versions:
        for binary in (0, 1):
            for param in ((0, 1) if ver in param_versions else (0,)):
                gmsh.clear()
                model_fn()
                if partition:
                    gmsh.model.mesh.partition(partition)
                gmsh.option.setNumber("Mesh.MshFileVersion", float(ver))
                gmsh.option.setNumber("Mesh.Binary", binary)
                gmsh.option.setNumber("Mesh.SaveParametric", param)
                f = os.path.join(out, f"{stem}_{ver}_{'bin' if binary else 'ascii'}{'_param' if param else ''}.msh")
                gmsh.write(f)
                files.append(f)
    gmsh.option.setNumber("Mesh.SaveParametric", 0)
    for f in files:
        n, c = counts_of_file(f)
        manifest.append(dict(file=os.path.basename(f), writer="gmsh", nodes=n, elements=c, **expect))

def sphere():
    gmsh.model.add("sphere")
    gmsh.model.occ.addSphere(0, 0, 0, 1)
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
    gmsh.model.mesh.generate(2)

def box(volume_only):
    def f():
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0, 0, 0, 1, 2, 3)
        gmsh.model.occ.synchronize()
        if volume_only:
            gmsh.model.addPhysicalGroup(3, [1], 7)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
        gmsh.model.mesh.generate(3)
    return f

def torus():
    gmsh.model.add("torus")
    gmsh.model.occ.addTorus(0, 0, 0, 2, 0.7)
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.4)
    gmsh.model.mesh.generate(2)

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.option.setNumber("General.NumThreads", 1)
write_all(sphere, "sphere", dict(closed=True, genus=0, volume=0.0))
write_all(torus, "torus", dict(closed=True, genus=1, volume=0.0), versions=("4.1",))
write_all(box(False), "box", dict(closed=True, genus=0, volume=6.0))
write_all(box(True), "boxvol", dict(closed=True, genus=0, volume=6.0))
# Partitioned: interface triangles between the two parts make the surface non-manifold.
write_all(box(False), "boxpart", dict(closed=None, genus=None, volume=6.0), versions=("4.1",), param_versions=(), partition=2)
# The Gmsh-written atlases of the shared data.
for name, closed in (("disk_tiny_atlas.msh", False), ("sphere_tiny_atlas.msh", True)):
    f = os.path.join(sys.argv[2], name)
    n, c = counts_of_file(f)
    manifest.append(dict(file=f, writer="gmsh", nodes=n, elements=c, closed=closed, genus=0, volume=0.0))

# A surface mesh for meshio: the sphere's nodes and triangles, plus a mixed triangle/quad patch.
gmsh.clear()
sphere()
ntags, coords, _ = gmsh.model.mesh.getNodes()
index = {t: i for i, t in enumerate(ntags.tolist())}
_, tri_nodes = gmsh.model.mesh.getElementsByType(2)
points = coords.reshape(-1, 3)
tris = np.array([index[t] for t in tri_nodes.tolist()]).reshape(-1, 3)
gmsh.finalize()

sphere_mesh = meshio.Mesh(points, [("triangle", tris)])
grid = np.array([[x, y, 0.0] for y in range(4) for x in range(4)], dtype=float)
quads = np.array([[y * 4 + x, y * 4 + x + 1, (y + 1) * 4 + x + 1, (y + 1) * 4 + x] for y in range(3) for x in range(2)])
ptris = np.array([[y * 4 + 2, y * 4 + 3, (y + 1) * 4 + 3] for y in range(3)] + [[y * 4 + 2, (y + 1) * 4 + 3, (y + 1) * 4 + 2] for y in range(3)])
mixed = meshio.Mesh(grid, [("triangle", ptris), ("quad", quads)])

def mio(mesh, name, fmt, expect, **kw):
    f = os.path.join(out, name)
    meshio.write(f, mesh, file_format=fmt, **kw)
    c = {}
    for block in mesh.cells:
        c[block.type] = c.get(block.type, 0) + len(block.data)
    manifest.append(dict(file=os.path.basename(f), writer="meshio", nodes=len(mesh.points), elements=c, **expect))

sph = dict(closed=True, genus=0, volume=0.0)
flat = dict(closed=False, genus=0, volume=0.0)
mio(sphere_mesh, "sphere_meshio_ascii.ply", "ply", sph, binary=False)
mio(sphere_mesh, "sphere_meshio_bin.ply", "ply", sph, binary=True)
mio(sphere_mesh, "sphere_meshio_ascii.stl", "stl", sph, binary=False)
mio(sphere_mesh, "sphere_meshio_bin.stl", "stl", sph, binary=True)
mio(sphere_mesh, "sphere_meshio.obj", "obj", sph)
mio(sphere_mesh, "sphere_meshio_22_ascii.msh", "gmsh22", sph, binary=False)
mio(sphere_mesh, "sphere_meshio_22_bin.msh", "gmsh22", sph, binary=True)
mio(sphere_mesh, "sphere_meshio_41_ascii.msh", "gmsh", sph, binary=False)
mio(sphere_mesh, "sphere_meshio_41_bin.msh", "gmsh", sph, binary=True)
mio(mixed, "mixed_meshio_ascii.ply", "ply", flat, binary=False)
mio(mixed, "mixed_meshio_bin.ply", "ply", flat, binary=True)
mio(mixed, "mixed_meshio.obj", "obj", flat)
json.dump(manifest, open(os.path.join(out, "manifest.json"), "w"), indent=1)
print(len(manifest), "files")
"#;

/// One generated file and what its writer reports.
#[derive(Debug, serde::Deserialize)]
struct Entry {
    file: PathBuf,
    writer: String,
    nodes: usize,
    elements: BTreeMap<String, usize>,
    closed: Option<bool>,
    genus: Option<i64>,
    volume: f64,
}

/// The generated files, made once per machine: a directory named after a
/// hash of the generator, filled under a private name and renamed into
/// place (atomic, so concurrent test processes never see a partial set).
/// Returns the manifest with paths made absolute.
fn generated() -> &'static Vec<Entry> {
    static MANIFEST: OnceLock<Vec<Entry>> = OnceLock::new();
    MANIFEST.get_or_init(|| {
        let key = GENERATOR
            .bytes()
            .chain(gmsh_data_dir().to_string_lossy().bytes())
            .fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3));
        let dir = std::env::temp_dir().join(format!("meshatlas-io-readers-{key:016x}"));
        if !dir.join("manifest.json").is_file() {
            let tmp = std::env::temp_dir().join(format!("meshatlas-io-readers-{key:016x}-{}", std::process::id()));
            std::fs::create_dir_all(&tmp).unwrap();
            let script = tmp.join("generate.py");
            std::fs::write(&script, GENERATOR).unwrap();
            let out = std::process::Command::new("python3")
                .arg(&script)
                .arg(&tmp)
                .arg(gmsh_data_dir())
                .output()
                .expect("python3 must be installed (with gmsh and meshio)");
            assert!(out.status.success(), "generator failed:\n{}", String::from_utf8_lossy(&out.stderr));
            if std::fs::rename(&tmp, &dir).is_err() {
                // Another process won the race: use its complete directory.
                std::fs::remove_dir_all(&tmp).ok();
            }
        }
        let text = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
        let mut entries: Vec<Entry> = serde_json::from_str(&text).unwrap();
        for e in &mut entries {
            e.file = dir.join(&e.file);
        }
        entries
    })
}

fn gmsh_data_dir() -> PathBuf {
    PathBuf::from(std::env::var("MESHATLAS_GMSH_DATA").unwrap_or_else(|_| "/work/shared/data/gmsh".into()))
}

fn format_of(path: &Path) -> Format {
    Format::from_extension(path.extension().unwrap().to_str().unwrap()).unwrap()
}

/// From the writer's element counts: triangles after fan triangulation,
/// tetrahedra, quads (fan-triangulated), and the other types (skipped).
fn expected_counts(e: &Entry) -> (usize, usize, usize, BTreeMap<String, usize>) {
    let (mut tris, mut tets, mut quads) = (0, 0, 0);
    let mut skipped = BTreeMap::new();
    for (name, &n) in &e.elements {
        match name.as_str() {
            "Triangle 3" | "triangle" => tris += n,
            "Tetrahedron 4" | "tetra" => tets += n,
            "quad" => {
                tris += 2 * n;
                quads += n;
            }
            other => {
                skipped.insert(other.to_string(), n);
            }
        }
    }
    (tris, tets, quads, skipped)
}

#[test]
fn files_written_by_gmsh_and_meshio_read_with_the_writers_counts() {
    let opts = LoadOptions::default();
    let mut failures = Vec::new();
    let manifest = generated();
    assert!(manifest.len() >= 38, "generator wrote {} files", manifest.len());
    for e in manifest {
        let format = format_of(&e.file);
        let len = std::fs::metadata(&e.file).unwrap().len();
        let file = std::fs::File::open(&e.file).unwrap();
        let raw = match meshatlas::io::load::read_raw(BufReader::new(file), format, Some(len), &opts.limits()) {
            Ok(r) => r,
            Err(err) => {
                failures.push(format!("{}: {err}", e.file.display()));
                continue;
            }
        };
        let (tris, tets, quads, skipped) = expected_counts(e);
        let nodes = if format == Format::Stl { 3 * tris } else { e.nodes };
        let got = (raw.positions.len(), raw.triangles.len(), raw.tets.len(), raw.n_polygons_triangulated, &raw.skipped);
        let want = (nodes, tris, tets, quads, &skipped);
        if got != want {
            failures.push(format!("{} ({}): read {got:?}, writer says {want:?}", e.file.display(), e.writer));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn generated_files_load_repaired_with_the_expected_topology() {
    let opts = LoadOptions::default();
    let mut failures = Vec::new();
    for e in generated() {
        let l = match load_path(&e.file, None, &opts) {
            Ok(l) => l,
            Err(err) => {
                failures.push(format!("{}: {err}", e.file.display()));
                continue;
            }
        };
        let r = &l.repair;
        let name = e.file.display();
        assert!(l.surface.validate().is_ok());
        if let Some(closed) = e.closed {
            if (r.closed, r.genus) != (closed, e.genus) || r.n_components != 1 {
                failures.push(format!("{name}: closed {} genus {:?} components {}", r.closed, r.genus, r.n_components));
            }
            // Surface meshes: every node is used by a triangle and distinct.
            if e.volume == 0.0 && (l.surface.n_vertices(), r.n_unreferenced_vertices_dropped) != (e.nodes, 0) {
                failures.push(format!("{name}: {} surface vertices of {} nodes", l.surface.n_vertices(), e.nodes));
            }
        }
        if e.volume > 0.0 {
            match &l.volume {
                Some(v) if v.validate().is_ok() && (v.volume() - e.volume).abs() < 1e-9 * e.volume => {}
                other => failures.push(format!("{name}: volume {:?}", other.as_ref().map(|v| v.volume()))),
            }
            if e.closed == Some(true) && (l.surface.signed_volume() - e.volume).abs() > 1e-9 * e.volume {
                failures.push(format!("{name}: surface encloses {}", l.surface.signed_volume()));
            }
        } else if l.volume.is_some() {
            failures.push(format!("{name}: unexpected volume"));
        }
        if e.closed == Some(true) && e.volume == 0.0 && l.surface.signed_volume() <= 0.0 {
            failures.push(format!("{name}: closed surface not outward"));
        }
        // The streaming path (size unknown) gives the same mesh.
        let bytes = std::fs::read(&e.file).unwrap();
        match load_reader(&bytes[..], format_of(&e.file), &opts) {
            Ok(s) if s.surface == l.surface => {}
            Ok(_) => failures.push(format!("{name}: streaming load differs")),
            Err(err) => failures.push(format!("{name}: streaming load: {err}")),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn tet_only_files_get_the_outward_boundary_as_surface() {
    for e in generated().iter().filter(|e| e.file.file_name().unwrap().to_str().unwrap().starts_with("boxvol")) {
        let l = load_path(&e.file, None, &LoadOptions::default()).unwrap();
        assert!(l.repair.surface_from_volume_boundary, "{}", e.file.display());
        assert_eq!(l.repair.n_components_reversed_outward + l.repair.n_triangles_flipped, 0);
        assert!((l.surface.signed_volume() - 6.0).abs() < 1e-9);
        // The same box written with its surface triangles has the same boundary.
        let with_tris = PathBuf::from(e.file.to_str().unwrap().replace("boxvol_", "box_"));
        let b = load_path(&with_tris, None, &LoadOptions::default()).unwrap();
        assert_eq!((b.surface.n_faces(), b.surface.n_vertices()), (l.surface.n_faces(), l.surface.n_vertices()));
    }
}

#[test]
fn gmsh_atlases_match_their_input_surfaces() {
    let dir = gmsh_data_dir();
    for (atlas, stl) in [("disk_tiny_atlas.msh", "disk_tiny.stl"), ("sphere_tiny_atlas.msh", "sphere_tiny.stl")] {
        let a = load_path(&dir.join(atlas), None, &LoadOptions::default()).unwrap();
        let s = load_path(&dir.join(stl), None, &LoadOptions::default()).unwrap();
        assert_eq!(a.format, Format::Msh);
        assert_eq!(
            (a.surface.n_faces(), a.surface.n_vertices()),
            (s.surface.n_faces(), s.surface.n_vertices()),
            "{atlas}"
        );
        assert_eq!(a.repair.euler_characteristic, s.repair.euler_characteristic);
        assert!(a.repair.skipped_elements.contains_key("Line 2"), "{atlas}: {:?}", a.repair.skipped_elements);
        // Same vertex set (the STL is f32, the atlas f64: compare in f32).
        let key = |p: &Vec3| [p.x as f32, p.y as f32, p.z as f32].map(f32::to_bits);
        let mut pa: Vec<_> = a.surface.positions.iter().map(key).collect();
        let mut ps: Vec<_> = s.surface.positions.iter().map(key).collect();
        pa.sort_unstable();
        ps.sort_unstable();
        assert_eq!(pa, ps, "{atlas}");
    }
}

/// Files written by this crate's writers read back to the same mesh.
#[test]
fn our_writers_round_trip() {
    use meshatlas::io::msh41::model::MshModel;
    use meshatlas::io::msh41::write::{Msh41Options, write_msh41};
    use meshatlas::mesh::{TetMesh, VertexId};
    let opts = LoadOptions::default();
    let m = fixtures::torus(1.0, 0.3, 24, 12);
    let load = |bytes: &[u8]| load_bytes(bytes, None, &opts).unwrap();

    let mut b = Vec::new();
    meshatlas::io::msh22::write::write_surface_msh22(&mut b, &m).unwrap();
    assert!(load(&b).surface == m, "MSH 2.2");
    for binary in [false, true] {
        let mut b = Vec::new();
        write_msh41(&mut b, &MshModel::from_surface(&m), &Msh41Options { binary }).unwrap();
        assert!(load(&b).surface == m, "MSH 4.1 binary={binary}");
    }
    let mut b = Vec::new();
    meshatlas::io::stl_write::write_stl_binary(&mut b, &m).unwrap();
    let l = load(&b);
    assert_eq!(l.format, Format::Stl);
    // STL keeps no indices: same triangles corner by corner (in f32), same vertex count.
    assert_eq!((l.surface.n_faces(), l.surface.n_vertices()), (m.n_faces(), m.n_vertices()));
    for f in 0..m.n_faces() {
        let f = meshatlas::mesh::FaceId::new(f);
        let as_f32 = |c: [Vec3; 3]| c.map(|p| p.map(|x| x as f32));
        assert!(as_f32(l.surface.corners(f)) == as_f32(m.corners(f)), "STL triangle {f}");
    }

    // A discrete atlas as the atlas stage writes it: entities, classified
    // nodes, $Parametrizations and an $ElementData view.
    {
        use meshatlas::geom::Vec2;
        use meshatlas::io::msh41::discrete::{DiscreteModelBuilder, PatchUv};
        use meshatlas::io::msh41::model::DataView;
        use meshatlas::mesh::FaceId;
        let disk = fixtures::disk(4);
        let ring: Vec<VertexId> = (0..disk.n_vertices())
            .filter(|&v| (disk.positions[v].norm() - 1.0).abs() < 1e-12)
            .map(VertexId::new)
            .collect();
        let mut b = DiscreteModelBuilder::new(&disk);
        b.add_corner(ring[0]).unwrap();
        let mut chain = ring.clone();
        chain.push(ring[0]);
        let curve = b.add_curve(chain).unwrap();
        let vertices: Vec<VertexId> = (0..disk.n_vertices()).map(VertexId::new).collect();
        let uv: Vec<Vec2> = vertices.iter().map(|v| disk.positions[v.idx()].xy()).collect();
        let faces: Vec<FaceId> = (0..disk.n_faces()).map(FaceId::new).collect();
        b.add_patch(faces, vec![curve], Some(PatchUv { vertices, uv, curvature: vec![] })).unwrap();
        let mut model = b.build().unwrap();
        model.element_data.push(DataView::contiguous("sigma", 1, vec![1.0; disk.n_faces()], 1));
        for binary in [false, true] {
            let mut out = Vec::new();
            write_msh41(&mut out, &model, &Msh41Options { binary }).unwrap();
            let l = load(&out);
            let r = &l.repair;
            assert_eq!(
                (l.surface.n_faces(), l.surface.n_vertices()),
                (disk.n_faces(), disk.n_vertices()),
                "binary={binary}"
            );
            assert_eq!((r.n_boundary_loops, r.euler_characteristic, r.n_unreferenced_vertices_dropped), (1, 1, 0));
            assert_eq!(r.skipped_elements.get("Line 2"), Some(&ring.len()), "{:?}", r.skipped_elements);
        }
    }

    // A tet mesh of the unit cube (Kuhn: 6 positive tets around the diagonal).
    let corners = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]];
    let tets = [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]];
    let vol = TetMesh {
        positions: corners.iter().map(|c| Vec3::new(c[0] as f64, c[1] as f64, c[2] as f64)).collect(),
        tets: tets.iter().map(|t| t.map(VertexId)).collect(),
    };
    assert!(vol.validate().is_ok());
    let mut b22 = Vec::new();
    meshatlas::io::msh22::write::write_volume_msh22(&mut b22, &vol).unwrap();
    let mut b41 = Vec::new();
    write_msh41(&mut b41, &MshModel::from_volume(&vol), &Msh41Options { binary: true }).unwrap();
    for b in [b22, b41] {
        let l = load(&b);
        assert!(l.volume.as_ref() == Some(&vol));
        assert_eq!((l.surface.n_faces(), l.repair.genus, l.repair.closed), (12, Some(0), true));
        assert!((l.surface.signed_volume() - 1.0).abs() < 1e-12);
    }
}

// ---------------------------------------------------------------- robustness

/// ASCII STL of a mesh.
fn ascii_stl(m: &TriMesh) -> Vec<u8> {
    let mut s = String::from("solid seed\n");
    for t in &m.triangles {
        s.push_str(" facet normal 0 0 1\n  outer loop\n");
        for v in t {
            let p = m.positions[v.idx()];
            s.push_str(&format!("   vertex {} {} {}\n", p.x, p.y, p.z));
        }
        s.push_str("  endloop\n endfacet\n");
    }
    (s + "endsolid seed\n").into_bytes()
}

/// Binary STL of a mesh, with a header starting with "solid".
fn binary_stl(m: &TriMesh) -> Vec<u8> {
    let mut out = b"solid binary header".to_vec();
    out.resize(80, b' ');
    out.extend_from_slice(&(m.n_faces() as u32).to_le_bytes());
    for t in &m.triangles {
        out.extend_from_slice(&[0u8; 12]);
        for v in t {
            let p = m.positions[v.idx()];
            for c in [p.x, p.y, p.z] {
                out.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        out.extend_from_slice(&[0, 0]);
    }
    out
}

/// OBJ with every face form and negative indices.
fn obj(m: &TriMesh) -> Vec<u8> {
    let mut s = String::from("# seed\no x\n");
    for p in &m.positions {
        s.push_str(&format!("v {} {} {}\nvt 0 0\nvn 0 0 1\n", p.x, p.y, p.z));
    }
    for (i, t) in m.triangles.iter().enumerate() {
        let [a, b, c] = t.map(|v| v.0 as i64 + 1);
        s.push_str(&match i % 4 {
            0 => format!("f {a} {b} {c}\n"),
            1 => format!("f {a}/{a} {b}/{b} {c}/{c}\n"),
            2 => format!("f {a}//{a} {b}//{b} {c}//{c}\n"),
            _ => {
                let n = m.n_vertices() as i64;
                format!("f {} {} {}\n", a - n - 1, b - n - 1, c - n - 1)
            }
        });
    }
    s.into_bytes()
}

/// PLY with extra properties and elements, in the given encoding.
fn ply(m: &TriMesh, encoding: &str) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat {encoding} 1.0\ncomment seed\nelement vertex {}\nproperty float x\nproperty double y\nproperty float z\nproperty uchar red\nelement face {}\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\nelement material 1\nproperty int a\nend_header\n",
        m.n_vertices(),
        m.n_faces()
    )
    .into_bytes();
    let big = encoding == "binary_big_endian";
    macro_rules! put {
        ($v:expr) => {
            if big { out.extend_from_slice(&$v.to_be_bytes()) } else { out.extend_from_slice(&$v.to_le_bytes()) }
        };
    }
    if encoding == "ascii" {
        for p in &m.positions {
            out.extend_from_slice(format!("{} {} {} 7\n", p.x as f32, p.y, p.z as f32).as_bytes());
        }
        for t in &m.triangles {
            out.extend_from_slice(format!("3 {} {} {} 2 0.5 0.5\n", t[0], t[1], t[2]).as_bytes());
        }
        out.extend_from_slice(b"9\n");
    } else {
        for p in &m.positions {
            put!(p.x as f32);
            put!(p.y);
            put!(p.z as f32);
            out.push(7);
        }
        for t in &m.triangles {
            out.push(3);
            for v in t {
                put!(v.0 as i32);
            }
            out.push(1);
            put!(0.5f32);
        }
        put!(9i32);
    }
    out
}

/// MSH 2.2 ASCII with points, lines, triangles and a data section.
fn msh22(m: &TriMesh) -> Vec<u8> {
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    s.push_str(&format!("{}\n", m.n_vertices()));
    for (i, p) in m.positions.iter().enumerate() {
        s.push_str(&format!("{} {} {} {}\n", 3 * i + 5, p.x, p.y, p.z));
    }
    s.push_str(&format!("$EndNodes\n$Elements\n{}\n", m.n_faces() + 2));
    s.push_str("1 15 2 0 1 5\n2 1 2 0 1 5 8\n");
    for (i, t) in m.triangles.iter().enumerate() {
        s.push_str(&format!("{} 2 2 0 1 {} {} {}\n", i + 3, 3 * t[0].0 + 5, 3 * t[1].0 + 5, 3 * t[2].0 + 5));
    }
    s.push_str("$EndElements\n$NodeData\n1\n\"a\"\n1\n0.0\n3\n0\n1\n1\n5 1.0\n$EndNodeData\n");
    s.into_bytes()
}

/// MSH 4.1 ASCII with entities and a parametric surface block.
fn msh41(m: &TriMesh) -> Vec<u8> {
    let n = m.n_vertices();
    let mut s =
        String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 1 0\n1 0 0 0 1 1 1 0 0\n$EndEntities\n");
    s.push_str(&format!("$Nodes\n1 {n} 1 {n}\n2 1 1 {n}\n"));
    for i in 0..n {
        s.push_str(&format!("{}\n", i + 1));
    }
    for p in &m.positions {
        s.push_str(&format!("{} {} {} 0 0\n", p.x, p.y, p.z));
    }
    s.push_str(&format!("$EndNodes\n$Elements\n1 {0} 1 {0}\n2 1 2 {0}\n", m.n_faces()));
    for (i, t) in m.triangles.iter().enumerate() {
        s.push_str(&format!("{} {} {} {}\n", i + 1, t[0].0 + 1, t[1].0 + 1, t[2].0 + 1));
    }
    s.push_str("$EndElements\n");
    s.into_bytes()
}

/// Valid small inputs of every reader and encoding.
fn seeds() -> Vec<(Format, Vec<u8>)> {
    let m = fixtures::icosphere(1);
    let mut v = vec![
        (Format::Stl, ascii_stl(&m)),
        (Format::Stl, binary_stl(&m)),
        (Format::Obj, obj(&m)),
        (Format::Ply, ply(&m, "ascii")),
        (Format::Ply, ply(&m, "binary_little_endian")),
        (Format::Ply, ply(&m, "binary_big_endian")),
        (Format::Msh, msh22(&m)),
        (Format::Msh, msh41(&m)),
    ];
    // Every seed loads, to the sphere.
    for (f, b) in &v {
        let l = load_bytes(b, Some(*f), &LoadOptions::default()).unwrap_or_else(|e| panic!("{f} seed: {e}"));
        assert_eq!((l.surface.n_faces(), l.repair.genus, l.repair.closed), (m.n_faces(), Some(0), true), "{f} seed");
    }
    // Binary MSH (2.2 and 4.1, parametric, partitioned) from Gmsh.
    for e in generated() {
        let name = e.file.file_name().unwrap().to_str().unwrap();
        if name.ends_with(".msh") && (name.contains("_bin") || name.contains("part")) && !name.starts_with("torus") {
            v.push((Format::Msh, std::fs::read(&e.file).unwrap()));
        }
    }
    v
}

/// Kinds an error may have.
const KINDS: &[FailureKind] = &[
    FailureKind::EmptyFile,
    FailureKind::UnknownFormat,
    FailureKind::Truncated,
    FailureKind::ParseError,
    FailureKind::NonFiniteCoordinate,
    FailureKind::CoordinateOutOfRange,
    FailureKind::IndexOutOfRange,
    FailureKind::TooManyTriangles,
    FailureKind::TooManyVertices,
    FailureKind::NoTriangles,
    FailureKind::Unsupported,
];

/// Load `bytes` every way; a panic or a slow case fails with the case named.
fn check_case(case: &str, format: Format, bytes: &[u8], opts: &LoadOptions, slowest: &mut Duration) {
    let start = Instant::now();
    let results = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let valid = |l: meshatlas::io::LoadedMesh| {
            assert!(l.surface.validate().is_ok() && l.surface.n_faces() > 0, "{case}: invalid surface");
            assert!(l.volume.is_none_or(|v| v.validate().is_ok()), "{case}: invalid volume");
        };
        [
            load_bytes(bytes, Some(format), opts).map(valid),
            load_reader(bytes, format, opts).map(valid),
            load_bytes(bytes, None, opts).map(valid),
        ]
    }));
    let took = start.elapsed();
    *slowest = (*slowest).max(took);
    assert!(took < Duration::from_secs(2), "{case}: took {took:?}");
    let results = results
        .unwrap_or_else(|_| panic!("{case}: panicked ({} bytes: {:?}…)", bytes.len(), &bytes[..bytes.len().min(64)]));
    for r in results {
        if let Err(e) = r {
            assert!(KINDS.contains(&e.kind()), "{case}: kind {} ({e})", e.kind());
            assert!(!e.to_string().is_empty());
        }
    }
}

#[test]
fn truncated_flipped_and_random_bytes_never_panic_or_hang() {
    let opts = LoadOptions { max_triangles: 200_000, ..LoadOptions::default() };
    let mut rng = StdRng::seed_from_u64(0x5eed_2026);
    let mut slowest = Duration::ZERO;
    let mut n_cases = 0usize;
    let start = Instant::now();
    for (s, (format, seed)) in seeds().iter().enumerate() {
        let len = seed.len();
        for k in 0..40 {
            let cut = if k < 10 { k * len / 10 } else { rng.random_range(0..len) };
            check_case(&format!("seed {s} ({format}) truncated at {cut}"), *format, &seed[..cut], &opts, &mut slowest);
            n_cases += 1;
        }
        for k in 0..200 {
            let mut b = seed.clone();
            let case = match k % 4 {
                0 => {
                    for _ in 0..rng.random_range(1..=4) {
                        let i = rng.random_range(0..len);
                        b[i] ^= 1 << rng.random_range(0..8);
                    }
                    "bit flips"
                }
                1 => {
                    let i = rng.random_range(0..len);
                    let n = rng.random_range(1..=16).min(len - i);
                    rng.fill(&mut b[i..i + n]);
                    "random bytes overwritten"
                }
                2 => {
                    let i = rng.random_range(0..len);
                    let n = rng.random_range(1..=64).min(len - i);
                    if rng.random_bool(0.5) {
                        b.drain(i..i + n);
                    } else {
                        let chunk: Vec<u8> = b[i..i + n].to_vec();
                        b.splice(i..i, chunk);
                    }
                    "chunk deleted or duplicated"
                }
                _ => {
                    // A digit replaced by an extreme token (text formats).
                    let digits: Vec<usize> = (0..len).filter(|&i| b[i].is_ascii_digit()).collect();
                    if let Some(&i) = digits.get(rng.random_range(0..digits.len().max(1))) {
                        let tok: &[u8] = [&b"99999999999999999999"[..], b"-1", b"nan", b"1e308", b"0", b"4294967296"]
                            [rng.random_range(0..6)];
                        b.splice(i..i + 1, tok.iter().copied());
                    }
                    "extreme number"
                }
            };
            check_case(&format!("seed {s} ({format}) case {k}: {case}"), *format, &b, &opts, &mut slowest);
            n_cases += 1;
        }
    }
    for k in 0..400 {
        let format = Format::ALL[k % 4];
        let n = rng.random_range(0..3000);
        let mut b = vec![0u8; n];
        rng.fill(&mut b[..]);
        if k % 8 >= 4 {
            // Text-like noise with a valid magic line.
            let magic: &[u8] = match format {
                Format::Stl => b"solid x\n",
                Format::Obj => b"v 1 2 3\n",
                Format::Ply => b"ply\nformat ascii 1.0\n",
                Format::Msh => b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n",
            };
            for x in &mut b {
                *x = b" \n0123456789.-eE$abcdefv/"[(*x as usize) % 24];
            }
            b.splice(0..0, magic.iter().copied());
        }
        check_case(&format!("random {k} ({format})"), format, &b, &opts, &mut slowest);
        n_cases += 1;
    }
    eprintln!("{n_cases} cases in {:?}, slowest {slowest:?}", start.elapsed());
    assert!(n_cases > 5000);
}

/// Hostile headers must not allocate from their counts.
#[test]
fn huge_declared_counts_are_rejected_without_allocating() {
    let opts = LoadOptions::default();
    let cases: Vec<(Format, Vec<u8>)> = vec![
        (Format::Stl, {
            let mut b = vec![0u8; 84];
            b[80..84].copy_from_slice(&4_000_000u32.to_le_bytes());
            b.extend_from_slice(&[0u8; 500]);
            b
        }),
        (Format::Ply, b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 4000000000\nproperty list uchar int vertex_indices\nend_header\n\x00\x00".to_vec()),
        (Format::Msh, b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4000000000\n1 0 0 0\n".to_vec()),
        (Format::Msh, b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4000000000 1 4000000000\n2 1 0 4000000000\n1\n2\n".to_vec()),
        (Format::Msh, {
            let mut b = b"$MeshFormat\n4.1 1 8\n".to_vec();
            b.extend_from_slice(&1i32.to_le_bytes());
            b.extend_from_slice(b"\n$EndMeshFormat\n$Nodes\n");
            for v in [1u64, u64::MAX, 1, u64::MAX] {
                b.extend_from_slice(&v.to_le_bytes());
            }
            b.extend_from_slice(&[2, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]);
            b.extend_from_slice(&u64::MAX.to_le_bytes());
            b
        }),
    ];
    for (i, (f, b)) in cases.iter().enumerate() {
        let start = Instant::now();
        let e = load_bytes(b, Some(*f), &opts).unwrap_err();
        assert!([FailureKind::Truncated, FailureKind::TooManyTriangles].contains(&e.kind()), "case {i}: {e}");
        let e2 = load_reader(&b[..], *f, &opts).unwrap_err();
        assert!(
            [FailureKind::Truncated, FailureKind::TooManyTriangles].contains(&e2.kind()),
            "case {i} streamed: {e2}"
        );
        assert!(start.elapsed() < Duration::from_secs(1), "case {i}");
    }
}
