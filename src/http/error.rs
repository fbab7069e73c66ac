//! [`ApiError`]: the one place where errors become HTTP status codes, and
//! the `application/problem+json` bodies (RFC 9457) every error carries.
//!
//! Every problem has a stable `type` (`urn:meshatlas:problem:<kind>`), a
//! `title` fixed per kind, a `status`, a `detail` for this occurrence and the
//! `request_id` (also sent as the `x-request-id` header). Server errors (5xx)
//! get a generic detail; the real cause goes to the log with the request id.
//!
//! The request-context middleware ([`request_context`]) assigns the request
//! id, opens the request's tracing span, and turns any error response that
//! is not yet problem+json (axum's 404/405, extractor rejections, a caught
//! panic) into one, so no error leaves the server without a problem body.

use axum::body::Body;
use axum::extract::Request;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use serde_json::{Map, Value, json};
use tracing::Instrument;

use crate::failure::FailureKind;
use crate::jobs::{JobError, JobsError};
use crate::pipeline::ParamsError;

/// Prefix of every problem `type`.
pub const PROBLEM_TYPE_PREFIX: &str = "urn:meshatlas:problem:";
/// Media type of error bodies.
pub const PROBLEM_JSON: &str = "application/problem+json";
/// The problem `type` of `kind`: `urn:meshatlas:problem:<kind>`.
pub fn problem_type(kind: FailureKind) -> String {
    format!("{PROBLEM_TYPE_PREFIX}{}", kind.as_str())
}

/// Header carrying the request id.
pub const REQUEST_ID_HEADER: &str = "x-request-id";

tokio::task_local! {
    static REQUEST_ID: String;
}

/// The id of the request being handled (`-` outside a request).
pub fn current_request_id() -> String {
    REQUEST_ID.try_with(Clone::clone).unwrap_or_else(|_| "-".to_string())
}

/// An error answered to a client (boxed: handlers return it in `Result`s).
#[derive(Debug)]
pub struct ApiError(Box<Problem>);

/// The fields of an [`ApiError`].
#[derive(Debug)]
struct Problem {
    status: StatusCode,
    kind: FailureKind,
    title: &'static str,
    detail: String,
    extra: Map<String, Value>,
    retry_after: Option<u64>,
    /// Cause logged (not shown) for server errors.
    cause: Option<String>,
    /// A 5xx whose detail and members are meant for the client (a quota).
    expose: bool,
}

