//! The HTTP API (axum): routes, handlers, problem+json errors, OpenAPI.
//!
//! [`routes`] is the single route table: [`router`] builds the axum router
//! from it, and the API test compares it with the `paths` of
//! `api/openapi.yaml`, so the served routes and the spec cannot drift.
//!
//! Every request gets a request id (`x-request-id`, echoed or generated), a
//! tracing span, and, on error, an `application/problem+json` body
//! ([`error`]). The upload route has no framework body limit: uploads stream
//! to disk and [`HttpLimits::max_upload_bytes`] is enforced while streaming.
//! [`serve`] runs the accept loop of [`server`] (header and body timeouts,
//! bounded graceful shutdown, problem+json for hyper's own rejections).
//! [`page`] serves the browser pages: `GET /` and, when `Accept` prefers
//! HTML, `GET /v1/jobs/{id}` answer one static shell whose script reads the
//! JSON API.
//! This is the only module that knows axum.

pub mod auth;
pub mod encoding;
pub mod error;
pub mod handlers;
pub mod idle_body;
pub mod multipart_framing;
pub mod page;
pub mod parser_answers;
pub mod range;
pub mod server;
pub mod upload;

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::http::Method;
use axum::routing::{MethodRouter, delete, get, post};

pub use error::ApiError;

use crate::jobs::JobService;

/// Request-level limits of the HTTP layer.
#[derive(Debug, Clone)]
pub struct HttpLimits {
    /// Largest accepted upload in bytes (413 beyond). Default 512 MiB.
    pub max_upload_bytes: u64,
    /// `Retry-After` seconds sent with 429. Default 10.
    pub retry_after_secs: u64,
    /// Longest time for a request head to arrive, and for a keep-alive
    /// connection to stay idle (closed beyond). Default 10 s.
    pub header_timeout: Duration,
    /// Longest pause between two chunks of a request body (408
    /// `upload-timeout` beyond). Default 30 s.
    pub body_idle_timeout: Duration,
    /// How long in-flight requests may run after shutdown is asked before
    /// their connections are dropped. Default 10 s.
    pub shutdown_grace: Duration,
}

impl Default for HttpLimits {
    fn default() -> Self {
        Self {
            max_upload_bytes: 512 * 1024 * 1024,
            retry_after_secs: 10,
            header_timeout: Duration::from_secs(10),
            body_idle_timeout: Duration::from_secs(30),
            shutdown_grace: Duration::from_secs(10),
        }
    }
}

/// State shared by the handlers.
#[derive(Clone)]
pub struct AppState {
    /// The job service.
    pub jobs: JobService,
    /// Request limits.
    pub limits: Arc<HttpLimits>,
    /// Bearer-token authentication; `None` serves without it.
    pub auth: Option<Arc<auth::Auth>>,
}

/// One served route: method, path (axum/OpenAPI `{param}` syntax), handler.
pub struct Route {
    /// HTTP method.
    pub method: Method,
    /// Path template.
    pub path: &'static str,
    /// The handler.
    pub handler: MethodRouter<AppState>,
}

/// The route table (single source of truth for the router and the spec test).
pub fn routes() -> Vec<Route> {
    let r = |method: Method, path: &'static str, handler: MethodRouter<AppState>| Route { method, path, handler };
    vec![
        r(Method::POST, "/v1/jobs", post(handlers::submit_job).layer(DefaultBodyLimit::disable())),
        r(Method::GET, "/v1/jobs", get(handlers::list_jobs)),
        r(Method::GET, "/v1/jobs/{id}", get(handlers::get_job)),
        r(Method::DELETE, "/v1/jobs/{id}", delete(handlers::delete_job)),
        r(Method::POST, "/v1/jobs/{id}/cancel", post(handlers::cancel_job)),
        r(Method::GET, "/v1/jobs/{id}/artifacts/{name}", get(handlers::get_artifact)),
        r(Method::GET, "/", get(page::index)),
        r(Method::GET, page::SCRIPT_PATH, get(page::script)),
        r(Method::GET, page::STYLE_PATH, get(page::style)),
        r(Method::GET, "/healthz", get(handlers::healthz)),
        r(Method::GET, "/metrics", get(handlers::metrics)),
    ]
}

/// The application router with its middleware.
pub fn router(state: AppState) -> Router {
    let mut app = Router::new();
    for route in routes() {
        app = app.route(route.path, route.handler);
    }
    app.fallback(handlers::not_found)
        .layer(axum::middleware::from_fn_with_state(state.clone(), auth::authenticate))
        .layer(tower_http::catch_panic::CatchPanicLayer::new())
        .layer(axum::middleware::from_fn(error::request_context))
        .with_state(state)
}

/// The router of a worker process: `/healthz` and `/metrics` only.
pub fn worker_router(state: AppState) -> Router {
    Router::new()
        .route("/healthz", get(handlers::healthz))
        .route("/metrics", get(handlers::metrics))
        .fallback(handlers::not_found)
        .layer(tower_http::catch_panic::CatchPanicLayer::new())
        .layer(axum::middleware::from_fn(error::request_context))
        .with_state(state)
}

/// Serves a worker's [`worker_router`] on `listener` until `shutdown` resolves.
///
/// # Errors
/// The listener's I/O error.
pub async fn serve_worker(
    listener: tokio::net::TcpListener,
    state: AppState,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let limits = state.limits.clone();
    server::serve(listener, worker_router(state), limits, shutdown).await
}

/// Serves the API on `listener` until `shutdown` resolves, then lets
/// in-flight requests finish for at most [`HttpLimits::shutdown_grace`].
///
/// # Errors
/// The listener's I/O error.
pub async fn serve(
    listener: tokio::net::TcpListener,
    state: AppState,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let limits = state.limits.clone();
    server::serve(listener, router(state), limits, shutdown).await
}
