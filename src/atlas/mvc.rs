//! Mean value coordinates parameterization of a patch (thesis ch. 2 §3.3–3.4).
//!
//! Every vertex not on the outer boundary satisfies the difference scheme
//! (2.4) `Σ_j λ_ij (u_i − u_j) = 0` with Floater's mean value weights (2.7)
//! `λ_ij = (tan(θ_k/2) + tan(θ_l/2)) / l_ij`, where `θ_k`, `θ_l` are the
//! angles at `i` of the two triangles sharing edge `ij` and `l_ij` its 3D
//! length. The weights are positive, so with the outer loop on the (convex)
//! unit circle the map is one-to-one (§3). The outer loop is the longest
//! boundary loop, placed on the unit circle by arc length (Dirichlet). A hole
//! with at most `max_fill_vertices` vertices is filled virtually (§3.4): its
//! vertices `h_j` are assumed on a circle of radius `r = P / 2π` (`P` its
//! perimeter) around a pseudo-centre `c` (one extra unknown), each virtual
//! triangle `(h_j, h_{j+1}, c)` isosceles with apex angle `α_j = l_j / r`
//! and base angles `(π − α_j) / 2`; these triangles add mean value weights
//! like real ones but are never built. Larger holes get homogeneous Neumann
//! conditions: their vertices keep only their real neighbours. One sparse
//! non-symmetric matrix `A`, two right-hand sides (u and v).
//!
//! Solvers ([`MvcSolver`]). `A` is non-symmetric, but its pattern is
//! symmetric and it is a row diagonally dominant M-matrix, so Gaussian
//! elimination needs no pivoting: the default factors it once with our
//! supernodal LU ([`SupernodalLu`], on the Cholesky structure of the mesh
//! graph) in single precision, and one step of iterative refinement in
//! double precision (at most two on the corpus; BiCGSTAB takes over should
//! refinement stall) brings u and v to the relative residual 10⁻¹⁰.
//! The other choice, BiCGSTAB preconditioned by the Cholesky factor of the
//! symmetrized matrix `S` (weights `(λ_ij + λ_ji) / 2`), needs several
//! iterations where this needs one, and more time and memory (the
//! single-precision `L` and `U` together are the size of `S`'s factor in
//! double precision); faer's LU with partial pivoting, slower still, is the
//! fallback for degenerate patches (runs in `docs/decisions.md`).

use super::error::AtlasError;
use super::patch::PatchMesh;
use crate::geom::{Vec2, Vec3};
use crate::linalg::{LinalgError, LuSolver, SparseMatrix, SupernodalCholesky, SupernodalLu, Triplets, bicgstab_block};
use crate::mesh::VertexId;
use crate::mesh::boundary::BoundaryLoop;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// Which sparse solver computes the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MvcSolver {
    /// Supernodal LU without pivoting of the MVC matrix (an M-matrix, see
    /// [`SupernodalLu`]), stored in single precision; iterative refinement
    /// (BiCGSTAB if it stalls) recovers double precision in one or two
    /// steps; one factorization for both right-hand sides.
    Lu,
    /// BiCGSTAB preconditioned by a Cholesky factor of the symmetrized matrix.
    Bicgstab,
    /// faer's sparse LU with partial pivoting: slow, but needs no structure.
    /// The other two fall back to it when they fail (a degenerate patch).
    PivotingLu,
}

/// Relative residual the iterative solver must reach.
const KRYLOV_TOLERANCE: f64 = 1e-10;
/// Iteration cap of the iterative solver before falling back to LU.
const KRYLOV_MAX_ITERATIONS: usize = 200;

/// The parametric coordinates of a patch and how its holes were treated.
#[derive(Debug, Clone)]
pub struct PatchParameterization {
    /// `(u, v)` of every local vertex of the patch.
    pub uv: Vec<Vec2>,
    /// Holes filled with a pseudo-centre.
    pub n_holes_filled: usize,
    /// Holes left with homogeneous Neumann conditions.
    pub n_holes_neumann: usize,
    /// Size of the solved system.
    pub n_unknowns: usize,
    /// Solver actually used (an iterative solve that fails falls back to LU).
    pub solver: MvcSolver,
    /// BiCGSTAB iterations (or refinement steps with [`MvcSolver::Lu`]) for u and v.
    pub iterations: [usize; 2],
}

