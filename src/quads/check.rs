//! Step 7b of the quads stage: what every output must satisfy, asserted
//! (a failure is a bug of an earlier step, reported as
//! [`QuadsError::CheckFailed`] naming the check and the first offender).
//!
//! Checks, in this order:
//! 1. `indices`: per-quad arrays as long as the quads, vertex indices in
//!    range, 4 distinct corners per quad (`triangles`: no quad degenerates
//!    to a triangle; the mesh has no other element).
//! 2. `inverted`: scaled Jacobian above
//!    [`super::quality::DEGENERATE_SCALED_JACOBIAN`] at every quad (no
//!    inverted or degenerate corner, flat within round-off included).
//! 3. `conformity`: every edge in 1 or 2 quads; an edge of 2 quads is used
//!    in opposite directions (consistent orientation); the edges of one
//!    quad are exactly the edges of the mesh on boundary feature curves
//!    (curves of boundary edges of the input); every curve edge is a mesh
//!    edge.
//! 4. `coverage`: every model face has quads, and their area matches the
//!    face's input area within 2 % plus the chordal allowance of each quad,
//!    `A_q (1 − cos δ_q)` with `δ_q` the largest angle between the quad's
//!    normal and the input normals under its corners (a flat quad spanning
//!    a curved patch loses about that much area).
//! 5. `valence-identity`: per connected component,
//!    `Σ_closed (4 − val) + Σ_open (3 − val) = 4χ` with `χ` the Euler
//!    characteristic of the corresponding input component (a pinch, where
//!    two fans of triangles meet at a vertex, counted split), so the mesh
//!    has the input's topology (see [`super::quality`] for the identity).

use std::collections::HashSet;

use super::error::QuadsError;
use super::model::QuadModel;
use super::quality::{QuadQuality, is_inverted_or_degenerate};
use super::surface_mesh::{ModelEntity, QuadMesh};
use crate::geom::{Vec3, angle_between};
use crate::mesh::components::{DisjointSets, connected_components, fan_of_each_face, nonmanifold_vertices};
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh};

/// Relative area mismatch every model face may have on top of the chordal allowance.
pub const AREA_TOLERANCE: f64 = 0.02;

/// Asserts what every output must satisfy (see the module documentation).
///
/// # Errors
/// [`QuadsError::CheckFailed`] naming the check and the first offender.
pub fn check_quad_mesh(
    mesh: &QuadMesh,
    quality: &QuadQuality,
    surface: &TriMesh,
    topo: &Topology,
    model: &QuadModel,
) -> Result<(), QuadsError> {
    check_indices(mesh, quality, model)?;
    check_inverted(mesh, quality)?;
    check_conformity(mesh, topo, model)?;
    check_coverage(mesh, surface, model)?;
    check_valence_identity(mesh, quality, surface, topo, model)
}

/// A [`QuadsError::CheckFailed`].
fn failed(check: &'static str, detail: String) -> QuadsError {
    QuadsError::CheckFailed { check, detail }
}

/// Array lengths, indices in range, four distinct corners per quad.
fn check_indices(mesh: &QuadMesh, quality: &QuadQuality, model: &QuadModel) -> Result<(), QuadsError> {
    let n = mesh.vertices.len();
    let v = &mesh.vertices;
    if v.on_surface.len() != n || v.entity.len() != n || quality.valence.len() != n {
        return Err(failed("indices", format!("{n} vertices but per-vertex arrays of other lengths")));
    }
    let nq = mesh.quads.len();
    if mesh.model_face_per_quad.len() != nq || quality.scaled_jacobian.len() != nq {
        return Err(failed("indices", format!("{nq} quads but per-quad arrays of other lengths")));
    }
    if let Some(nodes) = &mesh.high_order_nodes {
        if nodes.len() != nq {
            return Err(failed("indices", format!("{nq} quads but {} sets of order-2 nodes", nodes.len())));
        }
        if let Some(k) = nodes.iter().position(|h| h.iter().any(|&x| x as usize >= n)) {
            return Err(failed("indices", format!("order-2 node of quad {k} out of range ({n} vertices)")));
        }
    }
    for (k, q) in mesh.quads.iter().enumerate() {
        if q.iter().any(|&x| x as usize >= n) {
            return Err(failed("indices", format!("quad {k} {q:?} refers to a vertex ≥ {n}")));
        }
        let distinct = (0..4).all(|i| (i + 1..4).all(|j| q[i] != q[j]));
        if !distinct {
            return Err(failed("triangles", format!("quad {k} {q:?} repeats a corner (a triangle)")));
        }
        if mesh.model_face_per_quad[k] as usize >= model.n_faces {
            return Err(failed(
                "indices",
                format!("quad {k} is on model face {} ≥ {}", mesh.model_face_per_quad[k], model.n_faces),
            ));
        }
    }
    for (c, [a, b]) in &mesh.curve_edges {
        if *c as usize >= model.features.curves.len() || *a as usize >= n || *b as usize >= n {
            return Err(failed("indices", format!("curve edge ({a}, {b}) on curve {c} out of range")));
        }
    }
    Ok(())
}

