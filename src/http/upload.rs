//! Reading a job submission: the mesh streams to a file under the data
//! directory chunk by chunk (never held in memory), with the configured size
//! limit enforced while streaming (413), then cheap checks (empty file,
//! unknown format) before the job is queued.
//!
//! Two body shapes are accepted on `POST /v1/jobs`:
//! - raw: the body is the mesh file; format from `?format=`, else the
//!   `Content-Type`, else sniffed from the first bytes; parameters from the
//!   `params` query parameter (URL-encoded JSON) and/or the `stages`
//!   shorthand (`?stages=atlas,crossfield`);
//! - `multipart/form-data`: a `file` part (its file name's extension and
//!   Content-Type help detect the format) and an optional `params` part
//!   holding the JSON parameters; the preamble and part headers are capped
//!   (see [`super::multipart_framing`]).

use std::path::{Path, PathBuf};
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};

use axum::body::Bytes;
use axum::http::{HeaderMap, header};
use futures_util::{Stream, StreamExt};
use serde::Deserialize;
use tokio::io::AsyncWriteExt;

use super::error::ApiError;
use super::multipart_framing::{FramingError, FramingGuard, MAX_PART_HEADER_BYTES, MAX_PREAMBLE_BYTES};
use crate::failure::FailureKind;
use crate::io::Format;
use crate::jobs::artifact_store::StreamingPut;

/// Bytes kept from the start of the upload for format sniffing.
pub const HEAD_BYTES: usize = 4096;
/// Largest accepted `params` part or query value.
pub const MAX_PARAMS_BYTES: usize = 64 * 1024;

/// Query parameters of `POST /v1/jobs`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubmitQuery {
    /// Input format (`stl`, `obj`, `ply`, `msh`); overrides detection.
    pub format: Option<String>,
    /// Pipeline parameters as JSON (raw uploads; multipart may use a part).
    pub params: Option<String>,
    /// Comma-separated stages, shorthand for `{"stages": [...]}`.
    pub stages: Option<String>,
    /// Client-side file name for a raw upload (for reports).
    pub filename: Option<String>,
}

/// Opens the artifact-store transfer of an upload once the client's file
/// name is known (`None` from the part or the query: the default name);
/// it answers `None` when the data directory is the store.
pub type OpenRemote<'a> = &'a (dyn Fn(Option<&str>) -> Option<StreamingPut> + Send + Sync);

/// The input's file name as the job records it: the last path component
/// of the client's name, at most 200 characters, `upload` when none.
pub fn input_name(client_name: Option<&str>) -> String {
    client_name
        .map(|n| n.rsplit(['/', '\\']).next().unwrap_or(n).chars().take(200).collect::<String>())
        .filter(|n| !n.is_empty())
        .unwrap_or_else(|| "upload".to_string())
}

/// A received upload, stored in a temporary file removed on drop unless
/// [`Upload::keep`] is called.
pub struct Upload {
    /// The temporary file.
    pub path: PathBuf,
    /// Bytes received.
    pub bytes: u64,
    /// The first [`HEAD_BYTES`] bytes.
    pub head: Vec<u8>,
    /// File name given by the client (multipart file name or `?filename=`).
    pub filename: Option<String>,
    /// Content-Type of the body or of the file part.
    pub content_type: Option<String>,
    /// Raw JSON of a multipart `params` part.
    pub params_part: Option<Vec<u8>>,
    /// The file is also in the artifact store, streamed there as it came.
    pub stored: bool,
    keep: bool,
}

impl Upload {
    fn new(path: PathBuf) -> Self {
        Self {
            path,
            bytes: 0,
            head: Vec::new(),
            filename: None,
            content_type: None,
            params_part: None,
            stored: false,
            keep: false,
        }
    }

    /// The file now belongs to someone else (the job); do not remove it.
    pub fn keep(&mut self) {
        self.keep = true;
    }
}

