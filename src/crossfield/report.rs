//! The crossfield section of `report.json`: what the Ginzburg–Landau
//! continuation did ([`CrossfieldReport`]), per mesh level
//! ([`LevelReport`]) and per Newton iteration ([`NewtonRecord`]).

use serde::Serialize;
use std::collections::BTreeMap;

/// One Newton iteration of the continuation.
#[derive(Debug, Clone, Serialize)]
pub struct NewtonRecord {
    /// ε of this continuation stage (model units).
    pub epsilon: f64,
    /// Iteration within the stage (0 = before the first step).
    pub iteration: usize,
    /// Scaled residual before the step.
    pub residual: f64,
    /// Energy before the step.
    pub energy: f64,
    /// Line-search step length taken (0 when converged).
    pub step: f64,
    /// Levenberg–Marquardt parameter μ of the step (units of 1/ε²; 0 = Newton).
    pub shift: f64,
    /// `exact` (+ μ M, factored), `exact-cg` (+ μ M, conjugate gradients
    /// preconditioned by an earlier factorization) or `modified` Hessian.
    pub hessian: &'static str,
    /// Conjugate-gradient iterations of the step: those of the accepted
    /// solve (`exact-cg`), or of a failed attempt before the factorization
    /// (`exact`), else 0.
    pub krylov_iterations: usize,
    /// Mesh level of the step: 0 the input, 1 its first coarsening, ...
    pub level: usize,
}

/// One mesh of the multilevel continuation.
#[derive(Debug, Clone, Serialize, Default)]
pub struct LevelReport {
    /// 0 for the input mesh, k for its k-th coarsening.
    pub level: usize,
    /// Triangles of the mesh.
    pub n_faces: usize,
    /// Edges (CR unknowns, fixed ones included).
    pub n_edges: usize,
    /// ε of the stages solved on this mesh.
    pub epsilon_schedule: Vec<f64>,
    /// Newton iterations on this mesh.
    pub iterations: usize,
    /// Numeric factorizations on this mesh (failed ones included).
    pub n_factorizations: usize,
    /// Wall time on this mesh, seconds: its stages, from the moment the
    /// coarser levels are done (coarsening, their solves and the transfer
    /// run beside this level's symbolic analysis and are not counted here).
    pub seconds: f64,
}

/// What the crossfield stage did.
#[derive(Debug, Clone, Serialize, Default)]
pub struct CrossfieldReport {
    /// Symmetry order N.
    pub symmetry: u32,
    /// Edges of the mesh, and how many carry a fixed value (strong condition).
    pub n_edges: usize,
    /// Fixed edges (strong condition).
    pub n_fixed_edges: usize,
    /// Aligned edges (boundary + feature) given by the caller.
    pub n_aligned_edges: usize,
    /// Degenerate triangles left out of the energy.
    pub n_degenerate_faces: usize,
    /// How the initial field was obtained: `laplace` or `eigenvector`.
    pub initial_guess: String,
    /// Final energy of each candidate initial field tried (closed surfaces
    /// without aligned edges try two; the lower energy wins).
    pub candidate_energies: Vec<(String, f64)>,
    /// Curvature anisotropy in [0, 1] of a closed surface without aligned
    /// edges (the principal-curvature candidate is tried from 0.3 on).
    pub curvature_anisotropy: f64,
    /// Total Newton iterations over all stages.
    pub iterations: usize,
    /// Newton steps that needed a Levenberg–Marquardt shift or the modified Hessian.
    pub n_modified_steps: usize,
    /// Numeric Cholesky factorizations attempted (failed ones included).
    pub n_factorizations: usize,
    /// Preconditioned conjugate-gradient iterations (large systems reuse a
    /// factorization over several Newton steps), failed attempts included.
    pub n_krylov_iterations: usize,
    /// Scaled residual at the end.
    pub final_residual: f64,
    /// Final Ginzburg–Landau energy.
    pub energy: f64,
    /// Final ε (model units).
    pub epsilon: f64,
    /// ε of each continuation stage, over all levels.
    pub epsilon_schedule: Vec<f64>,
    /// The meshes of the multilevel continuation, coarsest first (one entry,
    /// the input, when it was solved on one level).
    pub levels: Vec<LevelReport>,
    /// True when the final stage reached `tolerance`, or stopped on the
    /// discretization's plateau (`stopped_on_plateau`).
    pub converged: bool,
    /// The final stage stopped because the energy stalled with the residual
    /// on a small plateau (vortex patterns creeping along a grid-pinned zero
    /// mode), before reaching `tolerance`.
    pub stopped_on_plateau: bool,
    /// Number of singular vertices.
    pub n_singularities: usize,
    /// Singular vertices by index (fraction of a turn, as text "0.25", "-0.25", ...).
    pub singularity_counts: BTreeMap<String, usize>,
    /// Sum of the indices (fraction of a turn).
    pub index_sum: f64,
    /// Euler characteristic V − E + F.
    pub euler_characteristic: i64,
    /// Every Newton iteration.
    pub history: Vec<NewtonRecord>,
    /// Wall time of the stage, seconds.
    pub wall_seconds: f64,
}
