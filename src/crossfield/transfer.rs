//! Transfer of a crossfield from a coarse triangulation of a surface to a
//! finer one of the same surface (the prolongation of the multilevel
//! continuation, see [`super::compute`]).
//!
//! Conforming interpolation. The coarse CR field is continuous only at edge
//! midpoints; interpolated as is, its jumps across coarse edges (of order
//! `h_c |∇f|`) become steep gradients on the fine mesh, with markedly more
//! energy than the coarse field (`docs/decisions.md`).
//! So the field is first made P1: in each coarse triangle `T` the CR
//! function's value at corner `i` is `F_i + F_{i+2} − F_{i+1}` (`F_k` the
//! value of local edge `k`, which goes from corner `k` to `k+1`, in `T`'s
//! frame); each vertex averages those values over its triangles after
//! rotating them into a vertex frame (`F_v = z^N F_T`, `z = exp(iβ)` with `β`
//! the angle of `T`'s reference direction projected on the vertex's tangent
//! plane). At a point of `T` with barycentric coordinates `λ` the field is
//! `W = Σ_i λ_i z̄_{T,i}^N F_{v_i}` in `T`'s frame.
//!
//! Location. For each fine edge `p` (CR node at its midpoint `m_p`) the
//! closest coarse triangle is found (uniform grid over the coarse triangles;
//! among triangles not facing against `p`'s normal, so two sheets close
//! together do not mix). One branch of the cross there is the tangent vector
//! `u = cos(θ) r̂_T + sin(θ) n̂_T × r̂_T` with `θ = arg(W)/N`; its projection on
//! `p`'s tangent plane has the angle `φ` from `ê^p`, and the fine value is
//! `f_p = |W| exp(i N φ)`. Taking the N-th power makes the result
//! independent of the branch chosen.
//!
//! Cost: `O(n_coarse)` for the vertex values, then `O(n_fine)` queries of a
//! few grid cells each, in parallel; the grid holds each coarse triangle in
//! the cells its bounding box overlaps.

use super::frames::{C64, Discretization, complex_pow, edge_direction, edge_normal, face_frame};
use crate::geom::Vec3;
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh};
use rayon::prelude::*;

/// Uniform grid of triangle bounding boxes, in compressed rows per cell.
struct TriangleGrid {
    origin: Vec3,
    cell: f64,
    dims: [usize; 3],
    start: Vec<u32>,
    items: Vec<u32>,
}

impl TriangleGrid {
    /// Grid over the triangles of `mesh`, with cells of about twice the mean
    /// edge length (a triangle then overlaps at most 8 cells in the usual case).
    fn new(mesh: &TriMesh) -> Self {
        let (lo, hi) = match mesh.bounding_box() {
            Some(b) => (b.min, b.max),
            None => (Vec3::zeros(), Vec3::zeros()),
        };
        let ext = hi - lo;
        let mut cell = (2.0 * mesh.mean_edge_length()).max(f64::MIN_POSITIVE);
        // At most about 4 cells per triangle.
        let max_cells = (4 * mesh.n_faces()).max(64) as f64;
        let count = |c: f64| (0..3).map(|k| (ext[k] / c).floor() + 1.0).product::<f64>();
        while count(cell) > max_cells {
            cell *= 1.5;
        }
        let dims = [0, 1, 2].map(|k| (ext[k] / cell).floor() as usize + 1);
        let mut grid = Self { origin: lo, cell, dims, start: Vec::new(), items: Vec::new() };
        grid.fill(mesh);
        grid
    }

    /// Cell coordinates of a point, clamped to the grid.
    fn coords(&self, p: &Vec3) -> [usize; 3] {
        [0, 1, 2].map(|k| {
            let c = ((p[k] - self.origin[k]) / self.cell).floor();
            (c.max(0.0) as usize).min(self.dims[k] - 1)
        })
    }

    /// Linear index of cell coordinates.
    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Cell ranges overlapped by the bounding box of triangle `f`.
    fn box_cells(&self, mesh: &TriMesh, f: usize) -> ([usize; 3], [usize; 3]) {
        let [a, b, c] = mesh.corners(FaceId::new(f));
        let lo = a.inf(&b).inf(&c);
        let hi = a.sup(&b).sup(&c);
        (self.coords(&lo), self.coords(&hi))
    }

