//! Step 3b of the quads stage: regions of sliver triangles in the merged
//! surface triangulation re-triangulated in 3D.
//!
//! Why. Each patch is triangulated in its `(u, v)` plane and corrected by
//! flips judged in 3D ([`super::flips`]), but a mean value map can stretch a
//! patch so much that the `(u, v)` triangulation is far from any good one on
//! the surface: next to a sharp corner of a patch whose sides are seams, the
//! frontal points leave a strip one size wide between the seam's row of
//! points and the next row, and the `(u, v)` Delaunay triangulation covers
//! it with a fan of slivers from one far point (cow's thin legs: slivers of
//! 0.02 × 0.6 at a target of 0.05). No single flip improves a fan (each
//! pair of its triangles is nearly flat), so the flips keep it, and
//! recombination turns it into a row of inverted quads.
//!
//! What. Triangles of shape below [`SLIVER_SHAPE`] are seeds. Each seed's
//! region (the slivers joined to it through edges that are not on feature
//! curves, in one model face) is grown until it is a disk bounded by one
//! simple loop whose inside vertices are plain face vertices; the loop is
//! then triangulated anew by dynamic programming over its diagonals
//! (maximize the worst [`signed_shape`] against the surface normal under
//! each triangle, O(n³) for n loop vertices, no diagonal that is already an
//! edge outside the region). The region grows by one ring of edge
//! neighbours at a time, [`MAX_RINGS`] times, and the disk whose best
//! triangulation is best replaces its triangles when that beats the disk's
//! own worst triangle by [`MIN_GAIN`]. A cluster that holds a folded
//! triangle (shape ≤ 0) keeps growing, up to [`MAX_RINGS_FOLDED`] rings,
//! while no disk has an unfolded triangulation: a fold on a strip one
//! triangle wide (the chamfers of a CAD part, triangulated through a disk
//! map that made their reflex corners convex) grows by two triangles a
//! ring and can need ten or more rings before its loop reaches points that
//! an upright fan can join; a folded triangle left there becomes an
//! inverted quad.
//! A loop of `n` vertices around `k` removed inside vertices held
//! `n − 2 + 2k` triangles and gets `n − 2`: every model face keeps the
//! parity of its triangle count. Regions are taken in seed order on one
//! thread, so the output does not depend on the thread count.

use std::collections::{HashMap, HashSet};

use serde::Serialize;

use super::flips::signed_shape;
use super::surface_mesh::{ModelEntity, SurfaceTriangulation, single_boundary_loop};
use crate::geom::Vec3;

/// A triangle whose [`signed_shape`] is below this seeds a region.
pub const SLIVER_SHAPE: f64 = 0.1;
/// A re-triangulation must raise the region's worst shape by this much.
pub const MIN_GAIN: f64 = 0.02;
/// Rings of edge neighbours a region may grow by before it is left as it is.
pub const MAX_RINGS: usize = 3;
/// Rings a region around a folded triangle may grow by while no disk has
/// an unfolded triangulation.
pub const MAX_RINGS_FOLDED: usize = 16;
/// Passes over the slivers at most.
pub const MAX_PASSES: usize = 4;
/// Loops longer than this are not re-triangulated (the O(n³) bound).
pub const MAX_LOOP: usize = 160;

/// What the step did (for the report).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SliverStats {
    /// Triangles of shape below [`SLIVER_SHAPE`] before the step.
    pub n_slivers_before: usize,
    /// After it.
    pub n_slivers_after: usize,
    /// Regions re-triangulated.
    pub n_regions_retriangulated: usize,
    /// Clusters left as they were in a pass (no disk found, or no better
    /// triangulation).
    pub n_regions_kept: usize,
    /// Inside vertices the re-triangulations removed.
    pub n_vertices_removed: usize,
}

type Edge = (u32, u32);

/// A region, its new triangles, their worst shape and the region's inside
/// vertex count.
type Candidate = (Vec<u32>, Vec<[u32; 3]>, f64, usize);

fn key(a: u32, b: u32) -> Edge {
    (a.min(b), a.max(b))
}

