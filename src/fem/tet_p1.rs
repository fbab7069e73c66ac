//! Linear (P1) Lagrange elements on tetrahedra: stiffness and lumped mass.
//!
//! On a tetrahedron `T = (x0, x1, x2, x3)` with `D = [x1−x0, x2−x0, x3−x0]`,
//! the barycentric gradients are the rows of `D⁻¹` (`∇φ1..3`) and
//! `∇φ0 = −(∇φ1 + ∇φ2 + ∇φ3)`; `|T| = det D / 6`. The stiffness matrix is
//! `K_ab = Σ_T |T| ∇φa · ∇φb`, so `xᵀ K x = ∫ |∇x_h|²` for the P1
//! interpolant `x_h`; the lumped mass is `M_aa = Σ_{T ∋ a} |T| / 4`.
//!
//! `K` is stored as the lower triangle of a compressed-column matrix whose
//! pattern is the vertex graph of the mesh (diagonal first in each column,
//! then the neighbours of larger index, sorted), built from the sorted edge
//! list without a triplet pass (16 triplets per tet would be 256 MB at a
//! million tets). The same pattern serves every matrix `α M + β K`, so a
//! Cholesky factorization of one is refactored for another with the numeric
//! phase only.

use crate::geom::Vec3;
use crate::linalg::SparseMatrix;
use crate::mesh::TetMesh;
use faer::sparse::SymbolicSparseColMat;

/// P1 operators of a tetrahedral mesh, sharing the lower-triangle pattern.
#[derive(Debug, Clone)]
pub struct TetP1Operators {
    /// Number of vertices (matrix size).
    pub n_vertices: usize,
    /// Column pointers of the lower triangle (length `n + 1`).
    col_ptr: Vec<usize>,
    /// Row indices: `row_idx[col_ptr[j]] = j`, then neighbours `> j` sorted.
    row_idx: Vec<usize>,
    /// Stiffness values aligned with `row_idx`.
    pub stiffness_lower: Vec<f64>,
    /// Lumped mass per vertex (`Σ |T|/4`).
    pub lumped_mass: Vec<f64>,
}

/// Barycentric gradients and volume of a tetrahedron (volume ≤ 0 for an
/// inverted or flat one, whose gradients are then zero).
pub fn tet_p1_gradients(p: &[Vec3; 4]) -> ([Vec3; 4], f64) {
    let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let det = e1.dot(&e2.cross(&e3));
    if !(det > 0.0) {
        return ([Vec3::zeros(); 4], det / 6.0);
    }
    // Rows of D⁻¹ are (e2×e3, e3×e1, e1×e2)/det.
    let g1 = e2.cross(&e3) / det;
    let g2 = e3.cross(&e1) / det;
    let g3 = e1.cross(&e2) / det;
    ([-(g1 + g2 + g3), g1, g2, g3], det / 6.0)
}

/// The 6 local edges of a tetrahedron as corner pairs.
pub const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

/// Sorted unique edges `[a, b]`, `a < b`, of a tetrahedral mesh.
pub fn tet_mesh_edges(mesh: &TetMesh) -> Vec<[u32; 2]> {
    let mut keys: Vec<u64> = Vec::with_capacity(mesh.tets.len() * 6);
    for t in &mesh.tets {
        for [i, j] in TET_EDGES {
            let (a, b) = (t[i].0.min(t[j].0), t[i].0.max(t[j].0));
            keys.push(((a as u64) << 32) | b as u64);
        }
    }
    keys.sort_unstable();
    keys.dedup();
    keys.into_iter().map(|k| [(k >> 32) as u32, (k & 0xffff_ffff) as u32]).collect()
}

/// Assemble the P1 stiffness (lower triangle) and lumped mass of `mesh`.
/// Tets with non-positive volume contribute nothing (validate the mesh first).
pub fn tet_p1_operators(mesh: &TetMesh) -> TetP1Operators {
    let n = mesh.n_vertices();
    let edges = tet_mesh_edges(mesh);
    let mut col_ptr = vec![0usize; n + 1];
    for e in &edges {
        col_ptr[e[0] as usize + 1] += 1;
    }
    for j in 0..n {
        col_ptr[j + 1] += col_ptr[j] + 1; // +1 for the diagonal
    }
    let mut row_idx = vec![0usize; col_ptr[n]];
    {
        let mut next: Vec<usize> = col_ptr[..n].to_vec();
        for j in 0..n {
            row_idx[next[j]] = j;
            next[j] += 1;
        }
        for e in &edges {
            let j = e[0] as usize;
            row_idx[next[j]] = e[1] as usize;
            next[j] += 1;
        }
    }
    let mut stiffness = vec![0.0; row_idx.len()];
    let mut mass = vec![0.0; n];
    let slot = |col: usize, row: usize, row_idx: &[usize]| -> usize {
        let (lo, hi) = (col_ptr[col], col_ptr[col + 1]);
        lo + row_idx[lo..hi].binary_search(&row).unwrap_or(0)
    };
    for t in &mesh.tets {
        let p = t.map(|v| mesh.positions[v.idx()]);
        let (g, vol) = tet_p1_gradients(&p);
        if !(vol > 0.0) {
            continue;
        }
        for a in 0..4 {
            let va = t[a].idx();
            mass[va] += vol / 4.0;
            let d = slot(va, va, &row_idx);
            stiffness[d] += vol * g[a].norm_squared();
        }
        for [i, j] in TET_EDGES {
            let (a, b) = (t[i].idx().min(t[j].idx()), t[i].idx().max(t[j].idx()));
            let s = slot(a, b, &row_idx);
            stiffness[s] += vol * g[i].dot(&g[j]);
        }
    }
    TetP1Operators { n_vertices: n, col_ptr, row_idx, stiffness_lower: stiffness, lumped_mass: mass }
}

