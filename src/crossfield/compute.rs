//! The crossfield stage: discretize, initialize, continue in ε with the
//! safeguarded Newton method, then compute per-triangle crosses and the
//! singularities.
//!
//! Continuation: ε₀ (default a quarter of the bounding-box diagonal; without
//! aligned edges at most `1/(2√λ₁)`, see [`super::initial`]) is multiplied by
//! `continuation_factor` until the final ε (default the mean edge length h).
//! At large ε the GL minimizer is close to the smoothest field and the cores
//! are wide; each smaller ε starts from the previous minimizer with the cores
//! shrunk to their new width ([`shrink_cores`]), so singularities of opposite
//! index that attract each other annihilate while the cores are wide, and the
//! survivors settle where the renormalized energy puts them (asymptotic
//! regime: few singularities of index ±1/N, well spread). Intermediate stages
//! are solved to `continuation_tolerance` (or until the energy stalls, at most
//! a third of `max_newton_iterations`), the last to `tolerance`.
//!
//! Closed surfaces without aligned edges. The continuation from the smoothest
//! eigenvector can end in a metastable state: on the torus R = 1, r = 0.4 it
//! keeps 12 vortices (±1/4 pairs facing each other across the tube, the
//! thesis' result), because the renormalized energy has a local minimum
//! there at every ε. When the surface's curvature is anisotropic (no umbilic
//! regions, [`principal_curvature_field`]) a second candidate aligned with the
//! principal directions is solved at the final ε, and the candidate with the
//! lower GL energy is kept: the energy, not a heuristic, decides. On the
//! torus the singularity-free candidate wins at ε = h but not yet at
//! ε = 2h, which is why the default ε is h (`docs/decisions.md`).
//!
//! Multilevel continuation (`multilevel`, from `multilevel_min_faces`
//! triangles). A stage at ε only needs a mesh whose edges are about ε long,
//! so the stages with ε ≥ ε_c = ε/factor^k (the first such ratio ≥
//! [`COARSE_EPSILON_RATIO`]: 4 by default) run on a copy of the surface
//! coarsened by half-edge collapses ([`crate::mesh::decimate`]) to
//! (ε/ε_c)² of the triangles, with the aligned edges kept; that copy is
//! itself solved the same way, recursively. The field is then transferred
//! to the finer mesh by a conforming interpolation ([`super::transfer`]) and
//! only the remaining stages (by default the last one) run there. Meanwhile
//! the fine level's symbolic analysis (the nested-dissection ordering, the
//! longest part of the setup on large meshes) runs beside the coarse levels.
//! The fine system is then factored a few times instead of once per stage,
//! with the same vortices (`docs/decisions.md`).

use super::energy::EnergyParams;
use super::frames::{C64, Discretization, check_orientation, face_frame};
use super::initial::{InitialKind, initial_field, principal_curvature_field};
use super::newton::{FINAL_SETTLED_RESIDUAL, NewtonSolver, StageSpec};
use super::singularities::vertex_indices;
use super::system::NewtonSystem;
use super::transfer::transfer_to_fine;
use super::{
    BoundaryCondition, Crossfield, CrossfieldError, CrossfieldOptions, CrossfieldReport, LevelReport, NewtonRecord,
};
use crate::geom::Vec3;
use crate::mesh::decimate::decimate;
use crate::mesh::summary::topology_summary;
use crate::mesh::{FaceId, Topology, TriMesh};
use crate::progress::Progress;
use std::time::Instant;

/// Below this curvature anisotropy (see [`principal_curvature_field`]) the
/// principal directions are noise and the curvature candidate is skipped.
const MIN_ANISOTROPY: f64 = 0.3;

/// Check the options.
pub fn validate_options(opts: &CrossfieldOptions) -> Result<(), CrossfieldError> {
    let bad = |name, reason: String| Err(CrossfieldError::InvalidOption { name, reason });
    if opts.symmetry != 4 && opts.symmetry != 6 {
        return bad("symmetry", format!("{} (must be 4 or 6)", opts.symmetry));
    }
    if !(opts.weak_weight > 0.0 && opts.weak_weight.is_finite()) {
        return bad("weak_weight", format!("{} (must be positive)", opts.weak_weight));
    }
    for (name, v) in [("epsilon", opts.epsilon), ("epsilon_start", opts.epsilon_start)] {
        if let Some(v) = v
            && !(v > 0.0 && v.is_finite())
        {
            return bad(name, format!("{v} (must be positive)"));
        }
    }
    if !(opts.epsilon_per_edge_length > 0.0 && opts.epsilon_per_edge_length.is_finite()) {
        return bad("epsilon_per_edge_length", format!("{} (must be positive)", opts.epsilon_per_edge_length));
    }
    if !(opts.continuation_factor > 0.0 && opts.continuation_factor < 1.0) {
        return bad("continuation_factor", format!("{} (must be in (0, 1))", opts.continuation_factor));
    }
    for (name, v) in [("tolerance", opts.tolerance), ("continuation_tolerance", opts.continuation_tolerance)] {
        if !(v > 0.0 && v.is_finite()) {
            return bad(name, format!("{v} (must be positive)"));
        }
    }
    if opts.max_newton_iterations == 0 {
        return bad("max_newton_iterations", "0 (must be at least 1)".into());
    }
    Ok(())
}

