//! Options of the atlas stage.

use super::error::AtlasError;
use super::mvc::MvcSolver;
use serde::{Deserialize, Serialize};

/// Parameters of [`super::build_atlas`]; every field has a default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AtlasOptions {
    /// Dihedral angle (degrees, between triangle normals) above which an edge
    /// is a feature edge. Default 40; 180 turns angle features off (boundary
    /// and non-manifold edges stay features).
    pub feature_angle_deg: f64,
    /// Largest patch (triangles, before refinement) parameterized in one
    /// piece; a larger patch is cut into as few parts as fit
    /// ([`super::partition::parts_for_size`]). Default 100000.
    pub max_patch_triangles: usize,
    /// Holes with at most this many vertices are filled with a pseudo-centre
    /// (thesis ch. 2 §3.4); larger ones get homogeneous Neumann conditions.
    /// Default 500.
    pub max_hole_fill_vertices: usize,
    /// A patch whose fraction of interior vertices is below this value is
    /// refined by longest-edge bisection before it is parameterized (§5.1).
    /// Default 0.25; 0 disables refinement.
    pub refine_below_interior_fraction: f64,
    /// Bisection passes at most (each roughly halves the inner edge lengths).
    /// Default 5.
    pub refine_max_passes: usize,
    /// A refined patch has at most this many times its triangles (at least
    /// 64 triangles, at most `max_patch_triangles`); bisection stops, longest
    /// edges first, when the cap is reached. Default 16.
    pub refine_max_growth: usize,
    /// A parametric triangle with area below this fraction of the patch's
    /// mean parametric area makes the map unusable, and the patch is split
    /// and redone (§4.2). Default 1e-12.
    pub min_relative_uv_area: f64,
    /// A one-to-one map whose area distortion (largest over smallest vertex
    /// area scale `A_uv / A_3d`) exceeds this is split, so that mesh
    /// generators do not have to resolve scales many orders of magnitude
    /// apart in `(u, v)` (long tubes, bulges). Default 1e4 (sphere halves:
    /// 12; CAD faces of the corpus: up to 1e3; a torus half: 1e7).
    pub max_area_distortion: f64,
    /// How many times a patch may be split because its map failed before
    /// the stage gives up with an error naming it. Default 16.
    pub max_split_depth: usize,
    /// Sparse solver of the mean value systems: `"lu"` (default; supernodal
    /// LU in single precision, refined in double), `"bicgstab"`
    /// (preconditioned by the Cholesky factor of the symmetrized matrix) or
    /// `"pivoting-lu"`; see [`MvcSolver`].
    pub solver: MvcSolver,
}

impl Default for AtlasOptions {
    fn default() -> Self {
        Self {
            feature_angle_deg: 40.0,
            max_patch_triangles: 100_000,
            max_hole_fill_vertices: 500,
            refine_below_interior_fraction: 0.25,
            refine_max_passes: 5,
            refine_max_growth: 16,
            min_relative_uv_area: 1e-12,
            max_area_distortion: 1e4,
            max_split_depth: 16,
            solver: MvcSolver::Lu,
        }
    }
}

impl AtlasOptions {
    /// Check every option is in range.
    ///
    /// # Errors
    /// [`AtlasError::InvalidOption`] naming the first bad option.
    pub fn validate(&self) -> Result<(), AtlasError> {
        let bad = |name, reason: &str| Err(AtlasError::InvalidOption { name, reason: reason.into() });
        if !(0.0..=180.0).contains(&self.feature_angle_deg) {
            return bad("feature_angle_deg", "must be within [0, 180]");
        }
        if self.max_patch_triangles < 2 {
            return bad("max_patch_triangles", "must be at least 2");
        }
        if !(0.0..=1.0).contains(&self.refine_below_interior_fraction) {
            return bad("refine_below_interior_fraction", "must be within [0, 1]");
        }
        if self.refine_max_passes > 12 {
            return bad("refine_max_passes", "must be at most 12");
        }
        if !(self.max_area_distortion >= 1.0) {
            return bad("max_area_distortion", "must be at least 1");
        }
        if !(0.0..1.0).contains(&self.min_relative_uv_area) {
            return bad("min_relative_uv_area", "must be within [0, 1)");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_fields_are_rejected_and_defaults_fill_in() {
        let o: AtlasOptions = serde_json::from_str(r#"{"feature_angle_deg": 30}"#).unwrap();
        assert_eq!(o.feature_angle_deg, 30.0);
        assert_eq!(o.max_patch_triangles, 100_000);
        let e = serde_json::from_str::<AtlasOptions>(r#"{"feature_angle": 30}"#).unwrap_err();
        assert!(e.to_string().contains("unknown field `feature_angle`"));
        assert!(AtlasOptions { feature_angle_deg: 200.0, ..Default::default() }.validate().is_err());
        assert!(AtlasOptions::default().validate().is_ok());
    }
}
