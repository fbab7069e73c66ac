//! Triangles the matching left free, joined in pairs through a strip of
//! split quads, so a face with a few free triangles becomes all-quad at the
//! size asked for instead of being midpoint-subdivided whole.
//!
//! For two free triangles `t₁`, `t₂` of one model face, the shortest path
//! of elements `t₁, q₁, …, q_k, t₂` across non-curve edges that crosses at
//! least one quad between opposite edges (breadth first over element,
//! entry edge and that flag, in element and corner order) is split at the
//! midpoint of every edge it crosses:
//! - `t₁` and `t₂` gain one midpoint on one edge: each becomes a quad;
//! - each `qᵢ` gains two midpoints: a hexagon, cut into two quads along the
//!   long diagonal from one of them, chosen by [`cuts`] so that every
//!   midpoint ends a cut (a midpoint that ends none stays a flat corner).
//!
//! Every split element keeps its orientation and its neighbours across the
//! split edges are the path's own elements, so the mesh stays conforming.
//! The midpoints are then relaxed to their neighbours' centroid; a strip
//! that still has a quad at or below [`MIN_SCALED_JACOBIAN`] is undone and
//! its triangles look for another route, around the quads it crossed, in
//! the next round. A face where a triangle still has no partner after
//! [`STRIP_ROUNDS`] rounds (odd count, or no valid route) has all its
//! strips undone and is left to subdivision. The midpoints' irregular
//! vertices are removed later by cavity remeshing.

use std::collections::{HashMap, HashSet, VecDeque};

use serde::Serialize;

use super::jacobian::scaled_jacobian;
use super::subdivision::{Element, push_mean_vertex};
use super::surface_mesh::{CurveEdge, ModelEntity, SurfaceVertices};
use crate::geom::Vec3;

/// What joining the free triangles did.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct StripStats {
    /// Pairs of free triangles joined.
    pub n_pairs_joined: usize,
    /// Quads split along the strips.
    pub n_quads_split: usize,
    /// Strips undone because a quad of a strip of their face stayed at or
    /// below the scaled Jacobian floor after relaxing (the face is left to
    /// subdivision).
    pub n_strips_undone: usize,
}

/// The elements with an index of their edges.
struct Elements<'a> {
    elements: Vec<Option<(Element, u32)>>,
    /// Elements made by a strip (not crossed by later strips, so a strip
    /// can be undone alone).
    frozen: Vec<bool>,
    by_edge: HashMap<(u32, u32), Vec<usize>>,
    curve: &'a HashSet<(u32, u32)>,
}

/// The edge `a b` as a key.
fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

impl<'a> Elements<'a> {
    fn new(elements: &[Element], faces: &[u32], curve: &'a HashSet<(u32, u32)>) -> Self {
        let mut out =
            Self { elements: Vec::with_capacity(elements.len()), frozen: Vec::new(), by_edge: HashMap::new(), curve };
        for (e, &f) in elements.iter().zip(faces) {
            out.add(*e, f);
        }
        out
    }

    /// Appends `element` of model face `face`.
    fn add(&mut self, element: Element, face: u32) -> usize {
        let i = self.elements.len();
        self.frozen.push(false);
        let c = element.corners();
        for k in 0..c.len() {
            self.by_edge.entry(key(c[k], c[(k + 1) % c.len()])).or_default().push(i);
        }
        self.elements.push(Some((element, face)));
        i
    }

    /// Removes element `i`.
    fn remove(&mut self, i: usize) {
        let Some((element, _)) = self.elements[i].take() else { return };
        let c = element.corners();
        for k in 0..c.len() {
            if let Some(list) = self.by_edge.get_mut(&key(c[k], c[(k + 1) % c.len()])) {
                list.retain(|&j| j != i);
            }
        }
    }

