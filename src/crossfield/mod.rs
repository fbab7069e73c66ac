//! Stage 2, the crossfield (thesis chapter 3): Ginzburg–Landau crossfield on
//! Crouzeix–Raviart unknowns, its singularities and their indices.
//!
//! A cross (N = 4) or asterisk (N = 6) with angle `θ` is stored as
//! `f = exp(i N θ)`, one complex unknown per edge in the edge's own frame
//! ([`frames`]). The field minimizes the discrete Ginzburg–Landau energy
//! ([`energy`], thesis (3.15), (3.27)) by a safeguarded Newton method with
//! continuation in the coherence length ε ([`newton`], [`compute`]), starting
//! from the smoothest field ([`initial`]). Indices of the result are computed per
//! vertex with the discrete Levi-Civita connection ([`singularities`]); they
//! sum to the Euler characteristic (Poincaré–Hopf, (3.13)).
//!
//! Entry point: [`compute_crossfield`]. Artifacts: [`output`].

pub mod compute;
pub mod energy;
pub mod frames;
pub mod initial;
pub mod newton;
pub mod output;
pub mod report;
pub mod singularities;
pub mod system;
pub mod transfer;

pub use compute::{compute_crossfield, validate_options};
pub use output::{write_crossfield_msh, write_crossfield_msh_as, write_crossfield_vtu, write_singularities_json};
pub use report::{CrossfieldReport, LevelReport, NewtonRecord};

use crate::geom::Vec3;
use crate::linalg::LinalgError;
use crate::mesh::VertexId;
use crate::progress::Cancelled;
use serde::{Deserialize, Serialize};

/// How aligned edges (boundary and feature edges) constrain the field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum BoundaryCondition {
    /// `f = 1` in the edge frame (cross aligned with the edge), eliminated from the unknowns.
    #[default]
    Strong,
    /// Penalty `w L/(2ε²) ∫ |f − 1|²` on aligned edges (thesis (3.27)).
    Weak,
}

/// Options of [`compute_crossfield`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CrossfieldOptions {
    /// Symmetry order N: 4 (cross) or 6 (asterisk). Default 4.
    pub symmetry: u32,
    /// Boundary condition on aligned edges: `strong` or `weak`. Default `strong`.
    pub boundary: BoundaryCondition,
    /// Weight `w` of the weak boundary term `w L/(2ε²) Σ ℓ_p |f_p − 1|²`
    /// (`L` = bounding-box diagonal); dimensionless. Default 1.
    pub weak_weight: f64,
    /// Final coherence length ε in model units. Default (`null`):
    /// `epsilon_per_edge_length` × mean edge length, so the vortex core
    /// (radius ≈ ε) spans a few triangles.
    pub epsilon: Option<f64>,
    /// ε as a multiple of the mean edge length when `epsilon` is not given.
    /// Default 1: the smallest ε whose core the CR field still resolves
    /// (smaller ε locks the field to be constant per triangle), and small
    /// enough for the asymptotic regime on the test surfaces (on the torus,
    /// ε = 2h still prefers 12 vortices: `docs/decisions.md`).
    pub epsilon_per_edge_length: f64,
    /// First ε of the continuation, model units. Default (`null`): a quarter
    /// of the bounding-box diagonal (never below the final ε); without aligned
    /// edges at most `1/(2√λ₁)` (λ₁ the smallest eigenvalue of the connection
    /// Laplacian), below which the GL minimizer is not `f = 0`.
    pub epsilon_start: Option<f64>,
    /// Ratio between consecutive ε of the continuation, in (0, 1). Default
    /// 0.25: each stage still starts close to its minimizer once the cores
    /// are shrunk (`shrink_cores`), and half the stages cost half the
    /// stage-start factorizations, with the same singularities
    /// (`docs/decisions.md`).
    pub continuation_factor: f64,
    /// Final tolerance on the scaled residual `ε² ‖Δf − (|f|²−1) f/ε²‖_{L²}/√area`
    /// (dimensionless). Default 1e-8. The final stage also ends, as
    /// converged, on the plateau rules of [`newton`] or at a residual of
    /// [`newton::FINAL_SETTLED_RESIDUAL`] away from a saddle
    /// (`stopped_on_plateau` in the report).
    pub tolerance: f64,
    /// Tolerance for the intermediate ε of the continuation. Default 1e-3:
    /// an intermediate stage only has to put the cores roughly in place for
    /// the next one (half the Newton iterations, same result:
    /// `docs/decisions.md`).
    pub continuation_tolerance: f64,
    /// Maximum Newton iterations of the final ε (intermediate ε: a third of
    /// it, at least 10). Default 60.
    pub max_newton_iterations: usize,
    /// Solve the stages with ε at least [`compute::COARSE_EPSILON_RATIO`] ×
    /// the final ε (rounded up to a power of `1/continuation_factor`) on a
    /// coarsened copy of the surface whose mean edge length is in the
    /// same proportion, recursively, and transfer the field to the finer
    /// mesh for the remaining stages ([`compute`], multilevel
    /// continuation), on meshes of at least `multilevel_min_faces`
    /// triangles. Default true.
    pub multilevel: bool,
    /// Triangles from which a mesh is coarsened for the multilevel
    /// continuation (the coarse copy also needs at least 150 triangles, or
    /// 2000 when it is the copy of a copy). Default 2000: meshes of a few
    /// thousand triangles already run faster on two levels, with the same
    /// singularities (`docs/decisions.md`).
    pub multilevel_min_faces: usize,
}

