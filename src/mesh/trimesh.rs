//! Indexed triangle mesh with `f64` coordinates.

use super::{FaceId, MeshError, VertexId};
use crate::geom::{BoundingBox, Vec3, triangle_area, triangle_area_vector};

/// An indexed triangle mesh: positions and triangles as vertex triples.
///
/// Invariants (checked by [`TriMesh::validate`]): every index is in range,
/// every coordinate is finite, no triangle repeats a vertex, counts fit `u32`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions, indexed by [`VertexId`].
    pub positions: Vec<Vec3>,
    /// Triangles, indexed by [`FaceId`]; corners counter-clockwise around the normal.
    pub triangles: Vec<[VertexId; 3]>,
}

impl TriMesh {
    /// A mesh from positions and `u32` triangles (as readers produce them).
    pub fn from_raw(positions: Vec<Vec3>, triangles: &[[u32; 3]]) -> Self {
        let triangles = triangles.iter().map(|t| t.map(VertexId)).collect();
        Self { positions, triangles }
    }

    /// Number of vertices.
    #[inline]
    pub fn n_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    #[inline]
    pub fn n_faces(&self) -> usize {
        self.triangles.len()
    }

    /// Position of vertex `v`.
    #[inline]
    pub fn position(&self, v: VertexId) -> &Vec3 {
        &self.positions[v.idx()]
    }

    /// The three corner positions of triangle `f`.
    #[inline]
    pub fn corners(&self, f: FaceId) -> [Vec3; 3] {
        self.triangles[f.idx()].map(|v| self.positions[v.idx()])
    }

    /// `(b − a) × (c − a)` of triangle `f`: twice its area along its normal.
    #[inline]
    pub fn face_area_vector(&self, f: FaceId) -> Vec3 {
        let [a, b, c] = self.corners(f);
        triangle_area_vector(&a, &b, &c)
    }

    /// Area of triangle `f`.
    #[inline]
    pub fn face_area(&self, f: FaceId) -> f64 {
        let [a, b, c] = self.corners(f);
        triangle_area(&a, &b, &c)
    }

    /// Unit normal of triangle `f` (zero vector when degenerate).
    pub fn face_normal(&self, f: FaceId) -> Vec3 {
        let n = self.face_area_vector(f);
        let l = n.norm();
        if l > 0.0 { n / l } else { Vec3::zeros() }
    }

    /// Unit normal of every triangle ([`TriMesh::face_normal`]), in triangle
    /// order: for loops that read the normals under many points again and
    /// again (one load instead of three corners and a square root).
    pub fn face_normals(&self) -> Vec<Vec3> {
        use rayon::prelude::*;
        (0..self.n_faces()).into_par_iter().map(|f| self.face_normal(FaceId::new(f))).collect()
    }

    /// Sum of triangle areas.
    pub fn area(&self) -> f64 {
        (0..self.n_faces()).map(|f| self.face_area(FaceId::new(f))).sum()
    }

    /// Signed volume enclosed (divergence theorem); positive for a closed
    /// surface with outward normals. Meaningless for open surfaces.
    pub fn signed_volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| self.positions[v.idx()]);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Bounding box of the vertices, `None` when the mesh is empty.
    pub fn bounding_box(&self) -> Option<BoundingBox> {
        BoundingBox::of_points(&self.positions)
    }

    /// Mean edge length over triangle edges (each shared edge counted per triangle).
    pub fn mean_edge_length(&self) -> f64 {
        if self.triangles.is_empty() {
            return 0.0;
        }
        let sum: f64 = self
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| self.positions[v.idx()]);
                (b - a).norm() + (c - b).norm() + (a - c).norm()
            })
            .sum();
        sum / (3.0 * self.triangles.len() as f64)
    }

    /// Reverse the orientation of triangle `f` (swap two corners).
    pub fn flip_face(&mut self, f: FaceId) {
        self.triangles[f.idx()].swap(1, 2);
    }

    /// Check every invariant of the type.
    ///
    /// # Errors
    /// The first violated invariant, naming the element.
    pub fn validate(&self) -> Result<(), MeshError> {
        check_count("vertex", self.positions.len())?;
        check_count("triangle", self.triangles.len())?;
        check_finite(&self.positions)?;
        check_elements(&self.triangles, self.positions.len())
    }
}

/// Counts must fit the 32-bit ids.
pub(crate) fn check_count(what: &'static str, count: usize) -> Result<(), MeshError> {
    let max = u32::MAX as usize;
    if count > max { Err(MeshError::TooLarge { what, count, max }) } else { Ok(()) }
}

/// Every coordinate must be finite.
pub(crate) fn check_finite(positions: &[Vec3]) -> Result<(), MeshError> {
    match positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        Some(i) => {
            let p = positions[i];
            Err(MeshError::NonFiniteCoordinate { vertex: i, x: p.x, y: p.y, z: p.z })
        }
        None => Ok(()),
    }
}

/// Every element index must be in range and distinct within its element.
pub(crate) fn check_elements<const N: usize>(elements: &[[VertexId; N]], n_vertices: usize) -> Result<(), MeshError> {
    for (e, el) in elements.iter().enumerate() {
        for (i, v) in el.iter().enumerate() {
            if v.idx() >= n_vertices {
                return Err(MeshError::VertexOutOfRange { element: e, vertex: v.0, n_vertices });
            }
            if el[..i].contains(v) {
                return Err(MeshError::RepeatedVertex { element: e, vertex: v.0 });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_square() -> TriMesh {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        TriMesh::from_raw(p, &[[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn measures_of_unit_square() {
        let m = unit_square();
        assert!(m.validate().is_ok());
        assert!((m.area() - 1.0).abs() < 1e-15);
        assert_eq!(m.face_normal(FaceId(0)), Vec3::z());
        assert!((m.bounding_box().unwrap().diagonal() - 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn validate_names_the_broken_element() {
        let mut m = unit_square();
        m.triangles[1][2] = VertexId(9);
        assert_eq!(m.validate(), Err(MeshError::VertexOutOfRange { element: 1, vertex: 9, n_vertices: 4 }));
        let mut m = unit_square();
        m.triangles[0][2] = VertexId(0);
        assert_eq!(m.validate(), Err(MeshError::RepeatedVertex { element: 0, vertex: 0 }));
        let mut m = unit_square();
        m.positions[3].y = f64::NAN;
        assert!(matches!(m.validate(), Err(MeshError::NonFiniteCoordinate { vertex: 3, .. })));
    }

    #[test]
    fn flip_reverses_normal() {
        let mut m = unit_square();
        m.flip_face(FaceId(0));
        assert_eq!(m.face_normal(FaceId(0)), -Vec3::z());
        assert!(m.validate().is_ok());
    }
}