/// The continuation schedule from `eps0` down to `eps`. An intermediate ε
/// within a factor `1/√factor` of the final one is dropped: it would cost a
/// stage (a factorization and a few Newton steps) to shrink the cores by
/// less than the last step does anyway (`docs/decisions.md`).
pub fn epsilon_schedule(eps0: f64, eps: f64, factor: f64) -> Vec<f64> {
    let mut s = Vec::new();
    let mut e = eps0;
    while e > eps / factor.sqrt() && s.len() < 200 {
        s.push(e);
        e *= factor;
    }
    s.push(eps);
    s
}

/// A coarse level takes the stages with ε at least this many times the
/// finest ε of the level below (rounded up to a power of
/// `1/continuation_factor`): 4 with the default factor, i.e. 16 times fewer
/// triangles per level.
pub const COARSE_EPSILON_RATIO: f64 = 2.5;
/// A coarse level of the input needs at least this many triangles (a
/// smaller one costs more in setup than it saves; a 3k-triangle input
/// already gains from a level of about 200: `docs/decisions.md`).
const MIN_COARSE_FACES: usize = 150;
/// A coarse level of a coarse level needs at least this many. A tiny one
/// starts its continuation above the eigenvalue-based ε₀ and leaves the
/// vortex arrangement to the finer levels, where Newton steps are dear
/// (`docs/decisions.md`); on a small mesh those extra iterations are
/// cheaper than the stage they replace.
const MIN_NESTED_COARSE_FACES: usize = 2_000;

/// One mesh of the multilevel continuation and its discretization.
struct Level<'m> {
    mesh: &'m TriMesh,
    topo: &'m Topology,
    /// 0 for the input, k for its k-th coarsening.
    depth: usize,
    disc: Discretization,
    /// Boundary and feature edges of this mesh.
    aligned: Vec<bool>,
    /// Edges whose value is fixed (strong condition, or no energy).
    fixed: Vec<bool>,
    /// Edges carrying the weak boundary term.
    weak_edges: Vec<bool>,
    /// Aligned edges with energy (they constrain the initial field).
    constrained: Vec<bool>,
    sys: NewtonSystem,
    /// Bounding-box diagonal (scales the weak term).
    diag: f64,
}

impl<'m> Level<'m> {
    /// Discretize `mesh` with its `aligned` edges.
    fn new(
        mesh: &'m TriMesh,
        topo: &'m Topology,
        aligned: Vec<bool>,
        depth: usize,
        opts: &CrossfieldOptions,
    ) -> Result<Self, CrossfieldError> {
        check_orientation(mesh, topo)?;
        let disc = Discretization::new(mesh, topo, opts.symmetry);
        // Edges without any non-degenerate triangle have no energy: fix them.
        let orphan: Vec<bool> = (0..topo.n_edges()).map(|e| disc.mass_per_edge[e] == 0.0).collect();
        let strong = opts.boundary == BoundaryCondition::Strong;
        let fixed: Vec<bool> = (0..topo.n_edges()).map(|e| orphan[e] || (strong && aligned[e])).collect();
        let constrained: Vec<bool> = aligned.iter().zip(&orphan).map(|(&a, &o)| a && !o).collect();
        let weak_edges = if strong { vec![false; topo.n_edges()] } else { constrained.clone() };
        let sys = NewtonSystem::new(topo, &disc, &fixed)?;
        let diag = mesh.bounding_box().map_or(1.0, |b| b.diagonal()).max(f64::MIN_POSITIVE);
        Ok(Self { mesh, topo, depth, disc, aligned, fixed, weak_edges, constrained, sys, diag })
    }

    /// Energy parameters at coherence length `e`.
    fn params(&self, e: f64, opts: &CrossfieldOptions) -> EnergyParams<'_> {
        EnergyParams {
            inv_eps2: 1.0 / (e * e),
            weak_coef: if opts.boundary == BoundaryCondition::Strong {
                0.0
            } else {
                opts.weak_weight * self.diag / (e * e)
            },
            weak_edges: &self.weak_edges,
        }
    }

    /// Reset the fixed edges to the aligned value 1.
    fn reset_fixed(&self, f: &mut [C64]) {
        for (z, &fx) in f.iter_mut().zip(&self.fixed) {
            if fx {
                *z = C64::new(1.0, 0.0);
            }
        }
    }
}

