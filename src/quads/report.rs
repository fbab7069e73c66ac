//! The quads stage report (owner: output helper). PLACEHOLDER on the
//! `quads` branch only: replaced before the branch is merged.

use serde::Serialize;

use super::cleanup::CleanupStats;
use super::quality::QuadQuality;
use super::recombine::RecombineStats;
use super::smooth::SmoothStats;
use super::surface_mesh::QuadMesh;
use super::triangulation::TriangulationStats;

/// What the quads stage did and what it produced.
#[derive(Debug, Clone, Default, Serialize)]
pub struct QuadsReport {
    /// Target edge length used.
    pub target_size: f64,
    /// The triangulation step.
    pub triangulation: TriangulationStats,
    /// The recombination step.
    pub recombination: RecombineStats,
    /// The cleanup step.
    pub cleanup: CleanupStats,
    /// The smoothing step.
    pub smoothing: SmoothStats,
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
    /// Smoothing.
    pub smoothing: SmoothStats,
    /// Wall seconds of the order-2 nodes (0 for order 1).
    pub high_order_seconds: f64,
    /// Wall seconds of the quality measures and checks.
    pub check_seconds: f64,
}

impl QuadsReport {
    /// The report of one run.
    pub fn new(inputs: ReportInputs) -> Self {
        Self {
            target_size: inputs.target_size,
            triangulation: inputs.triangulation,
            recombination: inputs.recombination,
            cleanup: inputs.cleanup,
            smoothing: inputs.smoothing,
        }
    }
}
