//! Bounding-volume hierarchy over the triangles of a surface, for the
//! inside test, the cut points and distance queries of the volume mesher.
//!
//! Axis-aligned boxes, binary tree built top-down by splitting the centroid
//! bounds at the median of their longest axis (`O(n log n)`), leaves of at
//! most [`LEAF_SIZE`] triangles. Queries:
//! - [`TriangleBvh::segment_hits`]: every crossing of a segment `p → q`
//!   with a triangle (Möller–Trumbore in `f64`), reporting the segment
//!   parameter, the triangle, and whether the crossing is *ambiguous* (it
//!   lies within a relative `1e-9` of a triangle edge, or the segment runs
//!   in the plane of a triangle), so that callers relying on crossing
//!   parity can perturb and retry;
//! - [`TriangleBvh::closest_point`]: nearest point on the surface
//!   (branch and bound on box distances).

use crate::geom::Vec3;
use crate::mesh::TriMesh;

/// Maximum number of triangles in a leaf.
pub const LEAF_SIZE: usize = 4;

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: first triangle slot; inner: index of the left child (right = left + 1).
    start: u32,
    /// Leaf: number of triangles (> 0); inner: 0.
    count: u32,
}

/// A crossing of a segment with a triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Segment parameter in `[0, 1]` (`p + t (q − p)`).
    pub t: f64,
    /// Index of the triangle in the input mesh.
    pub triangle: u32,
    /// The crossing is near a triangle edge or the segment is (nearly) in
    /// the triangle's plane: parity arguments are unreliable.
    pub ambiguous: bool,
}

/// BVH over the triangles of a mesh (positions copied, in leaf order).
#[derive(Debug, Clone)]
pub struct TriangleBvh {
    nodes: Vec<Node>,
    /// Triangle corners in leaf order.
    corners: Vec<[Vec3; 3]>,
    /// Input index of each slot.
    ids: Vec<u32>,
}

fn tri_bounds(t: &[Vec3; 3]) -> (Vec3, Vec3) {
    (t[0].inf(&t[1]).inf(&t[2]), t[0].sup(&t[1]).sup(&t[2]))
}

