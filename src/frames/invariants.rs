//! Invariant forms of the vierer, binary tetrahedral and binary octahedral
//! groups (thesis §3.3) and the model surface of `O`.
//!
//! With `(u, v)` the SU(2) coordinates (4.25):
//!
//! ```text
//! vierer (4.20):      f0 = (uv)²,  f1 = u⁴ + v⁴,  f2 = uv(u⁴ − v⁴),
//!                     f2² = f0 (f1² − 4 f0²)
//! tetrahedral (4.21): g0 = uv(u⁴ − v⁴),  g1 = u⁸ + v⁸ + 14 (uv)⁴,
//!                     g2 = u¹² + v¹² − 33 (uv)⁴ (u⁴ + v⁴),
//!                     g2² = g1³ − 108 g0⁴
//! octahedral (4.23):  h0 = g1,  h1 = g0²,  h2 = g0 g2,
//!                     h2² = h1 (h0³ − 108 h1²)     (the model surface)
//! ```
//!
//! The intermediate forms of the tetrahedral derivation are
//! `f̃0 = f1 + 2√3 i f0`, `f̃1 = f1 − 2√3 i f0` with `g1 = f̃0 f̃1` and
//! `g2 = (f̃0³ + f̃1³)/2`. Corrections to the printed text, all checked in
//! the tests: (4.21) writes `g2 = f̃0³ + f̃1³` (the factor ½ is missing);
//! §4 writes `f̃0,1 = u⁴ ± 4√3 i (uv)² + v⁴` (it is `2√3`, consistent with
//! `(uv)² = (f̃0 − f̃1)/(4√3 i)` printed next to it); (4.23) misses a
//! parenthesis in `h1 = (uv(u⁴ − v⁴))²`.
//!
//! The forms are homogeneous of degrees (4, 4, 6), (6, 8, 12) and
//! (8, 12, 18). [`frame_invariants`] evaluates (4.23) at the coordinates of a
//! *frame* quaternion (with the conjugation of §3.4, see [`super::su2`]).

use super::quaternion::Quat;
use super::su2::{C64, Su2, frame_su2};

/// `2√3`, the coefficient of the intermediate forms `f̃0, f̃1`.
pub const TWO_SQRT3: f64 = 3.464_101_615_137_754_6;

/// Invariant forms of the vierer group (4.20): `[f0, f1, f2]`.
pub fn vierer_forms(s: &Su2) -> [C64; 3] {
    let (u, v) = (s.u, s.v);
    let uv = u * v;
    let (u4, v4) = (pow4(u), pow4(v));
    [uv * uv, u4 + v4, uv * (u4 - v4)]
}

/// The intermediate forms `[f̃0, f̃1]` of the tetrahedral derivation:
/// `f1 ± 2√3 i f0`.
pub fn tilde_forms(s: &Su2) -> [C64; 2] {
    let [f0, f1, _] = vierer_forms(s);
    let t = C64::new(0.0, TWO_SQRT3) * f0;
    [f1 + t, f1 - t]
}

/// Invariant forms of the binary tetrahedral group (4.21): `[g0, g1, g2]`.
pub fn tetrahedral_forms(s: &Su2) -> [C64; 3] {
    let (u, v) = (s.u, s.v);
    let uv = u * v;
    let (u4, v4) = (pow4(u), pow4(v));
    let uv4 = pow4(uv);
    let g0 = uv * (u4 - v4);
    let g1 = u4 * u4 + v4 * v4 + uv4 * 14.0;
    let g2 = u4 * u4 * u4 + v4 * v4 * v4 - uv4 * (u4 + v4) * 33.0;
    [g0, g1, g2]
}

/// Invariant forms of the binary octahedral group (4.23): `[h0, h1, h2]`
/// at the SU(2) coordinates `s`.
pub fn octahedral_forms(s: &Su2) -> [C64; 3] {
    let [g0, g1, g2] = tetrahedral_forms(s);
    [g1, g0 * g0, g0 * g2]
}

/// The octahedral invariants `(h0, h1, h2)` of the frame with frame
/// quaternion `p` (axes = columns of `R(p)`): (4.23) at (4.25) of `p*`.
/// Equal for `p` and `p o`, `o ∈ O`.
pub fn frame_invariants(p: &Quat) -> [C64; 3] {
    octahedral_forms(&frame_su2(p))
}

/// Residual of the vierer relation `f2² − f0 (f1² − 4 f0²)`.
pub fn vierer_relation_residual(f: &[C64; 3]) -> C64 {
    f[2] * f[2] - f[0] * (f[1] * f[1] - f[0] * f[0] * 4.0)
}

/// Residual of the tetrahedral relation `g2² − (g1³ − 108 g0⁴)`.
pub fn tetrahedral_relation_residual(g: &[C64; 3]) -> C64 {
    g[2] * g[2] - (g[1] * g[1] * g[1] - pow4(g[0]) * 108.0)
}

/// Residual of the model surface `h2² − h1 (h0³ − 108 h1²)` (4.23).
pub fn model_surface_residual(h: &[C64; 3]) -> C64 {
    h[2] * h[2] - h[1] * (h[0] * h[0] * h[0] - h[1] * h[1] * 108.0)
}

/// Model-surface residual relative to the size of its terms, so that it is
/// scale free: `|h2² − h1(h0³ − 108 h1²)| / (|h2|² + |h1| |h0|³ + 108 |h1|³)`
/// (0 when all invariants vanish).
pub fn model_surface_relative_residual(h: &[C64; 3]) -> f64 {
    let scale = h[2].norm_sqr() + h[1].norm() * h[0].norm().powi(3) + 108.0 * h[1].norm().powi(3);
    if scale > 0.0 { model_surface_residual(h).norm() / scale } else { 0.0 }
}

