//! A cheap upper bound on the size of a stored mesh file, without parsing it:
//! the job service estimates a job's peak memory from it at submission.
//!
//! Per format, streaming and in bounded memory:
//! - binary STL: the header's triangle count, at most what the bytes hold
//!   (`(len − 84) / 50`); ASCII STL: a third of the `vertex` keywords;
//! - OBJ: per `f` line, its vertex count minus 2 (fan triangulation);
//! - PLY: the header's `element face` count (a polygon counts once; the
//!   reader's triangle cap bounds the rest);
//! - MSH: the `$Elements` header's element count (ASCII or binary), an upper
//!   bound for both surface triangles and tetrahedra.
//!
//! Counts read from headers are bounded by the bytes that could hold them,
//! so a lying header cannot inflate the estimate beyond the file's size. A
//! file that does not look like its format gets the byte-size bound
//! `len / 8` (no triangle is written in fewer than 8 bytes of text). The
//! scan never panics; it may overestimate.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use super::Format;

/// Upper bounds on the elements of a mesh file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InputSizes {
    /// Surface triangles after fan triangulation (upper bound).
    pub n_triangles: u64,
    /// Volume elements the file may carry (tetrahedra; MSH only, else 0).
    pub n_tets: u64,
}

/// Fewest bytes of any format that can hold one triangle (`f 1 2 3\n`).
const MIN_BYTES_PER_TRIANGLE: u64 = 8;
/// Bytes read per chunk while streaming.
const CHUNK: usize = 64 * 1024;
/// Longest PLY header read.
const MAX_PLY_HEADER: usize = 64 * 1024;

/// Upper bounds on the triangles and tetrahedra in the file at `path`,
/// read as `format`.
///
/// # Errors
/// The I/O error when the file cannot be read.
pub fn scan_input_sizes(path: &Path, format: Format) -> std::io::Result<InputSizes> {
    let file = File::open(path)?;
    let len = file.metadata()?.len();
    let mut r = BufReader::with_capacity(CHUNK, file);
    let fallback = InputSizes { n_triangles: len / MIN_BYTES_PER_TRIANGLE, n_tets: 0 };
    let sizes = match format {
        Format::Stl => stl_triangles(&mut r, len)?.map(|n| InputSizes { n_triangles: n, n_tets: 0 }),
        Format::Obj => Some(InputSizes { n_triangles: obj_triangles(&mut r)?, n_tets: 0 }),
        Format::Ply => ply_faces(&mut r)?.map(|n| InputSizes { n_triangles: n.min(len / 4), n_tets: 0 }),
        Format::Msh => msh_elements(&mut r)?.map(|n| {
            let n = n.min(len / MIN_BYTES_PER_TRIANGLE);
            InputSizes { n_triangles: n, n_tets: n }
        }),
    };
    Ok(sizes.unwrap_or(fallback))
}

