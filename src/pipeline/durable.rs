//! Durability of a job's artifacts without an `fsync` on the path of every
//! write.
//!
//! A job marked `succeeded` must have its files on disk (the jobs layer
//! records success only after [`super::run_pipeline`] returns). Syncing each
//! artifact right after writing it made every writer wait for the disk in
//! turn; instead each written file is handed to one background thread that
//! syncs the files in the order they were written, while the pipeline goes on
//! formatting the next artifact or computing the next stage (the disk and the
//! cores then work at the same time). [`Syncer::finish`] waits for the last
//! sync and reports the first failure; the pipeline calls it before it
//! writes `report.json` and returns, so the guarantee is unchanged.

use std::fs::File;
use std::path::PathBuf;
use std::sync::mpsc::{Sender, channel};
use std::thread::JoinHandle;

/// The first file that failed to sync, with its error.
type SyncFailure = (PathBuf, std::io::Error);

/// Background `fsync` of written files (see the module doc).
#[derive(Debug)]
pub struct Syncer {
    to_sync: Option<Sender<(PathBuf, File)>>,
    worker: Option<JoinHandle<Result<(), SyncFailure>>>,
}

impl Syncer {
    /// Starts the syncing thread. When the thread cannot be started, files
    /// are synced by [`Syncer::sync`] itself (same guarantee, no overlap).
    pub fn start() -> Self {
        let (tx, rx) = channel::<(PathBuf, File)>();
        let worker = std::thread::Builder::new().name("artifact-sync".into()).spawn(move || {
            let mut first_failure = Ok(());
            for (path, file) in rx {
                let synced = file.sync_all();
                if let (Err(e), true) = (synced, first_failure.is_ok()) {
                    first_failure = Err((path, e));
                }
            }
            first_failure
        });
        match worker {
            Ok(handle) => Self { to_sync: Some(tx), worker: Some(handle) },
            Err(_) => Self { to_sync: None, worker: None },
        }
    }

    /// Syncs `file` (written at `path`) in the background, or now when there
    /// is no background thread.
    ///
    /// # Errors
    /// Only in the fallback without a thread: the sync's own error.
    pub fn sync(&self, path: PathBuf, file: File) -> std::io::Result<()> {
        match &self.to_sync {
            Some(tx) => match tx.send((path, file)) {
                Ok(()) => Ok(()),
                // The thread is gone (it panicked): sync here instead.
                Err(std::sync::mpsc::SendError((_, file))) => file.sync_all(),
            },
            None => file.sync_all(),
        }
    }

    /// Waits until every file handed to [`Syncer::sync`] is on disk.
    ///
    /// # Errors
    /// The first file whose sync failed, with the error.
    pub fn finish(mut self) -> Result<(), SyncFailure> {
        drop(self.to_sync.take());
        match self.worker.take().map(JoinHandle::join) {
            None | Some(Ok(Ok(()))) => Ok(()),
            Some(Ok(Err(failure))) => Err(failure),
            Some(Err(_)) => Err((PathBuf::new(), std::io::Error::other("the artifact sync thread panicked"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn finish_returns_after_every_handed_file_and_reports_success() {
        let dir = tempfile::tempdir().expect("temp dir");
        let syncer = Syncer::start();
        for i in 0..5 {
            let path = dir.path().join(format!("f{i}"));
            let mut f = File::create(&path).expect("create");
            f.write_all(&vec![i as u8; 1000]).expect("write");
            syncer.sync(path, f).expect("hand over");
        }
        assert!(syncer.finish().is_ok());
        for i in 0..5 {
            assert_eq!(std::fs::read(dir.path().join(format!("f{i}"))).expect("read"), vec![i as u8; 1000]);
        }
    }
}
