//! Route handlers: thin adapters from HTTP to [`crate::jobs::JobService`].

use axum::Json;
use axum::body::Body;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, Request, State};
use axum::http::request::Parts;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::{Value, json};
use tower::ServiceExt;

use super::AppState;
use super::auth::Scope;
use super::encoding::{self, Coding};
use super::error::ApiError;
use super::upload::{self, SubmitQuery};
use super::{page, range};
use crate::failure::FailureKind;
use crate::jobs::{JobId, JobRecord, JobsError, NewJob, model::rfc3339};
use crate::pipeline::parse_params;

/// URL path of a job.
pub fn job_url(id: JobId) -> String {
    format!("/v1/jobs/{id}")
}

/// The job resource as JSON.
pub fn job_json(rec: &JobRecord) -> Value {
    let artifacts: Vec<Value> = rec
        .artifacts
        .iter()
        .map(|a| {
            json!({
                "name": a.name,
                "bytes": a.bytes,
                "media_type": a.media_type,
                "url": format!("{}/artifacts/{}", job_url(rec.id), a.name),
            })
        })
        .collect();
    json!({
        "id": rec.id,
        "url": job_url(rec.id),
        "state": rec.state,
        "created_at": rfc3339(rec.created_ms),
        "started_at": rec.started_ms.map(rfc3339),
        "finished_at": rec.finished_ms.map(rfc3339),
        "input": { "name": rec.input_name, "bytes": rec.input_bytes, "format": rec.format },
        "params": rec.params,
        "stage": rec.stage,
        "progress": rec.progress,
        "stage_seconds": rec.stage_seconds,
        "attempts": rec.attempts,
        "crashes": rec.crashes,
        "memory_estimate_bytes": rec.memory_estimate_bytes,
        "stop_requested": rec.stop_requested,
        "status_message": rec.status_message,
        "summary": rec.summary,
        "error": rec.error.as_ref().map(ApiError::job_problem),
        "artifacts": artifacts,
    })
}

fn parse_id(id: &str) -> Result<JobId, ApiError> {
    id.parse::<JobId>().map_err(|e| ApiError::new(FailureKind::JobNotFound, e.to_string()))
}

/// The job id of the path if the caller may see that job; another tenant's
/// job answers 404 exactly like a missing one.
async fn visible_id(st: &AppState, scope: &Scope, id: &str) -> Result<JobId, ApiError> {
    let id = parse_id(id)?;
    st.jobs.check_visible(id, scope.tenant()).await?;
    Ok(id)
}

/// Bytes a multipart body may carry besides the file (part headers, the
/// `params` part, boundaries), so the early quota check on the declared
/// Content-Length never refuses what the check on the real size accepts.
const MULTIPART_ALLOWANCE: u64 = 128 * 1024;

/// A submission refused by a per-tenant or stored-bytes limit (429 with
/// Retry-After, or 507).
fn refused(st: &AppState, e: JobsError) -> ApiError {
    let retry = matches!(e, JobsError::TenantQueueFull { .. });
    let err = ApiError::from(e);
    if retry { err.retry_after(st.limits.retry_after_secs) } else { err }
}

fn bad_query(e: QueryRejection) -> ApiError {
    ApiError::new(FailureKind::InvalidQuery, e.body_text())
}

/// The names of `?stages=`: empty for none, else the items between single
/// commas, verbatim (the spec's pattern), so an empty item or one with
/// spaces is an unknown stage (422 from the parameter check, naming it).
fn stage_list(stages: &str) -> Vec<Value> {
    if stages.is_empty() {
        return Vec::new();
    }
    stages.split(',').map(|s| Value::String(s.into())).collect()
}

