//! A request body that fails when the client stops sending: each time the
//! handler waits for the next chunk, a timer runs; when it expires before a
//! chunk arrives, the body yields [`BodyIdleTimeout`] and sets a flag the
//! connection's service reads to answer 408 `upload-timeout` (see
//! [`super::server`]). The timer runs only while the body is being polled,
//! so a handler busy writing a chunk to disk is never timed out.

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;

use axum::body::Bytes;
use http_body::{Body, Frame, SizeHint};

/// The error a stalled body yields.
#[derive(Debug, thiserror::Error)]
#[error("no request body bytes arrived for {} s", .0.as_secs())]
pub struct BodyIdleTimeout(pub Duration);

/// `inner` with an idle timeout of `idle` between chunks.
pub struct IdleTimeoutBody<B> {
    inner: B,
    idle: Duration,
    timer: Option<Pin<Box<tokio::time::Sleep>>>,
    fired: Arc<AtomicBool>,
}

impl<B> IdleTimeoutBody<B> {
    /// Wraps `inner`; `fired` becomes true when the timeout strikes.
    pub fn new(inner: B, idle: Duration, fired: Arc<AtomicBool>) -> Self {
        Self { inner, idle, timer: None, fired }
    }
}

impl<B> Body for IdleTimeoutBody<B>
where
    B: Body<Data = Bytes> + Unpin,
    B::Error: Into<axum::BoxError>,
{
    type Data = Bytes;
    type Error = axum::BoxError;

    /// The next frame of `inner`, or [`BodyIdleTimeout`] once no frame came
    /// for the idle time (and on every poll after that).
    fn poll_frame(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Result<Frame<Bytes>, Self::Error>>> {
        let this = &mut *self;
        if this.fired.load(Ordering::Relaxed) {
            return Poll::Ready(Some(Err(Box::new(BodyIdleTimeout(this.idle)))));
        }
        match Pin::new(&mut this.inner).poll_frame(cx) {
            Poll::Ready(frame) => {
                this.timer = None;
                Poll::Ready(frame.map(|r| r.map_err(Into::into)))
            }
            Poll::Pending => {
                let idle = this.idle;
                let timer = this.timer.get_or_insert_with(|| Box::pin(tokio::time::sleep(idle)));
                if timer.as_mut().poll(cx).is_ready() {
                    this.fired.store(true, Ordering::Relaxed);
                    return Poll::Ready(Some(Err(Box::new(BodyIdleTimeout(idle)))));
                }
                Poll::Pending
            }
        }
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}
