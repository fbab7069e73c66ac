//! A patch's `(u, v)` chart: point location among its triangles (a bucket
//! grid), the map `(u, v) → 3D` and its Jacobian, and where a chart point
//! lies on the input surface.

use super::surface_mesh::SurfacePoint;
use crate::atlas::{Atlas, AtlasPatch};
use crate::geom::{Vec2, Vec3};
use crate::mesh::{FaceId, TriMesh};

/// 3D position of a surface point.
pub fn surface_position(surface: &TriMesh, p: &SurfacePoint) -> Vec3 {
    let c = surface.corners(p.face);
    c[0] * p.bary[0] + c[1] * p.bary[1] + c[2] * p.bary[2]
}

/// Barycentric coordinates of `x` in the 2D triangle `p` (unclamped).
fn bary2(p: &[Vec2; 3], x: &Vec2) -> Option<[f64; 3]> {
    let (e1, e2, r) = (p[1] - p[0], p[2] - p[0], x - p[0]);
    let det = e1.x * e2.y - e1.y * e2.x;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let b1 = (r.x * e2.y - r.y * e2.x) / det;
    let b2 = (e1.x * r.y - e1.y * r.x) / det;
    Some([1.0 - b1 - b2, b1, b2])
}

/// The chart of one patch.
pub struct PatchChart<'a> {
    surface: &'a TriMesh,
    atlas: &'a Atlas,
    patch: &'a AtlasPatch,
    min: Vec2,
    cell: f64,
    nx: usize,
    ny: usize,
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl<'a> PatchChart<'a> {
    /// The chart of `patch` of `atlas` (built on `surface`).
    pub fn new(surface: &'a TriMesh, atlas: &'a Atlas, patch: &'a AtlasPatch) -> Self {
        let mut min = Vec2::new(f64::INFINITY, f64::INFINITY);
        let mut max = -min;
        for p in &patch.uv {
            min = min.inf(p);
            max = max.sup(p);
        }
        let n = (patch.triangles.len() as f64).sqrt().ceil().max(1.0) as usize;
        let extent = (max - min).max().max(1e-300);
        let cell = extent / n as f64 * (1.0 + 1e-9);
        let (nx, ny) = (n, n);
        let cell_of = |x: f64, lo: f64, k: usize| (((x - lo) / cell).floor().max(0.0) as usize).min(k - 1);
        let ranges: Vec<[usize; 4]> = patch
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| patch.uv[v as usize]);
                let lo = p[0].inf(&p[1]).inf(&p[2]);
                let hi = p[0].sup(&p[1]).sup(&p[2]);
                [cell_of(lo.x, min.x, nx), cell_of(hi.x, min.x, nx), cell_of(lo.y, min.y, ny), cell_of(hi.y, min.y, ny)]
            })
            .collect();
        let mut offsets = vec![0u32; nx * ny + 1];
        for r in &ranges {
            for j in r[2]..=r[3] {
                for i in r[0]..=r[1] {
                    offsets[j * nx + i + 1] += 1;
                }
            }
        }
        for k in 0..nx * ny {
            offsets[k + 1] += offsets[k];
        }
        let mut fill = offsets.clone();
        let mut items = vec![0u32; offsets[nx * ny] as usize];
        for (t, r) in ranges.iter().enumerate() {
            for j in r[2]..=r[3] {
                for i in r[0]..=r[1] {
                    items[fill[j * nx + i] as usize] = t as u32;
                    fill[j * nx + i] += 1;
                }
            }
        }
        Self { surface, atlas, patch, min, cell, nx, ny, offsets, items }
    }

    /// `(u, v)` of the corners of local triangle `t`.
    fn uv_corners(&self, t: u32) -> [Vec2; 3] {
        self.patch.triangles[t as usize].map(|v| self.patch.uv[v as usize])
    }

    /// 3D corners (atlas mesh) of local triangle `t`.
    fn corners(&self, t: u32) -> [Vec3; 3] {
        self.patch.triangles[t as usize].map(|v| self.atlas.mesh.positions[self.patch.vertices[v as usize].idx()])
    }

    /// Candidate triangles of the grid cell containing `uv` (empty outside;
    /// a point off the chart's bounding box by rounding, as a boundary
    /// point interpolated on an edge of the box can be, is in its border
    /// cell).
    fn cell_items(&self, uv: &Vec2) -> &[u32] {
        const SLACK: f64 = 1e-6;
        let fx = (uv.x - self.min.x) / self.cell;
        let fy = (uv.y - self.min.y) / self.cell;
        let (nx, ny) = (self.nx as f64, self.ny as f64);
        if !(fx >= -SLACK && fy >= -SLACK && fx < nx + SLACK && fy < ny + SLACK) {
            return &[];
        }
        let k = (fy.max(0.0) as usize).min(self.ny - 1) * self.nx + (fx.max(0.0) as usize).min(self.nx - 1);
        &self.items[self.offsets[k] as usize..self.offsets[k + 1] as usize]
    }

    /// The local triangle containing `uv` and the barycentric coordinates
    /// there (clamped); `None` outside the patch (holes included).
    pub fn locate(&self, uv: &Vec2) -> Option<(u32, [f64; 3])> {
        let (t, b) = self.nearest_in_cell(uv)?;
        (b.iter().fold(f64::INFINITY, |m, &x| m.min(x)) >= -1e-12).then(|| (t, clamp_bary(b)))
    }

    /// The triangle of `uv`'s grid cell containing it best (largest smallest
    /// barycentric coordinate), unclamped.
    fn nearest_in_cell(&self, uv: &Vec2) -> Option<(u32, [f64; 3])> {
        let mut best: Option<(u32, [f64; 3], f64)> = None;
        for &t in self.cell_items(uv) {
            if let Some(b) = bary2(&self.uv_corners(t), uv) {
                let m = b[0].min(b[1]).min(b[2]);
                if best.as_ref().is_none_or(|x| m > x.2) {
                    best = Some((t, b, m));
                }
            }
        }
        best.map(|(t, b, _)| (t, b))
    }

    /// Like [`Self::locate`] but accepts a point slightly outside (the
    /// nearest triangle of its cell), for centroids of boundary triangles.
    pub fn locate_near(&self, uv: &Vec2) -> Option<(u32, [f64; 3])> {
        self.nearest_in_cell(uv).map(|(t, b)| (t, clamp_bary(b)))
    }

    /// 3D position of the chart point `(t, bary)` (on the atlas triangle).
    pub fn position(&self, t: u32, bary: &[f64; 3]) -> Vec3 {
        let c = self.corners(t);
        c[0] * bary[0] + c[1] * bary[1] + c[2] * bary[2]
    }

    /// Area (3D) of the patch.
    pub fn area(&self) -> f64 {
        self.patch.faces.iter().map(|&f| self.atlas.mesh.face_area(f)).sum()
    }

    /// The surface triangle containing local triangle `t`.
    pub fn source_face(&self, t: u32) -> FaceId {
        self.atlas.source_face[self.patch.faces[t as usize].idx()]
    }

    /// Where the chart point `(t, bary)` lies on the input surface.
    pub fn surface_point(&self, t: u32, bary: &[f64; 3]) -> SurfacePoint {
        let x = self.position(t, bary);
        let face = self.source_face(t);
        let f = self.surface.corners(face);
        let (e1, e2, r) = (f[1] - f[0], f[2] - f[0], x - f[0]);
        let (a, b, d) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
        let det = a * d - b * b;
        let (b1, b2) = if det > 0.0 {
            let (r1, r2) = (r.dot(&e1), r.dot(&e2));
            ((d * r1 - b * r2) / det, (a * r2 - b * r1) / det)
        } else {
            (1.0 / 3.0, 1.0 / 3.0)
        };
        SurfacePoint { face, bary: clamp_bary([1.0 - b1 - b2, b1, b2]) }
    }

    /// `∂X/∂u`, `∂X/∂v` of the chart on local triangle `t`.
    pub fn jacobian(&self, t: u32) -> Option<[Vec3; 2]> {
        let p = self.uv_corners(t);
        let c = self.corners(t);
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let det = e1.x * e2.y - e1.y * e2.x;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let (x1, x2) = (c[1] - c[0], c[2] - c[0]);
        // [x1 x2] = J [e1 e2]  ⇒  J = [x1 x2] [e1 e2]⁻¹.
        let ju = (x1 * e2.y - x2 * e1.y) / det;
        let jv = (x2 * e1.x - x1 * e2.x) / det;
        Some([ju, jv])
    }

    /// The `(u, v)` step whose image is closest to the 3D step `d` on local
    /// triangle `t`: the pseudo-inverse `(JᵀJ)⁻¹Jᵀ d`.
    pub fn uv_step(&self, t: u32, d: &Vec3) -> Option<Vec2> {
        let [ju, jv] = self.jacobian(t)?;
        let (a, b, c) = (ju.dot(&ju), ju.dot(&jv), jv.dot(&jv));
        let det = a * c - b * b;
        if !(det > 0.0) {
            return None;
        }
        let (r1, r2) = (ju.dot(d), jv.dot(d));
        Some(Vec2::new((c * r1 - b * r2) / det, (a * r2 - b * r1) / det))
    }

    /// True when the chart keeps the orientation of the surface on local
    /// triangle `t` (positive `(∂X/∂u × ∂X/∂v) · n`).
    pub fn is_direct(&self, t: u32) -> bool {
        self.jacobian(t)
            .is_some_and(|[ju, jv]| ju.cross(&jv).dot(&self.surface.face_area_vector(self.source_face(t))) > 0.0)
    }
}

