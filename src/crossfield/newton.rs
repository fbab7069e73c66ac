//! Safeguarded Newton method on the discrete Ginzburg–Landau energy for one
//! coherence length ε (one stage of the continuation), thesis (3.16)–(3.21).
//!
//! Each step solves `(H + μ M/ε²) d = −g` with a sparse (supernodal) Cholesky
//! factorization whose symbolic analysis is done once and reused by every
//! step and stage ([`SupernodalCholesky`]), then backtracks on the energy (Armijo,
//! `E(f + α d) ≤ E(f) + 10⁻⁴ α gᵀd`, α halved).
//!
//! Why this safeguard. The Hessian is indefinite wherever `|f| < 1` (the
//! vortex cores, and everywhere at the start of a stage when ε shrinks), and
//! near a minimizer it has very flat directions (moving a vortex: on the
//! disk, rotating the four vortices together costs nothing in the continuum).
//! We use a Levenberg–Marquardt safeguard on the exact Hessian: factor
//! `H + μ M/ε²` (M the CR mass), starting from the last μ (or 10⁻⁴) and
//! raising it ×10 until the Cholesky factorization succeeds (the negative curvature of the
//! penalty is bounded by `M/ε²`, so μ ≈ 1 always succeeds); lower it ×10
//! after a full step (unless the step's own curvature says the lower μ
//! cannot factor, [`NewtonSolver::curvature_allows`]: one matrix-vector
//! product instead of a failed factorization), raise it ×10 after a
//! strongly cut one. (×100 steps overshoot: a stage whose Hessian needs
//! μ ≈ 0.1 alternates between a failed factorization and an over-damped
//! step; runs in `docs/decisions.md`.) Starting low matters: vortex motion is a nearly flat (sometimes slightly negative)
//! direction, and a large μ would make vortices creep. Near a minimizer μ
//! returns to 0: pure Newton, quadratic convergence. Clamping the indefinite
//! term instead (the "modified" Hessian of [`super::energy`], kept only as a
//! last resort) stalls in flat directions: its extra curvature in the cores
//! makes vortex motion creep. An eigenvalue-based modification would need an
//! eigen-solve per step, a trust region several solves per rejected radius.
//! The tiny shift `10⁻⁸ × mean diagonal` keeps the factorization defined at
//! a minimizer of a closed surface without aligned edges, where `i f` spans
//! the kernel (global rotation invariance of the GL energy): the gradient is
//! orthogonal to that kernel, so no pinned edge is needed.
//!
//! Reusing a factorization. On large systems ([`KRYLOV_MIN_DOFS`]) a step
//! that follows an accepted one (α ≥ 1/4) first solves the new exact
//! `H + μ M` by conjugate gradients preconditioned with the last
//! factorization of the stage, to the relative residual `√res` (inexact
//! Newton, clamped to [10⁻⁶, 0.1]); negative curvature or
//! [`KRYLOV_MAX_ITER`] iterations fall back to refactoring (with the μ
//! raises above). This halves the factorizations of large systems
//! (`docs/decisions.md`).
//!
//! Saddles. An intermediate stage stops at its (loose) tolerance only if
//! the last factorization attempt did not fail: a failure means
//! `H + μ' M/ε²` is indefinite, and a small residual there is the
//! symmetric vortex cluster just before it splits (the residual grows again
//! as it does), not a minimizer. Left to the next stage, the split happens
//! with cores a quarter the size, which move more slowly.
//!
//! Final-stage plateau. At ε ≈ h the vortices sit in a landscape that is
//! flat up to the grid's pinning: on the disk and the sphere, rotating the
//! whole vortex pattern is a zero mode of the continuum energy. Full Newton
//! steps then move the pattern by about a cell per iteration (the residual
//! stays near 10⁻⁴, the energy drops by ~10⁻⁷ relative per step) and the
//! 10⁻⁸ tolerance is only reached once the rotation settles, after tens of
//! iterations that change neither the vortex count nor the radii
//! (`docs/decisions.md`). The final stage therefore
//! also stops, as converged, when over [`FINAL_STALL_WINDOW`] iterations the
//! energy decreased by less than [`FINAL_STALL_DECREASE`] (relative) while
//! the residual stayed below [`FINAL_STALL_RESIDUAL`] (a plateau, not a
//! transient such as a vortex entering); [`StageOutcome::plateau`] says so.
//!
//! Residual. `g_p ≈ m_p (−Δf + (|f|²−1) f/ε²)_p` (CR mass `m_p`), so
//! `ε² (Σ_p |g_p|²/m_p / area)^{1/2}` is a dimensionless L² norm of the
//! strong residual of (3.16); it is what the tolerances measure.

