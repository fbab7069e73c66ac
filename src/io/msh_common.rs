//! What the MSH 2.2 and 4.1 readers share: the `$MeshFormat` header and the
//! dispatch by version, Gmsh's element type table, node-tag lookup, and the
//! small helpers both use for binary data and section ends.
//!
//! An MSH file is a sequence of sections `$Name … $EndName`. The first
//! (after optional `$Comments`) is `$MeshFormat` with the line
//! `version file-type data-size`: file-type 0 is ASCII, 1 binary. A binary
//! file then stores the `int` 1 in the writer's byte order, which tells the
//! endianness. Versions 2.x go to [`crate::io::msh22::read`], 4.1 to
//! [`crate::io::msh41::read`]; 4.0 and older formats are refused with a hint.
//!
//! Node tags are arbitrary positive integers, possibly with gaps: they are
//! mapped to dense 0-based indices with a vector when the tags are dense
//! enough (`max − min < 4·n + 1024`), else with a hash map.

use super::source::{Endian, MeshSink, Source};
use super::{Format, IoError, Limits, Location, RawMesh};
use std::io::BufRead;

/// Element types of Gmsh's MSH format: `(type, name, number of nodes)`,
/// as reported by `gmsh.model.mesh.getElementProperties` (Gmsh 4.15) and
/// `GmshDefines.h`. Types of variable size (polygons, polyhedra) or unknown
/// size are absent; they can be skipped in ASCII files only.
pub const ELEMENT_TYPES: &[(i32, &str, usize)] = &[
    (1, "Line 2", 2),
    (2, "Triangle 3", 3),
    (3, "Quadrilateral 4", 4),
    (4, "Tetrahedron 4", 4),
    (5, "Hexahedron 8", 8),
    (6, "Prism 6", 6),
    (7, "Pyramid 5", 5),
    (8, "Line 3", 3),
    (9, "Triangle 6", 6),
    (10, "Quadrilateral 9", 9),
    (11, "Tetrahedron 10", 10),
    (12, "Hexahedron 27", 27),
    (13, "Prism 18", 18),
    (14, "Pyramid 14", 14),
    (15, "Point", 1),
    (16, "Quadrilateral 8", 8),
    (17, "Hexahedron 20", 20),
    (18, "Prism 15", 15),
    (19, "Pyramid 13", 13),
    (20, "Triangle 9", 9),
    (21, "Triangle 10", 10),
    (22, "Triangle 12", 12),
    (23, "Triangle 15", 15),
    (24, "Triangle 15I", 15),
    (25, "Triangle 21", 21),
    (26, "Line 4", 4),
    (27, "Line 5", 5),
    (28, "Line 6", 6),
    (29, "Tetrahedron 20", 20),
    (30, "Tetrahedron 35", 35),
    (31, "Tetrahedron 56", 56),
    (32, "Tetrahedron 22", 22),
    (33, "Tetrahedron 28", 28),
    (36, "Quadrilateral 16", 16),
    (37, "Quadrilateral 25", 25),
    (38, "Quadrilateral 36", 36),
    (39, "Quadrilateral 12", 12),
    (40, "Quadrilateral 16I", 16),
    (41, "Quadrilateral 20", 20),
    (42, "Triangle 28", 28),
    (43, "Triangle 36", 36),
    (44, "Triangle 45", 45),
    (45, "Triangle 55", 55),
    (46, "Triangle 66", 66),
    (47, "Quadrilateral 49", 49),
    (48, "Quadrilateral 64", 64),
    (49, "Quadrilateral 81", 81),
    (50, "Quadrilateral 100", 100),
    (51, "Quadrilateral 121", 121),
    (52, "Triangle 18", 18),
    (53, "Triangle 21I", 21),
    (54, "Triangle 24", 24),
    (55, "Triangle 27", 27),
    (56, "Triangle 30", 30),
    (57, "Quadrilateral 24", 24),
    (58, "Quadrilateral 28", 28),
    (59, "Quadrilateral 32", 32),
    (60, "Quadrilateral 36I", 36),
    (61, "Quadrilateral 40", 40),
    (62, "Line 7", 7),
    (63, "Line 8", 8),
    (64, "Line 9", 9),
    (65, "Line 10", 10),
    (66, "Line 11", 11),
    (71, "Tetrahedron 84", 84),
    (72, "Tetrahedron 120", 120),
    (73, "Tetrahedron 165", 165),
    (74, "Tetrahedron 220", 220),
    (75, "Tetrahedron 286", 286),
    (79, "Tetrahedron 34", 34),
    (80, "Tetrahedron 40", 40),
    (81, "Tetrahedron 46", 46),
    (82, "Tetrahedron 52", 52),
    (83, "Tetrahedron 58", 58),
    (84, "Line 1", 1),
    (85, "Triangle 1", 1),
    (86, "Quadrilateral 1", 1),
    (87, "Tetrahedron 1", 1),
    (88, "Hexahedron 1", 1),
    (89, "Prism 1", 1),
    (90, "Prism 40", 40),
    (91, "Prism 75", 75),
    (92, "Hexahedron 64", 64),
    (93, "Hexahedron 125", 125),
    (94, "Hexahedron 216", 216),
    (95, "Hexahedron 343", 343),
    (96, "Hexahedron 512", 512),
    (97, "Hexahedron 729", 729),
    (98, "Hexahedron 1000", 1000),
    (99, "Hexahedron 32", 32),
    (100, "Hexahedron 44", 44),
    (101, "Hexahedron 56", 56),
    (102, "Hexahedron 68", 68),
    (103, "Hexahedron 80", 80),
    (104, "Hexahedron 92", 92),
    (105, "Hexahedron 104", 104),
    (106, "Prism 126", 126),
    (107, "Prism 196", 196),
    (108, "Prism 288", 288),
    (109, "Prism 405", 405),
    (110, "Prism 550", 550),
    (111, "Prism 24", 24),
    (112, "Prism 33", 33),
    (113, "Prism 42", 42),
    (114, "Prism 51", 51),
    (115, "Prism 60", 60),
    (116, "Prism 69", 69),
    (117, "Prism 78", 78),
    (118, "Pyramid 30", 30),
    (119, "Pyramid 55", 55),
    (120, "Pyramid 91", 91),
    (121, "Pyramid 140", 140),
    (122, "Pyramid 204", 204),
    (123, "Pyramid 285", 285),
    (124, "Pyramid 385", 385),
    (125, "Pyramid 21", 21),
    (126, "Pyramid 29", 29),
    (127, "Pyramid 37", 37),
    (128, "Pyramid 45", 45),
    (129, "Pyramid 53", 53),
    (130, "Pyramid 61", 61),
    (131, "Pyramid 69", 69),
    (132, "Pyramid 1", 1),
    (137, "Tetrahedron 16", 16),
];

