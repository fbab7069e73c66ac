//! MSH 4.1 writer (ASCII, or binary with `binary: true`) for [`MshModel`].
//!
//! Sections, in the order Gmsh itself writes them (Gmsh's reader stops its
//! mesh pass at the first data section, so views must come last):
//! `$MeshFormat`, `$PhysicalNames` (when named), `$Entities`, `$Nodes`,
//! `$Elements`, `$Parametrizations` (when present), `$NodeData`,
//! `$ElementData`. Node and element blocks are written with their tags
//! sorted (their arrays permuted alike); the header's tag range is the
//! model's. Floats use the shortest text that parses back to the same
//! `f64` (Gmsh writes `%.16g`, which can lose the last bit).
//!
//! The model is validated in full ([`MshModel::validate`]) before the first
//! byte is written. The long runs of rows (node tags and coordinates,
//! elements, parametrization points and triangles, data entries) are
//! formatted in parallel in fixed-size chunks and written in order
//! ([`write_rows_par`]), so the bytes do not depend on the number of
//! threads; the rest is buffered in 64 KiB chunks. Pass the `File` itself, no
//! `BufWriter` needed.
//!
//! Binary layout (MSH 4.1, `size_t` = 8 bytes, little endian): counts and
//! node/element tags are `size_t`, entity tags, dimensions, types and
//! physical tags `int`, coordinates `double`; data sections keep their
//! ASCII string/real/integer tag header and store `int tag, double values…`
//! per entry, as Gmsh and meshio read them.

use super::model::{DataView, ElementBlock, ModelIndex, MshModel, NodeBlock};
use crate::io::text_out::{CHUNK, push_f64, push_i64, push_u64, write_rows_par};
use crate::io::write_error::WriteError;
use crate::mesh::{TetMesh, TriMesh};
use serde::{Deserialize, Serialize};
use std::io::Write;

/// Options of [`write_msh41`].
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Msh41Options {
    /// Write the binary variant (about 2× smaller, 5–10× faster to read).
    /// Default `false` (ASCII).
    pub binary: bool,
}

/// Write `model` as MSH 4.1 to `w`.
///
/// # Errors
/// A validation error (nothing written) or [`WriteError::Io`].
pub fn write_msh41(w: impl Write, model: &MshModel, opts: &Msh41Options) -> Result<(), WriteError> {
    let index = model.index()?;
    if opts.binary {
        // Gmsh and meshio read the entry tag of a binary data section as an `int`.
        let too_big = model
            .node_data
            .iter()
            .chain(&model.element_data)
            .flat_map(|v| v.tags.iter())
            .find(|&&t| t > i32::MAX as u64);
        if let Some(&tag) = too_big {
            return Err(WriteError::TooLarge {
                what: "tag in a binary data section",
                count: tag as usize,
                max: i32::MAX as u64,
            });
        }
    }
    let mut out = Out::new(w, Enc { binary: opts.binary });
    out.text(if opts.binary { "$MeshFormat\n4.1 1 8\n" } else { "$MeshFormat\n4.1 0 8\n" });
    if opts.binary {
        out.buf.extend_from_slice(&1i32.to_le_bytes());
        out.text("\n");
    }
    out.text("$EndMeshFormat\n");
    write_physical_names(&mut out, model)?;
    write_entities(&mut out, model, &index)?;
    write_nodes(&mut out, model, &index)?;
    write_elements(&mut out, model)?;
    write_parametrizations(&mut out, model)?;
    for v in &model.node_data {
        write_view(&mut out, "NodeData", v)?;
    }
    for v in &model.element_data {
        write_view(&mut out, "ElementData", v)?;
    }
    out.finish()
}

/// Write `mesh` as one discrete surface (see [`MshModel::from_surface`]), ASCII.
///
/// # Errors
/// A validation error (non-finite coordinate, out-of-range vertex) or [`WriteError::Io`].
pub fn write_surface_msh41(w: impl Write, mesh: &TriMesh) -> Result<(), WriteError> {
    write_msh41(w, &MshModel::from_surface(mesh), &Msh41Options::default())
}

