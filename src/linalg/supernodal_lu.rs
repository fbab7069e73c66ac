//! Supernodal LU factorization without pivoting of a non-symmetric matrix
//! whose sparsity pattern is symmetric, on the structure of the Cholesky
//! factor of that pattern; one factorization, any number of right-hand
//! sides (solved `K` at a time, interleaved).
//!
//! What it is for: the mean value systems of the atlas (thesis eq. 2.4).
//! Their matrix `A` (row `i`: `Σ_j λ_ij (u_i − u_j)` with positive weights)
//! is non-symmetric, but its pattern is the mesh graph, hence symmetric, and
//! it is a row diagonally dominant M-matrix (irreducibly so once the outer
//! loop is fixed). Gaussian elimination without pivoting is then stable:
//! every Schur complement stays row diagonally dominant, so the pivots stay
//! positive and the growth factor is at most 2 (Wilkinson). Without pivoting,
//! `L` and `Uᵀ` both have the structure of the Cholesky factor of the
//! pattern, so faer's supernodal symbolic analysis (AMD ordering,
//! supernodes, row patterns) serves both, and the solve is two triangular
//! sweeps instead of the tens of preconditioner applications of a Krylov
//! method (measured in [`crate::atlas::mvc`]). faer's general LU pivots by
//! rows and orders columns with COLAMD; it was several times slower on these
//! systems (`docs/decisions.md`).
//!
//! Layout. Supernode `s` owns columns `c0..c0+nc` and the off-diagonal rows
//! `p` (`np` of them, sorted). `lu` holds, like faer's Cholesky values, a
//! column-major `(nc + np) × nc` block per supernode: rows `0..nc` the
//! diagonal block with `L` strictly below the diagonal (unit diagonal
//! implied) and `U` on and above it, rows `nc..` the rows `p` of `L`. `ut`
//! holds a column-major `np × nc` block per supernode: `U[c0 + c, p[r]]` at
//! `(r, c)`, i.e. the off-diagonal columns of `U` transposed.
//!
//! The numeric phase is right-looking: when supernode `s` is factored, its
//! Schur update `L[p, s] U[s, p]` is computed as one dense `np × np` block
//! and subtracted, entry by entry, from the supernodes that own the columns
//! (for `L`) or rows (for `U`) of `p`; the symbolic fill guarantees that
//! those supernodes store every position.

use super::{LinalgError, LuSolver, SparseMatrix, Triplets};
use faer::Side;
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_unit_lower_triangular_in_place;
use faer::prelude::{IntoConst, Reborrow, ReborrowMut};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::{Accum, MatMut, MatRef, Par};

/// Below this many multiply-adds a Schur product is done by plain loops
/// (faer's matrix product has a fixed setup cost that dominates tiny blocks).
const SMALL_PRODUCT: usize = 2048;

/// Pivot magnitudes below this fraction of the largest diagonal entry of
/// `A` are treated as zero: the matrix is then not one this factorization is
/// safe for (not diagonally dominant), and the caller must pivot.
const PIVOT_TOLERANCE: f64 = 1e-13;

/// A supernodal LU factorization `P A Pᵀ = L U` (no pivoting, `P` the
/// fill-reducing ordering of the symmetric pattern).
pub struct SupernodalLu<T: LuScalar = f64> {
    symbolic: SymbolicCholesky<usize>,
    lu: Vec<T>,
    ut: Vec<T>,
    ut_ptr: Vec<usize>,
    /// faer's pivoted LU, for the patterns faer will not analyse as supernodal.
    fallback: Option<LuSolver>,
}

impl<T: LuScalar> std::fmt::Debug for SupernodalLu<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SupernodalLu").field("n", &self.symbolic.nrows()).field("nnz", &self.nnz()).finish()
    }
}

