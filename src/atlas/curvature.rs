//! Principal curvatures and directions per vertex (Rusinkiewicz 2004,
//! "Estimating curvatures and their derivatives on triangle meshes"; thesis
//! ch. 2 §4.1).
//!
//! Per triangle, the second fundamental form `II` (2×2, symmetric) is the
//! least-squares fit of `II · (e·t, e·b) = (Δn·t, Δn·b)` over its three edges
//! `e`, with `Δn` the difference of vertex normals along the edge and `(t, b)`
//! an orthonormal frame of the triangle plane. Each vertex averages the forms
//! of its triangles, re-expressed in its own tangent frame (the frames are
//! rotated onto each other about the common tangent), weighted by the
//! Voronoi (mixed) area of its corner; the eigen-decomposition of the average
//! gives the principal curvatures and directions. Vertex normals use Max's
//! weights `Σ (a × b) / (|a|² |b|²)`.
//!
//! Conventions: with outward normals a sphere of radius `R` has curvature
//! `+1/R`; `curvature_max ≥ curvature_min` (signed), `direction_max` and
//! `direction_min` are unit tangents, `direction_min = n × direction_max`.

use crate::geom::Vec3;
use crate::mesh::{FaceId, Topology, TriMesh, VertexId};
use rayon::prelude::*;

/// Principal curvatures and directions at every vertex.
#[derive(Debug, Clone, Default)]
pub struct Curvature {
    /// Unit vertex normals.
    pub normal_per_vertex: Vec<Vec3>,
    /// Larger principal curvature (signed, 1/length).
    pub curvature_max: Vec<f64>,
    /// Smaller principal curvature (signed, 1/length).
    pub curvature_min: Vec<f64>,
    /// Unit direction of `curvature_max`.
    pub direction_max: Vec<Vec3>,
    /// Unit direction of `curvature_min`.
    pub direction_min: Vec<Vec3>,
}

/// Second fundamental form `(ku, kuv, kv)` of a triangle in its frame `(t, b)`,
/// with the Voronoi area of each corner.
struct FaceForm {
    t: Vec3,
    b: Vec3,
    form: [f64; 3],
    corner_area: [f64; 3],
}

/// Estimate curvature at every vertex of `mesh`.
pub fn principal_curvatures(mesh: &TriMesh, topo: &Topology) -> Curvature {
    let normals = vertex_normals(mesh);
    let forms: Vec<FaceForm> =
        (0..mesh.n_faces()).into_par_iter().map(|f| face_form(mesh, &normals, FaceId::new(f))).collect();
    let per_vertex: Vec<(f64, f64, Vec3, Vec3)> = (0..mesh.n_vertices())
        .into_par_iter()
        .map(|v| vertex_curvature(mesh, topo, &normals, &forms, VertexId::new(v)))
        .collect();
    let mut out = Curvature { normal_per_vertex: normals, ..Default::default() };
    for (k1, k2, d1, d2) in per_vertex {
        out.curvature_max.push(k1);
        out.curvature_min.push(k2);
        out.direction_max.push(d1);
        out.direction_min.push(d2);
    }
    out
}

/// Vertex normals with Max's weights (exact for spheres).
pub fn vertex_normals(mesh: &TriMesh) -> Vec<Vec3> {
    let mut n = vec![Vec3::zeros(); mesh.n_vertices()];
    for t in &mesh.triangles {
        let p = t.map(|v| mesh.positions[v.idx()]);
        for c in 0..3 {
            let (a, b) = (p[(c + 1) % 3] - p[c], p[(c + 2) % 3] - p[c]);
            let w = a.norm_squared() * b.norm_squared();
            if w > 0.0 {
                n[t[c].idx()] += a.cross(&b) / w;
            }
        }
    }
    for x in &mut n {
        let l = x.norm();
        if l > 0.0 {
            *x /= l;
        }
    }
    n
}

