//! Helpers for the crossfield tests and the benchmark example: loading the
//! shared meshes with the crate's own reader (`io::load_path`: weld, repair,
//! consistent orientation).
#![allow(dead_code)]

use meshatlas::io::{LoadOptions, load_path};
use meshatlas::mesh::TriMesh;
use std::path::{Path, PathBuf};

/// Load a mesh file (STL, OBJ, PLY, MSH) as a repaired, oriented surface.
pub fn load(path: &Path) -> TriMesh {
    load_path(path, None, &LoadOptions::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display())).surface
}

/// A file of the shared data directory: `../shared/data` next to the
/// repository (CI) or `/work/shared/data`.
pub fn data_path(rel: &str) -> Option<PathBuf> {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    [here.join("../shared/data").join(rel), Path::new("/work/shared/data").join(rel)].into_iter().find(|p| p.exists())
}