#[inline]
pub(crate) fn pow4(z: C64) -> C64 {
    let z2 = z * z;
    z2 * z2
}

#[cfg(test)]
mod tests {
    use super::super::groups::{binary_octahedral_group, binary_tetrahedral_group, vierer_group};
    use super::super::quaternion::tests::random_unit;
    use super::super::su2::su2_from_quaternion;
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn rel_close(a: &[C64; 3], b: &[C64; 3], tol: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).norm() <= tol * (x.norm().max(y.norm()).max(1e-300)))
            || a.iter().zip(b).all(|(x, y)| (x - y).norm() <= tol)
    }

    #[test]
    fn forms_are_invariant_under_their_group_in_the_thesis_order() {
        // §3.4: ô_i r̂ = q̂_i, left multiplication, with (4.25).
        let mut rng = StdRng::seed_from_u64(1);
        for _ in 0..100 {
            let q = random_unit(&mut rng);
            let s = su2_from_quaternion(&q);
            let (f, g, h) = (vierer_forms(&s), tetrahedral_forms(&s), octahedral_forms(&s));
            for o in vierer_group() {
                assert!(rel_close(&vierer_forms(&su2_from_quaternion(&o.mul(&q))), &f, 1e-12));
            }
            for o in binary_tetrahedral_group() {
                assert!(rel_close(&tetrahedral_forms(&su2_from_quaternion(&o.mul(&q))), &g, 1e-12));
            }
            for o in binary_octahedral_group() {
                assert!(rel_close(&octahedral_forms(&su2_from_quaternion(&o.mul(&q))), &h, 1e-12));
            }
        }
    }

    #[test]
    fn frame_invariants_are_invariant_under_right_multiplication() {
        let mut rng = StdRng::seed_from_u64(2);
        for _ in 0..200 {
            let p = random_unit(&mut rng);
            let h = frame_invariants(&p);
            for o in binary_octahedral_group() {
                let ho = frame_invariants(&p.mul(&o));
                for k in 0..3 {
                    assert!((ho[k] - h[k]).norm() <= 1e-12 * h[k].norm().max(1e-3), "{k}: {:?} vs {:?}", ho[k], h[k]);
                }
                // The frame itself is the same set of ± axes.
                let (a, b) = (p.axes(), p.mul(&o).axes());
                for x in &a {
                    assert!(b.iter().any(|y| (x - y).norm() < 1e-12 || (x + y).norm() < 1e-12));
                }
            }
            // A rotation that is not in O changes the invariants.
            let r = Quat::from_axis_angle(&crate::geom::Vec3::new(0.2, 0.9, -0.4), 0.3);
            let hr = frame_invariants(&p.mul(&r));
            assert!((0..3).any(|k| (hr[k] - h[k]).norm() > 1e-6));
        }
    }

    #[test]
    fn relations_and_intermediate_forms_hold() {
        let mut rng = StdRng::seed_from_u64(3);
        for _ in 0..200 {
            // Non-unit pairs too: the relations are homogeneous.
            let s = Su2 {
                u: C64::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0)),
                v: C64::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0)),
            };
            let (f, g, h) = (vierer_forms(&s), tetrahedral_forms(&s), octahedral_forms(&s));
            let scale = s.norm_squared();
            assert!(vierer_relation_residual(&f).norm() <= 1e-13 * scale.powi(6));
            assert!(tetrahedral_relation_residual(&g).norm() <= 1e-13 * scale.powi(12));
            assert!(model_surface_relative_residual(&h) <= 1e-14);
            let [t0, t1] = tilde_forms(&s);
            assert!((t0 * t1 - g[1]).norm() <= 1e-13 * scale.powi(4));
            // g2 = (f̃0³ + f̃1³)/2 (the ½ is missing in the printed (4.21)).
            assert!(((t0 * t0 * t0 + t1 * t1 * t1) * 0.5 - g[2]).norm() <= 1e-13 * scale.powi(6));
            // f̃0³ − f̃1³ = 12√3 i g0², the identity behind §4's cube root.
            assert!(
                (t0 * t0 * t0 - t1 * t1 * t1 - C64::new(0.0, 6.0 * TWO_SQRT3) * g[0] * g[0]).norm()
                    <= 1e-12 * scale.powi(6)
            );
            // (uv)² = (f̃0 − f̃1)/(4√3 i).
            assert!(((t0 - t1) / C64::new(0.0, 2.0 * TWO_SQRT3) - f[0]).norm() <= 1e-13 * scale.powi(2));
        }
    }

    #[test]
    fn affine_map_4_22_flips_the_sign_of_h2_only() {
        let mut rng = StdRng::seed_from_u64(4);
        let e = C64::from_polar(1.0, std::f64::consts::FRAC_PI_4);
        for _ in 0..50 {
            let s = su2_from_quaternion(&random_unit(&mut rng));
            let t = Su2 { u: e * s.u, v: -e.conj() * s.v };
            let (g, gt) = (tetrahedral_forms(&s), tetrahedral_forms(&t));
            assert!((g[0] - gt[0]).norm() < 1e-14 && (g[1] - gt[1]).norm() < 1e-14 && (g[2] + gt[2]).norm() < 1e-14);
            let (h, ht) = (octahedral_forms(&s), octahedral_forms(&t));
            assert!((h[0] - ht[0]).norm() < 1e-14 && (h[1] - ht[1]).norm() < 1e-14 && (h[2] + ht[2]).norm() < 1e-14);
        }
    }
}
