//! Forward and backward substitution with a supernodal Cholesky factor on
//! `K` right-hand sides stored interleaved (`[f64; K]` per unknown).
//!
//! Why not faer's own solve: it treats each supernode as a dense block and
//! calls a general matrix product for the off-diagonal part. On the factors
//! of 2D mesh matrices most supernodes are a few columns wide, so that
//! call's setup dominated the solves of the atlas's mean value systems and
//! of the crossfield's Newton systems (`docs/decisions.md`). Preconditioned
//! Krylov methods apply the
//! factor dozens of times, so the solve, not the factorization, is their
//! cost. These loops read each stored entry of `L` once per pass and update
//! all `K` columns with it (faster than faer's, most for K ≥ 2:
//! `docs/decisions.md`).
//!
//! Layout (faer's): supernode `s` owns columns `start..start+nc` and the
//! off-diagonal row pattern `p` (`np` rows); its values are a dense
//! column-major `(nc + np) × nc` block, rows `0..nc` the lower-triangular
//! diagonal block, rows `nc..` the rows `p`. The off-diagonal rows of a
//! supernode are gathered into (backward) or accumulated in (forward) the
//! contiguous buffer `tmp` once per supernode, not once per column.

use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;

/// Solve `L Lᵀ y = x` in place for the `K` interleaved columns of `x`
/// (already permuted to the factor's ordering); `tmp` is scratch space.
pub fn llt_solve_interleaved<const K: usize>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [[f64; K]],
    tmp: &mut Vec<[f64; K]>,
) {
    forward(symbolic, values, x, tmp);
    backward(symbolic, values, x, tmp);
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

/// `L y = x`: supernodes in order; each column is divided by its pivot and
/// eliminated from the later columns of its supernode, its updates of the
/// rows below are summed in `tmp` and applied once per supernode.
fn forward<const K: usize>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [[f64; K]],
    tmp: &mut Vec<[f64; K]>,
) {
    for s in 0..symbolic.n_supernodes() {
        let (start, nc, pattern, block) = supernode(symbolic, values, s);
        let ld = nc + pattern.len();
        tmp.clear();
        tmp.resize(pattern.len(), [0.0; K]);
        for c in 0..nc {
            let col = &block[c * ld..(c + 1) * ld];
            let mut xc = x[start + c];
            for v in &mut xc {
                *v /= col[c];
            }
            x[start + c] = xc;
            for r in c + 1..nc {
                let xr = &mut x[start + r];
                for k in 0..K {
                    xr[k] -= col[r] * xc[k];
                }
            }
            for (t, &l) in tmp.iter_mut().zip(&col[nc..]) {
                for k in 0..K {
                    t[k] += l * xc[k];
                }
            }
        }
        for (&row, t) in pattern.iter().zip(tmp.iter()) {
            for k in 0..K {
                x[row][k] -= t[k];
            }
        }
    }
}

/// `Lᵀ y = x`: supernodes in reverse; the solved rows below a supernode are
/// gathered into `tmp` once, then each column (last first) subtracts its
/// products with them and with the later columns, and divides by its pivot.
fn backward<const K: usize>(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [[f64; K]],
    tmp: &mut Vec<[f64; K]>,
) {
    for s in (0..symbolic.n_supernodes()).rev() {
        let (start, nc, pattern, block) = supernode(symbolic, values, s);
        let ld = nc + pattern.len();
        tmp.clear();
        tmp.extend(pattern.iter().map(|&r| x[r]));
        for c in (0..nc).rev() {
            let col = &block[c * ld..(c + 1) * ld];
            // Two partial sums per column: one would be a chain of
            // dependent additions (slower: `docs/decisions.md`).
            let (mut acc, mut acc2) = (x[start + c], [0.0; K]);
            for r in c + 1..nc {
                let xr = x[start + r];
                for k in 0..K {
                    acc[k] -= col[r] * xr[k];
                }
            }
            let (ls, ts) = (&col[nc..], &tmp[..]);
            let half = ls.len() / 2;
            for i in 0..half {
                let (la, lb, ta, tb) = (ls[2 * i], ls[2 * i + 1], ts[2 * i], ts[2 * i + 1]);
                for k in 0..K {
                    acc[k] -= la * ta[k];
                    acc2[k] -= lb * tb[k];
                }
            }
            if ls.len() % 2 == 1 {
                let (l, t) = (ls[ls.len() - 1], ts[ls.len() - 1]);
                for k in 0..K {
                    acc[k] -= l * t[k];
                }
            }
            for k in 0..K {
                acc[k] = (acc[k] + acc2[k]) / col[c];
            }
            x[start + c] = acc;
        }
    }
}
