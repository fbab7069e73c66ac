//! Small test meshes written by the test itself in every input format.

use meshatlas::mesh::TriMesh;

/// A closed unit icosphere: 42 vertices, 80 triangles.
pub fn mesh() -> TriMesh {
    meshatlas::mesh::fixtures::icosphere(1)
}

pub const N_VERTICES: usize = 42;
pub const N_TRIANGLES: usize = 80;

fn tri(m: &TriMesh, f: usize) -> [usize; 3] {
    let t = m.triangles[f];
    [t[0].idx(), t[1].idx(), t[2].idx()]
}

/// ASCII STL (unwelded triangle soup, as every STL is).
pub fn stl_ascii(m: &TriMesh) -> Vec<u8> {
    let mut s = String::from("solid test\n");
    for f in 0..m.triangles.len() {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for v in tri(m, f) {
            let p = m.positions[v];
            s.push_str(&format!("      vertex {:?} {:?} {:?}\n", p.x, p.y, p.z));
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid test\n");
    s.into_bytes()
}

/// Binary STL (80-byte header that starts with "solid" on purpose).
pub fn stl_binary(m: &TriMesh) -> Vec<u8> {
    let mut b = Vec::new();
    let mut header = b"solid but binary".to_vec();
    header.resize(80, b' ');
    b.extend_from_slice(&header);
    b.extend_from_slice(&(m.triangles.len() as u32).to_le_bytes());
    for f in 0..m.triangles.len() {
        b.extend_from_slice(&[0u8; 12]);
        for v in tri(m, f) {
            let p = m.positions[v];
            for c in [p.x, p.y, p.z] {
                b.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 2]);
    }
    b
}

pub fn obj(m: &TriMesh) -> Vec<u8> {
    let mut s = String::from("# test\no sphere\n");
    for p in &m.positions {
        s.push_str(&format!("v {:?} {:?} {:?}\n", p.x, p.y, p.z));
    }
    for f in 0..m.triangles.len() {
        let [a, b, c] = tri(m, f);
        s.push_str(&format!("f {} {} {}\n", a + 1, b + 1, c + 1));
    }
    s.into_bytes()
}

pub fn ply_ascii(m: &TriMesh) -> Vec<u8> {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    );
    for p in &m.positions {
        s.push_str(&format!("{:?} {:?} {:?}\n", p.x, p.y, p.z));
    }
    for f in 0..m.triangles.len() {
        let [a, b, c] = tri(m, f);
        s.push_str(&format!("3 {a} {b} {c}\n"));
    }
    s.into_bytes()
}

pub fn ply_binary_le(m: &TriMesh) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    )
    .into_bytes();
    for p in &m.positions {
        for c in [p.x, p.y, p.z] {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for f in 0..m.triangles.len() {
        b.push(3);
        for v in tri(m, f) {
            b.extend_from_slice(&(v as i32).to_le_bytes());
        }
    }
    b
}

/// MSH 2.2 ASCII with a line element that the reader must skip.
pub fn msh22(m: &TriMesh) -> Vec<u8> {
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    s.push_str(&format!("{}\n", m.positions.len()));
    for (i, p) in m.positions.iter().enumerate() {
        s.push_str(&format!("{} {:?} {:?} {:?}\n", i + 1, p.x, p.y, p.z));
    }
    s.push_str("$EndNodes\n$Elements\n");
    s.push_str(&format!("{}\n", m.triangles.len() + 1));
    s.push_str("1 1 2 0 1 1 2\n");
    for f in 0..m.triangles.len() {
        let [a, b, c] = tri(m, f);
        s.push_str(&format!("{} 2 2 0 1 {} {} {}\n", f + 2, a + 1, b + 1, c + 1));
    }
    s.push_str("$EndElements\n");
    s.into_bytes()
}

/// MSH 4.1 written by our writer.
pub fn msh41(m: &TriMesh) -> Vec<u8> {
    let mut out = Vec::new();
    meshatlas::io::msh41::write::write_surface_msh41(&mut out, m).unwrap();
    out
}

/// A file of the shared test data (`../shared/data/` beside the repository).
pub fn shared_data(rel: &str) -> std::path::PathBuf {
    let beside = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data").join(rel);
    if beside.exists() { beside } else { std::path::Path::new("/work/shared/data").join(rel) }
}
