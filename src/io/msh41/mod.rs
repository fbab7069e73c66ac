//! Gmsh MSH 4.1: the general model ([`model::MshModel`]) and its writer.
//!
//! See [`write`] for the file layout and the Gmsh behaviour the writer relies on.

pub mod model;
pub mod write;