/// Least-squares second fundamental form of triangle `f` and its corner areas.
fn face_form(mesh: &TriMesh, normals: &[Vec3], f: FaceId) -> FaceForm {
    let tri = mesh.triangles[f.idx()];
    let p = tri.map(|v| mesh.positions[v.idx()]);
    // e[j] is the edge opposite corner j, from corner j+1 to corner j+2.
    let e = [p[2] - p[1], p[0] - p[2], p[1] - p[0]];
    let n = e[0].cross(&e[1]);
    let corner_area = corner_areas(&e, 0.5 * n.norm());
    let t = e[0].try_normalize(0.0).unwrap_or_else(Vec3::x);
    let nn = n.try_normalize(0.0).unwrap_or_else(Vec3::z);
    let b = nn.cross(&t);
    let (mut w, mut m) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    for j in 0..3 {
        let (u, v) = (e[j].dot(&t), e[j].dot(&b));
        w[0][0] += u * u;
        w[0][1] += u * v;
        w[2][2] += v * v;
        let dn = normals[tri[(j + 2) % 3].idx()] - normals[tri[(j + 1) % 3].idx()];
        let (dnu, dnv) = (dn.dot(&t), dn.dot(&b));
        m[0] += dnu * u;
        m[1] += dnu * v + dnv * u;
        m[2] += dnv * v;
    }
    w[1][1] = w[0][0] + w[2][2];
    w[1][2] = w[0][1];
    let a = nalgebra::Matrix3::new(w[0][0], w[0][1], 0.0, w[0][1], w[1][1], w[1][2], 0.0, w[1][2], w[2][2]);
    let form = a
        .cholesky()
        .map(|c| c.solve(&nalgebra::Vector3::new(m[0], m[1], m[2])))
        .map(|x| [x[0], x[1], x[2]])
        .unwrap_or([0.0; 3]);
    FaceForm { t, b, form, corner_area }
}

/// Voronoi (mixed) areas of the three corners (Meyer et al. 2003, as in
/// Rusinkiewicz's code): the circumcentric split for acute triangles, half /
/// quarter splits at an obtuse corner.
fn corner_areas(e: &[Vec3; 3], area: f64) -> [f64; 3] {
    let l2 = [e[0].norm_squared(), e[1].norm_squared(), e[2].norm_squared()];
    let ew = [l2[0] * (l2[1] + l2[2] - l2[0]), l2[1] * (l2[2] + l2[0] - l2[1]), l2[2] * (l2[0] + l2[1] - l2[2])];
    let mut ca = [0.0; 3];
    if area <= 0.0 {
        return ca;
    }
    if ew[0] <= 0.0 {
        ca[1] = -0.25 * l2[2] * area / e[0].dot(&e[2]);
        ca[2] = -0.25 * l2[1] * area / e[0].dot(&e[1]);
        ca[0] = area - ca[1] - ca[2];
    } else if ew[1] <= 0.0 {
        ca[2] = -0.25 * l2[0] * area / e[1].dot(&e[0]);
        ca[0] = -0.25 * l2[2] * area / e[1].dot(&e[2]);
        ca[1] = area - ca[2] - ca[0];
    } else if ew[2] <= 0.0 {
        ca[0] = -0.25 * l2[1] * area / e[2].dot(&e[1]);
        ca[1] = -0.25 * l2[0] * area / e[2].dot(&e[0]);
        ca[2] = area - ca[0] - ca[1];
    } else {
        let s = 0.5 * area / (ew[0] + ew[1] + ew[2]);
        for j in 0..3 {
            ca[j] = s * (ew[(j + 1) % 3] + ew[(j + 2) % 3]);
        }
    }
    ca.map(|a| if a.is_finite() { a.max(0.0) } else { 0.0 })
}

/// Average the forms of the triangles around `v` in its tangent frame and diagonalize.
fn vertex_curvature(
    mesh: &TriMesh,
    topo: &Topology,
    normals: &[Vec3],
    forms: &[FaceForm],
    v: VertexId,
) -> (f64, f64, Vec3, Vec3) {
    let n = normals[v.idx()];
    let faces = topo.vertex_faces(v);
    let Some(&f0) = faces.first() else {
        return (0.0, 0.0, Vec3::zeros(), Vec3::zeros());
    };
    // Vertex frame: an incident edge projected on the tangent plane.
    let t0 = mesh.triangles[f0.idx()];
    let c0 = t0.iter().position(|&x| x == v).unwrap_or(0);
    let e = mesh.positions[t0[(c0 + 1) % 3].idx()] - mesh.positions[v.idx()];
    let u = (e - n * n.dot(&e)).try_normalize(0.0).unwrap_or_else(|| any_perpendicular(&n));
    let w = n.cross(&u);
    let (mut acc, mut total) = ([0.0f64; 3], 0.0);
    for &f in faces {
        let tri = mesh.triangles[f.idx()];
        let Some(c) = tri.iter().position(|&x| x == v) else {
            continue;
        };
        let ff = &forms[f.idx()];
        let wt = ff.corner_area[c];
        let k = project_form(&ff.t, &ff.b, ff.form, &u, &w);
        for i in 0..3 {
            acc[i] += wt * k[i];
        }
        total += wt;
    }
    if total <= 0.0 {
        return (0.0, 0.0, u, w);
    }
    let k = acc.map(|x| x / total);
    diagonalize(&u, &w, k, &n)
}

