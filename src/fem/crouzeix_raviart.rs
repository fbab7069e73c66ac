//! Crouzeix–Raviart (CR) elements on triangles: the nonconforming linear
//! element whose degrees of freedom are the values at the edge midpoints
//! (thesis ch. 3 §5, Fig. 3.7).
//!
//! Conventions. Triangle corners `0, 1, 2`; local edge `k` joins corners
//! `k` and `k + 1` (as in [`crate::mesh::Topology::face_edges`]), so edge
//! `k` is opposite corner `(k + 2) % 3`. With barycentric coordinates `λᵢ`,
//! the CR shape function of edge `k` is `ωₖ = 1 − 2 λ_{(k+2)%3}`: it is 1 at
//! the midpoint of edge `k`, 0 at the two other midpoints and −1 at the
//! opposite corner.
//!
//! - Stiffness `Sⱼₖ = ∫ ∇ωⱼ·∇ωₖ = 4 S¹_{opp j, opp k}` (`S¹` the P1 cotangent
//!   stiffness). For `j ≠ k` the two edges meet at a corner of angle `θ` and
//!   `Sⱼₖ = −2 cot θ`; rows sum to zero (constants are in the kernel).
//! - Mass: CR functions are L²-orthogonal on a triangle, `∫ ωⱼ ωₖ = A/3 δⱼₖ`,
//!   so the CR mass matrix is diagonal (no lumping error).
//! - A CR field is linear on the triangle; its values at the corners are
//!   `Gᵢ = Fᵢ + F_{i+2} − F_{i+1}` (the edges through corner `i` count +1,
//!   the opposite edge −1).
//! - Degree-4 integrands: `q = |F|² − 1` is quadratic on the triangle, so it
//!   is interpolated exactly by P2 from its values at the 3 corners and the 3
//!   midpoints; `∫ q² = qᵀ M₂ q` with the P2 mass matrix [`P2_MASS_OVER_AREA`]
//!   is then exact (this is how the Ginzburg–Landau penalty is integrated).

use crate::geom::Vec3;

/// Points where the quadratic `|F|² − 1` is sampled: corners `0..3` then edge
/// midpoints `3..6` (point `3 + k` is the midpoint of edge `k`).
pub const N_P2_NODES: usize = 6;

/// P2 mass matrix divided by the triangle area, nodes ordered as corners
/// `0, 1, 2` then midpoints of edges `0, 1, 2` (edge `k` joins corners `k`,
/// `k+1`). Exact: `∫ p q dA = A · pᵀ M q` for quadratic `p`, `q`.
pub const P2_MASS_OVER_AREA: [[f64; 6]; 6] = {
    const S: f64 = 1.0 / 180.0;
    [
        [6.0 * S, -S, -S, 0.0, -4.0 * S, 0.0],
        [-S, 6.0 * S, -S, 0.0, 0.0, -4.0 * S],
        [-S, -S, 6.0 * S, -4.0 * S, 0.0, 0.0],
        [0.0, 0.0, -4.0 * S, 32.0 * S, 16.0 * S, 16.0 * S],
        [-4.0 * S, 0.0, 0.0, 16.0 * S, 32.0 * S, 16.0 * S],
        [0.0, -4.0 * S, 0.0, 16.0 * S, 16.0 * S, 32.0 * S],
    ]
};

