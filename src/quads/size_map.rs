//! The conformal size map of a crossfield: the edge length `h(x)` at which
//! the cross's two directions, scaled by `1/h`, are the gradients of a
//! parameterization, so fronts placed along the cross at the local size
//! close up without adding rows (a torus needs longer quads on its outer
//! equator; a constant size there forces irregular vertices).
//!
//! Math. Write the cross as `u₁ = cos θ e₁ + sin θ e₂` in a local frame and
//! `G = ∇θ` for its covariant gradient (the frame's connection included).
//! The scaled frame `(u₁/h, u₂/h)` is closed (integrable) exactly when
//! `∇ log h = G × n`; on the plane with the polar cross (`θ` = polar angle)
//! this gives `h ∝ r`, the spacing of the grid of `log z`. Away from the
//! singularities this holds exactly for a smooth field; in general `log h`
//! is its least-squares solution, the Neumann problem
//! `∫ ∇ψ · ∇φᵢ = ∫ (G × n) · ∇φᵢ` with P1 `ψ = log h` (pinned at one vertex
//! per connected component). This is the conformal scaling of Gmsh's
//! quasi-structured mesher (`computeCrossFieldConformalScaling`).
//!
//! Discretization. In each triangle the crossfield's Crouzeix–Raviart
//! values, brought into the triangle frame (thesis ch. 3 §5, `F = r f`), give
//! the angles `Θₖ = arg(Fₖ)/4` at the edge midpoints, lifted to the branch
//! nearest `Θ₀`; the CR interpolant of those angles is linear with corner
//! values `Θᵢ + Θᵢ₋₁ − Θᵢ₊₁`, and `G` is its gradient.
//!
//! `log h` diverges logarithmically at the singularities; when the field has
//! any inside the surface, it is clamped as in Gmsh to its 5 %–95 % quantile range per
//! component. It is then offset so
//! that `∫ h⁻² dA` (the number of quads) equals `area / size²`, the count a
//! constant size would give.
//!
//! Curvature bound ([`curvature_bounded_sizes`]). Quads are chords of the
//! surface. Across a bend of radius `1/κ` a quad edge of length `h` spans
//! the angle `κh` and its quads lose `≈ (κh)²/24` of the area; a flat face
//! bounded by a curve of curvature `κ` cut into chords of length `h` loses
//! `≈ (κh)²/6` (a polygon inscribed in a circle). The size is capped at
//! `2π / (N κ)` with `N` = [`SEGMENTS_PER_TURN_SURFACE`] where the surface
//! bends off the model curves (`κ` = the dihedral angle of an edge over the
//! mean height of its two triangles above it) and `N` =
//! [`SEGMENTS_PER_TURN_CURVE`] along the model curves (`κ` = the polyline's
//! turning angle over its mean edge length, where it is not a kept corner):
//! both deficits come to about 0.6 % and 1.1 %, under the coverage check's
//! 2 %. The cap is never below [`MIN_SIZE_FRACTION_SURFACE`] (bends) or
//! [`MIN_SIZE_FRACTION_CURVE`] (curves) of the size asked (a noisy scan
//! bends everywhere; a flat face bounded by a coarse circle needs the finer
//! curve), except on a small model face: its floor is lowered to what
//! [`QUADS_PER_SMALL_FACE`] quads of its area allow,
//! `√(area / QUADS_PER_SMALL_FACE) / size`, down to
//! [`MIN_SIZE_FRACTION_SMALL_FACE`] (the curves bounding it share its floor).
//! A thin pin or a small hole of a CAD part, narrower than the size asked,
//! is real geometry a quad must not wrap around (at a quarter of the size a
//! pin of radius `size / 16` gets under two quads per turn, whose corners'
//! normals are opposite), and the extra quads it costs are bounded by its
//! area (over the square of the lowest size below); a scan's noise on a
//! large face stays at the floor. Below that floor a small face's bend
//! still gets [`SEGMENTS_PER_TURN_SMALL_FACE`] edges per turn (down to
//! [`MIN_SIZE_FRACTION_TURN`] of the size asked): with about 6 or fewer
//! edges per turn a pin's triangulation has too few points around it for
//! its quads' corners to face one way (inverted quads), and 8 keep
//! neighbouring corners' normals within 45°. The cap is graded
//! (`h(x) ≤ h(y) + g |x − y|`, `g` = [`SIZE_GRADIENT`]) so the size
//! changes no faster than a front can follow; the curves' caps are graded
//! apart and slower ([`CURVE_SIZE_GRADIENT`]) into the faces they bound,
//! where a front leaving a convex curve converges.

