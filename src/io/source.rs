//! Reading plumbing shared by every reader.
//!
//! [`Source`] wraps a `BufRead` and counts the bytes and lines consumed, so
//! an error can name its place: a 1-based line for text, a 0-based byte
//! offset for binary data. It reads bounded lines into one reused buffer
//! (no allocation per line), whitespace-separated tokens across lines,
//! fixed-size binary values of either endianness, and it skips `$Section`s
//! of MSH files by scanning for their end marker.
//!
//! [`MeshSink`] collects what the readers produce ([`RawMesh`]: positions,
//! triangles, tetrahedra, counts of skipped elements) and enforces the load
//! limits while reading, so a file can never make us allocate more than the
//! limits allow: counts announced by headers are only used as capped
//! capacity hints ([`capacity_hint`]); vectors grow with what is actually read.

use super::{Format, IoError, Location};
use crate::geom::Vec3;
use std::collections::BTreeMap;
use std::io::{BufRead, ErrorKind};

/// Longest accepted text line (64 MiB): bounds the line buffer on hostile input.
pub const MAX_LINE_BYTES: usize = 64 << 20;

/// Largest accepted coordinate magnitude: cubes of differences (tet volumes)
/// must stay finite in `f64`.
pub const MAX_COORDINATE: f64 = 1e100;

/// Largest capacity reserved up front from a count announced by a file.
const MAX_CAPACITY_HINT: u64 = 1 << 20;

/// Limits enforced while reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Maximum triangles (after fan triangulation); also caps tetrahedra.
    pub max_triangles: usize,
    /// Maximum vertices: `4 · max_triangles + 1024`, at most `u32::MAX − 1`.
    pub max_vertices: usize,
}

impl Limits {
    /// Limits derived from the triangle cap.
    pub fn from_max_triangles(max_triangles: usize) -> Self {
        let id_max = u32::MAX as usize - 1;
        Self {
            max_triangles: max_triangles.min(id_max),
            max_vertices: max_triangles.saturating_mul(4).saturating_add(1024).min(id_max),
        }
    }
}

/// What a reader found in a file, before welding and repair.
///
/// Indices are 0-based into `positions`. Triangles may still repeat a
/// vertex (degenerate) and reference vertices in any order; the repair step
/// cleans them and counts what it removes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RawMesh {
    /// Vertex positions in file order (for STL: three corners per facet).
    pub positions: Vec<Vec3>,
    /// Triangles, polygons already fan-triangulated.
    pub triangles: Vec<[u32; 3]>,
    /// Linear tetrahedra (MSH only), in any orientation.
    pub tets: Vec<[u32; 4]>,
    /// Elements not kept, counted by type name (e.g. "Line 2", "Quadrilateral 4").
    pub skipped: BTreeMap<String, usize>,
    /// Polygons with more than three vertices split into triangle fans.
    pub n_polygons_triangulated: usize,
}

/// A capacity to reserve for `count` announced items: at most what the
/// remaining input could hold (`remaining / min_item_bytes`) and at most
/// 2^20; vectors grow beyond it as items are actually read.
pub fn capacity_hint(count: u64, min_item_bytes: u64, remaining: Option<u64>) -> usize {
    let by_size = remaining.map_or(u64::MAX, |r| r / min_item_bytes.max(1));
    count.min(by_size).min(MAX_CAPACITY_HINT) as usize
}

/// Collects the mesh while enforcing [`Limits`].
#[derive(Debug)]
pub struct MeshSink {
    /// What has been read so far.
    pub mesh: RawMesh,
    /// The limits in force.
    pub limits: Limits,
    /// Format being read (for error messages).
    pub format: Format,
}

impl MeshSink {
    /// An empty sink.
    pub fn new(format: Format, limits: Limits) -> Self {
        Self { mesh: RawMesh::default(), limits, format }
    }

    /// Number of vertices so far.
    #[inline]
    pub fn n_vertices(&self) -> usize {
        self.mesh.positions.len()
    }

    /// Append a vertex after checking it; returns its 0-based index.
    /// `vertex_no` is how the file numbers it (1-based index or node tag).
    ///
    /// # Errors
    /// Non-finite or huge coordinates, or too many vertices.
    #[inline]
    pub fn vertex(&mut self, p: [f64; 3], vertex_no: u64, at: Location) -> Result<u32, IoError> {
        check_coordinates(self.format, p, vertex_no, at)?;
        if self.mesh.positions.len() >= self.limits.max_vertices {
            return Err(IoError::TooManyVertices { format: self.format, max: self.limits.max_vertices, at });
        }
        self.mesh.positions.push(Vec3::new(p[0], p[1], p[2]));
        Ok((self.mesh.positions.len() - 1) as u32)
    }

