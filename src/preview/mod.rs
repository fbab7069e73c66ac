//! Preview images of every stage, rendered headless: `preview.png` of the
//! repaired input, `atlas.png`, `crossfield.png`, `frames.png` and
//! `quads.png` ([`scenes`]).
//!
//! Each image shows two opposite isometric views side by side
//! ([`camera`]), fitted to the bounding box of the repaired surface, drawn
//! by a software z-buffer rasterizer ([`canvas`]) with flat shading and an
//! outline, and encoded as PNG. A rasterizer of our own rather than a 2D
//! vector library: hidden surfaces need a depth buffer, and triangles
//! smaller than a pixel (a million-triangle input on a 600-pixel view)
//! cost one bounding-box test each, so every input is drawn whole instead
//! of from a decimated copy.

pub mod camera;
pub mod canvas;
pub mod palette;
pub mod scenes;

use std::io::Write;

pub use scenes::{
    Framing, atlas_patch_colors, atlas_preview, crossfield_preview, defect_edges, frames_preview, input_preview,
    quads_preview,
};
use serde::{Deserialize, Serialize};

use self::canvas::Canvas;

/// Why a preview was not drawn. A failed preview is reported in the job
/// summary and never fails the job.
#[derive(Debug, thiserror::Error)]
pub enum PreviewError {
    /// The mesh has no triangles.
    #[error("nothing to draw: the mesh has no triangles")]
    Empty,
    /// The mesh has no extent to fit a view to.
    #[error("nothing to draw: {reason}")]
    Degenerate {
        /// What is degenerate.
        reason: String,
    },
    /// The PNG could not be encoded or written (the encoder's or the
    /// file's error).
    #[error("cannot write the PNG: {0}")]
    Encode(String),
}

/// Size of a preview image in pixels (`output.preview_size`), two views
/// side by side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "[u32; 2]", into = "[u32; 2]")]
pub struct PreviewSize {
    /// Width of the whole image (both views).
    pub width: u32,
    /// Height.
    pub height: u32,
}

impl PreviewSize {
    /// Smallest accepted width and height.
    pub const MIN: u32 = 64;
    /// Largest accepted width and height.
    pub const MAX: u32 = 4096;
}

impl Default for PreviewSize {
    fn default() -> Self {
        Self { width: 1200, height: 900 }
    }
}

impl TryFrom<[u32; 2]> for PreviewSize {
    type Error = String;

    fn try_from([width, height]: [u32; 2]) -> Result<Self, String> {
        let ok = |n: u32| (Self::MIN..=Self::MAX).contains(&n);
        if ok(width) && ok(height) {
            Ok(Self { width, height })
        } else {
            Err(format!(
                "preview_size [{width}, {height}]: width and height must each be {} to {} pixels",
                Self::MIN,
                Self::MAX
            ))
        }
    }
}

impl From<PreviewSize> for [u32; 2] {
    fn from(s: PreviewSize) -> Self {
        [s.width, s.height]
    }
}

/// An RGB image, row-major, 8 bits per channel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `3 · width · height` bytes.
    pub rgb: Vec<u8>,
}

impl Image {
    /// The colours of `canvas`.
    fn of(canvas: &Canvas) -> Self {
        Self { width: canvas.width, height: canvas.height, rgb: canvas.color.iter().flatten().copied().collect() }
    }

    /// The colour of pixel `(x, y)`.
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * self.width + x);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Writes the image as an 8-bit RGB PNG (fast deflate with adaptive
    /// row filters: flat shading compresses to a few hundred KiB).
    ///
    /// # Errors
    /// [`PreviewError::Encode`] with the writer's or encoder's error.
    pub fn write_png(&self, w: impl Write) -> Result<(), PreviewError> {
        let err = |e: png::EncodingError| PreviewError::Encode(e.to_string());
        let mut enc = png::Encoder::new(w, self.width as u32, self.height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        let mut writer = enc.write_header().map_err(err)?;
        writer.write_image_data(&self.rgb).map_err(err)?;
        writer.finish().map_err(err)
    }
}
