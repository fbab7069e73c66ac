//! The norm of the groupset of a model-surface coordinate, without
//! computing a quaternion (thesis §4.3).
//!
//! The binary octahedral group maps the vierer form `(uv)²` onto the three
//! values `(uv)²`, `−(u² + v²)²/4`, `(u² − v²)²/4` (the thesis prints the
//! middle one without its square). They are the roots of
//!
//! ```text
//! 16 x³ − h0 x + h1 = 0                                   (4.29)
//! ```
//!
//! (their sum is 0, the sum of their pairwise products `−h0/16`, their
//! product `−h1/16`). For a root `x*`, `u⁸` and `v⁸` are the roots of
//!
//! ```text
//! y² − (h0 − 14 x*²) y + x*⁴ = 0,   Δ² = h0² − 28 h0 x*² + 192 x*⁴   (4.30)
//! ```
//!
//! and `|u|² + |v|² = |u⁸|^¼ + |v⁸|^¼`, the same for every root (another
//! root is another pair of the groupset). Both polynomials are solved in a
//! cancellation-free way (Cardano with the larger cube-root argument, the
//! larger quadratic root first and the other from the product), and the
//! cubic root is refined by Newton steps.

use super::su2::C64;

/// `|u|² + |v|²` of the groupset of `h` by (4.29)–(4.30); this is `|q|²` of
/// the quaternions with these invariants (1 for frames given by unit
/// quaternions). Defined for points on the model surface.
pub fn su2_norm_squared_from_invariants(h: &[C64; 3]) -> f64 {
    let (h0, h1) = (h[0], h[1]);
    let x = cubic_root_4_29(h0, h1);
    let b = h0 - x * x * 14.0;
    let x4 = (x * x) * (x * x);
    let delta = (b * b - x4 * 4.0).sqrt();
    let big = if (b + delta).norm() >= (b - delta).norm() { (b + delta) * 0.5 } else { (b - delta) * 0.5 };
    let small = if big.norm() > 0.0 { x4 / big } else { C64::new(0.0, 0.0) };
    big.norm().powf(0.25) + small.norm().powf(0.25)
}

/// One root of `16 x³ − h0 x + h1 = 0` (4.29), refined by Newton.
pub fn cubic_root_4_29(h0: C64, h1: C64) -> C64 {
    // Depressed cubic x³ + p x + q = 0.
    let p = -h0 / 16.0;
    let q = h1 / 16.0;
    let disc = (q * q * 0.25 + p * p * p / 27.0).sqrt();
    let (a, b) = (-q * 0.5 + disc, -q * 0.5 - disc);
    let w = if a.norm() >= b.norm() { a } else { b }.cbrt();
    let mut x = if w.norm() > 0.0 { w - p / (w * 3.0) } else { C64::new(0.0, 0.0) };
    for _ in 0..3 {
        let f = x * x * x + p * x + q;
        let df = x * x * 3.0 + p;
        if df.norm() == 0.0 {
            break;
        }
        let next = x - f / df;
        if (next * next * next + p * next + q).norm() < f.norm() {
            x = next;
        } else {
            break;
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::super::invariants::{frame_invariants, octahedral_forms, vierer_forms};
    use super::super::quaternion::Quat;
    use super::super::su2::{Su2, su2_from_quaternion};
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    #[test]
    fn norm_from_invariants_recovers_the_quaternion_norm() {
        let mut rng = StdRng::seed_from_u64(31);
        for _ in 0..500 {
            let q = Quat::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let scale: f64 = rng.random_range(0.3..2.0);
            let q = Quat(q.normalized().0.map(|c| c * scale));
            let n2 = su2_norm_squared_from_invariants(&frame_invariants(&q));
            assert!((n2 - q.norm_squared()).abs() < 1e-12 * q.norm_squared(), "{n2} vs {}", q.norm_squared());
        }
    }

    #[test]
    fn the_three_roots_are_the_images_of_uv_squared() {
        let q = Quat::new(0.3, -0.5, 0.1, 0.8).normalized();
        let s = su2_from_quaternion(&q);
        let h = octahedral_forms(&s);
        let (u, v) = (s.u, s.v);
        let roots =
            [vierer_forms(&s)[0], -(u * u + v * v) * (u * u + v * v) * 0.25, (u * u - v * v) * (u * u - v * v) * 0.25];
        for x in roots {
            assert!((x * x * x * 16.0 - h[0] * x + h[1]).norm() < 1e-14);
        }
        // Any root gives the same norm: evaluate (4.30) at each.
        for x in roots {
            let b = h[0] - x * x * 14.0;
            let d = (h[0] * h[0] - h[0] * x * x * 28.0 + x * x * x * x * 192.0).sqrt();
            let n = ((b + d) * 0.5).norm().powf(0.25) + ((b - d) * 0.5).norm().powf(0.25);
            assert!((n - 1.0).abs() < 1e-12);
        }
        // Degenerate: u = 0 or v = 0 or u⁴ = v⁴.
        for pair in [
            Su2 { u: C64::new(1.0, 0.0), v: C64::new(0.0, 0.0) },
            Su2 { u: C64::new(0.0, 0.0), v: C64::new(0.0, 2.0) },
            Su2 { u: C64::new(1.0, 0.0), v: C64::new(0.0, 1.0) },
        ] {
            let n2 = su2_norm_squared_from_invariants(&octahedral_forms(&pair));
            assert!((n2 - pair.norm_squared()).abs() < 1e-12 * pair.norm_squared());
        }
    }
}
