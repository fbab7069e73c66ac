//! `Content-Encoding: gzip` for artifact downloads (RFC 9110 §8.4, §12.5.3).
//!
//! A download is answered gzip-encoded when the request's `Accept-Encoding`
//! gives `gzip` (or `x-gzip`, or `*` without a `gzip` entry) a non-zero
//! weight and the request has no `Range` (a range always addresses the
//! identity bytes, whose `Content-Length` and `ETag` stay as they are).
//! Every artifact is eligible, the `.vtu` files too: their arrays are
//! zlib-compressed at the writer's fast level, and gzip still takes 14-43 %
//! off them. Every artifact answer carries `Vary: Accept-Encoding`.
//!
//! The gzip representation is made once per artifact, on first request, in
//! `<job out dir>/.gzip/<name>.gz` (written under a temporary name and
//! renamed, so a reader never sees half a file); its own size and mtime give
//! it its own strong `ETag`. The job's directory removal takes it along.

use std::path::{Path, PathBuf};

use axum::http::{HeaderMap, header};

/// Directory of the cached gzip representations, inside a job's output
/// directory (a directory, so the job's artifact listing never counts it).
pub const CACHE_DIR: &str = ".gzip";

/// Whether `Accept-Encoding` allows gzip: the weight of `gzip` / `x-gzip`
/// if listed, else that of `*`, must be above 0; no header means identity.
pub fn accepts_gzip(headers: &HeaderMap) -> bool {
    let mut gzip = None;
    let mut any = None;
    for value in headers.get_all(header::ACCEPT_ENCODING) {
        let Ok(value) = value.to_str() else { continue };
        for item in value.split(',') {
            let mut parts = item.split(';');
            let coding = parts.next().unwrap_or("").trim().to_ascii_lowercase();
            let q = parts.find_map(|p| {
                let (k, v) = p.split_once('=')?;
                k.trim().eq_ignore_ascii_case("q").then(|| v.trim().parse::<f64>().unwrap_or(0.0))
            });
            let q = q.unwrap_or(1.0);
            match coding.as_str() {
                "gzip" | "x-gzip" => gzip = Some(gzip.map_or(q, |g: f64| g.max(q))),
                "*" => any = Some(q),
                _ => {}
            }
        }
    }
    gzip.or(any).is_some_and(|q| q > 0.0)
}

/// Where the gzip representation of the artifact at `path` is cached.
pub fn cached_path(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?.to_str()?;
    Some(path.parent()?.join(CACHE_DIR).join(format!("{name}.gz")))
}

/// The gzip representation of the artifact at `path`, made if missing or
/// older than the artifact (blocking: run it off the async threads).
///
/// # Errors
/// I/O errors reading the artifact or writing the cache.
pub fn ensure_gzip(path: &Path) -> std::io::Result<PathBuf> {
    let gz = cached_path(path).ok_or_else(|| std::io::Error::other("artifact path has no file name"))?;
    let source_mtime = std::fs::metadata(path)?.modified()?;
    if std::fs::metadata(&gz).and_then(|m| m.modified()).is_ok_and(|t| t >= source_mtime) {
        return Ok(gz);
    }
    let dir = gz.parent().ok_or_else(|| std::io::Error::other("cache path has no parent"))?;
    std::fs::create_dir_all(dir)?;
    let tmp = dir.join(format!(".{}.{}.tmp", uuid::Uuid::new_v4(), std::process::id()));
    let made = crate::io::gzip::gzip_file(path, &tmp).and_then(|_| std::fs::rename(&tmp, &gz));
    if made.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    made.map(|()| gz)
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn accepts(v: &'static str) -> bool {
        let mut h = HeaderMap::new();
        h.insert(header::ACCEPT_ENCODING, HeaderValue::from_static(v));
        accepts_gzip(&h)
    }

    #[test]
    fn weights_decide() {
        assert!(!accepts_gzip(&HeaderMap::new()));
        for yes in ["gzip", "gzip, deflate, br", "GZIP;q=0.5", "x-gzip", "*", "br, *;q=0.1", "gzip;q=0, gzip;q=1"] {
            assert!(accepts(yes), "{yes}");
        }
        for no in ["identity", "br, zstd", "gzip;q=0", "gzip; q=0.0", "*;q=0", "gzip;q=0, *", "", "deflate"] {
            assert!(!accepts(no), "{no}");
        }
    }

    #[test]
    fn the_cache_is_made_once_and_decodes_to_the_artifact() {
        use std::io::Read;
        let dir = tempfile::tempdir().unwrap();
        let art = dir.path().join("atlas.msh");
        std::fs::write(&art, b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n".repeat(1000)).unwrap();
        let gz = ensure_gzip(&art).unwrap();
        assert_eq!(gz, dir.path().join(".gzip/atlas.msh.gz"));
        let first = std::fs::metadata(&gz).unwrap().modified().unwrap();
        assert_eq!(ensure_gzip(&art).unwrap(), gz);
        assert_eq!(std::fs::metadata(&gz).unwrap().modified().unwrap(), first, "cached, not remade");
        let mut back = Vec::new();
        flate2::read::GzDecoder::new(std::fs::File::open(&gz).unwrap()).read_to_end(&mut back).unwrap();
        assert_eq!(back, std::fs::read(&art).unwrap());
    }
}
