//! Sparse Cholesky (LLᵀ) that always uses faer's supernodal kernel, with the
//! symbolic analysis (AMD ordering, elimination tree, supernodes) done once
//! and reused by every numeric refactorization.
//!
//! Why a second Cholesky wrapper: faer's high-level `Llt` picks the
//! simplicial kernel when its flop-ratio heuristic says so. On the
//! Crouzeix–Raviart Newton systems of the crossfield (2×2 blocks, ~10
//! nonzeros per row) it chose the simplicial kernel, an order of magnitude
//! slower than the supernodal one there (`docs/decisions.md`). The
//! mid-level API lets us force the
//! supernodal variant; the numeric buffers are kept across refactorizations.
//!
//! Ordering: AMD (faer's default) or METIS nested dissection on the graph of
//! `b×b` blocks ([`super::ordering`]); the latter is the better one for the
//! large 2D systems of surface meshes (measured in [`crate::crossfield::newton`]).
//! The permutation is applied once, to the pattern: the analysis and every
//! numeric factorization see `P A Pᵀ` with the identity ordering, and a
//! refactorization scatters the new values through a slot map instead of
//! running faer's general symmetric permutation each time (a visible part of
//! the crossfield's run time, as was analysing with the ordering once more:
//! `docs/decisions.md`).

use super::{LinalgError, SparseMatrix};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::SymbolicSparseColMat;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::{Conj, MatMut, Side};

/// Fill-reducing ordering of a [`SupernodalCholesky`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FillOrdering {
    /// Approximate minimum degree (faer).
    Amd,
    /// METIS nested dissection of the graph of blocks of this many
    /// consecutive unknowns (1 = scalar graph).
    NestedDissection { block: usize },
    /// A permutation (new → old) computed by the caller, who knows a
    /// smaller graph to order (the crossfield: the mesh vertices instead of
    /// its edges' unknowns).
    Given(Vec<usize>),
}

/// Supernodal sparse Cholesky of a symmetric positive definite matrix given
/// by its lower triangle; refactor with new values, same pattern.
pub struct SupernodalCholesky {
    /// Analysis of the permuted matrix `P A Pᵀ` (identity ordering).
    symbolic: SymbolicCholesky<usize>,
    /// The fill-reducing permutation (new → old), `None` for the identity.
    fwd: Option<Vec<usize>>,
    /// Lower pattern of `P A Pᵀ`, sorted by rows within each column.
    permuted: SymbolicSparseColMat<usize>,
    /// Per stored entry of `A`: its slot in `permuted` ([`NO_SLOT`]: upper triangle, ignored).
    slot: Vec<u32>,
    /// Values of `P A Pᵀ` (scattered from `A` at each factorization).
    permuted_values: Vec<f64>,
    l_values: Vec<f64>,
    work: MemBuffer,
    factored: bool,
    par: faer::Par,
    /// Solve buffers (permuted right-hand side, supernode gather/scatter).
    x: Vec<[f64; 1]>,
    tmp: Vec<[f64; 1]>,
}

impl std::fmt::Debug for SupernodalCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SupernodalCholesky")
            .field("n", &self.symbolic.nrows())
            .field("l_nnz", &self.l_values.len())
            .field("factored", &self.factored)
            .finish()
    }
}

/// Whether `perm` holds each of `0..n` once.
fn is_permutation(perm: &[usize], n: usize) -> bool {
    let mut seen = vec![false; n];
    perm.len() == n && perm.iter().all(|&p| p < n && !std::mem::replace(&mut seen[p], true))
}

impl SupernodalCholesky {
    /// Symbolic analysis of the pattern of `a` (lower triangle).
    ///
    /// # Errors
    /// [`LinalgError::Internal`] when the analysis fails (out of memory).
    pub fn analyze(a: &SparseMatrix) -> Result<Self, LinalgError> {
        Self::analyze_with(a, FillOrdering::Amd)
    }

