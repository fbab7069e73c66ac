//! Singular edges of a frame field on a tetrahedral mesh: edges around
//! which the frame, transported tet to tet, does not come back to itself.
//!
//! **Frames per tet.** The per-vertex field is P1 in the 9-vector
//! representation; the frame of a tet is the projection onto the octahedral
//! variety of the mean of its 4 vertex 9-vectors (its value at the
//! barycentre). Singularities of a per-vertex field run through tets and
//! faces, not along edges; with one frame per tet they lie on primal edges
//! and the holonomy is well defined (Nieser et al. 2011, Ray et al. 2016,
//! Liu et al. 2018). A per-vertex "link-cycle" test would flag the edges of
//! the tets a singular curve crosses, which do not form curves.
//!
//! **Matching and holonomy.** Across the face between tets `s` and `t` with
//! frame quaternions `q_s`, `q_t`, the matching is the element `o ∈ O`
//! closest to `q_t* q_s` (the cube rotation closest to `R_tᵀ R_s`), found in
//! O(1) as the largest of `|q_k|`, `(|q_a| + |q_b|)/√2` and `Σ|q_k|/2`.
//! Around an interior edge `ab` the tets form a ring `T_0, …, T_{k−1}`; the
//! holonomy `H = o_{k−1} ⋯ o_1 o_0` (in the frame of `T_0`) is exactly an
//! element of `O`. `H = ±1`: regular. Otherwise `R_0 H R_0ᵀ` is a world
//! rotation by `θ ∈ {90°, 120°, 180°}` about an axis `a` (the tangent of the
//! singular curve threading the ring). With `ê` the edge direction oriented
//! so that the ring turns positively about it, a quarter turn with
//! `a · ê > 0` is the centre of a 2D cross-section singularity of index
//! `+1/4`, i.e. **valence 3** (three hexahedra around the edge), and
//! `a · ê < 0` index `−1/4`, **valence 5**: only the sign matters, because a
//! curve crossing the mesh obliquely is carried by edges up to ~55° off its
//! tangent; the valence is given when `|a · ê|` exceeds the cosine of the
//! axis tolerance. Other holonomies (half turns, third turns, or quarter
//! turns about an axis nearly perpendicular to the edge) are *complex*.
//!
//! **Curves.** Around an interior vertex the holonomies of its edges
//! multiply to the identity (the link is a sphere), so a singular edge never
//! ends alone inside the volume; the report counts the interior vertices
//! with exactly one singular edge (dangling ends) and isolated singular
//! edges anyway, as a consistency check.

use super::groups::binary_octahedral_group;
use super::quaternion::{Mat3, Quat};
use super::sh4::{dot9, nearest_frame_to_tolerance};
use crate::mesh::TetMesh;
use crate::progress::{Cancelled, Progress};
use rayon::prelude::*;
use serde::Serialize;

/// Type of a singular edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SingularKind {
    /// Quarter turn `+π/2` about the edge: index `+1/4`, three hexahedra.
    Valence3,
    /// Quarter turn `−π/2` about the edge: index `−1/4`, five hexahedra.
    Valence5,
    /// Any other non-identity holonomy.
    Complex,
}

impl SingularKind {
    /// The valence code written to `frames_singular.vtu`: 3, 5, or 0 (complex).
    pub fn valence_code(&self) -> i32 {
        match self {
            SingularKind::Valence3 => 3,
            SingularKind::Valence5 => 5,
            SingularKind::Complex => 0,
        }
    }
}

/// A singular edge of the field.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SingularEdge {
    /// Its vertices (`a < b`).
    pub vertices: [u32; 2],
    /// Its type.
    pub kind: SingularKind,
    /// Rotation angle of the holonomy, degrees (90, 120 or 180).
    pub holonomy_angle_deg: f64,
    /// `|cos|` of the angle between the holonomy axis and the edge.
    pub axis_alignment: f64,
}

/// Counts and curve structure of the singular edges.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SingularReport {
    /// Interior edges examined.
    pub n_interior_edges: usize,
    /// Singular edges of valence 3.
    pub n_valence3: usize,
    /// Singular edges of valence 5.
    pub n_valence5: usize,
    /// Other singular edges.
    pub n_complex: usize,
    /// Connected singular curves (components of the singular-edge graph).
    pub n_curves: usize,
    /// Vertices where three or more singular edges meet.
    pub n_branch_vertices: usize,
    /// Interior vertices with exactly one singular edge (should be 0).
    pub n_dangling_interior_ends: usize,
    /// Singular edges whose two ends are both dangling (isolated, should be 0).
    pub n_isolated_edges: usize,
    /// Edges whose tet ring could not be ordered (non-manifold input).
    pub n_unordered_rings: usize,
}

