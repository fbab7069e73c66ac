//! Equal segment counts on the opposite sides of four-sided model faces.
//!
//! A quad mesh of a disk whose boundary turns at exactly four corners, each
//! held by one quad, has `Σ_inside (4 − valence) = 0`; it can be a regular
//! grid only when its opposite sides have as many segments. Counted from
//! each side's own length, two opposite sides that differ by a few percent
//! (a terrain's relief, a size map that grows along one side) get counts
//! that differ by one or more, and each unit of difference leaves a
//! valence 3–5 pair inside the face: the frontal points, the matching and
//! the cavity step cannot remove it, because no regular pattern fits the
//! boundary. This is the simplest case of quantizing a patch layout
//! (research `quad-meshing.md`, QuadWild / Bi-MDF): here the layout is the
//! model's own faces.
//!
//! A face qualifies when its boundary is exactly four curve pieces (see
//! [`super::curves`]) joined at four distinct corners, each corner's angle
//! in the face (the sum of the face's triangle angles there) below 135°, so
//! one quad fills it; no curve has the face on both sides. Opposite pieces
//! (sharing no corner) must get the same count; faces sharing a piece chain
//! these equalities, so the pieces fall into classes (union–find), and each
//! class gets the rounded mean of its members' target counts, at least
//! each member's minimum. A class whose targets differ by more than
//! [`MAX_TARGET_RATIO`] is left alone: the quads across it would stretch
//! more than a pair of irregular vertices costs. So is a class that would
//! move the count of a curve that also bounds a face that does not
//! qualify by more than [`MAX_CHANGE_BESIDE_OTHER_FACES`] from that
//! curve's own: the other face would pay for it with irregular vertices of
//! its own. A face with equal opposite sides has an even boundary count,
//! so the matched pieces need no parity bump.

use serde::Serialize;

use super::model::QuadModel;
use crate::geom::corner_angles;
use crate::mesh::components::DisjointSets;
use crate::mesh::{Topology, TriMesh, VertexId};

/// Largest interior angle, in degrees, of a corner one quad fills.
const MAX_CORNER_DEG: f64 = 135.0;

/// Largest change of a piece's count, from its own rounded target, where
/// its curve also bounds a face without matched sides.
const MAX_CHANGE_BESIDE_OTHER_FACES: usize = 1;

/// Largest ratio of target counts within a class of pieces made equal.
const MAX_TARGET_RATIO: f64 = 1.2;

/// One piece of a feature curve, as the side matching sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    /// The curve it belongs to.
    pub curve: u32,
    /// Its surface vertices at either end.
    pub ends: [VertexId; 2],
    /// Its length over the target size (size-map arc length).
    pub target: f64,
    /// Its smallest allowed segment count.
    pub min_segments: usize,
}

/// What the side matching did (for the report).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SideStats {
    /// Model faces that qualify: four sides, each corner filled by one quad.
    pub n_four_sided_faces: usize,
    /// Classes of pieces given one count.
    pub n_classes: usize,
    /// Pieces whose count was set by their class.
    pub n_pieces: usize,
    /// Classes left alone, their targets too far apart.
    pub n_classes_too_uneven: usize,
    /// Classes left alone because they would move the count of a curve
    /// that also bounds a face without matched sides by more than one.
    pub n_classes_beside_other_faces: usize,
    /// True when the classes were dropped because a face stayed odd with
    /// them (its other curves could not fix its parity); the curves were
    /// then counted one by one.
    pub dropped_for_parity: bool,
}

/// The segment count each of `pieces` must have (`None`: free) so that the
/// four-sided faces of `model` get equal opposite sides, and what was done.
pub fn match_sides(
    surface: &TriMesh,
    topo: &Topology,
    model: &QuadModel,
    pieces: &[Piece],
) -> (Vec<Option<usize>>, SideStats) {
    let mut per_face: Vec<Vec<usize>> = vec![Vec::new(); model.n_faces];
    let mut two_sided = vec![false; model.n_faces];
    for (i, p) in pieces.iter().enumerate() {
        let faces = &model.faces_per_curve[p.curve as usize];
        for (k, &f) in faces.iter().enumerate() {
            if faces[..k].contains(&f) {
                two_sided[f as usize] = true;
            } else if let Some(list) = per_face.get_mut(f as usize) {
                list.push(i);
            }
        }
    }
    let mut sets = DisjointSets::new(pieces.len());
    let mut n_four_sided_faces = 0;
    let mut qualified = vec![false; model.n_faces];
    for (f, list) in per_face.iter().enumerate() {
        if two_sided[f] {
            continue;
        }
        let Some(pairs) = opposite_pairs(pieces, list) else { continue };
        let mut corners: Vec<VertexId> = list.iter().flat_map(|&i| pieces[i].ends).collect();
        corners.sort_unstable();
        corners.dedup();
        let one_quad = |v: &VertexId| corner_angle(surface, topo, model, f as u32, *v) < MAX_CORNER_DEG.to_radians();
        if !corners.iter().all(one_quad) {
            continue;
        }
        n_four_sided_faces += 1;
        qualified[f] = true;
        for [a, b] in pairs {
            sets.union(a as u32, b as u32);
        }
    }
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); pieces.len()];
    for i in 0..pieces.len() {
        members[sets.find(i as u32) as usize].push(i);
    }
    let mut stats = SideStats { n_four_sided_faces, ..SideStats::default() };
    let mut counts = vec![None; pieces.len()];
    for class in members.iter().filter(|m| m.len() > 1) {
        let (lo, hi) = class
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), &i| (lo.min(pieces[i].target), hi.max(pieces[i].target)));
        if !(hi <= MAX_TARGET_RATIO * lo) {
            stats.n_classes_too_uneven += 1;
            continue;
        }
        let mean = class.iter().map(|&i| pieces[i].target).sum::<f64>() / class.len() as f64;
        let floor = class.iter().map(|&i| pieces[i].min_segments).max().unwrap_or(1).max(1);
        let n = (mean.round() as usize).max(floor);
        let moves_a_neighbour = class.iter().any(|&i| {
            let beside = model.faces_per_curve[pieces[i].curve as usize].iter().any(|&f| !qualified[f as usize]);
            beside && n.abs_diff(pieces[i].target.round() as usize) > MAX_CHANGE_BESIDE_OTHER_FACES
        });
        if moves_a_neighbour {
            stats.n_classes_beside_other_faces += 1;
            continue;
        }
        for &i in class {
            counts[i] = Some(n);
        }
        stats.n_classes += 1;
        stats.n_pieces += class.len();
    }
    (counts, stats)
}

