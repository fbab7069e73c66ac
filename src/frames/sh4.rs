//! Degree-4 spherical-harmonic representation of frames (Huang et al. 2011,
//! Ray et al. 2016, Palmer et al. 2020): a frame with axes `a_1, a_2, a_3`
//! is the polynomial `f(x) = Σ_k (a_k · x)⁴` on the unit sphere, i.e.
//! `x⁴ + y⁴ + z⁴` rotated (thesis (4.6)); its band-4 part is a 9-vector.
//!
//! **Basis.** Real orthonormal degree-4 harmonics `Y_{4,m}`, `m = −4..4`,
//! stored in that order (index `m + 4`), as Cartesian polynomials (see
//! [`sh4_basis`]). The Cartesian frame has the unit 9-vector
//! `(0, 0, 0, 0, √(7/12), 0, 0, 0, √(5/12))` ([`REFERENCE_SH9`]): the thesis's
//! decomposition `f̂ = (4√π/15)(Y40 + √(5/7) Y44) + 3/5` up to normalization.
//!
//! **Rotation, exactly.** By the addition theorem, the band-4 part of
//! `(a · x)⁴` is `λ Σ_m Y_{4m}(a) Y_{4m}(x)` for a constant `λ`, so the
//! 9-vector of the frame `R` is
//!
//! ```text
//! sh9(R) = C Σ_k Y4(R e_k),     C = √(7/12) · 8√π / 21,
//! ```
//!
//! with `C` fixed by the reference vector (`Σ_k Y40(e_k) = 21/(8√π)`). This
//! is the exact band-4 rotation (Wigner-D) of the reference vector, obtained
//! without Euler angles; [`band4_rotation_matrix`] gives the full 9×9 matrix
//! by an exact quadrature, and the tests check both against each other and
//! against a direct projection of `Σ (a_k · x)⁴`.
//!
//! **Projection onto the variety** (the closest frame to an arbitrary
//! 9-vector `s`, maximizing `⟨s, sh9(R)⟩` since `|sh9(R)| = 1`): Newton
//! iterations on the left perturbation `R ← exp([ω]ₓ) R`. The Jacobian
//! columns are `∂ sh9/∂ω_j = L_j sh9(R) = C Σ_k ∇Y4(a_k) · (e_j × a_k)` with
//! `L_j` the band-4 generators ([`band4_generators`]); by equivariance
//! `JᵀJ = (20/3) I` everywhere and `Jᵀ sh9(R) = 0`. The Hessian is
//! `½ sᵀ(L_i L_j + L_j L_i) sh9(R)`. Gauss–Newton alone (`ω = (3/20) Jᵀ s`)
//! converges linearly off the variety (measured: 40–1000 iterations for
//! random targets); Newton with a Gauss–Newton fallback takes 5–15. The
//! objective has local maxima off the variety; [`nearest_frame`] takes the
//! best of a warm start and a fixed set of starting rotations (measured on
//! 300 random and mixed targets: no miss against 60 random restarts).
//!
//! **Normal-aligned frames.** Frames with an axis along `n` are
//! `R_n Rz(θ)` with `R_n e_z = n`; `⟨s, sh9(R_n Rz(θ))⟩ = A + B cos 4θ +
//! C sin 4θ` (the z-rotation turns the `m = ±4` pair by `4θ` and fixes
//! `m = 0`), so the projection onto this family is closed-form
//! ([`nearest_normal_aligned_frame`]).

use super::quaternion::{Mat3, Quat, reorthonormalize, rotation_from_vector};
use crate::geom::Vec3;

/// The 9-vector of the Cartesian frame `x⁴ + y⁴ + z⁴` (unit norm).
pub const REFERENCE_SH9: [f64; 9] =
    [0.0, 0.0, 0.0, 0.0, 0.763_762_615_825_973_4, 0.0, 0.0, 0.0, 0.645_497_224_367_902_8];

const PI: f64 = std::f64::consts::PI;

/// Normalization constants of the basis (see [`sh4_basis`]).
struct Norms {
    c1: f64,
    c2: f64,
    c3: f64,
    c4: f64,
    c5: f64,
    c6: f64,
    c7: f64,
}

