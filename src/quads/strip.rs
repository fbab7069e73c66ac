//! Triangles the matching left free, joined in pairs through a strip of
//! split quads, so a face with a few free triangles becomes all-quad at the
//! size asked for instead of being midpoint-subdivided whole.
//!
//! For two free triangles `t₁`, `t₂` of one model face, the shortest path
//! of elements `t₁, q₁, …, q_k, t₂` (`k ≥ 1`) across non-curve edges
//! (breadth first over element and entry edge, in element and corner
//! order) is split at the midpoint of every edge it crosses:
//! - `t₁` and `t₂` gain one midpoint on one edge: each becomes a quad;
//! - each `qᵢ` gains two midpoints ([`split_crossed_quad`]): crossed
//!   between opposite edges, it is cut in two between them; crossed
//!   between adjacent edges (a turn), it becomes three quads around a new
//!   vertex joined to both midpoints and to the corner opposite the turn.
//!   Either way each midpoint ends an edge into the quad, so a midpoint
//!   between two quads of the strip is no flat corner; an end triangle's
//!   midpoint is one in its quad until relaxing moves it off the edge
//!   (the quad becomes a kite).
//!
//! Every split element keeps its orientation and its neighbours across the
//! split edges are the path's own elements, so the mesh stays conforming.
//! The midpoints are then relaxed to their neighbours' centroid; a strip
//! that still has a quad at or below [`MIN_SCALED_JACOBIAN`] is undone and
//! its triangles look for another route, around the quads it crossed, in
//! the next round. From round [`RESCUE_ROUND`] on, such a strip is first
//! relaxed again from its split with guarded moves ([`Relax::Guarded`]),
//! and a triangle with no route around closed quads may take one through
//! them. A kept strip's quads are open to later strips; strips are undone
//! in reverse order, each restoring the slots it took. A triangle that
//! still has no partner after [`STRIP_ROUNDS`] rounds (odd count, or no
//! valid route) is left free for subdivision
//! ([`super::transition::subdivide_alone`]). The midpoints' irregular
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
    /// below the scaled Jacobian floor after relaxing (their triangles are
    /// left to subdivision).
    pub n_strips_undone: usize,
}

/// The elements with an index of their edges.
pub(super) struct Elements<'a> {
    pub(super) elements: Vec<Option<(Element, u32)>>,
    /// Elements made by a strip of the round (not crossed by the round's
    /// later strips, so a strip can be undone alone).
    frozen: Vec<bool>,
    /// Quads an undone strip crossed: its triangles route around them.
    closed: Vec<bool>,
    pub(super) by_edge: HashMap<(u32, u32), Vec<usize>>,
    curve: &'a HashSet<(u32, u32)>,
}

/// The edge `a b` as a key.
pub(super) fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

impl<'a> Elements<'a> {
    pub(super) fn new(elements: &[Element], faces: &[u32], curve: &'a HashSet<(u32, u32)>) -> Self {
        let mut out = Self {
            elements: Vec::with_capacity(elements.len()),
            frozen: Vec::new(),
            closed: Vec::new(),
            by_edge: HashMap::new(),
            curve,
        };
        for (e, &f) in elements.iter().zip(faces) {
            out.add(*e, f);
        }
        out
    }

    /// Appends `element` of model face `face`.
    pub(super) fn add(&mut self, element: Element, face: u32) -> usize {
        let i = self.elements.len();
        self.frozen.push(false);
        self.closed.push(false);
        self.elements.push(None);
        self.restore(i, element, face);
        i
    }

    /// Puts `element` of model face `face` in the empty slot `i`.
    fn restore(&mut self, i: usize, element: Element, face: u32) {
        let c = element.corners();
        for k in 0..c.len() {
            self.by_edge.entry(key(c[k], c[(k + 1) % c.len()])).or_default().push(i);
        }
        self.elements[i] = Some((element, face));
    }