/// Write `mesh` as one discrete volume (see [`MshModel::from_volume`]), ASCII.
///
/// # Errors
/// A validation error (non-finite coordinate, out-of-range vertex) or [`WriteError::Io`].
pub fn write_volume_msh41(w: impl Write, mesh: &TetMesh) -> Result<(), WriteError> {
    write_msh41(w, &MshModel::from_volume(mesh), &Msh41Options::default())
}

/// Token encoder: ASCII tokens followed by a space (a line end replaces the
/// last one), or little-endian binary words. `Copy`, so that the parallel
/// row formatters each use it on their own buffer.
#[derive(Debug, Clone, Copy)]
struct Enc {
    binary: bool,
}

impl Enc {
    /// A `size_t` count or node/element tag.
    #[inline]
    fn size(self, buf: &mut Vec<u8>, x: u64) {
        if self.binary {
            buf.extend_from_slice(&x.to_le_bytes());
        } else {
            push_u64(buf, x);
            buf.push(b' ');
        }
    }

    /// An `int` (entity tag, dimension, type, physical tag).
    #[inline]
    fn int(self, buf: &mut Vec<u8>, x: i32) {
        if self.binary {
            buf.extend_from_slice(&x.to_le_bytes());
        } else {
            push_i64(buf, i64::from(x));
            buf.push(b' ');
        }
    }

    /// A `double`.
    #[inline]
    fn real(self, buf: &mut Vec<u8>, x: f64) {
        if self.binary {
            buf.extend_from_slice(&x.to_le_bytes());
        } else {
            push_f64(buf, x);
            buf.push(b' ');
        }
    }

    /// End an ASCII line (no-op in binary): the last space becomes `\n`.
    #[inline]
    fn eol(self, buf: &mut Vec<u8>) {
        if !self.binary {
            if buf.last() == Some(&b' ') {
                buf.pop();
            }
            buf.push(b'\n');
        }
    }
}

/// Token emitter into `w` through a 64 KiB buffer, with [`Out::rows`] for
/// the long runs of rows.
struct Out<W: Write> {
    w: W,
    buf: Vec<u8>,
    enc: Enc,
    binary: bool,
}

impl<W: Write> Out<W> {
    fn new(w: W, enc: Enc) -> Self {
        Self { w, buf: Vec::with_capacity(CHUNK + 4096), enc, binary: enc.binary }
    }

    /// Raw text, in both modes (section markers, data headers).
    fn text(&mut self, s: &str) {
        self.buf.extend_from_slice(s.as_bytes());
    }

    /// A `size_t` count or node/element tag.
    fn size(&mut self, x: u64) {
        self.enc.size(&mut self.buf, x);
    }

    /// An `int` (entity tag, dimension, type, physical tag).
    fn int(&mut self, x: i32) {
        self.enc.int(&mut self.buf, x);
    }

    /// A `double`.
    fn real(&mut self, x: f64) {
        self.enc.real(&mut self.buf, x);
    }

    /// End an ASCII line (no-op in binary); flushes a full buffer.
    fn line(&mut self) -> std::io::Result<()> {
        self.enc.eol(&mut self.buf);
        self.flush_if_full()
    }

    /// Rows `0..n`, each written by `row(enc, buf, i)` and ended by a line
    /// break (ASCII), formatted in parallel ([`write_rows_par`]).
    fn rows(&mut self, n: usize, row: impl Fn(Enc, &mut Vec<u8>, usize) + Sync) -> std::io::Result<()> {
        self.w.write_all(&self.buf)?;
        self.buf.clear();
        let enc = self.enc;
        write_rows_par(&mut self.w, n, |buf, i| {
            row(enc, buf, i);
            enc.eol(buf);
        })
    }

    fn flush_if_full(&mut self) -> std::io::Result<()> {
        if self.buf.len() >= CHUNK {
            self.w.write_all(&self.buf)?;
            self.buf.clear();
        }
        Ok(())
    }

