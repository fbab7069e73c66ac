//! Step 7a of the quads stage: the shape and topology measures of a quad
//! mesh that the checks assert and the report summarizes.
//!
//! - **Scaled Jacobian** of each quad ([`super::jacobian::scaled_jacobian`]
//!   against [`super::jacobian::quad_reference_normal`]): 1 for a square,
//!   ≤ 0 for an inverted or degenerate quad.
//! - **Max angle deviation** of each quad from 90°, degrees.
//! - **Valence** of each vertex: the number of distinct mesh edges at it
//!   (edges join consecutive quad corners); 0 for the edge and centre nodes
//!   of 9-node quadrangles and for any vertex no quad uses.
//! - **Open fans**: a vertex on a mesh boundary edge (an edge of one quad).
//! - **Expected valence**, corner-aware on open fans: with `θ` the sum of the
//!   corner angles the vertex's quads make at it, a boundary vertex that is
//!   regular has `round(θ / 90°) + 1` edges (3 on a straight boundary, 2 at
//!   a right-angle corner, 4 at a reentrant one; at least 2). A vertex of a
//!   closed fan (inside the mesh, also on a feature curve or at a model
//!   corner) is regular with 4 edges: a cube corner of valence 3 is irregular,
//!   as the crossfield has a singularity (index +1/4) there.
//! - **Irregular**: valence ≠ expected valence.
//!
//! The valence identity the checks assert uses the topological form
//! `Σ_closed (4 − val) + Σ_open (3 − val) = 4χ` (from `V − E + F = χ` and
//! `4F = 2E − E_boundary`), whatever the corner angles.

use std::collections::BTreeMap;

use super::jacobian::{max_angle_deviation_deg, quad_reference_normal, surface_quad_scaled_jacobian};
use super::surface_mesh::QuadMesh;
use crate::geom::{Vec3, angle_between};
use crate::mesh::TriMesh;

/// Scaled Jacobian at or below which a quad counts as inverted or
/// degenerate: a corner whose sine is within round-off of 0 is flat (a 180°
/// corner, three nodes on a line), which Gmsh rates minSICN 0; 10⁻⁹ is far
/// above the round-off of `f64` shape measures (about 10⁻¹⁵) and far below
/// any quad a mesh is meant to keep.
pub const DEGENERATE_SCALED_JACOBIAN: f64 = 1e-9;

/// True when a quad of scaled Jacobian `j` is inverted, degenerate or not
/// measurable (NaN).
pub fn is_inverted_or_degenerate(j: f64) -> bool {
    j.is_nan() || j <= DEGENERATE_SCALED_JACOBIAN
}

/// Shape and topology measures of a quad mesh.
#[derive(Debug, Clone, Default)]
pub struct QuadQuality {
    /// Scaled Jacobian of each quad (minimum over its corners).
    pub scaled_jacobian: Vec<f64>,
    /// Largest corner-angle deviation from 90° of each quad, degrees.
    pub max_angle_deviation: Vec<f64>,
    /// Number of edges at each vertex (0 for order-2 edge and face nodes).
    pub valence: Vec<u32>,
    /// Per vertex: true when it lies on a mesh boundary edge (an edge of one
    /// quad), so its quads form an open fan.
    pub on_boundary: Vec<bool>,
    /// Per vertex: sum of the corner angles of its quads at it, degrees.
    pub angle_sum_deg: Vec<f64>,
    /// Per vertex: the valence a regular vertex has there (4 on a closed fan,
    /// `round(θ/90°) + 1` on an open one; 0 for vertices no quad uses).
    pub expected_valence: Vec<u32>,
    /// Edges of the mesh (between consecutive quad corners) as
    /// `[min, max]`, sorted.
    pub edges: Vec<[u32; 2]>,
}

/// The measures of `mesh` on `surface` (the surface its vertices lie on).
pub fn quad_quality(mesh: &QuadMesh, surface: &TriMesh) -> QuadQuality {
    let n = mesh.vertices.len();
    let pos = &mesh.vertices.positions;
    let corners = |q: &[u32; 4]| q.map(|v| pos[v as usize]);
    let normals = surface.face_normals();
    let scaled: Vec<f64> = mesh
        .quads
        .iter()
        .map(|q| surface_quad_scaled_jacobian(&corners(q), &quad_reference_normal(&mesh.vertices, &normals, q)))
        .collect();
    let deviation: Vec<f64> = mesh.quads.iter().map(|q| max_angle_deviation_deg(&corners(q))).collect();
    let edge_uses = edge_uses(&mesh.quads);
    let mut valence = vec![0u32; n];
    let mut on_boundary = vec![false; n];
    for (&[a, b], &uses) in &edge_uses {
        for v in [a, b] {
            valence[v as usize] += 1;
            if uses == 1 {
                on_boundary[v as usize] = true;
            }
        }
    }
    let angle_sum_deg = angle_sums_deg(pos, &mesh.quads, n);
    let expected_valence = (0..n)
        .map(|v| match (valence[v], on_boundary[v]) {
            (0, _) => 0,
            (_, false) => 4,
            (_, true) => expected_boundary_valence(angle_sum_deg[v]),
        })
        .collect();
    QuadQuality {
        scaled_jacobian: scaled,
        max_angle_deviation: deviation,
        valence,
        on_boundary,
        angle_sum_deg,
        expected_valence,
        edges: edge_uses.into_keys().collect(),
    }
}