impl TetP1Operators {
    /// Index in the stored values of the diagonal entry of column `j`.
    pub fn diagonal_slot(&self, j: usize) -> usize {
        self.col_ptr[j]
    }

    /// The lower-triangle pattern `(col_ptr, row_idx)` shared by all matrices.
    pub fn pattern(&self) -> (&[usize], &[usize]) {
        (&self.col_ptr, &self.row_idx)
    }

    /// Number of stored (lower-triangle) entries.
    pub fn n_stored(&self) -> usize {
        self.row_idx.len()
    }

    /// The lower triangle of `mass_scale · M + stiffness_scale · K`, plus
    /// `extra_diagonal[i]` on the diagonal when given (penalties), as a
    /// compressed-column matrix with the shared pattern.
    pub fn combination(&self, mass_scale: f64, stiffness_scale: f64, extra_diagonal: Option<&[f64]>) -> SparseMatrix {
        let mut vals: Vec<f64> = self.stiffness_lower.iter().map(|k| k * stiffness_scale).collect();
        for j in 0..self.n_vertices {
            let d = self.col_ptr[j];
            vals[d] += mass_scale * self.lumped_mass[j] + extra_diagonal.map_or(0.0, |e| e[j]);
        }
        let symbolic = SymbolicSparseColMat::new_checked(
            self.n_vertices,
            self.n_vertices,
            self.col_ptr.clone(),
            None,
            self.row_idx.clone(),
        );
        SparseMatrix::new(symbolic, vals)
    }

    /// `y = K x` using the symmetric lower storage.
    pub fn apply_stiffness(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for j in 0..self.n_vertices {
            let (lo, hi) = (self.col_ptr[j], self.col_ptr[j + 1]);
            y[j] += self.stiffness_lower[lo] * x[j];
            for s in lo + 1..hi {
                let i = self.row_idx[s];
                let k = self.stiffness_lower[s];
                y[i] += k * x[j];
                y[j] += k * x[i];
            }
        }
    }

    /// Dirichlet energy `xᵀ K x = ∫ |∇x_h|²` of a nodal field.
    pub fn dirichlet_energy(&self, x: &[f64]) -> f64 {
        let mut e = 0.0;
        for j in 0..self.n_vertices {
            let (lo, hi) = (self.col_ptr[j], self.col_ptr[j + 1]);
            e += self.stiffness_lower[lo] * x[j] * x[j];
            for s in lo + 1..hi {
                e += 2.0 * self.stiffness_lower[s] * x[j] * x[self.row_idx[s]];
            }
        }
        e
    }

    /// Neighbours `i > j` of vertex `j` (the strict lower part of column `j`)
    /// with their stiffness entries.
    pub fn lower_neighbours(&self, j: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (lo, hi) = (self.col_ptr[j], self.col_ptr[j + 1]);
        (lo + 1..hi).map(move |s| (self.row_idx[s], self.stiffness_lower[s]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::VertexId;

    /// The unit cube split into 6 tets around the diagonal (0,0,0)–(1,1,1),
    /// scaled by `s`.
    fn cube6(s: f64) -> TetMesh {
        let positions =
            (0..8).map(|i| Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64) * s).collect();
        let raw = [[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]];
        let mut m = TetMesh { positions, tets: raw.iter().map(|t| t.map(VertexId)).collect() };
        m.orient_positive();
        m
    }

    #[test]
    fn stiffness_annihilates_constants_and_integrates_linear_gradients() {
        let m = cube6(2.0);
        assert!(m.validate().is_ok());
        let ops = tet_p1_operators(&m);
        let ones = vec![1.0; 8];
        let mut y = vec![0.0; 8];
        ops.apply_stiffness(&ones, &mut y);
        assert!(y.iter().all(|v| v.abs() < 1e-14));
        // x ↦ 3x − y + 2z has |∇|² = 14 over a volume of 8.
        let f: Vec<f64> = m.positions.iter().map(|p| 3.0 * p.x - p.y + 2.0 * p.z).collect();
        assert!((ops.dirichlet_energy(&f) - 14.0 * 8.0).abs() < 1e-12);
        assert!((ops.lumped_mass.iter().sum::<f64>() - 8.0).abs() < 1e-14);
        // The assembled matrix agrees with apply_stiffness.
        let a = ops.combination(0.0, 1.0, None);
        let dense = a.to_dense();
        let mut kf = vec![0.0; 8];
        ops.apply_stiffness(&f, &mut kf);
        for i in 0..8 {
            let mut s = 0.0;
            for j in 0..8 {
                let v = if i >= j { dense[(i, j)] } else { dense[(j, i)] };
                s += v * f[j];
            }
            assert!((s - kf[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn edges_are_unique_and_sorted() {
        let e = tet_mesh_edges(&cube6(1.0));
        // 12 cube edges + 6 face diagonals + 1 body diagonal.
        assert_eq!(e.len(), 19);
        assert!(e.windows(2).all(|w| w[0] < w[1]) && e.iter().all(|[a, b]| a < b));
    }
}
