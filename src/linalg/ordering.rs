//! Fill-reducing orderings for sparse Cholesky: METIS nested dissection
//! (`METIS_NodeND`) of a symmetric pattern, optionally compressed to blocks.
//!
//! Why: for matrices from surface meshes (2D graphs), nested dissection
//! bounds the fill of `L` by `O(n log n)` and the flops by `O(n^{3/2})`,
//! while minimum degree (AMD, faer's default) leaves long separators late and
//! grows faster; measured on the crossfield Newton systems (2×2 blocks per
//! mesh edge) in [`crate::crossfield::newton`].
//!
//! Block compression: when the unknowns come in groups of `b` consecutive
//! indices that share their sparsity (the real and imaginary part of one
//! complex unknown), the graph of the groups is ordered (b² times fewer
//! edges for METIS) and each group is kept together in the permutation,
//! which also makes supernodes line up with the blocks.
//!
//! METIS keeps its random state in globals: calls are serialized by a lock
//! so the ordering is deterministic whatever the thread pool does.

use super::LinalgError;
use faer::sparse::SymbolicSparseColMatRef;

/// Serializes every METIS call in the crate (this ordering and the atlas
/// partitioner): GKlib keeps its random generator in global state, so
/// concurrent calls would race and make results depend on timing.
pub static METIS_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Fill-reducing permutation `perm` (new index → old index) of the symmetric
/// matrix whose lower (or upper, or full) pattern is `a`, by METIS nested
/// dissection on the graph of `block`-sized groups of consecutive indices
/// (`block` must divide the size; entries of a group are merged).
///
/// # Errors
/// [`LinalgError::Internal`] when METIS fails or the size is not a multiple of `block`.
pub fn nested_dissection(a: SymbolicSparseColMatRef<'_, usize>, block: usize) -> Result<Vec<usize>, LinalgError> {
    let n = a.nrows();
    if block == 0 || n % block != 0 {
        return Err(LinalgError::Internal(format!(
            "nested dissection: size {n} is not a multiple of the block {block}"
        )));
    }
    let nb = n / block;
    if nb <= 1 {
        return Ok((0..n).collect());
    }
    // Symmetric block graph without self loops, in CSR (METIS form).
    let mut deg = vec![0i32; nb + 1];
    let (cp, ri) = (a.col_ptr(), a.row_idx());
    let col_nnz = a.col_nnz();
    let range = |j: usize| cp[j]..col_nnz.map_or(cp[j + 1], |c| cp[j] + c[j]);
    let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(ri.len() / (block * block) * 2 + 1);
    for j in 0..n {
        let bj = (j / block) as u32;
        for s in range(j) {
            let bi = (ri[s] / block) as u32;
            if bi != bj {
                pairs.push((bi, bj));
                pairs.push((bj, bi));
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    for &(i, _) in &pairs {
        deg[i as usize + 1] += 1;
    }
    for i in 0..nb {
        deg[i + 1] += deg[i];
    }
    let xadj = deg;
    let adjncy: Vec<i32> = pairs.iter().map(|&(_, j)| j as i32).collect();
    if adjncy.is_empty() {
        return Ok((0..n).collect());
    }
    let perm = graph_nested_dissection(xadj, adjncy)?;
    let mut out = Vec::with_capacity(n);
    for &p in &perm {
        out.extend(p * block..(p + 1) * block);
    }
    Ok(out)
}

/// METIS nested dissection (`METIS_NodeND`) of the symmetric graph given in
/// CSR form (`xadj`: `n + 1` offsets, `adjncy`: neighbours, no self loops,
/// each edge in both rows); returns the permutation new → old.
///
/// # Errors
/// [`LinalgError::Internal`] when METIS fails or returns an invalid permutation.
pub fn graph_nested_dissection(mut xadj: Vec<i32>, mut adjncy: Vec<i32>) -> Result<Vec<usize>, LinalgError> {
    let nb = xadj.len().saturating_sub(1);
    if nb <= 1 || adjncy.is_empty() {
        return Ok((0..nb).collect());
    }
    let mut perm = vec![0i32; nb];
    let mut iperm = vec![0i32; nb];
    let status = {
        let _guard = METIS_LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let mut nvtxs = nb as i32;
        let mut options = [0i32; metis_sys::METIS_NOPTIONS as usize];
        // The crate denies unsafe code; this FFI call is the one exception.
        #[allow(unsafe_code)]
        // SAFETY: the arrays have the sizes METIS expects (nvtxs + 1,
        // xadj[nvtxs], nvtxs, nvtxs); options are the defaults set by METIS.
        unsafe {
            metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr());
            metis_sys::METIS_NodeND(
                &mut nvtxs,
                xadj.as_mut_ptr(),
                adjncy.as_mut_ptr(),
                std::ptr::null_mut(),
                options.as_mut_ptr(),
                perm.as_mut_ptr(),
                iperm.as_mut_ptr(),
            )
        }
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return Err(LinalgError::Internal(format!("METIS_NodeND failed with status {status}")));
    }
    if perm.iter().any(|&p| p < 0 || p as usize >= nb) {
        return Err(LinalgError::Internal("METIS_NodeND returned an invalid permutation".into()));
    }
    Ok(perm.into_iter().map(|p| p as usize).collect())
}

/// Inverse of a permutation given as new → old.
pub fn inverse_permutation(perm: &[usize]) -> Vec<usize> {
    let mut inv = vec![0; perm.len()];
    for (new, &old) in perm.iter().enumerate() {
        inv[old] = new;
    }
    inv
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::Triplets;

    /// Lower triangle of the 5-point Laplacian on a k×k grid, each node a 2×2 block.
    fn grid(k: usize) -> crate::linalg::SparseMatrix {
        let n = 2 * k * k;
        let mut t = Triplets::new(n, n);
        let id = |i: usize, j: usize| i * k + j;
        for i in 0..k {
            for j in 0..k {
                let a = id(i, j);
                for c in 0..2 {
                    t.push(2 * a + c, 2 * a + c, 4.5);
                }
                t.push(2 * a + 1, 2 * a, 0.1);
                for (di, dj) in [(1, 0), (0, 1)] {
                    if i + di < k && j + dj < k {
                        let b = id(i + di, j + dj);
                        for c in 0..2 {
                            for d in 0..2 {
                                t.push(2 * b + c, 2 * a + d, if c == d { -1.0 } else { 0.0 });
                            }
                        }
                    }
                }
            }
        }
        t.to_matrix().unwrap()
    }

    #[test]
    fn nested_dissection_is_a_block_permutation() {
        let a = grid(20);
        let p = nested_dissection(a.symbolic(), 2).unwrap();
        assert_eq!(p.len(), a.nrows());
        let mut seen = vec![false; p.len()];
        for (k, &i) in p.iter().enumerate() {
            assert!(!seen[i]);
            seen[i] = true;
            // Blocks stay together and in order.
            if k % 2 == 1 {
                assert_eq!(i, p[k - 1] + 1);
                assert_eq!(i % 2, 1);
            }
        }
        let inv = inverse_permutation(&p);
        assert!((0..p.len()).all(|i| p[inv[i]] == i));
        assert!(nested_dissection(a.symbolic(), 3).is_err());
    }
}
