//! Stanford PLY reader: `ascii`, `binary_little_endian`, `binary_big_endian`.
//!
//! The header declares elements in file order, each with a count and
//! properties: scalars (`char/int8`, `uchar/uint8`, `short/int16`,
//! `ushort/uint16`, `int/int32`, `uint/uint32`, `float/float32`,
//! `double/float64`) or lists (`property list <count type> <item type> name`).
//! We keep the `x`, `y`, `z` scalars of the `vertex` element (any numeric
//! type) and the `vertex_indices` (or `vertex_index`) list of the `face`
//! element (integer count and item types). Every other property is read past,
//! lists included; every other element is read past and counted as skipped
//! under its name. Faces are fan-triangulated (counted); indices are
//! 0-based and checked once the whole file is read (elements may come in any
//! order), the error naming the first face with the largest bad index.
//!
//! Binary elements made only of scalars are decoded record by record from
//! one buffer; skipped all-scalar elements are skipped in one step.
//!
//! Hand-written rather than `ply-rs`: one pass with no per-element
//! allocation, errors with line or byte offset, limits enforced while
//! reading, and ASCII tokens may span lines as the format allows.

use super::source::{Endian, MeshSink, Source, capacity_hint, parse_f64, parse_i64, parse_u64, show, tokens};
use super::{Format, IoError, Limits, Location, RawMesh};
use std::io::BufRead;

/// Scalar types of PLY properties.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// Parse a type name (both the classic and the sized spellings).
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Size in bytes in binary encodings.
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decode from the first `size()` bytes of `b` (integers exactly as `f64`).
    #[inline]
    fn decode(self, b: &[u8], e: Endian) -> f64 {
        match self {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => f64::from(e.i16([b[0], b[1]])),
            Scalar::U16 => f64::from(e.u16([b[0], b[1]])),
            Scalar::I32 => f64::from(e.i32([b[0], b[1], b[2], b[3]])),
            Scalar::U32 => f64::from(e.u32([b[0], b[1], b[2], b[3]])),
            Scalar::F32 => f64::from(e.f32([b[0], b[1], b[2], b[3]])),
            Scalar::F64 => e.f64([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    }

    /// Parse an ASCII token of this type.
    fn parse(self, tok: &[u8]) -> Option<f64> {
        if self.is_float() {
            parse_f64(tok)
        } else if matches!(self, Scalar::U32) {
            parse_u64(tok).map(|v| v as f64)
        } else {
            parse_i64(tok).map(|v| v as f64)
        }
    }
}

/// A property: a scalar, or a list with its count and item types.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Property {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

/// What we do with an element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    /// `vertex`: property indices of x, y, z.
    Vertex([usize; 3]),
    /// `face`: property index of the vertex index list.
    Face(usize),
    /// Anything else: read past and count.
    Skip,
}

/// An element declaration.
#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: u64,
    props: Vec<(String, Property)>,
    header_line: u64,
}

/// Encoding of the body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary(Endian),
}

/// Read a PLY file.
///
/// # Errors
/// Malformed header or body (line for ASCII, byte offset for binary),
/// truncation, non-finite coordinates, negative or out-of-range indices,
/// too many triangles or vertices.
pub fn read<R: BufRead>(reader: R, total_len: Option<u64>, limits: &Limits) -> Result<RawMesh, IoError> {
    let mut src = Source::new(reader, Format::Ply);
    let (encoding, elements) = read_header(&mut src)?;
    let mut sink = MeshSink::new(Format::Ply, *limits);
    let mut checker = IndexChecker::default();
    // Check every declaration before reading data: header errors come first.
    let mut seen_vertex = false;
    let roles =
        elements.iter().map(|el| role_of(&src, el, &mut seen_vertex)).collect::<Result<Vec<Role>, IoError>>()?;
    for (el, &role) in elements.iter().zip(&roles) {
        let remaining = total_len.map(|t| t.saturating_sub(src.offset()));
        match role {
            Role::Vertex(_) => sink.mesh.positions.reserve(capacity_hint(el.count, 3, remaining)),
            Role::Face(_) => sink.mesh.triangles.reserve(capacity_hint(el.count, 4, remaining)),
            Role::Skip => {}
        }
        match encoding {
            Encoding::Ascii => read_ascii_element(&mut src, el, role, &mut sink, &mut checker)?,
            Encoding::Binary(e) => read_binary_element(&mut src, el, role, e, &mut sink, &mut checker)?,
        }
        if role == Role::Skip {
            sink.skip(&el.name, el.count.min(usize::MAX as u64) as usize);
        }
    }
    checker.finish(sink.n_vertices())?;
    Ok(sink.mesh)
}

