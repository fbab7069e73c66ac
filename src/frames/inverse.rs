//! From a coordinate `(h0, h1, h2)` of the octahedral model surface back to
//! its groupset of SU(2) pairs, hence to a frame quaternion (thesis §4).
//!
//! The derivation of (4.23) is rewound, `h → g → f̃ → (u, v)`:
//!
//! ```text
//! g1 = h0,   g0 = (−1)^k0 √h1,   g2 = h2 / g0          (|h1| ≠ 0)
//!                                g2 = (−1)^k0 √(h0³)    (h1 = 0)
//! f̃0 = e^{2πi k1/3} ∛(g2 + 6√3 i g0²),   f̃1 = g1 / f̃0  (f̃0 ≠ 0)
//!                       f̃1 = e^{2πi k1/3} ∛(g2 − 6√3 i g0²)  (f̃0 = 0)
//! (uv)² = (f̃0 − f̃1)/(4√3 i),   u⁴ + v⁴ = (f̃0 + f̃1)/2
//! v = i^k3 ⁴√( f̃0/4 + f̃1/4 + (−1)^k2 (√3/6) √(f̃0² + f̃0 f̃1 + f̃1²) )
//! u = (−1)^k4 √((uv)²) / v                       (f̃0 ≠ f̃1, uv ≠ 0)
//! u, v = 0 and ⁴√((f̃0 + f̃1)/2) in either order     (f̃0 = f̃1, uv = 0)
//! ```
//!
//! Corrections to the printed §4, all verified by the tests: `f̃0³` is
//! `g2 + 6√3 i g0²` (the printed `(2 g2 + 12√3 i g0²)/2` agrees); the
//! printed `u = (−1)^k4 √v` is a typo for `u = (−1)^k4 √((uv)²)/v`;
//! `f̃0,1 = u⁴ ± 2√3 i (uv)² + v⁴` (printed `4√3`).
//!
//! The 2·3·2·4·2 = 96 branches give 96 pairs of which 48 are the groupset of
//! `(h0, h1, h2)` and 48 that of `(h0, h1, −h2)`: `f̃0, f̃1` fix only the
//! vierer forms `f0, f1`, not the sign of `f2 = g0`. A pair of the wrong
//! groupset is mapped onto the right one by the affine map (4.22)
//! `(u, v) ↦ (e^{iπ/4} u, −e^{−iπ/4} v)`, which keeps `g0, g1` and flips `g2`.
//!
//! **Numerical choices.** The printed branches switch on exact zeros
//! (`h1 = 0`, `f̃0 = 0`, `f̃0 = f̃1`). Near those points the printed formulas
//! lose half of the digits (`g0 = √h1` for tiny `h1`, `f̃1 = g1/f̃0` for tiny
//! `f̃0`, …), although the surface is smooth there (`O` acts freely on
//! `C² \ 0`). [`su2_from_invariants`] therefore takes, at each step, the
//! better conditioned of two equivalent formulas (`g0 = √h1, g2 = h2/g0` or
//! `g2 = √(h0³ − 108 h1²), g0 = h2/g2`; the cube root of the larger of
//! `f̃0³, f̃1³`; the larger root of the quadratic for `v⁴`), then polishes
//! `(u, v)` with two Gauss–Newton steps on the holomorphic system
//! `h(u, v) = h`. The exact-zero branches of the thesis are the limits of
//! these choices.

use super::invariants::{TWO_SQRT3, octahedral_forms};
use super::quaternion::Quat;
use super::su2::{C64, Su2, frame_quaternion_from_su2};