    /// Append a triangle (indices are checked later, against the final vertex count).
    ///
    /// # Errors
    /// More than `max_triangles` triangles.
    #[inline]
    pub fn triangle(&mut self, t: [u32; 3], at: Location) -> Result<(), IoError> {
        if self.mesh.triangles.len() >= self.limits.max_triangles {
            return Err(self.too_many("triangles", at));
        }
        self.mesh.triangles.push(t);
        Ok(())
    }

    /// Append a tetrahedron.
    ///
    /// # Errors
    /// More than `max_triangles` tetrahedra.
    #[inline]
    pub fn tet(&mut self, t: [u32; 4], at: Location) -> Result<(), IoError> {
        if self.mesh.tets.len() >= self.limits.max_triangles {
            return Err(self.too_many("tetrahedra", at));
        }
        self.mesh.tets.push(t);
        Ok(())
    }

    /// Append a polygon: a triangle as is, a larger polygon as the fan
    /// `(v0, vi, vi+1)` (counted), fewer than 3 vertices skipped (counted).
    ///
    /// # Errors
    /// More than `max_triangles` triangles.
    pub fn polygon(&mut self, poly: &[u32], at: Location) -> Result<(), IoError> {
        match poly.len() {
            0..=2 => self.skip("polygon with fewer than 3 vertices", 1),
            3 => self.triangle([poly[0], poly[1], poly[2]], at)?,
            n => {
                for i in 1..n - 1 {
                    self.triangle([poly[0], poly[i], poly[i + 1]], at)?;
                }
                self.mesh.n_polygons_triangulated += 1;
            }
        }
        Ok(())
    }

    /// Count `n` skipped elements of type `name`.
    pub fn skip(&mut self, name: &str, n: usize) {
        if n == 0 {
            return;
        }
        match self.mesh.skipped.get_mut(name) {
            Some(c) => *c += n,
            None => {
                self.mesh.skipped.insert(name.to_string(), n);
            }
        }
    }

    /// The error for exceeding the triangle (or tetrahedron) cap.
    pub fn too_many(&self, what: &'static str, at: Location) -> IoError {
        IoError::TooManyTriangles { format: self.format, what, max: self.limits.max_triangles, at }
    }
}

/// Reject NaN/inf and coordinates above [`MAX_COORDINATE`].
///
/// # Errors
/// [`IoError::NonFiniteCoordinate`] or [`IoError::CoordinateOutOfRange`] naming the vertex.
#[inline]
pub fn check_coordinates(format: Format, p: [f64; 3], vertex: u64, at: Location) -> Result<(), IoError> {
    if p.iter().all(|c| c.abs() <= MAX_COORDINATE) {
        return Ok(());
    }
    if p.iter().any(|c| !c.is_finite()) {
        return Err(IoError::NonFiniteCoordinate { format, vertex, x: p[0], y: p[1], z: p[2], at });
    }
    let value = p.into_iter().find(|c| c.abs() > MAX_COORDINATE).unwrap_or(p[0]);
    Err(IoError::CoordinateOutOfRange { format, vertex, value, max: MAX_COORDINATE, at })
}

/// Byte order of binary data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endian {
    /// Least significant byte first.
    Little,
    /// Most significant byte first.
    Big,
}

macro_rules! endian_read {
    ($($name:ident: $t:ty),*) => {
        impl Endian {
            $(
                /// Decode a value of this byte order.
                #[inline]
                pub fn $name(self, b: [u8; std::mem::size_of::<$t>()]) -> $t {
                    match self {
                        Endian::Little => <$t>::from_le_bytes(b),
                        Endian::Big => <$t>::from_be_bytes(b),
                    }
                }
            )*
        }
    };
}
endian_read!(u16: u16, i16: i16, u32: u32, i32: i32, u64: u64, i64: i64, f32: f32, f64: f64);

/// A byte source that knows where it is.
pub struct Source<R> {
    inner: R,
    /// Format being read (for error messages).
    pub format: Format,
    offset: u64,
    line: u64,
    buf: Vec<u8>,
    tok: (usize, usize),
    tok_pos: usize,
}

