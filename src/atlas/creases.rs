//! Model faces cut along their inner creases, so every feature edge is a
//! patch border (thesis ch. 2 §4.1: patches are bounded by feature curves).
//!
//! A crease with the same model face on both sides (one that fades out
//! inside a face, as fandisk's do, or a closed one that does not disconnect
//! it) separates nothing, so cutting the model faces into disks gives the
//! atlas no reason to cut along it. Its patch would then span the crease,
//! and a quad mesh built on the patch crosses it: quads folded over a 90°
//! edge (fandisk's quads below 0.3 all lay at such creases).
//!
//! Each such face is grown from both sides of its inner creases at once
//! (breadth first, never across a feature edge): a triangle along a crease
//! edge is seeded with the crease's curve and its side (left or right of
//! the curve's direction), every other triangle takes the label of the
//! seed it is reached from first. The pieces are the connected parts of one
//! label. Two labels meet along the creases and along seams the growth
//! leaves where the fronts meet (past a crease's loose end, for one); the
//! atlas then splits a piece that is not a disk as it splits any patch.

use std::collections::VecDeque;

use crate::mesh::{EdgeId, FaceId, Topology, TriMesh};

use super::features::{FeatureCurve, Features, dihedral_angle};

/// What cutting the model faces along their inner creases gave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CreaseCut {
    /// The pieces, those of one model face after each other, each in
    /// order of its first triangle.
    pub pieces: Vec<Vec<FaceId>>,
    /// Model faces cut into more than one piece.
    pub n_faces_cut: usize,
    /// Per edge: an inner crease edge with different pieces on its sides
    /// (empty when no face has a crease sharp enough to cut).
    pub is_cut_crease: Vec<bool>,
}

/// The model faces `faces_of_model_face` (triangles of each), each face
/// with an inner crease cut along it (module documentation).
pub fn cut_along_inner_creases(
    mesh: &TriMesh,
    topo: &Topology,
    features: &Features,
    faces_of_model_face: Vec<Vec<FaceId>>,
) -> CreaseCut {
    let mut face_of = vec![u32::MAX; mesh.n_faces()];
    for (m, faces) in faces_of_model_face.iter().enumerate() {
        for f in faces {
            face_of[f.idx()] = m as u32;
        }
    }
    let seeds = crease_seeds(mesh, topo, features, &face_of);
    if seeds.is_empty() {
        return CreaseCut { pieces: faces_of_model_face, n_faces_cut: 0, is_cut_crease: Vec::new() };
    }
    let label = grow_labels(topo, features, &face_of, &seeds);
    let mut has_crease = vec![false; faces_of_model_face.len()];
    for &(f, _) in &seeds {
        has_crease[face_of[f.idx()] as usize] = true;
    }
    let mut out = Vec::with_capacity(faces_of_model_face.len());
    let mut n_cut = 0;
    for (m, faces) in faces_of_model_face.into_iter().enumerate() {
        if !has_crease[m] {
            out.push(faces);
            continue;
        }
        let pieces = connected_pieces(topo, features, &label, &faces);
        n_cut += usize::from(pieces.len() > 1);
        out.extend(pieces);
    }
    let mut piece_of = vec![usize::MAX; mesh.n_faces()];
    for (i, piece) in out.iter().enumerate() {
        for f in piece {
            piece_of[f.idx()] = i;
        }
    }
    let mut is_cut_crease = vec![false; topo.n_edges()];
    for (e, flag) in is_cut_crease.iter_mut().enumerate() {
        if let &[f, g] = topo.edge_faces(EdgeId::new(e)) {
            *flag = features.is_feature_edge[e]
                && face_of[f.idx()] == face_of[g.idx()]
                && piece_of[f.idx()] != piece_of[g.idx()];
        }
    }
    CreaseCut { pieces: out, n_faces_cut: n_cut, is_cut_crease }
}

