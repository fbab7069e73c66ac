//! MSH 4.1 reader (body after `$MeshFormat`).
//!
//! ASCII layout (binary is the same sequence with `size_t` = 8-byte
//! unsigned, `int` = 4 bytes, `double` = 8 bytes, and no line breaks):
//! ```text
//! $Nodes
//! numEntityBlocks numNodes minNodeTag maxNodeTag
//! entityDim entityTag parametric numNodesInBlock     (per block)
//! nodeTag                                            (numNodesInBlock times)
//! x y z [u [v [w]]]                                  (numNodesInBlock times)
//! $EndNodes
//! $Elements
//! numEntityBlocks numElements minElementTag maxElementTag
//! entityDim entityTag elementType numElementsInBlock (per block)
//! elementTag nodeTag…                                (numElementsInBlock times)
//! $EndElements
//! ```
//! Parametric node blocks (`parametric = 1`) carry `entityDim` extra
//! coordinates per node (u on curves, u v on surfaces, u v w in volumes);
//! they are read past. Node tags need not be contiguous or sorted.
//!
//! `$Entities` and `$PartitionedEntities` are skipped: in ASCII by their end
//! line, in binary by walking their structure (counts are `size_t`, tags
//! `int`; points have a 3-double box, other entities 6 doubles, physical
//! tags and bounding entities are counted lists; partitioned entities add
//! parent dim/tag, a partition list, and a ghost-entity list up front), as
//! Gmsh's own reader does. `$Parametrizations`, `$Periodic`, `$NodeData`,
//! `$ElementData`, `$PhysicalNames`, `$Comments` and unknown sections are
//! skipped up to their `$End…` line. Triangles (type 2) and tetrahedra
//! (type 4) are kept; every other element type of Gmsh's table is skipped
//! and counted by its Gmsh name; a type number not in the table (or of no
//! fixed size) is refused as `unsupported`, naming the type and the block.
//!
//! Consistency: the header's `numNodes` / `numElements` must equal the sum
//! of the block sizes, and every tag read must lie in the header's
//! `[minTag, maxTag]` (element tags of skipped binary blocks are not read);
//! a node tag given twice is tolerated only with bit-identical coordinates
//! (see [`prepare_nodes`]). Each error names the line (byte offset).

use crate::io::msh_common::{
    NodeTable, TETRAHEDRON, TRIANGLE, check_line_done, element_info, end_marker, keep_element, lookup_nodes,
    prepare_nodes, read_i32, read_u64, skip_items,
};
use crate::io::source::{Endian, MeshSink, Source, capacity_hint, show};
use crate::io::{Format, IoError, Location};
use std::io::BufRead;

/// Read the sections after `$MeshFormat` into `sink`.
///
/// # Errors
/// Malformed sections (line or byte offset), truncation, unknown node tags,
/// non-finite coordinates, limits exceeded.
pub fn read_body<R: BufRead>(src: &mut Source<R>, binary: Option<Endian>, sink: &mut MeshSink) -> Result<(), IoError> {
    let mut nodes = NodeTable::default();
    while src.next_line()? {
        let line = src.text().trim_ascii();
        if line.is_empty() {
            continue;
        }
        let Some(name) = line.strip_prefix(b"$") else {
            return Err(src.parse_error(format!("expected a section such as `$Nodes`, found `{}`", show(line))));
        };
        let name = name.to_vec();
        let end = end_marker(&name);
        match (name.as_slice(), binary) {
            (b"Entities" | b"PartitionedEntities", Some(e)) => {
                skip_entities_binary(src, e, name.as_slice() == b"PartitionedEntities")?;
                src.expect_marker(&end, true)?;
            }
            (b"Nodes", _) => read_nodes(src, binary, sink, &mut nodes)?,
            (b"Elements", _) => {
                prepare_nodes(src, &mut nodes, sink)?;
                read_elements(src, binary, sink, &nodes)?;
            }
            (b"MeshFormat", _) => return Err(src.parse_error("a second `$MeshFormat` section")),
            _ => src.skip_to_marker(&end, true)?,
        }
    }
    Ok(())
}