/// Mean value parameterization of `patch` with `loops[0]` as the outer loop.
///
/// # Errors
/// [`AtlasError::Linalg`] when the system cannot be factored.
pub fn mean_value_parameterization(
    patch: &PatchMesh,
    loops: &[BoundaryLoop],
    max_fill_vertices: usize,
    solver: MvcSolver,
) -> Result<PatchParameterization, AtlasError> {
    let never = |_: &[Vec2]| false;
    mean_value_parameterization_unless(patch, loops, max_fill_vertices, solver, &never)?
        .ok_or_else(|| AtlasError::Linalg(LinalgError::Internal("mean value solve abandoned".into())))
}

/// As [`mean_value_parameterization`], but with BiCGSTAB the first
/// approximation (the map of the symmetrized weights, `S⁻¹ b`, the
/// Krylov method's starting point, so it costs nothing extra) is shown
/// to `give_up` first; when it returns true the solve stops and `None` is
/// returned. Why: a patch whose map will be rejected anyway (e.g. a tube
/// whose far end is compressed 10⁵×) need not be solved to 10⁻¹⁰.
///
/// # Errors
/// [`AtlasError::Linalg`] when the system cannot be factored.
pub fn mean_value_parameterization_unless(
    patch: &PatchMesh,
    loops: &[BoundaryLoop],
    max_fill_vertices: usize,
    solver: MvcSolver,
    give_up: &dyn Fn(&[Vec2]) -> bool,
) -> Result<Option<PatchParameterization>, AtlasError> {
    let n_v = patch.mesh.n_vertices();
    let outer = &loops[0];
    let mut uv = vec![Vec2::zeros(); n_v];
    let mut unknown_of = vec![usize::MAX; n_v];
    for (v, p) in outer.vertices.iter().zip(circle_by_arc_length(&patch.mesh.positions, &outer.vertices)) {
        uv[v.idx()] = p;
    }
    let on_outer: Vec<bool> = {
        let mut f = vec![false; n_v];
        outer.vertices.iter().for_each(|v| f[v.idx()] = true);
        f
    };
    let mut n_unknowns = 0;
    for (v, slot) in unknown_of.iter_mut().enumerate() {
        if !on_outer[v] {
            *slot = n_unknowns;
            n_unknowns += 1;
        }
    }
    let filled: Vec<&BoundaryLoop> = loops[1..].iter().filter(|h| h.vertices.len() <= max_fill_vertices).collect();
    let n_centres = filled.len();
    let n = n_unknowns + n_centres;

    // Mean value weights per directed edge, accumulated over the triangles
    // first, so each matrix gets one entry per neighbour pair (not one per
    // triangle corner): ~3.5 triplets per triangle for A, ~2 for S.
    let pos = &patch.mesh.positions;
    let topo = &patch.topo;
    let (mut lam_lo_hi, mut lam_hi_lo) = (vec![0.0f64; topo.n_edges()], vec![0.0f64; topo.n_edges()]);
    for (f, t) in patch.mesh.triangles.iter().enumerate() {
        let fe = topo.face_edges[f];
        for c in 0..3 {
            let (i, j, k) = (t[c], t[(c + 1) % 3], t[(c + 2) % 3]);
            let (eij, eik) = (pos[j.idx()] - pos[i.idx()], pos[k.idx()] - pos[i.idx()]);
            let w = tan_half_angle(&eij, &eik);
            // Edge i→j is local edge c, edge k→i is local edge c+2.
            for (e, len) in [(fe[c], eij.norm()), (fe[(c + 2) % 3], eik.norm())] {
                if topo.edges[e.idx()][0] == i {
                    lam_lo_hi[e.idx()] += w / len;
                } else {
                    lam_hi_lo[e.idx()] += w / len;
                }
            }
        }
    }
    let capacity = 2 * topo.n_edges() + n + 6 * filled.iter().map(|h| h.vertices.len()).sum::<usize>();
    let mut system = MvcSystem::new(n, capacity, solver == MvcSolver::Bicgstab);
    for (e, [a, b]) in topo.edges.iter().enumerate() {
        let (ra, rb) = (unknown_of[a.idx()], unknown_of[b.idx()]);
        if ra != usize::MAX && lam_lo_hi[e] > 0.0 {
            system.add(ra, lam_lo_hi[e], rb, uv[b.idx()]);
        }
        if rb != usize::MAX && lam_hi_lo[e] > 0.0 {
            system.add(rb, lam_hi_lo[e], ra, uv[a.idx()]);
        }
    }
    for (h, hole) in filled.iter().enumerate() {
        add_virtual_fill(&mut system, pos, &hole.vertices, &unknown_of, n_unknowns + h);
    }
    // The per-edge weights are not needed any more (memory peaks in the solve).
    drop((lam_lo_hi, lam_hi_lo));
    let (a, s, mut rhs) = system.finish()?;
    let fill = |uv: &mut [Vec2], x: &[Vec<f64>]| {
        for v in 0..n_v {
            let r = unknown_of[v];
            if r != usize::MAX {
                uv[v] = Vec2::new(x[0][r], x[1][r]);
            }
        }
    };
    let preview = |x: &[Vec<f64>]| {
        let mut first = uv.clone();
        fill(&mut first, x);
        give_up(&first)
    };
    let Some((used, iterations)) = solve(&a, s, &mut rhs, solver, &preview)? else {
        return Ok(None);
    };
    fill(&mut uv, &rhs);
    Ok(Some(PatchParameterization {
        uv,
        n_holes_filled: n_centres,
        n_holes_neumann: loops.len() - 1 - n_centres,
        n_unknowns: n,
        solver: used,
        iterations,
    }))
}

