//! Gmsh MSH 2.2 (also 2.0 and 2.1 when reading): ASCII and binary reading
//! ([`read`]; see [`crate::io::msh_common`] for what the versions share),
//! and the ASCII writer ([`write`]) for tools that read only that version
//! (pyGIMLi, older FEM codes).

pub mod read;
pub mod write;