/// Walk a binary `$Entities` / `$PartitionedEntities` section without keeping it.
fn skip_entities_binary<R: BufRead>(src: &mut Source<R>, e: Endian, partitioned: bool) -> Result<(), IoError> {
    if partitioned {
        read_u64(src, e, "the number of partitions")?;
        let n_ghost = read_u64(src, e, "the number of ghost entities")?;
        skip_items(src, n_ghost, 8, "ghost entity tags")?;
    }
    let mut counts = [0u64; 4];
    for c in &mut counts {
        *c = read_u64(src, e, "an entity count")?;
    }
    for (dim, &count) in counts.iter().enumerate() {
        for _ in 0..count {
            if partitioned {
                src.skip_bytes(12, "entity tag, parent dimension and parent tag")?;
                let n_parts = read_u64(src, e, "the number of partitions of an entity")?;
                skip_items(src, n_parts, 4, "partition tags")?;
            } else {
                src.skip_bytes(4, "an entity tag")?;
            }
            src.skip_bytes(if dim == 0 { 24 } else { 48 }, "an entity bounding box")?;
            let n_phys = read_u64(src, e, "the number of physical tags")?;
            skip_items(src, n_phys, 4, "physical tags")?;
            if dim > 0 {
                let n_bound = read_u64(src, e, "the number of bounding entities")?;
                skip_items(src, n_bound, 4, "bounding entity tags")?;
            }
        }
    }
    Ok(())
}

/// Block header fields shared by nodes and elements.
struct Block {
    dim: i64,
    /// `parametric` for node blocks, element type for element blocks.
    kind: i64,
    count: u64,
}

/// Read a block header (`dim tag kind count`).
fn read_block<R: BufRead>(
    src: &mut Source<R>,
    binary: Option<Endian>,
    what: &str,
) -> Result<(Block, Location), IoError> {
    match binary {
        None => {
            let dim = src.expect_i64(&format!("the entity dimension of a {what} block"))?;
            let at = src.at_line();
            src.expect_i64("the entity tag")?;
            let kind = src.expect_i64(if what == "node" { "the parametric flag" } else { "the element type" })?;
            let count = src.expect_u64(&format!("the number of {what}s in the block"))?;
            Ok((Block { dim, kind, count }, at))
        }
        Some(e) => {
            let at = src.at_byte();
            let dim = i64::from(read_i32(src, e, "the entity dimension of a block")?);
            read_i32(src, e, "the entity tag of a block")?;
            let kind = i64::from(read_i32(src, e, "the block kind")?);
            let count = read_u64(src, e, "the block size")?;
            Ok((Block { dim, kind, count }, at))
        }
    }
}

/// Read the four `size_t` of a section header.
fn read_section_header<R: BufRead>(
    src: &mut Source<R>,
    binary: Option<Endian>,
    what: &str,
) -> Result<[u64; 4], IoError> {
    let mut h = [0u64; 4];
    for v in &mut h {
        *v = match binary {
            None => src.expect_u64(&format!("the {what} section header (4 numbers)"))?,
            Some(e) => read_u64(src, e, &format!("the {what} section header"))?,
        };
    }
    Ok(h)
}

/// A section header (`numEntityBlocks numItems minTag maxTag`) and where it is.
fn read_counted_header<R: BufRead>(
    src: &mut Source<R>,
    binary: Option<Endian>,
    what: &str,
) -> Result<([u64; 4], Location), IoError> {
    let before = src.at_byte();
    let h = read_section_header(src, binary, what)?;
    Ok((h, if binary.is_some() { before } else { src.at_line() }))
}

/// A tag outside the header's `[minTag, maxTag]` makes the file inconsistent
/// (Gmsh sizes its tag tables from them).
fn check_tag_range<R: BufRead>(
    src: &Source<R>,
    header: &[u64; 4],
    what: &str,
    tag: u64,
    at: Location,
) -> Result<(), IoError> {
    let [_, _, min, max] = *header;
    if (min..=max).contains(&tag) {
        return Ok(());
    }
    Err(src.parse_error_at(at, format!("{what} tag {tag} is outside the section header's range [{min}, {max}]")))
}