    /// Symbolic analysis of the pattern of `a` (lower triangle) with the given ordering.
    ///
    /// # Errors
    /// [`LinalgError::Internal`] when the ordering or the analysis fails.
    pub fn analyze_with(a: &SparseMatrix, ordering: FillOrdering) -> Result<Self, LinalgError> {
        let internal = |e| LinalgError::Internal(format!("{e:?}"));
        let params = || CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        };
        // The fill-reducing ordering (new → old) ...
        let fwd = match ordering {
            FillOrdering::Amd => amd_ordering(a)?,
            FillOrdering::NestedDissection { block } => super::ordering::nested_dissection(a.symbolic(), block)?,
            FillOrdering::Given(perm) => {
                if !is_permutation(&perm, a.nrows()) {
                    return Err(LinalgError::Internal("the given ordering is not a permutation".into()));
                }
                perm
            }
        };
        let fwd = (!fwd.iter().enumerate().all(|(i, &p)| i == p)).then_some(fwd);
        // ... is applied once to the pattern, and the factorization analyses
        // the permuted matrix with the identity ordering: a numeric
        // factorization is then a scatter of the values instead of faer's
        // general symmetric permutation (see the module doc).
        let (permuted, slot) = permuted_pattern(a, fwd.as_deref(), Side::Lower)?;
        // (faer's analysis reads the upper triangle when the ordering is the identity.)
        let (upper, _) = permuted_pattern(a, fwd.as_deref(), Side::Upper)?;
        let symbolic = factorize_symbolic_cholesky(upper.as_ref(), Side::Upper, SymmetricOrdering::Identity, params())
            .map_err(internal)?;
        let par = faer::Par::Seq;
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let work = MemBuffer::try_new(req).map_err(|e| LinalgError::Internal(format!("{e:?}")))?;
        Ok(Self {
            l_values: vec![0.0; symbolic.len_val()],
            permuted_values: vec![0.0; permuted.row_idx().len()],
            symbolic,
            fwd,
            permuted,
            slot,
            work,
            factored: false,
            par: faer::Par::Seq,
            x: Vec::new(),
            tmp: Vec::new(),
        })
    }

    /// Parallelism of the dense kernels inside the supernodes (factor and
    /// solve); sequential by default. The workspace is reallocated for
    /// `par`; if that allocation fails the setting is left unchanged.
    pub fn set_parallelism(&mut self, par: faer::Par) {
        let req = self
            .symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(self.symbolic.solve_in_place_scratch::<f64>(1, par));
        if let Ok(work) = MemBuffer::try_new(req) {
            self.work = work;
            self.par = par;
        }
    }

    /// Stored entries of the factor `L`.
    pub fn l_nnz(&self) -> usize {
        self.l_values.len()
    }

    /// Numeric factorization of `a` (same pattern as analysed).
    ///
    /// # Errors
    /// [`LinalgError::Singular`] when `a` is not positive definite,
    /// [`LinalgError::DimensionMismatch`] for a matrix of another size.
    pub fn factor(&mut self, a: &SparseMatrix) -> Result<(), LinalgError> {
        if a.nrows() != self.symbolic.nrows() {
            return Err(LinalgError::DimensionMismatch { expected: self.symbolic.nrows(), got: a.nrows() });
        }
        if a.val().len() != self.slot.len() {
            return Err(LinalgError::Internal(format!(
                "pattern changed since the analysis: {} stored entries, {} analysed",
                a.val().len(),
                self.slot.len()
            )));
        }
        self.factored = false;
        for (&k, &v) in self.slot.iter().zip(a.val()) {
            if k != NO_SLOT {
                self.permuted_values[k as usize] = v;
            }
        }
        let b = faer::sparse::SparseColMatRef::new(self.permuted.as_ref(), &self.permuted_values);
        let par = self.par;
        self.symbolic
            .factorize_numeric_llt::<f64>(
                &mut self.l_values,
                b,
                Side::Lower,
                LltRegularization::default(),
                par,
                MemStack::new(&mut self.work),
                Default::default(),
            )
            .map_err(|_| LinalgError::Singular { kind: "Cholesky" })?;
        self.factored = true;
        Ok(())
    }

    /// Solve `A x = b` in place with the last factorization.
    ///
    /// # Errors
    /// [`LinalgError::DimensionMismatch`] for a wrong length,
    /// [`LinalgError::Singular`] when the last factorization failed.
    pub fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinalgError> {
        let n = self.symbolic.nrows();
        if b.len() != n {
            return Err(LinalgError::DimensionMismatch { expected: n, got: b.len() });
        }
        if !self.factored {
            return Err(LinalgError::Singular { kind: "Cholesky" });
        }
        if let SymbolicCholeskyRaw::Supernodal(sym) = self.symbolic.raw() {
            // A plain loop over the supernodes ([`super::trisolve`]), in
            // buffers kept across solves.
            let x = &mut self.x;
            x.clear();
            match &self.fwd {
                Some(p) => x.extend(p.iter().map(|&f| [b[f]])),
                None => x.extend(b.iter().map(|&v| [v])),
            }
            super::trisolve::llt_solve_interleaved(sym, &self.l_values, x, &mut self.tmp);
            match &self.fwd {
                Some(p) => {
                    for (&[xi], &f) in x.iter().zip(p) {
                        b[f] = xi;
                    }
                }
                None => {
                    for (bi, &[xi]) in b.iter_mut().zip(x.iter()) {
                        *bi = xi;
                    }
                }
            }
            return Ok(());
        }
        let par = self.par;
        let mut y: Vec<f64> = match &self.fwd {
            Some(p) => p.iter().map(|&f| b[f]).collect(),
            None => b.to_vec(),
        };
        let rhs = MatMut::from_column_major_slice_mut(&mut y, n, 1);
        LltRef::new(&self.symbolic, &self.l_values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            par,
            MemStack::new(&mut self.work),
        );
        match &self.fwd {
            Some(p) => p.iter().zip(&y).for_each(|(&f, &v)| b[f] = v),
            None => b.copy_from_slice(&y),
        }
        Ok(())
    }

    /// Solve `A Y = X` for `K` right-hand sides stored interleaved
    /// (`x[i][k]` = row `i` of column `k`), in place, with the last
    /// factorization. Takes `&self`, so one factor serves concurrent
    /// preconditioner applications; see [`super::trisolve`] for why this
    /// beats faer's solve on mesh Laplacians.
    ///
    /// # Errors
    /// [`LinalgError::DimensionMismatch`] for a wrong length,
    /// [`LinalgError::Singular`] when the last factorization failed.
    pub fn solve_interleaved<const K: usize>(&self, x: &mut [[f64; K]]) -> Result<(), LinalgError> {
        let n = self.symbolic.nrows();
        if x.len() != n {
            return Err(LinalgError::DimensionMismatch { expected: n, got: x.len() });
        }
        if !self.factored {
            return Err(LinalgError::Singular { kind: "Cholesky" });
        }
        let SymbolicCholeskyRaw::Supernodal(sn) = self.symbolic.raw() else {
            return Err(LinalgError::Internal("factor is not supernodal".into()));
        };
        match &self.fwd {
            Some(fwd) => {
                let mut y: Vec<[f64; K]> = fwd.iter().map(|&old| x[old]).collect();
                super::trisolve::llt_solve_interleaved(sn, &self.l_values, &mut y, &mut Vec::new());
                for (&old, yi) in fwd.iter().zip(&y) {
                    x[old] = *yi;
                }
            }
            None => super::trisolve::llt_solve_interleaved(sn, &self.l_values, x, &mut Vec::new()),
        }
        Ok(())
    }
}

