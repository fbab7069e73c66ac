//! Quads stage known answers (issue 13): the valences a quad mesh must have
//! follow from the topology and the crossfield, not from the code.
//!
//! - Unit square with a constant cross: a regular grid, no irregular vertex,
//!   scaled Jacobian ≥ 0.95.
//! - Unit disk: 4 interior valence-3 vertices (4·χ = 4, the crossfield's four
//!   +1/4 singularities), each near one of them.
//! - Cube with its feature edges: the 8 corners are the only irregular
//!   vertices, of valence 3.
//! - Sphere: at most 10 irregular vertices, none of valence ≥ 6 (so at
//!   least 8 of valence 3), one within a target size of each of the 8
//!   square-antiprism singularities.
//! - Torus (χ = 0, no singularity): at most 8 irregular vertices.
//!
//! Valences are counted here from the quads themselves (edges used by one
//! quad are boundary edges), independently of the stage's own report.

mod crossfield_common;

use std::collections::{BTreeMap, BTreeSet};

use meshatlas::atlas::{AtlasOptions, build_atlas};
use meshatlas::crossfield::{Crossfield, CrossfieldOptions, compute_crossfield};
use meshatlas::geom::{Vec3, angle_between};
use meshatlas::mesh::{Topology, TriMesh, fixtures};
use meshatlas::progress::Progress;
use meshatlas::quads::{QuadsOptions, QuadsResult, build_quads};

/// Atlas, crossfield (aligned with the atlas's feature edges, as the
/// pipeline does) and quads of `mesh`.
fn quads_of(mesh: &TriMesh, opts: &QuadsOptions) -> (QuadsResult, Crossfield) {
    let atlas = build_atlas(mesh, &AtlasOptions::default(), &Progress::none()).expect("atlas");
    let topo = Topology::new(mesh);
    let field = compute_crossfield(
        mesh,
        &topo,
        &atlas.features.is_feature_edge,
        &CrossfieldOptions::default(),
        &Progress::none(),
    )
    .expect("crossfield");
    let quads = build_quads(mesh, &atlas, &field, opts, &Progress::none()).expect("quads");
    (quads, field)
}

/// A shared mesh that CI provides beside the repository.
fn shared(rel: &str) -> TriMesh {
    let path = crossfield_common::data_path(rel).unwrap_or_else(|| panic!("../shared/data/{rel} is missing"));
    crossfield_common::load(&path)
}

/// Valence and boundary flag of every quad corner vertex, and the angle
/// (radians) the quads make at each boundary vertex.
struct Valences {
    valence: BTreeMap<u32, usize>,
    boundary: BTreeSet<u32>,
    boundary_angle: BTreeMap<u32, f64>,
}

