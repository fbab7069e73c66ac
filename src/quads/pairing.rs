//! The triangle pairs recombination may choose from, and greedy pairing
//! (Gmsh's `RecombineTriangle`, `meshGFaceOptimize.cpp`; research
//! quad-meshing §1.1, §5.1 step 4).
//!
//! Two triangles `t₁ = (a, b, c)` and `t₂ = (b, a, d)` (counter-clockwise seen
//! from outside) sharing the edge `ab` of one model face, `ab` not on a
//! feature curve, form the quad `(a, d, b, c)`, counter-clockwise as they are.
//! The pair is a candidate when that quad is strictly convex against the
//! surface: its scaled Jacobian ([`super::jacobian::scaled_jacobian`]) against
//! the mean of the two triangles' normals exceeds
//! [`MIN_PAIR_SCALED_JACOBIAN`].
//!
//! Cost (lower is better): `max_i |90° − αᵢ| / ErrDir`, with `αᵢ` the quad's
//! corner angles in 3D and `ErrDir = min(|cos θ|, |sin θ|)`, `θ` the angle
//! between the removed diagonal `ab` (projected onto `t₁`'s tangent plane)
//! and the cross of `t₁`. A diagonal at 45° to the cross (`ErrDir = √2/2`)
//! is the diagonal of a cross-aligned square, so it wins; a diagonal along a
//! cross branch (`ErrDir → 0`) would leave a quad rotated 45° off the cross.

use super::jacobian::{max_angle_deviation_deg, scaled_jacobian};
use super::surface_mesh::SurfaceTriangulation;
use crate::geom::Vec3;

/// "No triangle" / "no pair" in the fixed-size per-triangle arrays.
pub const NONE: u32 = u32::MAX;

/// A pair whose quad has a scaled Jacobian at or below this is not a
/// candidate: the later steps need every corner strictly convex, and a
/// nearly flat corner is one smoothing step away from inverting.
pub const MIN_PAIR_SCALED_JACOBIAN: f64 = 0.02;

/// Floor of the pairs a face that the candidates cannot pair all-quad may
/// use as well ([`super::recombine`]): any quad that is convex against the
/// surface. Those faces were midpoint-subdivided whole, with the faces
/// next to them, which quarters the size asked for; a nearly flat corner
/// is left to the later steps (smoothing, pillowing) instead.
pub const MIN_POOR_PAIR_SCALED_JACOBIAN: f64 = 0.0;

/// Floor of `ErrDir` in the cost, so a diagonal exactly along the cross
/// gives a large finite cost (the pair stays usable by the completion).
const MIN_ERR_DIR: f64 = 1e-3;

/// Two triangles that may become one quad.
#[derive(Debug, Clone, PartialEq)]
pub struct Pair {
    /// The two triangles, lower index first.
    pub triangles: [u32; 2],
    /// The quad they form, counter-clockwise seen from outside.
    pub quad: [u32; 4],
    /// Its cost (module doc): lower is better.
    pub cost: f64,
}

/// The dual graph of the triangulation restricted to what recombination may
/// do: adjacency inside model faces across non-curve edges, and the
/// candidate pairs among those adjacencies.
#[derive(Debug, Clone, Default)]
pub struct DualGraph {
    /// Per triangle, the triangles across its non-curve edges in the same
    /// model face (whether or not they form a convex quad), [`NONE`]-padded.
    pub neighbours_per_triangle: Vec<[u32; 3]>,
    /// The candidate pairs, sorted by cost, then by triangle indices.
    pub pairs: Vec<Pair>,
    /// Per triangle, the indices in `pairs` of its candidates, ascending
    /// (cheapest first), [`NONE`]-padded.
    pub pairs_per_triangle: Vec<[u32; 3]>,
    /// Model faces sharing an edge (`[f, g]`, `f < g`, sorted, unique):
    /// subdividing one forces subdividing the other.
    pub face_links: Vec<[u32; 2]>,
}

impl DualGraph {
    /// The dual graph of `tri` (whose indices the caller has checked), its
    /// candidates the pairs above [`MIN_PAIR_SCALED_JACOBIAN`].
    pub fn new(tri: &SurfaceTriangulation) -> DualGraph {
        Self::with_floor(tri, &|_| MIN_PAIR_SCALED_JACOBIAN)
    }

