//! The boundary vertices of the triangulation: every feature curve and every
//! atlas seam discretized once, shared by the patches on either side.
//!
//! A feature curve gets `n ≈ L / size` segments (at least one per piece,
//! closed curves at least 3), its count chosen by [`super::parity`] so every
//! model face has an even number of boundary segments; the pieces of
//! opposite sides of four-sided faces get one count ([`super::sides`]) and
//! are left out of the parity fix. Points are placed at
//! equal 3D arc length inside each piece of the curve; pieces end at the
//! atlas corners on the curve (where a seam meets it: that vertex must exist
//! on both patches' boundaries), at sharp turns of the polyline (a square
//! bounded by one closed curve keeps its four corners) other than the tips
//! of spikes ([`SPIKE_TURN_DEG`]), and at polyline
//! vertices where a chord would cut a thin face across
//! ([`CHORD_SAGITTA_FRACTION`]). Seams get `max(1, round(L / size))`
//! segments, at equal arc length; their vertices lie inside a model face
//! and are not on feature curves.

use std::collections::{HashMap, HashSet};

use super::error::QuadsError;
use super::model::QuadModel;
use super::parity::{ParityCurve, ParityStats, fix_parity};
use super::patch_chart::surface_position;
use super::sides::{Piece, SideStats, match_sides};
use super::size_map::SizeMap;
use super::surface_mesh::{CurveEdge, ModelEntity, SurfacePoint, SurfaceVertices};
use crate::atlas::Atlas;
use crate::geom::angle_between;
use crate::mesh::{Topology, TriMesh, VertexId};

/// Turning angle of a feature polyline above which its vertex is kept as a
/// mesh vertex (degrees).
pub const SHARP_TURN_DEG: f64 = 40.0;

/// Turning angle above which a polyline vertex is the tip of a spike
/// (interior angle below 30°) and is cut by the chord unless it is a
/// corner ([`super::model`] makes it one where the cut would be visible):
/// one quad corner cannot meet it, and a mesh vertex there folds the quads
/// around it (bunny's hole boundary, a 24° spike a quarter of the quad
/// size long).
pub const SPIKE_TURN_DEG: f64 = 150.0;

/// A polyline vertex farther than this fraction of a model face's width
/// (area over perimeter, half the width of a strip) from the chord of its
/// two neighbours is kept as a mesh vertex: a one-triangle sliver face (two
/// fault surfaces have faces 4 m long and 1 cm wide) otherwise loses 4–5 %
/// of its area to the chord over its apex, more than the coverage check's
/// 2 %. A round face never reaches it before the sharp-turn rule: a disk's
/// width is `r/2`, and a chord's sagitta reaches `r/4` only at a turn of
/// 82°.
pub const CHORD_SAGITTA_FRACTION: f64 = 0.5;

/// A point on the surface's edge `a b`: `(1 − t) a + t b` (`a == b` for a
/// vertex).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgePoint {
    /// First end.
    pub a: VertexId,
    /// Second end.
    pub b: VertexId,
    /// Parameter along the edge, in `[0, 1]`.
    pub t: f64,
}

impl EdgePoint {
    /// The surface vertex `v`.
    pub fn vertex(v: VertexId) -> Self {
        Self { a: v, b: v, t: 0.0 }
    }
}

/// The discretized feature curves and seams.
#[derive(Debug, Clone, Default)]
pub struct BoundaryMesh {
    /// The boundary vertices (global ids `0..len`).
    pub vertices: SurfaceVertices,
    /// Where each boundary vertex lies on a surface edge.
    pub location: Vec<EdgePoint>,
    /// Per atlas curve, its vertices from the first to the last chain vertex.
    pub per_atlas_curve: Vec<Vec<u32>>,
    /// Edges on feature curves, in curve direction.
    pub curve_edges: Vec<CurveEdge>,
    /// Vertices on seams (including seam junctions inside a face).
    pub seam_vertices: Vec<u32>,
    /// Segment count of each feature curve.
    pub segments_per_curve: Vec<usize>,
    /// How the parity was reached.
    pub parity: ParityStats,
    /// How the opposite sides of four-sided faces were made equal.
    pub sides: SideStats,
}