impl<T: LuScalar> SupernodalLu<T> {
    /// Analyse the symmetrized pattern of `a` (AMD) and factor `a`.
    ///
    /// # Errors
    /// [`LinalgError::Singular`] when a pivot vanishes (the matrix needs
    /// pivoting), [`LinalgError::Internal`] when the analysis fails,
    /// [`LinalgError::DimensionMismatch`] for a non-square matrix.
    pub fn factor(a: &SparseMatrix) -> Result<Self, LinalgError> {
        if a.nrows() != a.ncols() {
            return Err(LinalgError::DimensionMismatch { expected: a.nrows(), got: a.ncols() });
        }
        let symbolic = supernodal_amd_analysis(&symmetric_lower_pattern(a)?)?;
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            // faer keeps a factor without any elimination work (a diagonal
            // matrix) simplicial even when told otherwise.
            return Ok(Self {
                symbolic,
                lu: Vec::new(),
                ut: Vec::new(),
                ut_ptr: Vec::new(),
                fallback: Some(LuSolver::new(a)?),
            });
        };
        let mut ut_ptr = Vec::with_capacity(sn.n_supernodes() + 1);
        ut_ptr.push(0);
        for s in 0..sn.n_supernodes() {
            let nc = sn.supernode_end()[s] - sn.supernode_begin()[s];
            ut_ptr.push(ut_ptr[s] + nc * sn.supernode(s).pattern().len());
        }
        let mut this = Self {
            lu: vec![T::zero(); symbolic.len_val()],
            ut: vec![T::zero(); ut_ptr[sn.n_supernodes()]],
            ut_ptr,
            symbolic,
            fallback: None,
        };
        this.numeric(a)?;
        Ok(this)
    }

    /// Stored entries of `L` and `U` together.
    pub fn nnz(&self) -> usize {
        self.lu.len() + self.ut.len()
    }

    /// The supernodal structure.
    fn structure(&self) -> &SymbolicSupernodalCholesky<usize> {
        structure_of(&self.symbolic)
    }

    /// Numeric factorization: scatter `P A Pᵀ` into the blocks, then factor
    /// the supernodes in order, each pushing its Schur update to later ones.
    fn numeric(&mut self, a: &SparseMatrix) -> Result<(), LinalgError> {
        let inv: Vec<usize> = match self.symbolic.perm() {
            Some(p) => p.arrays().1.to_vec(),
            None => (0..a.nrows()).collect(),
        };
        let owner = self.owners();
        self.scatter_matrix(a, &inv, &owner);
        let max_diag = (0..a.ncols())
            .flat_map(|j| {
                let (rows, vals) = (a.row_idx_of_col_raw(j), a.val_of_col(j));
                rows.iter().zip(vals).filter(move |(i, _)| **i == j).map(|(_, v)| v.abs())
            })
            .fold(0.0f64, f64::max);
        let tiny = T::from_f64(PIVOT_TOLERANCE * max_diag.max(f64::MIN_POSITIVE));
        let n_super = self.structure().n_supernodes();
        let mut schur = Vec::new();
        let mut loc = Vec::new();
        for s in 0..n_super {
            self.factor_supernode(s, tiny)?;
            self.push_schur_update(s, &owner, &mut schur, &mut loc);
        }
        Ok(())
    }

    /// Supernode owning each (permuted) column.
    fn owners(&self) -> Vec<u32> {
        let sn = self.structure();
        let mut owner = vec![0u32; self.symbolic.nrows()];
        for s in 0..sn.n_supernodes() {
            owner[sn.supernode_begin()[s]..sn.supernode_end()[s]].fill(s as u32);
        }
        owner
    }

    /// Add the entries of `P A Pᵀ` to the `L` and `U` blocks (zeroed first).
    fn scatter_matrix(&mut self, a: &SparseMatrix, inv: &[usize], owner: &[u32]) {
        self.lu.fill(T::zero());
        self.ut.fill(T::zero());
        for j in 0..a.ncols() {
            let pj = inv[j];
            for (&i, &v) in a.row_idx_of_col_raw(j).iter().zip(a.val_of_col(j)) {
                let pi = inv[i];
                let (lo, hi) = (pi.min(pj), pi.max(pj));
                let t = owner[lo] as usize;
                let slot = self.slot(t, lo, hi, pi >= pj);
                *slot += T::from_f64(v);
            }
        }
    }

    /// The stored position of entry `(row, col)` of `L` (`lower`, `row ≥
    /// col`) or `(col, row)` of `U`: `lo = min`, `hi = max` of the two, `t`
    /// the supernode owning column `lo`.
    fn slot(&mut self, t: usize, lo: usize, hi: usize, lower: bool) -> &mut T {
        let sn = structure_of(&self.symbolic);
        let (c0, c1) = (sn.supernode_begin()[t], sn.supernode_end()[t]);
        let nc = c1 - c0;
        let pattern = sn.supernode(t).pattern();
        let ld = nc + pattern.len();
        let base = sn.col_ptr_for_val()[t];
        let c = lo - c0;
        if hi < c1 {
            // Diagonal block: L below (column lo), U above (column hi).
            let (row, col) = if lower { (hi - c0, c) } else { (c, hi - c0) };
            return &mut self.lu[base + col * ld + row];
        }
        let r = pattern.partition_point(|&x| x < hi);
        debug_assert_eq!(pattern[r], hi, "entry outside the symbolic structure");
        if lower { &mut self.lu[base + c * ld + nc + r] } else { &mut self.ut[self.ut_ptr[t] + c * pattern.len() + r] }
    }

    /// Factor supernode `s` in place (its Schur updates from earlier
    /// supernodes already applied): dense LU of the diagonal block, then
    /// `L[p, s] ← L[p, s] U_ss⁻¹` and `U[s, p] ← L_ss⁻¹ U[s, p]`.
    fn factor_supernode(&mut self, s: usize, tiny: T) -> Result<(), LinalgError> {
        let sn = structure_of(&self.symbolic);
        let nc = sn.supernode_end()[s] - sn.supernode_begin()[s];
        let np = sn.supernode(s).pattern().len();
        let blk = &mut self.lu[sn.col_ptr_for_val()[s]..sn.col_ptr_for_val()[s + 1]];
        let ut = &mut self.ut[self.ut_ptr[s]..self.ut_ptr[s + 1]];
        dense_lu_no_pivoting(blk, nc + np, nc, ut, np, tiny)
    }

    /// Subtract the Schur update `L[p, s] U[s, p]` of supernode `s` from the
    /// supernodes owning the rows and columns of `p`.
    fn push_schur_update(&mut self, s: usize, owner: &[u32], schur: &mut Vec<T>, loc: &mut Vec<usize>) {
        let sn = structure_of(&self.symbolic);
        let nc = sn.supernode_end()[s] - sn.supernode_begin()[s];
        let p = sn.supernode(s).pattern();
        let np = p.len();
        if np == 0 {
            return;
        }
        let ld = nc + np;
        let vp = sn.col_ptr_for_val();
        schur_product(&self.lu[vp[s] + nc..vp[s + 1]], ld, &self.ut[self.ut_ptr[s]..self.ut_ptr[s + 1]], np, nc, schur);
        // The rows of p owned by one supernode t are consecutive.
        let mut g0 = 0;
        while g0 < np {
            let t = owner[p[g0]] as usize;
            let (c0, c1) = (sn.supernode_begin()[t], sn.supernode_end()[t]);
            let g1 = g0 + p[g0..].partition_point(|&r| r < c1);
            let pt = sn.supernode(t).pattern();
            local_rows(&p[g0..], g1 - g0, c0, c1 - c0, pt, loc);
            let target = Target {
                blk: &mut self.lu[vp[t]..vp[t + 1]],
                ut: &mut self.ut[self.ut_ptr[t]..self.ut_ptr[t + 1]],
                nc: c1 - c0,
                np: pt.len(),
            };
            subtract_schur_block(target, schur, np, g0, g1, &p[g0..g1], c0, loc);
            g0 = g1;
        }
    }

    /// Solve `A y = x` for the `K` interleaved columns of `x`, in place.
    ///
    /// # Errors
    /// [`LinalgError::DimensionMismatch`] for a wrong length.
    pub fn solve_interleaved<const K: usize>(&self, x: &mut [[f64; K]]) -> Result<(), LinalgError> {
        let n = self.symbolic.nrows();
        if x.len() != n {
            return Err(LinalgError::DimensionMismatch { expected: n, got: x.len() });
        }
        if let Some(lu) = &self.fallback {
            let mut cols: Vec<Vec<f64>> = (0..K).map(|k| x.iter().map(|v| v[k]).collect()).collect();
            lu.solve_columns(&mut cols)?;
            for (i, xi) in x.iter_mut().enumerate() {
                for k in 0..K {
                    xi[k] = cols[k][i];
                }
            }
            return Ok(());
        }
        let Some(perm) = self.symbolic.perm() else {
            let mut tmp = Vec::new();
            self.forward(x, &mut tmp);
            self.backward(x, &mut tmp);
            return Ok(());
        };
        let (fwd, _) = perm.arrays();
        let mut y: Vec<[f64; K]> = fwd.iter().map(|&old| x[old]).collect();
        let mut tmp = Vec::new();
        self.forward(&mut y, &mut tmp);
        self.backward(&mut y, &mut tmp);
        for (&old, yi) in fwd.iter().zip(&y) {
            x[old] = *yi;
        }
        Ok(())
    }

    /// `L y = x` (unit lower triangular), supernode by supernode; the
    /// updates of the off-diagonal rows are summed in `tmp` and applied once.
    fn forward<const K: usize>(&self, x: &mut [[f64; K]], tmp: &mut Vec<[f64; K]>) {
        let sn = self.structure();
        let vp = sn.col_ptr_for_val();
        for s in 0..sn.n_supernodes() {
            let start = sn.supernode_begin()[s];
            let nc = sn.supernode_end()[s] - start;
            let p = sn.supernode(s).pattern();
            let ld = nc + p.len();
            let blk = &self.lu[vp[s]..vp[s + 1]];
            tmp.clear();
            tmp.resize(p.len(), [0.0; K]);
            for c in 0..nc {
                let col = &blk[c * ld..(c + 1) * ld];
                let xc = x[start + c];
                for r in c + 1..nc {
                    let (l, xr) = (col[r].to_f64(), &mut x[start + r]);
                    for k in 0..K {
                        xr[k] -= l * xc[k];
                    }
                }
                for (t, &l) in tmp.iter_mut().zip(&col[nc..]) {
                    let l = l.to_f64();
                    for k in 0..K {
                        t[k] += l * xc[k];
                    }
                }
            }
            for (&r, t) in p.iter().zip(tmp.iter()) {
                for k in 0..K {
                    x[r][k] -= t[k];
                }
            }
        }
    }

    /// `U y = x` (upper triangular), supernodes in reverse: the off-diagonal
    /// rows are gathered once, then the diagonal block is solved by columns.
    fn backward<const K: usize>(&self, x: &mut [[f64; K]], tmp: &mut Vec<[f64; K]>) {
        let sn = self.structure();
        let vp = sn.col_ptr_for_val();
        for s in (0..sn.n_supernodes()).rev() {
            let start = sn.supernode_begin()[s];
            let nc = sn.supernode_end()[s] - start;
            let p = sn.supernode(s).pattern();
            let np = p.len();
            let ld = nc + np;
            let blk = &self.lu[vp[s]..vp[s + 1]];
            let ut = &self.ut[self.ut_ptr[s]..self.ut_ptr[s + 1]];
            tmp.clear();
            tmp.extend(p.iter().map(|&r| x[r]));
            for c in 0..nc {
                let mut acc = [0.0; K];
                for (&u, xr) in ut[c * np..(c + 1) * np].iter().zip(tmp.iter()) {
                    let u = u.to_f64();
                    for k in 0..K {
                        acc[k] += u * xr[k];
                    }
                }
                for k in 0..K {
                    x[start + c][k] -= acc[k];
                }
            }
            for c in (0..nc).rev() {
                let col = &blk[c * ld..c * ld + nc];
                let mut xc = x[start + c];
                let d = col[c].to_f64();
                for v in &mut xc {
                    *v /= d;
                }
                x[start + c] = xc;
                for r in 0..c {
                    let u = col[r].to_f64();
                    for k in 0..K {
                        x[start + r][k] -= u * xc[k];
                    }
                }
            }
        }
    }
}

