//! The model a quad mesh is classified on: the feature corners, the feature
//! curves and the model faces bounded by them (thesis ch. 2 §4.1). The
//! seams the atlas cut to get disks are not part of it: the mesh crosses
//! them.
//!
//! Only the feature curves that separate two model faces, lie on the
//! boundary or on a non-manifold edge, or that the atlas cut its patches
//! along ([`Features::is_cut_crease`], [`crate::atlas::creases`]) are
//! kept. A cut crease has the same model face on both sides (it is
//! two-sided for the parity) and the quads follow it. A crease the atlas
//! did not cut along (too blunt, or a model built without an atlas)
//! bounds nothing: no atlas curve carries it, and the quads cross it like
//! a seam.
//!
//! A curve is also split where a chord would cut a visible part of a
//! face: a vertex whose triangle with its two curve neighbours (the area a
//! chord over it cuts off) exceeds [`PIN_AREA_FRACTION`] of the smallest
//! face it bounds becomes a corner (all three vertices of a one-triangle
//! face do). As a corner it is a fixed mesh vertex: a curve vertex may be
//! slid along the curve by smoothing, and the chord would come back.
//! Other turns only start a mesh vertex on the curve, free to slide
//! ([`super::curves`]): pinning every turn of a jagged hole boundary
//! (bunny's turn by 40–156°, at edges down to a quarter of the quad size)
//! would fix the mesh to the input's zigzag, where cutting a spike costs no
//! visible area.

use crate::atlas::features::{Features, edge_chains_with_corners, model_faces};
use crate::geom::triangle_area;
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh, VertexId};

/// Fraction of a model face's area whose loss to a chord makes the cut
/// vertex a corner: half the coverage check's tolerance
/// ([`super::check::AREA_TOLERANCE`]), so that no single chord can fail it.
pub const PIN_AREA_FRACTION: f64 = 0.01;

/// Corners, curves and faces of the feature model of a surface.
#[derive(Debug, Clone)]
pub struct QuadModel {
    /// Corner vertices (of the repaired surface), sorted; model corner `i`
    /// is `corners[i]`.
    pub corners: Vec<VertexId>,
    /// Feature curves as chains of surface vertices and edges (a closed
    /// curve repeats its first vertex at the end); model curve `i` is
    /// `features.curves[i]`.
    pub features: Features,
    /// Model face of each surface triangle.
    pub face_per_triangle: Vec<u32>,
    /// Number of model faces.
    pub n_faces: usize,
    /// Area of each model face.
    pub face_area: Vec<f64>,
    /// For each curve, the model faces on either side (one for a boundary
    /// curve, more for a non-manifold one), sorted and deduplicated.
    pub faces_per_curve: Vec<Vec<u32>>,
}

impl QuadModel {
    /// Model corner index of surface vertex `v`, if it is a corner.
    pub fn corner_of(&self, v: VertexId) -> Option<u32> {
        self.corners.binary_search(&v).ok().map(|i| i as u32)
    }
}

/// The feature model of a surface with feature edges `features` (as the
/// atlas detected them), keeping the separating curves and the cut
/// creases only (module documentation), split at the vertices a chord
/// would cut off.
pub fn quad_model(surface: &TriMesh, topo: &Topology, features: &Features) -> QuadModel {
    let faces = model_faces(topo, features);
    let face_area = face_areas(surface, &faces.component_per_face, faces.n_components);
    let features = separating_features(surface, topo, features, &faces.component_per_face, &face_area);
    let features = &features;
    let faces_per_curve = features
        .curves
        .iter()
        .map(|c| {
            let mut f: Vec<u32> = c
                .edges
                .iter()
                .flat_map(|&e| topo.edge_faces(e).iter().map(|t| faces.component_per_face[t.idx()]))
                .collect();
            f.sort_unstable();
            f.dedup();
            f
        })
        .collect();
    QuadModel {
        corners: features.corners.clone(),
        features: features.clone(),
        face_per_triangle: faces.component_per_face,
        n_faces: faces.n_components,
        face_area,
        faces_per_curve,
    }
}