/// Gmsh type of the 3-node triangle.
pub const TRIANGLE: i32 = 2;
/// Gmsh type of the 4-node tetrahedron.
pub const TETRAHEDRON: i32 = 4;

/// Name and node count of element type `t`, when it has a fixed size.
pub fn element_info(t: i32) -> Option<(&'static str, usize)> {
    ELEMENT_TYPES.binary_search_by_key(&t, |e| e.0).ok().map(|i| (ELEMENT_TYPES[i].1, ELEMENT_TYPES[i].2))
}

/// The name under which skipped elements of type `t` are counted.
pub fn element_name(t: i32) -> String {
    match element_info(t) {
        Some((name, _)) => name.to_string(),
        None => format!("element type {t}"),
    }
}

/// MSH versions this crate reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Version {
    /// 2.0, 2.1 or 2.2.
    V2,
    /// 4.1.
    V41,
}

/// The `$MeshFormat` header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Format version.
    pub version: Version,
    /// Byte order when binary, `None` for ASCII files.
    pub binary: Option<Endian>,
}

/// Read an MSH file (2.x or 4.1, ASCII or binary).
///
/// # Errors
/// A missing or unsupported `$MeshFormat`, and every error of the version readers.
pub fn read<R: BufRead>(reader: R, limits: &Limits) -> Result<RawMesh, IoError> {
    let mut src = Source::new(reader, Format::Msh);
    let header = read_header(&mut src)?;
    let mut sink = MeshSink::new(Format::Msh, *limits);
    match header.version {
        Version::V2 => super::msh22::read::read_body(&mut src, header.binary, &mut sink)?,
        Version::V41 => super::msh41::read::read_body(&mut src, header.binary, &mut sink)?,
    }
    Ok(sink.mesh)
}

