//! Wavefront OBJ reader: `v` and `f` statements.
//!
//! `v x y z [w | r g b]` adds a vertex (extra numbers ignored). `f` lists
//! vertex references in the forms `i`, `i/t`, `i//n`, `i/t/n`; only `i` is
//! used. Indices are 1-based; a negative index `−k` is relative and means
//! the k-th most recent vertex at that point of the file. Polygons with more
//! than three vertices are fan-triangulated (counted); faces with fewer than
//! three are skipped (counted). `l` (polylines) and `p` (points) are counted
//! as skipped elements. Texture coordinates (`vt`), normals (`vn`), groups,
//! objects, smoothing groups and materials are ignored: they do not change
//! the surface, and ignoring `vt` means a file with more `vt` than `v` (UV
//! seams) still loads with one vertex per position.
//!
//! Positive indices may refer to vertices defined later in the file; they
//! are checked once the whole file is read, and the error names the first
//! face with the largest bad index and its line.
//!
//! Hand-written rather than `tobj`: errors here carry the line, limits are
//! enforced while reading, and no per-face allocation is made.

use super::source::{MeshSink, Source, parse_f64, parse_i64, show, tokens};
use super::{Format, IoError, Limits, Location, RawMesh};
use std::io::BufRead;

/// Read an OBJ file.
///
/// # Errors
/// Malformed statements (with the line), index 0 or out of range (naming the
/// face and index), non-finite coordinates, too many triangles or vertices.
pub fn read<R: BufRead>(reader: R, limits: &Limits) -> Result<RawMesh, IoError> {
    let mut src = Source::new(reader, Format::Obj);
    let mut sink = MeshSink::new(Format::Obj, *limits);
    let mut poly: Vec<u32> = Vec::with_capacity(8);
    let mut n_faces = 0u64;
    // Largest positive index seen, with the face and line that used it first.
    let mut max_ref: Option<(u64, u64, u64)> = None;
    while src.next_line()? {
        let mut toks = tokens(src.text());
        let Some(kw) = toks.next() else { continue };
        match kw {
            b"v" => {
                let mut p = [0.0; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let t =
                        toks.next().ok_or_else(|| src.parse_error(format!("`v` needs 3 coordinates, found {k}")))?;
                    *c = parse_f64(t).ok_or_else(|| src.parse_error(format!("`{}` is not a number", show(t))))?;
                }
                let no = sink.n_vertices() as u64 + 1;
                sink.vertex(p, no, src.at_line())?;
            }
            b"f" => {
                n_faces += 1;
                poly.clear();
                let n_v = sink.n_vertices() as i64;
                for t in toks {
                    let i_tok = t.split(|&b| b == b'/').next().unwrap_or(t);
                    let i = parse_i64(i_tok).ok_or_else(|| {
                        src.parse_error(format!("face {n_faces}: `{}` is not a vertex index", show(t)))
                    })?;
                    let idx = match i {
                        0 => {
                            return Err(
                                src.parse_error(format!("face {n_faces}: index 0 is invalid (OBJ indices start at 1)"))
                            );
                        }
                        i if i > 0 => {
                            let i = i as u64;
                            if max_ref.is_none_or(|(m, _, _)| i > m) {
                                max_ref = Some((i, n_faces, src.line()));
                            }
                            i - 1
                        }
                        i => {
                            let idx = n_v + i;
                            if idx < 0 {
                                return Err(IoError::IndexOutOfRange {
                                    format: Format::Obj,
                                    element: format!("face {n_faces}"),
                                    index: i,
                                    available: format!("only {n_v} vertices are defined before it"),
                                    at: src.at_line(),
                                });
                            }
                            idx as u64
                        }
                    };
                    let idx = u32::try_from(idx).map_err(|_| IoError::IndexOutOfRange {
                        format: Format::Obj,
                        element: format!("face {n_faces}"),
                        index: i,
                        available: "indices must fit in 32 bits".into(),
                        at: src.at_line(),
                    })?;
                    poly.push(idx);
                }
                sink.polygon(&poly, src.at_line())?;
            }
            b"l" => sink.skip("line", 1),
            b"p" => sink.skip("point", 1),
            _ => {}
        }
    }
    if let Some((m, face, line)) = max_ref {
        let n_v = sink.n_vertices() as u64;
        if m > n_v {
            return Err(IoError::IndexOutOfRange {
                format: Format::Obj,
                element: format!("face {face}"),
                index: m as i64,
                available: format!("the file defines {n_v} vertices"),
                at: Location::Line(line),
            });
        }
    }
    Ok(sink.mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::failure::FailureKind;

    fn limits() -> Limits {
        Limits::from_max_triangles(100)
    }

    #[test]
    fn reads_every_face_form_and_ignores_the_rest() {
        let text = "# test\nmtllib x.mtl\no obj\nv 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 9 9\nvn 0 0 1\ng grp\nusemtl m\ns 1\nf 1 2 3\nf 1/1 3/3 4/4\nf 1//1 2//1 3//1\nf 1/1/1 2/2/1 3/3/1 4/4/1\nf -4 -3 -2\nl 1 2\np 3\n";
        let m = read(text.as_bytes(), &limits()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 1, 2], [0, 2, 3], [0, 1, 2]]);
        assert_eq!(m.n_polygons_triangulated, 1);
        assert_eq!(m.skipped["line"], 1);
        assert_eq!(m.skipped["point"], 1);
    }

    #[test]
    fn forward_references_are_checked_at_the_end() {
        let m = read("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n".as_bytes(), &limits()).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        let e = read("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\nf 1 7 3\n".as_bytes(), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::IndexOutOfRange);
        let m = e.to_string();
        assert!(
            m.contains("face 2") && m.contains("vertex 7") && m.contains("line 5") && m.contains("3 vertices"),
            "{m}"
        );
    }

    #[test]
    fn errors_name_line_and_face() {
        let e = read("v 0 0 0\nv 1 0\n".as_bytes(), &limits()).unwrap_err();
        assert!(e.to_string().contains("line 2") && e.to_string().contains("found 2"), "{e}");
        let e = read("v 0 0 0\nv 1 0 zz\n".as_bytes(), &limits()).unwrap_err();
        assert!(e.to_string().contains("`zz` is not a number"), "{e}");
        let e = read("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n".as_bytes(), &limits()).unwrap_err();
        assert!(e.to_string().contains("line 4") && e.to_string().contains("index 0"), "{e}");
        let e = read("v 0 0 0\nf -1 -2 -3\n".as_bytes(), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::IndexOutOfRange);
        assert!(e.to_string().contains("face 1") && e.to_string().contains("-2"), "{e}");
        let e = read("v 0 0 0\nf 1 a 2\n".as_bytes(), &limits()).unwrap_err();
        assert!(e.to_string().contains("face 1: `a` is not a vertex index"), "{e}");
        let e = read("v 0 0 0\nv inf 0 0\n".as_bytes(), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::NonFiniteCoordinate);
        assert!(e.to_string().contains("vertex 2") && e.to_string().contains("line 2"), "{e}");
        let e = read("v 0 0 0\nf 1 99999999999 2\n".as_bytes(), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::IndexOutOfRange);
    }

    #[test]
    fn polygon_limit_is_enforced_while_reading() {
        let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
        for _ in 0..101 {
            text.push_str("f 1 2 3\n");
        }
        let e = read(text.as_bytes(), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::TooManyTriangles);
        assert!(e.to_string().contains("line 104"), "{e}");
    }
}