/// A coarsened copy of a level's mesh.
struct CoarseMesh {
    mesh: TriMesh,
    topo: Topology,
    aligned: Vec<bool>,
}

/// Coarsen `level` to about `target_faces` triangles, keeping its aligned
/// edges (their endpoints are locked, so each survives as a coarse edge).
/// `None` when the result would not serve: too little reduction, or a
/// different topology (Euler characteristic, orientation).
fn coarsen(level: &Level, target_faces: usize) -> Option<CoarseMesh> {
    // Edges up to 1.5 times the mean length of a uniform mesh with the target
    // number of triangles.
    let ratio = (level.mesh.n_faces() as f64 / target_faces.max(1) as f64).sqrt();
    let max_edge = 1.5 * ratio * level.mesh.mean_edge_length();
    let d = decimate(level.mesh, level.topo, &level.aligned, target_faces, max_edge).ok()?;
    if d.mesh.n_faces() * 4 > level.mesh.n_faces() * 3 {
        return None;
    }
    let topo = Topology::new(&d.mesh);
    topo.validate(&d.mesh).ok()?;
    check_orientation(&d.mesh, &topo).ok()?;
    let chi = |m: &TriMesh, t: &Topology| topology_summary(m, t).euler_characteristic;
    if chi(&d.mesh, &topo) != chi(level.mesh, level.topo) {
        return None;
    }
    let aligned = topo
        .edges
        .iter()
        .map(|&[a, b]| {
            let (fa, fb) = (d.fine_vertex[a.idx()], d.fine_vertex[b.idx()]);
            level.topo.edge_between(fa, fb).is_some_and(|e| level.aligned[e.idx()])
        })
        .collect();
    Some(CoarseMesh { mesh: d.mesh, topo, aligned })
}

/// The ε down to which a coarse level of a mesh solved to `eps` works:
/// `eps / factor^k`, the smallest such ratio reaching [`COARSE_EPSILON_RATIO`].
fn coarse_epsilon(eps: f64, factor: f64) -> f64 {
    let mut e = eps;
    while e < COARSE_EPSILON_RATIO * eps {
        e /= factor;
    }
    e
}

/// Compute the Ginzburg–Landau crossfield of `mesh` with `aligned_edges`
/// (one flag per edge of `topo`: boundary and feature edges the cross must
/// follow).
///
/// # Errors
/// [`CrossfieldError`]: empty mesh, wrong flag count, invalid options,
/// inconsistent orientation, solver failure, cancellation.
pub fn compute_crossfield(
    mesh: &TriMesh,
    topo: &Topology,
    aligned_edges: &[bool],
    opts: &CrossfieldOptions,
    progress: &Progress,
) -> Result<Crossfield, CrossfieldError> {
    let start = Instant::now();
    check_inputs(mesh, topo, aligned_edges, opts)?;
    let level = Level::new(mesh, topo, aligned_edges.to_vec(), 0, opts)?;
    let h = mesh.mean_edge_length();
    let eps = opts.epsilon.unwrap_or(opts.epsilon_per_edge_length * h);
    let eps0 = opts.epsilon_start.unwrap_or(0.25 * level.diag).max(eps);

    let mut f = vec![C64::new(1.0, 0.0); topo.n_edges()];
    let mut report = CrossfieldReport {
        symmetry: opts.symmetry,
        n_edges: topo.n_edges(),
        n_fixed_edges: level.fixed.iter().filter(|&&x| x).count(),
        n_aligned_edges: aligned_edges.iter().filter(|&&x| x).count(),
        n_degenerate_faces: level.disc.n_degenerate_faces,
        epsilon: eps,
        ..Default::default()
    };
    let mut solver = NewtonSolver::new(topo, &level.disc, &level.sys);
    if level.sys.n_dofs() > 0 {
        let continuation = Continuation { eps, eps0, opts };
        f = solve_candidates(&level, &mut solver, f, &continuation, progress, &mut report)?;
    } else {
        report.initial_guess = "none (all edges fixed)".into();
        report.converged = true;
        report.energy = super::energy::total_energy(&level.disc, topo, &f, &level.params(eps, opts));
    }
    add_solver_counts(&mut report, &solver);
    let field = crossfield_of(&level, f, report, start);
    progress.set(1.0);
    Ok(field)
}

