//! Bounds on the framing of a `multipart/form-data` body, enforced on the
//! byte stream before the multipart parser sees it.
//!
//! The parser (multer) buffers the preamble (bytes before the first
//! `--boundary`) and each part's header block (up to the blank line) whole
//! before it yields anything, and counts neither against a part's size
//! limit, so a 200 MB header line would sit in memory. [`FramingGuard`]
//! follows the framing as the bytes pass (RFC 2046 §5.1.1: a delimiter is
//! CRLF `--boundary`; the first one may come without the CRLF; the close
//! delimiter ends in `--`) and fails the stream as soon as a preamble passes
//! [`MAX_PREAMBLE_BYTES`] or a header block (from the delimiter to the blank
//! line, the delimiter line's rest included) passes [`MAX_PART_HEADER_BYTES`].
//! Part data is searched for the delimiter with `memmem`, so the guard adds a
//! scan, not a copy.

use std::pin::Pin;
use std::task::{Context, Poll};

use axum::body::Bytes;
use futures_util::{Stream, StreamExt};
use memchr::memmem;

/// Longest accepted preamble before the first boundary.
pub const MAX_PREAMBLE_BYTES: usize = 8192;
/// Longest accepted header block of one part.
pub const MAX_PART_HEADER_BYTES: usize = 8192;

/// Why the guard stopped the body.
#[derive(Debug, thiserror::Error)]
pub enum FramingError {
    /// The preamble is longer than [`MAX_PREAMBLE_BYTES`].
    #[error("the preamble before the first boundary exceeds {MAX_PREAMBLE_BYTES} bytes")]
    PreambleTooLong,
    /// A part's header block is longer than [`MAX_PART_HEADER_BYTES`].
    #[error("a part's headers exceed {MAX_PART_HEADER_BYTES} bytes")]
    PartHeadersTooLong,
    /// Reading the body failed (the client went away).
    #[error("reading the upload failed: {0}")]
    Body(String),
}

/// Where in the multipart framing the stream is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Place {
    /// Before the first `--boundary`.
    Preamble,
    /// After a delimiter: its line's rest, then header lines up to the blank line.
    Headers { line_done: bool },
    /// A part's data, up to the next delimiter.
    Data,
    /// After the close delimiter (the parser stops there).
    Epilogue,
}

/// A body stream that fails once its multipart framing exceeds the caps.
pub struct FramingGuard<S> {
    inner: S,
    /// `--boundary`, ending the preamble.
    dash_boundary: Vec<u8>,
    /// CRLF `--boundary`, ending a part's data.
    delimiter: memmem::Finder<'static>,
    place: Place,
    /// Bytes of the current preamble or header block so far.
    counted: usize,
    /// The last bytes seen, for patterns split across chunks.
    window: Vec<u8>,
    failed: bool,
}

impl<S> FramingGuard<S> {
    /// Guards `inner`, a body whose multipart boundary is `boundary`.
    pub fn new(inner: S, boundary: &str) -> Self {
        let delimiter = format!("\r\n--{boundary}").into_bytes();
        Self {
            inner,
            dash_boundary: delimiter[2..].to_vec(),
            delimiter: memmem::Finder::new(&delimiter).into_owned(),
            place: Place::Preamble,
            counted: 0,
            window: Vec::new(),
            failed: false,
        }
    }

    /// Enters a header block (just after a boundary).
    fn start_headers(&mut self) {
        self.place = Place::Headers { line_done: false };
        self.counted = 0;
        self.window.clear();
    }

    /// Follows one preamble or header byte; errors past the caps.
    fn step_framing_byte(&mut self, b: u8) -> Result<(), FramingError> {
        self.counted += 1;
        self.window.push(b);
        match self.place {
            Place::Preamble => {
                // The preamble is what precedes `--boundary`.
                let preamble = self.counted.saturating_sub(self.dash_boundary.len());
                if self.counted > MAX_PREAMBLE_BYTES + self.dash_boundary.len() {
                    return Err(FramingError::PreambleTooLong);
                }
                if self.window.ends_with(&self.dash_boundary) {
                    if preamble > MAX_PREAMBLE_BYTES {
                        return Err(FramingError::PreambleTooLong);
                    }
                    self.start_headers();
                    return Ok(());
                }
                let keep = self.dash_boundary.len();
                if self.window.len() > 2 * keep {
                    self.window.drain(..self.window.len() - keep);
                }
            }
            Place::Headers { line_done } => {
                if self.counted > MAX_PART_HEADER_BYTES {
                    return Err(FramingError::PartHeadersTooLong);
                }
                if !line_done && self.counted == 2 && self.window.ends_with(b"--") {
                    self.place = Place::Epilogue;
                } else if !line_done && self.window.ends_with(b"\r\n") {
                    // The parser looks for the blank line after the delimiter line.
                    self.place = Place::Headers { line_done: true };
                    self.window.clear();
                } else if line_done && self.window.ends_with(b"\r\n\r\n") {
                    self.place = Place::Data;
                    self.counted = 0;
                    self.window.clear();
                }
                if self.window.len() > 8 {
                    self.window.drain(..self.window.len() - 4);
                }
            }
            Place::Data | Place::Epilogue => {}
        }
        Ok(())
    }

