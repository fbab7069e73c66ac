//! Verification of a patch map (thesis ch. 2 §2–3, §4.2): injectivity and
//! the conformity indicator σ2/σ1.
//!
//! A discrete map is one-to-one if and only if every parametric triangle has
//! positive area (§3). Areas near round-off make the map useless even when
//! positive, so a triangle whose `(u, v)` area falls below
//! `min_relative_area` times the mean parametric area is a failure too and
//! the patch is split and redone (§4.2). The indicator of a triangle is the
//! ratio of the singular values `σ2 ≤ σ1` of the Jacobian `J = ∂x/∂(u, v)`
//! (2.2) of its affine map: 1 for conformal, → 0 for strongly anisotropic.

use super::patch::PatchMesh;
use crate::geom::{Vec2, Vec3, orient2d};
use serde::Serialize;

/// Outcome of checking a patch map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapCheck {
    /// Triangles with non-positive parametric area.
    pub n_flipped: usize,
    /// Triangles with positive parametric area below the relative tolerance.
    pub n_tiny: usize,
    /// Smallest parametric area divided by the mean parametric area.
    pub min_relative_area: f64,
}

impl MapCheck {
    /// True when the map is one-to-one and usable.
    pub fn is_valid(&self) -> bool {
        self.n_flipped == 0 && self.n_tiny == 0
    }
}

/// Check the parametric triangles of `patch` under `uv`.
pub fn check_map(patch: &PatchMesh, uv: &[Vec2], min_relative_area: f64) -> MapCheck {
    let areas: Vec<f64> = patch
        .mesh
        .triangles
        .iter()
        .map(|t| 0.5 * orient2d(&uv[t[0].idx()], &uv[t[1].idx()], &uv[t[2].idx()]))
        .collect();
    let total: f64 = areas.iter().filter(|a| **a > 0.0).sum();
    let mean = total / areas.len().max(1) as f64;
    let threshold = min_relative_area * mean;
    let n_flipped = areas.iter().filter(|a| a.is_nan() || **a <= 0.0).count();
    let n_tiny = areas.iter().filter(|a| **a > 0.0 && **a < threshold).count();
    let min = areas.iter().copied().fold(f64::INFINITY, f64::min);
    MapCheck { n_flipped, n_tiny, min_relative_area: if mean > 0.0 { min / mean } else { 0.0 } }
}

/// Area distortion of the map: the ratio of the largest to the smallest
/// vertex scale `s_v = Σ A_uv / Σ A_3d` over the triangles around `v`.
///
/// MVC maps of long or bulging patches compress exponentially (a tube's
/// far end, a bunny's ear): every triangle stays positive, but a mesh
/// generator working in `(u, v)` must then resolve scales that differ by
/// orders of magnitude, and Gmsh's planar meshers fail or crawl. Averaging
/// over the one-ring keeps single slivers from dominating the measure.
pub fn area_distortion(patch: &PatchMesh, uv: &[Vec2]) -> f64 {
    let n = patch.mesh.n_vertices();
    let (mut a_uv, mut a_3d) = (vec![0.0f64; n], vec![0.0f64; n]);
    for (f, t) in patch.mesh.triangles.iter().enumerate() {
        let auv = 0.5 * orient2d(&uv[t[0].idx()], &uv[t[1].idx()], &uv[t[2].idx()]);
        let a3 = patch.mesh.face_area(crate::mesh::FaceId::new(f));
        for v in t {
            a_uv[v.idx()] += auv;
            a_3d[v.idx()] += a3;
        }
    }
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in 0..n {
        if a_3d[v] > 0.0 && a_uv[v] > 0.0 {
            let s = a_uv[v] / a_3d[v];
            lo = lo.min(s);
            hi = hi.max(s);
        }
    }
    if lo.is_finite() && lo > 0.0 { hi / lo } else { f64::INFINITY }
}

/// σ2/σ1 of the affine map from parametric triangle `q` to 3D triangle `p`
/// (0 when the parametric triangle is degenerate).
pub fn sigma_ratio(p: [Vec3; 3], q: [Vec2; 3]) -> f64 {
    let (du1, du2) = (q[1] - q[0], q[2] - q[0]);
    let det = du1.x * du2.y - du1.y * du2.x;
    if det == 0.0 || !det.is_finite() {
        return 0.0;
    }
    let (dx1, dx2) = (p[1] - p[0], p[2] - p[0]);
    // J = [dx1 dx2] · inv([du1 du2]); its columns are ∂x/∂u and ∂x/∂v.
    let ju = (dx1 * du2.y - dx2 * du1.y) / det;
    let jv = (dx2 * du1.x - dx1 * du2.x) / det;
    let (a, b, c) = (ju.dot(&ju), ju.dot(&jv), jv.dot(&jv));
    // Eigenvalues of the 2×2 metric [[a, b], [b, c]] are σ1², σ2².
    let mean = 0.5 * (a + c);
    let disc = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (l1, l2) = (mean + disc, (mean - disc).max(0.0));
    if l1 <= 0.0 { 0.0 } else { (l2 / l1).sqrt() }
}

/// σ2/σ1 of every triangle of the patch.
pub fn sigma_ratios(patch: &PatchMesh, uv: &[Vec2]) -> Vec<f64> {
    patch
        .mesh
        .triangles
        .iter()
        .map(|t| sigma_ratio(t.map(|v| patch.mesh.positions[v.idx()]), t.map(|v| uv[v.idx()])))
        .collect()
}

/// Minimum and median of a list of σ2/σ1 values (`(0, 0)` when empty).
pub fn min_and_median(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    (v[0], v[v.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigma_ratio_of_known_maps() {
        let p = [Vec3::zeros(), Vec3::x(), Vec3::y()];
        // Identity-like (rotation + scale) map: conformal.
        let q = [Vec2::zeros(), Vec2::new(0.0, 2.0), Vec2::new(-2.0, 0.0)];
        assert!((sigma_ratio(p, q) - 1.0).abs() < 1e-14);
        // Stretch u by 4: σ2/σ1 = 1/4.
        let q = [Vec2::zeros(), Vec2::new(4.0, 0.0), Vec2::new(0.0, 1.0)];
        assert!((sigma_ratio(p, q) - 0.25).abs() < 1e-14);
        assert_eq!(sigma_ratio(p, [Vec2::zeros(); 3]), 0.0);
    }

    #[test]
    fn median_and_min() {
        assert_eq!(min_and_median(&[0.5, 0.1, 0.9]), (0.1, 0.5));
        assert_eq!(min_and_median(&[]), (0.0, 0.0));
    }
}
