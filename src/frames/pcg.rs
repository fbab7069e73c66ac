//! Preconditioned conjugate gradients for the 9 components of a frame
//! field at once, on the symmetric positive definite matrices
//! `αM + τK (+ P)` of [`super::mbo`].
//!
//! Why: a sparse Cholesky factorization of a 3D P1 matrix grows like `n²`
//! (seconds per numeric factorization on a million tetrahedra even with a
//! nested-dissection ordering: `docs/decisions.md`), and MBO needs one per
//! time step. For
//! `M + τK` with `τ` a few squared edge lengths the condition number is
//! bounded independently of `n` (`1 + O(τ/h²)`), so conjugate gradients
//! converge in a fixed number of iterations, each one sparse product; the
//! Dirichlet problem `K + P` of the harmonic start needs more iterations
//! (`O(1/h)`), once.
//!
//! The matrix is kept as full symmetric CSR (both triangles, rows in
//! parallel with rayon), the 9 right-hand sides interleaved per vertex so
//! the matrix is read once per iteration for all of them; each component
//! runs its own CG recurrence (independent step lengths) and stops at its
//! own tolerance. Preconditioner: Jacobi (the diagonal). Reductions are
//! over fixed chunks in a fixed order, so results do not depend on the
//! number of threads.

use crate::linalg::{CgOptions, conjugate_gradients};
use crate::progress::{Cancelled, Progress};
use rayon::prelude::*;

/// Rows per parallel chunk (fixed, for deterministic reductions).
const CHUNK: usize = 4096;

/// A symmetric matrix in full CSR form built from a lower-triangle
/// compressed-column pattern (diagonal first in each column).
#[derive(Debug, Clone)]
pub struct SymmetricCsr {
    n: usize,
    row_ptr: Vec<usize>,
    col: Vec<u32>,
    /// For each full-CSR slot, the lower-triangle slot holding its value.
    source: Vec<u32>,
    /// Full-CSR values.
    vals: Vec<f64>,
    /// Inverse diagonal (Jacobi).
    inv_diag: Vec<f64>,
}

impl SymmetricCsr {
    /// The pattern of the symmetric matrix whose lower triangle is given by
    /// `col_ptr`, `row_idx` (compressed columns, rows ≥ column).
    pub fn from_lower_pattern(col_ptr: &[usize], row_idx: &[usize]) -> Self {
        let n = col_ptr.len() - 1;
        let mut count = vec![0usize; n];
        for j in 0..n {
            for s in col_ptr[j]..col_ptr[j + 1] {
                let i = row_idx[s];
                count[i] += 1;
                if i != j {
                    count[j] += 1;
                }
            }
        }
        let mut row_ptr = vec![0usize; n + 1];
        for i in 0..n {
            row_ptr[i + 1] = row_ptr[i] + count[i];
        }
        let mut next = row_ptr[..n].to_vec();
        let mut col = vec![0u32; row_ptr[n]];
        let mut source = vec![0u32; row_ptr[n]];
        for j in 0..n {
            for s in col_ptr[j]..col_ptr[j + 1] {
                let i = row_idx[s];
                col[next[i]] = j as u32;
                source[next[i]] = s as u32;
                next[i] += 1;
                if i != j {
                    col[next[j]] = i as u32;
                    source[next[j]] = s as u32;
                    next[j] += 1;
                }
            }
        }
        Self { n, vals: vec![0.0; col.len()], inv_diag: vec![0.0; n], row_ptr, col, source }
    }

    /// Set the values from the lower-triangle values (same pattern).
    pub fn set_values(&mut self, lower: &[f64]) {
        let (source, col) = (&self.source, &self.col);
        self.vals.par_iter_mut().enumerate().for_each(|(k, v)| *v = lower[source[k] as usize]);
        let (row_ptr, vals) = (&self.row_ptr, &self.vals);
        self.inv_diag.par_iter_mut().enumerate().for_each(|(i, d)| {
            let mut diag = 0.0;
            for k in row_ptr[i]..row_ptr[i + 1] {
                if col[k] as usize == i {
                    diag = vals[k];
                }
            }
            *d = if diag > 0.0 { 1.0 / diag } else { 1.0 };
        });
    }

    /// Matrix size.
    pub fn n(&self) -> usize {
        self.n
    }

    /// `z = D⁻¹ r` for 9 interleaved columns (`D` the diagonal): the Jacobi
    /// preconditioner.
    pub fn jacobi9(&self, r: &[[f64; 9]], z: &mut [[f64; 9]]) {
        z.par_iter_mut().zip(r.par_iter()).zip(self.inv_diag.par_iter()).for_each(|((zi, ri), d)| {
            for c in 0..9 {
                zi[c] = ri[c] * d;
            }
        });
    }