    /// Bucket the triangles (two passes: count, then place).
    fn fill(&mut self, mesh: &TriMesh) {
        let n_cells = self.dims.iter().product::<usize>();
        let mut count = vec![0u32; n_cells + 1];
        let boxes: Vec<_> = (0..mesh.n_faces()).map(|f| self.box_cells(mesh, f)).collect();
        let each = |(lo, hi): &([usize; 3], [usize; 3]), visit: &mut dyn FnMut([usize; 3])| {
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        visit([x, y, z]);
                    }
                }
            }
        };
        for b in &boxes {
            each(b, &mut |c| count[self.index(c) + 1] += 1);
        }
        for i in 0..n_cells {
            count[i + 1] += count[i];
        }
        let mut next = count.clone();
        let mut items = vec![0u32; count[n_cells] as usize];
        for (f, b) in boxes.iter().enumerate() {
            each(b, &mut |c| {
                let i = self.index(c);
                items[next[i] as usize] = f as u32;
                next[i] += 1;
            });
        }
        self.start = count;
        self.items = items;
    }

    /// Triangles in the cells at Chebyshev distance `ring` from the cell of `p`.
    fn ring(&self, p: &Vec3, ring: usize, visit: &mut dyn FnMut(u32)) {
        let c = self.coords(p);
        let r = ring as isize;
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                        continue;
                    }
                    let q = [c[0] as isize + dx, c[1] as isize + dy, c[2] as isize + dz];
                    if (0..3).any(|k| q[k] < 0 || q[k] >= self.dims[k] as isize) {
                        continue;
                    }
                    let i = self.index([q[0] as usize, q[1] as usize, q[2] as usize]);
                    for &f in &self.items[self.start[i] as usize..self.start[i + 1] as usize] {
                        visit(f);
                    }
                }
            }
        }
    }

    /// Distance from `p` to the outside of the block of cells within
    /// Chebyshev distance `ring` of its cell (infinite on sides where the
    /// grid ends: no triangle lies there). A triangle not registered in the
    /// block has its closest point outside it, so at least this far.
    fn block_clearance(&self, p: &Vec3, ring: usize) -> f64 {
        let c = self.coords(p);
        let mut d = f64::INFINITY;
        for k in 0..3 {
            if c[k] > ring {
                let lo = self.origin[k] + (c[k] - ring) as f64 * self.cell;
                d = d.min(p[k] - lo);
            }
            if c[k] + ring + 1 < self.dims[k] {
                let hi = self.origin[k] + (c[k] + ring + 1) as f64 * self.cell;
                d = d.min(hi - p[k]);
            }
        }
        d.max(0.0)
    }

    /// The largest ring index that still contains a cell.
    fn max_ring(&self) -> usize {
        self.dims.iter().copied().max().unwrap_or(1)
    }
}

/// Barycentric coordinates of the point of triangle `[a, b, c]` closest to
/// `p` (Ericson, Real-Time Collision Detection §5.1.5), and the squared distance.
fn closest_point_barycentric(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> ([f64; 3], f64) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    let bary = if d1 <= 0.0 && d2 <= 0.0 {
        [1.0, 0.0, 0.0]
    } else {
        let bp = p - b;
        let d3 = ab.dot(&bp);
        let d4 = ac.dot(&bp);
        let cp = p - c;
        let d5 = ab.dot(&cp);
        let d6 = ac.dot(&cp);
        let vc = d1 * d4 - d3 * d2;
        let vb = d5 * d2 - d1 * d6;
        let va = d3 * d6 - d5 * d4;
        if d3 >= 0.0 && d4 <= d3 {
            [0.0, 1.0, 0.0]
        } else if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let v = d1 / (d1 - d3);
            [1.0 - v, v, 0.0]
        } else if d6 >= 0.0 && d5 <= d6 {
            [0.0, 0.0, 1.0]
        } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let w = d2 / (d2 - d6);
            [1.0 - w, 0.0, w]
        } else if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            [0.0, 1.0 - w, w]
        } else {
            let denom = va + vb + vc;
            if denom.abs() <= f64::MIN_POSITIVE {
                [1.0, 0.0, 0.0]
            } else {
                let v = vb / denom;
                let w = vc / denom;
                [1.0 - v - w, v, w]
            }
        }
    };
    let q = a * bary[0] + b * bary[1] + c * bary[2];
    (bary, (p - q).norm_squared())
}