/// Calls `f` on every chunk of `r` until the end.
fn for_each_chunk(r: &mut impl Read, mut f: impl FnMut(&[u8])) -> std::io::Result<()> {
    let mut buf = vec![0u8; CHUNK];
    loop {
        match r.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => f(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
}

/// Occurrences of `needle` in the stream (also across chunk boundaries).
fn count_occurrences(r: &mut impl Read, needle: &[u8]) -> std::io::Result<u64> {
    let finder = memchr::memmem::Finder::new(needle);
    let mut carry: Vec<u8> = Vec::new();
    let mut n = 0u64;
    for_each_chunk(r, |chunk| {
        carry.extend_from_slice(chunk);
        n += finder.find_iter(&carry).count() as u64;
        // Keep a tail shorter than the needle: it cannot hold a whole match.
        let keep = needle.len().saturating_sub(1).min(carry.len());
        carry.drain(..carry.len() - keep);
    })?;
    Ok(n)
}

/// Triangles of an STL file; `None` when it is neither binary nor ASCII.
fn stl_triangles(r: &mut impl Read, len: u64) -> std::io::Result<Option<u64>> {
    let mut head = [0u8; 84];
    let mut got = 0;
    while got < head.len() {
        match r.read(&mut head[got..])? {
            0 => break,
            n => got += n,
        }
    }
    let count = (got == 84).then(|| u64::from(u32::from_le_bytes([head[80], head[81], head[82], head[83]])));
    let exact_binary = count.is_some_and(|c| 84 + 50 * c == len);
    let text = &head[..got];
    let starts_solid = text.iter().skip_while(|b| b.is_ascii_whitespace()).take(5).eq(b"solid".iter());
    if starts_solid && !exact_binary {
        let mut rest = text.chain(r);
        return Ok(Some(count_occurrences(&mut rest, b"vertex")?.div_ceil(3)));
    }
    Ok(count.map(|c| c.min(len.saturating_sub(84) / 50)))
}

/// Triangles of an OBJ file: `Σ (vertices − 2)` over `f` lines.
fn obj_triangles(r: &mut impl Read) -> std::io::Result<u64> {
    #[derive(Clone, Copy, PartialEq)]
    enum State {
        LineStart,
        SawF,
        Face { in_token: bool },
        Skip,
    }
    let mut state = State::LineStart;
    let mut tokens = 0u64;
    let mut total = 0u64;
    let mut end_face = |tokens: &mut u64| {
        total += tokens.saturating_sub(2);
        *tokens = 0;
    };
    for_each_chunk(r, |chunk| {
        for &b in chunk {
            state = match (state, b) {
                (State::Face { .. }, b'\n') => {
                    end_face(&mut tokens);
                    State::LineStart
                }
                (_, b'\n') => State::LineStart,
                (State::LineStart, b' ' | b'\t') => State::LineStart,
                (State::LineStart, b'f') => State::SawF,
                (State::LineStart, _) => State::Skip,
                (State::SawF, b' ' | b'\t') => State::Face { in_token: false },
                (State::SawF, _) => State::Skip,
                (State::Face { .. }, b' ' | b'\t' | b'\r') => State::Face { in_token: false },
                (State::Face { in_token: false }, _) => {
                    tokens += 1;
                    State::Face { in_token: true }
                }
                (s @ State::Face { in_token: true }, _) => s,
                (State::Skip, _) => State::Skip,
            };
        }
    })?;
    if matches!(state, State::Face { .. }) {
        end_face(&mut tokens);
    }
    Ok(total)
}

/// The `element face N` count of a PLY header; `None` without a header.
fn ply_faces(r: &mut impl Read) -> std::io::Result<Option<u64>> {
    let mut head = Vec::new();
    r.take(MAX_PLY_HEADER as u64).read_to_end(&mut head)?;
    let text = String::from_utf8_lossy(&head);
    let mut faces = None;
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match (words.next(), words.next(), words.next()) {
            (Some("element"), Some("face"), Some(n)) => faces = n.parse::<u64>().ok(),
            (Some("end_header"), _, _) => return Ok(faces),
            _ => {}
        }
    }
    Ok(None)
}

/// The element count of the `$Elements` section of an MSH file (2.2 or
/// 4.1, ASCII or binary); `None` when there is none.
fn msh_elements(r: &mut impl Read) -> std::io::Result<Option<u64>> {
    const KEY: &[u8] = b"$Elements";
    let finder = memchr::memmem::Finder::new(KEY);
    let mut window: Vec<u8> = Vec::new();
    let mut format_line: Option<String> = None;
    let mut after: Option<Vec<u8>> = None;
    let mut buf = vec![0u8; CHUNK];
    loop {
        let n = match r.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if let Some(a) = after.as_mut() {
            a.extend_from_slice(&buf[..n]);
        } else {
            window.extend_from_slice(&buf[..n]);
            if format_line.is_none() {
                format_line = Some(msh_format_line(&window));
            }
            if let Some(at) = finder.find(&window) {
                after = Some(window[at + KEY.len()..].to_vec());
            } else {
                let keep = (KEY.len() - 1).min(window.len());
                window.drain(..window.len() - keep);
            }
        }
        if after.as_ref().is_some_and(|a| a.len() >= 128) {
            break;
        }
    }
    let Some(after) = after else { return Ok(None) };
    let binary_41 = format_line.as_deref().is_some_and(|l| {
        let mut w = l.split_whitespace();
        w.next().is_some_and(|v| v.starts_with('4')) && w.next() == Some("1")
    });
    let body = after.strip_prefix(b"\r\n").or_else(|| after.strip_prefix(b"\n")).unwrap_or(&after);
    if binary_41 {
        // numEntityBlocks, numElements, minTag, maxTag as size_t (8 bytes here).
        return Ok(body.get(8..16).map(|b| u64::from_le_bytes(b.try_into().unwrap_or([0; 8]))));
    }
    let line = String::from_utf8_lossy(body.split(|&b| b == b'\n').next().unwrap_or(&[]));
    let nums: Vec<u64> = line.split_whitespace().map_while(|w| w.parse().ok()).collect();
    let v4 = format_line.as_deref().is_some_and(|l| l.trim_start().starts_with('4'));
    Ok(if v4 { nums.get(1).copied() } else { nums.first().copied() })
}

/// The line after `$MeshFormat` (e.g. `4.1 0 8`), or empty.
fn msh_format_line(head: &[u8]) -> String {
    let text = String::from_utf8_lossy(&head[..head.len().min(256)]);
    let mut lines = text.lines();
    while let Some(l) = lines.next() {
        if l.trim() == "$MeshFormat" {
            return lines.next().unwrap_or("").to_string();
        }
    }
    String::new()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(bytes: &[u8], format: Format) -> InputSizes {
        let dir = tempfile_dir();
        let path = dir.join(format!("scan-{}", bytes.len()));
        std::fs::write(&path, bytes).unwrap();
        let s = scan_input_sizes(&path, format).unwrap();
        let _ = std::fs::remove_file(&path);
        s
    }

    fn tempfile_dir() -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("meshatlas-sizes-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn binary_stl_count_is_bounded_by_the_bytes() {
        let mut b = vec![0u8; 84 + 50 * 3];
        b[80..84].copy_from_slice(&3u32.to_le_bytes());
        assert_eq!(scan(&b, Format::Stl).n_triangles, 3);
        b[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(scan(&b, Format::Stl).n_triangles, 3);
    }

    #[test]
    fn ascii_stl_obj_ply_and_msh_are_counted() {
        let facet =
            "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n endloop\nendfacet\n";
        let stl = format!("solid x\n{}endsolid x\n", facet.repeat(2000));
        assert_eq!(scan(stl.as_bytes(), Format::Stl).n_triangles, 2000);
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1/1 2/2 4/4 3/3\n# f 1 2 3\n  f 1 2 3";
        assert_eq!(scan(obj.as_bytes(), Format::Obj).n_triangles, 4);
        let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0\n0\n0\n3 0 1 2\n";
        assert_eq!(scan(ply.as_bytes(), Format::Ply).n_triangles, 1);
        let msh41 = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 3 1 3\n$EndNodes\n$Elements\n1 7 1 7\n2 1 2 7\n$EndElements\n";
        assert_eq!(scan(msh41.as_bytes(), Format::Msh), InputSizes { n_triangles: 7, n_tets: 7 });
        let msh22 = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Elements\n5\n1 2 0 1 2 3\n$EndElements\n";
        assert_eq!(scan(msh22.as_bytes(), Format::Msh).n_triangles, 5);
    }

    #[test]
    fn garbage_gets_the_byte_bound_and_no_panic() {
        let junk: Vec<u8> = (0..10_000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8).collect();
        for f in Format::ALL {
            let s = scan(&junk, f);
            assert!(s.n_triangles <= junk.len() as u64, "{f:?}: {s:?}");
        }
        assert_eq!(scan(b"$MeshFormat\n4.1 1 8\n$Elements\n", Format::Msh).n_triangles, 29 / 8);
        assert_eq!(scan(b"", Format::Stl).n_triangles, 0);
    }
}
