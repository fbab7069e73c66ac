//! Scaled Jacobian and angle deviation of a quadrangle on a surface, the
//! shape measures every step of the quads stage agrees on.
//!
//! The scaled Jacobian at corner `i` of a quad `p0 p1 p2 p3` is
//! `((p_{i+1} − p_i) × (p_{i−1} − p_i)) · n / (|p_{i+1} − p_i| |p_{i−1} − p_i|)`
//! with `n` the unit normal of the surface under the quad (Verdict's
//! definition measured against the surface instead of the quad's own
//! plane, so a quad folded over relative to the surface is negative). It is
//! 1 for a square, ≤ 0 for an inverted or degenerate corner; the quad's value
//! is the minimum over its corners. A surface quad is also measured against
//! its own normals ([`surface_quad_scaled_jacobian`]), Gmsh's among them.

use super::surface_mesh::{ModelEntity, SurfacePoint, SurfaceVertices};
use crate::geom::Vec3;

/// Scaled Jacobian of each corner of the quad with corners `p`, measured
/// against the unit normal `n` (0 for a corner with a zero-length edge).
pub fn corner_scaled_jacobians(p: &[Vec3; 4], n: &Vec3) -> [f64; 4] {
    corner_frames(p).map(|frame| corner_value(&frame, n))
}

/// Per corner `i` of the quad `p`: the cross product of its two edges
/// `(p_{i+1} − p_i) × (p_{i−1} − p_i)` and the product of their lengths,
/// what every normal's scaled Jacobian at that corner divides.
fn corner_frames(p: &[Vec3; 4]) -> [(Vec3, f64); 4] {
    std::array::from_fn(|i| {
        let a = p[(i + 1) % 4] - p[i];
        let b = p[(i + 3) % 4] - p[i];
        (a.cross(&b), a.norm() * b.norm())
    })
}

/// Scaled Jacobian of one corner ([`corner_frames`]) against the unit
/// normal `n` (0 for a corner with a zero-length edge).
fn corner_value((cross, d): &(Vec3, f64), n: &Vec3) -> f64 {
    if *d > 0.0 { cross.dot(n) / d } else { 0.0 }
}

/// The quad's scaled Jacobian: the minimum over its corners.
pub fn scaled_jacobian(p: &[Vec3; 4], n: &Vec3) -> f64 {
    corner_scaled_jacobians(p, n).into_iter().fold(f64::INFINITY, f64::min)
}

/// Largest deviation from 90° of a corner angle of the quad with corners
/// `p`, in degrees (angles measured in 3D).
pub fn max_angle_deviation_deg(p: &[Vec3; 4]) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..4 {
        let a = p[(i + 1) % 4] - p[i];
        let b = p[(i + 3) % 4] - p[i];
        let angle = crate::geom::angle_between(&a, &b).to_degrees();
        worst = worst.max((angle - 90.0).abs());
    }
    worst
}

/// Scaled Jacobian of the surface quad `p`: the worst of its scaled
/// Jacobian against the surface normal `n` under it, against its own
/// centre normal (the cross product of its diagonals), and against the
/// normal of each of its four corner triangles `(p_i, p_{i+1}, p_{i+2})`.
/// The centre normal makes a quad folded across a crease count as inverted
/// even when each corner agrees with the surface under it. The corner
/// triangles are what Gmsh measures a surface quad against (`MFace::normal`,
/// the plane of its first three nodes, in `minSICN`): a warped quad can be
/// positive against its centre normal and negative against one of them,
/// which Gmsh rates inverted when the quad is written from that corner.
/// Every rotation is checked, so no order the quad is written in fails.
pub fn surface_quad_scaled_jacobian(p: &[Vec3; 4], n: &Vec3) -> f64 {
    surface_quad_scaled_jacobian_until(p, n, f64::NEG_INFINITY)
}

