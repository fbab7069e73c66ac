//! Binary glTF 2.0 (`.glb`) of a coloured triangle surface and a point
//! set, for three.js, Blender and any glTF viewer.
//!
//! Layout: one node (translated to the bounding-box centre, so the `f32`
//! positions keep their precision on georeferenced coordinates) with one
//! mesh of up to two primitives:
//! - the surface, mode `TRIANGLES`: `POSITION` (`f32` VEC3, with the
//!   `min`/`max` the format requires), `COLOR_0` (normalized `u8` VEC4,
//!   linear RGB as glTF defines vertex colours) and `u32` indices; a vertex
//!   whose triangles have several colours is written once per colour, so a
//!   colour is exactly a triangle's (a patch's) and never blends across a
//!   patch boundary;
//! - the points, mode `POINTS`, with their own `POSITION` and `COLOR_0`
//!   (absent when there are none: glTF accessors cannot be empty).
//!
//! Both primitives use one double-sided, non-metallic material (glTF's
//! default material is fully metallic, which renders black in most
//! viewers). The file is a 12-byte header, the JSON chunk (padded with
//! spaces) and the binary chunk (padded with zeros), each 4-byte aligned.

use std::io::Write;

use foldhash::HashMap;
use serde_json::{Value, json};

use crate::geom::{BoundingBox, Vec3};
use crate::mesh::VertexId;

use super::write_error::WriteError;

/// `glTF` magic of the file header.
const MAGIC: u32 = 0x4654_6C67;
/// Type of the JSON chunk.
const CHUNK_JSON: u32 = 0x4E4F_534A;
/// Type of the binary chunk.
const CHUNK_BIN: u32 = 0x004E_4942;
/// Buffer-view targets and accessor component types of glTF.
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_INT: u32 = 5125;

/// What a `.glb` holds.
#[derive(Debug, Clone, Copy)]
pub struct GlbScene<'a> {
    /// Vertex positions of the surface.
    pub positions: &'a [Vec3],
    /// Its triangles.
    pub triangles: &'a [[VertexId; 3]],
    /// sRGB colour of each triangle (one colour for all when `None`).
    pub face_colors: Option<&'a [[u8; 3]]>,
    /// Points (position, sRGB colour), drawn as a `POINTS` primitive.
    pub points: &'a [(Vec3, [u8; 3])],
}

/// Colour of the surface when no per-triangle colour is given.
const PLAIN: [u8; 3] = [200, 200, 205];

/// The linear value of an sRGB-encoded channel (glTF vertex colours are linear).
fn srgb_to_linear(c: u8) -> u8 {
    let s = f64::from(c) / 255.0;
    let l = if s <= 0.04045 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) };
    (l * 255.0).round() as u8
}

/// The binary chunk under construction and the buffer views cut from it.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
}

impl Bin {
    /// Appends `data` as a new buffer view (4-byte aligned) for `target`;
    /// returns its index.
    fn view(&mut self, data: &[u8], target: u32) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(data);
        self.views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len(), "target": target}));
        self.views.len() - 1
    }
}

/// Positions, linear RGBA colours and triangles of the written surface.
type SplitVertices = (Vec<[f32; 3]>, Vec<[u8; 4]>, Vec<[u32; 3]>);

/// The vertices of `scene` split by colour: positions relative to `origin`,
/// linear RGBA colours, and the triangles renumbered into them (in
/// first-use order, so the output is deterministic). A vertex's first
/// colour is found in an array; only the few vertices on a patch boundary
/// reach the hash map of further colours.
fn split_by_color(scene: &GlbScene, origin: &Vec3) -> SplitVertices {
    let n = scene.positions.len();
    let mut first: Vec<(u32, [u8; 3])> = vec![(u32::MAX, [0; 3]); n];
    let mut more: HashMap<(u32, [u8; 3]), u32> = HashMap::default();
    let (mut pos, mut col, mut tris) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::new());
    tris.reserve(scene.triangles.len());
    let mut add = |v: usize, c: [u8; 3]| {
        let p = scene.positions[v] - origin;
        pos.push([p.x as f32, p.y as f32, p.z as f32]);
        let [r, g, b] = c.map(srgb_to_linear);
        col.push([r, g, b, 255]);
        (pos.len() - 1) as u32
    };
    for (f, t) in scene.triangles.iter().enumerate() {
        let c = scene.face_colors.map_or(PLAIN, |cs| cs[f]);
        tris.push(t.map(|v| match first[v.idx()] {
            (u32::MAX, _) => {
                let i = add(v.idx(), c);
                first[v.idx()] = (i, c);
                i
            }
            (i, fc) if fc == c => i,
            _ => *more.entry((v.0, c)).or_insert_with(|| add(v.idx(), c)),
        }));
    }
    (pos, col, tris)
}

