//! The meshes the quads stage passes between its steps: a triangulation of
//! points on the input surface ([`SurfaceTriangulation`], the input of
//! recombination) and the quad mesh ([`QuadMesh`]).
//!
//! Conventions: every vertex carries its 3D position, where it lies on the
//! input surface ([`SurfacePoint`], barycentric on a triangle of the repaired
//! surface) and the model entity it is classified on ([`ModelEntity`]).
//! Triangles and quads are counter-clockwise seen from the side the surface's
//! triangle normals point to.

use crate::geom::Vec3;
use crate::mesh::FaceId;

/// A point of the input surface: barycentric coordinates on one of its
/// triangles (of the repaired surface the stages share, not of the atlas mesh).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// The triangle.
    pub face: FaceId,
    /// Barycentric coordinates, non-negative, summing to 1.
    pub bary: [f64; 3],
}

/// The model entity a vertex is classified on (indices into the
/// [`super::QuadModel`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ModelEntity {
    /// A model corner (fixed).
    Corner(u32),
    /// The inside of a feature curve (moves along it only).
    Curve(u32),
    /// The inside of a model face (moves on the surface).
    Face(u32),
}

/// Vertices on the input surface, shared by [`SurfaceTriangulation`] and
/// [`QuadMesh`].
#[derive(Debug, Clone, Default)]
pub struct SurfaceVertices {
    /// 3D position of each vertex.
    pub positions: Vec<Vec3>,
    /// Where each vertex lies on the input surface. Vertices created by
    /// midpoint subdivision may hold an approximation until the smoothing
    /// step projects every vertex.
    pub on_surface: Vec<SurfacePoint>,
    /// Model entity of each vertex.
    pub entity: Vec<ModelEntity>,
}

impl SurfaceVertices {
    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there is no vertex.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Drops the vertices from index `len` on.
    pub fn truncate(&mut self, len: usize) {
        self.positions.truncate(len);
        self.on_surface.truncate(len);
        self.entity.truncate(len);
    }

    /// Appends a vertex and returns its index.
    pub fn push(&mut self, position: Vec3, on_surface: SurfacePoint, entity: ModelEntity) -> u32 {
        self.positions.push(position);
        self.on_surface.push(on_surface);
        self.entity.push(entity);
        (self.positions.len() - 1) as u32
    }
}

/// An edge of the mesh on a feature curve: `(curve, [a, b])`, `a → b` in the
/// curve's direction.
pub type CurveEdge = (u32, [u32; 2]);

/// Points on the input surface and a triangulation of them, ready to be
/// recombined: the output of [`super::triangulation`].
#[derive(Debug, Clone, Default)]
pub struct SurfaceTriangulation {
    /// The vertices.
    pub vertices: SurfaceVertices,
    /// Triangles, counter-clockwise seen from the surface's outside.
    pub triangles: Vec<[u32; 3]>,
    /// Model face of each triangle.
    pub model_face_per_triangle: Vec<u32>,
    /// Unit tangent of one branch of the cross at each triangle (3D; the
    /// other branch is the normal × this one).
    pub cross_per_triangle: Vec<Vec3>,
    /// Unit normal of the input surface at each triangle.
    pub normal_per_triangle: Vec<Vec3>,
    /// Edges on feature curves, in curve order: recombination never removes
    /// them and they become the boundary lines of `quads.msh`.
    pub curve_edges: Vec<CurveEdge>,
    /// Vertices placed at crossfield singularities: `(vertex, index)` with
    /// the index in units of a quarter turn (+1: valence 3 expected, −1: 5).
    pub singular_vertices: Vec<(u32, i32)>,
    /// Vertices placed on atlas seams (not model entities: the mesh should
    /// cross seams; the report counts irregular vertices among these).
    pub seam_vertices: Vec<u32>,
}

/// The quad mesh: the output of the stage.
#[derive(Debug, Clone, Default)]
pub struct QuadMesh {
    /// The vertices (for order 2 also the edge and face nodes).
    pub vertices: SurfaceVertices,
    /// Quads as 4 corner vertices, counter-clockwise seen from the outside.
    pub quads: Vec<[u32; 4]>,
    /// Model face of each quad.
    pub model_face_per_quad: Vec<u32>,
    /// Edges on feature curves (boundary lines of `quads.msh`).
    pub curve_edges: Vec<CurveEdge>,
    /// For order 2: per quad the nodes of edges `01, 12, 23, 30` and the
    /// centre (Gmsh's 9-node quadrangle order after the 4 corners).
    pub high_order_nodes: Option<Vec<[u32; 5]>>,
    /// Vertices placed at crossfield singularities, as in
    /// [`SurfaceTriangulation::singular_vertices`] (indices follow any
    /// renumbering of the later steps).
    pub singular_vertices: Vec<(u32, i32)>,
    /// Vertices placed on atlas seams, as in
    /// [`SurfaceTriangulation::seam_vertices`] (indices follow renumbering).
    pub seam_vertices: Vec<u32>,
}

/// The loop that follows `next` from `start` back to `start`, when it
/// passes every one of the `n_edges` boundary edges `next` holds (one
/// simple loop); `None` when it breaks off, runs longer, or leaves edges
/// out. Shared by the steps that replace a disk of elements by a new
/// filling of its boundary.
pub fn single_boundary_loop(start: u32, n_edges: usize, next: impl Fn(u32) -> Option<u32>) -> Option<Vec<u32>> {
    let mut lp = vec![start];
    let mut v = next(start)?;
    while v != start {
        if lp.len() > n_edges {
            return None;
        }
        lp.push(v);
        v = next(v)?;
    }
    (lp.len() == n_edges).then_some(lp)
}