/// Frame per tet: the projection of the mean 9-vector of its vertices,
/// warm-started at the vertex frame that aligns best with it. `progress` is
/// checked per tet (a cancelled pass skips the remaining projections).
///
/// # Errors
/// [`Cancelled`] when `progress` is cancelled.
pub fn tet_frames(
    mesh: &TetMesh,
    sh9_per_vertex: &[[f64; 9]],
    rotation_per_vertex: &[Mat3],
    progress: &Progress,
) -> Result<Vec<Mat3>, Cancelled> {
    let frames = mesh
        .tets
        .par_iter()
        .map(|t| {
            if progress.is_cancelled() {
                return Mat3::identity();
            }
            let mut s = [0.0; 9];
            for v in t {
                for c in 0..9 {
                    s[c] += 0.25 * sh9_per_vertex[v.idx()][c];
                }
            }
            let best = t
                .iter()
                .max_by(|a, b| dot9(&s, &sh9_per_vertex[a.idx()]).total_cmp(&dot9(&s, &sh9_per_vertex[b.idx()])));
            let hint = best.map(|v| rotation_per_vertex[v.idx()]);
            nearest_frame_to_tolerance(&s, hint.as_ref(), 0.3, 1e-9).rotation
        })
        .collect();
    progress.check()?;
    Ok(frames)
}

/// The element of the binary octahedral group closest to the unit
/// quaternion `q` (up to sign), in O(1).
pub fn nearest_octahedral_element(q: &Quat) -> Quat {
    octa_group().elements[nearest_octahedral_index(q) as usize]
}

/// Index in [`binary_octahedral_group`] of the element closest to `q`
/// (with the sign of `q`): the largest of `|q_k|` (elements `±1, ±i, ±j,
/// ±k`), `(|q_a| + |q_b|)/√2` (the 24 `(±e_a ± e_b)/√2`) and `Σ|q_k|/2`
/// (the 16 `(±1 ± i ± j ± k)/2`). The arithmetic follows the order in
/// which the group is listed.
pub fn nearest_octahedral_index(q: &Quat) -> u8 {
    let a = q.0.map(f64::abs);
    let neg = |x: f64| x < 0.0;
    let mut idx = [0usize, 1, 2, 3];
    idx.sort_by(|&i, &j| a[j].total_cmp(&a[i]));
    let one = a[idx[0]];
    let two = (a[idx[0]] + a[idx[1]]) * std::f64::consts::FRAC_1_SQRT_2;
    let four = 0.5 * (a[0] + a[1] + a[2] + a[3]);
    if one >= two && one >= four {
        (2 * idx[0] + neg(q.0[idx[0]]) as usize) as u8
    } else if two >= four {
        let (p0, p1) = (idx[0].min(idx[1]), idx[0].max(idx[1]));
        const PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
        let pair = PAIRS.iter().position(|&p| p == (p0, p1)).unwrap_or(0);
        let signs = 2 * neg(q.0[p0]) as usize + neg(q.0[p1]) as usize;
        (24 + 4 * pair + signs) as u8
    } else {
        let bits = (0..4).map(|k| (neg(q.0[k]) as usize) << k).sum::<usize>();
        (8 + bits) as u8
    }
}

/// The binary octahedral group with its multiplication table.
struct OctaGroup {
    elements: Vec<Quat>,
    /// `mul[a][b]` is the index of `elements[a] · elements[b]`.
    mul: Vec<[u8; 48]>,
}

fn octa_group() -> &'static OctaGroup {
    static GROUP: std::sync::OnceLock<OctaGroup> = std::sync::OnceLock::new();
    GROUP.get_or_init(|| {
        let elements = binary_octahedral_group();
        let mul =
            elements.iter().map(|a| std::array::from_fn(|b| nearest_octahedral_index(&a.mul(&elements[b])))).collect();
        OctaGroup { elements, mul }
    })
}

/// Largest number of tets around an edge that is analysed.
const MAX_RING: usize = 64;

/// Per-chunk accumulation of [`singular_edges`].
#[derive(Default)]
struct ChunkResult {
    edges: Vec<SingularEdge>,
    n_interior: usize,
    n_unordered: usize,
}

