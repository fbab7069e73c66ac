//! VTK XML UnstructuredGrid (`.vtu`) writer: points, mixed cells, point and
//! cell data.
//!
//! # File layout
//! `<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian"
//! header_type="UInt64|UInt32">` with one `<Piece>` holding `<PointData>`,
//! `<CellData>`, `<Points>` (Float64 × 3, or Float32 × 3 when every
//! coordinate is exactly an `f32`, e.g. from binary STL) and `<Cells>` (`connectivity`,
//! `offsets` = end of each cell in `connectivity`, `types`). Connectivity and
//! offsets are `Int32` when every index fits, `Int64` otherwise.
//! Cell types: vertex 1, line 3, triangle 5, quad 9, tetra 10, biquadratic
//! quad 28. Cell data follow the cells block by block, in the order of
//! [`VtuMesh::cells`].
//!
//! # Encodings ([`VtuEncoding`])
//! - `Ascii`: values as text (shortest round-trip floats); biggest, slowest.
//! - `Base64`: `format="binary"` inline, the byte-count header and the data
//!   base64-encoded *separately*, as VTK writes them (meshio and VTK both
//!   read that; a single stream is misread by some VTK versions).
//! - `Raw` (default): `format="appended"` with `<AppendedData
//!   encoding="raw">_` followed by `header + bytes` per array, then a line
//!   break before `</AppendedData>` (meshio cuts the data at the last line
//!   break). The block holds the arrays in reverse document order, so that
//!   meshio's offset rewriting cannot match the wrong array (see
//!   `appended_len`). Smallest and fastest; what ParaView's own writer
//!   produces by default; not well-formed XML, so generic XML parsers cannot
//!   open it.
//!
//! Binary arrays are zlib-compressed by default ([`VtuCompression`]), in
//! VTK's block layout. Output is buffered internally in 64 KiB chunks (no
//! `BufWriter` needed). Input is validated in full before the first byte.

use crate::geom::Vec3;
use crate::io::text_out::{CHUNK, flush_if_full, push_f64, push_i64, push_u64};
use crate::io::write_error::WriteError;
use crate::mesh::{TetMesh, TriMesh, VertexId};
use base64::Engine;
use base64::engine::general_purpose::STANDARD as B64;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::io::Write;

/// How array values are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VtuEncoding {
    /// Text values inside each `DataArray`.
    Ascii,
    /// Base64 binary inside each `DataArray` (`format="binary"`).
    Base64,
    /// Raw binary in one `<AppendedData>` block at the end (`format="appended"`).
    #[default]
    Raw,
}

/// Integer type of the byte-count header in front of each binary array.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum VtuHeaderType {
    /// 32-bit counts (arrays up to 4 GiB).
    UInt32,
    /// 64-bit counts (VTK ≥ 6 default).
    #[default]
    UInt64,
}

/// Options of [`write_vtu`].
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VtuOptions {
    /// Value encoding. Default [`VtuEncoding::Raw`].
    pub encoding: VtuEncoding,
    /// Binary header integer type. Default [`VtuHeaderType::UInt64`].
    pub header_type: VtuHeaderType,
    /// Compression of binary arrays (ignored for ASCII). Default
    /// [`VtuCompression::Zlib`].
    pub compression: VtuCompression,
}

/// Compression of the binary arrays of a VTU file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum VtuCompression {
    /// Plain binary.
    None,
    /// `compressor="vtkZLibDataCompressor"`: each array in independently
    /// compressed zlib blocks, as VTK writes them (meshio and VTK read it).
    #[default]
    Zlib,
}

