//! Triangles left free by recombination, midpoint-subdivided alone instead
//! of with their model face and every face around it.
//!
//! A free triangle is split into three quads at its edge midpoints and
//! centroid. An edge it shares with an element that is not split is then
//! split on the triangle's side only: its midpoint hangs on the quad across
//! it. Each hanging midpoint is joined to another one, or to an open
//! boundary edge split at its middle, through a strip of quads split at the
//! midpoints of the edges it crosses ([`super::strip::split_crossed_quad`]):
//! every quad of the strip gains two midpoints and becomes two quads (three
//! around a new vertex where the strip turns), so a hanging midpoint ends
//! an edge into the quad and is no flat corner. A triangle has three edges,
//! so the count of hanging midpoints has the parity of the count of free
//! triangles. The shortest strip (breadth first over quad and entry edge,
//! straight on first, in element and corner order) may cross feature
//! curves: the midpoint of a crossed curve edge is classified on the curve,
//! and every split curve edge is replaced by its halves in curve order.
//!
//! Midpoints on curves stay on the curve's chord (the smoothing step
//! projects them onto the curve); the others are relaxed like the strips of
//! [`super::strip`], freely, then under guard if a quad folded. A strip
//! still folded is undone and another route sought, leaving its quads by
//! other edges (up to [`ROUTE_ATTEMPTS`]); if none is valid, the shortest
//! is kept and every strip relaxed again together at the end. A hanging
//! midpoint with no route, or a strip still folded, leaves the elements to
//! the caller's wider subdivision, with `vertices` and the curve edges as
//! they were.
//!
//! On the corpus the triangles left free are in tiny faces of two to four
//! triangles between curves (a non-convex pair, or no valid strip inside
//! them) or walled in by strips in a large face; subdividing their faces
//! with every face sharing an edge with them halved the size of every quad
//! of the part.

use std::collections::{HashMap, HashSet, VecDeque};

use super::jacobian::scaled_jacobian;
use super::strip::{
    Elements, MIN_SCALED_JACOBIAN, Relax, Step, Strip, insert_midpoint, key, polygon_normal, relax_midpoints,
    split_crossed_quad, unwind,
};
use super::subdivision::{Element, Subdivided, push_mean_vertex, subdivide};
use super::surface_mesh::{CurveEdge, ModelEntity, SurfaceVertices};
use crate::geom::Vec3;

/// The flagged elements subdivided alone and the hanging midpoints joined.
#[derive(Debug, Clone, Default)]
pub struct SubdividedAlone {
    /// The quads.
    pub quads: Vec<[u32; 4]>,
    /// Model face of each quad.
    pub faces: Vec<u32>,
    /// Quads made by the subdivision of the flagged elements.
    pub n_subdivision_quads: usize,
    /// Strips joining hanging midpoints.
    pub n_strips: usize,
    /// Quads the strips split.
    pub n_quads_split: usize,
}

/// Subdivides the elements of `elements` (model faces `face_per_element`)
/// flagged in `split` alone (module doc): the others are kept, but for the
/// strips that join the midpoints the subdivision leaves hanging on them.
/// Unflagged triangles are dropped (the caller flags every triangle).
/// `None`, with `vertices` and `curve_edges` unchanged, when a hanging
/// midpoint has no route or a strip stays folded.
pub fn subdivide_alone(
    vertices: &mut SurfaceVertices,
    elements: &[Element],
    face_per_element: &[u32],
    split: &[bool],
    curve_edges: &mut Vec<CurveEdge>,
) -> Option<SubdividedAlone> {
    let n_vertices = vertices.len();
    let curve_edges_before = curve_edges.clone();
    let subdivided = subdivide(vertices, elements, face_per_element, split, curve_edges);
    let joined = join_hanging_midpoints(vertices, subdivided, curve_edges);
    if joined.is_none() {
        vertices.truncate(n_vertices);
        *curve_edges = curve_edges_before;
    }
    joined
}

