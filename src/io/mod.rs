//! Mesh file formats: one module per format and version. Readers take a
//! `BufRead`, writers a `Write`; parse errors give the line or byte offset.
//!
//! Reading: [`load_path`], [`load_reader`] and [`load_bytes`] read STL
//! (ASCII/binary), OBJ, PLY (ASCII/binary either endianness) and MSH
//! (2.2 and 4.1, ASCII/binary), then weld and repair the surface
//! ([`crate::mesh::repair`]) and report what changed. [`Format`] is the one
//! table of formats (extensions, media types, content sniffing).
//!
//! The readers are hand-written, not taken from crates (`stl_io`, `tobj`,
//! `ply-rs`, `mshio`): they must stream, never allocate from an unchecked
//! count, never panic on hostile bytes, enforce the triangle cap while
//! reading, name the line or byte offset of every error, read MSH 2.2 and
//! parametric MSH 4.1, and leave welding to the repair step so that it can
//! be counted. None of the crates measured does all of that. The shared
//! plumbing is in [`source`].
//!
//! Writing: MSH 4.1 ([`msh41::write`]), MSH 2.2 ([`msh22::write`]), VTU
//! ([`vtu`]) and binary STL ([`stl_write`]); errors are [`WriteError`].
//! [`gzip`] compresses a finished file (the downloads' gzip encoding).

pub mod error;
pub mod format;
pub mod glb;
pub mod gzip;
pub mod load;
pub mod msh22;
pub mod msh41;
pub mod msh_common;
pub mod msh_output;
pub mod obj;
pub mod ply;
pub mod sizes;
pub mod source;
pub mod stl;
pub mod stl_write;
pub(crate) mod text_out;
pub mod vtu;
pub mod write_error;
pub mod zstandard;

pub use error::{IoError, Location};
pub use format::Format;
pub use load::{LoadOptions, LoadedMesh, load_bytes, load_path, load_reader};
pub use sizes::{InputSizes, scan_input_sizes};
pub use source::{Limits, RawMesh};

pub use write_error::WriteError;
