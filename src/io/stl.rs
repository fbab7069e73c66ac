//! STL reader, ASCII and binary.
//!
//! Binary layout: an 80-byte header, a little-endian `u32` triangle count
//! `n`, then `n` records of 50 bytes (normal and three corners as `f32`
//! triples, a `u16` attribute). ASCII: `solid name`, then per facet
//! `facet normal nx ny nz / outer loop / vertex x y z (×3) / endloop /
//! endfacet`, then `endsolid`; several solids may follow each other.
//!
//! **ASCII or binary?** When the total size is known it decides first: a
//! file of exactly `84 + 50·n` bytes is binary, whatever its header says
//! (several real binary files start their header with "solid"). Otherwise a
//! file that starts with `solid` and whose first bytes (header and up to 512
//! more) are all text is ASCII, and any other file is binary with a wrong
//! size, reported with expected and actual sizes. When the size is not known
//! (a stream) the same text test decides, and the binary reader checks at
//! the end of the stream that exactly `n` records were present.
//!
//! Stored normals are ignored (they are often wrong or zero); orientation
//! comes from the corner order. Each facet contributes three unwelded
//! corners: welding is the repair step's job. An ASCII `outer loop` with
//! more than three vertices is fan-triangulated and counted.
//!
//! Hand-written rather than `stl_io`: `stl_io` welds exactly while reading
//! (we must count welds), decides ASCII/binary by the leading "solid", and
//! its errors carry no line or byte offset.

use super::source::{MeshSink, Source, parse_f64, show, tokens};
use super::{Format, IoError, Limits, Location, RawMesh};
use std::io::{BufRead, Cursor, Read};

/// Bytes of the binary header (80 free bytes and the `u32` count).
const HEADER_BYTES: usize = 84;
/// Bytes of one binary triangle record.
const RECORD_BYTES: u64 = 50;

/// Read an STL file (ASCII or binary, see the module doc).
///
/// # Errors
/// Truncation (with expected vs actual size for binary), malformed ASCII
/// (with the line), non-finite coordinates, too many triangles.
pub fn read<R: BufRead>(mut reader: R, total_len: Option<u64>, limits: &Limits) -> Result<RawMesh, IoError> {
    let mut head = [0u8; HEADER_BYTES];
    let n_head = read_up_to(&mut reader, &mut head)?;
    if n_head == 0 {
        return Err(IoError::EmptyFile);
    }
    let head = &head[..n_head];
    let ascii = is_ascii_stl(head, total_len, &mut reader)?;
    let chained = Cursor::new(head.to_vec()).chain(reader);
    let mut src = Source::new(chained, Format::Stl);
    let mut sink = MeshSink::new(Format::Stl, *limits);
    if ascii {
        read_ascii(&mut src, &mut sink)?;
    } else {
        read_binary(&mut src, total_len, &mut sink)?;
    }
    Ok(sink.mesh)
}

/// Decide ASCII (true) or binary (false) as the module doc describes.
fn is_ascii_stl<R: BufRead>(head: &[u8], total_len: Option<u64>, rest: &mut R) -> Result<bool, IoError> {
    if let Some(len) = total_len {
        let declared = super::format::binary_stl_count(head).map(|n| 84 + RECORD_BYTES * u64::from(n));
        if declared == Some(len) {
            return Ok(false);
        }
    }
    if !starts_with_solid(head) {
        return Ok(false);
    }
    // "solid" and not the binary size: ASCII unless the first bytes are
    // binary (then it is a binary STL of the wrong size, reported as such).
    let more = loop {
        match rest.fill_buf() {
            Ok(b) => break b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(IoError::Io(e)),
        }
    };
    let more = &more[..more.len().min(512)];
    Ok(!super::format::looks_binary(head) && !super::format::looks_binary(more))
}

/// True when the data starts (after whitespace) with `solid`.
fn starts_with_solid(head: &[u8]) -> bool {
    let start = head.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(head.len());
    super::format::starts_with_ignore_case(&head[start..], b"solid")
}

