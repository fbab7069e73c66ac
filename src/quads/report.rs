//! The quads stage report (`stages.quads` in `report.json`): the counts a
//! finite-element user checks before simulating on the mesh, the
//! irregular vertices against the crossfield's singularities, the shape
//! measures, and what each step did and how long it took.
//!
//! Irregular vertices are counted as [`super::quality`] defines them
//! (closed fans: valence ≠ 4; boundary vertices corner-aware). The
//! crossfield's singularities include the corners of the boundary (index
//! ±1/4 of a turn at a right-angle or reentrant corner), where the
//! corner-aware rule expects no irregular vertex; so the excess is
//! `n_irregular_vertices − (n_singularities − n_boundary_corners)`, 0 when
//! the mesh has an irregular vertex for each singularity inside and none
//! elsewhere (negative when singularities are missing).

use std::collections::{BTreeMap, HashSet};

use serde::Serialize;

use super::cavity::CavityStats;
use super::cleanup::CleanupStats;
use super::pillow::PillowStats;
use super::quality::{QuadQuality, sample_stats};
use super::recombine::RecombineStats;
use super::smooth::SmoothStats;
use super::surface_mesh::QuadMesh;
use super::triangulation::TriangulationStats;
use super::untangle::RaiseStats;

/// Scaled Jacobian below which a quad is counted as poor (`n_below_0_3`).
pub const POOR_SCALED_JACOBIAN: f64 = 0.3;

/// Wall seconds of each step of the stage.
#[derive(Debug, Clone, Default, Serialize)]
pub struct StepSeconds {
    /// Point placement and triangulation.
    pub triangulation: f64,
    /// Recombination into quads.
    pub recombination: f64,
    /// Cleanup (valence-2 vertices, 3-3 diamonds).
    pub cleanup: f64,
    /// Cavity remeshing with patterns.
    pub cavities: f64,
    /// Smoothing and projection.
    pub smoothing: f64,
    /// Pillowing of the quads still inverted after smoothing.
    pub pillowing: f64,
    /// Raising the worst quads (both passes).
    pub raising: f64,
    /// Order-2 nodes (0 for order 1).
    pub high_order: f64,
    /// Quality measures and checks.
    pub check: f64,
}

/// What the quads stage did and what it produced.
#[derive(Debug, Clone, Default, Serialize)]
pub struct QuadsReport {
    /// Quadrangles.
    pub n_quads: usize,
    /// Triangles left (always 0: the stage outputs quadrangles only).
    pub n_triangles: usize,
    /// Quad corner vertices.
    pub n_vertices: usize,
    /// All nodes, with the edge and centre nodes of 9-node quadrangles.
    pub n_nodes: usize,
    /// Element order (1: 4-node, 2: 9-node quadrangles).
    pub order: u8,
    /// Target edge length used, model units.
    pub target_size: f64,
    /// Mean length of the quads' edges (corner to corner), model units.
    pub mean_edge_length: f64,
    /// `mean_edge_length / target_size`.
    pub edge_length_ratio: f64,
    /// Quad corners per valence (number of edges at the vertex).
    pub valence_histogram: BTreeMap<u32, usize>,
    /// Irregular vertices, inside and on the boundary.
    pub n_irregular_vertices: usize,
    /// Irregular vertices inside the mesh (valence ≠ 4, also on feature
    /// curves and at model corners).
    pub n_irregular_interior: usize,
    /// Irregular boundary vertices (valence ≠ `round(θ/90°) + 1`).
    pub n_irregular_boundary: usize,
    /// Singularities of the crossfield.
    pub n_singularities: usize,
    /// Sum of the singularities' indices, quarter turns (`4χ` on a manifold).
    pub singularity_index_sum: i64,
    /// Boundary corners of the mesh (regular valence ≠ 3), where the
    /// crossfield has a singularity and the mesh no irregular vertex.
    pub n_boundary_corners: usize,
    /// `n_irregular_vertices − (n_singularities − n_boundary_corners)`.
    pub irregular_excess: i64,
    /// Vertices placed at crossfield singularities.
    pub n_singular_vertices: usize,
    /// Irregular vertices that are not placed at a singularity.
    pub n_irregular_off_singularities: usize,
    /// Vertices placed on atlas seams.
    pub n_seam_vertices: usize,
    /// Irregular vertices among them (a seam should leave none).
    pub n_irregular_on_seams: usize,
    /// Smallest scaled Jacobian of a quad (1 for a square, must be > 0).
    pub scaled_jacobian_min: f64,
    /// Mean scaled Jacobian.
    pub scaled_jacobian_mean: f64,
    /// 5th percentile of the scaled Jacobian (nearest rank).
    pub scaled_jacobian_p5: f64,
    /// Quads with a scaled Jacobian below 0.3.
    pub n_below_0_3: usize,
    /// Fraction of the quads with a scaled Jacobian of at least 0.5.
    pub fraction_at_least_0_5: f64,
    /// Inverted or degenerate quads (scaled Jacobian ≤ 0; always 0, the
    /// checks refuse any).
    pub n_inverted: usize,
    /// Largest deviation of a quad corner angle from 90°, degrees.
    pub max_angle_deviation_deg: f64,
    /// Mean over the quads of their largest corner-angle deviation, degrees.
    pub mean_max_angle_deviation_deg: f64,
    /// The triangulation step's report.
    pub triangulation: TriangulationStats,
    /// The recombination step's report (with its subdivision fallbacks).
    pub recombination: RecombineStats,
    /// The cleanup step's report.
    pub cleanup: CleanupStats,
    /// The cavity remeshing step's report.
    pub cavities: CavityStats,
    /// The smoothing step's report.
    pub smoothing: SmoothStats,
    /// The pillowing step's report (regions repaired after smoothing).
    pub pillowing: PillowStats,
    /// Raising the worst quads, before and after pillowing.
    pub raising: RaiseStats,
    /// Wall seconds per step.
    pub seconds: StepSeconds,
}