/// Parse the header up to and including `end_header`.
fn read_header<R: BufRead>(src: &mut Source<R>) -> Result<(Encoding, Vec<Element>), IoError> {
    if !src.next_line()? || src.text().trim_ascii() != b"ply" {
        return Err(src.parse_error("the file does not start with `ply`"));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if !src.next_line()? {
            return Err(src.truncated_at(src.at_line(), "the header has no `end_header`"));
        }
        let mut toks = tokens(src.text());
        let Some(kw) = toks.next() else { continue };
        match kw {
            b"format" => {
                encoding = Some(match toks.next() {
                    Some(b"ascii") => Encoding::Ascii,
                    Some(b"binary_little_endian") => Encoding::Binary(Endian::Little),
                    Some(b"binary_big_endian") => Encoding::Binary(Endian::Big),
                    other => {
                        return Err(src.parse_error(format!("unknown PLY format `{}`", show(other.unwrap_or(b"")))));
                    }
                });
            }
            b"comment" | b"obj_info" => {}
            b"element" => {
                let (Some(name), Some(count)) = (toks.next(), toks.next()) else {
                    return Err(src.parse_error("`element` needs a name and a count"));
                };
                let count = parse_u64(count)
                    .ok_or_else(|| src.parse_error(format!("element count `{}` is not a number", show(count))))?;
                elements.push(Element {
                    name: String::from_utf8_lossy(name).into_owned(),
                    count,
                    props: Vec::new(),
                    header_line: src.line(),
                });
            }
            b"property" => {
                let prop = parse_property(src, &mut toks)?;
                let Some(el) = elements.last_mut() else {
                    return Err(src.parse_error("`property` before any `element`"));
                };
                el.props.push(prop);
            }
            b"end_header" => break,
            other => return Err(src.parse_error(format!("unknown header keyword `{}`", show(other)))),
        }
    }
    let encoding = encoding.ok_or_else(|| src.parse_error("the header has no `format` line"))?;
    Ok((encoding, elements))
}

/// Parse the rest of a `property` line.
fn parse_property<'a, R: BufRead>(
    src: &Source<R>,
    toks: &mut impl Iterator<Item = &'a [u8]>,
) -> Result<(String, Property), IoError> {
    let ty = toks.next().ok_or_else(|| src.parse_error("`property` needs a type and a name"))?;
    let scalar = |t: Option<&[u8]>| {
        let t = t.unwrap_or(b"");
        Scalar::from_name(t).ok_or_else(|| src.parse_error(format!("unknown property type `{}`", show(t))))
    };
    let prop = if ty == b"list" {
        let count = scalar(toks.next())?;
        let item = scalar(toks.next())?;
        if count.is_float() {
            return Err(src.parse_error("a list count type must be an integer type"));
        }
        Property::List { count, item }
    } else {
        Property::Scalar(scalar(Some(ty))?)
    };
    let name = toks.next().ok_or_else(|| src.parse_error("`property` needs a name"))?;
    Ok((String::from_utf8_lossy(name).into_owned(), prop))
}

