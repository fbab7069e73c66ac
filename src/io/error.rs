//! Errors of the IO layer: what is wrong with an input file, and where.
//!
//! Every variant names the place of the problem: a 1-based line number for
//! text data, a 0-based byte offset for binary data ([`Location`]). Each
//! variant maps to a stable [`FailureKind`] ([`IoError::kind`]) that the HTTP
//! layer uses as the `type` of its problem document; the kinds never change
//! once published, messages may be improved.

use super::Format;
use crate::failure::FailureKind;
use std::fmt;
use thiserror::Error;

/// Where in the input a problem was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// 1-based line number of text data.
    Line(u64),
    /// 0-based byte offset of binary data.
    Byte(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(l) => write!(f, "line {l}"),
            Location::Byte(b) => write!(f, "byte offset {b}"),
        }
    }
}

/// A mesh file that cannot be read, with the reason and its place.
#[derive(Debug, Error)]
pub enum IoError {
    /// The input has no bytes at all.
    #[error("the file is empty")]
    EmptyFile,

    /// The format could not be determined, or the given name is not a format.
    #[error("unknown mesh format: {reason}")]
    UnknownFormat {
        /// What was tried (extension, media type, content sniffing).
        reason: String,
    },

    /// The data ends before the structure it announced is complete.
    #[error("{format} file is truncated at {at}: {detail}")]
    Truncated {
        /// Format being read.
        format: Format,
        /// Where the data ended.
        at: Location,
        /// What was being read (and how much was expected when known).
        detail: String,
    },

    /// A binary STL whose size does not match its triangle count.
    #[error(
        "binary STL is truncated: its header declares {n_triangles} triangles, which need \
         84 + 50 × {n_triangles} = {expected_bytes} bytes, but the file has {actual_bytes} bytes"
    )]
    TruncatedBinaryStl {
        /// Triangle count from bytes 80..84 of the header.
        n_triangles: u64,
        /// `84 + 50 · n_triangles`.
        expected_bytes: u64,
        /// Bytes actually present.
        actual_bytes: u64,
    },

    /// Malformed content: a wrong keyword, a token that is not a number, ...
    #[error("{format} parse error at {at}: {message}")]
    Parse {
        /// Format being read.
        format: Format,
        /// Where the problem is.
        at: Location,
        /// What was expected and what was found.
        message: String,
    },

    /// A vertex coordinate is NaN or infinite.
    #[error("{format}: vertex {vertex} has a non-finite coordinate ({x}, {y}, {z}) at {at}")]
    NonFiniteCoordinate {
        /// Format being read.
        format: Format,
        /// 1-based vertex (node tag for MSH) as the file numbers it.
        vertex: u64,
        /// The coordinates read.
        x: f64,
        /// The coordinates read.
        y: f64,
        /// The coordinates read.
        z: f64,
        /// Where the vertex is.
        at: Location,
    },

    /// A vertex coordinate is finite but so large that products of
    /// coordinates (areas, volumes) would overflow.
    #[error("{format}: vertex {vertex} has coordinate {value:e} at {at}, beyond the supported magnitude {max:e}")]
    CoordinateOutOfRange {
        /// Format being read.
        format: Format,
        /// 1-based vertex (node tag for MSH) as the file numbers it.
        vertex: u64,
        /// The offending coordinate.
        value: f64,
        /// Largest accepted magnitude.
        max: f64,
        /// Where the vertex is.
        at: Location,
    },

    /// An element references a vertex that does not exist.
    #[error("{format}: {element} references vertex {index}, but {available} at {at}")]
    IndexOutOfRange {
        /// Format being read.
        format: Format,
        /// The element, as the file numbers it (e.g. "face 12", "element 7 (tag 31)").
        element: String,
        /// The index as written in the file.
        index: i64,
        /// What exists ("the file defines 500 vertices", "no node has that tag").
        available: String,
        /// Where the element is.
        at: Location,
    },

    /// More triangles (after fan triangulation) or tetrahedra than allowed.
    #[error("{format}: more than {max} {what} (limit `max_triangles`), exceeded at {at}")]
    TooManyTriangles {
        /// Format being read.
        format: Format,
        /// "triangles" or "tetrahedra".
        what: &'static str,
        /// The limit.
        max: usize,
        /// Where the limit was exceeded (or the header that declares too many).
        at: Location,
    },

    /// More vertices than the limit derived from `max_triangles` or 32-bit ids.
    #[error("{format}: more than {max} vertices, exceeded at {at}")]
    TooManyVertices {
        /// Format being read.
        format: Format,
        /// The limit.
        max: usize,
        /// Where the limit was exceeded.
        at: Location,
    },

    /// Nothing to mesh: no triangle (and no tetrahedron) was found, or repair removed all.
    #[error("{format}: no triangles: {detail}")]
    NoTriangles {
        /// Format read.
        format: Format,
        /// What the file contained instead, or what repair removed.
        detail: String,
    },

    /// A valid file using a feature this reader does not support.
    #[error("{format}: unsupported at {at}: {feature}")]
    Unsupported {
        /// Format being read.
        format: Format,
        /// Where the feature appears.
        at: Location,
        /// The feature ("MSH version 4.0", "binary element type 34 (Polygon)").
        feature: String,
    },

    /// The mesh read violates an invariant the readers should have caught
    /// (reported rather than panicking).
    #[error("{format}: invalid mesh: {detail}")]
    InvalidMesh {
        /// Format read.
        format: Format,
        /// The violated invariant.
        detail: String,
    },

    /// A [`crate::io::LoadOptions`] value out of range.
    #[error("invalid load option `{option}`: {reason}")]
    InvalidOptions {
        /// Field name.
        option: &'static str,
        /// Allowed range and value given.
        reason: String,
    },

    /// The operating system refused a read.
    #[error("read failed: {0}")]
    Io(#[from] std::io::Error),
}