/// Storage and arithmetic of a [`SupernodalLu`]: `f64`, or `f32` for half
/// the memory and twice the vector width when the factor only has to be a
/// preconditioner (a few Krylov steps in `f64` recover full accuracy).
pub trait LuScalar:
    faer::traits::ComplexField
    + Copy
    + PartialOrd
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::AddAssign
    + std::ops::SubAssign
    + std::ops::MulAssign
    + Send
    + Sync
    + 'static
{
    /// Rounded from `f64`.
    fn from_f64(x: f64) -> Self;
    /// Widened to `f64`.
    fn to_f64(self) -> f64;
    /// `|x|`.
    fn abs_value(self) -> Self;
    /// 0.
    fn zero() -> Self {
        Self::from_f64(0.0)
    }
    /// 1.
    fn one() -> Self {
        Self::from_f64(1.0)
    }
}

impl LuScalar for f64 {
    fn from_f64(x: f64) -> Self {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn abs_value(self) -> Self {
        self.abs()
    }
}

impl LuScalar for f32 {
    fn from_f64(x: f64) -> Self {
        x as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn abs_value(self) -> Self {
        self.abs()
    }
}

/// The `L` and `Uᵀ` blocks of the supernode receiving a Schur update.
struct Target<'a, T> {
    blk: &'a mut [T],
    ut: &'a mut [T],
    nc: usize,
    np: usize,
}

/// Local rows, in the receiving supernode (its `nc` columns from `c0`, then
/// its `pattern`), of `rows`, whose first `n_own` are among its columns and
/// the rest in its pattern (both sorted): a merge, no search.
fn local_rows(rows: &[usize], n_own: usize, c0: usize, nc: usize, pattern: &[usize], loc: &mut Vec<usize>) {
    loc.clear();
    loc.extend(rows[..n_own].iter().map(|&r| r - c0));
    let mut k = 0;
    for &r in &rows[n_own..] {
        while pattern[k] < r {
            k += 1;
        }
        loc.push(nc + k);
    }
}

/// Subtract from supernode `t` (its columns are `own = p[g0..g1]`, first
/// column `c0`) the entries of the dense `np × np` Schur block whose column
/// (for `L`) or row (for `U`) is one of its columns; `loc[a − g0]` is the
/// local row of `p[a]` in `t`.
#[allow(clippy::too_many_arguments)]
fn subtract_schur_block<T: LuScalar>(
    t: Target<'_, T>,
    schur: &[T],
    np: usize,
    g0: usize,
    g1: usize,
    own: &[usize],
    c0: usize,
    loc: &[usize],
) {
    let ld = t.nc + t.np;
    for (b, &col_b) in (g0..g1).zip(own) {
        let cb = col_b - c0;
        // L part: column p[b], rows p[a], a ≥ b.
        let col = &mut t.blk[cb * ld..(cb + 1) * ld];
        for (a, &v) in schur[b * np..(b + 1) * np].iter().enumerate().skip(b) {
            col[loc[a - g0]] -= v;
        }
        // U part: row p[b], columns p[a], a > b.
        for a in b + 1..np {
            let la = loc[a - g0];
            let v = schur[a * np + b];
            if la < t.nc {
                t.blk[la * ld + cb] -= v;
            } else {
                t.ut[cb * t.np + la - t.nc] -= v;
            }
        }
    }
}

/// Columns per panel of the blocked dense LU.
const PANEL: usize = 32;

/// LU without pivoting of the `ld × nc` column-major block `m` (`nc × nc`
/// diagonal block on top, `ld − nc` rows of `L` below) together with the
/// `np × nc` transposed rows `y` of `U` right of the diagonal block.
/// Right-looking by panels of [`PANEL`] columns: each panel is eliminated
/// column by column, then the rest is updated with one triangular solve and
/// two matrix products (faer's kernels), so wide separator supernodes run at
/// matrix-product speed.
fn dense_lu_no_pivoting<T: LuScalar>(
    m: &mut [T],
    ld: usize,
    nc: usize,
    y: &mut [T],
    np: usize,
    tiny: T,
) -> Result<(), LinalgError> {
    let mut k0 = 0;
    while k0 < nc {
        let k1 = (k0 + PANEL).min(nc);
        eliminate_panel(m, ld, k0, k1, y, np, tiny)?;
        if k1 < nc {
            let bw = k1 - k0;
            let mat = MatMut::from_column_major_slice_with_stride_mut(m, ld, nc, ld);
            let (left, right) = mat.split_at_col_mut(k1);
            let left = left.into_const();
            let l11 = left.submatrix(k0, k0, bw, bw);
            let (top, a22) = right.split_at_row_mut(k1);
            let mut u12 = top.submatrix_mut(k0, 0, bw, nc - k1);
            solve_unit_lower_triangular_in_place(l11, u12.rb_mut(), Par::Seq);
            matmul(a22, Accum::Add, left.submatrix(k1, k0, ld - k1, bw), u12.rb(), T::from_f64(-1.0), Par::Seq);
            if np > 0 {
                let ym = MatMut::from_column_major_slice_mut(y, np, nc);
                let (yl, yr) = ym.split_at_col_mut(k1);
                // The panel's rows of U are final ([`eliminate_panel`]).
                let yb = yl.into_const().subcols(k0, bw);
                let l_rows = left.submatrix(k1, k0, nc - k1, bw);
                matmul(yr, Accum::Add, yb, l_rows.transpose(), T::from_f64(-1.0), Par::Seq);
            }
        }
        k0 = k1;
    }
    Ok(())
}

/// Unblocked elimination of columns `k0..k1` of [`dense_lu_no_pivoting`]'s
/// block, updating only those columns (and the matching rows of `U` in `y`).
fn eliminate_panel<T: LuScalar>(
    m: &mut [T],
    ld: usize,
    k0: usize,
    k1: usize,
    y: &mut [T],
    np: usize,
    tiny: T,
) -> Result<(), LinalgError> {
    for k in k0..k1 {
        let pivot = m[k * ld + k];
        if !(pivot.abs_value() > tiny) {
            return Err(LinalgError::Singular { kind: "LU without pivoting" });
        }
        let inv = T::one() / pivot;
        // Column k of L (diagonal block and off-diagonal rows) ...
        for v in &mut m[k * ld + k + 1..(k + 1) * ld] {
            *v *= inv;
        }
        for j in k + 1..k1 {
            // ... eliminates row k of U from the later columns of the panel,
            let ukj = m[j * ld + k];
            if ukj != T::zero() {
                let (head, tail) = m.split_at_mut(j * ld);
                let lk = &head[k * ld + k + 1..(k + 1) * ld];
                for (x, &l) in tail[k + 1..ld].iter_mut().zip(lk) {
                    *x -= l * ukj;
                }
            }
            // ... and its off-diagonal part from the later rows of U.
            let ljk = m[k * ld + j];
            if ljk != T::zero() && np > 0 {
                let (head, tail) = y.split_at_mut(j * np);
                for (x, &u) in tail[..np].iter_mut().zip(&head[k * np..(k + 1) * np]) {
                    *x -= ljk * u;
                }
            }
        }
    }
    Ok(())
}

/// The supernodal structure of an analysis (always present: it is forced
/// by [`supernodal_amd_analysis`]).
fn structure_of(symbolic: &SymbolicCholesky<usize>) -> &SymbolicSupernodalCholesky<usize> {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(sn) => sn,
        SymbolicCholeskyRaw::Simplicial(_) => unreachable!("supernodal analysis forced"),
    }
}