/// The coherence lengths of a continuation, from `eps0` down to `eps`,
/// and the options that schedule its stages.
struct Continuation<'o> {
    /// Final ε (model units).
    eps: f64,
    /// First ε before any eigenvalue-based choice (model units).
    eps0: f64,
    opts: &'o CrossfieldOptions,
}

/// Reject invalid options, an empty mesh and a flag count that is not one
/// per edge of `topo`, before any work.
fn check_inputs(
    mesh: &TriMesh,
    topo: &Topology,
    aligned_edges: &[bool],
    opts: &CrossfieldOptions,
) -> Result<(), CrossfieldError> {
    validate_options(opts)?;
    if mesh.n_faces() == 0 {
        return Err(CrossfieldError::EmptyMesh);
    }
    if aligned_edges.len() != topo.n_edges() {
        return Err(CrossfieldError::AlignedEdgesLength { expected: topo.n_edges(), got: aligned_edges.len() });
    }
    Ok(())
}

/// Solve the continuation on the input `level` from `f`, then, on a closed
/// surface without aligned edges whose curvature is anisotropic, the
/// principal-curvature candidate at the final ε; returns the field of lower
/// GL energy (3.15) (module doc: the energy, not a heuristic, decides).
fn solve_candidates(
    level: &Level,
    solver: &mut NewtonSolver,
    mut f: Vec<C64>,
    continuation: &Continuation,
    progress: &Progress,
    report: &mut CrossfieldReport,
) -> Result<Vec<C64>, CrossfieldError> {
    progress.set(0.05);
    // Closed surfaces without aligned edges may get a second candidate:
    // leave it the last quarter.
    let no_aligned = !level.constrained.iter().any(|&c| c);
    let first = progress.sub(0.05, if no_aligned { 0.7 } else { 0.95 });
    let kind = solve_levels(level, solver, &mut f, continuation, &first, report)?;
    report.initial_guess = match kind {
        InitialKind::Laplace => "laplace",
        InitialKind::Eigenvector(_) => "eigenvector",
        InitialKind::Mixed(_) => "laplace+eigenvector",
    }
    .into();
    report.candidate_energies.push((report.initial_guess.clone(), report.energy));
    match curvature_candidate(level, kind, report) {
        Some(g) => solve_curvature_candidate(level, solver, f, g, continuation, progress, report),
        None => Ok(f),
    }
}

/// The principal-curvature start ([`principal_curvature_field`], fixed
/// edges reset) when the first candidate started from the eigenvector (a
/// closed surface without any aligned edge) and the curvature is not
/// (nearly) isotropic; records the anisotropy in `report`.
fn curvature_candidate(level: &Level, kind: InitialKind, report: &mut CrossfieldReport) -> Option<Vec<C64>> {
    if !matches!(kind, InitialKind::Eigenvector(_)) {
        return None;
    }
    let (mut g, anisotropy) = principal_curvature_field(level.mesh, level.topo, &level.disc);
    report.curvature_anisotropy = anisotropy;
    if anisotropy < MIN_ANISOTROPY {
        return None;
    }
    level.reset_fixed(&mut g);
    Some(g)
}

/// Candidate 2: the field aligned with the principal curvature directions
/// `g`, solved at the final ε only (a continuation from large ε would bring
/// back the eigenvector's singularities). Returns whichever of `f` (the
/// first candidate, whose numbers `report` holds) and the solved `g` has
/// the lower energy, with `report` updated to match.
fn solve_curvature_candidate(
    level: &Level,
    solver: &mut NewtonSolver,
    f: Vec<C64>,
    mut g: Vec<C64>,
    continuation: &Continuation,
    progress: &Progress,
    report: &mut CrossfieldReport,
) -> Result<Vec<C64>, CrossfieldError> {
    let mut alt = CrossfieldReport::default();
    let second = progress.sub(0.7, 0.95);
    let stages = Stages { schedule: vec![continuation.eps], previous: None };
    run_continuation(level, solver, &mut g, &stages, continuation.opts, &second, &mut alt)?;
    report.candidate_energies.push(("principal curvature".into(), alt.energy));
    report.iterations += alt.iterations;
    report.history.extend(alt.history);
    if !(alt.converged && alt.energy < report.energy) {
        return Ok(f);
    }
    report.initial_guess = "principal curvature".into();
    report.final_residual = alt.final_residual;
    report.energy = alt.energy;
    report.converged = alt.converged;
    report.stopped_on_plateau = alt.stopped_on_plateau;
    Ok(g)
}

