//! Step 6 of the quads stage: the extra nodes of 9-node quadrangles
//! (`quads.order = 2`, for spectral-element codes), every one on the input.
//!
//! - One node per edge, shared by the quads on either side: the edge's
//!   midpoint projected onto its feature curve for a curve edge (entity
//!   `Curve`), else onto the model face of the first quad using it.
//! - One node per quad: the centre of the biquadratic map through the
//!   corners and the projected edge nodes, `Σ edge nodes / 2 − Σ corners / 4`
//!   (the centroid for a flat quad, pushed towards the surface for a curved
//!   one), projected onto the quad's model face.
//!
//! `high_order_nodes[q]` lists the nodes of edges `01, 12, 23, 30` and the
//! centre, Gmsh's 9-node quadrangle order after the 4 corners. Nodes are
//! created in quad order, so the numbering is deterministic.

use std::collections::HashMap;

use super::projection::SurfaceProjector;
use super::surface_mesh::{ModelEntity, QuadMesh};
use crate::geom::Vec3;

/// Adds the edge and centre nodes of 9-node quadrangles, on the input.
pub fn add_high_order_nodes(mesh: &mut QuadMesh, projector: &SurfaceProjector) {
    let curve_per_edge: HashMap<[u32; 2], u32> =
        mesh.curve_edges.iter().map(|&(c, [a, b])| ([a.min(b), a.max(b)], c)).collect();
    let mut node_per_edge: HashMap<[u32; 2], u32> = HashMap::with_capacity(2 * mesh.quads.len());
    let mut nodes = Vec::with_capacity(mesh.quads.len());
    for qi in 0..mesh.quads.len() {
        let quad = mesh.quads[qi];
        let face = mesh.model_face_per_quad[qi];
        let mut ho = [0u32; 5];
        for k in 0..4 {
            let (a, b) = (quad[k], quad[(k + 1) % 4]);
            let key = [a.min(b), a.max(b)];
            ho[k] = match node_per_edge.get(&key) {
                Some(&n) => n,
                None => {
                    let n = add_edge_node(mesh, projector, a, b, curve_per_edge.get(&key).copied(), face);
                    node_per_edge.insert(key, n);
                    n
                }
            };
        }
        let p = &mesh.vertices.positions;
        let edges: Vec3 = ho[..4].iter().map(|&n| p[n as usize]).sum();
        let corners: Vec3 = quad.iter().map(|&v| p[v as usize]).sum();
        let centre = edges / 2.0 - corners / 4.0;
        let hint = mesh.vertices.on_surface[quad[0] as usize];
        let proj = projector.project(ModelEntity::Face(face), &centre, &hint);
        ho[4] = mesh.vertices.push(proj.position, proj.on_surface, ModelEntity::Face(face));
        nodes.push(ho);
    }
    mesh.high_order_nodes = Some(nodes);
}