use nalgebra::Complex;

use super::error::QuadsError;
use super::surface_mesh::SurfacePoint;
use crate::crossfield::Crossfield;
use crate::crossfield::frames::Discretization;
use crate::geom::Vec3;
use crate::linalg::{CholeskySolver, Triplets};
use crate::mesh::components::connected_components;
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh, VertexId};

use super::curves::SHARP_TURN_DEG;
use super::model::QuadModel;
use crate::atlas::features::dihedral_angle;
use crate::geom::{angle_between, barycentric_gradients};

/// Fraction of `log h` values clamped at each end, per component.
const QUANTILE: f64 = 0.05;

/// Quad edges per full turn where the surface bends, at least (module
/// documentation).
pub const SEGMENTS_PER_TURN_SURFACE: f64 = 16.0;

/// Quad edges per full turn of a model curve, at least (module
/// documentation).
pub const SEGMENTS_PER_TURN_CURVE: f64 = 24.0;

/// The bend cap never goes below this fraction of the size asked.
pub const MIN_SIZE_FRACTION_SURFACE: f64 = 0.25;

/// The curve cap never goes below this fraction of the size asked.
pub const MIN_SIZE_FRACTION_CURVE: f64 = 0.125;

/// The floor of a small model face's caps never goes below this fraction
/// of the size asked (module documentation).
pub const MIN_SIZE_FRACTION_SMALL_FACE: f64 = 0.06;

/// Quads a model face may get from following its curvature below the
/// floors of the size asked (module documentation).
pub const QUADS_PER_SMALL_FACE: f64 = 4096.0;

/// Quad edges per full turn of a small model face's bend, at least, below
/// its floor (module documentation).
pub const SEGMENTS_PER_TURN_SMALL_FACE: f64 = 8.0;

/// [`SEGMENTS_PER_TURN_SMALL_FACE`] never asks for edges shorter than this
/// fraction of the size asked.
pub const MIN_SIZE_FRACTION_TURN: f64 = 0.02;

/// Largest growth of the capped size per unit length.
pub const SIZE_GRADIENT: f64 = 0.5;

/// Largest growth per unit length of the size a curve's turning asks for,
/// into the faces it bounds: a front leaving a convex curve converges,
/// and a row that grows as well loses points next to the curve, where a
/// curve vertex left without an inward edge becomes a flat quad corner
/// (the caps of a cylinder).
pub const CURVE_SIZE_GRADIENT: f64 = 0.15;

/// Target edge length per surface vertex.
#[derive(Debug, Clone)]
pub struct SizeMap {
    /// Edge length at each vertex of the surface.
    pub size_per_vertex: Vec<f64>,
}

impl SizeMap {
    /// The same size everywhere.
    pub fn uniform(n_vertices: usize, size: f64) -> Self {
        Self { size_per_vertex: vec![size; n_vertices] }
    }

    /// The size at a point of the surface (linear on its triangle).
    pub fn at(&self, surface: &TriMesh, p: &SurfacePoint) -> f64 {
        let t = surface.triangles[p.face.idx()];
        (0..3).map(|i| p.bary[i] * self.size_per_vertex[t[i].idx()]).sum()
    }

    /// The size at the point `x` of surface triangle `face` (barycentric
    /// coordinates of its projection on the triangle's plane, clamped).
    pub fn at_position(&self, surface: &TriMesh, face: FaceId, x: &Vec3) -> f64 {
        let [a, b, c] = surface.corners(face);
        let (e1, e2, d) = (b - a, c - a, x - a);
        let (d11, d12, d22) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
        let det = d11 * d22 - d12 * d12;
        if !(det > 0.0) {
            let t = surface.triangles[face.idx()];
            return (0..3).map(|i| self.size_per_vertex[t[i].idx()]).sum::<f64>() / 3.0;
        }
        let (r1, r2) = (d.dot(&e1), d.dot(&e2));
        let l1 = ((d22 * r1 - d12 * r2) / det).clamp(0.0, 1.0);
        let l2 = ((d11 * r2 - d12 * r1) / det).clamp(0.0, 1.0 - l1);
        self.at(surface, &SurfacePoint { face, bary: [1.0 - l1 - l2, l1, l2] })
    }

