//! MSH 2.2 reader (body after `$MeshFormat`).
//!
//! ASCII layout:
//! ```text
//! $Nodes
//! n
//! tag x y z                       (n lines)
//! $EndNodes
//! $Elements
//! n
//! tag type ntags tag… node…       (n lines)
//! $EndElements
//! ```
//! Binary: the counts stay ASCII lines; nodes are `n` records
//! `int tag, double x y z`; elements come in blocks with the header
//! `int type, int count, int ntags`, then `count` records of
//! `1 + ntags + nodes(type)` ints. Triangles (type 2) and tetrahedra
//! (type 4) are kept, every other element type is skipped and counted by its
//! Gmsh name; in binary files a type without a fixed node count cannot be
//! skipped and is reported as unsupported. Other sections (`$PhysicalNames`,
//! `$NodeData`, `$ElementData`, `$Periodic`, `$Comments`, unknown ones) are
//! skipped up to their `$End…` line.

use crate::io::msh_common::{
    NodeTable, TETRAHEDRON, TRIANGLE, check_line_done, element_info, element_name, end_marker, keep_element,
    lookup_nodes, prepare_nodes, read_i32, skip_items,
};
use crate::io::source::{Endian, MeshSink, Source, capacity_hint, show};
use crate::io::{Format, IoError};
use std::io::BufRead;

/// Largest number of tags per element accepted in binary files (Gmsh writes 2–4).
const MAX_TAGS: i32 = 1 << 16;

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
        match name.as_slice() {
            b"Nodes" => read_nodes(src, binary, sink, &mut nodes)?,
            b"Elements" => {
                prepare_nodes(src, &mut nodes, sink)?;
                read_elements(src, binary, sink, &nodes)?;
            }
            b"MeshFormat" => return Err(src.parse_error("a second `$MeshFormat` section")),
            _ => src.skip_to_marker(&end_marker(&name), true)?,
        }
    }
    Ok(())
}

/// `$Nodes`: count line, then ASCII lines or binary records.
fn read_nodes<R: BufRead>(
    src: &mut Source<R>,
    binary: Option<Endian>,
    sink: &mut MeshSink,
    nodes: &mut NodeTable,
) -> Result<(), IoError> {
    let n = src.expect_u64("the number of nodes")?;
    check_line_done(src, "Nodes")?;
    let hint = capacity_hint(n, 28, None);
    sink.mesh.positions.reserve(hint);
    nodes.reserve(hint);
    match binary {
        None => {
            for _ in 0..n {
                let tag = src.expect_u64("a node tag")?;
                let at = src.at_line();
                let x = src.expect_f64("the node's x")?;
                let y = src.expect_f64("the node's y")?;
                let z = src.expect_f64("the node's z")?;
                let i = sink.vertex([x, y, z], tag, at)?;
                nodes.push(tag, i, at);
            }
            check_line_done(src, "Nodes")?;
        }
        Some(e) => {
            for _ in 0..n {
                let at = src.at_byte();
                let r: [u8; 28] = src.read_array("a node record (int tag, 3 doubles)")?;
                let tag = e.i32([r[0], r[1], r[2], r[3]]);
                let d = |o: usize| e.f64([r[o], r[o + 1], r[o + 2], r[o + 3], r[o + 4], r[o + 5], r[o + 6], r[o + 7]]);
                let tag = u64::try_from(tag).map_err(|_| src.parse_error_at(at, format!("negative node tag {tag}")))?;
                let i = sink.vertex([d(4), d(12), d(20)], tag, at)?;
                nodes.push(tag, i, at);
            }
        }
    }
    src.expect_marker(b"$EndNodes", binary.is_some())
}

/// `$Elements`: count line, then ASCII lines or binary blocks.
fn read_elements<R: BufRead>(
    src: &mut Source<R>,
    binary: Option<Endian>,
    sink: &mut MeshSink,
    nodes: &NodeTable,
) -> Result<(), IoError> {
    let n = src.expect_u64("the number of elements")?;
    check_line_done(src, "Elements")?;
    match binary {
        None => read_elements_ascii(src, n, sink, nodes)?,
        Some(e) => read_elements_binary(src, n, e, sink, nodes)?,
    }
    src.expect_marker(b"$EndElements", binary.is_some())
}

