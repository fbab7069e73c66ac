//! Triangle and tetrahedral meshes, their topology and invariants.
//!
//! [`TriMesh`] is an indexed triangle mesh with `f64` coordinates and typed
//! ids. [`Topology`] derives edges (sorted vertex pairs), edge → triangle and
//! vertex → triangle incidences from it; the other modules compute connected
//! components, boundary loops, orientation and Euler characteristics on top.
//! [`TetMesh`] is the volume mesh of the frame-field stage.
//!
//! Conventions: triangle `[a, b, c]` owns the directed edges `a→b`, `b→c`,
//! `c→a` (local edge `i` goes from corner `i` to corner `i+1`); two
//! triangles sharing an edge are consistently oriented when they traverse it
//! in opposite directions. Every mutation is followed in debug builds by
//! `debug_assert!(mesh.validate().is_ok())`.

pub mod boundary;
pub mod components;
pub mod decimate;
pub mod degenerate;
pub mod equal_keys;
pub mod error;
pub mod fixtures;
pub mod folds;
pub mod ids;
pub mod orientation;
pub mod repair;
pub mod summary;
pub mod tetmesh;
pub mod topology;
pub mod trimesh;
pub mod weld;

pub use error::MeshError;
pub use ids::{EdgeId, FaceId, TetId, VertexId};
pub use tetmesh::TetMesh;
pub use topology::Topology;
pub use trimesh::TriMesh;