/// The HTTP status and the fixed title of `kind`. Kinds from the mesh
/// readers (`parse-error`, `truncated`, …) and the job runner appear in job
/// resources with the status a synchronous request would have got; the
/// others are request errors. One exhaustive `match` (no catch-all arm), so
/// a new [`FailureKind`] does not compile until it is mapped here.
pub fn status_and_title(kind: FailureKind) -> (StatusCode, &'static str) {
    use FailureKind as K;
    match kind {
        K::BadRequest => (StatusCode::BAD_REQUEST, "Bad request"),
        K::InvalidQuery => (StatusCode::BAD_REQUEST, "Invalid query parameter"),
        K::InvalidJson => (StatusCode::BAD_REQUEST, "Parameters are not valid JSON"),
        K::InvalidMultipart => (StatusCode::BAD_REQUEST, "Malformed multipart body"),
        K::MissingFile => (StatusCode::BAD_REQUEST, "No file in the upload"),
        K::UploadInterrupted => (StatusCode::BAD_REQUEST, "The upload was interrupted"),
        K::UploadTimeout => (StatusCode::REQUEST_TIMEOUT, "The upload stalled"),
        K::UriTooLong => (StatusCode::URI_TOO_LONG, "URI too long"),
        K::HeadersTooLarge => (StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE, "Request headers too large"),
        K::EmptyFile => (StatusCode::BAD_REQUEST, "The uploaded file is empty"),
        K::Unauthorized => (StatusCode::UNAUTHORIZED, "Authentication required"),
        K::NotFound => (StatusCode::NOT_FOUND, "No such resource"),
        K::JobNotFound => (StatusCode::NOT_FOUND, "No such job"),
        K::ArtifactNotFound => (StatusCode::NOT_FOUND, "No such artifact"),
        K::MethodNotAllowed => (StatusCode::METHOD_NOT_ALLOWED, "Method not allowed"),
        K::UploadTooLarge => (StatusCode::PAYLOAD_TOO_LARGE, "Upload too large"),
        K::RangeNotSatisfiable => (StatusCode::RANGE_NOT_SATISFIABLE, "Range not satisfiable"),
        K::UnsupportedMediaType => (StatusCode::UNSUPPORTED_MEDIA_TYPE, "Unsupported media type"),
        K::UnknownFormat => (StatusCode::UNSUPPORTED_MEDIA_TYPE, "Unknown mesh format"),
        K::InvalidParams => (StatusCode::UNPROCESSABLE_ENTITY, "Invalid pipeline parameters"),
        K::MemoryBudgetExceeded => (StatusCode::UNPROCESSABLE_ENTITY, "Job exceeds the server's memory budget"),
        K::QueueFull => (StatusCode::TOO_MANY_REQUESTS, "Job queue full"),
        K::TenantQueueFull => (StatusCode::TOO_MANY_REQUESTS, "Too many queued jobs for this tenant"),
        K::InsufficientStorage => (StatusCode::INSUFFICIENT_STORAGE, "Insufficient storage"),
        K::ServiceUnavailable => (StatusCode::SERVICE_UNAVAILABLE, "Service unavailable"),
        // Job failures caused by the input (reader errors and limits).
        K::Truncated => (StatusCode::UNPROCESSABLE_ENTITY, "Truncated mesh file"),
        K::ParseError => (StatusCode::UNPROCESSABLE_ENTITY, "Mesh file does not parse"),
        K::NonFiniteCoordinate => (StatusCode::UNPROCESSABLE_ENTITY, "Non-finite coordinate"),
        K::CoordinateOutOfRange => (StatusCode::UNPROCESSABLE_ENTITY, "Coordinate out of range"),
        K::IndexOutOfRange => (StatusCode::UNPROCESSABLE_ENTITY, "Face index out of range"),
        K::TooManyVertices => (StatusCode::UNPROCESSABLE_ENTITY, "Too many vertices"),
        K::InvalidMesh => (StatusCode::UNPROCESSABLE_ENTITY, "Mesh violates an invariant after repair"),
        K::InvalidOptions => (StatusCode::UNPROCESSABLE_ENTITY, "Invalid load options"),
        K::TooManyTriangles => (StatusCode::UNPROCESSABLE_ENTITY, "Too many triangles"),
        K::NoTriangles => (StatusCode::UNPROCESSABLE_ENTITY, "No triangles in the mesh"),
        K::Unsupported => (StatusCode::UNPROCESSABLE_ENTITY, "Unsupported mesh content"),
        K::StageFailed => (StatusCode::UNPROCESSABLE_ENTITY, "A pipeline stage failed on this input"),
        K::NoValidMap => (StatusCode::UNPROCESSABLE_ENTITY, "A patch has no valid one-to-one parameterization"),
        K::NonOrientableSurface => (StatusCode::UNPROCESSABLE_ENTITY, "The surface cannot be oriented consistently"),
        K::OpenSurface => (StatusCode::UNPROCESSABLE_ENTITY, "The surface is not closed, so it encloses no volume"),
        K::InvalidTargetSize => (StatusCode::UNPROCESSABLE_ENTITY, "The target size gives no or too many elements"),
        K::TimeLimitExceeded => (StatusCode::UNPROCESSABLE_ENTITY, "Job time limit exceeded"),
        // Job failures caused by the server's storage (full disk, read-only).
        K::StorageFull => (StatusCode::INSUFFICIENT_STORAGE, "The server's storage was full"),
        K::StorageUnavailable => (StatusCode::SERVICE_UNAVAILABLE, "The server's storage did not accept writes"),
        K::Interrupted => (StatusCode::SERVICE_UNAVAILABLE, "Job interrupted repeatedly"),
        K::CrashedServer => (StatusCode::UNPROCESSABLE_ENTITY, "Job stopped the server twice"),
        K::InternalError => (StatusCode::INTERNAL_SERVER_ERROR, "Internal server error"),
    }
}

impl ApiError {
    /// An error of `kind` with a client-facing `detail`.
    pub fn new(kind: FailureKind, detail: impl Into<String>) -> Self {
        let (status, title) = status_and_title(kind);
        Self(Box::new(Problem {
            status,
            kind,
            title,
            detail: detail.into(),
            extra: Map::new(),
            retry_after: None,
            cause: None,
            expose: false,
        }))
    }

    /// A server error; `cause` is logged with the request id, never shown.
    pub fn internal(cause: impl std::fmt::Display) -> Self {
        let mut e = Self::new(FailureKind::InternalError, "");
        e.0.cause = Some(cause.to_string());
        e
    }