/// The coarse triangle closest to `p`, preferring triangles whose normal
/// does not point against `normal`; with its barycentric coordinates.
fn closest_triangle(
    grid: &TriangleGrid,
    mesh: &TriMesh,
    normals: &[Vec3],
    p: &Vec3,
    normal: &Vec3,
) -> Option<(usize, [f64; 3])> {
    // (facing the same way, squared distance, triangle, barycentrics)
    let mut best: Option<(bool, f64, usize, [f64; 3])> = None;
    for ring in 0..=grid.max_ring() {
        grid.ring(p, ring, &mut |f| {
            let f = f as usize;
            let [a, b, c] = mesh.corners(FaceId::new(f));
            let (bary, d2) = closest_point_barycentric(p, &a, &b, &c);
            let facing = normals[f].dot(normal) >= 0.0;
            let better = match best {
                None => true,
                Some((bf, bd, _, _)) => (facing && !bf) || (facing == bf && d2 < bd),
            };
            if better {
                best = Some((facing, d2, f, bary));
            }
        });
        // Stop once the best facing candidate is closer than any triangle
        // not yet visited (those lie outside the block of visited cells).
        if let Some((true, d2, _, _)) = best
            && d2.sqrt() <= grid.block_clearance(p, ring)
        {
            break;
        }
    }
    best.map(|(_, _, f, bary)| (f, bary))
}

/// The coarse field as P1 data: per vertex its value in the vertex frame,
/// per triangle corner the factor `z^N` from the triangle's frame to its
/// vertex's frame.
struct VertexField {
    value_per_vertex: Vec<C64>,
    to_vertex_per_corner: Vec<[C64; 3]>,
}

/// Average the CR field's corner values at each vertex (see the module doc).
fn vertex_field(mesh: &TriMesh, topo: &Topology, disc: &Discretization, f: &[C64]) -> VertexField {
    let n = disc.symmetry;
    let nv = mesh.n_vertices();
    let mut normal = vec![Vec3::zeros(); nv];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let a = mesh.face_area_vector(FaceId::new(t));
        for v in tri {
            normal[v.idx()] += a;
        }
    }
    // Reference direction per vertex: the first triangle's, projected.
    let mut reference: Vec<Option<Vec3>> = vec![None; nv];
    let mut to_vertex_per_corner = vec![[C64::new(1.0, 0.0); 3]; mesh.n_faces()];
    let mut sum = vec![C64::new(0.0, 0.0); nv];
    let mut count = vec![0u32; nv];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let fd = &disc.faces[t];
        let fe = &topo.face_edges[t];
        let big_f = [0, 1, 2].map(|k| fd.rot[k] * f[fe[k].idx()]);
        let (r, _) = face_frame(mesh, FaceId::new(t));
        for (i, v) in tri.iter().enumerate() {
            let v = v.idx();
            let nrm = normal[v].try_normalize(0.0).unwrap_or_else(Vec3::zeros);
            let p = (r - nrm * r.dot(&nrm)).try_normalize(0.0);
            let (Some(p), false) = (p, nrm == Vec3::zeros()) else {
                continue;
            };
            let rv = *reference[v].get_or_insert(p);
            let z = C64::new(p.dot(&rv), p.dot(&nrm.cross(&rv)));
            let zn = complex_pow(z / z.norm().max(f64::MIN_POSITIVE), n);
            to_vertex_per_corner[t][i] = zn;
            let corner = big_f[i] + big_f[(i + 2) % 3] - big_f[(i + 1) % 3];
            sum[v] += zn * corner;
            count[v] += 1;
        }
    }
    let value_per_vertex = sum.iter().zip(&count).map(|(s, &c)| if c > 0 { s / c as f64 } else { *s }).collect();
    VertexField { value_per_vertex, to_vertex_per_corner }
}