/// ASCII element lines `tag type ntags tag… node…`.
fn read_elements_ascii<R: BufRead>(
    src: &mut Source<R>,
    n: u64,
    sink: &mut MeshSink,
    nodes: &NodeTable,
) -> Result<(), IoError> {
    let mut node_tags = [0u64; 4];
    for _ in 0..n {
        let tag = src.expect_u64("an element tag")?;
        let at = src.at_line();
        let ty = src.expect_i64("an element type")?;
        let n_tags = src.expect_u64("the number of element tags")?;
        let ty32 = i32::try_from(ty).unwrap_or(-1);
        let Some((name, nn)) = element_info(ty32) else {
            // Unknown size: the element is the rest of its line.
            src.discard_line();
            sink.skip(&element_name(ty32), 1);
            continue;
        };
        for _ in 0..n_tags {
            src.expect_token("an element tag value")?;
        }
        if ty32 == TRIANGLE || ty32 == TETRAHEDRON {
            for t in node_tags.iter_mut().take(nn) {
                *t = src.expect_u64("a node tag of the element")?;
            }
            let v = lookup_nodes(nodes, &node_tags[..nn], tag, at)?;
            keep_element(sink, ty32, &v[..nn], at)?;
        } else {
            for _ in 0..nn {
                src.expect_token("a node tag of the element")?;
            }
            sink.skip(name, 1);
        }
        if !src.line_done() {
            src.next_token()?;
            return Err(src.parse_error(format!(
                "element {tag} of type {ty} ({name}) has more than {nn} nodes: unexpected `{}`",
                show(src.token())
            )));
        }
    }
    Ok(())
}

