//! Small-vector geometry on `f64`: triangle measures, angles and bounding boxes.
//!
//! Conventions: points and vectors are [`Vec3`] (nalgebra `Vector3<f64>`);
//! a triangle `(a, b, c)` is counter-clockwise when seen from the side its
//! normal `(b − a) × (c − a)` points to. Angles are in radians.

pub mod bbox;
pub mod triangle;

pub use bbox::BoundingBox;
pub use triangle::{
    angle_between, barycentric_gradients, corner_angles, triangle_area, triangle_area_vector, triangle_normal,
    triangle_quality,
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

/// True when the closed segments `ab` and `cd` share a point: they cross,
/// or an end of one lies on the other (collinear segments only when they
/// overlap; a planar chart puts a straight curve's segments on one line).
pub fn segments_meet(a: &Vec2, b: &Vec2, c: &Vec2, d: &Vec2) -> bool {
    let within = |p: &Vec2, q: &Vec2, r: &Vec2| {
        r.x >= p.x.min(q.x) && r.x <= p.x.max(q.x) && r.y >= p.y.min(q.y) && r.y <= p.y.max(q.y)
    };
    let (d1, d2) = (orient2d(c, d, a), orient2d(c, d, b));
    let (d3, d4) = (orient2d(a, b, c), orient2d(a, b, d));
    let opposite = |x: f64, y: f64| (x > 0.0 && y < 0.0) || (x < 0.0 && y > 0.0);
    (opposite(d1, d2) && opposite(d3, d4))
        || (d1 == 0.0 && within(c, d, a))
        || (d2 == 0.0 && within(c, d, b))
        || (d3 == 0.0 && within(a, b, c))
        || (d4 == 0.0 && within(a, b, d))
}

/// The pairs `[i, j]` of `segments` (index pairs into `points`) that meet
/// ([`segments_meet`]) and share no end, `i` the later in the sweep:
/// segments are swept in order of their smallest `x`, each tested against
/// the earlier ones whose `x` range reaches it.
pub fn meeting_segments(points: &[Vec2], segments: &[[usize; 2]]) -> Vec<[usize; 2]> {
    let span = |s: &[usize; 2]| (points[s[0]].x.min(points[s[1]].x), points[s[0]].x.max(points[s[1]].x));
    let mut order: Vec<usize> = (0..segments.len()).collect();
    order.sort_by(|&i, &j| span(&segments[i]).0.total_cmp(&span(&segments[j]).0).then(i.cmp(&j)));
    let mut active: Vec<usize> = Vec::new();
    let mut out = Vec::new();
    for &i in &order {
        let [a, b] = segments[i];
        let lo = span(&segments[i]).0;
        active.retain(|&j| span(&segments[j]).1 >= lo);
        for &j in &active {
            let [c, d] = segments[j];
            if [c, d].contains(&a) || [c, d].contains(&b) {
                continue;
            }
            if segments_meet(&points[a], &points[b], &points[c], &points[d]) {
                out.push([i, j]);
            }
        }
        active.push(i);
    }
    out
}

/// True when every coordinate of `points` is exactly an `f32` (always the
/// case for binary STL input): such points can be keyed and stored in 32
/// bits with nothing rounded.
pub fn every_coordinate_is_f32(points: &[Vec3]) -> bool {
    use rayon::prelude::*;
    points.par_iter().all(|p| p.iter().all(|&c| f64::from(c as f32) == c))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_meet_when_they_cross_touch_or_overlap() {
        let p = |x: f64, y: f64| Vec2::new(x, y);
        assert!(segments_meet(&p(0.0, 0.0), &p(1.0, 1.0), &p(0.0, 1.0), &p(1.0, 0.0)), "crossing");
        assert!(segments_meet(&p(0.0, 0.0), &p(2.0, 0.0), &p(1.0, 0.0), &p(1.0, 1.0)), "an end on the other");
        assert!(segments_meet(&p(0.0, 0.0), &p(2.0, 0.0), &p(1.0, 0.0), &p(3.0, 0.0)), "collinear overlap");
        assert!(!segments_meet(&p(0.0, 0.0), &p(1.0, 0.0), &p(2.0, 0.0), &p(3.0, 0.0)), "collinear apart");
        assert!(
            !segments_meet(&p(0.0, 0.0), &p(1.0, 0.0), &p(3.0, 0.0), &p(3.0, 1.0)),
            "an end on the line, off the segment"
        );
        assert!(!segments_meet(&p(0.0, 0.0), &p(1.0, 0.0), &p(0.0, 1.0), &p(1.0, 1.0)), "parallel");
    }
}
