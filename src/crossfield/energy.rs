//! The discrete Ginzburg–Landau energy (thesis (3.15), with the weak boundary
//! term (3.27)), its gradient and Hessian on Crouzeix–Raviart unknowns.
//!
//! Unknowns: `f_p ∈ ℂ` per edge, in the edge frame (see [`super::frames`]);
//! as real unknowns `(Re f_p, Im f_p)`. In triangle `T` with local edges
//! `k = 0, 1, 2`, `F_k = r_{T,k} f_{p(k)}` are the values in `T`'s frame and
//! the field is `F = Σ_k ω_k F_k` (CR shape functions). Per triangle
//!
//! ```text
//! E_T = ½ Σ_jk S_jk Re(F̄_j F_k)  +  A/(4ε²) · qᵀ M₂ q,   q_m = |U_m|² − 1,
//! ```
//!
//! where `U_m = Σ_k c_mk F_k` is the field at the 6 P2 nodes (corners and
//! midpoints, [`P2_NODE_FROM_CR`]) and `M₂` the P2 mass matrix over the area.
//! `|F|² − 1` is quadratic on `T`, so this integrates the quartic penalty
//! exactly (no quadrature error). The weak term on aligned edges is the CR
//! midpoint rule `κ/2 · ℓ_p |f_p − 1|²` with `κ = w L / ε²` (`L` the
//! bounding-box diagonal, `w` the user weight): (3.27) evaluated at the CR
//! degree of freedom, which is where CR fields are continuous.
//!
//! Derivatives (derived here; the thesis' (3.21) has typos). With `F_k` as
//! real 2-vectors and `U_m = Σ_k c_mk F_k`:
//!
//! ```text
//! ∂E_T/∂F_k   = Σ_j S_kj F_j + (A/ε²) Σ_m (M₂q)_m c_mk U_m
//! ∂²E_T/∂F_k∂F_l = S_kl I + (2A/ε²) Σ_mn M₂_mn c_mk c_nl U_m U_nᵀ
//!                  + (A/ε²) Σ_m (M₂q)_m c_mk c_ml I
//! ```
//!
//! and in edge-frame unknowns `g_k = R_kᵀ ∂E/∂F_k`, `h_kl = R_kᵀ H_kl R_l`
//! (`R_k` the 2×2 rotation of multiplication by `r_{T,k}`). The first two
//! Hessian terms are positive semi-definite; the last is indefinite where
//! `|F| < 1` (`M₂q < 0`). The *modified* Hessian replaces `(M₂q)_m` by
//! `max((M₂q)_m, 0)`, which makes every element matrix positive
//! semi-definite (a positive-definite modification used by the safeguarded
//! Newton method, see [`super::newton`]).

use super::frames::{C64, Discretization, FaceData};
use crate::fem::crouzeix_raviart::{P2_MASS_OVER_AREA, P2_NODE_FROM_CR};
use crate::mesh::Topology;
use rayon::prelude::*;

/// Which Hessian to assemble.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HessianKind {
    /// The exact second derivative of the discrete energy.
    Exact,
    /// The positive semi-definite modification (negative `M₂q` clamped to 0).
    Modified,
}

/// Energy, gradient and Hessian of one triangle in its own frame.
#[derive(Debug, Clone, Copy)]
pub struct ElementResult {
    /// Energy of the triangle.
    pub energy: f64,
    /// Gradient with respect to `(Re f_k, Im f_k)`, edge frames.
    pub grad: [f64; 6],
    /// Hessian with respect to `(Re f_k, Im f_k)`, edge frames, full 6×6.
    pub hess: [[f64; 6]; 6],
}

/// `F_k = r_k f_k`: edge-frame values to the triangle frame.
#[inline]
pub fn to_face_frame(fd: &FaceData, f: [C64; 3]) -> [C64; 3] {
    [fd.rot[0] * f[0], fd.rot[1] * f[1], fd.rot[2] * f[2]]
}

/// Field values at the 6 P2 nodes.
#[inline]
fn node_values(big_f: &[C64; 3]) -> [C64; 6] {
    let mut u = [C64::new(0.0, 0.0); 6];
    for (m, um) in u.iter_mut().enumerate() {
        let c = P2_NODE_FROM_CR[m];
        *um = big_f[0] * c[0] + big_f[1] * c[1] + big_f[2] * c[2];
    }
    u
}

