//! problem+json for requests hyper refuses itself. A request head that does
//! not parse (a target over hyper's fixed 64 KiB, too many or too large
//! header fields, control bytes in a value) never reaches a handler: hyper
//! writes a bare status line with an empty body and closes the connection.
//! [`ProblemIo`] wraps the connection's socket and replaces that answer with
//! the same status as a problem+json body (see
//! [`ApiError::parser_rejection`]).
//!
//! Telling hyper's answer from ours without parsing the output stream: hyper
//! answers a parse error only when no exchange is open, i.e. when every
//! response the service returned has been dropped by hyper (counted in
//! [`Exchanges`]) and the socket has been flushed since, so the write starts
//! a new message. Such a write that starts with an HTTP/1.1 error status
//! line and whose head has no `x-request-id` (which all our responses carry)
//! is hyper's. When unsure, bytes pass unchanged: the client then gets
//! hyper's bodiless answer, never a corrupted one.

use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::task::{Context, Poll};

use axum::http::StatusCode;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

use super::error::{ApiError, REQUEST_ID_HEADER};

/// Per connection: requests handed to the service and responses hyper has
/// finished with (their bodies dropped).
#[derive(Debug, Default)]
pub struct Exchanges {
    started: AtomicU64,
    finished: AtomicU64,
}

impl Exchanges {
    /// The service got a request.
    pub fn start(&self) {
        self.started.fetch_add(1, Ordering::SeqCst);
    }

    /// hyper dropped a response body: that response is fully handed over.
    pub fn finish(&self) {
        self.finished.fetch_add(1, Ordering::SeqCst);
    }

    /// Finished responses, when no exchange is open.
    fn idle_count(&self) -> Option<u64> {
        let finished = self.finished.load(Ordering::SeqCst);
        (self.started.load(Ordering::SeqCst) == finished).then_some(finished)
    }
}

/// A response body that reports to [`Exchanges`] when hyper drops it.
pub struct FinishOnDrop<B> {
    inner: B,
    exchanges: Arc<Exchanges>,
}

impl<B> FinishOnDrop<B> {
    /// Wraps a response body of the exchange counted in `exchanges`.
    pub fn new(inner: B, exchanges: Arc<Exchanges>) -> Self {
        Self { inner, exchanges }
    }
}

impl<B> Drop for FinishOnDrop<B> {
    fn drop(&mut self) {
        self.exchanges.finish();
    }
}

