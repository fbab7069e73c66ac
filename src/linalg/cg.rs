//! Preconditioned conjugate gradients (Hestenes–Stiefel 1952) on a block of
//! `K` right-hand sides of one symmetric positive definite matrix: the one
//! CG loop of the crate, serving the Newton steps of the crossfield (`K = 1`,
//! preconditioned by the last Cholesky factorization) and the frame-field
//! diffusion (`K = 9` spherical-harmonic components, Jacobi).
//!
//! Each column runs its own recurrence (its own step lengths `α`, `β`) and
//! stops at its own tolerance, `‖b − A x‖ ≤ rel_tol ‖b‖`; the operator and
//! the preconditioner are applied to the whole block at once, so a matrix
//! stored once is read once per iteration for all columns. With
//! `r = b − A x`, `z = M⁻¹ r`:
//!
//! ```text
//! p = z,  α = rᵀz / pᵀAp,  x += α p,  r −= α Ap,  β = r'ᵀz' / rᵀz,  p = z' + β p
//! ```
//!
//! A column whose curvature `pᵀAp` or `rᵀz` is not positive (an indefinite
//! matrix or preconditioner, or NaN) stops as not converged: the Newton
//! solver reads that as "refactor". The layout of a block row and the order
//! of its reductions are the row type's ([`BlockRow`]): `f64` for one
//! column, `[f64; K]` for `K` interleaved columns.

use super::KrylovReport;
use rayon::prelude::*;

/// Rows per parallel chunk of `[f64; K]` blocks (fixed, so the reductions
/// and thus the results do not depend on the number of threads).
const CHUNK: usize = 4096;

/// One row of a block of `K` vectors (one entry per column), and the vector
/// operations conjugate gradients needs on slices of such rows. Every
/// operation acts column by column; reductions sum in an order fixed by the
/// length alone.
pub trait BlockRow<const K: usize>: Copy + PartialEq + Send + Sync {
    /// The row of zeros.
    const ZERO: Self;
    /// Per-column dot products `Σ_i a_i[c] b_i[c]`.
    fn dot(a: &[Self], b: &[Self]) -> [f64; K];
    /// `y_i[c] += α[c] x_i[c]`.
    fn add_scaled(y: &mut [Self], alpha: &[f64; K], x: &[Self]);
    /// `y_i[c] −= α[c] x_i[c]`.
    fn sub_scaled(y: &mut [Self], alpha: &[f64; K], x: &[Self]);
    /// `p_i[c] = z_i[c] + β[c] p_i[c]` (the new search direction).
    fn set_direction(p: &mut [Self], z: &[Self], beta: &[f64; K]);
}

/// One column: plain sequential loops (the Newton solver's vectors, whose
/// cost is the preconditioner's triangular solves).
impl BlockRow<1> for f64 {
    const ZERO: Self = 0.0;

    fn dot(a: &[f64], b: &[f64]) -> [f64; 1] {
        [a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>()]
    }

    fn add_scaled(y: &mut [f64], alpha: &[f64; 1], x: &[f64]) {
        y.iter_mut().zip(x).for_each(|(yi, xi)| *yi += alpha[0] * xi);
    }

    fn sub_scaled(y: &mut [f64], alpha: &[f64; 1], x: &[f64]) {
        y.iter_mut().zip(x).for_each(|(yi, xi)| *yi -= alpha[0] * xi);
    }

    fn set_direction(p: &mut [f64], z: &[f64], beta: &[f64; 1]) {
        p.iter_mut().zip(z).for_each(|(pi, zi)| *pi = zi + beta[0] * *pi);
    }
}

/// `K` interleaved columns: rows in parallel (rayon) over fixed chunks of
/// [`CHUNK`] rows, chunk sums added in chunk order.
impl<const K: usize> BlockRow<K> for [f64; K] {
    const ZERO: Self = [0.0; K];

    fn dot(a: &[Self], b: &[Self]) -> [f64; K] {
        let parts: Vec<[f64; K]> = a
            .par_chunks(CHUNK)
            .zip(b.par_chunks(CHUNK))
            .map(|(x, y)| {
                let mut s = [0.0; K];
                for (u, v) in x.iter().zip(y) {
                    for c in 0..K {
                        s[c] += u[c] * v[c];
                    }
                }
                s
            })
            .collect();
        let mut s = [0.0; K];
        for p in parts {
            for c in 0..K {
                s[c] += p[c];
            }
        }
        s
    }