    /// Smallest and largest size.
    pub fn range(&self) -> (f64, f64) {
        self.size_per_vertex.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &h| (lo.min(h), hi.max(h)))
    }
}

/// `G = ∇θ` of the cross in face `f` from the CR values in the triangle
/// frame (module documentation); `None` where the field vanishes.
fn cross_angle_gradient(big_f: &[Complex<f64>; 3], grads: &[Vec3; 3]) -> Option<Vec3> {
    if big_f.iter().any(|z| !(z.norm() > 1e-12)) {
        return None;
    }
    let theta0 = big_f[0].arg() / 4.0;
    let mid: [f64; 3] = std::array::from_fn(|k| theta0 + (big_f[k] * big_f[0].conj()).arg() / 4.0);
    let corner = |i: usize| mid[i] + mid[(i + 2) % 3] - mid[(i + 1) % 3];
    Some((0..3).map(|i| grads[i] * corner(i)).sum())
}

/// The conformal size map of `field` on `surface`, scaled so its quad count
/// matches the uniform `size` (module documentation).
///
/// # Errors
/// [`QuadsError::Triangulation`] (patch 0) when the Laplacian cannot be
/// factored.
pub fn conformal_size_map(
    surface: &TriMesh,
    topo: &Topology,
    field: &Crossfield,
    size: f64,
) -> Result<SizeMap, QuadsError> {
    size_map_of_edge_field(surface, topo, &field.f_per_edge, has_interior_singularity(topo, field), size)
}

/// [`conformal_size_map`] of the 4-symmetric field with edge-frame values
/// `f_per_edge` (`exp(4iθ)`, as [`Crossfield::f_per_edge`]); `clamp` clamps
/// `log h` to its quantile range (for fields with singularities).
///
/// # Errors
/// As [`conformal_size_map`].
pub fn size_map_of_edge_field(
    surface: &TriMesh,
    topo: &Topology,
    f_per_edge: &[[f64; 2]],
    clamp: bool,
    size: f64,
) -> Result<SizeMap, QuadsError> {
    let n_v = surface.n_vertices();
    let disc = Discretization::new(surface, topo, 4);
    let components = connected_components(topo);
    let pinned = pinned_vertices(surface, &components.component_per_face, components.n_components);
    let mut triplets = Triplets::new(n_v, n_v);
    let mut rhs = vec![0.0; n_v];
    for (f, fd) in disc.faces.iter().enumerate() {
        if fd.area == 0.0 {
            continue;
        }
        let face = FaceId::new(f);
        let t = surface.triangles[f];
        let p = surface.corners(face);
        let n = surface.face_normal(face);
        let grads = barycentric_gradients(&p, &n, fd.area);
        for i in 0..3 {
            for j in 0..3 {
                let (a, b) = (t[i].idx(), t[j].idx());
                if !pinned[a] && !pinned[b] {
                    triplets.push(a, b, fd.area * grads[i].dot(&grads[j]));
                }
            }
        }
        let edges = topo.face_edges[f];
        let big_f: [Complex<f64>; 3] = std::array::from_fn(|k| {
            let [re, im] = f_per_edge[edges[k].idx()];
            fd.rot[k] * Complex::new(re, im)
        });
        if let Some(g) = cross_angle_gradient(&big_f, &grads) {
            let w = g.cross(&n);
            for i in 0..3 {
                rhs[t[i].idx()] += fd.area * w.dot(&grads[i]);
            }
        }
    }
    for (v, &pin) in pinned.iter().enumerate() {
        if pin {
            triplets.push(v, v, 1.0);
            rhs[v] = 0.0;
        }
    }
    let factor_error = |e: crate::linalg::LinalgError| QuadsError::Triangulation {
        patch: 0,
        reason: format!("conformal size map: the surface Laplacian cannot be factored ({e})"),
    };
    let matrix = triplets.to_matrix().map_err(factor_error)?;
    let solver = CholeskySolver::new(&matrix).map_err(factor_error)?;
    let mut columns = vec![rhs];
    solver.solve_columns(&mut columns).map_err(factor_error)?;
    let mut log_h = columns.pop().unwrap_or_default();
    let vertex_component = vertex_components(surface, &components.component_per_face, n_v);
    if clamp {
        clamp_to_quantiles(&mut log_h, &vertex_component, components.n_components);
    }
    Ok(SizeMap {
        size_per_vertex: scaled_sizes(surface, &log_h, &components.component_per_face, components.n_components, size),
    })
}