/// Singular edges of the field given by one frame per tet, and the report.
/// `boundary_vertex[v]` tells which vertices lie on the boundary (for the
/// curve check). `axis_tolerance_deg` is the largest angle between a
/// quarter-turn holonomy axis and the (unoriented) edge for valence 3/5.
/// `progress` is checked between the passes and per chunk of edges.
///
/// # Errors
/// [`Cancelled`] when `progress` is cancelled.
pub fn singular_edges(
    mesh: &TetMesh,
    frame_per_tet: &[Mat3],
    boundary_vertex: &[bool],
    axis_tolerance_deg: f64,
    progress: &Progress,
) -> Result<(Vec<SingularEdge>, SingularReport), Cancelled> {
    let n = mesh.n_vertices();
    let group = octa_group();
    let quats: Vec<Quat> = frame_per_tet.par_iter().map(Quat::from_matrix).collect();
    // Vertex → tets (CSR, increasing tet order).
    let mut ptr = vec![0usize; n + 1];
    for t in &mesh.tets {
        for v in t {
            ptr[v.idx() + 1] += 1;
        }
    }
    for v in 0..n {
        ptr[v + 1] += ptr[v];
    }
    let mut fill = ptr.clone();
    let mut vt = vec![0u32; ptr[n]];
    for (ti, t) in mesh.tets.iter().enumerate() {
        for v in t {
            vt[fill[v.idx()]] = ti as u32;
            fill[v.idx()] += 1;
        }
    }
    progress.check()?;
    let edges = crate::fem::tet_p1::tet_mesh_edges(mesh);
    progress.check()?;
    let cos_tol = axis_tolerance_deg.to_radians().cos();
    let chunks: Vec<ChunkResult> = edges
        .par_chunks(4096)
        .map(|chunk| {
            let mut res = ChunkResult::default();
            if progress.is_cancelled() {
                return res;
            }
            let mut ring = [0u32; MAX_RING];
            let mut link = [[0u32; 2]; MAX_RING];
            let mut order = [(0u8, false); MAX_RING];
            for &[a, b] in chunk {
                let (ta, tb) = (&vt[ptr[a as usize]..ptr[a as usize + 1]], &vt[ptr[b as usize]..ptr[b as usize + 1]]);
                let Some(k) = sorted_intersection_into(ta, tb, &mut ring) else {
                    res.n_interior += 1;
                    res.n_unordered += 1;
                    continue;
                };
                for (i, &t) in ring[..k].iter().enumerate() {
                    let mut o = [u32::MAX; 2];
                    let mut m = 0;
                    for v in &mesh.tets[t as usize] {
                        if v.0 != a && v.0 != b && m < 2 {
                            o[m] = v.0;
                            m += 1;
                        }
                    }
                    link[i] = o;
                }
                match order_ring(&link[..k], &mut order) {
                    RingOrder::Open => continue,
                    RingOrder::Invalid => {
                        res.n_interior += 1;
                        res.n_unordered += 1;
                        continue;
                    }
                    RingOrder::Closed => res.n_interior += 1,
                }
                // H = o_{k−1} ⋯ o_0, o_i the matching from ring tet i to i+1.
                let mut h = 0u8; // index of 1
                for i in 0..k {
                    let s = quats[ring[order[i].0 as usize] as usize];
                    let t = quats[ring[order[(i + 1) % k].0 as usize] as usize];
                    let o = nearest_octahedral_index(&t.conj().mul(&s));
                    h = group.mul[o as usize][h as usize];
                }
                let hq = group.elements[h as usize];
                let angle = 2.0 * hq.vector().norm().atan2(hq.scalar().abs());
                if angle < 0.1 {
                    continue;
                }
                // Loop orientation: sign of vol(a, b, c0, c1).
                let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
                let [c0, c1] = link[order[0].0 as usize];
                let (c0, c1) = if order[0].1 { (c1, c0) } else { (c0, c1) };
                let e = pb - pa;
                let turn = e.dot(&(mesh.positions[c0 as usize] - pa).cross(&(mesh.positions[c1 as usize] - pa)));
                let e_loop = if turn >= 0.0 { e.normalize() } else { -e.normalize() };
                // World axis of the holonomy (rotation by `angle` about it).
                let hq = if hq.scalar() < 0.0 { hq.neg() } else { hq };
                let axis = frame_per_tet[ring[order[0].0 as usize] as usize] * hq.vector().normalize();
                let align = axis.dot(&e_loop);
                let quarter = (angle - std::f64::consts::FRAC_PI_2).abs() < 0.1;
                let kind = if quarter && align >= cos_tol {
                    SingularKind::Valence3
                } else if quarter && align <= -cos_tol {
                    SingularKind::Valence5
                } else {
                    SingularKind::Complex
                };
                res.edges.push(SingularEdge {
                    vertices: [a, b],
                    kind,
                    holonomy_angle_deg: angle.to_degrees(),
                    axis_alignment: align.abs(),
                });
            }
            res
        })
        .collect();
    progress.check()?;
    let mut report = SingularReport::default();
    let mut out = Vec::new();
    for c in chunks {
        report.n_interior_edges += c.n_interior;
        report.n_unordered_rings += c.n_unordered;
        for e in c.edges {
            match e.kind {
                SingularKind::Valence3 => report.n_valence3 += 1,
                SingularKind::Valence5 => report.n_valence5 += 1,
                SingularKind::Complex => report.n_complex += 1,
            }
            out.push(e);
        }
    }
    curve_structure(&out, boundary_vertex, &mut report);
    Ok((out, report))
}