    /// Adds an extension member to the problem body.
    pub fn with(mut self, key: &str, value: impl Into<Value>) -> Self {
        self.0.extra.insert(key.to_string(), value.into());
        self
    }

    /// Asks the client to retry after `secs` seconds (`Retry-After`).
    pub fn retry_after(mut self, secs: u64) -> Self {
        self.0.retry_after = Some(secs);
        self
    }

    /// Shows the detail and members even though the status is 5xx (a
    /// refusal the client can act on, such as a full storage quota).
    pub fn exposed(mut self) -> Self {
        self.0.expose = true;
        self
    }

    /// True when the body must be generic and the cause logged as an error.
    fn is_hidden(&self) -> bool {
        // Storage refusals and an unhealthy store carry our own text, never a cause.
        let own_text = matches!(self.0.kind, FailureKind::InsufficientStorage | FailureKind::ServiceUnavailable);
        self.0.status.is_server_error() && !self.0.expose && !own_text
    }

    /// The HTTP status of this error.
    pub fn status(&self) -> StatusCode {
        self.0.status
    }

    /// The stable kind (suffix of `type`).
    pub fn kind(&self) -> FailureKind {
        self.0.kind
    }

    /// The server's storage refused a write: `insufficient-storage` (507)
    /// for a full or read-only disk, else an internal error; `cause` is logged.
    pub fn storage(kind: Option<FailureKind>, cause: impl std::fmt::Display) -> Self {
        if kind.is_none() {
            return Self::internal(cause);
        }
        let mut e = Self::new(
            FailureKind::InsufficientStorage,
            "the server's storage is full or read-only, so the request could not be stored; retry later",
        );
        e.0.cause = Some(cause.to_string());
        e
    }

    /// An I/O error of the data directory ([`ApiError::storage`]).
    pub fn io(what: &str, e: &std::io::Error) -> Self {
        Self::storage(crate::pipeline::error::storage_kind(e), format!("{what}: {e}"))
    }

    /// Invalid pipeline parameters (422), or not JSON at all (400).
    pub fn params(e: ParamsError) -> Self {
        let kind = if e.syntax { FailureKind::InvalidJson } else { FailureKind::InvalidParams };
        let detail = match &e.field {
            Some(f) => format!("parameter `{f}`: {}", e.message),
            None => e.message.clone(),
        };
        let mut err = Self::new(kind, detail);
        if let Some(f) = e.field {
            err = err.with("field", f);
        }
        err
    }

    /// The upload exceeded `limit` bytes (413).
    pub fn upload_too_large(limit: u64) -> Self {
        Self::new(FailureKind::UploadTooLarge, format!("the upload exceeds this server's limit of {limit} bytes"))
            .with("max_bytes", limit)
    }

    /// An upload that sent no bytes for `idle_secs` seconds (408).
    pub fn upload_timeout(idle_secs: u64) -> Self {
        Self::new(
            FailureKind::UploadTimeout,
            format!("no upload bytes arrived for {idle_secs} s; the upload was dropped"),
        )
        .with("idle_timeout_secs", idle_secs)
    }

    /// A request the HTTP parser refused before any handler saw it, by the
    /// `status` the parser chose: 414 (`uri-too-long`), 431
    /// (`headers-too-large`), anything else `bad-request`.
    pub fn parser_rejection(status: StatusCode) -> Self {
        match status {
            StatusCode::URI_TOO_LONG => {
                Self::new(FailureKind::UriTooLong, "the request target exceeds this server's limit")
            }
            StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE => {
                Self::new(FailureKind::HeadersTooLarge, "the request has too many or too large header fields")
            }
            _ => Self::new(
                FailureKind::BadRequest,
                "the request head is malformed (e.g. control bytes in a header value)",
            ),
        }
    }

    /// The whole HTTP/1.1 answer (head and problem body, `Connection:
    /// close`) as bytes, for answering below the framework; logged like any
    /// other rejection.
    pub fn http1_bytes(&self, request_id: &str) -> Vec<u8> {
        tracing::info!(
            request_id,
            kind = self.0.kind.as_str(),
            status = self.0.status.as_u16(),
            "request rejected by the HTTP parser"
        );
        let body = serde_json::to_vec(&self.body(request_id)).unwrap_or_default();
        let status = self.0.status;
        let mut out = format!(
            "HTTP/1.1 {} {}\r\ncontent-type: {PROBLEM_JSON}\r\ncontent-length: {}\r\nconnection: close\r\n{REQUEST_ID_HEADER}: {request_id}\r\n\r\n",
            status.as_u16(),
            status.canonical_reason().unwrap_or(""),
            body.len()
        )
        .into_bytes();
        out.extend_from_slice(&body);
        out
    }

