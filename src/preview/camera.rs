//! The two cameras of a preview: opposite isometric views, fitted to the
//! model, so that every side of a closed part is seen once.
//!
//! View 0 looks from the `(+1, +1, +1)` octant toward the box centre, view 1
//! from `(−1, −1, −1)`; both keep `+z` pointing up on the screen (the up
//! vector is `z` minus its component along the view direction). The
//! projection is orthographic: a point maps to pixel
//! `(cx + s·(d·right), cy − s·(d·up))` with `d = p − centre`, and its depth
//! is `d·forward` (larger is farther). One scale `s` serves both views,
//! chosen so that the projected points fit inside a margin in either.

use crate::geom::{BoundingBox, Vec3};

use super::PreviewError;

/// Fraction of the smaller side of a view left free around the fitted box.
const MARGIN_FRACTION: f64 = 0.06;

/// An orthographic camera: screen axes, centre, scale and pixel offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Unit screen-right direction in model space.
    pub right: Vec3,
    /// Unit screen-up direction in model space.
    pub up: Vec3,
    /// Unit view direction (from the eye into the scene).
    pub forward: Vec3,
    /// Model point drawn at the pixel centre `(cx, cy)`.
    pub center: Vec3,
    /// Pixels per model unit.
    pub scale: f64,
    /// Pixel column of `center`.
    pub cx: f64,
    /// Pixel row of `center`.
    pub cy: f64,
}

impl View {
    /// The camera looking along `forward` with `+z` up (or `+y` when
    /// looking along `z`), not yet fitted (`scale` 1, centre at the origin).
    fn looking(forward: Vec3) -> Self {
        let forward = forward.normalize();
        let z = Vec3::z();
        let up_raw = z - forward * z.dot(&forward);
        let up = if up_raw.norm() > 1e-9 { up_raw.normalize() } else { Vec3::y() };
        let right = up.cross(&(-forward));
        Self { right, up, forward, center: Vec3::zeros(), scale: 1.0, cx: 0.0, cy: 0.0 }
    }

    /// Pixel coordinates `(x, y)` and depth of model point `p`.
    #[inline]
    pub fn project(&self, p: &Vec3) -> [f64; 3] {
        let d = p - self.center;
        [self.cx + self.scale * d.dot(&self.right), self.cy - self.scale * d.dot(&self.up), d.dot(&self.forward)]
    }

    /// The pixel `(column, row)` holding model point `p`, if it falls inside
    /// a `width × height` view.
    pub fn pixel_of(&self, p: &Vec3, width: usize, height: usize) -> Option<(usize, usize)> {
        let [x, y, _] = self.project(p);
        let inside = x >= 0.0 && y >= 0.0 && x < width as f64 && y < height as f64;
        inside.then_some((x as usize, y as usize))
    }
}