enum RingOrder {
    /// Tets in cyclic order, written to the `order` buffer: (index into the
    /// ring, link pair reversed?).
    Closed,
    /// The link is a path: the edge is on the boundary.
    Open,
    /// Not a simple path or cycle.
    Invalid,
}

/// Order the tets around an edge from their link pairs `[c, d]`.
fn order_ring(link: &[[u32; 2]], order: &mut [(u8, bool)]) -> RingOrder {
    let k = link.len();
    if k == 0 || k > order.len() {
        return RingOrder::Invalid;
    }
    // Every link vertex must appear exactly twice for a closed ring.
    let count = |x: u32| link.iter().filter(|p| p[0] == x || p[1] == x).count();
    for p in link {
        for &x in p {
            match count(x) {
                1 => return RingOrder::Open,
                2 => {}
                _ => return RingOrder::Invalid,
            }
        }
    }
    let mut used = 1u64;
    order[0] = (0, false);
    let first = link[0][0];
    let mut cur = link[0][1];
    let mut len = 1;
    while cur != first {
        let Some(next) = (0..k).find(|&i| used & (1 << i) == 0 && (link[i][0] == cur || link[i][1] == cur)) else {
            return RingOrder::Invalid;
        };
        used |= 1 << next;
        let rev = link[next][1] == cur;
        order[len] = (next as u8, rev);
        len += 1;
        cur = if rev { link[next][0] } else { link[next][1] };
    }
    if len != k {
        return RingOrder::Invalid;
    }
    RingOrder::Closed
}

/// Intersection of two increasing lists into `out`; `None` when it does not fit.
fn sorted_intersection_into(a: &[u32], b: &[u32], out: &mut [u32]) -> Option<usize> {
    let (mut i, mut j, mut k) = (0, 0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                if k == out.len() {
                    return None;
                }
                out[k] = a[i];
                k += 1;
                i += 1;
                j += 1;
            }
        }
    }
    Some(k)
}

