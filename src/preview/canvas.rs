//! A software rasterizer for one view: colour, depth and triangle-id
//! buffers, flat-shaded triangles, depth-tested thick lines, dots, an
//! outline pass and text.
//!
//! Triangles are filled by edge functions over their pixel bounding box,
//! sampling pixel centres; a pixel centre on an edge belongs to every
//! triangle that touches it, so a closed surface leaves no gap, and
//! triangles smaller than a pixel cost one bounding-box test. Faces are
//! two-sided (an open surface shows its back), shaded by
//! `ambient + diffuse·|n·forward|` (light from the eye). Overlays test their
//! depth against the surface with a bias, so a curve on the surface is not
//! hidden by the surface it lies on.

use crate::geom::Vec3;

use super::camera::View;

/// Id-buffer value of a pixel no triangle covers.
pub const NO_FACE: u32 = u32::MAX;
/// Background colour (white).
pub const BACKGROUND: [u8; 3] = [255, 255, 255];
/// Colour of the silhouette and crease outline.
const OUTLINE: [u8; 3] = [40, 40, 40];
/// Brightness of a face seen edge-on.
const AMBIENT: f64 = 0.35;

/// Colour, depth and face id of every pixel of one view.
#[derive(Debug, Clone)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// RGB per pixel, row-major.
    pub color: Vec<[u8; 3]>,
    /// Depth of the nearest triangle per pixel (`+∞` where none).
    pub depth: Vec<f32>,
    /// Id of the nearest triangle per pixel ([`NO_FACE`] where none).
    pub face: Vec<u32>,
}

/// The brightness factor of a face with normal `n` seen along `forward`.
pub fn shade(n: &Vec3, forward: &Vec3) -> f64 {
    let len = n.norm();
    let cos = if len > 0.0 { (n.dot(forward) / len).abs() } else { 0.0 };
    AMBIENT + (1.0 - AMBIENT) * cos
}

/// `color` scaled by the brightness `factor` (in `[0, 1]`).
pub fn shaded(color: [u8; 3], factor: f64) -> [u8; 3] {
    color.map(|c| (f64::from(c) * factor).round().clamp(0.0, 255.0) as u8)
}

/// `top` over `bottom` with opacity `alpha` (in `[0, 1]`).
pub fn blend(bottom: [u8; 3], top: [u8; 3], alpha: f64) -> [u8; 3] {
    let mix = |b: u8, t: u8| (f64::from(b) * (1.0 - alpha) + f64::from(t) * alpha).round() as u8;
    [mix(bottom[0], top[0]), mix(bottom[1], top[1]), mix(bottom[2], top[2])]
}