/// [`surface_quad_scaled_jacobian`], stopping as soon as a normal puts the
/// quad below `floor`: the value returned is then only known to be below
/// `floor` (a guard that rejects anything below it needs no more). The
/// corners' frames ([`corner_frames`]) are formed once for the six normals.
pub fn surface_quad_scaled_jacobian_until(p: &[Vec3; 4], n: &Vec3, floor: f64) -> f64 {
    let corners = corner_frames(p);
    let against = |unit: &Vec3| corners.iter().map(|c| corner_value(c, unit)).fold(f64::INFINITY, f64::min);
    let mut worst = against(n);
    if worst < floor {
        return worst;
    }
    let own = (p[2] - p[0]).cross(&(p[3] - p[1]));
    for normal in std::iter::once(own).chain((0..4).map(|i| (p[(i + 1) % 4] - p[i]).cross(&(p[(i + 2) % 4] - p[i])))) {
        worst = match normal.try_normalize(0.0) {
            Some(unit) => worst.min(against(&unit)),
            None => worst.min(0.0),
        };
        if worst < floor {
            return worst;
        }
    }
    worst
}

/// Unit normal of the input surface under quad `quad` of `vertices`: the
/// mean normal of the input triangles carrying its corners that lie inside
/// a model face (a curve or corner vertex sits on an edge shared with
/// another face, whose normal may point elsewhere); the quad's own
/// (Newell) normal when all four corners lie on curves or corners.
/// `normals` holds the unit normal of every input triangle
/// ([`crate::mesh::TriMesh::face_normals`]).
pub fn quad_reference_normal(vertices: &SurfaceVertices, normals: &[Vec3], quad: &[u32; 4]) -> Vec3 {
    reference_normal_of_corners(normals, &quad.map(|v| corner_of(vertices, v)))
}

/// What the reference normal reads of a quad corner: its model entity,
/// where it lies on the input, its position.
pub type QuadCorner = (ModelEntity, SurfacePoint, Vec3);

/// Corner data of vertex `v`.
pub fn corner_of(vertices: &SurfaceVertices, v: u32) -> QuadCorner {
    (vertices.entity[v as usize], vertices.on_surface[v as usize], vertices.positions[v as usize])
}

/// Scaled Jacobian of a quad given by its corners' data against the input
/// surface's normal under it ([`surface_quad_scaled_jacobian`] against
/// [`reference_normal_of_corners`]).
pub fn scaled_jacobian_of_corners(normals: &[Vec3], corners: &[QuadCorner; 4]) -> f64 {
    scaled_jacobian_of_corners_until(normals, corners, f64::NEG_INFINITY)
}

/// [`scaled_jacobian_of_corners`], stopping below `floor` as
/// [`surface_quad_scaled_jacobian_until`] does.
pub fn scaled_jacobian_of_corners_until(normals: &[Vec3], corners: &[QuadCorner; 4], floor: f64) -> f64 {
    surface_quad_scaled_jacobian_until(&corners.map(|c| c.2), &reference_normal_of_corners(normals, corners), floor)
}

