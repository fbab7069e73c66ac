//! Tetrahedral mesh of a volume, for the frame-field stage.

use super::trimesh::{check_count, check_elements, check_finite};
use super::{MeshError, TetId, VertexId};
use crate::geom::Vec3;

/// An indexed tetrahedral mesh.
///
/// Invariants (checked by [`TetMesh::validate`]): indices in range and
/// distinct per tet, finite coordinates, every tet positively oriented
/// (`(b − a) · ((c − a) × (d − a)) > 0`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TetMesh {
    /// Vertex positions, indexed by [`VertexId`].
    pub positions: Vec<Vec3>,
    /// Tetrahedra, indexed by [`TetId`].
    pub tets: Vec<[VertexId; 4]>,
}

impl TetMesh {
    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of tetrahedra.
    pub fn n_tets(&self) -> usize {
        self.tets.len()
    }

    /// Six times the signed volume of tet `t`.
    pub fn signed_volume6(&self, t: TetId) -> f64 {
        let [a, b, c, d] = self.tets[t.idx()].map(|v| self.positions[v.idx()]);
        (b - a).dot(&(c - a).cross(&(d - a)))
    }

    /// Total volume.
    pub fn volume(&self) -> f64 {
        (0..self.n_tets()).map(|t| self.signed_volume6(TetId::new(t))).sum::<f64>() / 6.0
    }

    /// Swap two corners of every negatively oriented tet; returns how many.
    pub fn orient_positive(&mut self) -> usize {
        let mut n = 0;
        for t in 0..self.tets.len() {
            if self.signed_volume6(TetId::new(t)) < 0.0 {
                self.tets[t].swap(2, 3);
                n += 1;
            }
        }
        n
    }

    /// Check every invariant of the type.
    ///
    /// # Errors
    /// The first violated invariant, naming the element.
    pub fn validate(&self) -> Result<(), MeshError> {
        check_count("vertex", self.positions.len())?;
        check_count("tetrahedron", self.tets.len())?;
        check_finite(&self.positions)?;
        check_elements(&self.tets, self.positions.len())?;
        for t in 0..self.tets.len() {
            let v = self.signed_volume6(TetId::new(t));
            if v.is_nan() || v <= 0.0 {
                return Err(MeshError::InvertedTet { tet: t, volume: v / 6.0 });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_and_volume() {
        let mut m = TetMesh {
            positions: vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            tets: vec![[VertexId(0), VertexId(2), VertexId(1), VertexId(3)]],
        };
        assert!(matches!(m.validate(), Err(MeshError::InvertedTet { tet: 0, .. })));
        assert_eq!(m.orient_positive(), 1);
        assert!(m.validate().is_ok());
        assert!((m.volume() - 1.0 / 6.0).abs() < 1e-15);
    }
}