/// The header's item count must equal the sum of the block sizes.
fn check_total<R: BufRead>(
    src: &Source<R>,
    section: &str,
    what: &str,
    declared: u64,
    total: u64,
    header_at: Location,
) -> Result<(), IoError> {
    if declared == total {
        return Ok(());
    }
    Err(src.parse_error_at(
        header_at,
        format!("the {section} header declares {declared} {what}s, but its blocks hold {total}"),
    ))
}

/// `$Nodes`: blocks of tags then coordinates.
fn read_nodes<R: BufRead>(
    src: &mut Source<R>,
    binary: Option<Endian>,
    sink: &mut MeshSink,
    nodes: &mut NodeTable,
) -> Result<(), IoError> {
    let (header, header_at) = read_counted_header(src, binary, "$Nodes")?;
    let [n_blocks, n_nodes, _, _] = header;
    let hint = capacity_hint(n_nodes, 32, None);
    let mut total = 0u64;
    sink.mesh.positions.reserve(hint);
    nodes.reserve(hint);
    let mut block_tags: Vec<u64> = Vec::new();
    for _ in 0..n_blocks {
        let (b, at) = read_node_block_header(src, binary)?;
        if !(0..=3).contains(&b.dim) || !(0..=1).contains(&b.kind) {
            return Err(src.parse_error_at(
                at,
                format!("node block with entity dimension {} and parametric flag {}", b.dim, b.kind),
            ));
        }
        let n_param = if b.kind == 1 { b.dim as usize } else { 0 };
        total = total.saturating_add(b.count);
        block_tags.clear();
        for _ in 0..b.count {
            if block_tags.len() + sink.n_vertices() >= sink.limits.max_vertices {
                return Err(IoError::TooManyVertices { format: Format::Msh, max: sink.limits.max_vertices, at });
            }
            let (tag, at) = match binary {
                None => (src.expect_u64("a node tag")?, src.at_line()),
                Some(e) => (read_u64(src, e, "a node tag")?, src.at_byte()),
            };
            check_tag_range(src, &header, "node", tag, at)?;
            block_tags.push(tag);
        }
        for &tag in &block_tags {
            let (p, at) = match binary {
                None => {
                    let x = src.expect_f64("the node's x")?;
                    let at = src.at_line();
                    let y = src.expect_f64("the node's y")?;
                    let z = src.expect_f64("the node's z")?;
                    for _ in 0..n_param {
                        src.expect_f64("a parametric coordinate")?;
                    }
                    ([x, y, z], at)
                }
                Some(e) => {
                    let at = src.at_byte();
                    let mut buf = [0u8; 48];
                    src.read_exact(&mut buf[..8 * (3 + n_param)], "node coordinates")?;
                    let d = |k: usize| {
                        let o = 8 * k;
                        e.f64([
                            buf[o],
                            buf[o + 1],
                            buf[o + 2],
                            buf[o + 3],
                            buf[o + 4],
                            buf[o + 5],
                            buf[o + 6],
                            buf[o + 7],
                        ])
                    };
                    ([d(0), d(1), d(2)], at)
                }
            };
            let i = sink.vertex(p, tag, at)?;
            nodes.push(tag, i, at);
        }
    }
    check_total(src, "$Nodes", "node", n_nodes, total, header_at)?;
    if binary.is_none() {
        check_line_done(src, "Nodes")?;
    }
    src.expect_marker(b"$EndNodes", binary.is_some())
}

/// A node block header.
fn read_node_block_header<R: BufRead>(
    src: &mut Source<R>,
    binary: Option<Endian>,
) -> Result<(Block, Location), IoError> {
    read_block(src, binary, "node")
}

