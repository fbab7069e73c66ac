//! What each preview draws: the repaired input, the atlas, the crossfield,
//! the frame field and the quad mesh, each in the two views of one
//! [`Framing`] (fitted to the repaired surface, so the five pictures of a
//! job line up).

use crate::atlas::Atlas;
use crate::crossfield::Crossfield;
use crate::frames::FrameField;
use crate::frames::singular::SingularKind;
use crate::geom::{BoundingBox, Vec3};
use crate::mesh::{EdgeId, Topology, TriMesh};
use crate::quads::{QuadMesh, QuadQuality};
use foldhash::HashMap;

use super::camera::{View, isometric_pair};
use super::canvas::{Canvas, NO_FACE, blend};
use super::palette::{
    DEFECT, INK, NEGATIVE, OTHER, POSITIVE, SURFACE, color_patches, index_color, patch_color, valence_color,
};
use super::{Image, PreviewError, PreviewSize};

/// Spacing of the crossfield's cross glyphs, pixels.
const GLYPH_CELL: usize = 26;
/// Opacity of the boundary drawn over the frames' singular edges.
const FRAMES_SURFACE_ALPHA: f64 = 0.3;
/// Colour of the quads' shading under the wireframe.
const QUAD_SURFACE: [u8; 3] = [236, 222, 180];
/// Colour of the quad wireframe (blended by [`wireframe_opacity`]).
const WIRE: [u8; 3] = [40, 40, 40];

/// The two views of a preview and the tolerances derived from the model size.
#[derive(Debug, Clone, Copy)]
pub struct Framing {
    /// View 0 (left half) and view 1 (right half).
    pub views: [View; 2],
    /// Width of one view, pixels.
    pub view_width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Depth by which an overlay may lie behind the surface and still show.
    pub bias: f64,
    /// Depth jump between neighbouring pixels drawn as an outline.
    pub outline_jump: f32,
}

impl Framing {
    /// The framing of `points` (the repaired surface) in an image of `size`.
    ///
    /// # Errors
    /// [`PreviewError::Empty`] without points, [`PreviewError::Degenerate`]
    /// when they span no box or the size is too small.
    pub fn fit(points: &[Vec3], size: PreviewSize) -> Result<Self, PreviewError> {
        let bbox = BoundingBox::of_points(points).ok_or(PreviewError::Empty)?;
        let view_width = size.width as usize / 2;
        let height = size.height as usize;
        let views = isometric_pair(points, view_width, height)?;
        let diagonal = bbox.diagonal();
        Ok(Self { views, view_width, height, bias: 0.01 * diagonal, outline_jump: (0.04 * diagonal) as f32 })
    }

    /// Draws both views with `draw` (in parallel) and places them side by side.
    fn render(&self, draw: impl Fn(&mut Canvas, &View) + Sync) -> Canvas {
        let one = |v: &View| {
            let mut c = Canvas::new(self.view_width, self.height);
            draw(&mut c, v);
            c
        };
        let (a, b) = rayon::join(|| one(&self.views[0]), || one(&self.views[1]));
        let mut out = Canvas::new(2 * self.view_width, self.height);
        for y in 0..self.height {
            let row = y * out.width;
            out.color[row..row + self.view_width].copy_from_slice(&a.color[y * a.width..(y + 1) * a.width]);
            out.color[row + self.view_width..row + out.width].copy_from_slice(&b.color[y * b.width..(y + 1) * b.width]);
        }
        out
    }
}

/// Checks that `mesh` has a triangle with area to draw.
fn require_triangles(positions: &[Vec3], tris: impl Iterator<Item = [u32; 3]>) -> Result<(), PreviewError> {
    let mut any = false;
    for t in tris {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        if (b - a).cross(&(c - a)).norm() > 0.0 {
            return Ok(());
        }
        any = true;
    }
    Err(if any {
        PreviewError::Degenerate { reason: "every triangle has zero area".into() }
    } else {
        PreviewError::Empty
    })
}

/// The triangles of `mesh` as `u32` triples.
fn triangles(mesh: &TriMesh) -> impl Iterator<Item = [u32; 3]> + '_ {
    mesh.triangles.iter().map(|t| t.map(|v| v.0))
}

