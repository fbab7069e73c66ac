//! Projection onto the input surface, its feature curves and its corners:
//! where the cleanup, smoothing and order-2 steps put every vertex they
//! move or create, so that the output lies on the input (issue 13 §4).
//!
//! - A point of model face `f` goes to the closest point of the triangles of
//!   `f` only (a bounding-volume hierarchy per model face,
//!   [`crate::frames::bvh::TriangleBvh`]), so a vertex never jumps across a
//!   feature curve to another face.
//! - A point of curve `c` goes to the closest point of `c`'s polyline. From a
//!   hint (the vertex's current [`SurfacePoint`]) the search walks along the
//!   polyline from the hinted segment while the distance decreases, in a
//!   window re-centred on the best segment; without a usable hint it scans
//!   the whole polyline. The result lies on a surface edge of the curve and
//!   is returned on the first triangle of that edge.
//! - A corner is its surface vertex.
//!
//! Closest points on triangles follow Ericson (Real-Time Collision Detection
//! §5.1.5); barycentric coordinates are clamped to `[0, 1]` and renormalized
//! so they are a valid [`SurfacePoint`].

use foldhash::HashMap;

use super::model::QuadModel;
use super::surface_mesh::{ModelEntity, SurfacePoint};
use crate::frames::bvh::TriangleBvh;
use crate::geom::Vec3;
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh, VertexId};

/// Half-width, in segments, of the window a hinted curve search scans
/// before re-centring on its best segment.
const CURVE_WINDOW: usize = 4;

/// A projected point: its position and where it lies on the input surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// 3D position (on the input surface).
    pub position: Vec3,
    /// The same point as barycentric coordinates on an input triangle.
    pub on_surface: SurfacePoint,
}

/// The triangles of one model face, with a hierarchy over them.
struct FaceIndex {
    /// Hierarchy over the face's triangles (local triangle ids).
    bvh: TriangleBvh,
    /// Input triangle of each local triangle.
    global: Vec<FaceId>,
}

/// Projects points onto the input surface, its curves and corners.
pub struct SurfaceProjector<'a> {
    /// The input surface.
    pub surface: &'a TriMesh,
    /// Its topology.
    pub topo: &'a Topology,
    /// Its feature model.
    pub model: &'a QuadModel,
    /// One index per model face.
    faces: Vec<FaceIndex>,
    /// Per curve: position in the curve of each of its surface vertices
    /// (the first one for the repeated vertex of a closed curve).
    index_per_curve_vertex: Vec<HashMap<VertexId, usize>>,
    /// Per surface edge: its segment index in its curve (`u32::MAX` off curves).
    segment_per_edge: Vec<u32>,
    /// Per curve: arc length from its first vertex to each of its vertices.
    arc_length_per_curve_vertex: Vec<Vec<f64>>,
    /// Unit normal of every input triangle ([`TriMesh::face_normals`]).
    face_normals: Vec<Vec3>,
}

impl<'a> SurfaceProjector<'a> {
    /// A projector onto `surface` with feature model `model` (one hierarchy
    /// per model face is built here, `O(n log n)` in all).
    pub fn new(surface: &'a TriMesh, topo: &'a Topology, model: &'a QuadModel) -> Self {
        let faces = face_indices(surface, model);
        let mut segment_per_edge = vec![u32::MAX; topo.n_edges()];
        let mut index_per_curve_vertex = Vec::with_capacity(model.features.curves.len());
        for curve in &model.features.curves {
            for (i, e) in curve.edges.iter().enumerate() {
                segment_per_edge[e.idx()] = i as u32;
            }
            let mut map = HashMap::with_capacity_and_hasher(curve.vertices.len(), Default::default());
            for (i, &v) in curve.vertices.iter().enumerate() {
                map.entry(v).or_insert(i);
            }
            index_per_curve_vertex.push(map);
        }
        let arc_length_per_curve_vertex = model
            .features
            .curves
            .iter()
            .map(|c| {
                let mut acc = 0.0;
                let mut out = vec![0.0];
                for w in c.vertices.windows(2) {
                    acc += (surface.positions[w[1].idx()] - surface.positions[w[0].idx()]).norm();
                    out.push(acc);
                }
                out
            })
            .collect();
        let face_normals = surface.face_normals();
        Self {
            surface,
            topo,
            model,
            faces,
            index_per_curve_vertex,
            segment_per_edge,
            arc_length_per_curve_vertex,
            face_normals,
        }
    }

