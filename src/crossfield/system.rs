//! Sparse Newton system of the Ginzburg–Landau energy: the free unknowns,
//! the symbolic structure of the Hessian (lower triangle, CSC) built once,
//! and the numeric assembly of gradient and Hessian at each Newton step.
//!
//! Real unknowns are numbered `2i, 2i+1` for the real and imaginary parts of
//! free edge `i`. Each triangle couples its three edges with a dense 6×6
//! block; the slot of every lower-triangle entry in the CSC value array is
//! computed once per triangle, so an assembly is a scatter-add of element
//! matrices (computed in parallel chunks, added in a fixed order: results do
//! not depend on the number of threads).

use super::CrossfieldError;
use super::energy::{EnergyParams, HessianKind, element_derivatives};
use super::frames::{C64, Discretization};
use crate::linalg::SparseMatrix;
use crate::mesh::Topology;
use faer::sparse::SymbolicSparseColMat;
use rayon::prelude::*;

/// No slot: the entry is in the upper triangle or touches a fixed edge.
const NONE: u32 = u32::MAX;

/// Triangles per parallel chunk during assembly (bounds the memory of element results).
const CHUNK: usize = 8192;

/// Free unknowns and the Hessian's symbolic structure.
#[derive(Debug, Clone)]
pub struct NewtonSystem {
    /// Per edge: its free index, or `u32::MAX` when the edge value is fixed.
    pub free_index: Vec<u32>,
    /// Free edges in order.
    pub free_edges: Vec<u32>,
    symbolic: SymbolicSparseColMat<usize>,
    /// Per triangle, per local (row, col) of the 6×6 element matrix: CSC slot or [`NONE`].
    slots: Vec<[u32; 36]>,
    /// Slot of each diagonal entry, per real unknown.
    diag_slot: Vec<u32>,
}

/// Gradient (free unknowns) and Hessian values of one assembly.
#[derive(Debug, Clone)]
pub struct Assembled {
    /// Total energy.
    pub energy: f64,
    /// Gradient with respect to the free real unknowns.
    pub grad: Vec<f64>,
    /// CSC values of the lower triangle of the Hessian.
    pub hess_values: Vec<f64>,
}

impl NewtonSystem {
    /// Number of real unknowns.
    pub fn n_dofs(&self) -> usize {
        2 * self.free_edges.len()
    }