/// Centroid of quad `q` (for messages).
fn centroid(mesh: &QuadMesh, q: &[u32; 4]) -> Vec3 {
    q.iter().map(|&v| mesh.vertices.positions[v as usize]).sum::<Vec3>() / 4.0
}

/// No quad inverted or degenerate ([`is_inverted_or_degenerate`]).
fn check_inverted(mesh: &QuadMesh, quality: &QuadQuality) -> Result<(), QuadsError> {
    match quality.scaled_jacobian.iter().position(|&j| is_inverted_or_degenerate(j)) {
        None => Ok(()),
        Some(k) => {
            let c = centroid(mesh, &mesh.quads[k]);
            Err(failed(
                "inverted",
                format!(
                    "quad {k} {:?} at ({:.6}, {:.6}, {:.6}) has scaled Jacobian {:.6} ({} of {} quads ≤ 0)",
                    mesh.quads[k],
                    c.x,
                    c.y,
                    c.z,
                    quality.scaled_jacobian[k],
                    quality.n_inverted(),
                    mesh.quads.len()
                ),
            ))
        }
    }
}

/// True when feature curve `c` is made of boundary edges of the input.
fn is_boundary_curve(model: &QuadModel, topo: &Topology, c: u32) -> bool {
    model.features.curves[c as usize].edges.first().is_some_and(|&e: &EdgeId| topo.is_boundary_edge(e))
}

/// Edge uses, orientation, boundary edges exactly on boundary curves.
fn check_conformity(mesh: &QuadMesh, topo: &Topology, model: &QuadModel) -> Result<(), QuadsError> {
    // (edge [min, max], quad, forward) for every quad side, sorted.
    let mut sides: Vec<([u32; 2], u32, bool)> = Vec::with_capacity(4 * mesh.quads.len());
    for (k, q) in mesh.quads.iter().enumerate() {
        for i in 0..4 {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            sides.push(([a.min(b), a.max(b)], k as u32, a < b));
        }
    }
    sides.sort_unstable();
    let boundary_curve_edges: HashSet<[u32; 2]> = mesh
        .curve_edges
        .iter()
        .filter(|(c, _)| is_boundary_curve(model, topo, *c))
        .map(|&(_, [a, b])| [a.min(b), a.max(b)])
        .collect();
    let mut mesh_edges = HashSet::with_capacity(sides.len() / 2);
    for run in sides.chunk_by(|x, y| x.0 == y.0) {
        let [a, b] = run[0].0;
        mesh_edges.insert([a, b]);
        match run {
            [(_, q, _)] if !boundary_curve_edges.contains(&[a, b]) => {
                return Err(failed(
                    "conformity",
                    format!("edge ({a}, {b}) is in quad {q} only, but it is not on a boundary curve (a hole or crack)"),
                ));
            }
            [_] => {}
            [(_, q, f), (_, r, g)] => {
                if f == g {
                    return Err(failed(
                        "conformity",
                        format!("edge ({a}, {b}) is used in the same direction by quads {q} and {r} (orientation)"),
                    ));
                }
                if boundary_curve_edges.contains(&[a, b]) {
                    return Err(failed(
                        "conformity",
                        format!("boundary-curve edge ({a}, {b}) is shared by quads {q} and {r}"),
                    ));
                }
            }
            more => {
                let quads: Vec<u32> = more.iter().map(|s| s.1).collect();
                return Err(failed(
                    "conformity",
                    format!("edge ({a}, {b}) is shared by {} quads {quads:?}", quads.len()),
                ));
            }
        }
    }
    for (c, [a, b]) in &mesh.curve_edges {
        if !mesh_edges.contains(&[*a.min(b), *a.max(b)]) {
            return Err(failed("conformity", format!("curve edge ({a}, {b}) of curve {c} is not an edge of any quad")));
        }
    }
    Ok(())
}