/// Builds the params JSON from the multipart part, `?params=` and `?stages=`.
fn params_json(q: &SubmitQuery, part: Option<&[u8]>) -> Result<Value, ApiError> {
    let given = match (part, q.params.as_deref()) {
        (Some(_), Some(_)) => {
            return Err(ApiError::new(
                FailureKind::BadRequest,
                "parameters given twice: both a `params` part and a `params` query parameter",
            ));
        }
        (Some(p), None) => Some(p.to_vec()),
        (None, Some(p)) => Some(p.as_bytes().to_vec()),
        (None, None) => None,
    };
    if given.as_ref().is_some_and(|g| g.len() > upload::MAX_PARAMS_BYTES) {
        return Err(ApiError::new(FailureKind::InvalidParams, "parameters exceed 64 KiB"));
    }
    let mut value: Value = match &given {
        Some(bytes) => {
            // Validate fully first so errors name the field.
            parse_params(bytes).map_err(ApiError::params)?;
            serde_json::from_slice(bytes).map_err(|e| ApiError::new(FailureKind::InvalidJson, e.to_string()))?
        }
        None => json!({}),
    };
    if let Some(stages) = q.stages.as_deref() {
        let list = stage_list(stages);
        match value.as_object_mut() {
            Some(obj) if obj.contains_key("stages") => {
                return Err(ApiError::new(
                    FailureKind::BadRequest,
                    "stages given twice: in `params` and in `?stages=`",
                ));
            }
            Some(obj) => {
                obj.insert("stages".into(), Value::Array(list));
            }
            None => return Err(ApiError::new(FailureKind::InvalidParams, "parameters must be a JSON object")),
        }
    }
    let bytes = serde_json::to_vec(&value).map_err(ApiError::internal)?;
    let params = parse_params(&bytes).map_err(ApiError::params)?;
    serde_json::to_value(params).map_err(ApiError::internal)
}

/// `POST /v1/jobs`: stream the upload to disk, validate, queue the job.
pub async fn submit_job(
    State(st): State<AppState>,
    scope: Scope,
    query: Result<Query<SubmitQuery>, QueryRejection>,
    req: Request,
) -> Result<Response, ApiError> {
    // Errors found before the body is read still read (and discard) it, so
    // the client gets the answer rather than a reset connection.
    let headers = req.headers().clone();
    let early = async {
        let Query(q) = query.map_err(bad_query)?;
        let limit = st.limits.max_upload_bytes;
        if upload::content_length(&headers).is_some_and(|n| n > limit) {
            return Err(ApiError::upload_too_large(limit));
        }
        if !st.jobs.has_queue_room().await? {
            return Err(queue_full(&st));
        }
        let is_multipart = upload::media_type(&headers).is_some_and(|m| m == "multipart/form-data");
        let allowance = if is_multipart { MULTIPART_ALLOWANCE } else { 0 };
        let declared = upload::content_length(&headers).unwrap_or(0).saturating_sub(allowance);
        st.jobs.check_admission(scope.tenant(), declared).await.map_err(|e| refused(&st, e))?;
        // Parameters of a raw upload are all in the query: reject bad ones before reading the body.
        let early_params = if is_multipart { None } else { Some(params_json(&q, None)?) };
        Ok((q, limit, is_multipart, early_params))
    };
    let (q, limit, is_multipart, early_params) = match early.await {
        Ok(v) => v,
        Err(e) if upload::expects_continue(&headers) => return Ok(upload::refuse_unsent(e)),
        Err(e) => {
            upload::drain(req.into_body().into_data_stream()).await;
            return Err(e);
        }
    };
    let path = st.jobs.upload_path();
    let id = JobId::random();
    let jobs = st.jobs.clone();
    let query_name = q.filename.clone();
    let remote =
        move |part_name: Option<&str>| jobs.stream_input(id, &upload::input_name(part_name.or(query_name.as_deref())));
    let received = if is_multipart {
        upload::receive_multipart(req.into_body(), &headers, path, limit, &remote).await
    } else {
        upload::receive_raw(req.into_body(), &headers, path, limit, &remote).await
    };
    let mut up = received?;
    // Until the submission takes it, an upload streamed into the store is removed with the refusal.
    let stored = StoredInput { jobs: &st.jobs, id, armed: up.stored };
    if up.filename.is_none() {
        up.filename = q.filename.clone();
    }
    let params = match early_params {
        Some(p) => p,
        None => params_json(&q, up.params_part.as_deref())?,
    };
    if up.bytes == 0 {
        return Err(ApiError::new(FailureKind::EmptyFile, "the uploaded mesh file is empty (0 bytes)"));
    }
    let format = upload::resolve_format(q.format.as_deref(), &up)?;
    let input_name = upload::input_name(up.filename.as_deref());
    let new = NewJob {
        id,
        input_stored: up.stored,
        upload_path: up.path.clone(),
        input_name,
        input_bytes: up.bytes,
        format: format.map(|f| f.extension().to_string()),
        params,
        tenant: scope.tenant(),
    };
    // From here on the submission removes what it refuses.
    stored.disarm();
    let rec = match st.jobs.submit(new).await {
        Ok(rec) => {
            up.keep();
            rec
        }
        Err(crate::jobs::JobsError::QueueFull { .. }) => return Err(queue_full(&st)),
        Err(e @ (JobsError::TenantQueueFull { .. } | JobsError::QuotaExceeded { .. })) => return Err(refused(&st, e)),
        Err(e) => return Err(e.into()),
    };
    let mut resp = (StatusCode::ACCEPTED, Json(job_json(&rec))).into_response();
    if let Ok(v) = HeaderValue::from_str(&job_url(rec.id)) {
        resp.headers_mut().insert(header::LOCATION, v);
    }
    Ok(resp)
}

