//! Errors of the frame-field stage.

use crate::linalg::LinalgError;
use crate::mesh::MeshError;
use crate::progress::Cancelled;
use thiserror::Error;

/// One boundary loop of an open surface, as named in [`FramesError::OpenSurface`].
#[derive(Debug, Clone, PartialEq)]
pub struct OpenLoop {
    /// Number of boundary edges in the loop.
    pub n_edges: usize,
    /// Its first vertices (at most 5), input numbering.
    pub first_vertices: Vec<u32>,
    /// Its length in model units.
    pub length: f64,
}

fn describe_loops(loops: &[OpenLoop]) -> String {
    let mut s = String::new();
    for (i, l) in loops.iter().take(5).enumerate() {
        let vs: Vec<String> = l.first_vertices.iter().map(|v| v.to_string()).collect();
        s.push_str(&format!(
            "{}loop {i}: {} edges, length {:.4e}, through vertices {}{}",
            if i > 0 { "; " } else { "" },
            l.n_edges,
            l.length,
            vs.join(", "),
            if l.n_edges > l.first_vertices.len() { ", …" } else { "" }
        ));
    }
    if loops.len() > 5 {
        s.push_str(&format!("; and {} more", loops.len() - 5));
    }
    s
}

/// The note on non-manifold edges of an open surface (empty when none).
fn describe_nonmanifold(n: usize) -> String {
    if n == 0 { String::new() } else { format!(" and is non-manifold: {n} edge(s) shared by three or more triangles") }
}

/// Why the frame field could not be computed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FramesError {
    /// The surface has no triangles.
    #[error("the surface has no triangles: there is no volume to fill")]
    EmptySurface,
    /// The surface is not closed, so it encloses no volume.
    #[error("the surface is not closed (it has {} boundary loop(s){}), so it encloses no volume; close these holes: {}", .loops.len(), describe_nonmanifold(*.n_nonmanifold_edges), describe_loops(.loops))]
    OpenSurface {
        /// The boundary loops found (connected pieces of the boundary-edge
        /// graph, as repair counts them).
        loops: Vec<OpenLoop>,
        /// Edges shared by three or more triangles (not boundary, but they
        /// also keep the surface from enclosing a volume).
        n_nonmanifold_edges: usize,
    },
    /// The surface fails its invariants (index out of range, non-finite
    /// coordinate, repeated vertex).
    #[error("invalid surface: {0}")]
    InvalidSurface(MeshError),
    /// The uploaded tetrahedral mesh has no tetrahedron.
    #[error("the uploaded volume has no tetrahedron")]
    EmptyVolume,
    /// The uploaded (or generated) tetrahedral mesh is invalid.
    #[error("invalid tetrahedral mesh: {0}")]
    InvalidVolume(#[from] MeshError),
    /// The tetrahedralization found no interior: the volume is thinner
    /// than the lattice spacing.
    #[error(
        "no tetrahedron fits inside the surface at target size {spacing:.4e} (enclosed volume {volume:.4e}); use a smaller target_size"
    )]
    NoInterior {
        /// Lattice spacing used.
        spacing: f64,
        /// Volume enclosed by the surface.
        volume: f64,
    },
    /// The requested target size would give too many tetrahedra.
    #[error(
        "target_size {target_size:.4e} would give about {estimated_tets} tetrahedra, above max_tets = {max_tets}; raise target_size or max_tets"
    )]
    TooManyTets {
        /// The requested size.
        target_size: f64,
        /// Estimated tetrahedron count.
        estimated_tets: u64,
        /// The cap.
        max_tets: usize,
    },
    /// An option value is out of its domain.
    #[error("invalid frames option {name}: {reason}")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// Why.
        reason: String,
    },
    /// A sparse factorization or solve failed.
    #[error("linear algebra failure in the frame field: {0}")]
    Linalg(#[from] LinalgError),
    /// The job was cancelled.
    #[error("cancelled")]
    Cancelled(#[from] Cancelled),
}