/// A block of cells of one kind, indexing [`VtuMesh::points`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CellBlock<'a> {
    /// VTK_VERTEX (1).
    Vertices(&'a [VertexId]),
    /// VTK_LINE (3).
    Lines(&'a [[VertexId; 2]]),
    /// VTK_TRIANGLE (5).
    Triangles(&'a [[VertexId; 3]]),
    /// VTK_TETRA (10).
    Tetrahedra(&'a [[VertexId; 4]]),
    /// VTK_QUAD (9), corners counter-clockwise.
    Quads(&'a [[VertexId; 4]]),
    /// VTK_BIQUADRATIC_QUAD (28): 4 corners, the mid nodes of edges 01, 12,
    /// 23, 30, the centre (Gmsh's 9-node order too).
    BiquadraticQuads(&'a [[VertexId; 9]]),
}

impl CellBlock<'_> {
    /// Number of cells.
    pub fn len(&self) -> usize {
        match self {
            Self::Vertices(c) => c.len(),
            Self::Lines(c) => c.len(),
            Self::Triangles(c) => c.len(),
            Self::Tetrahedra(c) => c.len(),
            Self::Quads(c) => c.len(),
            Self::BiquadraticQuads(c) => c.len(),
        }
    }

    /// Whether the block has no cell.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Points per cell.
    pub fn n_points_per_cell(&self) -> usize {
        match self {
            Self::Vertices(_) => 1,
            Self::Lines(_) => 2,
            Self::Triangles(_) => 3,
            Self::Tetrahedra(_) => 4,
            Self::Quads(_) => 4,
            Self::BiquadraticQuads(_) => 9,
        }
    }

    /// VTK cell type code.
    pub fn vtk_type(&self) -> u8 {
        match self {
            Self::Vertices(_) => 1,
            Self::Lines(_) => 3,
            Self::Triangles(_) => 5,
            Self::Tetrahedra(_) => 10,
            Self::Quads(_) => 9,
            Self::BiquadraticQuads(_) => 28,
        }
    }

    /// All point indices, cell after cell.
    fn indices(&self) -> &[VertexId] {
        match self {
            Self::Vertices(c) => c,
            Self::Lines(c) => c.as_flattened(),
            Self::Triangles(c) => c.as_flattened(),
            Self::Tetrahedra(c) => c.as_flattened(),
            Self::Quads(c) => c.as_flattened(),
            Self::BiquadraticQuads(c) => c.as_flattened(),
        }
    }
}

/// Values of a data array.
#[derive(Debug, Clone, PartialEq)]
pub enum DataValues<'a> {
    /// `Float64`.
    Float64(Cow<'a, [f64]>),
    /// `Float32`.
    Float32(Cow<'a, [f32]>),
    /// `Int32`.
    Int32(Cow<'a, [i32]>),
    /// `Int64`.
    Int64(Cow<'a, [i64]>),
    /// `UInt8` (flags).
    UInt8(Cow<'a, [u8]>),
    /// `UInt32`.
    UInt32(Cow<'a, [u32]>),
}

impl DataValues<'_> {
    fn len(&self) -> usize {
        match self {
            Self::Float64(v) => v.len(),
            Self::Float32(v) => v.len(),
            Self::Int32(v) => v.len(),
            Self::Int64(v) => v.len(),
            Self::UInt8(v) => v.len(),
            Self::UInt32(v) => v.len(),
        }
    }

    fn vtk_name(&self) -> &'static str {
        match self {
            Self::Float64(_) => "Float64",
            Self::Float32(_) => "Float32",
            Self::Int32(_) => "Int32",
            Self::Int64(_) => "Int64",
            Self::UInt8(_) => "UInt8",
            Self::UInt32(_) => "UInt32",
        }
    }
}

/// A named point or cell data array: `n_components` values per point or cell.
#[derive(Debug, Clone, PartialEq)]
pub struct DataArray<'a> {
    /// Array name (XML-escaped on output).
    pub name: String,
    /// Components per tuple: 1 scalar, 3 vector, 4 quaternion, 9 tensor, …
    pub n_components: usize,
    /// Values, tuple after tuple.
    pub values: DataValues<'a>,
}

impl<'a> DataArray<'a> {
    /// A `Float64` array.
    pub fn f64(name: impl Into<String>, n_components: usize, values: impl Into<Cow<'a, [f64]>>) -> Self {
        Self { name: name.into(), n_components, values: DataValues::Float64(values.into()) }
    }

    /// A `Float64` array of 3-vectors (copied).
    pub fn vectors(name: impl Into<String>, values: &[Vec3]) -> Self {
        let flat: Vec<f64> = values.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        Self::f64(name, 3, flat)
    }

    /// A `Float32` array rounded from `f64` values, for data whose precision
    /// is far below `f32`'s (estimated curvatures, unit directions, ratios):
    /// half the bytes of [`DataArray::f64`].
    pub fn f32_rounded(name: impl Into<String>, n_components: usize, values: &[f64]) -> Self {
        let v: Vec<f32> = values.iter().map(|&x| x as f32).collect();
        Self { name: name.into(), n_components, values: DataValues::Float32(v.into()) }
    }

    /// A `Float32` array of 3-vectors rounded from `f64` (see
    /// [`DataArray::f32_rounded`]).
    pub fn vectors_f32(name: impl Into<String>, values: &[Vec3]) -> Self {
        let flat: Vec<f32> = values.iter().flat_map(|v| [v.x as f32, v.y as f32, v.z as f32]).collect();
        Self { name: name.into(), n_components: 3, values: DataValues::Float32(flat.into()) }
    }

    /// An `Int32` scalar array.
    pub fn i32(name: impl Into<String>, values: impl Into<Cow<'a, [i32]>>) -> Self {
        Self { name: name.into(), n_components: 1, values: DataValues::Int32(values.into()) }
    }

    /// A `UInt8` scalar array (flags).
    pub fn u8(name: impl Into<String>, values: impl Into<Cow<'a, [u8]>>) -> Self {
        Self { name: name.into(), n_components: 1, values: DataValues::UInt8(values.into()) }
    }
}

/// What [`write_vtu`] writes: points, cell blocks and data, all borrowed
/// where possible.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VtuMesh<'a> {
    /// Point positions.
    pub points: &'a [Vec3],
    /// Cell blocks, written in this order.
    pub cells: Vec<CellBlock<'a>>,
    /// Arrays with one tuple per point.
    pub point_data: Vec<DataArray<'a>>,
    /// Arrays with one tuple per cell (all blocks, in block order).
    pub cell_data: Vec<DataArray<'a>>,
}

impl<'a> VtuMesh<'a> {
    /// The triangles of `mesh`, no data.
    pub fn from_surface(mesh: &'a TriMesh) -> Self {
        Self { points: &mesh.positions, cells: vec![CellBlock::Triangles(&mesh.triangles)], ..Default::default() }
    }

    /// The tetrahedra of `mesh`, no data.
    pub fn from_volume(mesh: &'a TetMesh) -> Self {
        Self { points: &mesh.positions, cells: vec![CellBlock::Tetrahedra(&mesh.tets)], ..Default::default() }
    }

    /// Total number of cells.
    pub fn n_cells(&self) -> usize {
        self.cells.iter().map(CellBlock::len).sum()
    }

    /// Indices in range, finite points, data lengths matching.
    ///
    /// # Errors
    /// The first violation, naming the cell or array.
    pub fn validate(&self) -> Result<(), WriteError> {
        for (i, p) in self.points.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(WriteError::NonFiniteCoordinate { what: format!("point {i}"), x: p.x, y: p.y, z: p.z });
            }
        }
        let n = self.points.len();
        let mut first = 0;
        for block in &self.cells {
            let k = block.n_points_per_cell();
            if let Some(pos) = block.indices().iter().position(|v| v.idx() >= n) {
                return Err(WriteError::IndexOutOfRange {
                    what: format!("cell {}", first + pos / k),
                    index: u64::from(block.indices()[pos].0),
                    n_points: n,
                });
            }
            first += block.len();
        }
        for (arrays, count, what) in [(&self.point_data, n, "point"), (&self.cell_data, self.n_cells(), "cell")] {
            for a in arrays {
                if a.n_components == 0 {
                    return Err(WriteError::BadComponents {
                        view: a.name.clone(),
                        n_components: 0,
                        allowed: "VTK arrays need at least 1",
                    });
                }
                if a.values.len() != count * a.n_components {
                    return Err(WriteError::LengthMismatch {
                        what: format!("{what} data {:?}", a.name),
                        expected: count * a.n_components,
                        got: a.values.len(),
                    });
                }
            }
        }
        Ok(())
    }
}

/// Write `mesh` as a `.vtu` file.
///
/// # Errors
/// A validation error (nothing written) or [`WriteError::Io`].
pub fn write_vtu(w: impl Write, mesh: &VtuMesh<'_>, opts: &VtuOptions) -> Result<(), WriteError> {
    mesh.validate()?;
    let n_conn: usize = mesh.cells.iter().map(|b| b.indices().len()).sum();
    let wide = mesh.points.len() > i32::MAX as usize || n_conn > i32::MAX as usize;
    // Float32 points when every coordinate is exactly an `f32` (always so for
    // a mesh read from binary STL): half the bytes, the same values for every
    // reader. Points computed in `f64` (a tet mesh's interior nodes, OBJ or
    // PLY doubles, coordinates far from the origin) keep Float64, so no
    // precision is ever lost.
    let points_f32 = crate::geom::every_coordinate_is_f32(mesh.points);
    if opts.header_type == VtuHeaderType::UInt32 && opts.encoding != VtuEncoding::Ascii {
        let sources = [
            Source::Points(mesh.points, points_f32),
            Source::Connectivity(&mesh.cells, wide),
            Source::Offsets(&mesh.cells, wide),
        ];
        let data = mesh.point_data.iter().chain(&mesh.cell_data).map(|a| Source::Values(&a.values));
        if let Some(n) = sources.into_iter().chain(data).map(|s| s.n_bytes()).find(|&n| n > u32::MAX as usize) {
            return Err(WriteError::TooLarge {
                what: "VTU array bytes with a UInt32 header",
                count: n,
                max: u64::from(u32::MAX),
            });
        }
    }
    let int = if wide { "Int64" } else { "Int32" };
    // Every array in document order, with the element that holds it.
    let mut items: Vec<(&str, Source<'_>, String)> = Vec::new();
    for (tag, data) in [("PointData", &mesh.point_data), ("CellData", &mesh.cell_data)] {
        for a in data {
            items.push((tag, Source::Values(&a.values), attrs(&a.name, a.values.vtk_name(), a.n_components)));
        }
    }
    let point_type = if points_f32 { "Float32" } else { "Float64" };
    items.push(("Points", Source::Points(mesh.points, points_f32), attrs("Points", point_type, 3)));
    items.push(("Cells", Source::Connectivity(&mesh.cells, wide), attrs("connectivity", int, 1)));
    items.push(("Cells", Source::Offsets(&mesh.cells, wide), attrs("offsets", int, 1)));
    items.push(("Cells", Source::Types(&mesh.cells), attrs("types", "UInt8", 1)));
    let header64 = opts.header_type == VtuHeaderType::UInt64;
    let compressed = opts.compression == VtuCompression::Zlib && opts.encoding != VtuEncoding::Ascii;
    let mut payloads: Vec<Option<Compressed>> = Vec::with_capacity(items.len());
    for (_, src, _) in &items {
        payloads.push(if compressed { Some(compress_array(src, header64)?) } else { None });
    }
    let mut xml = XmlOut::new(w, opts);
    xml.offset = items.iter().zip(&payloads).map(|((_, src, _), p)| appended_len(src, p.as_ref(), header64)).sum();
    xml.text("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"");
    xml.text(match opts.header_type {
        VtuHeaderType::UInt32 => "UInt32",
        VtuHeaderType::UInt64 => "UInt64",
    });
    if compressed {
        xml.text("\" compressor=\"vtkZLibDataCompressor");
    }
    xml.text(&format!(
        "\">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n",
        mesh.points.len(),
        mesh.n_cells()
    ));
    let mut items = items.into_iter().zip(payloads).peekable();
    for tag in ["PointData", "CellData", "Points", "Cells"] {
        xml.text(&format!("<{tag}>\n"));
        while let Some(((_, src, attrs), payload)) = items.next_if(|((t, _, _), _)| *t == tag) {
            xml.array(src, &attrs, payload)?;
        }
        xml.text(&format!("</{tag}>\n"));
    }
    xml.text("</Piece>\n</UnstructuredGrid>\n");
    xml.appended()?;
    xml.text("</VTKFile>\n");
    xml.finish()
}

/// Bytes an array takes in the raw appended block: its header and data,
/// compressed or not.
///
/// The block holds the arrays in *reverse* document order: the first
/// `DataArray` of the XML is the last in the block. VTK reads each array at
/// its offset, whatever the order. meshio converts the block to base64 in
/// block order, rewriting each array's `offset` as it goes and looking the
/// next one up by its raw offset with the first match in document order; in
/// reverse order every array still to be found comes before every rewritten
/// one, so a rewritten offset that equals a pending raw offset can no longer
/// be matched in its place.
fn appended_len(src: &Source<'_>, payload: Option<&Compressed>, header64: bool) -> usize {
    match payload {
        Some(c) => c.header.len() + c.data.len(),
        None => src.n_bytes() + if header64 { 8 } else { 4 },
    }
}

/// Uncompressed bytes per zlib block. VTK's default is 32 KiB; larger
/// blocks lose nothing in ratio (zlib's window is 32 KiB) and give fewer
/// headers, and 128 KiB blocks still let every core compress its share.
const ZLIB_BLOCK: usize = 128 * 1024;

/// Bytes of an array's start on which its deflate settings are chosen.
const SAMPLE: usize = 32 * 1024;

/// An array is coded with matching at level 2 only when that shrinks its
/// sample to this fraction of the better fast coding or less: level 2
/// takes about twice the time of the fast codings.
const LEVEL2_GAIN: f64 = 0.75;

/// The deflate settings of one array, chosen on its first [`SAMPLE`]
/// bytes among three zlib-rs codings (measured in `docs/decisions.md`):
/// level 1 (matching with static Huffman tables: fastest on indices and
/// coordinates, but it expands noisy floats), Huffman-only (dynamic tables
/// without matching: fastest and smallest on noisy floats) and level 2
/// (matching with dynamic tables: half the size of level 1 on
/// connectivity, at twice its time). Every choice is a plain zlib stream
/// that every inflater reads, and it depends on the bytes alone.
fn deflate_config(sample: &[u8]) -> Result<zlib_rs::DeflateConfig, WriteError> {
    let level1 = zlib_rs::DeflateConfig::new(1);
    let huffman = zlib_rs::DeflateConfig { strategy: zlib_rs::Strategy::HuffmanOnly, ..zlib_rs::DeflateConfig::new(2) };
    let level2 = zlib_rs::DeflateConfig::new(2);
    let size = |c| deflate_block(sample, c).map(|z| z.len() as f64);
    let (s1, sh) = (size(level1)?, size(huffman)?);
    let (fast, fast_size) = if s1 <= sh { (level1, s1) } else { (huffman, sh) };
    Ok(if size(level2)? <= LEVEL2_GAIN * fast_size { level2 } else { fast })
}

/// One zlib stream of `block`.
fn deflate_block(block: &[u8], config: zlib_rs::DeflateConfig) -> Result<Vec<u8>, WriteError> {
    let mut out = vec![0u8; zlib_rs::compress_bound(block.len())];
    let (written, rc) = zlib_rs::compress_slice(&mut out, block, config);
    if rc != zlib_rs::ReturnCode::Ok {
        return Err(std::io::Error::other(format!("zlib compression failed ({rc:?})")).into());
    }
    let n = written.len();
    out.truncate(n);
    Ok(out)
}

/// One array in VTK's compressed layout: the header
/// `[n_blocks, block_size, last_partial_block_size, compressed_size…]`
/// (header-type integers) and the concatenated zlib streams.
#[derive(Debug)]
struct Compressed {
    header: Vec<u8>,
    data: Vec<u8>,
}

/// Compresses `src` in [`ZLIB_BLOCK`]-sized blocks, in parallel, with the
/// settings [`deflate_config`] chooses; the bytes do not depend on the
/// number of threads.
fn compress_array(src: &Source<'_>, header64: bool) -> Result<Compressed, WriteError> {
    use rayon::prelude::*;
    let mut raw = Vec::with_capacity(src.n_bytes());
    src.for_each(|bytes, _| -> Result<(), std::convert::Infallible> {
        raw.extend_from_slice(bytes);
        Ok(())
    })
    .unwrap_or_else(|never| match never {});
    let config = deflate_config(&raw[..raw.len().min(SAMPLE)])?;
    let blocks: Vec<Vec<u8>> =
        raw.par_chunks(ZLIB_BLOCK).map(|chunk| deflate_block(chunk, config)).collect::<Result<_, _>>()?;
    let mut ints = vec![blocks.len(), ZLIB_BLOCK, raw.len() % ZLIB_BLOCK];
    ints.extend(blocks.iter().map(Vec::len));
    let mut header = Vec::with_capacity(ints.len() * 8);
    for n in ints {
        if header64 {
            header.extend_from_slice(&(n as u64).to_le_bytes());
        } else {
            let n = u32::try_from(n).map_err(|_| WriteError::TooLarge {
                what: "compressed VTU block count or size with a UInt32 header",
                count: n,
                max: u64::from(u32::MAX),
            })?;
            header.extend_from_slice(&n.to_le_bytes());
        }
    }
    Ok(Compressed { header, data: blocks.concat() })
}

/// `type="…" Name="…" NumberOfComponents="…"` with the name XML-escaped.
fn attrs(name: &str, ty: &str, n_components: usize) -> String {
    let mut esc = String::with_capacity(name.len());
    for c in name.chars() {
        match c {
            '&' => esc.push_str("&amp;"),
            '<' => esc.push_str("&lt;"),
            '>' => esc.push_str("&gt;"),
            '"' => esc.push_str("&quot;"),
            '\n' => esc.push_str("&#10;"),
            c => esc.push(c),
        }
    }
    format!("type=\"{ty}\" Name=\"{esc}\" NumberOfComponents=\"{n_components}\"")
}

/// One array's values, produced on the fly (no full copy of big arrays).
enum Source<'a> {
    /// Point coordinates as Float64, or as Float32 when `true` (only when
    /// every coordinate is exactly an `f32`, see [`crate::geom::every_coordinate_is_f32`]).
    Points(&'a [Vec3], bool),
    /// Concatenated cell indices; `true` = Int64.
    Connectivity(&'a [CellBlock<'a>], bool),
    /// End offset of each cell; `true` = Int64.
    Offsets(&'a [CellBlock<'a>], bool),
    /// VTK cell type per cell.
    Types(&'a [CellBlock<'a>]),
    /// A user array.
    Values(&'a DataValues<'a>),
}

/// Value of one scalar for ASCII output.
enum Scalar {
    F(f64),
    I(i64),
    U(u64),
}

impl Source<'_> {
    /// Size in bytes of the binary data.
    fn n_bytes(&self) -> usize {
        match self {
            Self::Points(p, single) => (if *single { 12 } else { 24 }) * p.len(),
            Self::Connectivity(c, wide) => {
                c.iter().map(|b| b.indices().len()).sum::<usize>() * if *wide { 8 } else { 4 }
            }
            Self::Offsets(c, wide) => c.iter().map(CellBlock::len).sum::<usize>() * if *wide { 8 } else { 4 },
            Self::Types(c) => c.iter().map(CellBlock::len).sum(),
            Self::Values(v) => match v {
                DataValues::Float64(x) => 8 * x.len(),
                DataValues::Float32(x) => 4 * x.len(),
                DataValues::Int32(x) => 4 * x.len(),
                DataValues::Int64(x) => 8 * x.len(),
                DataValues::UInt8(x) => x.len(),
                DataValues::UInt32(x) => 4 * x.len(),
            },
        }
    }

    /// Feed every scalar, in order, to `f`; `f` gets the little-endian bytes
    /// and the value. Stops at the first error.
    fn for_each<E>(&self, mut f: impl FnMut(&[u8], Scalar) -> Result<(), E>) -> Result<(), E> {
        match self {
            Self::Points(p, false) => {
                for x in p.iter().flat_map(|v| [v.x, v.y, v.z]) {
                    f(&x.to_le_bytes(), Scalar::F(x))?;
                }
            }
            Self::Points(p, true) => {
                for x in p.iter().flat_map(|v| [v.x, v.y, v.z]) {
                    f(&(x as f32).to_le_bytes(), Scalar::F(x))?;
                }
            }
            Self::Connectivity(cells, wide) => {
                for v in cells.iter().flat_map(|b| b.indices()) {
                    int(&mut f, i64::from(v.0), *wide)?;
                }
            }
            Self::Offsets(cells, wide) => {
                let mut end = 0i64;
                for b in cells.iter() {
                    let k = b.n_points_per_cell() as i64;
                    for _ in 0..b.len() {
                        end += k;
                        int(&mut f, end, *wide)?;
                    }
                }
            }
            Self::Types(cells) => {
                for b in cells.iter() {
                    let t = b.vtk_type();
                    for _ in 0..b.len() {
                        f(&[t], Scalar::U(u64::from(t)))?;
                    }
                }
            }
            Self::Values(v) => match v {
                DataValues::Float64(x) => x.iter().try_for_each(|&x| f(&x.to_le_bytes(), Scalar::F(x)))?,
                DataValues::Float32(x) => x.iter().try_for_each(|&x| f(&x.to_le_bytes(), Scalar::F(f64::from(x))))?,
                DataValues::Int32(x) => x.iter().try_for_each(|&x| f(&x.to_le_bytes(), Scalar::I(i64::from(x))))?,
                DataValues::Int64(x) => x.iter().try_for_each(|&x| f(&x.to_le_bytes(), Scalar::I(x)))?,
                DataValues::UInt8(x) => x.iter().try_for_each(|&x| f(&[x], Scalar::U(u64::from(x))))?,
                DataValues::UInt32(x) => x.iter().try_for_each(|&x| f(&x.to_le_bytes(), Scalar::U(u64::from(x))))?,
            },
        }
        Ok(())
    }

    /// Float32 values are written as text from their `f32` shortest form.
    fn is_f32(&self) -> bool {
        matches!(self, Self::Values(DataValues::Float32(_)) | Self::Points(_, true))
    }
}

/// An index as Int32 (validated to fit) or Int64.
fn int<E>(f: &mut impl FnMut(&[u8], Scalar) -> Result<(), E>, x: i64, wide: bool) -> Result<(), E> {
    if wide { f(&x.to_le_bytes(), Scalar::I(x)) } else { f(&(x as i32).to_le_bytes(), Scalar::I(x)) }
}

/// An array waiting for the raw appended block.
enum Pending<'s> {
    /// Written from its source with a byte-count header.
    Plain(Source<'s>),
    /// Already compressed (header and blocks).
    Compressed(Compressed),
}

/// The output with its encoding state.
struct XmlOut<'s, W: Write> {
    w: W,
    buf: Vec<u8>,
    encoding: VtuEncoding,
    header64: bool,
    /// Raw encoding: arrays waiting for the appended block.
    pending: Vec<Pending<'s>>,
    /// Raw encoding: offset of the array written last (the appended block
    /// holds the arrays in reverse document order, see [`appended_len`]).
    offset: usize,
}

