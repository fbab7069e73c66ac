//! The load API: read a mesh in any supported format, then weld and repair
//! it into a valid, consistently oriented surface (and a volume mesh for MSH
//! files with tetrahedra), with a report of everything that was changed.
//!
//! Format choice ([`load_path`]): the explicit argument, else the file
//! extension, else content sniffing ([`Format::sniff`]).
//!
//! Volume meshes: tetrahedra of an MSH file become a [`TetMesh`] over the
//! nodes they use (file order), every tet oriented to positive volume
//! (corners 2 and 3 swapped when negative; tets repeating a node or of zero
//! volume are removed and counted). When the file has no triangles, the
//! surface is the boundary of the tets: the faces used by exactly one tet,
//! oriented outward (for a positive tet `[a, b, c, d]` the outward faces are
//! `[b, c, d]`, `[a, d, c]`, `[a, b, d]`, `[a, c, b]`). Surface and volume
//! share positions bit for bit but not vertex numbering.
//!
//! Counting conventions of [`RepairReport`] for MSH files: input vertices
//! are all nodes; unreferenced vertices are nodes used by no kept element
//! (triangle or tetrahedron) plus surface vertices orphaned by repair —
//! interior nodes of a volume are not "dropped", they live in the volume.

use super::source::{Limits, RawMesh};
use super::{Format, IoError, msh_common, obj, ply, stl};
use crate::mesh::repair::{RepairReport, repair_triangle_soup};
use crate::mesh::{TetId, TetMesh, TriMesh, VertexId};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::{BufRead, BufReader};
use std::path::Path;

/// Size of the read buffer for files (1 MiB).
const READ_BUFFER_BYTES: usize = 1 << 20;

/// Options of [`load_path`] / [`load_reader`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LoadOptions {
    /// Weld tolerance relative to the bounding-box diagonal; default 1e-6;
    /// 0 = exact weld only. Accepted range `[0, 0.01]`.
    pub weld_tolerance: f64,
    /// Maximum number of triangles accepted (after fan triangulation);
    /// default 5_000_000. Tetrahedra of a volume mesh are capped by the same
    /// number, vertices by `4 · max_triangles + 1024`.
    pub max_triangles: usize,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self { weld_tolerance: 1e-6, max_triangles: 5_000_000 }
    }
}

impl LoadOptions {
    /// Largest accepted relative weld tolerance.
    pub const MAX_WELD_TOLERANCE: f64 = 0.01;

    /// Check the ranges of the options.
    ///
    /// # Errors
    /// [`IoError::InvalidOptions`] naming the field.
    pub fn validate(&self) -> Result<(), IoError> {
        if !(self.weld_tolerance >= 0.0 && self.weld_tolerance <= Self::MAX_WELD_TOLERANCE) {
            return Err(IoError::InvalidOptions {
                option: "weld_tolerance",
                reason: format!("must be in [0, {}], got {}", Self::MAX_WELD_TOLERANCE, self.weld_tolerance),
            });
        }
        if self.max_triangles == 0 {
            return Err(IoError::InvalidOptions { option: "max_triangles", reason: "must be at least 1".into() });
        }
        Ok(())
    }

    /// The reading limits these options imply.
    pub fn limits(&self) -> Limits {
        Limits::from_max_triangles(self.max_triangles)
    }
}

/// A loaded, welded and repaired mesh.
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// The repaired surface: valid, consistently oriented per component,
    /// closed components outward.
    pub surface: TriMesh,
    /// The tetrahedral mesh of an MSH file with tetrahedra, all positive
    /// (`None` when the file has none, or none of non-zero volume).
    pub volume: Option<TetMesh>,
    /// What reading and repair did.
    pub repair: RepairReport,
    /// The format that was read.
    pub format: Format,
}

