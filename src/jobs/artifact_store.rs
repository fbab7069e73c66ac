//! Where uploads and artifacts are kept for good: [`ArtifactStore`], chosen
//! by `--artifacts` ([`ArtifactLocation`]).
//!
//! Every process works on files in its own `--data-dir` (uploads stream to
//! disk, stages write files, downloads are served from files with `Range`
//! and gzip). The artifact store is what makes those files shared:
//! - [`LocalArtifacts`] (`file://`, the default): the data directory *is* the
//!   store; every process that shares a job store must see the same one.
//! - [`S3Artifacts`] (`s3://BUCKET/PREFIX`): an S3-compatible bucket through
//!   the `object_store` crate. The API uploads each accepted upload before
//!   the job is queued; a worker fetches the input when its data directory
//!   lacks it and uploads every artifact of an attempt (under the attempt's
//!   key, `jobs/<id>/out/<attempt>/`) before it records the job finished, so
//!   a record never lists an artifact the bucket lacks, and a late attempt
//!   cannot overwrite the winner's objects (a `worker` then drops its copy;
//!   a `serve` that runs jobs keeps it, since it may be serving it); an API
//!   fetches an artifact into its data directory on its first download and
//!   serves the file.
//!
//! Keys are the paths relative to the data directory (`jobs/<id>/…`), so
//! a file and its object have the same name. Transfers stream between file
//! and bucket (multipart uploads of 10 MiB parts): neither side holds a
//! whole file in memory.

use std::path::Path;
use std::sync::Arc;

use object_store::ObjectStore;
use object_store::path::Path as ObjectPath;

use super::blocking_runtime::BlockingRuntime;

/// Errors of the artifact store.
#[derive(Debug, thiserror::Error)]
pub enum ArtifactError {
    /// The bucket failed or could not be reached.
    #[error("artifact store: {0}")]
    Remote(String),
    /// A local file could not be read or written.
    #[error("artifact store, local file {path}: {source}")]
    Local {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
}

/// Where artifacts live: `file://` (the data directory) or
/// `s3://BUCKET[/PREFIX]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ArtifactLocation {
    /// The data directory.
    Local,
    /// An S3 bucket and key prefix (empty for the bucket's root).
    S3 {
        /// Bucket name.
        bucket: String,
        /// Key prefix, without leading or trailing `/`.
        prefix: String,
    },
}

impl ArtifactLocation {
    /// Parses `--artifacts`: `file://` or `s3://BUCKET[/PREFIX]`.
    ///
    /// # Errors
    /// A message naming the accepted forms.
    pub fn parse(text: &str) -> Result<Self, String> {
        if text == "file://" || text == "file" {
            return Ok(Self::Local);
        }
        if let Some(rest) = text.strip_prefix("s3://") {
            let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
            if bucket.is_empty() {
                return Err("s3:// needs a bucket, e.g. s3://meshatlas/lab1".into());
            }
            return Ok(Self::S3 { bucket: bucket.to_string(), prefix: prefix.trim_matches('/').to_string() });
        }
        Err(format!(
            "unsupported artifact store `{text}`: use file:// (the data directory) or s3://BUCKET/PREFIX \
             (endpoint and credentials from AWS_ENDPOINT_URL, AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY, AWS_REGION)"
        ))
    }
}

/// The shared store of uploads and artifacts (see the module doc). Keys
/// are paths relative to the data directory; `local` is the data directory.
pub trait ArtifactStore: Send + Sync {
    /// Makes the file `local/key` durable in the store under `key`.
    ///
    /// # Errors
    /// [`ArtifactError`] when it cannot.
    fn put(&self, local: &Path, key: &str) -> Result<(), ArtifactError>;

    /// A transfer into the object `key` that takes the bytes as they
    /// arrive (an upload streaming in from a client), so the object is
    /// stored when the last chunk is, not after a second pass over the
    /// file; `None` for the data directory, where the file is the object.
    fn stream_put(&self, key: &str) -> Option<StreamingPut> {
        let _ = key;
        None
    }