    fn add_scaled(y: &mut [Self], alpha: &[f64; K], x: &[Self]) {
        y.par_iter_mut().zip(x.par_iter()).for_each(|(yi, xi)| {
            for c in 0..K {
                yi[c] += alpha[c] * xi[c];
            }
        });
    }

    fn sub_scaled(y: &mut [Self], alpha: &[f64; K], x: &[Self]) {
        y.par_iter_mut().zip(x.par_iter()).for_each(|(yi, xi)| {
            for c in 0..K {
                yi[c] -= alpha[c] * xi[c];
            }
        });
    }

    fn set_direction(p: &mut [Self], z: &[Self], beta: &[f64; K]) {
        p.par_iter_mut().zip(z.par_iter()).for_each(|(pi, zi)| {
            for c in 0..K {
                pi[c] = zi[c] + beta[c] * pi[c];
            }
        });
    }
}

/// Stopping rule of [`conjugate_gradients`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CgOptions {
    /// A column stops once `‖b − A x‖ ≤ rel_tol ‖b‖` (dimensionless).
    pub rel_tol: f64,
    /// Iterations at most (each one product with `A` and one with `M⁻¹`).
    pub max_iter: usize,
}

/// Per-column state of the recurrence.
struct Column {
    /// `rᵀz` of the current residual.
    rz: f64,
    /// `‖b‖`.
    b_norm: f64,
    /// `‖r‖`.
    r_norm: f64,
    active: bool,
    /// Stopped on non-positive curvature.
    broke_down: bool,
    iterations: usize,
}

impl Column {
    /// The report of this column: converged when the tolerance was met.
    fn report(&self, rel_tol: f64) -> KrylovReport {
        let relative_residual = if self.b_norm > 0.0 { self.r_norm / self.b_norm } else { 0.0 };
        KrylovReport {
            iterations: self.iterations,
            relative_residual,
            converged: !self.broke_down && (self.b_norm == 0.0 || self.r_norm <= rel_tol * self.b_norm),
        }
    }
}

/// Solve `A x_c = b_c` for the `K` columns of the block by preconditioned
/// conjugate gradients from the initial `x`, each column until
/// `‖b_c − A x_c‖ ≤ rel_tol ‖b_c‖`, a breakdown (non-positive curvature),
/// or `max_iter` iterations. `apply(x, y)` sets `y = A x` and
/// `precondition(r, z)` sets `z = M⁻¹ r`, both for the whole block; either
/// may fail (a cancel check, a solve without factorization), which ends the
/// solve with that error. A zero initial `x` costs no product (`r = b`).
///
/// # Errors
/// The first error of `apply` or `precondition`.
#[track_caller]
pub fn conjugate_gradients<R, E, const K: usize>(
    mut apply: impl FnMut(&[R], &mut [R]) -> Result<(), E>,
    mut precondition: impl FnMut(&[R], &mut [R]) -> Result<(), E>,
    b: &[R],
    x: &mut [R],
    opts: &CgOptions,
) -> Result<[KrylovReport; K], E>
where
    R: BlockRow<K>,
{
    assert_eq!(b.len(), x.len(), "conjugate_gradients: b and x differ in length");
    let mut r = initial_residual(&mut apply, b, x)?;
    let b_norm = R::dot(b, b).map(f64::sqrt);
    let r_norm = R::dot(&r, &r).map(f64::sqrt);
    let mut cols: [Column; K] = std::array::from_fn(|c| Column {
        rz: 0.0,
        b_norm: b_norm[c],
        r_norm: r_norm[c],
        active: !(r_norm[c] <= opts.rel_tol * b_norm[c] || b_norm[c] == 0.0),
        broke_down: false,
        iterations: 0,
    });
    let n = b.len();
    let (mut z, mut ap) = (vec![R::ZERO; n], vec![R::ZERO; n]);
    if cols.iter().any(|c| c.active) {
        precondition(&r, &mut z)?;
    }
    let rz = R::dot(&r, &z);
    cols.iter_mut().zip(rz).for_each(|(c, rz)| c.rz = rz);
    let mut p = z.clone();
    let mut it = 0;
    while it < opts.max_iter && cols.iter().any(|c| c.active) {
        it += 1;
        apply(&p, &mut ap)?;
        let alpha = step_lengths(&mut cols, &R::dot(&p, &ap));
        R::add_scaled(x, &alpha, &p);
        R::sub_scaled(&mut r, &alpha, &ap);
        update_residual_norms(&mut cols, &R::dot(&r, &r).map(f64::sqrt), opts.rel_tol);
        if !cols.iter().any(|c| c.active) {
            break;
        }
        precondition(&r, &mut z)?;
        let beta = direction_weights(&mut cols, &R::dot(&r, &z));
        R::set_direction(&mut p, &z, &beta);
    }
    Ok(std::array::from_fn(|c| cols[c].report(opts.rel_tol)))
}