/// [`quad_reference_normal`] of a quad given by its corners' data (so that
/// a corner can be evaluated at a trial position without moving it).
pub fn reference_normal_of_corners(normals: &[Vec3], corners: &[QuadCorner; 4]) -> Vec3 {
    let mut n = Vec3::zeros();
    for (entity, on_surface, _) in corners {
        if matches!(entity, ModelEntity::Face(_)) {
            n += normals[on_surface.face.idx()];
        }
    }
    if n.norm_squared() == 0.0 {
        for i in 0..4 {
            n += corners[i].2.cross(&corners[(i + 1) % 4].2);
        }
    }
    let len = n.norm();
    if len > 0.0 { n / len } else { n }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> [Vec3; 4] {
        [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)]
    }

    /// Stopped early only below the floor, exact otherwise.
    #[test]
    fn the_early_stop_is_exact_above_the_floor_and_below_it_when_stopped() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let mut rng = StdRng::seed_from_u64(7);
        let mut r = || rng.random_range(-0.5..0.5);
        let n = Vec3::new(0.1, -0.2, 1.0).normalize();
        for _ in 0..2000 {
            let mut p = square();
            for c in &mut p {
                *c += Vec3::new(r(), r(), 0.3 * r());
            }
            let exact = surface_quad_scaled_jacobian(&p, &n);
            let floor = 2.0 * r();
            let stopped = surface_quad_scaled_jacobian_until(&p, &n, floor);
            if exact >= floor {
                assert_eq!(stopped, exact);
            } else {
                assert!(stopped < floor && stopped >= exact);
            }
        }
    }

    #[test]
    fn a_quad_is_measured_against_the_surface_and_its_own_centre_normal() {
        let z = Vec3::new(0.0, 0.0, 1.0);
        let square =
            [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        assert!((surface_quad_scaled_jacobian(&square, &z) - 1.0).abs() < 1e-12);
        // Clockwise against +z: −1 against the surface, whatever its own normal says.
        let cw = [square[0], square[3], square[2], square[1]];
        assert!((surface_quad_scaled_jacobian(&cw, &z) + 1.0).abs() < 1e-12);
        // A bow tie (corners 2 and 3 swapped): its diagonals are parallel, no own normal.
        let bow = [square[0], square[1], square[3], square[2]];
        assert!(surface_quad_scaled_jacobian(&bow, &z) <= 0.0);
    }

    #[test]
    fn a_warped_quad_is_measured_against_every_corner_triangle_as_gmsh_would() {
        // plate_holes.stl, quad [59, 1207, 1208, 1206]: corner angles 30°,
        // 132°, 37°, 131°. Against its centre normal every corner is about
        // 0.5; against the plane of its first three corners (Gmsh's
        // reference) corner 3 is −0.001, and Gmsh rated it minSICN −0.70.
        let p = [
            Vec3::new(121.16467687, 304.80001831, 12.69999981),
            Vec3::new(124.66052544, 304.80001831, 6.57548487),
            Vec3::new(123.88373875, 300.93843083, 0.56635135),
            Vec3::new(121.07025125, 304.34934742, 4.14089334),
        ];
        let centre = (p[2] - p[0]).cross(&(p[3] - p[1])).normalize();
        assert!(scaled_jacobian(&p, &centre) > 0.48);
        let first_three = (p[1] - p[0]).cross(&(p[2] - p[0])).normalize();
        assert!(corner_scaled_jacobians(&p, &first_three)[3] < 0.0);
        assert!(surface_quad_scaled_jacobian(&p, &centre) < 0.0);
        // A planar convex quad is unaffected.
        let z = Vec3::z();
        assert!((surface_quad_scaled_jacobian(&square(), &z) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_square_scores_one_and_its_mirror_minus_one() {
        let z = Vec3::z();
        assert!((scaled_jacobian(&square(), &z) - 1.0).abs() < 1e-15);
        assert!((scaled_jacobian(&square(), &-z) + 1.0).abs() < 1e-15);
        assert!(max_angle_deviation_deg(&square()).abs() < 1e-12);
    }

    #[test]
    fn a_rhombus_of_60_degrees_scores_sin_60_and_deviates_30() {
        let s = 3f64.sqrt() / 2.0;
        let p = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.5, s, 0.0), Vec3::new(0.5, s, 0.0)];
        assert!((scaled_jacobian(&p, &Vec3::z()) - s).abs() < 1e-12);
        assert!((max_angle_deviation_deg(&p) - 30.0).abs() < 1e-9);
    }

    #[test]
    fn a_non_convex_quad_is_negative_at_its_reflex_corner() {
        let p =
            [Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.5, 0.5, 0.0), Vec3::new(0.0, 2.0, 0.0)];
        let j = corner_scaled_jacobians(&p, &Vec3::z());
        assert!(j[2] < 0.0 && j[0] > 0.0);
    }
}