/// Removes an upload streamed into the artifact store when the request
/// ends before [`crate::jobs::JobService::submit`] takes it over (its
/// parameters, format or size refused).
struct StoredInput<'a> {
    jobs: &'a crate::jobs::JobService,
    id: JobId,
    armed: bool,
}

impl StoredInput<'_> {
    /// The submission owns the object now.
    fn disarm(mut self) {
        self.armed = false;
    }
}

impl Drop for StoredInput<'_> {
    fn drop(&mut self) {
        if self.armed {
            self.jobs.forget_streamed_input(self.id);
        }
    }
}

fn queue_full(st: &AppState) -> ApiError {
    let max = st.jobs.config().max_queued;
    ApiError::new(FailureKind::QueueFull, format!("the job queue is full ({max} jobs waiting); retry later"))
        .retry_after(st.limits.retry_after_secs)
        .with("max_queued", max)
}

/// `GET /v1/jobs/{id}`: the job as JSON, or the browser page's static
/// shell when `Accept` prefers HTML ([`page::prefers_html`]; the shell needs
/// no token, so the scope is only read for JSON). Both answers vary by
/// `Accept`.
pub async fn get_job(
    State(st): State<AppState>,
    headers: HeaderMap,
    scope: Result<Scope, ApiError>,
    Path(id): Path<String>,
) -> Response {
    let mut resp =
        if page::prefers_html(&headers) { page::shell() } else { job_answer(&st, scope, &id).await.into_response() };
    resp.headers_mut().insert(header::VARY, HeaderValue::from_static("accept"));
    resp
}

/// The JSON answer of `GET /v1/jobs/{id}` for `scope`.
async fn job_answer(st: &AppState, scope: Result<Scope, ApiError>, id: &str) -> Result<Json<Value>, ApiError> {
    let scope = scope?;
    let rec = st.jobs.get(visible_id(st, &scope, id).await?).await?;
    Ok(Json(job_json(&rec)))
}

/// Query of `GET /v1/jobs`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ListQuery {
    /// Page size, 1–100 (default 20).
    pub limit: Option<usize>,
    /// `next_cursor` of the previous page.
    pub cursor: Option<String>,
}

/// Longest cursor: 18 decimal digits always fit an `i64`.
const MAX_CURSOR_DIGITS: usize = 18;

/// The position of a `?cursor=`: empty or absent is the first page, else
/// 1–18 ASCII digits (the spec's pattern `^[0-9]{0,18}$`); a sign, spaces or
/// anything else is rejected rather than read leniently, so the spec says
/// exactly what is accepted.
fn parse_cursor(cursor: Option<&str>) -> Result<Option<i64>, ApiError> {
    let c = match cursor {
        None | Some("") => return Ok(None),
        Some(c) => c,
    };
    let digits = c.len() <= MAX_CURSOR_DIGITS && c.bytes().all(|b| b.is_ascii_digit());
    match c.parse::<i64>() {
        Ok(n) if digits => Ok(Some(n)),
        _ => {
            Err(ApiError::new(FailureKind::InvalidQuery, format!("cursor `{c}` is not a cursor from a previous page"))
                .with("field", "cursor"))
        }
    }
}

/// `GET /v1/jobs`: newest first, cursor pagination.
pub async fn list_jobs(
    State(st): State<AppState>,
    scope: Scope,
    query: Result<Query<ListQuery>, QueryRejection>,
) -> Result<Json<Value>, ApiError> {
    let Query(q) = query.map_err(bad_query)?;
    let limit = q.limit.unwrap_or(20);
    if !(1..=100).contains(&limit) {
        return Err(
            ApiError::new(FailureKind::InvalidQuery, format!("limit {limit} is not in 1..=100")).with("field", "limit")
        );
    }
    let cursor = parse_cursor(q.cursor.as_deref())?;
    let page = st.jobs.list(limit, cursor, scope.tenant()).await?;
    Ok(Json(json!({
        "jobs": page.jobs.iter().map(job_json).collect::<Vec<_>>(),
        "next_cursor": page.next_cursor.map(|c| c.to_string()),
    })))
}