/// `sizes` capped by the curvature of `surface` off and along the curves
/// of `model`, for the size `size` asked (module documentation).
pub fn curvature_bounded_sizes(
    sizes: SizeMap,
    surface: &TriMesh,
    topo: &Topology,
    model: &QuadModel,
    size: f64,
) -> SizeMap {
    let (surface_turns, curve_turns) = turns_per_length(surface, topo, model, size);
    let mut h = sizes.size_per_vertex;
    let capped = apply_caps(&mut h, &surface_turns);
    if capped {
        grade_sizes(surface, topo, &mut h, SIZE_GRADIENT);
    }
    let mut along_curves = vec![f64::INFINITY; h.len()];
    if apply_caps(&mut along_curves, &curve_turns) {
        grade_sizes(surface, topo, &mut along_curves, CURVE_SIZE_GRADIENT);
        for (hv, c) in h.iter_mut().zip(along_curves) {
            *hv = hv.min(c);
        }
    }
    SizeMap { size_per_vertex: h }
}

/// Lowers each `h` to `1 / turns` where that is smaller (`turns` 0: no
/// cap). Returns whether any was lowered.
fn apply_caps(h: &mut [f64], turns: &[f64]) -> bool {
    let mut capped = false;
    for (hv, &t) in h.iter_mut().zip(turns) {
        if t > 0.0 && 1.0 / t < *hv {
            *hv = 1.0 / t;
            capped = true;
        }
    }
    capped
}

/// Per vertex, the quad edges per unit length its curvature asks for
/// (`N κ / 2π`, each at most its floor's; module documentation), for the
/// size `size` asked: the largest over its non-curve edges (where the
/// surface bends), and, apart, on a model curve, the curve's turning.
fn turns_per_length(surface: &TriMesh, topo: &Topology, model: &QuadModel, size: f64) -> (Vec<f64>, Vec<f64>) {
    let mut turns = vec![0.0f64; surface.n_vertices()];
    let mut curve_turns = vec![0.0f64; surface.n_vertices()];
    let per_radian_surface = SEGMENTS_PER_TURN_SURFACE / std::f64::consts::TAU;
    let per_radian_curve = SEGMENTS_PER_TURN_CURVE / std::f64::consts::TAU;
    let per_radian_small_face = SEGMENTS_PER_TURN_SMALL_FACE / std::f64::consts::TAU;
    let face_floor = face_floor_fractions(model, size);
    let most_surface = |face: u32| 1.0 / (face_floor[face as usize] * size);
    let curve_floor: Vec<f64> = model
        .faces_per_curve
        .iter()
        .map(|faces| faces.iter().map(|&m| face_floor[m as usize]).fold(MIN_SIZE_FRACTION_CURVE, f64::min))
        .collect();
    for e in 0..topo.n_edges() {
        let edge = EdgeId::new(e);
        let &[f, g] = topo.edge_faces(edge) else { continue };
        if model.features.is_feature_edge[e] {
            continue;
        }
        let [a, b] = topo.edges[e];
        let length = (surface.position(b) - surface.position(a)).norm();
        if length == 0.0 {
            continue;
        }
        // Mean height of the two triangles over the edge: the width the
        // bend is spread over.
        let width = (surface.face_area(f) + surface.face_area(g)) / length;
        if width > 0.0 {
            let face = model.face_per_triangle[f.idx()];
            let kappa = dihedral_angle(surface, f, g) / width;
            let mut t = (per_radian_surface * kappa).min(most_surface(face));
            if face_floor[face as usize] < MIN_SIZE_FRACTION_SURFACE {
                t = t.max((per_radian_small_face * kappa).min(1.0 / (MIN_SIZE_FRACTION_TURN * size)));
            }
            for v in [a, b] {
                turns[v.idx()] = turns[v.idx()].max(t);
            }
        }
    }
    for (curve, &floor) in model.features.curves.iter().zip(&curve_floor) {
        let most_curve = 1.0 / (floor * size);
        let verts = &curve.vertices;
        let mut turn_at = |prev: VertexId, v: VertexId, next: VertexId| {
            let (p, q, r) = (surface.position(prev), surface.position(v), surface.position(next));
            let turn = angle_between(&(q - p), &(r - q));
            let length = 0.5 * ((q - p).norm() + (r - q).norm());
            if turn.to_degrees() <= SHARP_TURN_DEG && length > 0.0 {
                curve_turns[v.idx()] = curve_turns[v.idx()].max((per_radian_curve * turn / length).min(most_curve));
            }
        };
        for w in verts.windows(3) {
            turn_at(w[0], w[1], w[2]);
        }
        if curve.is_closed() && verts.len() > 2 {
            turn_at(verts[verts.len() - 2], verts[0], verts[1]);
        }
    }
    (turns, curve_turns)
}