/// Barycentric coordinates clamped to be non-negative and sum to 1.
fn clamp_bary(b: [f64; 3]) -> [f64; 3] {
    let c = b.map(|x| x.max(0.0));
    let s = c[0] + c[1] + c[2];
    if s > 0.0 { c.map(|x| x / s) } else { [1.0 / 3.0; 3] }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::{AtlasOptions, build_atlas};
    use crate::mesh::fixtures::square_structured;
    use crate::progress::Progress;

    #[test]
    fn a_point_off_the_chart_box_by_rounding_is_located() {
        let mesh = square_structured(4);
        let atlas = build_atlas(&mesh, &AtlasOptions::default(), &Progress::none()).expect("atlas");
        let patch = &atlas.patches[0];
        let chart = PatchChart::new(&mesh, &atlas, patch);
        let lowest = patch.uv.iter().copied().min_by(|a, b| a.y.total_cmp(&b.y)).expect("vertices");
        // Interpolated on a boundary edge, a point can land an ulp below
        // the lowest vertex.
        let below = Vec2::new(lowest.x, lowest.y - 4.0 * f64::EPSILON);
        assert!(chart.locate_near(&below).is_some());
        assert!(chart.locate_near(&Vec2::new(lowest.x, lowest.y - 0.5)).is_none(), "far outside");
    }
}