/// Joins the midpoints of `subdivided.midpoints` whose edge is still
/// whole in a quad that was not split, in pairs or to open boundary edges
/// (module doc); splits the curve edges the strips cross or end at.
fn join_hanging_midpoints(
    vertices: &mut SurfaceVertices,
    subdivided: Subdivided,
    curve_edges: &mut Vec<CurveEdge>,
) -> Option<SubdividedAlone> {
    let Subdivided { quads, faces, n_subdivision_quads, midpoints } = subdivided;
    let mut curves = CurveSplits::new(curve_edges);
    let curve: HashSet<(u32, u32)> = curves.curve_of.keys().copied().collect();
    let elements: Vec<Element> = quads.iter().map(|&q| Element::Quad(q)).collect();
    let mut work = Elements::new(&elements, &faces, &curve);
    let mut hanging: HashMap<(u32, u32), u32> =
        midpoints.into_iter().filter(|(edge, _)| work.by_edge.get(edge).is_some_and(|l| !l.is_empty())).collect();
    let mut order: Vec<(u32, u32)> = hanging.keys().copied().collect();
    order.sort_unstable();
    // The subdivided side's halves of a hanging edge: alone in their quad
    // until the strip splits the quad across, but no open boundary.
    let halves: HashSet<(u32, u32)> = hanging.iter().flat_map(|(&(a, b), &m)| [key(a, m), key(m, b)]).collect();
    let mut out = SubdividedAlone { n_subdivision_quads, ..SubdividedAlone::default() };
    let mut strips: Vec<TransitionStrip> = Vec::new();
    let mut folded = false;
    for edge in order {
        let Some(start) = hanging.remove(&edge) else { continue };
        // A route whose strip stays folded is undone, and the next search
        // may not leave its quads by the edges it left them by.
        let mut blocked: HashSet<(usize, (u32, u32))> = HashSet::new();
        let mut joined = false;
        for _ in 0..ROUTE_ATTEMPTS {
            let Some(route) = route_from_hanging_edge(&work, edge, &hanging, &curves.curve_of, &halves, &blocked)
            else {
                break;
            };
            let n_splits = curves.log.len();
            let (end, was_hanging) = match hanging.remove(&route.exit) {
                Some(m) => (m, true),
                None => (curves.split(vertices, route.exit)?, false),
            };
            let strip = split_route(&mut work, vertices, &route, [start, end], &mut curves);
            if relax_until_valid(&work, vertices, &strip) {
                out.n_quads_split += route.quads.len();
                strips.push(strip);
                joined = true;
                break;
            }
            strip.strip.undo(&mut work);
            curves.undo_to(n_splits);
            if was_hanging {
                hanging.insert(route.exit, end);
            }
            let exits = route.quads[1..].iter().map(|q| q.1).chain([route.exit]);
            blocked.extend(route.quads.iter().map(|q| q.0).zip(exits));
        }
        if !joined {
            // The shortest route again, kept folded: relaxing every strip
            // together below may still open it.
            let route = route_from_hanging_edge(&work, edge, &hanging, &curves.curve_of, &halves, &HashSet::new())?;
            let end = match hanging.remove(&route.exit) {
                Some(m) => m,
                None => curves.split(vertices, route.exit)?,
            };
            out.n_quads_split += route.quads.len();
            strips.push(split_route(&mut work, vertices, &route, [start, end], &mut curves));
            folded = true;
        }
    }
    out.n_strips = strips.len();
    // A later strip only splits an earlier one's quads and moves its own
    // midpoints, so a strip relaxed valid stays so. A folded one is opened,
    // if it can be, by relaxing all of them together, freely, then from
    // their split positions under guard.
    if folded && !relax_together(&work, vertices, &strips) {
        return None;
    }
    *curve_edges = curve_edges.iter().flat_map(|&edge| curves.halves(edge)).collect();
    for (element, face) in work.elements.into_iter().flatten() {
        let Element::Quad(q) = element else { return None };
        out.quads.push(q);
        out.faces.push(face);
    }
    Some(out)
}

/// Routes tried for one hanging midpoint before the shortest is kept
/// folded, for the joint relax.
const ROUTE_ATTEMPTS: usize = 4;

/// The curve edges, and those the strips split.
struct CurveSplits {
    /// The curve of each curve edge (the halves of split ones included).
    curve_of: HashMap<(u32, u32), u32>,
    /// The midpoint of each curve edge a strip split.
    midpoint: HashMap<(u32, u32), u32>,
    /// The edges split, in order (so an undone strip's splits can be
    /// forgotten).
    log: Vec<(u32, u32)>,
}

