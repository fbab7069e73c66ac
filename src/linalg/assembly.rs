//! Assembly of sparse matrices from triplets, with a reusable pattern.

use super::{LinalgError, SparseMatrix};
use faer::sparse::{Argsort, Pair, SymbolicSparseColMat};

/// Row/column/value triplets of a sparse matrix being assembled; duplicates add.
#[derive(Debug, Clone, Default)]
pub struct Triplets {
    n_rows: usize,
    n_cols: usize,
    rows: Vec<u32>,
    cols: Vec<u32>,
    vals: Vec<f64>,
}

impl Triplets {
    /// Empty `n_rows × n_cols` assembly.
    pub fn new(n_rows: usize, n_cols: usize) -> Self {
        Self {
            n_rows,
            n_cols,
            ..Default::default()
        }
    }

    /// Empty assembly with room for `capacity` entries.
    pub fn with_capacity(n_rows: usize, n_cols: usize, capacity: usize) -> Self {
        Self {
            n_rows,
            n_cols,
            rows: Vec::with_capacity(capacity),
            cols: Vec::with_capacity(capacity),
            vals: Vec::with_capacity(capacity),
        }
    }

    /// Add `value` at `(row, col)`.
    #[inline]
    pub fn push(&mut self, row: usize, col: usize, value: f64) {
        self.rows.push(row as u32);
        self.cols.push(col as u32);
        self.vals.push(value);
    }

    /// Number of triplets pushed (before duplicates are summed).
    pub fn len(&self) -> usize {
        self.vals.len()
    }

    /// True when no triplet was pushed.
    pub fn is_empty(&self) -> bool {
        self.vals.is_empty()
    }

    /// The values, in push order (to reassemble with a [`Pattern`]).
    pub fn values(&self) -> &[f64] {
        &self.vals
    }

    /// Mutable values, in push order.
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.vals
    }

    /// The symbolic pattern of these triplets, reusable for new values.
    ///
    /// # Errors
    /// [`LinalgError::IndexOutOfRange`] for an entry outside the matrix.
    pub fn pattern(&self) -> Result<Pattern, LinalgError> {
        for k in 0..self.len() {
            let (r, c) = (self.rows[k] as usize, self.cols[k] as usize);
            if r >= self.n_rows || c >= self.n_cols {
                return Err(LinalgError::IndexOutOfRange {
                    row: r,
                    col: c,
                    n_rows: self.n_rows,
                    n_cols: self.n_cols,
                });
            }
        }
        let idx: Vec<Pair<usize, usize>> = self
            .rows
            .iter()
            .zip(&self.cols)
            .map(|(&r, &c)| Pair::new(r as usize, c as usize))
            .collect();
        let (symbolic, argsort) =
            SymbolicSparseColMat::try_new_from_indices(self.n_rows, self.n_cols, &idx)
                .map_err(|e| LinalgError::Internal(format!("{e:?}")))?;
        Ok(Pattern {
            symbolic,
            argsort,
            n_triplets: self.len(),
        })
    }

    /// Build the compressed matrix (duplicates summed).
    ///
    /// # Errors
    /// [`LinalgError::IndexOutOfRange`] for an entry outside the matrix.
    pub fn to_matrix(&self) -> Result<SparseMatrix, LinalgError> {
        self.pattern()?.matrix(&self.vals)
    }
}

/// Symbolic structure of an assembled matrix plus the order that maps a
/// triplet sequence onto it; building a new matrix with the same sequence
/// of `(row, col)` costs one pass over the values.
#[derive(Debug, Clone)]
pub struct Pattern {
    symbolic: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    n_triplets: usize,
}

impl Pattern {
    /// The matrix with this pattern and `values` given in triplet order.
    ///
    /// # Errors
    /// [`LinalgError::PatternMismatch`] when `values` has the wrong length.
    pub fn matrix(&self, values: &[f64]) -> Result<SparseMatrix, LinalgError> {
        if values.len() != self.n_triplets {
            return Err(LinalgError::PatternMismatch {
                expected: self.n_triplets,
                got: values.len(),
            });
        }
        SparseMatrix::new_from_argsort(self.symbolic.clone(), &self.argsort, values)
            .map_err(|e| LinalgError::Internal(format!("{e:?}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicates_are_summed_and_pattern_reused() {
        let mut t = Triplets::new(2, 2);
        t.push(0, 0, 1.0);
        t.push(1, 1, 2.0);
        t.push(0, 0, 3.0);
        t.push(1, 0, -1.0);
        let m = t.to_matrix().unwrap();
        let d = m.to_dense();
        assert_eq!(
            (d[(0, 0)], d[(1, 1)], d[(1, 0)], d[(0, 1)]),
            (4.0, 2.0, -1.0, 0.0)
        );
        let p = t.pattern().unwrap();
        let m2 = p.matrix(&[1.0, 1.0, 1.0, 1.0]).unwrap().to_dense();
        assert_eq!(m2[(0, 0)], 2.0);
        assert!(matches!(
            p.matrix(&[1.0]),
            Err(LinalgError::PatternMismatch { .. })
        ));
        let mut bad = Triplets::new(2, 2);
        bad.push(2, 0, 1.0);
        assert!(matches!(
            bad.to_matrix(),
            Err(LinalgError::IndexOutOfRange { row: 2, .. })
        ));
    }
}