/// Find and parse `$MeshFormat … $EndMeshFormat`.
fn read_header<R: BufRead>(src: &mut Source<R>) -> Result<Header, IoError> {
    loop {
        if !src.next_line()? {
            return Err(src.truncated_at(src.at_line(), "no `$MeshFormat` section"));
        }
        let line = src.text().trim_ascii();
        if line.is_empty() {
            continue;
        }
        if line == b"$MeshFormat" {
            break;
        }
        if line == b"$Comments" {
            src.skip_to_marker(b"$EndComments", true)?;
            continue;
        }
        return Err(src.parse_error(format!("expected `$MeshFormat` first, found `{}`", super::source::show(line))));
    }
    let v = src.expect_token("the MSH version")?.to_vec();
    let file_type = src.expect_u64("the file type (0 = ASCII, 1 = binary)")?;
    let data_size = src.expect_u64("the data size")?;
    let at = src.at_line();
    let version = match v.as_slice() {
        b"2" | b"2.0" | b"2.1" | b"2.2" => Version::V2,
        b"4.1" => Version::V41,
        other => {
            let hint = if other.starts_with(b"4") || other.starts_with(b"3") {
                "; save it as MSH 4.1 or 2.2 (Gmsh: -format msh41)"
            } else {
                ""
            };
            return Err(IoError::Unsupported {
                format: Format::Msh,
                at,
                feature: format!("MSH version {}{hint}", super::source::show(other)),
            });
        }
    };
    if !src.line_done() {
        return Err(src.parse_error("unexpected extra numbers on the `$MeshFormat` line"));
    }
    let binary = match file_type {
        0 => None,
        1 => {
            if data_size != 8 {
                return Err(IoError::Unsupported {
                    format: Format::Msh,
                    at,
                    feature: format!("binary data size {data_size} (only 8 is supported)"),
                });
            }
            let one: [u8; 4] = src.read_array("the binary byte-order marker (int 1)")?;
            Some(match (i32::from_le_bytes(one), i32::from_be_bytes(one)) {
                (1, _) => Endian::Little,
                (_, 1) => Endian::Big,
                _ => {
                    return Err(src.parse_error_at(
                        Location::Byte(src.offset() - 4),
                        format!("binary byte-order marker is {one:?}, expected the int 1"),
                    ));
                }
            })
        }
        t => return Err(src.parse_error(format!("file type {t}, expected 0 (ASCII) or 1 (binary)"))),
    };
    src.expect_marker(b"$EndMeshFormat", binary.is_some())?;
    Ok(Header { version, binary })
}

/// Maps node tags to 0-based vertex indices.
#[derive(Debug, Default)]
pub struct NodeTable {
    /// Tag of each vertex, in reading order.
    tags: Vec<u64>,
    /// Where each vertex was read (for errors naming both copies of a tag).
    at: Vec<Location>,
    lookup: Lookup,
}

/// A node tag defined twice; the places of its first and second definition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DuplicateTag {
    /// The tag.
    pub tag: u64,
    /// Vertex index and place of the first node with the tag.
    pub first: (u32, Location),
    /// Vertex index and place of the later node with the tag.
    pub second: (u32, Location),
}

/// Tag → index lookup, rebuilt when nodes are added.
#[derive(Debug, Default)]
enum Lookup {
    /// Not built (or stale).
    #[default]
    None,
    /// `index[tag − min]`, `u32::MAX` for no node.
    Dense { min: u64, index: Vec<u32> },
    /// Sparse tags.
    Sparse(foldhash::HashMap<u64, u32>),
}

impl NodeTable {
    /// Record that vertex `index` has tag `tag`.
    pub fn push(&mut self, tag: u64, index: u32, at: Location) {
        debug_assert_eq!(index as usize, self.tags.len());
        self.tags.push(tag);
        self.at.push(at);
        self.lookup = Lookup::None;
    }

    /// Reserve room for `n` more tags.
    pub fn reserve(&mut self, n: usize) {
        self.tags.reserve(n);
        self.at.reserve(n);
    }