/// `M₂ q` and `qᵀ M₂ q` for `q_m = |U_m|² − 1` (mass matrix over the area).
#[inline]
fn penalty_moments(u: &[C64; 6]) -> ([f64; 6], f64) {
    let q: [f64; 6] = std::array::from_fn(|m| u[m].norm_sqr() - 1.0);
    let mut mq = [0.0; 6];
    let mut qmq = 0.0;
    for m in 0..6 {
        let row = &P2_MASS_OVER_AREA[m];
        let s = row[0] * q[0] + row[1] * q[1] + row[2] * q[2] + row[3] * q[3] + row[4] * q[4] + row[5] * q[5];
        mq[m] = s;
        qmq += q[m] * s;
    }
    (mq, qmq)
}

/// Energy of one triangle for edge-frame values `f` and `inv_eps2 = 1/ε²`.
#[inline]
pub fn element_energy(fd: &FaceData, f: [C64; 3], inv_eps2: f64) -> f64 {
    if fd.area == 0.0 {
        return 0.0;
    }
    let big_f = to_face_frame(fd, f);
    let s = &fd.stiffness;
    let mut dir = 0.0;
    for j in 0..3 {
        for k in 0..3 {
            dir += s[j][k] * (big_f[j].conj() * big_f[k]).re;
        }
    }
    if inv_eps2 == 0.0 {
        return 0.5 * dir;
    }
    let u = node_values(&big_f);
    let (_, qmq) = penalty_moments(&u);
    0.5 * dir + 0.25 * fd.area * inv_eps2 * qmq
}

/// Energy, gradient and Hessian of one triangle (edge-frame unknowns): the
/// element vector and matrix of the Newton step (thesis (3.21), (3.20), as
/// corrected in the module doc), in the triangle frame, then rotated to the
/// edge frames (`k = Rᵀ K R`, `b = Rᵀ B`).
pub fn element_derivatives(fd: &FaceData, f: [C64; 3], inv_eps2: f64, kind: HessianKind) -> ElementResult {
    let mut out = ElementResult { energy: 0.0, grad: [0.0; 6], hess: [[0.0; 6]; 6] };
    if fd.area == 0.0 {
        return out;
    }
    let big_f = to_face_frame(fd, f);
    let (mut g, dir, mut h) = dirichlet_derivatives(&fd.stiffness, &big_f);
    let mut energy = 0.5 * dir;
    if inv_eps2 > 0.0 {
        energy += add_penalty_derivatives(fd.area * inv_eps2, &big_f, kind, &mut g, &mut h);
    }
    out.energy = energy;
    rotate_to_edge_frames(fd, &g, &h, &mut out);
    out
}

/// The Dirichlet term in the triangle frame: its gradient `Σ_j S_kj F_j`,
/// `Σ_k Re(F̄_k (S F)_k)` (twice its energy) and its Hessian `S_kl I`.
fn dirichlet_derivatives(s: &[[f64; 3]; 3], big_f: &[C64; 3]) -> ([C64; 3], f64, [[f64; 6]; 6]) {
    let mut g = [C64::new(0.0, 0.0); 3];
    let mut dir = 0.0;
    for k in 0..3 {
        for j in 0..3 {
            g[k] += big_f[j] * s[k][j];
        }
        dir += (big_f[k].conj() * g[k]).re;
    }
    let mut h = [[0.0; 6]; 6];
    for k in 0..3 {
        for l in 0..3 {
            h[2 * k][2 * l] = s[k][l];
            h[2 * k + 1][2 * l + 1] = s[k][l];
        }
    }
    (g, dir, h)
}

/// Add the penalty's gradient and Hessian (module doc, `a = A/ε²`) to `g`
/// and `h` (triangle frame; `kind` chooses the exact or the modified last
/// term); returns the penalty energy `a/4 · qᵀ M₂ q`.
fn add_penalty_derivatives(
    a: f64,
    big_f: &[C64; 3],
    kind: HessianKind,
    g: &mut [C64; 3],
    h: &mut [[f64; 6]; 6],
) -> f64 {
    let u = node_values(big_f);
    let (mq, qmq) = penalty_moments(&u);
    for m in 0..6 {
        let c = P2_NODE_FROM_CR[m];
        for k in 0..3 {
            g[k] += u[m] * (a * mq[m] * c[k]);
        }
    }
    add_node_outer_products(a, &u, h);
    add_weighted_mass(a, &mq, kind, h);
    // The V M₂ Vᵀ part was added to the lower triangle only: mirror it.
    for r in 0..6 {
        for c2 in 0..r {
            h[c2][r] = h[r][c2];
        }
    }
    0.25 * a * qmq
}