fn norms() -> Norms {
    Norms {
        c1: 0.75 * (35.0 / PI).sqrt(),
        c2: 0.75 * (35.0 / (2.0 * PI)).sqrt(),
        c3: 0.75 * (5.0 / PI).sqrt(),
        c4: 0.75 * (5.0 / (2.0 * PI)).sqrt(),
        c5: 3.0 / 16.0 * (1.0 / PI).sqrt(),
        c6: 3.0 / 8.0 * (5.0 / PI).sqrt(),
        c7: 3.0 / 16.0 * (35.0 / PI).sqrt(),
    }
}

/// The constant `C` of `sh9(R) = C Σ_k Y4(R e_k)`.
fn frame_constant() -> f64 {
    (7.0f64 / 12.0).sqrt() * 8.0 * PI.sqrt() / 21.0
}

/// The 9 real degree-4 harmonics at a unit vector `p`, order `m = −4..4`:
///
/// ```text
/// Y−4 = ¾√(35/π) xy(x² − y²)        Y1 = ¾√(5/2π) xz(7z² − 3)
/// Y−3 = ¾√(35/2π) (3x² − y²) yz     Y2 = ⅜√(5/π) (x² − y²)(7z² − 1)
/// Y−2 = ¾√(5/π) xy(7z² − 1)         Y3 = ¾√(35/2π) (x² − 3y²) xz
/// Y−1 = ¾√(5/2π) yz(7z² − 3)        Y4 = 3/16 √(35/π) (x⁴ − 6x²y² + y⁴)
/// Y0  = 3/16 √(1/π) (35z⁴ − 30z² + 3)
/// ```
///
/// (`r² = 1` substituted; the polynomials are evaluated in the homogeneous
/// forms used by [`sh4_basis_gradient`], which agree on the sphere.)
pub fn sh4_basis(p: &Vec3) -> [f64; 9] {
    let n = norms();
    let (x, y, z) = (p.x, p.y, p.z);
    let (x2, y2, z2) = (x * x, y * y, z * z);
    let r2 = x2 + y2 + z2;
    [
        n.c1 * x * y * (x2 - y2),
        n.c2 * (3.0 * x2 - y2) * y * z,
        n.c3 * x * y * (6.0 * z2 - x2 - y2),
        n.c4 * y * z * (4.0 * z2 - 3.0 * x2 - 3.0 * y2),
        n.c5 * (35.0 * z2 * z2 - 30.0 * z2 * r2 + 3.0 * r2 * r2),
        n.c4 * x * z * (4.0 * z2 - 3.0 * x2 - 3.0 * y2),
        n.c6 * (6.0 * x2 * z2 - x2 * x2 - 6.0 * y2 * z2 + y2 * y2),
        n.c2 * (x2 - 3.0 * y2) * x * z,
        n.c7 * (x2 * x2 - 6.0 * x2 * y2 + y2 * y2),
    ]
}

/// Gradients of the 9 polynomials of [`sh4_basis`] at `p`
/// (tangential parts are the surface gradients on the unit sphere).
pub fn sh4_basis_gradient(p: &Vec3) -> [[f64; 3]; 9] {
    let n = norms();
    let (x, y, z) = (p.x, p.y, p.z);
    let (x2, y2, z2) = (x * x, y * y, z * z);
    let r2 = x2 + y2 + z2;
    let s = |c: f64, g: [f64; 3]| g.map(|v| c * v);
    [
        s(n.c1, [3.0 * x2 * y - y2 * y, x2 * x - 3.0 * x * y2, 0.0]),
        s(n.c2, [6.0 * x * y * z, 3.0 * x2 * z - 3.0 * y2 * z, 3.0 * x2 * y - y2 * y]),
        s(n.c3, [6.0 * y * z2 - 3.0 * x2 * y - y2 * y, 6.0 * x * z2 - x2 * x - 3.0 * x * y2, 12.0 * x * y * z]),
        s(
            n.c4,
            [-6.0 * x * y * z, 4.0 * z2 * z - 3.0 * x2 * z - 9.0 * y2 * z, 12.0 * y * z2 - 3.0 * x2 * y - 3.0 * y2 * y],
        ),
        s(n.c5, [-60.0 * x * z2 + 12.0 * x * r2, -60.0 * y * z2 + 12.0 * y * r2, 80.0 * z2 * z - 48.0 * z * r2]),
        s(
            n.c4,
            [4.0 * z2 * z - 9.0 * x2 * z - 3.0 * y2 * z, -6.0 * x * y * z, 12.0 * x * z2 - 3.0 * x2 * x - 3.0 * x * y2],
        ),
        s(n.c6, [12.0 * x * z2 - 4.0 * x2 * x, -12.0 * y * z2 + 4.0 * y2 * y, 12.0 * x2 * z - 12.0 * y2 * z]),
        s(n.c2, [3.0 * x2 * z - 3.0 * y2 * z, -6.0 * x * y * z, x2 * x - 3.0 * x * y2]),
        s(n.c7, [4.0 * x2 * x - 12.0 * x * y2, -12.0 * x2 * y + 4.0 * y2 * y, 0.0]),
    ]
}