/// The crossfield of the solved edge values `f` on the input `level`: the
/// per-triangle crosses, the vertex indices and singularities, checked
/// against Poincaré–Hopf (3.13) through the reported index sum and Euler
/// characteristic; `report` completed with them and the wall time since
/// `start`.
fn crossfield_of(level: &Level, f: Vec<C64>, mut report: CrossfieldReport, start: Instant) -> Crossfield {
    let (mesh, topo) = (level.mesh, level.topo);
    let idx = vertex_indices(mesh, topo, &level.disc, &f);
    let chi = topology_summary(mesh, topo).euler_characteristic;
    let (cross_per_face, norm_per_face) = face_crosses(mesh, topo, &level.disc, &f);
    report.n_singularities = idx.singularities.len();
    for s in &idx.singularities {
        *report.singularity_counts.entry(format_index(s.index)).or_default() += 1;
    }
    report.index_sum = idx.index_sum;
    report.euler_characteristic = chi;
    report.wall_seconds = start.elapsed().as_secs_f64();
    Crossfield {
        symmetry: report.symmetry,
        f_per_edge: f.iter().map(|z| [z.re, z.im]).collect(),
        cross_per_face,
        norm_per_face,
        index_per_vertex: idx.index_per_vertex,
        singularities: idx.singularities,
        euler_characteristic: chi,
        index_sum: idx.index_sum,
        report,
    }
}

/// The continuation from `eps0` down to `eps` on `level` (field `f`, solver
/// `solver` of that level), multilevel when the mesh is large: the stages
/// with ε ≥ ε_c ([`coarse_epsilon`]) run on a copy coarsened in proportion
/// ((ε/ε_c)² of the triangles, so ε_c is resolved as well as ε is here),
/// itself solved recursively; the field is then transferred to this mesh
/// ([`transfer_to_fine`]) and the remaining stages run here. The large-ε
/// stages (the vortices entering and settling, most of the Newton
/// iterations) thus cost a fraction of a fine factorization each. Returns
/// the kind of initial field (computed on the coarsest level).
fn solve_levels(
    level: &Level,
    solver: &mut NewtonSolver,
    f: &mut [C64],
    continuation: &Continuation,
    progress: &Progress,
    report: &mut CrossfieldReport,
) -> Result<InitialKind, CrossfieldError> {
    let t0 = Instant::now();
    let opts = continuation.opts;
    let eps_c = coarse_epsilon(continuation.eps, opts.continuation_factor);
    let t_coarse = Instant::now();
    let coarse = solve_coarse_levels(level, solver, eps_c, continuation, progress, report)?;
    let coarse_seconds = t_coarse.elapsed().as_secs_f64();
    let (kind, stages) = match coarse {
        Some((kind, g)) => {
            f.copy_from_slice(&g);
            let schedule = epsilon_schedule(eps_c, continuation.eps, opts.continuation_factor)[1..].to_vec();
            (kind, Stages { schedule, previous: Some(eps_c) })
        }
        None => {
            let (kind, schedule) = fresh_start(level, solver, f, continuation)?;
            (kind, Stages { schedule, previous: None })
        }
    };
    let stage_progress = if stages.previous.is_some() { progress.sub(0.3, 1.0) } else { progress.clone() };
    let iterations = report.iterations;
    run_continuation(level, solver, f, &stages, opts, &stage_progress, report)?;
    report.epsilon_schedule.extend_from_slice(&stages.schedule);
    report.levels.push(LevelReport {
        level: level.depth,
        n_faces: level.mesh.n_faces(),
        n_edges: level.topo.n_edges(),
        epsilon_schedule: stages.schedule,
        iterations: report.iterations - iterations,
        n_factorizations: 0,
        seconds: t0.elapsed().as_secs_f64() - coarse_seconds,
    });
    Ok(kind)
}

/// The stages of a continuation down to `eps_c` on a coarsened copy of
/// `level` ([`solve_coarse`]) when the level is large enough to have one,
/// run beside this level's symbolic analysis, which only needs the
/// pattern: on large meshes the nested-dissection ordering alone is the
/// longest part of the setup. Returns the initial kind and the field transferred to `level`,
/// or `None` when there is no coarse level; a coarse level that fails
/// (other than by cancellation) is an accelerator lost, not an error: its
/// records are removed from `report` and `None` returned.
fn solve_coarse_levels(
    level: &Level,
    solver: &mut NewtonSolver,
    eps_c: f64,
    continuation: &Continuation,
    progress: &Progress,
    report: &mut CrossfieldReport,
) -> Result<Option<(InitialKind, Vec<C64>)>, CrossfieldError> {
    let opts = continuation.opts;
    let target = (level.mesh.n_faces() as f64 * (continuation.eps / eps_c).powi(2)) as usize;
    let wants_coarse = opts.multilevel
        && level.mesh.n_faces() >= opts.multilevel_min_faces
        && target >= if level.depth == 0 { MIN_COARSE_FACES } else { MIN_NESTED_COARSE_FACES }
        && eps_c < continuation.eps0;
    if !wants_coarse {
        return Ok(None);
    }
    let marks = (report.history.len(), report.levels.len(), report.epsilon_schedule.len());
    let coarse_continuation = Continuation { eps: eps_c, eps0: continuation.eps0, opts };
    let (analysis, coarse) =
        rayon::join(|| solver.analyze(), || solve_coarse(level, target, &coarse_continuation, progress, report));
    analysis?;
    match coarse {
        Ok(c) => Ok(c),
        Err(e @ CrossfieldError::Cancelled(_)) => Err(e),
        // A coarse level is an accelerator: if it fails (a factorization
        // of a poorly shaped copy, say), solve this level on its own.
        Err(_) => {
            report.history.truncate(marks.0);
            report.levels.truncate(marks.1);
            report.epsilon_schedule.truncate(marks.2);
            Ok(None)
        }
    }
}