/// Solve `A x = b` for both columns of `rhs` in place with the chosen solver;
/// returns the solver used and the iteration counts, or `None` when
/// `give_up` rejects BiCGSTAB's starting point. Either preconditioner is
/// applied to u and v together, in one pass over its factor.
fn solve(
    a: &SparseMatrix,
    s: Option<SparseMatrix>,
    rhs: &mut [Vec<f64>],
    solver: MvcSolver,
    give_up: &dyn Fn(&[Vec<f64>]) -> bool,
) -> Result<Option<(MvcSolver, [usize; 2])>, AtlasError> {
    let outcome = match (solver, s) {
        (MvcSolver::Lu, _) => match SupernodalLu::<f32>::factor(a) {
            Ok(lu) => preconditioned_solve(a, &|x| lu.solve_interleaved(x), true, rhs, give_up),
            Err(_) => Krylov::Failed,
        },
        (MvcSolver::Bicgstab, Some(s)) => {
            match SupernodalCholesky::analyze(&s).and_then(|mut c| c.factor(&s).map(|()| c)) {
                Ok(chol) => {
                    // `S` only serves the factorization: free it before the Krylov vectors.
                    drop(s);
                    preconditioned_solve(a, &|x| chol.solve_interleaved(x), false, rhs, give_up)
                }
                Err(_) => Krylov::Failed,
            }
        }
        (MvcSolver::Bicgstab, None) | (MvcSolver::PivotingLu, _) => Krylov::Failed,
    };
    match outcome {
        Krylov::Converged(its) => Ok(Some((solver, its))),
        Krylov::GaveUp => Ok(None),
        Krylov::Failed => {
            // A degenerate patch (a vanishing pivot, no convergence): pivoting LU.
            LuSolver::new(a)?.solve_columns(rhs)?;
            Ok(Some((MvcSolver::PivotingLu, [0, 0])))
        }
    }
}

/// How a preconditioned Krylov solve ended.
enum Krylov {
    /// Converged (iterations for u and v); the solution is in `rhs`.
    Converged([usize; 2]),
    /// `give_up` rejected the starting point.
    GaveUp,
    /// No convergence, or the preconditioner could not be built.
    Failed,
}

/// Iterative refinement steps tried before BiCGSTAB takes over.
const MAX_REFINEMENTS: usize = 3;