/// Load a mesh file: format from `format`, else the extension, else the content.
///
/// # Errors
/// [`IoError`]: unreadable file, unknown format, malformed content, limits,
/// no triangles.
pub fn load_path(path: &Path, format: Option<Format>, opts: &LoadOptions) -> Result<LoadedMesh, IoError> {
    opts.validate()?;
    let file = std::fs::File::open(path)?;
    let len = file.metadata()?.len();
    if len == 0 {
        return Err(IoError::EmptyFile);
    }
    let mut reader = BufReader::with_capacity(READ_BUFFER_BYTES, file);
    let ext = path.extension().and_then(|e| e.to_str());
    let format = match format.or_else(|| ext.and_then(Format::from_extension)) {
        Some(f) => f,
        None => {
            let head = reader.fill_buf()?;
            Format::sniff(head, Some(len)).ok_or_else(|| IoError::UnknownFormat {
                reason: format!(
                    "{} and the content is not recognised as STL, OBJ, PLY or MSH",
                    match ext {
                        Some(e) => format!("the extension `.{e}` is not one of stl, obj, ply, msh"),
                        None => "the file has no extension".to_string(),
                    }
                ),
            })?
        }
    };
    let raw = read_raw(reader, format, Some(len), &opts.limits())?;
    finish(raw, format, opts)
}

/// Load a mesh of a known format from a stream (size unknown).
///
/// # Errors
/// As [`load_path`].
pub fn load_reader<R: BufRead>(mut reader: R, format: Format, opts: &LoadOptions) -> Result<LoadedMesh, IoError> {
    opts.validate()?;
    if reader.fill_buf()?.is_empty() {
        return Err(IoError::EmptyFile);
    }
    let raw = read_raw(reader, format, None, &opts.limits())?;
    finish(raw, format, opts)
}

/// Load a mesh held in memory; `format` `None` sniffs the content.
///
/// # Errors
/// As [`load_path`].
pub fn load_bytes(bytes: &[u8], format: Option<Format>, opts: &LoadOptions) -> Result<LoadedMesh, IoError> {
    opts.validate()?;
    if bytes.is_empty() {
        return Err(IoError::EmptyFile);
    }
    let len = bytes.len() as u64;
    let format = match format {
        Some(f) => f,
        None => Format::sniff(&bytes[..bytes.len().min(4096)], Some(len)).ok_or_else(|| IoError::UnknownFormat {
            reason: "the content is not recognised as STL, OBJ, PLY or MSH".into(),
        })?,
    };
    let raw = read_raw(bytes, format, Some(len), &opts.limits())?;
    finish(raw, format, opts)
}

/// Run the reader of `format` (no welding or repair). `total_len` is the
/// size of the whole input when known (it decides ASCII vs binary STL).
///
/// # Errors
/// Every reader error.
pub fn read_raw<R: BufRead>(
    reader: R,
    format: Format,
    total_len: Option<u64>,
    limits: &Limits,
) -> Result<RawMesh, IoError> {
    match format {
        Format::Stl => stl::read(reader, total_len, limits),
        Format::Obj => obj::read(reader, limits),
        Format::Ply => ply::read(reader, total_len, limits),
        Format::Msh => msh_common::read(reader, limits),
    }
}