impl IoError {
    /// The stable failure kind (the problem `type`). A read the operating
    /// system refused (`Io`) is the server's fault: `internal-error`.
    pub fn kind(&self) -> FailureKind {
        match self {
            IoError::EmptyFile => FailureKind::EmptyFile,
            IoError::UnknownFormat { .. } => FailureKind::UnknownFormat,
            IoError::Truncated { .. } | IoError::TruncatedBinaryStl { .. } => FailureKind::Truncated,
            IoError::Parse { .. } => FailureKind::ParseError,
            IoError::NonFiniteCoordinate { .. } => FailureKind::NonFiniteCoordinate,
            IoError::CoordinateOutOfRange { .. } => FailureKind::CoordinateOutOfRange,
            IoError::IndexOutOfRange { .. } => FailureKind::IndexOutOfRange,
            IoError::TooManyTriangles { .. } => FailureKind::TooManyTriangles,
            IoError::TooManyVertices { .. } => FailureKind::TooManyVertices,
            IoError::NoTriangles { .. } => FailureKind::NoTriangles,
            IoError::Unsupported { .. } => FailureKind::Unsupported,
            IoError::InvalidMesh { .. } => FailureKind::InvalidMesh,
            IoError::InvalidOptions { .. } => FailureKind::InvalidOptions,
            IoError::Io(_) => FailureKind::InternalError,
        }
    }

    /// True when the input (not the machine) is at fault: every kind but `io`.
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, IoError::Io(_))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_are_stable_and_messages_name_the_place() {
        let e = IoError::Parse { format: Format::Obj, at: Location::Line(12), message: "bad".into() };
        assert_eq!(e.kind(), FailureKind::ParseError);
        assert_eq!(e.to_string(), "OBJ parse error at line 12: bad");
        let e = IoError::TruncatedBinaryStl { n_triangles: 10, expected_bytes: 584, actual_bytes: 300 };
        assert_eq!(e.kind(), FailureKind::Truncated);
        assert!(e.to_string().contains("584 bytes") && e.to_string().contains("300 bytes"), "{e}");
        let e = IoError::Truncated { format: Format::Ply, at: Location::Byte(99), detail: "x".into() };
        assert!(e.to_string().contains("byte offset 99"));
        assert_eq!(IoError::EmptyFile.kind(), FailureKind::EmptyFile);
        assert!(!IoError::Io(std::io::Error::other("disk")).is_bad_input());
    }
}