/// `r = b − A x`, without the product when `x` is zero (then `r = b`
/// exactly, as `A · 0 = 0`).
fn initial_residual<R: BlockRow<K>, E, const K: usize>(
    apply: &mut impl FnMut(&[R], &mut [R]) -> Result<(), E>,
    b: &[R],
    x: &[R],
) -> Result<Vec<R>, E> {
    let mut r = b.to_vec();
    if x.iter().any(|v| *v != R::ZERO) {
        let mut ax = vec![R::ZERO; b.len()];
        apply(x, &mut ax)?;
        R::sub_scaled(&mut r, &[1.0; K], &ax);
    }
    Ok(r)
}

/// `α_c = r_cᵀz_c / p_cᵀAp_c` for the active columns, 0 for the others; a
/// column with `pᵀAp ≤ 0` or `rᵀz ≤ 0` (or NaN) breaks down: it stops, not
/// converged, with `α = 0`.
fn step_lengths<const K: usize>(cols: &mut [Column; K], pap: &[f64; K]) -> [f64; K] {
    std::array::from_fn(|c| {
        let col = &mut cols[c];
        if !col.active {
            return 0.0;
        }
        if !(pap[c] > 0.0) || !(col.rz > 0.0) {
            col.active = false;
            col.broke_down = true;
            return 0.0;
        }
        col.rz / pap[c]
    })
}

/// Count the step of the active columns, record their new residual norms
/// and stop those that met the tolerance.
fn update_residual_norms<const K: usize>(cols: &mut [Column; K], r_norm: &[f64; K], rel_tol: f64) {
    for (col, &r) in cols.iter_mut().zip(r_norm) {
        if col.active {
            col.iterations += 1;
            col.r_norm = r;
            if r <= rel_tol * col.b_norm {
                col.active = false;
            }
        }
    }
}