/// Add `2a V M₂ Vᵀ` to the lower triangle of `h`, with
/// `V[2k+c][m] = c_mk U_m[c]`: the `(2A/ε²) Σ_mn M₂_mn c_mk c_nl U_m U_nᵀ`
/// term (positive semi-definite).
fn add_node_outer_products(a: f64, u: &[C64; 6], h: &mut [[f64; 6]; 6]) {
    let mut v = [[0.0; 6]; 6];
    for m in 0..6 {
        let c = P2_NODE_FROM_CR[m];
        for k in 0..3 {
            v[2 * k][m] = c[k] * u[m].re;
            v[2 * k + 1][m] = c[k] * u[m].im;
        }
    }
    // P = V M₂.
    let mut pm = [[0.0; 6]; 6];
    for r in 0..6 {
        for n in 0..6 {
            let mut acc = 0.0;
            for m in 0..6 {
                acc += v[r][m] * P2_MASS_OVER_AREA[m][n];
            }
            pm[r][n] = acc;
        }
    }
    for r in 0..6 {
        for c2 in 0..=r {
            let mut acc = 0.0;
            for n in 0..6 {
                acc += pm[r][n] * v[c2][n];
            }
            h[r][c2] += 2.0 * a * acc;
        }
    }
}

/// Add `Σ_m w_m c_mk c_ml I` with `w_m = a (M₂q)_m` to `h`: the term that is
/// indefinite where `|F| < 1`, clamped at 0 for the modified Hessian.
fn add_weighted_mass(a: f64, mq: &[f64; 6], kind: HessianKind, h: &mut [[f64; 6]; 6]) {
    let mut d = [[0.0; 3]; 3];
    for m in 0..6 {
        let w = match kind {
            HessianKind::Exact => a * mq[m],
            HessianKind::Modified => a * mq[m].max(0.0),
        };
        let c = P2_NODE_FROM_CR[m];
        for k in 0..3 {
            for l in 0..3 {
                d[k][l] += w * c[k] * c[l];
            }
        }
    }
    for k in 0..3 {
        for l in 0..3 {
            h[2 * k][2 * l] += d[k][l];
            h[2 * k + 1][2 * l + 1] += d[k][l];
        }
    }
}

/// Rotate the triangle-frame gradient `g` and Hessian `h` to the edge
/// frames into `out`: `g_k = R_kᵀ G_k` (multiplication by `conj r_k`),
/// `h_kl = R_kᵀ H_kl R_l`.
fn rotate_to_edge_frames(fd: &FaceData, g: &[C64; 3], h: &[[f64; 6]; 6], out: &mut ElementResult) {
    for k in 0..3 {
        let gk = fd.rot[k].conj() * g[k];
        out.grad[2 * k] = gk.re;
        out.grad[2 * k + 1] = gk.im;
    }
    for k in 0..3 {
        let (ck, sk) = (fd.rot[k].re, fd.rot[k].im);
        for l in 0..3 {
            let (cl, sl) = (fd.rot[l].re, fd.rot[l].im);
            let b = [[h[2 * k][2 * l], h[2 * k][2 * l + 1]], [h[2 * k + 1][2 * l], h[2 * k + 1][2 * l + 1]]];
            // B R_l with R_l = [[cl, -sl], [sl, cl]].
            let br = [
                [b[0][0] * cl + b[0][1] * sl, -b[0][0] * sl + b[0][1] * cl],
                [b[1][0] * cl + b[1][1] * sl, -b[1][0] * sl + b[1][1] * cl],
            ];
            // R_kᵀ (B R_l) with R_kᵀ = [[ck, sk], [-sk, ck]].
            out.hess[2 * k][2 * l] = ck * br[0][0] + sk * br[1][0];
            out.hess[2 * k][2 * l + 1] = ck * br[0][1] + sk * br[1][1];
            out.hess[2 * k + 1][2 * l] = -sk * br[0][0] + ck * br[1][0];
            out.hess[2 * k + 1][2 * l + 1] = -sk * br[0][1] + ck * br[1][1];
        }
    }
}

/// Problem data that changes with ε: `1/ε²`, the weak-term coefficient and
/// which edges carry it.
#[derive(Debug, Clone, Copy)]
pub struct EnergyParams<'a> {
    /// `1/ε²` (0 disables the penalty: pure Dirichlet energy).
    pub inv_eps2: f64,
    /// `κ = w L / ε²` of the weak term, 0 for none.
    pub weak_coef: f64,
    /// Edges carrying the weak term (`f̄ = 1`).
    pub weak_edges: &'a [bool],
}

