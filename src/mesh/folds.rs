//! Caps folded back over the surface, unfolded by flipping their long edge.
//!
//! A **folded cap** is a thin triangle (one corner `m` close to the
//! opposite, long edge `ab`) whose normal points against the normals of
//! all three of its neighbours: `m` sits a little on the wrong side of
//! `ab`, so the triangle lies folded flat over the surface around it. A
//! consistently oriented scan can carry one (`cow.obj`, triangle 5465: height
//! 0.028 of its long edge, normal at −0.99, −0.77 and −0.99 to its three
//! neighbours'). It is not a
//! feature: every atlas chart puts the fold's hole or triangle upside down,
//! and a quad mesh across it would run its boundary the wrong way round.
//!
//! With the neighbour `u = (b, a, d)` across `ab`, flipping `ab` replaces the
//! pair by `{m, a, d}` and `{m, d, b}` (the flip of [`super::degenerate`]):
//! the same four outer edges, each triangle keeping its orientation, the
//! surface closed and χ unchanged. It is done only when both new triangles
//! face the side `u` faces (`m` lies over `u`), so the result has no fold.
//!
//! Requiring the fold against *all three* neighbours keeps real sharp
//! edges: a thin triangle along the trailing edge of a thin blade is folded
//! against the triangle across the edge, but not against its neighbours on
//! its own side of the blade. Caps with another folded cap within two
//! triangles are left as they are (a crumpled patch, not one fold).

use rayon::prelude::*;

use super::{FaceId, Topology, TriMesh, VertexId};
use crate::geom::Vec3;

/// Height of a folded cap's far corner over its long edge, relative to that
/// edge's length, at or below which it is unfolded (a corner angle of at
/// least about 157°). Thicker triangles folded against every neighbour are
/// a different defect (a vertex pushed through the surface) that one flip
/// does not mend.
pub const FOLDED_CAP_MAX_RELATIVE_HEIGHT: f64 = 0.1;

/// Flips the long edge of every folded cap of `mesh` (module doc) with no
/// other folded cap within two triangles of it, in triangle order,
/// skipping a cap whose neighbour an earlier flip changed;
/// returns how many were flipped. `topo` is `mesh`'s topology before the
/// flips (stale afterwards when the count is positive).
pub fn unfold_caps(mesh: &mut TriMesh, topo: &Topology) -> usize {
    let caps: Vec<usize> = (0..mesh.n_faces()).into_par_iter().filter(|&f| is_folded_cap(mesh, topo, f)).collect();
    let mut changed = vec![false; if caps.is_empty() { 0 } else { mesh.n_faces() }];
    let mut n = 0;
    for &f in &caps {
        if has_a_folded_cap_near(topo, f, &caps) {
            continue;
        }
        let Some((g, flipped)) = unfolded(mesh, topo, f) else { continue };
        if changed[f] || changed[g.idx()] {
            continue;
        }
        [mesh.triangles[f], mesh.triangles[g.idx()]] = flipped;
        changed[f] = true;
        changed[g.idx()] = true;
        n += 1;
    }
    n
}

/// Whether another of the sorted `caps` is within two triangles of `f`
/// (across edges). Such caps are a crumpled patch, not one fold: each
/// flip there changes what the next one sees, and on `camelhead.obj` (three
/// caps sharing neighbours beside its sliver faces) every subset of their
/// flips gave a different surface that the quads stage then failed on
/// (`docs/decisions.md`, session 33). Only isolated folds are unfolded.
fn has_a_folded_cap_near(topo: &Topology, f: usize, caps: &[usize]) -> bool {
    let f = FaceId::new(f);
    let across = |g: FaceId| (0..3).filter_map(move |i| topo.face_across(g, i));
    across(f).flat_map(|g| std::iter::once(g).chain(across(g))).any(|h| h != f && caps.binary_search(&h.idx()).is_ok())
}

/// Unit normal of triangle `f` (zero when degenerate).
fn unit_normal(mesh: &TriMesh, f: usize) -> Vec3 {
    mesh.face_area_vector(FaceId::new(f)).try_normalize(0.0).unwrap_or_else(Vec3::zeros)
}

/// The corner of `f` opposite its longest edge, as the index in the triangle.
fn far_corner(mesh: &TriMesh, f: usize) -> usize {
    let p = mesh.triangles[f].map(|v| mesh.positions[v.idx()]);
    let opposite = |k: usize| (p[(k + 2) % 3] - p[(k + 1) % 3]).norm_squared();
    (0..3).max_by(|&i, &j| opposite(i).total_cmp(&opposite(j))).unwrap_or(0)
}

/// True when `f` is a folded cap: thin over its long edge and facing
/// against each of its three neighbours (module doc).
fn is_folded_cap(mesh: &TriMesh, topo: &Topology, f: usize) -> bool {
    let p = mesh.triangles[f].map(|v| mesh.positions[v.idx()]);
    let k = far_corner(mesh, f);
    let long = (p[(k + 2) % 3] - p[(k + 1) % 3]).norm();
    let twice_area = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
    if !(long > 0.0 && twice_area > 0.0 && twice_area <= FOLDED_CAP_MAX_RELATIVE_HEIGHT * long * long) {
        return false;
    }
    let n = unit_normal(mesh, f);
    (0..3).all(|i| topo.face_across(FaceId::new(f), i).is_some_and(|g| unit_normal(mesh, g.idx()).dot(&n) < 0.0))
}