/// The initial field on `level` (into `f`) and the ε schedule from it,
/// when no coarse level gave one. Without boundary data, f = 0 is the GL
/// minimizer as long as 1/ε² ≤ λ₁ (the smallest eigenvalue of the
/// connection Laplacian): the continuation then starts where 1/ε₀² = 4 λ₁,
/// i.e. |f|² ≈ 3/4 (unless `epsilon_start` is set).
fn fresh_start(
    level: &Level,
    solver: &mut NewtonSolver,
    f: &mut [C64],
    continuation: &Continuation,
) -> Result<(InitialKind, Vec<f64>), CrossfieldError> {
    let (eps, eps0, opts) = (continuation.eps, continuation.eps0, continuation.opts);
    let mut schedule = epsilon_schedule(eps0, eps, opts.continuation_factor);
    let kind = initial_field(solver, f, &level.params(schedule[0], opts), &level.constrained)?;
    if let InitialKind::Eigenvector(l1) | InitialKind::Mixed(l1) = kind
        && l1 > 0.0
        && opts.epsilon_start.is_none()
    {
        let e0 = (0.5 / l1.sqrt()).min(eps0).max(eps);
        schedule = epsilon_schedule(e0, eps, opts.continuation_factor);
    }
    Ok((kind, schedule))
}

/// Coarsen `level` towards `target` triangles and solve the continuation
/// down to `continuation.eps` there (recursively, [`solve_levels`]);
/// returns the kind of initial field and the result transferred to `level`
/// (fixed edges reset), or `None` when coarsening does not serve (see
/// [`coarsen`]).
fn solve_coarse(
    level: &Level,
    target: usize,
    continuation: &Continuation,
    progress: &Progress,
    report: &mut CrossfieldReport,
) -> Result<Option<(InitialKind, Vec<C64>)>, CrossfieldError> {
    let Some(c) = coarsen(level, target) else {
        return Ok(None);
    };
    let opts = continuation.opts;
    let cl = Level::new(&c.mesh, &c.topo, c.aligned.clone(), level.depth + 1, opts)?;
    let mut cs = NewtonSolver::new(&c.topo, &cl.disc, &cl.sys);
    let mut fc = vec![C64::new(1.0, 0.0); c.topo.n_edges()];
    let kind = solve_levels(&cl, &mut cs, &mut fc, continuation, &progress.sub(0.0, 0.3), report)?;
    add_solver_counts(report, &cs);
    let mut g = transfer_to_fine(&c.mesh, &c.topo, &cl.disc, &fc, level.mesh, level.topo);
    level.reset_fixed(&mut g);
    Ok(Some((kind, g)))
}

/// Add a level's solver counters to `report`, and its factorizations to the
/// level last reported (the one that solver worked on).
fn add_solver_counts(report: &mut CrossfieldReport, solver: &NewtonSolver) {
    report.n_modified_steps += solver.n_modified_steps;
    report.n_factorizations += solver.n_factorizations;
    report.n_krylov_iterations += solver.n_krylov_iterations;
    if let Some(l) = report.levels.last_mut() {
        l.n_factorizations = solver.n_factorizations;
    }
}

/// The ε stages one call of [`run_continuation`] solves: `schedule`, from
/// a field solved at `previous` (`None` for a fresh initial field).
struct Stages {
    schedule: Vec<f64>,
    previous: Option<f64>,
}

