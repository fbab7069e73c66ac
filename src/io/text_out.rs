//! Small helpers for writing ASCII numbers fast into a byte buffer.
//!
//! Floats are written in the shortest form that parses back to the same
//! `f64` (`zmij`, the algorithm `serde_json` uses): `0.1`, `1.0`, `1e-7`,
//! `1.5e300`. C's `strtod` (Gmsh), Python's `float` (meshio) and VTK's
//! readers all accept this form, so an ASCII file round-trips exactly.
//! Non-finite values come out as `NaN`, `inf`, `-inf`, which `strtod` and
//! Python also accept.

/// Append `x` in shortest round-trip form.
#[inline]
pub(crate) fn push_f64(buf: &mut Vec<u8>, x: f64) {
    let mut b = zmij::Buffer::new();
    buf.extend_from_slice(b.format(x).as_bytes());
}

/// Append an unsigned integer.
#[inline]
pub(crate) fn push_u64(buf: &mut Vec<u8>, x: u64) {
    let mut b = itoa::Buffer::new();
    buf.extend_from_slice(b.format(x).as_bytes());
}

/// Append a signed integer.
#[inline]
pub(crate) fn push_i64(buf: &mut Vec<u8>, x: i64) {
    let mut b = itoa::Buffer::new();
    buf.extend_from_slice(b.format(x).as_bytes());
}

/// Append the floats of `xs` separated by single spaces.
#[inline]
pub(crate) fn push_f64s(buf: &mut Vec<u8>, xs: &[f64]) {
    for (i, &x) in xs.iter().enumerate() {
        if i > 0 {
            buf.push(b' ');
        }
        push_f64(buf, x);
    }
}

/// Flush `buf` into `w` once it holds more than `limit` bytes; keeps the
/// allocation for reuse. Writers call this after each line so memory stays
/// bounded however large the mesh.
#[inline]
pub(crate) fn flush_if_full(w: &mut impl std::io::Write, buf: &mut Vec<u8>, limit: usize) -> std::io::Result<()> {
    if buf.len() >= limit {
        w.write_all(buf)?;
        buf.clear();
    }
    Ok(())
}

/// Buffer size at which the writers hand bytes to the underlying writer.
pub(crate) const CHUNK: usize = 1 << 16;

/// Rows formatted by one task of [`write_rows_par`]: large enough that a
/// task's overhead is negligible, small enough that every core gets work.
pub(crate) const ROWS_PER_CHUNK: usize = 4096;

/// Chunks formatted before they are written (bounds the memory held at once
/// to about this many chunks, a few MB).
const CHUNKS_PER_ROUND: usize = 16;

/// Writes rows `0..n_rows` to `w`: `format_row(buf, i)` appends row `i` to
/// `buf`. Rows are formatted in parallel in chunks of [`ROWS_PER_CHUNK`] and
/// written in order, so the bytes do not depend on the number of threads
/// (each row's text depends only on `i`). Chunk buffers are reused between
/// rounds; nothing is allocated per number.
pub(crate) fn write_rows_par<W: std::io::Write + ?Sized>(
    w: &mut W,
    n_rows: usize,
    format_row: impl Fn(&mut Vec<u8>, usize) + Sync,
) -> std::io::Result<()> {
    use rayon::prelude::*;
    let n_chunks = n_rows.div_ceil(ROWS_PER_CHUNK);
    let mut bufs: Vec<Vec<u8>> = vec![Vec::new(); CHUNKS_PER_ROUND.min(n_chunks)];
    for first in (0..n_chunks).step_by(CHUNKS_PER_ROUND) {
        let n = CHUNKS_PER_ROUND.min(n_chunks - first);
        bufs[..n].par_iter_mut().enumerate().for_each(|(k, buf)| {
            buf.clear();
            let lo = (first + k) * ROWS_PER_CHUNK;
            for i in lo..(lo + ROWS_PER_CHUNK).min(n_rows) {
                format_row(buf, i);
            }
        });
        for buf in &bufs[..n] {
            w.write_all(buf)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_round_trip_through_text() {
        for x in [0.0, -0.0, 1.0, 0.1, 1.0 / 3.0, 1e-7, 6.123234262925839e-17, 1.5e300, -2.5e-310, f64::MAX] {
            let mut buf = Vec::new();
            push_f64(&mut buf, x);
            let s = std::str::from_utf8(&buf).unwrap();
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), x.to_bits(), "{s}");
        }
        let mut buf = Vec::new();
        push_f64s(&mut buf, &[1.0, 2.5]);
        push_u64(&mut buf, 7);
        push_i64(&mut buf, -3);
        assert_eq!(buf, b"1.0 2.57-3");
    }
}