/// Per model face, the fraction of the size `size` its caps may not go
/// below: [`MIN_SIZE_FRACTION_SURFACE`], lowered on a small face to
/// `√(area / QUADS_PER_SMALL_FACE) / size`, at least
/// [`MIN_SIZE_FRACTION_SMALL_FACE`] (module documentation).
fn face_floor_fractions(model: &QuadModel, size: f64) -> Vec<f64> {
    model
        .face_area
        .iter()
        .map(|&area| {
            let affordable = (area / QUADS_PER_SMALL_FACE).sqrt() / size;
            affordable.clamp(MIN_SIZE_FRACTION_SMALL_FACE, MIN_SIZE_FRACTION_SURFACE)
        })
        .collect()
}

/// Lowers `h` to `min over y of h(y) + g |x − y|` along the surface edges
/// (Dijkstra from every vertex at once; infinite sizes are uncapped).
fn grade_sizes(surface: &TriMesh, topo: &Topology, h: &mut [f64], g: f64) {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let mut neighbours: Vec<Vec<(u32, f64)>> = vec![Vec::new(); h.len()];
    for [a, b] in &topo.edges {
        let l = g * (surface.position(*a) - surface.position(*b)).norm();
        neighbours[a.idx()].push((b.0, l));
        neighbours[b.idx()].push((a.0, l));
    }
    // Sizes are positive, so their bit patterns order like the values.
    let mut heap: BinaryHeap<Reverse<(u64, u32)>> =
        h.iter().enumerate().map(|(v, x)| Reverse((x.to_bits(), v as u32))).collect();
    while let Some(Reverse((bits, v))) = heap.pop() {
        let hv = f64::from_bits(bits);
        if hv > h[v as usize] {
            continue;
        }
        for &(w, l) in &neighbours[v as usize] {
            if hv + l < h[w as usize] {
                h[w as usize] = hv + l;
                heap.push(Reverse(((hv + l).to_bits(), w)));
            }
        }
    }
}

/// True when a singularity of `field` lies off the boundary (the ones at
/// boundary corners leave the field smooth in the domain).
fn has_interior_singularity(topo: &Topology, field: &Crossfield) -> bool {
    let n_v = field.index_per_vertex.len();
    let mut on_boundary = vec![false; n_v];
    for (e, [a, b]) in topo.edges.iter().enumerate() {
        if topo.is_boundary_edge(crate::mesh::EdgeId::new(e)) {
            on_boundary[a.idx()] = true;
            on_boundary[b.idx()] = true;
        }
    }
    field.singularities.iter().any(|s| !on_boundary[s.vertex.idx()])
}

/// Component of each vertex (`u32::MAX` for a vertex of no triangle).
fn vertex_components(surface: &TriMesh, component_per_face: &[u32], n_v: usize) -> Vec<u32> {
    let mut out = vec![u32::MAX; n_v];
    for (t, &c) in surface.triangles.iter().zip(component_per_face) {
        for v in t {
            out[v.idx()] = c;
        }
    }
    out
}

/// One vertex per component fixes the additive constant of the Neumann
/// problem (its smallest vertex), plus every vertex of no triangle.
fn pinned_vertices(surface: &TriMesh, component_per_face: &[u32], n_components: usize) -> Vec<bool> {
    let n_v = surface.n_vertices();
    let comp = vertex_components(surface, component_per_face, n_v);
    let mut pinned: Vec<bool> = comp.iter().map(|&c| c == u32::MAX).collect();
    let mut seen = vec![false; n_components];
    for (v, &c) in comp.iter().enumerate() {
        if c != u32::MAX && !seen[c as usize] {
            seen[c as usize] = true;
            pinned[v] = true;
        }
    }
    pinned
}

