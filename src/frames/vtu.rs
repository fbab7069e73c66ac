//! The frame-field artifacts (names are part of the API):
//!
//! - `frames.vtu`: the tetrahedra of the volume with, per point, `frame_x`,
//!   `frame_y`, `frame_z` (unit 3-vectors, the frame axes), `quaternion`
//!   (4: `q0, q1, q2, q3`, axes = columns of its rotation), `sh9` (9:
//!   degree-4 harmonics `m = −4..4`), `h0`, `h1`, `h2` (2 each: real and
//!   imaginary parts of the octahedral invariants (4.23)) and `boundary`
//!   (1 on the boundary); per cell, `tet_quaternion` (4, the frame of the
//!   tet used for the singular edges).
//! - `frames_singular.vtu`: the singular edges as line cells on their own
//!   points, with cell data `valence` (3, 5, or 0 for other holonomies),
//!   `holonomy_angle` (degrees) and `axis_alignment` (|cos| between the
//!   holonomy axis and the edge).
//!
//! Written with [`crate::io::vtu`] (raw appended binary, read by ParaView
//! and meshio).

use super::field::FrameField;
use crate::geom::Vec3;
use crate::io::WriteError;
use crate::io::vtu::{CellBlock, DataArray, VtuMesh, VtuOptions, write_vtu};
use crate::mesh::VertexId;
use std::io::Write;

/// Write `frames.vtu` (module docs).
///
/// # Errors
/// [`WriteError`] on invalid data or an I/O failure.
pub fn write_frames_vtu(field: &FrameField, w: impl Write) -> Result<(), WriteError> {
    write_frames_vtu_with(field, w, &VtuOptions::default())
}

/// [`write_frames_vtu`] with explicit VTU options (encoding, header type).
///
/// # Errors
/// [`WriteError`] on invalid data or an I/O failure.
pub fn write_frames_vtu_with(field: &FrameField, w: impl Write, opts: &VtuOptions) -> Result<(), WriteError> {
    let axis = |k: usize| field.axes_per_vertex.iter().map(|a| a[k]).collect::<Vec<Vec3>>();
    let complex =
        |k: usize| -> Vec<f64> { field.invariants_per_vertex.iter().flat_map(|h| [h[k].re, h[k].im]).collect() };
    let point_data = vec![
        DataArray::vectors("frame_x", &axis(0)),
        DataArray::vectors("frame_y", &axis(1)),
        DataArray::vectors("frame_z", &axis(2)),
        DataArray::f64("quaternion", 4, field.quaternion_per_vertex.as_flattened()),
        DataArray::f64("sh9", 9, field.sh9_per_vertex.as_flattened()),
        DataArray::f64("h0", 2, complex(0)),
        DataArray::f64("h1", 2, complex(1)),
        DataArray::f64("h2", 2, complex(2)),
        DataArray::u8("boundary", field.boundary_per_vertex.iter().map(|b| *b as u8).collect::<Vec<u8>>()),
    ];
    let cell_data = vec![DataArray::f64("tet_quaternion", 4, field.quaternion_per_tet.as_flattened())];
    let mesh = VtuMesh {
        points: &field.volume.positions,
        cells: vec![CellBlock::Tetrahedra(&field.volume.tets)],
        point_data,
        cell_data,
    };
    write_vtu(w, &mesh, opts)
}

/// Write `frames_singular.vtu` (module docs).
///
/// # Errors
/// [`WriteError`] on invalid data or an I/O failure.
pub fn write_singular_edges_vtu(field: &FrameField, w: impl Write) -> Result<(), WriteError> {
    write_singular_edges_vtu_with(field, w, &VtuOptions::default())
}

/// [`write_singular_edges_vtu`] with explicit VTU options.
///
/// # Errors
/// [`WriteError`] on invalid data or an I/O failure.
pub fn write_singular_edges_vtu_with(field: &FrameField, w: impl Write, opts: &VtuOptions) -> Result<(), WriteError> {
    // Only the points of singular edges, numbered in order of first use.
    let mut local = std::collections::HashMap::new();
    let mut points = Vec::new();
    let mut lines = Vec::with_capacity(field.singular_edges.len());
    for e in &field.singular_edges {
        let ids = e.vertices.map(|v| {
            *local.entry(v).or_insert_with(|| {
                points.push(field.volume.positions[v as usize]);
                VertexId((points.len() - 1) as u32)
            })
        });
        lines.push(ids);
    }
    let cell_data = vec![
        DataArray::i32("valence", field.singular_edges.iter().map(|e| e.kind.valence_code()).collect::<Vec<i32>>()),
        DataArray::f64(
            "holonomy_angle",
            1,
            field.singular_edges.iter().map(|e| e.holonomy_angle_deg).collect::<Vec<f64>>(),
        ),
        DataArray::f64(
            "axis_alignment",
            1,
            field.singular_edges.iter().map(|e| e.axis_alignment).collect::<Vec<f64>>(),
        ),
    ];
    let mesh = VtuMesh { points: &points, cells: vec![CellBlock::Lines(&lines)], point_data: Vec::new(), cell_data };
    write_vtu(w, &mesh, opts)
}
