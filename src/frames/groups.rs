//! The finite quaternion groups of thesis §3.1: the vierer group `V` (8
//! elements), the binary tetrahedral group `T` (24) and the binary
//! octahedral group `O` (48), and the 24 rotations of the cube (the image of
//! `O` in SO(3)) as signed permutation matrices.
//!
//! ```text
//! V = {±1, ±i, ±j, ±k}
//! T = V ∪ {½(±1 ± i ± j ± k)}
//! O = T ∪ {(±1 ± i)/√2, (±1 ± j)/√2, (±1 ± k)/√2, (±i ± j)/√2, (±j ± k)/√2, (±i ± k)/√2}
//! ```
//!
//! Two frame quaternions describe the same frame exactly when they differ by
//! right multiplication with an element of `O`: the frame of `q o` is the
//! frame of `q` with its axes permuted and flipped.

use super::quaternion::{Mat3, Quat};

/// The 8 elements of the vierer group `V` (half turns about the axes, ±1).
pub fn vierer_group() -> Vec<Quat> {
    let mut g = Vec::with_capacity(8);
    for i in 0..4 {
        for s in [1.0, -1.0] {
            let mut q = [0.0; 4];
            q[i] = s;
            g.push(Quat(q));
        }
    }
    g
}

/// The 24 elements of the binary tetrahedral group `T`.
pub fn binary_tetrahedral_group() -> Vec<Quat> {
    let mut g = vierer_group();
    for bits in 0..16u32 {
        let s = |b: u32| if bits & (1 << b) != 0 { -0.5 } else { 0.5 };
        g.push(Quat([s(0), s(1), s(2), s(3)]));
    }
    g
}

/// The 48 elements of the binary octahedral group `O`.
pub fn binary_octahedral_group() -> Vec<Quat> {
    let mut g = binary_tetrahedral_group();
    let r = std::f64::consts::FRAC_1_SQRT_2;
    for a in 0..4 {
        for b in a + 1..4 {
            for (sa, sb) in [(r, r), (r, -r), (-r, r), (-r, -r)] {
                let mut q = [0.0; 4];
                q[a] = sa;
                q[b] = sb;
                g.push(Quat(q));
            }
        }
    }
    g
}

/// The 24 rotations of the cube: all signed permutation matrices with
/// determinant +1 (the image of `O` in SO(3), each element once).
pub fn cube_rotations() -> Vec<Mat3> {
    const PERMS: [[usize; 3]; 6] = [[0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 2, 1], [2, 1, 0], [1, 0, 2]];
    let mut out = Vec::with_capacity(24);
    for (p_idx, p) in PERMS.iter().enumerate() {
        let parity = if p_idx < 3 { 1.0 } else { -1.0 };
        for bits in 0..8u32 {
            let signs = [0, 1, 2].map(|b| if bits & (1 << b) != 0 { -1.0 } else { 1.0 });
            if signs[0] * signs[1] * signs[2] * parity < 0.0 {
                continue;
            }
            let mut m = Mat3::zeros();
            for col in 0..3 {
                m[(p[col], col)] = signs[col];
            }
            out.push(m);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed under product and inverse, with the expected order.
    fn assert_group(g: &[Quat], order: usize) {
        assert_eq!(g.len(), order);
        let find = |q: &Quat| g.iter().any(|p| (0..4).all(|i| (p.0[i] - q.0[i]).abs() < 1e-12));
        for a in g {
            assert!((a.norm() - 1.0).abs() < 1e-15);
            assert!(find(&a.conj()));
            for b in g {
                assert!(find(&a.mul(b)));
            }
        }
    }

    #[test]
    fn groups_are_closed_with_orders_8_24_48() {
        assert_group(&vierer_group(), 8);
        assert_group(&binary_tetrahedral_group(), 24);
        assert_group(&binary_octahedral_group(), 48);
    }

    #[test]
    fn generators_satisfy_the_triplet_relations_4_17() {
        let q = |p: f64, axis: [f64; 3]| {
            let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
            let (s, c) = (std::f64::consts::PI / p).sin_cos();
            Quat([c, s * axis[0] / n, s * axis[1] / n, s * axis[2] / n])
        };
        let minus_one = Quat::new(-1.0, 0.0, 0.0, 0.0);
        let pow = |x: &Quat, n: usize| (1..n).fold(*x, |acc, _| acc.mul(x));
        let close = |x: Quat, y: Quat| (0..4).all(|i| (x.0[i] - y.0[i]).abs() < 1e-14);
        // (3, 3, 2) for T with the thesis's axes.
        let (a, b, c) = (q(3.0, [1.0, 1.0, 1.0]), q(3.0, [-1.0, 1.0, 1.0]), q(2.0, [0.0, 0.0, 1.0]));
        assert!(close(pow(&a, 3), minus_one) && close(pow(&b, 3), minus_one) && close(pow(&c, 2), minus_one));
        assert!(close(a.mul(&b).mul(&c), minus_one));
        // (4, 3, 2) for O: the thesis prints c = (j − k)/√2, for which â b̂ ĉ
        // is not −1 (it is ½(1 − i + j + k)); the relation holds with
        // c = (i + k)/√2 = â b̂ (a half turn), derived from ĉ = −(â b̂)⁻¹.
        let (a, b, c) = (q(4.0, [1.0, 0.0, 0.0]), q(3.0, [1.0, 1.0, 1.0]), q(2.0, [1.0, 0.0, 1.0]));
        assert!(close(pow(&a, 4), minus_one) && close(pow(&b, 3), minus_one) && close(pow(&c, 2), minus_one));
        assert!(close(a.mul(&b).mul(&c), minus_one));
        let thesis_c = q(2.0, [0.0, 1.0, -1.0]);
        assert!(!close(a.mul(&b).mul(&thesis_c), minus_one));
        // Both choices generate the 48 elements of O.
        let g = binary_octahedral_group();
        for gens in [[a, b, c], [a, b, thesis_c]] {
            let mut span = vec![Quat::IDENTITY];
            let mut k = 0;
            while k < span.len() {
                let x = span[k];
                for g in &gens {
                    let y = x.mul(g);
                    if !span.iter().any(|z| close(*z, y)) {
                        span.push(y);
                    }
                }
                k += 1;
            }
            assert_eq!(span.len(), 48);
            assert!(span.iter().all(|x| g.iter().any(|z| close(*z, *x))));
        }
    }

    #[test]
    fn cube_rotations_are_the_image_of_o() {
        let rots = cube_rotations();
        assert_eq!(rots.len(), 24);
        for o in binary_octahedral_group() {
            let m = o.to_matrix();
            assert!(rots.iter().any(|r| (r - m).norm() < 1e-14));
        }
        for r in &rots {
            assert!((r.determinant() - 1.0).abs() < 1e-15);
        }
    }
}