/// Number of quads using each edge `[min, max]`, in edge order.
pub fn edge_uses(quads: &[[u32; 4]]) -> BTreeMap<[u32; 2], u32> {
    let mut uses = BTreeMap::new();
    for q in quads {
        for i in 0..4 {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            *uses.entry([a.min(b), a.max(b)]).or_insert(0) += 1;
        }
    }
    uses
}

/// Per vertex, the sum of the 3D corner angles of the quads at it, degrees.
fn angle_sums_deg(pos: &[Vec3], quads: &[[u32; 4]], n: usize) -> Vec<f64> {
    let mut sum = vec![0.0; n];
    for q in quads {
        for i in 0..4 {
            let p = pos[q[i] as usize];
            let a = pos[q[(i + 1) % 4] as usize] - p;
            let b = pos[q[(i + 3) % 4] as usize] - p;
            sum[q[i] as usize] += angle_between(&a, &b).to_degrees();
        }
    }
    sum
}

/// Valence of a regular boundary vertex whose quads span `theta_deg`:
/// `round(θ / 90°) + 1` quads' worth of edges, at least 2 (one quad).
pub fn expected_boundary_valence(theta_deg: f64) -> u32 {
    ((theta_deg / 90.0).round().max(1.0) as u32) + 1
}

/// Summary of a sample: minimum, mean and 5th percentile (nearest rank).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleStats {
    /// Smallest value (`NaN` for an empty sample).
    pub min: f64,
    /// Mean (`NaN` for an empty sample).
    pub mean: f64,
    /// 5th percentile, nearest-rank: the `⌈0.05 n⌉`-th smallest value.
    pub p5: f64,
    /// Largest value (`NaN` for an empty sample).
    pub max: f64,
}