    /// Close a section (binary data is followed by a line break first).
    fn end(&mut self, name: &str) -> std::io::Result<()> {
        if self.binary {
            self.buf.push(b'\n');
        }
        self.text("$End");
        self.text(name);
        self.text("\n");
        self.flush_if_full()
    }

    fn finish(mut self) -> Result<(), WriteError> {
        self.w.write_all(&self.buf)?;
        self.w.flush()?;
        Ok(())
    }
}

/// `$PhysicalNames`: always ASCII, `dim tag "name"` per line.
fn write_physical_names<W: Write>(out: &mut Out<W>, model: &MshModel) -> Result<(), WriteError> {
    if model.physical_names.is_empty() {
        return Ok(());
    }
    out.text("$PhysicalNames\n");
    out.text(&format!("{}\n", model.physical_names.len()));
    for n in &model.physical_names {
        out.text(&format!("{} {} \"{}\"\n", n.dim, n.tag, n.name));
    }
    out.text("$EndPhysicalNames\n");
    Ok(())
}

/// `$Entities`: points `tag x y z nPhys phys…`; curves, surfaces, volumes
/// `tag bbox(6) nPhys phys… nBound ±bound…`.
fn write_entities<W: Write>(out: &mut Out<W>, model: &MshModel, index: &ModelIndex) -> Result<(), WriteError> {
    out.text("$Entities\n");
    for n in [model.points.len(), model.curves.len(), model.surfaces.len(), model.volumes.len()] {
        out.size(n as u64);
    }
    out.line()?;
    for p in &model.points {
        out.int(p.tag);
        for c in p.position.iter() {
            out.real(*c);
        }
        tag_list_size(out, &p.physical_tags);
        out.line()?;
    }
    for row in model.entity_rows().filter(|r| r.dim > 0) {
        out.int(row.tag);
        let bb = index.bboxes.get(&(row.dim, row.tag)).map_or([0.0; 6], |b| b.to_array());
        for c in bb {
            out.real(c);
        }
        tag_list_size(out, row.physical_tags);
        tag_list_size(out, row.boundary);
        out.line()?;
    }
    out.end("Entities")?;
    Ok(())
}

/// A `size_t` count followed by that many `int` tags.
fn tag_list_size<W: Write>(out: &mut Out<W>, tags: &[i32]) {
    out.size(tags.len() as u64);
    for &t in tags {
        out.int(t);
    }
}

/// The order that sorts `tags`, or `None` when they already are sorted.
fn sorting_order(tags: &[u64]) -> Option<Vec<usize>> {
    if tags.is_sorted() {
        return None;
    }
    let mut order: Vec<usize> = (0..tags.len()).collect();
    order.sort_unstable_by_key(|&i| tags[i]);
    Some(order)
}

/// `$Nodes`: header `nBlocks nNodes minTag maxTag`, per block
/// `dim tag parametric n`, the tags, then `x y z [u [v [w]]]` per node.
fn write_nodes<W: Write>(out: &mut Out<W>, model: &MshModel, index: &ModelIndex) -> Result<(), WriteError> {
    out.text("$Nodes\n");
    let (lo, hi) = index.nodes.range();
    out.size(model.node_blocks.len() as u64);
    out.size(model.n_nodes() as u64);
    out.size(lo);
    out.size(hi);
    out.line()?;
    for block in &model.node_blocks {
        write_node_block(out, block)?;
    }
    out.end("Nodes")?;
    Ok(())
}

fn write_node_block<W: Write>(out: &mut Out<W>, block: &NodeBlock) -> Result<(), WriteError> {
    out.int(i32::from(block.entity_dim));
    out.int(block.entity_tag);
    out.int(i32::from(block.parametric.is_some()));
    out.size(block.tags.len() as u64);
    out.line()?;
    let order = sorting_order(&block.tags);
    let at = |k: usize| order.as_ref().map_or(k, |o| o[k]);
    let n = block.tags.len();
    out.rows(n, |e, buf, k| e.size(buf, block.tags[at(k)]))?;
    let dim = usize::from(block.entity_dim);
    out.rows(n, |e, buf, k| {
        let i = at(k);
        for c in block.positions[i].iter() {
            e.real(buf, *c);
        }
        if let Some(p) = &block.parametric {
            for &u in &p[dim * i..dim * (i + 1)] {
                e.real(buf, u);
            }
        }
    })?;
    Ok(())
}