/// Accessors of positions (with bounds) and colours; returns their indices.
fn vertex_accessors(bin: &mut Bin, accessors: &mut Vec<Value>, pos: &[[f32; 3]], col: &[[u8; 4]]) -> (usize, usize) {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in pos {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    let pos_bytes: Vec<u8> = pos.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    let v = bin.view(&pos_bytes, ARRAY_BUFFER);
    accessors.push(json!({"bufferView": v, "componentType": FLOAT, "count": pos.len(), "type": "VEC3",
        "min": lo, "max": hi}));
    let col_bytes: Vec<u8> = col.iter().flatten().copied().collect();
    let v = bin.view(&col_bytes, ARRAY_BUFFER);
    accessors.push(json!({"bufferView": v, "componentType": UNSIGNED_BYTE, "normalized": true,
        "count": col.len(), "type": "VEC4"}));
    (accessors.len() - 2, accessors.len() - 1)
}

/// Checks what the writer needs before anything is written.
fn validate(scene: &GlbScene) -> Result<(), WriteError> {
    if scene.triangles.is_empty() {
        return Err(WriteError::Invalid("a glTF surface needs at least one triangle".into()));
    }
    if let Some(cs) = scene.face_colors
        && cs.len() != scene.triangles.len()
    {
        return Err(WriteError::LengthMismatch {
            what: "face colours".into(),
            expected: scene.triangles.len(),
            got: cs.len(),
        });
    }
    let n = scene.positions.len();
    if let Some(v) = scene.triangles.iter().flatten().find(|v| v.idx() >= n) {
        return Err(WriteError::IndexOutOfRange { what: "a glTF triangle".into(), index: u64::from(v.0), n_points: n });
    }
    let all = scene.positions.iter().chain(scene.points.iter().map(|(p, _)| p));
    if let Some(p) = all.into_iter().find(|p| !p.iter().all(|x| x.is_finite())) {
        return Err(WriteError::NonFiniteCoordinate { what: "a glTF vertex".into(), x: p.x, y: p.y, z: p.z });
    }
    Ok(())
}

/// Writes `scene` as a binary glTF 2.0 file.
///
/// # Errors
/// [`WriteError`] for a scene without triangles, colours that do not match
/// the triangles, an index out of range or a non-finite coordinate (nothing
/// written), or the writer's I/O error.
pub fn write_glb(mut w: impl Write, scene: &GlbScene) -> Result<(), WriteError> {
    validate(scene)?;
    let origin = BoundingBox::of_points(scene.positions).map_or_else(Vec3::zeros, |b| b.center());
    let (pos, col, tris) = split_by_color(scene, &origin);
    let mut bin = Bin::default();
    let mut accessors = Vec::new();
    let (p, c) = vertex_accessors(&mut bin, &mut accessors, &pos, &col);
    let idx_bytes: Vec<u8> = tris.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
    let v = bin.view(&idx_bytes, ELEMENT_ARRAY_BUFFER);
    accessors.push(json!({"bufferView": v, "componentType": UNSIGNED_INT, "count": 3 * tris.len(),
        "type": "SCALAR", "max": [pos.len() - 1], "min": [0]}));
    let mut primitives = vec![json!({"attributes": {"POSITION": p, "COLOR_0": c}, "indices": accessors.len() - 1,
        "mode": 4, "material": 0})];
    if !scene.points.is_empty() {
        let ppos: Vec<[f32; 3]> = scene
            .points
            .iter()
            .map(|(q, _)| {
                let d = q - origin;
                [d.x as f32, d.y as f32, d.z as f32]
            })
            .collect();
        let pcol: Vec<[u8; 4]> = scene
            .points
            .iter()
            .map(|(_, c)| {
                let [r, g, b] = c.map(srgb_to_linear);
                [r, g, b, 255]
            })
            .collect();
        let (p, c) = vertex_accessors(&mut bin, &mut accessors, &ppos, &pcol);
        primitives.push(json!({"attributes": {"POSITION": p, "COLOR_0": c}, "mode": 0, "material": 0}));
    }
    while !bin.bytes.len().is_multiple_of(4) {
        bin.bytes.push(0);
    }
    let doc = json!({
        "asset": {"version": "2.0", "generator": concat!("meshatlas ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "surface", "translation": [origin.x, origin.y, origin.z]}],
        "meshes": [{"name": "surface", "primitives": primitives}],
        "materials": [{"name": "vertex colours", "doubleSided": true,
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
                "roughnessFactor": 0.8}}],
        "accessors": accessors,
        "bufferViews": bin.views,
        "buffers": [{"byteLength": bin.bytes.len()}],
    });
    let mut text = serde_json::to_vec(&doc).map_err(|e| WriteError::Invalid(e.to_string()))?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bin.bytes.len();
    let total = u32::try_from(total).map_err(|_| WriteError::Invalid(format!("a {total}-byte glTF exceeds 4 GiB")))?;
    for word in [MAGIC, 2, total, text.len() as u32, CHUNK_JSON] {
        w.write_all(&word.to_le_bytes())?;
    }
    w.write_all(&text)?;
    for word in [bin.bytes.len() as u32, CHUNK_BIN] {
        w.write_all(&word.to_le_bytes())?;
    }
    w.write_all(&bin.bytes)?;
    w.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn a_vertex_is_split_once_per_colour_of_its_triangles() {
        let square = fixtures::square(1);
        let colors = vec![[255, 0, 0], [0, 0, 255]];
        let scene = GlbScene {
            positions: &square.positions,
            triangles: &square.triangles,
            face_colors: Some(&colors),
            points: &[],
        };
        let (pos, col, tris) = split_by_color(&scene, &Vec3::zeros());
        // Two triangles share an edge: its two vertices appear in both colours.
        assert_eq!(pos.len(), 6);
        assert_eq!(col.iter().filter(|c| c[0] == 255).count(), 3);
        assert!(tris.iter().flatten().all(|&i| (i as usize) < pos.len()));
    }

    #[test]
    fn the_file_has_aligned_chunks_and_its_stated_length() {
        let cube = fixtures::cube(2);
        let points = [(Vec3::new(1.0, 1.0, 1.0), [0, 0, 255])];
        let scene =
            GlbScene { positions: &cube.positions, triangles: &cube.triangles, face_colors: None, points: &points };
        let mut out = Vec::new();
        write_glb(&mut out, &scene).unwrap();
        let word = |i: usize| u32::from_le_bytes(out[i..i + 4].try_into().unwrap()) as usize;
        assert_eq!(word(0), MAGIC as usize);
        assert_eq!(word(8), out.len());
        let json_len = word(12);
        assert_eq!(json_len % 4, 0);
        assert_eq!(word(16), CHUNK_JSON as usize);
        assert_eq!(word(20 + json_len + 4), CHUNK_BIN as usize);
        assert_eq!(20 + json_len + 8 + word(20 + json_len), out.len());
    }

    #[test]
    fn an_empty_surface_or_a_bad_index_is_refused_before_writing() {
        let empty = GlbScene { positions: &[], triangles: &[], face_colors: None, points: &[] };
        let mut out = Vec::new();
        assert!(write_glb(&mut out, &empty).is_err());
        let tri = [[VertexId(0), VertexId(1), VertexId(5)]];
        let p = [Vec3::zeros(), Vec3::x(), Vec3::y()];
        let bad = GlbScene { positions: &p, triangles: &tri, face_colors: None, points: &[] };
        assert!(matches!(write_glb(&mut out, &bad), Err(WriteError::IndexOutOfRange { .. })));
        assert!(out.is_empty());
    }

    #[test]
    fn srgb_maps_to_linear_at_its_ends_and_midpoint() {
        assert_eq!(srgb_to_linear(0), 0);
        assert_eq!(srgb_to_linear(255), 255);
        assert_eq!(srgb_to_linear(188), 128);
    }
}