/// Fill the curve counts of `report` from the singular edges.
fn curve_structure(edges: &[SingularEdge], boundary_vertex: &[bool], report: &mut SingularReport) {
    use std::collections::HashMap;
    let mut degree: HashMap<u32, usize> = HashMap::new();
    for e in edges {
        for v in e.vertices {
            *degree.entry(v).or_default() += 1;
        }
    }
    let dangling = |v: u32| degree.get(&v) == Some(&1) && !boundary_vertex.get(v as usize).copied().unwrap_or(false);
    report.n_dangling_interior_ends = degree.keys().filter(|&&v| dangling(v)).count();
    report.n_branch_vertices = degree.values().filter(|&&d| d >= 3).count();
    report.n_isolated_edges =
        edges.iter().filter(|e| degree[&e.vertices[0]] == 1 && degree[&e.vertices[1]] == 1).count();
    // Components by union-find over vertices.
    let mut ids: Vec<u32> = degree.keys().copied().collect();
    ids.sort_unstable();
    let index: HashMap<u32, u32> = ids.iter().enumerate().map(|(i, &v)| (v, i as u32)).collect();
    let mut sets = crate::mesh::components::DisjointSets::new(ids.len());
    for e in edges {
        sets.union(index[&e.vertices[0]], index[&e.vertices[1]]);
    }
    report.n_curves = sets.labels().1;
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn nearest_element_is_the_best_of_the_48() {
        use rand::rngs::StdRng;
        use rand::{Rng, SeedableRng};
        let mut rng = StdRng::seed_from_u64(71);
        let group = binary_octahedral_group();
        for _ in 0..500 {
            let q = Quat::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalized();
            let o = nearest_octahedral_element(&q);
            let best = group.iter().map(|g| g.dot(&q).abs()).fold(0.0, f64::max);
            assert!((o.dot(&q).abs() - best).abs() < 1e-14);
            assert!(group.iter().any(|g| (0..4).all(|k| (g.0[k] - o.0[k]).abs() < 1e-15)));
        }
    }

    /// Kuhn (Freudenthal) tetrahedralization of the box
    /// `[−n, n]² × [0, m]` with unit cubes, 6 tets per cube.
    pub(crate) fn kuhn_box(n: i64, m: i64) -> TetMesh {
        let w = (2 * n + 1) as usize;
        let id = |i: i64, j: i64, k: i64| ((i + n) as usize + w * ((j + n) as usize + w * k as usize)) as u32;
        let mut positions = Vec::new();
        for k in 0..=m {
            for j in -n..=n {
                for i in -n..=n {
                    positions.push(crate::geom::Vec3::new(i as f64, j as f64, k as f64));
                }
            }
        }
        let mut tets = Vec::new();
        for k in 0..m {
            for j in -n..n {
                for i in -n..n {
                    let v = |a: i64, b: i64, c: i64| crate::mesh::VertexId(id(i + a, j + b, k + c));
                    let (v000, v111) = (v(0, 0, 0), v(1, 1, 1));
                    let ring = [v(1, 0, 0), v(1, 1, 0), v(0, 1, 0), v(0, 1, 1), v(0, 0, 1), v(1, 0, 1)];
                    for r in 0..6 {
                        tets.push([v000, ring[r], ring[(r + 1) % 6], v111]);
                    }
                }
            }
        }
        let mut mesh = TetMesh { positions, tets };
        mesh.orient_positive();
        mesh
    }

    #[test]
    fn quarter_turn_fields_give_valence_3_and_5_on_the_axis() {
        let mesh = kuhn_box(3, 3);
        assert!(mesh.validate().is_ok());
        let boundary = crate::frames::volume::boundary_vertices(&mesh);
        for (sign, expected) in [(1.0, SingularKind::Valence3), (-1.0, SingularKind::Valence5)] {
            let frames: Vec<Mat3> = mesh
                .tets
                .iter()
                .map(|t| {
                    let c = t.iter().map(|v| mesh.positions[v.idx()]).sum::<crate::geom::Vec3>() / 4.0;
                    let phi = c.y.atan2(c.x);
                    // An arbitrary octahedral relabelling per tet must not matter.
                    let o = crate::frames::groups::cube_rotations()[(t[0].0 as usize * 7 + t[3].0 as usize) % 24];
                    super::super::quaternion::rotation_from_vector(&(crate::geom::Vec3::z() * (sign * phi / 4.0))) * o
                })
                .collect();
            let (edges, report) = singular_edges(&mesh, &frames, &boundary, 30.0, &Progress::none()).unwrap();
            assert_eq!(edges.len(), 3, "{edges:?}");
            for e in &edges {
                let [a, b] = e.vertices.map(|v| mesh.positions[v as usize]);
                assert!(a.x == 0.0 && a.y == 0.0 && b.x == 0.0 && b.y == 0.0, "{e:?}");
                assert_eq!(e.kind, expected);
                assert!((e.holonomy_angle_deg - 90.0).abs() < 1e-9 && e.axis_alignment > 0.999);
            }
            assert_eq!((report.n_curves, report.n_dangling_interior_ends, report.n_isolated_edges), (1, 0, 0));
        }
        // A smooth field has no singular edge.
        let frames: Vec<Mat3> = mesh.tets.iter().map(|_| Mat3::identity()).collect();
        assert!(singular_edges(&mesh, &frames, &boundary, 30.0, &Progress::none()).unwrap().0.is_empty());
    }

    #[test]
    fn rings_are_ordered_or_recognized_as_open() {
        let mut order = [(0u8, false); MAX_RING];
        let closed = [[1, 2], [3, 4], [2, 3], [4, 1]];
        assert!(matches!(order_ring(&closed, &mut order), RingOrder::Closed));
        assert_eq!(order[..4].iter().map(|o| o.0).collect::<Vec<_>>(), vec![0, 2, 1, 3]);
        assert!(matches!(order_ring(&[[1, 2], [2, 3]], &mut order), RingOrder::Open));
        assert!(matches!(order_ring(&[[1, 2], [1, 3], [1, 4]], &mut order), RingOrder::Invalid));
    }

    #[test]
    fn group_table_is_the_quaternion_product() {
        let g = octa_group();
        for (a, qa) in g.elements.iter().enumerate() {
            assert_eq!(nearest_octahedral_index(qa) as usize, a);
            for (b, qb) in g.elements.iter().enumerate() {
                let p = qa.mul(qb);
                let r = g.elements[g.mul[a][b] as usize];
                assert!((0..4).all(|k| (p.0[k] - r.0[k]).abs() < 1e-14));
            }
        }
    }
}
