//! Invariants of the frames that share one axis `n` (thesis §4.2, (4.27)
//! and (4.28)): the one-parameter family used for boundary alignment.
//!
//! In our conventions (frame quaternion `p`, coordinates (4.25) of `p*`,
//! see [`super::su2`]) the rotations about the Cartesian `x` axis act
//! diagonally on `(u, v)`, so the family is built around the frame's `x`
//! axis: `p = q_{x→n} q_x(α)` with `q_x(α) = cos(α/2) + sin(α/2) i` and
//! `q_{x→n}` the shortest rotation taking `e_x` to `n`,
//!
//! ```text
//! q_{x→n} = ( √((1+nx)/2),  0,  −nz/√(2(1+nx)),  ny/√(2(1+nx)) ).
//! ```
//!
//! Then `u = √((1+nx)/2) e^{iα/2}`, `v = (nz − i ny)/√(2(1+nx)) e^{−iα/2}`,
//! `uv = a` is constant and `v/u = w`:
//!
//! ```text
//! a = (nz − i ny)/2,     w(α) = (nz − i ny)/(1 + nx) · e^{−iα}
//! h0 = a⁴ (w⁴ + w⁻⁴ + 14)
//! h1 = a⁶ (w² − w⁻²)² = a⁶ (w⁴ + w⁻⁴ − 2)
//! h2 = −a⁹ (w² − w⁻²)(w⁶ + w⁻⁶ − 33 (w² + w⁻²)) = −a⁹ (w⁴ − w⁻⁴)(w⁴ + w⁻⁴ − 34)
//! ```
//!
//! which is (4.28) with the thesis's `z` axis relabelled `x` (the thesis
//! builds the family about `k`, for which (4.25) is not diagonal; its (4.27)
//! mixes `n_x + 1` and `n_z + 1`). Consequences, with corrections:
//! `a² h0 − h1 = 16 a⁶` (as printed) and `h2 = −a³ (w⁴ − w⁻⁴)(h1 − 32 a⁶)`
//! (printed `h1 − 32`); with `H0 = h0/a⁴`, `H1 = h1/a⁶`,
//! `H0 = ρ⁴ e^{it} + ρ⁻⁴ e^{−it} + 14`, `H1 = H0 − 16`, `t = 4 arg w`, where
//! `ρ = |w| = √((1 − nx)/(1 + nx))`, so `p = 1/q = ρ⁴ = ((1 − nx)/(1 + nx))²`
//! (printed with exponent 4): ellipses in the complex plane.
//!
//! The family is singular at `nx = −1`; since the frames with an axis along
//! `n` are those with an axis along `−n`, the functions here use `−n` when
//! `nx < 0`, which keeps `ρ ≤ 1`.

use super::quaternion::Quat;
use super::su2::C64;
use crate::geom::Vec3;

/// `n` normalized and flipped to `n_x ≥ 0` (same family of frames).
fn canonical_axis(n: &Vec3) -> Vec3 {
    let n = n.normalize();
    if n.x < 0.0 { -n } else { n }
}

/// Frame quaternion `q_{x→n} q_x(α)`: the frame whose `x` axis is `n`
/// (`−n` when `n_x < 0`), turned by `alpha` radians about that axis.
pub fn axis_frame_quaternion(n: &Vec3, alpha: f64) -> Quat {
    let n = canonical_axis(n);
    let a = (0.5 * (1.0 + n.x)).sqrt();
    let b = 1.0 / (2.0 * (1.0 + n.x)).sqrt();
    let q_xn = Quat::new(a, 0.0, -n.z * b, n.y * b);
    let (s, c) = (0.5 * alpha).sin_cos();
    q_xn.mul(&Quat::new(c, s, 0.0, 0.0))
}

/// The constants `(a, w(α))` of (4.28) for the axis `n` and angle `alpha`.
pub fn axis_form_parameters(n: &Vec3, alpha: f64) -> (C64, C64) {
    let n = canonical_axis(n);
    let m = C64::new(n.z, -n.y);
    (m * 0.5, m / (1.0 + n.x) * C64::from_polar(1.0, -alpha))
}

/// Octahedral invariants `(h0, h1, h2)` of the frame
/// [`axis_frame_quaternion`]`(n, alpha)` by the closed forms (4.28).
pub fn axis_invariants(n: &Vec3, alpha: f64) -> [C64; 3] {
    let (a, w) = axis_form_parameters(n, alpha);
    let w4 = (w * w) * (w * w);
    let wi4 = w4.inv();
    let a3 = a * a * a;
    let a6 = a3 * a3;
    [a3 * a * (w4 + wi4 + 14.0), a6 * (w4 + wi4 - 2.0), -a6 * a3 * (w4 - wi4) * (w4 + wi4 - 34.0)]
}

#[cfg(test)]
mod tests {
    use super::super::invariants::{frame_invariants, model_surface_relative_residual};
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    #[test]
    fn closed_forms_match_the_invariants_of_the_family() {
        let mut rng = StdRng::seed_from_u64(41);
        for _ in 0..200 {
            let n = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            if n.norm() < 0.1 {
                continue;
            }
            let alpha = rng.random_range(-4.0..4.0);
            let p = axis_frame_quaternion(&n, alpha);
            let x_axis = p.axes()[0];
            assert!((x_axis - canonical_axis(&n)).norm() < 1e-14);
            let (h, hf) = (frame_invariants(&p), axis_invariants(&n, alpha));
            for k in 0..3 {
                assert!((h[k] - hf[k]).norm() < 1e-14, "h{k}");
            }
            assert!(model_surface_relative_residual(&hf) < 1e-13);
            let (a, w) = axis_form_parameters(&n, alpha);
            let a6 = a.powi(6);
            // a² h0 − h1 = 16 a⁶ and h2 = −a³ (w⁴ − w⁻⁴)(h1 − 32 a⁶).
            assert!((a * a * h[0] - h[1] - a6 * 16.0).norm() < 1e-14);
            let w4 = w.powi(4);
            assert!((-a.powi(3) * (w4 - w4.inv()) * (h[1] - a6 * 32.0) - h[2]).norm() < 1e-13);
            // |w|⁴ = ((1 − nx)/(1 + nx))² (the ellipse parameter p).
            let nc = canonical_axis(&n);
            assert!((w.norm().powi(4) - ((1.0 - nc.x) / (1.0 + nc.x)).powi(2)).abs() < 1e-13);
        }
    }

    #[test]
    fn family_has_period_a_quarter_turn_and_covers_flipped_axes() {
        let n = Vec3::new(-0.3, 0.5, 0.8);
        for &alpha in &[0.0, 0.7, 2.1] {
            let h = axis_invariants(&n, alpha);
            let h4 = axis_invariants(&n, alpha + std::f64::consts::FRAC_PI_2);
            for k in 0..3 {
                assert!((h[k] - h4[k]).norm() < 1e-14);
            }
        }
        // The frames all contain ±n.
        let p = axis_frame_quaternion(&n, 1.0);
        assert!(p.axes().iter().any(|a| (a - n.normalize()).norm() < 1e-14 || (a + n.normalize()).norm() < 1e-14));
    }
}