/// Arc length at every vertex of the chain `verts`, measured in the size
/// map (`∫ size / h(s) ds`), so equal steps are equal numbers of quad
/// edges at the local size.
fn arc_lengths(surface: &TriMesh, sizes: &SizeMap, size: f64, verts: &[VertexId]) -> Vec<f64> {
    let h = |v: VertexId| sizes.size_per_vertex.get(v.idx()).copied().unwrap_or(size);
    let mut s = Vec::with_capacity(verts.len());
    let mut acc = 0.0;
    s.push(0.0);
    for w in verts.windows(2) {
        let local = 0.5 * (h(w[0]) + h(w[1]));
        acc += (surface.position(w[1]) - surface.position(w[0])).norm() * size / local;
        s.push(acc);
    }
    s
}

/// The point at arc length `target` on the chain, searching from edge `*i`
/// on (advanced; targets must be increasing).
fn point_at(verts: &[VertexId], s: &[f64], target: f64, i: &mut usize) -> (usize, EdgePoint) {
    while *i + 2 < s.len() && s[*i + 1] < target {
        *i += 1;
    }
    let len = s[*i + 1] - s[*i];
    let t = if len > 0.0 { ((target - s[*i]) / len).clamp(0.0, 1.0) } else { 0.0 };
    (*i, EdgePoint { a: verts[*i], b: verts[*i + 1], t })
}

/// The surface point of `p` (on a triangle next to its edge).
pub fn edge_surface_point(surface: &TriMesh, topo: &Topology, p: &EdgePoint) -> Option<SurfacePoint> {
    let (v, w, t) = if p.a == p.b || p.t <= 0.0 {
        (p.a, p.a, 0.0)
    } else if p.t >= 1.0 {
        (p.b, p.b, 0.0)
    } else {
        (p.a, p.b, p.t)
    };
    let face =
        if v == w { *topo.vertex_faces(v).first()? } else { *topo.edge_faces(topo.edge_between(v, w)?).first()? };
    let tri = surface.triangles[face.idx()];
    let mut bary = [0.0; 3];
    for (b, &x) in bary.iter_mut().zip(&tri) {
        if x == v {
            *b += 1.0 - t;
        }
        if x == w && v != w {
            *b += t;
        }
    }
    Some(SurfacePoint { face, bary })
}

/// Everything the discretization shares.
struct Builder<'a> {
    surface: &'a TriMesh,
    topo: &'a Topology,
    atlas: &'a Atlas,
    out: BoundaryMesh,
    /// Global vertex placed at a surface vertex.
    at_vertex: HashMap<VertexId, u32>,
    /// Per atlas curve, the vertices strictly inside it with their position
    /// along its chain (edge index + parameter).
    inside: Vec<Vec<(f64, u32)>>,
    /// Atlas curve, edge index and first chain vertex of each atlas-curve
    /// edge, by sorted vertex pair.
    atlas_edge: HashMap<(VertexId, VertexId), (u32, u32, VertexId)>,
}

impl Builder<'_> {
    fn error(&self, ac: usize, reason: String) -> QuadsError {
        let patch = self.atlas.patches.iter().position(|p| p.curves.iter().any(|&(c, _)| c as usize == ac));
        QuadsError::Triangulation { patch: patch.unwrap_or(0), reason }
    }

    fn push(&mut self, p: EdgePoint, entity: ModelEntity) -> Result<u32, QuadsError> {
        let sp = edge_surface_point(self.surface, self.topo, &p)
            .ok_or_else(|| self.error(0, format!("boundary point on {}–{} is on no surface triangle", p.a.0, p.b.0)))?;
        self.out.location.push(p);
        Ok(self.out.vertices.push(surface_position(self.surface, &sp), sp, entity))
    }

    /// The global vertex at surface vertex `v`, created with `entity` if new.
    fn vertex(&mut self, v: VertexId, entity: ModelEntity) -> Result<u32, QuadsError> {
        if let Some(&g) = self.at_vertex.get(&v) {
            return Ok(g);
        }
        let g = self.push(EdgePoint::vertex(v), entity)?;
        self.at_vertex.insert(v, g);
        Ok(g)
    }

    /// Records that `g`, on the surface edge `a b` at `t`, lies inside the
    /// atlas curve through that edge.
    fn record_inside(&mut self, a: VertexId, b: VertexId, t: f64, g: u32) -> Result<(), QuadsError> {
        let &(ac, j, from) = self
            .atlas_edge
            .get(&(a.min(b), a.max(b)))
            .ok_or_else(|| self.error(0, format!("feature edge {}–{} is on no atlas curve", a.0, b.0)))?;
        let pos = f64::from(j) + if from == a { t } else { 1.0 - t };
        self.inside[ac as usize].push((pos, g));
        Ok(())
    }
}