impl TriangleBvh {
    /// Build the hierarchy over all triangles of `mesh`.
    pub fn new(mesh: &TriMesh) -> Self {
        let tris: Vec<[Vec3; 3]> = mesh.triangles.iter().map(|t| t.map(|v| mesh.positions[v.idx()])).collect();
        let mut order: Vec<u32> = (0..tris.len() as u32).collect();
        let centroids: Vec<Vec3> = tris.iter().map(|t| (t[0] + t[1] + t[2]) / 3.0).collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF_SIZE + 1);
        nodes.push(Node { lo: Vec3::zeros(), hi: Vec3::zeros(), start: 0, count: 0 });
        // (node index, range start, range end)
        let mut stack = vec![(0usize, 0usize, tris.len())];
        while let Some((ni, s, e)) = stack.pop() {
            let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
            let (mut clo, mut chi) = (lo, hi);
            for &i in &order[s..e] {
                let (a, b) = tri_bounds(&tris[i as usize]);
                lo = lo.inf(&a);
                hi = hi.sup(&b);
                clo = clo.inf(&centroids[i as usize]);
                chi = chi.sup(&centroids[i as usize]);
            }
            if e - s <= LEAF_SIZE {
                nodes[ni] = Node { lo, hi, start: s as u32, count: (e - s) as u32 };
                continue;
            }
            let ext = chi - clo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = (s + e) / 2;
            order[s..e].select_nth_unstable_by(mid - s, |&a, &b| {
                centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
            });
            let left = nodes.len();
            nodes.push(Node { lo: Vec3::zeros(), hi: Vec3::zeros(), start: 0, count: 0 });
            nodes.push(Node { lo: Vec3::zeros(), hi: Vec3::zeros(), start: 0, count: 0 });
            nodes[ni] = Node { lo, hi, start: left as u32, count: 0 };
            stack.push((left, s, mid));
            stack.push((left + 1, mid, e));
        }
        let corners = order.iter().map(|&i| tris[i as usize]).collect();
        Self { nodes, corners, ids: order }
    }

    /// Number of triangles.
    pub fn n_triangles(&self) -> usize {
        self.ids.len()
    }

    /// Every crossing of the segment `p → q` with a triangle, unsorted.
    pub fn segment_hits(&self, p: &Vec3, q: &Vec3, out: &mut Vec<Hit>) {
        out.clear();
        if self.ids.is_empty() {
            return;
        }
        let d = q - p;
        let inv = Vec3::new(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let node = self.nodes[stack[sp] as usize];
            if !segment_box(p, &inv, &node.lo, &node.hi) {
                continue;
            }
            if node.count > 0 {
                for slot in node.start as usize..(node.start + node.count) as usize {
                    if let Some((t, ambiguous)) = segment_triangle(p, &d, &self.corners[slot]) {
                        out.push(Hit { t, triangle: self.ids[slot], ambiguous });
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.start;
                stack[sp + 1] = node.start + 1;
                sp += 2;
            }
        }
    }

    /// Closest point of the surface to `x`: `(distance, point, triangle)`.
    /// `None` for an empty mesh.
    pub fn closest_point(&self, x: &Vec3) -> Option<(f64, Vec3, u32)> {
        if self.ids.is_empty() {
            return None;
        }
        let mut best = (f64::INFINITY, Vec3::zeros(), 0u32);
        // The tree is balanced (median splits), so its depth is below 40 and
        // the stack grows by at most one entry per level.
        let mut stack = [(0.0f64, 0u32); 80];
        stack[0] = (box_distance2(x, &self.nodes[0].lo, &self.nodes[0].hi), 0);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (d2, ni) = stack[sp];
            if d2 >= best.0 * best.0 {
                continue;
            }
            let node = self.nodes[ni as usize];
            if node.count > 0 {
                for slot in node.start as usize..(node.start + node.count) as usize {
                    let c = closest_on_triangle(x, &self.corners[slot]);
                    let dist = (c - x).norm();
                    if dist < best.0 {
                        best = (dist, c, self.ids[slot]);
                    }
                }
            } else {
                let (l, r) = (node.start, node.start + 1);
                let dl = box_distance2(x, &self.nodes[l as usize].lo, &self.nodes[l as usize].hi);
                let dr = box_distance2(x, &self.nodes[r as usize].lo, &self.nodes[r as usize].hi);
                // Visit the nearer child first (pushed last).
                if sp + 2 > stack.len() {
                    continue;
                }
                let (first, second) = if dl < dr { ((dr, r), (dl, l)) } else { ((dl, l), (dr, r)) };
                stack[sp] = first;
                stack[sp + 1] = second;
                sp += 2;
            }
        }
        Some(best)
    }
}