/// Build the volume (if any), then weld and repair the surface.
///
/// # Errors
/// [`IoError::NoTriangles`] when nothing is left to mesh.
pub fn finish(raw: RawMesh, format: Format, opts: &LoadOptions) -> Result<LoadedMesh, IoError> {
    let n_nodes = raw.positions.len();
    // The readers guarantee this; checked so that a reader bug is an error, not a panic.
    let max_index = raw.triangles.iter().flatten().chain(raw.tets.iter().flatten()).max();
    if let Some(&m) = max_index.filter(|&&m| m as usize >= n_nodes) {
        return Err(IoError::InvalidMesh { format, detail: format!("index {m} with {n_nodes} vertices") });
    }
    let mut used_by_tri = vec![false; n_nodes];
    let mut used_by_tet = vec![false; n_nodes];
    for t in &raw.triangles {
        t.iter().for_each(|&v| used_by_tri[v as usize] = true);
    }
    for t in &raw.tets {
        t.iter().for_each(|&v| used_by_tet[v as usize] = true);
    }
    let n_unused_in_file = (0..n_nodes).filter(|&v| !used_by_tri[v] && !used_by_tet[v]).count();

    let volume = (!raw.tets.is_empty()).then(|| tet_mesh(&raw.positions, &raw.tets));
    let from_boundary = raw.triangles.is_empty();
    if from_boundary && volume.is_none() {
        return Err(IoError::NoTriangles { format, detail: describe_contents(&raw) });
    }
    let RawMesh { positions, triangles, skipped, n_polygons_triangulated, .. } = raw;
    let (positions, triangles, n_volume_only) = match &volume {
        Some((vol, _)) if from_boundary => {
            let faces = tet_boundary(vol);
            let mut on_boundary = vec![false; vol.n_vertices()];
            faces.iter().flatten().for_each(|&v| on_boundary[v as usize] = true);
            let interior = on_boundary.iter().filter(|&&b| !b).count();
            (vol.positions.clone(), faces, interior)
        }
        _ => {
            let tet_only = (0..n_nodes).filter(|&v| used_by_tet[v] && !used_by_tri[v]).count();
            (positions, triangles, tet_only)
        }
    };
    let n_input_triangles = triangles.len();
    let (surface, mut report) = repair_triangle_soup(positions, triangles, opts.weld_tolerance)
        .map_err(|e| IoError::InvalidMesh { format, detail: e.to_string() })?;
    if surface.n_faces() == 0 {
        return Err(IoError::NoTriangles {
            format,
            detail: format!(
                "all {n_input_triangles} triangles were removed by repair ({} repeat a vertex after welding, {} have zero area, {} are duplicates)",
                report.n_degenerate_triangles_removed,
                report.n_zero_area_triangles_removed,
                report.n_duplicate_triangles_removed
            ),
        });
    }
    // Interior volume nodes are not "dropped"; nodes no element uses are.
    if from_boundary {
        report.n_unreferenced_vertices_dropped =
            report.n_unreferenced_vertices_dropped.saturating_sub(n_volume_only) + n_unused_in_file;
    } else {
        report.n_unreferenced_vertices_dropped = report.n_unreferenced_vertices_dropped.saturating_sub(n_volume_only);
    }
    report.n_input_vertices = n_nodes;
    report.n_input_triangles = n_input_triangles;
    report.skipped_elements = skipped;
    report.n_polygons_fan_triangulated = n_polygons_triangulated;
    report.surface_from_volume_boundary = from_boundary;
    let volume = volume.and_then(|(vol, stats)| {
        report.n_tets = vol.n_tets();
        report.n_tets_reoriented = stats.n_reoriented;
        report.n_degenerate_tets_removed = stats.n_degenerate;
        (vol.n_tets() > 0).then_some(vol)
    });
    Ok(LoadedMesh { surface, volume, repair: report, format })
}

/// What [`tet_mesh`] changed.
#[derive(Debug, Clone, Copy, Default)]
struct TetStats {
    n_reoriented: usize,
    n_degenerate: usize,
}

/// The tetrahedral mesh over the nodes the tets use, all positively oriented.
fn tet_mesh(positions: &[crate::geom::Vec3], tets: &[[u32; 4]]) -> (TetMesh, TetStats) {
    let mut used = vec![false; positions.len()];
    tets.iter().flatten().for_each(|&v| used[v as usize] = true);
    let mut new_id = vec![u32::MAX; positions.len()];
    let mut vol = TetMesh::default();
    for (v, p) in positions.iter().enumerate() {
        if used[v] {
            new_id[v] = vol.positions.len() as u32;
            vol.positions.push(*p);
        }
    }
    let mut stats = TetStats::default();
    vol.tets = tets
        .iter()
        .map(|t| t.map(|v| VertexId(new_id[v as usize])))
        .filter(|t| (0..4).all(|i| !t[i + 1..].contains(&t[i])))
        .collect();
    stats.n_degenerate = tets.len() - vol.tets.len();
    let before = vol.tets.len();
    let keep: Vec<bool> = (0..vol.n_tets())
        .map(|t| {
            let v = vol.signed_volume6(TetId::new(t));
            v != 0.0 && v.is_finite()
        })
        .collect();
    let mut k = keep.iter();
    vol.tets.retain(|_| *k.next().unwrap_or(&false));
    stats.n_degenerate += before - vol.tets.len();
    stats.n_reoriented = vol.orient_positive();
    // Nodes used only by removed tets stay: harmless for the volume, and rare.
    debug_assert!(vol.validate().is_ok());
    (vol, stats)
}