/// `POST /v1/jobs/{id}/cancel`: stop a queued or running job, keep its
/// record. 200 once it stopped; 202 with `stop_requested` while the stop is
/// pending.
pub async fn cancel_job(
    State(st): State<AppState>,
    scope: Scope,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let rec = st.jobs.cancel(visible_id(&st, &scope, &id).await?).await?;
    let status = if rec.stop_requested { StatusCode::ACCEPTED } else { StatusCode::OK };
    Ok((status, Json(job_json(&rec))).into_response())
}

/// `DELETE /v1/jobs/{id}`: cancel if running, then remove record and files.
/// 204 once gone; 202 with the job (`stop_requested`) while the running job
/// has not stopped yet (its files go when it does). When some of the job's
/// files could not be removed, the record is gone all the same and the answer
/// is 200 with `not_removed` (paths relative to the data directory).
pub async fn delete_job(
    State(st): State<AppState>,
    scope: Scope,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id = visible_id(&st, &scope, &id).await?;
    let deletion = st.jobs.delete(id).await?;
    if let Some(rec) = deletion.pending {
        return Ok((StatusCode::ACCEPTED, Json(job_json(&rec))).into_response());
    }
    if deletion.not_removed.is_empty() {
        return Ok(StatusCode::NO_CONTENT.into_response());
    }
    let body = json!({"id": id, "deleted": true, "not_removed": deletion.not_removed});
    Ok((StatusCode::OK, Json(body)).into_response())
}

/// Serves the file at `path` for `req`, with `range` (canonical, from
/// [`range::range_to_serve`]) as the only `Range` the file server sees.
async fn serve_file(path: &std::path::Path, req: &Parts, range: Option<&str>) -> Result<Response, ApiError> {
    let mut inner = Request::new(Body::empty());
    *inner.method_mut() = req.method.clone();
    *inner.uri_mut() = req.uri.clone();
    *inner.headers_mut() = req.headers.clone();
    inner.headers_mut().remove(header::RANGE);
    if let Some(v) = range.and_then(|r| HeaderValue::from_str(r).ok()) {
        inner.headers_mut().insert(header::RANGE, v);
    }
    let served = tower_http::services::ServeFile::new(path).oneshot(inner).await.map_err(ApiError::internal)?;
    if served.status() == StatusCode::NOT_FOUND {
        return Err(ApiError::internal(format!("artifact file {} is missing", path.display())));
    }
    Ok(served.map(Body::new))
}

/// The identity bytes of the artifact at `path`, honouring one `Range`.
async fn serve_identity(path: &std::path::Path, req: &Parts) -> Result<Response, ApiError> {
    let range = range::range_to_serve(&req.headers);
    let mut resp = serve_file(path, req, range.as_deref()).await?;
    if range.is_some() && !range::if_range_holds(&req.headers, resp.headers()) {
        resp = serve_file(path, req, None).await?;
    }
    if resp.status() == StatusCode::RANGE_NOT_SATISFIABLE {
        return Ok(range_not_satisfiable(range.as_deref().unwrap_or(""), &resp));
    }
    Ok(resp)
}

/// The 416 problem for a range past the end, keeping `Content-Range: bytes */LEN`.
fn range_not_satisfiable(range: &str, served: &Response) -> Response {
    let content_range = served.headers().get(header::CONTENT_RANGE).cloned();
    let len = content_range.as_ref().and_then(|v| v.to_str().ok()).and_then(|v| v.strip_prefix("bytes */"));
    let detail = match len {
        Some(len) => format!("the range `{range}` lies outside the artifact's {len} bytes"),
        None => format!("the range `{range}` lies outside the artifact"),
    };
    let mut resp = ApiError::new(FailureKind::RangeNotSatisfiable, detail).into_response();
    if let Some(v) = content_range {
        resp.headers_mut().insert(header::CONTENT_RANGE, v);
    }
    resp
}

/// The `coding` representation of the artifact at `path` (made on first
/// use, see [`encoding`]), served with its `Content-Encoding`.
async fn serve_encoded(path: &std::path::Path, req: &Parts, coding: Coding) -> Result<Response, ApiError> {
    let src = path.to_path_buf();
    let enc = tokio::task::spawn_blocking(move || encoding::ensure_encoded(&src, coding))
        .await
        .map_err(ApiError::internal)?
        .map_err(|e| ApiError::internal(format!("cannot {}-encode {}: {e}", coding.token(), path.display())))?;
    let mut resp = serve_file(&enc, req, None).await?;
    if resp.status().is_success() || resp.status() == StatusCode::NOT_MODIFIED {
        resp.headers_mut().insert(header::CONTENT_ENCODING, HeaderValue::from_static(coding.token()));
    }
    Ok(resp)
}