    /// Makes sure `local/key` holds the object `key`, fetching it if the
    /// data directory lacks it; false when the store has no such object.
    ///
    /// # Errors
    /// [`ArtifactError`] on a failed transfer.
    fn fetch(&self, local: &Path, key: &str) -> Result<bool, ArtifactError>;

    /// Removes every object whose key starts with `prefix` (a directory
    /// such as `jobs/<id>/`), except those under `keep` when given.
    ///
    /// # Errors
    /// [`ArtifactError`] when the store refuses.
    fn delete_prefix(&self, prefix: &str, keep: Option<&str>) -> Result<(), ArtifactError>;

    /// Whether the data directory is the store itself (then local copies
    /// must stay; otherwise they are caches a process may drop).
    fn is_local(&self) -> bool;

    /// Checks that the store takes a write.
    ///
    /// # Errors
    /// [`ArtifactError`] when it does not.
    fn probe(&self) -> Result<(), ArtifactError>;

    /// The job directories (`jobs/<id>/`, as `<id>`) whose newest object
    /// is older than `age`, so a sweep can remove those no job record
    /// names (an upload cut off between the bucket and the row); empty for
    /// the data directory, whose orphans the service removes as files.
    ///
    /// # Errors
    /// [`ArtifactError`] when the store cannot be listed.
    fn job_dirs_older_than(&self, age: std::time::Duration) -> Result<Vec<String>, ArtifactError> {
        let _ = age;
        Ok(Vec::new())
    }

    /// A URL that downloads the object `key` without credentials for
    /// `expires`, answered with `media_type` and as an attachment named
    /// `filename`; `None` for a store that has no URLs of its own (the data
    /// directory), whose files the API serves itself.
    ///
    /// # Errors
    /// [`ArtifactError`] when the store cannot sign one.
    fn presigned_get(
        &self,
        key: &str,
        filename: &str,
        media_type: &str,
        expires: std::time::Duration,
    ) -> Result<Option<String>, ArtifactError> {
        let _ = (key, filename, media_type, expires);
        Ok(None)
    }
}

/// An object being written chunk by chunk ([`ArtifactStore::stream_put`]).
/// At most [`STREAM_CHUNKS`] chunks and [`STREAM_PARTS`] multipart parts are
/// in flight, so a slow store slows the sender instead of filling memory.
/// Dropped before [`StreamingPut::finish`], the transfer is aborted and no
/// object is left.
pub struct StreamingPut {
    chunks: tokio::sync::mpsc::Sender<Option<bytes::Bytes>>,
    done: tokio::sync::oneshot::Receiver<Result<(), ArtifactError>>,
}

/// Chunks queued between the sender and the transfer.
const STREAM_CHUNKS: usize = 4;
/// Multipart parts of one streaming transfer uploaded at once.
const STREAM_PARTS: usize = 2;

impl StreamingPut {
    /// Hands `chunk` to the transfer; waits while the store is behind.
    ///
    /// # Errors
    /// The transfer's error when it has failed.
    pub async fn write(&mut self, chunk: bytes::Bytes) -> Result<(), ArtifactError> {
        if self.chunks.send(Some(chunk)).await.is_ok() {
            return Ok(());
        }
        match (&mut self.done).await {
            Ok(Err(e)) => Err(e),
            _ => Err(remote("the transfer task stopped")),
        }
    }

    /// Completes the object and waits until the store has it.
    ///
    /// # Errors
    /// The transfer's error.
    pub async fn finish(mut self) -> Result<(), ArtifactError> {
        let _ = self.chunks.send(None).await;
        (&mut self.done).await.unwrap_or_else(|_| Err(remote("the transfer task stopped")))
    }
}

/// Feeds the chunks of `rx` into `w` until the sender finishes (`None`
/// sent: the object is completed) or goes away (aborted).
async fn pump(
    w: &mut object_store::buffered::BufWriter,
    rx: &mut tokio::sync::mpsc::Receiver<Option<bytes::Bytes>>,
) -> Result<(), ArtifactError> {
    loop {
        match rx.recv().await {
            Some(Some(chunk)) => w.put(chunk).await.map_err(remote)?,
            Some(None) => return tokio::io::AsyncWriteExt::shutdown(w).await.map_err(remote),
            None => return Err(remote("the upload was abandoned before its end")),
        }
    }
}

