//! Errors of the linear algebra layer.

use thiserror::Error;

/// Why a sparse system could not be built or solved.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LinalgError {
    /// A triplet names a row or column outside the matrix.
    #[error("matrix entry ({row}, {col}) outside a {n_rows}×{n_cols} matrix")]
    IndexOutOfRange { row: usize, col: usize, n_rows: usize, n_cols: usize },
    /// The factorization met a zero pivot or a non-positive diagonal.
    #[error("the {kind} factorization failed: the matrix is singular or not positive definite")]
    Singular { kind: &'static str },
    /// Values do not match the pattern they are assembled into.
    #[error("{got} values for a pattern of {expected} triplets")]
    PatternMismatch { expected: usize, got: usize },
    /// A right-hand side has the wrong length.
    #[error("right-hand side of length {got} for a system of size {expected}")]
    DimensionMismatch { expected: usize, got: usize },
    /// Out of memory or another internal failure of the sparse library.
    #[error("sparse library failure: {0}")]
    Internal(String),
}
