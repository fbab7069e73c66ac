//! Artifacts of the crossfield stage.
//!
//! `singularities.json`:
//! `{"symmetry": 4, "euler_characteristic": χ, "index_sum": s,
//!   "singularities": [{"position": [x, y, z], "index": 0.25, "vertex": id}, ...]}`
//! with indices as fractions of a full turn (±1/4 crosses, ±1/6 asterisks).
//!
//! `crossfield.vtu`: the triangles with cell data `cross_u`, `cross_v`
//! (unit 3D vectors, `v = n × u`, `n` the triangle normal) and `norm`
//! (`|f|` at the centroid), point data `index` (fraction of a turn, 0 where
//! regular). All four are Float32 (a unit direction needs no more than
//! `f32`'s 6·10⁻⁸, and the indices k/4 are exact); `crossfield.msh` writes
//! the same values rounded to `f32` in MSH's `f64` fields
//! ([`f32_precision`]), which its gzip representation compresses.
//!
//! `crossfield.msh`: MSH 4.1, one discrete surface with every vertex and
//! triangle (tags `i + 1`), and three `$ElementData` views: `cross_u` and
//! `cross_v` (3 components) and `norm` (1 component).

use super::Crossfield;
use crate::geom::Vec3;
use crate::io::WriteError;
use crate::io::msh_output::{OutputOptions, write_msh};
use crate::io::msh41::model::{DataView, MshModel, f32_precision};
use crate::io::vtu::{DataArray, VtuMesh, VtuOptions, write_vtu};
use crate::mesh::{FaceId, TriMesh};
use serde::Serialize;
use std::io::Write;

#[derive(Serialize)]
struct SingularityJson {
    position: [f64; 3],
    index: f64,
    vertex: u32,
}

#[derive(Serialize)]
struct SingularitiesJson {
    symmetry: u32,
    euler_characteristic: i64,
    index_sum: f64,
    singularities: Vec<SingularityJson>,
}

/// Write `singularities.json` for `field` to `w`.
///
/// # Errors
/// I/O errors of `w`.
pub fn write_singularities_json(field: &Crossfield, w: impl Write) -> std::io::Result<()> {
    let doc = SingularitiesJson {
        symmetry: field.symmetry,
        euler_characteristic: field.euler_characteristic,
        index_sum: field.index_sum,
        singularities: field
            .singularities
            .iter()
            .map(|s| SingularityJson {
                position: [s.position.x, s.position.y, s.position.z],
                index: s.index,
                vertex: s.vertex.0,
            })
            .collect(),
    };
    serde_json::to_writer_pretty(w, &doc).map_err(std::io::Error::other)
}

/// Per triangle `v = n × u` (the second branch of the cross).
fn cross_v(field: &Crossfield, mesh: &TriMesh) -> Vec<Vec3> {
    field.cross_per_face.iter().enumerate().map(|(f, u)| mesh.face_normal(FaceId::new(f)).cross(u)).collect()
}

/// Check that `field` was computed on `mesh`.
fn check_sizes(field: &Crossfield, mesh: &TriMesh) -> Result<(), WriteError> {
    if field.cross_per_face.len() != mesh.n_faces() || field.index_per_vertex.len() != mesh.n_vertices() {
        return Err(WriteError::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "crossfield of {} triangles / {} vertices written with a mesh of {} / {}",
                field.cross_per_face.len(),
                field.index_per_vertex.len(),
                mesh.n_faces(),
                mesh.n_vertices()
            ),
        )));
    }
    Ok(())
}

/// Write `crossfield.vtu` (raw appended binary) for `field` on `mesh`.
///
/// # Errors
/// [`WriteError`] when the sizes do not match or on I/O failure.
pub fn write_crossfield_vtu(field: &Crossfield, mesh: &TriMesh, w: impl Write) -> Result<(), WriteError> {
    check_sizes(field, mesh)?;
    let n = f64::from(field.symmetry);
    let mut vtu = VtuMesh::from_surface(mesh);
    vtu.cell_data = vec![
        DataArray::vectors_f32("cross_u", &field.cross_per_face),
        DataArray::vectors_f32("cross_v", &cross_v(field, mesh)),
        DataArray::f32_rounded("norm", 1, &field.norm_per_face),
    ];
    let index: Vec<f64> = field.index_per_vertex.iter().map(|&k| f64::from(k) / n).collect();
    vtu.point_data = vec![DataArray::f32_rounded("index", 1, &index)];
    write_vtu(w, &vtu, &VtuOptions::default())
}

/// Write `crossfield.msh` with the default output options (MSH 4.1, ASCII
/// below [`crate::io::msh_output::AUTO_BINARY_MIN_ELEMENTS`] triangles,
/// binary from there on) for `field` on `mesh`.
///
/// # Errors
/// [`WriteError`] when the sizes do not match or on I/O failure.
pub fn write_crossfield_msh(field: &Crossfield, mesh: &TriMesh, w: impl Write) -> Result<(), WriteError> {
    write_crossfield_msh_as(field, mesh, w, &OutputOptions::default())
}

/// Write `crossfield.msh` in the MSH variant `opts` selects (4.1 ASCII or
/// binary, or 2.2).
///
/// # Errors
/// [`WriteError`] when the sizes do not match or on I/O failure.
pub fn write_crossfield_msh_as(
    field: &Crossfield,
    mesh: &TriMesh,
    w: impl Write,
    opts: &OutputOptions,
) -> Result<(), WriteError> {
    check_sizes(field, mesh)?;
    let mut model = MshModel::from_surface(mesh);
    let flat = |v: &[Vec3]| v.iter().flat_map(|x| [x.x, x.y, x.z].map(f32_precision)).collect::<Vec<f64>>();
    model.element_data = vec![
        DataView::contiguous("cross_u", 3, flat(&field.cross_per_face), 1),
        DataView::contiguous("cross_v", 3, flat(&cross_v(field, mesh)), 1),
        DataView::contiguous("norm", 1, field.norm_per_face.iter().map(|&x| f32_precision(x)).collect(), 1),
    ];
    write_msh(w, &model, opts)
}