/// The data directory as the store: nothing to transfer.
pub struct LocalArtifacts;

impl ArtifactStore for LocalArtifacts {
    fn put(&self, _: &Path, _: &str) -> Result<(), ArtifactError> {
        Ok(())
    }

    fn fetch(&self, local: &Path, key: &str) -> Result<bool, ArtifactError> {
        Ok(local.join(key).is_file())
    }

    /// The job machinery removes local files itself.
    fn delete_prefix(&self, _: &str, _: Option<&str>) -> Result<(), ArtifactError> {
        Ok(())
    }

    fn is_local(&self) -> bool {
        true
    }

    fn probe(&self) -> Result<(), ArtifactError> {
        Ok(())
    }
}

/// Multipart part size of uploads.
const PART_BYTES: usize = 10 * 1024 * 1024;

/// An S3-compatible bucket.
pub struct S3Artifacts {
    store: Arc<dyn ObjectStore>,
    /// The same client, for presigned URLs.
    signer: Arc<object_store::aws::AmazonS3>,
    prefix: String,
    rt: BlockingRuntime,
}

fn remote(e: impl std::fmt::Display) -> ArtifactError {
    ArtifactError::Remote(e.to_string())
}

fn local_err(path: &Path) -> impl FnOnce(std::io::Error) -> ArtifactError + '_ {
    move |source| ArtifactError::Local { path: path.display().to_string(), source }
}

impl S3Artifacts {
    /// A client of `bucket` under `prefix`, configured from the usual
    /// variables: `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_REGION`
    /// (default `us-east-1`) and, for a server other than AWS,
    /// `AWS_ENDPOINT_URL` (path-style requests, plain HTTP allowed for an
    /// `http://` endpoint).
    ///
    /// # Errors
    /// [`ArtifactError::Remote`] when the configuration is incomplete.
    pub fn connect(bucket: &str, prefix: &str) -> Result<Self, ArtifactError> {
        let mut b = object_store::aws::AmazonS3Builder::from_env().with_bucket_name(bucket);
        if std::env::var_os("AWS_REGION").is_none() && std::env::var_os("AWS_DEFAULT_REGION").is_none() {
            b = b.with_region("us-east-1");
        }
        if let Some(ep) = std::env::var("AWS_ENDPOINT_URL").ok().filter(|e| !e.is_empty()) {
            b = b.with_allow_http(ep.starts_with("http://")).with_endpoint(ep).with_virtual_hosted_style_request(false);
        }
        let signer = Arc::new(b.build().map_err(remote)?);
        let rt = BlockingRuntime::new("meshatlas-s3").map_err(remote)?;
        Ok(Self { store: signer.clone(), signer, prefix: prefix.trim_matches('/').to_string(), rt })
    }

    /// The object path of `key` under the prefix.
    fn path(&self, key: &str) -> ObjectPath {
        let key = key.trim_start_matches('/');
        if self.prefix.is_empty() { ObjectPath::from(key) } else { ObjectPath::from(format!("{}/{key}", self.prefix)) }
    }

    fn run<T: Send + 'static>(
        &self,
        fut: impl std::future::Future<Output = Result<T, ArtifactError>> + Send + 'static,
    ) -> Result<T, ArtifactError> {
        self.rt.run(fut).ok_or_else(|| remote("the transfer task stopped"))?
    }
}

impl ArtifactStore for S3Artifacts {
    fn stream_put(&self, key: &str) -> Option<StreamingPut> {
        let handle = self.rt.handle()?;
        let (chunks, mut rx) = tokio::sync::mpsc::channel(STREAM_CHUNKS);
        let (done_tx, done) = tokio::sync::oneshot::channel();
        let mut w = object_store::buffered::BufWriter::with_capacity(self.store.clone(), self.path(key), PART_BYTES)
            .with_max_concurrency(STREAM_PARTS);
        handle.spawn(async move {
            let r = pump(&mut w, &mut rx).await;
            if r.is_err() {
                let _ = w.abort().await;
            }
            let _ = done_tx.send(r);
        });
        Some(StreamingPut { chunks, done })
    }