/// One SU(2) pair of the groupset of the model-surface coordinate `h`, by
/// the well-conditioned branch choices described in the module docs,
/// corrected with (4.22) when needed and polished by Gauss–Newton.
/// All 48 pairs of the groupset have the same norm, `|u|² + |v|²`, which is
/// `|q|²` of the quaternions that produced `h`. Off the model surface the
/// result is the pair whose invariants best match `h` in the weighted
/// least-squares sense of the polish (inputs with NaN give NaN).
pub fn su2_from_invariants(h: &[C64; 3]) -> Su2 {
    let [h0, h1, h2] = *h;
    let zero = C64::new(0.0, 0.0);
    // h → g: pick the formula whose divisor is larger (scale-free test).
    let g1 = h0;
    let r0 = h0 * h0 * h0 - h1 * h1 * 108.0; // = g2²
    let (g0, g2) = if h1.norm().powf(1.0 / 12.0) >= r0.norm().powf(1.0 / 24.0) {
        let g0 = h1.sqrt();
        (g0, h2 / g0)
    } else {
        let g2 = r0.sqrt();
        (h2 / g2, g2)
    };
    // g → f̃: cube root of the larger of f̃0³, f̃1³; the other from f̃0 f̃1 = g1.
    let c = C64::new(0.0, 3.0 * TWO_SQRT3) * g0 * g0; // 6√3 i g0²
    let (a3, b3) = (g2 + c, g2 - c);
    let (t0, t1) = if a3.norm() >= b3.norm() {
        let t0 = a3.cbrt();
        (t0, if t0 != zero { g1 / t0 } else { b3.cbrt() })
    } else {
        let t1 = b3.cbrt();
        (if t1 != zero { g1 / t1 } else { a3.cbrt() }, t1)
    };
    // f̃ → (u, v).
    let p = (t0 - t1) / C64::new(0.0, 2.0 * TWO_SQRT3); // (uv)²
    let s = (t0 + t1) * 0.5; // u⁴ + v⁴
    let d = (s * s - p * p * 4.0).sqrt();
    let big = if (s + d).norm() >= (s - d).norm() { (s + d) * 0.5 } else { (s - d) * 0.5 };
    if !big.is_finite() {
        let nan = C64::new(f64::NAN, f64::NAN);
        return Su2 { u: nan, v: nan };
    }
    if big == zero {
        return Su2 { u: zero, v: zero };
    }
    let v = big.sqrt().sqrt();
    let u = p.sqrt() / v;
    let mut pair = Su2 { u, v };
    // Wrong groupset (h0, h1, −h2)? Apply (4.22).
    let hp = octahedral_forms(&pair);
    if (hp[2] - h2).norm() > (hp[2] + h2).norm() {
        pair = affine_4_22(&pair);
    }
    polish(&pair, h, 2)
}

/// The frame quaternion of the model-surface coordinate `h`: the conjugate
/// of (4.25)⁻¹ of [`su2_from_invariants`] (§3.4). Its norm is the common
/// norm of the groupset (1 for invariants of a unit quaternion).
pub fn frame_quaternion_from_invariants(h: &[C64; 3]) -> Quat {
    frame_quaternion_from_su2(&su2_from_invariants(h))
}

/// The 96 pairs of the printed branches `k0..k4` of §4, in the order
/// `k0, k1, k2, k3, k4` (outermost first), *before* the (4.22) correction.
/// Exactly half belong to the groupset of `h`, the other half to that of
/// `(h0, h1, −h2)`. Uses the switches of the thesis (`h1 = 0`, `f̃0 = 0`,
/// `f̃0 = f̃1`), tested up to a relative 1e-12 (an exact test sends round-off
/// into the wrong branch), so it is meant for exposition and tests; near the
/// degenerate points its results carry only half of the digits.
pub fn thesis_inverse_branches(h: &[C64; 3]) -> Vec<Su2> {
    let [h0, h1, h2] = *h;
    let zero = C64::new(0.0, 0.0);
    let omega = |k: u32| C64::from_polar(1.0, 2.0 * std::f64::consts::PI * k as f64 / 3.0);
    let i_pow = |k: u32| [C64::new(1.0, 0.0), C64::new(0.0, 1.0), C64::new(-1.0, 0.0), C64::new(0.0, -1.0)][k as usize];
    let mut out = Vec::with_capacity(96);
    for k0 in 0..2u32 {
        let sign0 = if k0 == 0 { 1.0 } else { -1.0 };
        let g1 = h0;
        let g0 = h1.sqrt() * sign0;
        // Scale of the forms: |h0| ~ r⁸, |h1| ~ r¹², |h2| ~ r¹⁸.
        let r2 = h0.norm().powf(0.25).max(h1.norm().powf(1.0 / 6.0)).max(h2.norm().powf(1.0 / 9.0));
        let g2 = if h1.norm() > 1e-12 * r2.powi(6) { h2 / g0 } else { (h0 * h0 * h0).sqrt() * sign0 };
        let c = C64::new(0.0, 3.0 * TWO_SQRT3) * g0 * g0;
        for k1 in 0..3u32 {
            let t0 = omega(k1) * (g2 + c).cbrt();
            let t1 = if t0.norm() > 1e-12 * r2.powi(2) { g1 / t0 } else { omega(k1) * (g2 - c).cbrt() };
            let distinct = (t0 - t1).norm() > 1e-12 * r2.powi(2);
            let p = (t0 - t1) / C64::new(0.0, 2.0 * TWO_SQRT3);
            for k2 in 0..2u32 {
                for k3 in 0..4u32 {
                    for k4 in 0..2u32 {
                        let sign4 = if k4 == 0 { 1.0 } else { -1.0 };
                        if distinct {
                            let root = (t0 * t0 + t0 * t1 + t1 * t1).sqrt() * (3f64.sqrt() / 6.0);
                            let v4 = (t0 + t1) * 0.25 + if k2 == 0 { root } else { -root };
                            let v = i_pow(k3) * v4.sqrt().sqrt();
                            let u = p.sqrt() * sign4 / v;
                            out.push(Su2 { u, v });
                        } else {
                            // uv = 0: one of u, v vanishes (k2 chooses which);
                            // k4 is redundant there and repeats the pair.
                            let r = i_pow(k3) * ((t0 + t1) * 0.5).sqrt().sqrt();
                            out.push(if k2 == 1 { Su2 { u: r, v: zero } } else { Su2 { u: zero, v: r } });
                        }
                    }
                }
            }
        }
    }
    out
}