impl<'s, W: Write> XmlOut<'s, W> {
    fn new(w: W, opts: &VtuOptions) -> Self {
        Self {
            w,
            buf: Vec::with_capacity(CHUNK + 4096),
            encoding: opts.encoding,
            header64: opts.header_type == VtuHeaderType::UInt64,
            pending: Vec::new(),
            offset: 0,
        }
    }

    fn text(&mut self, s: &str) {
        self.buf.extend_from_slice(s.as_bytes());
    }

    fn header_bytes(&self, n: usize) -> Vec<u8> {
        if self.header64 { (n as u64).to_le_bytes().to_vec() } else { (n as u32).to_le_bytes().to_vec() }
    }

    /// Writes one `DataArray` element; `payload` is its compressed form
    /// when the file is compressed.
    fn array(&mut self, src: Source<'s>, attrs: &str, payload: Option<Compressed>) -> Result<(), WriteError> {
        // With a UInt32 header, sizes were checked to fit before writing started.
        let n = src.n_bytes();
        match (self.encoding, payload) {
            (VtuEncoding::Ascii, _) => {
                self.text(&format!("<DataArray {attrs} format=\"ascii\">\n"));
                self.ascii_values(&src)?;
                self.text("</DataArray>\n");
            }
            (VtuEncoding::Base64, payload) => {
                self.text(&format!("<DataArray {attrs} format=\"binary\">\n"));
                match payload {
                    Some(c) => {
                        push_base64(&mut self.buf, &c.header)?;
                        push_base64(&mut self.buf, &c.data)?;
                    }
                    None => {
                        let header = self.header_bytes(n);
                        push_base64(&mut self.buf, &header)?;
                        self.base64_values(&src)?;
                    }
                }
                self.text("\n</DataArray>\n");
            }
            (VtuEncoding::Raw, payload) => {
                self.offset -= appended_len(&src, payload.as_ref(), self.header64);
                self.text(&format!("<DataArray {attrs} format=\"appended\" offset=\"{}\"/>\n", self.offset));
                self.pending.push(match payload {
                    Some(c) => Pending::Compressed(c),
                    None => Pending::Plain(src),
                });
            }
        }
        flush_if_full(&mut self.w, &mut self.buf, CHUNK)?;
        Ok(())
    }