impl Canvas {
    /// A blank `width × height` canvas.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        Self { width, height, color: vec![BACKGROUND; n], depth: vec![f32::INFINITY; n], face: vec![NO_FACE; n] }
    }

    /// Fills the triangle of projected corners `p` (pixel x, y, depth) with
    /// `color` where it is nearer than what is drawn, recording `id`.
    pub fn fill_triangle(&mut self, p: [[f64; 3]; 3], color: [u8; 3], id: u32) {
        let area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
        if area == 0.0 || !area.is_finite() {
            return;
        }
        let (xmin, xmax) = (p[0][0].min(p[1][0]).min(p[2][0]), p[0][0].max(p[1][0]).max(p[2][0]));
        let (ymin, ymax) = (p[0][1].min(p[1][1]).min(p[2][1]), p[0][1].max(p[1][1]).max(p[2][1]));
        let x0 = (xmin - 0.5).ceil().max(0.0) as usize;
        let y0 = (ymin - 0.5).ceil().max(0.0) as usize;
        let x1 = ((xmax - 0.5).floor().min(self.width as f64 - 1.0)).max(-1.0) as i64;
        let y1 = ((ymax - 0.5).floor().min(self.height as f64 - 1.0)).max(-1.0) as i64;
        let inv = 1.0 / area;
        for y in y0 as i64..=y1 {
            let py = y as f64 + 0.5;
            for x in x0 as i64..=x1 {
                let px = x as f64 + 0.5;
                // Barycentric weights from the three edge functions.
                let w0 = ((p[1][0] - px) * (p[2][1] - py) - (p[2][0] - px) * (p[1][1] - py)) * inv;
                let w1 = ((p[2][0] - px) * (p[0][1] - py) - (p[0][0] - px) * (p[2][1] - py)) * inv;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < -1e-12 {
                    continue;
                }
                let z = (w0 * p[0][2] + w1 * p[1][2] + w2 * p[2][2]) as f32;
                let i = y as usize * self.width + x as usize;
                if z < self.depth[i] {
                    self.depth[i] = z;
                    self.color[i] = color;
                    self.face[i] = id;
                }
            }
        }
    }

    /// Draws the flat-shaded triangles `tris` of `positions` seen by `view`,
    /// triangle `k` in `color_of(k)`, with id `k`.
    pub fn draw_surface(
        &mut self,
        view: &View,
        positions: &[Vec3],
        tris: impl Iterator<Item = [u32; 3]>,
        mut color_of: impl FnMut(usize) -> [u8; 3],
    ) {
        let projected: Vec<[f64; 3]> = positions.iter().map(|p| view.project(p)).collect();
        for (k, t) in tris.enumerate() {
            let [a, b, c] = t.map(|v| &positions[v as usize]);
            let factor = shade(&(b - a).cross(&(c - a)), &view.forward);
            self.fill_triangle(t.map(|v| projected[v as usize]), shaded(color_of(k), factor), k as u32);
        }
    }

    /// Darkens the silhouette (a covered pixel next to an uncovered one)
    /// and depth jumps larger than `depth_jump` between neighbours.
    pub fn outline(&mut self, depth_jump: f32) {
        let (w, h) = (self.width, self.height);
        let mut edge = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if self.face[i] == NO_FACE {
                    continue;
                }
                let neighbours =
                    [(x > 0, i.wrapping_sub(1)), (x + 1 < w, i + 1), (y > 0, i.wrapping_sub(w)), (y + 1 < h, i + w)];
                edge[i] = neighbours
                    .iter()
                    .any(|&(ok, j)| ok && (self.face[j] == NO_FACE || (self.depth[j] - self.depth[i]) > depth_jump));
            }
        }
        for (c, e) in self.color.iter_mut().zip(edge) {
            if e {
                *c = OUTLINE;
            }
        }
    }

    /// Whether a point at pixel `(x, y)` and depth `z` is in front of the
    /// surface, within `bias`.
    fn visible(&self, x: f64, y: f64, z: f64, bias: f64) -> bool {
        if x < 0.0 || y < 0.0 || x >= self.width as f64 || y >= self.height as f64 {
            return false;
        }
        let i = y as usize * self.width + x as usize;
        z <= f64::from(self.depth[i]) + bias
    }

    /// The pixels whose centre is within `r` of `(x, y)`: an iterator that
    /// does not borrow the canvas, so callers may write while they walk it.
    fn disc(&self, x: f64, y: f64, r: f64) -> impl Iterator<Item = usize> + use<> {
        let w = self.width;
        let (x0, x1) = ((x - r).floor().max(0.0) as i64, (x + r).ceil().min(self.width as f64 - 1.0) as i64);
        let (y0, y1) = ((y - r).floor().max(0.0) as i64, (y + r).ceil().min(self.height as f64 - 1.0) as i64);
        (y0..=y1).flat_map(move |py| (x0..=x1).map(move |px| (px, py))).filter_map(move |(px, py)| {
            let (dx, dy) = (px as f64 + 0.5 - x, py as f64 + 0.5 - y);
            (dx * dx + dy * dy <= r * r).then_some(py as usize * w + px as usize)
        })
    }

    /// Sets the pixels of a disc of radius `r` around `(x, y)` to `color`.
    fn stamp(&mut self, x: f64, y: f64, r: f64, color: [u8; 3]) {
        for i in self.disc(x, y, r) {
            self.color[i] = color;
        }
    }

    /// The disc centres of the segment `a → b` (projected: pixel x, y,
    /// depth) `width` pixels wide that are in front of the surface within
    /// `bias` (with `bias = ∞`, all of them), and the disc radius.
    fn line_samples(&self, a: [f64; 3], b: [f64; 3], width: f64, bias: f64) -> (Vec<(f64, f64)>, f64) {
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        if !len.is_finite() {
            return (Vec::new(), 0.0);
        }
        let steps = (len * 2.0).ceil().max(1.0) as usize;
        let samples = (0..=steps)
            .map(|s| s as f64 / steps as f64)
            .map(|t| (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])))
            .filter(|&(x, y, z)| self.visible(x, y, z, bias))
            .map(|(x, y, _)| (x, y))
            .collect();
        (samples, (width / 2.0).max(0.5))
    }

    /// Calls `hit` with every pixel of the segment `a → b` (projected: pixel
    /// x, y, depth) `width` pixels wide that is in front of the surface
    /// within `bias` (with `bias = ∞`, every pixel of it). A pixel may be
    /// hit more than once.
    pub fn line_pixels(&self, a: [f64; 3], b: [f64; 3], width: f64, bias: f64, mut hit: impl FnMut(usize)) {
        let (samples, r) = self.line_samples(a, b, width, bias);
        for (x, y) in samples {
            self.disc(x, y, r).for_each(&mut hit);
        }
    }

    /// Draws the segment `a → b` in `color` ([`Canvas::line_pixels`]).
    pub fn line(&mut self, a: [f64; 3], b: [f64; 3], width: f64, color: [u8; 3], bias: f64) {
        let (samples, r) = self.line_samples(a, b, width, bias);
        for (x, y) in samples {
            self.stamp(x, y, r, color);
        }
    }

    /// Draws a dot of radius `r` with a dark rim at projected point `p`
    /// when its centre is in front of the surface within `bias`; returns
    /// whether it was drawn.
    pub fn dot(&mut self, p: [f64; 3], r: f64, color: [u8; 3], bias: f64) -> bool {
        if !self.visible(p[0], p[1], p[2], bias) {
            return false;
        }
        self.stamp(p[0], p[1], r + 1.0, OUTLINE);
        self.stamp(p[0], p[1], r, color);
        true
    }

    /// Blends `color` over pixel `i` with opacity `alpha`.
    pub fn blend_pixel(&mut self, i: usize, color: [u8; 3], alpha: f64) {
        self.color[i] = blend(self.color[i], color, alpha);
    }

    /// Writes `text` with its top-left corner at pixel `(x, y)` in the 8×8
    /// bitmap font scaled by `scale`.
    pub fn text(&mut self, x: usize, y: usize, text: &str, scale: usize, color: [u8; 3]) {
        for (k, ch) in text.chars().enumerate() {
            let glyph = font8x8::legacy::BASIC_LEGACY.get(ch as usize).copied().unwrap_or([0; 8]);
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits & (1 << col) == 0 {
                        continue;
                    }
                    for dy in 0..scale {
                        for dx in 0..scale {
                            let (px, py) = (x + (k * 8 + col) * scale + dx, y + row * scale + dy);
                            if px < self.width && py < self.height {
                                self.color[py * self.width + px] = color;
                            }
                        }
                    }
                }
            }
        }
    }

    /// A filled axis-aligned rectangle (legend swatches).
    pub fn rect(&mut self, x: usize, y: usize, w: usize, h: usize, color: [u8; 3]) {
        for py in y..(y + h).min(self.height) {
            for px in x..(x + w).min(self.width) {
                self.color[py * self.width + px] = color;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_triangles_of_a_square_cover_it_without_gap_or_overlap_count() {
        let mut c = Canvas::new(20, 20);
        let (a, b, cc, d) = ([2.0, 2.0, 1.0], [18.0, 2.0, 1.0], [18.0, 18.0, 1.0], [2.0, 18.0, 1.0]);
        c.fill_triangle([a, b, cc], [255, 0, 0], 0);
        c.fill_triangle([a, cc, d], [0, 0, 255], 1);
        let covered = c.face.iter().filter(|&&f| f != NO_FACE).count();
        assert_eq!(covered, 16 * 16, "pixel centres 2.5..17.5 in both directions");
        assert_eq!(c.face[0], NO_FACE);
    }

    #[test]
    fn the_nearer_triangle_wins_whatever_the_order_and_orientation() {
        let tri_near = [[0.0, 0.0, 1.0], [10.0, 0.0, 1.0], [0.0, 10.0, 1.0]];
        let tri_far = [[0.0, 0.0, 5.0], [0.0, 10.0, 5.0], [10.0, 0.0, 5.0]];
        for order in [[tri_near, tri_far], [tri_far, tri_near]] {
            let mut c = Canvas::new(10, 10);
            for (k, t) in order.iter().enumerate() {
                c.fill_triangle(*t, [k as u8, 0, 0], k as u32);
            }
            assert_eq!(c.depth[2 * 10 + 2], 1.0);
        }
    }

    #[test]
    fn a_hidden_line_is_not_drawn_and_a_biased_one_is() {
        let mut c = Canvas::new(10, 10);
        c.fill_triangle([[0.0, 0.0, 1.0], [20.0, 0.0, 1.0], [0.0, 20.0, 1.0]], [200, 200, 200], 0);
        c.line([1.0, 5.0, 2.0], [9.0, 5.0, 2.0], 1.0, [0, 0, 0], 0.1);
        assert_eq!(c.color[5 * 10 + 5], [200, 200, 200]);
        c.line([1.0, 5.0, 1.05], [9.0, 5.0, 1.05], 1.0, [0, 0, 0], 0.1);
        assert_eq!(c.color[5 * 10 + 5], [0, 0, 0]);
    }

    #[test]
    fn the_outline_marks_the_silhouette_only() {
        let mut c = Canvas::new(12, 12);
        c.fill_triangle([[1.0, 1.0, 1.0], [11.0, 1.0, 1.0], [11.0, 11.0, 1.0]], [200, 200, 200], 0);
        c.fill_triangle([[1.0, 1.0, 1.0], [11.0, 11.0, 1.0], [1.0, 11.0, 1.0]], [200, 200, 200], 1);
        c.outline(0.5);
        assert_eq!(c.color[12 + 5], OUTLINE, "top row of the square");
        assert_eq!(c.color[5 * 12 + 5], [200, 200, 200], "inside, across the diagonal");
    }

    #[test]
    fn shading_is_two_sided_and_brightest_facing_the_eye() {
        let f = Vec3::new(0.0, 0.0, -1.0);
        assert_eq!(shade(&Vec3::new(0.0, 0.0, 2.0), &f), 1.0);
        assert_eq!(shade(&Vec3::new(0.0, 0.0, -2.0), &f), 1.0);
        assert!((shade(&Vec3::new(1.0, 0.0, 0.0), &f) - AMBIENT).abs() < 1e-12);
    }
}
