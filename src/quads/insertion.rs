//! Frontal point placement in a patch's `(u, v)` plane ("packing of
//! parallelograms", research doc §1.1 and §5.1 step 2): a FIFO front seeded
//! with the boundary points; each accepted point spawns candidates one
//! target size away along `±t1`, `±t2` of the cross (mapped to `(u, v)`
//! through the pseudo-inverse of the chart's Jacobian, the step corrected
//! so its 3D length is the size). A candidate is rejected outside the patch,
//! inside the exclusion square of an existing point (half-width
//! [`EXCLUSION`] × size, aligned with that point's cross, in its tangent
//! plane), within [`EXCLUSION`] × size of a singular point, or closer than
//! [`BOUNDARY_CLEARANCE`] × size to the boundary polyline.
//!
//! The size is the size map's at the candidate, except for the first row
//! (the candidates of points on a model curve; a seam is crossed as if it
//! were not there), which is judged at the smaller of that and the curve
//! point's size, with the narrower [`FIRST_ROW_EXCLUSION`]: where the size grows away from a convex curve (the disk
//! capping a cylinder, whose circle is cut finer than its inside needs),
//! the inward steps converge while the size grows, and a first row judged
//! at the larger size loses every other point; a curve point left with no
//! inward edge then gets a flat quad corner (165° on a 24-gon). The
//! narrower square keeps the points of two inward steps that are not quite
//! parallel.

use std::collections::{HashMap, VecDeque};

use super::patch_chart::PatchChart;
use super::size_map::SizeMap;
use crate::crossfield::Crossfield;
use crate::geom::{Vec2, Vec3};
use crate::mesh::TriMesh;
use crate::progress::{Cancelled, Progress};

/// Half-width of a point's exclusion square, in units of the size.
pub const EXCLUSION: f64 = 0.7;
/// Half-width of the exclusion square for the first row (candidates of a
/// point on a model curve), in units of the size: two inward steps from
/// neighbouring curve points are not quite parallel (on cylinder_coarse's
/// caps they land 0.168–0.184 apart against an exclusion of 0.183 at 0.7),
/// and a first-row point lost leaves its curve point a flat quad corner.
pub const FIRST_ROW_EXCLUSION: f64 = 0.6;
/// Smallest distance of an inserted point to the boundary, in units of the size.
pub const BOUNDARY_CLEARANCE: f64 = 0.5;

/// A point of the chart: `(u, v)`, local triangle and barycentric coordinates there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChartPoint {
    /// `(u, v)`.
    pub uv: Vec2,
    /// Local triangle of the patch.
    pub tri: u32,
    /// Barycentric coordinates on it.
    pub bary: [f64; 3],
}

/// A point already placed: 3D position and the frame `t1, t2, n` of its
/// exclusion square (`None` for a singular point: a disk).
struct Placed {
    x: Vec3,
    frame: Option<[Vec3; 3]>,
}

/// 3D bucket grid of cell `size` for the exclusion and clearance queries.
struct Grid {
    cell: f64,
    points: HashMap<[i64; 3], Vec<u32>>,
    segments: HashMap<[i64; 3], Vec<u32>>,
}

impl Grid {
    fn key(&self, x: &Vec3) -> [i64; 3] {
        [(x.x / self.cell).floor() as i64, (x.y / self.cell).floor() as i64, (x.z / self.cell).floor() as i64]
    }

    fn neighbours<'g>(&'g self, map: &'g HashMap<[i64; 3], Vec<u32>>, x: &Vec3) -> impl Iterator<Item = u32> + 'g {
        let k = self.key(x);
        (-1..=1).flat_map(move |i| {
            (-1..=1).flat_map(move |j| {
                (-1..=1).flat_map(move |l| map.get(&[k[0] + i, k[1] + j, k[2] + l]).into_iter().flatten().copied())
            })
        })
    }
}

/// Distance from `x` to the segment `a b`.
fn segment_distance(x: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let t = if l2 > 0.0 { ((x - a).dot(&ab) / l2).clamp(0.0, 1.0) } else { 0.0 };
    (x - (a + ab * t)).norm()
}

/// Everything one patch's front works with.
struct Front<'a> {
    chart: &'a PatchChart<'a>,
    surface: &'a TriMesh,
    field: &'a Crossfield,
    sizes: &'a SizeMap,
    grid: Grid,
    placed: Vec<Placed>,
    boundary: Vec<[Vec3; 2]>,
}