/// Decide the role of an element and validate what it needs.
fn role_of<R: BufRead>(src: &Source<R>, el: &Element, seen_vertex: &mut bool) -> Result<Role, IoError> {
    let at = Location::Line(el.header_line);
    let find = |name: &str| el.props.iter().position(|(n, _)| n == name);
    match el.name.as_str() {
        "vertex" if !*seen_vertex => {
            *seen_vertex = true;
            let mut idx = [0; 3];
            for (k, axis) in ["x", "y", "z"].into_iter().enumerate() {
                idx[k] = find(axis)
                    .ok_or_else(|| src.parse_error_at(at, format!("the `vertex` element has no `{axis}` property")))?;
                if !matches!(el.props[idx[k]].1, Property::Scalar(_)) {
                    return Err(src.parse_error_at(at, format!("vertex property `{axis}` must be a scalar")));
                }
            }
            Ok(Role::Vertex(idx))
        }
        "vertex" => Err(src.parse_error_at(at, "a second `vertex` element")),
        "face" => {
            let i = find("vertex_indices").or_else(|| find("vertex_index")).ok_or_else(|| {
                src.parse_error_at(at, "the `face` element has no `vertex_indices` (or `vertex_index`) list")
            })?;
            match el.props[i].1 {
                Property::List { item, .. } if !item.is_float() => Ok(Role::Face(i)),
                _ => Err(src.parse_error_at(at, "`vertex_indices` must be a list of an integer type")),
            }
        }
        _ => Ok(Role::Skip),
    }
}

/// Tracks face indices so they can be checked after all vertices are read.
#[derive(Debug, Default)]
struct IndexChecker {
    n_faces: u64,
    /// Largest index, with the face that used it first and where.
    max: Option<(u64, u64, Location)>,
}

impl IndexChecker {
    /// Convert a raw index value of face `self.n_faces` (1-based).
    #[inline]
    fn index(&mut self, v: f64, at: Location) -> Result<u32, IoError> {
        if !(v >= 0.0 && v < f64::from(u32::MAX)) {
            return Err(IoError::IndexOutOfRange {
                format: Format::Ply,
                element: format!("face {}", self.n_faces),
                index: v as i64,
                available: "indices must be in 0..2^32 − 1".into(),
                at,
            });
        }
        let i = v as u64;
        if self.max.is_none_or(|(m, _, _)| i > m) {
            self.max = Some((i, self.n_faces, at));
        }
        Ok(i as u32)
    }

    /// Check the largest index against the vertex count.
    fn finish(&self, n_vertices: usize) -> Result<(), IoError> {
        match self.max {
            Some((m, face, at)) if m >= n_vertices as u64 => Err(IoError::IndexOutOfRange {
                format: Format::Ply,
                element: format!("face {face}"),
                index: m as i64,
                available: format!("the file has {n_vertices} vertices (indices are 0-based)"),
                at,
            }),
            _ => Ok(()),
        }
    }
}

/// Read (or read past) every instance of an ASCII element.
fn read_ascii_element<R: BufRead>(
    src: &mut Source<R>,
    el: &Element,
    role: Role,
    sink: &mut MeshSink,
    checker: &mut IndexChecker,
) -> Result<(), IoError> {
    if el.props.is_empty() {
        return Ok(());
    }
    let mut poly: Vec<u32> = Vec::with_capacity(8);
    let mut xyz = [0.0; 3];
    for i in 0..el.count {
        poly.clear();
        let mut start: Option<Location> = None;
        for (k, (name, prop)) in el.props.iter().enumerate() {
            match *prop {
                Property::Scalar(ty) => {
                    let v = ascii_value(src, ty, el, i, name)?;
                    start.get_or_insert(src.at_line());
                    if let Role::Vertex(idx) = role
                        && let Some(axis) = idx.iter().position(|&j| j == k)
                    {
                        xyz[axis] = v;
                    }
                }
                Property::List { count, item } => {
                    let n = ascii_value(src, count, el, i, name)?;
                    start.get_or_insert(src.at_line());
                    if n < 0.0 {
                        return Err(src.parse_error(format!("{} {}: negative list length {n}", el.name, i + 1)));
                    }
                    let keep = role == Role::Face(k);
                    if keep {
                        checker.n_faces = i + 1;
                    }
                    for _ in 0..n as u64 {
                        let v = ascii_value(src, item, el, i, name)?;
                        if keep {
                            poly.push(checker.index(v, src.at_line())?);
                        }
                    }
                }
            }
        }
        let at = start.unwrap_or(src.at_line());
        match role {
            Role::Vertex(_) => {
                sink.vertex(xyz, i + 1, at)?;
            }
            Role::Face(_) => sink.polygon(&poly, at)?,
            Role::Skip => {}
        }
    }
    Ok(())
}

