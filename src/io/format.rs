//! The table of supported mesh formats and how to recognise them: by file
//! extension, by a `?format=` name, by HTTP media type, or by content.
//!
//! Content sniffing ([`Format::sniff`]) looks at the first bytes only:
//! `$MeshFormat` (or another `$Section` line) → MSH, `ply` → PLY, a binary
//! STL whose size is exactly `84 + 50·n` (n = the `u32` at bytes 80..84) →
//! STL, `solid` → STL (ASCII), a first statement that is an OBJ keyword →
//! OBJ. The size rule is checked before `solid` because several real binary
//! STL files start their 80-byte header with "solid".

use serde::{Deserialize, Serialize};
use std::fmt;

/// A supported input mesh format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// STL, ASCII or binary (triangle soup).
    Stl,
    /// Wavefront OBJ (`v` and `f` statements).
    Obj,
    /// Stanford PLY, ASCII or binary (either endianness).
    Ply,
    /// Gmsh MSH 2.2 or 4.1, ASCII or binary.
    Msh,
}

impl Format {
    /// Every format, in a fixed order.
    pub const ALL: [Format; 4] = [Format::Stl, Format::Obj, Format::Ply, Format::Msh];

    /// The format for a file extension (case-insensitive, with or without the dot).
    pub fn from_extension(ext: &str) -> Option<Format> {
        let ext = ext.strip_prefix('.').unwrap_or(ext);
        Format::ALL.into_iter().find(|f| f.extension().eq_ignore_ascii_case(ext))
    }

    /// The format for a name as used in `?format=`: `stl`, `obj`, `ply` or `msh`
    /// (case-insensitive).
    pub fn from_name(name: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.extension().eq_ignore_ascii_case(name.trim()))
    }

    /// The format for an HTTP media type (`Content-Type`), ignoring parameters
    /// such as `; charset=utf-8`. Generic types (`application/octet-stream`,
    /// `text/plain`) give `None`: sniff the content instead.
    pub fn from_media_type(ct: &str) -> Option<Format> {
        let essence = ct.split(';').next().unwrap_or("").trim().to_ascii_lowercase();
        let f = match essence.as_str() {
            "model/stl"
            | "model/x.stl-ascii"
            | "model/x.stl-binary"
            | "application/sla"
            | "application/vnd.ms-pki.stl"
            | "application/x-stl"
            | "application/stl"
            | "model/x-stl"
            | "text/x-stl" => Format::Stl,
            "model/obj" | "model/x-obj" | "application/x-obj" | "text/x-obj" | "application/obj"
            | "application/x-tgif" => Format::Obj,
            "application/ply" | "model/ply" | "model/x-ply" | "application/x-ply" | "text/x-ply" => Format::Ply,
            "model/x-gmsh" | "application/x-gmsh" | "model/vnd.gmsh" | "model/x-msh" | "application/x-msh"
            | "text/x-gmsh" | "text/x-msh" => Format::Msh,
            _ => return None,
        };
        Some(f)
    }

    /// Guess the format from the first bytes of the content. `total_len` is
    /// the full size when known; it makes binary STL recognition exact.
    ///
    /// Without `total_len`, a head of at least 84 bytes that is not text is
    /// taken for binary STL (the STL reader then checks the size).
    pub fn sniff(head: &[u8], total_len: Option<u64>) -> Option<Format> {
        if let Some(n) = binary_stl_count(head)
            && total_len == Some(84 + 50 * u64::from(n))
        {
            return Some(Format::Stl);
        }
        let text = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(head);
        let start = text.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(text.len());
        let text = &text[start..];
        if text.starts_with(b"$") && text.len() > 1 && text[1].is_ascii_alphabetic() {
            return Some(Format::Msh);
        }
        if text.starts_with(b"ply") && matches!(text.get(3), Some(b'\n' | b'\r')) {
            return Some(Format::Ply);
        }
        if starts_with_ignore_case(text, b"solid") {
            return Some(Format::Stl);
        }
        if looks_binary(head) {
            return (total_len.is_none() && head.len() >= 84).then_some(Format::Stl);
        }
        if first_statement_is_obj(text) {
            return Some(Format::Obj);
        }
        None
    }

    /// The usual file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Stl => "stl",
            Format::Obj => "obj",
            Format::Ply => "ply",
            Format::Msh => "msh",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Stl => "STL",
            Format::Obj => "OBJ",
            Format::Ply => "PLY",
            Format::Msh => "MSH",
        })
    }
}