    /// The shortest path of elements of `from`'s face from `from` to
    /// another free triangle, across non-curve edges, through quads not
    /// made by an earlier strip and crossing at least one of them between
    /// opposite edges (see [`cuts`]), with no element twice; with the edge
    /// crossed into each element after the first.
    fn path_to_free_triangle(&self, from: usize) -> Option<Vec<(usize, (u32, u32))>> {
        let (_, face) = self.elements[from]?;
        let start = Step { element: from, entry: NO_ENTRY, straight: false };
        let mut parent: HashMap<Step, (Step, (u32, u32))> = HashMap::new();
        let mut queue = VecDeque::from([start]);
        while let Some(step) = queue.pop_front() {
            let Some((element, _)) = self.elements[step.element] else { continue };
            let c = element.corners();
            for k in 0..c.len() {
                if k == step.entry {
                    continue;
                }
                let edge = key(c[k], c[(k + 1) % c.len()]);
                if self.curve.contains(&edge) {
                    continue;
                }
                let straight = step.straight || (c.len() == 4 && step.entry != NO_ENTRY && (step.entry + 2) % 4 == k);
                for &n in self.by_edge.get(&edge).into_iter().flatten() {
                    let Some((other, f)) = self.elements[n] else { continue };
                    if n == step.element || f != face || self.frozen.get(n).copied().unwrap_or(false) {
                        continue;
                    }
                    let oc = other.corners();
                    let entry = (0..oc.len()).find(|&j| key(oc[j], oc[(j + 1) % oc.len()]) == edge).unwrap_or(NO_ENTRY);
                    let next = Step { element: n, entry, straight };
                    if next.element == from || parent.contains_key(&next) {
                        continue;
                    }
                    parent.insert(next, (step, edge));
                    match other {
                        Element::Triangle(_) if straight => {
                            let path = unwind(&parent, start, next);
                            let mut seen: Vec<usize> = path.iter().map(|p| p.0).collect();
                            seen.sort_unstable();
                            seen.dedup();
                            if seen.len() == path.len() {
                                return Some(path);
                            }
                        }
                        Element::Triangle(_) => {}
                        Element::Quad(_) => queue.push_back(next),
                    }
                }
            }
        }
        None
    }
}

/// No entry edge (the first element of a path).
const NO_ENTRY: usize = usize::MAX;

/// A state of the path search: an element, the corner slot of the edge it
/// was entered by, and whether a quad was crossed straight on the way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Step {
    element: usize,
    entry: usize,
    straight: bool,
}

/// The path from `start` to `end` in the search's `parent` links:
/// `(element, edge crossed into it)`, the first element with a dummy edge.
fn unwind(parent: &HashMap<Step, (Step, (u32, u32))>, start: Step, end: Step) -> Vec<(usize, (u32, u32))> {
    let mut path = Vec::new();
    let mut s = end;
    while s != start {
        let (p, edge) = parent[&s];
        path.push((s.element, edge));
        s = p;
    }
    path.push((start.element, (u32::MAX, u32::MAX)));
    path.reverse();
    path
}

/// `corners` with `mid` inserted on edge `edge` (wherever it is in the cycle).
fn insert_midpoint(corners: &[u32], edge: (u32, u32), mid: u32) -> Vec<u32> {
    let n = corners.len();
    let mut out = Vec::with_capacity(n + 1);
    for k in 0..n {
        out.push(corners[k]);
        if key(corners[k], corners[(k + 1) % n]) == edge {
            out.push(mid);
        }
    }
    out
}

/// The two quads of hexagon `h` along its long diagonal from `through`.
fn split_hexagon(h: &[u32], through: u32) -> [[u32; 4]; 2] {
    let j = h.iter().position(|&v| v == through).unwrap_or(0);
    let q = |s: usize| [h[(j + s) % 6], h[(j + s + 1) % 6], h[(j + s + 2) % 6], h[(j + s + 3) % 6]];
    [q(0), q(3)]
}

/// For each quad of a strip (the elements between its two triangles), the
/// midpoint its hexagon is cut from, so that every midpoint is the end of
/// a cut (else it stays a flat corner in both elements beside it). Quad
/// `i` lies between midpoints `i` and `i + 1`; a quad crossed between
/// opposite edges is cut between its two midpoints and serves both.
/// `None` when no quad is crossed straight (then some midpoint cannot be
/// served).
fn cuts(straight: &[bool]) -> Option<Vec<usize>> {
    if !straight.iter().any(|&s| s) {
        return None;
    }
    let mut served = vec![false; straight.len() + 1];
    let mut out = Vec::with_capacity(straight.len());
    for (i, &s) in straight.iter().enumerate() {
        let from = if served[i] { i + 1 } else { i };
        served[from] = true;
        if s {
            served[i] = true;
            served[i + 1] = true;
        }
        out.push(from);
    }
    served.iter().all(|&s| s).then_some(out)
}

/// Unit normal of the polygon `corners` (Newell's formula), `+z` if degenerate.
fn polygon_normal(corners: &[u32], positions: &[Vec3]) -> Vec3 {
    let n = corners.len();
    let sum = (0..n).fold(Vec3::zeros(), |acc, k| {
        acc + positions[corners[k] as usize].cross(&positions[corners[(k + 1) % n] as usize])
    });
    sum.try_normalize(0.0).unwrap_or_else(Vec3::z)
}

