//! The quads stage: an all-quadrilateral surface mesh aligned with the
//! crossfield, conforming across the atlas (thesis introduction and ch. 3:
//! "how to spawn vertices to merge them into quadrangles").
//!
//! Steps, each in its own module:
//! 1. [`model`]: the feature model the mesh is classified on (corners,
//!    feature curves, model faces bounded by them); atlas seams are not part
//!    of it.
//! 2. [`curves`]: every feature curve discretized once at the target size,
//!    shared by the faces it bounds, segment counts chosen so every model
//!    face has an even number of boundary segments (parity).
//! 3. [`triangulation`]: in each atlas patch's `(u, v)` plane, points placed
//!    frontally along the cross at the target size, a vertex at every
//!    crossfield singularity, and a constrained Delaunay triangulation;
//!    the patches' triangulations joined into one [`SurfaceTriangulation`].
//! 4. [`recombine`]: triangles paired into quads by alignment and shape,
//!    completed to a perfect matching, midpoint subdivision as last resort.
//! 5. [`cleanup`] and [`smooth`]: valence-2 vertices and 3-3 diamonds
//!    removed; smoothing that never lowers a neighbourhood's worst scaled
//!    Jacobian, every vertex projected back onto the input ([`projection`]).
//! 6. [`order2`]: optional 9-node quadrangles, new nodes on the input.
//! 7. [`quality`] and [`check`]: scaled Jacobians, valences, the valence
//!    identity and conformity, asserted on every output; [`report`].
//! 8. [`output`]: `quads.msh` and `quads.vtu`.

pub mod error;
pub mod model;
pub mod options;
pub mod surface_mesh;

pub use error::QuadsError;
pub use model::{QuadModel, quad_model};
pub use options::QuadsOptions;
pub use surface_mesh::{ModelEntity, QuadMesh, SurfacePoint, SurfaceTriangulation};
