//! [`FailureKind`]: the stable, machine-readable kind of every failure the
//! service can report, from the mesh readers through the pipeline and the
//! job store to the HTTP problem documents.
//!
//! Each kind has a kebab-case id ([`FailureKind::as_str`]) that is the
//! suffix of the problem `type` (`urn:meshatlas:problem:<id>`), is stored in
//! the job database and is printed by the CLI. The ids never change once
//! published; messages may be improved. The enum lives beside the core
//! (which produces the reader and stage kinds) and knows nothing of HTTP:
//! `http::ApiError` maps each kind to a status code and a title by one
//! exhaustive `match`, so a new kind does not compile until it is mapped.
//!
//! Serialized as its id. An id that is not a kind (a job stored by an older
//! or newer version) reads back as [`FailureKind::InternalError`]
//! ([`FailureKind::from_stored`]), never as an error or a panic.

use std::fmt;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Defines [`FailureKind`], its id table and [`FailureKind::ALL`] from one
/// list, so `ALL` holds every variant by construction.
macro_rules! failure_kinds {
    ($( $(#[$doc:meta])* $variant:ident = $id:literal, )*) => {
        /// The stable kind of a failure (see the module documentation).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum FailureKind {
            $( $(#[$doc])* $variant, )*
        }

        impl FailureKind {
            /// Every kind, in declaration order.
            pub const ALL: &'static [FailureKind] = &[$(FailureKind::$variant),*];

            /// The stable kebab-case id (suffix of the problem `type`).
            pub fn as_str(self) -> &'static str {
                match self {
                    $( FailureKind::$variant => $id, )*
                }
            }
        }
    };
}

failure_kinds! {
    // Request errors (answered by the HTTP layer before a job exists).
    /// The request is malformed (e.g. a bad header, stages given twice).
    BadRequest = "bad-request",
    /// A query parameter is not valid (`limit`, `cursor`, `format`).
    InvalidQuery = "invalid-query",
    /// The pipeline parameters are not JSON.
    InvalidJson = "invalid-json",
    /// The multipart body is malformed.
    InvalidMultipart = "invalid-multipart",
    /// The multipart body has no `file` part.
    MissingFile = "missing-file",
    /// The client stopped sending the upload part-way.
    UploadInterrupted = "upload-interrupted",
    /// The upload sent no bytes for the idle timeout.
    UploadTimeout = "upload-timeout",
    /// The request target exceeds the server's limit.
    UriTooLong = "uri-too-long",
    /// Too many or too large header fields.
    HeadersTooLarge = "headers-too-large",
    /// No valid bearer token.
    Unauthorized = "unauthorized",
    /// No route matches the path.
    NotFound = "not-found",
    /// No such job (or another tenant's).
    JobNotFound = "job-not-found",
    /// The job has no artifact of that name.
    ArtifactNotFound = "artifact-not-found",
    /// The path does not support the method.
    MethodNotAllowed = "method-not-allowed",
    /// The upload exceeds the server's limit.
    UploadTooLarge = "upload-too-large",
    /// The `Range` header selects no byte of the artifact.
    RangeNotSatisfiable = "range-not-satisfiable",
    /// The body's media type is not accepted.
    UnsupportedMediaType = "unsupported-media-type",
    /// The pipeline parameters are JSON but not valid.
    InvalidParams = "invalid-params",
    /// The job's estimated peak memory exceeds the server's budget.
    MemoryBudgetExceeded = "memory-budget-exceeded",
    /// The job queue is full.
    QueueFull = "queue-full",
    /// The tenant has too many queued jobs.
    TenantQueueFull = "tenant-queue-full",
    /// A stored-bytes quota is full, or the disk refused the request's data.
    InsufficientStorage = "insufficient-storage",
    /// The job store does not answer or does not write.
    ServiceUnavailable = "service-unavailable",

    // Failures of the input, from the readers (request or job).
    /// The input has no bytes.
    EmptyFile = "empty-file",
    /// The format could not be determined, or is not a format.
    UnknownFormat = "unknown-format",
    /// The data ends before the structure it announced is complete.
    Truncated = "truncated",
    /// Malformed content: a wrong keyword, a token that is not a number.
    ParseError = "parse-error",
    /// A vertex coordinate is NaN or infinite.
    NonFiniteCoordinate = "non-finite-coordinate",
    /// A vertex coordinate beyond the supported magnitude.
    CoordinateOutOfRange = "coordinate-out-of-range",
    /// An element references a vertex that does not exist.
    IndexOutOfRange = "index-out-of-range",
    /// More vertices than the limit.
    TooManyVertices = "too-many-vertices",
    /// The mesh read violates an invariant the readers should have caught.
    InvalidMesh = "invalid-mesh",
    /// A load option out of range.
    InvalidOptions = "invalid-options",
    /// More triangles (or tetrahedra) than the limit.
    TooManyTriangles = "too-many-triangles",
    /// No triangle in the input, or repair removed them all.
    NoTriangles = "no-triangles",
    /// A valid file using a feature the reader does not support.
    Unsupported = "unsupported",

    // Failures of a stage on this input.
    /// A stage could not handle this input (no more specific kind).
    StageFailed = "stage-failed",
    /// A patch has no one-to-one parameterization after the allowed splits.
    NoValidMap = "no-valid-map",
    /// The surface cannot be oriented consistently.
    NonOrientableSurface = "non-orientable-surface",
    /// The surface is not closed, so it encloses no volume.
    OpenSurface = "open-surface",
    /// The target size gives no or too many elements (tetrahedra of the
    /// frames stage, quads of the quads stage).
    InvalidTargetSize = "invalid-target-size",

    // Failures of the job around the stages.
    /// The job ran longer than the server's limit.
    TimeLimitExceeded = "time-limit-exceeded",
    /// The server's disk or quota was full while the job wrote.
    StorageFull = "storage-full",
    /// The server's storage was read-only while the job wrote.
    StorageUnavailable = "storage-unavailable",
    /// The server stopped during the job too many times.
    Interrupted = "interrupted",
    /// The server process died twice while the job ran.
    CrashedServer = "crashed-server",
    /// A fault of the server (the cause is logged, not shown); also what an
    /// unknown stored id reads back as.
    InternalError = "internal-error",
}

impl FailureKind {
    /// The kind whose id is `id`, if any.
    pub fn parse(id: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|k| k.as_str() == id)
    }

    /// The kind of an id read back from storage: [`FailureKind::parse`], or
    /// [`FailureKind::InternalError`] for an id this version does not know
    /// (an older `write-failed` or `io`, or a newer kind), so reading an old
    /// or foreign record never fails.
    pub fn from_stored(id: &str) -> Self {
        Self::parse(id).unwrap_or(FailureKind::InternalError)
    }
}

impl fmt::Display for FailureKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for FailureKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for FailureKind {
    /// Any string: unknown ids become [`FailureKind::InternalError`]
    /// ([`FailureKind::from_stored`]).
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let id = std::borrow::Cow::<str>::deserialize(d)?;
        Ok(Self::from_stored(&id))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_unique_kebab_case_and_round_trip() {
        let mut seen = std::collections::BTreeSet::new();
        for &k in FailureKind::ALL {
            let id = k.as_str();
            assert!(seen.insert(id), "id `{id}` used twice");
            let kebab = !id.is_empty()
                && !id.starts_with('-')
                && !id.ends_with('-')
                && !id.contains("--")
                && id.bytes().all(|b| b.is_ascii_lowercase() || b == b'-');
            assert!(kebab, "id `{id}` is not kebab-case");
            assert_eq!(FailureKind::parse(id), Some(k));
            let json = serde_json::to_value(k).unwrap();
            assert_eq!(json, serde_json::Value::String(id.into()));
            assert_eq!(serde_json::from_value::<FailureKind>(json).unwrap(), k);
        }
    }

    #[test]
    fn published_ids_keep_their_spelling() {
        // Spellings clients and stored jobs already use (API tests, job database).
        let cases = [
            (FailureKind::ParseError, "parse-error"),
            (FailureKind::TooManyTriangles, "too-many-triangles"),
            (FailureKind::InvalidTargetSize, "invalid-target-size"),
            (FailureKind::MemoryBudgetExceeded, "memory-budget-exceeded"),
            (FailureKind::CrashedServer, "crashed-server"),
            (FailureKind::TenantQueueFull, "tenant-queue-full"),
            (FailureKind::UriTooLong, "uri-too-long"),
            (FailureKind::InternalError, "internal-error"),
        ];
        for (k, id) in cases {
            assert_eq!(k.as_str(), id);
        }
    }

    #[test]
    fn unknown_stored_ids_read_back_as_internal_error() {
        for id in ["write-failed", "io", "cancelled", "", "Parse-Error", "a-kind-from-the-future"] {
            assert_eq!(FailureKind::parse(id), None, "{id}");
            assert_eq!(FailureKind::from_stored(id), FailureKind::InternalError, "{id}");
            let k: FailureKind = serde_json::from_value(serde_json::Value::String(id.into())).unwrap();
            assert_eq!(k, FailureKind::InternalError, "{id}");
        }
        // A non-string is still an error (a corrupt record), not a silent default.
        assert!(serde_json::from_value::<FailureKind>(serde_json::json!(3)).is_err());
    }
}