/// The features of `features` without the edges whose two triangles lie in
/// the same model face (`face_per_triangle`, areas `face_area`) and that
/// the atlas did not cut along, curves and corners rebuilt with a corner at
/// every pinned vertex ([`pinned_vertices`]). Dropping the edges leaves the
/// model faces unchanged: they separate nothing.
fn separating_features(
    surface: &TriMesh,
    topo: &Topology,
    features: &Features,
    face_per_triangle: &[u32],
    face_area: &[f64],
) -> Features {
    let separates = |e: usize| match topo.edge_faces(EdgeId::new(e)) {
        [f, g] => {
            face_per_triangle[f.idx()] != face_per_triangle[g.idx()]
                || features.is_cut_crease.get(e).copied().unwrap_or(false)
        }
        _ => true,
    };
    let is_feature_edge: Vec<bool> =
        features.is_feature_edge.iter().enumerate().map(|(e, &flag)| flag && separates(e)).collect();
    let pinned = pinned_vertices(surface, topo, &is_feature_edge, face_per_triangle, face_area);
    if is_feature_edge == features.is_feature_edge && pinned.iter().all(|&p| !p) {
        return features.clone();
    }
    let (corners, curves, curve_per_edge) = edge_chains_with_corners(topo, &is_feature_edge, &pinned);
    Features { is_feature_edge, corners, curves, curve_per_edge, ..features.clone() }
}

/// Per vertex: it has exactly two flagged edges, and the triangle it
/// forms with its two neighbours on them is larger than
/// [`PIN_AREA_FRACTION`] of the smallest adjacent model face (module
/// documentation; `face_area` the model faces' areas).
fn pinned_vertices(
    surface: &TriMesh,
    topo: &Topology,
    is_feature_edge: &[bool],
    face_per_triangle: &[u32],
    face_area: &[f64],
) -> Vec<bool> {
    let n = topo.n_vertices();
    let (mut count, mut other) = (vec![0u8; n], vec![[VertexId::new(0); 2]; n]);
    let mut smallest = vec![f64::INFINITY; n];
    for (e, _) in is_feature_edge.iter().enumerate().filter(|(_, f)| **f) {
        let area = topo
            .edge_faces(EdgeId::new(e))
            .iter()
            .map(|t| face_area[face_per_triangle[t.idx()] as usize])
            .fold(f64::INFINITY, f64::min);
        let [a, b] = topo.edges[e];
        for (v, w) in [(a, b), (b, a)] {
            let c = &mut count[v.idx()];
            if *c < 2 {
                other[v.idx()][*c as usize] = w;
            }
            *c = c.saturating_add(1);
            smallest[v.idx()] = smallest[v.idx()].min(area);
        }
    }
    (0..n)
        .map(|v| {
            count[v] == 2 && {
                let [p, r] = other[v].map(|w| surface.positions[w.idx()]);
                triangle_area(&p, &surface.positions[v], &r) > PIN_AREA_FRACTION * smallest[v]
            }
        })
        .collect()
}