/// Minimum, mean, 5th percentile and maximum of `values` (in sorted order,
/// so the result does not depend on the order of the input).
pub fn sample_stats(values: &[f64]) -> SampleStats {
    if values.is_empty() {
        return SampleStats { min: f64::NAN, mean: f64::NAN, p5: f64::NAN, max: f64::NAN };
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((0.05 * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    SampleStats {
        min: sorted[0],
        mean: sorted.iter().sum::<f64>() / sorted.len() as f64,
        p5: sorted[rank - 1],
        max: sorted[sorted.len() - 1],
    }
}

impl QuadQuality {
    /// True when vertex `v` is a quad corner whose valence differs from the
    /// expected one (see the module documentation).
    pub fn is_irregular(&self, v: usize) -> bool {
        self.valence[v] > 0 && self.valence[v] != self.expected_valence[v]
    }

    /// Irregular vertices, ascending.
    pub fn irregular_vertices(&self) -> Vec<u32> {
        (0..self.valence.len()).filter(|&v| self.is_irregular(v)).map(|v| v as u32).collect()
    }

    /// Irregular vertices inside the mesh (closed fans: valence ≠ 4).
    pub fn n_irregular_interior(&self) -> usize {
        (0..self.valence.len()).filter(|&v| self.is_irregular(v) && !self.on_boundary[v]).count()
    }

    /// Irregular vertices on the mesh boundary (corner-aware).
    pub fn n_irregular_boundary(&self) -> usize {
        (0..self.valence.len()).filter(|&v| self.is_irregular(v) && self.on_boundary[v]).count()
    }

    /// Boundary vertices where a regular vertex does not have valence 3
    /// (the corners of the boundary: right angles, reentrant corners); the
    /// crossfield counts a singularity at each (index ±1/4 of a turn).
    pub fn n_boundary_corners(&self) -> usize {
        (0..self.valence.len()).filter(|&v| self.on_boundary[v] && self.expected_valence[v] != 3).count()
    }

    /// Number of quad corners per valence (vertices of valence 0 are not
    /// corners and are not counted).
    pub fn valence_histogram(&self) -> BTreeMap<u32, usize> {
        let mut h = BTreeMap::new();
        for &val in self.valence.iter().filter(|&&v| v > 0) {
            *h.entry(val).or_insert(0) += 1;
        }
        h
    }

    /// Quads whose scaled Jacobian is at most [`DEGENERATE_SCALED_JACOBIAN`]
    /// (inverted or degenerate) or not a number.
    pub fn n_inverted(&self) -> usize {
        self.scaled_jacobian.iter().filter(|&&j| is_inverted_or_degenerate(j)).count()
    }

    /// Quads whose scaled Jacobian is below `threshold`.
    pub fn n_below(&self, threshold: f64) -> usize {
        self.scaled_jacobian.iter().filter(|&&j| j.is_nan() || j < threshold).count()
    }

    /// Mean length of the mesh's edges (straight, corner to corner) with
    /// positions `positions`; `NaN` without edges.
    pub fn mean_edge_length(&self, positions: &[Vec3]) -> f64 {
        let total: f64 = self.edges.iter().map(|&[a, b]| (positions[a as usize] - positions[b as usize]).norm()).sum();
        total / self.edges.len() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::features::detect_features;
    use crate::mesh::{Topology, fixtures};
    use crate::quads::fixtures::quads_from_triangle_pairs;
    use crate::quads::model::quad_model;

    fn grid(surface: &TriMesh) -> (QuadMesh, QuadQuality) {
        let topo = Topology::new(surface);
        let model = quad_model(surface, &topo, &detect_features(surface, &topo, 30.0));
        let mesh = quads_from_triangle_pairs(surface, &topo, &model);
        let q = quad_quality(&mesh, surface);
        (mesh, q)
    }

    #[test]
    fn a_square_grid_is_regular_with_unit_jacobians() {
        let surface = fixtures::square_structured(4);
        let (mesh, q) = grid(&surface);
        assert_eq!(mesh.quads.len(), 16);
        assert!(q.scaled_jacobian.iter().all(|&j| (j - 1.0).abs() < 1e-12), "{:?}", q.scaled_jacobian);
        assert!(q.max_angle_deviation.iter().all(|&d| d.abs() < 1e-9));
        // 9 interior vertices of valence 4, 12 boundary of valence 3, 4 corners of valence 2.
        assert_eq!(q.valence_histogram(), BTreeMap::from([(2, 4), (3, 12), (4, 9)]));
        assert!(q.irregular_vertices().is_empty());
        assert_eq!(q.n_boundary_corners(), 4);
        assert_eq!(q.edges.len(), 2 * 4 * 5);
        assert!((q.mean_edge_length(&mesh.vertices.positions) - 0.25).abs() < 1e-12);
        assert_eq!((q.n_inverted(), q.n_below(0.3)), (0, 0));
    }

    #[test]
    fn cube_corners_are_the_only_irregular_vertices() {
        let surface = fixtures::cube(3);
        let (mesh, q) = grid(&surface);
        assert_eq!(mesh.quads.len(), 6 * 9);
        let irregular = q.irregular_vertices();
        assert_eq!(irregular.len(), 8);
        for v in irregular {
            let p = mesh.vertices.positions[v as usize];
            assert!(p.iter().all(|c| (c.abs() - 1.0).abs() < 1e-12), "{p:?}");
            assert_eq!(q.valence[v as usize], 3);
            assert!((q.angle_sum_deg[v as usize] - 270.0).abs() < 1e-9);
        }
        assert_eq!((q.n_irregular_interior(), q.n_irregular_boundary(), q.n_boundary_corners()), (8, 0, 0));
    }

    #[test]
    fn an_open_cylinder_has_straight_boundaries_only() {
        let surface = fixtures::cylinder(1.0, 1.0, 16, 3);
        let (mesh, q) = grid(&surface);
        assert_eq!(mesh.quads.len(), 48);
        // Rings of 16 at both ends, valence 3, angle sum 180° (the quads are planar).
        assert_eq!(q.valence_histogram(), BTreeMap::from([(3, 32), (4, 32)]));
        assert!(q.irregular_vertices().is_empty());
        assert_eq!(q.n_boundary_corners(), 0);
    }

    #[test]
    fn a_flipped_quad_is_inverted_and_boundary_expectations_follow_the_angle() {
        let surface = fixtures::square_structured(2);
        let (mut mesh, _) = grid(&surface);
        mesh.quads[0].reverse();
        let q = quad_quality(&mesh, &surface);
        assert_eq!(q.n_inverted(), 1);
        assert!((q.scaled_jacobian[0] + 1.0).abs() < 1e-12);
        assert_eq!(expected_boundary_valence(90.0), 2);
        assert_eq!(expected_boundary_valence(180.0), 3);
        assert_eq!(expected_boundary_valence(270.0), 4);
        assert_eq!(expected_boundary_valence(20.0), 2);
    }

    #[test]
    fn sample_stats_use_the_nearest_rank() {
        let v: Vec<f64> = (1..=40).rev().map(f64::from).collect();
        let s = sample_stats(&v);
        assert_eq!((s.min, s.p5, s.max), (1.0, 2.0, 40.0));
        assert!((s.mean - 20.5).abs() < 1e-12);
        assert_eq!(sample_stats(&[0.7]).p5, 0.7);
        assert!(sample_stats(&[]).min.is_nan());
    }
}
