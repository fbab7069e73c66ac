//! Edge flips of a patch triangulation toward good triangles on the surface.
//!
//! The triangulation of step 3 is Delaunay in the patch's `(u, v)` plane,
//! which is not Delaunay on the surface: where the chart stretches one way
//! more than the other (mean value maps do near a patch's boundary), the
//! `(u, v)` circumcircle test can pick the diagonal that is short in
//! `(u, v)` and long in 3D: a sliver on the surface, or a triangle folded
//! over it (its normal against the surface's). Gmsh meets the same problem
//! with a metric in the parametric plane; here the triangulation is
//! corrected afterwards by flips judged on the 3D points, in two passes:
//!
//! 1. [`flip_to_delaunay_in_3d`]: an edge whose two opposite angles, measured
//!    in 3D, add up to more than `π +` [`DELAUNAY_ANGLE_MARGIN`] is flipped
//!    (the circumcircle test with 3D lengths). The frontal points were
//!    placed at the target size in 3D, so this recovers the triangles their
//!    spacing asks for. The margin keeps the chart's diagonal in
//!    near-cocircular pairs (the square cells of the frontal lattice, whose
//!    angle sums scatter a few degrees around π), so the lattice is not
//!    scrambled.
//! 2. [`flip_toward_surface_shape`]: an edge next to a folded triangle
//!    (signed shape ≤ 0, [`signed_shape`]) is flipped when the worse of the
//!    pair improves.
//!
//! Every flip keeps both new triangles counter-clockwise in `(u, v)` (the
//! triangulation stays embedded in the chart) and makes no triangle of
//! signed shape below [`MIN_SHAPE_MADE`] (no fold, and no flat triangle such
//! as three points of a straight curve). Constrained edges (the patch
//! boundary) are never flipped. Each pass is bounded, so it ends; it
//! depends on the triangles' order only, which is the triangulation's
//! (deterministic).

use std::collections::HashMap;

use crate::geom::{Vec2, Vec3, orient2d};

/// The geometry the flips are judged on, per chart point.
pub struct FlipGeometry<'a> {
    /// `(u, v)` of every point.
    pub uv: &'a [Vec2],
    /// 3D position of every point.
    pub position: &'a [Vec3],
    /// Surface normal at a `(u, v)` location of the chart, oriented so that a
    /// triangle counter-clockwise in `(u, v)` faces it when upright.
    pub normal_at: &'a dyn Fn(&Vec2) -> Vec3,
}

/// Flips made at most per triangle and pass (a bound that real inputs never
/// reach; it keeps a pathological chart from looping).
const MAX_FLIPS_PER_TRIANGLE: usize = 8;

/// Smallest [`signed_shape`] a flip may make: a flip that would make a
/// degenerate triangle (three points of a straight curve, say) is not made.
const MIN_SHAPE_MADE: f64 = 0.01;

/// Radians by which the 3D angles opposite an edge must exceed π before
/// [`flip_to_delaunay_in_3d`] flips it (about 11.5°; the choice and the
/// values measured are in `docs/decisions.md`).
pub const DELAUNAY_ANGLE_MARGIN: f64 = 0.2;

/// Signed shape of the 3D triangle `(a, b, c)` against the normal `n`:
/// `2√3 ((b − a) × (c − a)) · n / (|ab|² + |bc|² + |ca|²)`, which is 1 for an
/// equilateral triangle facing `n`, near 0 for a sliver and negative for a
/// triangle folded against `n`.
pub fn signed_shape(a: &Vec3, b: &Vec3, c: &Vec3, n: &Vec3) -> f64 {
    let sum = (b - a).norm_squared() + (c - b).norm_squared() + (a - c).norm_squared();
    if sum <= 0.0 {
        return 0.0;
    }
    2.0 * 3f64.sqrt() * (b - a).cross(&(c - a)).dot(n) / sum
}

/// Angle at `c` of the 3D triangle `(a, b, c)`, in radians.
fn angle_at(a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    let (u, v) = (a - c, b - c);
    u.cross(&v).norm().atan2(u.dot(&v))
}

/// The vertex of `t` opposite the directed edge `a → b`, when `t` has it.
fn opposite(t: &[usize; 3], a: usize, b: usize) -> Option<usize> {
    (0..3).find(|&i| t[i] == a && t[(i + 1) % 3] == b).map(|i| t[(i + 2) % 3])
}

