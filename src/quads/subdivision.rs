//! Midpoint subdivision, the last resort of recombination (Gmsh's
//! full-quad guarantee; research quad-meshing §1.1, §5.1 step 4): every
//! element of a set (free triangles alone, [`super::transition`], or whole
//! model faces) is split at its edge midpoints and its centroid, a quad `(a, b, c, d)` into the 4 quads `(a, m_ab, g, m_da)`, …,
//! a triangle `(a, b, c)` into the 3 quads `(a, m_ab, g, m_ca)`, …, all
//! counter-clockwise as their parent. Every element then becomes quads, and
//! a face whose triangles cannot all be paired (odd count, or no perfect
//! matching among the convex pairs) gets an all-quad mesh.
//!
//! Splitting a set's boundary edges changes its neighbours' boundaries
//! too: [`super::transition`] joins the midpoints left on them through
//! strips; where it cannot, the set of faces is closed over faces sharing
//! an edge ([`faces_to_subdivide`]), so a face is either split whole, with
//! its neighbours, or left alone, and the mesh stays conforming.
//!
//! A midpoint on a feature curve is classified on that curve and the curve
//! edge is replaced by its two halves, in curve order; other new vertices
//! are classified on the element's model face. Their 3D position is the
//! mean of the corners; their [`SurfacePoint`] the mean of the corners'
//! barycentric coordinates when all corners lie on one input triangle, else
//! the first corner's (an approximation the smoothing step's projection
//! replaces: recombination does not see the input surface).

use std::collections::HashMap;

use super::surface_mesh::{CurveEdge, ModelEntity, SurfacePoint, SurfaceVertices};
use crate::geom::Vec3;

/// An element before subdivision: a quad or a triangle left unpaired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Element {
    /// A quad, counter-clockwise.
    Quad([u32; 4]),
    /// A triangle, counter-clockwise.
    Triangle([u32; 3]),
}

impl Element {
    /// The corners, counter-clockwise.
    pub fn corners(&self) -> &[u32] {
        match self {
            Element::Quad(q) => q,
            Element::Triangle(t) => t,
        }
    }
}

/// The model faces to subdivide: those in `failing` and every face
/// reachable from them through `face_links` (faces sharing an edge), as a
/// per-face flag over `n_faces` faces.
pub fn faces_to_subdivide(n_faces: usize, failing: &[u32], face_links: &[[u32; 2]]) -> Vec<bool> {
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n_faces];
    for &[f, g] in face_links {
        neighbours[f as usize].push(g);
        neighbours[g as usize].push(f);
    }
    let mut flag = vec![false; n_faces];
    let mut stack: Vec<u32> = Vec::new();
    for &f in failing {
        if !flag[f as usize] {
            flag[f as usize] = true;
            stack.push(f);
        }
        while let Some(f) = stack.pop() {
            for &g in &neighbours[f as usize] {
                if !flag[g as usize] {
                    flag[g as usize] = true;
                    stack.push(g);
                }
            }
        }
    }
    flag
}

/// What [`subdivide`] made.
#[derive(Debug, Clone, Default)]
pub struct Subdivided {
    /// The quads, in element order.
    pub quads: Vec<[u32; 4]>,
    /// Model face of each quad.
    pub faces: Vec<u32>,
    /// Quads made by subdivision.
    pub n_subdivision_quads: usize,
    /// The edges split, as `(edge key, midpoint)` in key order: an
    /// unflagged element on the other side still holds the whole edge (its
    /// caller joins such midpoints through strips).
    pub midpoints: Vec<((u32, u32), u32)>,
}

/// Splits each element of `elements` (model face `face_per_element`)
/// flagged in `split` (module doc), appending the new vertices to
/// `vertices` and updating `curve_edges`. Unflagged triangles are dropped
/// (the caller flags every triangle).
pub fn subdivide(
    vertices: &mut SurfaceVertices,
    elements: &[Element],
    face_per_element: &[u32],
    split: &[bool],
    curve_edges: &mut Vec<CurveEdge>,
) -> Subdivided {
    let curve_of: HashMap<(u32, u32), u32> = curve_edges.iter().map(|&(c, [a, b])| ((a.min(b), a.max(b)), c)).collect();
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
    let mut quads = Vec::with_capacity(elements.len());
    let mut faces = Vec::with_capacity(elements.len());
    let mut n_subdivision_quads = 0;
    for ((element, &face), &split) in elements.iter().zip(face_per_element).zip(split) {
        if !split {
            if let Element::Quad(q) = element {
                quads.push(*q);
                faces.push(face);
            }
            continue;
        }
        let corners = element.corners();
        let k = corners.len();
        let mids: Vec<u32> = (0..k)
            .map(|i| {
                let (a, b) = (corners[i], corners[(i + 1) % k]);
                let key = (a.min(b), a.max(b));
                *midpoints.entry(key).or_insert_with(|| {
                    let entity = curve_of.get(&key).map_or(ModelEntity::Face(face), |&c| ModelEntity::Curve(c));
                    push_mean_vertex(vertices, &[a, b], entity)
                })
            })
            .collect();
        let centre = push_mean_vertex(vertices, corners, ModelEntity::Face(face));
        for i in 0..k {
            quads.push([corners[i], mids[i], centre, mids[(i + k - 1) % k]]);
            faces.push(face);
        }
        n_subdivision_quads += k;
    }
    *curve_edges = curve_edges
        .iter()
        .flat_map(|&(c, [a, b])| match midpoints.get(&(a.min(b), a.max(b))) {
            Some(&m) => vec![(c, [a, m]), (c, [m, b])],
            None => vec![(c, [a, b])],
        })
        .collect();
    let mut midpoints: Vec<((u32, u32), u32)> = midpoints.into_iter().collect();
    midpoints.sort_unstable();
    Subdivided { quads, faces, n_subdivision_quads, midpoints }
}

/// Appends the vertex at the mean of `corners` (module doc) and returns it.
pub(super) fn push_mean_vertex(vertices: &mut SurfaceVertices, corners: &[u32], entity: ModelEntity) -> u32 {
    let k = corners.len() as f64;
    let position = corners.iter().fold(Vec3::zeros(), |s, &v| s + vertices.positions[v as usize]) / k;
    let first = vertices.on_surface[corners[0] as usize];
    let on_one_triangle = corners.iter().all(|&v| vertices.on_surface[v as usize].face == first.face);
    let on_surface = if on_one_triangle {
        let mut bary = [0.0; 3];
        for &v in corners {
            for (s, b) in bary.iter_mut().zip(vertices.on_surface[v as usize].bary) {
                *s += b / k;
            }
        }
        SurfacePoint { face: first.face, bary }
    } else {
        first
    };
    vertices.push(position, on_surface, entity)
}
