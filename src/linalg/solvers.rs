//! Factorizations that serve several right-hand sides.

use super::{LinalgError, SparseMatrix};
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, Lu, SymbolicLlt, SymbolicLu};
use faer::{Mat, Side};

/// Sparse LU factorization of a square non-symmetric matrix, factored once
/// and applied to any number of right-hand sides.
#[derive(Debug, Clone)]
pub struct LuSolver {
    lu: Lu<usize, f64>,
    n: usize,
}

impl LuSolver {
    /// Factor `a` (symbolic analysis with COLAMD ordering, then numeric).
    ///
    /// # Errors
    /// [`LinalgError::Singular`] when a pivot vanishes.
    pub fn new(a: &SparseMatrix) -> Result<Self, LinalgError> {
        super::use_sequential_kernels();
        let symbolic = SymbolicLu::try_new(a.symbolic()).map_err(|e| LinalgError::Internal(format!("{e:?}")))?;
        let lu = Lu::try_new_with_symbolic(symbolic, a.as_ref()).map_err(|_| LinalgError::Singular { kind: "LU" })?;
        Ok(Self { lu, n: a.nrows() })
    }

    /// Solve `A x = b` for each column of `rhs`, in place.
    ///
    /// # Errors
    /// [`LinalgError::DimensionMismatch`] when a column has the wrong length.
    pub fn solve_columns(&self, rhs: &mut [Vec<f64>]) -> Result<(), LinalgError> {
        solve_columns_with(&self.lu, self.n, rhs)
    }
}

/// Sparse Cholesky (LLᵀ) factorization of a symmetric positive definite
/// matrix; the symbolic analysis is kept so a matrix with the same pattern
/// (a later Newton step) is refactored with the numeric phase only.
#[derive(Debug, Clone)]
pub struct CholeskySolver {
    symbolic: SymbolicLlt<usize>,
    llt: Llt<usize, f64>,
    n: usize,
}

impl CholeskySolver {
    /// Analyse and factor `a`; only its lower triangle is read.
    ///
    /// # Errors
    /// [`LinalgError::Singular`] when `a` is not positive definite.
    pub fn new(a: &SparseMatrix) -> Result<Self, LinalgError> {
        super::use_sequential_kernels();
        let symbolic =
            SymbolicLlt::try_new(a.symbolic(), Side::Lower).map_err(|e| LinalgError::Internal(format!("{e:?}")))?;
        let llt = Llt::try_new_with_symbolic(symbolic.clone(), a.as_ref(), Side::Lower)
            .map_err(|_| LinalgError::Singular { kind: "Cholesky" })?;
        Ok(Self { symbolic, llt, n: a.nrows() })
    }

    /// Refactor a matrix with the same sparsity pattern, reusing the analysis.
    ///
    /// # Errors
    /// [`LinalgError::Singular`] when `a` is not positive definite.
    pub fn refactor(&mut self, a: &SparseMatrix) -> Result<(), LinalgError> {
        if a.nrows() != self.n {
            return Err(LinalgError::DimensionMismatch { expected: self.n, got: a.nrows() });
        }
        self.llt = Llt::try_new_with_symbolic(self.symbolic.clone(), a.as_ref(), Side::Lower)
            .map_err(|_| LinalgError::Singular { kind: "Cholesky" })?;
        Ok(())
    }

    /// Solve `A x = b` for each column of `rhs`, in place.
    ///
    /// # Errors
    /// [`LinalgError::DimensionMismatch`] when a column has the wrong length.
    pub fn solve_columns(&self, rhs: &mut [Vec<f64>]) -> Result<(), LinalgError> {
        solve_columns_with(&self.llt, self.n, rhs)
    }

    /// Replace `x` by `A⁻¹ x` (no allocation; for use inside iterative solvers).
    ///
    /// # Panics
    /// When `x.len()` differs from the matrix size.
    pub fn solve_in_place(&self, x: &mut [f64]) {
        assert_eq!(x.len(), self.n, "right-hand side length");
        let n = self.n;
        self.llt.solve_in_place(faer::MatMut::from_column_major_slice_mut(x, n, 1));
    }

    /// Size of the factored matrix.
    pub fn dim(&self) -> usize {
        self.n
    }
}

/// Copy columns into one dense block, solve once, copy back.
fn solve_columns_with(solver: &impl Solve<f64>, n: usize, rhs: &mut [Vec<f64>]) -> Result<(), LinalgError> {
    if let Some(bad) = rhs.iter().find(|c| c.len() != n) {
        return Err(LinalgError::DimensionMismatch { expected: n, got: bad.len() });
    }
    let mut block = Mat::<f64>::from_fn(n, rhs.len(), |i, j| rhs[j][i]);
    solver.solve_in_place(block.as_mut());
    for (j, col) in rhs.iter_mut().enumerate() {
        for (i, x) in col.iter_mut().enumerate() {
            *x = block[(i, j)];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::Triplets;

    /// 1D Laplacian with Dirichlet ends, size n (SPD, tridiagonal).
    fn laplacian(n: usize, shift: f64) -> Triplets {
        let mut t = Triplets::new(n, n);
        for i in 0..n {
            t.push(i, i, 2.0 + shift);
            if i > 0 {
                t.push(i, i - 1, -1.0);
                t.push(i - 1, i, -1.0);
            }
        }
        t
    }

    #[test]
    fn lu_solves_nonsymmetric_system_with_two_rhs() {
        let mut t = laplacian(50, 0.0);
        t.push(3, 7, 0.25); // break symmetry
        let a = t.to_matrix().unwrap();
        let x_true: Vec<f64> = (0..50).map(|i| (i as f64 * 0.1).sin()).collect();
        let b = &a * faer::Col::<f64>::from_fn(50, |i| x_true[i]);
        let mut cols = vec![(0..50).map(|i| b[i]).collect::<Vec<_>>(), vec![0.0; 50]];
        LuSolver::new(&a).unwrap().solve_columns(&mut cols).unwrap();
        for i in 0..50 {
            assert!((cols[0][i] - x_true[i]).abs() < 1e-10);
            assert_eq!(cols[1][i], 0.0);
        }
    }

    #[test]
    fn cholesky_refactors_with_same_pattern() {
        let t = laplacian(40, 0.0);
        let mut s = CholeskySolver::new(&t.to_matrix().unwrap()).unwrap();
        let t2 = laplacian(40, 1.0);
        s.refactor(&t2.pattern().unwrap().matrix(t2.values()).unwrap()).unwrap();
        let mut cols = vec![vec![1.0; 40]];
        s.solve_columns(&mut cols).unwrap();
        // Residual of the shifted system.
        let a = t2.to_matrix().unwrap();
        let r = &a * faer::Col::<f64>::from_fn(40, |i| cols[0][i]);
        assert!((0..40).all(|i| (r[i] - 1.0).abs() < 1e-12));
        let mut neg = Triplets::new(2, 2);
        neg.push(0, 0, -1.0);
        neg.push(1, 1, 1.0);
        assert!(matches!(CholeskySolver::new(&neg.to_matrix().unwrap()), Err(LinalgError::Singular { .. })));
        let mut wrong = vec![vec![1.0; 3]];
        assert!(s.solve_columns(&mut wrong).is_err());
    }
}
