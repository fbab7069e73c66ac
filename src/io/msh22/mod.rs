//! Gmsh MSH 2.2 (also 2.0 and 2.1 for reading): the reader ([`read`], ASCII
//! and binary) and the legacy ASCII writer ([`write`]) for tools that read
//! only that version (pyGIMLi, older FEM codes). What the versions share
//! when reading (header, element types, node tags) is in
//! [`crate::io::msh_common`].

pub mod read;
pub mod write;