/// The neighbour `u` of cap `f` across its long edge and the two triangles
/// that replace `(f, u)` when the flip is valid: `u` is `f`'s only
/// neighbour there, the new edge does not exist yet, and both new
/// triangles face the side `u` faces.
fn unfolded(mesh: &TriMesh, topo: &Topology, f: usize) -> Option<(FaceId, [[VertexId; 3]; 2])> {
    let t = mesh.triangles[f];
    let k = far_corner(mesh, f);
    let (m, a, b) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
    let edge = topo.edge_between(a, b)?;
    let [x, y] = topo.edge_faces(edge) else { return None };
    let g = if x.idx() == f { *y } else { *x };
    let u = mesh.triangles[g.idx()];
    let d = *u.iter().find(|&&v| v != a && v != b)?;
    if d == m || topo.edge_between(m, d).is_some() {
        return None;
    }
    // Cap: b → d; neighbour: a → m (each keeps its orientation).
    let flipped = [t.map(|v| if v == b { d } else { v }), u.map(|v| if v == a { m } else { v })];
    let facing = unit_normal(mesh, g.idx());
    let faces_u = |tri: &[VertexId; 3]| {
        let q = tri.map(|v| mesh.positions[v.idx()]);
        (q[1] - q[0]).cross(&(q[2] - q[0])).dot(&facing) > 0.0
    };
    flipped.iter().all(faces_u).then_some((g, flipped))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cap `(a, b, m)` with `m` just below the long edge `ab`, over its
    /// neighbour `(a, d, b)` below, and two triangles above `m`: every
    /// triangle but the cap faces +z.
    fn folded(m_height: f64) -> TriMesh {
        let p = [
            Vec3::new(0.0, 1.0, 0.0),      // a
            Vec3::new(2.0, 1.0, 0.0),      // b
            Vec3::new(1.0, m_height, 0.0), // m
            Vec3::new(1.0, 0.0, 0.0),      // d
            Vec3::new(1.0, 2.0, 0.0),      // x
        ];
        TriMesh::from_raw(p.to_vec(), &[[0, 1, 2], [0, 3, 1], [2, 1, 4], [2, 4, 0]])
    }

    fn normals_z(mesh: &TriMesh) -> Vec<f64> {
        (0..mesh.n_faces()).map(|f| unit_normal(mesh, f).z).collect()
    }

    #[test]
    fn a_cap_folded_over_its_neighbours_is_flipped_flat() {
        let mut mesh = folded(0.95);
        assert_eq!(normals_z(&mesh), [-1.0, 1.0, 1.0, 1.0]);
        let topo = Topology::new(&mesh);
        assert_eq!(unfold_caps(&mut mesh, &topo), 1);
        assert!(normals_z(&mesh).iter().all(|&z| z == 1.0), "{:?}", normals_z(&mesh));
        assert_eq!(mesh.n_faces(), 4);
        // The same outer boundary: every edge of the old pair's outline remains.
        let topo = Topology::new(&mesh);
        for (a, b) in [(0, 3), (3, 1), (1, 4), (4, 0)] {
            assert!(topo.edge_between(VertexId::new(a), VertexId::new(b)).is_some());
        }
        assert!(topo.edge_between(VertexId::new(2), VertexId::new(3)).is_some(), "the new edge m–d");
        assert!(topo.edge_between(VertexId::new(0), VertexId::new(1)).is_none(), "the long edge is gone");
    }

    #[test]
    fn an_unfolded_or_thick_triangle_is_left_alone() {
        // m above ab: the cap faces +z like its neighbours.
        let mut mesh = folded(1.05);
        let topo = Topology::new(&mesh);
        assert_eq!(unfold_caps(&mut mesh, &topo), 0);
        // m far below ab (height 0.3 of the long edge 2): folded, but no cap.
        let mut mesh = folded(0.4);
        let topo = Topology::new(&mesh);
        assert_eq!(unfold_caps(&mut mesh, &topo), 0);
    }

    #[test]
    fn a_thin_triangle_along_a_sharp_edge_is_kept() {
        // A blade: the cap and its own side face +z, the neighbour across
        // ab is folded under them (facing −z). The cap is folded against
        // that one neighbour only.
        let mut mesh = folded(1.05);
        mesh.positions[3] = Vec3::new(1.0, 2.0, -0.05);
        assert_eq!(normals_z(&mesh).iter().map(|z| z.signum()).collect::<Vec<_>>(), [1.0, -1.0, 1.0, 1.0]);
        let topo = Topology::new(&mesh);
        assert_eq!(unfold_caps(&mut mesh, &topo), 0);
    }

    #[test]
    fn two_caps_folded_over_one_neighbour_are_left_alone() {
        // A second cap (b, d, m2) folded over the first cap's neighbour
        // (a, d, b) across its edge db, with two triangles beyond db.
        let mut mesh = folded(0.95);
        mesh.positions.extend([Vec3::new(1.47, 0.53, 0.0), Vec3::new(2.0, 0.0, 0.0)]); // m2 = 5, y = 6
        let t = |a: usize, b: usize, c: usize| [a, b, c].map(VertexId::new);
        mesh.triangles.extend([t(1, 3, 5), t(5, 3, 6), t(1, 5, 6)]);
        assert_eq!(
            normals_z(&mesh).iter().map(|z| z.signum()).collect::<Vec<_>>(),
            [-1.0, 1.0, 1.0, 1.0, -1.0, 1.0, 1.0]
        );
        let topo = Topology::new(&mesh);
        assert!(is_folded_cap(&mesh, &topo, 0) && is_folded_cap(&mesh, &topo, 4));
        assert_eq!(unfold_caps(&mut mesh, &topo), 0);
    }
}
