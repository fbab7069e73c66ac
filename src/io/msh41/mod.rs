//! Gmsh MSH 4.1: the general model ([`model::MshModel`]), a builder for
//! discrete atlases ([`discrete::DiscreteModelBuilder`]) and the writer.
//!
//! See [`write`] for the file layout and the Gmsh behaviour the writer relies on.

pub mod discrete;
pub mod model;
pub mod write;