/// `read` until `out` is full or the input ends.
fn read_up_to<R: Read>(r: &mut R, out: &mut [u8]) -> Result<usize, IoError> {
    let mut done = 0;
    while done < out.len() {
        match r.read(&mut out[done..]) {
            Ok(0) => break,
            Ok(n) => done += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(IoError::Io(e)),
        }
    }
    Ok(done)
}

/// Binary STL: header, count, records; the size must match `84 + 50·n` exactly.
fn read_binary<R: BufRead>(src: &mut Source<R>, total_len: Option<u64>, sink: &mut MeshSink) -> Result<(), IoError> {
    let mut header = [0u8; HEADER_BYTES];
    let got = src.read_up_to(&mut header)?;
    if got < HEADER_BYTES {
        return Err(IoError::Truncated {
            format: Format::Stl,
            at: Location::Byte(got as u64),
            detail: format!("a binary STL needs an 84-byte header, the file has {got} bytes"),
        });
    }
    let n = u64::from(u32::from_le_bytes([header[80], header[81], header[82], header[83]]));
    let expected = 84 + RECORD_BYTES * n;
    if let Some(len) = total_len {
        if len < expected {
            return Err(IoError::TruncatedBinaryStl { n_triangles: n, expected_bytes: expected, actual_bytes: len });
        }
        if len > expected {
            return Err(trailing_bytes_error(n, expected, len));
        }
    }
    if n > sink.limits.max_triangles as u64 {
        return Err(sink.too_many("triangles", Location::Byte(80)));
    }
    let cap = super::source::capacity_hint(n, RECORD_BYTES, total_len.map(|l| l.saturating_sub(84)));
    sink.mesh.positions.reserve(3 * cap);
    sink.mesh.triangles.reserve(cap);
    let mut rec = [0u8; RECORD_BYTES as usize];
    for i in 0..n {
        let start = src.offset();
        if let Err(e) = src.read_exact(&mut rec, "a 50-byte triangle record") {
            return Err(match e {
                IoError::Truncated { .. } => {
                    IoError::TruncatedBinaryStl { n_triangles: n, expected_bytes: expected, actual_bytes: src.offset() }
                }
                other => other,
            });
        }
        let mut corner = [0u32; 3];
        for (k, c) in corner.iter_mut().enumerate() {
            let o = 12 + 12 * k;
            let f =
                |j: usize| f64::from(f32::from_le_bytes([rec[o + j], rec[o + j + 1], rec[o + j + 2], rec[o + j + 3]]));
            let at = Location::Byte(start + o as u64);
            *c = sink.vertex([f(0), f(4), f(8)], 3 * i + k as u64 + 1, at)?;
        }
        sink.triangle(corner, Location::Byte(start))?;
    }
    if total_len.is_none() {
        let mut extra = 0u64;
        loop {
            let k = src.peek()?.len();
            if k == 0 {
                break;
            }
            extra += k as u64;
            src.skip_bytes(k as u64, "trailing data")?;
            if extra > 1 << 20 {
                break;
            }
        }
        if extra > 0 {
            return Err(trailing_bytes_error(n, expected, expected + extra));
        }
    }
    Ok(())
}

/// A binary STL with more bytes than its count announces: the count is
/// probably wrong, so reading only `n` records would drop data silently.
fn trailing_bytes_error(n: u64, expected: u64, len: u64) -> IoError {
    IoError::Parse {
        format: Format::Stl,
        at: Location::Byte(expected),
        message: format!(
            "binary STL header declares {n} triangles (84 + 50 × {n} = {expected} bytes), but the file has {len} bytes \
             ({} bytes more); the triangle count is wrong or the file is not a binary STL",
            len - expected
        ),
    }
}

/// Where the ASCII parser is inside a solid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Before `solid`, or after `endsolid`.
    Outside,
    /// Inside a solid, between facets.
    InSolid,
    /// After `facet normal ...`, expecting `outer loop`.
    InFacet,
    /// Inside `outer loop`, reading `vertex` lines.
    InLoop,
    /// After `endloop`, expecting `endfacet`.
    AfterLoop,
}