/// `$Elements`: blocks of one element type each.
fn read_elements<R: BufRead>(
    src: &mut Source<R>,
    binary: Option<Endian>,
    sink: &mut MeshSink,
    nodes: &NodeTable,
) -> Result<(), IoError> {
    let (header, header_at) = read_counted_header(src, binary, "$Elements")?;
    let [n_blocks, n_elements, _, _] = header;
    let mut node_tags = [0u64; 4];
    let mut total = 0u64;
    for block_no in 1..=n_blocks {
        let (b, at) = read_block(src, binary, "element")?;
        let ty = i32::try_from(b.kind).unwrap_or(-1);
        total = total.saturating_add(b.count);
        let Some(info) = element_info(ty) else {
            return Err(IoError::Unsupported {
                format: Format::Msh,
                at,
                feature: format!(
                    "element type {} in element block {block_no} of {n_blocks}: not a Gmsh element type of fixed size \
                     that this reader knows",
                    b.kind
                ),
            });
        };
        let kept = ty == TRIANGLE || ty == TETRAHEDRON;
        match (binary, info) {
            (_, (_, nn)) if kept => {
                for _ in 0..b.count {
                    let (tag, at) = match binary {
                        None => {
                            let tag = src.expect_u64("an element tag")?;
                            let at = src.at_line();
                            check_tag_range(src, &header, "element", tag, at)?;
                            for t in node_tags.iter_mut().take(nn) {
                                *t = src.expect_u64("a node tag of the element")?;
                            }
                            (tag, at)
                        }
                        Some(e) => {
                            let at = src.at_byte();
                            let mut buf = [0u8; 40];
                            src.read_exact(&mut buf[..8 * (1 + nn)], "an element record")?;
                            let u = |k: usize| {
                                let o = 8 * k;
                                e.u64([
                                    buf[o],
                                    buf[o + 1],
                                    buf[o + 2],
                                    buf[o + 3],
                                    buf[o + 4],
                                    buf[o + 5],
                                    buf[o + 6],
                                    buf[o + 7],
                                ])
                            };
                            for (k, t) in node_tags.iter_mut().take(nn).enumerate() {
                                *t = u(k + 1);
                            }
                            check_tag_range(src, &header, "element", u(0), at)?;
                            (u(0), at)
                        }
                    };
                    let v = lookup_nodes(nodes, &node_tags[..nn], tag, at)?;
                    keep_element(sink, ty, &v[..nn], at)?;
                }
            }
            (None, (name, nn)) => {
                for _ in 0..b.count {
                    let tag = src.expect_u64("an element tag")?;
                    check_tag_range(src, &header, "element", tag, src.at_line())?;
                    for _ in 0..nn {
                        src.expect_token("a node tag of the element")?;
                    }
                }
                sink.skip(name, usize::try_from(b.count).unwrap_or(usize::MAX));
            }
            (Some(_), (name, nn)) => {
                skip_items(src, b.count, 8 * (1 + nn as u64), name)?;
                sink.skip(name, usize::try_from(b.count).unwrap_or(usize::MAX));
            }
        }
    }
    check_total(src, "$Elements", "element", n_elements, total, header_at)?;
    if binary.is_none() {
        check_line_done(src, "Elements")?;
    }
    src.expect_marker(b"$EndElements", binary.is_some())
}

#[cfg(test)]
mod tests {
    use crate::failure::FailureKind;
    use crate::io::Limits;
    use crate::io::msh_common::read;

    fn lim() -> Limits {
        Limits::from_max_triangles(100)
    }

    /// Two node blocks (one parametric surface block with u v columns),
    /// sparse tags, entities, parametrizations and data sections.
    const ASCII: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n1 0 1 0\n1 0 0 0 0\n1 0 0 0 1 1 0 0 0\n$EndEntities\n$Nodes\n2 5 3 1000\n0 1 0 1\n3\n0 0 0\n2 1 1 4\n1000\n7\n8\n9\n1 0 0 0.5 0.5\n0 1 0 0.1 0.2\n0 0 1 0 0\n1 1 1 1 1\n$EndNodes\n$Elements\n3 4 1 4\n0 1 15 1\n1 3\n2 1 2 2\n2 3 1000 7\n3 3 7 8\n3 1 4 1\n4 3 1000 7 8\n$EndElements\n$Parametrizations\n0 1\n1\n3 1\n0 0 0 0 0 0 0 0 0 0 0\n1 0 0 1 0 0 0 0 0 0 0\n0 1 0 0 1 0 0 0 0 0 0\n0 1 2\n$EndParametrizations\n$NodeData\n1\n\"v\"\n0\n3\n0\n1\n1\n3 2.5\n$EndNodeData\n";