    /// The projection of `x` onto the entity `entity`: the closest point of
    /// its model face, the closest point of its curve (searched from
    /// `hint`), or the corner itself. Falls back to `hint` (evaluated on the
    /// surface) only for an entity index out of range.
    pub fn project(&self, entity: ModelEntity, x: &Vec3, hint: &SurfacePoint) -> Projection {
        let found = match entity {
            ModelEntity::Corner(i) => self.corner(i),
            ModelEntity::Curve(c) => self.project_to_curve(c, x, Some(hint)),
            ModelEntity::Face(f) => self.project_to_face(f, x),
        };
        found.unwrap_or_else(|| Projection { position: self.position_of(hint), on_surface: *hint })
    }

    /// The closest point to `x` on the triangles of model face `face`
    /// (`None` when the face does not exist).
    pub fn project_to_face(&self, face: u32, x: &Vec3) -> Option<Projection> {
        let index = self.faces.get(face as usize)?;
        let (_, p, local) = index.bvh.closest_point(x)?;
        let f = index.global[local as usize];
        Some(Projection { position: p, on_surface: SurfacePoint { face: f, bary: self.barycentric(f, &p) } })
    }

    /// The closest point to `x` on the polyline of curve `curve` (`None`
    /// when the curve does not exist or has no edge). With a `hint` on or
    /// next to the curve the search is local, `O(distance moved)`.
    pub fn project_to_curve(&self, curve: u32, x: &Vec3, hint: Option<&SurfacePoint>) -> Option<Projection> {
        let (seg, t) = self.closest_on_curve(curve, x, hint)?;
        Some(self.curve_point(curve, seg, t))
    }

    /// Arc length from the start of curve `curve` to the point of the curve
    /// closest to `x` (searched from `hint` as in
    /// [`SurfaceProjector::project_to_curve`]).
    pub fn curve_arc_length(&self, curve: u32, x: &Vec3, hint: Option<&SurfacePoint>) -> Option<f64> {
        let (seg, t) = self.closest_on_curve(curve, x, hint)?;
        let s = &self.arc_length_per_curve_vertex[curve as usize];
        Some(s[seg] + t * (s[seg + 1] - s[seg]))
    }

    /// Length of curve `curve` (0 for a curve that does not exist).
    pub fn curve_length(&self, curve: u32) -> f64 {
        self.arc_length_per_curve_vertex.get(curve as usize).and_then(|s| s.last().copied()).unwrap_or(0.0)
    }

    /// Area between curve `curve` from arc length `s0` to `s1` (`s0 ≤ s1`,
    /// no wrap) and the chord joining its two ends: the fan of triangles
    /// from the chord's start over the polyline's points between (exact for
    /// a planar convex arc). It is what a quad edge cutting the curve there
    /// takes from the face's area.
    pub fn chord_area(&self, curve: u32, s0: f64, s1: f64) -> f64 {
        let (Some(a), Some(b)) = (self.curve_point_at(curve, s0), self.curve_point_at(curve, s1)) else { return 0.0 };
        let c = &self.model.features.curves[curve as usize];
        let lengths = &self.arc_length_per_curve_vertex[curve as usize];
        let inside = lengths.partition_point(|&l| l <= s0)..lengths.partition_point(|&l| l < s1);
        let mut previous = a.position;
        let mut area = 0.0;
        for p in c.vertices[inside].iter().map(|v| self.surface.positions[v.idx()]).chain([b.position]) {
            area += 0.5 * (previous - a.position).cross(&(p - a.position)).norm();
            previous = p;
        }
        area
    }

