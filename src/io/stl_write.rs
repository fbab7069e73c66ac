//! Binary STL writer.
//!
//! Layout: an 80-byte header (ours starts with `meshatlas`, never with
//! `solid`, which would make readers guess ASCII), a little-endian `u32`
//! triangle count, then per triangle 50 bytes: the unit normal and the three
//! corners as `f32` triples and a zero `u16` attribute. Coordinates are
//! rounded to `f32`, as the format demands; shared vertices are repeated per
//! triangle (readers weld them back). Degenerate triangles get a zero normal.
//! Output is buffered internally (no `BufWriter` needed).

use crate::io::text_out::CHUNK;
use crate::io::write_error::WriteError;
use crate::mesh::{FaceId, TriMesh};
use std::io::Write;

/// Write `mesh` as binary STL.
///
/// # Errors
/// [`WriteError::IndexOutOfRange`] for a triangle naming a missing vertex,
/// [`WriteError::NonFiniteCoordinate`], [`WriteError::TooLarge`] above
/// `u32::MAX` triangles (nothing written in these cases), or [`WriteError::Io`].
pub fn write_stl_binary(mut w: impl Write, mesh: &TriMesh) -> Result<(), WriteError> {
    let n = u32::try_from(mesh.n_faces()).map_err(|_| WriteError::TooLarge {
        what: "STL triangles",
        count: mesh.n_faces(),
        max: u64::from(u32::MAX),
    })?;
    check(mesh)?;
    let mut buf = Vec::with_capacity(CHUNK + 64);
    let mut header = [b' '; 80];
    let tag = b"meshatlas binary STL";
    header[..tag.len()].copy_from_slice(tag);
    buf.extend_from_slice(&header);
    buf.extend_from_slice(&n.to_le_bytes());
    for f in 0..mesh.n_faces() {
        let normal = mesh.face_normal(FaceId::new(f));
        let corners = mesh.corners(FaceId::new(f));
        for p in std::iter::once(&normal).chain(corners.iter()) {
            for c in p.iter() {
                buf.extend_from_slice(&(*c as f32).to_le_bytes());
            }
        }
        buf.extend_from_slice(&[0, 0]);
        if buf.len() >= CHUNK {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    w.write_all(&buf)?;
    w.flush()?;
    Ok(())
}

/// Indices in range and coordinates finite (also after rounding to `f32`).
fn check(mesh: &TriMesh) -> Result<(), WriteError> {
    for (i, p) in mesh.positions.iter().enumerate() {
        if !p.iter().all(|c| c.is_finite() && (*c as f32).is_finite()) {
            return Err(WriteError::NonFiniteCoordinate {
                what: format!("vertex {i} (as f32)"),
                x: p.x,
                y: p.y,
                z: p.z,
            });
        }
    }
    for (f, t) in mesh.triangles.iter().enumerate() {
        for v in t {
            if v.idx() >= mesh.n_vertices() {
                return Err(WriteError::IndexOutOfRange {
                    what: format!("triangle {f}"),
                    index: u64::from(v.0),
                    n_points: mesh.n_vertices(),
                });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{VertexId, fixtures};

    /// Decode our own output independently of the writer: header, count,
    /// then 12 floats + attribute per triangle.
    fn decode(bytes: &[u8]) -> (u32, Vec<[f32; 12]>) {
        let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap());
        let tris = bytes[84..]
            .chunks_exact(50)
            .map(|c| std::array::from_fn(|k| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap())))
            .collect();
        (n, tris)
    }

    #[test]
    fn layout_normals_and_corners() {
        let mesh = fixtures::tetrahedron();
        let mut v = Vec::new();
        write_stl_binary(&mut v, &mesh).unwrap();
        assert_eq!(v.len(), 84 + 50 * 4);
        assert!(v.starts_with(b"meshatlas"));
        let (n, tris) = decode(&v);
        assert_eq!(n, 4);
        // Face [0, 2, 1] of the unit tetrahedron lies in z = 0 with normal −z.
        assert_eq!(tris[0], [0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0]);
        let s = 1.0 / 3f32.sqrt();
        assert!((tris[3][0] - s).abs() < 1e-6 && (tris[3][2] - s).abs() < 1e-6);
    }

    #[test]
    fn rejects_broken_meshes_before_writing() {
        let mut mesh = fixtures::square(1);
        mesh.triangles[1][0] = VertexId(10);
        let mut v = Vec::new();
        assert!(matches!(write_stl_binary(&mut v, &mesh), Err(WriteError::IndexOutOfRange { index: 10, .. })));
        let mut mesh = fixtures::square(1);
        mesh.positions[0].x = 1e300;
        assert!(matches!(write_stl_binary(&mut v, &mesh), Err(WriteError::NonFiniteCoordinate { .. })));
        assert!(v.is_empty());
    }
}