    fn put(&self, local: &Path, key: &str) -> Result<(), ArtifactError> {
        let file = local.join(key);
        let (store, path) = (self.store.clone(), self.path(key));
        self.run(async move {
            let mut src = tokio::fs::File::open(&file).await.map_err(local_err(&file))?;
            let mut dst = object_store::buffered::BufWriter::with_capacity(store, path, PART_BYTES);
            tokio::io::copy(&mut src, &mut dst).await.map_err(remote)?;
            tokio::io::AsyncWriteExt::shutdown(&mut dst).await.map_err(remote)
        })
    }

    fn fetch(&self, local: &Path, key: &str) -> Result<bool, ArtifactError> {
        let file = local.join(key);
        if file.is_file() {
            return Ok(true);
        }
        let (store, path) = (self.store.clone(), self.path(key));
        self.run(async move {
            use futures_util::StreamExt;
            use object_store::ObjectStoreExt;
            let got = match store.get(&path).await {
                Ok(g) => g,
                Err(object_store::Error::NotFound { .. }) => return Ok(false),
                Err(e) => return Err(remote(e)),
            };
            if let Some(dir) = file.parent() {
                tokio::fs::create_dir_all(dir).await.map_err(local_err(dir))?;
            }
            let part = file.with_extension(format!("part-{}", uuid::Uuid::new_v4().simple()));
            let mut out = tokio::fs::File::create(&part).await.map_err(local_err(&part))?;
            let mut stream = got.into_stream();
            let copied: Result<(), ArtifactError> = async {
                while let Some(chunk) = stream.next().await {
                    let chunk = chunk.map_err(remote)?;
                    tokio::io::AsyncWriteExt::write_all(&mut out, &chunk).await.map_err(local_err(&part))?;
                }
                super::storage::flush_and_sync(&mut out).await.map_err(local_err(&part))
            }
            .await;
            if let Err(e) = copied {
                let _ = tokio::fs::remove_file(&part).await;
                return Err(e);
            }
            tokio::fs::rename(&part, &file).await.map_err(local_err(&file))?;
            Ok(true)
        })
    }

    fn delete_prefix(&self, prefix: &str, keep: Option<&str>) -> Result<(), ArtifactError> {
        let (store, dir) = (self.store.clone(), self.path(prefix));
        let keep = keep.map(|k| self.path(k).to_string());
        self.run(async move {
            use futures_util::StreamExt;
            let listed: Vec<ObjectPath> =
                store.list(Some(&dir)).filter_map(|m| async move { m.ok().map(|m| m.location) }).collect().await;
            let doomed: Vec<ObjectPath> = listed
                .into_iter()
                .filter(|p| keep.as_deref().is_none_or(|k| !p.as_ref().starts_with(&format!("{k}/"))))
                .collect();
            let mut deleted = store.delete_stream(futures_util::stream::iter(doomed.into_iter().map(Ok)).boxed());
            while let Some(r) = deleted.next().await {
                match r {
                    Ok(_) | Err(object_store::Error::NotFound { .. }) => {}
                    Err(e) => return Err(remote(e)),
                }
            }
            Ok(())
        })
    }

    fn is_local(&self) -> bool {
        false
    }

    /// Lists every object under `jobs/` once, keeping per job directory
    /// its newest `last_modified`.
    fn job_dirs_older_than(&self, age: std::time::Duration) -> Result<Vec<String>, ArtifactError> {
        let (store, dir) = (self.store.clone(), self.path("jobs"));
        let under = format!("{dir}/");
        self.run(async move {
            use futures_util::StreamExt;
            let mut newest: std::collections::BTreeMap<String, i64> = Default::default();
            let mut listed = store.list(Some(&dir));
            while let Some(meta) = listed.next().await {
                let meta = meta.map_err(remote)?;
                let Some(id) = meta.location.as_ref().strip_prefix(&under).and_then(|r| r.split('/').next()) else {
                    continue;
                };
                let at = meta.last_modified.timestamp_millis();
                let e = newest.entry(id.to_string()).or_insert(at);
                *e = (*e).max(at);
            }
            let cutoff = super::model::now_ms() - i64::try_from(age.as_millis()).unwrap_or(i64::MAX);
            Ok(newest.into_iter().filter(|&(_, at)| at < cutoff).map(|(id, _)| id).collect())
        })
    }