    /// Build the lookup if needed; returns the number of duplicate tags
    /// whose nodes `same(first, second)` accepts as one (the first node with
    /// a tag wins, as in Gmsh).
    ///
    /// # Errors
    /// The first duplicate tag whose two nodes `same` rejects.
    pub fn build(&mut self, same: impl Fn(u32, u32) -> bool) -> Result<usize, DuplicateTag> {
        if !matches!(self.lookup, Lookup::None) || self.tags.is_empty() {
            return Ok(0);
        }
        let dup = |tags: &[u64], at: &[Location], first: u32, second: usize| -> Result<(), DuplicateTag> {
            if same(first, second as u32) {
                return Ok(());
            }
            Err(DuplicateTag {
                tag: tags[second],
                first: (first, at[first as usize]),
                second: (second as u32, at[second]),
            })
        };
        let (min, max) = self.tags.iter().fold((u64::MAX, 0), |(lo, hi), &t| (lo.min(t), hi.max(t)));
        let n = self.tags.len() as u64;
        let mut duplicates = 0;
        if max - min < 4 * n + 1024 {
            let mut index = vec![u32::MAX; (max - min + 1) as usize];
            for (i, &t) in self.tags.iter().enumerate() {
                let slot = &mut index[(t - min) as usize];
                if *slot == u32::MAX {
                    *slot = i as u32;
                } else {
                    dup(&self.tags, &self.at, *slot, i)?;
                    duplicates += 1;
                }
            }
            self.lookup = Lookup::Dense { min, index };
        } else {
            let mut map = foldhash::HashMap::with_capacity_and_hasher(self.tags.len(), Default::default());
            for (i, &t) in self.tags.iter().enumerate() {
                match map.entry(t) {
                    std::collections::hash_map::Entry::Occupied(o) => {
                        dup(&self.tags, &self.at, *o.get(), i)?;
                        duplicates += 1;
                    }
                    std::collections::hash_map::Entry::Vacant(v) => {
                        v.insert(i as u32);
                    }
                }
            }
            self.lookup = Lookup::Sparse(map);
        }
        Ok(duplicates)
    }

    /// The vertex index of `tag` (after [`Self::build`]).
    #[inline]
    pub fn get(&self, tag: u64) -> Option<u32> {
        match &self.lookup {
            Lookup::None => None,
            Lookup::Dense { min, index } => {
                let i = tag.checked_sub(*min)?;
                index.get(usize::try_from(i).ok()?).copied().filter(|&v| v != u32::MAX)
            }
            Lookup::Sparse(map) => map.get(&tag).copied(),
        }
    }

    /// Number of nodes recorded.
    pub fn len(&self) -> usize {
        self.tags.len()
    }

    /// True when no node has been recorded.
    pub fn is_empty(&self) -> bool {
        self.tags.is_empty()
    }
}

/// Build the node lookup before an `$Elements` section. A tag given twice
/// with the same coordinates (bit for bit) is tolerated and counted as
/// skipped (`duplicate node tag`; the first node wins, as in Gmsh); with
/// different coordinates the file is ambiguous and refused.
///
/// # Errors
/// Elements before any node; a tag defined twice with different coordinates
/// (a parse error naming the tag and both places).
pub fn prepare_nodes<R: BufRead>(src: &Source<R>, nodes: &mut NodeTable, sink: &mut MeshSink) -> Result<(), IoError> {
    if nodes.is_empty() {
        return Err(src.parse_error("`$Elements` before any `$Nodes`"));
    }
    let positions = &sink.mesh.positions;
    let same = |a: u32, b: u32| positions.get(a as usize) == positions.get(b as usize);
    match nodes.build(same) {
        Ok(dup) => {
            sink.skip("duplicate node tag", dup);
            Ok(())
        }
        Err(d) => {
            let p =
                |i: u32| positions.get(i as usize).map(|v| format!("({}, {}, {})", v.x, v.y, v.z)).unwrap_or_default();
            Err(src.parse_error_at(
                d.second.1,
                format!(
                    "node tag {} is defined twice with different coordinates: {} at {} and {} at {}",
                    d.tag,
                    p(d.first.0),
                    d.first.1,
                    p(d.second.0),
                    d.second.1
                ),
            ))
        }
    }
}

/// Map the node tags of element `elem_tag` (at most 4) to vertex indices;
/// the first `tags.len()` entries of the result are set.
///
/// # Errors
/// [`IoError::IndexOutOfRange`] naming the element and the unknown node tag.
#[inline]
pub fn lookup_nodes(nodes: &NodeTable, tags: &[u64], elem_tag: u64, at: Location) -> Result<[u32; 4], IoError> {
    let mut out = [0u32; 4];
    for (o, &t) in out.iter_mut().zip(tags.iter()) {
        *o = nodes.get(t).ok_or_else(|| IoError::IndexOutOfRange {
            format: Format::Msh,
            element: format!("element {elem_tag}"),
            index: i64::try_from(t).unwrap_or(i64::MAX),
            available: format!("no node has that tag ({} nodes read)", nodes.len()),
            at,
        })?;
    }
    Ok(out)
}

