//! Gmsh MSH 4.1, ASCII and binary.
//!
//! Reading lives in [`read`]; see [`crate::io::msh_common`] for what the
//! versions share (header, element types, node tags).

pub mod read;