    /// A SigV4 query-signed GET whose `response-content-type` and
    /// `response-content-disposition` (signed with it) make the bucket
    /// answer with the artifact's media type and file name.
    fn presigned_get(
        &self,
        key: &str,
        filename: &str,
        media_type: &str,
        expires: std::time::Duration,
    ) -> Result<Option<String>, ArtifactError> {
        use object_store::signer::{Method, SignedUrlOptions, Signer};
        let (signer, path) = (self.signer.clone(), self.path(key));
        let opts = SignedUrlOptions::default().with_query([
            ("response-content-type", media_type.to_string()),
            ("response-content-disposition", format!("attachment; filename=\"{filename}\"")),
        ]);
        self.run(async move {
            let url = signer.signed_url_opts(Method::GET, &path, expires, &opts).await.map_err(remote)?;
            Ok(Some(url.to_string()))
        })
    }

    fn probe(&self) -> Result<(), ArtifactError> {
        let (store, path) = (self.store.clone(), self.path(&format!("tmp/probe-{}", uuid::Uuid::new_v4().simple())));
        self.run(async move {
            use object_store::ObjectStoreExt;
            store.put(&path, "meshatlas health probe\n".into()).await.map_err(remote)?;
            store.delete(&path).await.map_err(remote)
        })
    }
}