/// The triangulation being edited: a removed flag per triangle (removed
/// ones are dropped at the end of the pass), the triangles on each edge,
/// the curve edges and the vertices no region may remove.
struct Editor<'a> {
    tri: &'a mut SurfaceTriangulation,
    removed: Vec<bool>,
    faces_of: HashMap<Edge, Vec<u32>>,
    curve: HashSet<Edge>,
    fixed: Vec<bool>,
}

impl Editor<'_> {
    /// [`signed_shape`] of triangle `t` of the triangulation against its
    /// surface normal.
    fn shape_of(&self, t: u32) -> f64 {
        let v = self.tri.triangles[t as usize];
        shape_against(&self.tri.vertices.positions, &v, &self.tri.normal_per_triangle[t as usize])
    }

    /// Unit normal at each vertex of `region`: the mean surface normal of
    /// its triangles there (the normals of the model face being edited; a
    /// curve vertex's own input triangle may lie on the other face).
    fn vertex_normals(&self, region: &[u32]) -> HashMap<u32, Vec3> {
        let mut out: HashMap<u32, Vec3> = HashMap::new();
        for &t in region {
            for v in self.tri.triangles[t as usize] {
                *out.entry(v).or_insert_with(Vec3::zeros) += self.tri.normal_per_triangle[t as usize];
            }
        }
        out
    }

    /// Triangles sharing a non-curve edge with `region`, in the same model
    /// face, not yet in it (sorted).
    fn ring(&self, region: &[u32], face: u32) -> Vec<u32> {
        let inside: HashSet<u32> = region.iter().copied().collect();
        let mut out: Vec<u32> = Vec::new();
        for &t in region {
            let tv = self.tri.triangles[t as usize];
            for i in 0..3 {
                let e = key(tv[i], tv[(i + 1) % 3]);
                if self.curve.contains(&e) {
                    continue;
                }
                for &u in self.faces_of.get(&e).into_iter().flatten() {
                    if !inside.contains(&u)
                        && !self.removed[u as usize]
                        && self.tri.model_face_per_triangle[u as usize] == face
                    {
                        out.push(u);
                    }
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The boundary loop of `region` in the direction its triangles run it,
    /// with the region's inside vertices, when the region is a disk bounded
    /// by one simple loop that crosses no curve edge inside.
    fn disk_loop(&self, region: &[u32]) -> Option<(Vec<u32>, Vec<u32>)> {
        let mut count: HashMap<Edge, u32> = HashMap::new();
        for &t in region {
            let tv = self.tri.triangles[t as usize];
            for i in 0..3 {
                *count.entry(key(tv[i], tv[(i + 1) % 3])).or_default() += 1;
            }
        }
        let mut next: HashMap<u32, u32> = HashMap::new();
        for &t in region {
            let tv = self.tri.triangles[t as usize];
            for i in 0..3 {
                let (a, b) = (tv[i], tv[(i + 1) % 3]);
                match count[&key(a, b)] {
                    1 => {
                        if next.insert(a, b).is_some() {
                            return None;
                        }
                    }
                    2 if self.curve.contains(&key(a, b)) => return None,
                    2 => {}
                    _ => return None,
                }
            }
        }
        let lp = single_boundary_loop(*next.keys().min()?, next.len(), |v| next.get(&v).copied())?;
        let on_loop: HashSet<u32> = lp.iter().copied().collect();
        let mut vertices: Vec<u32> = region.iter().flat_map(|&t| self.tri.triangles[t as usize]).collect();
        vertices.sort_unstable();
        vertices.dedup();
        let inside: Vec<u32> = vertices.into_iter().filter(|v| !on_loop.contains(v)).collect();
        // A disk: V − E + F = 1.
        let (n_v, n_e, n_f) = (lp.len() + inside.len(), count.len(), region.len());
        if n_v + n_f != n_e + 1 || inside.iter().any(|&v| self.fixed[v as usize]) {
            return None;
        }
        Some((lp, inside))
    }

    /// True when the diagonal `a b` of a region's loop is already an edge of
    /// a triangle outside the region.
    fn is_outside_edge(&self, a: u32, b: u32, region: &HashSet<u32>) -> bool {
        self.faces_of
            .get(&key(a, b))
            .is_some_and(|fs| fs.iter().any(|f| !region.contains(f) && !self.removed[*f as usize]))
    }

    /// The triangulation of the loop `lp` that maximizes its worst shape
    /// (dynamic programming over diagonals), with that worst shape.
    fn best_triangulation(&self, lp: &[u32], region: &[u32]) -> Option<(Vec<[u32; 3]>, f64)> {
        let n = lp.len();
        let normals = self.vertex_normals(region);
        let region: HashSet<u32> = region.iter().copied().collect();
        let region = &region;
        let positions = &self.tri.vertices.positions;
        let shape = |t: [u32; 3]| {
            let m: Vec3 = t.iter().map(|v| normals[v]).sum();
            shape_against(positions, &t, &m.try_normalize(0.0).unwrap_or(m))
        };
        let mut best = vec![f64::INFINITY; n * n];
        let mut split = vec![usize::MAX; n * n];
        for len in 2..n {
            for i in 0..n - len {
                let j = i + len;
                if !(i == 0 && j == n - 1) && self.is_outside_edge(lp[i], lp[j], region) {
                    best[i * n + j] = f64::NEG_INFINITY;
                    continue;
                }
                let mut b = f64::NEG_INFINITY;
                for k in i + 1..j {
                    let inner = best[i * n + k].min(best[k * n + j]);
                    if inner <= b {
                        continue;
                    }
                    let s = inner.min(shape([lp[i], lp[k], lp[j]]));
                    if s > b {
                        b = s;
                        split[i * n + j] = k;
                    }
                }
                best[i * n + j] = b;
            }
        }
        let worst = best[n - 1];
        if !worst.is_finite() {
            return None;
        }
        let mut out = Vec::with_capacity(n - 2);
        let mut stack = vec![(0, n - 1)];
        while let Some((i, j)) = stack.pop() {
            if j - i < 2 {
                continue;
            }
            let k = split[i * n + j];
            out.push([lp[i], lp[k], lp[j]]);
            stack.push((i, k));
            stack.push((k, j));
        }
        Some((out, worst))
    }

    /// Replace `region` by `triangles`; the cross and normal of each new
    /// triangle are those of the removed triangle nearest to it.
    fn replace(&mut self, region: &[u32], triangles: Vec<[u32; 3]>) {
        let p = &self.tri.vertices.positions;
        let centre = |t: &[u32; 3]| (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0;
        let old: Vec<(Vec3, u32)> = region.iter().map(|&t| (centre(&self.tri.triangles[t as usize]), t)).collect();
        let face = self.tri.model_face_per_triangle[region[0] as usize];
        let mut added = Vec::with_capacity(triangles.len());
        for t in &triangles {
            let c = centre(t);
            let nearest = old
                .iter()
                .min_by(|a, b| (a.0 - c).norm_squared().total_cmp(&(b.0 - c).norm_squared()))
                .map_or(region[0], |x| x.1);
            added.push((
                *t,
                self.tri.cross_per_triangle[nearest as usize],
                self.tri.normal_per_triangle[nearest as usize],
            ));
        }
        for &t in region {
            self.removed[t as usize] = true;
            let tv = self.tri.triangles[t as usize];
            for i in 0..3 {
                if let Some(fs) = self.faces_of.get_mut(&key(tv[i], tv[(i + 1) % 3])) {
                    fs.retain(|&f| f != t);
                }
            }
        }
        for (t, cross, normal) in added {
            let id = self.tri.triangles.len() as u32;
            self.tri.triangles.push(t);
            self.tri.model_face_per_triangle.push(face);
            self.tri.cross_per_triangle.push(cross);
            self.tri.normal_per_triangle.push(normal);
            self.removed.push(false);
            for i in 0..3 {
                self.faces_of.entry(key(t[i], t[(i + 1) % 3])).or_default().push(id);
            }
        }
    }

    /// The slivers joined to `seed` through non-curve edges in its model face.
    fn sliver_cluster(&self, seed: u32, is_sliver: &[bool]) -> Vec<u32> {
        let face = self.tri.model_face_per_triangle[seed as usize];
        let mut seen = HashSet::from([seed]);
        let mut stack = vec![seed];
        while let Some(t) = stack.pop() {
            for u in self.ring(&[t], face) {
                if (u as usize) < is_sliver.len() && is_sliver[u as usize] && seen.insert(u) {
                    stack.push(u);
                }
            }
        }
        let mut out: Vec<u32> = seen.into_iter().collect();
        out.sort_unstable();
        out
    }

    /// Re-triangulate the region around `seed`: of the disks it grows into
    /// (ring by ring, [`MAX_RINGS`] rings, up to [`MAX_RINGS_FOLDED`] around
    /// a fold that is not undone yet), the one whose best triangulation is
    /// best, when that beats the disk's own worst triangle by [`MIN_GAIN`]
    /// (counted in `stats` either way). Returns the slivers of the seed's
    /// cluster, which need no second attempt.
    fn repair(&mut self, seed: u32, is_sliver: &[bool], stats: &mut SliverStats) -> Vec<u32> {
        let face = self.tri.model_face_per_triangle[seed as usize];
        let cluster = self.sliver_cluster(seed, is_sliver);
        let mut region = cluster.clone();
        let mut best: Option<Candidate> = None;
        let folded = cluster.iter().any(|&t| self.shape_of(t) <= 0.0);
        for rings in 0..=MAX_RINGS_FOLDED {
            let unfolded = best.as_ref().is_some_and(|b| b.2 > 0.0);
            if rings > MAX_RINGS && (!folded || unfolded) {
                break;
            }
            if let Some((lp, inside)) = self.disk_loop(&region)
                && lp.len() <= MAX_LOOP
            {
                let old = region.iter().map(|&t| self.shape_of(t)).fold(f64::INFINITY, f64::min);
                let bar = best.as_ref().map_or(old + MIN_GAIN, |b| b.2.max(old + MIN_GAIN));
                if let Some((triangles, worst)) = self.best_triangulation(&lp, &region)
                    && worst > bar
                {
                    best = Some((region.clone(), triangles, worst, inside.len()));
                }
            }
            let ring = self.ring(&region, face);
            if ring.is_empty() {
                break;
            }
            region.extend(ring);
            region.sort_unstable();
        }
        match best {
            Some((region, triangles, _, n_inside)) => {
                self.replace(&region, triangles);
                stats.n_regions_retriangulated += 1;
                stats.n_vertices_removed += n_inside;
            }
            None => stats.n_regions_kept += 1,
        }
        cluster
    }
}

/// Re-triangulate the sliver regions of `tri` (see the module doc).
pub fn retriangulate_slivers(tri: &mut SurfaceTriangulation) -> SliverStats {
    let mut stats = SliverStats::default();
    for pass in 0..MAX_PASSES {
        let (n_slivers, n_done) = retriangulation_pass(tri, &mut stats);
        if pass == 0 {
            stats.n_slivers_before = n_slivers;
        }
        stats.n_slivers_after = n_slivers;
        if n_done == 0 {
            return stats;
        }
    }
    stats.n_slivers_after = (0..tri.triangles.len())
        .filter(|&t| {
            shape_against(&tri.vertices.positions, &tri.triangles[t], &tri.normal_per_triangle[t]) < SLIVER_SHAPE
        })
        .count();
    stats
}

/// One pass over the slivers of `tri`, each cluster tried once (regions
/// re-triangulated earlier in the pass change later clusters' disks, so
/// [`retriangulate_slivers`] runs passes until one changes nothing).
/// Returns the slivers found at its start and the regions it re-triangulated.
fn retriangulation_pass(tri: &mut SurfaceTriangulation, stats: &mut SliverStats) -> (usize, usize) {
    let n = tri.triangles.len();
    let mut fixed = vec![false; tri.vertices.len()];
    for (v, e) in tri.vertices.entity.iter().enumerate() {
        fixed[v] = !matches!(e, ModelEntity::Face(_));
    }
    for &(v, _) in &tri.singular_vertices {
        fixed[v as usize] = true;
    }
    let curve: HashSet<Edge> = tri.curve_edges.iter().map(|(_, [a, b])| key(*a, *b)).collect();
    let mut editor = Editor { tri, removed: vec![false; n], faces_of: HashMap::new(), curve, fixed };
    let is_sliver: Vec<bool> = (0..n).map(|t| editor.shape_of(t as u32) < SLIVER_SHAPE).collect();
    let n_slivers = is_sliver.iter().filter(|&&s| s).count();
    if n_slivers == 0 {
        return (0, 0);
    }
    for (f, t) in editor.tri.triangles.iter().enumerate() {
        for i in 0..3 {
            editor.faces_of.entry(key(t[i], t[(i + 1) % 3])).or_default().push(f as u32);
        }
    }
    let done_before = stats.n_regions_retriangulated;
    let mut tried = vec![false; n];
    for seed in 0..n {
        if is_sliver[seed] && !tried[seed] && !editor.removed[seed] {
            for t in editor.repair(seed as u32, &is_sliver, stats) {
                tried[t as usize] = true;
            }
        }
    }
    let removed = std::mem::take(&mut editor.removed);
    compact(editor.tri, &removed);
    (n_slivers, stats.n_regions_retriangulated - done_before)
}

/// [`signed_shape`] of the triangle `t` of `positions` against `n`.
fn shape_against(positions: &[Vec3], t: &[u32; 3], n: &Vec3) -> f64 {
    signed_shape(&positions[t[0] as usize], &positions[t[1] as usize], &positions[t[2] as usize], n)
}

/// Drop the removed triangles and the vertices no triangle uses any more
/// (inside vertices of re-triangulated regions), renumbering the rest in
/// order.
fn compact(tri: &mut SurfaceTriangulation, removed: &[bool]) {
    let kept: Vec<bool> = removed.iter().map(|&r| !r).collect();
    retain_flagged(&mut tri.triangles, &kept);
    retain_flagged(&mut tri.model_face_per_triangle, &kept);
    retain_flagged(&mut tri.cross_per_triangle, &kept);
    retain_flagged(&mut tri.normal_per_triangle, &kept);
    let mut used = vec![false; tri.vertices.len()];
    for t in &tri.triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    for (_, e) in &tri.curve_edges {
        for &v in e {
            used[v as usize] = true;
        }
    }
    if used.iter().all(|&u| u) {
        return;
    }
    let mut new_id = vec![u32::MAX; used.len()];
    let mut next = 0u32;
    for (v, &u) in used.iter().enumerate() {
        if u {
            new_id[v] = next;
            next += 1;
        }
    }
    retain_flagged(&mut tri.vertices.positions, &used);
    retain_flagged(&mut tri.vertices.on_surface, &used);
    retain_flagged(&mut tri.vertices.entity, &used);
    for t in &mut tri.triangles {
        *t = t.map(|v| new_id[v as usize]);
    }
    for (_, e) in &mut tri.curve_edges {
        *e = e.map(|v| new_id[v as usize]);
    }
    tri.singular_vertices.retain(|(v, _)| used[*v as usize]);
    for (v, _) in &mut tri.singular_vertices {
        *v = new_id[*v as usize];
    }
    tri.seam_vertices.retain(|v| used[*v as usize]);
    for v in &mut tri.seam_vertices {
        *v = new_id[*v as usize];
    }
}

/// Keep the entries of `v` whose flag in `keep` is set, in order.
fn retain_flagged<T>(v: &mut Vec<T>, keep: &[bool]) {
    let mut i = 0;
    v.retain(|_| {
        i += 1;
        keep[i - 1]
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quads::fixtures::planar_triangulation;

    /// Shape of every triangle of `tri` against its normal.
    fn shapes(tri: &SurfaceTriangulation) -> Vec<f64> {
        (0..tri.triangles.len())
            .map(|t| shape_against(&tri.vertices.positions, &tri.triangles[t], &tri.normal_per_triangle[t]))
            .collect()
    }

    /// Directed edges used by exactly one triangle (the outline).
    fn outline(tri: &SurfaceTriangulation) -> Vec<[u32; 2]> {
        let mut count: HashMap<Edge, usize> = HashMap::new();
        for t in &tri.triangles {
            for i in 0..3 {
                *count.entry(key(t[i], t[(i + 1) % 3])).or_default() += 1;
            }
        }
        let mut out: Vec<[u32; 2]> = tri
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |i| [t[i], t[(i + 1) % 3]]))
            .filter(|e| count[&key(e[0], e[1])] == 1)
            .collect();
        out.sort_unstable();
        out
    }

    /// A 5 × 1 strip whose two rows of 6 points are joined by two fans
    /// (from the top-left and the bottom-right point): slivers down to 0.08.
    fn fanned_strip() -> SurfaceTriangulation {
        let mut points: Vec<[f64; 2]> = (0..6).map(|i| [f64::from(i), 0.0]).collect();
        points.extend((0..6).map(|i| [f64::from(i), 1.0]));
        let mut triangles: Vec<[u32; 3]> = (0..5).map(|i| [i, i + 1, 6]).collect();
        triangles.extend((0..5).map(|i| [5, 7 + i, 6 + i]));
        planar_triangulation(&points, triangles, vec![0; 10])
    }

    #[test]
    fn a_fan_across_a_strip_becomes_a_strip_of_good_triangles() {
        let mut tri = fanned_strip();
        let before = outline(&tri);
        assert!(shapes(&tri).iter().any(|&s| s < SLIVER_SHAPE));
        let stats = retriangulate_slivers(&mut tri);
        assert!(stats.n_slivers_before > 0 && stats.n_regions_retriangulated > 0, "{stats:?}");
        assert_eq!(stats.n_slivers_after, 0, "{stats:?}");
        // Same points, same outline (the curve edges), n − 2 triangles.
        assert_eq!(tri.vertices.len(), 12);
        assert_eq!(tri.triangles.len(), 10);
        assert_eq!(outline(&tri), before);
        // The region grows three rings from the two slivers, so the fans'
        // first two triangles may stay: (0, 1, 6) of shape √3 / 2 and
        // (1, 2, 6) of shape 2√3 / 8; nothing is worse than the latter.
        let worst = shapes(&tri).into_iter().fold(f64::INFINITY, f64::min);
        assert!(worst >= 3f64.sqrt() / 4.0 - 1e-12, "worst shape {worst}");
        assert_eq!(tri.model_face_per_triangle.len(), 10);
        assert_eq!(tri.cross_per_triangle.len(), 10);
        assert_eq!(tri.normal_per_triangle.len(), 10);
    }

    /// A 4 × 4 square (vertices 1–4) fanned around vertex 0 at (2, 0.02),
    /// next to its bottom side.
    fn square_with_a_vertex_near_its_side() -> SurfaceTriangulation {
        let points = [[2.0, 0.02], [0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]];
        let triangles = vec![[1, 2, 0], [2, 3, 0], [3, 4, 0], [4, 1, 0]];
        let mut tri = planar_triangulation(&points, triangles, vec![0; 4]);
        tri.seam_vertices = vec![0, 3];
        tri
    }

    #[test]
    fn a_face_vertex_inside_a_sliver_region_is_removed_and_the_indices_follow() {
        let mut tri = square_with_a_vertex_near_its_side();
        let stats = retriangulate_slivers(&mut tri);
        assert_eq!(stats.n_vertices_removed, 1, "{stats:?}");
        assert_eq!(tri.vertices.len(), 4);
        assert_eq!(tri.triangles.len(), 2, "4 − 2 triangles: the parity of the face is kept");
        assert_eq!(tri.vertices.positions[0], Vec3::new(0.0, 0.0, 0.0));
        assert_eq!(tri.seam_vertices, vec![2], "old vertex 3 is now 2");
        assert!(shapes(&tri).iter().all(|&s| s > 0.5));
        assert!(tri.curve_edges.iter().all(|(_, e)| e.iter().all(|&v| v < 4)));
        assert_eq!(outline(&tri).len(), 4);
    }

    #[test]
    fn singular_and_curve_vertices_are_never_removed() {
        let mut tri = square_with_a_vertex_near_its_side();
        tri.singular_vertices = vec![(0, 1)];
        let before = tri.clone();
        let stats = retriangulate_slivers(&mut tri);
        assert_eq!(stats.n_vertices_removed, 0, "{stats:?}");
        assert_eq!(tri.vertices.len(), before.vertices.len());
        assert_eq!(tri.singular_vertices, vec![(0, 1)]);
        assert_eq!(tri.triangles.len(), 4);
    }

    #[test]
    fn a_triangulation_without_slivers_is_left_as_it_is() {
        let points = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let mut tri = planar_triangulation(&points, vec![[0, 1, 2], [0, 2, 3]], vec![0; 2]);
        let before = tri.triangles.clone();
        let stats = retriangulate_slivers(&mut tri);
        assert_eq!(stats, SliverStats::default());
        assert_eq!(tri.triangles, before);
    }
}