impl<R: BufRead> Source<R> {
    /// Wrap `inner`, positioned at the start of the data.
    pub fn new(inner: R, format: Format) -> Self {
        Self { inner, format, offset: 0, line: 0, buf: Vec::with_capacity(256), tok: (0, 0), tok_pos: 0 }
    }

    /// Bytes consumed so far (the offset of the next byte).
    #[inline]
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// Number of the current line (the one last returned by [`Self::next_line`]).
    #[inline]
    pub fn line(&self) -> u64 {
        self.line
    }

    /// The current line as a location.
    #[inline]
    pub fn at_line(&self) -> Location {
        Location::Line(self.line)
    }

    /// The next byte offset as a location.
    #[inline]
    pub fn at_byte(&self) -> Location {
        Location::Byte(self.offset)
    }

    /// The text of the current line (without `\n` / `\r\n`).
    #[inline]
    pub fn text(&self) -> &[u8] {
        &self.buf
    }

    /// A parse error at the current line.
    pub fn parse_error(&self, message: impl Into<String>) -> IoError {
        IoError::Parse { format: self.format, at: self.at_line(), message: message.into() }
    }

    /// A parse error at a given location.
    pub fn parse_error_at(&self, at: Location, message: impl Into<String>) -> IoError {
        IoError::Parse { format: self.format, at, message: message.into() }
    }

    /// A truncation error at a given location.
    pub fn truncated_at(&self, at: Location, detail: impl Into<String>) -> IoError {
        IoError::Truncated { format: self.format, at, detail: detail.into() }
    }

    /// `fill_buf`, retrying on `Interrupted`.
    fn fill(&mut self) -> Result<&[u8], IoError> {
        fill_retry(&mut self.inner)
    }

    #[inline]
    fn consume(&mut self, n: usize) {
        self.inner.consume(n);
        self.offset += n as u64;
    }

    /// Read the next line into the line buffer ([`Self::text`]); false at end
    /// of input. Strips `\n` and a trailing `\r`.
    ///
    /// # Errors
    /// A line longer than [`MAX_LINE_BYTES`], or a read failure.
    pub fn next_line(&mut self) -> Result<bool, IoError> {
        let got = self.read_line()?;
        self.tok_pos = self.buf.len();
        Ok(got)
    }

    /// Read the next line into the buffer, tokens starting at its beginning.
    fn read_line(&mut self) -> Result<bool, IoError> {
        self.buf.clear();
        self.tok_pos = 0;
        let mut got_any = false;
        loop {
            let avail = fill_retry(&mut self.inner)?;
            if avail.is_empty() {
                break;
            }
            got_any = true;
            let (take, done) = match memchr::memchr(b'\n', avail) {
                Some(i) => (i, true),
                None => (avail.len(), false),
            };
            if self.buf.len() + take > MAX_LINE_BYTES {
                self.line += 1;
                return Err(self.parse_error(format!("line longer than {MAX_LINE_BYTES} bytes")));
            }
            self.buf.extend_from_slice(&avail[..take]);
            self.consume(take + usize::from(done));
            if done {
                break;
            }
        }
        if !got_any {
            return Ok(false);
        }
        self.line += 1;
        if self.buf.last() == Some(&b'\r') {
            self.buf.pop();
        }
        Ok(true)
    }

    /// Advance to the next whitespace-separated token, reading lines as
    /// needed; false at end of input. The token is [`Self::token`], its line
    /// [`Self::line`].
    ///
    /// # Errors
    /// As [`Self::next_line`].
    pub fn next_token(&mut self) -> Result<bool, IoError> {
        loop {
            let rest = &self.buf[self.tok_pos..];
            if let Some(s) = rest.iter().position(|b| !b.is_ascii_whitespace()) {
                let start = self.tok_pos + s;
                let len =
                    self.buf[start..].iter().position(|b| b.is_ascii_whitespace()).unwrap_or(self.buf.len() - start);
                self.tok = (start, start + len);
                self.tok_pos = start + len;
                return Ok(true);
            }
            if !self.read_line()? {
                return Ok(false);
            }
        }
    }

    /// Drop the tokens left on the current line: the next token comes from the next line.
    pub fn discard_line(&mut self) {
        self.tok_pos = self.buf.len();
    }

    /// True when no token is left on the current line.
    pub fn line_done(&self) -> bool {
        self.buf[self.tok_pos..].iter().all(|b| b.is_ascii_whitespace())
    }