/// Iterative refinement `x ← x + M⁻¹ (b − A x)` of both columns until the
/// relative residual reaches [`KRYLOV_TOLERANCE`]; the number of steps, or
/// `None` (with `x` improved) when [`MAX_REFINEMENTS`] steps do not suffice
/// or the residual stops shrinking tenfold per step. With the
/// single-precision LU of `A` itself, `M⁻¹ A` is the identity up to ~10⁻⁶
/// and one step reaches 10⁻¹⁰ (every corpus patch): two applications of
/// `M⁻¹` where a BiCGSTAB iteration costs three.
fn refine(a: &SparseMatrix, apply: &dyn Fn(&mut [Vec<f64>]), b: &[Vec<f64>], x: &mut [Vec<f64>]) -> Option<usize> {
    let norm = |v: &[f64]| v.iter().map(|t| t * t).sum::<f64>().sqrt();
    let b_norm: Vec<f64> = b.iter().map(|c| norm(c)).collect();
    let mut r = vec![vec![0.0; b[0].len()]; b.len()];
    let mut last = f64::INFINITY;
    for step in 0..=MAX_REFINEMENTS {
        let mut worst = 0.0f64;
        for c in 0..b.len() {
            crate::linalg::sparse_matvec(a, &x[c], &mut r[c]);
            for (ri, bi) in r[c].iter_mut().zip(&b[c]) {
                *ri = bi - *ri;
            }
            worst = worst.max(norm(&r[c]) / b_norm[c].max(f64::MIN_POSITIVE));
        }
        if worst <= KRYLOV_TOLERANCE {
            return Some(step);
        }
        if step == MAX_REFINEMENTS || worst > 0.1 * last {
            return None;
        }
        last = worst;
        apply(&mut r);
        for (xc, rc) in x.iter_mut().zip(&r) {
            for (xi, ri) in xc.iter_mut().zip(rc) {
                *xi += ri;
            }
        }
    }
    None
}

/// Applies `M⁻¹` in place to interleaved `(u, v)` pairs.
type Preconditioner<'a> = dyn Fn(&mut [[f64; 2]]) -> Result<(), LinalgError> + Sync + 'a;

/// Both columns of `rhs` to [`KRYLOV_TOLERANCE`] from the starting point
/// `M⁻¹ b`, which is first shown to `give_up`: iterative refinement first
/// when `M` approximates `A` itself (`refinable`, see [`refine`]), then
/// BiCGSTAB; `precond` applies `M⁻¹` to interleaved `(u, v)` pairs.
fn preconditioned_solve(
    a: &SparseMatrix,
    precond: &Preconditioner,
    refinable: bool,
    rhs: &mut [Vec<f64>],
    give_up: &dyn Fn(&[Vec<f64>]) -> bool,
) -> Krylov {
    let apply = |cols: &mut [Vec<f64>]| {
        let mut x: Vec<[f64; 2]> = cols[0].iter().zip(&cols[1]).map(|(&u, &v)| [u, v]).collect();
        // Lengths always match the factored matrix here.
        let _ = precond(&mut x);
        for (i, [u, v]) in x.into_iter().enumerate() {
            cols[0][i] = u;
            cols[1][i] = v;
        }
    };
    let mut x = rhs.to_vec();
    apply(&mut x);
    if give_up(&x) {
        return Krylov::GaveUp;
    }
    if let Some(steps) = refinable.then(|| refine(a, &apply, rhs, &mut x)).flatten() {
        rhs.clone_from_slice(&x);
        return Krylov::Converged([steps; 2]);
    }
    let reps = bicgstab_block(a, &apply, rhs, &mut x, KRYLOV_TOLERANCE, KRYLOV_MAX_ITERATIONS);
    if reps.iter().all(|r| r.converged) {
        rhs.clone_from_slice(&x);
        Krylov::Converged([reps[0].iterations, reps[1].iterations])
    } else {
        Krylov::Failed
    }
}

/// Points on the unit circle at angles proportional to arc length along the loop.
pub fn circle_by_arc_length(positions: &[Vec3], loop_vertices: &[VertexId]) -> Vec<Vec2> {
    let m = loop_vertices.len();
    let mut s = Vec::with_capacity(m);
    let mut acc = 0.0;
    for k in 0..m {
        s.push(acc);
        acc += (positions[loop_vertices[(k + 1) % m].idx()] - positions[loop_vertices[k].idx()]).norm();
    }
    let total = if acc > 0.0 { acc } else { 1.0 };
    s.iter()
        .map(|&sk| {
            let t = TAU * sk / total;
            Vec2::new(t.cos(), t.sin())
        })
        .collect()
}

/// `tan(θ/2)` of the angle between `a` and `b`, as `|a×b| / (|a||b| + a·b)`;
/// finite and positive for every non-degenerate corner (capped near θ = π).
#[inline]
pub fn tan_half_angle(a: &Vec3, b: &Vec3) -> f64 {
    let s = a.cross(b).norm();
    let d = a.norm() * b.norm() + a.dot(b);
    if d > s * 1e-15 { s / d } else { 1e15 }
}