/// The two pairs of opposite pieces of a face bounded by `list`: `None`
/// unless it is exactly four pieces joined in one loop at four distinct
/// corners, each the end of two of them.
fn opposite_pairs(pieces: &[Piece], list: &[usize]) -> Option<[[usize; 2]; 2]> {
    let [a, b, c, d] = list[..] else { return None };
    let ends: Vec<VertexId> = list.iter().flat_map(|&i| pieces[i].ends).collect();
    if list.iter().any(|&i| pieces[i].ends[0] == pieces[i].ends[1])
        || ends.iter().any(|v| ends.iter().filter(|w| *w == v).count() != 2)
    {
        return None;
    }
    let share = |i: usize, j: usize| pieces[i].ends.iter().any(|v| pieces[j].ends.contains(v));
    // One loop: each piece meets exactly two others (not two lenses).
    if list.iter().any(|&i| list.iter().filter(|&&j| j != i && share(i, j)).count() != 2) {
        return None;
    }
    let partner = [b, c, d].into_iter().find(|&j| !share(a, j))?;
    let others: Vec<usize> = [b, c, d].into_iter().filter(|&j| j != partner).collect();
    (!share(others[0], others[1])).then_some([[a, partner], [others[0], others[1]]])
}

/// The angle of model face `face` at vertex `v`: the sum of the angles at
/// `v` of its input triangles there (radians).
fn corner_angle(surface: &TriMesh, topo: &Topology, model: &QuadModel, face: u32, v: VertexId) -> f64 {
    topo.vertex_faces(v)
        .iter()
        .filter(|t| model.face_per_triangle[t.idx()] == face)
        .filter_map(|&t| {
            let tri = surface.triangles[t.idx()];
            let k = tri.iter().position(|&w| w == v)?;
            let [a, b, c] = surface.corners(t);
            Some(corner_angles(&a, &b, &c)[k])
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn piece(a: u32, b: u32) -> Piece {
        Piece { curve: 0, ends: [VertexId(a), VertexId(b)], target: 1.0, min_segments: 1 }
    }

    #[test]
    fn the_pieces_of_a_four_cycle_pair_up_across() {
        // Corners 0..4 around, the pieces listed out of order.
        let pieces = [piece(0, 1), piece(2, 3), piece(1, 2), piece(3, 0)];
        assert_eq!(opposite_pairs(&pieces, &[0, 1, 2, 3]), Some([[0, 1], [2, 3]]));
        assert_eq!(opposite_pairs(&pieces, &[0, 2, 1, 3]), Some([[0, 1], [2, 3]]));
    }

    #[test]
    fn other_boundaries_have_no_opposite_sides() {
        // Three sides, or five.
        let triangle = [piece(0, 1), piece(1, 2), piece(2, 0)];
        assert_eq!(opposite_pairs(&triangle, &[0, 1, 2]), None);
        let pentagon = [piece(0, 1), piece(1, 2), piece(2, 3), piece(3, 4), piece(4, 0)];
        assert_eq!(opposite_pairs(&pentagon, &[0, 1, 2, 3, 4]), None);
        // A triangle and a closed hole curve (one piece from a vertex to itself).
        let holed = [piece(0, 1), piece(1, 2), piece(2, 0), piece(5, 5)];
        assert_eq!(opposite_pairs(&holed, &[0, 1, 2, 3]), None);
        // Two sides between the same two corners, twice (two lenses).
        let lenses = [piece(0, 1), piece(1, 0), piece(2, 3), piece(3, 2)];
        assert_eq!(opposite_pairs(&lenses, &[0, 1, 2, 3]), None);
    }
}
