//! Errors of the mesh layer: violated invariants, named with the element.

use thiserror::Error;

/// A mesh invariant that does not hold, with the element that breaks it.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MeshError {
    /// A triangle or tetrahedron names a vertex that does not exist.
    #[error("element {element} references vertex {vertex}, but the mesh has {n_vertices} vertices")]
    VertexOutOfRange { element: usize, vertex: u32, n_vertices: usize },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate ({x}, {y}, {z})")]
    NonFiniteCoordinate { vertex: usize, x: f64, y: f64, z: f64 },
    /// A triangle or tetrahedron uses the same vertex twice.
    #[error("element {element} repeats vertex {vertex}")]
    RepeatedVertex { element: usize, vertex: u32 },
    /// The mesh has more elements than 32-bit ids can name.
    #[error("{what} count {count} exceeds the supported maximum of {max}")]
    TooLarge { what: &'static str, count: usize, max: usize },
    /// A derived structure disagrees with the mesh it was built from.
    #[error("inconsistent topology: {0}")]
    Inconsistent(String),
    /// A per-element input has the wrong number of entries.
    #[error("{what} has {found} entries, expected one per {per} ({expected})")]
    LengthMismatch { what: &'static str, per: &'static str, expected: usize, found: usize },
    /// A tetrahedron has non-positive volume.
    #[error("tetrahedron {tet} has non-positive signed volume {volume:e}")]
    InvertedTet { tet: usize, volume: f64 },
}