/// Add the virtual triangles `(h_j, h_{j+1}, c)` of a filled hole to the system.
fn add_virtual_fill(system: &mut MvcSystem, pos: &[Vec3], hole: &[VertexId], unknown_of: &[usize], centre: usize) {
    let m = hole.len();
    let lengths: Vec<f64> = (0..m).map(|j| (pos[hole[(j + 1) % m].idx()] - pos[hole[j].idx()]).norm()).collect();
    let perimeter: f64 = lengths.iter().sum();
    if perimeter <= 0.0 {
        return;
    }
    let r = perimeter / TAU;
    for j in 0..m {
        let (a, b) = (hole[j], hole[(j + 1) % m]);
        let l = lengths[j].max(f64::MIN_POSITIVE);
        let alpha = (l / r).min(PI * (1.0 - 1e-12));
        let beta = 0.5 * (PI - alpha);
        let tb = (0.5 * beta).tan();
        let ta = (0.5 * alpha).tan();
        // Corners h_j and h_{j+1}: neighbours are each other and the centre.
        for (p, q) in [(a, b), (b, a)] {
            let row = unknown_of[p.idx()];
            system.add(row, tb / l, unknown_of[q.idx()], Vec2::zeros());
            system.add(row, tb / r, centre, Vec2::zeros());
        }
        // Apex at the centre.
        system.add(centre, ta / r, unknown_of[a.idx()], Vec2::zeros());
        system.add(centre, ta / r, unknown_of[b.idx()], Vec2::zeros());
    }
}

/// `A`, `S` (only for the Cholesky preconditioner) and the right-hand sides `[u, v]`.
type AssembledSystem = (SparseMatrix, Option<SparseMatrix>, Vec<Vec<f64>>);

/// Triplets of the difference scheme `A`, of its symmetrization `S` (lower
/// triangle, when asked for), and the two right-hand sides.
struct MvcSystem {
    triplets: Triplets,
    diagonal: Vec<f64>,
    /// Whether `S` is assembled too (only BiCGSTAB's preconditioner needs it).
    with_symmetric: bool,
    symmetric: Triplets,
    symmetric_diagonal: Vec<f64>,
    rhs: [Vec<f64>; 2],
}

impl MvcSystem {
    fn new(n: usize, capacity: usize, with_symmetric: bool) -> Self {
        let n_sym = if with_symmetric { n } else { 0 };
        Self {
            triplets: Triplets::with_capacity(n, n, capacity),
            diagonal: vec![0.0; n],
            with_symmetric,
            symmetric: Triplets::with_capacity(n_sym, n_sym, if with_symmetric { capacity / 2 + n } else { 0 }),
            symmetric_diagonal: vec![0.0; n_sym],
            rhs: [vec![0.0; n], vec![0.0; n]],
        }
    }

    /// Add `w (u_row − u_col)` to row `row`; `col == usize::MAX` means the
    /// neighbour is on the outer circle with known `(u, v) = fixed`.
    #[inline]
    fn add(&mut self, row: usize, w: f64, col: usize, fixed: Vec2) {
        self.diagonal[row] += w;
        if col == usize::MAX {
            self.rhs[0][row] += w * fixed.x;
            self.rhs[1][row] += w * fixed.y;
            if self.with_symmetric {
                self.symmetric_diagonal[row] += w;
            }
        } else {
            self.triplets.push(row, col, -w);
            if !self.with_symmetric {
                return;
            }
            let h = 0.5 * w;
            self.symmetric_diagonal[row] += h;
            self.symmetric_diagonal[col] += h;
            self.symmetric.push(row.max(col), row.min(col), -h);
        }
    }

