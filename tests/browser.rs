//! The HTML pages in a real browser (issue 15): Debian's `chromium`, headless,
//! against the real `meshatlas serve` binary on a loopback port.
//!
//! 1. A job submitted over the JSON API, then its page loaded with
//!    `chromium --dump-dom` and `--screenshot`: the progress bar is at 100 %,
//!    every `image/*` artifact is a loaded `<img>` (the page's script writes
//!    `data-natural-width` on `load`, `data-failed` on `error`), and every
//!    download link answers 200 with the byte count the page shows.
//! 2. A mesh uploaded through the start page's form by puppeteer-core
//!    (`tests/browser/upload.js`), which follows the page to the job page and
//!    records the progress bar until the job is final; the job is then read
//!    back over the JSON API.
//!
//! Tools: chromium (`$CHROMIUM`, else `chromium` or `chromium-browser` on
//! PATH), node, and `tests/browser/node_modules` (`npm ci` there; `.ci/run`
//! installs all three). With `CI` set a missing tool fails the test;
//! otherwise the test is skipped with the reason printed.

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// Virtual-time budget of `--dump-dom`/`--screenshot`, ms: enough for the
/// page's fetches and image loads of a finished job.
const VIRTUAL_TIME_MS: &str = "15000";
/// Longest wall time of one chromium run.
const CHROMIUM_TIMEOUT: Duration = Duration::from_secs(90);

