//! Small-vector geometry on `f64`: triangle measures, angles and bounding boxes.
//!
//! Conventions: points and vectors are [`Vec3`] (nalgebra `Vector3<f64>`);
//! a triangle `(a, b, c)` is counter-clockwise when seen from the side its
//! normal `(b − a) × (c − a)` points to. Angles are in radians.

pub mod bbox;
pub mod triangle;

pub use bbox::BoundingBox;
pub use triangle::{
    angle_between, corner_angles, triangle_area, triangle_area_vector, triangle_normal, triangle_quality,
};

/// A 3-vector (or point) of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 2-vector (or point) of `f64`, used for parametric `(u, v)` coordinates.
pub type Vec2 = nalgebra::Vector2<f64>;

/// Twice the signed area of the 2D triangle `(a, b, c)`: positive when
/// counter-clockwise. This is the orientation predicate used for the
/// injectivity check of parametrizations (thesis ch. 2 §3).
#[inline]
pub fn orient2d(a: &Vec2, b: &Vec2, c: &Vec2) -> f64 {
    (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
}

/// True when every coordinate of `points` is exactly an `f32` (always the
/// case for binary STL input): such points can be keyed and stored in 32
/// bits with nothing rounded.
pub fn every_coordinate_is_f32(points: &[Vec3]) -> bool {
    use rayon::prelude::*;
    points.par_iter().all(|p| p.iter().all(|&c| f64::from(c as f32) == c))
}