    /// `A`, `S` (when assembled) and the right-hand sides `[u, v]`.
    fn finish(self) -> Result<AssembledSystem, AtlasError> {
        let Self { mut triplets, diagonal, with_symmetric, mut symmetric, symmetric_diagonal, rhs: [u, v] } = self;
        for (i, d) in diagonal.iter().enumerate() {
            triplets.push(i, i, *d);
        }
        let s = if with_symmetric {
            for (i, sd) in symmetric_diagonal.iter().enumerate() {
                symmetric.push(i, i, *sd);
            }
            Some(symmetric.to_matrix()?)
        } else {
            None
        };
        Ok((triplets.to_matrix()?, s, vec![u, v]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{FaceId, fixtures};

    fn whole(m: &crate::mesh::TriMesh) -> PatchMesh {
        PatchMesh::extract(m, &(0..m.n_faces()).map(FaceId::new).collect::<Vec<_>>())
    }

    #[test]
    fn planar_disk_maps_to_itself() {
        // The unit disk with its boundary on the unit circle by arc length:
        // MVC reproduces linear functions, so the map is the identity.
        let m = fixtures::disk(8);
        let p = whole(&m);
        let loops = p.loops_longest_first();
        let par = mean_value_parameterization(&p, &loops, 100, MvcSolver::Lu).unwrap();
        let err = p.mesh.positions.iter().zip(&par.uv).map(|(x, u)| (x.xy() - u).norm()).fold(0.0, f64::max);
        assert!(err < 1e-12, "max error {err}");
        // Boundary exactly on the circle.
        for v in &loops[0].vertices {
            assert!((par.uv[v.idx()].norm() - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn iterative_and_direct_solvers_agree_on_a_curved_patch() {
        // A bumpy, irregular patch: a sphere cap with jittered vertices.
        let mut m = fixtures::icosphere(4);
        for (i, p) in m.positions.iter_mut().enumerate() {
            *p *= 1.0 + 0.05 * ((i * 7919) % 17) as f64 / 17.0;
        }
        let faces: Vec<FaceId> = (0..m.n_faces())
            .filter(|&f| m.corners(FaceId::new(f)).iter().all(|c| c.z > -0.3))
            .map(FaceId::new)
            .collect();
        let p = PatchMesh::extract(&m, &faces);
        let loops = p.loops_longest_first();
        let exact = mean_value_parameterization(&p, &loops, 100, MvcSolver::PivotingLu).unwrap();
        for solver in [MvcSolver::Lu, MvcSolver::Bicgstab] {
            let it = mean_value_parameterization(&p, &loops, 100, solver).unwrap();
            assert_eq!(it.solver, solver);
            assert!(it.iterations[0] < 50, "{solver:?}: {:?}", it.iterations);
            let err = exact.uv.iter().zip(&it.uv).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
            assert!(err < 1e-10, "{solver:?}: max difference {err}");
            // The first approximation seen by `give_up` is close to the
            // map; giving up returns no map.
            let seen = std::cell::Cell::new(f64::NAN);
            let look = |uv: &[Vec2]| {
                seen.set(uv.iter().zip(&exact.uv).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max));
                true
            };
            let stopped = mean_value_parameterization_unless(&p, &loops, 100, solver, &look).unwrap();
            assert!(stopped.is_none());
            let close = if solver == MvcSolver::Lu { 1e-4 } else { 0.1 };
            assert!(seen.get() < close, "{solver:?}: first approximation off by {}", seen.get());
        }
        // The single-precision LU needs one or two refinement steps.
        let lu = mean_value_parameterization(&p, &loops, 100, MvcSolver::Lu).unwrap();
        assert!(lu.iterations.iter().all(|&i| i <= 2), "{:?}", lu.iterations);
        // The pivoting LU has no preview.
        let look = |_: &[Vec2]| true;
        let direct = mean_value_parameterization_unless(&p, &loops, 100, MvcSolver::PivotingLu, &look);
        assert!(direct.unwrap().is_some());
    }

    #[test]
    fn weights_are_positive_even_for_slivers() {
        let a = Vec3::new(1.0, 0.0, 0.0);
        assert!(tan_half_angle(&a, &Vec3::new(1.0, 1e-9, 0.0)) > 0.0);
        assert!(tan_half_angle(&a, &Vec3::new(-1.0, 1e-9, 0.0)).is_finite());
        assert!((tan_half_angle(&a, &Vec3::new(0.0, 1.0, 0.0)) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn annulus_hole_filled_or_neumann_both_injective() {
        let m = fixtures::annulus(0.3, 1.0, 32, 6);
        let p = whole(&m);
        let loops = p.loops_longest_first();
        for (max_fill, solver) in
            [(1000, MvcSolver::Lu), (0, MvcSolver::Lu), (1000, MvcSolver::Bicgstab), (0, MvcSolver::Bicgstab)]
        {
            let par = mean_value_parameterization(&p, &loops, max_fill, solver).unwrap();
            assert_eq!(par.solver, solver);
            assert_eq!(par.n_holes_filled + par.n_holes_neumann, 1);
            for t in &p.mesh.triangles {
                let [a, b, c] = t.map(|v| par.uv[v.idx()]);
                assert!(crate::geom::orient2d(&a, &b, &c) > 0.0);
            }
        }
    }
}