/// faer's approximate minimum degree ordering (new → old) of the pattern of `a`.
fn amd_ordering(a: &SparseMatrix) -> Result<Vec<usize>, LinalgError> {
    let n = a.nrows();
    let nnz = a.symbolic().compute_nnz();
    let mut work = MemBuffer::try_new(faer::sparse::linalg::amd::order_maybe_unsorted_scratch::<usize>(n, nnz))
        .map_err(|e| LinalgError::Internal(format!("{e:?}")))?;
    let (mut fwd, mut inv) = (vec![0usize; n], vec![0usize; n]);
    faer::sparse::linalg::amd::order_maybe_unsorted(
        &mut fwd,
        &mut inv,
        a.symbolic(),
        Default::default(),
        MemStack::new(&mut work),
    )
    .map_err(|e| LinalgError::Internal(format!("{e:?}")))?;
    Ok(fwd)
}

/// No slot: an entry of the upper triangle (ignored, as by faer with [`Side::Lower`]).
const NO_SLOT: u32 = u32::MAX;

/// Lower (or upper) pattern of `P A Pᵀ` (`fwd`: new → old; `None` =
/// identity) from the lower triangle of `A`, rows sorted within columns,
/// and the slot of each stored entry of `A` in it.
fn permuted_pattern(
    a: &SparseMatrix,
    fwd: Option<&[usize]>,
    side: Side,
) -> Result<(SymbolicSparseColMat<usize>, Vec<u32>), LinalgError> {
    let n = a.nrows();
    let inv = fwd.map(super::ordering::inverse_permutation);
    let new = |i: usize| inv.as_ref().map_or(i, |q| q[i]);
    let (cp, ri) = (a.symbolic().col_ptr(), a.symbolic().row_idx());
    let nnz = ri.len();
    if nnz >= NO_SLOT as usize || a.symbolic().col_nnz().is_some() || cp[n] != nnz {
        return Err(LinalgError::Internal("matrix too large or not compressed for the supernodal Cholesky".into()));
    }
    // (new column, new row, entry of A) of the lower entries, bucketed by column.
    let mut count = vec![0usize; n + 1];
    let mut entries: Vec<(usize, usize, u32)> = Vec::with_capacity(nnz);
    for j in 0..n {
        for (k, &i) in ri.iter().enumerate().take(cp[j + 1]).skip(cp[j]) {
            if i >= j {
                let (pi, pj) = (new(i), new(j));
                let (r, c) = match side {
                    Side::Lower => (pi.max(pj), pi.min(pj)),
                    Side::Upper => (pi.min(pj), pi.max(pj)),
                };
                count[c + 1] += 1;
                entries.push((c, r, k as u32));
            }
        }
    }
    for c in 0..n {
        count[c + 1] += count[c];
    }
    let col_ptr = count.clone();
    let mut next = count;
    let mut rows = vec![(0usize, 0u32); entries.len()];
    for &(c, r, k) in &entries {
        rows[next[c]] = (r, k);
        next[c] += 1;
    }
    drop(entries);
    for c in 0..n {
        rows[col_ptr[c]..col_ptr[c + 1]].sort_unstable();
    }
    let mut slot = vec![NO_SLOT; nnz];
    for (s, &(_, k)) in rows.iter().enumerate() {
        slot[k as usize] = s as u32;
    }
    let row_idx: Vec<usize> = rows.into_iter().map(|(r, _)| r).collect();
    let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
    Ok((pattern, slot))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::Triplets;

    #[test]
    fn factors_refactors_and_rejects_indefinite() {
        let n = 30;
        let lap = |shift: f64| {
            let mut t = Triplets::new(n, n);
            for i in 0..n {
                t.push(i, i, 2.0 + shift);
                if i > 0 {
                    t.push(i, i - 1, -1.0);
                }
            }
            t.to_matrix().unwrap()
        };
        let mut s = SupernodalCholesky::analyze(&lap(0.0)).unwrap();
        for shift in [0.0, 1.0] {
            s.factor(&lap(shift)).unwrap();
            let mut x = vec![1.0; n];
            s.solve_in_place(&mut x).unwrap();
            // Check A x = 1 with the full symmetric matrix.
            for i in 0..n {
                let mut r = (2.0 + shift) * x[i];
                if i > 0 {
                    r -= x[i - 1];
                }
                if i + 1 < n {
                    r -= x[i + 1];
                }
                assert!((r - 1.0).abs() < 1e-10);
            }
        }
        // The interleaved solve agrees with faer's, column by column.
        let mut cols: Vec<[f64; 2]> = (0..n).map(|i| [1.0, (i as f64).sin()]).collect();
        s.solve_interleaved(&mut cols).unwrap();
        for k in 0..2 {
            let mut x: Vec<f64> = (0..n).map(|i| if k == 0 { 1.0 } else { (i as f64).sin() }).collect();
            s.solve_in_place(&mut x).unwrap();
            for i in 0..n {
                assert!((x[i] - cols[i][k]).abs() < 1e-12 * (1.0 + x[i].abs()));
            }
        }
        // The hand-written supernodal solve agrees with faer's, with either ordering.
        let grid = |k: usize| {
            let id = |i: usize, j: usize| i * k + j;
            let mut t = Triplets::new(k * k, k * k);
            for i in 0..k {
                for j in 0..k {
                    t.push(id(i, j), id(i, j), 4.01);
                    if i + 1 < k {
                        t.push(id(i + 1, j), id(i, j), -1.0);
                    }
                    if j + 1 < k {
                        t.push(id(i, j + 1), id(i, j), -1.0);
                    }
                }
            }
            t.to_matrix().unwrap()
        };
        let g = grid(40);
        for ord in [
            FillOrdering::Amd,
            FillOrdering::NestedDissection { block: 1 },
            FillOrdering::Given((0..1600).rev().collect()),
        ] {
            let mut c = SupernodalCholesky::analyze_with(&g, ord.clone()).unwrap();
            c.factor(&g).unwrap();
            let b: Vec<f64> = (0..g.nrows()).map(|i| ((i * 7) % 13) as f64 - 6.0).collect();
            let mut x = b.clone();
            c.solve_in_place(&mut x).unwrap();
            // faer's solve works in the factor's ordering.
            let fwd: Vec<usize> = c.fwd.clone().unwrap_or_else(|| (0..g.nrows()).collect());
            let mut yp: Vec<f64> = fwd.iter().map(|&f| b[f]).collect();
            LltRef::new(&c.symbolic, &c.l_values).solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(&mut yp, g.nrows(), 1),
                faer::Par::Seq,
                MemStack::new(&mut c.work),
            );
            let mut y = vec![0.0; g.nrows()];
            fwd.iter().zip(&yp).for_each(|(&f, &v)| y[f] = v);
            let err = x.iter().zip(&y).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(err < 1e-12, "{ord:?}: {err}");
            // Two interleaved columns give the same as one at a time.
            let mut both: Vec<[f64; 2]> = b.iter().map(|&v| [v, 2.0 * v]).collect();
            c.solve_interleaved(&mut both).unwrap();
            assert!(both.iter().zip(&x).all(|(p, q)| (p[0] - q).abs() < 1e-12 && (p[1] - 2.0 * q).abs() < 1e-12));
        }
        assert!(s.factor(&lap(-3.0)).is_err());
        assert!(s.solve_interleaved(&mut cols).is_err());
        let mut x = vec![1.0; n];
        assert!(s.solve_in_place(&mut x).is_err());
        assert!(s.solve_in_place(&mut [1.0]).is_err());
    }
}
