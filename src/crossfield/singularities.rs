//! Indices of the field at vertices (thesis (3.11)–(3.13)): the turning of
//! `f` around each vertex relative to parallel transport.
//!
//! Around vertex `v`, consecutive edges `e_i, e_{i+1}` of its star share a
//! triangle `T`; in `T`'s frame their values are `F = r_{T,·} f` (the
//! discrete Levi-Civita connection between the two edge frames is the
//! rotation `r_{T,e_{i+1}} / r_{T,e_i}`). The turning across `T` is the
//! principal angle `Δ_T = arg(F_{e_{i+1}} / F_{e_i}) ∈ (−π, π]` (shortest
//! rotation, thesis Fig. 3.3). The sum of the turnings is `2π k − N K_v`
//! with `K_v` the angle defect (for a boundary vertex the geodesic
//! curvature `π − Σθ`), so
//!
//! ```text
//! k_v = (N (2π − Σ_T θ_T − π b_v / 2) + Σ_T Δ_T) / (2π)     (b_v: boundary edges at v)
//! ```
//!
//! is an integer, the index of `f` at `v`; the cross index is `k_v / N`
//! of a turn. For strong boundary conditions the boundary term gives the
//! corner contributions (`+1/4` at a convex right angle, `−1/4` at a
//! reentrant one). A CR field can also wind inside a triangle (a zero in
//! the medial triangle, enclosed by no vertex loop): the three turnings of
//! `T` then sum to `∓2π`, giving a triangle index `t_T = −Σ Δ / 2π`. It is
//! attributed to the corner nearest the zero, so that, by discrete
//! Gauss–Bonnet, `Σ_v k_v + Σ_T t_T = N χ` exactly on a manifold mesh
//! (Poincaré–Hopf (3.13)); the test suite asserts it.

use super::Singularity;
use super::energy::to_face_frame;
use super::frames::{C64, Discretization};
use crate::geom::{Vec3, corner_angles};
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh, VertexId};
use std::f64::consts::{PI, TAU};

/// Per-vertex indices and the list of singular vertices.
#[derive(Debug, Clone)]
pub struct IndexField {
    /// Index of each vertex in units of `1/N`.
    pub index_per_vertex: Vec<i32>,
    /// Vertices with a non-zero index.
    pub singularities: Vec<Singularity>,
    /// Sum of the indices, fraction of a turn.
    pub index_sum: f64,
    /// Triangle windings attributed to a corner.
    pub n_face_windings: usize,
}

/// Corner values `Gᵢ = Fᵢ + F_{i+2} − F_{i+1}` of a CR field.
fn corner_values(big_f: &[C64; 3]) -> [C64; 3] {
    std::array::from_fn(|i| big_f[i] + big_f[(i + 2) % 3] - big_f[(i + 1) % 3])
}

/// Barycentric coordinates of the zero of the linear field with corner
/// values `g`, or `None` when the field is degenerate (constant direction).
pub fn linear_zero(g: &[C64; 3]) -> Option<[f64; 3]> {
    let (a, b) = (g[0] - g[2], g[1] - g[2]);
    let det = a.re * b.im - a.im * b.re;
    if det.abs() <= 1e-300 {
        return None;
    }
    let (rx, ry) = (-g[2].re, -g[2].im);
    let l0 = (rx * b.im - ry * b.re) / det;
    let l1 = (a.re * ry - a.im * rx) / det;
    Some([l0, l1, 1.0 - l0 - l1])
}

/// Indices of the field `f` (edge frames) at every vertex.
pub fn vertex_indices(mesh: &TriMesh, topo: &Topology, disc: &Discretization, f: &[C64]) -> IndexField {
    let n = disc.symmetry as f64;
    let nv = mesh.n_vertices();
    let mut turning = vec![0.0; nv];
    let mut angle = vec![0.0; nv];
    let mut n_faces = vec![0u32; nv];
    let mut border = vec![0u32; nv];
    for e in 0..topo.n_edges() {
        if topo.edge_valence(EdgeId::new(e)) == 1 {
            for v in topo.edges[e] {
                border[v.idx()] += 1;
            }
        }
    }
    let mut face_index: Vec<(usize, i32)> = Vec::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let fe = &topo.face_edges[t];
        let big_f = to_face_frame(&disc.faces[t], [f[fe[0].idx()], f[fe[1].idx()], f[fe[2].idx()]]);
        let th =
            corner_angles(&mesh.positions[tri[0].idx()], &mesh.positions[tri[1].idx()], &mesh.positions[tri[2].idx()]);
        let mut sum = 0.0;
        for i in 0..3 {
            let d = (big_f[(i + 2) % 3] * big_f[i].conj()).arg();
            sum += d;
            let v = tri[i].idx();
            turning[v] += d;
            angle[v] += th[i];
            n_faces[v] += 1;
        }
        let w = -(sum / TAU).round() as i32;
        if w != 0 {
            face_index.push((t, w));
        }
    }
    let mut index_per_vertex = vec![0i32; nv];
    for v in 0..nv {
        if n_faces[v] == 0 {
            continue;
        }
        let k = (n * (TAU - angle[v] - PI * border[v] as f64 / 2.0) + turning[v]) / TAU;
        index_per_vertex[v] = k.round() as i32;
    }
    let n_face_windings = face_index.len();
    for &(t, w) in &face_index {
        let fe = &topo.face_edges[t];
        let big_f = to_face_frame(&disc.faces[t], [f[fe[0].idx()], f[fe[1].idx()], f[fe[2].idx()]]);
        let corner = linear_zero(&corner_values(&big_f))
            .map(|l| (0..3).max_by(|&a, &b| l[a].total_cmp(&l[b])).unwrap_or(0))
            .unwrap_or(0);
        index_per_vertex[mesh.triangles[t][corner].idx()] += w;
    }
    let singularities = index_per_vertex
        .iter()
        .enumerate()
        .filter(|&(_, &k)| k != 0)
        .map(|(v, &k)| {
            let v = VertexId::new(v);
            Singularity { position: singularity_position(mesh, topo, disc, f, v), index: k as f64 / n, vertex: v }
        })
        .collect();
    let index_sum = index_per_vertex.iter().map(|&k| k as i64).sum::<i64>() as f64 / n;
    IndexField { index_per_vertex, singularities, index_sum, n_face_windings }
}

/// The zero of the field nearest to `v` among the triangles of its star
/// (inside a triangle, up to round-off); `v`'s position when there is none.
fn singularity_position(mesh: &TriMesh, topo: &Topology, disc: &Discretization, f: &[C64], v: VertexId) -> Vec3 {
    let pv = mesh.positions[v.idx()];
    let mut best: Option<(f64, Vec3)> = None;
    for &t in topo.vertex_faces(v) {
        let FaceId(ti) = t;
        let ti = ti as usize;
        let fe = &topo.face_edges[ti];
        let big_f = to_face_frame(&disc.faces[ti], [f[fe[0].idx()], f[fe[1].idx()], f[fe[2].idx()]]);
        if let Some(l) = linear_zero(&corner_values(&big_f))
            && l.iter().all(|&x| x >= -1e-9)
        {
            let p: Vec3 = mesh.triangles[ti].iter().zip(l).map(|(c, w)| mesh.positions[c.idx()] * w).sum();
            let d = (p - pv).norm();
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, p));
            }
        }
    }
    best.map_or(pv, |(_, p)| p)
}