use super::energy::{EnergyParams, HessianKind, total_energy};
use super::frames::{C64, Discretization};
use super::system::{Assembled, NewtonSystem};
use super::{CrossfieldError, NewtonRecord};
use crate::linalg::{CgOptions, FillOrdering, SupernodalCholesky, conjugate_gradients};
use crate::mesh::Topology;
use crate::progress::Progress;

/// Relative diagonal shift `μ`.
const SHIFT: f64 = 1e-8;
/// Armijo constant.
const ARMIJO: f64 = 1e-4;
/// Iterations over which an intermediate stage must decrease the energy...
const STALL_WINDOW: usize = 5;
/// ... by at least this relative amount, or it stops.
const STALL_DECREASE: f64 = 1e-7;
/// Final stage: iterations over which the energy must decrease ...
const FINAL_STALL_WINDOW: usize = 5;
/// ... by at least this relative amount while ... (the iterations a
/// smaller value adds only turn the vortex pattern, radii unchanged:
/// `docs/decisions.md`)
const FINAL_STALL_DECREASE: f64 = 3e-5;
/// ... the scaled residual stays below this, or the stage stops (plateau).
const FINAL_STALL_RESIDUAL: f64 = 1e-3;
/// Newton systems from this many real unknowns on reuse the factorization
/// as a CG preconditioner. Below, refactoring costs only a few solves, and
/// CG was slower (`docs/decisions.md`).
pub const KRYLOV_MIN_DOFS: usize = 200_000;
/// CG iterations before giving up and refactoring. A solve with the factor
/// costs a seventh to a tenth of a refactorization, and an attempt that
/// runs out is paid on top of the refactorization, so few iterations pay
/// best (`docs/decisions.md`).
const KRYLOV_MAX_ITER: usize = 5;
/// From this many real unknowns on, the factorization is ordered by a
/// nested dissection of the mesh's vertices
/// ([`NewtonSystem::vertex_dissection_order`]) instead of AMD: a third less
/// fill and faster numeric factorizations (`docs/decisions.md`).
const NESTED_DISSECTION_MIN_DOFS: usize = 200_000;
/// Final stage: Newton steps over which the singular vertices must stay the
/// same (with the residual below [`FINAL_STALL_RESIDUAL`]) for the stage to
/// stop as settled. The steps after that move the vortex zeros within their
/// stars, by a fraction of a cell (`docs/decisions.md`).
const SETTLE_STEPS: usize = 2;
/// The continuation's final stage: once the scaled residual is at or below
/// this, a step that raises it ends the stage at the iterate before that
/// step (see [`StageSpec::settled_residual`]). Such steps carry the vortex
/// pattern along the flat valley of the renormalized energy, a cell per
/// step, and the plateau rule ends them on a larger residual after many
/// factorizations (`docs/decisions.md`).
pub const FINAL_SETTLED_RESIDUAL: f64 = 3e-5;
/// Maximum step halvings.
const MAX_HALVINGS: usize = 40;
/// First non-zero Levenberg–Marquardt parameter (units of 1/ε²). 10⁻⁴
/// rather than 10⁻⁸: a Hessian that fails at μ = 0 needs μ ≈ 10⁻¹, and
/// each raise from further below is a failed factorization
/// (`docs/decisions.md`).
const MU_FIRST: f64 = 1e-4;
/// Factor by which μ is raised after a failed factorization, and lowered after a full step.
const MU_STEP: f64 = 10.0;
/// Factorization attempts with a raised parameter before the modified Hessian.
const MAX_SHIFT_RAISES: usize = 6;

/// The singular vertices of a field and their indices (units of 1/N), in
/// vertex order: what the final stage watches to stop once they settle.
pub type SingularVertices<'s> = dyn Fn(&[C64]) -> Vec<(u32, i32)> + 's;

/// The reusable part of the Newton solver: system structure and factorization.
pub struct NewtonSolver<'a> {
    /// Mesh topology.
    pub topo: &'a Topology,
    /// Geometric discretization.
    pub disc: &'a Discretization,
    /// Free unknowns and Hessian structure.
    pub sys: &'a NewtonSystem,
    chol: Option<SupernodalCholesky>,
    /// Number of steps that fell back to the modified Hessian.
    pub n_modified_steps: usize,
    /// Numeric factorizations attempted (failed ones included).
    pub n_factorizations: usize,
    /// Conjugate-gradient iterations of the Newton steps solved iteratively.
    pub n_krylov_iterations: usize,
    /// Systems with at least this many real unknowns try preconditioned CG
    /// before refactoring (see [`KRYLOV_MIN_DOFS`]).
    pub krylov_min_dofs: usize,
}

