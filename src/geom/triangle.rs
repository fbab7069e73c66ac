//! Measures of a single 3D triangle: area, normal, corner angles, quality.

use super::Vec3;

/// `(b − a) × (c − a)`: normal of length twice the area (not normalized).
#[inline]
pub fn triangle_area_vector(a: &Vec3, b: &Vec3, c: &Vec3) -> Vec3 {
    (b - a).cross(&(c - a))
}

/// Area of the triangle `(a, b, c)`.
#[inline]
pub fn triangle_area(a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    0.5 * triangle_area_vector(a, b, c).norm()
}

/// Unit normal of `(a, b, c)`, or `None` for a degenerate triangle.
#[inline]
pub fn triangle_normal(a: &Vec3, b: &Vec3, c: &Vec3) -> Option<Vec3> {
    let n = triangle_area_vector(a, b, c);
    let len = n.norm();
    (len > 0.0 && len.is_finite()).then(|| n / len)
}

/// Gradients `∇λᵢ` of the barycentric coordinates of triangle `p` with unit
/// normal `n` and area `area` (each perpendicular to the opposite edge).
pub fn barycentric_gradients(p: &[Vec3; 3], n: &Vec3, area: f64) -> [Vec3; 3] {
    std::array::from_fn(|i| n.cross(&(p[(i + 2) % 3] - p[(i + 1) % 3])) / (2.0 * area))
}

/// Unsigned angle in `[0, π]` between two vectors, computed with `atan2`
/// so that it stays accurate for nearly parallel vectors (slivers).
#[inline]
pub fn angle_between(u: &Vec3, v: &Vec3) -> f64 {
    u.cross(v).norm().atan2(u.dot(v))
}

/// Interior angles at the three corners of `(a, b, c)`.
pub fn corner_angles(a: &Vec3, b: &Vec3, c: &Vec3) -> [f64; 3] {
    [angle_between(&(b - a), &(c - a)), angle_between(&(c - b), &(a - b)), angle_between(&(a - c), &(b - c))]
}

/// Shape quality `4√3·area / Σ edge²`: 1 for equilateral, 0 for degenerate.
pub fn triangle_quality(a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    let s = (b - a).norm_squared() + (c - b).norm_squared() + (a - c).norm_squared();
    if s == 0.0 {
        return 0.0;
    }
    4.0 * 3f64.sqrt() * triangle_area(a, b, c) / s
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn right_triangle_measures() {
        let a = Vec3::new(0.0, 0.0, 0.0);
        let b = Vec3::new(1.0, 0.0, 0.0);
        let c = Vec3::new(0.0, 1.0, 0.0);
        assert!((triangle_area(&a, &b, &c) - 0.5).abs() < 1e-15);
        assert_eq!(triangle_normal(&a, &b, &c).unwrap(), Vec3::z());
        let ang = corner_angles(&a, &b, &c);
        assert!((ang[0] - PI / 2.0).abs() < 1e-15);
        assert!((ang.iter().sum::<f64>() - PI).abs() < 1e-14);
        assert!(triangle_normal(&a, &a, &c).is_none());
    }

    #[test]
    fn equilateral_quality_is_one() {
        let a = Vec3::new(0.0, 0.0, 0.0);
        let b = Vec3::new(1.0, 0.0, 0.0);
        let c = Vec3::new(0.5, 3f64.sqrt() / 2.0, 0.0);
        assert!((triangle_quality(&a, &b, &c) - 1.0).abs() < 1e-14);
    }
}