/// Everything the report is made from.
pub struct ReportInputs<'a> {
    /// Target edge length used.
    pub target_size: f64,
    /// Element order (1 or 2).
    pub order: u8,
    /// The final mesh.
    pub mesh: &'a QuadMesh,
    /// Its measures.
    pub quality: &'a QuadQuality,
    /// Singularities of the crossfield: `(index in quarter turns)` each.
    pub singularity_indices: Vec<i32>,
    /// The steps' own reports.
    pub triangulation: TriangulationStats,
    /// Recombination.
    pub recombination: RecombineStats,
    /// Cleanup.
    pub cleanup: CleanupStats,
    /// Cavity remeshing.
    pub cavities: CavityStats,
    /// Smoothing.
    pub smoothing: SmoothStats,
    /// Pillowing.
    pub pillowing: PillowStats,
    /// Raising the worst quads.
    pub raising: RaiseStats,
    /// Wall seconds of the order-2 nodes (0 for order 1).
    pub high_order_seconds: f64,
    /// Wall seconds of the quality measures and checks.
    pub check_seconds: f64,
}

impl QuadsReport {
    /// The report of one run.
    pub fn new(inputs: ReportInputs) -> Self {
        let (mesh, q) = (inputs.mesh, inputs.quality);
        let irregular = q.irregular_vertices();
        let singular: HashSet<u32> = mesh.singular_vertices.iter().map(|s| s.0).collect();
        let seams: HashSet<u32> = mesh.seam_vertices.iter().copied().collect();
        let count = |set: &HashSet<u32>| irregular.iter().filter(|v| set.contains(v)).count();
        let n_singularities = inputs.singularity_indices.len();
        let n_boundary_corners = q.n_boundary_corners();
        let sj = sample_stats(&q.scaled_jacobian);
        let dev = sample_stats(&q.max_angle_deviation);
        let mean_edge_length = q.mean_edge_length(&mesh.vertices.positions);
        let n_quads = mesh.quads.len();
        let at_least_half = q.scaled_jacobian.iter().filter(|&&j| j >= 0.5).count();
        let seconds = StepSeconds {
            triangulation: inputs.triangulation.seconds,
            recombination: inputs.recombination.seconds,
            cleanup: inputs.cleanup.seconds,
            cavities: inputs.cavities.seconds,
            smoothing: inputs.smoothing.seconds,
            pillowing: inputs.pillowing.seconds,
            raising: inputs.raising.seconds,
            high_order: inputs.high_order_seconds,
            check: inputs.check_seconds,
        };
        Self {
            n_quads,
            n_triangles: 0,
            n_vertices: q.valence.iter().filter(|&&v| v > 0).count(),
            n_nodes: mesh.vertices.len(),
            order: inputs.order,
            target_size: inputs.target_size,
            mean_edge_length,
            edge_length_ratio: mean_edge_length / inputs.target_size,
            valence_histogram: q.valence_histogram(),
            n_irregular_vertices: irregular.len(),
            n_irregular_interior: q.n_irregular_interior(),
            n_irregular_boundary: q.n_irregular_boundary(),
            n_singularities,
            singularity_index_sum: inputs.singularity_indices.iter().map(|&i| i64::from(i)).sum(),
            n_boundary_corners,
            irregular_excess: irregular.len() as i64 - (n_singularities as i64 - n_boundary_corners as i64),
            n_singular_vertices: singular.len(),
            n_irregular_off_singularities: irregular.len() - count(&singular),
            n_seam_vertices: seams.len(),
            n_irregular_on_seams: count(&seams),
            scaled_jacobian_min: sj.min,
            scaled_jacobian_mean: sj.mean,
            scaled_jacobian_p5: sj.p5,
            n_below_0_3: q.n_below(POOR_SCALED_JACOBIAN),
            fraction_at_least_0_5: if n_quads > 0 { at_least_half as f64 / n_quads as f64 } else { 0.0 },
            n_inverted: q.n_inverted(),
            max_angle_deviation_deg: dev.max,
            mean_max_angle_deviation_deg: dev.mean,
            triangulation: inputs.triangulation,
            recombination: inputs.recombination,
            cleanup: inputs.cleanup,
            cavities: inputs.cavities,
            smoothing: inputs.smoothing,
            pillowing: inputs.pillowing,
            raising: inputs.raising,
            seconds,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::features::detect_features;
    use crate::mesh::{Topology, TriMesh, fixtures};
    use crate::quads::fixtures::quads_from_triangle_pairs;
    use crate::quads::model::quad_model;
    use crate::quads::quality::quad_quality;

    // The steps' stats gain fields on their own branches: keep the update syntax.
    #[allow(clippy::needless_update)]
    fn report_of(surface: &TriMesh, singularities: Vec<i32>, edit: impl FnOnce(&mut QuadMesh)) -> QuadsReport {
        let topo = Topology::new(surface);
        let model = quad_model(surface, &topo, &detect_features(surface, &topo, 30.0));
        let mut mesh = quads_from_triangle_pairs(surface, &topo, &model);
        edit(&mut mesh);
        let quality = quad_quality(&mesh, surface);
        QuadsReport::new(ReportInputs {
            target_size: 0.5,
            order: 1,
            mesh: &mesh,
            quality: &quality,
            singularity_indices: singularities,
            triangulation: TriangulationStats { seconds: 1.5, ..Default::default() },
            recombination: RecombineStats::default(),
            cleanup: CleanupStats::default(),
            cavities: CavityStats::default(),
            smoothing: SmoothStats::default(),
            pillowing: PillowStats::default(),
            raising: RaiseStats::default(),
            high_order_seconds: 0.0,
            check_seconds: 0.25,
        })
    }

    #[test]
    fn a_cube_grid_has_its_8_corner_singularities_and_no_excess() {
        // The crossfield of a cube has index +1/4 at each of its 8 corners (χ = 2).
        let r = report_of(&fixtures::cube(4), vec![1; 8], |m| {
            m.singular_vertices = vec![(0, 1)];
        });
        assert_eq!((r.n_quads, r.n_triangles, r.n_vertices, r.n_nodes), (96, 0, 98, 98));
        assert_eq!(r.valence_histogram, BTreeMap::from([(3, 8), (4, 90)]));
        assert_eq!((r.n_irregular_vertices, r.n_irregular_interior, r.n_irregular_boundary), (8, 8, 0));
        assert_eq!(
            (r.n_singularities, r.singularity_index_sum, r.n_boundary_corners, r.irregular_excess),
            (8, 8, 0, 0)
        );
        assert_eq!((r.scaled_jacobian_min, r.scaled_jacobian_p5, r.n_inverted, r.n_below_0_3), (1.0, 1.0, 0, 0));
        assert!((r.edge_length_ratio - 1.0).abs() < 1e-12, "edges of 2/4 against a target of 0.5");
        assert_eq!(r.fraction_at_least_0_5, 1.0);
        assert_eq!((r.seconds.triangulation, r.seconds.check), (1.5, 0.25));
        assert_eq!(r.n_singular_vertices, 1);
        // Vertex 0 is a cube corner (irregular) and placed at a singularity.
        assert_eq!(r.n_irregular_off_singularities, 7);
    }

    #[test]
    fn a_square_grid_has_no_excess_over_its_corner_singularities() {
        // Index +1/4 at each corner of the square (χ = 1); the corner-aware count is 0.
        let r = report_of(&fixtures::square_structured(4), vec![1; 4], |m| {
            m.seam_vertices = vec![12, 0];
        });
        assert_eq!((r.n_irregular_vertices, r.n_boundary_corners, r.irregular_excess), (0, 4, 0));
        assert_eq!((r.n_seam_vertices, r.n_irregular_on_seams), (2, 0));
        assert!(r.max_angle_deviation_deg.abs() < 1e-9);
    }

    #[test]
    fn the_report_serializes_every_field_with_the_valence_histogram_keyed_by_valence() {
        let r = report_of(&fixtures::square_structured(2), vec![1; 4], |_| {});
        let v = serde_json::to_value(&r).unwrap();
        assert_eq!(v["valence_histogram"], serde_json::json!({"2": 4, "3": 4, "4": 1}));
        assert_eq!(v["n_triangles"], 0);
        assert_eq!(v["seconds"]["triangulation"], 1.5);
        assert!(v["recombination"].is_object() && v["triangulation"].is_object());
    }
}