    /// The point of curve `curve` at arc length `s` from its start (clamped
    /// to the curve; wrapped for a closed curve).
    pub fn curve_point_at(&self, curve: u32, s: f64) -> Option<Projection> {
        let c = self.model.features.curves.get(curve as usize)?;
        let lengths = &self.arc_length_per_curve_vertex[curve as usize];
        let total = *lengths.last()?;
        if c.edges.is_empty() {
            return None;
        }
        let s = if c.is_closed() && total > 0.0 { s.rem_euclid(total) } else { s.clamp(0.0, total) };
        let seg = lengths.partition_point(|&l| l <= s).saturating_sub(1).min(c.edges.len() - 1);
        let len = lengths[seg + 1] - lengths[seg];
        let t = if len > 0.0 { ((s - lengths[seg]) / len).clamp(0.0, 1.0) } else { 0.0 };
        Some(self.curve_point(curve, seg, t))
    }

    /// `(segment, parameter)` of the point of curve `curve` closest to `x`.
    fn closest_on_curve(&self, curve: u32, x: &Vec3, hint: Option<&SurfacePoint>) -> Option<(usize, f64)> {
        let n = self.model.features.curves.get(curve as usize)?.edges.len();
        if n == 0 {
            return None;
        }
        // The walk finds a local minimum; one farther than the hint itself
        // started in the wrong place (a hint on a large triangle whose curve
        // vertex is far along the curve), so the whole curve is scanned.
        let walked = hint.and_then(|h| {
            let (seg, t) = self.walk_curve(curve, x, self.hinted_segment(curve, h)?);
            let walked_distance = self.segment_closest(curve, seg, x).1;
            (walked_distance <= (self.position_of(h) - x).norm() * (1.0 + 1e-9) + 1e-12).then_some((seg, t))
        });
        match walked {
            Some(found) => Some(found),
            None => (0..n)
                .map(|s| (s, self.segment_closest(curve, s, x)))
                .min_by(|a, b| a.1.1.total_cmp(&b.1.1))
                .map(|(s, (t, _))| (s, t)),
        }
    }

    /// The surface point of model corner `corner` (`None` when it does not
    /// exist).
    pub fn corner(&self, corner: u32) -> Option<Projection> {
        let v = *self.model.corners.get(corner as usize)?;
        let f = *self.topo.vertex_faces(v).first()?;
        let slot = self.surface.triangles[f.idx()].iter().position(|&w| w == v)?;
        let mut bary = [0.0; 3];
        bary[slot] = 1.0;
        Some(Projection { position: self.surface.positions[v.idx()], on_surface: SurfacePoint { face: f, bary } })
    }

    /// 3D position of the surface point `p`.
    pub fn position_of(&self, p: &SurfacePoint) -> Vec3 {
        let [a, b, c] = self.surface.corners(p.face);
        a * p.bary[0] + b * p.bary[1] + c * p.bary[2]
    }

    /// Unit normal of the input triangle carrying `p`.
    pub fn normal_at(&self, p: &SurfacePoint) -> Vec3 {
        self.face_normals[p.face.idx()]
    }

    /// Unit normal of every input triangle, in triangle order.
    pub fn face_normals(&self) -> &[Vec3] {
        &self.face_normals
    }

    /// Barycentric coordinates of `p` (a point of triangle `f` or near it)
    /// on `f`, clamped to the triangle and summing to 1.
    fn barycentric(&self, f: FaceId, p: &Vec3) -> [f64; 3] {
        let [a, b, c] = self.surface.corners(f);
        let (v0, v1, v2) = (b - a, c - a, p - a);
        let (d00, d01, d11) = (v0.dot(&v0), v0.dot(&v1), v1.dot(&v1));
        let (d20, d21) = (v2.dot(&v0), v2.dot(&v1));
        let den = d00 * d11 - d01 * d01;
        if !(den > 0.0) {
            return [1.0, 0.0, 0.0];
        }
        let v = (d11 * d20 - d01 * d21) / den;
        let w = (d00 * d21 - d01 * d20) / den;
        let mut l = [(1.0 - v - w).max(0.0), v.max(0.0), w.max(0.0)];
        let s: f64 = l.iter().sum();
        if s > 0.0 {
            l.iter_mut().for_each(|x| *x /= s);
        } else {
            l = [1.0, 0.0, 0.0];
        }
        l
    }

