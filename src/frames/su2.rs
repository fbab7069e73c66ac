//! The SU(2) coordinates `(u, v) ∈ C²` of a quaternion (thesis §2.2, (4.25)).
//!
//! The thesis maps a quaternion to the first column of the quaternionic
//! matrix `[[u, −v*], [v, u*]]` (4.13). Its final choice (4.25) is
//!
//! ```text
//! u = q0 − q1 i,   v = q2 + q3 i          (4.25)
//! ```
//!
//! **Which quaternions share invariants.** Verified numerically to round-off
//! (tests below and in `invariants`): with (4.25) the octahedral forms (4.23)
//! satisfy `h(o q) = h(q)` for all 48 `o ∈ O` (left multiplication), which
//! is the order `ô_i r̂ = q̂_i` of §3.4. A frame, however, is the rotation
//! of the Cartesian frame by a *frame quaternion* `p` (axes = columns of
//! `R(p)`), and `p` and `p o` give the same frame (right multiplication).
//! §3.4 resolves this by conjugation (4.24): the groupset `{o r}` of a
//! coordinate describes the frame rotated by its conjugate `r* o*`. So the
//! coordinates of the frame with frame quaternion `p` are (4.25) applied to
//! `p*` ([`frame_su2`]); they are invariant under `p ↦ p o`.
//!
//! (The thesis presents (4.25) as (4.12) updated for the conjugation; as
//! printed it is not (4.12) of `q*` — that would be `u = q0 − q3 i,
//! v = q2 + q1 i` — but (4.12) composed with a half turn of O, so it is still
//! left-invariant. We keep (4.25) as printed and apply it to `p*`.)
//!
//! `|u|² + |v|² = |q|²`, so unit quaternions map to SU(2) (4.14).

use super::quaternion::Quat;
use nalgebra::Complex;

/// A complex number in double precision.
pub type C64 = Complex<f64>;

/// SU(2) coordinates `(u, v)`: the first column of the quaternionic matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Su2 {
    /// `u = q0 − q1 i`.
    pub u: C64,
    /// `v = q2 + q3 i`.
    pub v: C64,
}

impl Su2 {
    /// `|u|² + |v|²`, equal to `|q|²`.
    pub fn norm_squared(&self) -> f64 {
        self.u.norm_sqr() + self.v.norm_sqr()
    }
}

/// The map (4.25): `u = q0 − q1 i`, `v = q2 + q3 i`.
#[inline]
pub fn su2_from_quaternion(q: &Quat) -> Su2 {
    let [q0, q1, q2, q3] = q.0;
    Su2 { u: C64::new(q0, -q1), v: C64::new(q2, q3) }
}

/// Inverse of (4.25): `q0 = Re u`, `q1 = −Im u`, `q2 = Re v`, `q3 = Im v`.
#[inline]
pub fn quaternion_from_su2(s: &Su2) -> Quat {
    Quat([s.u.re, -s.u.im, s.v.re, s.v.im])
}

/// SU(2) coordinates of the frame with frame quaternion `p`: (4.25) applied
/// to `p*` (the conjugation of §3.4, (4.24)).
#[inline]
pub fn frame_su2(p: &Quat) -> Su2 {
    su2_from_quaternion(&p.conj())
}

/// Frame quaternion of the SU(2) coordinates of a frame: the conjugate of
/// the inverse of (4.25).
#[inline]
pub fn frame_quaternion_from_su2(s: &Su2) -> Quat {
    quaternion_from_su2(s).conj()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_is_bijective_and_preserves_the_norm() {
        let q = Quat::new(0.3, -0.4, 0.5, 0.7);
        let s = su2_from_quaternion(&q);
        assert_eq!(quaternion_from_su2(&s), q);
        assert!((s.norm_squared() - q.norm_squared()).abs() < 1e-15);
        assert_eq!(frame_quaternion_from_su2(&frame_su2(&q)), q);
    }

    #[test]
    fn left_rotation_about_i_acts_diagonally() {
        // Under (4.25), left multiplication by cos θ + i sin θ is the affine
        // map (u, v) ↦ (e^{−iθ} u, e^{iθ} v): the quarter turn about i of
        // §3.3 (θ = π/4) up to the orientation of the angle.
        let th: f64 = 0.37;
        let e = Quat::new(th.cos(), th.sin(), 0.0, 0.0);
        let q = Quat::new(0.3, -0.4, 0.5, 0.7);
        let a = su2_from_quaternion(&q);
        let b = su2_from_quaternion(&e.mul(&q));
        let ph = C64::from_polar(1.0, th);
        assert!((b.u - a.u * ph.conj()).norm() < 1e-15);
        assert!((b.v - a.v * ph).norm() < 1e-15);
    }
}
