//! The frame-field artifacts `frames.vtu` and `frames_singular.vtu` read back
//! by meshio (an independent reader) with the documented array names,
//! shapes and values.

mod common;

use meshatlas::frames::{FramesOptions, compute_frame_field, write_frames_vtu, write_singular_edges_vtu};
use meshatlas::mesh::fixtures;
use meshatlas::progress::Progress;

#[test]
fn frames_artifacts_are_read_by_meshio() {
    let field = compute_frame_field(
        &fixtures::icosphere(2),
        None,
        &FramesOptions { target_size: Some(0.25), ..Default::default() },
        &Progress::none(),
    )
    .unwrap();
    assert!(!field.singular_edges.is_empty());
    let dir = common::scratch("frames_vtu", "ball");
    let (f1, f2) = (dir.join("frames.vtu"), dir.join("frames_singular.vtu"));
    write_frames_vtu(&field, std::fs::File::create(&f1).unwrap()).unwrap();
    write_singular_edges_vtu(&field, std::fs::File::create(&f2).unwrap()).unwrap();
    let script = r#"
m = meshio.read(sys.argv[1])
s = meshio.read(sys.argv[2])
pd = {k: list(np.asarray(v).shape) for k, v in m.point_data.items()}
fx = np.asarray(m.point_data['frame_x'])
q = np.asarray(m.point_data['quaternion'])
h0 = np.asarray(m.point_data['h0'])
print(json.dumps({
  'n_points': len(m.points), 'cells': [[b.type, len(b.data)] for b in m.cells], 'point_data': pd,
  'cell_data': {k: [list(np.asarray(a).shape) for a in v] for k, v in m.cell_data.items()},
  'fx0': fx[0].tolist(), 'q0': q[0].tolist(), 'h00': h0[0].tolist(),
  'unit_axes': float(np.abs(np.linalg.norm(fx, axis=1) - 1).max()),
  's_cells': [[b.type, len(b.data)] for b in s.cells],
  'valence': sorted(set(int(x) for x in np.asarray(s.cell_data['valence'][0]).ravel())),
  's_points': len(s.points),
}))
"#;
    let out = common::python(script, &[common::path_str(&f1), common::path_str(&f2)]);
    let nv = field.volume.n_vertices() as u64;
    assert_eq!(out["n_points"].as_u64(), Some(nv));
    assert_eq!(out["cells"][0][0], "tetra");
    assert_eq!(out["cells"][0][1].as_u64(), Some(field.volume.n_tets() as u64));
    for (name, k) in
        [("frame_x", 3), ("frame_y", 3), ("frame_z", 3), ("quaternion", 4), ("sh9", 9), ("h0", 2), ("h1", 2), ("h2", 2)]
    {
        assert_eq!(out["point_data"][name], serde_json::json!([nv, k]), "{name}");
    }
    assert_eq!(out["cell_data"]["tet_quaternion"], serde_json::json!([[field.volume.n_tets(), 4]]));
    assert!(out["unit_axes"].as_f64().unwrap() < 1e-12);
    let fx0: Vec<f64> = serde_json::from_value(out["fx0"].clone()).unwrap();
    let q0: Vec<f64> = serde_json::from_value(out["q0"].clone()).unwrap();
    let h00: Vec<f64> = serde_json::from_value(out["h00"].clone()).unwrap();
    // serde_json parses floats to within an ulp, not exactly.
    let close = |a: &[f64], b: &[f64]| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-14 * (1.0 + y.abs()))
    };
    let a = field.axes_per_vertex[0][0];
    assert!(close(&fx0, &[a.x, a.y, a.z]));
    assert!(close(&q0, &field.quaternion_per_vertex[0]));
    assert!(close(&h00, &[field.invariants_per_vertex[0][0].re, field.invariants_per_vertex[0][0].im]));
    assert_eq!(out["s_cells"][0][0], "line");
    assert_eq!(out["s_cells"][0][1].as_u64(), Some(field.singular_edges.len() as u64));
    let valence: Vec<i64> = serde_json::from_value(out["valence"].clone()).unwrap();
    assert!(valence.iter().all(|v| [0, 3, 5].contains(v)) && valence.contains(&3));
}