/// The 9-vector of the frame whose axes are the columns of `r`.
pub fn sh9_from_rotation(r: &Mat3) -> [f64; 9] {
    let c = frame_constant();
    let mut out = [0.0; 9];
    for k in 0..3 {
        let y = sh4_basis(&r.column(k).into_owned());
        for m in 0..9 {
            out[m] += c * y[m];
        }
    }
    out
}

/// The 9-vector of the frame with frame quaternion `q`.
pub fn sh9_from_quaternion(q: &Quat) -> [f64; 9] {
    sh9_from_rotation(&q.to_matrix())
}

/// `sh9(R)` and its 9×3 Jacobian for the left perturbation `exp([ω]ₓ) R`.
pub fn sh9_with_jacobian(r: &Mat3) -> ([f64; 9], [[f64; 3]; 9]) {
    let c = frame_constant();
    let mut val = [0.0; 9];
    let mut jac = [[0.0; 3]; 9];
    for k in 0..3 {
        let a = r.column(k).into_owned();
        let y = sh4_basis(&a);
        let g = sh4_basis_gradient(&a);
        // e_j × a for j = x, y, z.
        let t = [[0.0, -a.z, a.y], [a.z, 0.0, -a.x], [-a.y, a.x, 0.0]];
        for m in 0..9 {
            val[m] += c * y[m];
            for j in 0..3 {
                jac[m][j] += c * (g[m][0] * t[j][0] + g[m][1] * t[j][1] + g[m][2] * t[j][2]);
            }
        }
    }
    (val, jac)
}

/// `⟨a, b⟩` of 9-vectors.
#[inline]
pub fn dot9(a: &[f64; 9], b: &[f64; 9]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Result of projecting a 9-vector onto the octahedral variety.
#[derive(Debug, Clone, Copy)]
pub struct Projection {
    /// The frame (columns are its axes).
    pub rotation: Mat3,
    /// Its 9-vector `sh9(rotation)`.
    pub sh9: [f64; 9],
    /// `⟨s, sh9(rotation)⟩`, the maximized objective (≤ |s|).
    pub alignment: f64,
    /// Gauss–Newton iterations used.
    pub iterations: usize,
}

/// The band-4 generators `L_x, L_y, L_z` (9×9, skew-symmetric): the
/// derivatives at 0 of `ε ↦ D(exp(ε [e_j]ₓ))`, so that
/// `∂ sh9(exp([ω]ₓ) R)/∂ω_j = L_j sh9(R)` and `[L_x, L_y] = L_z`.
/// Computed once by the exact quadrature
/// `(L_j)_{m'm} = −∫ Y_{m'}(x) ∇Y_m(x) · (e_j × x) dx` (degree 8).
pub fn band4_generators() -> &'static [[[f64; 9]; 9]; 3] {
    static GEN: std::sync::OnceLock<[[[f64; 9]; 9]; 3]> = std::sync::OnceLock::new();
    GEN.get_or_init(|| {
        let mut l = [[[0.0; 9]; 9]; 3];
        for (x, w) in sphere_quadrature_degree9() {
            let y = sh4_basis(&x);
            let g = sh4_basis_gradient(&x);
            let t = [Vec3::x().cross(&x), Vec3::y().cross(&x), Vec3::z().cross(&x)];
            for j in 0..3 {
                for mp in 0..9 {
                    for m in 0..9 {
                        let d = g[m][0] * t[j].x + g[m][1] * t[j].y + g[m][2] * t[j].z;
                        l[j][mp][m] -= w * y[mp] * d;
                    }
                }
            }
        }
        l
    })
}