/// `schur = L_p U_pᵀ` as a dense column-major `np × np` block, where `L_p`
/// is `np × nc` with column stride `ld` and `U_p` (the transposed
/// off-diagonal rows of `U`) is `np × nc` column-major: `schur[a + b np] =
/// Σ_k L_p[a, k] U_p[b, k]`, the update of entry `(p[a], p[b])`.
fn schur_product<T: LuScalar>(l: &[T], ld: usize, u: &[T], np: usize, nc: usize, schur: &mut Vec<T>) {
    schur.clear();
    schur.resize(np * np, T::zero());
    if np * np * nc < SMALL_PRODUCT {
        for k in 0..nc {
            let lk = &l[k * ld..k * ld + np];
            for (b, &ub) in u[k * np..(k + 1) * np].iter().enumerate() {
                if ub != T::zero() {
                    for (s, &la) in schur[b * np..(b + 1) * np].iter_mut().zip(lk) {
                        *s += la * ub;
                    }
                }
            }
        }
        return;
    }
    let lhs = MatRef::from_column_major_slice_with_stride(l, np, nc, ld);
    let rhs = MatRef::from_column_major_slice(u, np, nc).transpose();
    let dst = MatMut::from_column_major_slice_mut(schur, np, np);
    matmul(dst, Accum::Replace, lhs, rhs, T::one(), Par::Seq);
}