/// Area of the (possibly non-planar) quad with corners `p`: half the norm
/// of the cross product of its diagonals, and its unit normal.
fn quad_area_normal(p: &[Vec3; 4]) -> (f64, Vec3) {
    let n = (p[2] - p[0]).cross(&(p[3] - p[1])) / 2.0;
    let a = n.norm();
    (a, if a > 0.0 { n / a } else { n })
}

/// Every model face has quads whose area matches its input area.
fn check_coverage(mesh: &QuadMesh, surface: &TriMesh, model: &QuadModel) -> Result<(), QuadsError> {
    let nf = model.n_faces;
    let mut input_area = vec![0.0; nf];
    for (f, &m) in model.face_per_triangle.iter().enumerate() {
        input_area[m as usize] += surface.face_area(FaceId::new(f));
    }
    let (mut area, mut allowance, mut count) = (vec![0.0; nf], vec![0.0; nf], vec![0usize; nf]);
    for (k, q) in mesh.quads.iter().enumerate() {
        let m = mesh.model_face_per_quad[k] as usize;
        let (a, n) = quad_area_normal(&q.map(|v| mesh.vertices.positions[v as usize]));
        let delta = q
            .iter()
            .filter(|&&v| matches!(mesh.vertices.entity[v as usize], ModelEntity::Face(_)))
            .map(|&v| angle_between(&n, &surface.face_normal(mesh.vertices.on_surface[v as usize].face)))
            .fold(0.0f64, f64::max);
        area[m] += a;
        allowance[m] += a * (1.0 - delta.cos());
        count[m] += 1;
    }
    for (m, &n) in count.iter().enumerate() {
        if n == 0 {
            return Err(failed("coverage", format!("model face {m} (area {:.6e}) has no quad", input_area[m])));
        }
        let tolerance = AREA_TOLERANCE * input_area[m] + allowance[m];
        if (area[m] - input_area[m]).abs() > tolerance {
            return Err(failed(
                "coverage",
                format!(
                    "model face {m}: its {} quads cover area {:.6e}, the input face has {:.6e} (tolerance {:.3e})",
                    n, area[m], input_area[m], tolerance
                ),
            ));
        }
    }
    Ok(())
}

/// Euler characteristic `V − E + F` of each edge-connected component of
/// the input with every pinch split (a vertex counted once per fan of its
/// triangles: the quads are a manifold, so two sheets that touch at a
/// vertex get a vertex each), and the component of each triangle.
fn input_euler_characteristics(surface: &TriMesh, topo: &Topology) -> (Vec<i64>, Vec<u32>) {
    let comps = connected_components(topo);
    let per_face = comps.component_per_face;
    let mut chi = vec![0i64; comps.n_components];
    for &c in &per_face {
        chi[c as usize] += 1;
    }
    for e in 0..topo.n_edges() {
        if let Some(f) = topo.edge_faces(EdgeId::new(e)).first() {
            chi[per_face[f.idx()] as usize] -= 1;
        }
    }
    let mut seen: HashSet<(u32, u32)> = HashSet::new();
    for (f, t) in surface.triangles.iter().enumerate() {
        for v in t {
            if seen.insert((v.0, per_face[f])) {
                chi[per_face[f] as usize] += 1;
            }
        }
    }
    // A pinch: each fan of it beyond the first in its component.
    for v in nonmanifold_vertices(surface, topo) {
        let fans = fan_of_each_face(surface, topo, v);
        let mut fans_in: HashSet<(u32, u32)> = HashSet::new();
        let mut first_in: HashSet<u32> = HashSet::new();
        for (f, fan) in topo.vertex_faces(v).iter().zip(fans) {
            let c = per_face[f.idx()];
            // The vertex loop above counted the first fan of each component.
            if fans_in.insert((c, fan)) && !first_in.insert(c) {
                chi[c as usize] += 1;
            }
        }
    }
    (chi, per_face)
}