#[cfg(test)]
fn mat9_vec(m: &[[f64; 9]; 9], v: &[f64; 9]) -> [f64; 9] {
    std::array::from_fn(|i| (0..9).map(|j| m[i][j] * v[j]).sum())
}

/// The nonzero entries `(row, col, value)` of the three generators (about
/// a fifth of the 81 entries each), for fast products.
fn sparse_generators() -> &'static [Vec<(u8, u8, f64)>; 3] {
    static SPARSE: std::sync::OnceLock<[Vec<(u8, u8, f64)>; 3]> = std::sync::OnceLock::new();
    SPARSE.get_or_init(|| {
        let l = band4_generators();
        std::array::from_fn(|j| {
            let mut v = Vec::new();
            for a in 0..9 {
                for b in 0..9 {
                    if l[j][a][b].abs() > 1e-12 {
                        v.push((a as u8, b as u8, l[j][a][b]));
                    }
                }
            }
            v
        })
    })
}

fn sparse_mat9_vec(m: &[(u8, u8, f64)], v: &[f64; 9]) -> [f64; 9] {
    let mut out = [0.0; 9];
    for &(a, b, x) in m {
        out[a as usize] += x * v[b as usize];
    }
    out
}

/// Gradient and Hessian of `ω ↦ ⟨s, sh9(exp([ω]ₓ) R)⟩` at `ω = 0`, with
/// `t = sh9(R)`: `g_i = sᵀ L_i t`, `H_ij = ½ sᵀ (L_i L_j + L_j L_i) t`.
fn gradient_hessian(s: &[f64; 9], t: &[f64; 9]) -> (Vec3, [[f64; 3]; 3]) {
    let l = sparse_generators();
    let lt: [[f64; 9]; 3] = std::array::from_fn(|i| sparse_mat9_vec(&l[i], t));
    let ls: [[f64; 9]; 3] = std::array::from_fn(|i| sparse_mat9_vec(&l[i], s));
    let g = Vec3::new(dot9(s, &lt[0]), dot9(s, &lt[1]), dot9(s, &lt[2]));
    // sᵀ L_i L_j t = −(L_i s) · (L_j t) (L_i is skew).
    let mut h = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            h[i][j] = -0.5 * (dot9(&ls[i], &lt[j]) + dot9(&ls[j], &lt[i]));
        }
    }
    (g, h)
}

/// Newton step `−H⁻¹ g` when `−H` is positive definite (Cholesky), else `None`.
fn newton_step(g: &Vec3, h: &[[f64; 3]; 3]) -> Option<Vec3> {
    let a = nalgebra::Matrix3::from_fn(|i, j| -h[i][j]);
    let chol = a.cholesky()?;
    let w = chol.solve(g);
    if w.iter().all(|x| x.is_finite()) { Some(w) } else { None }
}

/// Local projection of `s` onto the variety from the starting frame
/// `start`: maximizes `⟨s, sh9(R)⟩` over `R ← exp([ω]ₓ) R` by Newton steps
/// (exact Hessian from the band-4 generators) where the objective is
/// locally concave, Gauss–Newton steps `ω = (3/20) g` elsewhere, halving a
/// step that does not increase the objective. Stops when the step is below
/// `tol` radians or after `max_iter` iterations. Converges quadratically
/// near a non-degenerate maximum (Gauss–Newton alone is linear off the
/// variety, with hundreds of iterations for flat maxima).
pub fn project_from(s: &[f64; 9], start: &Mat3, max_iter: usize, tol: f64) -> Projection {
    let mut r = *start;
    let mut val = sh9_from_rotation(&r);
    let mut f = dot9(s, &val);
    let mut it = 0;
    while it < max_iter {
        it += 1;
        let (g, h) = gradient_hessian(s, &val);
        let gn = g * (3.0 / 20.0);
        let w = match newton_step(&g, &h) {
            Some(w) if w.norm() <= 1.0 => w,
            _ => gn,
        };
        let mut step = 1.0;
        let mut accepted = false;
        let mut dir = w;
        for attempt in 0..12 {
            let cand = reorthonormalize(&(rotation_from_vector(&(dir * step)) * r));
            let v2 = sh9_from_rotation(&cand);
            let f2 = dot9(s, &v2);
            if f2 >= f - 1e-15 * f.abs().max(1e-300) {
                r = cand;
                val = v2;
                f = f2;
                accepted = true;
                break;
            }
            // After two failed halvings of a Newton step, fall back to GN.
            if attempt == 1 && dir != gn {
                dir = gn;
                step = 1.0;
            } else {
                step *= 0.5;
            }
        }
        if !accepted || dir.norm() * step < tol {
            break;
        }
    }
    Projection { rotation: r, sh9: val, alignment: f, iterations: it }
}