/// How one stage of the continuation is solved: its coherence length and
/// the stopping rules of the Newton iterations on (3.16) at that ε.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageSpec {
    /// Coherence length ε of the stage (model units).
    pub eps: f64,
    /// Tolerance on the scaled residual (module doc, "Residual"; dimensionless).
    pub tol: f64,
    /// Newton steps at most.
    pub max_iter: usize,
    /// An intermediate stage: stop when the energy stalls, never at a
    /// saddle. The final stage (`false`) stops on the plateau rule or once
    /// the singular vertices settle instead.
    pub stop_on_stall: bool,
    /// Levenberg–Marquardt parameter μ of the first step (units of 1/ε²):
    /// 1 right after ε decreased, where the shrinking cores make the
    /// Hessian indefinite, else 0.
    pub mu_start: f64,
    /// Final stage: once an iterate has a scaled residual at or below this
    /// (and the last factorization attempt found no negative curvature: not
    /// a saddle), a step that raises the residual is undone and the stage
    /// ends there, as converged; 0 to iterate to `tol` or a plateau.
    pub settled_residual: f64,
}

/// Outcome of one stage.
#[derive(Debug, Clone)]
pub struct StageOutcome {
    /// Newton steps taken.
    pub iterations: usize,
    /// Scaled residual at the end.
    pub residual: f64,
    /// Energy at the end.
    pub energy: f64,
    /// Whether the tolerance was reached (or, in the final stage, the
    /// discretization's plateau: see [`FINAL_STALL_DECREASE`]).
    pub converged: bool,
    /// The final stage stopped on the plateau rule with the residual above the tolerance.
    pub plateau: bool,
    /// One record per iteration of the stage (`level` 0: the caller knows the level).
    pub history: Vec<NewtonRecord>,
}

/// What every step of one stage shares.
struct StageContext<'s, 'p> {
    /// The energy (3.15) at this ε, with the weak boundary term.
    params: &'s EnergyParams<'p>,
    /// CR mass per real unknown (the Levenberg–Marquardt term `μ M/ε²`).
    mass: Vec<f64>,
    /// `1/ε²`.
    inv_eps2: f64,
}

/// What the iterations of one stage carry from step to step.
struct StageState {
    /// Levenberg–Marquardt parameter μ, in units of 1/ε² (0 = pure Newton).
    mu: f64,
    /// Energy before each step so far.
    energies: Vec<f64>,
    /// Scaled residual before each step so far.
    residuals: Vec<f64>,
    /// Singular vertices (with their indices) before each step (final stage).
    singular: Vec<Vec<(u32, i32)>>,
    /// Whether the last factorization (of this stage) may precondition CG.
    precond_ok: bool,
    /// Whether the last CG attempt failed: the next step refactors
    /// directly (in the final stage each step moves the vortex cores, and a
    /// failed attempt is likely to fail again).
    cg_failed: bool,
    /// Whether the last factorization attempts found `H + μM/ε²` indefinite.
    indefinite: bool,
}

impl StageState {
    /// The state before the first step, with μ = `mu_start`.
    fn new(mu_start: f64) -> Self {
        Self {
            mu: mu_start,
            energies: Vec::new(),
            residuals: Vec::new(),
            singular: Vec::new(),
            precond_ok: false,
            cg_failed: false,
            indefinite: false,
        }
    }

    /// Whether the stage stops for lack of progress at iteration `it`
    /// (energy `energy`, scaled residual `res`, singular vertices
    /// `singular_now` in the final stage), then remember this iteration's
    /// numbers. Intermediate stages only need the vortices roughly in
    /// place: they stop when the energy stalls (vortices creeping along a
    /// flat valley). The final stage stops on a plateau (module doc,
    /// "Final-stage plateau") or once its singular vertices have settled.
    fn stalled(
        &mut self,
        spec: &StageSpec,
        it: usize,
        energy: f64,
        res: f64,
        singular_now: Option<Vec<(u32, i32)>>,
    ) -> bool {
        let stalled = self.energy_stalled(spec, it, energy, res);
        let settled = singular_now.is_some_and(|s| self.singularities_settled(it, res, s));
        self.energies.push(energy);
        self.residuals.push(res);
        stalled || settled
    }

    /// The energy decreased by less than the stall rule allows over the
    /// last window: [`STALL_DECREASE`] (relative) over [`STALL_WINDOW`]
    /// steps for an intermediate stage; [`FINAL_STALL_DECREASE`] over
    /// [`FINAL_STALL_WINDOW`] steps with the residual below
    /// [`FINAL_STALL_RESIDUAL`] throughout for the final one (a plateau,
    /// not a transient such as a vortex entering).
    fn energy_stalled(&self, spec: &StageSpec, it: usize, energy: f64, res: f64) -> bool {
        let drop = |w: usize| self.energies[it - w] - energy;
        if spec.stop_on_stall {
            it >= STALL_WINDOW && drop(STALL_WINDOW) <= STALL_DECREASE * energy.abs()
        } else {
            it >= FINAL_STALL_WINDOW
                && drop(FINAL_STALL_WINDOW) <= FINAL_STALL_DECREASE * energy.abs()
                && self.residuals_small_since(it - FINAL_STALL_WINDOW, res)
        }
    }

