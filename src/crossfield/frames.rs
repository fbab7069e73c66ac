//! Edge frames, triangle frames and the rotations between them (thesis ch. 3
//! §5, the matrix `R^{ijk}`), plus the per-triangle CR stiffness.
//!
//! Conventions.
//! - Edge `p = [a, b]` (`a < b`, as in [`Topology::edges`]) has the frame
//!   `(ê^p, t̂^p = n̂^p × ê^p)` with `ê^p = (x_b − x_a)/|x_b − x_a|` and `n̂^p`
//!   the normalized mean of the unit normals of its triangles. The unknown
//!   `f_p = exp(i N θ_p)` stores the cross angle `θ_p` measured from `ê^p`
//!   towards `t̂^p`; `f_p = 1` is a cross aligned with the edge.
//! - Triangle `T = [v₀, v₁, v₂]` has the frame `(r̂_T, n̂_T × r̂_T)` with
//!   `r̂_T` along `x_{v₁} − x_{v₀}` and `n̂_T` its unit normal.
//! - Edge `p` lies in the plane of each of its triangles, so unfolding the
//!   edge frame into triangle `T` (rotation about `ê^p` by the half dihedral
//!   angle, the discrete Levi-Civita connection) keeps the angle to the edge.
//!   If `α_{T,p}` is the angle of `ê^p` in the frame of `T`, the cross angle in
//!   `T`'s frame is `Θ = θ_p + α_{T,p}`, i.e. `F = r_{T,p} f_p` with
//!   `r_{T,p} = exp(i N α_{T,p})`. This is the thesis' `R^{ijk}` written as a
//!   complex factor (its sign convention for `α` is the opposite one; the
//!   thesis takes the first edge as the reference, we take the first corner
//!   edge, which is the same choice).
//! - `exp(i N α)` is computed as `(cos α + i sin α)^N` from dot products:
//!   no trigonometric call. For a degenerate (collinear) triangle every edge
//!   direction is `±r̂_T`, so `r = (±1)^N = 1` (N even): consistent angles.
//! - Interior edges must be traversed in opposite directions by their two
//!   triangles (consistent orientation); otherwise the transport would be a
//!   reflection and the complex representation breaks.

use super::CrossfieldError;
use crate::fem::crouzeix_raviart::cr_stiffness;
use crate::geom::Vec3;
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh};
use nalgebra::Complex;
use rayon::prelude::*;

/// Complex `f64`.
pub type C64 = Complex<f64>;

/// Per-triangle data of the discretization: area, CR stiffness and the three
/// edge → triangle frame factors `r_{T,k}` (local edge `k`).
#[derive(Debug, Clone)]
pub struct FaceData {
    /// Triangle area (0 for a degenerate triangle, which is then left out of the energy).
    pub area: f64,
    /// CR stiffness `Sⱼₖ` (see [`cr_stiffness`]).
    pub stiffness: [[f64; 3]; 3],
    /// `r_{T,k} = exp(i N α_{T,k})`: edge frame of local edge `k` → triangle frame.
    pub rot: [C64; 3],
}

/// The geometric part of the discretization, independent of ε and of the field.
#[derive(Debug, Clone)]
pub struct Discretization {
    /// Symmetry order `N`.
    pub symmetry: u32,
    /// Per triangle.
    pub faces: Vec<FaceData>,
    /// CR mass per edge: `Σ_T |T|/3` over its (non-degenerate) triangles.
    pub mass_per_edge: Vec<f64>,
    /// Length of each edge.
    pub length_per_edge: Vec<f64>,
    /// Total area.
    pub area: f64,
    /// Number of degenerate triangles (zero area), left out of the energy.
    pub n_degenerate_faces: usize,
}

/// Unit-modulus `z^N` for a unit complex `z` (repeated squaring).
#[inline]
pub fn complex_pow(z: C64, n: u32) -> C64 {
    let (mut acc, mut base, mut k) = (C64::new(1.0, 0.0), z, n);
    while k > 0 {
        if k & 1 == 1 {
            acc *= base;
        }
        base *= base;
        k >>= 1;
    }
    acc
}

/// Reference direction and unit normal of triangle `f` (zero vectors when degenerate).
pub fn face_frame(mesh: &TriMesh, f: FaceId) -> (Vec3, Vec3) {
    let [a, b, _] = mesh.corners(f);
    let d = b - a;
    let l = d.norm();
    let r = if l > 0.0 { d / l } else { Vec3::zeros() };
    (r, mesh.face_normal(f))
}

/// Unit direction `ê^p` of edge `p` (from its smaller to its larger vertex id).
pub fn edge_direction(mesh: &TriMesh, topo: &Topology, e: EdgeId) -> Vec3 {
    let [a, b] = topo.edges[e.idx()];
    let d = mesh.positions[b.idx()] - mesh.positions[a.idx()];
    let l = d.norm();
    if l > 0.0 { d / l } else { Vec3::zeros() }
}

