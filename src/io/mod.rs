//! Mesh file formats: one module per format and version. Readers take a
//! `BufRead`, writers a `Write`; parse errors give the line or byte offset.

pub mod msh22;
pub mod msh41;
pub mod stl_write;
pub(crate) mod text_out;
pub mod vtu;
pub mod write_error;

pub use write_error::WriteError;