/// Smallest segment count of each atlas curve: 3 for a closed curve, 2 when
/// another curve joins the same two corners (two single segments would
/// bound a flat 2-gon), else 1.
fn atlas_min_segments(atlas: &Atlas) -> Vec<usize> {
    let ends: Vec<(VertexId, VertexId)> = atlas
        .curves
        .iter()
        .map(|c| {
            let (a, b) = (c.chain.vertices[0], *c.chain.vertices.last().unwrap_or(&c.chain.vertices[0]));
            (a.min(b), a.max(b))
        })
        .collect();
    let mut count: HashMap<(VertexId, VertexId), usize> = HashMap::new();
    for e in &ends {
        *count.entry(*e).or_default() += 1;
    }
    atlas
        .curves
        .iter()
        .zip(&ends)
        .map(|(c, e)| {
            if c.chain.is_closed() {
                3
            } else if count[e] > 1 {
                2
            } else {
                1
            }
        })
        .collect()
}

/// Indices of the chain vertices where a feature curve's pieces end: its
/// ends, atlas corners (`corners`, sorted), the vertices in `kept`, sharp
/// turns other than spikes ([`SPIKE_TURN_DEG`]), and vertices
/// farther from the chord of their two polyline neighbours than
/// [`CHORD_SAGITTA_FRACTION`] of `width` (the smallest area-over-perimeter
/// of the model faces the curve bounds): a chord over such a vertex would
/// cut a thin face across.
fn piece_ends(
    surface: &TriMesh,
    corners: &[VertexId],
    kept: &HashSet<VertexId>,
    verts: &[VertexId],
    width: f64,
) -> Vec<usize> {
    let m = verts.len() - 1;
    let mut ends = vec![0];
    for i in 1..m {
        let corner = corners.binary_search(&verts[i]).is_ok() || kept.contains(&verts[i]);
        let (p, q, r) = (surface.position(verts[i - 1]), surface.position(verts[i]), surface.position(verts[i + 1]));
        let turn = angle_between(&(q - p), &(r - q)).to_degrees();
        let sagitta = (q - p).cross(&(r - p)).norm() / (r - p).norm();
        let spike = turn > SPIKE_TURN_DEG;
        if corner || (turn > SHARP_TURN_DEG && !spike) || sagitta > CHORD_SAGITTA_FRACTION * width {
            ends.push(i);
        }
    }
    ends.push(m);
    ends
}

/// Per model face, its area over the length of the curves bounding it (a
/// curve with the face on both sides counted twice); infinite for a face
/// without curves.
fn face_widths(surface: &TriMesh, model: &QuadModel) -> Vec<f64> {
    let area = &model.face_area;
    let mut perimeter = vec![0.0; model.n_faces];
    for (curve, faces) in model.features.curves.iter().zip(&model.faces_per_curve) {
        let length: f64 =
            curve.vertices.windows(2).map(|w| (surface.position(w[1]) - surface.position(w[0])).norm()).sum();
        for &f in faces {
            perimeter[f as usize] += length;
        }
    }
    area.iter().zip(&perimeter).map(|(&a, &p)| if p > 0.0 { a / p } else { f64::INFINITY }).collect()
}

/// Splits `n` segments over pieces of lengths `lengths` with minimums
/// `mins`: each extra segment goes to the piece with the longest segments.
fn distribute(n: usize, lengths: &[f64], mins: &[usize]) -> Vec<usize> {
    let mut counts = mins.to_vec();
    let mut left = n.saturating_sub(mins.iter().sum());
    while left > 0 {
        let segment = |k: usize| lengths[k] / counts[k] as f64;
        let best = (1..counts.len()).fold(0, |b, k| if segment(k) > segment(b) { k } else { b });
        counts[best] += 1;
        left -= 1;
    }
    counts
}