impl Front<'_> {
    /// The cross frame `t1, t2, n` on local triangle `t`.
    fn frame(&self, t: u32) -> [Vec3; 3] {
        let f = self.chart.source_face(t);
        let n = self.surface.face_normal(f);
        let t1 = self.field.cross_per_face.get(f.idx()).copied().unwrap_or_else(Vec3::zeros);
        [t1, n.cross(&t1), n]
    }

    /// The target size at `x` on local triangle `t` (the size map).
    fn size_at(&self, t: u32, x: &Vec3) -> f64 {
        self.sizes.at_position(self.surface, self.chart.source_face(t), x)
    }

    fn add(&mut self, x: Vec3, frame: Option<[Vec3; 3]>) {
        let k = self.grid.key(&x);
        self.grid.points.entry(k).or_default().push(self.placed.len() as u32);
        self.placed.push(Placed { x, frame });
    }

    fn add_segment(&mut self, a: Vec3, b: Vec3) {
        let id = self.boundary.len() as u32;
        let steps = ((b - a).norm() / (0.25 * self.grid.cell)).ceil().max(1.0) as usize;
        let mut keys: Vec<[i64; 3]> =
            (0..=steps).map(|i| self.grid.key(&(a + (b - a) * (i as f64 / steps as f64)))).collect();
        keys.sort_unstable();
        keys.dedup();
        for k in keys {
            self.grid.segments.entry(k).or_default().push(id);
        }
        self.boundary.push([a, b]);
    }

    /// True when a point at `x` keeps its distance to every placed point
    /// (outside their exclusion squares of half-width `exclusion` × `local`)
    /// and to the boundary.
    fn is_free(&self, x: &Vec3, local: f64, exclusion: f64) -> bool {
        let h = exclusion * local;
        for q in self.grid.neighbours(&self.grid.points, x) {
            let q = &self.placed[q as usize];
            let d = x - q.x;
            if d.norm() >= local {
                continue;
            }
            let inside = match &q.frame {
                None => d.norm() < h,
                Some([t1, t2, n]) => d.dot(t1).abs() < h && d.dot(t2).abs() < h && d.dot(n).abs() < h,
            };
            if inside {
                return false;
            }
        }
        let clearance = BOUNDARY_CLEARANCE * local;
        !self.grid.neighbours(&self.grid.segments, x).any(|s| {
            let [a, b] = &self.boundary[s as usize];
            segment_distance(x, a, b) < clearance
        })
    }

    /// The candidate one size from `p` along the 3D direction `dir`, if it
    /// lies in the patch.
    fn candidate(&self, p: &ChartPoint, x: &Vec3, dir: &Vec3) -> Option<(ChartPoint, Vec3)> {
        let length = self.size_at(p.tri, x);
        let duv = self.chart.uv_step(p.tri, &(dir * length))?;
        let mut scale = 1.0;
        let mut out = None;
        for _ in 0..2 {
            let uv = p.uv + duv * scale;
            let (tri, bary) = self.chart.locate(&uv)?;
            let y = self.chart.position(tri, &bary);
            let step = (y - x).norm();
            out = Some((ChartPoint { uv, tri, bary }, y));
            if step.is_nan() || step <= 1e-12 * length {
                return None;
            }
            scale *= length / step;
        }
        out
    }
}

/// Points inside one patch at spacing `size` along `field`: `boundary` are
/// the patch's boundary points (chart point, spawning; `on_curve`: whether
/// each lies on a model curve rather than a seam), `segments` the
/// boundary polyline (pairs of indices into `boundary`), `singular` the
/// points placed at singularities (kept, never spawning). Returns the new
/// points (not the boundary or singular ones), in placement order.
///
/// # Errors
/// [`Cancelled`].
#[allow(clippy::too_many_arguments)]
pub fn insert_points(
    chart: &PatchChart,
    surface: &TriMesh,
    field: &Crossfield,
    sizes: &SizeMap,
    boundary: &[ChartPoint],
    on_curve: &[bool],
    segments: &[[usize; 2]],
    singular: &[ChartPoint],
    progress: &Progress,
) -> Result<Vec<ChartPoint>, Cancelled> {
    let (size, largest) = sizes.range();
    let mut front = Front {
        chart,
        surface,
        field,
        sizes,
        grid: Grid { cell: largest, points: HashMap::new(), segments: HashMap::new() },
        placed: Vec::new(),
        boundary: Vec::new(),
    };
    let positions: Vec<Vec3> = boundary.iter().map(|p| chart.position(p.tri, &p.bary)).collect();
    for &[a, b] in segments {
        front.add_segment(positions[a], positions[b]);
    }
    // Queued points, with the size of the curve point that spawned them
    // (the first row) or `None`.
    let mut queue: VecDeque<(ChartPoint, Vec3, Option<f64>)> = VecDeque::new();
    for ((p, x), &curve) in boundary.iter().zip(&positions).zip(on_curve) {
        front.add(*x, Some(front.frame(p.tri)));
        queue.push_back((*p, *x, curve.then(|| front.size_at(p.tri, x))));
    }
    for p in singular {
        front.add(chart.position(p.tri, &p.bary), None);
    }
    let cap = (4.0 * chart.area() / (size * size)) as usize + 1000;
    let mut out = Vec::new();
    while let Some((p, x, curve_size)) = queue.pop_front() {
        let [t1, t2, _] = front.frame(p.tri);
        for dir in [t1, t2, -t1, -t2] {
            if dir.norm_squared() == 0.0 {
                continue;
            }
            let Some((c, y)) = front.candidate(&p, &x, &dir) else { continue };
            let local = front.size_at(c.tri, &y);
            let exclusion = if curve_size.is_some() { FIRST_ROW_EXCLUSION } else { EXCLUSION };
            if front.is_free(&y, curve_size.map_or(local, |b| b.min(local)), exclusion) {
                front.add(y, Some(front.frame(c.tri)));
                out.push(c);
                queue.push_back((c, y, None));
            }
        }
        if out.len() % 1024 == 1023 {
            progress.check()?;
        }
        if out.len() > cap {
            break;
        }
    }
    Ok(out)
}