/// The field of `coarse` (values `coarse_f` per coarse edge) at the edges of
/// the fine mesh, one value per fine edge in its edge frame.
pub fn transfer_to_fine(
    coarse_mesh: &TriMesh,
    coarse_topo: &Topology,
    coarse_disc: &Discretization,
    coarse_f: &[C64],
    fine_mesh: &TriMesh,
    fine_topo: &Topology,
) -> Vec<C64> {
    let n = coarse_disc.symmetry;
    let p1 = vertex_field(coarse_mesh, coarse_topo, coarse_disc, coarse_f);
    let grid = TriangleGrid::new(coarse_mesh);
    let normals: Vec<Vec3> = (0..coarse_mesh.n_faces()).map(|f| coarse_mesh.face_normal(FaceId::new(f))).collect();
    (0..fine_topo.n_edges())
        .into_par_iter()
        .map(|e| {
            let e = EdgeId::new(e);
            let [a, b] = fine_topo.edges[e.idx()];
            let mid = (fine_mesh.positions[a.idx()] + fine_mesh.positions[b.idx()]) * 0.5;
            let normal = edge_normal(fine_mesh, fine_topo, e);
            let Some((t, bary)) = closest_triangle(&grid, coarse_mesh, &normals, &mid, &normal) else {
                return C64::new(1.0, 0.0);
            };
            let tri = &coarse_mesh.triangles[t];
            let w: C64 = (0..3)
                .map(|i| p1.to_vertex_per_corner[t][i].conj() * p1.value_per_vertex[tri[i].idx()] * bary[i])
                .sum();
            let (r, nrm) = face_frame(coarse_mesh, FaceId::new(t));
            let th = w.arg() / n as f64;
            let u = r * th.cos() + nrm.cross(&r) * th.sin();
            let ed = edge_direction(fine_mesh, fine_topo, e);
            let z = C64::new(u.dot(&ed), u.dot(&normal.cross(&ed)));
            let m = z.norm();
            if m > 0.0 { complex_pow(z / m, n) * w.norm() } else { C64::new(w.norm(), 0.0) }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    /// The field of a constant direction `d` (projected on the tangent plane)
    /// in every edge frame of `mesh`.
    fn constant_field(mesh: &TriMesh, topo: &Topology, d: &Vec3, n: u32) -> Vec<C64> {
        (0..topo.n_edges())
            .map(|e| {
                let e = EdgeId::new(e);
                let ed = edge_direction(mesh, topo, e);
                let t = edge_normal(mesh, topo, e).cross(&ed);
                let z = C64::new(d.dot(&ed), d.dot(&t));
                complex_pow(z / z.norm(), n)
            })
            .collect()
    }

    #[test]
    fn closest_point_covers_inside_edges_and_corners() {
        let (a, b, c) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
        let (l, d2) = closest_point_barycentric(&Vec3::new(0.25, 0.25, 1.0), &a, &b, &c);
        assert!((l[0] - 0.5).abs() < 1e-12 && (l[1] - 0.25).abs() < 1e-12 && (d2 - 1.0).abs() < 1e-12);
        let (l, _) = closest_point_barycentric(&Vec3::new(2.0, -1.0, 0.0), &a, &b, &c);
        assert_eq!(l, [0.0, 1.0, 0.0]);
        let (l, d2) = closest_point_barycentric(&Vec3::new(1.0, 1.0, 0.0), &a, &b, &c);
        assert!((l[1] - 0.5).abs() < 1e-12 && (l[2] - 0.5).abs() < 1e-12 && (d2 - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_constant_direction_survives_the_transfer() {
        // Planar disk: a constant cross is represented exactly by CR.
        for n in [4, 6] {
            let coarse = fixtures::disk(6);
            let fine = fixtures::disk(17);
            let (ct, ft) = (Topology::new(&coarse), Topology::new(&fine));
            let disc = Discretization::new(&coarse, &ct, n);
            let d = Vec3::new(0.6, 0.8, 0.0);
            let fc = constant_field(&coarse, &ct, &d, n);
            let got = transfer_to_fine(&coarse, &ct, &disc, &fc, &fine, &ft);
            let want = constant_field(&fine, &ft, &d, n);
            let err = got.iter().zip(&want).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
            assert!(err < 1e-9, "N = {n}: {err}");
        }
    }

    #[test]
    fn a_smooth_field_on_a_sphere_transfers_with_small_error() {
        // The projection of a fixed direction on a sphere is smooth away
        // from the poles (±z); compare there.
        let coarse = fixtures::icosphere(3);
        let fine = fixtures::icosphere(5);
        let (ct, ft) = (Topology::new(&coarse), Topology::new(&fine));
        let disc = Discretization::new(&coarse, &ct, 4);
        let d = Vec3::new(0.0, 0.0, 1.0);
        let fc = constant_field(&coarse, &ct, &d, 4);
        let got = transfer_to_fine(&coarse, &ct, &disc, &fc, &fine, &ft);
        let want = constant_field(&fine, &ft, &d, 4);
        let mut worst: f64 = 0.0;
        for e in 0..ft.n_edges() {
            let [a, b] = ft.edges[e];
            let mid = (fine.positions[a.idx()] + fine.positions[b.idx()]) * 0.5;
            if mid.z.abs() / mid.norm() < 0.8 {
                worst = worst.max((got[e] - want[e]).norm());
            }
        }
        assert!(worst < 0.1, "{worst}");
        assert!(worst > 0.0);
    }
}