/// `$Elements`: header `nBlocks nElements minTag maxTag`, per block
/// `dim tag type n`, then `tag node…` per element.
fn write_elements<W: Write>(out: &mut Out<W>, model: &MshModel) -> Result<(), WriteError> {
    out.text("$Elements\n");
    let lo = model.element_blocks.iter().flat_map(|b| b.tags.iter()).min().copied().unwrap_or(0);
    let hi = model.element_blocks.iter().flat_map(|b| b.tags.iter()).max().copied().unwrap_or(0);
    out.size(model.element_blocks.len() as u64);
    out.size(model.n_elements() as u64);
    out.size(lo);
    out.size(hi);
    out.line()?;
    for block in &model.element_blocks {
        write_element_block(out, block)?;
    }
    out.end("Elements")?;
    Ok(())
}

fn write_element_block<W: Write>(out: &mut Out<W>, block: &ElementBlock) -> Result<(), WriteError> {
    out.int(i32::from(block.entity_dim));
    out.int(block.entity_tag);
    out.int(block.element_type.gmsh_code());
    out.size(block.tags.len() as u64);
    out.line()?;
    let k = block.element_type.n_nodes();
    let order = sorting_order(&block.tags);
    out.rows(block.tags.len(), |e, buf, j| {
        let i = order.as_ref().map_or(j, |o| o[j]);
        e.size(buf, block.tags[i]);
        for &n in &block.nodes[k * i..k * (i + 1)] {
            e.size(buf, n);
        }
    })?;
    Ok(())
}

/// `$Parametrizations`: `nCurves nSurfaces`; per curve `tag`, `N`, `N` lines
/// `x y z u` with `u = k`; per surface `tag`, `N T`, `N` lines
/// `x y z u v kmax(3) kmin(3)`, `T` lines of 0-based point indices.
fn write_parametrizations<W: Write>(out: &mut Out<W>, model: &MshModel) -> Result<(), WriteError> {
    if model.curve_parametrizations.is_empty() && model.surface_parametrizations.is_empty() {
        return Ok(());
    }
    out.text("$Parametrizations\n");
    out.size(model.curve_parametrizations.len() as u64);
    out.size(model.surface_parametrizations.len() as u64);
    out.line()?;
    for p in &model.curve_parametrizations {
        out.int(p.curve);
        out.line()?;
        out.size(p.points.len() as u64);
        out.line()?;
        out.rows(p.points.len(), |e, buf, k| {
            for c in p.points[k].iter() {
                e.real(buf, *c);
            }
            e.real(buf, k as f64);
        })?;
    }
    for p in &model.surface_parametrizations {
        out.int(p.surface);
        out.line()?;
        out.size(p.positions.len() as u64);
        out.size(p.triangles.len() as u64);
        out.line()?;
        out.rows(p.positions.len(), |e, buf, i| {
            for c in p.positions[i].iter() {
                e.real(buf, *c);
            }
            e.real(buf, p.uv[i].x);
            e.real(buf, p.uv[i].y);
            match p.curvature.get(i) {
                Some([kmax, kmin]) => kmax.iter().chain(kmin.iter()).for_each(|c| e.real(buf, *c)),
                None => (0..6).for_each(|_| e.real(buf, 0.0)),
            }
        })?;
        out.rows(p.triangles.len(), |e, buf, k| {
            for &i in &p.triangles[k] {
                // Validated to be < positions.len() <= i32::MAX.
                e.int(buf, i as i32);
            }
        })?;
    }
    out.end("Parametrizations")?;
    Ok(())
}

