//! zstd (RFC 8878) of a file, for the `Content-Encoding: zstd`
//! representation of downloads (RFC 9659).
//!
//! One frame, compressed by libzstd's own worker threads. Its
//! multi-threaded mode cuts the input into jobs whose size and overlap
//! depend only on the parameters, so the bytes are the same for any number
//! of workers ≥ 1 ([`tests::bytes_do_not_depend_on_the_worker_count`]); the
//! overlap keeps most of the one-thread ratio, which independent frames
//! lose (see `docs/decisions.md`, session 17).

use std::path::Path;

use ::zstd::stream::write::Encoder;
use ::zstd::zstd_safe::CParameter;

/// Compression level: level 9 has level 12's ratio on the artifacts at a
/// third of its time.
pub const LEVEL: i32 = 9;

/// log2 of the window: 4 MiB, within the 8 MiB an HTTP client may refuse
/// to go beyond (RFC 9659 §3).
pub const WINDOW_LOG: u32 = 22;

/// Writes the zstd frame of the file at `src` to `dst` (created or
/// truncated) with `workers` compression threads (at least 1) and returns
/// the bytes written. The frame records the content size and a checksum.
///
/// # Errors
/// I/O errors of either file, or `src` changing length while it is read.
pub fn zstd_file(src: &Path, dst: &Path, workers: u32) -> std::io::Result<u64> {
    let mut input = std::fs::File::open(src)?;
    let len = input.metadata()?.len();
    let mut enc = Encoder::new(std::fs::File::create(dst)?, LEVEL)?;
    enc.multithread(workers.max(1))?;
    enc.set_parameter(CParameter::WindowLog(WINDOW_LOG))?;
    enc.include_checksum(true)?;
    enc.set_pledged_src_size(Some(len))?;
    let copied = std::io::copy(&mut input, &mut enc)?;
    if copied != len {
        return Err(std::io::Error::other(format!("{} changed length while it was compressed", src.display())));
    }
    let out = enc.finish()?;
    out.sync_all()?;
    Ok(out.metadata()?.len())
}

/// Compression workers for the current rayon pool (its thread count).
#[must_use]
pub fn pool_workers() -> u32 {
    u32::try_from(rayon::current_num_threads()).unwrap_or(1).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::gzip::tests::sample;

    fn compress(data: &[u8], workers: u32) -> Vec<u8> {
        let dir = tempfile::tempdir().unwrap();
        let (src, dst) = (dir.path().join("a"), dir.path().join("a.zst"));
        std::fs::write(&src, data).unwrap();
        let written = zstd_file(&src, &dst, workers).unwrap();
        let z = std::fs::read(&dst).unwrap();
        assert_eq!(written, z.len() as u64);
        z
    }

    #[test]
    fn decodes_to_the_input() {
        for n in [0, 1, 1000, (1 << 20) + 17] {
            let data = sample(n);
            let z = compress(&data, 2);
            assert!(::zstd::decode_all(&z[..]).unwrap() == data, "{n} bytes do not round-trip");
        }
    }

    #[test]
    fn the_window_is_at_most_8_mib_and_the_size_is_recorded() {
        let data = sample(12 << 20); // larger than the window
        let z = compress(&data, 2);
        // Frame header (RFC 8878 §3.1.1.1): magic, descriptor, window descriptor.
        assert_eq!(&z[..4], &[0x28, 0xb5, 0x2f, 0xfd]);
        let descriptor = z[4];
        assert_eq!(descriptor & 0x20, 0, "not single-segment: a window descriptor follows");
        assert_ne!(descriptor >> 6, 0, "the content size is recorded");
        assert_ne!(descriptor & 0x04, 0, "the checksum flag is set");
        let exponent = u32::from(z[5] >> 3);
        let mantissa = u64::from(z[5] & 7);
        let base = 1u64 << (10 + exponent);
        let window = base + base / 8 * mantissa;
        assert!(window <= 8 << 20, "window {window}");
    }

    #[test]
    fn bytes_do_not_depend_on_the_worker_count() {
        // Larger than one multi-threaded job (4 windows), so several run at once.
        let data = sample(40 << 20);
        let one = compress(&data, 1);
        assert!(compress(&data, 2) == one);
        assert!(compress(&data, 3) == one);
        assert!(::zstd::decode_all(&one[..]).unwrap() == data);
    }
}
