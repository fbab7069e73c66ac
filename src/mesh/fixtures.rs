//! Meshes built in code with known geometry and topology, for tests and
//! benchmarks: disk, annulus, square, L-shape, sphere, torus, cube,
//! cylinder, tetrahedron and a Möbius band.
//!
//! All are consistently oriented (closed ones outward, planar ones with
//! normal `+z`) and free of degenerate triangles.

use super::{TriMesh, VertexId};
use crate::geom::Vec3;
use std::collections::HashMap;
use std::f64::consts::TAU;

/// The unit tetrahedron `(0,0,0), x, y, z`, outward oriented.
pub fn tetrahedron() -> TriMesh {
    TriMesh::from_raw(
        vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
        &[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
}

/// Unit square `[0,1]²` in the plane `z = 0`, `n × n` cells, two triangles
/// each, diagonals alternating with the cell parity (a "union jack" pattern,
/// symmetric under the square's reflections).
pub fn square(n: usize) -> TriMesh {
    grid_mesh_cells(n, n, |_, _| true, true, |i, j| Vec3::new(i as f64 / n as f64, j as f64 / n as f64, 0.0))
}

/// Unit square with every diagonal in the same direction (the "structured"
/// mesh of thesis appendix A.B, on which mean value coordinates are not a
/// Laplacian).
pub fn square_structured(n: usize) -> TriMesh {
    grid_mesh(n, n, |i, j| Some(Vec3::new(i as f64 / n as f64, j as f64 / n as f64, 0.0)))
}

/// L-shaped domain `[0,2]² \ (1,2]²` with `n` cells per unit length.
pub fn l_shape(n: usize) -> TriMesh {
    let m = grid_mesh_cells(
        2 * n,
        2 * n,
        |i, j| !(i >= n && j >= n),
        true,
        |i, j| Vec3::new(i as f64 / n as f64, j as f64 / n as f64, 0.0),
    );
    compact(m)
}

/// A concave planar domain with a concave hole (thesis ch. 2 fig. 2.9): the
/// L-shaped region `[0,1]² \ [2/3,1]²` with an L-shaped hole made of the
/// squares `[1/6,1/2]×[1/6,1/3]` and `[1/6,1/3]×[1/3,1/2]`; `n` cells per unit
/// length (a multiple of 6).
pub fn l_plate_with_l_hole(n: usize) -> TriMesh {
    let k = n / 6;
    let keep = |i: usize, j: usize| {
        let outer_notch = i >= 4 * k && j >= 4 * k;
        let hole_bar = (k..3 * k).contains(&i) && (k..2 * k).contains(&j);
        let hole_leg = (k..2 * k).contains(&i) && (2 * k..3 * k).contains(&j);
        !(outer_notch || hole_bar || hole_leg)
    };
    let m = grid_mesh_cells(6 * k, 6 * k, keep, true, |i, j| {
        Vec3::new(i as f64 / (6 * k) as f64, j as f64 / (6 * k) as f64, 0.0)
    });
    compact(m)
}

/// Unit disk in the plane `z = 0`: a centre and `n_rings` rings, ring `k`
/// holding `6k` vertices at radius `k / n_rings` (near-equilateral triangles).
pub fn disk(n_rings: usize) -> TriMesh {
    let mut positions = vec![Vec3::zeros()];
    let mut rings: Vec<Vec<u32>> = vec![vec![0]];
    for k in 1..=n_rings {
        let r = k as f64 / n_rings as f64;
        let n = 6 * k;
        let ring = (0..n)
            .map(|j| {
                let t = TAU * j as f64 / n as f64;
                positions.push(Vec3::new(r * t.cos(), r * t.sin(), 0.0));
                (positions.len() - 1) as u32
            })
            .collect();
        rings.push(ring);
    }
    let mut tris = Vec::new();
    for k in 1..rings.len() {
        zip_rings(&positions, &rings[k - 1], &rings[k], &mut tris);
    }
    TriMesh::from_raw(positions, &tris)
}

/// Planar annulus `r_in ≤ |x| ≤ r_out` with `n_around` vertices per ring and
/// `n_rings` radial layers.
pub fn annulus(r_in: f64, r_out: f64, n_around: usize, n_rings: usize) -> TriMesh {
    let mut positions = Vec::new();
    let mut rings: Vec<Vec<u32>> = Vec::new();
    for k in 0..=n_rings {
        let r = r_in + (r_out - r_in) * k as f64 / n_rings as f64;
        let shift = if k % 2 == 1 { 0.5 } else { 0.0 };
        rings.push(
            (0..n_around)
                .map(|j| {
                    let t = TAU * (j as f64 + shift) / n_around as f64;
                    positions.push(Vec3::new(r * t.cos(), r * t.sin(), 0.0));
                    (positions.len() - 1) as u32
                })
                .collect(),
        );
    }
    let mut tris = Vec::new();
    for k in 1..rings.len() {
        zip_rings(&positions, &rings[k - 1], &rings[k], &mut tris);
    }
    TriMesh::from_raw(positions, &tris)
}

/// Unit sphere from an icosahedron subdivided `level` times (20·4^level triangles).
pub fn icosphere(level: usize) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let mut m = |x: u32, y: u32| {
                *mid.entry((x.min(y), x.max(y))).or_insert_with(|| {
                    positions.push(((positions[x as usize] + positions[y as usize]) * 0.5).normalize());
                    (positions.len() - 1) as u32
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    TriMesh::from_raw(positions, &tris)
}

/// Torus of major radius `major`, minor radius `minor`, with `n_major` ×
/// `n_minor` quads split in two, outward oriented.
pub fn torus(major: f64, minor: f64, n_major: usize, n_minor: usize) -> TriMesh {
    let mut positions = Vec::with_capacity(n_major * n_minor);
    for i in 0..n_major {
        let u = TAU * i as f64 / n_major as f64;
        for j in 0..n_minor {
            let v = TAU * j as f64 / n_minor as f64;
            let rho = major + minor * v.cos();
            positions.push(Vec3::new(rho * u.cos(), rho * u.sin(), minor * v.sin()));
        }
    }
    let id = |i: usize, j: usize| ((i % n_major) * n_minor + (j % n_minor)) as u32;
    let mut tris = Vec::with_capacity(2 * n_major * n_minor);
    for i in 0..n_major {
        for j in 0..n_minor {
            tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh::from_raw(positions, &tris)
}

/// Surface of the cube `[-1, 1]³` with `n × n` cells per face, outward oriented.
pub fn cube(n: usize) -> TriMesh {
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut tris = Vec::new();
    let n_i = n as i64;
    for axis in 0..3 {
        for side in [0i64, n_i] {
            let (b, c) = if side == n_i { ((axis + 1) % 3, (axis + 2) % 3) } else { ((axis + 2) % 3, (axis + 1) % 3) };
            let mut vid = |i: i64, j: i64| {
                let mut key = [0i64; 3];
                key[axis] = side;
                key[b] = i;
                key[c] = j;
                *index.entry(key).or_insert_with(|| {
                    positions.push(Vec3::from_iterator(key.iter().map(|&k| 2.0 * k as f64 / n as f64 - 1.0)));
                    (positions.len() - 1) as u32
                })
            };
            for i in 0..n_i {
                for j in 0..n_i {
                    let (p00, p10, p11, p01) = (vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1));
                    tris.push([p00, p10, p11]);
                    tris.push([p00, p11, p01]);
                }
            }
        }
    }
    TriMesh::from_raw(positions, &tris)
}

/// The plate `[0, 2] × [0, 1]` (`n` cells across, `n` along, in the
/// pattern of [`square`]; `n` even) folded along `y = ½` by
/// `z = 2 (1 − x)₊ |y − ½|`: a crease of 127° between normals at `x = 0`
/// that fades out inside the plate (it is sharper than 40° while
/// `2 atan(2 (1 − x)) > 40°`, i.e. for `x < 0.82`).
pub fn folded_plate(n: usize) -> TriMesh {
    let mut mesh = square(n);
    for p in &mut mesh.positions {
        let x = 2.0 * p.x;
        *p = Vec3::new(x, p.y, 2.0 * (1.0 - x).max(0.0) * (p.y - 0.5).abs());
    }
    mesh
}

/// Open cylinder of radius `radius` and height `height` around `z`,
/// `n_around` vertices per ring and `n_height` layers, normals outward.
pub fn cylinder(radius: f64, height: f64, n_around: usize, n_height: usize) -> TriMesh {
    let mut positions = Vec::new();
    for k in 0..=n_height {
        let z = height * k as f64 / n_height as f64;
        for j in 0..n_around {
            let t = TAU * j as f64 / n_around as f64;
            positions.push(Vec3::new(radius * t.cos(), radius * t.sin(), z));
        }
    }
    let id = |k: usize, j: usize| (k * n_around + j % n_around) as u32;
    let mut tris = Vec::new();
    for k in 0..n_height {
        for j in 0..n_around {
            tris.push([id(k, j), id(k, j + 1), id(k + 1, j + 1)]);
            tris.push([id(k, j), id(k + 1, j + 1), id(k + 1, j)]);
        }
    }
    TriMesh::from_raw(positions, &tris)
}

/// A Möbius band with `n` segments (non-orientable, one boundary loop).
pub fn mobius_band(n: usize) -> TriMesh {
    let mut positions = Vec::new();
    for i in 0..n {
        let u = TAU * i as f64 / n as f64;
        for t in [-1.0f64, 1.0] {
            let r = 1.0 + 0.25 * t * (u / 2.0).cos();
            positions.push(Vec3::new(r * u.cos(), r * u.sin(), 0.25 * t * (u / 2.0).sin()));
        }
    }
    let mut tris = Vec::new();
    for i in 0..n {
        let (a0, b0) = (2 * i as u32, 2 * i as u32 + 1);
        let (a1, b1) = if i + 1 < n { (2 * (i + 1) as u32, 2 * (i + 1) as u32 + 1) } else { (1, 0) };
        tris.push([a0, a1, b1]);
        tris.push([a0, b1, b0]);
    }
    TriMesh::from_raw(positions, &tris)
}

/// `mesh` scaled by `s` per axis, then moved by `d`: separate parts of
/// chosen sizes and shapes for multi-part inputs.
pub fn placed(mesh: &TriMesh, s: Vec3, d: Vec3) -> TriMesh {
    let mut m = mesh.clone();
    for p in &mut m.positions {
        *p = p.component_mul(&s) + d;
    }
    m
}

/// The meshes as one surface (one vertex and triangle list, nothing welded).
pub fn union(meshes: &[TriMesh]) -> TriMesh {
    let mut out = TriMesh::default();
    for m in meshes {
        let n = out.positions.len() as u32;
        out.positions.extend(&m.positions);
        out.triangles.extend(m.triangles.iter().map(|t| t.map(|v| VertexId(v.0 + n))));
    }
    out
}

/// Drop vertices no triangle uses, renumbering the rest in order.
pub fn compact(mut mesh: TriMesh) -> TriMesh {
    let used = super::components::referenced_vertices(&mesh);
    let mut new_id = vec![u32::MAX; mesh.n_vertices()];
    let mut positions = Vec::new();
    for (v, &u) in used.iter().enumerate() {
        if u {
            new_id[v] = positions.len() as u32;
            positions.push(mesh.positions[v]);
        }
    }
    for t in &mut mesh.triangles {
        *t = t.map(|v| VertexId(new_id[v.idx()]));
    }
    mesh.positions = positions;
    mesh
}

/// Structured `nx × ny` grid with every vertex present.
fn grid_mesh(nx: usize, ny: usize, at: impl Fn(usize, usize) -> Option<Vec3>) -> TriMesh {
    grid_mesh_cells(nx, ny, |_, _| true, false, |i, j| at(i, j).expect("grid vertex"))
}

/// Structured grid keeping only the cells `(i, j)` for which `keep` holds;
/// with `alternate` the diagonal direction flips with the cell parity.
fn grid_mesh_cells(
    nx: usize,
    ny: usize,
    keep: impl Fn(usize, usize) -> bool,
    alternate: bool,
    at: impl Fn(usize, usize) -> Vec3,
) -> TriMesh {
    let mut positions = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            positions.push(at(i, j));
        }
    }
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut tris = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            if !keep(i, j) {
                continue;
            }
            if alternate && (i + j) % 2 == 1 {
                tris.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                tris.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            } else {
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
    }
    TriMesh::from_raw(positions, &tris)
}

/// Triangulate the band between two concentric vertex rings (counter-clockwise,
/// starting near angle 0) by merging them in angular order.
fn zip_rings(positions: &[Vec3], inner: &[u32], outer: &[u32], tris: &mut Vec<[u32; 3]>) {
    let angle = |v: u32| {
        let p = positions[v as usize];
        let a = p.y.atan2(p.x);
        if a < -1e-12 { a + TAU } else { a.max(0.0) }
    };
    let (m, n) = (inner.len(), outer.len());
    if m == 1 {
        for j in 0..n {
            tris.push([inner[0], outer[j], outer[(j + 1) % n]]);
        }
        return;
    }
    let next_angle = |ring: &[u32], i: usize| {
        let a = angle(ring[(i + 1) % ring.len()]);
        if i + 1 >= ring.len() || a < angle(ring[i]) { a + TAU } else { a }
    };
    let (mut i, mut j) = (0, 0);
    while i < m || j < n {
        let advance_outer = if i == m {
            true
        } else if j == n {
            false
        } else {
            next_angle(outer, j) <= next_angle(inner, i)
        };
        if advance_outer {
            tris.push([inner[i % m], outer[j % n], outer[(j + 1) % n]]);
            j += 1;
        } else {
            tris.push([inner[i % m], outer[j % n], inner[(i + 1) % m]]);
            i += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{FaceId, Topology, orientation::n_inconsistent_edges};

    fn check(m: &TriMesh) {
        assert!(m.validate().is_ok());
        let t = Topology::new(m);
        assert_eq!(n_inconsistent_edges(m, &t), 0);
        assert_eq!(t.n_nonmanifold_edges(), 0);
        let min_area = (0..m.n_faces()).map(|f| m.face_area(FaceId::new(f))).fold(f64::INFINITY, f64::min);
        assert!(min_area > 0.0);
    }

    #[test]
    fn fixtures_are_valid_and_oriented() {
        for m in [
            tetrahedron(),
            square(4),
            l_shape(3),
            disk(6),
            annulus(0.4, 1.0, 30, 4),
            icosphere(3),
            torus(1.0, 0.4, 30, 12),
            cube(4),
            cylinder(1.0, 2.0, 16, 5),
        ] {
            check(&m);
        }
        let band = mobius_band(20);
        assert!(band.validate().is_ok());
        assert_eq!(n_inconsistent_edges(&band, &Topology::new(&band)), 1);
    }

    #[test]
    fn planar_fixtures_face_up_and_closed_ones_out() {
        for m in [square(3), l_shape(2), disk(5), annulus(0.4, 1.0, 20, 3)] {
            assert!((0..m.n_faces()).all(|f| m.face_normal(FaceId::new(f)).z > 0.999));
        }
        for m in [icosphere(2), torus(1.0, 0.4, 24, 12), cube(3), tetrahedron()] {
            assert!(m.signed_volume() > 0.0);
        }
        let d = disk(8);
        assert!((d.area() - std::f64::consts::PI).abs() < 0.05);
        assert_eq!(d.n_faces(), 6 * 64);
        assert!((l_shape(2).area() - 3.0).abs() < 1e-12);
        assert!((cube(2).area() - 24.0).abs() < 1e-12);
    }
}
