//! The `Range` request header as RFC 9110 §14 asks a server to read it.
//!
//! A server may ignore `Range`, and must ignore a range unit it does not
//! know and a range set that does not parse; it answers the whole
//! representation (200) then. This server honours one byte range
//! (`bytes=first-last`, `bytes=first-`, `bytes=-suffix`; the unit is
//! case-insensitive) and answers a request for several ranges with the whole
//! file rather than a `multipart/byteranges` body. A single range that parses
//! but lies past the end stays unsatisfiable (416).
//!
//! [`range_to_serve`] turns the client's header into the canonical form the
//! file server understands, or into nothing; [`if_range_holds`] evaluates
//! `If-Range` (§13.1.5) against the validators of the served file.

use axum::http::{HeaderMap, header};

/// One syntactically valid byte range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ByteRange {
    /// `first-last` (`last` absent: to the end).
    From { first: u64, last: Option<u64> },
    /// `-n`: the last `n` bytes.
    Suffix(u64),
}

/// Parses `1*DIGIT`, saturating at `u64::MAX` (a huge `first` stays
/// unsatisfiable, a huge `last` or suffix means "to the end").
fn parse_digits(s: &str) -> Option<u64> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some(s.bytes().fold(0u64, |n, d| n.saturating_mul(10).saturating_add(u64::from(d - b'0'))))
}

/// Parses one `range-spec` of the `bytes` unit; `None` when it is invalid
/// (not digits, or `last` before `first`).
fn parse_range_spec(spec: &str) -> Option<ByteRange> {
    let (first, last) = spec.split_once('-')?;
    if first.is_empty() {
        return parse_digits(last).map(ByteRange::Suffix);
    }
    let first = parse_digits(first)?;
    if last.is_empty() {
        return Some(ByteRange::From { first, last: None });
    }
    let last = parse_digits(last)?;
    (last >= first).then_some(ByteRange::From { first, last: Some(last) })
}

/// The ranges of a `Range` value, or `None` when the unit is not `bytes` or
/// the set does not parse (empty list elements are skipped, as for any list).
fn parse_byte_ranges(value: &str) -> Option<Vec<ByteRange>> {
    let (unit, set) = value.split_once('=')?;
    if !unit.eq_ignore_ascii_case("bytes") {
        return None;
    }
    let specs: Vec<&str> = set.split(',').map(|s| s.trim_matches([' ', '\t'])).filter(|s| !s.is_empty()).collect();
    if specs.is_empty() {
        return None;
    }
    specs.into_iter().map(parse_range_spec).collect()
}

/// The `Range` value to serve for the request's headers: the one byte range
/// in canonical form, or `None` to serve the whole file (no `Range`, an
/// unknown unit, an invalid set, or several ranges).
pub fn range_to_serve(headers: &HeaderMap) -> Option<String> {
    let value = headers.get(header::RANGE)?.to_str().ok()?;
    match parse_byte_ranges(value)?.as_slice() {
        [ByteRange::From { first, last: Some(last) }] => Some(format!("bytes={first}-{last}")),
        [ByteRange::From { first, last: None }] => Some(format!("bytes={first}-")),
        [ByteRange::Suffix(n)] => Some(format!("bytes=-{n}")),
        _ => None,
    }
}

/// Whether the request's `If-Range` (if any) lets the range be served: an
/// entity tag must equal the response's strong `ETag`, a date must equal its
/// `Last-Modified` exactly; anything else means the client's copy is stale
/// and it gets the whole file.
pub fn if_range_holds(request: &HeaderMap, response: &HeaderMap) -> bool {
    let Some(validator) = request.get(header::IF_RANGE) else { return true };
    let validator = validator.as_bytes();
    if validator.starts_with(b"\"") || validator.starts_with(b"W/") {
        let etag = response.get(header::ETAG).map(|v| v.as_bytes());
        return !validator.starts_with(b"W/") && etag.is_some_and(|e| !e.starts_with(b"W/") && e == validator);
    }
    response.get(header::LAST_MODIFIED).is_some_and(|d| d.as_bytes() == validator)
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn serve(range: &str) -> Option<String> {
        let mut h = HeaderMap::new();
        h.insert(header::RANGE, HeaderValue::from_str(range).unwrap());
        range_to_serve(&h)
    }

    #[test]
    fn one_byte_range_is_served_in_canonical_form() {
        assert_eq!(serve("bytes=0-9").as_deref(), Some("bytes=0-9"));
        assert_eq!(serve("Bytes=10-").as_deref(), Some("bytes=10-"));
        assert_eq!(serve("bytes= -5 ,").as_deref(), Some("bytes=-5"));
        assert_eq!(serve("bytes=5-5").as_deref(), Some("bytes=5-5"));
        assert_eq!(
            serve("bytes=0-99999999999999999999999").as_deref(),
            Some(format!("bytes=0-{}", u64::MAX)).as_deref()
        );
        assert_eq!(serve("bytes=999999999-").as_deref(), Some("bytes=999999999-"), "unsatisfiable, not invalid");
        assert_eq!(serve("bytes=-0").as_deref(), Some("bytes=-0"), "unsatisfiable, not invalid");
    }

    #[test]
    fn unknown_units_invalid_sets_and_multiple_ranges_are_ignored() {
        for r in [
            "items=0-5",
            "bytes=abc",
            "bytes=9-5",
            "bytes=",
            "bytes=,",
            "bytes=1-2-3",
            "0-5",
            "bytes =0-5",
            "bytes=0-9,20-29",
            "bytes=+1-2",
        ] {
            assert_eq!(serve(r), None, "{r}");
        }
        assert_eq!(range_to_serve(&HeaderMap::new()), None);
    }

    #[test]
    fn if_range_needs_an_exact_strong_validator() {
        let mut resp = HeaderMap::new();
        resp.insert(header::ETAG, HeaderValue::from_static("\"abc\""));
        resp.insert(header::LAST_MODIFIED, HeaderValue::from_static("Tue, 01 Dec 2026 18:00:00 GMT"));
        let req = |v: &'static str| {
            let mut h = HeaderMap::new();
            h.insert(header::IF_RANGE, HeaderValue::from_static(v));
            h
        };
        assert!(if_range_holds(&HeaderMap::new(), &resp));
        assert!(if_range_holds(&req("\"abc\""), &resp));
        assert!(!if_range_holds(&req("W/\"abc\""), &resp));
        assert!(!if_range_holds(&req("\"abd\""), &resp));
        assert!(if_range_holds(&req("Tue, 01 Dec 2026 18:00:00 GMT"), &resp));
        assert!(!if_range_holds(&req("Tue, 01 Dec 2026 17:00:00 GMT"), &resp));
    }
}
