//! `Content-Encoding: zstd` and `gzip` for artifact downloads (RFC 9110
//! §8.4, §12.5.3; RFC 9659).
//!
//! A download is answered encoded when the request has no `Range` (a range
//! always addresses the identity bytes, whose `Content-Length` and `ETag`
//! stay as they are) and its `Accept-Encoding` gives `zstd` or `gzip`
//! (`x-gzip`; `*` for whichever is not listed) a non-zero weight: the
//! higher weight wins, zstd on a tie (about a fifth fewer bytes than gzip on
//! the artifacts). Every artifact is eligible, the `.vtu` files too: their
//! arrays are zlib-compressed at the writer's fast level, and gzip still
//! takes 14-43 % off them. Every artifact answer carries
//! `Vary: Accept-Encoding`.
//!
//! An encoded representation is made once per artifact and coding, on first
//! request, in `<job out dir>/.gzip/<name>.gz` or `.zstd/<name>.zst`
//! (written under a temporary name and renamed, so a reader never sees half
//! a file); its own size and mtime give it its own strong `ETag`. The job's
//! directory removal takes them along.

use std::path::{Path, PathBuf};

use axum::http::{HeaderMap, header};

/// A content coding the server can answer with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coding {
    /// RFC 1952, every HTTP client's.
    Gzip,
    /// RFC 8878, smaller; curl, browsers, and python-requests with
    /// `zstandard` installed ask for it.
    Zstd,
}

impl Coding {
    /// The `Content-Encoding` token.
    #[must_use]
    pub fn token(self) -> &'static str {
        match self {
            Coding::Gzip => "gzip",
            Coding::Zstd => "zstd",
        }
    }

    /// Directory of the cached representations, inside a job's output
    /// directory (a directory, so the job's artifact listing never counts it).
    #[must_use]
    pub fn cache_dir(self) -> &'static str {
        match self {
            Coding::Gzip => ".gzip",
            Coding::Zstd => ".zstd",
        }
    }

    /// File name suffix of a cached representation.
    fn suffix(self) -> &'static str {
        match self {
            Coding::Gzip => "gz",
            Coding::Zstd => "zst",
        }
    }

    /// Writes this coding of the file `src` to `dst`.
    fn encode(self, src: &Path, dst: &Path) -> std::io::Result<u64> {
        match self {
            Coding::Gzip => crate::io::gzip::gzip_file(src, dst),
            Coding::Zstd => crate::io::zstandard::zstd_file(src, dst, crate::io::zstandard::pool_workers()),
        }
    }
}

/// The coding to answer with, from `Accept-Encoding`: the weight of `zstd`,
/// and of `gzip` / `x-gzip`, each if listed, else that of `*`; the higher
/// non-zero weight wins, zstd on a tie; no header (or no non-zero weight)
/// means identity.
#[must_use]
pub fn negotiate(headers: &HeaderMap) -> Option<Coding> {
    let (mut gzip, mut zstd, mut any) = (None, None, None);
    let raise = |w: &mut Option<f64>, q: f64| *w = Some(w.map_or(q, |old: f64| old.max(q)));
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
                "gzip" | "x-gzip" => raise(&mut gzip, q),
                "zstd" => raise(&mut zstd, q),
                "*" => any = Some(q),
                _ => {}
            }
        }
    }
    let (gzip, zstd) = (gzip.or(any).unwrap_or(0.0), zstd.or(any).unwrap_or(0.0));
    if zstd > 0.0 && zstd >= gzip {
        Some(Coding::Zstd)
    } else if gzip > 0.0 {
        Some(Coding::Gzip)
    } else {
        None
    }
}

/// Where the `coding` representation of the artifact at `path` is cached.
pub fn cached_path(path: &Path, coding: Coding) -> Option<PathBuf> {
    let name = path.file_name()?.to_str()?;
    Some(path.parent()?.join(coding.cache_dir()).join(format!("{name}.{}", coding.suffix())))
}

/// The `coding` representation of the artifact at `path`, made if missing
/// or older than the artifact (blocking: run it off the async threads).
///
/// # Errors
/// I/O errors reading the artifact or writing the cache.
pub fn ensure_encoded(path: &Path, coding: Coding) -> std::io::Result<PathBuf> {
    let enc = cached_path(path, coding).ok_or_else(|| std::io::Error::other("artifact path has no file name"))?;
    let source_mtime = std::fs::metadata(path)?.modified()?;
    if std::fs::metadata(&enc).and_then(|m| m.modified()).is_ok_and(|t| t >= source_mtime) {
        return Ok(enc);
    }
    let dir = enc.parent().ok_or_else(|| std::io::Error::other("cache path has no parent"))?;
    std::fs::create_dir_all(dir)?;
    let tmp = dir.join(format!(".{}.{}.tmp", uuid::Uuid::new_v4(), std::process::id()));
    let made = coding.encode(path, &tmp).and_then(|_| std::fs::rename(&tmp, &enc));
    if made.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    made.map(|()| enc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn chosen(v: &'static str) -> Option<Coding> {
        let mut h = HeaderMap::new();
        h.insert(header::ACCEPT_ENCODING, HeaderValue::from_static(v));
        negotiate(&h)
    }

    #[test]
    fn weights_decide() {
        assert_eq!(negotiate(&HeaderMap::new()), None);
        for gzip in ["gzip", "gzip, deflate, br", "GZIP;q=0.5", "x-gzip", "br, *;q=0.1, zstd;q=0", "gzip;q=0, gzip;q=1"]
        {
            assert_eq!(chosen(gzip), Some(Coding::Gzip), "{gzip}");
        }
        for zstd in
            ["zstd", "deflate, gzip, br, zstd", "*", "gzip;q=0.5, zstd;q=0.6", "gzip, zstd", "br, *;q=0.1", "ZSTD"]
        {
            assert_eq!(chosen(zstd), Some(Coding::Zstd), "{zstd}");
        }
        assert_eq!(chosen("gzip;q=0.9, zstd;q=0.8"), Some(Coding::Gzip));
        for none in ["identity", "br", "gzip;q=0", "gzip; q=0.0", "*;q=0", "gzip;q=0, zstd;q=0, *", "", "deflate"] {
            assert_eq!(chosen(none), None, "{none}");
        }
    }

    #[test]
    fn the_cache_is_made_once_and_decodes_to_the_artifact() {
        use std::io::Read;
        let dir = tempfile::tempdir().unwrap();
        let art = dir.path().join("atlas.msh");
        std::fs::write(&art, b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n".repeat(1000)).unwrap();
        for (coding, cached) in [(Coding::Gzip, ".gzip/atlas.msh.gz"), (Coding::Zstd, ".zstd/atlas.msh.zst")] {
            let enc = ensure_encoded(&art, coding).unwrap();
            assert_eq!(enc, dir.path().join(cached));
            let first = std::fs::metadata(&enc).unwrap().modified().unwrap();
            assert_eq!(ensure_encoded(&art, coding).unwrap(), enc);
            assert_eq!(std::fs::metadata(&enc).unwrap().modified().unwrap(), first, "cached, not remade");
            let back = match coding {
                Coding::Gzip => {
                    let mut back = Vec::new();
                    flate2::read::GzDecoder::new(std::fs::File::open(&enc).unwrap()).read_to_end(&mut back).unwrap();
                    back
                }
                Coding::Zstd => zstd::decode_all(std::fs::File::open(&enc).unwrap()).unwrap(),
            };
            assert_eq!(back, std::fs::read(&art).unwrap());
        }
    }
}
