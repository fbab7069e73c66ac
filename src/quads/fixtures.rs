//! Quad meshes built in code, for tests of the measures, checks and
//! writers of the quads stage: the triangles of a fixture surface
//! ([`crate::mesh::fixtures`]) that come in consecutive pairs sharing an
//! edge (the cells of `square_structured`, `cube`, `cylinder`, …) merged
//! into quads. Every vertex is a vertex of the surface (barycentric
//! `(1, 0, 0)` on one of its triangles), so the quads lie exactly on the
//! input and their known answers (areas, valences, χ) are those of the
//! fixture.

use std::collections::HashMap;

use super::model::QuadModel;
use super::surface_mesh::{ModelEntity, QuadMesh, SurfacePoint, SurfaceTriangulation, SurfaceVertices};
use crate::geom::Vec3;
use crate::mesh::{FaceId, Topology, TriMesh, VertexId};

/// The quad of triangles `t` and `s` sharing an edge, counter-clockwise as
/// they are: `t` rotated so the shared edge is its last (`t[2] → t[0]`),
/// then the corner of `s` off that edge.
///
/// # Panics
/// When the two triangles do not share exactly one edge (a bad fixture).
fn merged(t: [u32; 3], s: [u32; 3]) -> [u32; 4] {
    let rot = (0..3)
        .find(|&r| {
            let (a, c) = (t[r], t[(r + 2) % 3]);
            s.contains(&a) && s.contains(&c) && !s.contains(&t[(r + 1) % 3])
        })
        .expect("fixture triangles must share one edge");
    let t = [t[rot], t[(rot + 1) % 3], t[(rot + 2) % 3]];
    let d = s.into_iter().find(|v| !t.contains(v)).expect("two distinct triangles");
    [t[0], t[1], t[2], d]
}

/// The model entity of each surface vertex: its corner, else the feature
/// curve it lies inside, else the model face of a triangle at it.
fn entities(surface: &TriMesh, topo: &Topology, model: &QuadModel) -> Vec<ModelEntity> {
    let mut entity: Vec<Option<ModelEntity>> = vec![None; surface.n_vertices()];
    for (c, curve) in model.features.curves.iter().enumerate() {
        for v in &curve.vertices {
            entity[v.idx()] = Some(ModelEntity::Curve(c as u32));
        }
    }
    for (i, v) in model.corners.iter().enumerate() {
        entity[v.idx()] = Some(ModelEntity::Corner(i as u32));
    }
    (0..surface.n_vertices())
        .map(|v| {
            entity[v].unwrap_or_else(|| {
                let f = topo.vertex_faces(VertexId::new(v)).first().map_or(0, |f| f.idx());
                ModelEntity::Face(model.face_per_triangle.get(f).copied().unwrap_or(0))
            })
        })
        .collect()
}

/// The quad mesh of the consecutive triangle pairs `(2k, 2k + 1)` of
/// `surface`, classified on `model` (its feature model), with the feature
/// curves' edges as curve edges and no singular or seam vertices.
///
/// # Panics
/// When a pair does not share an edge (`surface` is not such a fixture).
pub fn quads_from_triangle_pairs(surface: &TriMesh, topo: &Topology, model: &QuadModel) -> QuadMesh {
    let mut vertices = SurfaceVertices::default();
    let entity = entities(surface, topo, model);
    for (v, &e) in entity.iter().enumerate() {
        let (face, corner) = match topo.vertex_faces(VertexId::new(v)).first() {
            Some(&f) => (f, surface.triangles[f.idx()].iter().position(|c| c.idx() == v).unwrap_or(0)),
            None => (FaceId(0), 0),
        };
        let mut bary = [0.0; 3];
        bary[corner] = 1.0;
        vertices.push(surface.positions[v], SurfacePoint { face, bary }, e);
    }
    let tri = |f: usize| surface.triangles[f].map(|v| v.0);
    let quads: Vec<[u32; 4]> = (0..surface.n_faces() / 2).map(|k| merged(tri(2 * k), tri(2 * k + 1))).collect();
    let model_face_per_quad = (0..quads.len()).map(|k| model.face_per_triangle[2 * k]).collect();
    let curve_edges = model
        .features
        .curves
        .iter()
        .enumerate()
        .flat_map(|(c, curve)| curve.vertices.windows(2).map(move |w| (c as u32, [w[0].0, w[1].0])))
        .collect();
    QuadMesh {
        vertices,
        quads,
        model_face_per_quad,
        curve_edges,
        high_order_nodes: None,
        singular_vertices: Vec::new(),
        seam_vertices: Vec::new(),
    }
}