/// The 48 pairs of the groupset of `h`: the printed branches, each moved to
/// the right groupset with (4.22) when it landed on `(h0, h1, −h2)`, polished
/// and deduplicated.
pub fn groupset_from_invariants(h: &[C64; 3]) -> Vec<Su2> {
    let mut out: Vec<Su2> = Vec::with_capacity(48);
    let scale = su2_from_invariants(h).norm_squared().sqrt().max(1e-300);
    for pair in thesis_inverse_branches(h) {
        let hp = octahedral_forms(&pair);
        let fixed = if (hp[2] - h[2]).norm() > (hp[2] + h[2]).norm() { affine_4_22(&pair) } else { pair };
        let fixed = polish(&fixed, h, 2);
        let dup = out.iter().any(|q| (q.u - fixed.u).norm() + (q.v - fixed.v).norm() < 1e-8 * scale);
        if !dup {
            out.push(fixed);
        }
    }
    out
}

/// The affine map (4.22): `(u, v) ↦ (e^{iπ/4} u, −e^{−iπ/4} v)`; keeps
/// `g0, g1` (so `h0, h1`) and flips the signs of `g2` and `h2`.
pub fn affine_4_22(s: &Su2) -> Su2 {
    let e = C64::from_polar(1.0, std::f64::consts::FRAC_PI_4);
    Su2 { u: e * s.u, v: -e.conj() * s.v }
}

/// Partial derivatives `(∂/∂u, ∂/∂v)` of `(h0, h1, h2)` at `s`.
fn octahedral_jacobian(s: &Su2) -> [[C64; 2]; 3] {
    let (u, v) = (s.u, s.v);
    let (u2, v2) = (u * u, v * v);
    let (u3, v3) = (u2 * u, v2 * v);
    let (u4, v4) = (u2 * u2, v2 * v2);
    let (u7, v7) = (u4 * u3, v4 * v3);
    let (u8, v8) = (u4 * u4, v4 * v4);
    let g0 = u * v * (u4 - v4);
    let g2 = u8 * u4 + v8 * v4 - (u8 * v4 + u4 * v8) * 33.0;
    let dg0 = [u4 * v * 5.0 - v4 * v, u4 * u - u * v4 * 5.0];
    let dg1 = [u7 * 8.0 + u3 * v4 * 56.0, v7 * 8.0 + u4 * v3 * 56.0];
    let dg2 = [
        u8 * u3 * 12.0 - (u7 * v4 * 8.0 + u3 * v8 * 4.0) * 33.0,
        v8 * v3 * 12.0 - (u8 * v3 * 4.0 + u4 * v7 * 8.0) * 33.0,
    ];
    [dg1, [g0 * dg0[0] * 2.0, g0 * dg0[1] * 2.0], [dg0[0] * g2 + g0 * dg2[0], dg0[1] * g2 + g0 * dg2[1]]]
}