    /// Final stage: the singular vertices and their indices (`now` at
    /// iteration `it`) have not changed over the last [`SETTLE_STEPS`]
    /// steps, on a small residual. Remembers `now`.
    fn singularities_settled(&mut self, it: usize, res: f64, now: Vec<(u32, i32)>) -> bool {
        self.singular.push(now);
        it >= SETTLE_STEPS
            && self.singular[it - SETTLE_STEPS..].iter().all(|s| *s == self.singular[it])
            && self.residuals_small_since(it - SETTLE_STEPS, res)
    }

    /// The residuals from iteration `from` on, and the current `res`, are
    /// all below [`FINAL_STALL_RESIDUAL`].
    fn residuals_small_since(&self, from: usize, res: f64) -> bool {
        self.residuals[from..].iter().chain(std::iter::once(&res)).all(|&r| r <= FINAL_STALL_RESIDUAL)
    }

    /// Whether the stage ends at iteration `it` before stepping: the
    /// tolerance met, a non-finite residual, the iterations spent, or
    /// `stalled`. An intermediate stage does not stop on the tolerance at a
    /// point where the last factorization attempt showed negative
    /// curvature: a small residual there is a saddle (the symmetric vortex
    /// cluster before it splits), not a minimizer, and the next stage would
    /// have to split it with smaller, slower cores (`docs/decisions.md`).
    fn ends(&self, spec: &StageSpec, it: usize, res: f64, stalled: bool) -> bool {
        let at_saddle = spec.stop_on_stall && self.indefinite;
        (res <= spec.tol && !at_saddle) || !res.is_finite() || it == spec.max_iter || stalled
    }
}

/// The last iterate of a final stage whose residual was at or below
/// [`StageSpec::settled_residual`]: where the stage returns if the next step
/// raises the residual.
struct SettledIterate {
    /// The field.
    f: Vec<C64>,
    /// Its scaled residual.
    residual: f64,
    /// Its energy.
    energy: f64,
}

/// μ after a failed factorization or a strongly cut step: [`MU_FIRST`]
/// from 0, else ×[`MU_STEP`].
fn raised(mu: f64) -> f64 {
    if mu == 0.0 { MU_FIRST } else { mu * MU_STEP }
}