impl Default for CrossfieldOptions {
    fn default() -> Self {
        Self {
            symmetry: 4,
            boundary: BoundaryCondition::Strong,
            weak_weight: 1.0,
            epsilon: None,
            epsilon_per_edge_length: 1.0,
            epsilon_start: None,
            continuation_factor: 0.25,
            tolerance: 1e-8,
            continuation_tolerance: 1e-3,
            max_newton_iterations: 60,
            multilevel: true,
            multilevel_min_faces: 2_000,
        }
    }
}

/// Why the crossfield could not be computed.
#[derive(Debug, thiserror::Error)]
pub enum CrossfieldError {
    /// The mesh has no triangle.
    #[error("the mesh has no triangle")]
    EmptyMesh,
    /// `aligned_edges` does not have one flag per edge.
    #[error("aligned_edges has {got} flags for {expected} edges")]
    AlignedEdgesLength { expected: usize, got: usize },
    /// An option is out of range.
    #[error("invalid crossfield option {name}: {reason}")]
    InvalidOption { name: &'static str, reason: String },
    /// Two triangles traverse their common edge in the same direction.
    #[error(
        "triangles sharing edge ({a}, {b}) are oriented inconsistently (orient the mesh first; non-orientable surfaces are not supported)"
    )]
    InconsistentOrientation { a: u32, b: u32 },
    /// A sparse factorization failed.
    #[error("linear solver failure: {0}")]
    Linalg(#[from] LinalgError),
    /// The computation was cancelled.
    #[error("cancelled")]
    Cancelled(#[from] Cancelled),
}

/// A singular vertex of the field.
#[derive(Debug, Clone, PartialEq)]
pub struct Singularity {
    /// Location: the zero of the linear field in the vertex's star (the vertex when none).
    pub position: Vec3,
    /// Index as a fraction of a full turn (±1/4 for crosses, ±1/6 for asterisks).
    pub index: f64,
    /// The vertex carrying the index.
    pub vertex: VertexId,
}

/// The computed field and its singularities.
#[derive(Debug, Clone)]
pub struct Crossfield {
    /// Symmetry order N.
    pub symmetry: u32,
    /// Per edge: `f = (Re, Im)` in the edge frame (`f = 1`: aligned with the edge).
    pub f_per_edge: Vec<[f64; 2]>,
    /// Per triangle: unit tangent direction `u` of one branch of the cross.
    pub cross_per_face: Vec<Vec3>,
    /// Per triangle: `|f|` at the centroid.
    pub norm_per_face: Vec<f64>,
    /// Per vertex: index in units of `1/N` (0 where regular).
    pub index_per_vertex: Vec<i32>,
    /// Singular vertices.
    pub singularities: Vec<Singularity>,
    /// Euler characteristic V − E + F.
    pub euler_characteristic: i64,
    /// Sum of the indices (fraction of a turn); equals χ for manifold meshes.
    pub index_sum: f64,
    /// What was done.
    pub report: CrossfieldReport,
}