/// The valence identity per component against the input's χ.
fn check_valence_identity(
    mesh: &QuadMesh,
    quality: &QuadQuality,
    surface: &TriMesh,
    topo: &Topology,
    model: &QuadModel,
) -> Result<(), QuadsError> {
    let (chi, comp_per_face) = input_euler_characteristics(surface, topo);
    // Input component of each model face (model faces never cross components).
    let mut comp_of_model_face = vec![u32::MAX; model.n_faces];
    for (f, &m) in model.face_per_triangle.iter().enumerate() {
        if comp_of_model_face[m as usize] == u32::MAX {
            comp_of_model_face[m as usize] = comp_per_face[f];
        }
    }
    // Edge-connected components of the quads.
    let mut sets = DisjointSets::new(mesh.quads.len());
    let mut first_quad_of_edge = std::collections::HashMap::with_capacity(2 * mesh.quads.len());
    for (k, q) in mesh.quads.iter().enumerate() {
        for i in 0..4 {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            let other = *first_quad_of_edge.entry([a.min(b), a.max(b)]).or_insert(k as u32);
            sets.union(other, k as u32);
        }
    }
    let (label, n_quad_comps) = sets.labels();
    // Input component of each quad component; one quad component per input component.
    let mut input_of = vec![u32::MAX; n_quad_comps];
    let mut quad_comp_of_input = vec![u32::MAX; chi.len()];
    for (k, &l) in label.iter().enumerate() {
        let c = comp_of_model_face[mesh.model_face_per_quad[k] as usize];
        match input_of[l as usize] {
            u32::MAX => {
                input_of[l as usize] = c;
                if quad_comp_of_input[c as usize] != u32::MAX {
                    return Err(failed(
                        "valence-identity",
                        format!("input component {c} is covered by two separate pieces of quads (a seam left open)"),
                    ));
                }
                quad_comp_of_input[c as usize] = l;
            }
            known if known != c => {
                return Err(failed(
                    "valence-identity",
                    format!("quads of input components {known} and {c} are connected (quad {k})"),
                ));
            }
            _ => {}
        }
    }
    // Σ (4 − val) on closed fans, (3 − val) on open ones, per quad component.
    let mut sum = vec![0i64; n_quad_comps];
    let mut counted = vec![false; mesh.vertices.len()];
    for (k, q) in mesh.quads.iter().enumerate() {
        for &v in q {
            let v = v as usize;
            if !std::mem::replace(&mut counted[v], true) {
                let regular = if quality.on_boundary[v] { 3 } else { 4 };
                sum[label[k] as usize] += regular - i64::from(quality.valence[v]);
            }
        }
    }
    for (l, &s) in sum.iter().enumerate() {
        let c = input_of[l] as usize;
        if s != 4 * chi[c] {
            return Err(failed(
                "valence-identity",
                format!(
                    "quads of input component {c}: Σ(4 − valence) + Σ_boundary(3 − valence) = {s}, but 4χ = {} \
                     (χ = {} of the input): the mesh does not have the input's topology",
                    4 * chi[c],
                    chi[c]
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::features::detect_features;
    use crate::mesh::fixtures;
    use crate::quads::fixtures::quads_from_triangle_pairs;
    use crate::quads::model::quad_model;
    use crate::quads::quality::quad_quality;

    struct Case {
        surface: TriMesh,
        topo: Topology,
        model: QuadModel,
        mesh: QuadMesh,
    }

    fn case(surface: TriMesh) -> Case {
        let topo = Topology::new(&surface);
        let model = quad_model(&surface, &topo, &detect_features(&surface, &topo, 30.0));
        let mesh = quads_from_triangle_pairs(&surface, &topo, &model);
        Case { surface, topo, model, mesh }
    }

    fn run_checks(c: &Case) -> Result<(), QuadsError> {
        let q = quad_quality(&c.mesh, &c.surface);
        check_quad_mesh(&c.mesh, &q, &c.surface, &c.topo, &c.model)
    }

    fn failed_check(c: &Case) -> (&'static str, String) {
        match run_checks(c) {
            Err(QuadsError::CheckFailed { check, detail }) => (check, detail),
            other => panic!("expected a failed check, got {other:?}"),
        }
    }

    #[test]
    fn grids_on_square_cube_cylinder_and_two_components_pass() {
        for surface in [
            fixtures::square_structured(5),
            fixtures::cube(3),
            fixtures::cylinder(1.0, 2.0, 16, 4),
            fixtures::union(&[
                fixtures::cube(2),
                fixtures::placed(&fixtures::cube(2), Vec3::repeat(1.0), Vec3::repeat(5.0)),
            ]),
        ] {
            let c = case(surface);
            assert_eq!(run_checks(&c).map_err(|e| e.to_string()), Ok(()));
        }
    }

    #[test]
    fn a_flipped_quad_is_inverted() {
        let mut c = case(fixtures::square_structured(3));
        c.mesh.quads[4].reverse();
        let (check, detail) = failed_check(&c);
        assert_eq!(check, "inverted");
        assert!(detail.starts_with("quad 4 "), "{detail}");
    }

    #[test]
    fn a_degenerate_quad_is_inverted_and_a_repeated_corner_is_a_triangle() {
        let mut c = case(fixtures::square_structured(3));
        let q = c.mesh.quads[0];
        c.mesh.vertices.positions[q[2] as usize] = c.mesh.vertices.positions[q[1] as usize];
        assert_eq!(failed_check(&c).0, "inverted");
        // Flat within round-off: corner 1 moved onto the line of its two
        // neighbours, to 1e-13 of it (a 180° corner, Gmsh's minSICN 0).
        let mut c = case(fixtures::square_structured(3));
        let q = c.mesh.quads[0];
        let p = &mut c.mesh.vertices.positions;
        let mid = (p[q[0] as usize] + p[q[2] as usize]) * 0.5;
        let towards = (p[q[1] as usize] - mid).normalize();
        p[q[1] as usize] = mid + towards * 1e-13;
        let (check, detail) = failed_check(&c);
        assert_eq!(check, "inverted", "{detail}");
        let mut c = case(fixtures::square_structured(3));
        c.mesh.quads[0][3] = c.mesh.quads[0][0];
        assert_eq!(failed_check(&c).0, "triangles");
    }

    #[test]
    fn a_hole_fails_conformity() {
        // One quad removed from the middle: its 4 edges become boundary edges off any curve.
        let mut c = case(fixtures::square_structured(3));
        c.mesh.quads.remove(4);
        c.mesh.model_face_per_quad.remove(4);
        let (check, detail) = failed_check(&c);
        assert_eq!(check, "conformity", "{detail}");
        assert!(detail.contains("not on a boundary curve"), "{detail}");
    }

    #[test]
    fn a_model_face_without_quads_fails_coverage() {
        // The quads of cube face 0 relabelled as face 1: the mesh stays closed and
        // conforming, face 0 is uncovered.
        let mut c = case(fixtures::cube(2));
        let face0: Vec<usize> = (0..c.mesh.quads.len()).filter(|&k| c.mesh.model_face_per_quad[k] == 0).collect();
        assert_eq!(face0.len(), 4);
        for k in face0 {
            c.mesh.model_face_per_quad[k] = 1;
        }
        let (check, detail) = failed_check(&c);
        assert_eq!(check, "coverage");
        assert!(detail.contains("model face 0") && detail.contains("no quad"), "{detail}");
    }

    #[test]
    fn a_stretched_face_fails_the_area_check() {
        // Quads 10 % wider than the input square: area +10 %, beyond 2 % (flat: no allowance).
        let mut c = case(fixtures::square_structured(4));
        for p in &mut c.mesh.vertices.positions {
            p.x *= 1.1;
        }
        let (check, detail) = failed_check(&c);
        assert_eq!(check, "coverage", "{detail}");
        // 1 % stays within the tolerance.
        let mut c = case(fixtures::square_structured(4));
        for p in &mut c.mesh.vertices.positions {
            p.x *= 1.01;
        }
        assert!(run_checks(&c).is_ok());
    }

    #[test]
    fn an_edge_used_twice_in_one_direction_breaks_orientation() {
        let mut c = case(fixtures::square_structured(2));
        c.mesh.quads[3].reverse();
        let e = check_conformity(&c.mesh, &c.topo, &c.model).unwrap_err();
        assert!(e.to_string().contains("same direction"), "{e}");
        // A duplicated quad puts its inner edges in three quads.
        let mut c = case(fixtures::square_structured(2));
        let q = c.mesh.quads[0];
        c.mesh.quads.push(q);
        c.mesh.model_face_per_quad.push(c.mesh.model_face_per_quad[0]);
        assert_eq!(failed_check(&c).0, "conformity");
    }

    #[test]
    fn a_boundary_curve_edge_must_be_a_boundary_edge() {
        // Dropping the curve edges of the square's boundary leaves boundary edges off any curve.
        let mut c = case(fixtures::square_structured(2));
        c.mesh.curve_edges.clear();
        let (check, detail) = failed_check(&c);
        assert_eq!(check, "conformity");
        assert!(detail.contains("not on a boundary curve"), "{detail}");
    }

    #[test]
    fn quads_with_the_wrong_topology_fail_the_identity() {
        // The quads of a cube (Σ = 8) classified on a torus (χ = 0).
        let torus = fixtures::torus(2.0, 0.5, 32, 16);
        let cube = case(fixtures::cube(2));
        let topo = Topology::new(&torus);
        let model = quad_model(&torus, &topo, &detect_features(&torus, &topo, 30.0));
        assert_eq!(model.n_faces, 1);
        let mut mesh = cube.mesh.clone();
        mesh.model_face_per_quad.iter_mut().for_each(|m| *m = 0);
        let q = quad_quality(&mesh, &cube.surface);
        let e = check_valence_identity(&mesh, &q, &torus, &topo, &model).unwrap_err();
        assert!(matches!(e, QuadsError::CheckFailed { check: "valence-identity", .. }), "{e}");
        assert!(e.to_string().contains("= 8, but 4χ = 0"), "{e}");
    }

    #[test]
    fn two_pieces_on_one_component_fail_the_identity() {
        // The square's quads split along x = 1/2 by duplicating the middle column of vertices.
        let mut c = case(fixtures::square_structured(2));
        let n = c.mesh.vertices.len() as u32;
        let mut copy = std::collections::HashMap::new();
        for k in 0..c.mesh.quads.len() {
            let right = c.mesh.quads[k].iter().all(|&v| c.mesh.vertices.positions[v as usize].x >= 0.5 - 1e-12);
            if right {
                for i in 0..4 {
                    let v = c.mesh.quads[k][i];
                    if (c.mesh.vertices.positions[v as usize].x - 0.5).abs() < 1e-12 {
                        let (p, s, e) = (
                            c.mesh.vertices.positions[v as usize],
                            c.mesh.vertices.on_surface[v as usize],
                            c.mesh.vertices.entity[v as usize],
                        );
                        c.mesh.quads[k][i] = *copy.entry(v).or_insert_with(|| c.mesh.vertices.push(p, s, e));
                    }
                }
            }
        }
        assert!(c.mesh.vertices.len() as u32 > n);
        let q = quad_quality(&c.mesh, &c.surface);
        let e = check_valence_identity(&c.mesh, &q, &c.surface, &c.topo, &c.model).unwrap_err();
        assert!(e.to_string().contains("two separate pieces"), "{e}");
    }

    #[test]
    fn input_euler_characteristics_are_known() {
        let m = fixtures::union(&[fixtures::cube(2), fixtures::torus(2.0, 0.5, 12, 6), fixtures::square(3)]);
        let topo = Topology::new(&m);
        let (chi, _) = input_euler_characteristics(&m, &topo);
        let mut chi = chi;
        chi.sort_unstable();
        assert_eq!(chi, vec![0, 1, 2]);
    }

    #[test]
    fn a_pinch_is_counted_split() {
        // A cube with two opposite corners made one vertex: one component,
        // V − E + F = 1, but two fans at the pinch; the manifold the quads
        // can be (the pinch split) is a sphere, χ = 2.
        let mut m = fixtures::cube(2);
        let corner = |m: &TriMesh, best: f64| {
            (0..m.n_vertices()).find(|&v| m.positions[v].sum() == best).map(crate::mesh::VertexId::new)
        };
        let lo = m.positions.iter().map(|p| p.sum()).fold(f64::INFINITY, f64::min);
        let hi = m.positions.iter().map(|p| p.sum()).fold(f64::NEG_INFINITY, f64::max);
        let (a, b) = (corner(&m, lo).unwrap(), corner(&m, hi).unwrap());
        m.triangles.iter_mut().flatten().filter(|v| **v == b).for_each(|v| *v = a);
        let m = fixtures::compact(m);
        let topo = Topology::new(&m);
        assert_eq!(nonmanifold_vertices(&m, &topo).len(), 1);
        assert_eq!(input_euler_characteristics(&m, &topo).0, vec![2]);
        // Two cubes touching at a corner: two components, each a sphere.
        let two = fixtures::union(&[
            fixtures::cube(2),
            fixtures::placed(&fixtures::cube(2), Vec3::repeat(1.0), Vec3::repeat(2.0)),
        ]);
        let (positions, triangles) = (two.positions.clone(), two.triangles.iter().map(|t| t.map(|v| v.0)).collect());
        let (two, _) = crate::mesh::repair::repair_triangle_soup(positions, triangles, 0.0).unwrap();
        let topo = Topology::new(&two);
        assert_eq!(nonmanifold_vertices(&two, &topo).len(), 1);
        assert_eq!(input_euler_characteristics(&two, &topo).0, vec![2, 2]);
    }
}