/// Area of each of the `n_faces` model faces (`face_per_triangle` gives
/// the face of each surface triangle).
fn face_areas(surface: &TriMesh, face_per_triangle: &[u32], n_faces: usize) -> Vec<f64> {
    let mut area = vec![0.0; n_faces];
    for (t, &f) in face_per_triangle.iter().enumerate() {
        area[f as usize] += surface.face_area(FaceId::new(t));
    }
    area
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::features::detect_features;
    use crate::mesh::fixtures;

    #[test]
    fn a_cube_has_8_corners_12_curves_and_6_faces() {
        let mesh = fixtures::cube(4);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        assert_eq!(model.corners.len(), 8);
        assert_eq!(model.features.curves.len(), 12);
        assert_eq!(model.n_faces, 6);
        assert!(model.faces_per_curve.iter().all(|f| f.len() == 2));
    }

    /// A crease that ends inside a face separates nothing: one model face,
    /// no curve inside it; the boundary curves are the 8 rim edges.
    #[test]
    fn a_crease_ending_inside_a_face_is_not_a_model_curve() {
        // A fan of 8 triangles around the origin with its first rim vertex
        // lifted to z = 0.8: the spoke to it folds by 64°, its neighbours by
        // 49°, the other spokes are flat; at 55° only the first spoke is a
        // crease, from the rim to the centre.
        let mut positions = vec![crate::geom::Vec3::zeros()];
        for k in 0..8 {
            let a = std::f64::consts::TAU * f64::from(k) / 8.0;
            positions.push(crate::geom::Vec3::new(a.cos(), a.sin(), if k == 0 { 0.8 } else { 0.0 }));
        }
        let triangles =
            (0..8).map(|k| [VertexId::new(0), VertexId::new(1 + k), VertexId::new(1 + (k + 1) % 8)]).collect();
        let mesh = crate::mesh::TriMesh { positions, triangles };
        let topo = Topology::new(&mesh);
        let features = detect_features(&mesh, &topo, 55.0);
        let inside = |c: &crate::atlas::features::FeatureCurve| c.edges.iter().any(|&e| !topo.is_boundary_edge(e));
        assert!(features.curves.iter().any(inside), "the fixture has no interior crease");
        let model = quad_model(&mesh, &topo, &features);
        assert_eq!(model.n_faces, 1);
        assert!(!model.features.curves.iter().any(inside));
        let rim: usize = model.features.curves.iter().map(|c| c.edges.len()).sum();
        assert_eq!(rim, 8, "the rim is the only curve");
    }

    /// A strip of `n` triangles, `length` long and `width` wide, as one
    /// model face bounded by one closed feature curve (its boundary).
    fn strip(n: u32, length: f64, width: f64) -> TriMesh {
        let mut positions = Vec::new();
        for i in 0..=n {
            let x = length * f64::from(i) / f64::from(n);
            positions.push(crate::geom::Vec3::new(x, 0.0, 0.0));
            positions.push(crate::geom::Vec3::new(x, width, 0.0));
        }
        let v = |i: u32| VertexId::new(i as usize);
        let triangles = (0..n)
            .flat_map(|i| [[v(2 * i), v(2 * i + 2), v(2 * i + 3)], [v(2 * i), v(2 * i + 3), v(2 * i + 1)]])
            .collect();
        TriMesh { positions, triangles }
    }

    /// A one-triangle face: a chord over any vertex cuts the whole face, so
    /// all three are corners.
    #[test]
    fn every_vertex_of_a_one_triangle_face_is_a_corner() {
        let positions = vec![
            crate::geom::Vec3::zeros(),
            crate::geom::Vec3::new(4.0, 0.0, 0.0),
            crate::geom::Vec3::new(2.0, 0.01, 0.0),
        ];
        let mesh = TriMesh { positions, triangles: vec![[VertexId::new(0), VertexId::new(1), VertexId::new(2)]] };
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        assert_eq!(model.corners, (0..3).map(VertexId::new).collect::<Vec<_>>());
        assert_eq!(model.features.curves.len(), 3);
    }

    /// The vertices along a strip's sides lie on their chords (nothing cut
    /// off); a chord over a corner of the fine strip cuts `0.0625 / 2`, less
    /// than 1 % of its area 4: the boundary stays one closed curve. The
    /// coarse strip's corners cut `1 / 2` each, and are corners.
    #[test]
    fn a_fine_strip_keeps_one_curve_and_a_coarse_one_gets_its_corners() {
        let fine = strip(64, 4.0, 1.0);
        let topo = Topology::new(&fine);
        let model = quad_model(&fine, &topo, &detect_features(&fine, &topo, 30.0));
        assert_eq!(model.features.curves.len(), 1);
        assert_eq!(model.corners.len(), 1);
        let coarse = strip(4, 4.0, 1.0);
        let topo = Topology::new(&coarse);
        let model = quad_model(&coarse, &topo, &detect_features(&coarse, &topo, 30.0));
        assert_eq!(model.corners, [0, 1, 8, 9].map(VertexId::new).to_vec());
        assert_eq!(model.features.curves.len(), 4);
    }
}