/// The next ASCII token as a number of type `ty`.
fn ascii_value<R: BufRead>(src: &mut Source<R>, ty: Scalar, el: &Element, i: u64, name: &str) -> Result<f64, IoError> {
    if !src.next_token()? {
        return Err(src.truncated_at(
            src.at_line(),
            format!("expected property `{name}` of {} {} of {}", el.name, i + 1, el.count),
        ));
    }
    ty.parse(src.token()).ok_or_else(|| {
        src.parse_error(format!(
            "{} {}: property `{name}`: `{}` is not a {ty:?} number",
            el.name,
            i + 1,
            show(src.token())
        ))
    })
}

/// Read (or read past) every instance of a binary element.
fn read_binary_element<R: BufRead>(
    src: &mut Source<R>,
    el: &Element,
    role: Role,
    e: Endian,
    sink: &mut MeshSink,
    checker: &mut IndexChecker,
) -> Result<(), IoError> {
    if el.props.is_empty() {
        return Ok(());
    }
    let scalar_offsets: Option<Vec<(usize, Scalar)>> = {
        let mut off = 0;
        el.props
            .iter()
            .map(|(_, p)| match *p {
                Property::Scalar(s) => {
                    let o = off;
                    off += s.size();
                    Some((o, s))
                }
                Property::List { .. } => None,
            })
            .collect()
    };
    if let (Some(offsets), Role::Skip | Role::Vertex(_)) = (scalar_offsets, role) {
        let record: usize = offsets.iter().map(|(_, s)| s.size()).sum();
        match role {
            Role::Skip | Role::Face(_) => {
                let total = el.count.checked_mul(record as u64).ok_or_else(|| {
                    src.truncated_at(src.at_byte(), format!("{} × {record}-byte `{}` records", el.count, el.name))
                })?;
                return src.skip_bytes(total, &format!("{} `{}` records", el.count, el.name));
            }
            Role::Vertex(idx) => {
                let mut buf = vec![0u8; record];
                for i in 0..el.count {
                    let at = src.at_byte();
                    src.read_exact(&mut buf, "a vertex record")?;
                    let p = idx.map(|j| offsets[j].1.decode(&buf[offsets[j].0..], e));
                    sink.vertex(p, i + 1, at)?;
                }
                return Ok(());
            }
        }
    }
    let mut poly: Vec<u32> = Vec::with_capacity(8);
    let mut xyz = [0.0; 3];
    let mut buf = [0u8; 8];
    for i in 0..el.count {
        poly.clear();
        let at = src.at_byte();
        for (k, (name, prop)) in el.props.iter().enumerate() {
            match *prop {
                Property::Scalar(ty) => {
                    src.read_exact(&mut buf[..ty.size()], name)?;
                    if let Role::Vertex(idx) = role
                        && let Some(axis) = idx.iter().position(|&j| j == k)
                    {
                        xyz[axis] = ty.decode(&buf, e);
                    }
                }
                Property::List { count, item } => {
                    src.read_exact(&mut buf[..count.size()], name)?;
                    let n = count.decode(&buf, e);
                    if n < 0.0 {
                        return Err(src.parse_error_at(at, format!("{} {}: negative list length {n}", el.name, i + 1)));
                    }
                    let n = n as u64;
                    if role == Role::Face(k) {
                        checker.n_faces = i + 1;
                        for _ in 0..n {
                            src.read_exact(&mut buf[..item.size()], name)?;
                            poly.push(checker.index(item.decode(&buf, e), at)?);
                        }
                    } else {
                        let bytes = n.saturating_mul(item.size() as u64);
                        src.skip_bytes(bytes, name)?;
                    }
                }
            }
        }
        match role {
            Role::Vertex(_) => {
                sink.vertex(xyz, i + 1, at)?;
            }
            Role::Face(_) => sink.polygon(&poly, at)?,
            Role::Skip => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::failure::FailureKind;

    fn limits() -> Limits {
        Limits::from_max_triangles(100)
    }

    const ASCII: &str = "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 4\nproperty float x\nproperty double y\nproperty int z\nproperty list uchar float extra\nproperty uchar red\nelement face 2\nproperty list uchar int vertex_indices\nproperty int flags\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n0 0 0 2 0.5 0.5 255\n1 0 0 0 10\n1 1 0 1 7 10\n0 1 0 0 10\n3 0 1 2 5\n4 0 1\n 2 3 0\n0 1\n";

    #[test]
    fn ascii_with_extra_properties_lists_and_elements() {
        let m = read(ASCII.as_bytes(), None, &limits()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.positions[2], crate::geom::Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.n_polygons_triangulated, 1);
        assert_eq!(m.skipped["edge"], 1);
    }

    /// The same mesh in a binary encoding, built by hand.
    fn binary(e: Endian) -> Vec<u8> {
        let name = if e == Endian::Little { "binary_little_endian" } else { "binary_big_endian" };
        let mut out = format!(
            "ply\nformat {name} 1.0\nelement vertex 4\nproperty float x\nproperty double y\nproperty short z\nproperty list uchar float extra\nelement face 2\nproperty list uchar uint vertex_index\nproperty uchar flags\nelement edge 1\nproperty int vertex1\nproperty list int int more\nend_header\n"
        )
        .into_bytes();
        let f32b = |v: f32| if e == Endian::Little { v.to_le_bytes() } else { v.to_be_bytes() };
        let f64b = |v: f64| if e == Endian::Little { v.to_le_bytes() } else { v.to_be_bytes() };
        let i16b = |v: i16| if e == Endian::Little { v.to_le_bytes() } else { v.to_be_bytes() };
        let u32b = |v: u32| if e == Endian::Little { v.to_le_bytes() } else { v.to_be_bytes() };
        for (i, p) in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]].iter().enumerate() {
            out.extend_from_slice(&f32b(p[0] as f32));
            out.extend_from_slice(&f64b(p[1]));
            out.extend_from_slice(&i16b(p[2] as i16));
            out.push(i as u8 % 2);
            for _ in 0..i % 2 {
                out.extend_from_slice(&f32b(0.25));
            }
        }
        out.push(3);
        for v in [0, 1, 2] {
            out.extend_from_slice(&u32b(v));
        }
        out.push(1);
        out.push(4);
        for v in [0, 1, 2, 3] {
            out.extend_from_slice(&u32b(v));
        }
        out.push(0);
        out.extend_from_slice(&u32b(7));
        out.extend_from_slice(&u32b(2));
        out.extend_from_slice(&u32b(1));
        out.extend_from_slice(&u32b(2));
        out
    }

    #[test]
    fn binary_both_endians() {
        for e in [Endian::Little, Endian::Big] {
            let bytes = binary(e);
            let m = read(&bytes[..], Some(bytes.len() as u64), &limits()).unwrap();
            assert_eq!(m.positions[2], crate::geom::Vec3::new(1.0, 1.0, 0.0), "{e:?}");
            assert_eq!(m.triangles, vec![[0, 1, 2], [0, 1, 2], [0, 2, 3]]);
            assert_eq!(m.skipped["edge"], 1);
        }
    }

    #[test]
    fn truncated_binary_names_offset() {
        let bytes = binary(Endian::Little);
        let e = read(&bytes[..bytes.len() - 3], None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        assert!(e.to_string().contains("byte offset"), "{e}");
    }

    #[test]
    fn header_and_body_errors() {
        let e = read("plx\n".as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("does not start with `ply`"), "{e}");
        let e = read(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n".as_bytes(),
            None,
            &limits(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("no `z` property") && e.to_string().contains("line 3"), "{e}");
        let e =
            read("ply\nformat ascii 1.0\nelement vertex 1\nproperty flt x\n".as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("unknown property type `flt`") && e.to_string().contains("line 4"), "{e}");
        let e = read("ply\nformat ascii 1.0\nelement vertex 1\n".as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        let bad = ASCII.replace("1 1 0 1 7 10", "1 1 q 1 7 10");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert!(
            e.to_string().contains("line 19") && e.to_string().contains("vertex 3") && e.to_string().contains("`q`"),
            "{e}"
        );
        let bad = ASCII.replace("3 0 1 2 5", "3 0 1 9 5");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::IndexOutOfRange);
        assert!(
            e.to_string().contains("face 1") && e.to_string().contains("vertex 9") && e.to_string().contains("line 21"),
            "{e}"
        );
        let bad = ASCII.replace("3 0 1 2 5", "3 0 -1 2 5");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::IndexOutOfRange);
        let bad = ASCII.replace("1 0 0 0 10", "1 nan 0 0 10");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::NonFiniteCoordinate);
        assert!(e.to_string().contains("vertex 2") && e.to_string().contains("line 18"), "{e}");
        let bad = ASCII.replace("0 1 0 0 10\n3 0 1 2 5\n4 0 1\n 2 3 0\n0 1\n", "0 1 0 0 10\n3 0 1 2 5\n4 0 1\n");
        let e = read(bad.as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        assert!(e.to_string().contains("face 2 of 2"), "{e}");
    }

    #[test]
    fn element_declaration_errors() {
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
        let e = read(
            format!("{head}element face 1\nproperty list uchar float vertex_indices\nend_header\n").as_bytes(),
            None,
            &limits(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("integer type") && e.to_string().contains("line 7"), "{e}");
        let e = read(format!("{head}element face 1\nproperty int flags\nend_header\n").as_bytes(), None, &limits())
            .unwrap_err();
        assert!(e.to_string().contains("no `vertex_indices`"), "{e}");
        let e = read(format!("{head}element vertex 1\nproperty float x\nend_header\n").as_bytes(), None, &limits())
            .unwrap_err();
        assert!(e.to_string().contains("second `vertex`"), "{e}");
        let e = read("ply\nelement vertex 1\nend_header\n".as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("no `format`"), "{e}");
        let e = read("ply\nformat binary_middle_endian 1.0\n".as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("unknown PLY format"), "{e}");
        let e = read("ply\nformat ascii 1.0\nproperty float x\n".as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("before any `element`"), "{e}");
        let e = read("ply\nformat ascii 1.0\nelemnt vertex 1\n".as_bytes(), None, &limits()).unwrap_err();
        assert!(e.to_string().contains("unknown header keyword `elemnt`"), "{e}");
        // Faces before vertices are fine; indices are checked at the end.
        let text = "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar uint vertex_index\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n3 0 1 2\n0 0 0\n1 0 0\n0 1 0\n";
        assert_eq!(read(text.as_bytes(), None, &limits()).unwrap().triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn huge_counts_do_not_allocate_or_hang() {
        let text = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nelement nothing 18446744073709551615\nend_header\n";
        let e = read(text.as_bytes(), Some(text.len() as u64), &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        let text = "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement nothing 18446744073709551615\nproperty int a\nend_header\n";
        let e = read(text.as_bytes(), None, &limits()).unwrap_err();
        assert_eq!(e.kind(), FailureKind::Truncated);
        let text = "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement nothing 18446744073709551615\nend_header\n";
        let m = read(text.as_bytes(), None, &limits()).unwrap();
        assert_eq!(m.skipped["nothing"], usize::MAX);
    }
}