    /// A segment of curve `curve` next to the surface point `h`: an edge of
    /// `h`'s triangle on the curve, else a curve vertex of that triangle.
    fn hinted_segment(&self, curve: u32, h: &SurfacePoint) -> Option<usize> {
        let f = h.face.idx();
        let c = &self.model.features.curves[curve as usize];
        let on_curve = |e: EdgeId| {
            let s = self.segment_per_edge[e.idx()];
            (s != u32::MAX && c.edges.get(s as usize) == Some(&e)).then_some(s as usize)
        };
        if let Some(s) = self.topo.face_edges.get(f)?.iter().filter_map(|&e| on_curve(e)).next() {
            return Some(s);
        }
        let map = &self.index_per_curve_vertex[curve as usize];
        let i = self.surface.triangles[f].iter().filter_map(|v| map.get(v)).next()?;
        Some((*i).min(c.edges.len() - 1))
    }

    /// Local search along curve `curve` from segment `start`: scans a window
    /// of [`CURVE_WINDOW`] segments each side, re-centres on the best one
    /// until it stops moving. Returns `(segment, parameter)`.
    fn walk_curve(&self, curve: u32, x: &Vec3, start: usize) -> (usize, f64) {
        let c = &self.model.features.curves[curve as usize];
        let n = c.edges.len();
        let closed = c.is_closed();
        let mut centre = start;
        let (mut best_t, mut best_d) = self.segment_closest(curve, centre, x);
        for _ in 0..n {
            let mut moved = false;
            for k in 1..=CURVE_WINDOW {
                for s in [shift(centre, k as isize, n, closed), shift(centre, -(k as isize), n, closed)]
                    .into_iter()
                    .flatten()
                {
                    let (t, d) = self.segment_closest(curve, s, x);
                    if d < best_d {
                        (best_t, best_d) = (t, d);
                        centre = s;
                        moved = true;
                    }
                }
            }
            if !moved {
                break;
            }
        }
        (centre, best_t)
    }

    /// Closest point of segment `s` of curve `curve` to `x`: `(parameter
    /// from the segment's first vertex, distance)`.
    fn segment_closest(&self, curve: u32, s: usize, x: &Vec3) -> (f64, f64) {
        let c = &self.model.features.curves[curve as usize];
        let (a, b) = (self.surface.positions[c.vertices[s].idx()], self.surface.positions[c.vertices[s + 1].idx()]);
        let d = b - a;
        let l2 = d.norm_squared();
        let t = if l2 > 0.0 { ((x - a).dot(&d) / l2).clamp(0.0, 1.0) } else { 0.0 };
        (t, (a + d * t - x).norm())
    }

    /// The point at parameter `t` of segment `s` of curve `curve`, on the
    /// first triangle of the segment's surface edge.
    fn curve_point(&self, curve: u32, s: usize, t: f64) -> Projection {
        let c = &self.model.features.curves[curve as usize];
        let (va, vb) = (c.vertices[s], c.vertices[s + 1]);
        let position = self.surface.positions[va.idx()] * (1.0 - t) + self.surface.positions[vb.idx()] * t;
        let e = c.edges[s];
        let f = self.topo.edge_faces(e)[0];
        let tri = self.surface.triangles[f.idx()];
        let mut bary = [0.0; 3];
        for (k, &w) in tri.iter().enumerate() {
            if w == va {
                bary[k] = 1.0 - t;
            } else if w == vb {
                bary[k] = t;
            }
        }
        Projection { position, on_surface: SurfacePoint { face: f, bary } }
    }
}

/// Segment `s + k` of a curve of `n` segments: wrapped for a closed curve,
/// `None` past the ends of an open one.
fn shift(s: usize, k: isize, n: usize, closed: bool) -> Option<usize> {
    let j = s as isize + k;
    if closed { Some(j.rem_euclid(n as isize) as usize) } else { (0..n as isize).contains(&j).then_some(j as usize) }
}