impl Drop for Upload {
    fn drop(&mut self) {
        if !self.keep {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// The declared body length, when the client sent one.
pub fn content_length(headers: &HeaderMap) -> Option<u64> {
    headers.get(header::CONTENT_LENGTH)?.to_str().ok()?.parse().ok()
}

/// The media type of a header value, lowercased, without parameters.
pub fn media_type(headers: &HeaderMap) -> Option<String> {
    let v = headers.get(header::CONTENT_TYPE)?.to_str().ok()?;
    let mt = v.split(';').next().unwrap_or("").trim().to_ascii_lowercase();
    (!mt.is_empty()).then_some(mt)
}

/// True when the client waits for `100 Continue` before sending the body.
pub fn expects_continue(headers: &HeaderMap) -> bool {
    headers.get(header::EXPECT).and_then(|v| v.to_str().ok()).is_some_and(|v| v.eq_ignore_ascii_case("100-continue"))
}

/// The answer to a rejected upload whose body the client has not sent (it
/// asked `Expect: 100-continue`): the error with `Connection: close`, and
/// the body is never polled, so no `100 Continue` goes out and the client
/// does not upload.
pub fn refuse_unsent(e: ApiError) -> axum::response::Response {
    let mut resp = axum::response::IntoResponse::into_response(e);
    resp.headers_mut().insert(header::CONNECTION, axum::http::HeaderValue::from_static("close"));
    resp
}

/// Most bytes read and discarded after a rejected upload.
pub const DRAIN_MAX_BYTES: u64 = 16 * 1024 * 1024;
/// Longest time spent discarding a rejected upload.
pub const DRAIN_MAX_TIME: std::time::Duration = std::time::Duration::from_secs(2);

/// Reads and discards what is left of a rejected upload (at most
/// [`DRAIN_MAX_BYTES`] for at most [`DRAIN_MAX_TIME`]), so that a client
/// still sending gets the error response instead of a connection reset.
/// Larger uploads are cut off: the connection closes after the response.
pub async fn drain<E>(mut stream: impl Stream<Item = Result<Bytes, E>> + Unpin) {
    let discard = async {
        let mut n = 0u64;
        while let Some(Ok(chunk)) = stream.next().await {
            n += chunk.len() as u64;
            if n > DRAIN_MAX_BYTES {
                break;
            }
        }
    };
    let _ = tokio::time::timeout(DRAIN_MAX_TIME, discard).await;
}

/// Streams `stream` into `upload`'s file, enforcing `limit` on the total,
/// and into `remote` (the artifact store) chunk by chunk beside it, so
/// the upload is in the store when its last byte is on disk. A failed or
/// cut-off upload drops `remote`, which aborts it.
async fn stream_to_file<E: std::fmt::Display>(
    mut stream: impl Stream<Item = Result<Bytes, E>> + Unpin,
    upload: &mut Upload,
    limit: u64,
    mut remote: Option<StreamingPut>,
) -> Result<(), ApiError> {
    let mut file = tokio::fs::File::create(&upload.path)
        .await
        .map_err(|e| ApiError::io(&format!("cannot create {}", upload.path.display()), &e))?;
    while let Some(chunk) = stream.next().await {
        let chunk = chunk
            .map_err(|e| ApiError::new(FailureKind::UploadInterrupted, format!("reading the upload failed: {e}")))?;
        upload.bytes += chunk.len() as u64;
        if upload.bytes > limit {
            drain(stream).await;
            return Err(ApiError::upload_too_large(limit));
        }
        if upload.head.len() < HEAD_BYTES {
            let take = (HEAD_BYTES - upload.head.len()).min(chunk.len());
            upload.head.extend_from_slice(&chunk[..take]);
        }
        if let Some(r) = &mut remote {
            r.write(chunk.clone()).await.map_err(stored_err)?;
        }
        file.write_all(&chunk).await.map_err(|e| ApiError::io("writing the upload", &e))?;
    }
    crate::jobs::storage::flush_and_sync(&mut file).await.map_err(|e| ApiError::io("writing the upload", &e))?;
    if let Some(r) = remote {
        r.finish().await.map_err(stored_err)?;
        upload.stored = true;
    }
    Ok(())
}

/// The client-facing error of a failed transfer to the artifact store.
fn stored_err(e: crate::jobs::artifact_store::ArtifactError) -> ApiError {
    crate::jobs::JobsError::Artifacts(e).into()
}

/// Receives a raw body into `path`.
///
/// # Errors
/// 413 past `limit`, 400 when the connection breaks, 500 on disk errors.
pub async fn receive_raw(
    body: axum::body::Body,
    headers: &HeaderMap,
    path: PathBuf,
    limit: u64,
    remote: OpenRemote<'_>,
) -> Result<Upload, ApiError> {
    let mut up = Upload::new(path);
    up.content_type = media_type(headers);
    stream_to_file(body.into_data_stream(), &mut up, limit, remote(None)).await?;
    Ok(up)
}

/// A stream shared between the multipart parser and the code that drains
/// the rest of a rejected body.
struct SharedStream<S>(Arc<Mutex<S>>);

impl<S> Clone for SharedStream<S> {
    fn clone(&self) -> Self {
        Self(Arc::clone(&self.0))
    }
}

impl<S: Stream + Unpin> Stream for SharedStream<S> {
    type Item = S::Item;

    fn poll_next(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<S::Item>> {
        match self.0.lock() {
            Ok(mut s) => s.poll_next_unpin(cx),
            Err(_) => Poll::Ready(None),
        }
    }
}

/// The parser's limits: the whole body may hold the upload limit plus the
/// `params` part and the (capped) framing; a `params` part at most
/// [`MAX_PARAMS_BYTES`], the `file` part at most `limit`.
fn multipart_constraints(limit: u64) -> multer::Constraints {
    let framing = (MAX_PREAMBLE_BYTES + 4 * MAX_PART_HEADER_BYTES + 1024) as u64;
    let params = MAX_PARAMS_BYTES as u64;
    multer::Constraints::new().size_limit(
        multer::SizeLimit::new()
            .whole_stream(limit.saturating_add(params).saturating_add(framing))
            .per_field(params)
            .for_field("params", params)
            .for_field("file", limit),
    )
}

/// The client-facing error for a multipart parser error.
fn multipart_error(e: multer::Error, limit: u64) -> ApiError {
    match e {
        multer::Error::StreamReadFailed(inner) => match inner.downcast_ref::<FramingError>() {
            Some(FramingError::Body(cause)) => {
                ApiError::new(FailureKind::UploadInterrupted, format!("reading the upload failed: {cause}"))
            }
            Some(framing) => ApiError::new(FailureKind::InvalidMultipart, framing.to_string()),
            None => ApiError::new(FailureKind::UploadInterrupted, format!("reading the upload failed: {inner}")),
        },
        multer::Error::StreamSizeExceeded { .. } => ApiError::upload_too_large(limit),
        multer::Error::FieldSizeExceeded { field_name, .. } if field_name.as_deref() == Some("file") => {
            ApiError::upload_too_large(limit)
        }
        multer::Error::FieldSizeExceeded { field_name, .. } => {
            let name = field_name.unwrap_or_default();
            ApiError::new(FailureKind::InvalidParams, format!("the `{name}` part exceeds {MAX_PARAMS_BYTES} bytes"))
        }
        other => ApiError::new(FailureKind::InvalidMultipart, other.to_string()),
    }
}

/// A part's data as a stream whose parser errors are kept, classified, in
/// `error` (the file writer only sees their text).
struct PartData<'a> {
    field: multer::Field<'static>,
    limit: u64,
    error: &'a mut Option<ApiError>,
}

impl Stream for PartData<'_> {
    type Item = Result<Bytes, String>;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        match self.field.poll_next_unpin(cx) {
            Poll::Ready(Some(Err(e))) => {
                let err = multipart_error(e, self.limit);
                let text = err.kind().to_string();
                *self.error = Some(err);
                Poll::Ready(Some(Err(text)))
            }
            Poll::Ready(Some(Ok(b))) => Poll::Ready(Some(Ok(b))),
            Poll::Ready(None) => Poll::Ready(None),
            Poll::Pending => Poll::Pending,
        }
    }
}

/// Reads a small text part (params) with a size cap.
async fn read_small_part(mut field: multer::Field<'static>, name: &str, limit: u64) -> Result<Vec<u8>, ApiError> {
    let mut buf = Vec::new();
    while let Some(chunk) = field.chunk().await.map_err(|e| multipart_error(e, limit))? {
        buf.extend_from_slice(&chunk);
        if buf.len() > MAX_PARAMS_BYTES {
            return Err(ApiError::new(
                FailureKind::InvalidParams,
                format!("the `{name}` part exceeds {MAX_PARAMS_BYTES} bytes"),
            ));
        }
    }
    Ok(buf)
}

/// The boundary of a `multipart/form-data` Content-Type.
fn multipart_boundary(headers: &HeaderMap) -> Result<String, ApiError> {
    let ct = headers.get(header::CONTENT_TYPE).and_then(|v| v.to_str().ok()).unwrap_or("");
    multer::parse_boundary(ct).map_err(|e| ApiError::new(FailureKind::InvalidMultipart, format!("Content-Type: {e}")))
}

/// Receives a multipart body: one `file` part (streamed to `path`) and an
/// optional `params` part. Other part names are rejected. The preamble and
/// each part's headers are capped ([`MAX_PREAMBLE_BYTES`],
/// [`MAX_PART_HEADER_BYTES`]) and the whole body may exceed `limit` only by
/// the `params` part and that framing. After an error what is left of the
/// body is drained (see [`drain`]).
///
/// # Errors
/// 400 for malformed multipart (framing over its caps included), a missing
/// or repeated part, or an unknown part; 413 past `limit`; 422 for a
/// `params` part over [`MAX_PARAMS_BYTES`]; 500 on disk errors.
pub async fn receive_multipart(
    body: axum::body::Body,
    headers: &HeaderMap,
    path: PathBuf,
    limit: u64,
    remote: OpenRemote<'_>,
) -> Result<Upload, ApiError> {
    let boundary = multipart_boundary(headers)?;
    let shared = SharedStream(Arc::new(Mutex::new(body.into_data_stream())));
    let guarded = FramingGuard::new(shared.clone(), &boundary);
    let mp = multer::Multipart::with_constraints(guarded, boundary, multipart_constraints(limit));
    let result = read_parts(mp, path, limit, remote).await;
    if result.is_err() {
        drain(shared).await;
    }
    result
}

/// Reads the parts of `mp` (see [`receive_multipart`]).
async fn read_parts(
    mut mp: multer::Multipart<'static>,
    path: PathBuf,
    limit: u64,
    remote: OpenRemote<'_>,
) -> Result<Upload, ApiError> {
    let mut up = Upload::new(path);
    let mut have_file = false;
    while let Some(field) = mp.next_field().await.map_err(|e| multipart_error(e, limit))? {
        let name = field.name().unwrap_or("").to_string();
        match name.as_str() {
            "file" => {
                if have_file {
                    return Err(ApiError::new(FailureKind::InvalidMultipart, "more than one `file` part"));
                }
                have_file = true;
                up.filename = field.file_name().map(str::to_string);
                up.content_type = field
                    .headers()
                    .get(header::CONTENT_TYPE)
                    .and_then(|v| v.to_str().ok())
                    .map(|c| c.split(';').next().unwrap_or("").trim().to_ascii_lowercase());
                let mut error = None;
                let sink = remote(up.filename.as_deref());
                let written = stream_to_file(PartData { field, limit, error: &mut error }, &mut up, limit, sink).await;
                if let Err(e) = written {
                    return Err(error.unwrap_or(e));
                }
            }
            "params" => {
                if up.params_part.is_some() {
                    return Err(ApiError::new(FailureKind::InvalidMultipart, "more than one `params` part"));
                }
                up.params_part = Some(read_small_part(field, "params", limit).await?);
            }
            other => {
                return Err(ApiError::new(
                    FailureKind::InvalidMultipart,
                    format!("unknown part `{other}`; expected `file` and optionally `params`"),
                )
                .with("part", other));
            }
        }
    }
    if !have_file {
        return Err(ApiError::new(FailureKind::MissingFile, "the multipart body has no `file` part"));
    }
    Ok(up)
}

/// Media types that say nothing about the format (then it is detected).
fn is_generic_media_type(mt: &str) -> bool {
    matches!(mt, "application/octet-stream" | "text/plain" | "application/x-www-form-urlencoded")
}

/// The input format from, in order: `?format=` (its name in any case), the
/// Content-Type, the file name's extension, the content (first bytes and
/// total size). `None` when none of them names a format: the job's reader
/// then fails with `unknown-format`, so every non-empty body the spec
/// describes is accepted here (the spec cannot say which bytes are a mesh).
///
/// # Errors
/// 400 for an unknown `?format=`; 415 for a Content-Type that is not a mesh
/// (`unsupported-media-type`).
pub fn resolve_format(explicit: Option<&str>, upload: &Upload) -> Result<Option<Format>, ApiError> {
    if let Some(name) = explicit {
        return Format::ALL.into_iter().find(|f| f.extension().eq_ignore_ascii_case(name)).map(Some).ok_or_else(|| {
            let names: Vec<&str> = Format::ALL.iter().map(|f| f.extension()).collect();
            ApiError::new(FailureKind::InvalidQuery, format!("format `{name}` is not one of {}", names.join(", ")))
                .with("field", "format")
        });
    }
    if let Some(mt) = upload.content_type.as_deref()
        && !is_generic_media_type(mt)
    {
        return Format::from_media_type(mt).map(Some).ok_or_else(|| {
            ApiError::new(
                FailureKind::UnsupportedMediaType,
                format!(
                    "Content-Type `{mt}` is not a mesh format; send model/stl, model/obj, model/ply, \
                     application/x-gmsh or application/octet-stream, or multipart/form-data"
                ),
            )
        });
    }
    let ext = upload.filename.as_deref().and_then(|n| Path::new(n).extension()).and_then(|e| e.to_str());
    if let Some(f) = ext.and_then(Format::from_extension) {
        return Ok(Some(f));
    }
    Ok(Format::sniff(&upload.head, Some(upload.bytes)))
}