/// The two opposite isometric views of `points`, each `width × height`
/// pixels, sharing one scale: the largest at which the points' projection
/// fits inside the margin in both views, each view centred on its own
/// projection.
///
/// # Errors
/// [`PreviewError::Empty`] without points; [`PreviewError::Degenerate`]
/// when their bounding box has no extent or is not finite (nothing could be
/// fitted), or when a view has under 16 pixels a side.
pub fn isometric_pair(points: &[Vec3], width: usize, height: usize) -> Result<[View; 2], PreviewError> {
    let bbox = BoundingBox::of_points(points).ok_or(PreviewError::Empty)?;
    let diagonal = bbox.diagonal();
    if !diagonal.is_finite() || diagonal <= f64::MIN_POSITIVE {
        return Err(PreviewError::Degenerate {
            reason: format!("the bounding box has no extent (diagonal {diagonal})"),
        });
    }
    if width < 16 || height < 16 {
        return Err(PreviewError::Degenerate { reason: format!("a {width}×{height} view is too small to draw") });
    }
    let center = bbox.center();
    let views = [View::looking(Vec3::new(-1.0, -1.0, -1.0)), View::looking(Vec3::new(1.0, 1.0, 1.0))];
    // Extent of the projection along each screen axis, relative to the centre.
    let extent = |axis: &Vec3| {
        points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            let t = (p - center).dot(axis);
            (lo.min(t), hi.max(t))
        })
    };
    let extents: Vec<[(f64, f64); 2]> = views.iter().map(|v| [extent(&v.right), extent(&v.up)]).collect();
    let margin = MARGIN_FRACTION * width.min(height) as f64;
    let mut scale = f64::INFINITY;
    for [(x0, x1), (y0, y1)] in &extents {
        if x1 > x0 {
            scale = scale.min((width as f64 - 2.0 * margin) / (x1 - x0));
        }
        if y1 > y0 {
            scale = scale.min((height as f64 - 2.0 * margin) / (y1 - y0));
        }
    }
    if !scale.is_finite() || scale <= 0.0 {
        return Err(PreviewError::Degenerate { reason: "the points project to a single pixel".into() });
    }
    let mut out = views;
    for (v, [(x0, x1), (y0, y1)]) in out.iter_mut().zip(&extents) {
        *v = View {
            center,
            scale,
            cx: width as f64 / 2.0 - scale * (x0 + x1) / 2.0,
            cy: height as f64 / 2.0 + scale * (y0 + y1) / 2.0,
            ..*v
        };
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn box_corners(min: Vec3, max: Vec3) -> Vec<Vec3> {
        (0..8)
            .map(|k| {
                let pick = |bit: usize, i: usize| if k & bit == 0 { min[i] } else { max[i] };
                Vec3::new(pick(1, 0), pick(2, 1), pick(4, 2))
            })
            .collect()
    }

    fn unit_box() -> Vec<Vec3> {
        box_corners(Vec3::zeros(), Vec3::new(1.0, 1.0, 1.0))
    }

    #[test]
    fn views_are_opposite_orthonormal_and_keep_z_up() {
        let [a, b] = isometric_pair(&unit_box(), 600, 900).unwrap();
        assert!((a.forward + b.forward).norm() < 1e-12);
        for v in [a, b] {
            assert!(v.right.dot(&v.up).abs() < 1e-12 && v.right.dot(&v.forward).abs() < 1e-12);
            assert!(v.up.z > 0.0, "+z points up on the screen");
            // Right-handed screen: right × up points back at the eye.
            assert!((v.right.cross(&v.up) + v.forward).norm() < 1e-12);
        }
    }

    #[test]
    fn the_points_fill_the_view_inside_the_margin() {
        let corners = box_corners(Vec3::new(-2.0, 0.0, 1.0), Vec3::new(3.0, 0.5, 4.0));
        let views = isometric_pair(&corners, 600, 900).unwrap();
        for v in views {
            let px: Vec<[f64; 3]> = corners.iter().map(|p| v.project(p)).collect();
            let (x0, x1) = px.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[0]), b.max(p[0])));
            let (y0, y1) = px.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[1]), b.max(p[1])));
            // Centred, inside the 36-pixel margin, touching it on one axis.
            assert!(((x0 + x1) / 2.0 - 300.0).abs() < 1e-9 && ((y0 + y1) / 2.0 - 450.0).abs() < 1e-9);
            assert!(x0 >= 36.0 - 1e-9 && x1 <= 564.0 + 1e-9 && y0 >= 36.0 - 1e-9 && y1 <= 864.0 + 1e-9);
        }
        let touches = |v: &View| {
            let xs: Vec<f64> = corners.iter().map(|p| v.project(p)[0]).collect();
            let ys: Vec<f64> = corners.iter().map(|p| v.project(p)[1]).collect();
            let min = |a: &[f64]| a.iter().copied().fold(f64::MAX, f64::min);
            (min(&xs) - 36.0).abs() < 1e-6 || (min(&ys) - 36.0).abs() < 1e-6
        };
        assert!(views.iter().any(touches));
    }

    #[test]
    fn no_points_a_point_or_a_tiny_view_is_refused() {
        assert!(matches!(isometric_pair(&[], 600, 900), Err(PreviewError::Empty)));
        let point = vec![Vec3::new(1.0, 1.0, 1.0); 3];
        assert!(matches!(isometric_pair(&point, 600, 900), Err(PreviewError::Degenerate { .. })));
        let nan = vec![Vec3::zeros(), Vec3::new(f64::NAN, 1.0, 1.0)];
        assert!(matches!(isometric_pair(&nan, 600, 900), Err(PreviewError::Degenerate { .. })));
        assert!(matches!(isometric_pair(&unit_box(), 8, 900), Err(PreviewError::Degenerate { .. })));
    }
}
