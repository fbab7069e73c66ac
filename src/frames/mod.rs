//! Stage 3, 3D frames (thesis chapter 4): SU(2) parameterization of frames by
//! octahedral invariant forms, volume tetrahedralization, frame field.
//!
//! **Frame algebra** (exact, tested to round-off):
//! [`quaternion`] (product (4.7), rotations), [`groups`] (the vierer,
//! binary tetrahedral and binary octahedral groups), [`su2`] (the map (4.25)
//! and the conjugation of §3.4), [`invariants`] ((4.20), (4.21), (4.23) and
//! the model surface), [`inverse`] (model surface → groupset, §4),
//! [`norm`] (§4.3), [`axis`] (frames sharing an axis, (4.27)–(4.28)),
//! [`sh4`] (the degree-4 spherical-harmonic 9-vector of Ray et al. 2016 and
//! Palmer et al. 2020, with projection onto the octahedral variety).
//!
//! **Volume and field**: [`bvh`] and [`stuffing`] (isosurface stuffing of
//! the enclosed volume), [`parts`] (the surface split into independently
//! meshed parts), [`sizing`] (the lattice spacing per part from its
//! thickness and the tet budget), [`volume`] (checks, quality measures),
//! [`mbo`] (diffusion–projection smoothing of the 9-vector field),
//! [`singular`] (holonomy of tet frames around edges), [`field`] (the
//! stage entry point [`compute_frame_field`], its options and report),
//! [`vtu`] (the `frames.vtu` and `frames_singular.vtu` artifacts), [`pcg`]
//! (the iterative solver of the large diffusions).
//!
//! Conventions used throughout: a frame is given by a *frame quaternion*
//! `p` (or rotation matrix `R(p)`) whose columns are the frame axes; `p`
//! and `p o`, `o ∈ O`, are the same frame. Its invariants are (4.23) at
//! (4.25) of `p*`. Where the printed thesis has typesetting errors the
//! module docs say so and the tests check the corrected formula.

pub mod axis;
pub mod bvh;
pub mod error;
pub mod field;
pub mod groups;
pub mod invariants;
pub mod inverse;
pub mod mbo;
pub mod norm;
pub mod parts;
pub mod pcg;
pub mod quaternion;
pub mod sh4;
pub mod singular;
pub mod sizing;
pub mod stuffing;
pub mod su2;
pub mod volume;
pub mod vtu;

pub use error::FramesError;
pub use field::{FrameField, FramesOptions, FramesReport, compute_frame_field};
pub use quaternion::{Mat3, Quat};
pub use singular::{SingularEdge, SingularKind};
pub use su2::{C64, Su2};
pub use vtu::{write_frames_vtu, write_singular_edges_vtu};