/// Appends the node of edge `a b`: its midpoint projected onto curve
/// `curve` when the edge lies on one, else onto model face `face`.
fn add_edge_node(
    mesh: &mut QuadMesh,
    projector: &SurfaceProjector,
    a: u32,
    b: u32,
    curve: Option<u32>,
    face: u32,
) -> u32 {
    let v = &mesh.vertices;
    let mid = (v.positions[a as usize] + v.positions[b as usize]) / 2.0;
    let entity = curve.map_or(ModelEntity::Face(face), ModelEntity::Curve);
    // A curve's own vertex gives the better hint (a corner's surface point
    // may sit on a triangle away from this curve).
    let hint = if matches!(v.entity[a as usize], ModelEntity::Curve(_)) { a } else { b };
    let proj = projector.project(entity, &mid, &v.on_surface[hint as usize]);
    mesh.vertices.push(proj.position, proj.on_surface, entity)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;
    use crate::quads::jacobian::{quad_reference_normal, scaled_jacobian};
    use crate::quads::smooth::project_all;
    use crate::quads::smooth::tests::{Input, grid_mesh};
    use std::f64::consts::{PI, TAU};

    /// The cylinder, its quad grid with order-2 nodes, and the radius.
    fn cylinder_order2(n_around: usize) -> (Input, QuadMesh) {
        let input = Input::new(fixtures::cylinder(1.0, 1.0, n_around, 8));
        let (n, m) = (12, 4);
        let mut mesh = grid_mesh(&input, n, m, true, |i, j| {
            let t = TAU * i as f64 / n as f64;
            Vec3::new(t.cos(), t.sin(), j as f64 / m as f64)
        });
        let proj = input.projector();
        project_all(&mut mesh, &proj);
        add_high_order_nodes(&mut mesh, &proj);
        (input, mesh)
    }

    #[test]
    fn order2_nodes_on_a_cylinder_lie_on_it_and_edges_share_them() {
        let n_around = 96;
        let (input, mesh) = cylinder_order2(n_around);
        let proj = input.projector();
        let n_corners = 12 * 5;
        let ho = mesh.high_order_nodes.as_ref().unwrap();
        assert_eq!(ho.len(), mesh.quads.len());
        // Edges: 12 × 5 rings' worth around plus 12 × 4 up; quads 48.
        assert_eq!(mesh.vertices.len(), n_corners + 12 * 5 + 12 * 4 + 48);
        // The input's discretization: within the sagitta of its 96-gon.
        let sagitta = 1.0 - (PI / n_around as f64).cos();
        for v in n_corners..mesh.vertices.len() {
            let p = mesh.vertices.positions[v];
            let rho = (p.x * p.x + p.y * p.y).sqrt();
            assert!(rho <= 1.0 + 1e-12 && rho >= 1.0 - sagitta - 1e-12, "node {v}: radius {rho}");
            assert!((proj.position_of(&mesh.vertices.on_surface[v]) - p).norm() < 1e-12);
            if let ModelEntity::Curve(_) = mesh.vertices.entity[v] {
                assert!(p.z.abs() < 1e-12 || (p.z - 1.0).abs() < 1e-12, "curve node {v} off its ring");
            }
        }
        // A straight midpoint would sit at cos(π/12) ≈ 0.966: the nodes are
        // really on the cylinder, not on the chords.
        assert!((1.0 - sagitta) > (PI / 12.0).cos() + 0.03);
        // Neighbouring quads share their edge's node; each quad's 4 sub-quads
        // (corner, edge node, centre, edge node) are valid.
        for (q, quad) in mesh.quads.iter().enumerate() {
            let right = (q / 12) * 12 + (q % 12 + 1) % 12;
            assert_eq!(ho[q][1], ho[right][3], "quad {q} and {right} share edge 12 / 30");
            let n = quad_reference_normal(&mesh.vertices, &input.surface.face_normals(), quad);
            for k in 0..4 {
                let sub = [quad[k], ho[q][k], ho[q][4], ho[q][(k + 3) % 4]];
                let sj = scaled_jacobian(&sub.map(|v| mesh.vertices.positions[v as usize]), &n);
                assert!(sj > 0.9, "quad {q} corner {k}: sub-quad scaled Jacobian {sj}");
            }
        }
    }

    #[test]
    fn order2_is_deterministic_and_curve_edges_get_curve_nodes() {
        let (_, a) = cylinder_order2(48);
        let (_, b) = cylinder_order2(48);
        assert_eq!(a.vertices.positions, b.vertices.positions);
        assert_eq!(a.high_order_nodes, b.high_order_nodes);
        let ho = a.high_order_nodes.as_ref().unwrap();
        // The bottom row's edge 01 lies on the ring z = 0, the top row's edge 23 on z = 1.
        for q in 0..12 {
            assert!(matches!(a.vertices.entity[ho[q][0] as usize], ModelEntity::Curve(_)));
            assert!(matches!(a.vertices.entity[ho[36 + q][2] as usize], ModelEntity::Curve(_)));
            assert!(matches!(a.vertices.entity[ho[q][1] as usize], ModelEntity::Face(_)));
        }
    }
}