/// Opens the artifact store at `location`.
///
/// # Errors
/// [`ArtifactError`] when an S3 store cannot be configured.
pub fn open(location: &ArtifactLocation) -> Result<Arc<dyn ArtifactStore>, ArtifactError> {
    Ok(match location {
        ArtifactLocation::Local => Arc::new(LocalArtifacts),
        ArtifactLocation::S3 { bucket, prefix } => Arc::new(S3Artifacts::connect(bucket, prefix)?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_parse() {
        assert_eq!(ArtifactLocation::parse("file://").unwrap(), ArtifactLocation::Local);
        assert_eq!(
            ArtifactLocation::parse("s3://b/lab/one/").unwrap(),
            ArtifactLocation::S3 { bucket: "b".into(), prefix: "lab/one".into() }
        );
        assert_eq!(
            ArtifactLocation::parse("s3://b").unwrap(),
            ArtifactLocation::S3 { bucket: "b".into(), prefix: String::new() }
        );
        assert!(ArtifactLocation::parse("s3://").is_err());
        assert!(ArtifactLocation::parse("gs://b").unwrap_err().contains("s3://BUCKET"));
    }

    /// The bucket of `.ci/run`'s SeaweedFS under a fresh prefix, or `None`
    /// (skipped with a note) without `MESHATLAS_TEST_S3_ENDPOINT`; in CI an
    /// unset variable fails the test.
    fn test_bucket() -> Option<S3Artifacts> {
        if std::env::var_os("MESHATLAS_TEST_S3_ENDPOINT").is_none() {
            assert!(std::env::var_os("CI").is_none(), "CI must set MESHATLAS_TEST_S3_ENDPOINT (see .ci/run)");
            eprintln!("MESHATLAS_TEST_S3_ENDPOINT is unset: S3 artifact tests skipped");
            return None;
        }
        // .ci/services.sh exports AWS_ENDPOINT_URL and the credentials beside it.
        let bucket = std::env::var("MESHATLAS_TEST_S3_BUCKET").unwrap_or_else(|_| "meshatlas".into());
        Some(S3Artifacts::connect(&bucket, &format!("t_{}", uuid::Uuid::new_v4().simple())).unwrap())
    }

    #[test]
    fn job_directories_are_listed_once_with_their_age() {
        let Some(s3) = test_bucket() else { return };
        let dir = tempfile::tempdir().unwrap();
        for key in ["jobs/a/input/x.stl", "jobs/a/out/1/mesh.msh", "jobs/b/input/y.stl", "tmp/probe"] {
            let file = dir.path().join(key);
            std::fs::create_dir_all(file.parent().unwrap()).unwrap();
            std::fs::write(&file, key).unwrap();
            s3.put(dir.path(), key).unwrap();
        }
        // Written just now; S3 keeps `last_modified` to the second.
        std::thread::sleep(std::time::Duration::from_millis(1100));
        assert_eq!(s3.job_dirs_older_than(std::time::Duration::ZERO).unwrap(), ["a", "b"]);
        assert!(s3.job_dirs_older_than(std::time::Duration::from_secs(3600)).unwrap().is_empty());
        assert!(LocalArtifacts.job_dirs_older_than(std::time::Duration::ZERO).unwrap().is_empty());
    }

    #[test]
    fn files_go_up_and_come_back_byte_for_byte_and_prefixes_delete() {
        let Some(s3) = test_bucket() else { return };
        s3.probe().unwrap();
        let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        // Larger than one multipart part, with no repeating pattern.
        let big: Vec<u8> = (0..PART_BYTES + 12_345).map(|i| ((i * 2_654_435_761usize) >> 13) as u8).collect();
        for (key, bytes) in
            [("jobs/x/out/1/big.msh", &big[..]), ("jobs/x/out/2/r.json", b"{}"), ("jobs/x/input/a.stl", b"solid")]
        {
            let f = a.path().join(key);
            std::fs::create_dir_all(f.parent().unwrap()).unwrap();
            std::fs::write(&f, bytes).unwrap();
            s3.put(a.path(), key).unwrap();
        }
        assert!(s3.fetch(b.path(), "jobs/x/out/1/big.msh").unwrap());
        assert_eq!(std::fs::read(b.path().join("jobs/x/out/1/big.msh")).unwrap(), big);
        assert!(!s3.fetch(b.path(), "jobs/x/out/1/none.msh").unwrap());
        s3.delete_prefix("jobs/x/out/", Some("jobs/x/out/2")).unwrap();
        let c = tempfile::tempdir().unwrap();
        assert!(!s3.fetch(c.path(), "jobs/x/out/1/big.msh").unwrap(), "other attempts are removed");
        assert!(s3.fetch(c.path(), "jobs/x/out/2/r.json").unwrap(), "the kept attempt stays");
        s3.delete_prefix("jobs/x/", None).unwrap();
        let d = tempfile::tempdir().unwrap();
        assert!(!s3.fetch(d.path(), "jobs/x/input/a.stl").unwrap());
    }

    #[test]
    fn a_streamed_object_is_whole_once_finished_and_absent_when_dropped() {
        let Some(s3) = test_bucket() else { return };
        let big: Vec<u8> = (0..2 * PART_BYTES + 777).map(|i| ((i * 2_654_435_761usize) >> 11) as u8).collect();
        let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
        let send = |key: &str, finish: bool| {
            let mut put = s3.stream_put(key).unwrap();
            rt.block_on(async {
                for chunk in big.chunks(64 * 1024 + 3) {
                    put.write(bytes::Bytes::copy_from_slice(chunk)).await.unwrap();
                }
                if finish {
                    put.finish().await.unwrap();
                }
            });
        };
        send("jobs/s/input/big.stl", true);
        send("jobs/s/input/cut.stl", false);
        let d = tempfile::tempdir().unwrap();
        assert!(s3.fetch(d.path(), "jobs/s/input/big.stl").unwrap());
        assert_eq!(std::fs::read(d.path().join("jobs/s/input/big.stl")).unwrap(), big);
        // Two parts were sent before the drop; an unfinished multipart upload is no object.
        assert!(!s3.fetch(d.path(), "jobs/s/input/cut.stl").unwrap(), "an abandoned upload left an object");
        assert!(LocalArtifacts.stream_put("jobs/s/input/x.stl").is_none());
        s3.delete_prefix("jobs/s/", None).unwrap();
    }
}