impl CurveSplits {
    fn new(curve_edges: &[CurveEdge]) -> Self {
        let curve_of = curve_edges.iter().map(|&(c, [a, b])| (key(a, b), c)).collect();
        Self { curve_of, midpoint: HashMap::new(), log: Vec::new() }
    }

    /// Forgets the splits after the first `n` (their halves stay in
    /// `curve_of`: no element has those edges any more).
    fn undo_to(&mut self, n: usize) {
        for edge in self.log.drain(n..) {
            self.midpoint.remove(&edge);
        }
    }

    /// Splits the curve edge `edge` at a new midpoint classified on its
    /// curve; `None` if it is on no curve.
    fn split(&mut self, vertices: &mut SurfaceVertices, edge: (u32, u32)) -> Option<u32> {
        let &c = self.curve_of.get(&edge)?;
        let (a, b) = edge;
        let m = push_mean_vertex(vertices, &[a, b], ModelEntity::Curve(c));
        self.midpoint.insert(edge, m);
        self.log.push(edge);
        self.curve_of.insert(key(a, m), c);
        self.curve_of.insert(key(m, b), c);
        Some(m)
    }

    /// The curve edge `(c, [a, b])` as the edges its splits left, in curve
    /// order (a half split again by a later strip is expanded too).
    fn halves(&self, (c, [a, b]): CurveEdge) -> Vec<CurveEdge> {
        match self.midpoint.get(&key(a, b)) {
            Some(&m) => {
                let mut out = self.halves((c, [a, m]));
                out.extend(self.halves((c, [m, b])));
                out
            }
            None => vec![(c, [a, b])],
        }
    }
}

/// How much lower than its parent a split quad's scaled Jacobian may be:
/// a parent with a flat corner (three points of a straight curve) passes
/// the corner, exactly as flat up to rounding, to one of its quads.
const FLAT_TOLERANCE: f64 = 1e-6;

/// A strip that joins a hanging midpoint, with the scaled Jacobian of the
/// quad each of its quads was split from.
struct TransitionStrip {
    strip: Strip,
    parent_scaled_jacobian: Vec<f64>,
}

impl TransitionStrip {
    /// Whether each quad the strip made (and no later strip split) is above
    /// [`MIN_SCALED_JACOBIAN`] or no worse than the quad it was split from,
    /// each against that quad's normal. Next to the tiny faces, matching
    /// leaves quads with a flat corner on the curve (poor pairs the later
    /// steps open); the strip's quads there keep that corner, and refusing
    /// them sent every such part back to whole-component subdivision.
    fn is_valid(&self, work: &Elements, vertices: &SurfaceVertices) -> bool {
        self.strip.made.iter().zip(&self.parent_scaled_jacobian).all(|((e, normal), &parent)| match work.elements[*e] {
            Some((Element::Quad(q), _)) => {
                let sj = scaled_jacobian(&q.map(|v| vertices.positions[v as usize]), normal);
                sj > MIN_SCALED_JACOBIAN || sj >= parent - FLAT_TOLERANCE
            }
            _ => true,
        })
    }
}

/// Relaxes the strip's midpoints off curves freely; if a quad folds, again
/// from the split positions under guard. Whether it ends valid.
fn relax_until_valid(work: &Elements, vertices: &mut SurfaceVertices, strip: &TransitionStrip) -> bool {
    let mids: Vec<u32> = strip.strip.mids.iter().map(|&(m, _)| m).collect();
    relax_midpoints(work, vertices, &mids, &[&strip.strip], Relax::Free);
    if strip.is_valid(work, vertices) {
        return true;
    }
    for &(m, at) in &strip.strip.mids {
        vertices.positions[m as usize] = at;
    }
    relax_midpoints(work, vertices, &mids, &[&strip.strip], Relax::Guarded);
    strip.is_valid(work, vertices)
}