/// Centroid sweeps over the midpoints after the strips are split: a
/// midpoint on its edge is a flat corner of the quads beside it until it
/// moves off the edge.
const RELAX_SWEEPS: usize = 20;

/// A strip that leaves a quad at or below this scaled Jacobian (after
/// relaxing) is undone.
const MIN_SCALED_JACOBIAN: f64 = 0.05;

/// Rounds of strip joining: a strip left invalid by relaxing is undone and
/// the quads it crossed are closed to later strips, so its two triangles
/// look for another route in the next round.
const STRIP_ROUNDS: usize = 4;

/// Joins the free triangles of `elements` (model faces `faces`) in pairs
/// (module doc), appending the midpoints to `vertices`. Returns the new
/// elements and faces. A strip that relaxing leaves invalid is undone alone
/// and its triangles try another route (up to [`STRIP_ROUNDS`] rounds); in
/// a face where triangles stay free after that every strip is undone, so
/// subdivision splits the matching's elements (midpoints of undone strips
/// are left unused: cleanup drops vertices in no quad).
pub fn join_free_triangles(
    vertices: &mut SurfaceVertices,
    elements: &[Element],
    faces: &[u32],
    curve_edges: &[CurveEdge],
) -> (Vec<Element>, Vec<u32>, StripStats) {
    let curve: HashSet<(u32, u32)> = curve_edges.iter().map(|&(_, [a, b])| key(a, b)).collect();
    let mut work = Elements::new(elements, faces, &curve);
    let mut stats = StripStats::default();
    let mut kept: Vec<Strip> = Vec::new();
    let mut mids: Vec<u32> = Vec::new();
    for _ in 0..STRIP_ROUNDS {
        let made = strip_round(&mut work, vertices, &mut mids);
        if made.is_empty() {
            break;
        }
        relax_midpoints(&work, vertices, &mids);
        let (valid, invalid): (Vec<Strip>, Vec<Strip>) = made.into_iter().partition(|s| s.is_valid(&work, vertices));
        kept.extend(valid);
        if invalid.is_empty() {
            break;
        }
        for strip in &invalid {
            let restored = strip.undo(&mut work);
            // Closed to later strips: the next round routes around them.
            for &i in &restored[1..restored.len() - 1] {
                work.frozen[i] = true;
            }
            stats.n_strips_undone += 1;
        }
    }
    // A face where a triangle stays free (or a strip stays invalid) is
    // subdivided: all its strips are undone.
    let n_faces = faces.iter().map(|&f| f as usize + 1).max().unwrap_or(0);
    let mut refused = vec![false; n_faces];
    for (element, face) in work.elements.iter().flatten() {
        if matches!(element, Element::Triangle(_)) {
            refused[*face as usize] = true;
        }
    }
    for strip in &kept {
        if !strip.is_valid(&work, vertices) {
            refused[strip.face() as usize] = true;
        }
    }
    for strip in &kept {
        if refused[strip.face() as usize] {
            strip.undo(&mut work);
            stats.n_strips_undone += 1;
        } else {
            stats.n_pairs_joined += 1;
            stats.n_quads_split += strip.originals.len() - 2;
        }
    }
    let (out, out_faces) = work.elements.into_iter().flatten().unzip();
    (out, out_faces, stats)
}

/// One round: every free triangle that is still free, in element order,
/// joined with the nearest free triangle a strip can reach; the strips made
/// (their midpoints appended to `mids`).
fn strip_round(work: &mut Elements, vertices: &mut SurfaceVertices, mids: &mut Vec<u32>) -> Vec<Strip> {
    let free: Vec<usize> = (0..work.elements.len())
        .filter(|&i| matches!(work.elements[i], Some((Element::Triangle(_), _))) && !work.frozen[i])
        .collect();
    let mut made = Vec::new();
    for t in free {
        if !matches!(work.elements[t], Some((Element::Triangle(_), _))) {
            continue;
        }
        let Some(path) = work.path_to_free_triangle(t) else { continue };
        let originals: Vec<(Element, u32)> = path.iter().filter_map(|&(e, _)| work.elements[e]).collect();
        let Some((new_elements, new_mids)) = split_strip(work, vertices, &path) else { continue };
        mids.extend(new_mids);
        made.push(Strip { originals, made: new_elements });
    }
    made
}

/// A strip that was split: the elements it replaced and the ones it made
/// (each with the normal of the element it came from).
struct Strip {
    originals: Vec<(Element, u32)>,
    made: Vec<(usize, Vec3)>,
}

impl Strip {
    /// The model face of the strip.
    fn face(&self) -> u32 {
        self.originals[0].1
    }