/// A pair of triangles `(a, b, c)`, `(b, a, d)` across the edge `a–b`, as a
/// flip criterion sees it: the signed shapes of the pair before and after
/// the flip to `(a, d, c)`, `(d, b, c)`, against the surface normal at the
/// edge, and the 3D points.
struct Pair<'a> {
    a: usize,
    b: usize,
    c: usize,
    d: usize,
    position: &'a [Vec3],
    /// Worse signed shape of the two triangles now.
    before: f64,
    /// Worse signed shape of the two triangles the flip makes.
    after: f64,
}

/// Flips edges of `triangles` (counter-clockwise in `(u, v)`) for which
/// `wanted` holds, among those the module doc allows (not constrained, new
/// triangles counter-clockwise in `(u, v)` and of shape at least
/// [`MIN_SHAPE_MADE`]), until none is left or the bound is reached; the
/// edges of each flipped pair are examined again. Returns the flips made.
fn flip_while(
    geometry: &FlipGeometry<'_>,
    triangles: &mut [[usize; 3]],
    is_constrained: &dyn Fn(usize, usize) -> bool,
    wanted: impl Fn(&Pair<'_>) -> bool,
) -> usize {
    let key = |a: usize, b: usize| (a.min(b), a.max(b));
    let mut faces_of: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
    for (f, t) in triangles.iter().enumerate() {
        for i in 0..3 {
            faces_of.entry(key(t[i], t[(i + 1) % 3])).or_default().push(f);
        }
    }
    let mut stack: Vec<(usize, usize)> = faces_of.keys().copied().collect();
    stack.sort_unstable();
    stack.reverse();
    let (uv, position) = (geometry.uv, geometry.position);
    let budget = MAX_FLIPS_PER_TRIANGLE * triangles.len();
    let mut n_flips = 0;
    while let Some((p, q)) = stack.pop() {
        if n_flips >= budget {
            break;
        }
        let Some(faces) = faces_of.get(&(p, q)) else { continue };
        if faces.len() != 2 || is_constrained(p, q) {
            continue;
        }
        let (f1, f2) = (faces[0], faces[1]);
        // Orient the pair as t1 = (a, b, c), t2 = (b, a, d).
        let (a, b) = if opposite(&triangles[f1], p, q).is_some() { (p, q) } else { (q, p) };
        let (Some(c), Some(d)) = (opposite(&triangles[f1], a, b), opposite(&triangles[f2], b, a)) else { continue };
        if c == d || orient2d(&uv[a], &uv[d], &uv[c]) <= 0.0 || orient2d(&uv[d], &uv[b], &uv[c]) <= 0.0 {
            continue;
        }
        let n = (geometry.normal_at)(&((uv[a] + uv[b]) * 0.5));
        let shape = |x: usize, y: usize, z: usize| signed_shape(&position[x], &position[y], &position[z], &n);
        let pair = Pair {
            a,
            b,
            c,
            d,
            position,
            before: shape(a, b, c).min(shape(b, a, d)),
            after: shape(a, d, c).min(shape(d, b, c)),
        };
        if pair.after < MIN_SHAPE_MADE || !wanted(&pair) {
            continue;
        }
        triangles[f1] = [a, d, c];
        triangles[f2] = [d, b, c];
        faces_of.remove(&key(a, b));
        faces_of.insert(key(c, d), vec![f1, f2]);
        for (edge, from, to) in [(key(b, c), f1, f2), (key(a, d), f2, f1)] {
            if let Some(fs) = faces_of.get_mut(&edge) {
                fs.iter_mut().filter(|f| **f == from).for_each(|f| *f = to);
            }
        }
        stack.extend([key(a, d), key(d, b), key(b, c), key(c, a)]);
        n_flips += 1;
    }
    n_flips
}

/// Pass 1 of the module doc: flips the edges of `triangles` (counter-clockwise
/// in `(u, v)`, indexing the points of `geometry`) whose opposite 3D angles
/// add up to more than `π +` [`DELAUNAY_ANGLE_MARGIN`]; `is_constrained`
/// names the edges that must stay. Returns the number of flips.
pub fn flip_to_delaunay_in_3d(
    geometry: &FlipGeometry<'_>,
    triangles: &mut [[usize; 3]],
    is_constrained: &dyn Fn(usize, usize) -> bool,
) -> usize {
    flip_while(geometry, triangles, is_constrained, |e| {
        let p = e.position;
        angle_at(&p[e.a], &p[e.b], &p[e.c]) + angle_at(&p[e.a], &p[e.b], &p[e.d])
            > std::f64::consts::PI + DELAUNAY_ANGLE_MARGIN
    })
}

/// Pass 2 of the module doc: flips edges of `triangles` next to a folded
/// triangle when the flip improves the worse triangle of the pair in 3D;
/// `is_constrained` names the edges that must stay. Returns the number of
/// flips.
pub fn flip_toward_surface_shape(
    geometry: &FlipGeometry<'_>,
    triangles: &mut [[usize; 3]],
    is_constrained: &dyn Fn(usize, usize) -> bool,
) -> usize {
    flip_while(geometry, triangles, is_constrained, |e| e.before <= 0.0 && e.after > e.before + 1e-9)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square in `(u, v)` whose corner 2 sits, on the surface, at
    /// (0.2, 0.2): the diagonal 1–3 then folds the triangle (1, 2, 3) over
    /// the surface (normal +z), the diagonal 0–2 does not.
    fn dented_square() -> (Vec<Vec2>, Vec<Vec3>) {
        let uv = vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)];
        let position = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.2, 0.2, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        (uv, position)
    }

    /// The surface normal of the tests: +z everywhere.
    fn up(_: &Vec2) -> Vec3 {
        Vec3::z()
    }

    fn worst(tris: &[[usize; 3]], position: &[Vec3]) -> f64 {
        tris.iter()
            .map(|t| signed_shape(&position[t[0]], &position[t[1]], &position[t[2]], &Vec3::z()))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn shape_is_one_for_equilateral_and_changes_sign_with_the_normal() {
        let (a, b, c) = (Vec3::zeros(), Vec3::x(), Vec3::new(0.5, 3f64.sqrt() / 2.0, 0.0));
        assert!((signed_shape(&a, &b, &c, &Vec3::z()) - 1.0).abs() < 1e-12);
        assert!((signed_shape(&a, &b, &c, &-Vec3::z()) + 1.0).abs() < 1e-12);
        assert_eq!(signed_shape(&a, &a, &a, &Vec3::z()), 0.0);
    }

    #[test]
    fn a_folded_pair_is_flipped_to_the_diagonal_that_follows_the_surface() {
        let (uv, position) = dented_square();
        let geometry = FlipGeometry { uv: &uv, position: &position, normal_at: &up };
        let mut tris = vec![[0, 1, 3], [1, 2, 3]];
        assert!(worst(&tris, &position) < 0.0);
        assert_eq!(flip_toward_surface_shape(&geometry, &mut tris, &|_, _| false), 1);
        assert!(worst(&tris, &position) > 0.0);
        let mut sorted: Vec<[usize; 3]> = tris
            .iter()
            .map(|t| {
                let mut t = *t;
                t.sort_unstable();
                t
            })
            .collect();
        sorted.sort_unstable();
        assert_eq!(sorted, [[0, 1, 2], [0, 2, 3]]);
        for t in &tris {
            assert!(orient2d(&uv[t[0]], &uv[t[1]], &uv[t[2]]) > 0.0, "{t:?} stays counter-clockwise in (u, v)");
        }
        // Already the better diagonal: nothing to do.
        assert_eq!(flip_toward_surface_shape(&geometry, &mut tris, &|_, _| false), 0);
    }

    /// A planar square whose chart is stretched 4× along v: in (u, v) the
    /// diagonal 0–2 of the rhombus-like pair is Delaunay, in 3D it is the
    /// long one (opposite angles 2·76° > 180° + margin), so the 3D pass flips
    /// it to 1–3; the fold pass, which sees no fold, does not.
    /// The rhombus of [`a_diagonal_long_in_3d_is_flipped_to_the_short_one`]:
    /// 3D points with diagonals 0–2 of length 2 and 1–3 of length 1, and a
    /// chart stretching y 4× (so 0–2 is the `(u, v)` Delaunay diagonal).
    fn stretched_rhombus() -> (Vec<Vec2>, Vec<Vec3>) {
        let position = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, -0.5, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(1.0, 0.5, 0.0),
        ];
        let uv: Vec<Vec2> = position.iter().map(|p| Vec2::new(p.x, 4.0 * p.y)).collect();
        (uv, position)
    }

    #[test]
    fn a_diagonal_long_in_3d_is_flipped_to_the_short_one() {
        let (uv, position) = stretched_rhombus();
        let geometry = FlipGeometry { uv: &uv, position: &position, normal_at: &up };
        let mut tris = vec![[0, 1, 2], [0, 2, 3]];
        assert_eq!(flip_toward_surface_shape(&geometry, &mut tris, &|_, _| false), 0);
        assert_eq!(flip_to_delaunay_in_3d(&geometry, &mut tris, &|_, _| false), 1);
        let mut edges: Vec<(usize, usize)> = tris
            .iter()
            .flat_map(|t| (0..3).map(move |i| (t[i].min(t[(i + 1) % 3]), t[i].max(t[(i + 1) % 3]))))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        assert!(edges.contains(&(1, 3)) && !edges.contains(&(0, 2)), "{edges:?}");
        for t in &tris {
            assert!(orient2d(&uv[t[0]], &uv[t[1]], &uv[t[2]]) > 0.0, "{t:?} stays counter-clockwise in (u, v)");
        }
        // Delaunay now: nothing more to flip; a constrained diagonal stays.
        assert_eq!(flip_to_delaunay_in_3d(&geometry, &mut tris, &|_, _| false), 0);
        let mut tris = vec![[0, 1, 2], [0, 2, 3]];
        assert_eq!(flip_to_delaunay_in_3d(&geometry, &mut tris, &|a, b| (a.min(b), a.max(b)) == (0, 2)), 0);
    }

    /// Against a surface facing the other way, both diagonals make folded
    /// triangles: the 3D pass makes no flip that folds.
    #[test]
    fn a_flip_that_makes_a_folded_triangle_is_not_made() {
        let (uv, position) = stretched_rhombus();
        let down = |_: &Vec2| -Vec3::z();
        let geometry = FlipGeometry { uv: &uv, position: &position, normal_at: &down };
        let mut tris = vec![[0, 1, 2], [0, 2, 3]];
        assert_eq!(flip_to_delaunay_in_3d(&geometry, &mut tris, &|_, _| false), 0);
        assert_eq!(tris, vec![[0, 1, 2], [0, 2, 3]]);
    }

    /// A square cell (cocircular, opposite angles 90° + 90°) and a nearly
    /// square one (within the margin) keep the diagonal the chart chose.
    #[test]
    fn near_cocircular_pairs_keep_their_diagonal() {
        for skew in [0.0, 0.05] {
            let position = vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0 + skew, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ];
            let uv: Vec<Vec2> = position.iter().map(|p| Vec2::new(p.x, p.y)).collect();
            let geometry = FlipGeometry { uv: &uv, position: &position, normal_at: &up };
            for diagonal in [vec![[0, 1, 2], [0, 2, 3]], vec![[0, 1, 3], [1, 2, 3]]] {
                let mut tris = diagonal.clone();
                assert_eq!(flip_to_delaunay_in_3d(&geometry, &mut tris, &|_, _| false), 0, "skew {skew}");
                assert_eq!(tris, diagonal);
            }
        }
    }

    #[test]
    fn upright_slivers_are_left_alone() {
        // A kite whose long diagonal 0–2 makes two upright slivers: no fold, no flip.
        let position = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, -0.1, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(1.0, 0.1, 0.0),
        ];
        let uv: Vec<Vec2> = position.iter().map(|p| Vec2::new(p.x, p.y)).collect();
        let geometry = FlipGeometry { uv: &uv, position: &position, normal_at: &up };
        let mut tris = vec![[0, 1, 2], [0, 2, 3]];
        assert!(worst(&tris, &position) > 0.0);
        assert_eq!(flip_toward_surface_shape(&geometry, &mut tris, &|_, _| false), 0);
    }

    #[test]
    fn constrained_edges_and_nonconvex_pairs_stay() {
        let (uv, position) = dented_square();
        let geometry = FlipGeometry { uv: &uv, position: &position, normal_at: &up };
        let mut tris = vec![[0, 1, 3], [1, 2, 3]];
        let constrained = |a: usize, b: usize| (a.min(b), a.max(b)) == (1, 3);
        assert_eq!(flip_toward_surface_shape(&geometry, &mut tris, &constrained), 0);
        // Corner 1 moved in (u, v) so that the pair is not convex there: the
        // triangle (0, 1, 2) of the flip would be clockwise.
        let uv = vec![uv[0], Vec2::new(0.3, 0.35), uv[2], uv[3]];
        let geometry = FlipGeometry { uv: &uv, position: &position, normal_at: &up };
        let mut tris = vec![[0, 1, 3], [1, 2, 3]];
        assert_eq!(flip_toward_surface_shape(&geometry, &mut tris, &|_, _| false), 0);
    }
}
