//! meshatlas: turns raw surface triangulations into what mesh generators need.
//!
//! The numerical core (`geom`, `mesh`, `linalg`, `fem`, `io`, `atlas`,
//! `crossfield`, `frames`, `quads`) is synchronous, knows nothing of HTTP or jobs, and
//! takes a [`progress::Progress`] handle for progress and cancellation.
//! `pipeline` sequences the stages and writes artifacts; `jobs` runs pipelines
//! durably on a rayon pool; `http` exposes jobs over axum.
//!
//! Dependencies point downward:
//! `geom ← mesh ← fem ← stages ← pipeline ← jobs ← http ← main`,
//! with `io`, `linalg`, `progress` and `failure` (the stable failure kinds)
//! used by the core.

// Numeric kernels index several parallel arrays with one loop index.
#![allow(clippy::needless_range_loop)]
// `!(x > 0.0)` is used on purpose: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod failure;
pub mod geom;
pub mod linalg;
pub mod mesh;
pub mod progress;

pub mod fem;
pub mod io;

pub mod atlas;
pub mod crossfield;
pub mod frames;
pub mod preview;
pub mod quads;

pub mod pipeline;

pub mod jobs;

pub mod http;

pub mod log_format;