    /// The response with `request_id` (for answers built outside a request's
    /// task, where [`current_request_id`] is unknown).
    pub fn into_response_for(self, request_id: &str) -> Response {
        self.into_response_with_id(request_id)
    }

    /// The problem+json object of a failed job (shown inside the job
    /// resource; its `status` is what a synchronous request would have got).
    pub fn job_problem(e: &JobError) -> Value {
        let (status, title) = status_and_title(e.kind);
        let detail = if e.kind == FailureKind::InternalError {
            "the job stopped because of an internal error; it has been logged".to_string()
        } else {
            e.detail.clone()
        };
        json!({
            "type": problem_type(e.kind),
            "title": title,
            "status": status.as_u16(),
            "detail": detail,
        })
    }

    /// The problem body (with the current request id).
    fn body(&self, request_id: &str) -> Value {
        let detail = if self.is_hidden() {
            format!("the server could not complete the request; quote request id {request_id} when reporting it")
        } else {
            self.0.detail.clone()
        };
        let mut obj = Map::new();
        obj.insert("type".into(), Value::String(problem_type(self.0.kind)));
        obj.insert("title".into(), Value::String(self.0.title.into()));
        obj.insert("status".into(), Value::from(self.0.status.as_u16()));
        obj.insert("detail".into(), Value::String(detail));
        obj.insert("request_id".into(), Value::String(request_id.into()));
        if !self.is_hidden() {
            for (k, v) in &self.0.extra {
                obj.insert(k.clone(), v.clone());
            }
        }
        Value::Object(obj)
    }

    fn into_response_with_id(self, request_id: &str) -> Response {
        if self.is_hidden() {
            tracing::error!(
                request_id,
                kind = self.0.kind.as_str(),
                cause = self.0.cause.as_deref().unwrap_or(&self.0.detail),
                "request failed"
            );
        } else {
            tracing::info!(request_id, kind = self.0.kind.as_str(), status = self.0.status.as_u16(), detail = %self.0.detail, "request rejected");
        }
        let body = serde_json::to_vec(&self.body(request_id)).unwrap_or_default();
        let mut resp = Response::new(Body::from(body));
        *resp.status_mut() = self.0.status;
        resp.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
        if let Some(secs) = self.0.retry_after {
            resp.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(secs));
        }
        resp
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let id = current_request_id();
        self.into_response_with_id(&id)
    }
}

impl From<JobsError> for ApiError {
    fn from(e: JobsError) -> Self {
        match e {
            JobsError::NotFound(id) => Self::new(FailureKind::JobNotFound, format!("job {id} does not exist")),
            JobsError::ArtifactNotFound { id, name } => {
                Self::new(FailureKind::ArtifactNotFound, format!("job {id} has no artifact named `{name}`"))
            }
            JobsError::QueueFull { max_queued } => Self::new(
                FailureKind::QueueFull,
                format!("the job queue is full ({max_queued} jobs waiting); retry after the Retry-After delay"),
            ),
            e @ JobsError::MemoryBudgetExceeded { estimated_bytes, budget_bytes } => {
                Self::new(FailureKind::MemoryBudgetExceeded, e.to_string())
                    .with("estimated_bytes", estimated_bytes)
                    .with("budget_bytes", budget_bytes)
            }
            JobsError::TenantQueueFull { max_queued } => Self::new(
                FailureKind::TenantQueueFull,
                format!("you already have {max_queued} queued jobs; retry after the Retry-After delay"),
            )
            .with("max_queued", max_queued),
            JobsError::QuotaExceeded { tenant, max_bytes } => Self::new(
                FailureKind::InsufficientStorage,
                format!(
                    "storing this upload would exceed the {} storage quota of {max_bytes} bytes; \
                     delete finished jobs to make room",
                    if tenant { "tenant's" } else { "server's" }
                ),
            )
            .with("max_stored_bytes", max_bytes)
            .with("quota", if tenant { "tenant" } else { "server" })
            .exposed(),
            other => Self::storage(crate::jobs::storage::jobs_error_kind(&other), other),
        }
    }
}

