//! Test-only helpers for the crossfield tests: a minimal STL reader (exact
//! weld) and a minimal OBJ reader, used until `crate::io::load_path` lands.
#![allow(dead_code)]

use meshatlas::geom::Vec3;
use meshatlas::mesh::TriMesh;
use std::collections::HashMap;
use std::path::Path;

/// Read an STL file (ASCII or binary, told apart by the size check
/// `84 + 50 n`) and weld bitwise-equal corners.
pub fn read_stl(path: &Path) -> TriMesh {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut corners: Vec<[f64; 3]> = Vec::new();
    let binary = bytes.len() >= 84 && {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        bytes.len() == 84 + 50 * n
    };
    if binary {
        let n = (bytes.len() - 84) / 50;
        for t in 0..n {
            let base = 84 + 50 * t + 12;
            for c in 0..3 {
                let mut p = [0.0; 3];
                for (k, x) in p.iter_mut().enumerate() {
                    let o = base + 12 * c + 4 * k;
                    *x = f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]])
                        as f64;
                }
                corners.push(p);
            }
        }
    } else {
        let text = String::from_utf8_lossy(&bytes);
        for line in text.lines() {
            let mut it = line.split_whitespace();
            if it.next() == Some("vertex") {
                let p: Vec<f64> = it.map(|s| s.parse().expect("coordinate")).collect();
                corners.push([p[0], p[1], p[2]]);
            }
        }
    }
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut tris = Vec::new();
    for c in corners.chunks(3) {
        let mut t = [0u32; 3];
        for (k, p) in c.iter().enumerate() {
            let key = p.map(|x| (x + 0.0).to_bits());
            t[k] = *index.entry(key).or_insert_with(|| {
                positions.push(Vec3::new(p[0], p[1], p[2]));
                (positions.len() - 1) as u32
            });
        }
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            tris.push(t);
        }
    }
    TriMesh::from_raw(positions, &tris)
}

/// Read the `v` and `f` lines of an OBJ file (polygons fanned).
pub fn read_obj(path: &Path) -> TriMesh {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut positions = Vec::new();
    let mut tris = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let p: Vec<f64> = it.take(3).map(|s| s.parse().expect("coordinate")).collect();
                positions.push(Vec3::new(p[0], p[1], p[2]));
            }
            Some("f") => {
                let idx: Vec<u32> = it
                    .map(|s| s.split('/').next().unwrap().parse::<u32>().expect("index") - 1)
                    .collect();
                for k in 1..idx.len() - 1 {
                    tris.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    TriMesh::from_raw(positions, &tris)
}

/// `/work/shared/data/...` or the `shared/` directory next to the repository (CI).
pub fn data_path(rel: &str) -> Option<std::path::PathBuf> {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    [
        here.join("../shared/data").join(rel),
        Path::new("/work/shared/data").join(rel),
    ]
    .into_iter()
    .find(|p| p.exists())
}
