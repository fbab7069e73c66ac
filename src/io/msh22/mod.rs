//! Gmsh MSH 2.2 (also 2.0 and 2.1), ASCII and binary.
//!
//! Reading lives in [`read`]; see [`crate::io::msh_common`] for what the
//! versions share (header, element types, node tags).

pub mod read;