/// Query of `GET /v1/jobs/{id}/artifacts/{name}` (other parameters are
/// ignored, e.g. a browser's cache buster).
#[derive(Debug, Deserialize)]
pub struct ArtifactQuery {
    /// `1`: answer 307 to a presigned URL of the artifact store when it has
    /// them (S3); `0` or absent: serve the file.
    #[serde(default, deserialize_with = "zero_or_one")]
    pub redirect: Option<u8>,
}

/// `0` or `1` exactly (the spec's enum); anything else is a 400.
fn zero_or_one<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<u8>, D::Error> {
    match String::deserialize(d)?.as_str() {
        "0" => Ok(Some(0)),
        "1" => Ok(Some(1)),
        other => Err(serde::de::Error::custom(format!("redirect must be 0 or 1, not {other:?}"))),
    }
}

/// 307 to `url`, not cached (the URL expires).
fn presigned_redirect(url: &str) -> Response {
    let mut resp = StatusCode::TEMPORARY_REDIRECT.into_response();
    if let Ok(v) = HeaderValue::from_str(url) {
        resp.headers_mut().insert(header::LOCATION, v);
    }
    resp.headers_mut().insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    resp
}

/// `GET /v1/jobs/{id}/artifacts/{name}`: the file, with one byte range at
/// most (RFC 9110: unknown units, invalid or multiple ranges give the whole
/// file; a stale `If-Range` too). Without `Range`, a client whose
/// `Accept-Encoding` allows zstd or gzip gets that representation; see
/// [`encoding`]. With `?redirect=1` and an S3 artifact store, a 307 to a
/// presigned URL of the object (valid
/// [`crate::jobs::service::PRESIGNED_URL_SECS`]) instead.
pub async fn get_artifact(
    State(st): State<AppState>,
    scope: Scope,
    Path((id, name)): Path<(String, String)>,
    query: Result<Query<ArtifactQuery>, QueryRejection>,
    req: Request,
) -> Result<Response, ApiError> {
    let Query(query) = query.map_err(bad_query)?;
    let id = visible_id(&st, &scope, &id).await?;
    if query.redirect == Some(1)
        && let Some(url) = st.jobs.artifact_url(id, name.clone()).await?
    {
        return Ok(presigned_redirect(&url));
    }
    let (path, art) = st.jobs.artifact(id, name).await?;
    let (req, _) = req.into_parts();
    let coding = if req.headers.contains_key(header::RANGE) { None } else { encoding::negotiate(&req.headers) };
    let mut resp = match coding {
        Some(coding) => serve_encoded(&path, &req, coding).await?,
        None => serve_identity(&path, &req).await?,
    };
    resp.headers_mut().insert(header::VARY, HeaderValue::from_static("accept-encoding"));
    if resp.status().is_success() {
        if let Ok(v) = HeaderValue::from_str(&art.media_type) {
            resp.headers_mut().insert(header::CONTENT_TYPE, v);
        }
        if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{}\"", art.name)) {
            resp.headers_mut().insert(header::CONTENT_DISPOSITION, v);
        }
    }
    Ok(resp)
}

/// `GET /healthz`.
pub async fn healthz(State(st): State<AppState>) -> Result<Json<Value>, ApiError> {
    st.jobs.health().await.map_err(|e| {
        ApiError::new(FailureKind::ServiceUnavailable, "the job store does not answer").with("cause", e.to_string())
    })?;
    let problems = st.jobs.storage_problems().await;
    if !problems.is_empty() {
        return Err(ApiError::new(
            FailureKind::ServiceUnavailable,
            format!("the store is not writable: {}", problems.join("; ")),
        )
        .with("problems", problems));
    }
    Ok(Json(json!({"status": "ok", "version": env!("CARGO_PKG_VERSION")})))
}

/// `GET /metrics`: Prometheus text format.
pub async fn metrics(State(st): State<AppState>) -> Result<Response, ApiError> {
    let text = st.jobs.metrics_text().await?;
    Ok(([(header::CONTENT_TYPE, "text/plain; version=0.0.4; charset=utf-8")], text).into_response())
}

/// Fallback for unknown paths.
pub async fn not_found(req: Request) -> ApiError {
    ApiError::new(
        FailureKind::NotFound,
        format!("no route for {} {}; see api/openapi.yaml", req.method(), req.uri().path()),
    )
}