/// [`relax_until_valid`] for all `strips` together, each midpoint moving
/// toward the centroid of its neighbours in any of their quads.
fn relax_together(work: &Elements, vertices: &mut SurfaceVertices, strips: &[TransitionStrip]) -> bool {
    let all: Vec<&Strip> = strips.iter().map(|s| &s.strip).collect();
    let mids: Vec<u32> = all.iter().flat_map(|s| s.mids.iter().map(|&(m, _)| m)).collect();
    relax_midpoints(work, vertices, &mids, &all, Relax::Free);
    if strips.iter().all(|s| s.is_valid(work, vertices)) {
        return true;
    }
    for &(m, at) in all.iter().flat_map(|s| &s.mids) {
        vertices.positions[m as usize] = at;
    }
    relax_midpoints(work, vertices, &mids, &all, Relax::Guarded);
    strips.iter().all(|s| s.is_valid(work, vertices))
}

/// A strip's route: the quads crossed, each with the edge it is entered by
/// (the first by the hanging edge), and the edge the last one is left by.
struct Route {
    quads: Vec<(usize, (u32, u32))>,
    exit: (u32, u32),
}

/// The shortest route of quads from the one holding the hanging edge
/// `from` to an edge that is hanging (in `hanging`) or an open boundary
/// edge on a curve (not one of the subdivided side's `halves` of a hanging
/// edge), crossing any edge between two quads, with no quad twice, and
/// leaving no quad by an edge `blocked` pairs with it.
fn route_from_hanging_edge(
    work: &Elements,
    from: (u32, u32),
    hanging: &HashMap<(u32, u32), u32>,
    curve_of: &HashMap<(u32, u32), u32>,
    halves: &HashSet<(u32, u32)>,
    blocked: &HashSet<(usize, (u32, u32))>,
) -> Option<Route> {
    let edge_slot = |c: &[u32], edge: (u32, u32)| (0..c.len()).find(|&j| key(c[j], c[(j + 1) % c.len()]) == edge);
    let &first = work.by_edge.get(&from)?.first()?;
    let (element, _) = work.elements[first]?;
    let start = Step { element: first, entry: edge_slot(element.corners(), from)? };
    let mut parent: HashMap<Step, (Step, (u32, u32))> = HashMap::new();
    let mut queue = VecDeque::from([start]);
    while let Some(step) = queue.pop_front() {
        let Some((Element::Quad(c), _)) = work.elements[step.element] else { continue };
        // Straight on first: a strip that does not turn adds no vertex.
        for k in [2, 1, 3].map(|d| (step.entry + d) % 4) {
            let edge = key(c[k], c[(k + 1) % 4]);
            if blocked.contains(&(step.element, edge)) {
                continue;
            }
            let across = work.by_edge.get(&edge).map_or(&[][..], Vec::as_slice);
            let open = across.len() == 1 && curve_of.contains_key(&edge) && !halves.contains(&edge);
            if hanging.contains_key(&edge) || open {
                let mut quads = unwind(&parent, start, step);
                quads[0].1 = from;
                let mut seen: Vec<usize> = quads.iter().map(|q| q.0).collect();
                seen.sort_unstable();
                seen.dedup();
                if seen.len() == quads.len() {
                    return Some(Route { quads, exit: edge });
                }
                continue;
            }
            for &n in across {
                let Some((Element::Quad(other), _)) = work.elements[n] else { continue };
                if n == step.element {
                    continue;
                }
                let Some(entry) = edge_slot(&other, edge) else { continue };
                let next = Step { element: n, entry };
                if next != start && !parent.contains_key(&next) {
                    parent.insert(next, (step, edge));
                    queue.push_back(next);
                }
            }
        }
    }
    None
}

