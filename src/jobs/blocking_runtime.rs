//! A small tokio runtime owned by a client of an async service (the
//! PostgreSQL store, the S3 artifact store), so that the job machinery,
//! which calls its stores from plain threads, can call them synchronously.
//!
//! [`BlockingRuntime::run`] spawns the future on the runtime and waits for
//! its result on a channel: this works from any thread, including a thread
//! that drives another runtime's async tasks (where `block_on` would panic).

use std::future::Future;

/// The runtime; shut down without blocking when dropped (dropping a runtime
/// inside async code would panic).
pub struct BlockingRuntime(Option<tokio::runtime::Runtime>);

impl BlockingRuntime {
    /// A multi-threaded runtime of one worker thread named `name`.
    ///
    /// # Errors
    /// The OS error when the thread cannot be started.
    pub fn new(name: &str) -> std::io::Result<Self> {
        let rt =
            tokio::runtime::Builder::new_multi_thread().worker_threads(1).thread_name(name).enable_all().build()?;
        Ok(Self(Some(rt)))
    }

    /// The runtime's handle, to spawn background tasks or enter it.
    pub fn handle(&self) -> Option<&tokio::runtime::Handle> {
        self.0.as_ref().map(tokio::runtime::Runtime::handle)
    }

    /// Runs `fut` on the runtime and waits for its output; `None` when the
    /// runtime is gone or the task panicked.
    pub fn run<T: Send + 'static>(&self, fut: impl Future<Output = T> + Send + 'static) -> Option<T> {
        let rt = self.0.as_ref()?;
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        rt.spawn(async move {
            let _ = tx.send(fut.await);
        });
        rx.recv().ok()
    }
}

impl Drop for BlockingRuntime {
    fn drop(&mut self) {
        if let Some(rt) = self.0.take() {
            rt.shutdown_background();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn runs_from_inside_async_code_and_drops_there() {
        let rt = BlockingRuntime::new("test-runtime").unwrap();
        assert_eq!(rt.run(async { 6 * 7 }), Some(42));
        drop(rt);
    }
}