/// faer's supernodal symbolic Cholesky analysis (AMD ordering, elimination
/// tree, supernodes and their row patterns) of the lower triangle `a`; the
/// supernodal variant is forced (faer's heuristic may pick the simplicial
/// one, which has no supernodes to hold the LU's blocks).
///
/// # Errors
/// [`LinalgError::Internal`] when the analysis fails.
fn supernodal_amd_analysis(a: &SparseMatrix) -> Result<SymbolicCholesky<usize>, LinalgError> {
    factorize_symbolic_cholesky(
        a.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        },
    )
    .map_err(|e| LinalgError::Internal(format!("{e:?}")))
}

/// The lower triangle of the pattern of `A + Aᵀ` (values 1), the input of
/// the symbolic analysis.
fn symmetric_lower_pattern(a: &SparseMatrix) -> Result<SparseMatrix, LinalgError> {
    let n = a.nrows();
    let mut t = Triplets::with_capacity(n, n, a.compute_nnz());
    for j in 0..a.ncols() {
        for &i in a.row_idx_of_col_raw(j) {
            t.push(i.max(j), i.min(j), 1.0);
        }
    }
    t.to_matrix()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A non-symmetric, row diagonally dominant matrix on the graph of an
    /// `m × m` grid with diagonals (a mean-value-like M-matrix).
    fn grid_mvc(m: usize) -> SparseMatrix {
        let n = m * m;
        let id = |i: usize, j: usize| i * m + j;
        let mut t = Triplets::new(n, n);
        for i in 0..m {
            for j in 0..m {
                let row = id(i, j);
                let mut diag = 0.1;
                for (di, dj) in [(0i64, 1i64), (1, 0), (0, -1), (-1, 0), (1, 1), (-1, -1)] {
                    let (a, b) = (i as i64 + di, j as i64 + dj);
                    if a >= 0 && b >= 0 && (a as usize) < m && (b as usize) < m {
                        let w = 1.0 + ((row * 7 + (a as usize) * 3 + b as usize) % 5) as f64 * 0.3;
                        t.push(row, id(a as usize, b as usize), -w);
                        diag += w;
                    }
                }
                t.push(row, row, diag);
            }
        }
        t.to_matrix().unwrap()
    }

    #[test]
    fn solves_like_faer_pivoted_lu() {
        for m in [1, 2, 7, 40, 90] {
            let a = grid_mvc(m);
            let n = a.nrows();
            let lu = SupernodalLu::<f64>::factor(&a).unwrap();
            if m == 90 {
                // The blocked path (several panels) and faer's Schur product run.
                let sn = lu.structure();
                let widest =
                    (0..sn.n_supernodes()).map(|s| sn.supernode_end()[s] - sn.supernode_begin()[s]).max().unwrap();
                assert!(widest > 2 * PANEL, "widest supernode {widest}");
            }
            let b: Vec<[f64; 2]> = (0..n).map(|i| [((i * 7) % 13) as f64 - 6.0, (i % 3) as f64]).collect();
            let mut x = b.clone();
            lu.solve_interleaved(&mut x).unwrap();
            let mut cols = vec![b.iter().map(|v| v[0]).collect::<Vec<_>>(), b.iter().map(|v| v[1]).collect()];
            LuSolver::new(&a).unwrap().solve_columns(&mut cols).unwrap();
            for (i, xi) in x.iter().enumerate() {
                for k in 0..2 {
                    assert!((xi[k] - cols[k][i]).abs() < 1e-10 * (1.0 + cols[k][i].abs()), "m {m} row {i}");
                }
            }
            // Residual of the original system.
            let mut r = b.clone();
            for j in 0..n {
                for (&i, &v) in a.row_idx_of_col_raw(j).iter().zip(a.val_of_col(j)) {
                    for k in 0..2 {
                        r[i][k] -= v * x[j][k];
                    }
                }
            }
            assert!(r.iter().all(|ri| ri[0].abs() < 1e-10 && ri[1].abs() < 1e-10));
        }
    }

    #[test]
    fn single_precision_factor_is_a_close_inverse() {
        let a = grid_mvc(60);
        let n = a.nrows();
        let (lo, hi) = (SupernodalLu::<f32>::factor(&a).unwrap(), SupernodalLu::<f64>::factor(&a).unwrap());
        assert!(lo.lu.len() == hi.lu.len() && lo.ut.len() == hi.ut.len());
        let b: Vec<[f64; 1]> = (0..n).map(|i| [((i * 5) % 11) as f64 - 5.0]).collect();
        let (mut x, mut y) = (b.clone(), b.clone());
        lo.solve_interleaved(&mut x).unwrap();
        hi.solve_interleaved(&mut y).unwrap();
        let norm = y.iter().map(|v| v[0] * v[0]).sum::<f64>().sqrt();
        let err = x.iter().zip(&y).map(|(p, q)| (p[0] - q[0]).powi(2)).sum::<f64>().sqrt();
        // Single precision, condition number of a 3600-unknown mesh matrix.
        assert!(err < 1e-4 * norm && err > 0.0, "relative error {}", err / norm);
    }

    #[test]
    fn rejects_a_zero_pivot() {
        // [[0, 1], [1, 0]] needs pivoting.
        let mut t = Triplets::new(2, 2);
        t.push(0, 1, 1.0);
        t.push(1, 0, 1.0);
        t.push(0, 0, 0.0);
        let a = t.to_matrix().unwrap();
        assert!(matches!(SupernodalLu::<f64>::factor(&a), Err(LinalgError::Singular { .. })));
        assert!(matches!(SupernodalLu::<f32>::factor(&a), Err(LinalgError::Singular { .. })));
    }
}