/// `β_c = r'ᵀz' / rᵀz` for the active columns (0 for the others), and the
/// new `rᵀz`.
fn direction_weights<const K: usize>(cols: &mut [Column; K], rz_new: &[f64; K]) -> [f64; K] {
    std::array::from_fn(|c| {
        let col = &mut cols[c];
        let beta = if col.active && col.rz != 0.0 { rz_new[c] / col.rz } else { 0.0 };
        col.rz = rz_new[c];
        beta
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `y = A x` for a dense row-major `n × n` matrix, column by column of the block.
    fn dense_apply<R: BlockRow<K>, const K: usize>(
        a: &[f64],
        n: usize,
        get: impl Fn(&R, usize) -> f64,
        set: impl Fn(&mut R, usize, f64),
    ) -> impl FnMut(&[R], &mut [R]) -> Result<(), ()> {
        move |x: &[R], y: &mut [R]| {
            for i in 0..n {
                let mut row = R::ZERO;
                for c in 0..K {
                    set(&mut row, c, (0..n).map(|j| a[i * n + j] * get(&x[j], c)).sum());
                }
                y[i] = row;
            }
            Ok(())
        }
    }

    fn scalar_apply(a: &[f64], n: usize) -> impl FnMut(&[f64], &mut [f64]) -> Result<(), ()> {
        dense_apply::<f64, 1>(a, n, |x, _| *x, |x, _, v| *x = v)
    }

    fn identity(r: &[f64], z: &mut [f64]) -> Result<(), ()> {
        z.copy_from_slice(r);
        Ok(())
    }

    /// The 1D Dirichlet Laplacian `tridiag(−1, 2, −1)` of size `n`.
    fn laplacian(n: usize) -> Vec<f64> {
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            a[i * n + i] = 2.0;
            if i + 1 < n {
                a[i * n + i + 1] = -1.0;
                a[(i + 1) * n + i] = -1.0;
            }
        }
        a
    }

    #[test]
    fn solves_an_spd_system_with_a_known_solution() {
        // b = A x* with integer x*, so b is exact and x* the exact solution.
        let n = 30;
        let a = laplacian(n);
        let x_star: Vec<f64> = (0..n).map(|i| ((i * 7) % 11) as f64 - 5.0).collect();
        let b: Vec<f64> = (0..n).map(|i| (0..n).map(|j| a[i * n + j] * x_star[j]).sum()).collect();
        let mut x = vec![0.0; n];
        let opts = CgOptions { rel_tol: 1e-13, max_iter: 200 };
        let [rep] = conjugate_gradients(scalar_apply(&a, n), identity, &b, &mut x, &opts).unwrap();
        assert!(rep.converged && rep.relative_residual <= 1e-13, "{rep:?}");
        // The Laplacian has n distinct eigenvalues: at most n steps in exact arithmetic.
        assert!(rep.iterations <= n, "{rep:?}");
        let err = x.iter().zip(&x_star).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
        assert!(err < 1e-10, "max error {err}");
    }

    #[test]
    fn terminates_in_as_many_steps_as_distinct_eigenvalues() {
        // diag(1, 1, 4, 4, 9, 9): three distinct eigenvalues, so the Krylov
        // space of any b has dimension ≤ 3 and CG is exact after 3 steps.
        let d = [1.0, 1.0, 4.0, 4.0, 9.0, 9.0];
        let n = d.len();
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            a[i * n + i] = d[i];
        }
        let b = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let mut x = vec![0.0; n];
        let opts = CgOptions { rel_tol: 1e-14, max_iter: 50 };
        let [rep] = conjugate_gradients(scalar_apply(&a, n), identity, &b, &mut x, &opts).unwrap();
        assert!(rep.converged, "{rep:?}");
        assert!(rep.iterations <= 3, "{rep:?}");
        for i in 0..n {
            assert!((x[i] - b[i] / d[i]).abs() < 1e-13);
        }
    }

    #[test]
    fn jacobi_preconditioner_solves_a_scaled_system_in_fewer_steps() {
        // A = D L D with D = diag(1..100): badly scaled; Jacobi undoes the
        // scaling exactly (diag A = 2 D², so M^(-1/2) A M^(-1/2) = L / 2).
        let n = 40;
        let l = laplacian(n);
        let s: Vec<f64> = (0..n).map(|i| 10f64.powf(2.0 * i as f64 / (n - 1) as f64)).collect();
        let a: Vec<f64> = (0..n * n).map(|k| s[k / n] * l[k] * s[k % n]).collect();
        let x_star: Vec<f64> = (0..n).map(|i| 1.0 + (i % 3) as f64).collect();
        let b: Vec<f64> = (0..n).map(|i| (0..n).map(|j| a[i * n + j] * x_star[j]).sum()).collect();
        let opts = CgOptions { rel_tol: 1e-12, max_iter: 2000 };
        let jacobi = |r: &[f64], z: &mut [f64]| {
            for i in 0..n {
                z[i] = r[i] / a[i * n + i];
            }
            Ok(())
        };
        let mut x = vec![0.0; n];
        let [pre] = conjugate_gradients(scalar_apply(&a, n), jacobi, &b, &mut x, &opts).unwrap();
        assert!(pre.converged, "{pre:?}");
        let err = x.iter().zip(&x_star).map(|(p, q)| ((p - q) / q).abs()).fold(0.0, f64::max);
        assert!(err < 1e-4, "max relative error {err}");
        let mut y = vec![0.0; n];
        let [plain] = conjugate_gradients(scalar_apply(&a, n), identity, &b, &mut y, &opts).unwrap();
        assert!(pre.iterations < plain.iterations, "Jacobi {pre:?} vs none {plain:?}");
    }

    #[test]
    fn a_block_solves_each_column_as_the_scalar_solver_does() {
        // Three right-hand sides, one of them zero, one already an
        // eigenvector (one step): each column stops on its own.
        let n = 12;
        let a = laplacian(n);
        let eigen: Vec<f64> = (0..n).map(|i| (std::f64::consts::PI * (i + 1) as f64 / (n + 1) as f64).sin()).collect();
        let general: Vec<f64> = (0..n).map(|i| (i as f64 - 4.5).powi(2)).collect();
        let b: Vec<[f64; 3]> = (0..n).map(|i| [general[i], 0.0, eigen[i]]).collect();
        let mut x = vec![[0.0; 3]; n];
        let opts = CgOptions { rel_tol: 1e-12, max_iter: 100 };
        let apply = dense_apply::<[f64; 3], 3>(&a, n, |x, c| x[c], |x, c, v| x[c] = v);
        let reps = conjugate_gradients(
            apply,
            |r: &[[f64; 3]], z: &mut [[f64; 3]]| {
                z.copy_from_slice(r);
                Ok(())
            },
            &b,
            &mut x,
            &opts,
        )
        .unwrap();
        assert!(reps.iter().all(|r| r.converged), "{reps:?}");
        assert_eq!(reps[1].iterations, 0);
        assert_eq!(reps[2].iterations, 1);
        assert!(x.iter().all(|v| v[1] == 0.0));
        let mut y = vec![0.0; n];
        let [single] = conjugate_gradients(scalar_apply(&a, n), identity, &general, &mut y, &opts).unwrap();
        assert_eq!(single.iterations, reps[0].iterations);
        for i in 0..n {
            assert!((x[i][0] - y[i]).abs() <= 1e-12 * y[i].abs().max(1.0));
            // The eigenvector column: x = b / λ₁.
            let lambda = 2.0 - 2.0 * (std::f64::consts::PI / (n + 1) as f64).cos();
            assert!((x[i][2] - eigen[i] / lambda).abs() < 1e-12);
        }
    }

    #[test]
    fn negative_curvature_stops_the_column_unconverged() {
        // diag(1, −1): indefinite; b along the negative direction has pᵀAp < 0.
        let a = [1.0, 0.0, 0.0, -1.0];
        let mut x = vec![0.0; 2];
        let opts = CgOptions { rel_tol: 1e-12, max_iter: 10 };
        let [rep] = conjugate_gradients(scalar_apply(&a, 2), identity, &[0.0, 1.0], &mut x, &opts).unwrap();
        assert!(!rep.converged && rep.iterations == 0, "{rep:?}");
        // NaN in the matrix stops at once too, instead of spinning to max_iter.
        let nan = [f64::NAN, 0.0, 0.0, 1.0];
        let [rep] = conjugate_gradients(scalar_apply(&nan, 2), identity, &[1.0, 1.0], &mut x, &opts).unwrap();
        assert!(!rep.converged && rep.iterations == 0, "{rep:?}");
    }

    #[test]
    fn a_zero_right_hand_side_or_exact_start_costs_nothing() {
        let a = laplacian(4);
        let calls = std::cell::Cell::new(0);
        let apply = |x: &[f64], y: &mut [f64]| {
            calls.set(calls.get() + 1);
            scalar_apply(&a, 4)(x, y)
        };
        let mut x = vec![0.0; 4];
        let opts = CgOptions { rel_tol: 1e-12, max_iter: 10 };
        let [rep] = conjugate_gradients(apply, identity, &[0.0; 4], &mut x, &opts).unwrap();
        assert!(rep.converged && rep.iterations == 0 && calls.get() == 0, "{rep:?}");
        // From the exact solution: one product (the residual), no step.
        let mut x = vec![1.0; 4];
        let b = [1.0, 0.0, 0.0, 1.0];
        let [rep] = conjugate_gradients(apply, identity, &b, &mut x, &opts).unwrap();
        assert!(rep.converged && rep.iterations == 0 && calls.get() == 1, "{rep:?}");
        assert_eq!(x, vec![1.0; 4]);
    }

    #[test]
    fn errors_of_the_operator_end_the_solve() {
        let mut x = vec![0.0; 2];
        let opts = CgOptions { rel_tol: 1e-12, max_iter: 10 };
        let failing = |_: &[f64], _: &mut [f64]| Err("cancelled");
        let r = conjugate_gradients(
            failing,
            |r: &[f64], z: &mut [f64]| {
                z.copy_from_slice(r);
                Ok(())
            },
            &[1.0, 2.0],
            &mut x,
            &opts,
        );
        assert_eq!(r, Err("cancelled"));
    }
}