    /// Whether every quad the strip made is above [`MIN_SCALED_JACOBIAN`]
    /// against the normal of the element it came from.
    fn is_valid(&self, work: &Elements, vertices: &SurfaceVertices) -> bool {
        self.made.iter().all(|(e, normal)| match work.elements[*e] {
            Some((Element::Quad(q), _)) => {
                scaled_jacobian(&q.map(|v| vertices.positions[v as usize]), normal) > MIN_SCALED_JACOBIAN
            }
            _ => true,
        })
    }

    /// Replaces the strip's elements by the ones it split; returns their new
    /// indices, in path order.
    fn undo(&self, work: &mut Elements) -> Vec<usize> {
        for (e, _) in &self.made {
            work.remove(*e);
        }
        self.originals.iter().map(|&(element, face)| work.add(element, face)).collect()
    }
}

/// Moves each midpoint to the centroid of its edge neighbours,
/// [`RELAX_SWEEPS`] times in order (positions only: the smoothing step
/// projects every vertex onto the surface).
fn relax_midpoints(work: &Elements, vertices: &mut SurfaceVertices, mids: &[u32]) {
    let wanted: HashSet<u32> = mids.iter().copied().collect();
    let mut around: HashMap<u32, Vec<u32>> = HashMap::new();
    for (element, _) in work.elements.iter().flatten() {
        let c = element.corners();
        for k in 0..c.len() {
            let (a, b) = (c[k], c[(k + 1) % c.len()]);
            if wanted.contains(&a) {
                around.entry(a).or_default().push(b);
            }
            if wanted.contains(&b) {
                around.entry(b).or_default().push(a);
            }
        }
    }
    for list in around.values_mut() {
        list.sort_unstable();
        list.dedup();
    }
    for _ in 0..RELAX_SWEEPS {
        for m in mids {
            let Some(list) = around.get(m) else { continue };
            let p = &vertices.positions;
            let sum = list.iter().fold(Vec3::zeros(), |acc, &w| acc + p[w as usize]);
            vertices.positions[*m as usize] = sum / list.len() as f64;
        }
    }
}

/// What splitting a strip made: the new elements, each with the normal of
/// the element it came from, and the midpoints.
type SplitStrip = (Vec<(usize, Vec3)>, Vec<u32>);