/// Newton minimizations along the ε `stages` on `level`, accumulating into
/// `report`. The last stage on the input mesh is solved to `tolerance`,
/// every other to `continuation_tolerance`.
fn run_continuation(
    level: &Level,
    solver: &mut NewtonSolver,
    f: &mut [C64],
    stages: &Stages,
    opts: &CrossfieldOptions,
    progress: &Progress,
    report: &mut CrossfieldReport,
) -> Result<(), CrossfieldError> {
    let n_stages = stages.schedule.len();
    // Only the input mesh has a final stage; a coarse level's last ε is an
    // intermediate one of the whole continuation.
    let finest = level.depth == 0;
    let mut previous = stages.previous;
    for (s, &e) in stages.schedule.iter().enumerate() {
        if let Some(p) = previous {
            shrink_cores(solver, f, p / e);
        }
        let last = finest && s + 1 == n_stages;
        let stage_progress = progress.sub(s as f64 / n_stages as f64, (s + 1) as f64 / n_stages as f64);
        let spec = stage_spec(e, last, previous.is_some(), opts);
        let singular = |g: &[C64]| singular_vertices(level, g);
        let out = solver.minimize(f, &level.params(e, opts), &spec, Some(&singular), &stage_progress)?;
        report.history.extend(out.history.into_iter().map(|r| NewtonRecord { level: level.depth, ..r }));
        report.iterations += out.iterations;
        report.final_residual = out.residual;
        report.energy = out.energy;
        report.converged = out.converged;
        report.stopped_on_plateau = out.plateau;
        stage_progress.set(1.0);
        previous = Some(e);
    }
    Ok(())
}

/// The stage at ε = `e`: the final one (`last`) to `tolerance` with all
/// `max_newton_iterations`, an intermediate one to `continuation_tolerance`
/// with a third of them (at least 10), stopping when the energy stalls; μ
/// starts at 1 after a decrease of ε (`shrunk`), else at 0.
fn stage_spec(e: f64, last: bool, shrunk: bool, opts: &CrossfieldOptions) -> StageSpec {
    StageSpec {
        eps: e,
        tol: if last { opts.tolerance } else { opts.continuation_tolerance },
        max_iter: if last { opts.max_newton_iterations } else { (opts.max_newton_iterations / 3).max(10) },
        stop_on_stall: !last,
        mu_start: if shrunk { 1.0 } else { 0.0 },
        settled_residual: if last { FINAL_SETTLED_RESIDUAL } else { 0.0 },
    }
}

/// The singular vertices of the field `g` on `level` with their indices
/// (units of 1/N), in vertex order: what the final stage watches.
fn singular_vertices(level: &Level, g: &[C64]) -> Vec<(u32, i32)> {
    vertex_indices(level.mesh, level.topo, &level.disc, g)
        .index_per_vertex
        .iter()
        .enumerate()
        .filter(|&(_, &k)| k != 0)
        .map(|(v, &k)| (v as u32, k))
        .collect()
}

/// Predictor for a smaller ε: a vortex core has the profile `|f| ≈ ρ(r/ε)`
/// with `ρ(s) ≈ s/√(1+s²)`; dividing ε by `k` maps a modulus `a` to
/// `ρ(k ρ⁻¹(a)) = k a / √(1 + (k² − 1) a²)` (phase unchanged). This shrinks
/// the cores and boundary layers to their new width, so the Newton method
/// starts each stage close to its minimizer.
fn shrink_cores(solver: &NewtonSolver, f: &mut [C64], k: f64) {
    for &e in &solver.sys.free_edges {
        let z = f[e as usize];
        let a = z.norm();
        if a > 0.0 && a < 1.0 {
            let b = k * a / (1.0 + (k * k - 1.0) * a * a).sqrt();
            f[e as usize] = z * (b / a);
        }
    }
}