    /// `y = A x` for 9 interleaved columns.
    pub fn apply9(&self, x: &[[f64; 9]], y: &mut [[f64; 9]]) {
        y.par_chunks_mut(CHUNK).enumerate().for_each(|(ci, ys)| {
            for (r, yi) in ys.iter_mut().enumerate() {
                let i = ci * CHUNK + r;
                let mut acc = [0.0; 9];
                for k in self.row_ptr[i]..self.row_ptr[i + 1] {
                    let a = self.vals[k];
                    let xj = &x[self.col[k] as usize];
                    for c in 0..9 {
                        acc[c] += a * xj[c];
                    }
                }
                *yi = acc;
            }
        });
    }
}

/// Outcome of [`pcg9`].
#[derive(Debug, Clone, Copy)]
pub struct PcgOutcome {
    /// Iterations of the slowest column.
    pub iterations: usize,
    /// Largest final relative residual `|b − A x| / |b|` over the columns.
    pub relative_residual: f64,
}

/// Solve `A x_c = b_c` for the 9 interleaved columns by Jacobi-preconditioned
/// CG ([`conjugate_gradients`] on `[f64; 9]` rows) from the initial `x`,
/// until `|r_c| ≤ tol |b_c|` for every column or `max_iter` iterations.
/// `progress` is checked before every product (one atomic load beside a
/// sparse product), so a cancel stops the solve at once.
///
/// # Errors
/// [`Cancelled`] when `progress` is cancelled.
pub fn pcg9(
    a: &SymmetricCsr,
    b: &[[f64; 9]],
    x: &mut [[f64; 9]],
    tol: f64,
    max_iter: usize,
    progress: &Progress,
) -> Result<PcgOutcome, Cancelled> {
    let apply = |p: &[[f64; 9]], y: &mut [[f64; 9]]| {
        progress.check()?;
        a.apply9(p, y);
        Ok(())
    };
    let precondition = |r: &[[f64; 9]], z: &mut [[f64; 9]]| {
        a.jacobi9(r, z);
        Ok(())
    };
    let columns = conjugate_gradients(apply, precondition, b, x, &CgOptions { rel_tol: tol, max_iter })?;
    Ok(PcgOutcome {
        iterations: columns.iter().map(|c| c.iterations).max().unwrap_or(0),
        relative_residual: columns.iter().map(|c| c.relative_residual).fold(0.0, f64::max),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::tet_p1::tet_p1_operators;
    use crate::linalg::CholeskySolver;

    #[test]
    fn pcg_matches_the_direct_solver() {
        let mesh = crate::frames::singular::tests::kuhn_box(2, 3);
        let ops = tet_p1_operators(&mesh);
        let n = ops.n_vertices;
        let a = ops.combination(1.0, 0.7, None);
        let (cp, ri) = ops.pattern();
        let mut csr = SymmetricCsr::from_lower_pattern(cp, ri);
        let (_, lower) = a.parts();
        csr.set_values(lower);
        let b: Vec<[f64; 9]> = (0..n).map(|i| std::array::from_fn(|c| ((i * 7 + c * 3) % 11) as f64 - 5.0)).collect();
        let mut x = vec![[0.0; 9]; n];
        let out = pcg9(&csr, &b, &mut x, 1e-12, 500, &Progress::none()).unwrap();
        assert!(out.relative_residual <= 1e-12, "{out:?}");
        let mut cols: Vec<Vec<f64>> = (0..9).map(|c| b.iter().map(|v| v[c]).collect()).collect();
        CholeskySolver::new(&a).unwrap().solve_columns(&mut cols).unwrap();
        for i in 0..n {
            for c in 0..9 {
                assert!((x[i][c] - cols[c][i]).abs() < 1e-9 * (1.0 + cols[c][i].abs()));
            }
        }
        // The CSR product agrees with the lower-storage product.
        let mut y = vec![[0.0; 9]; n];
        csr.apply9(&x, &mut y);
        let mut kx = vec![0.0; n];
        let xs: Vec<f64> = x.iter().map(|v| v[0]).collect();
        let stiff = ops.combination(0.0, 1.0, None);
        let mut k = SymmetricCsr::from_lower_pattern(cp, ri);
        k.set_values(stiff.parts().1);
        let mut ky = vec![[0.0; 9]; n];
        k.apply9(&x, &mut ky);
        ops.apply_stiffness(&xs, &mut kx);
        for i in 0..n {
            assert!((ky[i][0] - kx[i]).abs() < 1e-10);
        }
    }
}
