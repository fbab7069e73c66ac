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
        Self { n_rows, n_cols, ..Default::default() }
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

    /// Check every triplet lies inside the matrix.
    fn check_indices(&self) -> Result<(), LinalgError> {
        let bad = self
            .rows
            .iter()
            .zip(&self.cols)
            .position(|(&r, &c)| r as usize >= self.n_rows || c as usize >= self.n_cols);
        match bad {
            Some(k) => Err(LinalgError::IndexOutOfRange {
                row: self.rows[k] as usize,
                col: self.cols[k] as usize,
                n_rows: self.n_rows,
                n_cols: self.n_cols,
            }),
            None => Ok(()),
        }
    }

    /// The symbolic pattern of these triplets, reusable for new values.
    ///
    /// # Errors
    /// [`LinalgError::IndexOutOfRange`] for an entry outside the matrix.
    pub fn pattern(&self) -> Result<Pattern, LinalgError> {
        self.check_indices()?;
        let idx: Vec<Pair<usize, usize>> =
            self.rows.iter().zip(&self.cols).map(|(&r, &c)| Pair::new(r as usize, c as usize)).collect();
        let (symbolic, argsort) = SymbolicSparseColMat::try_new_from_indices(self.n_rows, self.n_cols, &idx)
            .map_err(|e| LinalgError::Internal(format!("{e:?}")))?;
        Ok(Pattern { symbolic, argsort, n_triplets: self.len() })
    }

    /// Build the compressed matrix (duplicates summed).
    ///
    /// A counting sort by column then a small sort per column: `O(nnz)` plus
    /// `O(d log d)` per column of `d` entries, several times faster than a
    /// global sort of the triplets for finite element matrices.
    ///
    /// # Errors
    /// [`LinalgError::IndexOutOfRange`] for an entry outside the matrix.
    pub fn to_matrix(&self) -> Result<SparseMatrix, LinalgError> {
        self.check_indices()?;
        let nnz_raw = self.len();
        let mut start = vec![0usize; self.n_cols + 1];
        for &c in &self.cols {
            start[c as usize + 1] += 1;
        }
        for j in 0..self.n_cols {
            start[j + 1] += start[j];
        }
        let mut next = start.clone();
        let mut entries = vec![(0u32, 0.0f64); nnz_raw];
        for k in 0..nnz_raw {
            let c = self.cols[k] as usize;
            entries[next[c]] = (self.rows[k], self.vals[k]);
            next[c] += 1;
        }
        let mut col_ptr = Vec::with_capacity(self.n_cols + 1);
        let mut row_idx = Vec::with_capacity(nnz_raw);
        let mut val = Vec::with_capacity(nnz_raw);
        col_ptr.push(0usize);
        for j in 0..self.n_cols {
            let seg = &mut entries[start[j]..start[j + 1]];
            seg.sort_unstable_by_key(|e| e.0);
            for &(r, v) in seg.iter() {
                if row_idx.len() > col_ptr[j] && *row_idx.last().unwrap_or(&usize::MAX) == r as usize {
                    *val.last_mut().expect("an entry was pushed") += v;
                } else {
                    row_idx.push(r as usize);
                    val.push(v);
                }
            }
            col_ptr.push(row_idx.len());
        }
        let symbolic = SymbolicSparseColMat::new_checked(self.n_rows, self.n_cols, col_ptr, None, row_idx);
        Ok(SparseMatrix::new(symbolic, val))
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
            return Err(LinalgError::PatternMismatch { expected: self.n_triplets, got: values.len() });
        }
        SparseMatrix::new_from_argsort(self.symbolic.clone(), &self.argsort, values)
            .map_err(|e| LinalgError::Internal(format!("{e:?}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counting_sort_assembly_matches_the_pattern_path() {
        let mut t = Triplets::new(7, 5);
        let mut x = 12345u64;
        for _ in 0..200 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let (r, c) = ((x >> 33) as usize % 7, (x >> 45) as usize % 5);
            t.push(r, c, ((x >> 20) % 1000) as f64 / 7.0);
        }
        let a = t.to_matrix().unwrap().to_dense();
        let b = t.pattern().unwrap().matrix(t.values()).unwrap().to_dense();
        for i in 0..7 {
            for j in 0..5 {
                assert!((a[(i, j)] - b[(i, j)]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn duplicates_are_summed_and_pattern_reused() {
        let mut t = Triplets::new(2, 2);
        t.push(0, 0, 1.0);
        t.push(1, 1, 2.0);
        t.push(0, 0, 3.0);
        t.push(1, 0, -1.0);
        let m = t.to_matrix().unwrap();
        let d = m.to_dense();
        assert_eq!((d[(0, 0)], d[(1, 1)], d[(1, 0)], d[(0, 1)]), (4.0, 2.0, -1.0, 0.0));
        let p = t.pattern().unwrap();
        let m2 = p.matrix(&[1.0, 1.0, 1.0, 1.0]).unwrap().to_dense();
        assert_eq!(m2[(0, 0)], 2.0);
        assert!(matches!(p.matrix(&[1.0]), Err(LinalgError::PatternMismatch { .. })));
        let mut bad = Triplets::new(2, 2);
        bad.push(2, 0, 1.0);
        assert!(matches!(bad.to_matrix(), Err(LinalgError::IndexOutOfRange { row: 2, .. })));
    }
}
