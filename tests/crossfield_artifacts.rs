//! The crossfield artifacts (`crossfield.vtu`, `crossfield.msh`,
//! `singularities.json`) read back by meshio and Gmsh (python3 subprocess).

mod common;

use meshatlas::crossfield::{
    Crossfield, CrossfieldOptions, compute_crossfield, write_crossfield_msh, write_crossfield_msh_as,
    write_crossfield_vtu, write_singularities_json,
};
use meshatlas::io::msh_output::{MshVersion, OutputOptions};
use meshatlas::mesh::{EdgeId, Topology, TriMesh, fixtures};
use meshatlas::progress::Progress;
use std::fs::File;

/// The unit disk of `rings` rings and its default crossfield, boundary-aligned.
fn disk_field(rings: usize) -> (TriMesh, Crossfield) {
    let mesh = fixtures::disk(rings);
    let topo = Topology::new(&mesh);
    let aligned: Vec<bool> = (0..topo.n_edges()).map(|e| topo.is_boundary_edge(EdgeId::new(e))).collect();
    let field = compute_crossfield(&mesh, &topo, &aligned, &CrossfieldOptions::default(), &Progress::none()).unwrap();
    (mesh, field)
}

#[test]
fn artifacts_open_in_meshio_and_gmsh() {
    let (mesh, field) = disk_field(8);
    let dir = common::scratch("crossfield_artifacts", "disk");
    let (vtu, msh, json) = (dir.join("crossfield.vtu"), dir.join("crossfield.msh"), dir.join("singularities.json"));
    write_crossfield_vtu(&field, &mesh, File::create(&vtu).unwrap()).unwrap();
    write_crossfield_msh(&field, &mesh, File::create(&msh).unwrap()).unwrap();
    write_singularities_json(&field, File::create(&json).unwrap()).unwrap();
    let script = r#"
vtu, msh, js = sys.argv[1], sys.argv[2], sys.argv[3]
m = meshio.read(vtu)
tri = m.cells_dict['triangle']
u = np.asarray(m.cell_data['cross_u'][0]); v = np.asarray(m.cell_data['cross_v'][0])
nrm = np.asarray(m.cell_data['norm'][0]); idx = np.asarray(m.point_data['index'])
gmsh.initialize(); gmsh.option.setNumber('General.Terminal', 0)
gmsh.open(msh)
views = {}
for t in gmsh.view.getTags():
    name = gmsh.option.getString(f'View[{gmsh.view.getIndex(t)}].Name')
    kind, tags, data, time, nc = gmsh.view.getModelData(t, 0)
    views[name] = [kind, len(tags), nc, [float(x) for x in data[0]]]
_, etags, _ = gmsh.model.mesh.getElements(2)
gmsh.finalize()
s = json.load(open(js))
print(json.dumps({
  'n_tri': int(len(tri)), 'n_pts': int(len(m.points)),
  'u_unit': float(np.abs(np.linalg.norm(u, axis=1) - 1).max()),
  'uv_dot': float(np.abs((u * v).sum(axis=1)).max()),
  'norm_max': float(nrm.max()), 'index_sum': float(idx.sum()), 'vtu_dtype': str(u.dtype),
  'views': views, 'n_gmsh_tri': int(sum(len(e) for e in etags)),
  'json_sum': s['index_sum'], 'json_n': len(s['singularities'])}))
"#;
    let out = common::python(script, &[common::path_str(&vtu), common::path_str(&msh), common::path_str(&json)]);
    assert_eq!(out["n_tri"], mesh.n_faces());
    assert_eq!(out["n_pts"], mesh.n_vertices());
    // The VTU stores the directions as Float32 (unit vectors to f32's 6e-8).
    assert_eq!(out["vtu_dtype"], "float32");
    assert!(out["u_unit"].as_f64().unwrap() < 1e-6);
    assert!(out["uv_dot"].as_f64().unwrap() < 1e-6);
    assert!(out["norm_max"].as_f64().unwrap() <= 1.2);
    assert!((out["index_sum"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    assert_eq!(out["n_gmsh_tri"], mesh.n_faces());
    let u = &out["views"]["cross_u"];
    assert_eq!(u[0], "ElementData");
    assert_eq!(u[1], mesh.n_faces());
    assert_eq!(u[2], 3);
    let first: Vec<f64> = u[3].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    // The MSH view holds the direction rounded to f32 (in f64 fields), exactly.
    let want = field.cross_per_face[0];
    assert_eq!(first[0], f64::from(want.x as f32));
    assert_eq!(first[1], f64::from(want.y as f32));
    assert!((first[0] - want.x).abs() < 1e-7 && (first[1] - want.y).abs() < 1e-7);
    assert_eq!(out["views"]["norm"][2], 1);
    assert_eq!(out["json_sum"], 1.0);
    assert_eq!(out["json_n"], field.singularities.len());
}

/// `crossfield.msh` as MSH 2.2 and as binary 4.1 (the `output` options):
/// Gmsh and meshio read the same triangles and element data as from the
/// default ASCII 4.1.
#[test]
fn crossfield_msh_in_2_2_and_binary_opens_in_meshio_and_gmsh() {
    let (mesh, field) = disk_field(6);
    let dir = common::scratch("crossfield_artifacts", "msh_variants");
    let variants = [
        (
            "v22.msh",
            OutputOptions { msh_version: MshVersion::V22, msh_binary: Some(false), ..Default::default() },
            "2.2",
        ),
        (
            "v41_binary.msh",
            OutputOptions { msh_version: MshVersion::V41, msh_binary: Some(true), ..Default::default() },
            "4.1",
        ),
    ];
    let script = r#"
f = sys.argv[1]
head = open(f, 'rb').read(40).split(b'\n')[1].decode()
m = meshio.read(f)
gmsh.initialize(); gmsh.option.setNumber('General.Terminal', 0)
gmsh.open(f)
_, etags, _ = gmsh.model.mesh.getElements(2)
views = {}
for t in gmsh.view.getTags():
    name = gmsh.option.getString(f'View[{gmsh.view.getIndex(t)}].Name')
    kind, tags, data, time, nc = gmsh.view.getModelData(t, 0)
    views[name] = [len(tags), nc, float(np.asarray(data).sum())]
gmsh.finalize()
print(json.dumps({'head': head, 'n_tri': int(len(m.cells_dict['triangle'])), 'n_gmsh_tri': int(sum(len(e) for e in etags)),
                  'norm_sum': float(np.asarray(m.cell_data['norm'][0]).sum()), 'views': views}))
"#;
    // The MSH views hold the values rounded to f32 (in f64 fields).
    let norm_sum: f64 = field.norm_per_face.iter().map(|&x| f64::from(x as f32)).sum();
    for (name, opts, version) in variants {
        let file = dir.join(name);
        write_crossfield_msh_as(&field, &mesh, File::create(&file).unwrap(), &opts).unwrap();
        let out = common::python(script, &[common::path_str(&file)]);
        assert!(out["head"].as_str().unwrap().starts_with(version), "{name}: {out}");
        assert_eq!(out["n_tri"], mesh.n_faces(), "{name}");
        assert_eq!(out["n_gmsh_tri"], mesh.n_faces(), "{name}");
        assert!((out["norm_sum"].as_f64().unwrap() - norm_sum).abs() < 1e-9, "{name}: meshio norm");
        assert_eq!(out["views"]["norm"][0], mesh.n_faces(), "{name}: gmsh view");
        assert!((out["views"]["norm"][2].as_f64().unwrap() - norm_sum).abs() < 1e-9, "{name}: gmsh norm");
    }
}
