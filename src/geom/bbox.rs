//! Axis-aligned bounding boxes, used to make tolerances relative to model size.

use super::Vec3;

/// Axis-aligned bounding box of a point set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundingBox {
    /// Componentwise minimum.
    pub min: Vec3,
    /// Componentwise maximum.
    pub max: Vec3,
}

impl BoundingBox {
    /// The box of `points`, or `None` when there are none.
    pub fn of_points<'a>(points: impl IntoIterator<Item = &'a Vec3>) -> Option<Self> {
        let mut it = points.into_iter();
        let first = *it.next()?;
        let mut b = BoundingBox { min: first, max: first };
        for p in it {
            b.min = b.min.inf(p);
            b.max = b.max.sup(p);
        }
        Some(b)
    }

    /// Length of the main diagonal; the model size every tolerance is relative to.
    pub fn diagonal(&self) -> f64 {
        (self.max - self.min).norm()
    }

    /// Centre of the box.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// The six numbers `xmin ymin zmin xmax ymax zmax`, as MSH `$Entities` write them.
    pub fn to_array(&self) -> [f64; 6] {
        [self.min.x, self.min.y, self.min.z, self.max.x, self.max.y, self.max.z]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_of_points_and_diagonal() {
        let pts = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 2.0), Vec3::new(0.5, -1.0, 0.0)];
        let b = BoundingBox::of_points(&pts).unwrap();
        assert_eq!(b.min, Vec3::new(0.0, -1.0, 0.0));
        assert_eq!(b.max, Vec3::new(1.0, 2.0, 2.0));
        assert!((b.diagonal() - (1.0f64 + 9.0 + 4.0).sqrt()).abs() < 1e-15);
        assert!(BoundingBox::of_points(&[]).is_none());
    }
}