    /// Text values, six per line.
    fn ascii_values(&mut self, src: &Source<'_>) -> Result<(), WriteError> {
        let f32s = src.is_f32();
        let (w, buf) = (&mut self.w, &mut self.buf);
        let mut k = 0usize;
        src.for_each(|_, s| -> std::io::Result<()> {
            match s {
                Scalar::F(x) if f32s => buf.extend_from_slice(zmij::Buffer::new().format(x as f32).as_bytes()),
                Scalar::F(x) => push_f64(buf, x),
                Scalar::I(x) => push_i64(buf, x),
                Scalar::U(x) => push_u64(buf, x),
            }
            k += 1;
            buf.push(if k.is_multiple_of(6) { b'\n' } else { b' ' });
            flush_if_full(w, buf, CHUNK)
        })?;
        if !k.is_multiple_of(6) {
            self.buf.push(b'\n');
        }
        Ok(())
    }

    /// Base64 of the binary values, encoded in chunks of a multiple of 3 bytes
    /// so the concatenation equals the encoding of the whole.
    fn base64_values(&mut self, src: &Source<'_>) -> Result<(), WriteError> {
        const RAW: usize = 3 * 16384;
        let (w, buf) = (&mut self.w, &mut self.buf);
        let mut raw: Vec<u8> = Vec::with_capacity(RAW + 8);
        src.for_each(|bytes, _| -> std::io::Result<()> {
            raw.extend_from_slice(bytes);
            if raw.len() >= RAW {
                let rest = raw.split_off(RAW);
                push_base64(buf, &raw)?;
                raw = rest;
                flush_if_full(w, buf, CHUNK)?;
            }
            Ok(())
        })?;
        push_base64(&mut self.buf, &raw)?;
        Ok(())
    }