/// Keep a triangle or tetrahedron given by its node indices.
///
/// # Errors
/// Limits exceeded.
#[inline]
pub fn keep_element(sink: &mut MeshSink, ty: i32, v: &[u32], at: Location) -> Result<(), IoError> {
    match (ty, v) {
        (TRIANGLE, &[a, b, c]) => sink.triangle([a, b, c], at),
        (TETRAHEDRON, &[a, b, c, d]) => sink.tet([a, b, c, d], at),
        _ => Ok(()),
    }
}

/// The end marker of a section: `$End` + name.
pub fn end_marker(name: &[u8]) -> Vec<u8> {
    let mut m = b"$End".to_vec();
    m.extend_from_slice(name);
    m
}

/// In ASCII sections, nothing may follow the last record on its line.
///
/// # Errors
/// [`IoError::Parse`] naming the unexpected token.
pub fn check_line_done<R: BufRead>(src: &mut Source<R>, name: &str) -> Result<(), IoError> {
    if src.line_done() {
        return Ok(());
    }
    src.next_token()?;
    Err(src.parse_error(format!("unexpected `{}` in `${name}`", super::source::show(src.token()))))
}

/// Read a binary `u64` (`size_t`).
///
/// # Errors
/// Truncation.
#[inline]
pub fn read_u64<R: BufRead>(src: &mut Source<R>, e: Endian, what: &str) -> Result<u64, IoError> {
    Ok(e.u64(src.read_array(what)?))
}

/// Read a binary `i32` (`int`).
///
/// # Errors
/// Truncation.
#[inline]
pub fn read_i32<R: BufRead>(src: &mut Source<R>, e: Endian, what: &str) -> Result<i32, IoError> {
    Ok(e.i32(src.read_array(what)?))
}

/// Read a binary `f64` (`double`).
///
/// # Errors
/// Truncation.
#[inline]
pub fn read_f64<R: BufRead>(src: &mut Source<R>, e: Endian, what: &str) -> Result<f64, IoError> {
    Ok(e.f64(src.read_array(what)?))
}