/// Gauss–Newton steps on `h(u, v) = target`, rows scaled by `r^{−deg}`
/// (degrees 8, 12, 18, `r² = |u|² + |v|²`) so that the three equations weigh
/// alike; a step is kept only when it lowers the scaled residual.
fn polish(start: &Su2, target: &[C64; 3], steps: usize) -> Su2 {
    let residual = |s: &Su2, w: &[f64; 3]| -> f64 {
        let hs = octahedral_forms(s);
        (0..3).map(|k| ((hs[k] - target[k]) * w[k]).norm_sqr()).sum()
    };
    let mut s = *start;
    for _ in 0..steps {
        let r2 = s.norm_squared();
        if !(r2 > 0.0) || !r2.is_finite() {
            break;
        }
        let w = [r2.powi(-4), r2.powi(-6), r2.powi(-9)];
        let hs = octahedral_forms(&s);
        let j = octahedral_jacobian(&s);
        // Normal equations of the 3×2 complex least-squares problem.
        let mut a = [[C64::new(0.0, 0.0); 2]; 2];
        let mut b = [C64::new(0.0, 0.0); 2];
        for k in 0..3 {
            let row = [j[k][0] * w[k], j[k][1] * w[k]];
            let f = (target[k] - hs[k]) * w[k];
            for x in 0..2 {
                for y in 0..2 {
                    a[x][y] += row[x].conj() * row[y];
                }
                b[x] += row[x].conj() * f;
            }
        }
        let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        if det.norm() <= 1e-300 {
            break;
        }
        let du = (b[0] * a[1][1] - a[0][1] * b[1]) / det;
        let dv = (a[0][0] * b[1] - a[1][0] * b[0]) / det;
        let next = Su2 { u: s.u + du, v: s.v + dv };
        if residual(&next, &w) < residual(&s, &w) {
            s = next;
        } else {
            break;
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::super::groups::binary_octahedral_group;
    use super::super::invariants::{frame_invariants, model_surface_relative_residual};
    use super::super::quaternion::tests::random_unit;
    use super::super::su2::frame_su2;
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// Distance between frame quaternions up to the groupset `±q O`.
    fn distance_mod_o(a: &Quat, b: &Quat) -> f64 {
        binary_octahedral_group()
            .iter()
            .map(|o| {
                let bo = b.mul(o);
                (0..4).map(|i| (a.0[i] - bo.0[i]).powi(2)).sum::<f64>().sqrt()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn inverse_recovers_the_frame_up_to_the_octahedral_group() {
        let mut rng = StdRng::seed_from_u64(21);
        let mut worst = 0.0f64;
        for _ in 0..500 {
            let q = random_unit(&mut rng);
            let back = frame_quaternion_from_invariants(&frame_invariants(&q));
            assert!((back.norm() - 1.0).abs() < 1e-12, "norm {}", back.norm());
            worst = worst.max(distance_mod_o(&back, &q));
        }
        assert!(worst < 1e-11, "worst distance {worst}");
    }

    #[test]
    fn inverse_handles_the_degenerate_branches() {
        // uv = 0 (u = 0 or v = 0), h1 = 0 with uv ≠ 0 (u⁴ = v⁴), f̃0 = 0
        // (g1 = h0 = 0), f̃0 = f̃1, and points close to each of them.
        let s = |u: C64, v: C64| Su2 { u, v };
        let c = |re: f64, im: f64| C64::new(re, im);
        let r = std::f64::consts::FRAC_1_SQRT_2;
        // A root of u⁸ + 14 u⁴ + 1 = 0 with v = 1 gives h0 = 0.
        let z4 = c(-7.0 + 48f64.sqrt(), 0.0); // u⁴ = −7 + 4√3
        let u_h0 = z4.sqrt().sqrt();
        let mut cases = vec![
            s(c(1.0, 0.0), c(0.0, 0.0)),
            s(c(0.0, 0.0), c(0.6, 0.8)),
            s(c(r, 0.0), c(r, 0.0)),
            s(c(r, 0.0), c(0.0, r)),
            s(c(0.5, 0.5), c(0.5, -0.5)),
            s(u_h0, c(1.0, 0.0)),
        ];
        for eps in [1e-3, 1e-6, 1e-9] {
            cases.push(s(c(1.0, 0.0), c(eps, eps)));
            cases.push(s(c(r, eps), c(r, 0.0)));
            cases.push(s(u_h0 + c(eps, 0.0), c(1.0, 0.0)));
        }
        for pair in cases {
            let norm = pair.norm_squared().sqrt();
            let pair = Su2 { u: pair.u / norm, v: pair.v / norm };
            let h = octahedral_forms(&pair);
            let back = su2_from_invariants(&h);
            let hb = octahedral_forms(&back);
            for k in 0..3 {
                assert!((hb[k] - h[k]).norm() < 1e-12, "{pair:?}: h{k} {:?} vs {:?}", hb[k], h[k]);
            }
            assert!((back.norm_squared() - 1.0).abs() < 1e-12, "{pair:?}: norm {}", back.norm_squared());
            // Same frame up to O.
            let (p, q) = (frame_quaternion_from_su2(&pair), frame_quaternion_from_su2(&back));
            assert!(distance_mod_o(&p, &q) < 1e-9, "{pair:?}");
        }
    }

    #[test]
    fn printed_branches_give_two_groupsets_and_4_22_merges_them() {
        let mut rng = StdRng::seed_from_u64(22);
        for _ in 0..20 {
            let q = random_unit(&mut rng);
            let h = frame_invariants(&q);
            let flipped = [h[0], h[1], -h[2]];
            let branches = thesis_inverse_branches(&h);
            assert_eq!(branches.len(), 96);
            let close = |a: &[C64; 3], b: &[C64; 3]| (0..3).all(|k| (a[k] - b[k]).norm() < 1e-10);
            let n_right = branches.iter().filter(|p| close(&octahedral_forms(p), &h)).count();
            let n_wrong = branches.iter().filter(|p| close(&octahedral_forms(p), &flipped)).count();
            assert_eq!((n_right, n_wrong), (48, 48));
            // After (4.22): the 48 distinct pairs are the groupset {p o}.
            let set = groupset_from_invariants(&h);
            assert_eq!(set.len(), 48);
            for o in binary_octahedral_group() {
                let target = frame_su2(&q.mul(&o));
                assert!(set.iter().any(|p| (p.u - target.u).norm() + (p.v - target.v).norm() < 1e-9));
            }
            assert!(set.iter().all(|p| model_surface_relative_residual(&octahedral_forms(p)) < 1e-13));
        }
    }

    #[test]
    fn printed_branches_cover_the_degenerate_points() {
        // (u, v) = (1, 0): h = (1, 0, 0), so h1 = 0 (the √(h0³) branch of
        // g2), f̃0 = f̃1 on one branch (uv = 0) and u⁴ = v⁴ on the others;
        // h2 = 0 makes both groupsets the same. Also a point with u⁴ = v⁴,
        // uv ≠ 0 and one with h0 = 0 (f̃0 = 0 on a branch).
        let r = std::f64::consts::FRAC_1_SQRT_2;
        let z4 = C64::new(-7.0 + 48f64.sqrt(), 0.0);
        let u_h0 = z4.sqrt().sqrt();
        let n = (u_h0.norm_sqr() + 1.0).sqrt();
        for pair in [
            Su2 { u: C64::new(1.0, 0.0), v: C64::new(0.0, 0.0) },
            Su2 { u: C64::new(r, 0.0), v: C64::new(0.0, r) },
            Su2 { u: u_h0 / n, v: C64::new(1.0 / n, 0.0) },
        ] {
            let h = octahedral_forms(&pair);
            let flipped = [h[0], h[1], -h[2]];
            let branches = thesis_inverse_branches(&h);
            assert_eq!(branches.len(), 96);
            // The printed formulas lose half of the digits here (a double root
            // of the quadratic for v⁴ under a square root): 1e-6, not 1e-12.
            let loose = |a: &[C64; 3], b: &[C64; 3]| (0..3).all(|k| (a[k] - b[k]).norm() < 1e-6);
            let close = |a: &[C64; 3], b: &[C64; 3]| (0..3).all(|k| (a[k] - b[k]).norm() < 1e-12);
            let bad: Vec<usize> = (0..96)
                .filter(|&i| {
                    let hp = octahedral_forms(&branches[i]);
                    !(loose(&hp, &h) || loose(&hp, &flipped))
                })
                .collect();
            assert!(
                bad.is_empty(),
                "{pair:?}: h {h:?}, bad branches {bad:?}, e.g. {:?}",
                bad.first().map(|&i| (branches[i], octahedral_forms(&branches[i])))
            );
            let set = groupset_from_invariants(&h);
            assert_eq!(set.len(), 48, "{pair:?}");
            // After the (4.22) correction and the polish: exact to round-off.
            assert!(set.iter().all(|p| close(&octahedral_forms(p), &h) && (p.norm_squared() - 1.0).abs() < 1e-12));
        }
    }

    #[test]
    fn non_unit_groupsets_keep_their_norm() {
        let mut rng = StdRng::seed_from_u64(23);
        for _ in 0..50 {
            let scale = rng.random_range(0.2..3.0);
            let q = random_unit(&mut rng);
            let qs = Quat(q.0.map(|c| c * scale));
            let back = frame_quaternion_from_invariants(&frame_invariants(&qs));
            assert!((back.norm() - scale).abs() < 1e-11 * scale);
        }
    }
}