    /// Removes element `i`.
    pub(super) fn remove(&mut self, i: usize) {
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
    /// made by a strip of the round (nor closed by an undone strip unless
    /// `reopen`), crossing at least one quad, with no element twice; with
    /// the edge crossed into each element after the first.
    fn path_to_free_triangle(&self, from: usize, reopen: bool) -> Option<Vec<(usize, (u32, u32))>> {
        let (_, face) = self.elements[from]?;
        let start = Step { element: from, entry: NO_ENTRY };
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
                for &n in self.by_edge.get(&edge).into_iter().flatten() {
                    let Some((other, f)) = self.elements[n] else { continue };
                    if n == step.element || f != face || self.frozen[n] || (self.closed[n] && !reopen) {
                        continue;
                    }
                    let oc = other.corners();
                    let entry = (0..oc.len()).find(|&j| key(oc[j], oc[(j + 1) % oc.len()]) == edge).unwrap_or(NO_ENTRY);
                    let next = Step { element: n, entry };
                    if next.element == from || parent.contains_key(&next) {
                        continue;
                    }
                    parent.insert(next, (step, edge));
                    match other {
                        Element::Triangle(_) if step.element != from => {
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
/// was entered by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) struct Step {
    pub(super) element: usize,
    pub(super) entry: usize,
}

/// The path from `start` to `end` in the search's `parent` links:
/// `(element, edge crossed into it)`, the first element with a dummy edge.
pub(super) fn unwind(parent: &HashMap<Step, (Step, (u32, u32))>, start: Step, end: Step) -> Vec<(usize, (u32, u32))> {
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
pub(super) fn insert_midpoint(corners: &[u32], edge: (u32, u32), mid: u32) -> Vec<u32> {
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

/// The quads of a strip's quad `h` (a hexagon: its four corners and the
/// midpoints `m` of the two edges the strip crosses): crossed between
/// opposite edges, the two quads on either side of the cut between the
/// midpoints; crossed between adjacent edges (a turn), three quads around a
/// new vertex at the corners' centroid (appended to `extra`), joined to both
/// midpoints and to the corner opposite the turn. Either way each midpoint
/// ends an edge into the quad, so no midpoint is left a flat corner.
pub(super) fn split_crossed_quad(
    vertices: &mut SurfaceVertices,
    h: &[u32],
    m: [u32; 2],
    face: u32,
    extra: &mut Vec<u32>,
) -> Vec<[u32; 4]> {
    let at = |v: u32| h.iter().position(|&w| w == v).unwrap_or(0);
    let (i, j) = (at(m[0]), at(m[1]));
    let q = |s: usize| [h[s % 6], h[(s + 1) % 6], h[(s + 2) % 6], h[(s + 3) % 6]];
    if (i + 3) % 6 == j {
        return vec![q(i), q(j)];
    }
    // The turn: `a` the midpoint after which the corner between both comes.
    let a = if (i + 2) % 6 == j { i } else { j };
    let corners: Vec<u32> = h.iter().copied().filter(|v| !m.contains(v)).collect();
    let x = push_mean_vertex(vertices, &corners, ModelEntity::Face(face));
    extra.push(x);
    let v = |s: usize| h[(a + s) % 6];
    vec![[v(0), v(1), v(2), x], [v(2), v(3), v(4), x], [v(4), v(5), v(0), x]]
}

/// Unit normal of the polygon `corners` (Newell's formula), `+z` if degenerate.
pub(super) fn polygon_normal(corners: &[u32], positions: &[Vec3]) -> Vec3 {
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
pub(super) const MIN_SCALED_JACOBIAN: f64 = 0.05;

/// Rounds of strip joining: a strip left invalid by relaxing is undone and
/// the quads it crossed are closed to later strips, so its two triangles
/// look for another route in the next round.
const STRIP_ROUNDS: usize = 6;

/// The first round whose folded strips are relaxed again under guard
/// before being undone, and whose triangles may route through closed quads
/// when there is no way around them. Earlier rounds only reroute: a route
/// that relaxes freely gives cleanup evener quads than a rescued one.
const RESCUE_ROUND: usize = 2;

/// Joins the free triangles of `elements` (model faces `faces`) in pairs
/// (module doc), appending the midpoints to `vertices`. Returns the new
/// elements and faces. A strip that relaxing leaves invalid is undone alone
/// and its triangles try another route (up to [`STRIP_ROUNDS`] rounds);
/// triangles still free after that are left for subdivision (midpoints of
/// undone strips are left unused: cleanup drops vertices in no quad).
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
    for round in 0..STRIP_ROUNDS {
        let made = strip_round(&mut work, vertices, round >= RESCUE_ROUND);
        if made.is_empty() {
            break;
        }
        let strips: Vec<&Strip> = kept.iter().chain(&made).collect();
        let mids: Vec<u32> = made.iter().flat_map(|s| s.mids.iter().map(|&(m, _)| m)).collect();
        relax_midpoints(&work, vertices, &mids, &strips, Relax::Free);
        let (mut valid, mut invalid): (Vec<Strip>, Vec<Strip>) =
            made.into_iter().partition(|s| s.is_valid(&work, vertices));
        // From round `RESCUE_ROUND` on, a strip relaxing folds is relaxed
        // again from its split, each move kept only when its quads' worst
        // does not drop; before, it is undone and its triangles look for
        // another route (which cleanup takes better when there is one).
        if round >= RESCUE_ROUND && !invalid.is_empty() {
            for &(m, at) in invalid.iter().flat_map(|s| &s.mids) {
                vertices.positions[m as usize] = at;
            }
            let strips: Vec<&Strip> = kept.iter().chain(&valid).chain(&invalid).collect();
            let mids: Vec<u32> = invalid.iter().flat_map(|s| s.mids.iter().map(|&(m, _)| m)).collect();
            relax_midpoints(&work, vertices, &mids, &strips, Relax::Guarded);
            let rescued;
            (rescued, invalid) = invalid.into_iter().partition(|s| s.is_valid(&work, vertices));
            valid.extend(rescued);
        }
        kept.extend(valid);
        // A kept strip's quads are open to later strips (undone in
        // reverse order, each restores its own slots).
        for strip in &kept {
            for &(e, _) in &strip.made {
                work.frozen[e] = false;
            }
        }
        for strip in invalid.iter().rev() {
            strip.undo(&mut work);
            // Closed to later strips: the next round routes around them.
            for &i in &strip.path[1..strip.path.len() - 1] {
                work.closed[i] = true;
            }
            stats.n_strips_undone += 1;
        }
    }
    // A face where a strip stays invalid has all its strips undone (a later
    // strip of the face may have split the invalid one's quads). Triangles
    // left free are split by subdivision, alone where it can.
    let n_faces = faces.iter().map(|&f| f as usize + 1).max().unwrap_or(0);
    let mut refused = vec![false; n_faces];
    for strip in &kept {
        if !strip.is_valid(&work, vertices) {
            refused[strip.face() as usize] = true;
        }
    }
    for strip in kept.iter().rev() {
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
/// joined with the nearest free triangle a strip can reach (through closed
/// quads when `reopen` and there is no way around them); the strips made.
fn strip_round(work: &mut Elements, vertices: &mut SurfaceVertices, reopen: bool) -> Vec<Strip> {
    let free: Vec<usize> = (0..work.elements.len())
        .filter(|&i| matches!(work.elements[i], Some((Element::Triangle(_), _))) && !work.frozen[i])
        .collect();
    let mut made = Vec::new();
    for t in free {
        if !matches!(work.elements[t], Some((Element::Triangle(_), _))) {
            continue;
        }
        let path = work.path_to_free_triangle(t, false);
        let Some(path) = path.or_else(|| if reopen { work.path_to_free_triangle(t, true) } else { None }) else {
            continue;
        };
        let originals: Vec<(Element, u32)> = path.iter().filter_map(|&(e, _)| work.elements[e]).collect();
        let Some((new_elements, new_mids)) = split_strip(work, vertices, &path) else { continue };
        let mids = new_mids.into_iter().map(|m| (m, vertices.positions[m as usize])).collect();
        made.push(Strip { path: path.iter().map(|&(e, _)| e).collect(), originals, made: new_elements, mids });
    }
    made
}

/// A strip that was split: the elements it replaced and the ones it made
/// (each with the normal of the element it came from).
pub(super) struct Strip {
    /// The slots of the elements it replaced, in path order.
    pub(super) path: Vec<usize>,
    pub(super) originals: Vec<(Element, u32)>,
    pub(super) made: Vec<(usize, Vec3)>,
    /// The vertices it added, with their position when split.
    pub(super) mids: Vec<(u32, Vec3)>,
}

impl Strip {
    /// The model face of the strip.
    fn face(&self) -> u32 {
        self.originals[0].1
    }

    /// Whether every quad the strip made is above [`MIN_SCALED_JACOBIAN`]
    /// against the normal of the element it came from.
    pub(super) fn is_valid(&self, work: &Elements, vertices: &SurfaceVertices) -> bool {
        self.made.iter().all(|(e, normal)| match work.elements[*e] {
            Some((Element::Quad(q), _)) => {
                scaled_jacobian(&q.map(|v| vertices.positions[v as usize]), normal) > MIN_SCALED_JACOBIAN
            }
            _ => true,
        })
    }

    /// Replaces the strip's elements by the ones it split, in their own
    /// slots (so strips undone in reverse order of making restore a
    /// consistent mesh even where a later strip split an earlier one's
    /// quads).
    pub(super) fn undo(&self, work: &mut Elements) {
        for (e, _) in &self.made {
            work.remove(*e);
        }
        for (&i, &(element, face)) in self.path.iter().zip(&self.originals) {
            work.restore(i, element, face);
        }
    }
}

/// How [`relax_midpoints`] takes a move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Relax {
    /// Every move to the centroid: the evenest strips, which later cleanup
    /// and cavity remeshing take best.
    Free,
    /// A move kept only when it does not lower the worst scaled Jacobian of
    /// the strips' quads around the midpoint (each against the normal of
    /// the element it came from), else tried at half the step. Freely, the
    /// centroid of a midpoint on a curved, uneven surface can fold a quad
    /// of its strip (bunny's strips went from valid splits to −0.7).
    Guarded,
}

/// Moves each midpoint of `mids` toward the centroid of its edge
/// neighbours in the quads `strips` made, [`RELAX_SWEEPS`] times in order,
/// as `relax` allows. Positions only: the smoothing step projects every
/// vertex onto the surface.
pub(super) fn relax_midpoints(
    work: &Elements,
    vertices: &mut SurfaceVertices,
    mids: &[u32],
    strips: &[&Strip],
    relax: Relax,
) {
    // Every element at a midpoint is a quad one of `strips` made (the
    // elements on both sides of a crossed edge are the strip's own).
    let wanted: HashSet<u32> = mids.iter().copied().collect();
    let mut around: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut quads_at: HashMap<u32, Vec<([u32; 4], Vec3)>> = HashMap::new();
    for strip in strips {
        for &(e, normal) in &strip.made {
            let Some((Element::Quad(q), _)) = work.elements[e] else { continue };
            for k in 0..4 {
                if wanted.contains(&q[k]) {
                    around.entry(q[k]).or_default().extend([q[(k + 3) % 4], q[(k + 1) % 4]]);
                    quads_at.entry(q[k]).or_default().push((q, normal));
                }
            }
        }
    }
    for list in around.values_mut() {
        list.sort_unstable();
        list.dedup();
    }
    for _ in 0..RELAX_SWEEPS {
        for &m in mids {
            let Some(list) = around.get(&m) else { continue };
            let p = &vertices.positions;
            let target = list.iter().fold(Vec3::zeros(), |acc, &w| acc + p[w as usize]) / list.len() as f64;
            let quads = quads_at.get(&m).map_or(&[][..], Vec::as_slice);
            let worst = |at: Vec3| {
                quads.iter().fold(f64::INFINITY, |acc, (q, normal)| {
                    let corners = q.map(|v| if v == m { at } else { p[v as usize] });
                    acc.min(scaled_jacobian(&corners, normal))
                })
            };
            let here = p[m as usize];
            let half = (here + target) / 2.0;
            let to = match relax {
                Relax::Free => Some(target),
                Relax::Guarded => {
                    let before = worst(here);
                    [target, half].into_iter().find(|&at| worst(at) >= before)
                }
            };
            if let Some(at) = to {
                vertices.positions[m as usize] = at;
            }
        }
    }
}

/// What splitting a strip made: the new elements, each with the normal of
/// the element it came from, and the midpoints (with the vertices of the
/// turns' splits, to be relaxed alike).
type SplitStrip = (Vec<(usize, Vec3)>, Vec<u32>);

/// Splits the elements of `path` (a free triangle, at least one quad, a
/// free triangle) at the midpoints of the edges it crosses. Returns the new
/// elements, each with the normal of the element it came from, and the new
/// vertices; `None` for a path without a quad.
fn split_strip(
    work: &mut Elements,
    vertices: &mut SurfaceVertices,
    path: &[(usize, (u32, u32))],
) -> Option<SplitStrip> {
    if path.len() < 3 {
        return None;
    }
    let face = work.elements[path[0].0].map_or(0, |(_, f)| f);
    let mut mids: Vec<u32> =
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
        let quads = if corners.len() == 6 {
            split_crossed_quad(vertices, &corners, [mids[i - 1], mids[i]], face, &mut mids)
        } else {
            vec![[corners[0], corners[1], corners[2], corners[3]]]
        };
        for q in quads {
            made.push((work.add(Element::Quad(q), face), normal));
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
    fn a_strip_that_turns_in_a_quad_splits_it_into_three_around_a_new_vertex() {
        // The unit square with a free triangle on its left edge (apex
        // (−1, ½)) and one on its top edge (apex (½, 2)): the strip enters
        // and leaves the square by adjacent edges.
        let mut v = SurfaceVertices::default();
        let s = SurfacePoint { face: FaceId(0), bary: [1.0, 0.0, 0.0] };
        for (x, y) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (-1.0, 0.5), (0.5, 2.0)] {
            v.push(Vec3::new(x, y, 0.0), s, ModelEntity::Face(0));
        }
        let elements = vec![Element::Triangle([4, 0, 3]), Element::Quad([0, 1, 2, 3]), Element::Triangle([3, 2, 5])];
        let (out, _, stats) = join_free_triangles(&mut v, &elements, &[0, 0, 0], &[]);
        assert_eq!(stats, StripStats { n_pairs_joined: 1, n_quads_split: 1, n_strips_undone: 0 });
        // Two end quads, three in the square; two midpoints and the new vertex.
        assert_eq!(out.len(), 5, "{out:?}");
        assert_eq!(v.len(), 9);
        let mut total = 0.0;
        for e in &out {
            let Element::Quad(q) = e else { panic!("a triangle is left: {out:?}") };
            let sj = scaled_jacobian(&q.map(|w| v.positions[w as usize]), &Vec3::z());
            assert!(sj > MIN_SCALED_JACOBIAN, "quad {q:?} scaled Jacobian {sj}");
            total += area(q, &v.positions);
        }
        assert!((total - 2.0).abs() < 1e-12, "area {total}");
    }
}