    #[test]
    fn ascii_parametric_blocks_and_skipped_sections() {
        let m = read(ASCII.as_bytes(), &lim()).unwrap();
        assert_eq!(m.positions.len(), 5);
        assert_eq!(m.positions[2], crate::geom::Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
        assert_eq!(m.skipped["Point"], 1);
    }

    #[test]
    fn ascii_errors() {
        let bad = ASCII.replace("3 3 7 8", "3 3 7 6");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::IndexOutOfRange);
        assert!(
            e.to_string().contains("element 3")
                && e.to_string().contains("vertex 6")
                && e.to_string().contains("line 30"),
            "{e}"
        );
        let bad = ASCII.replace("0 1 0 0.1 0.2", "0 1 0 0.1 x");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert!(e.to_string().contains("line 20") && e.to_string().contains("parametric coordinate"), "{e}");
        let bad = ASCII.replace("2 1 1 4", "2 1 2 4");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert!(e.to_string().contains("parametric flag 2") && e.to_string().contains("line 14"), "{e}");
        let bad = ASCII.replace("$EndEntities", "$EndEntitie");
        assert_eq!(read(bad.as_bytes(), &lim()).unwrap_err().kind(), FailureKind::Truncated);
    }

    /// The reproduction of issue 11 item 7: tag 3 twice, at (0, 1, 0) and (5, 5, 5).
    const DUPLICATE: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 3\n2 1 0 4\n1\n2\n3\n3\n0 0 0\n1 0 0\n0 1 0\n5 5 5\n$EndNodes\n$Elements\n1 1 1 1\n2 1 2 1\n1 1 2 3\n$EndElements\n";

    #[test]
    fn duplicate_node_tag_with_other_coordinates_is_refused() {
        let e = read(DUPLICATE.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::ParseError);
        let msg = e.to_string();
        assert!(
            msg.contains("node tag 3 is defined twice") && msg.contains("line 13") && msg.contains("line 14"),
            "{msg}"
        );
        // The same coordinates twice are tolerated (the first wins, as in Gmsh).
        let same = DUPLICATE.replace("5 5 5", "0 1 0");
        let m = read(same.as_bytes(), &lim()).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(m.skipped["duplicate node tag"], 1);
    }