    /// The dual graph of `tri` whose candidates in model face `f` are the
    /// pairs whose quad has a scaled Jacobian above `floor(f)`.
    pub fn with_floor(tri: &SurfaceTriangulation, floor: &dyn Fn(u32) -> f64) -> DualGraph {
        let n = tri.triangles.len();
        let mut curve: Vec<(u32, u32)> = tri.curve_edges.iter().map(|&(_, [a, b])| (a.min(b), a.max(b))).collect();
        curve.sort_unstable();
        curve.dedup();
        let mut half_edges: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * n);
        for (t, tv) in tri.triangles.iter().enumerate() {
            for i in 0..3 {
                let (a, b) = (tv[i], tv[(i + 1) % 3]);
                half_edges.push((a.min(b), a.max(b), t as u32));
            }
        }
        half_edges.sort_unstable();
        let mut graph = DualGraph {
            neighbours_per_triangle: vec![[NONE; 3]; n],
            pairs_per_triangle: vec![[NONE; 3]; n],
            ..DualGraph::default()
        };
        let mut start = 0;
        while start < half_edges.len() {
            let (a, b, _) = half_edges[start];
            let mut end = start + 1;
            while end < half_edges.len() && (half_edges[end].0, half_edges[end].1) == (a, b) {
                end += 1;
            }
            graph.link_faces(tri, &half_edges[start..end]);
            if end - start == 2 && curve.binary_search(&(a, b)).is_err() {
                let (t1, t2) = (half_edges[start].2, half_edges[start + 1].2);
                if t1 != t2 && tri.model_face_per_triangle[t1 as usize] == tri.model_face_per_triangle[t2 as usize] {
                    push_slot(&mut graph.neighbours_per_triangle[t1 as usize], t2);
                    push_slot(&mut graph.neighbours_per_triangle[t2 as usize], t1);
                    if let Some(pair) = candidate_pair(tri, t1, t2, floor(tri.model_face_per_triangle[t1 as usize])) {
                        graph.pairs.push(pair);
                    }
                }
            }
            start = end;
        }
        graph.face_links.sort_unstable();
        graph.face_links.dedup();
        graph.pairs.sort_by(|p, q| p.cost.total_cmp(&q.cost).then(p.triangles.cmp(&q.triangles)));
        graph.pairs.dedup_by(|p, q| p.triangles == q.triangles);
        for (i, p) in graph.pairs.iter().enumerate() {
            for &t in &p.triangles {
                push_slot(&mut graph.pairs_per_triangle[t as usize], i as u32);
            }
        }
        graph
    }

    /// Records the model faces meeting at one edge (its half-edges `run`).
    fn link_faces(&mut self, tri: &SurfaceTriangulation, run: &[(u32, u32, u32)]) {
        for (i, x) in run.iter().enumerate() {
            for y in &run[i + 1..] {
                let (f, g) = (tri.model_face_per_triangle[x.2 as usize], tri.model_face_per_triangle[y.2 as usize]);
                if f != g {
                    self.face_links.push([f.min(g), f.max(g)]);
                }
            }
        }
    }

    /// The candidate pairing triangles `t` and `u`, if any.
    pub fn pair_of(&self, t: u32, u: u32) -> Option<&Pair> {
        self.pairs_per_triangle[t as usize]
            .iter()
            .take_while(|&&p| p != NONE)
            .map(|&p| &self.pairs[p as usize])
            .find(|p| p.triangles.contains(&u))
    }
}

/// Puts `value` in the first free slot of `slots` (an edge has at most three
/// neighbours; a fourth, impossible on a triangle, is dropped).
fn push_slot(slots: &mut [u32; 3], value: u32) {
    if let Some(s) = slots.iter_mut().find(|s| **s == NONE) {
        *s = value;
    }
}

/// The quad of triangles `t1 < t2` (sharing one edge) and its cost, or
/// `None` when its scaled Jacobian is not above `floor` or it is degenerate.
fn candidate_pair(tri: &SurfaceTriangulation, t1: u32, t2: u32, floor: f64) -> Option<Pair> {
    let (t1, t2) = (t1.min(t2), t1.max(t2));
    let quad = quad_of_triangles(&tri.triangles[t1 as usize], &tri.triangles[t2 as usize])?;
    let p = quad.map(|v| tri.vertices.positions[v as usize]);
    let n1 = tri.normal_per_triangle[t1 as usize];
    let n = n1 + tri.normal_per_triangle[t2 as usize];
    let len = n.norm();
    if !(len > 0.0) {
        return None;
    }
    if !(scaled_jacobian(&p, &(n / len)) > floor) {
        return None;
    }
    // The removed diagonal joins quad corners 0 and 2.
    let err_dir = diagonal_alignment(&(p[2] - p[0]), &n1, &tri.cross_per_triangle[t1 as usize]);
    let cost = max_angle_deviation_deg(&p) / err_dir.max(MIN_ERR_DIR);
    cost.is_finite().then_some(Pair { triangles: [t1, t2], quad, cost })
}

/// `ErrDir = min(|cos θ|, |sin θ|)` of the diagonal `d` against the cross
/// `cross` in the tangent plane of normal `n` (0 for a diagonal along the
/// normal).
pub fn diagonal_alignment(d: &Vec3, n: &Vec3, cross: &Vec3) -> f64 {
    let tangent = d - n * d.dot(n);
    let len = tangent.norm();
    if !(len > 0.0) {
        return 0.0;
    }
    let cos = tangent.dot(cross) / len;
    let sin = tangent.dot(&n.cross(cross)) / len;
    cos.abs().min(sin.abs())
}

/// The quad `(a, d, b, c)` of `t1 = (a, b, c)` and `t2 = (b, a, d)` (module
/// doc), or `None` when they do not share exactly one edge with opposite
/// orientations.
pub fn quad_of_triangles(t1: &[u32; 3], t2: &[u32; 3]) -> Option<[u32; 4]> {
    for i in 0..3 {
        let (a, b, c) = (t1[i], t1[(i + 1) % 3], t1[(i + 2) % 3]);
        for j in 0..3 {
            if t2[j] == b && t2[(j + 1) % 3] == a {
                let d = t2[(j + 2) % 3];
                return (d != c && d != a && d != b).then_some([a, d, b, c]);
            }
        }
    }
    None
}

/// Greedy pairing: candidates taken cheapest first whenever both triangles
/// are still free. Returns the partner of each triangle ([`NONE`] if free).
pub fn greedy_partners(graph: &DualGraph) -> Vec<u32> {
    let mut partner = vec![NONE; graph.neighbours_per_triangle.len()];
    for p in &graph.pairs {
        let [t, u] = p.triangles;
        if partner[t as usize] == NONE && partner[u as usize] == NONE {
            partner[t as usize] = u;
            partner[u as usize] = t;
        }
    }
    partner
}