    /// Raw encoding: the `<AppendedData>` block with every pending array.
    fn appended(&mut self) -> Result<(), WriteError> {
        if self.encoding != VtuEncoding::Raw {
            return Ok(());
        }
        self.text("<AppendedData encoding=\"raw\">\n_");
        debug_assert_eq!(self.offset, 0, "every appended array was given its offset");
        for pending in std::mem::take(&mut self.pending).into_iter().rev() {
            match pending {
                Pending::Compressed(c) => {
                    self.buf.extend_from_slice(&c.header);
                    flush_if_full(&mut self.w, &mut self.buf, CHUNK)?;
                    self.w.write_all(&self.buf)?;
                    self.buf.clear();
                    self.w.write_all(&c.data)?;
                }
                Pending::Plain(src) => {
                    let header = self.header_bytes(src.n_bytes());
                    self.buf.extend_from_slice(&header);
                    let (w, buf) = (&mut self.w, &mut self.buf);
                    src.for_each(|bytes, _| -> std::io::Result<()> {
                        buf.extend_from_slice(bytes);
                        flush_if_full(w, buf, CHUNK)
                    })?;
                }
            }
        }
        self.text("\n</AppendedData>\n");
        Ok(())
    }

    fn finish(mut self) -> Result<(), WriteError> {
        self.w.write_all(&self.buf)?;
        self.w.flush()?;
        Ok(())
    }
}

