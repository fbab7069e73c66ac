//! Artifact downloads with `Content-Encoding: zstd` or `gzip` (issue 12 §2):
//! a client that accepts either gets fewer bytes that decode to the file
//! (zstd when it weighs zstd at least as high as gzip); a range, or a
//! client without `Accept-Encoding`, gets the identity bytes with their own
//! `Content-Length` and `ETag`; every answer says `Vary: Accept-Encoding`.
//! reqwest (with its `gzip` feature) and `curl --compressed` decode the
//! encoded downloads.

use std::io::Read;
use std::time::Duration;

use serde_json::Value;

use crate::common::{Server, is_final, shared_data};

/// Runs the atlas on the small sphere and returns the finished job.
async fn finished_job(s: &Server) -> Value {
    let stl = std::fs::read(shared_data("gmsh/sphere_tiny.stl")).unwrap();
    let r = s.submit_bytes("sphere_tiny.stl", stl, Some(r#"{"stages": ["atlas"]}"#)).await;
    assert_eq!(r.status(), 202);
    let job: Value = r.json().await.unwrap();
    let done = s.wait_final(job["id"].as_str().unwrap(), Duration::from_secs(60)).await;
    assert!(is_final(&done) && done["state"] == "succeeded", "{done:#}");
    done
}

/// The download URL and listed size of artifact `name`.
fn artifact(s: &Server, job: &Value, name: &str) -> (String, u64) {
    let a = job["artifacts"].as_array().unwrap().iter().find(|a| a["name"] == name).expect(name);
    (s.url(a["url"].as_str().unwrap()), a["bytes"].as_u64().unwrap())
}

fn header(r: &reqwest::Response, name: &str) -> Option<String> {
    r.headers().get(name).map(|v| v.to_str().unwrap().to_string())
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(bytes).read_to_end(&mut out).unwrap();
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gzip_is_sent_to_clients_that_accept_it_and_identity_otherwise() {
    let s = Server::start(&[]);
    let job = finished_job(&s).await;
    for name in ["atlas.msh", "mesh.msh", "mesh.vtu", "report.json"] {
        let (url, bytes) = artifact(&s, &job, name);
        let plain = s.client.get(&url).send().await.unwrap();
        assert_eq!(plain.status(), 200);
        assert_eq!(header(&plain, "content-encoding"), None, "{name}: no Accept-Encoding, identity");
        assert_eq!(header(&plain, "content-length"), Some(bytes.to_string()), "{name}");
        assert_eq!(header(&plain, "vary").as_deref(), Some("accept-encoding"), "{name}");
        let plain_etag = header(&plain, "etag").unwrap();
        let identity = plain.bytes().await.unwrap().to_vec();
        assert_eq!(identity.len() as u64, bytes);

        let gz = s.client.get(&url).header("accept-encoding", "br;q=1, gzip;q=0.8").send().await.unwrap();
        assert_eq!(gz.status(), 200);
        assert_eq!(header(&gz, "content-encoding").as_deref(), Some("gzip"), "{name}");
        assert_eq!(header(&gz, "vary").as_deref(), Some("accept-encoding"), "{name}");
        let gz_etag = header(&gz, "etag").unwrap();
        assert_ne!(gz_etag, plain_etag, "{name}: each representation has its own ETag");
        assert!(header(&gz, "content-type").is_some_and(|t| !t.contains("gzip")), "{name}: the artifact's type");
        let body = gz.bytes().await.unwrap().to_vec();
        assert!(body.len() < identity.len(), "{name}: gzip {} >= identity {}", body.len(), identity.len());
        assert!(gunzip(&body) == identity, "{name}: the gzip body decodes to the file");

        // Conditional GET on the gzip representation.
        let again = s
            .client
            .get(&url)
            .header("accept-encoding", "gzip")
            .header("if-none-match", &gz_etag)
            .send()
            .await
            .unwrap();
        assert_eq!(again.status(), 304, "{name}");
        assert_eq!(header(&again, "vary").as_deref(), Some("accept-encoding"));

        // A range addresses the identity bytes, whatever Accept-Encoding says.
        let r =
            s.client.get(&url).header("accept-encoding", "gzip").header("range", "bytes=5-24").send().await.unwrap();
        assert_eq!(r.status(), 206, "{name}");
        assert_eq!(header(&r, "content-encoding"), None, "{name}");
        assert_eq!(header(&r, "content-range"), Some(format!("bytes 5-24/{bytes}")));
        assert_eq!(header(&r, "etag"), Some(plain_etag.clone()), "{name}");
        assert_eq!(r.bytes().await.unwrap().to_vec(), identity[5..25].to_vec());

        // A zero weight refuses gzip.
        let r = s.client.get(&url).header("accept-encoding", "gzip;q=0, identity").send().await.unwrap();
        assert_eq!(header(&r, "content-encoding"), None, "{name}");
        assert_eq!(header(&r, "etag"), Some(plain_etag));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reqwest_decodes_the_gzip_download_of_msh_and_vtu() {
    let s = Server::start(&[]);
    let job = finished_job(&s).await;
    // reqwest's own gzip decoding (it sends `Accept-Encoding: gzip` itself).
    let client = reqwest::Client::builder().gzip(true).build().unwrap();
    let (url, bytes) = artifact(&s, &job, "atlas.msh");
    let identity = s.client.get(&url).send().await.unwrap().bytes().await.unwrap().to_vec();
    let decoded = client.get(&url).send().await.unwrap().bytes().await.unwrap().to_vec();
    assert_eq!(decoded.len() as u64, bytes);
    assert!(decoded == identity, "reqwest decodes to the identity bytes");
    // The VTU files (zlib-compressed arrays) are gzip-encoded too.
    let (url, bytes) = artifact(&s, &job, "atlas.vtu");
    let identity = s.client.get(&url).send().await.unwrap().bytes().await.unwrap().to_vec();
    let r = client.get(&url).send().await.unwrap();
    assert_eq!(header(&r, "vary").as_deref(), Some("accept-encoding"));
    let decoded = r.bytes().await.unwrap().to_vec();
    assert!(decoded.len() as u64 == bytes && decoded == identity, "atlas.vtu decodes to the identity bytes");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn zstd_is_sent_when_weighed_at_least_as_high_as_gzip() {
    let s = Server::start(&[]);
    let job = finished_job(&s).await;
    for name in ["atlas.msh", "atlas.vtu", "report.json"] {
        let (url, bytes) = artifact(&s, &job, name);
        let plain = s.client.get(&url).send().await.unwrap();
        let plain_etag = header(&plain, "etag").unwrap();
        let identity = plain.bytes().await.unwrap().to_vec();
        let gz = s.client.get(&url).header("accept-encoding", "gzip").send().await.unwrap();
        let gz_etag = header(&gz, "etag").unwrap();
        let gz_len = gz.bytes().await.unwrap().len();

        for accept in ["gzip, deflate, br, zstd", "zstd;q=0.5, gzip;q=0.5", "zstd", "*"] {
            let z = s.client.get(&url).header("accept-encoding", accept).send().await.unwrap();
            assert_eq!(z.status(), 200, "{name} {accept}");
            assert_eq!(header(&z, "content-encoding").as_deref(), Some("zstd"), "{name} {accept}");
            assert_eq!(header(&z, "vary").as_deref(), Some("accept-encoding"), "{name}");
            let etag = header(&z, "etag").unwrap();
            assert!(etag != plain_etag && etag != gz_etag, "{name}: each representation has its own ETag");
            let body = z.bytes().await.unwrap().to_vec();
            assert!(body.len() < identity.len(), "{name}: zstd {} >= identity {bytes}", body.len());
            assert!(zstd::decode_all(&body[..]).unwrap() == identity, "{name}: the zstd body decodes to the file");
            if name == "atlas.msh" {
                assert!(body.len() < gz_len, "{name}: zstd {} >= gzip {gz_len}", body.len());
            }
        }
        // gzip weighed higher, or zstd refused, gives gzip.
        for accept in ["gzip;q=1, zstd;q=0.5", "zstd;q=0, *"] {
            let r = s.client.get(&url).header("accept-encoding", accept).send().await.unwrap();
            assert_eq!(header(&r, "content-encoding").as_deref(), Some("gzip"), "{name} {accept}");
        }
        // A range still addresses the identity bytes.
        let r = s.client.get(&url).header("accept-encoding", "zstd").header("range", "bytes=0-9").send().await.unwrap();
        assert_eq!(r.status(), 206, "{name}");
        assert_eq!(header(&r, "content-encoding"), None, "{name}");
    }
}

/// `curl --compressed` (it asks for every coding its libcurl decodes; Debian's
/// has zstd) gets a download that decodes to the identity bytes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn curl_decodes_the_compressed_download() {
    let s = Server::start(&[]);
    let job = finished_job(&s).await;
    let (url, _) = artifact(&s, &job, "atlas.msh");
    let identity = s.client.get(&url).send().await.unwrap().bytes().await.unwrap().to_vec();
    let dir = tempfile::tempdir().unwrap();
    let (body, head) = (dir.path().join("body"), dir.path().join("head"));
    let mut cmd = std::process::Command::new("curl");
    cmd.args(["--silent", "--show-error", "--fail", "--compressed", "--dump-header"])
        .arg(&head)
        .arg("--output")
        .arg(&body);
    let out = cmd.arg(&url).output().expect("curl runs");
    assert!(out.status.success(), "curl: {}", String::from_utf8_lossy(&out.stderr));
    let head = std::fs::read_to_string(&head).unwrap().to_ascii_lowercase();
    let version = std::process::Command::new("curl").arg("--version").output().unwrap();
    let coding = if String::from_utf8_lossy(&version.stdout).contains("zstd/") { "zstd" } else { "gzip" };
    assert!(head.contains(&format!("content-encoding: {coding}")), "{head}");
    assert!(std::fs::read(&body).unwrap() == identity, "curl decodes to the identity bytes");
}