/// Draws a legend (swatch and label per entry) in the bottom-left corner.
fn legend(canvas: &mut Canvas, entries: &[([u8; 3], &str)]) {
    let scale = if canvas.height >= 600 { 2 } else { 1 };
    let line = 12 * scale;
    let x = 10 * scale;
    let mut y = canvas.height.saturating_sub(8 * scale + line * entries.len());
    for (color, label) in entries {
        canvas.rect(x - 1, y - 1, 8 * scale + 2, 8 * scale + 2, INK);
        canvas.rect(x, y, 8 * scale, 8 * scale, *color);
        canvas.text(x + 12 * scale, y, label, scale, INK);
        y += line;
    }
}

/// The boundary and non-manifold edges of `surface` (those `preview.png`
/// draws in red), by its edge topology.
pub fn defect_edges(surface: &TriMesh) -> Vec<[u32; 2]> {
    let topo = Topology::new(surface);
    (0..topo.n_edges())
        .filter(|&e| {
            let e = EdgeId::new(e);
            topo.is_boundary_edge(e) || topo.is_nonmanifold_edge(e)
        })
        .map(|e| topo.edges[e].map(|v| v.0))
        .collect()
}

/// `preview.png`: the repaired surface, shaded, with `defects` (its
/// boundary and non-manifold edges, [`defect_edges`]) in red, so a user sees
/// what repair reported.
///
/// # Errors
/// [`PreviewError`] for a mesh with nothing to draw.
pub fn input_preview(surface: &TriMesh, defects: &[[u32; 2]], size: PreviewSize) -> Result<Image, PreviewError> {
    require_triangles(&surface.positions, triangles(surface))?;
    let framing = Framing::fit(&surface.positions, size)?;
    let mut canvas = framing.render(|c, view| {
        c.draw_surface(view, &surface.positions, triangles(surface), |_| SURFACE);
        c.outline(framing.outline_jump);
        for &[a, b] in defects {
            let (pa, pb) = (view.project(&surface.positions[a as usize]), view.project(&surface.positions[b as usize]));
            c.line(pa, pb, 3.0, DEFECT, framing.bias);
        }
    });
    if !defects.is_empty() {
        legend(&mut canvas, &[(DEFECT, "boundary / non-manifold edge")]);
    }
    Ok(Image::of(&canvas))
}

/// The patch adjacency of an atlas: patches sharing an edge of its mesh.
/// Patches meet only along curves, so only triangle edges joining two
/// curve vertices are looked at (a hash of `O(curve length)` entries, not
/// of every edge).
fn patch_neighbours(atlas: &Atlas) -> Vec<Vec<u32>> {
    let mesh = &atlas.mesh;
    let mut on_curve = vec![false; mesh.n_vertices()];
    for v in atlas.curves.iter().flat_map(|c| &c.chain.vertices) {
        on_curve[v.idx()] = true;
    }
    let mut sides: HashMap<[u32; 2], Vec<u32>> = HashMap::default();
    for (f, t) in mesh.triangles.iter().enumerate() {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            if on_curve[a.idx()] && on_curve[b.idx()] {
                sides.entry([a.0.min(b.0), a.0.max(b.0)]).or_default().push(atlas.patch_per_face[f]);
            }
        }
    }
    let mut out = vec![Vec::new(); atlas.patches.len()];
    for patches in sides.values() {
        for (i, &p) in patches.iter().enumerate() {
            for &q in &patches[i + 1..] {
                if p != q {
                    out[p as usize].push(q);
                    out[q as usize].push(p);
                }
            }
        }
    }
    for list in &mut out {
        list.sort_unstable();
        list.dedup();
    }
    out
}

/// The colour of each patch of `atlas` in `atlas.png` (neighbours differ).
pub fn atlas_patch_colors(atlas: &Atlas) -> Vec<[u8; 3]> {
    color_patches(&patch_neighbours(atlas)).into_iter().map(patch_color).collect()
}