/// Binary element blocks.
fn read_elements_binary<R: BufRead>(
    src: &mut Source<R>,
    n: u64,
    e: Endian,
    sink: &mut MeshSink,
    nodes: &NodeTable,
) -> Result<(), IoError> {
    let mut done = 0u64;
    let mut buf: Vec<u8> = Vec::new();
    while done < n {
        let at = src.at_byte();
        let ty = read_i32(src, e, "an element block header (type)")?;
        let count = read_i32(src, e, "an element block header (count)")?;
        let n_tags = read_i32(src, e, "an element block header (number of tags)")?;
        if count <= 0 || count as u64 > n - done {
            return Err(src.parse_error_at(
                at,
                format!("element block of {count} elements, but {} of the {n} elements remain", n - done),
            ));
        }
        if !(0..=MAX_TAGS).contains(&n_tags) {
            return Err(src.parse_error_at(at, format!("element block with {n_tags} tags per element")));
        }
        let Some((name, nn)) = element_info(ty) else {
            return Err(IoError::Unsupported {
                format: Format::Msh,
                at,
                feature: format!("element type {ty} in a binary file (no fixed node count, cannot be skipped)"),
            });
        };
        let record = 4 * (1 + n_tags as usize + nn);
        if ty == TRIANGLE || ty == TETRAHEDRON {
            buf.resize(record, 0);
            let first = 4 * (1 + n_tags as usize);
            let mut node_tags = [0u64; 4];
            for _ in 0..count {
                let at = src.at_byte();
                src.read_exact(&mut buf, "an element record")?;
                let tag = e.i32([buf[0], buf[1], buf[2], buf[3]]);
                for (k, t) in node_tags.iter_mut().take(nn).enumerate() {
                    let o = first + 4 * k;
                    let v = e.i32([buf[o], buf[o + 1], buf[o + 2], buf[o + 3]]);
                    *t = u64::try_from(v).unwrap_or(u64::MAX);
                }
                let v = lookup_nodes(nodes, &node_tags[..nn], u64::try_from(tag).unwrap_or(0), at)?;
                keep_element(sink, ty, &v[..nn], at)?;
            }
        } else {
            skip_items(src, count as u64, record as u64, name)?;
            sink.skip(name, count as usize);
        }
        done += count as u64;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::failure::FailureKind;
    use crate::io::Limits;
    use crate::io::msh_common::read;

    fn lim() -> Limits {
        Limits::from_max_triangles(100)
    }

    const ASCII: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 1 \"surf\"\n$EndPhysicalNames\n$Nodes\n5\n10 0 0 0\n20 1 0 0\n30 0 1 0\n40 0 0 1\n7 9 9 9\n$EndNodes\n$Elements\n5\n1 15 2 0 1 10\n2 1 2 0 1 10 20\n3 2 2 0 1 10 30 20\n4 2 2 0 1 10 20 40\n5 4 2 0 1 10 20 30 40\n$EndElements\n$NodeData\n1\n\"x\"\n1\n0\n3\n0\n1\n4\n10 1\n20 1\n30 1\n40 1\n$EndNodeData\n";

    #[test]
    fn ascii_keeps_triangles_and_tets_and_counts_the_rest() {
        let m = read(ASCII.as_bytes(), &lim()).unwrap();
        assert_eq!(m.positions.len(), 5);
        assert_eq!(m.triangles, vec![[0, 2, 1], [0, 1, 3]]);
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
        assert_eq!(m.skipped["Point"], 1);
        assert_eq!(m.skipped["Line 2"], 1);
    }

    #[test]
    fn duplicate_node_tag_with_other_coordinates_is_refused() {
        let bad = ASCII.replace("7 9 9 9", "20 9 9 9");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::ParseError);
        let msg = e.to_string();
        assert!(
            msg.contains("node tag 20 is defined twice") && msg.contains("line 11") && msg.contains("line 14"),
            "{msg}"
        );
        let same = ASCII.replace("7 9 9 9", "20 1 0 0");
        let m = read(same.as_bytes(), &lim()).unwrap();
        assert_eq!(m.skipped["duplicate node tag"], 1);
        assert_eq!(m.triangles, vec![[0, 2, 1], [0, 1, 3]]);
    }

    #[test]
    fn ascii_errors() {
        let bad = ASCII.replace("3 2 2 0 1 10 30 20", "3 2 2 0 1 10 30 21");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::IndexOutOfRange);
        assert!(
            e.to_string().contains("element 3")
                && e.to_string().contains("vertex 21")
                && e.to_string().contains("line 20"),
            "{e}"
        );
        let bad = ASCII.replace("30 0 1 0", "30 0 inf 0");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::NonFiniteCoordinate);
        assert!(e.to_string().contains("vertex 30") && e.to_string().contains("line 12"), "{e}");
        let bad = ASCII.replace("$Nodes\n5\n", "$Nodes\n4\n");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert!(
            e.to_string().contains("expected `$EndNodes`, found `7 9 9 9") && e.to_string().contains("line 14"),
            "{e}"
        );
        let bad = ASCII.replace("3 2 2 0 1 10 30 20", "3 2 2 0 1 10 30 20 40");
        let e = read(bad.as_bytes(), &lim()).unwrap_err();
        assert!(e.to_string().contains("more than 3 nodes"), "{e}");
        let cut = &ASCII[..ASCII.find("$NodeData").unwrap() + 20];
        let e = read(cut.as_bytes(), &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        assert!(e.to_string().contains("$EndNodeData"), "{e}");
        let bad = ASCII.replace("5 4 2 0 1 10 20 30 40", "5 200 2 0 1 10 20 30 40 50 60");
        let m = read(bad.as_bytes(), &lim()).unwrap();
        assert_eq!(m.skipped["element type 200"], 1);
    }

    /// The ASCII mesh written in binary by hand.
    fn binary() -> Vec<u8> {
        let mut out = b"$MeshFormat\n2.2 1 8\n".to_vec();
        out.extend_from_slice(&1i32.to_le_bytes());
        out.extend_from_slice(b"\n$EndMeshFormat\n$Nodes\n4\n");
        for (tag, p) in [(10, [0.0, 0.0, 0.0]), (20, [1.0, 0.0, 0.0]), (30, [0.0, 1.0, 0.0]), (40, [0.0, 0.0, 1.0])] {
            out.extend_from_slice(&i32::to_le_bytes(tag));
            for c in p {
                out.extend_from_slice(&f64::to_le_bytes(c));
            }
        }
        out.extend_from_slice(b"\n$EndNodes\n$Elements\n4\n");
        let ints = |out: &mut Vec<u8>, v: &[i32]| v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
        ints(&mut out, &[1, 1, 2, 2, 0, 1, 10, 20]);
        ints(&mut out, &[2, 2, 2, 3, 0, 1, 10, 30, 20, 4, 0, 1, 10, 20, 40]);
        ints(&mut out, &[4, 1, 2, 5, 0, 1, 10, 20, 30, 40]);
        out.extend_from_slice(b"\n$EndElements\n");
        out
    }

    #[test]
    fn binary_blocks() {
        let m = read(&binary()[..], &lim()).unwrap();
        assert_eq!(m.triangles, vec![[0, 2, 1], [0, 1, 3]]);
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
        assert_eq!(m.skipped["Line 2"], 1);
        let b = binary();
        let e = read(&b[..b.len() - 30], &lim()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        assert!(e.to_string().contains("byte offset"), "{e}");
    }
}