/// One [`FaceIndex`] per model face: its triangles as a compact mesh and a
/// hierarchy over them.
fn face_indices(surface: &TriMesh, model: &QuadModel) -> Vec<FaceIndex> {
    let mut per_face: Vec<Vec<FaceId>> = vec![Vec::new(); model.n_faces];
    for (t, &f) in model.face_per_triangle.iter().enumerate() {
        if let Some(list) = per_face.get_mut(f as usize) {
            list.push(FaceId::new(t));
        }
    }
    per_face
        .into_iter()
        .map(|global| {
            let mut local_of: HashMap<VertexId, u32> = HashMap::default();
            let mut positions = Vec::new();
            let mut tris = Vec::with_capacity(global.len());
            for f in &global {
                let tri = surface.triangles[f.idx()].map(|v| {
                    *local_of.entry(v).or_insert_with(|| {
                        positions.push(surface.positions[v.idx()]);
                        (positions.len() - 1) as u32
                    })
                });
                tris.push(tri);
            }
            FaceIndex { bvh: TriangleBvh::new(&TriMesh::from_raw(positions, &tris)), global }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::features::detect_features;
    use crate::mesh::fixtures;
    use crate::quads::model::quad_model;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// On a regular `N`-gon of radius `r`, the area between `k` sides and
    /// their chord is the circular segment of the polygon,
    /// `r²/2 (k sin θ − sin kθ)` with `θ = 2π/N`; between points inside two
    /// sides the fan is exact too, and a straight side cuts nothing.
    #[test]
    fn the_chord_area_of_a_regular_polygon_is_its_segment() {
        let (r, n) = (1.5, 48);
        let mesh = fixtures::cylinder(r, 2.0, n, 4);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        let proj = SurfaceProjector::new(&mesh, &topo, &model);
        let theta = std::f64::consts::TAU / n as f64;
        let side = 2.0 * r * (theta / 2.0).sin();
        assert!((proj.curve_length(0) - n as f64 * side).abs() < 1e-9);
        for k in [1, 2, 5, 12] {
            let expected = 0.5 * r * r * (k as f64 * theta.sin() - (k as f64 * theta).sin());
            for start in [0.0, 3.0 * side] {
                let got = proj.chord_area(0, start, start + k as f64 * side);
                assert!((got - expected).abs() < 1e-9 * r * r, "k = {k}: {got} against {expected}");
            }
        }
        // Within one side the curve is its own chord.
        assert!(proj.chord_area(0, 0.2 * side, 0.7 * side) < 1e-12);
        // From the middle of a side to the middle of the next: one triangle
        // of half sides meeting at the polygon's angle π − θ.
        let half = 0.5 * side;
        let expected = 0.5 * half * half * theta.sin();
        assert!((proj.chord_area(0, half, 3.0 * half) - expected).abs() < 1e-12);
    }

    #[test]
    fn points_above_a_square_project_straight_down_onto_it() {
        let mesh = fixtures::square(6);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        let proj = SurfaceProjector::new(&mesh, &topo, &model);
        let mut rng = StdRng::seed_from_u64(5);
        for _ in 0..100 {
            let (x, y) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
            let p = proj.project_to_face(0, &Vec3::new(x, y, rng.random_range(-0.3..0.3))).unwrap();
            assert!((p.position - Vec3::new(x, y, 0.0)).norm() < 1e-12);
            assert!((proj.position_of(&p.on_surface) - p.position).norm() < 1e-12);
            assert!(
                p.on_surface.bary.iter().all(|&b| b >= 0.0)
                    && (p.on_surface.bary.iter().sum::<f64>() - 1.0).abs() < 1e-12
            );
        }
    }

    #[test]
    fn a_point_near_a_cube_edge_stays_on_its_own_face() {
        let mesh = fixtures::cube(4);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        let proj = SurfaceProjector::new(&mesh, &topo, &model);
        // The face z = 1 and a point beyond its edge x = 1, nearer the face x = 1.
        let top =
            model.face_per_triangle[(0..mesh.n_faces()).find(|&t| mesh.face_normal(FaceId::new(t)).z > 0.9).unwrap()];
        let p = proj.project_to_face(top, &Vec3::new(1.3, 0.2, 0.9)).unwrap();
        assert!((p.position - Vec3::new(1.0, 0.2, 1.0)).norm() < 1e-12);
        assert_eq!(model.face_per_triangle[p.on_surface.face.idx()], top);
    }

    #[test]
    fn curve_projection_lands_on_the_curve_locally_and_by_full_scan() {
        let mesh = fixtures::cube(6);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        let proj = SurfaceProjector::new(&mesh, &topo, &model);
        let mut rng = StdRng::seed_from_u64(9);
        for (c, curve) in model.features.curves.iter().enumerate() {
            let [a, b] = [curve.vertices[0], curve.vertices[curve.vertices.len() - 1]].map(|v| mesh.positions[v.idx()]);
            for _ in 0..20 {
                let t = rng.random_range(0.05..0.95);
                let on = a + (b - a) * t;
                let off = on
                    + Vec3::new(rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1));
                let full = proj.project_to_curve(c as u32, &off, None).unwrap();
                // A hint at the curve's start: the walk must travel the whole way.
                let start = proj.project_to_curve(c as u32, &a, None).unwrap().on_surface;
                let walked = proj.project_to_curve(c as u32, &off, Some(&start)).unwrap();
                for p in [full, walked] {
                    let d = (b - a).normalize();
                    let along = (p.position - a).dot(&d);
                    assert!((a + d * along - p.position).norm() < 1e-12, "off the curve");
                    assert!((proj.position_of(&p.on_surface) - p.position).norm() < 1e-12);
                }
                assert!((full.position - walked.position).norm() < 1e-12);
                let s = proj.curve_arc_length(c as u32, &off, Some(&start)).unwrap();
                assert!((proj.curve_point_at(c as u32, s).unwrap().position - full.position).norm() < 1e-12);
            }
        }
    }

    #[test]
    fn arc_length_wraps_around_the_closed_boundary_of_a_square() {
        // Fine enough that its corners stay inside one closed curve.
        let mesh = fixtures::square(8);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        assert_eq!(model.features.curves.len(), 1);
        let proj = SurfaceProjector::new(&mesh, &topo, &model);
        assert!((proj.curve_length(0) - 4.0).abs() < 1e-12);
        let start = proj.curve_point_at(0, 0.0).unwrap();
        for k in 0..16 {
            let s = 0.3 + 0.25 * k as f64;
            let p = proj.curve_point_at(0, s).unwrap();
            let r = s.rem_euclid(4.0);
            let back = proj.curve_arc_length(0, &p.position, Some(&start.on_surface)).unwrap();
            assert!((back - r).abs() < 1e-12 || (back - r).abs() > 4.0 - 1e-12, "{s}: {back}");
            let q = p.position;
            assert!(q.x.abs() < 1e-12 || (q.x - 1.0).abs() < 1e-12 || q.y.abs() < 1e-12 || (q.y - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn points_near_an_icosphere_land_on_its_facets() {
        let mesh = fixtures::icosphere(3);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        assert_eq!(model.n_faces, 1);
        let proj = SurfaceProjector::new(&mesh, &topo, &model);
        // Every facet is at least this far from the centre.
        let inner = (0..mesh.n_faces())
            .map(|f| mesh.face_normal(FaceId::new(f)).dot(&mesh.corners(FaceId::new(f))[0]))
            .fold(f64::INFINITY, f64::min);
        let mut rng = StdRng::seed_from_u64(17);
        for _ in 0..200 {
            let d = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            if d.norm() < 0.1 {
                continue;
            }
            let x = d.normalize() * rng.random_range(0.8..1.2);
            let p = proj.project_to_face(0, &x).unwrap();
            let r = p.position.norm();
            assert!(r <= 1.0 + 1e-12 && r >= inner - 1e-12, "radius {r}");
            assert!((p.position.normalize() - x.normalize()).norm() < 0.1, "a nearby facet");
            assert!((proj.position_of(&p.on_surface) - p.position).norm() < 1e-12);
        }
    }

    #[test]
    fn a_corner_is_its_surface_vertex() {
        let mesh = fixtures::cube(2);
        let topo = Topology::new(&mesh);
        let model = quad_model(&mesh, &topo, &detect_features(&mesh, &topo, 30.0));
        let proj = SurfaceProjector::new(&mesh, &topo, &model);
        for (i, &v) in model.corners.iter().enumerate() {
            let p = proj.project(ModelEntity::Corner(i as u32), &Vec3::zeros(), &proj.corner(0).unwrap().on_surface);
            assert_eq!(p.position, mesh.positions[v.idx()]);
            assert_eq!(proj.position_of(&p.on_surface), p.position);
        }
    }
}
