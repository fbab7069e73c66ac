//! Gmsh MSH 2.2 (legacy ASCII), for tools that read only that version
//! (pyGIMLi, older FEM codes).

pub mod write;