/// `Σ a_i b_i`, in index order.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl<'a> NewtonSolver<'a> {
    /// A solver for `sys` (no factorization yet).
    pub fn new(topo: &'a Topology, disc: &'a Discretization, sys: &'a NewtonSystem) -> Self {
        Self {
            topo,
            disc,
            sys,
            chol: None,
            n_modified_steps: 0,
            n_factorizations: 0,
            n_krylov_iterations: 0,
            krylov_min_dofs: KRYLOV_MIN_DOFS,
        }
    }

    /// The symbolic analysis of the Hessian pattern (fill-reducing ordering,
    /// supernodes), done once; the numeric factorizations reuse it. It only
    /// needs the pattern, so the multilevel continuation runs it beside the
    /// coarse levels' solves.
    ///
    /// # Errors
    /// [`CrossfieldError::Linalg`] when the ordering fails.
    pub fn analyze(&mut self) -> Result<(), CrossfieldError> {
        if self.chol.is_some() {
            return Ok(());
        }
        let a = self.sys.matrix(vec![0.0; self.sys.n_values()])?;
        let ordering = if a.nrows() >= NESTED_DISSECTION_MIN_DOFS {
            FillOrdering::Given(self.sys.vertex_dissection_order(self.topo)?)
        } else {
            FillOrdering::Amd
        };
        self.chol = Some(SupernodalCholesky::analyze_with(&a, ordering)?);
        Ok(())
    }

    /// Factor `values + μ·mass` (+ a relative round-off shift), reusing the
    /// symbolic analysis. `mass` holds one entry per real unknown.
    ///
    /// # Errors
    /// [`CrossfieldError::Linalg`] when the matrix is not positive definite.
    pub fn factor(&mut self, mut values: Vec<f64>, mass: &[f64], mu: f64) -> Result<(), CrossfieldError> {
        self.n_factorizations += 1;
        self.shift_values(&mut values, mass, mu);
        self.analyze()?;
        let a = self.sys.matrix(values)?;
        if let Some(c) = &mut self.chol {
            c.factor(&a)?;
        }
        Ok(())
    }

    /// Add the relative round-off shift and `μ·mass` to the diagonal.
    fn shift_values(&self, values: &mut [f64], mass: &[f64], mu: f64) {
        let diag = self.sys.diagonal(values);
        let mean = diag.iter().map(|d| d.abs()).sum::<f64>() / diag.len().max(1) as f64;
        let ones = vec![1.0; diag.len()];
        self.sys.add_to_diagonal(values, &ones, SHIFT * mean.max(f64::MIN_POSITIVE));
        if mu > 0.0 {
            self.sys.add_to_diagonal(values, mass, mu);
        }
    }

    /// Solve `A d = b` (`A`: lower-triangle `values`, already shifted) by
    /// conjugate gradients preconditioned with the last factorization, to
    /// the relative residual `rtol` in at most `max_it` iterations; returns
    /// the solution (`None` when `A` shows negative curvature or the
    /// iterations run out: the caller refactors) and the iterations spent.
    fn pcg(
        &mut self,
        values: &[f64],
        b: &[f64],
        rtol: f64,
        max_it: usize,
    ) -> Result<(Option<Vec<f64>>, usize), CrossfieldError> {
        let (sys, chol) = (self.sys, &mut self.chol);
        let apply = |p: &[f64], q: &mut [f64]| {
            sys.sym_matvec(values, p, q);
            Ok(())
        };
        let precondition = |r: &[f64], z: &mut [f64]| {
            z.copy_from_slice(r);
            solve_with(chol, z)
        };
        let mut x = vec![0.0; b.len()];
        let [rep] =
            conjugate_gradients(apply, precondition, b, &mut x, &CgOptions { rel_tol: rtol, max_iter: max_it })?;
        Ok((rep.converged.then_some(x), rep.iterations))
    }

    /// Whether lowering the Levenberg–Marquardt parameter to `mu_new` keeps
    /// `H + μ_new M/ε²` positive along the last step `d`: the Rayleigh
    /// quotient `q = ε² dᵀHd / dᵀMd` bounds the smallest eigenvalue of
    /// `(H, M/ε²)` from above, so `q + μ_new ≤ 0` means the factorization
    /// at `μ_new` would fail. `d = −(H + μM/ε²)⁻¹ g` is one step of inverse
    /// iteration, so it leans towards the softest (possibly negative)
    /// directions, which is what makes the test sharp in practice.
    fn curvature_allows(&self, hess_values: &[f64], mass: &[f64], d: &[f64], eps: f64, mu_new: f64) -> bool {
        let mut hd = vec![0.0; d.len()];
        self.sys.sym_matvec(hess_values, d, &mut hd);
        let dhd: f64 = d.iter().zip(&hd).map(|(a, b)| a * b).sum();
        let dmd: f64 = d.iter().zip(mass).map(|(a, m)| a * a * m).sum();
        if !(dmd > 0.0) {
            return true;
        }
        let q = eps * eps * dhd / dmd;
        q + mu_new > 0.0
    }

    /// CR mass per real unknown.
    pub fn dof_mass(&self) -> Vec<f64> {
        self.sys.free_edges.iter().flat_map(|&e| [self.disc.mass_per_edge[e as usize]; 2]).collect()
    }

    /// Solve with the last factorization, in place.
    ///
    /// # Errors
    /// [`CrossfieldError::Linalg`] when nothing was factored or sizes differ.
    pub fn solve(&mut self, rhs: &mut [f64]) -> Result<(), CrossfieldError> {
        solve_with(&mut self.chol, rhs)
    }

    /// Scaled residual of a gradient (see the module doc).
    pub fn residual(&self, grad: &[f64], eps: f64) -> f64 {
        let mut s = 0.0;
        for (i, &e) in self.sys.free_edges.iter().enumerate() {
            let m = self.disc.mass_per_edge[e as usize];
            if m > 0.0 {
                s += (grad[2 * i] * grad[2 * i] + grad[2 * i + 1] * grad[2 * i + 1]) / m;
            }
        }
        eps * eps * (s / self.disc.area.max(f64::MIN_POSITIVE)).sqrt()
    }

    /// Minimize the energy (3.15) for one ε from `f` (updated in place) by
    /// Newton steps on (3.16), each solving (3.19) with the Hessian (3.20)
    /// and gradient (3.21) assembled in the edge frames, safeguarded as the
    /// module doc says; `spec` gives ε, the tolerance, the iteration limit,
    /// the kind of stage and the first Levenberg–Marquardt parameter.
    ///
    /// # Errors
    /// [`CrossfieldError::Cancelled`] when `progress` is cancelled, or a
    /// linear-solver failure of the modified (positive semi-definite) system.
    pub fn minimize(
        &mut self,
        f: &mut [C64],
        params: &EnergyParams,
        spec: &StageSpec,
        singular_vertices: Option<&SingularVertices>,
        progress: &Progress,
    ) -> Result<StageOutcome, CrossfieldError> {
        let ctx = StageContext { params, mass: self.dof_mass(), inv_eps2: 1.0 / (spec.eps * spec.eps) };
        let mut state = StageState::new(spec.mu_start);
        let mut trial = f.to_vec();
        let mut settled: Option<SettledIterate> = None;
        let mut out = StageOutcome {
            iterations: 0,
            residual: f64::INFINITY,
            energy: f64::INFINITY,
            converged: false,
            plateau: false,
            history: Vec::new(),
        };
        for it in 0..=spec.max_iter {
            progress.check()?;
            let asm = self.sys.assemble(self.topo, self.disc, f, params, HessianKind::Exact);
            let res = self.residual(&asm.grad, spec.eps);
            out.residual = res;
            out.energy = asm.energy;
            let mut record = NewtonRecord {
                epsilon: spec.eps,
                iteration: it,
                residual: res,
                energy: asm.energy,
                step: 0.0,
                shift: 0.0,
                hessian: "exact",
                krylov_iterations: 0,
                level: 0,
            };
            if let Some(kept) = settled.take_if(|k| res > k.residual) {
                // The last step started a drift: undo it (`FINAL_SETTLED_RESIDUAL`).
                f.copy_from_slice(&kept.f);
                (out.residual, out.energy) = (kept.residual, kept.energy);
                out.converged = true;
                out.plateau = kept.residual > spec.tol;
                out.history.push(record);
                break;
            }
            if !spec.stop_on_stall && res <= spec.settled_residual && !state.indefinite {
                settled = Some(SettledIterate { f: f.to_vec(), residual: res, energy: asm.energy });
            }
            let singular_now = singular_vertices.filter(|_| !spec.stop_on_stall).map(|sv| sv(f));
            let stalled = state.stalled(spec, it, asm.energy, res, singular_now);
            if state.ends(spec, it, res, stalled) {
                out.converged = res <= spec.tol || (stalled && !spec.stop_on_stall);
                out.plateau = stalled && !spec.stop_on_stall && res > spec.tol;
                out.history.push(record);
                break;
            }
            let d = match self.krylov_direction(&ctx, &asm, res, &mut state, &mut record)? {
                Some(d) => d,
                None => self.factored_direction(f, &ctx, &asm, &mut state, &mut record)?,
            };
            let slope = dot(&d, &asm.grad);
            if !(slope < 0.0) {
                // Not a descent direction (round-off at convergence): stop the stage.
                out.history.push(record);
                break;
            }
            let alpha = self.armijo_step(f, &d, &mut trial, params, asm.energy, slope);
            record.step = alpha.unwrap_or(0.0);
            out.history.push(record);
            let Some(alpha) = alpha else {
                // No decrease measurable in floating point: the stage is as converged as it gets.
                break;
            };
            for &e in &self.sys.free_edges {
                f[e as usize] = trial[e as usize];
            }
            out.iterations += 1;
            // The factorization stays a good preconditioner while steps are not cut hard.
            state.precond_ok = alpha >= 0.25;
            self.adapt_mu(&mut state, alpha, &asm.hess_values, &ctx.mass, &d, spec.eps);
        }
        Ok(out)
    }

    /// Large systems ([`Self::krylov_min_dofs`]), after a step that was not
    /// cut hard: the Newton direction by conjugate gradients on the exact
    /// `H + μ M/ε²`, preconditioned by the stage's last factorization
    /// (inexact Newton, forcing term `√res` clamped to [10⁻⁶, 0.1]). `None`
    /// when CG does not apply or fails: the caller refactors. The CG
    /// iterations are counted even when the attempt fails: their solves
    /// were paid for.
    fn krylov_direction(
        &mut self,
        ctx: &StageContext,
        asm: &Assembled,
        res: f64,
        state: &mut StageState,
        record: &mut NewtonRecord,
    ) -> Result<Option<Vec<f64>>, CrossfieldError> {
        if !(state.precond_ok && !state.cg_failed && self.sys.n_dofs() >= self.krylov_min_dofs) {
            return Ok(None);
        }
        let mut values = asm.hess_values.clone();
        self.shift_values(&mut values, &ctx.mass, state.mu * ctx.inv_eps2);
        let b: Vec<f64> = asm.grad.iter().map(|g| -g).collect();
        let rtol = res.sqrt().clamp(1e-6, 0.1);
        let (x, k) = self.pcg(&values, &b, rtol, KRYLOV_MAX_ITER)?;
        self.n_krylov_iterations += k;
        record.krylov_iterations = k;
        state.cg_failed = x.is_none();
        if x.is_some() {
            record.hessian = "exact-cg";
            record.shift = state.mu;
            if state.mu > 0.0 {
                self.n_modified_steps += 1;
            }
        }
        Ok(x)
    }

    /// The Newton direction `d = −(H + μ M/ε²)⁻¹ g` by a new factorization:
    /// of the exact Hessian with μ raised until it factors
    /// ([`Self::factor_raising_mu`]), or, when it never does, of the
    /// modified (positive semi-definite) Hessian of [`super::energy`].
    fn factored_direction(
        &mut self,
        f: &[C64],
        ctx: &StageContext,
        asm: &Assembled,
        state: &mut StageState,
        record: &mut NewtonRecord,
    ) -> Result<Vec<f64>, CrossfieldError> {
        // A step refactored without trying CG re-arms it.
        if record.krylov_iterations == 0 {
            state.cg_failed = false;
        }
        let factored = self.factor_raising_mu(&asm.hess_values, ctx, state);
        if !factored {
            let m = self.sys.assemble(self.topo, self.disc, f, ctx.params, HessianKind::Modified);
            self.factor(m.hess_values, &ctx.mass, 0.0)?;
            record.hessian = "modified";
        }
        if state.mu > 0.0 || !factored {
            self.n_modified_steps += 1;
        }
        record.shift = state.mu;
        let mut d: Vec<f64> = asm.grad.iter().map(|g| -g).collect();
        self.solve(&mut d)?;
        Ok(d)
    }

    /// Factor the exact `H + μ M/ε²`, raising μ ([`raised`]) after each
    /// failure, at most [`MAX_SHIFT_RAISES`] attempts; whether one
    /// succeeded. Any failure marks the point indefinite (see
    /// [`StageState::ends`]).
    fn factor_raising_mu(&mut self, hess_values: &[f64], ctx: &StageContext, state: &mut StageState) -> bool {
        state.indefinite = false;
        for _ in 0..MAX_SHIFT_RAISES {
            if self.factor(hess_values.to_vec(), &ctx.mass, state.mu * ctx.inv_eps2).is_ok() {
                return true;
            }
            state.indefinite = true;
            state.mu = raised(state.mu);
        }
        false
    }

    /// Backtracking line search along `d` from `f` (energy `energy`,
    /// directional derivative `slope`): Armijo, `E(f + α d) ≤ E(f) +
    /// 10⁻⁴ α gᵀd`, α halved at most [`MAX_HALVINGS`] times. Returns the
    /// accepted α with `trial = f + α d` on the free edges, or `None` when
    /// no step decreases the energy measurably.
    fn armijo_step(
        &self,
        f: &[C64],
        d: &[f64],
        trial: &mut [C64],
        params: &EnergyParams,
        energy: f64,
        slope: f64,
    ) -> Option<f64> {
        let mut alpha = 1.0;
        for _ in 0..MAX_HALVINGS {
            for (i, &e) in self.sys.free_edges.iter().enumerate() {
                trial[e as usize] = f[e as usize] + C64::new(alpha * d[2 * i], alpha * d[2 * i + 1]);
            }
            if total_energy(self.disc, self.topo, trial, params) <= energy + ARMIJO * alpha * slope {
                return Some(alpha);
            }
            alpha *= 0.5;
        }
        None
    }

    /// Levenberg–Marquardt update after an accepted step of length `alpha`
    /// along `d`: trust the quadratic model more after a full step (μ
    /// lowered ×[`MU_STEP`], to 0 from [`MU_FIRST`], unless
    /// [`Self::curvature_allows`] shows the lower μ cannot factor), less
    /// after a strongly cut one (α < 1/4: μ [`raised`]).
    fn adapt_mu(&self, state: &mut StageState, alpha: f64, hess_values: &[f64], mass: &[f64], d: &[f64], eps: f64) {
        if alpha == 1.0 {
            let lower = if state.mu <= MU_FIRST { 0.0 } else { state.mu / MU_STEP };
            if self.curvature_allows(hess_values, mass, d, eps, lower) {
                state.mu = lower;
            }
        } else if alpha < 0.25 {
            state.mu = raised(state.mu);
        }
    }
}