/// Coefficients `c[m][k]`: the value of a CR field at P2 node `m` is
/// `Σₖ c[m][k] Fₖ` (corner `i`: +1 on its two edges, −1 on the opposite one;
/// midpoint `3 + k`: the CR value of edge `k`).
pub const P2_NODE_FROM_CR: [[f64; 3]; 6] =
    [[1.0, -1.0, 1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// CR stiffness matrix `Sⱼₖ = ∫ ∇ωⱼ·∇ωₖ dA` of the triangle `p`, computed
/// with cotangents: off-diagonal `−2 cot θ` (θ the angle between the two
/// edges), diagonal minus the row's off-diagonal sum. Returns zeros for a
/// degenerate triangle (zero area).
pub fn cr_stiffness(p: &[Vec3; 3]) -> [[f64; 3]; 3] {
    let twice_area = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
    if !(twice_area > 0.0) || !twice_area.is_finite() {
        return [[0.0; 3]; 3];
    }
    // cot of the angle at corner c, between the edges to the two other corners.
    let cot = |c: usize| {
        let u = p[(c + 1) % 3] - p[c];
        let w = p[(c + 2) % 3] - p[c];
        u.dot(&w) / twice_area
    };
    let mut s = [[0.0; 3]; 3];
    // Edges j and j+1 meet at corner j+1.
    for j in 0..3 {
        let k = (j + 1) % 3;
        let v = -2.0 * cot(k);
        s[j][k] = v;
        s[k][j] = v;
    }
    for j in 0..3 {
        s[j][j] = -(s[j][(j + 1) % 3] + s[j][(j + 2) % 3]);
    }
    s
}

/// CR shape function values `[ω₀, ω₁, ω₂]` at barycentric coordinates `λ`.
#[inline]
pub fn cr_shape_values(lambda: [f64; 3]) -> [f64; 3] {
    [1.0 - 2.0 * lambda[2], 1.0 - 2.0 * lambda[0], 1.0 - 2.0 * lambda[1]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> [Vec3; 3] {
        [Vec3::new(0.1, -0.2, 0.0), Vec3::new(1.3, 0.1, 0.2), Vec3::new(0.4, 0.9, -0.1)]
    }

    /// Barycentric → point.
    fn point(p: &[Vec3; 3], l: [f64; 3]) -> Vec3 {
        p[0] * l[0] + p[1] * l[1] + p[2] * l[2]
    }

    /// Barycentric coordinates of `x` in the plane of `p` (least squares).
    fn bary(p: &[Vec3; 3], x: &Vec3) -> [f64; 3] {
        let (e1, e2, d) = (p[1] - p[0], p[2] - p[0], x - p[0]);
        let (a, b, c) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
        let (r1, r2) = (d.dot(&e1), d.dot(&e2));
        let det = a * c - b * b;
        let l1 = (r1 * c - r2 * b) / det;
        let l2 = (a * r2 - b * r1) / det;
        [1.0 - l1 - l2, l1, l2]
    }

    #[test]
    fn shape_functions_are_one_at_their_midpoint_and_minus_one_opposite() {
        for k in 0..3 {
            let mut l = [0.0; 3];
            l[k] = 0.5;
            l[(k + 1) % 3] = 0.5;
            let w = cr_shape_values(l);
            for j in 0..3 {
                assert!((w[j] - if j == k { 1.0 } else { 0.0 }).abs() < 1e-15);
            }
            let mut corner = [0.0; 3];
            corner[(k + 2) % 3] = 1.0;
            assert!((cr_shape_values(corner)[k] + 1.0).abs() < 1e-15);
        }
        // P2_NODE_FROM_CR rows are the shape values at corners and midpoints.
        for m in 0..6 {
            let mut l = [0.0; 3];
            if m < 3 {
                l[m] = 1.0;
            } else {
                l[m - 3] = 0.5;
                l[(m - 2) % 3] = 0.5;
            }
            assert_eq!(cr_shape_values(l), P2_NODE_FROM_CR[m]);
        }
    }

    #[test]
    fn stiffness_matches_gradients_of_shape_functions() {
        let p = tri();
        let s = cr_stiffness(&p);
        // Gradient of ω_k by finite differences in the plane (ω_k is linear).
        let area = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
        let c = point(&p, [1.0 / 3.0; 3]);
        let (e1, e2) = ((p[1] - p[0]).normalize(), {
            let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
            n.cross(&(p[1] - p[0])).normalize()
        });
        let grad = |k: usize| {
            let f = |x: Vec3| cr_shape_values(bary(&p, &x))[k];
            let h = 1e-6;
            (f(c + e1 * h) - f(c - e1 * h)) / (2.0 * h) * e1 + (f(c + e2 * h) - f(c - e2 * h)) / (2.0 * h) * e2
        };
        for j in 0..3 {
            for k in 0..3 {
                let exact = grad(j).dot(&grad(k)) * area;
                assert!((s[j][k] - exact).abs() < 1e-6, "{j}{k}: {} {}", s[j][k], exact);
            }
        }
        assert_eq!(cr_stiffness(&[Vec3::zeros(); 3]), [[0.0; 3]; 3]);
    }

    #[test]
    fn p2_mass_integrates_quartics_exactly() {
        // ∫ λ^a λ^b λ^c dA = 2A a! b! c! / (a+b+c+2)!
        let fact = |n: usize| (1..=n).product::<usize>() as f64;
        let moment = |e: [usize; 3]| 2.0 * fact(e[0]) * fact(e[1]) * fact(e[2]) / fact(e[0] + e[1] + e[2] + 2);
        // Quadratics λ_i λ_j: P2 nodal values, then pᵀ M q vs the exact moment.
        let nodes: Vec<[f64; 3]> = (0..6)
            .map(|m| {
                let mut l = [0.0; 3];
                if m < 3 {
                    l[m] = 1.0;
                } else {
                    l[m - 3] = 0.5;
                    l[(m - 2) % 3] = 0.5;
                }
                l
            })
            .collect();
        for (a, b) in [(0, 0), (0, 1), (1, 2), (2, 2)] {
            for (c, d) in [(0, 0), (1, 1), (0, 2), (1, 0)] {
                let p: Vec<f64> = nodes.iter().map(|l| l[a] * l[b]).collect();
                let q: Vec<f64> = nodes.iter().map(|l| l[c] * l[d]).collect();
                let mut got = 0.0;
                for i in 0..6 {
                    for j in 0..6 {
                        got += p[i] * P2_MASS_OVER_AREA[i][j] * q[j];
                    }
                }
                let mut e = [0usize; 3];
                for i in [a, b, c, d] {
                    e[i] += 1;
                }
                assert!((got - moment(e)).abs() < 1e-15, "{a}{b}{c}{d}");
            }
        }
    }
}