/// `atlas.png`: patches in `colors` (one per patch,
/// [`atlas_patch_colors`]), the curves in black (cuts thinner than feature
/// curves), corners as dots.
///
/// # Errors
/// [`PreviewError`] for an atlas with nothing to draw.
pub fn atlas_preview(atlas: &Atlas, colors: &[[u8; 3]], size: PreviewSize) -> Result<Image, PreviewError> {
    let mesh = &atlas.mesh;
    require_triangles(&mesh.positions, triangles(mesh))?;
    let framing = Framing::fit(&mesh.positions, size)?;
    let canvas = framing.render(|c, view| {
        c.draw_surface(view, &mesh.positions, triangles(mesh), |f| colors[atlas.patch_per_face[f] as usize]);
        c.outline(framing.outline_jump);
        for curve in &atlas.curves {
            let width = if curve.is_feature { 2.5 } else { 1.5 };
            for pair in curve.chain.vertices.windows(2) {
                let [a, b] = [pair[0], pair[1]].map(|v| view.project(&mesh.positions[v.idx()]));
                c.line(a, b, width, INK, framing.bias);
            }
        }
        for v in &atlas.corners {
            c.dot(view.project(&mesh.positions[v.idx()]), 3.5, INK, framing.bias);
        }
    });
    Ok(Image::of(&canvas))
}

/// `crossfield.png`: the surface with a cross glyph on one face per
/// [`GLYPH_CELL`]-pixel cell (the face seen at the cell centre), and the
/// singularities as large dots coloured by index, with a legend.
///
/// # Errors
/// [`PreviewError`] for a surface with nothing to draw.
pub fn crossfield_preview(surface: &TriMesh, field: &Crossfield, size: PreviewSize) -> Result<Image, PreviewError> {
    require_triangles(&surface.positions, triangles(surface))?;
    let framing = Framing::fit(&surface.positions, size)?;
    let mut canvas = framing.render(|c, view| {
        c.draw_surface(view, &surface.positions, triangles(surface), |_| SURFACE);
        c.outline(framing.outline_jump);
        draw_crosses(c, view, surface, field, framing.bias);
        for s in &field.singularities {
            c.dot(view.project(&s.position), 6.0, index_color(s.index, field.symmetry), 2.0 * framing.bias);
        }
    });
    let symmetry = field.symmetry.max(1);
    let (plus, minus) = (format!("index +1/{symmetry}"), format!("index -1/{symmetry}"));
    legend(&mut canvas, &[(POSITIVE, &plus), (NEGATIVE, &minus), (OTHER, "other index")]);
    Ok(Image::of(&canvas))
}

/// The cross glyphs of [`crossfield_preview`] on canvas `c`: at each cell
/// centre the face drawn there gets its field's `N` branches (`u` and
/// `n × u` for a cross, three lines for an asterisk).
fn draw_crosses(c: &mut Canvas, view: &View, surface: &TriMesh, field: &Crossfield, bias: f64) {
    let half = 0.36 * GLYPH_CELL as f64 / view.scale;
    let glyph = [70, 70, 95];
    for cy in (GLYPH_CELL / 2..c.height).step_by(GLYPH_CELL) {
        for cx in (GLYPH_CELL / 2..c.width).step_by(GLYPH_CELL) {
            let f = c.face[cy * c.width + cx];
            if f == NO_FACE {
                continue;
            }
            let t = surface.triangles[f as usize].map(|v| surface.positions[v.idx()]);
            let centroid = (t[0] + t[1] + t[2]) / 3.0;
            let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
            let (Some(u), Some(n)) = (field.cross_per_face.get(f as usize), n.try_normalize(0.0)) else { continue };
            // The N-fold glyph: N/2 lines through the centroid, 2π/N apart.
            let v = n.cross(u);
            let lines = (field.symmetry / 2).max(1);
            for k in 0..lines {
                let angle = std::f64::consts::TAU * f64::from(k) / f64::from(field.symmetry.max(1));
                let arm = u * angle.cos() + v * angle.sin();
                let (a, b) = (view.project(&(centroid - arm * half)), view.project(&(centroid + arm * half)));
                c.line(a, b, 1.5, glyph, bias);
            }
        }
    }
}

