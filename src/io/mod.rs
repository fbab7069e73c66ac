//! Mesh file formats: one module per format and version. Readers take a
//! `BufRead`, writers a `Write`; parse errors give the line or byte offset.