    #[test]
    fn header_totals_must_match_the_blocks() {
        let bad = ASCII.replace("$Nodes\n2 5 3 1000", "$Nodes\n2 6 3 1000");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::ParseError);
        assert!(
            e.to_string().contains("declares 6 nodes, but its blocks hold 5") && e.to_string().contains("line 10"),
            "{e}"
        );
        let bad = ASCII.replace("$Elements\n3 4 1 4", "$Elements\n3 3 1 4");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert!(
            e.to_string().contains("declares 3 elements, but its blocks hold 4") && e.to_string().contains("line 25"),
            "{e}"
        );
    }

    #[test]
    fn tags_outside_the_header_range_are_refused() {
        let bad = ASCII.replace("$Nodes\n2 5 3 1000", "$Nodes\n2 5 3 999");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::ParseError);
        assert!(e.to_string().contains("node tag 1000 is outside") && e.to_string().contains("line 15"), "{e}");
        let bad = ASCII.replace("$Elements\n3 4 1 4", "$Elements\n3 4 2 4");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert!(
            e.to_string().contains("element tag 1 is outside the section header's range [2, 4]")
                && e.to_string().contains("line 27"),
            "{e}"
        );
        let bad = ASCII.replace("4 3 1000 7 8", "5 3 1000 7 8");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert!(e.to_string().contains("element tag 5 is outside") && e.to_string().contains("line 32"), "{e}");
    }

    #[test]
    fn unknown_element_type_is_unsupported_naming_type_and_block() {
        let bad = ASCII.replace("$Elements\n3 4 1 4\n", "$Elements\n4 5 1 5\n0 1 200 1\n5 2 3 4 5 6\n");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Unsupported);
        let msg = e.to_string();
        assert!(msg.contains("element type 200") && msg.contains("block 1 of 4") && msg.contains("line 26"), "{msg}");
    }

    /// A binary file with (partitioned) entities, written by hand.
    fn binary(partitioned: bool) -> Vec<u8> {
        let u = |out: &mut Vec<u8>, v: &[u64]| v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
        let i = |out: &mut Vec<u8>, v: &[i32]| v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
        let d = |out: &mut Vec<u8>, v: &[f64]| v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
        let mut out = b"$MeshFormat\n4.1 1 8\n".to_vec();
        i(&mut out, &[1]);
        out.extend_from_slice(b"\n$EndMeshFormat\n");
        if partitioned {
            out.extend_from_slice(b"$PartitionedEntities\n");
            u(&mut out, &[2, 1]);
            i(&mut out, &[5, 1]);
            u(&mut out, &[1, 0, 1, 0]);
            i(&mut out, &[1, 0, 1]);
            u(&mut out, &[2]);
            i(&mut out, &[1, 2]);
            d(&mut out, &[0.0; 3]);
            u(&mut out, &[0]);
            i(&mut out, &[2, 2, 1]);
            u(&mut out, &[1]);
            i(&mut out, &[1]);
            d(&mut out, &[0.0; 6]);
            u(&mut out, &[1]);
            i(&mut out, &[7]);
            u(&mut out, &[2]);
            i(&mut out, &[3, -4]);
            out.extend_from_slice(b"\n$EndPartitionedEntities\n");
        } else {
            out.extend_from_slice(b"$Entities\n");
            u(&mut out, &[1, 0, 1, 0]);
            i(&mut out, &[1]);
            d(&mut out, &[0.0; 3]);
            u(&mut out, &[1]);
            i(&mut out, &[9]);
            i(&mut out, &[1]);
            d(&mut out, &[0.0; 6]);
            u(&mut out, &[0, 3]);
            i(&mut out, &[1, 2, -3]);
            out.extend_from_slice(b"\n$EndEntities\n");
        }
        out.extend_from_slice(b"$Nodes\n");
        u(&mut out, &[1, 4, 10, 40]);
        i(&mut out, &[2, 1, 1]);
        u(&mut out, &[4, 10, 20, 30, 40]);
        for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] {
            d(&mut out, &p);
            d(&mut out, &[0.25, 0.5]);
        }
        out.extend_from_slice(b"\n$EndNodes\n$Elements\n");
        u(&mut out, &[3, 4, 1, 4]);
        i(&mut out, &[1, 1, 1]);
        u(&mut out, &[1, 1, 10, 20]);
        i(&mut out, &[2, 1, 2]);
        u(&mut out, &[2, 2, 10, 30, 20, 3, 10, 20, 40]);
        i(&mut out, &[3, 1, 4]);
        u(&mut out, &[1, 4, 10, 20, 30, 40]);
        out.extend_from_slice(b"\n$EndElements\n");
        out
    }

    #[test]
    fn binary_with_entities_and_parametric_nodes() {
        for partitioned in [false, true] {
            let b = binary(partitioned);
            let m = read(&b[..], &lim()).unwrap();
            assert_eq!(m.positions[1], crate::geom::Vec3::new(1.0, 0.0, 0.0));
            assert_eq!(m.triangles, vec![[0, 2, 1], [0, 1, 3]], "partitioned {partitioned}");
            assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
            assert_eq!(m.skipped["Line 2"], 1);
        }
    }

    #[test]
    fn binary_huge_counts_and_unknown_types() {
        let mut b = binary(false);
        // Claim 2^62 node blocks: reading stops at the end of the data.
        let at = b.windows(7).position(|w| w == b"$Nodes\n").unwrap() + 7;
        b[at..at + 8].copy_from_slice(&(1u64 << 62).to_le_bytes());
        assert_eq!(read(&b[..], &lim()).unwrap_err().kind(), FailureKind::ParseError);
        let mut b = binary(false);
        let at = b.windows(10).position(|w| w == b"$Elements\n").unwrap() + 10 + 32 + 8;
        b[at..at + 4].copy_from_slice(&34i32.to_le_bytes());
        let e = read(&b[..], &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Unsupported);
        assert!(e.to_string().contains("element type 34 in element block 1 of 3"), "{e}");
    }
}