/// Express the form `(ku, kuv, kv)` given in frame `(old_u, old_v)` in frame
/// `(new_u, new_v)`, after rotating the new frame into the old plane.
fn project_form(old_u: &Vec3, old_v: &Vec3, k: [f64; 3], new_u: &Vec3, new_v: &Vec3) -> [f64; 3] {
    let (ru, rv) = rotate_frame(new_u, new_v, &old_u.cross(old_v));
    let (u1, v1, u2, v2) = (ru.dot(old_u), ru.dot(old_v), rv.dot(old_u), rv.dot(old_v));
    [
        k[0] * u1 * u1 + k[1] * 2.0 * u1 * v1 + k[2] * v1 * v1,
        k[0] * u1 * u2 + k[1] * (u1 * v2 + u2 * v1) + k[2] * v1 * v2,
        k[0] * u2 * u2 + k[1] * 2.0 * u2 * v2 + k[2] * v2 * v2,
    ]
}

/// Rotate the frame `(u, v)` (normal `u × v`) so that its normal becomes `new_n`.
fn rotate_frame(u: &Vec3, v: &Vec3, new_n: &Vec3) -> (Vec3, Vec3) {
    let old_n = u.cross(v);
    let ndot = old_n.dot(new_n);
    if ndot <= -1.0 + 1e-15 {
        return (-u, -v);
    }
    let perp_old = new_n - old_n * ndot;
    let dperp = (old_n + new_n) / (1.0 + ndot);
    (u - dperp * u.dot(&perp_old), v - dperp * v.dot(&perp_old))
}

/// Principal curvatures (`k1 ≥ k2`) and directions of the form `k` in frame `(u, v)`.
fn diagonalize(u: &Vec3, v: &Vec3, k: [f64; 3], n: &Vec3) -> (f64, f64, Vec3, Vec3) {
    let (ku, kuv, kv) = (k[0], k[1], k[2]);
    let (mut c, mut s, mut tt) = (1.0, 0.0, 0.0);
    if kuv != 0.0 {
        let h = 0.5 * (kv - ku) / kuv;
        tt = if h < 0.0 { 1.0 / (h - (1.0 + h * h).sqrt()) } else { 1.0 / (h + (1.0 + h * h).sqrt()) };
        c = 1.0 / (1.0 + tt * tt).sqrt();
        s = tt * c;
    }
    let (k1, k2) = (ku - tt * kuv, kv + tt * kuv);
    let d1 = u * c - v * s;
    let d2 = u * s + v * c;
    if k1 >= k2 { (k1, k2, d1, n.cross(&d1)) } else { (k2, k1, d2, n.cross(&d2)) }
}

/// Some unit vector perpendicular to `n`.
fn any_perpendicular(n: &Vec3) -> Vec3 {
    let a = if n.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
    n.cross(&a).try_normalize(0.0).unwrap_or_else(Vec3::x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn sphere_has_unit_curvature() {
        let m = fixtures::icosphere(4);
        let c = principal_curvatures(&m, &Topology::new(&m));
        for v in 0..m.n_vertices() {
            assert!((c.curvature_max[v] - 1.0).abs() < 0.02, "k1 {}", c.curvature_max[v]);
            assert!((c.curvature_min[v] - 1.0).abs() < 0.02, "k2 {}", c.curvature_min[v]);
            assert!((c.normal_per_vertex[v] - m.positions[v]).norm() < 1e-3);
        }
    }

    #[test]
    fn cylinder_curves_around_not_along() {
        let r = 2.0;
        let m = fixtures::cylinder(r, 4.0, 64, 16);
        let c = principal_curvatures(&m, &Topology::new(&m));
        // Interior rings only (the open ends have one-sided stencils).
        for v in 64 * 4..64 * 12 {
            assert!((c.curvature_max[v] - 1.0 / r).abs() < 0.01, "k1 {}", c.curvature_max[v]);
            assert!(c.curvature_min[v].abs() < 0.01, "k2 {}", c.curvature_min[v]);
            assert!(c.direction_min[v].z.abs() > 0.99, "axis direction {:?}", c.direction_min[v]);
            assert!(c.direction_max[v].z.abs() < 0.05);
        }
    }

    #[test]
    fn plane_is_flat() {
        let m = fixtures::square(6);
        let c = principal_curvatures(&m, &Topology::new(&m));
        assert!(c.curvature_max.iter().chain(&c.curvature_min).all(|k| k.abs() < 1e-12));
    }
}
