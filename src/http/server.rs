//! The accept loop: one hyper HTTP/1.1 connection per accepted socket, with
//! the timeouts axum's `serve` lacks and a bounded graceful shutdown.
//!
//! - **Header timeout** ([`HttpLimits::header_timeout`]): a request head
//!   (request line and all header fields) must arrive within it, or hyper
//!   closes the connection. The same timer runs while a keep-alive
//!   connection waits for its next request, so it is also the keep-alive
//!   idle timeout.
//! - **Body idle timeout** ([`HttpLimits::body_idle_timeout`]): see
//!   [`super::idle_body`]; a stalled upload is answered 408 `upload-timeout`
//!   with `Connection: close`, and its partial file is removed by the
//!   handler's upload guard.
//! - **Shutdown**: when `shutdown` resolves, the listener closes, idle
//!   connections close, in-flight requests get
//!   [`HttpLimits::shutdown_grace`] to finish; the connections still open
//!   then are dropped (with their handlers, whose upload guards remove
//!   half-written files), and [`serve`] returns.
//! - hyper's own error answers become problem+json ([`super::parser_answers`]).

use std::convert::Infallible;
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use axum::Router;
use axum::body::Body;
use axum::http::{HeaderValue, Request, StatusCode, header};
use axum::response::Response;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tokio::task::JoinSet;
use tower::ServiceExt;

use super::HttpLimits;
use super::error::{ApiError, REQUEST_ID_HEADER};
use super::idle_body::IdleTimeoutBody;
use super::parser_answers::{Exchanges, FinishOnDrop, ProblemIo};

/// Serves `app` on `listener` until `shutdown` resolves, then drains the
/// connections for at most `limits.shutdown_grace`.
///
/// # Errors
/// None today (accept errors are logged and retried); the `Result` keeps
/// the signature of the listener-level failures a future change may add.
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: Arc<HttpLimits>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let (stop_tx, stop_rx) = watch::channel(false);
    let mut conns = JoinSet::new();
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            () = &mut shutdown => break,
            accepted = listener.accept() => match accepted {
                Ok((stream, _peer)) => {
                    conns.spawn(serve_connection(stream, app.clone(), limits.clone(), stop_rx.clone()));
                }
                Err(e) => {
                    // E.g. out of file descriptors: wait instead of spinning.
                    tracing::warn!(error = %e, "accepting a connection failed");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            },
            Some(_) = conns.join_next(), if !conns.is_empty() => {}
        }
    }
    drop(listener);
    let _ = stop_tx.send(true);
    drain_connections(&mut conns, limits.shutdown_grace).await;
    Ok(())
}

/// Waits up to `grace` for the connections to finish, then drops the rest.
async fn drain_connections(conns: &mut JoinSet<()>, grace: Duration) {
    let open = conns.len();
    let drained = tokio::time::timeout(grace, async { while conns.join_next().await.is_some() {} }).await;
    if drained.is_err() {
        tracing::warn!(
            open,
            still_open = conns.len(),
            grace_secs = grace.as_secs_f64(),
            "shutdown grace elapsed; closing the remaining connections"
        );
        conns.shutdown().await;
    }
}

/// One connection: HTTP/1.1 with the header timeout, shut down gracefully
/// (finish the current request, then close) once `stop` changes.
async fn serve_connection(stream: TcpStream, app: Router, limits: Arc<HttpLimits>, mut stop: watch::Receiver<bool>) {
    let exchanges = Arc::new(Exchanges::default());
    let io = TokioIo::new(ProblemIo::new(stream, exchanges.clone()));
    let idle = limits.body_idle_timeout;
    let service = hyper::service::service_fn(move |req: Request<Incoming>| {
        exchanges.start();
        exchange(app.clone(), req, idle, exchanges.clone())
    });
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder.timer(TokioTimer::new()).header_read_timeout(limits.header_timeout);
    let conn = builder.serve_connection(io, service);
    tokio::pin!(conn);
    let mut stopping = false;
    loop {
        tokio::select! {
            result = conn.as_mut() => {
                if let Err(e) = result {
                    tracing::debug!(error = %e, "connection closed with an error");
                }
                return;
            }
            _ = stop.changed(), if !stopping => {
                stopping = true;
                conn.as_mut().graceful_shutdown();
            }
        }
    }
}

/// One request through the router, its body under the idle timeout; a
/// request that failed because its body stalled is answered 408.
async fn exchange(
    app: Router,
    req: Request<Incoming>,
    idle: Duration,
    exchanges: Arc<Exchanges>,
) -> Result<Response<FinishOnDrop<Body>>, Infallible> {
    let stalled = Arc::new(AtomicBool::new(false));
    let req = req.map(|b| Body::new(IdleTimeoutBody::new(b, idle, stalled.clone())));
    let resp = match app.oneshot(req).await {
        Ok(resp) => resp,
        Err(never) => match never {},
    };
    let resp = if stalled.load(Ordering::Relaxed) && resp.status() == StatusCode::BAD_REQUEST {
        upload_timeout(&resp, idle)
    } else {
        resp
    };
    Ok(resp.map(|b| FinishOnDrop::new(b, exchanges)))
}

/// The 408 replacing `resp` (a 400 caused by a stalled body), with the same
/// request id and `Connection: close` (the rest of the body never came).
fn upload_timeout(resp: &Response, idle: Duration) -> Response {
    let id = resp.headers().get(REQUEST_ID_HEADER).and_then(|v| v.to_str().ok()).unwrap_or("-").to_string();
    let mut out = ApiError::upload_timeout(idle.as_secs()).into_response_for(&id);
    if let Ok(v) = HeaderValue::from_str(&id) {
        out.headers_mut().insert(REQUEST_ID_HEADER, v);
    }
    out.headers_mut().insert(header::CONNECTION, HeaderValue::from_static("close"));
    out
}