/// Fixed starting frames for the global search: the identity and quarter-
/// or third-turn-sized rotations spread over the fundamental domain of the
/// octahedral group.
fn global_starts() -> Vec<Mat3> {
    let t = std::f64::consts::FRAC_PI_6;
    let mut out = vec![Mat3::identity()];
    for axis in
        [Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, 1.0, -1.0), Vec3::new(1.0, -1.0, 1.0), Vec3::new(-1.0, 1.0, 1.0)]
    {
        out.push(rotation_from_vector(&(axis.normalize() * t)));
    }
    for axis in [Vec3::x(), Vec3::y(), Vec3::z()] {
        out.push(rotation_from_vector(&(axis * std::f64::consts::FRAC_PI_4)));
    }
    out
}

/// The frame closest to `s`: the best of the local projections from `hint`
/// (when given) and from the fixed starts, unless the hint's projection is
/// already aligned to within `accept` of `|s|` (then it alone is used).
/// Newton stops at steps below 1e-12 rad.
pub fn nearest_frame(s: &[f64; 9], hint: Option<&Mat3>, accept: f64) -> Projection {
    nearest_frame_to_tolerance(s, hint, accept, 1e-12)
}

/// [`nearest_frame`] with the Newton step tolerance `tol` (radians).
pub fn nearest_frame_to_tolerance(s: &[f64; 9], hint: Option<&Mat3>, accept: f64, tol: f64) -> Projection {
    let norm = dot9(s, s).sqrt();
    let mut best: Option<Projection> = None;
    if let Some(h) = hint {
        let p = project_from(s, h, 50, tol);
        if p.alignment >= (1.0 - accept) * norm {
            return p;
        }
        best = Some(p);
    }
    for start in global_starts() {
        let p = project_from(s, &start, 50, tol);
        if best.as_ref().is_none_or(|b| p.alignment > b.alignment) {
            best = Some(p);
        }
    }
    best.unwrap_or_else(|| project_from(s, &Mat3::identity(), 50, tol))
}

/// The frame quaternion (unit, `q0 ≥ 0`) of the frame closest to the
/// 9-vector `s` (global search): the inverse of [`sh9_from_quaternion`] up
/// to the octahedral group.
pub fn quaternion_from_sh9(s: &[f64; 9]) -> Quat {
    Quat::from_matrix(&nearest_frame(s, None, 0.0).rotation)
}

/// A rotation `R_n` with `R_n e_z = n` (`−n` when `n_z < 0`, the same
/// family of frames), the shortest rotation from `e_z` (thesis §4.2).
pub fn z_to_axis_rotation(n: &Vec3) -> Mat3 {
    let n = n.normalize();
    let n = if n.z < 0.0 { -n } else { n };
    let a = (0.5 * (1.0 + n.z)).sqrt();
    let b = 1.0 / (2.0 * (1.0 + n.z)).sqrt();
    Quat::new(a, -n.y * b, n.x * b, 0.0).to_matrix()
}

/// The frame `R_n Rz(θ)`: an axis along `n`, turned by `theta` about it.
pub fn normal_aligned_frame(n: &Vec3, theta: f64) -> Mat3 {
    z_to_axis_rotation(n) * rotation_from_vector(&(Vec3::z() * theta))
}

