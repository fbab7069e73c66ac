//! Real quaternions `q = q0 + q1 i + q2 j + q3 k` and the rotations they
//! represent (thesis §2.1).
//!
//! Product (4.7), with `i² = j² = k² = −1`, `ij = k`, `jk = i`, `ki = j`:
//!
//! ```text
//! p q = (p0 q0 − p·q) + (p0 q + q0 p + p × q)
//! ```
//!
//! (the thesis prints the real part as `q0 q0 − …`; it is `p0 q0 − …`, as its
//! vector form right below shows and as the tests check).
//!
//! A unit quaternion `q` rotates a vector `v` by the inner automorphism (4.9)
//! `v ↦ q v q*`; `q` and `−q` give the same rotation (4.10). The rotation
//! matrix [`Quat::to_matrix`] has as columns the images of the Cartesian
//! axes, so a *frame quaternion* `q` describes the frame whose axes are the
//! columns of `R(q)`. Composition: `R(p q) = R(p) R(q)`.

use crate::geom::Vec3;
use nalgebra::Matrix3;

/// A 3×3 rotation matrix (columns are the rotated Cartesian axes).
pub type Mat3 = Matrix3<f64>;

/// A real quaternion `[q0, q1, q2, q3] = q0 + q1 i + q2 j + q3 k`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Quat(pub [f64; 4]);

impl Quat {
    /// The identity rotation `1`.
    pub const IDENTITY: Quat = Quat([1.0, 0.0, 0.0, 0.0]);

    /// The quaternion with components `q0 + q1 i + q2 j + q3 k`.
    #[inline]
    pub const fn new(q0: f64, q1: f64, q2: f64, q3: f64) -> Self {
        Quat([q0, q1, q2, q3])
    }

    /// Scalar (real) part `q0`.
    #[inline]
    pub fn scalar(&self) -> f64 {
        self.0[0]
    }

    /// Vector (imaginary) part `(q1, q2, q3)`.
    #[inline]
    pub fn vector(&self) -> Vec3 {
        Vec3::new(self.0[1], self.0[2], self.0[3])
    }

    /// The unit quaternion `cos(θ/2) + sin(θ/2) a` of the rotation by angle
    /// `angle` (radians, right-handed) around `axis` (normalized here; a zero
    /// axis gives the identity).
    pub fn from_axis_angle(axis: &Vec3, angle: f64) -> Self {
        let n = axis.norm();
        if !(n > 0.0) {
            return Self::IDENTITY;
        }
        let (s, c) = (0.5 * angle).sin_cos();
        let a = axis * (s / n);
        Quat([c, a.x, a.y, a.z])
    }

    /// Quaternion product `self · other` (4.7).
    #[inline]
    pub fn mul(&self, other: &Quat) -> Quat {
        let [p0, p1, p2, p3] = self.0;
        let [q0, q1, q2, q3] = other.0;
        Quat([
            p0 * q0 - (p1 * q1 + p2 * q2 + p3 * q3),
            p0 * q1 + q0 * p1 + (p2 * q3 - q2 * p3),
            p0 * q2 + q0 * p2 + (p3 * q1 - q3 * p1),
            p0 * q3 + q0 * p3 + (p1 * q2 - q1 * p2),
        ])
    }

    /// Conjugate `q* = q0 − (q1 i + q2 j + q3 k)`.
    #[inline]
    pub fn conj(&self) -> Quat {
        let [q0, q1, q2, q3] = self.0;
        Quat([q0, -q1, -q2, -q3])
    }

    /// Negation `−q` (same rotation).
    #[inline]
    pub fn neg(&self) -> Quat {
        Quat(self.0.map(|c| -c))
    }

    /// Squared norm `|q|² = q q*`.
    #[inline]
    pub fn norm_squared(&self) -> f64 {
        self.0.iter().map(|c| c * c).sum()
    }

    /// Norm `|q|`.
    #[inline]
    pub fn norm(&self) -> f64 {
        self.norm_squared().sqrt()
    }

    /// `q / |q|`; the identity for a zero quaternion.
    pub fn normalized(&self) -> Quat {
        let n = self.norm();
        if n > 0.0 { Quat(self.0.map(|c| c / n)) } else { Self::IDENTITY }
    }

    /// Euclidean dot product in `R⁴`.
    #[inline]
    pub fn dot(&self, other: &Quat) -> f64 {
        self.0.iter().zip(&other.0).map(|(a, b)| a * b).sum()
    }

    /// Rotate `v` by the unit quaternion: the vector part of `q v q*` (4.9).
    pub fn rotate(&self, v: &Vec3) -> Vec3 {
        let w = self.scalar();
        let u = self.vector();
        // q v q* = v + 2w (u × v) + 2 u × (u × v) for unit q.
        let t = 2.0 * u.cross(v);
        v + w * t + u.cross(&t)
    }