    /// Skips part data in `rest` up to just past the next delimiter; the
    /// number of bytes consumed (all of `rest` when there is none).
    fn skip_data(&mut self, rest: &[u8]) -> usize {
        let n = self.delimiter.needle().len();
        if !self.window.is_empty() {
            // A delimiter split between the previous chunk and this one.
            let mut seam = self.window.clone();
            seam.extend_from_slice(&rest[..rest.len().min(n - 1)]);
            if let Some(p) = self.delimiter.find(&seam) {
                let used = p + n - self.window.len();
                self.start_headers();
                return used;
            }
        }
        if let Some(p) = self.delimiter.find(rest) {
            self.start_headers();
            return p + n;
        }
        self.window.extend_from_slice(&rest[rest.len().saturating_sub(n - 1)..]);
        let excess = self.window.len().saturating_sub(n - 1);
        self.window.drain(..excess);
        rest.len()
    }

    /// Follows the framing through one chunk.
    fn check_chunk(&mut self, chunk: &[u8]) -> Result<(), FramingError> {
        let mut i = 0;
        while i < chunk.len() {
            match self.place {
                Place::Data => i += self.skip_data(&chunk[i..]),
                Place::Epilogue => return Ok(()),
                Place::Preamble | Place::Headers { .. } => {
                    self.step_framing_byte(chunk[i])?;
                    i += 1;
                }
            }
        }
        Ok(())
    }
}

impl<S, E> Stream for FramingGuard<S>
where
    S: Stream<Item = Result<Bytes, E>> + Unpin,
    E: std::fmt::Display,
{
    type Item = Result<Bytes, FramingError>;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        if self.failed {
            return Poll::Ready(None);
        }
        let item = match self.inner.poll_next_unpin(cx) {
            Poll::Ready(Some(Ok(chunk))) => match self.check_chunk(&chunk) {
                Ok(()) => Ok(chunk),
                Err(e) => Err(e),
            },
            Poll::Ready(Some(Err(e))) => Err(FramingError::Body(e.to_string())),
            Poll::Ready(None) => return Poll::Ready(None),
            Poll::Pending => return Poll::Pending,
        };
        self.failed = item.is_err();
        Poll::Ready(Some(item))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds `body` in chunks of `size` bytes; the first error.
    fn check_in_chunks(body: &[u8], size: usize) -> Result<(), FramingError> {
        let mut g = FramingGuard::new((), "XyZ");
        body.chunks(size).try_for_each(|c| g.check_chunk(c))
    }

    fn body(preamble: &str, headers: &str, data: &str) -> Vec<u8> {
        format!(
            "{preamble}--XyZ\r\nContent-Disposition: form-data; name=\"file\"\r\n{headers}\r\n{data}\r\n--XyZ\r\n\
             Content-Disposition: form-data; name=\"params\"\r\n\r\n{{}}\r\n--XyZ--\r\nepilogue"
        )
        .into_bytes()
    }

    #[test]
    fn ordinary_bodies_pass_in_any_chunking() {
        let b = body("preamble\r\n", "Content-Type: model/stl\r\n", "solid x\r\n--XyZnot a delimiter\r\n--X");
        for size in [1, 2, 3, 5, 7, 64, 4096] {
            check_in_chunks(&b, size).unwrap();
        }
        // A long part body is data, not headers.
        let long = "d".repeat(100_000);
        check_in_chunks(&body("", "", &long), 1000).unwrap();
    }

    #[test]
    fn long_preambles_and_header_blocks_fail_in_any_chunking() {
        let long = "h".repeat(MAX_PART_HEADER_BYTES);
        let cases = [
            (body(&"p".repeat(MAX_PREAMBLE_BYTES + 1), "", "x"), "preamble"),
            (body("", &format!("X-Junk: {long}\r\n"), "x"), "headers"),
            (body("", &"X-A: b\r\n".repeat(MAX_PART_HEADER_BYTES / 8 + 1), "x"), "headers"),
        ];
        for (b, what) in &cases {
            for size in [1, 3, 4096, 1 << 20] {
                let e = check_in_chunks(b, size).unwrap_err();
                assert!(e.to_string().contains(what), "{size}: {e}");
            }
        }
        // The second part's headers are checked too.
        let b = format!("--XyZ\r\n\r\n\r\nx\r\n--XyZ\r\nX-Junk: {long}\r\n\r\ny\r\n--XyZ--\r\n");
        assert!(matches!(check_in_chunks(b.as_bytes(), 100), Err(FramingError::PartHeadersTooLong)));
    }

    #[test]
    fn a_delimiter_split_across_chunks_is_found() {
        let data = "a".repeat(50);
        let long = "h".repeat(MAX_PART_HEADER_BYTES + 10);
        let b = format!("--XyZ\r\nA: b\r\n\r\n{data}\r\n--XyZ\r\nX-Junk: {long}\r\n\r\ny\r\n--XyZ--\r\n");
        for size in 40..70 {
            assert!(matches!(check_in_chunks(b.as_bytes(), size), Err(FramingError::PartHeadersTooLong)), "{size}");
        }
    }
}