/// The frame with an axis along `n` closest to `s` and its angle `θ`:
/// maximizes `A + B cos 4θ + C sin 4θ` in closed form (module docs).
pub fn nearest_normal_aligned_frame(s: &[f64; 9], n: &Vec3) -> (Projection, f64) {
    let base = z_to_axis_rotation(n);
    let at = |theta: f64| {
        let r = base * rotation_from_vector(&(Vec3::z() * theta));
        let v = sh9_from_rotation(&r);
        (dot9(s, &v), r, v)
    };
    let (v0, _, _) = at(0.0);
    let (v1, _, _) = at(PI / 8.0);
    let (v2, _, _) = at(PI / 4.0);
    let a = 0.5 * (v0 + v2);
    let (b, c) = (0.5 * (v0 - v2), v1 - a);
    let theta = 0.25 * c.atan2(b);
    let (f, r, v) = at(theta);
    (Projection { rotation: r, sh9: v, alignment: f, iterations: 0 }, theta)
}

/// A product quadrature on the unit sphere exact for polynomials of degree
/// ≤ 9: 5-point Gauss–Legendre in `z` times 10 equispaced longitudes.
/// Returns `(point, weight)` pairs (weights sum to 4π).
pub fn sphere_quadrature_degree9() -> Vec<(Vec3, f64)> {
    const Z: [f64; 5] =
        [-0.906_179_845_938_664, -0.538_469_310_105_683_1, 0.0, 0.538_469_310_105_683_1, 0.906_179_845_938_664];
    const W: [f64; 5] = [
        0.236_926_885_056_189_1,
        0.478_628_670_499_366_5,
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
    ];
    let m = 10;
    let mut out = Vec::with_capacity(5 * m);
    for (z, w) in Z.iter().zip(W) {
        let rho = (1.0 - z * z).sqrt();
        for k in 0..m {
            let phi = 2.0 * PI * (k as f64 + 0.5) / m as f64;
            out.push((Vec3::new(rho * phi.cos(), rho * phi.sin(), *z), w * 2.0 * PI / m as f64));
        }
    }
    out
}