/// The count each piece of each curve must have so that four-sided faces
/// get equal opposite sides ([`super::sides`]), per curve, per piece, and
/// what the matching did.
fn matched_sides(
    surface: &TriMesh,
    topo: &Topology,
    model: &QuadModel,
    pieces: &[CurvePieces],
    size: f64,
) -> (Vec<Vec<Option<usize>>>, SideStats) {
    let flat: Vec<Piece> = pieces
        .iter()
        .enumerate()
        .flat_map(|(c, (ends, lengths, mins, _))| {
            let verts = &model.features.curves[c].vertices;
            ends.windows(2).zip(lengths).zip(mins).map(move |((w, &length), &min_segments)| Piece {
                curve: c as u32,
                ends: [verts[w[0]], verts[w[1]]],
                target: length / size,
                min_segments,
            })
        })
        .collect();
    let (counts, stats) = match_sides(surface, topo, model, &flat);
    let mut left = counts.into_iter();
    let per_curve = pieces.iter().map(|(_, lengths, _, _)| left.by_ref().take(lengths.len()).collect()).collect();
    (per_curve, stats)
}

/// The segment count of every piece of every curve, and whether the
/// matched sides were kept: a curve with a matched piece gets the matched
/// counts there and its other pieces' share of the rest, and is not
/// bumped by the parity fix (`parity` is its outcome). Should the faces
/// stay odd that way, the matching is dropped and the curves counted and
/// fixed as without it.
fn piece_counts(
    curves: &mut [ParityCurve],
    n_faces: usize,
    pieces: &[CurvePieces],
    matched: &[Vec<Option<usize>>],
    parity: &mut ParityStats,
) -> (Vec<Vec<usize>>, bool) {
    let free = curves.to_vec();
    for ((curve, (_, lengths, mins, _)), fixed) in curves.iter_mut().zip(pieces).zip(matched) {
        if fixed.iter().all(Option::is_none) {
            continue;
        }
        let rest: f64 = lengths.iter().zip(fixed).filter(|(_, f)| f.is_none()).map(|(l, _)| l).sum();
        let rest_min: usize = mins.iter().zip(fixed).filter(|(_, f)| f.is_none()).map(|(m, _)| m).sum();
        let rest_count = ((rest / lengths.iter().sum::<f64>() * curve.target).round() as usize).max(rest_min);
        curve.segments = fixed.iter().flatten().sum::<usize>() + rest_count;
        curve.fixed = true;
    }
    *parity = fix_parity(curves, n_faces);
    let kept = parity.odd_faces_after == 0;
    if !kept {
        curves.clone_from_slice(&free);
        *parity = fix_parity(curves, n_faces);
    }
    let counts = curves
        .iter()
        .zip(pieces)
        .zip(matched)
        .map(|((curve, (_, lengths, mins, _)), fixed)| {
            if !kept || !curve.fixed {
                return distribute(curve.segments, lengths, mins);
            }
            let free: Vec<usize> = (0..lengths.len()).filter(|&k| fixed[k].is_none()).collect();
            let rest = curve.segments - fixed.iter().flatten().sum::<usize>();
            let shares = distribute(
                rest,
                &free.iter().map(|&k| lengths[k]).collect::<Vec<_>>(),
                &free.iter().map(|&k| mins[k]).collect::<Vec<_>>(),
            );
            let mut shares = shares.into_iter();
            fixed.iter().map(|f| f.unwrap_or_else(|| shares.next().unwrap_or(1))).collect()
        })
        .collect();
    (counts, kept)
}

/// One feature curve cut into pieces: the vertex index of each piece end,
/// the length of each piece, its minimum segment count, and the arc length
/// at each vertex of the curve.
type CurvePieces = (Vec<usize>, Vec<f64>, Vec<usize>, Vec<f64>);