/// The triangles beside inner crease edges (feature edges with the same
/// model face `face_of` on both sides) of the curves sharp and long enough
/// to cut along ([`is_sharp_crease`]), each with its label: twice the curve's
/// index, plus one on the curve's right. In edge order; a triangle beside
/// several creases appears once per edge.
fn crease_seeds(mesh: &TriMesh, topo: &Topology, features: &Features, face_of: &[u32]) -> Vec<(FaceId, u32)> {
    let mut seeds = Vec::new();
    let inner = |e: EdgeId| match topo.edge_faces(e) {
        &[f, g] => face_of[f.idx()] == face_of[g.idx()],
        _ => false,
    };
    let shortest = MIN_CUT_CREASE_EDGES * mesh.mean_edge_length();
    for (c, curve) in features.curves.iter().enumerate() {
        if !is_sharp_crease(mesh, topo, curve, &inner, shortest) {
            continue;
        }
        for (k, &e) in curve.edges.iter().enumerate() {
            let &[f, g] = topo.edge_faces(e) else { continue };
            if !inner(e) {
                continue;
            }
            let (a, b) = (curve.vertices[k], curve.vertices[k + 1]);
            let left_of = |t: FaceId| {
                let tri = mesh.triangles[t.idx()];
                (0..3).any(|i| tri[i] == a && tri[(i + 1) % 3] == b)
            };
            let (left, right) = if left_of(f) { (f, g) } else { (g, f) };
            seeds.push((left, 2 * c as u32));
            seeds.push((right, 2 * c as u32 + 1));
        }
    }
    seeds
}

/// Angle between the normals (degrees) that the inner edges of a crease
/// must make on average, weighted by length, for the atlas to cut along
/// it. Most inner creases of the organic corpus files (scans of a cow, a
/// bunny, a camel's head, an aorta) are fragments at 40° to 62° on
/// average, where cutting made 26 inverted quads on camelhead and
/// subdivided aorta_closed; fandisk's two machined creases are 76° and 80°
/// (decisions, session 29).
pub const MIN_CUT_CREASE_ANGLE_DEG: f64 = 70.0;

/// Length, in mean edge lengths of the input (the quads' default size), a
/// crease must have for the atlas to cut along it. Shorter ones carry a
/// curve of a few segments ending at a corner inside the face, which costs
/// irregular vertices and small pieces for a fold the quads barely cross;
/// the sharp fragments of the cow and the bunny (2 to 8 edges, 1.7 to 7.9
/// mean edges long) gave 43 and 30 inverted quads. fandisk's creases are 31
/// and 44 long.
pub const MIN_CUT_CREASE_EDGES: f64 = 10.0;

/// True when the inner edges of `curve` (those `inner` accepts) are at
/// least `shortest` long and turn the normal by at least
/// [`MIN_CUT_CREASE_ANGLE_DEG`] on average (by length).
fn is_sharp_crease(
    mesh: &TriMesh,
    topo: &Topology,
    curve: &FeatureCurve,
    inner: &dyn Fn(EdgeId) -> bool,
    shortest: f64,
) -> bool {
    let (mut length, mut turned) = (0.0, 0.0);
    for &e in curve.edges.iter().filter(|&&e| inner(e)) {
        let &[f, g] = topo.edge_faces(e) else { continue };
        let [a, b] = topo.edges[e.idx()];
        let l = (mesh.position(b) - mesh.position(a)).norm();
        length += l;
        turned += l * dihedral_angle(mesh, f, g);
    }
    length > 0.0 && length >= shortest && turned >= MIN_CUT_CREASE_ANGLE_DEG.to_radians() * length
}

/// Per triangle, the label of the seed its model face is grown from first
/// (breadth first across non-feature edges, seeds in order; the first seed
/// of a triangle wins); `u32::MAX` in faces without seeds.
fn grow_labels(topo: &Topology, features: &Features, face_of: &[u32], seeds: &[(FaceId, u32)]) -> Vec<u32> {
    let mut label = vec![u32::MAX; face_of.len()];
    let mut queue = VecDeque::with_capacity(seeds.len());
    for &(f, l) in seeds {
        if label[f.idx()] == u32::MAX {
            label[f.idx()] = l;
            queue.push_back(f);
        }
    }
    while let Some(f) = queue.pop_front() {
        for i in 0..3 {
            if features.is_feature_edge[topo.face_edges[f.idx()][i].idx()] {
                continue;
            }
            let Some(g) = topo.face_across(f, i) else { continue };
            if label[g.idx()] == u32::MAX && face_of[g.idx()] == face_of[f.idx()] {
                label[g.idx()] = label[f.idx()];
                queue.push_back(g);
            }
        }
    }
    label
}