    /// Build the free-unknown numbering (edges with `fixed[e]` are excluded)
    /// and the symbolic structure of the Hessian.
    ///
    /// # Errors
    /// [`CrossfieldError::Linalg`] when the structure cannot be built.
    pub fn new(topo: &Topology, disc: &Discretization, fixed: &[bool]) -> Result<Self, CrossfieldError> {
        let mut free_index = vec![NONE; topo.n_edges()];
        let mut free_edges = Vec::new();
        for e in 0..topo.n_edges() {
            if !fixed[e] {
                free_index[e] = free_edges.len() as u32;
                free_edges.push(e as u32);
            }
        }
        let n = 2 * free_edges.len();
        // Lower-triangle (col, row) pairs: diagonals plus the triangle couplings.
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(n * 2 + disc.faces.len() * 12);
        for i in 0..free_edges.len() as u32 {
            pairs.push((2 * i, 2 * i));
            pairs.push((2 * i, 2 * i + 1));
            pairs.push((2 * i + 1, 2 * i + 1));
        }
        for (fd, fe) in disc.faces.iter().zip(&topo.face_edges) {
            if fd.area == 0.0 {
                continue;
            }
            for a in 0..3 {
                for b in 0..3 {
                    let (ia, ib) = (free_index[fe[a].idx()], free_index[fe[b].idx()]);
                    if ia == NONE || ib == NONE || ia <= ib {
                        continue;
                    }
                    for ra in 0..2 {
                        for cb in 0..2 {
                            pairs.push((2 * ib + cb, 2 * ia + ra));
                        }
                    }
                }
            }
        }
        pairs.par_sort_unstable();
        pairs.dedup();
        let mut col_ptr = vec![0usize; n + 1];
        for &(c, _) in &pairs {
            col_ptr[c as usize + 1] += 1;
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let row_idx: Vec<usize> = pairs.iter().map(|&(_, r)| r as usize).collect();
        let slot_of = |row: u32, col: u32| -> u32 {
            let (lo, hi) = (col_ptr[col as usize], col_ptr[col as usize + 1]);
            match row_idx[lo..hi].binary_search(&(row as usize)) {
                Ok(k) => (lo + k) as u32,
                Err(_) => NONE,
            }
        };
        let diag_slot: Vec<u32> = (0..n as u32).map(|d| slot_of(d, d)).collect();
        let slots: Vec<[u32; 36]> = disc
            .faces
            .par_iter()
            .zip(topo.face_edges.par_iter())
            .map(|(fd, fe)| {
                let mut s = [NONE; 36];
                if fd.area == 0.0 {
                    return s;
                }
                for a in 0..6 {
                    for b in 0..6 {
                        let (ia, ib) = (free_index[fe[a / 2].idx()], free_index[fe[b / 2].idx()]);
                        if ia == NONE || ib == NONE {
                            continue;
                        }
                        let (row, col) = (2 * ia + (a % 2) as u32, 2 * ib + (b % 2) as u32);
                        if row >= col {
                            s[6 * a + b] = slot_of(row, col);
                        }
                    }
                }
                s
            })
            .collect();
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        Ok(Self { free_index, free_edges, symbolic, slots, diag_slot })
    }

    /// Fill-reducing ordering (new → old) of the real unknowns from a nested
    /// dissection of the mesh's vertex graph: each free edge is ranked by the
    /// earlier of its endpoints in the vertex order (then the later), and its
    /// two unknowns stay together. Why this is a nested dissection of the
    /// Hessian's graph: the Hessian couples the edges of one triangle, and no
    /// triangle has vertices in two sibling parts of the vertex dissection,
    /// so an edge ranked in one part (it has a vertex there) never meets an
    /// edge ranked in a sibling; a separator's block holds the edges with both
    /// endpoints in it or its ancestors, about one edge per separator vertex.
    /// (Ranking by the later endpoint instead puts every edge that touches a
    /// separator into it: separators three times wider, five times the fill.)
    /// The vertex graph has a third of the nodes and half the adjacency of
    /// the edges' graph: METIS takes a fifth of the time, for 5–35 % more
    /// fill (fixed edges are invisible to it) but faster factorizations
    /// (`docs/decisions.md`).
    ///
    /// # Errors
    /// [`CrossfieldError::Linalg`] when METIS fails.
    pub fn vertex_dissection_order(&self, topo: &Topology) -> Result<Vec<usize>, CrossfieldError> {
        let nv = topo.n_vertices();
        let mut xadj = vec![0i32; nv + 1];
        for [a, b] in &topo.edges {
            xadj[a.0 as usize + 1] += 1;
            xadj[b.0 as usize + 1] += 1;
        }
        for v in 0..nv {
            xadj[v + 1] += xadj[v];
        }
        let mut next: Vec<i32> = xadj[..nv].to_vec();
        let mut adjncy = vec![0i32; 2 * topo.edges.len()];
        for [a, b] in &topo.edges {
            for (x, y) in [(a.0, b.0), (b.0, a.0)] {
                adjncy[next[x as usize] as usize] = y as i32;
                next[x as usize] += 1;
            }
        }
        let vertex_perm = crate::linalg::ordering::graph_nested_dissection(xadj, adjncy)?;
        let mut rank = vec![0u32; nv];
        for (new, &old) in vertex_perm.iter().enumerate() {
            rank[old] = new as u32;
        }
        let key = |i: usize| {
            let [a, b] = topo.edges[self.free_edges[i] as usize];
            let (ra, rb) = (rank[a.0 as usize], rank[b.0 as usize]);
            (ra.min(rb), ra.max(rb))
        };
        let mut order: Vec<usize> = (0..self.free_edges.len()).collect();
        order.sort_unstable_by_key(|&i| key(i));
        Ok(order.into_iter().flat_map(|i| [2 * i, 2 * i + 1]).collect())
    }

    /// Assemble energy, gradient and Hessian (lower triangle) at `f`.
    pub fn assemble(
        &self,
        topo: &Topology,
        disc: &Discretization,
        f: &[C64],
        params: &EnergyParams,
        kind: HessianKind,
    ) -> Assembled {
        let n = self.n_dofs();
        let mut grad = vec![0.0; n];
        let mut hess_values = vec![0.0; self.symbolic.row_idx().len()];
        let mut energy = 0.0;
        for (ci, chunk) in disc.faces.chunks(CHUNK).enumerate() {
            let base = ci * CHUNK;
            let results: Vec<_> = chunk
                .par_iter()
                .enumerate()
                .map(|(i, fd)| {
                    let fe = &topo.face_edges[base + i];
                    element_derivatives(fd, [f[fe[0].idx()], f[fe[1].idx()], f[fe[2].idx()]], params.inv_eps2, kind)
                })
                .collect();
            for (i, r) in results.iter().enumerate() {
                let t = base + i;
                energy += r.energy;
                let fe = &topo.face_edges[t];
                for k in 0..3 {
                    let fi = self.free_index[fe[k].idx()];
                    if fi != NONE {
                        grad[2 * fi as usize] += r.grad[2 * k];
                        grad[2 * fi as usize + 1] += r.grad[2 * k + 1];
                    }
                }
                let s = &self.slots[t];
                for a in 0..6 {
                    for b in 0..6 {
                        let slot = s[6 * a + b];
                        if slot != NONE {
                            hess_values[slot as usize] += r.hess[a][b];
                        }
                    }
                }
            }
        }
        if params.weak_coef > 0.0 {
            for (e, &w) in params.weak_edges.iter().enumerate() {
                if !w {
                    continue;
                }
                let k = params.weak_coef * disc.length_per_edge[e];
                let d = f[e] - C64::new(1.0, 0.0);
                energy += 0.5 * k * d.norm_sqr();
                let fi = self.free_index[e];
                if fi != NONE {
                    grad[2 * fi as usize] += k * d.re;
                    grad[2 * fi as usize + 1] += k * d.im;
                    hess_values[self.diag_slot[2 * fi as usize] as usize] += k;
                    hess_values[self.diag_slot[2 * fi as usize + 1] as usize] += k;
                }
            }
        }
        Assembled { energy, grad, hess_values }
    }

    /// Add `shift · d_i` to each diagonal entry `i`.
    pub fn add_to_diagonal(&self, values: &mut [f64], d: &[f64], shift: f64) {
        for (i, &s) in self.diag_slot.iter().enumerate() {
            values[s as usize] += shift * d[i];
        }
    }

    /// `y = A x` for the symmetric matrix whose lower triangle holds `values`.
    pub fn sym_matvec(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        let (cp, ri) = (self.symbolic.col_ptr(), self.symbolic.row_idx());
        for j in 0..x.len() {
            let xj = x[j];
            let mut acc = 0.0;
            for s in cp[j]..cp[j + 1] {
                let (i, v) = (ri[s], values[s]);
                if i == j {
                    acc += v * xj;
                } else {
                    y[i] += v * xj;
                    acc += v * x[i];
                }
            }
            y[j] += acc;
        }
    }

    /// The diagonal entries of assembled values.
    pub fn diagonal(&self, values: &[f64]) -> Vec<f64> {
        self.diag_slot.iter().map(|&s| values[s as usize]).collect()
    }

    /// Entries of the Hessian pattern (lower triangle).
    pub fn n_values(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    /// Owned sparse matrix (lower triangle) with the given values.
    ///
    /// # Errors
    /// [`CrossfieldError::Linalg`] when the value count does not match.
    pub fn matrix(&self, values: Vec<f64>) -> Result<SparseMatrix, CrossfieldError> {
        if values.len() != self.symbolic.row_idx().len() {
            return Err(CrossfieldError::Linalg(crate::linalg::LinalgError::PatternMismatch {
                expected: self.symbolic.row_idx().len(),
                got: values.len(),
            }));
        }
        Ok(SparseMatrix::new(self.symbolic.clone(), values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crossfield::energy::total_energy;
    use crate::mesh::fixtures;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// The vertex-dissection order keeps each edge's two unknowns together
    /// and leaves a fill within 20 % of METIS run on the edges' own graph
    /// (the independent reference), and far below the natural order's.
    #[test]
    fn vertex_dissection_order_fills_like_the_edge_graph_dissection() {
        use crate::linalg::{FillOrdering, SupernodalCholesky};
        let mesh = fixtures::icosphere(5);
        let topo = Topology::new(&mesh);
        let disc = Discretization::new(&mesh, &topo, 4);
        let fixed = vec![false; topo.n_edges()];
        let sys = NewtonSystem::new(&topo, &disc, &fixed).unwrap();
        let order = sys.vertex_dissection_order(&topo).unwrap();
        assert_eq!(order.len(), sys.n_dofs());
        assert!(order.chunks(2).all(|p| p[0] % 2 == 0 && p[1] == p[0] + 1), "pairs split");
        let a = sys.matrix(vec![0.0; sys.n_values()]).unwrap();
        let fill = |o: FillOrdering| SupernodalCholesky::analyze_with(&a, o).unwrap().l_nnz();
        let ours = fill(FillOrdering::Given(order));
        let edges = fill(FillOrdering::NestedDissection { block: 2 });
        let natural = fill(FillOrdering::Given((0..sys.n_dofs()).collect()));
        assert!((ours as f64) < 1.2 * edges as f64, "{ours} vs {edges}");
        assert!(3 * ours < natural, "{ours} vs {natural}");
    }

    /// The assembled gradient and Hessian are the derivatives of the total
    /// discrete energy (3.27): central finite differences on a curved mesh
    /// with fixed edges and the weak term.
    #[test]
    fn assembled_gradient_and_hessian_match_finite_differences() {
        let mesh = fixtures::icosphere(1);
        let topo = Topology::new(&mesh);
        let disc = Discretization::new(&mesh, &topo, 4);
        let fixed: Vec<bool> = (0..topo.n_edges()).map(|e| e % 7 == 0).collect();
        let weak: Vec<bool> = (0..topo.n_edges()).map(|e| e % 5 == 0).collect();
        let sys = NewtonSystem::new(&topo, &disc, &fixed).unwrap();
        let mut rng = StdRng::seed_from_u64(11);
        let f: Vec<C64> =
            (0..topo.n_edges()).map(|_| C64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))).collect();
        let params = EnergyParams { inv_eps2: 1.0 / 0.3f64.powi(2), weak_coef: 2.0, weak_edges: &weak };
        let asm = sys.assemble(&topo, &disc, &f, &params, HessianKind::Exact);
        assert!((asm.energy - total_energy(&disc, &topo, &f, &params)).abs() < 1e-10 * asm.energy.abs());
        let h_full = sys.matrix(asm.hess_values.clone()).unwrap().to_dense();
        let perturbed = |i: usize, s: f64| {
            let mut g = f.clone();
            let e = sys.free_edges[i / 2] as usize;
            if i.is_multiple_of(2) {
                g[e].re += s
            } else {
                g[e].im += s
            }
            g
        };
        let h = 1e-6;
        for i in (0..sys.n_dofs()).step_by(7) {
            let (fp, fm) = (perturbed(i, h), perturbed(i, -h));
            let fd = (total_energy(&disc, &topo, &fp, &params) - total_energy(&disc, &topo, &fm, &params)) / (2.0 * h);
            assert!((fd - asm.grad[i]).abs() < 1e-5 * (1.0 + fd.abs()), "grad {i}");
            let gp = sys.assemble(&topo, &disc, &fp, &params, HessianKind::Exact).grad;
            let gm = sys.assemble(&topo, &disc, &fm, &params, HessianKind::Exact).grad;
            for j in 0..sys.n_dofs() {
                let fdh = (gp[j] - gm[j]) / (2.0 * h);
                let (r, c) = if j >= i { (j, i) } else { (i, j) };
                assert!(
                    (fdh - h_full[(r, c)]).abs() < 1e-4 * (1.0 + fdh.abs()),
                    "hess ({j}, {i}): {fdh} vs {}",
                    h_full[(r, c)]
                );
            }
        }
    }
}