/// The 9×9 band-4 rotation (real Wigner-D) matrix `D(R)`, with
/// `D_{m'm} = ∫ Y_{m'}(x) Y_m(Rᵀ x) dx` by an exact quadrature: the
/// coefficients of `g(Rᵀ x)` are `D(R)` times those of `g`, and
/// `sh9(R) = D(R) · REFERENCE_SH9`.
pub fn band4_rotation_matrix(r: &Mat3) -> [[f64; 9]; 9] {
    let mut d = [[0.0; 9]; 9];
    let rt = r.transpose();
    for (x, w) in sphere_quadrature_degree9() {
        let a = sh4_basis(&x);
        let b = sh4_basis(&(rt * x));
        for i in 0..9 {
            for j in 0..9 {
                d[i][j] += w * a[i] * b[j];
            }
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::super::groups::cube_rotations;
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn random_rotation(rng: &mut StdRng) -> Mat3 {
        let q = Quat::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        q.normalized().to_matrix()
    }

    fn dist9(a: &[f64; 9], b: &[f64; 9]) -> f64 {
        a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
    }

    #[test]
    fn basis_is_orthonormal_and_gradient_matches_differences() {
        let quad = sphere_quadrature_degree9();
        let mut gram = [[0.0; 9]; 9];
        for (x, w) in &quad {
            let y = sh4_basis(x);
            for i in 0..9 {
                for j in 0..9 {
                    gram[i][j] += w * y[i] * y[j];
                }
            }
        }
        for i in 0..9 {
            for j in 0..9 {
                assert!((gram[i][j] - if i == j { 1.0 } else { 0.0 }).abs() < 1e-13, "({i},{j}) {}", gram[i][j]);
            }
        }
        let p = Vec3::new(0.3, -0.5, 0.81);
        let g = sh4_basis_gradient(&p);
        let h = 1e-6;
        for d in 0..3 {
            let mut e = Vec3::zeros();
            e[d] = h;
            let (yp, ym) = (sh4_basis(&(p + e)), sh4_basis(&(p - e)));
            for m in 0..9 {
                assert!(((yp[m] - ym[m]) / (2.0 * h) - g[m][d]).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn reference_vector_is_the_projection_of_x4_y4_z4() {
        assert!(dist9(&sh9_from_rotation(&Mat3::identity()), &REFERENCE_SH9) < 1e-15);
        // Independent check: project Σ (a_k · x)⁴ by quadrature, normalize.
        let mut rng = StdRng::seed_from_u64(51);
        for _ in 0..20 {
            let r = random_rotation(&mut rng);
            let mut c = [0.0; 9];
            for (x, w) in sphere_quadrature_degree9() {
                let f: f64 = (0..3).map(|k| r.column(k).dot(&x).powi(4)).sum();
                let y = sh4_basis(&x);
                for m in 0..9 {
                    c[m] += w * f * y[m];
                }
            }
            let n = dot9(&c, &c).sqrt();
            let c = c.map(|v| v / n);
            assert!(dist9(&c, &sh9_from_rotation(&r)) < 1e-13);
            // The full band-4 rotation agrees and is orthogonal.
            let d = band4_rotation_matrix(&r);
            let mut dr = [0.0; 9];
            for i in 0..9 {
                dr[i] = (0..9).map(|j| d[i][j] * REFERENCE_SH9[j]).sum();
                for k in 0..9 {
                    let dd: f64 = (0..9).map(|j| d[i][j] * d[k][j]).sum();
                    assert!((dd - if i == k { 1.0 } else { 0.0 }).abs() < 1e-13);
                }
            }
            assert!(dist9(&dr, &sh9_from_rotation(&r)) < 1e-13);
        }
    }

    #[test]
    fn sh9_is_invariant_under_the_24_cube_rotations() {
        let mut rng = StdRng::seed_from_u64(52);
        for _ in 0..50 {
            let r = random_rotation(&mut rng);
            let s = sh9_from_rotation(&r);
            assert!((dot9(&s, &s) - 1.0).abs() < 1e-14);
            for o in cube_rotations() {
                assert!(dist9(&sh9_from_rotation(&(r * o)), &s) < 1e-14);
            }
            // A rotation outside O changes it.
            let t = r * rotation_from_vector(&Vec3::new(0.1, 0.2, 0.05));
            assert!(dist9(&sh9_from_rotation(&t), &s) > 1e-3);
        }
    }

    #[test]
    fn jacobian_matches_finite_differences_and_jtj_is_20_over_3() {
        let mut rng = StdRng::seed_from_u64(53);
        let r = random_rotation(&mut rng);
        let (v, j) = sh9_with_jacobian(&r);
        let h = 1e-6;
        for d in 0..3 {
            let mut w = Vec3::zeros();
            w[d] = h;
            let vp = sh9_from_rotation(&(rotation_from_vector(&w) * r));
            let vm = sh9_from_rotation(&(rotation_from_vector(&(-w)) * r));
            for m in 0..9 {
                assert!(((vp[m] - vm[m]) / (2.0 * h) - j[m][d]).abs() < 1e-8);
            }
        }
        for a in 0..3 {
            let jv: f64 = (0..9).map(|m| j[m][a] * v[m]).sum();
            assert!(jv.abs() < 1e-13);
            for b in 0..3 {
                let jj: f64 = (0..9).map(|m| j[m][a] * j[m][b]).sum();
                assert!((jj - if a == b { 20.0 / 3.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn generators_are_skew_satisfy_the_lie_bracket_and_give_the_jacobian() {
        let l = band4_generators();
        let mul = |a: &[[f64; 9]; 9], b: &[[f64; 9]; 9]| -> [[f64; 9]; 9] {
            std::array::from_fn(|i| std::array::from_fn(|j| (0..9).map(|k| a[i][k] * b[k][j]).sum()))
        };
        for j in 0..3 {
            for a in 0..9 {
                for b in 0..9 {
                    assert!((l[j][a][b] + l[j][b][a]).abs() < 1e-13);
                }
            }
        }
        for (x, y, z) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)] {
            let (p, q) = (mul(&l[x], &l[y]), mul(&l[y], &l[x]));
            for a in 0..9 {
                for b in 0..9 {
                    assert!((p[a][b] - q[a][b] - l[z][a][b]).abs() < 1e-12);
                }
            }
        }
        // Casimir: L_x² + L_y² + L_z² = −l(l+1) I = −20 I on band 4.
        let c: Vec<[[f64; 9]; 9]> = (0..3).map(|j| mul(&l[j], &l[j])).collect();
        for a in 0..9 {
            for b in 0..9 {
                let v = c[0][a][b] + c[1][a][b] + c[2][a][b];
                assert!((v - if a == b { -20.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        let mut rng = StdRng::seed_from_u64(57);
        let r = random_rotation(&mut rng);
        let (t, jac) = sh9_with_jacobian(&r);
        for j in 0..3 {
            let lt = mat9_vec(&l[j], &t);
            for m in 0..9 {
                assert!((lt[m] - jac[m][j]).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn newton_projection_converges_in_few_iterations() {
        let mut rng = StdRng::seed_from_u64(58);
        let mut total = 0;
        for _ in 0..50 {
            let mut s = [0.0; 9];
            for _ in 0..3 {
                let v = sh9_from_rotation(&random_rotation(&mut rng));
                let w: f64 = rng.random_range(0.2..1.0);
                for m in 0..9 {
                    s[m] += w * v[m];
                }
            }
            let p = project_from(&s, &random_rotation(&mut rng), 100, 1e-12);
            total += p.iterations;
            let (g, _) = gradient_hessian(&s, &p.sh9);
            assert!(g.norm() < 1e-9, "gradient {} after {} iterations", g.norm(), p.iterations);
        }
        assert!(total < 50 * 30, "mean iterations {}", total as f64 / 50.0);
    }

    #[test]
    fn projection_round_trip_recovers_the_frame_up_to_o() {
        let mut rng = StdRng::seed_from_u64(54);
        for _ in 0..100 {
            let r = random_rotation(&mut rng);
            let s = sh9_from_rotation(&r);
            // Quaternion ↔ 9-vector, up to the 48 elements of O.
            let q = quaternion_from_sh9(&s);
            let q_in = Quat::from_matrix(&r);
            let best = super::super::groups::binary_octahedral_group()
                .iter()
                .map(|o| q_in.mul(o).dot(&q).abs())
                .fold(0.0, f64::max);
            assert!((best - 1.0).abs() < 1e-12, "{best}");
            let p = nearest_frame(&s, None, 1e-9);
            assert!((p.alignment - 1.0).abs() < 1e-12);
            // rᵀ p.rotation must be a cube rotation.
            let o = r.transpose() * p.rotation;
            assert!(cube_rotations().iter().any(|c| (c - o).norm() < 1e-6), "{o}");
        }
    }

    #[test]
    fn global_projection_beats_or_matches_random_local_searches() {
        // Off-variety targets (sums of frames, as after diffusion).
        let mut rng = StdRng::seed_from_u64(55);
        let mut worse = 0;
        for _ in 0..100 {
            let k = rng.random_range(2..5);
            let mut s = [0.0; 9];
            for _ in 0..k {
                let w: f64 = rng.random_range(0.1..1.0);
                let v = sh9_from_rotation(&random_rotation(&mut rng));
                for m in 0..9 {
                    s[m] += w * v[m];
                }
            }
            let best = nearest_frame(&s, None, 0.0);
            let mut reference = f64::NEG_INFINITY;
            for _ in 0..30 {
                reference = reference.max(project_from(&s, &random_rotation(&mut rng), 100, 1e-12).alignment);
            }
            if best.alignment < reference - 1e-9 {
                worse += 1;
            }
        }
        assert!(worse <= 2, "{worse} of 100 projections missed the best of 30 random starts");
    }

    #[test]
    fn normal_aligned_projection_is_exact_on_the_family() {
        let mut rng = StdRng::seed_from_u64(56);
        for _ in 0..50 {
            let n = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
                .normalize();
            let theta = rng.random_range(-3.0..3.0);
            let r = normal_aligned_frame(&n, theta);
            assert!(r.column(2).dot(&n).abs() > 1.0 - 1e-14);
            let s = sh9_from_rotation(&r);
            let (p, _) = nearest_normal_aligned_frame(&s, &n);
            assert!(dist9(&p.sh9, &s) < 1e-12);
            // For a general target, no sampled angle does better.
            let t = sh9_from_rotation(&random_rotation(&mut rng));
            let (q, _) = nearest_normal_aligned_frame(&t, &n);
            for k in 0..64 {
                let th = k as f64 * PI / 128.0;
                assert!(dot9(&t, &sh9_from_rotation(&normal_aligned_frame(&n, th))) <= q.alignment + 1e-12);
            }
        }
    }
}
