//! Forward and backward substitution with a supernodal Cholesky factor on
//! `K` right-hand sides stored interleaved (`[f64; K]` per unknown).
//!
//! Why not faer's own solve: it treats each supernode as a dense block and
//! calls a general matrix product for the off-diagonal part. On the factors
//! of 2D mesh Laplacians most supernodes are a few columns wide, so that
//! call's setup dominated: on the 100k-triangle mean value systems of the
//! atlas, `perf` put 60 % of the solve in `nano_gemm::copy_millikernel`.
//! Preconditioned Krylov methods apply the factor dozens of times, so the
//! solve, not the factorization, is their cost. These loops read each
//! stored entry of `L` once per pass and update all `K` columns with it.
//!
//! Layout (faer's): supernode `s` owns columns `start..start+nc` and the
//! off-diagonal row pattern `p` (`np` rows); its values are a dense
//! column-major `(nc + np) × nc` block, rows `0..nc` the lower-triangular
//! diagonal block, rows `nc..` the rows `p`.

use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;

/// Solve `L Lᵀ y = x` in place for the `K` interleaved columns of `x`
/// (already permuted to the factor's ordering).
pub fn llt_solve_interleaved<const K: usize>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [[f64; K]],
) {
    forward(symbolic, values, x);
    backward(symbolic, values, x);
}

/// One supernode: first column, width, off-diagonal rows, value block.
fn supernode<'a>(
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    values: &'a [f64],
    s: usize,
) -> (usize, usize, &'a [usize], &'a [f64]) {
    let start = symbolic.supernode_begin()[s];
    let nc = symbolic.supernode_end()[s] - start;
    let pattern = symbolic.supernode(s).pattern();
    let vp = symbolic.col_ptr_for_val();
    (start, nc, pattern, &values[vp[s]..vp[s + 1]])
}

/// `L y = x`: supernodes in order, each column divided by its pivot and
/// then eliminated from the rows below it.
fn forward<const K: usize>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [[f64; K]],
) {
    for s in 0..symbolic.n_supernodes() {
        let (start, nc, pattern, block) = supernode(symbolic, values, s);
        let ld = nc + pattern.len();
        for c in 0..nc {
            let col = &block[c * ld..(c + 1) * ld];
            let mut xc = x[start + c];
            let pivot = col[c];
            xc.iter_mut().for_each(|v| *v /= pivot);
            x[start + c] = xc;
            for r in c + 1..nc {
                let l = col[r];
                let xr = &mut x[start + r];
                for k in 0..K {
                    xr[k] -= l * xc[k];
                }
            }
            for (&row, &l) in pattern.iter().zip(&col[nc..]) {
                let xr = &mut x[row];
                for k in 0..K {
                    xr[k] -= l * xc[k];
                }
            }
        }
    }
}

/// `Lᵀ y = x`: supernodes in reverse, each column gathers the solved rows
/// below it and is divided by its pivot.
fn backward<const K: usize>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [[f64; K]],
) {
    for s in (0..symbolic.n_supernodes()).rev() {
        let (start, nc, pattern, block) = supernode(symbolic, values, s);
        let ld = nc + pattern.len();
        for c in (0..nc).rev() {
            let col = &block[c * ld..(c + 1) * ld];
            // Two independent partial sums per column: the gather is a
            // chain of dependent additions otherwise (measured 2× slower
            // than the forward pass).
            let (mut acc, mut acc2) = (x[start + c], [0.0; K]);
            for r in c + 1..nc {
                let l = col[r];
                let xr = x[start + r];
                for k in 0..K {
                    acc[k] -= l * xr[k];
                }
            }
            let (rows, ls) = (pattern, &col[nc..]);
            let pairs = rows.len() / 2;
            for p in 0..pairs {
                let (xa, xb) = (x[rows[2 * p]], x[rows[2 * p + 1]]);
                let (la, lb) = (ls[2 * p], ls[2 * p + 1]);
                for k in 0..K {
                    acc[k] -= la * xa[k];
                    acc2[k] -= lb * xb[k];
                }
            }
            if rows.len() % 2 == 1 {
                let (xr, l) = (x[rows[rows.len() - 1]], ls[rows.len() - 1]);
                for k in 0..K {
                    acc[k] -= l * xr[k];
                }
            }
            let pivot = col[c];
            for k in 0..K {
                acc[k] = (acc[k] + acc2[k]) / pivot;
            }
            x[start + c] = acc;
        }
    }
}