/// Total energy of the field `f` (all edges).
pub fn total_energy(disc: &Discretization, topo: &Topology, f: &[C64], p: &EnergyParams) -> f64 {
    const CHUNK: usize = 4096;
    let parts: Vec<f64> = disc
        .faces
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(ci, chunk)| {
            let base = ci * CHUNK;
            chunk
                .iter()
                .enumerate()
                .map(|(i, fd)| {
                    let fe = &topo.face_edges[base + i];
                    element_energy(fd, [f[fe[0].idx()], f[fe[1].idx()], f[fe[2].idx()]], p.inv_eps2)
                })
                .sum::<f64>()
        })
        .collect();
    let mut e: f64 = parts.iter().sum();
    if p.weak_coef > 0.0 {
        for (i, &w) in p.weak_edges.iter().enumerate() {
            if w {
                e += 0.5 * p.weak_coef * disc.length_per_edge[i] * (f[i] - C64::new(1.0, 0.0)).norm_sqr();
            }
        }
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::crouzeix_raviart::cr_stiffness;
    use crate::geom::Vec3;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn face(rng: &mut StdRng) -> FaceData {
        let p = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.2, 0.1), Vec3::new(0.3, 0.8, -0.2)];
        let area = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
        FaceData {
            area,
            stiffness: cr_stiffness(&p),
            rot: std::array::from_fn(|_| C64::from_polar(1.0, rng.random_range(0.0..6.3))),
        }
    }

    fn unpack(x: &[f64; 6]) -> [C64; 3] {
        std::array::from_fn(|k| C64::new(x[2 * k], x[2 * k + 1]))
    }

    #[test]
    fn element_gradient_and_hessian_match_finite_differences() {
        let mut rng = StdRng::seed_from_u64(7);
        for trial in 0..20 {
            let fd = face(&mut rng);
            let inv_eps2 = if trial == 0 { 0.0 } else { rng.random_range(0.5..50.0) };
            let x: [f64; 6] = std::array::from_fn(|_| rng.random_range(-1.2..1.2));
            let r = element_derivatives(&fd, unpack(&x), inv_eps2, HessianKind::Exact);
            assert!((r.energy - element_energy(&fd, unpack(&x), inv_eps2)).abs() < 1e-12);
            let h = 1e-6;
            for i in 0..6 {
                let mut xp = x;
                let mut xm = x;
                xp[i] += h;
                xm[i] -= h;
                let fdg = (element_energy(&fd, unpack(&xp), inv_eps2) - element_energy(&fd, unpack(&xm), inv_eps2))
                    / (2.0 * h);
                assert!((fdg - r.grad[i]).abs() < 1e-6 * (1.0 + fdg.abs()), "grad {i}: {fdg} vs {}", r.grad[i]);
                let gp = element_derivatives(&fd, unpack(&xp), inv_eps2, HessianKind::Exact).grad;
                let gm = element_derivatives(&fd, unpack(&xm), inv_eps2, HessianKind::Exact).grad;
                for j in 0..6 {
                    let fdh = (gp[j] - gm[j]) / (2.0 * h);
                    assert!((fdh - r.hess[j][i]).abs() < 1e-5 * (1.0 + fdh.abs()), "hess {j}{i}");
                }
            }
        }
    }

    #[test]
    fn modified_hessian_is_positive_semidefinite() {
        let mut rng = StdRng::seed_from_u64(3);
        for _ in 0..50 {
            let fd = face(&mut rng);
            let x: [f64; 6] = std::array::from_fn(|_| rng.random_range(-0.3..0.3));
            let r = element_derivatives(&fd, unpack(&x), 100.0, HessianKind::Modified);
            let m = nalgebra::Matrix6::from_fn(|i, j| r.hess[i][j]);
            let ev = m.symmetric_eigenvalues();
            assert!(ev.iter().all(|&l| l > -1e-9 * m.norm()), "{ev}");
            let e = element_derivatives(&fd, unpack(&x), 100.0, HessianKind::Exact);
            let me = nalgebra::Matrix6::from_fn(|i, j| e.hess[i][j]);
            // Small |F|: the exact Hessian is indefinite.
            assert!(me.symmetric_eigenvalues().min() < 0.0);
        }
    }
}