    /// The next token, which must exist: `what` names it in the error.
    ///
    /// # Errors
    /// [`IoError::Truncated`] at end of input.
    pub fn expect_token(&mut self, what: &str) -> Result<&[u8], IoError> {
        if !self.next_token()? {
            return Err(self.truncated_at(self.at_line(), format!("expected {what}, but the file ends")));
        }
        Ok(self.token())
    }

    /// The next token as a non-negative integer.
    ///
    /// # Errors
    /// Truncation, or a token that is not a non-negative integer.
    pub fn expect_u64(&mut self, what: &str) -> Result<u64, IoError> {
        self.expect_token(what)?;
        parse_u64(self.token())
            .ok_or_else(|| self.parse_error(format!("expected {what}, found `{}`", show(self.token()))))
    }

    /// The next token as an integer.
    ///
    /// # Errors
    /// Truncation, or a token that is not an integer.
    pub fn expect_i64(&mut self, what: &str) -> Result<i64, IoError> {
        self.expect_token(what)?;
        parse_i64(self.token())
            .ok_or_else(|| self.parse_error(format!("expected {what}, found `{}`", show(self.token()))))
    }

    /// The next token as a number.
    ///
    /// # Errors
    /// Truncation, or a token that is not a number.
    pub fn expect_f64(&mut self, what: &str) -> Result<f64, IoError> {
        self.expect_token(what)?;
        parse_f64(self.token())
            .ok_or_else(|| self.parse_error(format!("expected {what}, found `{}`", show(self.token()))))
    }

    /// The current token (see [`Self::next_token`]).
    #[inline]
    pub fn token(&self) -> &[u8] {
        &self.buf[self.tok.0..self.tok.1]
    }

    /// Fill `out` completely.
    ///
    /// # Errors
    /// [`IoError::Truncated`] naming `what` and the offset when the input ends first.
    #[inline]
    pub fn read_exact(&mut self, out: &mut [u8], what: &str) -> Result<(), IoError> {
        let start = self.offset;
        let mut done = 0;
        while done < out.len() {
            let avail = self.fill()?;
            if avail.is_empty() {
                return Err(self.truncated_at(
                    Location::Byte(start),
                    format!("expected {what} ({} bytes), but the data ends after {done} bytes", out.len()),
                ));
            }
            let n = avail.len().min(out.len() - done);
            out[done..done + n].copy_from_slice(&avail[..n]);
            self.consume(n);
            done += n;
        }
        Ok(())
    }