/// Discretize the feature curves of `model` and the seams of `atlas` at
/// `size` (see the module documentation); every surface vertex of `kept`
/// on a curve or seam becomes a boundary vertex.
///
/// # Errors
/// [`QuadsError::Triangulation`] when a curve does not lie on the atlas
/// curves it should (an inconsistent atlas).
pub fn discretize_boundaries(
    surface: &TriMesh,
    topo: &Topology,
    atlas: &Atlas,
    model: &QuadModel,
    size: f64,
    sizes: &SizeMap,
    kept: &HashSet<VertexId>,
) -> Result<BoundaryMesh, QuadsError> {
    let n_surface = surface.n_vertices();
    let mut atlas_edge = HashMap::new();
    for (ac, c) in atlas.curves.iter().enumerate() {
        if let Some(v) = c.chain.vertices.iter().find(|v| v.idx() >= n_surface) {
            return Err(QuadsError::Triangulation {
                patch: 0,
                reason: format!("atlas curve {ac} passes through vertex {} not on the surface", v.0),
            });
        }
        for (j, w) in c.chain.vertices.windows(2).enumerate() {
            atlas_edge.insert((w[0].min(w[1]), w[0].max(w[1])), (ac as u32, j as u32, w[0]));
        }
    }
    let mut b = Builder {
        surface,
        topo,
        atlas,
        out: BoundaryMesh::default(),
        at_vertex: HashMap::new(),
        inside: vec![Vec::new(); atlas.curves.len()],
        atlas_edge,
    };
    let atlas_min = atlas_min_segments(atlas);

    // Pieces and segment counts of the feature curves, then parity.
    let curves = &model.features.curves;
    let widths = face_widths(surface, model);
    let mut pieces: Vec<CurvePieces> = Vec::with_capacity(curves.len());
    let mut parity_curves = Vec::with_capacity(curves.len());
    for (c, curve) in curves.iter().enumerate() {
        let verts = &curve.vertices;
        let s = arc_lengths(surface, sizes, size, verts);
        let width = model.faces_per_curve[c].iter().map(|&f| widths[f as usize]).fold(f64::INFINITY, f64::min);
        let ends = piece_ends(surface, &atlas.corners, kept, verts, width);
        let lengths: Vec<f64> = ends.windows(2).map(|w| s[w[1]] - s[w[0]]).collect();
        let mut mins = Vec::with_capacity(lengths.len());
        for w in ends.windows(2) {
            let (a, bb) = (verts[w[0]], verts[w[0] + 1]);
            // A closed atlas curve needs 3 segments in all, not per piece.
            let ac = b.atlas_edge.get(&(a.min(bb), a.max(bb))).map_or(1, |x| match atlas_min[x.0 as usize] {
                3 => 1,
                m => m,
            });
            mins.push(ac);
        }
        let total: usize = mins.iter().sum();
        if curve.is_closed() && total < 3 {
            mins[0] += 3 - total;
        }
        let min_segments: usize = mins.iter().sum();
        let target = s[s.len() - 1] / size;
        let faces = model.faces_per_curve[c].clone();
        let two_sided = faces.len() == 1 && curve.edges.first().is_some_and(|&e| topo.edge_valence(e) == 2);
        parity_curves.push(ParityCurve {
            faces,
            target,
            segments: (target.round() as usize).max(min_segments),
            min_segments,
            two_sided,
            fixed: false,
        });
        pieces.push((ends, lengths, mins, s));
    }
    let (matched, sides) = matched_sides(surface, topo, model, &pieces, size);
    let (counts_per_curve, matched_kept) =
        piece_counts(&mut parity_curves, model.n_faces, &pieces, &matched, &mut b.out.parity);
    b.out.sides = SideStats { dropped_for_parity: !matched_kept && sides.n_classes > 0, ..sides };

    // Feature curve points, in curve order.
    for (c, (curve, (ends, lengths, _, s))) in curves.iter().zip(&pieces).enumerate() {
        let verts = &curve.vertices;
        let n = parity_curves[c].segments;
        b.out.segments_per_curve.push(n);
        let counts = &counts_per_curve[c];
        let corner = model.corner_of(verts[0]).ok_or_else(|| {
            b.error(0, format!("feature curve {c} starts at vertex {} which is not a model corner", verts[0].0))
        })?;
        let first = b.vertex(verts[0], ModelEntity::Corner(corner))?;
        if atlas.corners.binary_search(&verts[0]).is_err() {
            b.record_inside(verts[0], verts[1], 0.0, first)?;
        }
        let mut prev = first;
        let mut edge = 0usize;
        for (k, w) in ends.windows(2).enumerate() {
            let step = lengths[k] / counts[k] as f64;
            for j in 1..counts[k] {
                let (i, p) = point_at(verts, s, s[w[0]] + step * j as f64, &mut edge);
                let g = b.push(p, ModelEntity::Curve(c as u32))?;
                b.record_inside(verts[i], verts[i + 1], p.t, g)?;
                b.out.curve_edges.push((c as u32, [prev, g]));
                prev = g;
            }
            let end = w[1];
            let g = if end == verts.len() - 1 {
                let corner = model.corner_of(verts[end]).ok_or_else(|| {
                    b.error(0, format!("feature curve {c} ends at vertex {} which is not a model corner", verts[end].0))
                })?;
                let g = b.vertex(verts[end], ModelEntity::Corner(corner))?;
                if atlas.corners.binary_search(&verts[end]).is_err() && !curve.is_closed() {
                    b.record_inside(verts[end - 1], verts[end], 1.0, g)?;
                }
                g
            } else {
                let g = b.vertex(verts[end], ModelEntity::Curve(c as u32))?;
                if atlas.corners.binary_search(&verts[end]).is_err() {
                    b.record_inside(verts[end], verts[end + 1], 0.0, g)?;
                }
                g
            };
            b.out.curve_edges.push((c as u32, [prev, g]));
            prev = g;
        }
    }

    // Seams: the atlas curves off the model's curves (a crease the model
    // leaves out is a seam here, whatever the atlas calls it).
    for (ac, curve) in atlas.curves.iter().enumerate() {
        let verts = &curve.chain.vertices;
        let e0 = topo
            .edge_between(verts[0], verts[1])
            .ok_or_else(|| b.error(ac, format!("atlas curve {ac} is not on surface edges")))?;
        if model.features.is_feature_edge[e0.idx()] {
            continue;
        }
        let face = model.face_per_triangle[topo.edge_faces(e0)[0].idx()];
        let s = arc_lengths(surface, sizes, size, verts);
        let len = s[s.len() - 1];
        for v in [verts[0], verts[verts.len() - 1]] {
            if !b.at_vertex.contains_key(&v) {
                let g = b.vertex(v, ModelEntity::Face(face))?;
                b.out.seam_vertices.push(g);
            }
        }
        // Pieces between the kept vertices, at least one segment each.
        let m = verts.len() - 1;
        let ends: Vec<usize> =
            std::iter::once(0).chain((1..m).filter(|&i| kept.contains(&verts[i]))).chain(std::iter::once(m)).collect();
        let lengths: Vec<f64> = ends.windows(2).map(|w| s[w[1]] - s[w[0]]).collect();
        let mins = if ends.len() == 2 { vec![atlas_min[ac]] } else { vec![1; lengths.len()] };
        let n = ((len / size).round() as usize).max(mins.iter().sum());
        let counts = distribute(n, &lengths, &mins);
        let mut edge = 0usize;
        for (k, w) in ends.windows(2).enumerate() {
            for j in 1..counts[k] {
                let at = s[w[0]] + lengths[k] * j as f64 / counts[k] as f64;
                let (i, p) = point_at(verts, &s, at, &mut edge);
                let g = b.push(p, ModelEntity::Face(face))?;
                b.out.seam_vertices.push(g);
                b.inside[ac].push((i as f64 + p.t, g));
            }
            if w[1] < m {
                let new = !b.at_vertex.contains_key(&verts[w[1]]);
                let g = b.vertex(verts[w[1]], ModelEntity::Face(face))?;
                if new {
                    b.out.seam_vertices.push(g);
                }
                b.inside[ac].push((w[1] as f64, g));
            }
        }
    }

    // Each atlas curve's vertices in chain order.
    let mut per_atlas_curve = Vec::with_capacity(atlas.curves.len());
    for (ac, curve) in atlas.curves.iter().enumerate() {
        let verts = &curve.chain.vertices;
        let (Some(&g0), Some(&g1)) = (b.at_vertex.get(&verts[0]), b.at_vertex.get(&verts[verts.len() - 1])) else {
            return Err(b.error(ac, format!("atlas curve {ac} ends at a vertex that was not discretized")));
        };
        let mut inside = std::mem::take(&mut b.inside[ac]);
        inside.sort_by(|x, y| x.0.total_cmp(&y.0));
        // A model corner inside an atlas curve ends one model curve and
        // starts the next: both record it, at the same place.
        inside.dedup_by(|x, y| x.1 == y.1 && (x.0 - y.0).abs() < 1e-9);
        if inside.windows(2).any(|w| w[0].1 == w[1].1) {
            return Err(b.error(ac, format!("atlas curve {ac} holds a vertex twice")));
        }
        let mut list = Vec::with_capacity(inside.len() + 2);
        list.push(g0);
        list.extend(inside.iter().map(|x| x.1));
        list.push(g1);
        per_atlas_curve.push(list);
    }
    let mut out = b.out;
    out.per_atlas_curve = per_atlas_curve;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Vec3;
    use crate::mesh::fixtures;
    use crate::quads::model::quad_model;

    /// A mesh with only the points of a polyline (the test needs positions).
    fn polyline(points: &[Vec3]) -> (TriMesh, Vec<VertexId>) {
        let mesh = TriMesh::from_raw(points.to_vec(), &[]);
        (mesh, (0..points.len() as u32).map(VertexId).collect())
    }

    #[test]
    fn the_apex_of_a_sliver_face_ends_a_piece() {
        // Two sides of a sliver 4 long and 0.01 wide at its apex: its
        // area over perimeter is 0.02 / 8 = 0.0025.
        let (mesh, verts) = polyline(&[Vec3::zeros(), Vec3::new(2.0, 0.01, 0.0), Vec3::new(4.0, 0.0, 0.0)]);
        assert_eq!(piece_ends(&mesh, &[], &HashSet::new(), &verts, 0.0025), vec![0, 1, 2]);
        // The same turn on a wide face is crossed by a chord.
        assert_eq!(piece_ends(&mesh, &[], &HashSet::new(), &verts, 1.0), vec![0, 2]);
    }

    #[test]
    fn a_right_angle_ends_a_piece_and_a_spike_is_cut() {
        // At (2, 0), on a face 10 wide: a turn by 90°, then by 171°
        // (interior angle 9°).
        let (mesh, verts) = polyline(&[Vec3::zeros(), Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 2.0, 0.0)]);
        assert_eq!(piece_ends(&mesh, &[], &HashSet::new(), &verts, 10.0), vec![0, 1, 2]);
        let (mesh, verts) = polyline(&[Vec3::zeros(), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.2, 0.3, 0.0)]);
        assert_eq!(piece_ends(&mesh, &[], &HashSet::new(), &verts, 10.0), vec![0, 2]);
        // As an atlas corner, or on a face narrower than its sagitta, it stays.
        assert_eq!(piece_ends(&mesh, &[verts[1]], &HashSet::new(), &verts, 10.0), vec![0, 1, 2]);
        assert_eq!(piece_ends(&mesh, &[], &HashSet::new(), &verts, 1.0), vec![0, 1, 2]);
    }

    #[test]
    fn a_round_face_keeps_no_vertex_of_its_boundary_below_the_sharp_turn() {
        // A 12-gon of radius 1 (turns of 30°) around a disk of width 1/2.
        let points: Vec<Vec3> = (0..=12)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 12.0;
                Vec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let (mesh, verts) = polyline(&points);
        assert_eq!(piece_ends(&mesh, &[], &HashSet::new(), &verts, 0.5), vec![0, 12]);
    }

    #[test]
    fn a_square_is_as_wide_as_a_quarter_of_its_side() {
        let mesh = fixtures::square(4);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &crate::atlas::features::detect_features(&mesh, &topo, 30.0));
        let widths = face_widths(&mesh, &model);
        assert_eq!(widths.len(), 1);
        assert!((widths[0] - 0.25).abs() < 1e-12, "{widths:?}");
    }
}