/// Counts edges per vertex from the quads of `result`.
fn valences(result: &QuadsResult) -> Valences {
    let mut edge_uses: BTreeMap<(u32, u32), usize> = BTreeMap::new();
    for q in &result.mesh.quads {
        for i in 0..4 {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            *edge_uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut valence: BTreeMap<u32, usize> = BTreeMap::new();
    let mut boundary = BTreeSet::new();
    for (&(a, b), &uses) in &edge_uses {
        assert!(uses <= 2, "edge ({a}, {b}) is used by {uses} quads");
        *valence.entry(a).or_default() += 1;
        *valence.entry(b).or_default() += 1;
        if uses == 1 {
            boundary.insert(a);
            boundary.insert(b);
        }
    }
    let p = &result.mesh.vertices.positions;
    let mut boundary_angle: BTreeMap<u32, f64> = BTreeMap::new();
    for q in &result.mesh.quads {
        for i in 0..4 {
            let v = q[i];
            if boundary.contains(&v) {
                let (a, b) = (p[q[(i + 1) % 4] as usize] - p[v as usize], p[q[(i + 3) % 4] as usize] - p[v as usize]);
                *boundary_angle.entry(v).or_default() += angle_between(&a, &b);
            }
        }
    }
    Valences { valence, boundary, boundary_angle }
}

impl Valences {
    /// Interior vertices whose valence is not 4.
    fn interior_irregular(&self) -> Vec<(u32, usize)> {
        self.valence.iter().filter(|(v, d)| !self.boundary.contains(v) && **d != 4).map(|(v, d)| (*v, *d)).collect()
    }

    /// Boundary vertices whose valence differs from the one their angle
    /// asks for (`round(θ / 90°) + 1`: 2 at a right-angle corner, 3 on a
    /// straight boundary).
    fn boundary_irregular(&self) -> Vec<(u32, usize)> {
        self.boundary
            .iter()
            .filter_map(|v| {
                let expected = (self.boundary_angle[v] / std::f64::consts::FRAC_PI_2).round() as usize + 1;
                (self.valence[v] != expected).then_some((*v, self.valence[v]))
            })
            .collect()
    }
}

/// Minimum over quads of the scaled Jacobian against the `z` axis (planar inputs).
fn min_planar_scaled_jacobian(result: &QuadsResult) -> f64 {
    let p = &result.mesh.vertices.positions;
    let mut worst = f64::INFINITY;
    for q in &result.mesh.quads {
        for i in 0..4 {
            let c = p[q[i] as usize];
            let (a, b) = (p[q[(i + 1) % 4] as usize] - c, p[q[(i + 3) % 4] as usize] - c);
            worst = worst.min(a.cross(&b).z / (a.norm() * b.norm()));
        }
    }
    worst
}

/// Distance from vertex `v` to the nearest crossfield singularity.
fn distance_to_singularity(result: &QuadsResult, field: &Crossfield, v: u32) -> f64 {
    let x: Vec3 = result.mesh.vertices.positions[v as usize];
    field.singularities.iter().map(|s| (s.position - x).norm()).fold(f64::INFINITY, f64::min)
}

#[test]
fn unit_square_with_a_constant_cross_is_a_regular_grid() {
    let mesh = fixtures::square(16);
    let (result, field) = quads_of(&mesh, &QuadsOptions { size: Some(0.1), ..Default::default() });
    let inside = |x: &Vec3| x.x > 1e-9 && x.x < 1.0 - 1e-9 && x.y > 1e-9 && x.y < 1.0 - 1e-9;
    assert!(
        field.singularities.iter().all(|s| !inside(&s.position)),
        "the square's aligned cross has singularities only at its corners: {:?}",
        field.singularities
    );
    let v = valences(&result);
    assert_eq!(v.interior_irregular(), vec![], "interior irregular vertices");
    assert_eq!(v.boundary_irregular(), vec![], "boundary irregular vertices");
    let sj = min_planar_scaled_jacobian(&result);
    assert!(sj >= 0.95, "min scaled Jacobian {sj}");
}

#[test]
fn unit_disk_has_exactly_four_valence_3_vertices_at_the_singularities() {
    let mesh = shared("gmsh/disk_3k.stl");
    let (result, field) = quads_of(&mesh, &QuadsOptions::default());
    assert_eq!(field.singularities.len(), 4);
    let size = result.report.target_size;
    let v = valences(&result);
    let irregular = v.interior_irregular();
    assert_eq!(irregular.len(), 4, "interior irregular vertices {irregular:?}");
    for (vertex, valence) in irregular {
        assert_eq!(valence, 3);
        let d = distance_to_singularity(&result, &field, vertex);
        assert!(d <= size, "valence-3 vertex {vertex} is {d} from the nearest singularity (size {size})");
    }
    assert!(min_planar_scaled_jacobian(&result) > 0.0);
}

#[test]
fn cube_corners_are_the_only_irregular_vertices() {
    let mesh = fixtures::cube(6);
    let (result, _) = quads_of(&mesh, &QuadsOptions { size: Some(0.25), ..Default::default() });
    let v = valences(&result);
    assert!(v.boundary.is_empty(), "the cube is closed");
    let irregular = v.interior_irregular();
    assert_eq!(irregular.len(), 8, "irregular vertices {irregular:?}");
    let p = &result.mesh.vertices.positions;
    for (vertex, valence) in irregular {
        assert_eq!(valence, 3);
        let x = p[vertex as usize];
        assert!(x.iter().all(|c| (c.abs() - 1.0).abs() < 1e-9), "valence-3 vertex {vertex} at {x:?} is not a corner");
    }
}

#[test]
fn sphere_has_at_most_10_irregular_vertices_all_of_valence_3() {
    let mesh = shared("gmsh/sphere_3k.stl");
    let (result, field) = quads_of(&mesh, &QuadsOptions::default());
    assert_eq!(field.singularities.len(), 8);
    let irregular = valences(&result).interior_irregular();
    assert!(irregular.len() <= 10, "{} irregular vertices: {irregular:?}", irregular.len());
    // 4χ = 8: with at most 10 irregular vertices and none of valence ≥ 6,
    // at least 8 are of valence 3.
    assert!(irregular.iter().all(|(_, d)| *d < 6), "valence ≥ 6 in {irregular:?}");
    assert!(irregular.iter().filter(|(_, d)| *d == 3).count() >= 8, "{irregular:?}");
}

/// A finer sphere (20172 triangles, the cube grid of the bench's
/// generator projected on the sphere): the matching leaves two triangles
/// far apart, which used to send the whole sphere to midpoint subdivision
/// (30128 quads at half the size asked, 30 irregular vertices). The same
/// bounds as on sphere_3k hold, with no subdivision.
#[test]
fn a_finer_sphere_is_all_quad_without_subdivision_and_at_most_10_irregular_vertices() {
    let mut mesh = fixtures::cube(41);
    for p in &mut mesh.positions {
        *p = p.normalize();
    }
    let (result, field) = quads_of(&mesh, &QuadsOptions::default());
    assert_eq!(field.singularities.len(), 8);
    assert_eq!(result.report.recombination.n_subdivided_faces, 0, "{:?}", result.report.recombination);
    let irregular = valences(&result).interior_irregular();
    assert!(irregular.len() <= 10, "{} irregular vertices: {irregular:?}", irregular.len());
    assert!(irregular.iter().all(|(_, d)| *d < 6), "valence ≥ 6 in {irregular:?}");
}

#[test]
#[ignore = "issue 13 open: the 8 valence-3 vertices of sphere_3k lie 0.2–3.3 target sizes from the crossfield's singularities (the cavity step's second phase moves them; keeping its singular-centre rules there leaves 31–43 irregular vertices instead of 8)"]
fn sphere_has_a_valence_3_vertex_within_one_size_of_each_singularity() {
    let mesh = shared("gmsh/sphere_3k.stl");
    let (result, field) = quads_of(&mesh, &QuadsOptions::default());
    let size = result.report.target_size;
    let irregular = valences(&result).interior_irregular();
    for s in &field.singularities {
        let near = irregular
            .iter()
            .any(|(vx, d)| *d == 3 && (result.mesh.vertices.positions[*vx as usize] - s.position).norm() <= size);
        assert!(near, "no valence-3 vertex within {size} of the singularity at {:?}", s.position);
    }
}

/// χ = 0 and no singularity: a torus can be meshed with no irregular vertex;
/// issue 13's test bound is 8 (Gmsh's quasi-structured mesher does not
/// finish on this input).
#[test]
fn torus_has_at_most_8_irregular_vertices() {
    let mesh = shared("gmsh/torus_20k.stl");
    let (result, field) = quads_of(&mesh, &QuadsOptions::default());
    assert!(field.singularities.is_empty());
    let irregular = valences(&result).interior_irregular();
    assert!(irregular.len() <= 8, "{} irregular vertices: {irregular:?}", irregular.len());
}

/// The cube `[-1, 1]³` tapered to `x (1 + 0.09 (z + 1))`: two of its faces
/// are trapezoids whose parallel edges (separate feature curves) want 10
/// and 11.8 segments at size 0.2, counted one by one 10 and 12. A quad
/// mesh of a face with four corners of one quad each has no irregular
/// vertex only when its opposite sides have as many segments (each unit of
/// difference is a valence 3–5 pair inside); 11 on all four edges along
/// `x` makes every face a regular grid, so the 8 corners must be the only
/// irregular vertices, as on the cube.
#[test]
fn a_tapered_box_has_equal_opposite_sides_and_only_its_corners_irregular() {
    let mut mesh = fixtures::cube(10);
    for p in &mut mesh.positions {
        p.x *= 1.0 + 0.09 * (p.z + 1.0);
    }
    let (result, _) = quads_of(&mesh, &QuadsOptions { size: Some(0.2), ..Default::default() });
    let v = valences(&result);
    let irregular = v.interior_irregular();
    assert_eq!(irregular.len(), 8, "irregular vertices {irregular:?}");
    assert!(irregular.iter().all(|&(_, valence)| valence == 3), "{irregular:?}");
    let sides = &result.report.triangulation.sides;
    assert_eq!(sides.n_four_sided_faces, 6, "{sides:?}");
    // 11 × 10 on the four faces along x, 10 × 10 on the two across it.
    assert_eq!(result.mesh.quads.len(), 4 * 110 + 2 * 100);
}

/// The terrain of the Gmsh examples (an open patch with 4 corners): issue 13's
/// test bound is 4 irregular vertices (Gmsh's quasi-structured mesher puts 11)
/// and its goal 0, which equal opposite sides reach (with sides counted
/// one by one, 49 and 45 segments, a valence 3–5 pair was left near a
/// corner); none inverted and no face subdivided.
#[test]
fn terrain_has_no_irregular_vertex_and_no_subdivision() {
    let mesh = shared("corpus/gmsh_terrain.stl");
    let (result, _) = quads_of(&mesh, &QuadsOptions::default());
    let r = &result.report;
    assert_eq!(r.n_irregular_vertices, 0, "irregular vertices");
    assert_eq!(r.recombination.n_subdivided_faces, 0);
    assert!(min_planar_scaled_jacobian(&result) > 0.0);
}

/// The plate `[0, 2] × [0, 1]` folded along `y = 1/2` by
/// `z = 2 (1 − x)₊ |y − 1/2|` ([`fixtures::folded_plate`]): a 127° crease
/// at `x = 0` that fades out inside the one model face (at the default
/// 40°, it is a feature edge while `x < 0.82`; 88° on average, above the
/// atlas' 70° for cutting along it, and 16 mean edges long). No quad may fold over it: the
/// quads must follow a crease that bounds nothing as they follow a curve
/// between two faces (before the atlas cut along such creases, 11 quads
/// straddled it).
#[test]
fn a_crease_that_fades_out_inside_a_face_is_followed_by_quad_edges() {
    let mesh = fixtures::folded_plate(32);
    let (result, _) = quads_of(&mesh, &QuadsOptions { size: Some(0.1), ..Default::default() });
    let p = &result.mesh.vertices.positions;
    let straddling: Vec<[u32; 4]> = result
        .mesh
        .quads
        .iter()
        .filter(|q| {
            let side = q.map(|v| p[v as usize].y - 0.5);
            let centre_x = q.iter().map(|&v| p[v as usize].x).sum::<f64>() / 4.0;
            let tol = 1e-3;
            centre_x < 0.5 && side.iter().any(|&s| s > tol) && side.iter().any(|&s| s < -tol)
        })
        .copied()
        .collect();
    assert!(straddling.is_empty(), "{} quads fold over the crease: {straddling:?}", straddling.len());
    assert_eq!(result.report.recombination.n_subdivided_faces, 0);
    let sj = result.report.scaled_jacobian_min;
    assert!(sj > 0.3, "min scaled Jacobian {sj}");
}

/// The 44-triangle cylinder of the corpus (Gmsh's quad mesher never
/// finishes on it): its caps' rims are cut finer than their insides, and a
/// first row of points lost along them left rim points flat quad corners
/// (scaled Jacobian 0.255, 8 quads under 0.3, before the narrower
/// first-row exclusion).
#[test]
fn cylinder_coarse_has_no_quad_under_0_3() {
    let mesh = shared("corpus/cylinder_coarse.stl");
    let (result, _) = quads_of(&mesh, &QuadsOptions::default());
    let r = &result.report;
    assert_eq!(r.recombination.n_subdivided_faces, 0);
    assert!(
        r.scaled_jacobian_min >= 0.3,
        "min scaled Jacobian {} ({} under 0.3)",
        r.scaled_jacobian_min,
        r.n_below_0_3
    );
}