/// The connected parts of `faces` (one model face) of equal `label`,
/// joined across non-feature edges, in order of their first triangle.
fn connected_pieces(topo: &Topology, features: &Features, label: &[u32], faces: &[FaceId]) -> Vec<Vec<FaceId>> {
    let mut piece_of: std::collections::HashMap<FaceId, usize> = std::collections::HashMap::new();
    let in_face: std::collections::HashSet<FaceId> = faces.iter().copied().collect();
    let mut pieces: Vec<Vec<FaceId>> = Vec::new();
    for &start in faces {
        if piece_of.contains_key(&start) {
            continue;
        }
        let id = pieces.len();
        piece_of.insert(start, id);
        let mut piece = vec![start];
        let mut next = 0;
        while next < piece.len() {
            let f = piece[next];
            next += 1;
            for i in 0..3 {
                let e: EdgeId = topo.face_edges[f.idx()][i];
                if features.is_feature_edge[e.idx()] {
                    continue;
                }
                let Some(g) = topo.face_across(f, i) else { continue };
                if in_face.contains(&g) && label[g.idx()] == label[f.idx()] && !piece_of.contains_key(&g) {
                    piece_of.insert(g, id);
                    piece.push(g);
                }
            }
        }
        piece.sort_unstable();
        pieces.push(piece);
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::features::{detect_features, model_faces};
    use crate::mesh::fixtures;

    /// The plate of [`fixtures::folded_plate`] with 32 cells: its crease
    /// (y = ½, x < 0.82) is 88° on average and 16 mean edges long.
    #[test]
    fn a_crease_ending_inside_a_face_separates_two_pieces() {
        let mesh = fixtures::folded_plate(32);
        let topo = Topology::new(&mesh);
        let features = detect_features(&mesh, &topo, 40.0);
        let faces = model_faces(&topo, &features).faces_per_component();
        assert_eq!(faces.len(), 1);
        let cut = cut_along_inner_creases(&mesh, &topo, &features, faces);
        assert_eq!((cut.pieces.len(), cut.n_faces_cut), (2, 1));
        assert_eq!(cut.pieces.iter().map(Vec::len).sum::<usize>(), mesh.n_faces());
        // Every feature edge on y = ½ is cut, and only they (the fold's
        // end at x = 1 is sharper than 40° near the plate's sides, but
        // those fragments are short).
        let on_crease = |e: usize| topo.edges[e].iter().all(|&v| (mesh.position(v).y - 0.5).abs() < 1e-12);
        let crease: Vec<usize> = (0..topo.n_edges()).filter(|&e| features.is_feature_edge[e] && on_crease(e)).collect();
        assert!(crease.len() >= 12, "{crease:?}");
        let cut_edges: Vec<usize> = (0..topo.n_edges()).filter(|&e| cut.is_cut_crease[e]).collect();
        assert_eq!(cut_edges, crease);
    }

    /// The same plate folded half as much (`z = (1 − x)₊ |y − ½|`): 90° at
    /// `x = 0`, 66° on average over its feature edges, below
    /// [`MIN_CUT_CREASE_ANGLE_DEG`], so the face stays whole.
    #[test]
    fn a_blunt_crease_is_not_cut() {
        let mut mesh = fixtures::folded_plate(32);
        for p in &mut mesh.positions {
            p.z /= 2.0;
        }
        let topo = Topology::new(&mesh);
        let features = detect_features(&mesh, &topo, 40.0);
        assert!(features.curves.iter().any(|c| c.edges.iter().any(|&e| !topo.is_boundary_edge(e))));
        let faces = model_faces(&topo, &features).faces_per_component();
        let cut = cut_along_inner_creases(&mesh, &topo, &features, faces.clone());
        assert_eq!(cut, CreaseCut { pieces: faces, n_faces_cut: 0, is_cut_crease: Vec::new() });
    }

    #[test]
    fn faces_without_inner_creases_are_kept_whole() {
        let mesh = crate::mesh::fixtures::cube(3);
        let topo = Topology::new(&mesh);
        let features = detect_features(&mesh, &topo, 30.0);
        let faces = model_faces(&topo, &features).faces_per_component();
        let cut = cut_along_inner_creases(&mesh, &topo, &features, faces.clone());
        assert_eq!(cut, CreaseCut { pieces: faces, n_faces_cut: 0, is_cut_crease: Vec::new() });
    }
}