/// The triangle count of a binary STL header, when `head` holds 84 bytes.
pub(crate) fn binary_stl_count(head: &[u8]) -> Option<u32> {
    let b: [u8; 4] = head.get(80..84)?.try_into().ok()?;
    Some(u32::from_le_bytes(b))
}

/// True when `head` has a control byte that text formats never contain.
pub(crate) fn looks_binary(head: &[u8]) -> bool {
    head.iter().any(|&b| b < 0x09 || (0x0E..0x20).contains(&b) || b == 0x7F)
}

/// ASCII case-insensitive prefix test.
pub(crate) fn starts_with_ignore_case(text: &[u8], prefix: &[u8]) -> bool {
    text.len() >= prefix.len() && text[..prefix.len()].eq_ignore_ascii_case(prefix)
}

/// True when the first line that is not blank or a `#` comment starts with an
/// OBJ keyword (or when every complete line is a comment).
fn first_statement_is_obj(text: &[u8]) -> bool {
    const KEYWORDS: &[&[u8]] = &[
        b"v", b"vt", b"vn", b"vp", b"f", b"l", b"p", b"o", b"g", b"s", b"usemtl", b"mtllib", b"cstype", b"deg",
        b"curv", b"surf",
    ];
    let mut saw_comment = false;
    for line in text.split(|&b| b == b'\n') {
        let mut words = line.split(|b| b.is_ascii_whitespace()).filter(|w| !w.is_empty());
        match words.next() {
            None => continue,
            Some(w) if w.starts_with(b"#") => saw_comment = true,
            Some(w) => return KEYWORDS.contains(&w),
        }
    }
    saw_comment
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_extensions_and_media_types() {
        assert_eq!(Format::from_extension("STL"), Some(Format::Stl));
        assert_eq!(Format::from_extension(".Obj"), Some(Format::Obj));
        assert_eq!(Format::from_extension("ply"), Some(Format::Ply));
        assert_eq!(Format::from_extension(".msh"), Some(Format::Msh));
        assert_eq!(Format::from_extension("vtk"), None);
        assert_eq!(Format::from_extension(""), None);
        assert_eq!(Format::from_name("msh"), Some(Format::Msh));
        assert_eq!(Format::from_name("gltf"), None);
        assert_eq!(Format::from_media_type("model/stl"), Some(Format::Stl));
        assert_eq!(Format::from_media_type("application/SLA; charset=binary"), Some(Format::Stl));
        assert_eq!(Format::from_media_type("model/obj"), Some(Format::Obj));
        assert_eq!(Format::from_media_type("application/ply"), Some(Format::Ply));
        assert_eq!(Format::from_media_type("model/x-gmsh"), Some(Format::Msh));
        assert_eq!(Format::from_media_type("application/octet-stream"), None);
        for f in Format::ALL {
            assert_eq!(Format::from_extension(f.extension()), Some(f));
            assert_eq!(Format::from_name(f.extension()), Some(f));
        }
        assert_eq!(serde_json::to_string(&Format::Msh).unwrap(), "\"msh\"");
        assert_eq!(serde_json::from_str::<Format>("\"ply\"").unwrap(), Format::Ply);
    }

    #[test]
    fn sniffs_content() {
        assert_eq!(Format::sniff(b"$MeshFormat\n4.1 0 8\n", None), Some(Format::Msh));
        assert_eq!(Format::sniff(b"ply\nformat ascii 1.0\n", None), Some(Format::Ply));
        assert_eq!(Format::sniff(b"ply\r\nformat ascii 1.0\r\n", None), Some(Format::Ply));
        assert_eq!(Format::sniff(b"solid cube\n facet normal 0 0 1\n", None), Some(Format::Stl));
        assert_eq!(Format::sniff(b"# comment\n\nv 0 0 0\nv 1 0 0\n", None), Some(Format::Obj));
        assert_eq!(Format::sniff(b"mtllib a.mtl\n", None), Some(Format::Obj));
        assert_eq!(Format::sniff(b"hello world\n", None), None);
        assert_eq!(Format::sniff(b"", None), None);
        // A binary STL whose header starts with "solid" is recognised by its size.
        let mut bin = vec![b' '; 84];
        bin[..5].copy_from_slice(b"solid");
        bin[80..84].copy_from_slice(&2u32.to_le_bytes());
        assert_eq!(Format::sniff(&bin, Some(84 + 100)), Some(Format::Stl));
        let mut bin = vec![0u8; 84];
        bin[80] = 1;
        assert_eq!(Format::sniff(&bin, Some(134)), Some(Format::Stl));
        assert_eq!(Format::sniff(&bin, None), Some(Format::Stl));
        assert_eq!(Format::sniff(&bin, Some(135)), None);
    }
}