/// Slab test of the segment `p + t d`, `t ∈ [0, 1]`, against a box
/// (inflated by a relative 1e-9 so that touching segments are kept).
fn segment_box(p: &Vec3, inv: &Vec3, lo: &Vec3, hi: &Vec3) -> bool {
    let pad = 1e-9 * (hi - lo).norm().max(1e-300);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for a in 0..3 {
        let (l, h) = (lo[a] - pad, hi[a] + pad);
        if inv[a].is_infinite() {
            if p[a] < l || p[a] > h {
                return false;
            }
            continue;
        }
        let (mut ta, mut tb) = ((l - p[a]) * inv[a], (h - p[a]) * inv[a]);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Crossing of `p + t d` (`t ∈ [0, 1]`) with triangle `tri`: `(t, ambiguous)`.
fn segment_triangle(p: &Vec3, d: &Vec3, tri: &[Vec3; 3]) -> Option<(f64, bool)> {
    const EPS: f64 = 1e-9;
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let n = e1.cross(&e2);
    let nn = n.norm();
    if !(nn > 0.0) {
        return None; // degenerate triangle: no area, no crossing
    }
    let h = d.cross(&e2);
    let det = e1.dot(&h);
    let dn = d.norm();
    if det.abs() <= EPS * nn * dn {
        // Segment (nearly) parallel to the plane: ambiguous only if it lies
        // in the plane and overlaps the triangle's bounding box.
        let dist = n.dot(&(p - tri[0])).abs() / nn;
        let scale = e1.norm().max(e2.norm());
        if dist <= EPS * scale {
            let (lo, hi) = tri_bounds(tri);
            let (slo, shi) = (p.inf(&(p + d)), p.sup(&(p + d)));
            let overlap = (0..3).all(|a| slo[a] <= hi[a] + EPS * scale && shi[a] >= lo[a] - EPS * scale);
            if overlap {
                return Some((0.5, true));
            }
        }
        return None;
    }
    let f = 1.0 / det;
    let s = p - tri[0];
    let u = f * s.dot(&h);
    let qv = s.cross(&e1);
    let v = f * d.dot(&qv);
    let t = f * e2.dot(&qv);
    let w = 1.0 - u - v;
    let tol = EPS;
    if u < -tol || v < -tol || w < -tol || t < -tol || t > 1.0 + tol {
        return None;
    }
    let ambiguous = u < tol || v < tol || w < tol;
    Some((t.clamp(0.0, 1.0), ambiguous))
}

fn box_distance2(x: &Vec3, lo: &Vec3, hi: &Vec3) -> f64 {
    let mut d2 = 0.0;
    for a in 0..3 {
        let v = if x[a] < lo[a] {
            lo[a] - x[a]
        } else if x[a] > hi[a] {
            x[a] - hi[a]
        } else {
            0.0
        };
        d2 += v * v;
    }
    d2
}

/// Closest point on a triangle (Ericson, Real-Time Collision Detection §5.1.5).
pub fn closest_on_triangle(p: &Vec3, t: &[Vec3; 3]) -> Vec3 {
    let (a, b, c) = (t[0], t[1], t[2]);
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return a + ab * v;
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return a + ac * w;
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return b + (c - b) * w;
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    a + ab * v + ac * w
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    #[test]
    fn segment_hits_match_brute_force() {
        let mesh = fixtures::icosphere(2);
        let bvh = TriangleBvh::new(&mesh);
        let mut rng = StdRng::seed_from_u64(61);
        let mut hits = Vec::new();
        for _ in 0..200 {
            let p = Vec3::new(rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5));
            let q = Vec3::new(rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5));
            bvh.segment_hits(&p, &q, &mut hits);
            let mut brute: Vec<u32> = (0..mesh.n_faces())
                .filter(|&f| segment_triangle(&p, &(q - p), &mesh.corners(crate::mesh::FaceId::new(f))).is_some())
                .map(|f| f as u32)
                .collect();
            let mut got: Vec<u32> = hits.iter().map(|h| h.triangle).collect();
            brute.sort_unstable();
            got.sort_unstable();
            assert_eq!(got, brute);
            // A segment from inside the unit-ish sphere to far outside crosses once.
        }
        bvh.segment_hits(&Vec3::new(0.01, 0.02, 0.03), &Vec3::new(3.0, 0.1, 0.2), &mut hits);
        assert_eq!(hits.iter().filter(|h| !h.ambiguous).count(), 1);
    }

    #[test]
    fn closest_point_matches_brute_force() {
        let mesh = fixtures::torus(2.0, 0.5, 24, 12);
        let bvh = TriangleBvh::new(&mesh);
        let mut rng = StdRng::seed_from_u64(62);
        for _ in 0..200 {
            let x = Vec3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(-1.0..1.0));
            let (d, c, _) = bvh.closest_point(&x).unwrap();
            let brute = (0..mesh.n_faces())
                .map(|f| (closest_on_triangle(&x, &mesh.corners(crate::mesh::FaceId::new(f))) - x).norm())
                .fold(f64::INFINITY, f64::min);
            assert!((d - brute).abs() < 1e-12);
            assert!(((c - x).norm() - d).abs() < 1e-12);
        }
    }
}