/// ASCII STL, keyword by keyword (one statement per line).
fn read_ascii<R: BufRead>(src: &mut Source<R>, sink: &mut MeshSink) -> Result<(), IoError> {
    let mut state = State::Outside;
    let mut poly: Vec<u32> = Vec::with_capacity(4);
    let mut n_vertices_seen = 0u64;
    let mut facet_line = 0u64;
    let mut n_solids = 0usize;
    while src.next_line()? {
        let mut toks = tokens(src.text());
        let Some(kw) = toks.next() else { continue };
        let kw_lower = kw.to_ascii_lowercase();
        match (state, kw_lower.as_slice()) {
            (State::Outside, b"solid") => {
                state = State::InSolid;
                n_solids += 1;
            }
            (State::InSolid, b"facet") => {
                state = State::InFacet;
                facet_line = src.line();
            }
            (State::InSolid, b"endsolid") => state = State::Outside,
            (State::InFacet, b"outer") => {
                state = State::InLoop;
                poly.clear();
            }
            (State::InLoop, b"vertex") => {
                let mut p = [0.0; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let t = toks
                        .next()
                        .ok_or_else(|| src.parse_error(format!("`vertex` needs 3 coordinates, found {k}")))?;
                    *c = parse_f64(t).ok_or_else(|| src.parse_error(format!("`{}` is not a number", show(t))))?;
                }
                n_vertices_seen += 1;
                poly.push(sink.vertex(p, n_vertices_seen, src.at_line())?);
            }
            (State::InLoop, b"endloop") => {
                if poly.len() < 3 {
                    return Err(src.parse_error(format!(
                        "facet starting at line {facet_line} has {} vertices, at least 3 are needed",
                        poly.len()
                    )));
                }
                sink.polygon(&poly, Location::Line(facet_line))?;
                state = State::AfterLoop;
            }
            (State::AfterLoop, b"endfacet") => state = State::InSolid,
            (State::Outside, _) if n_solids > 0 && src.text().iter().all(|b| b.is_ascii_whitespace() || *b == 0) => {}
            _ => {
                let expected = match state {
                    State::Outside => "`solid`",
                    State::InSolid => "`facet` or `endsolid`",
                    State::InFacet => "`outer loop`",
                    State::InLoop => "`vertex` or `endloop`",
                    State::AfterLoop => "`endfacet`",
                };
                return Err(src.parse_error(format!("expected {expected}, found `{}`", show(kw))));
            }
        }
    }
    match state {
        // A missing final `endsolid` loses nothing: accept it.
        State::Outside | State::InSolid => Ok(()),
        _ => Err(
            src.truncated_at(src.at_line(), format!("the file ends inside the facet that starts at line {facet_line}"))
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::failure::FailureKind;
    use crate::io::Limits;

    fn limits() -> Limits {
        Limits::from_max_triangles(1000)
    }

    fn binary_stl(tris: &[[[f32; 3]; 3]], header: &[u8]) -> Vec<u8> {
        let mut out = vec![b' '; 80];
        out[..header.len()].copy_from_slice(header);
        out.extend_from_slice(&(tris.len() as u32).to_le_bytes());
        for t in tris {
            out.extend_from_slice(&[0u8; 12]);
            for c in t {
                for x in c {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
            out.extend_from_slice(&[0, 0]);
        }
        out
    }

    const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    const TRI2: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn binary_with_solid_header_is_binary_by_size() {
        let bytes = binary_stl(&[TRI, TRI2], b"solid but binary");
        for len in [Some(bytes.len() as u64), None] {
            let m = read(&bytes[..], len, &limits()).unwrap();
            assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5]]);
            assert_eq!(m.positions[4], crate::geom::Vec3::new(1.0, 1.0, 0.0));
        }
    }

    #[test]
    fn truncated_binary_names_expected_and_actual_size() {
        let bytes = binary_stl(&[TRI, TRI2], b"bin");
        let cut = &bytes[..bytes.len() - 7];
        for len in [Some(cut.len() as u64), None] {
            let e = read(cut, len, &limits()).unwrap_err();
            assert_eq!(e.kind(), FailureKind::Truncated);
            assert!(
                matches!(e, IoError::TruncatedBinaryStl { n_triangles: 2, expected_bytes: 184, actual_bytes: 177 }),
                "{e}"
            );
            assert!(e.to_string().contains("184 bytes") && e.to_string().contains("177 bytes"));
        }
        let e = read(&bytes[..40], Some(40), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        assert!(e.to_string().contains("84-byte header"), "{e}");
    }

    #[test]
    fn trailing_bytes_are_an_error() {
        let mut bytes = binary_stl(&[TRI], b"bin");
        bytes.extend_from_slice(&[1u8; 60]);
        for len in [Some(bytes.len() as u64), None] {
            let e = read(&bytes[..], len, &limits()).unwrap_err();
            assert_eq!(e.kind(), FailureKind::ParseError);
            assert!(e.to_string().contains("declares 1 triangles") && e.to_string().contains("60 bytes more"), "{e}");
        }
    }

    #[test]
    fn binary_nan_names_vertex_and_offset() {
        let mut t = TRI2;
        t[1][2] = f32::NAN;
        let bytes = binary_stl(&[TRI, t], b"bin");
        let e = read(&bytes[..], Some(bytes.len() as u64), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::NonFiniteCoordinate);
        // Second record starts at 134; its corner 1 at 134 + 24.
        assert!(e.to_string().contains("vertex 5") && e.to_string().contains("byte offset 158"), "{e}");
    }

    #[test]
    fn binary_count_above_limit_fails_before_reading() {
        let mut bytes = binary_stl(&[TRI], b"bin");
        bytes[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = read(&bytes[..], None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::TooManyTriangles);
        let e = read(&bytes[..], Some(bytes.len() as u64), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
    }

    const ASCII: &str = "solid t\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n  endloop\n endfacet\n facet normal 0 0 0\n  outer loop\n   vertex 1 0 0\n   vertex 1 1 0\n   vertex 0 1 0\n   vertex 0.5 2 0\n  endloop\n endfacet\nendsolid t\n";

    #[test]
    fn ascii_reads_facets_and_fans_polygons() {
        let m = read(ASCII.as_bytes(), Some(ASCII.len() as u64), &limits()).unwrap();
        assert_eq!(m.positions.len(), 7);
        assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5], [3, 5, 6]]);
        assert_eq!(m.n_polygons_triangulated, 1);
        let m2 = read(ASCII.as_bytes(), None, &limits()).unwrap();
        assert_eq!(m, m2);
        // Several solids and a missing final endsolid are fine.
        let two = format!("{ASCII}{}", ASCII.replace("endsolid t\n", ""));
        assert_eq!(read(two.as_bytes(), None, &limits()).unwrap().triangles.len(), 6);
    }

    #[test]
    fn ascii_errors_name_the_line() {
        let bad = ASCII.replace("   vertex 1 1 0", "   vertex 1 x 0");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::ParseError);
        assert!(e.to_string().contains("line 12") && e.to_string().contains("`x` is not a number"), "{e}");
        let bad = ASCII.replace("  endloop\n endfacet\nendsolid", "  endloop\n endfacet\n vertex 0 0 0\nendsolid");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("line 17") && e.to_string().contains("expected `facet` or `endsolid`"), "{e}");
        let bad = ASCII.replace("vertex 0 1 0\n  endloop", "vertex 0 1\n  endloop");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("line 6") && e.to_string().contains("3 coordinates, found 2"), "{e}");
        let bad = ASCII.replace("vertex 0 1 0\n  endloop", "vertex 0 1 nan\n  endloop");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::NonFiniteCoordinate);
        assert!(e.to_string().contains("vertex 3") && e.to_string().contains("line 6"), "{e}");
        let cut = &ASCII[..ASCII.find("   vertex 1 1 0").unwrap()];
        let e = read(cut.as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        assert!(e.to_string().contains("line 9"), "{e}");
        let two_vertices = ASCII.replace(
            "   vertex 0 1 0\n  endloop\n endfacet\n facet normal 0 0 0",
            "  endloop\n endfacet\n facet normal 0 0 0",
        );
        let e = read(two_vertices.as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("2 vertices"), "{e}");
    }
}