/// Faces used by exactly one tet, oriented outward (see the module doc).
fn tet_boundary(vol: &TetMesh) -> Vec<[u32; 3]> {
    const LOCAL: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    let mut keys: Vec<([u32; 3], u32)> = Vec::with_capacity(4 * vol.n_tets());
    for (t, tet) in vol.tets.iter().enumerate() {
        for (l, loc) in LOCAL.iter().enumerate() {
            let mut k = loc.map(|i| tet[i].0);
            k.sort_unstable();
            keys.push((k, (4 * t + l) as u32));
        }
    }
    keys.par_sort_unstable();
    let mut is_boundary = vec![false; keys.len()];
    let mut i = 0;
    while i < keys.len() {
        let mut j = i + 1;
        while j < keys.len() && keys[j].0 == keys[i].0 {
            j += 1;
        }
        if j - i == 1 {
            is_boundary[keys[i].1 as usize] = true;
        }
        i = j;
    }
    is_boundary
        .iter()
        .enumerate()
        .filter(|(_, b)| **b)
        .map(|(f, _)| LOCAL[f % 4].map(|i| vol.tets[f / 4][i].0))
        .collect()
}

/// "N vertices and no triangles or tetrahedra (skipped: …)".
fn describe_contents(raw: &RawMesh) -> String {
    let mut s = format!("the file has {} vertices and no triangles or tetrahedra", raw.positions.len());
    if !raw.skipped.is_empty() {
        let parts: Vec<String> = raw.skipped.iter().map(|(k, v)| format!("{v} × {k}")).collect();
        s.push_str(&format!(" (skipped: {})", parts.join(", ")));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::failure::FailureKind;
    use crate::mesh::fixtures;

    fn ascii_stl(m: &TriMesh) -> String {
        let mut s = String::from("solid x\n");
        for t in &m.triangles {
            s.push_str("facet normal 0 0 0\nouter loop\n");
            for v in t {
                let p = m.positions[v.idx()];
                s.push_str(&format!("vertex {:?} {:?} {:?}\n", p.x, p.y, p.z));
            }
            s.push_str("endloop\nendfacet\n");
        }
        s + "endsolid x\n"
    }

    #[test]
    fn stl_end_to_end_welds_and_orients() {
        let m = fixtures::torus(1.0, 0.3, 16, 8);
        let text = ascii_stl(&m);
        let l = load_reader(text.as_bytes(), Format::Stl, &LoadOptions::default()).unwrap();
        assert_eq!(l.surface.n_vertices(), m.n_vertices());
        assert_eq!(l.surface.n_faces(), m.n_faces());
        assert_eq!(l.repair.n_input_vertices, 3 * m.n_faces());
        assert_eq!(l.repair.genus, Some(1));
        assert!(l.repair.closed);
        assert_eq!(l.format, Format::Stl);
        let b = load_bytes(text.as_bytes(), None, &LoadOptions::default()).unwrap();
        assert_eq!(b.surface, l.surface);
    }

    #[test]
    fn options_are_validated_and_deserialized_strictly() {
        let o: LoadOptions = serde_json::from_str(r#"{"weld_tolerance": 0}"#).unwrap();
        assert_eq!((o.weld_tolerance, o.max_triangles), (0.0, 5_000_000));
        assert!(serde_json::from_str::<LoadOptions>(r#"{"weld": 1}"#).is_err());
        for bad in [
            LoadOptions { weld_tolerance: -1.0, ..Default::default() },
            LoadOptions { weld_tolerance: f64::NAN, ..Default::default() },
            LoadOptions { max_triangles: 0, ..Default::default() },
        ] {
            assert_eq!(load_bytes(b"x", Some(Format::Obj), &bad).unwrap_err().kind(), FailureKind::InvalidOptions);
        }
    }

    #[test]
    fn empty_and_meshless_inputs() {
        let o = LoadOptions::default();
        assert_eq!(load_bytes(b"", None, &o).unwrap_err().kind(), FailureKind::EmptyFile);
        assert_eq!(load_reader(&b""[..], Format::Ply, &o).unwrap_err().kind(), FailureKind::EmptyFile);
        assert_eq!(load_bytes(b"hello", None, &o).unwrap_err().kind(), FailureKind::UnknownFormat);
        let e = load_bytes(b"v 0 0 0\nv 1 0 0\nl 1 2\n", None, &o).unwrap_err();
        assert_eq!(e.kind(), FailureKind::NoTriangles);
        assert!(e.to_string().contains("2 vertices") && e.to_string().contains("1 × line"), "{e}");
        let e = load_bytes(b"v 0 0 0\nv 1 0 0\nf 1 2 2\n", None, &o).unwrap_err();
        assert_eq!(e.kind(), FailureKind::NoTriangles);
        assert!(e.to_string().contains("1 repeat a vertex"), "{e}");
    }

    /// A tet mesh of the unit cube (6 tets around the diagonal), some inverted.
    fn cube_tets_msh(with_triangles: bool) -> String {
        let p = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]];
        let tets = [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]];
        let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n9\n");
        for (i, q) in p.iter().enumerate() {
            s.push_str(&format!("{} {} {} {}\n", i + 1, q[0], q[1], q[2]));
        }
        s.push_str("99 5 5 5\n");
        let n = tets.len() + usize::from(with_triangles);
        s.push_str(&format!("$EndNodes\n$Elements\n{n}\n"));
        for (i, t) in tets.iter().enumerate() {
            // Invert every other tet.
            let t = if i % 2 == 1 { [t[0], t[1], t[3], t[2]] } else { *t };
            s.push_str(&format!("{} 4 2 0 1 {} {} {} {}\n", i + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1));
        }
        if with_triangles {
            s.push_str("100 2 2 0 1 1 2 3\n");
        }
        s + "$EndElements\n"
    }

    #[test]
    fn tet_only_msh_gives_outward_boundary_and_positive_volume() {
        let l = load_bytes(cube_tets_msh(false).as_bytes(), None, &LoadOptions::default()).unwrap();
        let vol = l.volume.as_ref().unwrap();
        assert_eq!(vol.n_tets(), 6);
        assert!(vol.validate().is_ok());
        assert!((vol.volume() - 1.0).abs() < 1e-12);
        // The Kuhn tets above are all positive before the inversion of every other one.
        assert_eq!(l.repair.n_tets_reoriented, 3);
        assert_eq!(l.surface.n_faces(), 12);
        assert_eq!(l.surface.n_vertices(), 8);
        assert!((l.surface.signed_volume() - 1.0).abs() < 1e-12);
        assert_eq!(l.repair.n_components_reversed_outward, 0);
        assert_eq!(l.repair.n_triangles_flipped, 0);
        assert!(l.repair.surface_from_volume_boundary && l.repair.closed);
        assert_eq!(l.repair.n_unreferenced_vertices_dropped, 1); // node 99
        assert_eq!(l.repair.n_input_vertices, 9);

        let l = load_bytes(cube_tets_msh(true).as_bytes(), None, &LoadOptions::default()).unwrap();
        assert_eq!(l.surface.n_faces(), 1);
        assert_eq!(l.volume.unwrap().n_tets(), 6);
        assert_eq!(l.repair.n_unreferenced_vertices_dropped, 1);
        assert!(!l.repair.surface_from_volume_boundary);
    }
}