impl<B: http_body::Body + Unpin> http_body::Body for FinishOnDrop<B> {
    type Data = B::Data;
    type Error = B::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Self::Data>, Self::Error>>> {
        Pin::new(&mut self.inner).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

/// The socket of one connection, replacing hyper's own error answers.
pub struct ProblemIo<T> {
    inner: T,
    exchanges: Arc<Exchanges>,
    /// `finished` count at the last flush with nothing written since: a
    /// write now starts a new message if it still equals `finished`.
    flushed_at: Option<u64>,
    /// Our replacement answer and how much of it is written.
    replacement: Vec<u8>,
    written: usize,
    /// After a replacement, hyper's further output is discarded.
    replaced: bool,
}

impl<T> ProblemIo<T> {
    /// Wraps a fresh connection whose service counts into `exchanges`.
    pub fn new(inner: T, exchanges: Arc<Exchanges>) -> Self {
        Self { inner, exchanges, flushed_at: Some(0), replacement: Vec::new(), written: 0, replaced: false }
    }

    /// True when a write now starts a message no handler produced.
    fn at_unanswered_boundary(&self) -> bool {
        self.flushed_at.is_some() && self.exchanges.idle_count() == self.flushed_at
    }
}

/// The status of hyper's own error answer at the start of `buf`: an
/// HTTP/1.1 4xx/5xx status line whose complete head has no request id.
fn hyper_error_status(buf: &[u8]) -> Option<StatusCode> {
    let rest = buf.strip_prefix(b"HTTP/1.1 ")?;
    let end = buf.windows(4).position(|w| w == b"\r\n\r\n")?;
    let head = String::from_utf8_lossy(&buf[..end]).to_ascii_lowercase();
    if head.contains(&format!("\r\n{REQUEST_ID_HEADER}:")) {
        return None;
    }
    let code = std::str::from_utf8(rest.get(..3)?).ok()?.parse::<u16>().ok()?;
    StatusCode::from_u16(code).ok().filter(|s| s.is_client_error() || s.is_server_error())
}

impl<T: AsyncWrite + Unpin> ProblemIo<T> {
    /// Writes what is left of the replacement; ready when all is written.
    fn poll_replacement(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        while self.written < self.replacement.len() {
            let n = std::task::ready!(Pin::new(&mut self.inner).poll_write(cx, &self.replacement[self.written..]))?;
            if n == 0 {
                return Poll::Ready(Err(io::ErrorKind::WriteZero.into()));
            }
            self.written += n;
        }
        Poll::Ready(Ok(()))
    }
}

impl<T: AsyncRead + Unpin> AsyncRead for ProblemIo<T> {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for ProblemIo<T> {
    /// Passes `buf` on, unless it is hyper's own error answer (then the
    /// problem+json answer is written instead) or follows one (discarded).
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        if this.replaced {
            std::task::ready!(this.poll_replacement(cx))?;
            return Poll::Ready(Ok(buf.len()));
        }
        if this.at_unanswered_boundary()
            && let Some(status) = hyper_error_status(buf)
        {
            let id = uuid::Uuid::new_v4().simple().to_string();
            this.replacement = ApiError::parser_rejection(status).http1_bytes(&id);
            this.replaced = true;
            // Written by the next write, flush or shutdown if the socket is full now.
            let _ = this.poll_replacement(cx)?;
            return Poll::Ready(Ok(buf.len()));
        }
        let n = std::task::ready!(Pin::new(&mut this.inner).poll_write(cx, buf))?;
        if n > 0 {
            this.flushed_at = None;
        }
        Poll::Ready(Ok(n))
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = &mut *self;
        std::task::ready!(this.poll_replacement(cx))?;
        std::task::ready!(Pin::new(&mut this.inner).poll_flush(cx))?;
        // hyper flushes its own buffer completely before flushing the socket.
        this.flushed_at = this.exchanges.idle_count();
        Poll::Ready(Ok(()))
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = &mut *self;
        std::task::ready!(this.poll_replacement(cx))?;
        Pin::new(&mut this.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_hyper_error_heads_without_a_request_id_are_recognised() {
        let hyper = b"HTTP/1.1 414 URI Too Long\r\ncontent-length: 0\r\ndate: x\r\n\r\n";
        assert_eq!(hyper_error_status(hyper), Some(StatusCode::URI_TOO_LONG));
        let ours = b"HTTP/1.1 404 Not Found\r\nx-request-id: abc\r\ncontent-length: 0\r\n\r\n";
        assert_eq!(hyper_error_status(ours), None);
        assert_eq!(hyper_error_status(b"HTTP/1.1 200 OK\r\n\r\n"), None);
        assert_eq!(hyper_error_status(b"HTTP/1.1 400 Bad Req"), None, "incomplete head");
        assert_eq!(hyper_error_status(b"solid x\nHTTP/1.1 400\r\n\r\n"), None);
    }

    #[test]
    fn a_connection_is_at_a_boundary_only_with_no_open_exchange_and_a_flush_since() {
        let ex = Arc::new(Exchanges::default());
        let mut io = ProblemIo::new(Vec::<u8>::new(), ex.clone());
        assert!(io.at_unanswered_boundary(), "a fresh connection");
        ex.start();
        assert!(!io.at_unanswered_boundary(), "a request is being answered");
        ex.finish();
        assert!(!io.at_unanswered_boundary(), "its response may still be buffered");
        io.flushed_at = ex.idle_count();
        assert!(io.at_unanswered_boundary());
    }
}