    /// Read a fixed-size array.
    ///
    /// # Errors
    /// As [`Self::read_exact`].
    #[inline]
    pub fn read_array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], IoError> {
        let mut b = [0u8; N];
        self.read_exact(&mut b, what)?;
        Ok(b)
    }

    /// Read up to `out.len()` bytes, fewer only at end of input; returns the count.
    ///
    /// # Errors
    /// A read failure.
    pub fn read_up_to(&mut self, out: &mut [u8]) -> Result<usize, IoError> {
        let mut done = 0;
        while done < out.len() {
            let avail = self.fill()?;
            if avail.is_empty() {
                break;
            }
            let n = avail.len().min(out.len() - done);
            out[done..done + n].copy_from_slice(&avail[..n]);
            self.consume(n);
            done += n;
        }
        Ok(done)
    }

    /// Skip `n` bytes.
    ///
    /// # Errors
    /// [`IoError::Truncated`] naming `what` when fewer remain.
    pub fn skip_bytes(&mut self, n: u64, what: &str) -> Result<(), IoError> {
        let start = self.offset;
        let mut left = n;
        while left > 0 {
            let avail = self.fill()?.len();
            if avail == 0 {
                return Err(self.truncated_at(
                    Location::Byte(start),
                    format!("expected {what} ({n} bytes), but the data ends after {} bytes", n - left),
                ));
            }
            let k = (avail as u64).min(left) as usize;
            self.consume(k);
            left -= k as u64;
        }
        Ok(())
    }

    /// True when no byte is left.
    ///
    /// # Errors
    /// A read failure.
    pub fn is_eof(&mut self) -> Result<bool, IoError> {
        Ok(self.fill()?.is_empty())
    }

    /// The next bytes without consuming them (as many as are buffered).
    ///
    /// # Errors
    /// A read failure.
    pub fn peek(&mut self) -> Result<&[u8], IoError> {
        self.fill()
    }

    /// Skip everything up to and including the line that starts with
    /// `marker` (e.g. `$EndNodeData`). `at_line_start` says whether the next
    /// byte starts a line. Works on text and binary content alike and keeps
    /// the line count of text content.
    ///
    /// # Errors
    /// [`IoError::Truncated`] when the marker never comes.
    pub fn skip_to_marker(&mut self, marker: &[u8], at_line_start: bool) -> Result<(), IoError> {
        debug_assert!(!marker.is_empty() && !marker.contains(&b'\n'));
        let start = self.at_line();
        let mut line_start = at_line_start;
        let mut k = 0usize;
        loop {
            let avail = self.fill()?;
            if avail.is_empty() {
                return Err(self.truncated_at(start, format!("missing `{}`", String::from_utf8_lossy(marker))));
            }
            let mut used = 0;
            let mut found = false;
            let mut newlines = 0u64;
            for &b in avail {
                used += 1;
                if k > 0 || line_start {
                    if b == marker[k] {
                        k += 1;
                        if k == marker.len() {
                            found = true;
                            break;
                        }
                    } else {
                        k = 0;
                    }
                }
                line_start = b == b'\n';
                newlines += u64::from(line_start);
            }
            self.consume(used);
            self.line += newlines;
            if found {
                return self.finish_line();
            }
        }
    }

    /// Skip whitespace, then require `marker` at the start of a line and
    /// consume that line.
    ///
    /// # Errors
    /// [`IoError::Parse`] naming the marker and what was found instead.
    pub fn expect_marker(&mut self, marker: &[u8], binary: bool) -> Result<(), IoError> {
        loop {
            let avail = self.fill()?;
            let Some(&b) = avail.first() else {
                let at = if binary { self.at_byte() } else { self.at_line() };
                return Err(self.truncated_at(at, format!("missing `{}`", String::from_utf8_lossy(marker))));
            };
            if !b.is_ascii_whitespace() {
                break;
            }
            self.consume(1);
            if b == b'\n' {
                self.line += 1;
            }
        }
        let at = if binary { self.at_byte() } else { Location::Line(self.line + 1) };
        let mut got = [0u8; 64];
        let n = marker.len().min(got.len());
        let read = self.read_up_to(&mut got[..n])?;
        if got[..read] != marker[..n] {
            let found = String::from_utf8_lossy(&got[..read]).into_owned();
            return Err(self.parse_error_at(
                at,
                format!("expected `{}`, found `{}`", String::from_utf8_lossy(marker), found.escape_debug()),
            ));
        }
        self.finish_line()
    }

    /// Consume the rest of the current line, including its `\n` (bounded).
    fn finish_line(&mut self) -> Result<(), IoError> {
        let mut skipped = 0usize;
        loop {
            let avail = self.fill()?;
            if avail.is_empty() {
                self.line += 1;
                return Ok(());
            }
            match memchr::memchr(b'\n', avail) {
                Some(i) => {
                    self.consume(i + 1);
                    self.line += 1;
                    return Ok(());
                }
                None => {
                    let n = avail.len();
                    self.consume(n);
                    skipped += n;
                    if skipped > MAX_LINE_BYTES {
                        return Err(self.parse_error(format!("line longer than {MAX_LINE_BYTES} bytes")));
                    }
                }
            }
        }
    }
}

/// `fill_buf`, retrying on `Interrupted`.
fn fill_retry<R: BufRead>(inner: &mut R) -> Result<&[u8], IoError> {
    loop {
        match inner.fill_buf() {
            Ok(_) => break,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) => return Err(IoError::Io(e)),
        }
    }
    Ok(inner.fill_buf()?)
}

/// Whitespace-separated tokens of a line.
#[inline]
pub fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty())
}

/// Parse a decimal floating-point token (`inf`/`nan` parse too and are
/// rejected later as non-finite coordinates).
#[inline]
pub fn parse_f64(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse().ok()
}

/// Parse a decimal integer token.
#[inline]
pub fn parse_i64(tok: &[u8]) -> Option<i64> {
    std::str::from_utf8(tok).ok()?.parse().ok()
}

/// Parse a non-negative decimal integer token.
#[inline]
pub fn parse_u64(tok: &[u8]) -> Option<u64> {
    std::str::from_utf8(tok).ok()?.parse().ok()
}