/// A `meshatlas serve` child on `127.0.0.1:0` with its own data directory; killed on drop.
struct Server {
    child: Child,
    base: String,
    dir: tempfile::TempDir,
    client: reqwest::Client,
    /// The bearer token of the server's one tenant, when it needs one.
    token: Option<String>,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Server {
    /// Starts the binary with one worker; with `token`, that token is the
    /// only one (`--auth-tokens`).
    fn start(token: Option<&str>) -> Server {
        let dir = tempfile::tempdir().unwrap();
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshatlas"));
        cmd.args(["serve", "--addr", "127.0.0.1:0", "--workers", "1"]);
        if let Some(t) = token {
            let tokens = dir.path().join("tokens.txt");
            std::fs::write(&tokens, format!("{t} browser\n")).unwrap();
            cmd.arg("--auth-tokens").arg(tokens);
        }
        cmd.arg("--data-dir").arg(dir.path().join("data")).env("MESHATLAS_LOG", "warn");
        let (child, base) = common::spawn_listening_logged(cmd, &dir.path().join("server.log"));
        let client = reqwest::Client::builder().no_gzip().build().unwrap();
        Server { child, base, dir, client, token: token.map(str::to_string) }
    }

    fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// GET `path` with the server's token, if any.
    fn get(&self, path: &str) -> reqwest::RequestBuilder {
        let req = self.client.get(self.url(path));
        match &self.token {
            Some(t) => req.bearer_auth(t),
            None => req,
        }
    }

    /// The job resource as JSON.
    async fn job(&self, id: &str) -> Value {
        let resp = self.get(&format!("/v1/jobs/{id}")).send().await.unwrap();
        assert_eq!(resp.status(), 200);
        resp.json().await.unwrap()
    }

    /// Polls the job until it is succeeded, failed or cancelled.
    async fn wait_final(&self, id: &str) -> Value {
        let start = Instant::now();
        loop {
            let job = self.job(id).await;
            if matches!(job["state"].as_str(), Some("succeeded" | "failed" | "cancelled")) {
                return job;
            }
            assert!(start.elapsed() < Duration::from_secs(120), "job never finished: {job:#}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
}

/// A fresh `<target tmp>/browser/<test>` for a test's DOM dump and
/// screenshots, kept after the run for a look.
fn out_dir(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("browser").join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An icosphere of `20 · 4^level` triangles as binary STL (the library's writer).
fn sphere_stl(level: usize) -> Vec<u8> {
    let mut out = Vec::new();
    meshatlas::io::stl_write::write_stl_binary(&mut out, &meshatlas::mesh::fixtures::icosphere(level)).unwrap();
    out
}

/// `found`, or: with `CI` set a failure naming `what`, else `None` after
/// printing why the test is skipped.
fn required<T>(what: &str, found: Option<T>) -> Option<T> {
    if found.is_some() {
        return found;
    }
    assert!(std::env::var_os("CI").is_none(), "{what} is missing; .ci/run installs it");
    eprintln!("skipping: {what} is missing (run .ci/run to install it)");
    None
}

/// The first of `names` that is an executable file on PATH.
fn on_path(names: &[&str]) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    names.iter().flat_map(|n| std::env::split_paths(&path).map(move |d| d.join(n))).find(|p| p.is_file())
}

/// The chromium binary: `$CHROMIUM`, else `chromium` or `chromium-browser` on PATH.
fn chromium() -> Option<PathBuf> {
    let found = match std::env::var_os("CHROMIUM") {
        Some(p) => Some(PathBuf::from(p)).filter(|p| p.is_file()),
        None => on_path(&["chromium", "chromium-browser"]),
    };
    required("chromium (apt-get install chromium)", found)
}

/// `tests/browser`, where the node helpers and their node_modules live.
fn helpers_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser")
}

/// node, if puppeteer-core is installed beside the helpers.
fn node_with_puppeteer() -> Option<PathBuf> {
    let node = required("node (apt-get install nodejs npm)", on_path(&["node", "nodejs"]))?;
    let installed = helpers_dir().join("node_modules/puppeteer-core/package.json").is_file();
    required("puppeteer-core (npm ci in tests/browser)", installed.then_some(node))
}

/// Runs headless chromium on `url` with `extra` flags; its stdout.
fn run_chromium(chromium: &Path, profile: &Path, url: &str, extra: &[&str]) -> String {
    let mut child = Command::new(chromium)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--hide-scrollbars"])
        .args(["--no-first-run", "--no-default-browser-check", "--window-size=1280,2000"])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--virtual-time-budget={VIRTUAL_TIME_MS}"))
        .args(extra)
        .arg(url)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", chromium.display()));
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > CHROMIUM_TIMEOUT {
            let _ = child.kill();
            panic!("chromium did not finish within {CHROMIUM_TIMEOUT:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "chromium failed ({}): {}", out.status, String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// One element of a serialized DOM: its attributes (entities decoded) and
/// the text up to the next tag.
struct Element {
    attrs: HashMap<String, String>,
    text: String,
}

/// Decodes the entities Chromium's serializer writes.
fn unescape(s: &str) -> String {
    s.replace("&quot;", "\"")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&nbsp;", "\u{a0}")
        .replace("&amp;", "&")
}

/// Every `<tag …>` of `dom`, in document order. Chromium serializes every
/// attribute as `name="value"` or a bare `name`.
fn elements(dom: &str, tag: &str) -> Vec<Element> {
    let open = format!("<{tag}");
    let mut found = Vec::new();
    let mut rest = dom;
    while let Some(i) = rest.find(&open) {
        rest = &rest[i + open.len()..];
        if !rest.starts_with([' ', '>', '/']) {
            continue;
        }
        let mut attrs = HashMap::new();
        let mut s = rest.trim_start();
        while !s.starts_with('>') && !s.is_empty() {
            let end = s.find(['=', ' ', '>']).unwrap_or(s.len());
            let name = s[..end].to_string();
            s = &s[end..];
            if let Some(v) = s.strip_prefix("=\"") {
                let close = v.find('"').expect("closing quote");
                attrs.insert(name, unescape(&v[..close]));
                s = &v[close + 1..];
            } else {
                attrs.insert(name, String::new());
            }
            s = s.trim_start();
        }
        let after = s.strip_prefix('>').unwrap_or(s);
        let text = unescape(&after[..after.find('<').unwrap_or(after.len())]);
        found.push(Element { attrs, text });
    }
    found
}

/// `n` bytes as the page shows them (`humanBytes` in src/http/page/app.js).
fn human_bytes(n: u64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB"];
    let (mut v, mut u) = (n as f64, 0);
    while v >= 1024.0 && u < units.len() - 1 {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        return format!("{n} B");
    }
    let digits = if v >= 100.0 {
        0
    } else if v >= 10.0 {
        1
    } else {
        2
    };
    // JavaScript's toFixed rounds an exact tie up, Rust's `{:.1}` to even
    // (17.25 KiB: "17.3" against "17.2"), so round in integers, half up:
    // n / 1024^u is exact, and so is this.
    let (scale, unit) = (10u128.pow(digits), 1024u128.pow(u as u32));
    let q = (u128::from(n) * scale * 2 + unit) / (2 * unit);
    let (whole, frac) = (q / scale, q % scale);
    match digits {
        0 => format!("{whole} {}", units[u]),
        d => format!("{whole}.{frac:0width$} {}", units[u], width = d as usize),
    }
}

/// Names of the job's artifacts whose media type is an image.
fn image_artifacts(job: &Value) -> Vec<String> {
    job["artifacts"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["media_type"].as_str().is_some_and(|m| m.starts_with("image/")))
        .map(|a| a["name"].as_str().unwrap().to_string())
        .collect()
}

/// Submits `stl` as a multipart upload with `?stages=`; the job JSON.
async fn submit(s: &Server, name: &str, stl: Vec<u8>, stages: &str) -> Value {
    let form =
        reqwest::multipart::Form::new().part("file", reqwest::multipart::Part::bytes(stl).file_name(name.to_string()));
    let resp = s.client.post(s.url(&format!("/v1/jobs?stages={stages}"))).multipart(form).send().await.unwrap();
    assert_eq!(resp.status(), 202);
    resp.json().await.unwrap()
}

/// Every download link of the page answers 200 with the bytes the page and
/// the JSON state, and the page shows that size.
async fn check_downloads(s: &Server, dom: &str, job: &Value) {
    let links: Vec<Element> =
        elements(dom, "a").into_iter().filter(|a| a.attrs.get("class").is_some_and(|c| c == "download")).collect();
    let sizes: Vec<String> = elements(dom, "td")
        .into_iter()
        .filter(|t| t.attrs.get("class").is_some_and(|c| c == "num size"))
        .map(|t| t.text)
        .collect();
    let artifacts = job["artifacts"].as_array().unwrap();
    assert_eq!(links.len(), artifacts.len(), "one link per artifact");
    assert_eq!(sizes.len(), links.len(), "one size per link");
    for ((link, shown), art) in links.iter().zip(&sizes).zip(artifacts) {
        let href = &link.attrs["href"];
        assert_eq!(Some(href.as_str()), art["url"].as_str());
        let resp = s.client.get(s.url(href)).send().await.unwrap();
        assert_eq!(resp.status(), 200, "{href}");
        let n = resp.bytes().await.unwrap().len() as u64;
        assert_eq!(Some(n), art["bytes"].as_u64(), "{href}: bytes downloaded vs the JSON");
        assert_eq!(link.attrs["data-bytes"], n.to_string(), "{href}: bytes in the page");
        assert_eq!(shown, &human_bytes(n), "{href}: size shown");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_finished_job_page_shows_full_progress_previews_and_working_downloads() {
    let Some(chromium) = chromium() else { return };
    let s = Server::start(None);
    let job = submit(&s, "sphere.stl", sphere_stl(4), "atlas,crossfield").await;
    let id = job["id"].as_str().unwrap();
    let job = s.wait_final(id).await;
    assert_eq!(job["state"], "succeeded", "{job:#}");
    let page = s.url(&format!("/v1/jobs/{id}"));
    let out = out_dir("finished_job_page");
    let profile = s.dir.path().join("chromium");

    let dom = run_chromium(&chromium, &profile, &page, &["--dump-dom"]);
    std::fs::write(out.join("job.html"), &dom).unwrap();
    let body = &elements(&dom, "body")[0];
    assert_eq!(body.attrs.get("data-final").map(String::as_str), Some("succeeded"), "page not final:\n{dom}");
    let bar = &elements(&dom, "progress")[0];
    assert_eq!((bar.attrs["value"].as_str(), bar.attrs["data-progress"].as_str()), ("1", "100"), "{dom}");
    assert!(dom.contains("sphere.stl"), "the input's name is shown");

    let images = image_artifacts(&job);
    let shown = elements(&dom, "img");
    for name in &images {
        let img = shown.iter().find(|i| i.attrs.get("data-artifact") == Some(name));
        let img = img.unwrap_or_else(|| panic!("no <img> for {name}:\n{dom}"));
        assert!(!img.attrs.contains_key("data-failed"), "{name} failed to load");
        let width: u32 = img.attrs.get("data-natural-width").and_then(|w| w.parse().ok()).unwrap_or(0);
        assert!(width > 0, "{name} has no natural width");
    }
    assert!(!images.is_empty(), "the job has no image/* artifact (previews)");
    check_downloads(&s, &dom, &job).await;

    let png = out.join("job.png");
    run_chromium(&chromium, &profile, &page, &[&format!("--screenshot={}", png.display())]);
    let bytes = std::fs::read(&png).expect("screenshot written");
    assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000, "screenshot {} looks empty", png.display());
    eprintln!("screenshot: {}", png.display());
}

/// Runs `tests/browser/upload.js` (puppeteer-core) against `s`: uploads
/// `mesh` with stages atlas and crossfield through the start page, typing the
/// server's token when it has one; its JSON report.
async fn upload_through_the_form(s: &Server, node: PathBuf, chromium: PathBuf, mesh: &Path, png: &Path) -> Value {
    let mut cmd = Command::new(node);
    cmd.arg(helpers_dir().join("upload.js")).arg(chromium).arg(&s.base).arg(mesh).arg("atlas,crossfield").arg(png);
    cmd.args(&s.token);
    let out = tokio::task::spawn_blocking(move || cmd.output().expect("run node")).await.unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "upload.js failed: {}\n{stdout}", String::from_utf8_lossy(&out.stderr));
    let report: Value = serde_json::from_str(stdout.lines().last().unwrap_or("")).expect("JSON from upload.js");
    eprintln!("screenshot: {}\n{report}", png.display());
    assert_eq!(report["final_state"], "succeeded", "{report:#}");
    assert_eq!(report["console_errors"], serde_json::json!([]), "{report:#}");
    report
}

/// Every image artifact of `job` is a loaded image in the page's `report`
/// (through an object URL when `via_blob`), and there is at least one.
fn assert_previews_loaded(job: &Value, report: &Value, via_blob: bool) {
    let images = image_artifacts(job);
    for name in &images {
        let img = report["images"].as_array().unwrap().iter().find(|i| i["name"] == name.as_str());
        let img = img.unwrap_or_else(|| panic!("no <img> for {name}: {report:#}"));
        assert!(img["width"].as_u64() > Some(0), "{name} not loaded: {report:#}");
        assert_eq!(img["blob"], via_blob, "{name}: loaded through an object URL: {report:#}");
    }
    assert!(!images.is_empty(), "the job has no image/* artifact (previews)");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_mesh_uploaded_through_the_form_runs_to_the_end_on_its_page() {
    let Some(chromium) = chromium() else { return };
    let Some(node) = node_with_puppeteer() else { return };
    let s = Server::start(None);
    let mesh = s.dir.path().join("ball.stl");
    std::fs::write(&mesh, sphere_stl(5)).unwrap();
    let png = out_dir("upload_form").join("upload.png");
    let report = upload_through_the_form(&s, node, chromium, &mesh, &png).await;
    let seen: Vec<u64> = report["progress_seen"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
    assert_eq!(seen.last(), Some(&100), "{report:#}");
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "the progress bar went back: {seen:?}");
    // The 20k-triangle job runs for a second or more: the page showed it unfinished first.
    let states = report["states_seen"].as_array().unwrap();
    assert!(
        states.iter().any(|s| s == "running" || s == "queued"),
        "the page never showed the job running: {report:#}"
    );
    let id = report["id"].as_str().unwrap();
    let job = s.job(id).await;
    assert_eq!(job["state"], "succeeded");
    assert_eq!(job["input"]["name"], "ball.stl");
    assert_eq!(job["params"]["stages"], serde_json::json!(["atlas", "crossfield"]));
    let names: Vec<&str> =
        report["downloads"].as_array().unwrap().iter().map(|d| d["name"].as_str().unwrap()).collect();
    let listed: Vec<&str> = job["artifacts"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
    assert_eq!(names, listed, "the page links every artifact");
    assert_previews_loaded(&job, &report, false);
    assert!(std::fs::metadata(&png).is_ok_and(|m| m.len() > 10_000), "screenshot missing");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_tokens_the_page_asks_for_one_and_loads_previews_with_it() {
    let Some(chromium) = chromium() else { return };
    let Some(node) = node_with_puppeteer() else { return };
    let s = Server::start(Some("browser-test-token-0123456789"));
    let shell = s.client.get(s.url("/")).header("accept", "text/html").send().await.unwrap();
    assert_eq!(shell.status(), 200, "the shell needs no token");
    let list = s.client.get(s.url("/v1/jobs")).send().await.unwrap();
    assert_eq!(list.status(), 401, "the JSON does");
    let mesh = s.dir.path().join("small.stl");
    std::fs::write(&mesh, sphere_stl(3)).unwrap();
    let png = out_dir("upload_with_token").join("upload.png");
    let report = upload_through_the_form(&s, node, chromium, &mesh, &png).await;
    let job = s.job(report["id"].as_str().unwrap()).await;
    assert_eq!((&job["state"], &job["input"]["name"]), (&"succeeded".into(), &"small.stl".into()));
    assert_previews_loaded(&job, &report, true);
}

#[test]
fn sizes_are_formatted_as_the_page_formats_them() {
    // Node's answers for the page's humanBytes, ties (17.25, 1.125) included.
    let cases = [
        (17664, "17.3 KiB"),
        (1023, "1023 B"),
        (1024, "1.00 KiB"),
        (102400, "100 KiB"),
        (17612, "17.2 KiB"),
        (1029, "1.00 KiB"),
        (5767168, "5.50 MiB"),
        (1152, "1.13 KiB"),
    ];
    for (n, want) in cases {
        assert_eq!(human_bytes(n), want, "{n} bytes");
    }
}
