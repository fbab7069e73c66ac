//! The atlas section of `report.json`.

use super::build::Atlas;
use super::mvc::MvcSolver;
use super::patch::PatchDefect;
use crate::mesh::TriMesh;
use crate::mesh::summary::TopologySummary;
use serde::Serialize;

/// Summary numbers of one patch.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PatchReport {
    /// Patch index (the surface entity is `id + 1` in `atlas.msh`).
    pub id: usize,
    /// Input triangles in the patch.
    pub n_input_triangles: usize,
    /// Triangles after refinement.
    pub n_triangles: usize,
    /// Vertices after refinement.
    pub n_vertices: usize,
    /// Boundary loops (1 for a disk).
    pub n_boundary_loops: usize,
    /// Holes filled with a pseudo-centre.
    pub n_holes_filled: usize,
    /// Holes with homogeneous Neumann conditions.
    pub n_holes_neumann: usize,
    /// Longest-edge bisections done before parameterizing.
    pub n_bisections: usize,
    /// Smallest σ2/σ1 over the patch triangles.
    pub sigma_ratio_min: f64,
    /// Median σ2/σ1.
    pub sigma_ratio_median: f64,
    /// Median |Δ σ2/σ1| across inner edges (smoothness of the map).
    pub sigma_ratio_jump_median: f64,
    /// Smallest parametric area over the mean parametric area.
    pub min_relative_uv_area: f64,
    /// Largest over smallest vertex area scale `A_uv / A_3d` (1 for an
    /// isometry up to scale; see `verify::area_distortion`).
    pub area_distortion: f64,
    /// Times this patch's ancestors were split because a map failed.
    pub n_map_splits: usize,
    /// Sparse solver used for the map.
    pub solver: MvcSolver,
    /// BiCGSTAB iterations (refinement steps with the default `lu`; 0 with
    /// `pivoting-lu`) for u and v.
    pub krylov_iterations: [usize; 2],
    /// Wall seconds spent refining, solving and verifying this patch.
    pub solve_seconds: f64,
}

/// Why patches were split, counted.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct SplitCounts {
    /// Closed model faces (no boundary).
    pub closed: usize,
    /// Genus above zero.
    pub genus: usize,
    /// Non-manifold vertex inside.
    pub nonmanifold: usize,
    /// Not orientable.
    pub not_orientable: usize,
    /// Disconnected (after an earlier split).
    pub disconnected: usize,
    /// Boundary touching itself.
    pub pinched_boundary: usize,
    /// Above `max_patch_triangles` (one count per cut, whatever its number of parts).
    pub size: usize,
    /// The map failed verification (flipped or near-zero parametric areas).
    pub map_failed: usize,
    /// The map's area distortion exceeded `max_area_distortion`.
    pub distortion: usize,
    /// Model faces cut along a crease that has the face on both sides
    /// ([`super::creases`]).
    pub inner_crease: usize,
}

/// Why one patch was split.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SplitReason {
    /// Not a disk with holes.
    Topology(PatchDefect),
    /// Above `max_patch_triangles`.
    Size,
    /// The map failed verification.
    MapFailed,
    /// The map is one-to-one but its area distortion exceeds `max_area_distortion`.
    Distortion,
}

impl SplitCounts {
    /// Count one split with its reason.
    pub fn count(&mut self, reason: SplitReason) {
        let slot = match reason {
            SplitReason::MapFailed => &mut self.map_failed,
            SplitReason::Distortion => &mut self.distortion,
            SplitReason::Size => &mut self.size,
            SplitReason::Topology(PatchDefect::Closed) => &mut self.closed,
            SplitReason::Topology(PatchDefect::Genus) => &mut self.genus,
            SplitReason::Topology(PatchDefect::NonManifold) => &mut self.nonmanifold,
            SplitReason::Topology(PatchDefect::NotOrientable) => &mut self.not_orientable,
            SplitReason::Topology(PatchDefect::Disconnected) => &mut self.disconnected,
            SplitReason::Topology(PatchDefect::PinchedBoundary) => &mut self.pinched_boundary,
        };
        *slot += 1;
    }
}

/// Summary of the atlas stage.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct AtlasReport {
    /// Input triangles.
    pub n_input_triangles: usize,
    /// Atlas triangles (after refinement).
    pub n_triangles: usize,
    /// Patches.
    pub n_patches: usize,
    /// Model faces (regions between feature edges) before splitting.
    pub n_model_faces: usize,
    /// Feature edges by dihedral angle.
    pub n_sharp_edges: usize,
    /// Feature curves of the input (chains of feature edges).
    pub n_feature_curves: usize,
    /// Curves of the atlas (feature curves and cuts).
    pub n_curves: usize,
    /// Corners of the atlas.
    pub n_corners: usize,
    /// Euler characteristic of each input component.
    pub euler_characteristic_per_component: Vec<i64>,
    /// Splits by reason.
    pub splits: SplitCounts,
    /// Patches refined by bisection.
    pub n_refined_patches: usize,
    /// Smallest σ2/σ1 over all patches.
    pub sigma_ratio_min: f64,
    /// Median of the per-patch median σ2/σ1 (weighted by nothing).
    pub sigma_ratio_median: f64,
    /// Wall seconds: feature detection.
    pub features_seconds: f64,
    /// Wall seconds: splitting, refining and parameterizing patches.
    pub patches_seconds: f64,
    /// Wall seconds: curves, corners and curvature.
    pub curves_seconds: f64,
    /// Per-patch details.
    pub patches: Vec<PatchReport>,
}

impl AtlasReport {
    /// Summarize a finished atlas.
    pub fn new(
        input: &TriMesh,
        summary: &TopologySummary,
        atlas: &Atlas,
        n_model_faces: usize,
        splits: SplitCounts,
        [features_seconds, patches_seconds, curves_seconds]: [f64; 3],
    ) -> Self {
        let patches: Vec<PatchReport> = atlas.patches.iter().map(|p| p.report.clone()).collect();
        let mut medians: Vec<f64> = patches.iter().map(|p| p.sigma_ratio_median).collect();
        medians.sort_by(f64::total_cmp);
        AtlasReport {
            n_input_triangles: input.n_faces(),
            n_triangles: atlas.mesh.n_faces(),
            n_patches: atlas.patches.len(),
            n_model_faces,
            n_sharp_edges: atlas.features.n_sharp_edges,
            n_feature_curves: atlas.features.curves.len(),
            n_curves: atlas.curves.len(),
            n_corners: atlas.corners.len(),
            euler_characteristic_per_component: summary.components.iter().map(|c| c.euler_characteristic).collect(),
            splits,
            n_refined_patches: patches.iter().filter(|p| p.n_bisections > 0).count(),
            sigma_ratio_min: patches.iter().map(|p| p.sigma_ratio_min).fold(f64::INFINITY, f64::min),
            sigma_ratio_median: medians.get(medians.len() / 2).copied().unwrap_or(0.0),
            features_seconds,
            patches_seconds,
            curves_seconds,
            patches,
        }
    }
}
