//! Artifacts of the atlas stage: `atlas.msh`, `atlas.vtu`, `atlas_uv.vtu`.
//!
//! - `atlas.msh` (MSH 4.1, binary for large atlases): point entities at the corners, curve entities
//!   for the atlas curves (feature curves and cuts, each from corner to
//!   corner), one surface entity per patch bounded by its signed curves;
//!   nodes and triangles classified on them; and, in `$Parametrizations`,
//!   each curve as a polyline and each patch's `(u, v)` triangulation with
//!   its principal curvature directions scaled by the curvatures, which is
//!   what Gmsh reads to remesh discrete surfaces (`gmsh atlas.msh -2`).
//! - `atlas.vtu`: atlas triangles (cell data `patch`, `sigma_ratio`) and the
//!   feature edges as line cells (cell data `feature_curve`; `-1` / NaN
//!   where an array does not apply to a cell kind); point data
//!   `curvature_max`, `curvature_min`, `direction_max`, `direction_min`.
//!   The real-valued arrays are Float32: they are estimates (curvatures,
//!   their directions, σ2/σ1) whose error is orders of magnitude above
//!   `f32`'s 6·10⁻⁸, and a viewer gains nothing from Float64. `atlas.msh`
//!   writes its curvature rounded to `f32` the same way (in `f64` fields),
//!   which its gzip representation compresses; positions and `(u, v)` stay
//!   exact `f64`, since the maps' injectivity depends on them.
//! - `atlas_uv.vtu`: every patch laid out in its own `(u, v)` plane as points
//!   `(u, v, 0)`, seam vertices duplicated per patch; cell data `patch`.

use super::build::Atlas;
use crate::geom::Vec3;
use crate::io::msh_output::OutputOptions;
use crate::io::msh41::discrete::{DiscreteModelBuilder, PatchUv};
use crate::io::msh41::model::f32_precision;
use crate::io::msh41::write::{Msh41Options, write_msh41};
use crate::io::vtu::{CellBlock, DataArray, VtuMesh, VtuOptions, write_vtu};
use crate::io::write_error::WriteError;
use crate::mesh::VertexId;
use std::io::Write;

/// Write `atlas.msh` with the default output options (ASCII below
/// [`crate::io::msh_output::AUTO_BINARY_MIN_ELEMENTS`] triangles, binary
/// from there on).
///
/// # Errors
/// [`WriteError`] on an I/O failure or an inconsistent atlas (never expected).
pub fn write_atlas_msh(atlas: &Atlas, w: impl Write) -> Result<(), WriteError> {
    write_atlas_msh_as(atlas, w, &OutputOptions::default())
}

/// Write `atlas.msh`: entities, classified mesh and parametrizations, as
/// MSH 4.1 (whatever `opts.msh_version` says), binary or ASCII as
/// [`OutputOptions::binary_msh41`] decides. Gmsh reads both variants with
/// their `$Parametrizations`.
///
/// # Errors
/// [`WriteError`] on an I/O failure or an inconsistent atlas (never expected).
pub fn write_atlas_msh_as(atlas: &Atlas, w: impl Write, opts: &OutputOptions) -> Result<(), WriteError> {
    let mut builder = DiscreteModelBuilder::new(&atlas.mesh);
    for &c in &atlas.corners {
        builder.add_corner(c)?;
    }
    for curve in &atlas.curves {
        builder.add_curve(curve.chain.vertices.clone())?;
    }
    let c = &atlas.curvature;
    for p in &atlas.patches {
        let boundary =
            p.curves.iter().map(|&(k, forward)| if forward { k as i32 + 1 } else { -(k as i32 + 1) }).collect();
        let curvature = p
            .vertices
            .iter()
            .map(|v| {
                let i = v.idx();
                let scaled = |d: Vec3, k: f64| {
                    let s = d * k.abs();
                    Vec3::new(f32_precision(s.x), f32_precision(s.y), f32_precision(s.z))
                };
                [scaled(c.direction_max[i], c.curvature_max[i]), scaled(c.direction_min[i], c.curvature_min[i])]
            })
            .collect();
        let uv = PatchUv { vertices: p.vertices.clone(), uv: p.uv.clone(), curvature };
        builder.add_patch(p.faces.clone(), boundary, Some(uv))?;
    }
    let model = builder.build()?;
    write_msh41(w, &model, &Msh41Options { binary: opts.binary_msh41(&model) })
}

/// Write `atlas.vtu`: triangles with patch and σ2/σ1, feature edges as lines,
/// curvature at the points.
///
/// # Errors
/// [`WriteError`] on an I/O failure.
pub fn write_atlas_vtu(atlas: &Atlas, w: impl Write) -> Result<(), WriteError> {
    let lines: Vec<[VertexId; 2]> = atlas
        .curves
        .iter()
        .filter(|c| c.is_feature)
        .flat_map(|c| c.chain.vertices.windows(2).map(|w| [w[0], w[1]]))
        .collect();
    let line_curve: Vec<i32> = atlas
        .curves
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_feature)
        .flat_map(|(k, c)| std::iter::repeat_n(k as i32, c.chain.edges.len()))
        .collect();
    let n_tri = atlas.mesh.n_faces();
    let mut sigma = vec![f64::NAN; n_tri + lines.len()];
    for p in &atlas.patches {
        for (f, s) in p.faces.iter().zip(&p.sigma_ratio) {
            sigma[f.idx()] = *s;
        }
    }
    let patch: Vec<i32> =
        atlas.patch_per_face.iter().map(|&p| p as i32).chain(std::iter::repeat_n(-1, lines.len())).collect();
    let feature_curve: Vec<i32> = std::iter::repeat_n(-1, n_tri).chain(line_curve).collect();
    let c = &atlas.curvature;
    let mesh = VtuMesh {
        points: &atlas.mesh.positions,
        cells: vec![CellBlock::Triangles(&atlas.mesh.triangles), CellBlock::Lines(&lines)],
        point_data: vec![
            DataArray::f32_rounded("curvature_max", 1, &c.curvature_max),
            DataArray::f32_rounded("curvature_min", 1, &c.curvature_min),
            DataArray::vectors_f32("direction_max", &c.direction_max),
            DataArray::vectors_f32("direction_min", &c.direction_min),
        ],
        cell_data: vec![
            DataArray::i32("patch", patch),
            DataArray::f32_rounded("sigma_ratio", 1, &sigma),
            DataArray::i32("feature_curve", feature_curve),
        ],
    };
    write_vtu(w, &mesh, &VtuOptions::default())
}

/// Write `atlas_uv.vtu`: each patch in its `(u, v)` plane, points `(u, v, 0)`.
///
/// # Errors
/// [`WriteError`] on an I/O failure.
pub fn write_atlas_uv_vtu(atlas: &Atlas, w: impl Write) -> Result<(), WriteError> {
    let mut points = Vec::new();
    let mut triangles = Vec::new();
    let mut patch = Vec::new();
    for (k, p) in atlas.patches.iter().enumerate() {
        let first = points.len() as u32;
        points.extend(p.uv.iter().map(|q| Vec3::new(q.x, q.y, 0.0)));
        triangles.extend(p.triangles.iter().map(|t| t.map(|v| VertexId(first + v))));
        patch.extend(std::iter::repeat_n(k as i32, p.triangles.len()));
    }
    let mesh = VtuMesh {
        points: &points,
        cells: vec![CellBlock::Triangles(&triangles)],
        point_data: vec![],
        cell_data: vec![DataArray::i32("patch", patch)],
    };
    write_vtu(w, &mesh, &VtuOptions::default())
}