/// Clamps `values` to their [`QUANTILE`], `1 − QUANTILE` range within each component.
fn clamp_to_quantiles(values: &mut [f64], component: &[u32], n_components: usize) {
    let mut per: Vec<Vec<f64>> = vec![Vec::new(); n_components];
    for (v, &c) in values.iter().zip(component) {
        if c != u32::MAX {
            per[c as usize].push(*v);
        }
    }
    let bounds: Vec<(f64, f64)> = per
        .into_iter()
        .map(|mut xs| {
            if xs.is_empty() {
                return (0.0, 0.0);
            }
            xs.sort_by(f64::total_cmp);
            let at = |q: f64| xs[((xs.len() - 1) as f64 * q).round() as usize];
            (at(QUANTILE), at(1.0 - QUANTILE))
        })
        .collect();
    for (v, &c) in values.iter_mut().zip(component) {
        if c != u32::MAX {
            let (lo, hi) = bounds[c as usize];
            *v = v.clamp(lo, hi);
        }
    }
}

/// `h = s·exp(log h)` with `s` per component such that `∫ h⁻² dA = A / size²`.
fn scaled_sizes(
    surface: &TriMesh,
    log_h: &[f64],
    component_per_face: &[u32],
    n_components: usize,
    size: f64,
) -> Vec<f64> {
    let h: Vec<f64> = log_h.iter().map(|l| l.exp()).collect();
    let mut quads = vec![0.0; n_components];
    let mut area = vec![0.0; n_components];
    for (f, t) in surface.triangles.iter().enumerate() {
        let a = surface.face_area(FaceId::new(f));
        let mean = (h[t[0].idx()] + h[t[1].idx()] + h[t[2].idx()]) / 3.0;
        let c = component_per_face[f] as usize;
        quads[c] += a / (mean * mean);
        area[c] += a;
    }
    let vertex_component = vertex_components(surface, component_per_face, h.len());
    h.iter()
        .zip(&vertex_component)
        .map(|(&hv, &c)| {
            if c == u32::MAX || !(quads[c as usize] > 0.0) {
                return size;
            }
            let s = (quads[c as usize] * size * size / area[c as usize]).sqrt();
            s * hv
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On an open 12-sided prism of radius 1 (facet width `w = 2 sin 15°`,
    /// a 30° fold between facets, the two rims turning 30° per vertex), at a
    /// size far too large: the rims get 24 edges per turn (`h = w/2`), the
    /// rest 16 per turn of the folds (`h = 12 w / 16`), or less where the
    /// rims' size, graded at [`CURVE_SIZE_GRADIENT`] along the vertical
    /// edges, is smaller; a plane gets no cap.
    #[test]
    fn the_curvature_cap_gives_a_prism_24_edges_on_its_rims_and_16_around() {
        let mesh = fixtures::cylinder(1.0, 2.0, 12, 4);
        let topo = Topology::new(&mesh);
        let model =
            crate::quads::quad_model(&mesh, &topo, &crate::atlas::features::detect_features(&mesh, &topo, 40.0));
        let size = 1.0;
        let map = curvature_bounded_sizes(SizeMap::uniform(mesh.n_vertices(), size), &mesh, &topo, &model, size);
        let w = 2.0 * 15f64.to_radians().sin();
        for (p, h) in mesh.positions.iter().zip(&map.size_per_vertex) {
            let on_rim = p.z.abs() < 1e-12 || (p.z - 2.0).abs() < 1e-12;
            let from_rim = w / 2.0 + CURVE_SIZE_GRADIENT * p.z.min(2.0 - p.z);
            let expected = if on_rim { w / 2.0 } else { from_rim.min(12.0 * w / 16.0) };
            assert!((h - expected).abs() < 1e-9, "z = {}: h = {h}, expected {expected}", p.z);
        }
        let plane = fixtures::square(4);
        let topo = Topology::new(&plane);
        let model =
            crate::quads::quad_model(&plane, &topo, &crate::atlas::features::detect_features(&plane, &topo, 40.0));
        let map = curvature_bounded_sizes(SizeMap::uniform(plane.n_vertices(), 0.3), &plane, &topo, &model, 0.3);
        assert!(map.size_per_vertex.iter().all(|&h| h == 0.3));
    }
    /// Sizes on a pin (open 36-sided prism of radius `radius`, 10° folds,
    /// its two rims its curves) of height `height`, with the size asked 1:
    /// per vertex the size, whether it is on a rim, and the pin's area and
    /// circumference.
    fn sizes_on_pin(radius: f64, height: f64) -> (Vec<f64>, Vec<bool>, f64, f64) {
        let size = 1.0;
        let mesh = fixtures::cylinder(radius, height, 36, 8);
        let topo = Topology::new(&mesh);
        let model =
            crate::quads::quad_model(&mesh, &topo, &crate::atlas::features::detect_features(&mesh, &topo, 40.0));
        assert_eq!(model.n_faces, 1);
        let map = curvature_bounded_sizes(SizeMap::uniform(mesh.n_vertices(), size), &mesh, &topo, &model, size);
        let on_rim: Vec<bool> = mesh.positions.iter().map(|p| p.z == 0.0 || p.z == height).collect();
        let circumference = 36.0 * 2.0 * radius * 5f64.to_radians().sin();
        (map.size_per_vertex, on_rim, mesh.area(), circumference)
    }

    /// A pin of radius `size / 8` on a model face of area `a`: a small face
    /// may follow its bends below the size asked's floors, down to
    /// `√(a / QUADS_PER_SMALL_FACE)`, at least
    /// [`MIN_SIZE_FRACTION_SMALL_FACE`] of the size; a large one keeps the
    /// floors (¼ of the size on the surface, ⅛ on the rims). Its own caps
    /// (circumference / 16 and / 24) are below every floor and its 8 edges
    /// per turn above them, so each vertex gets exactly its floor.
    #[test]
    fn a_small_face_follows_its_bends_below_the_floor_of_the_size_asked() {
        let (size, radius) = (1.0, 1.0 / 8.0);
        // A 0.5-long pin (area 0.4 size²): the lowest floor everywhere.
        let (h, _, _, circumference) = sizes_on_pin(radius, 0.5);
        assert!(circumference / 16.0 < MIN_SIZE_FRACTION_SMALL_FACE * size);
        assert!(circumference / SEGMENTS_PER_TURN_SMALL_FACE > MIN_SIZE_FRACTION_SMALL_FACE * size);
        assert!(h.iter().all(|&h| (h - MIN_SIZE_FRACTION_SMALL_FACE * size).abs() < 1e-12), "{h:?}");
        // 42 long (area 33 size²): the floor its area affords, about 0.09.
        let (h, _, area, _) = sizes_on_pin(radius, 42.0);
        let affordable = (area / QUADS_PER_SMALL_FACE).sqrt();
        assert!(affordable > MIN_SIZE_FRACTION_SMALL_FACE && affordable < MIN_SIZE_FRACTION_CURVE);
        assert!(h.iter().all(|&h| (h - affordable * size).abs() < 1e-12), "{affordable}: {h:?}");
        // 800 long (area 628 size²): the floors of the size asked.
        let (h, on_rim, _, _) = sizes_on_pin(radius, 800.0);
        for (h, rim) in h.iter().zip(on_rim) {
            let floor = if rim { MIN_SIZE_FRACTION_CURVE } else { MIN_SIZE_FRACTION_SURFACE };
            assert!((h - floor * size).abs() < 1e-12, "rim {rim}: h = {h}");
        }
    }

    /// A small face's bend keeps [`SEGMENTS_PER_TURN_SMALL_FACE`] edges per
    /// turn below its floor: a pin of radius `size / 16` gets a circumference
    /// / 8 under the lowest floor (0.06 of the size would give it 6.5 edges
    /// per turn), and one of radius `size / 100` stops at
    /// [`MIN_SIZE_FRACTION_TURN`] of the size.
    #[test]
    fn a_small_face_gets_eight_edges_per_turn_below_its_floor() {
        let (h, _, _, circumference) = sizes_on_pin(1.0 / 16.0, 0.5);
        let eighth = circumference / SEGMENTS_PER_TURN_SMALL_FACE;
        assert!(eighth < MIN_SIZE_FRACTION_SMALL_FACE && eighth > MIN_SIZE_FRACTION_TURN);
        assert!(h.iter().all(|&h| (h - eighth).abs() < 1e-9), "{eighth}: {h:?}");
        let (h, _, _, circumference) = sizes_on_pin(1.0 / 100.0, 0.5);
        assert!(circumference / SEGMENTS_PER_TURN_SMALL_FACE < MIN_SIZE_FRACTION_TURN);
        assert!(h.iter().all(|&h| (h - MIN_SIZE_FRACTION_TURN).abs() < 1e-12), "{h:?}");
    }

    use crate::crossfield::frames::{edge_direction, edge_normal};
    use crate::mesh::{EdgeId, fixtures};

    /// Edge values `exp(4iθ)` of the cross whose first branch at a point `x`
    /// is `direction(x)` (projected on each edge's tangent plane).
    fn analytic_field(mesh: &TriMesh, topo: &Topology, direction: impl Fn(&Vec3) -> Vec3) -> Vec<[f64; 2]> {
        (0..topo.n_edges())
            .map(|e| {
                let id = EdgeId::new(e);
                let [a, b] = topo.edges[e];
                let mid = (mesh.positions[a.idx()] + mesh.positions[b.idx()]) / 2.0;
                let (ex, n) = (edge_direction(mesh, topo, id), edge_normal(mesh, topo, id));
                let d = direction(&mid);
                let theta = d.dot(&n.cross(&ex)).atan2(d.dot(&ex));
                [(4.0 * theta).cos(), (4.0 * theta).sin()]
            })
            .collect()
    }

    fn size_map_of(mesh: &TriMesh, direction: impl Fn(&Vec3) -> Vec3) -> SizeMap {
        let topo = Topology::new(mesh);
        let f = analytic_field(mesh, &topo, direction);
        size_map_of_edge_field(mesh, &topo, &f, false, 0.1).expect("size map")
    }

    /// Coefficient of variation of `xs`.
    fn variation(xs: &[f64]) -> f64 {
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt() / mean
    }

    /// Tangent of the circles around the `z` axis.
    fn around_z(x: &Vec3) -> Vec3 {
        Vec3::new(-x.y, x.x, 0.0)
    }

    #[test]
    fn a_constant_cross_gets_the_uniform_size() {
        let c = 0.3f64;
        let map = size_map_of(&fixtures::square(12), |_| Vec3::new(c.cos(), c.sin(), 0.0));
        assert!(map.size_per_vertex.iter().all(|h| (h - 0.1).abs() < 1e-9), "{:?}", map.range());
    }

    /// The polar cross on an annulus is integrable with `h ∝ r` (the grid
    /// of `log z`).
    #[test]
    fn the_polar_cross_gets_a_size_proportional_to_the_radius() {
        let mesh = fixtures::annulus(0.5, 2.0, 96, 24);
        let map = size_map_of(&mesh, around_z);
        let ratio: Vec<f64> = mesh.positions.iter().zip(&map.size_per_vertex).map(|(p, h)| h / p.xy().norm()).collect();
        let (lo, hi) = map.range();
        assert!(hi / lo > 3.0, "the size must follow r ∈ [0.5, 2]: range {lo}..{hi}");
        assert!(variation(&ratio) < 0.02, "h / r varies by {}", variation(&ratio));
    }

    /// On a torus the principal-direction cross (parallels and meridians)
    /// is integrable with `h ∝ ρ`, the distance to the axis (parallels of
    /// length 2πρ, all with the same number of quads).
    #[test]
    fn the_principal_cross_of_a_torus_gets_a_size_proportional_to_the_distance_to_its_axis() {
        let mesh = fixtures::torus(2.0, 1.0, 96, 48);
        let map = size_map_of(&mesh, around_z);
        let ratio: Vec<f64> = mesh.positions.iter().zip(&map.size_per_vertex).map(|(p, h)| h / p.xy().norm()).collect();
        let (lo, hi) = map.range();
        assert!(hi / lo > 2.5, "the size must follow ρ ∈ [1, 3]: range {lo}..{hi}");
        assert!(variation(&ratio) < 0.02, "h / ρ varies by {}", variation(&ratio));
    }

    #[test]
    fn the_quad_count_of_the_map_matches_the_uniform_size() {
        let mesh = fixtures::annulus(0.5, 2.0, 96, 24);
        let map = size_map_of(&mesh, around_z);
        let quads: f64 = (0..mesh.n_faces())
            .map(|f| {
                let t = mesh.triangles[f];
                let h = (0..3).map(|i| map.size_per_vertex[t[i].idx()]).sum::<f64>() / 3.0;
                mesh.face_area(FaceId::new(f)) / (h * h)
            })
            .sum();
        let uniform = mesh.area() / 0.01;
        assert!((quads / uniform - 1.0).abs() < 1e-9, "{quads} vs {uniform}");
    }
}