/// A request id from the client's header, if it is short and plain.
fn client_request_id(headers: &HeaderMap) -> Option<String> {
    let v = headers.get(REQUEST_ID_HEADER)?.to_str().ok()?;
    let ok = !v.is_empty() && v.len() <= 128 && v.bytes().all(|b| b.is_ascii_alphanumeric() || b"-_.:".contains(&b));
    ok.then(|| v.to_string())
}

/// Kind for an error status produced outside our handlers (a status code
/// has no fixed set of values, so unknown ones fall back by class).
fn kind_for_status(status: StatusCode) -> FailureKind {
    match status {
        StatusCode::NOT_FOUND => FailureKind::NotFound,
        StatusCode::METHOD_NOT_ALLOWED => FailureKind::MethodNotAllowed,
        StatusCode::PAYLOAD_TOO_LARGE => FailureKind::UploadTooLarge,
        StatusCode::RANGE_NOT_SATISFIABLE => FailureKind::RangeNotSatisfiable,
        StatusCode::UNSUPPORTED_MEDIA_TYPE => FailureKind::UnsupportedMediaType,
        StatusCode::TOO_MANY_REQUESTS => FailureKind::QueueFull,
        StatusCode::SERVICE_UNAVAILABLE => FailureKind::ServiceUnavailable,
        s if s.is_client_error() => FailureKind::BadRequest,
        _ => FailureKind::InternalError,
    }
}