/// Splits the quads of `route` at the midpoints of the edges it crosses,
/// `ends` on its entry and exit edges: a new midpoint between two quads is
/// classified on the curve (and the split recorded in `curves`) when the
/// edge is a curve edge, else on the quads' face. Returns the strip, whose `mids`
/// are the vertices to relax (off curves: the face midpoints and the turns'
/// new vertices).
fn split_route(
    work: &mut Elements,
    vertices: &mut SurfaceVertices,
    route: &Route,
    ends: [u32; 2],
    curves: &mut CurveSplits,
) -> TransitionStrip {
    let mut relaxed: Vec<u32> = Vec::new();
    let mut parent_scaled_jacobian = Vec::new();
    let mut cut = vec![ends[0]];
    for &(element, (a, b)) in &route.quads[1..] {
        let face = work.elements[element].map_or(0, |(_, f)| f);
        let m = match curves.split(vertices, key(a, b)) {
            Some(m) => m,
            None => {
                let m = push_mean_vertex(vertices, &[a, b], ModelEntity::Face(face));
                relaxed.push(m);
                m
            }
        };
        cut.push(m);
    }
    cut.push(ends[1]);
    let exits: Vec<(u32, u32)> = route.quads[1..].iter().map(|q| q.1).chain([route.exit]).collect();
    let mut made = Vec::new();
    let mut originals = Vec::new();
    for (i, (&(e, entry), &exit)) in route.quads.iter().zip(&exits).enumerate() {
        let Some((element, face)) = work.elements[e] else { continue };
        originals.push((element, face));
        let normal: Vec3 = polygon_normal(element.corners(), &vertices.positions);
        let parent = match element {
            Element::Quad(q) => scaled_jacobian(&q.map(|v| vertices.positions[v as usize]), &normal),
            Element::Triangle(_) => f64::INFINITY,
        };
        let corners = insert_midpoint(&insert_midpoint(element.corners(), entry, cut[i]), exit, cut[i + 1]);
        work.remove(e);
        for q in split_crossed_quad(vertices, &corners, [cut[i], cut[i + 1]], face, &mut relaxed) {
            made.push((work.add(Element::Quad(q), face), normal));
            parent_scaled_jacobian.push(parent);
        }
    }
    let mids = relaxed.into_iter().map(|m| (m, vertices.positions[m as usize])).collect();
    let strip = Strip { path: route.quads.iter().map(|q| q.0).collect(), originals, made, mids };
    TransitionStrip { strip, parent_scaled_jacobian }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::FaceId;
    use crate::quads::surface_mesh::SurfacePoint;

    /// Vertices at the points `(x, y, 0)` of `xy`, classified by `entity`.
    fn vertices(xy: &[(f64, f64)], entity: impl Fn(usize) -> ModelEntity) -> SurfaceVertices {
        let mut v = SurfaceVertices::default();
        let s = SurfacePoint { face: FaceId(0), bary: [1.0, 0.0, 0.0] };
        for (i, &(x, y)) in xy.iter().enumerate() {
            v.push(Vec3::new(x, y, 0.0), s, entity(i));
        }
        v
    }

    /// Edge multiplicities of `quads`: every edge in one or two quads, the
    /// ones in one (the outline) counted.
    fn outline_edges(quads: &[[u32; 4]]) -> usize {
        let mut count: HashMap<(u32, u32), usize> = HashMap::new();
        for q in quads {
            for k in 0..4 {
                *count.entry(key(q[k], q[(k + 1) % 4])).or_default() += 1;
            }
        }
        assert!(count.values().all(|&c| c <= 2), "non-conforming: {count:?}");
        count.values().filter(|&&c| c == 1).count()
    }

    #[test]
    fn a_face_of_two_triangles_is_subdivided_alone_and_its_midpoints_joined_through_the_quads_around_it() {
        // A 4 × 4 square of unit quads (face 0) with the middle-bottom cell
        // replaced by the two triangles of face 1, bounded by curve 0.
        // Vertex (i, j) is 5 j + i.
        let xy: Vec<(f64, f64)> = (0..5).flat_map(|j| (0..5).map(move |i| (f64::from(i), f64::from(j)))).collect();
        let v = |i: u32, j: u32| 5 * j + i;
        let mut verts = vertices(&xy, |_| ModelEntity::Face(0));
        let mut elements = Vec::new();
        let mut faces = Vec::new();
        for j in 0..4 {
            for i in 0..4 {
                let c = [v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)];
                if (i, j) == (1, 1) {
                    elements.extend([Element::Triangle([c[0], c[1], c[2]]), Element::Triangle([c[0], c[2], c[3]])]);
                    faces.extend([1, 1]);
                } else {
                    elements.push(Element::Quad(c));
                    faces.push(0);
                }
            }
        }
        let ring = [v(1, 1), v(2, 1), v(2, 2), v(1, 2)];
        let mut curve_edges: Vec<CurveEdge> = (0..4).map(|k| (0, [ring[k], ring[(k + 1) % 4]])).collect();
        let split: Vec<bool> = elements.iter().map(|e| matches!(e, Element::Triangle(_))).collect();
        let before = verts.len();
        let out = subdivide_alone(&mut verts, &elements, &faces, &split, &mut curve_edges).expect("joined");
        // Two triangles → 6 quads; 4 hanging midpoints → 2 strips.
        assert_eq!(out.n_subdivision_quads, 6);
        assert_eq!(out.n_strips, 2, "{out:?}");
        assert_eq!(out.faces.iter().filter(|&&f| f == 1).count(), 6);
        // Each strip turns through the three quads around a corner of the
        // hole: 9 quads untouched, 6 split into 3 each.
        assert_eq!(out.n_quads_split, 6);
        assert_eq!(out.quads.len(), 6 + 9 + 18);
        // Still the outline of the 4 × 4 square, split nowhere on it.
        assert_eq!(outline_edges(&out.quads), 16);
        // Every curve edge is half of a ring edge, in order.
        assert_eq!(curve_edges.len(), 8);
        for q in &out.quads {
            let sj = scaled_jacobian(&q.map(|w| verts.positions[w as usize]), &Vec3::z());
            assert!(sj > MIN_SCALED_JACOBIAN, "quad {q:?} scaled Jacobian {sj}");
        }
        let area: f64 = out
            .quads
            .iter()
            .map(|q| {
                let p = q.map(|w| verts.positions[w as usize]);
                (0..4).map(|k| p[k].x * p[(k + 1) % 4].y - p[(k + 1) % 4].x * p[k].y).sum::<f64>() / 2.0
            })
            .sum();
        assert!((area - 16.0).abs() < 1e-9, "area {area}");
        assert!(verts.len() > before);
    }

    #[test]
    fn an_odd_hanging_midpoint_ends_at_an_open_boundary_edge_on_a_curve() {
        // Unit square quad (face 0) beside a triangle (face 1) across the
        // curve edge 1–2; the outline is curve 1 (open boundary).
        let mut verts =
            vertices(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (2.0, 0.5)], |_| ModelEntity::Face(0));
        let elements = vec![Element::Quad([0, 1, 2, 3]), Element::Triangle([1, 4, 2])];
        let faces = vec![0, 1];
        let mut curve_edges: Vec<CurveEdge> =
            vec![(0, [1, 2]), (1, [0, 1]), (1, [1, 4]), (1, [4, 2]), (1, [2, 3]), (1, [3, 0])];
        let out = subdivide_alone(&mut verts, &elements, &faces, &[false, true], &mut curve_edges).expect("joined");
        assert_eq!((out.n_subdivision_quads, out.n_strips, out.n_quads_split), (3, 1, 1));
        // The square is cut from the hanging midpoint of 1–2 to the middle of
        // the opposite boundary edge 3–0, now two curve edges.
        assert_eq!(out.quads.len(), 5);
        assert_eq!(outline_edges(&out.quads), 8);
        assert_eq!(curve_edges.len(), 10);
        let m = verts.len() as u32 - 1;
        assert_eq!(verts.entity[m as usize], ModelEntity::Curve(1));
        assert!((verts.positions[m as usize] - Vec3::new(0.0, 0.5, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn a_hanging_midpoint_with_no_route_leaves_everything_as_it_was() {
        // The triangle's face beside a quad whose other edges are interior
        // to nothing and not on a curve: no open boundary edge to end at.
        let mut verts =
            vertices(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (2.0, 0.5)], |_| ModelEntity::Face(0));
        let elements = vec![Element::Quad([0, 1, 2, 3]), Element::Triangle([1, 4, 2])];
        let mut curve_edges: Vec<CurveEdge> = vec![(0, [1, 2]), (1, [1, 4]), (1, [4, 2])];
        let before = (verts.len(), curve_edges.clone());
        assert!(subdivide_alone(&mut verts, &elements, &[0, 1], &[false, true], &mut curve_edges).is_none());
        assert_eq!((verts.len(), curve_edges), before);
    }
}