/// A token for an error message: lossy UTF-8, at most 40 characters, escaped.
pub fn show(tok: &[u8]) -> String {
    let s = String::from_utf8_lossy(tok);
    let mut out: String = s.chars().take(40).collect::<String>().escape_debug().to_string();
    if s.chars().count() > 40 {
        out.push('…');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::failure::FailureKind;

    fn src(bytes: &[u8]) -> Source<&[u8]> {
        Source::new(bytes, Format::Obj)
    }

    #[test]
    fn lines_and_tokens_track_line_numbers() {
        let mut s = src(b"a b\r\n\n  c\nd");
        assert!(s.next_line().unwrap());
        assert_eq!((s.text(), s.line()), (&b"a b"[..], 1));
        assert!(s.next_line().unwrap());
        assert_eq!((s.text(), s.line()), (&b""[..], 2));
        assert!(s.next_token().unwrap());
        assert_eq!((s.token(), s.line()), (&b"c"[..], 3));
        assert!(s.next_token().unwrap());
        assert_eq!((s.token(), s.line()), (&b"d"[..], 4));
        assert!(!s.next_token().unwrap());
        assert!(!s.next_line().unwrap());
        assert_eq!(s.offset(), 11);
    }

    #[test]
    fn read_exact_reports_truncation_with_offset() {
        let mut s = src(b"12345");
        let _: [u8; 2] = s.read_array("two").unwrap();
        let e = s.read_array::<4>("a float").unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        let m = e.to_string();
        assert!(m.contains("byte offset 2") && m.contains("a float (4 bytes)") && m.contains("after 3 bytes"), "{m}");
    }

    #[test]
    fn markers_are_found_at_line_starts_only() {
        let mut s = src(b"x $EndFoo\n\x00\x01$EndFo\n$EndFoo  \nnext\n");
        s.skip_to_marker(b"$EndFoo", true).unwrap();
        assert!(s.next_line().unwrap());
        assert_eq!(s.text(), b"next");
        assert_eq!(s.line(), 4);
        let mut s = src(b"abc");
        assert_eq!(s.skip_to_marker(b"$EndFoo", true).unwrap_err().kind(), FailureKind::Truncated);
        let mut s = src(b"\n\n  $EndNodes\r\nrest");
        s.expect_marker(b"$EndNodes", false).unwrap();
        assert!(s.next_line().unwrap());
        assert_eq!((s.text(), s.line()), (&b"rest"[..], 4));
        let mut s = src(b"\n$EndNodez\n");
        let e = s.expect_marker(b"$EndNodes", false).unwrap_err();
        assert!(e.to_string().contains("line 2") && e.to_string().contains("$EndNodez"), "{e}");
    }

    #[test]
    fn overlong_lines_are_rejected() {
        let big = vec![b'x'; MAX_LINE_BYTES + 10];
        let mut s = src(&big);
        assert_eq!(s.next_line().unwrap_err().kind(), FailureKind::ParseError);
    }

    #[test]
    fn sink_enforces_limits_and_triangulates() {
        let mut k = MeshSink::new(Format::Obj, Limits { max_triangles: 2, max_vertices: 3 });
        for i in 0..3 {
            k.vertex([i as f64, 0.0, 0.0], i + 1, Location::Line(1)).unwrap();
        }
        assert_eq!(k.vertex([0.0; 3], 4, Location::Line(2)).unwrap_err().kind(), FailureKind::TooManyVertices);
        k.polygon(&[0, 1, 2, 0], Location::Line(3)).unwrap();
        assert_eq!(k.mesh.triangles, vec![[0, 1, 2], [0, 2, 0]]);
        assert_eq!(k.mesh.n_polygons_triangulated, 1);
        assert_eq!(k.polygon(&[0, 1, 2], Location::Line(4)).unwrap_err().kind(), FailureKind::TooManyTriangles);
        k.polygon(&[0, 1], Location::Line(5)).unwrap();
        assert_eq!(k.mesh.skipped["polygon with fewer than 3 vertices"], 1);
        let e = k.vertex([f64::NAN, 0.0, 0.0], 9, Location::Line(7)).unwrap_err();
        assert!(e.to_string().contains("vertex 9") && e.to_string().contains("line 7"), "{e}");
        let e = check_coordinates(Format::Stl, [1e200, 0.0, 0.0], 1, Location::Byte(96)).unwrap_err();
        assert_eq!(e.kind(), FailureKind::CoordinateOutOfRange);
    }

    #[test]
    fn capacity_hints_are_capped() {
        assert_eq!(capacity_hint(4_000_000_000, 50, Some(5000)), 100);
        assert_eq!(capacity_hint(4_000_000_000, 50, None), 1 << 20);
        assert_eq!(capacity_hint(10, 50, None), 10);
    }
}