/// Middleware: request id, tracing span, access log, problem+json for every
/// error response.
pub async fn request_context(req: Request, next: Next) -> Response {
    let id = client_request_id(req.headers()).unwrap_or_else(|| uuid::Uuid::new_v4().simple().to_string());
    let span = tracing::info_span!("request", request_id = %id, method = %req.method(), path = %req.uri().path());
    let start = std::time::Instant::now();
    let resp = REQUEST_ID.scope(id.clone(), next.run(req).instrument(span.clone())).await;
    let mut resp = if resp.status().is_client_error() || resp.status().is_server_error() {
        let is_problem = resp
            .headers()
            .get(header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .is_some_and(|v| v.starts_with(PROBLEM_JSON));
        if is_problem { resp } else { problemize(resp, &id).instrument(span.clone()).await }
    } else {
        resp
    };
    if let Ok(v) = HeaderValue::from_str(&id) {
        resp.headers_mut().insert(REQUEST_ID_HEADER, v);
    }
    span.in_scope(|| {
        tracing::info!(status = resp.status().as_u16(), ms = start.elapsed().as_secs_f64() * 1e3, "request done");
    });
    resp
}

/// Rewrites a framework error response as problem+json, keeping its headers
/// (e.g. `Allow` of a 405) and its text as the detail.
async fn problemize(resp: Response, id: &str) -> Response {
    let (parts, body) = resp.into_parts();
    let text = match axum::body::to_bytes(body, 16 * 1024).await {
        Ok(b) => String::from_utf8_lossy(&b).trim().to_string(),
        Err(_) => String::new(),
    };
    let kind = kind_for_status(parts.status);
    let detail = match (kind, text.is_empty()) {
        (FailureKind::NotFound, true) => "no route matches this path; see api/openapi.yaml".to_string(),
        (FailureKind::MethodNotAllowed, true) => {
            "this path does not support this method (see the Allow header)".to_string()
        }
        (_, true) => parts.status.canonical_reason().unwrap_or("error").to_string(),
        (_, false) => text,
    };
    let mut err = if parts.status.is_server_error() { ApiError::internal(detail) } else { ApiError::new(kind, detail) };
    err.0.status = parts.status;
    let mut out = err.into_response_with_id(id);
    for (name, value) in &parts.headers {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            out.headers_mut().insert(name.clone(), value.clone());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_maps_to_an_error_status_and_a_title() {
        let mut titles = std::collections::BTreeSet::new();
        for &k in FailureKind::ALL {
            let (status, title) = status_and_title(k);
            assert!(status.is_client_error() || status.is_server_error(), "{k}: {status}");
            assert!(title.starts_with(char::is_uppercase) && !title.ends_with('.'), "{k}: title `{title}`");
            assert!(titles.insert(title), "{k}: title `{title}` is used by two kinds");
            let e = ApiError::new(k, "x");
            assert_eq!((e.kind(), e.status()), (k, status));
            assert_eq!(e.body("r")["type"], format!("urn:meshatlas:problem:{k}"));
        }
    }

    #[test]
    fn published_statuses_of_kinds_do_not_change() {
        // The statuses api/openapi.yaml documents for each kind.
        let cases = [
            (FailureKind::BadRequest, 400),
            (FailureKind::EmptyFile, 400),
            (FailureKind::Unauthorized, 401),
            (FailureKind::JobNotFound, 404),
            (FailureKind::MethodNotAllowed, 405),
            (FailureKind::UploadTimeout, 408),
            (FailureKind::UploadTooLarge, 413),
            (FailureKind::UriTooLong, 414),
            (FailureKind::UnknownFormat, 415),
            (FailureKind::RangeNotSatisfiable, 416),
            (FailureKind::InvalidParams, 422),
            (FailureKind::MemoryBudgetExceeded, 422),
            (FailureKind::TooManyTriangles, 422),
            (FailureKind::InvalidTargetSize, 422),
            (FailureKind::CrashedServer, 422),
            (FailureKind::TenantQueueFull, 429),
            (FailureKind::HeadersTooLarge, 431),
            (FailureKind::InternalError, 500),
            (FailureKind::StorageUnavailable, 503),
            (FailureKind::Interrupted, 503),
            (FailureKind::StorageFull, 507),
            (FailureKind::InsufficientStorage, 507),
        ];
        for (k, status) in cases {
            assert_eq!(status_and_title(k).0.as_u16(), status, "{k}");
        }
    }

    #[test]
    fn job_problems_carry_the_kind_and_hide_internal_details() {
        let p = ApiError::job_problem(&JobError::new(FailureKind::TooManyTriangles, "7 > 5"));
        assert_eq!(p["status"], 422);
        assert_eq!(p["type"], "urn:meshatlas:problem:too-many-triangles");
        assert_eq!(p["detail"], "7 > 5");
        let p = ApiError::job_problem(&JobError::new(FailureKind::InternalError, "secret panic text"));
        assert_eq!(p["status"], 500);
        assert!(!p["detail"].as_str().unwrap().contains("secret"));
        // A kind stored by another version reads back as an internal error, detail hidden.
        let stored: JobError = serde_json::from_value(json!({"kind": "write-failed", "detail": "EIO on /x"})).unwrap();
        let p = ApiError::job_problem(&stored);
        assert_eq!(
            (p["status"].as_u64(), p["type"].as_str()),
            (Some(500), Some("urn:meshatlas:problem:internal-error"))
        );
        assert!(!p["detail"].as_str().unwrap().contains("EIO"));
    }

    #[test]
    fn framework_statuses_get_a_kind_of_their_class() {
        assert_eq!(kind_for_status(StatusCode::NOT_FOUND), FailureKind::NotFound);
        assert_eq!(kind_for_status(StatusCode::LENGTH_REQUIRED), FailureKind::BadRequest);
        assert_eq!(kind_for_status(StatusCode::BAD_GATEWAY), FailureKind::InternalError);
    }

    /// The `enum` of `components.schemas.ProblemType` in api/openapi.yaml.
    fn documented_problem_types() -> Vec<String> {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/api/openapi.yaml");
        let text = std::fs::read_to_string(path).unwrap();
        let doc = yaml_rust2::YamlLoader::load_from_str(&text).unwrap().remove(0);
        let values = doc["components"]["schemas"]["ProblemType"]["enum"].as_vec().expect("ProblemType has an enum");
        values.iter().map(|v| v.as_str().expect("a string").to_string()).collect()
    }

    #[test]
    fn every_kind_and_only_kinds_have_a_documented_type_uri() {
        let documented = documented_problem_types();
        let unique: std::collections::BTreeSet<&str> = documented.iter().map(String::as_str).collect();
        assert_eq!(unique.len(), documented.len(), "a type is listed twice in ProblemType");
        for &k in FailureKind::ALL {
            let uri = problem_type(k);
            assert!(unique.contains(uri.as_str()), "kind `{k}`: {uri} is not in api/openapi.yaml ProblemType");
        }
        for uri in &documented {
            let kind = uri.strip_prefix(PROBLEM_TYPE_PREFIX).and_then(FailureKind::parse);
            assert!(kind.is_some(), "api/openapi.yaml ProblemType lists {uri}, which is no FailureKind");
        }
    }

    #[test]
    fn server_error_bodies_are_generic() {
        let e = ApiError::internal("disk /var/lib/x is full");
        let b = e.body("abc");
        assert_eq!(b["status"], 500);
        assert!(!b["detail"].as_str().unwrap().contains("disk"));
        assert_eq!(b["request_id"], "abc");
    }
}