/// Append the base64 encoding of `bytes` to `buf`.
fn push_base64(buf: &mut Vec<u8>, bytes: &[u8]) -> std::io::Result<()> {
    let start = buf.len();
    let n =
        base64::encoded_len(bytes.len(), true).ok_or_else(|| std::io::Error::other("base64 length overflows usize"))?;
    buf.resize(start + n, 0);
    let written = B64.encode_slice(bytes, &mut buf[start..]).map_err(std::io::Error::other)?;
    buf.truncate(start + written);
    Ok(())
}

/// Write the triangles of `mesh` with default options (raw appended, zlib, UInt64 headers).
///
/// # Errors
/// A validation error or [`WriteError::Io`].
pub fn write_surface_vtu(w: impl Write, mesh: &TriMesh) -> Result<(), WriteError> {
    write_vtu(w, &VtuMesh::from_surface(mesh), &VtuOptions::default())
}

/// Write the tetrahedra of `mesh` with default options (raw appended, zlib, UInt64 headers).
///
/// # Errors
/// A validation error or [`WriteError::Io`].
pub fn write_volume_vtu(w: impl Write, mesh: &TetMesh) -> Result<(), WriteError> {
    write_vtu(w, &VtuMesh::from_volume(mesh), &VtuOptions::default())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    fn write(mesh: &VtuMesh<'_>, encoding: VtuEncoding, header_type: VtuHeaderType) -> Vec<u8> {
        let mut v = Vec::new();
        write_vtu(&mut v, mesh, &VtuOptions { encoding, header_type, compression: VtuCompression::None }).unwrap();
        v
    }

    fn sample(m: &TriMesh) -> VtuMesh<'_> {
        let mut mesh = VtuMesh::from_surface(m);
        mesh.point_data.push(DataArray::vectors("normal", &m.positions));
        mesh.cell_data.push(DataArray::i32("patch", (0..m.n_faces() as i32).collect::<Vec<_>>()));
        mesh
    }

    /// The text of the `DataArray` named `name`.
    fn array_text<'a>(text: &'a str, name: &str) -> &'a str {
        let start = text.find(&format!("Name=\"{name}\"")).unwrap();
        let open = start + text[start..].find('>').unwrap() + 1;
        let close = open + text[open..].find("</DataArray>").unwrap();
        text[open..close].trim()
    }

    #[test]
    fn ascii_has_counts_offsets_types_and_values() {
        let m = fixtures::square(1);
        let text = String::from_utf8(write(&sample(&m), VtuEncoding::Ascii, VtuHeaderType::UInt64)).unwrap();
        assert!(text.contains("NumberOfPoints=\"4\" NumberOfCells=\"2\""));
        assert_eq!(
            array_text(&text, "connectivity").split_whitespace().collect::<Vec<_>>(),
            ["0", "1", "3", "0", "3", "2"]
        );
        assert_eq!(array_text(&text, "offsets"), "3 6");
        assert_eq!(array_text(&text, "types"), "5 5");
        assert_eq!(array_text(&text, "patch"), "0 1");
        let pts: Vec<f64> = array_text(&text, "Points").split_whitespace().map(|s| s.parse().unwrap()).collect();
        assert_eq!(pts, m.positions.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>());
        assert!(text.contains("type=\"Int32\" Name=\"connectivity\""));
    }

    #[test]
    fn base64_decodes_to_header_and_bytes() {
        let m = fixtures::square(1);
        let text = String::from_utf8(write(&sample(&m), VtuEncoding::Base64, VtuHeaderType::UInt32)).unwrap();
        let s = array_text(&text, "types");
        // Header (4 bytes → 8 chars with padding) encoded apart from the data.
        let header = B64.decode(&s[..8]).unwrap();
        assert_eq!(header, 2u32.to_le_bytes());
        assert_eq!(B64.decode(&s[8..]).unwrap(), [5, 5]);
        // The square's coordinates are exact in `f32`: 4 points × 3 × 4 bytes.
        let p = array_text(&text, "Points");
        assert_eq!(B64.decode(&p[..8]).unwrap(), 48u32.to_le_bytes());
        let xyz: Vec<f64> = B64
            .decode(&p[8..])
            .unwrap()
            .chunks_exact(4)
            .map(|c| f64::from(f32::from_le_bytes(c.try_into().unwrap())))
            .collect();
        assert_eq!(xyz, m.positions.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>());
    }

    #[test]
    fn points_are_float64_unless_every_coordinate_is_an_f32() {
        let mut m = fixtures::square(1);
        let text = String::from_utf8(write(&sample(&m), VtuEncoding::Ascii, VtuHeaderType::UInt32)).unwrap();
        assert!(text.contains("type=\"Float32\" Name=\"Points\""));
        // 0.1 is not an f32: one such coordinate keeps every point in Float64, exactly.
        m.positions[2].x = 0.1;
        let text = String::from_utf8(write(&sample(&m), VtuEncoding::Base64, VtuHeaderType::UInt32)).unwrap();
        assert!(text.contains("type=\"Float64\" Name=\"Points\""));
        let p = array_text(&text, "Points");
        assert_eq!(B64.decode(&p[..8]).unwrap(), 96u32.to_le_bytes());
        let xyz: Vec<f64> =
            B64.decode(&p[8..]).unwrap().chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
        assert_eq!(xyz, m.positions.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>());
    }

    #[test]
    fn raw_appended_offsets_point_at_headers() {
        let m = fixtures::square(2);
        let bytes = write(&sample(&m), VtuEncoding::Raw, VtuHeaderType::UInt64);
        let marker = b"<AppendedData encoding=\"raw\">\n_";
        let start = bytes.windows(marker.len()).position(|w| w == marker).unwrap() + marker.len();
        let head = String::from_utf8_lossy(&bytes[..start]).into_owned();
        let offsets: Vec<usize> = head
            .match_indices("offset=\"")
            .map(|(i, _)| head[i + 8..].split('"').next().unwrap().parse().unwrap())
            .collect();
        assert_eq!(offsets.len(), 6);
        // `normal` (the positions as f64 data), patch, Points (exact in f32:
        // 12 bytes each), connectivity, offsets, types.
        let expected_sizes = [24 * 9, 4 * 8, 12 * 9, 4 * 24, 4 * 8, 8];
        for (o, n) in offsets.iter().zip(expected_sizes) {
            let h = u64::from_le_bytes(bytes[start + o..start + o + 8].try_into().unwrap());
            assert_eq!(h as usize, n);
        }
        assert!(bytes.ends_with(b"\n</AppendedData>\n</VTKFile>\n"));
    }

    #[test]
    fn convenience_writers_use_the_defaults() {
        let m = fixtures::torus(1.0, 0.3, 6, 4);
        let mut a = Vec::new();
        write_surface_vtu(&mut a, &m).unwrap();
        let mut b = Vec::new();
        write_vtu(&mut b, &VtuMesh::from_surface(&m), &VtuOptions::default()).unwrap();
        assert_eq!(a, b);
        assert!(String::from_utf8_lossy(&a).contains("compressor=\"vtkZLibDataCompressor\""));
        let tets = TetMesh {
            positions: vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            tets: vec![[0, 1, 2, 3].map(VertexId)],
        };
        let mut v = Vec::new();
        write_volume_vtu(&mut v, &tets).unwrap();
        let text = String::from_utf8_lossy(&v);
        assert!(text.contains("NumberOfPoints=\"4\" NumberOfCells=\"1\""));
        let ascii =
            String::from_utf8(write(&VtuMesh::from_volume(&tets), VtuEncoding::Ascii, VtuHeaderType::UInt64)).unwrap();
        assert_eq!(array_text(&ascii, "types"), "10");
        assert_eq!(array_text(&ascii, "offsets"), "4");
    }

    #[test]
    fn each_array_is_coded_as_its_sample_favours_and_inflates_back() {
        use rand::{Rng, SeedableRng};
        use std::io::Read;
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let bytes = |v: Vec<u32>| v.into_iter().flat_map(u32::to_le_bytes).collect::<Vec<u8>>();
        // Unit-vector-like floats: matching finds nothing, Huffman coding the
        // exponent bytes does.
        let noisy = bytes((0..100_000).map(|_| rng.random_range(-1.0f32..1.0).to_bits()).collect());
        // Strip connectivity (i, i+1, i+2): long repeats, which level 2 matches.
        let strip = bytes((0..100_000u32).flat_map(|i| [i, i + 1, i + 2]).collect());
        let noisy_config = deflate_config(&noisy[..SAMPLE]).unwrap();
        assert_eq!(noisy_config.strategy, zlib_rs::Strategy::HuffmanOnly);
        let strip_config = deflate_config(&strip[..SAMPLE]).unwrap();
        assert_eq!((strip_config.level, strip_config.strategy), (2, zlib_rs::Strategy::Default));
        for (data, config) in [(&noisy, noisy_config), (&strip, strip_config), (&strip, zlib_rs::DeflateConfig::new(1))]
        {
            let block = &data[..ZLIB_BLOCK];
            let z = deflate_block(block, config).unwrap();
            let mut back = Vec::new();
            flate2::read::ZlibDecoder::new(&z[..]).read_to_end(&mut back).unwrap();
            assert_eq!(back, block);
        }
        assert!(deflate_block(&noisy[..ZLIB_BLOCK], noisy_config).unwrap().len() < ZLIB_BLOCK * 95 / 100);
    }

    #[test]
    fn validation() {
        let m = fixtures::square(1);
        let mut mesh = sample(&m);
        mesh.cell_data[0].values = DataValues::Int32(vec![1].into());
        let mut v = Vec::new();
        assert!(matches!(
            write_vtu(&mut v, &mesh, &VtuOptions::default()),
            Err(WriteError::LengthMismatch { expected: 2, got: 1, .. })
        ));
        let bad = [[VertexId(0), VertexId(7)]];
        let mesh = VtuMesh { points: &m.positions, cells: vec![CellBlock::Lines(&bad)], ..Default::default() };
        assert!(matches!(
            write_vtu(&mut v, &mesh, &VtuOptions::default()),
            Err(WriteError::IndexOutOfRange { index: 7, .. })
        ));
        assert!(v.is_empty());
    }
}