/// Adds 9-node quadrangle nodes to `mesh` by straight midpoints (edge
/// nodes shared by the quads of an edge, classified like the edge: on its
/// curve when the edge is a curve edge, else on the quad's model face),
/// each recorded on the surface point of the edge's first corner. Only for
/// flat fixtures, where midpoints lie on the input.
pub fn add_midpoint_nodes(mesh: &mut QuadMesh) {
    let curve_of: std::collections::HashMap<[u32; 2], u32> =
        mesh.curve_edges.iter().map(|&(c, [a, b])| ([a.min(b), a.max(b)], c)).collect();
    let mut mid: std::collections::HashMap<[u32; 2], u32> = std::collections::HashMap::new();
    let mut nodes = Vec::with_capacity(mesh.quads.len());
    for (qi, q) in mesh.quads.clone().iter().enumerate() {
        let face = ModelEntity::Face(mesh.model_face_per_quad[qi]);
        let mut n = [0u32; 5];
        for i in 0..4 {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            let key = [a.min(b), a.max(b)];
            n[i] = *mid.entry(key).or_insert_with(|| {
                let p = (mesh.vertices.positions[a as usize] + mesh.vertices.positions[b as usize]) / 2.0;
                let e = curve_of.get(&key).map_or(face, |&c| ModelEntity::Curve(c));
                let s = mesh.vertices.on_surface[a as usize];
                mesh.vertices.push(p, s, e)
            });
        }
        let c = q.iter().map(|&v| mesh.vertices.positions[v as usize]).sum::<crate::geom::Vec3>() / 4.0;
        let s = mesh.vertices.on_surface[q[0] as usize];
        n[4] = mesh.vertices.push(c, s, face);
        nodes.push(n);
    }
    mesh.high_order_nodes = Some(nodes);
}

/// A planar triangulation of `points` (z = 0) with triangles `triangles`
/// in model faces `faces`, cross along x, normal +z, and every edge used
/// by one triangle or by two faces made a curve edge (curve 0).
pub fn planar_triangulation(points: &[[f64; 2]], triangles: Vec<[u32; 3]>, faces: Vec<u32>) -> SurfaceTriangulation {
    let mut tri = SurfaceTriangulation::default();
    for (i, p) in points.iter().enumerate() {
        let sp = SurfacePoint { face: FaceId(i as u32), bary: [1.0, 0.0, 0.0] };
        tri.vertices.push(Vec3::new(p[0], p[1], 0.0), sp, ModelEntity::Face(0));
    }
    // Per undirected edge: (model face, directed edge) of each use.
    type Uses = Vec<(u32, [u32; 2])>;
    let mut uses: HashMap<(u32, u32), Uses> = HashMap::new();
    for (t, tv) in triangles.iter().enumerate() {
        for i in 0..3 {
            let (a, b) = (tv[i], tv[(i + 1) % 3]);
            uses.entry((a.min(b), a.max(b))).or_default().push((faces[t], [a, b]));
        }
    }
    let mut curve: Vec<[u32; 2]> = uses.values().filter(|u| u.len() == 1 || u[0].0 != u[1].0).map(|u| u[0].1).collect();
    curve.sort_unstable();
    for &[a, b] in &curve {
        for v in [a, b] {
            tri.vertices.entity[v as usize] = ModelEntity::Curve(0);
        }
    }
    tri.curve_edges = curve.into_iter().map(|e| (0, e)).collect();
    tri.cross_per_triangle = vec![Vec3::x(); triangles.len()];
    tri.normal_per_triangle = vec![Vec3::z(); triangles.len()];
    tri.triangles = triangles;
    tri.model_face_per_triangle = faces;
    tri
}