/// Solve with the factorization `chol`, in place.
///
/// # Errors
/// [`CrossfieldError::Linalg`] when nothing was factored or sizes differ.
fn solve_with(chol: &mut Option<SupernodalCholesky>, rhs: &mut [f64]) -> Result<(), CrossfieldError> {
    let c = chol
        .as_mut()
        .ok_or(CrossfieldError::Linalg(crate::linalg::LinalgError::Internal("solve before factorization".into())))?;
    c.solve_in_place(rhs)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{EdgeId, fixtures};

    /// Two large-ε stages on a disk with the boundary fixed (no vortex yet,
    /// hence no zero mode: at smaller ε the four vortices can rotate
    /// together); returns the energy, the field and the history.
    fn run(krylov_min_dofs: usize) -> (f64, Vec<C64>, Vec<NewtonRecord>) {
        let mesh = fixtures::disk(10);
        let topo = Topology::new(&mesh);
        let disc = Discretization::new(&mesh, &topo, 4);
        let fixed: Vec<bool> = (0..topo.n_edges()).map(|e| topo.is_boundary_edge(EdgeId::new(e))).collect();
        let sys = NewtonSystem::new(&topo, &disc, &fixed).unwrap();
        let mut solver = NewtonSolver::new(&topo, &disc, &sys);
        solver.krylov_min_dofs = krylov_min_dofs;
        let weak = vec![false; topo.n_edges()];
        let mut f = vec![C64::new(1.0, 0.0); topo.n_edges()];
        let mut history = Vec::new();
        let mut energy = 0.0;
        for (s, eps) in [0.8, 0.5].into_iter().enumerate() {
            let params = EnergyParams { inv_eps2: 1.0 / (eps * eps), weak_coef: 0.0, weak_edges: &weak };
            let spec = StageSpec {
                eps,
                tol: 1e-10,
                max_iter: 40,
                stop_on_stall: false,
                mu_start: if s > 0 { 1.0 } else { 0.0 },
                settled_residual: 0.0,
            };
            let out = solver.minimize(&mut f, &params, &spec, None, &Progress::none()).unwrap();
            history.extend_from_slice(&out.history);
            assert!(out.converged && !out.plateau, "{out:?}");
            energy = out.energy;
        }
        (energy, f, history)
    }

    /// The final stage at ε = 0.1 on a disk with a fixed boundary (four
    /// vortices) from the continuation 0.4, 0.2, with `settled_residual`;
    /// returns the stage's outcome, its field and that field's residual
    /// recomputed from scratch.
    fn vortex_stage(settled_residual: f64) -> (StageOutcome, f64) {
        let mesh = fixtures::disk(12);
        let topo = Topology::new(&mesh);
        let disc = Discretization::new(&mesh, &topo, 4);
        let fixed: Vec<bool> = (0..topo.n_edges()).map(|e| topo.is_boundary_edge(EdgeId::new(e))).collect();
        let sys = NewtonSystem::new(&topo, &disc, &fixed).unwrap();
        let weak = vec![false; topo.n_edges()];
        let mut solver = NewtonSolver::new(&topo, &disc, &sys);
        let mut f = vec![C64::new(1.0, 0.0); topo.n_edges()];
        let mut last = None;
        for (s, eps) in [0.4, 0.2, 0.1].into_iter().enumerate() {
            let params = EnergyParams { inv_eps2: 1.0 / (eps * eps), weak_coef: 0.0, weak_edges: &weak };
            let spec = StageSpec {
                eps,
                tol: 1e-10,
                max_iter: 40,
                stop_on_stall: s < 2,
                mu_start: if s > 0 { 1.0 } else { 0.0 },
                settled_residual: if s == 2 { settled_residual } else { 0.0 },
            };
            let out = solver.minimize(&mut f, &params, &spec, None, &Progress::none()).unwrap();
            let asm = sys.assemble(&topo, &disc, &f, &params, HessianKind::Exact);
            last = Some((out, solver.residual(&asm.grad, eps)));
        }
        last.unwrap()
    }

    #[test]
    fn a_step_that_raises_a_settled_residual_is_undone() {
        // Without the rule the vortices drift: the residual falls to ~4e-6,
        // jumps to ~2e-4 and the plateau rule ends the stage higher.
        let (plain, plain_res) = vortex_stage(0.0);
        let residuals: Vec<f64> = plain.history.iter().map(|r| r.residual).collect();
        let best = residuals.iter().copied().fold(f64::INFINITY, f64::min);
        let at = residuals.iter().position(|&r| r == best).unwrap();
        assert!(at + 1 < residuals.len() && residuals[at + 1] > 10.0 * best, "{residuals:?}");
        assert!(plain_res > best, "{residuals:?}");
        // With it, the stage ends on the small-residual iterate, one step
        // after it (the step that raised the residual is undone).
        let (settled, settled_res) = vortex_stage(1e-4);
        assert!(settled.converged && settled.plateau);
        assert_eq!(settled.history.len(), at + 2);
        assert_eq!(settled.residual, best);
        assert!((settled_res - best).abs() <= 1e-12 * best, "{settled_res} vs {best}");
        assert!(settled.history.last().unwrap().residual > best);
    }

    #[test]
    fn cg_steps_reach_the_minimizer_of_factored_steps() {
        let (e_direct, f_direct, h_direct) = run(usize::MAX);
        let (e_cg, f_cg, h_cg) = run(0);
        assert!(h_direct.iter().all(|r| r.hessian != "exact-cg"));
        assert!(h_cg.iter().any(|r| r.hessian == "exact-cg" && r.krylov_iterations > 0));
        let show = |h: &[NewtonRecord]| {
            h.iter()
                .map(|r| {
                    format!(
                        "{} {} {:.3e} {:.10} {} {}",
                        r.epsilon, r.iteration, r.residual, r.energy, r.step, r.hessian
                    )
                })
                .collect::<Vec<_>>()
                .join("\n")
        };
        assert!(
            (e_direct - e_cg).abs() <= 1e-9 * e_direct.abs(),
            "{e_direct} vs {e_cg}\n{}\n--\n{}",
            show(&h_direct),
            show(&h_cg)
        );
        let diff = f_direct.iter().zip(&f_cg).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(diff < 1e-6, "{diff}");
    }
}