/// Skip `count` items of `size` bytes (overflow-checked).
///
/// # Errors
/// Truncation.
pub fn skip_items<R: BufRead>(src: &mut Source<R>, count: u64, size: u64, what: &str) -> Result<(), IoError> {
    match count.checked_mul(size) {
        Some(n) => src.skip_bytes(n, what),
        None => Err(src.truncated_at(src.at_byte(), format!("{count} × {size} bytes of {what}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::failure::FailureKind;

    #[test]
    fn element_table_is_sorted_and_knows_the_common_types() {
        assert!(ELEMENT_TYPES.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!(element_info(2), Some(("Triangle 3", 3)));
        assert_eq!(element_info(4), Some(("Tetrahedron 4", 4)));
        assert_eq!(element_info(15), Some(("Point", 1)));
        assert_eq!(element_info(34), None);
        assert_eq!(element_name(34), "element type 34");
    }

    #[test]
    fn node_table_dense_and_sparse() {
        let mut t = NodeTable::default();
        for (i, tag) in [5u64, 7, 6, 7].into_iter().enumerate() {
            t.push(tag, i as u32, Location::Line(i as u64 + 1));
        }
        assert_eq!(t.build(|_, _| true), Ok(1));
        assert_eq!((t.get(5), t.get(6), t.get(7), t.get(8), t.get(1)), (Some(0), Some(2), Some(1), None, None));
        let mut t = NodeTable::default();
        for (i, tag) in [1u64, 1 << 40, 3, 1 << 40].into_iter().enumerate() {
            t.push(tag, i as u32, Location::Byte(10 * i as u64));
        }
        assert_eq!(t.build(|_, _| true), Ok(1));
        assert_eq!((t.get(1 << 40), t.get(3), t.get(2)), (Some(1), Some(2), None));
    }

    #[test]
    fn node_table_reports_a_rejected_duplicate_with_both_places() {
        for tags in [[5u64, 7, 6, 7], [1, 1 << 40, 3, 1 << 40]] {
            let mut t = NodeTable::default();
            for (i, tag) in tags.into_iter().enumerate() {
                t.push(tag, i as u32, Location::Line(i as u64 + 1));
            }
            let d = t.build(|_, _| false).unwrap_err();
            assert_eq!(d, DuplicateTag { tag: tags[3], first: (1, Location::Line(2)), second: (3, Location::Line(4)) });
        }
    }

    #[test]
    fn header_versions() {
        let lim = Limits::from_max_triangles(10);
        let e = read("$MeshFormat\n4 0 8\n$EndMeshFormat\n".as_bytes(), &lim).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Unsupported);
        assert!(e.to_string().contains("MSH version 4") && e.to_string().contains("msh41"), "{e}");
        let e = read("$Nodes\n".as_bytes(), &lim).unwrap_err();
        assert!(e.to_string().contains("expected `$MeshFormat` first"), "{e}");
        let e = read("$MeshFormat\n2.2 0 8\n".as_bytes(), &lim).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        let e = read("$MeshFormat\n2.2 1 4\n".as_bytes(), &lim).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Unsupported);
        let e = read("$MeshFormat\n2.2 1 8\n\x07\x00\x00\x00\n$EndMeshFormat\n".as_bytes(), &lim).unwrap_err();
        assert!(e.to_string().contains("byte-order marker"), "{e}");
        let e = read("$MeshFormat\n2.2 0 8 9\n$EndMeshFormat\n".as_bytes(), &lim).unwrap_err();
        assert!(e.to_string().contains("extra numbers"), "{e}");
        let e = read("$MeshFormat\n2.2 2 8\n$EndMeshFormat\n".as_bytes(), &lim).unwrap_err();
        assert!(e.to_string().contains("file type 2"), "{e}");
        // Comments before the header are skipped.
        let ok = "$Comments\nhello\n$EndComments\n$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n$EndNodes\n$Elements\n1\n1 2 0 1 2 3\n$EndElements\n";
        assert_eq!(read(ok.as_bytes(), &lim).unwrap().triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn section_structure_errors() {
        let lim = Limits::from_max_triangles(10);
        for v in ["2.2", "4.1"] {
            let head = format!("$MeshFormat\n{v} 0 8\n$EndMeshFormat\n");
            let e = read(format!("{head}$Elements\n0\n$EndElements\n").as_bytes(), &lim).unwrap_err();
            assert!(e.to_string().contains("before any `$Nodes`") && e.to_string().contains("line 4"), "{v}: {e}");
            let e = read(format!("{head}garbage\n").as_bytes(), &lim).unwrap_err();
            assert!(e.to_string().contains("expected a section") && e.to_string().contains("line 4"), "{v}: {e}");
            let e = read(format!("{head}$MeshFormat\n").as_bytes(), &lim).unwrap_err();
            assert!(e.to_string().contains("second `$MeshFormat`"), "{v}: {e}");
            let e = read(format!("{head}$Unknown\n1 2 3\n").as_bytes(), &lim).unwrap_err();
            assert!(e.kind() == FailureKind::Truncated && e.to_string().contains("$EndUnknown"), "{v}: {e}");
        }
        // Binary 2.2: a block claiming more elements than announced, a negative node tag.
        let mut b = b"$MeshFormat\n2.2 1 8\n".to_vec();
        b.extend_from_slice(&1i32.to_le_bytes());
        b.extend_from_slice(b"\n$EndMeshFormat\n$Nodes\n1\n");
        b.extend_from_slice(&(-5i32).to_le_bytes());
        b.extend_from_slice(&[0u8; 24]);
        let e = read(&b[..], &lim).unwrap_err();
        assert!(e.to_string().contains("negative node tag -5") && e.to_string().contains("byte offset 49"), "{e}");
        let mut b = b"$MeshFormat\n2.2 1 8\n".to_vec();
        b.extend_from_slice(&1i32.to_le_bytes());
        b.extend_from_slice(b"\n$EndMeshFormat\n$Nodes\n1\n");
        b.extend_from_slice(&5i32.to_le_bytes());
        b.extend_from_slice(&[0u8; 24]);
        b.extend_from_slice(b"\n$EndNodes\n$Elements\n1\n");
        for x in [15i32, 2, 2] {
            b.extend_from_slice(&x.to_le_bytes());
        }
        let e = read(&b[..], &lim).unwrap_err();
        assert!(e.to_string().contains("block of 2 elements, but 1 of the 1"), "{e}");
    }
}