/// `frames.png`: the singular edges of the frame field as thick lines
/// coloured by valence, seen through the boundary drawn in translucent
/// grey.
///
/// # Errors
/// [`PreviewError`] for a surface with nothing to draw.
pub fn frames_preview(surface: &TriMesh, field: &FrameField, size: PreviewSize) -> Result<Image, PreviewError> {
    require_triangles(&surface.positions, triangles(surface))?;
    let framing = Framing::fit(&surface.positions, size)?;
    let positions = &field.volume.positions;
    let mut canvas = framing.render(|c, view| {
        let mut lines = Canvas::new(c.width, c.height);
        for e in &field.singular_edges {
            let valence = match e.kind {
                SingularKind::Valence3 => 3,
                SingularKind::Valence5 => 5,
                SingularKind::Complex => 0,
            };
            let [a, b] = e.vertices.map(|v| view.project(&positions[v as usize]));
            lines.line(a, b, 3.5, valence_color(valence), f64::INFINITY);
        }
        c.draw_surface(view, &surface.positions, triangles(surface), |_| [150, 150, 155]);
        c.outline(framing.outline_jump);
        for i in 0..c.color.len() {
            c.color[i] = if c.face[i] == NO_FACE {
                lines.color[i]
            } else {
                blend(lines.color[i], c.color[i], FRAMES_SURFACE_ALPHA)
            };
        }
    });
    legend(&mut canvas, &[(POSITIVE, "valence 3"), (NEGATIVE, "valence 5"), (OTHER, "other")]);
    Ok(Image::of(&canvas))
}

/// Opacity of the quad wireframe: full for quads many pixels wide, down
/// to a faint texture where the mean edge is a pixel or two long (an
/// opaque wireframe would paint the whole surface dark).
fn wireframe_opacity(positions: &[Vec3], edges: &[[u32; 2]], scale: f64) -> f64 {
    if edges.is_empty() {
        return 1.0;
    }
    let total: f64 = edges.iter().map(|&[a, b]| (positions[a as usize] - positions[b as usize]).norm()).sum();
    let mean_px = scale * total / edges.len() as f64;
    (mean_px / 10.0).clamp(0.15, 0.9)
}

/// `quads.png`: the quads shaded, their edges as a wireframe, irregular
/// vertices as dots coloured by valence, framed like the surface
/// `reference` they were built on.
///
/// # Errors
/// [`PreviewError`] for a quad mesh with nothing to draw.
pub fn quads_preview(
    reference: &TriMesh,
    mesh: &QuadMesh,
    quality: &QuadQuality,
    size: PreviewSize,
) -> Result<Image, PreviewError> {
    let positions = &mesh.vertices.positions;
    let split = || mesh.quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
    require_triangles(positions, split())?;
    let framing = Framing::fit(&reference.positions, size)?;
    let mut edges: Vec<[u32; 2]> = mesh
        .quads
        .iter()
        .flat_map(|q| (0..4).map(move |i| [q[i].min(q[(i + 1) % 4]), q[i].max(q[(i + 1) % 4])]))
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let irregular = quality.irregular_vertices();
    let alpha = wireframe_opacity(positions, &edges, framing.views[0].scale);
    let mut canvas = framing.render(|c, view| {
        c.draw_surface(view, positions, split(), |_| QUAD_SURFACE);
        c.outline(framing.outline_jump);
        let mut wire = vec![false; c.color.len()];
        for &[a, b] in &edges {
            let (pa, pb) = (view.project(&positions[a as usize]), view.project(&positions[b as usize]));
            c.line_pixels(pa, pb, 1.0, framing.bias, |i| wire[i] = true);
        }
        for (i, _) in wire.iter().enumerate().filter(|(_, w)| **w) {
            c.blend_pixel(i, WIRE, alpha);
        }
        for &v in &irregular {
            let color = valence_color(quality.valence[v as usize]);
            c.dot(view.project(&positions[v as usize]), 4.0, color, framing.bias);
        }
    });
    legend(&mut canvas, &[(POSITIVE, "valence 3"), (NEGATIVE, "valence 5"), (OTHER, "other irregular")]);
    Ok(Image::of(&canvas))
}