/// An index as short text for the report ("0.25", "-0.1667").
fn format_index(x: f64) -> String {
    let s = format!("{x:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    if s == "-0" { "0".into() } else { s }
}

/// Per triangle: the unit direction `u` of one branch (angle `arg(F)/N` in
/// the triangle frame, `F` the centroid value, i.e. the mean of the three
/// CR values) and `|F|`.
pub fn face_crosses(mesh: &TriMesh, topo: &Topology, disc: &Discretization, f: &[C64]) -> (Vec<Vec3>, Vec<f64>) {
    let n = disc.symmetry as f64;
    let mut u = Vec::with_capacity(mesh.n_faces());
    let mut norm = Vec::with_capacity(mesh.n_faces());
    for (t, fd) in disc.faces.iter().enumerate() {
        let fe = &topo.face_edges[t];
        let c = (fd.rot[0] * f[fe[0].idx()] + fd.rot[1] * f[fe[1].idx()] + fd.rot[2] * f[fe[2].idx()]) / 3.0;
        let (r, nrm) = face_frame(mesh, FaceId::new(t));
        let th = c.arg() / n;
        let dir = r * th.cos() + nrm.cross(&r) * th.sin();
        u.push(dir);
        norm.push(c.norm());
    }
    (u, norm)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;
    use crate::progress::ProgressSink;
    use std::sync::Arc;
    use std::sync::atomic::AtomicBool;

    fn boundary_flags(topo: &Topology) -> Vec<bool> {
        (0..topo.n_edges()).map(|e| topo.is_boundary_edge(crate::mesh::EdgeId::new(e))).collect()
    }

    #[test]
    fn options_parse_with_defaults_and_reject_unknown_fields() {
        let o: CrossfieldOptions =
            serde_json::from_str(r#"{"symmetry": 6, "boundary": "weak", "epsilon": 0.1}"#).unwrap();
        assert_eq!((o.symmetry, o.boundary, o.epsilon), (6, BoundaryCondition::Weak, Some(0.1)));
        assert_eq!(o.continuation_factor, 0.25);
        assert!(serde_json::from_str::<CrossfieldOptions>(r#"{"symetry": 4}"#).is_err());
        assert!(serde_json::from_str::<CrossfieldOptions>(r#"{"boundary": "soft"}"#).is_err());
    }

    #[test]
    fn bad_inputs_are_reported() {
        let mesh = fixtures::disk(3);
        let topo = Topology::new(&mesh);
        let flags = boundary_flags(&topo);
        let run = |o: &CrossfieldOptions, flags: &[bool]| compute_crossfield(&mesh, &topo, flags, o, &Progress::none());
        let bad = CrossfieldOptions { symmetry: 5, ..Default::default() };
        assert!(matches!(run(&bad, &flags), Err(CrossfieldError::InvalidOption { name: "symmetry", .. })));
        let bad = CrossfieldOptions { continuation_factor: 1.5, ..Default::default() };
        assert!(matches!(run(&bad, &flags), Err(CrossfieldError::InvalidOption { .. })));
        assert!(matches!(
            run(&CrossfieldOptions::default(), &flags[1..]),
            Err(CrossfieldError::AlignedEdgesLength { .. })
        ));
        let empty = TriMesh::default();
        let et = Topology::new(&empty);
        assert!(matches!(
            compute_crossfield(&empty, &et, &[], &CrossfieldOptions::default(), &Progress::none()),
            Err(CrossfieldError::EmptyMesh)
        ));
    }

    struct Nothing;
    impl ProgressSink for Nothing {
        fn report(&self, _: &str, _: f64) {}
    }

    #[test]
    fn cancellation_stops_the_newton_iterations() {
        let mesh = fixtures::disk(4);
        let topo = Topology::new(&mesh);
        let cancel = Arc::new(AtomicBool::new(true));
        let p = Progress::new(Arc::new(Nothing), cancel);
        let r = compute_crossfield(&mesh, &topo, &boundary_flags(&topo), &CrossfieldOptions::default(), &p);
        assert!(matches!(r, Err(CrossfieldError::Cancelled(_))));
    }

    #[test]
    fn singularities_json_has_the_documented_shape() {
        let mesh = fixtures::disk(6);
        let topo = Topology::new(&mesh);
        let field =
            compute_crossfield(&mesh, &topo, &boundary_flags(&topo), &CrossfieldOptions::default(), &Progress::none())
                .unwrap();
        let mut buf = Vec::new();
        crate::crossfield::write_singularities_json(&field, &mut buf).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        assert_eq!(v["symmetry"], 4);
        assert_eq!(v["euler_characteristic"], 1);
        assert_eq!(v["index_sum"], 1.0);
        let s = v["singularities"].as_array().unwrap();
        assert_eq!(s.len(), field.singularities.len());
        assert!(s.iter().all(|x| x["position"].as_array().unwrap().len() == 3 && x["vertex"].is_u64()));
        let report = serde_json::to_value(&field.report).unwrap();
        assert!(report["history"].as_array().unwrap().len() >= report["iterations"].as_u64().unwrap() as usize);
    }

    #[test]
    fn schedule_ends_at_the_final_epsilon() {
        let s = epsilon_schedule(1.0, 0.1, 0.5);
        // 0.125 is within √2 of 0.1: dropped.
        assert_eq!(s, vec![1.0, 0.5, 0.25, 0.1]);
        assert_eq!(epsilon_schedule(0.1, 0.1, 0.5), vec![0.1]);
        assert_eq!(epsilon_schedule(0.4, 0.099, 0.5), vec![0.4, 0.2, 0.099]);
        assert_eq!(epsilon_schedule(0.8, 0.04, 0.25), vec![0.8, 0.2, 0.04], "0.05 is within 2 of 0.04");
    }
}