    /// Rotation matrix `R(q)` of a unit quaternion: `R(q) v = q v q*`.
    pub fn to_matrix(&self) -> Mat3 {
        let [w, x, y, z] = self.0;
        Mat3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        )
    }

    /// Unit quaternion of a rotation matrix (Shepperd's method: the largest
    /// of the four squared components is taken from the diagonal, the others
    /// from off-diagonal sums, so no cancellation occurs). The sign is chosen
    /// with `q0 ≥ 0`. The input is assumed orthonormal with determinant 1;
    /// the result is normalized.
    pub fn from_matrix(r: &Mat3) -> Quat {
        let (m00, m11, m22) = (r[(0, 0)], r[(1, 1)], r[(2, 2)]);
        let trace = m00 + m11 + m22;
        let q = if trace >= m00.max(m11).max(m22) {
            let s = 2.0 * (1.0 + trace).max(0.0).sqrt();
            Quat([0.25 * s, (r[(2, 1)] - r[(1, 2)]) / s, (r[(0, 2)] - r[(2, 0)]) / s, (r[(1, 0)] - r[(0, 1)]) / s])
        } else if m00 >= m11 && m00 >= m22 {
            let s = 2.0 * (1.0 + m00 - m11 - m22).max(0.0).sqrt();
            Quat([(r[(2, 1)] - r[(1, 2)]) / s, 0.25 * s, (r[(0, 1)] + r[(1, 0)]) / s, (r[(0, 2)] + r[(2, 0)]) / s])
        } else if m11 >= m22 {
            let s = 2.0 * (1.0 + m11 - m00 - m22).max(0.0).sqrt();
            Quat([(r[(0, 2)] - r[(2, 0)]) / s, (r[(0, 1)] + r[(1, 0)]) / s, 0.25 * s, (r[(1, 2)] + r[(2, 1)]) / s])
        } else {
            let s = 2.0 * (1.0 + m22 - m00 - m11).max(0.0).sqrt();
            Quat([(r[(1, 0)] - r[(0, 1)]) / s, (r[(0, 2)] + r[(2, 0)]) / s, (r[(1, 2)] + r[(2, 1)]) / s, 0.25 * s])
        };
        let q = q.normalized();
        if q.0[0] < 0.0 { q.neg() } else { q }
    }

    /// The three frame axes `R(q) e_x, R(q) e_y, R(q) e_z`.
    pub fn axes(&self) -> [Vec3; 3] {
        let r = self.to_matrix();
        [r.column(0).into_owned(), r.column(1).into_owned(), r.column(2).into_owned()]
    }

    /// Rotation angle in `[0, π]` of the unit quaternion.
    pub fn angle(&self) -> f64 {
        2.0 * self.vector().norm().atan2(self.scalar().abs())
    }
}

/// The rotation matrix `exp([ω]ₓ)` of the rotation vector `ω` (Rodrigues).
pub fn rotation_from_vector(w: &Vec3) -> Mat3 {
    let th2 = w.norm_squared();
    let k = Mat3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0);
    // Taylor expansions below θ ≈ 1e-4 keep round-off at machine precision.
    let (a, b) = if th2 < 1e-8 {
        (1.0 - th2 / 6.0, 0.5 - th2 / 24.0)
    } else {
        let th = th2.sqrt();
        (th.sin() / th, (1.0 - th.cos()) / th2)
    };
    Mat3::identity() + k * a + k * k * b
}

/// Nearest rotation to a 3×3 matrix in the Frobenius norm (polar factor via
/// the quaternion eigen-free route: Shepperd on the matrix, then renormalize).
/// Accurate for matrices already close to a rotation, as produced by
/// accumulated updates; used to remove drift.
pub fn reorthonormalize(r: &Mat3) -> Mat3 {
    Quat::from_matrix(r).to_matrix()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// A uniformly random unit quaternion (rejection sampling in the 4-ball);
    /// shared by the frame tests.
    pub(crate) fn random_unit(rng: &mut StdRng) -> Quat {
        loop {
            let q = Quat::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let n = q.norm();
            if n > 0.1 && n < 1.0 {
                return q.normalized();
            }
        }
    }

    #[test]
    fn product_follows_hamilton_rules() {
        let (i, j, k) = (Quat::new(0.0, 1.0, 0.0, 0.0), Quat::new(0.0, 0.0, 1.0, 0.0), Quat::new(0.0, 0.0, 0.0, 1.0));
        assert_eq!(i.mul(&j), k);
        assert_eq!(j.mul(&k), i);
        assert_eq!(k.mul(&i), j);
        assert_eq!(j.mul(&i), k.neg());
        assert_eq!(i.mul(&i), Quat::new(-1.0, 0.0, 0.0, 0.0));
        // Real part p0 q0 − p·q (the thesis misprints q0 q0).
        let p = Quat::new(2.0, 0.0, 0.0, 0.0);
        let q = Quat::new(3.0, 0.0, 0.0, 0.0);
        assert_eq!(p.mul(&q).0[0], 6.0);
    }

    #[test]
    fn rotation_matrix_round_trip_and_composition() {
        let mut rng = StdRng::seed_from_u64(11);
        for _ in 0..200 {
            let p = random_unit(&mut rng);
            let q = random_unit(&mut rng);
            let rp = p.to_matrix();
            assert!((rp.transpose() * rp - Mat3::identity()).norm() < 1e-14);
            assert!((rp.determinant() - 1.0).abs() < 1e-14);
            let back = Quat::from_matrix(&rp);
            assert!((back.dot(&p).abs() - 1.0).abs() < 1e-14);
            assert!((p.mul(&q).to_matrix() - rp * q.to_matrix()).norm() < 1e-14);
            let v = Vec3::new(0.3, -1.2, 0.7);
            assert!((p.rotate(&v) - rp * v).norm() < 1e-14);
            // q v q* through the product itself.
            let vq = Quat::new(0.0, v.x, v.y, v.z);
            let w = p.mul(&vq).mul(&p.conj());
            assert!((w.vector() - rp * v).norm() < 1e-14 && w.0[0].abs() < 1e-14);
        }
    }

    #[test]
    fn axis_angle_and_exponential_agree() {
        let axis = Vec3::new(1.0, 2.0, -0.5);
        for &angle in &[0.0, 1e-6, 0.3, 2.0, std::f64::consts::PI] {
            let q = Quat::from_axis_angle(&axis, angle);
            let r = rotation_from_vector(&(axis.normalize() * angle));
            assert!((q.to_matrix() - r).norm() < 1e-14);
            assert!((q.angle() - angle).abs() < 1e-7);
        }
    }
}