/// Unit normal `n̂^p` of edge `p`: normalized mean of its triangles' normals.
pub fn edge_normal(mesh: &TriMesh, topo: &Topology, e: EdgeId) -> Vec3 {
    let n: Vec3 = topo.edge_faces(e).iter().map(|&f| mesh.face_normal(f)).sum();
    let l = n.norm();
    if l > 0.0 { n / l } else { n }
}

/// `r_{T,k} = exp(i N α)` for every local edge of triangle `f`.
fn face_rotations(mesh: &TriMesh, topo: &Topology, f: FaceId, n: u32) -> [C64; 3] {
    let (r, nrm) = face_frame(mesh, f);
    let t = nrm.cross(&r);
    let mut out = [C64::new(1.0, 0.0); 3];
    for (k, e) in topo.face_edges[f.idx()].iter().enumerate() {
        let d = edge_direction(mesh, topo, *e);
        let z = C64::new(d.dot(&r), d.dot(&t));
        let m = z.norm();
        out[k] = if m > 0.0 { complex_pow(z / m, n) } else { C64::new(1.0, 0.0) };
    }
    out
}

/// Check that every interior edge is traversed in opposite directions by its
/// two triangles.
///
/// # Errors
/// [`CrossfieldError::InconsistentOrientation`] naming the first bad edge.
pub fn check_orientation(mesh: &TriMesh, topo: &Topology) -> Result<(), CrossfieldError> {
    for e in 0..topo.n_edges() {
        let e = EdgeId::new(e);
        if let [f, g] = topo.edge_faces(e) {
            let forward = |f: FaceId| {
                let i = topo.local_edge(f, e).unwrap_or(0);
                let t = mesh.triangles[f.idx()];
                t[i] < t[(i + 1) % 3]
            };
            if forward(*f) == forward(*g) {
                let [a, b] = topo.edges[e.idx()];
                return Err(CrossfieldError::InconsistentOrientation { a: a.0, b: b.0 });
            }
        }
    }
    Ok(())
}

impl Discretization {
    /// Frames, rotations, stiffness and masses of `mesh` for symmetry `n`.
    pub fn new(mesh: &TriMesh, topo: &Topology, n: u32) -> Self {
        let faces: Vec<FaceData> = (0..mesh.n_faces())
            .into_par_iter()
            .map(|f| {
                let f = FaceId::new(f);
                let p = mesh.corners(f);
                let area = mesh.face_area(f);
                let ok = area.is_finite() && area > 0.0;
                FaceData {
                    area: if ok { area } else { 0.0 },
                    stiffness: if ok { cr_stiffness(&p) } else { [[0.0; 3]; 3] },
                    rot: face_rotations(mesh, topo, f, n),
                }
            })
            .collect();
        let mut mass_per_edge = vec![0.0; topo.n_edges()];
        for (fd, fe) in faces.iter().zip(&topo.face_edges) {
            for e in fe {
                mass_per_edge[e.idx()] += fd.area / 3.0;
            }
        }
        let length_per_edge =
            topo.edges.iter().map(|[a, b]| (mesh.positions[b.idx()] - mesh.positions[a.idx()]).norm()).collect();
        let n_degenerate_faces = faces.iter().filter(|f| f.area == 0.0).count();
        let area = faces.iter().map(|f| f.area).sum();
        Self { symmetry: n, faces, mass_per_edge, length_per_edge, area, n_degenerate_faces }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn planar_constant_field_is_constant_in_every_triangle_frame() {
        // A cross at angle φ in the global frame: in edge frame θ_p = φ − angle(ê^p),
        // in triangle frame Θ = φ − angle(r̂_T); check r_{T,k} f_p = exp(iNΘ).
        let mesh = fixtures::disk(3);
        let topo = Topology::new(&mesh);
        let n = 4;
        let disc = Discretization::new(&mesh, &topo, n);
        let phi: f64 = 0.3;
        let angle = |v: Vec3| v.y.atan2(v.x);
        for (f, fd) in disc.faces.iter().enumerate() {
            let (r, _) = face_frame(&mesh, FaceId::new(f));
            let want = C64::from_polar(1.0, n as f64 * (phi - angle(r)));
            for (k, e) in topo.face_edges[f].iter().enumerate() {
                let d = edge_direction(&mesh, &topo, *e);
                let fp = C64::from_polar(1.0, n as f64 * (phi - angle(d)));
                assert!((fd.rot[k] * fp - want).norm() < 1e-12);
            }
        }
        let total: f64 = disc.mass_per_edge.iter().sum();
        assert!((total - disc.area).abs() < 1e-12);
        assert_eq!(complex_pow(C64::new(0.0, 1.0), 6), C64::new(-1.0, 0.0));
    }

    #[test]
    fn inconsistent_orientation_is_reported() {
        let mut mesh = fixtures::square(2);
        let topo = Topology::new(&mesh);
        assert!(check_orientation(&mesh, &topo).is_ok());
        mesh.flip_face(FaceId(3));
        let topo = Topology::new(&mesh);
        assert!(matches!(check_orientation(&mesh, &topo), Err(CrossfieldError::InconsistentOrientation { .. })));
    }
}