/// Splits the elements of `path` (a free triangle, quads, a free triangle)
/// at the midpoints of the edges it crosses, when [`cuts`] can serve every
/// midpoint. Returns the new elements, each with the normal of the element
/// it came from, and the midpoints.
fn split_strip(
    work: &mut Elements,
    vertices: &mut SurfaceVertices,
    path: &[(usize, (u32, u32))],
) -> Option<SplitStrip> {
    let inner = &path[1..path.len() - 1];
    let straight: Vec<bool> = inner
        .iter()
        .enumerate()
        .map(|(i, &(e, entry))| {
            let c = work.elements[e].map_or(Vec::new(), |(el, _)| el.corners().to_vec());
            let at = |edge: (u32, u32)| (0..c.len()).find(|&k| key(c[k], c[(k + 1) % c.len()]) == edge);
            matches!((at(entry), at(path[i + 2].1)), (Some(a), Some(b)) if (a + 2) % 4 == b)
        })
        .collect();
    let cut_from = cuts(&straight)?;
    let face = work.elements[path[0].0].map_or(0, |(_, f)| f);
    let mids: Vec<u32> =
        path[1..].iter().map(|&(_, (a, b))| push_mean_vertex(vertices, &[a, b], ModelEntity::Face(face))).collect();
    let mut made = Vec::new();
    for (i, &(e, _)) in path.iter().enumerate() {
        let Some((element, _)) = work.elements[e] else { continue };
        let normal = polygon_normal(element.corners(), &vertices.positions);
        let mut corners = element.corners().to_vec();
        if i > 0 {
            corners = insert_midpoint(&corners, path[i].1, mids[i - 1]);
        }
        if i + 1 < path.len() {
            corners = insert_midpoint(&corners, path[i + 1].1, mids[i]);
        }
        work.remove(e);
        if corners.len() == 6 {
            for q in split_hexagon(&corners, mids[cut_from[i - 1]]) {
                made.push((work.add(Element::Quad(q), face), normal));
            }
        } else {
            made.push((work.add(Element::Quad([corners[0], corners[1], corners[2], corners[3]]), face), normal));
        }
        for &(m, _) in &made {
            work.frozen[m] = true;
        }
    }
    Some((made, mids))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::FaceId;
    use crate::quads::surface_mesh::SurfacePoint;

    /// A row of `n` unit squares (vertex `2i` at `(i, 0)`, `2i + 1` at
    /// `(i, 1)`) with a free triangle on each end, apexes at `x = −1` and
    /// `x = n + 1`: area `n + 1`.
    fn strip_of_squares(n: u32) -> (SurfaceVertices, Vec<Element>) {
        let mut v = SurfaceVertices::default();
        let s = SurfacePoint { face: FaceId(0), bary: [1.0, 0.0, 0.0] };
        for i in 0..=n {
            v.push(Vec3::new(f64::from(i), 0.0, 0.0), s, ModelEntity::Face(0));
            v.push(Vec3::new(f64::from(i), 1.0, 0.0), s, ModelEntity::Face(0));
        }
        let left = v.push(Vec3::new(-1.0, 0.5, 0.0), s, ModelEntity::Face(0));
        let right = v.push(Vec3::new(f64::from(n) + 1.0, 0.5, 0.0), s, ModelEntity::Face(0));
        let mut elements = vec![Element::Triangle([left, 0, 1])];
        elements.extend((0..n).map(|i| Element::Quad([2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1])));
        elements.push(Element::Triangle([2 * n, right, 2 * n + 1]));
        (v, elements)
    }

    /// Signed area of the polygon `c` in the plane z = 0.
    fn area(c: &[u32], p: &[Vec3]) -> f64 {
        let n = c.len();
        (0..n)
            .map(|i| {
                p[c[i] as usize].x * p[c[(i + 1) % n] as usize].y - p[c[(i + 1) % n] as usize].x * p[c[i] as usize].y
            })
            .sum::<f64>()
            / 2.0
    }

    #[test]
    fn two_free_triangles_are_joined_through_the_squares_between_them() {
        let n = 4;
        let (mut v, elements) = strip_of_squares(n);
        let faces = vec![0; elements.len()];
        let (out, out_faces, stats) = join_free_triangles(&mut v, &elements, &faces, &[]);
        assert_eq!(stats, StripStats { n_pairs_joined: 1, n_quads_split: n as usize, n_strips_undone: 0 });
        assert_eq!(out_faces, vec![0; out.len()]);
        // Each end triangle becomes a quad, each square two quads.
        assert_eq!(out.len(), 2 + 2 * n as usize);
        assert!(out.iter().all(|e| matches!(e, Element::Quad(_))), "{out:?}");
        let normal = Vec3::z();
        let mut total = 0.0;
        for e in &out {
            let Element::Quad(q) = e else { unreachable!() };
            let sj = scaled_jacobian(&q.map(|w| v.positions[w as usize]), &normal);
            assert!(sj > MIN_SCALED_JACOBIAN, "quad {q:?} scaled Jacobian {sj}");
            total += area(q, &v.positions);
        }
        assert!((total - f64::from(n + 1)).abs() < 1e-12, "area {total}");
        // Conforming: every edge in one element (the outline) or two.
        let mut count: HashMap<(u32, u32), usize> = HashMap::new();
        for e in &out {
            let c = e.corners();
            for k in 0..c.len() {
                *count.entry(key(c[k], c[(k + 1) % c.len()])).or_default() += 1;
            }
        }
        assert!(count.values().all(|&c| c <= 2));
        assert_eq!(count.values().filter(|&&c| c == 1).count(), 2 * n as usize + 4, "outline edges");
    }

    #[test]
    fn a_curve_edge_is_never_crossed_and_the_triangles_stay() {
        let (mut v, elements) = strip_of_squares(3);
        let faces = vec![0; elements.len()];
        let before = v.len();
        // The edge 2–3 (x = 1) is on a curve: no path joins the ends.
        let (out, _, stats) = join_free_triangles(&mut v, &elements, &faces, &[(0, [2, 3])]);
        assert_eq!(stats.n_pairs_joined, 0);
        assert_eq!(out, elements);
        assert_eq!(v.len(), before);
    }

    #[test]
    fn every_midpoint_of_a_strip_is_served_by_a_cut_when_one_quad_is_crossed_straight() {
        assert_eq!(cuts(&[]), None, "two adjacent triangles: their midpoint stays flat");
        assert_eq!(cuts(&[false, false]), None);
        assert_eq!(cuts(&[true]), Some(vec![0]));
        // Quads between midpoints (0, 1), (1, 2), (2, 3): the straight one
        // serves 1 and 2, the last serves 3.
        assert_eq!(cuts(&[false, true, false]), Some(vec![0, 1, 3]));
        assert_eq!(cuts(&[false, false, true]), Some(vec![0, 1, 2]));
    }
}