/// `$NodeData` / `$ElementData`: one string tag (the quoted name), one real
/// tag (time), four integer tags (step, components, count, partition 0),
/// then `tag value…` per entry.
fn write_view<W: Write>(out: &mut Out<W>, section: &str, view: &DataView) -> Result<(), WriteError> {
    let mut header = format!("${section}\n1\n\"{}\"\n1\n", view.name);
    push_f64_string(&mut header, view.time);
    header.push_str(&format!("\n4\n{}\n{}\n{}\n0\n", view.step, view.n_components, view.tags.len()));
    out.text(&header);
    let nc = view.n_components;
    out.rows(view.tags.len(), |e, buf, i| {
        let tag = view.tags[i];
        if e.binary {
            // Checked against i32::MAX before writing started.
            e.int(buf, tag as i32);
        } else {
            e.size(buf, tag);
        }
        for &x in &view.values[nc * i..nc * (i + 1)] {
            e.real(buf, x);
        }
    })?;
    out.end(section)?;
    Ok(())
}

/// Shortest round-trip text of `x` appended to a `String`.
fn push_f64_string(s: &mut String, x: f64) {
    s.push_str(zmij::Buffer::new().format(x));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{Vec2, Vec3};
    use crate::io::msh41::model::{CurveEntity, CurveParametrization, PointEntity, SurfaceParametrization};
    use crate::mesh::fixtures;

    fn ascii(model: &MshModel) -> String {
        let mut v = Vec::new();
        write_msh41(&mut v, model, &Msh41Options::default()).unwrap();
        String::from_utf8(v).unwrap()
    }

    /// Lines between `$name` and `$Endname`.
    fn section<'a>(text: &'a str, name: &str) -> Vec<&'a str> {
        let start = format!("${name}");
        let end = format!("$End{name}");
        let mut lines = text.lines().skip_while(|l| *l != start);
        lines.next().expect("section present");
        lines.take_while(|l| *l != end).collect()
    }

    #[test]
    fn surface_file_has_counts_gmsh_expects() {
        let mesh = fixtures::icosphere(1);
        let text = ascii(&MshModel::from_surface(&mesh));
        assert_eq!(section(&text, "MeshFormat"), ["4.1 0 8"]);
        let ent = section(&text, "Entities");
        assert_eq!(ent[0], "0 0 1 0");
        let bb: Vec<f64> = ent[1].split(' ').skip(1).take(6).map(|s| s.parse().unwrap()).collect();
        assert!((bb[0] + 1.0).abs() < 1e-12 && (bb[5] - 1.0).abs() < 1e-12);
        assert!(ent[1].ends_with(" 0 0"), "no physicals, no boundary: {}", ent[1]);
        let nodes = section(&text, "Nodes");
        assert_eq!(nodes[0], "1 42 1 42");
        assert_eq!(nodes[1], "2 1 0 42");
        assert_eq!(nodes.len(), 2 + 2 * 42);
        let xyz: Vec<f64> = nodes[2 + 42].split(' ').map(|s| s.parse().unwrap()).collect();
        assert_eq!(xyz, mesh.positions[0].as_slice());
        let els = section(&text, "Elements");
        assert_eq!(els[0], "1 80 1 80");
        assert_eq!(els[1], "2 1 2 80");
        let t0 = mesh.triangles[0].map(|v| v.0 + 1);
        assert_eq!(els[2], format!("1 {} {} {}", t0[0], t0[1], t0[2]));
        assert!(!text.contains("$Parametrizations"));
    }

    #[test]
    fn blocks_are_written_sorted_with_their_data() {
        let mut m = MshModel::from_surface(&fixtures::square(1));
        m.node_blocks[0].tags = vec![40, 10, 30, 20];
        m.element_blocks[0].tags = vec![9, 5];
        m.element_blocks[0].nodes = vec![40, 10, 30, 40, 30, 20];
        let text = ascii(&m);
        let nodes = section(&text, "Nodes");
        assert_eq!(nodes[0], "1 4 10 40");
        assert_eq!(&nodes[2..6], ["10", "20", "30", "40"]);
        assert_eq!(nodes[6], "1.0 0.0 0.0"); // tag 10 = second vertex of the square
        let els = section(&text, "Elements");
        assert_eq!(els[0], "1 2 5 9");
        assert_eq!(&els[2..4], ["5 40 30 20", "9 40 10 30"]);
    }

    #[test]
    fn views_and_volume() {
        let mut m = MshModel::from_volume(&crate::mesh::TetMesh {
            positions: vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            tets: vec![[0, 1, 2, 3].map(crate::mesh::VertexId)],
        });
        m.node_data.push(DataView::contiguous("frame", 9, (0..36).map(f64::from).collect(), 1));
        m.element_data.push(DataView { time: 0.5, step: 2, ..DataView::contiguous("q", 3, vec![0.1, 0.2, 0.3], 1) });
        let text = ascii(&m);
        assert_eq!(section(&text, "Elements")[1], "3 1 4 1");
        let nd = section(&text, "NodeData");
        assert_eq!(&nd[..9], ["1", "\"frame\"", "1", "0.0", "4", "0", "9", "4", "0"]);
        assert_eq!(nd[9], "1 0.0 1.0 2.0 3.0 4.0 5.0 6.0 7.0 8.0");
        let ed = section(&text, "ElementData");
        assert_eq!(&ed[3..], ["0.5", "4", "2", "3", "1", "0", "1 0.1 0.2 0.3"]);
    }

    #[test]
    fn parametrizations_follow_gmsh_layout() {
        let mut m = MshModel::from_surface(&fixtures::square(1));
        m.points.push(PointEntity { tag: 1, position: Vec3::zeros(), physical_tags: vec![] });
        m.curves.push(CurveEntity { tag: 1, bounding_points: vec![1, -1], physical_tags: vec![3] });
        m.surfaces[0].bounding_curves = vec![1];
        m.curve_parametrizations.push(CurveParametrization {
            curve: 1,
            points: vec![Vec3::zeros(), Vec3::x(), Vec3::new(1.0, 1.0, 0.0), Vec3::y(), Vec3::zeros()],
        });
        m.surface_parametrizations.push(SurfaceParametrization {
            surface: 1,
            positions: vec![Vec3::zeros(), Vec3::x(), Vec3::y()],
            uv: vec![Vec2::new(-1.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)],
            curvature: vec![],
            triangles: vec![[0, 1, 2]],
        });
        let text = ascii(&m);
        let ent = section(&text, "Entities");
        assert_eq!(ent[0], "1 1 1 0");
        assert_eq!(ent[1], "1 0.0 0.0 0.0 0");
        assert_eq!(ent[2], "1 0.0 0.0 0.0 1.0 1.0 0.0 1 3 2 1 -1");
        assert!(ent[3].ends_with(" 0 1 1"));
        let p = section(&text, "Parametrizations");
        assert_eq!(&p[..4], ["1 1", "1", "5", "0.0 0.0 0.0 0.0"]);
        assert_eq!(p[6], "0.0 1.0 0.0 3.0");
        assert_eq!(
            &p[8..],
            [
                "1",
                "3 1",
                "0.0 0.0 0.0 -1.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0",
                "1.0 0.0 0.0 1.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0",
                "0.0 1.0 0.0 0.0 1.0 0.0 0.0 0.0 0.0 0.0 0.0",
                "0 1 2"
            ]
        );
        // Parametrizations come after the mesh, data after them.
        assert!(text.find("$EndElements").unwrap() < text.find("$Parametrizations").unwrap());
    }

    #[test]
    fn invalid_model_writes_nothing() {
        let mut m = MshModel::from_surface(&fixtures::square(1));
        m.element_blocks[0].nodes[0] = 77;
        let mut v = Vec::new();
        assert!(matches!(
            write_msh41(&mut v, &m, &Msh41Options::default()),
            Err(WriteError::MissingNode { node: 77, .. })
        ));
        assert!(v.is_empty());
    }

    #[test]
    fn convenience_writers_match_the_model_path() {
        let tri = fixtures::cube(2);
        let mut a = Vec::new();
        write_surface_msh41(&mut a, &tri).unwrap();
        assert_eq!(String::from_utf8(a).unwrap(), ascii(&MshModel::from_surface(&tri)));
        let tet = crate::mesh::TetMesh {
            positions: vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            tets: vec![[0, 1, 2, 3].map(crate::mesh::VertexId)],
        };
        let mut a = Vec::new();
        write_volume_msh41(&mut a, &tet).unwrap();
        let text = String::from_utf8(a).unwrap();
        assert_eq!(section(&text, "Entities")[0], "0 0 0 1");
        assert_eq!(section(&text, "Elements")[1..], ["3 1 4 1", "1 1 2 3 4"]);
    }

    #[test]
    fn binary_data_tags_must_fit_an_int() {
        let mut m = MshModel::from_surface(&fixtures::square(1));
        m.node_blocks[0].tags[0] = 1 << 33;
        m.element_blocks[0].nodes.iter_mut().filter(|n| **n == 1).for_each(|n| *n = 1 << 33);
        m.node_data.push(DataView { tags: vec![1 << 33], ..DataView::contiguous("f", 1, vec![1.0], 1) });
        let mut v = Vec::new();
        write_msh41(&mut v, &m, &Msh41Options::default()).unwrap();
        assert!(String::from_utf8(v).unwrap().contains("\n8589934592 1.0\n"));
        let mut v = Vec::new();
        assert!(matches!(write_msh41(&mut v, &m, &Msh41Options { binary: true }), Err(WriteError::TooLarge { .. })));
        assert!(v.is_empty());
    }

    #[test]
    fn bytes_do_not_depend_on_the_thread_count() {
        use crate::io::text_out::ROWS_PER_CHUNK;
        // 76800 triangles and views: more rows than one round of chunks.
        let mesh = fixtures::cube(80);
        let mut m = MshModel::from_surface(&mesh);
        let n_f = mesh.n_faces();
        assert!(n_f > 16 * ROWS_PER_CHUNK);
        m.element_data.push(DataView::contiguous("q", 3, (0..3 * n_f).map(|i| i as f64 / 7.0).collect(), 1));
        m.surface_parametrizations.push(SurfaceParametrization {
            surface: 1,
            positions: mesh.positions.clone(),
            uv: mesh.positions.iter().map(|p| Vec2::new(p.x, p.y)).collect(),
            curvature: vec![],
            triangles: mesh.triangles.iter().map(|t| t.map(|v| v.0 as _)).collect(),
        });
        for binary in [false, true] {
            let on = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let mut v = Vec::new();
                pool.install(|| write_msh41(&mut v, &m, &Msh41Options { binary })).unwrap();
                v
            };
            let (one, two) = (on(1), on(2));
            assert!(one == two, "binary {binary}: 1 and 2 threads differ");
            if !binary {
                let text = String::from_utf8(one).unwrap();
                assert_eq!(section(&text, "Elements").len(), 2 + n_f);
                assert_eq!(section(&text, "ElementData").len(), 9 + n_f);
                let nodes = section(&text, "Nodes");
                assert_eq!(nodes.len(), 2 + 2 * mesh.n_vertices());
                let last: Vec<f64> = nodes.last().unwrap().split(' ').map(|s| s.parse().unwrap()).collect();
                assert_eq!(last, mesh.positions.last().unwrap().as_slice());
            }
        }
    }

    #[test]
    fn binary_layout() {
        let m = MshModel::from_surface(&fixtures::square(1));
        let mut v = Vec::new();
        write_msh41(&mut v, &m, &Msh41Options { binary: true }).unwrap();
        let head = b"$MeshFormat\n4.1 1 8\n\x01\x00\x00\x00\n$EndMeshFormat\n$Entities\n";
        assert_eq!(&v[..head.len()], head);
        let nodes = v.windows(7).position(|w| w == b"$Nodes\n").unwrap() + 7;
        let word = |k: usize| u64::from_le_bytes(v[nodes + 8 * k..nodes + 8 * k + 8].try_into().unwrap());
        assert_eq!([word(0), word(1), word(2), word(3)], [1, 4, 1, 4]);
        let text_end = String::from_utf8_lossy(&v[v.len() - 30..]).into_owned();
        assert!(text_end.ends_with("\n$EndElements\n"), "{text_end:?}");
    }
}
