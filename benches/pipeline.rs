//! Bench harness (issue 2 §7): runs the meshatlas pipeline (release build)
//! on the files given on the command line, one child process per file, and
//! prints per-step wall time (each stage's `<stage>.write` and the final
//! `write` included), the bytes of every artifact written with their total
//! (on disk, and as gzip and zstd downloads),
//! and peak memory; with `--gmsh` it runs Gmsh's
//! Python API on the same file (`benches/gmsh_reference.py`) and prints the
//! time ratio per step.
//!
//! ```sh
//! cargo bench --bench pipeline -- [--gmsh] [--stages atlas,crossfield] [--out bench-out] FILE...
//! cargo bench --bench pipeline -- --generate sphere:1000000:bench-out/sphere_1m.stl [FILE...]
//! cargo bench --bench pipeline -- --gmsh --stages quads [--gmsh-timeout 120] FILE...
//! ```
//!
//! With `quads` among the stages, each file also gets a side-by-side table
//! against Gmsh's quasi-structured quad mesher (`pipeline/quads.rs`): both
//! quad meshes scored by one script (`benches/quad_metrics.py`), beside the
//! numbers of meshatlas's own report. Gmsh runs with 1 thread (2 deadlock)
//! and is killed after `--gmsh-timeout` seconds (default 120), reported as
//! `hang > N s`.
//!
//! `--service` also runs each file through `meshatlas serve` (one server
//! for the run, its numerical pool on every core) from POST to `succeeded`
//! and prints the job's own step timings and the whole job beside the CLI's,
//! with the ratio service / CLI.
//!
//! `--generate KIND:N:PATH` (repeatable) first writes a binary STL of about
//! N triangles: `sphere` (a cube grid projected on the unit sphere, 12·n²
//! triangles) or `torus` (radii 1 and 0.3, 6·n² triangles), then benches it
//! with the other files.
//!
//! It is stage-agnostic: rows come from the `timings` of the pipeline
//! report (`meshatlas run --json`), so a new stage shows up by itself.
//! Memory is each child's peak RSS (`VmHWM` / `ru_maxrss`).

#[path = "pipeline/quads.rs"]
mod quads;

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use clap::Parser;
use serde_json::Value;

#[derive(Parser)]
#[command(about = "meshatlas pipeline bench (optionally against Gmsh)")]
struct Args {
    /// Input meshes.
    files: Vec<PathBuf>,
    /// Also run Gmsh's reference for each file and print ratios.
    #[arg(long)]
    gmsh: bool,
    /// Stages to run (default: none, i.e. load + repair + write).
    #[arg(long, default_value = "")]
    stages: String,
    /// Directory for the outputs.
    #[arg(long, default_value = "bench-out")]
    out: PathBuf,
    /// Generate an input first: `sphere:N:PATH` or `torus:N:PATH` (about N
    /// triangles, binary STL). Repeatable; generated files are benched too.
    #[arg(long)]
    generate: Vec<String>,
    /// Also run each file through the service (`meshatlas serve`, numerical
    /// pool on every core) from POST to `succeeded`, and print it beside the
    /// CLI run with the ratio.
    #[arg(long)]
    service: bool,
    /// Seconds after which the Gmsh reference is killed and reported as a
    /// hang (its quad mesher never finishes on some inputs).
    #[arg(long, default_value_t = 120.0)]
    gmsh_timeout: f64,
    /// Passed by `cargo bench`; ignored.
    #[arg(long, hide = true)]
    bench: bool,
}

/// Result of one tool on one file.
#[derive(Default)]
struct Run {
    steps: Vec<(String, f64)>,
    peak_rss_kb: Option<u64>,
    n_triangles: Option<u64>,
    wall: f64,
    failure: Option<String>,
    /// `(name, bytes)` of every artifact the run wrote.
    artifacts: Vec<(String, u64)>,
    /// The pipeline's own `total_seconds`.
    total_seconds: Option<f64>,
    /// The quads stage's report (`stages.quads`), meshatlas only.
    quads_report: Option<Value>,
    /// The quad mesh size Gmsh was given (the mean input edge length).
    mesh_size: Option<f64>,
}

fn run_meshatlas(file: &Path, stages: &str, out: &Path) -> Run {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshatlas"));
    cmd.arg("run").arg(file).arg("--out").arg(out).arg("--json");
    if !stages.is_empty() {
        cmd.arg("--stages").arg(stages);
    }
    let start = Instant::now();
    let output = match cmd.output() {
        Ok(o) => o,
        Err(e) => return Run { failure: Some(format!("cannot start meshatlas: {e}")), ..Run::default() },
    };
    let wall = start.elapsed().as_secs_f64();
    if !output.status.success() {
        let err = String::from_utf8_lossy(&output.stderr).trim().to_string();
        return Run { wall, failure: Some(format!("{}: {err}", output.status)), ..Run::default() };
    }
    let report: Value = match serde_json::from_slice(&output.stdout) {
        Ok(v) => v,
        Err(e) => return Run { wall, failure: Some(format!("unreadable report: {e}")), ..Run::default() },
    };
    let steps = report["timings"]
        .as_array()
        .map(|ts| ts.iter().filter_map(|t| Some((t["step"].as_str()?.to_string(), t["seconds"].as_f64()?))).collect())
        .unwrap_or_default();
    let artifacts = report["artifacts"]
        .as_array()
        .map(|a| a.iter().filter_map(|x| Some((x["name"].as_str()?.to_string(), x["bytes"].as_u64()?))).collect())
        .unwrap_or_default();
    Run {
        steps,
        artifacts,
        total_seconds: report["total_seconds"].as_f64(),
        peak_rss_kb: report["peak_rss_kb"].as_u64(),
        n_triangles: report["input"]["n_triangles"].as_u64(),
        quads_report: report["stages"].get("quads").cloned(),
        wall,
        failure: None,
        mesh_size: None,
    }
}

/// Everything a pipe gives until it closes (empty when there is none).
fn read_pipe(pipe: Option<impl Read>) -> String {
    let mut text = String::new();
    if let Some(mut p) = pipe {
        let _ = p.read_to_string(&mut text);
    }
    text
}

/// Waits for `child` at most `limit`; kills it when the limit passes
/// (`None`: killed).
fn wait_at_most(child: &mut Child, limit: Duration) -> Option<ExitStatus> {
    let start = Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(status)) => return Some(status),
            Ok(None) if start.elapsed() < limit => std::thread::sleep(Duration::from_millis(20)),
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                return None;
            }
        }
    }
}

/// Runs `benches/gmsh_reference.py` on `file` (Gmsh's own atlas, and its
/// quad mesh into `out` for the quads stage), killed after `timeout_s`.
fn run_gmsh(file: &Path, stages: &str, out: &Path, timeout_s: f64) -> Run {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/gmsh_reference.py");
    let gmsh_stages = if stages.is_empty() { "atlas" } else { stages };
    let start = Instant::now();
    let spawned = Command::new("python3")
        .arg(script)
        .arg(file)
        .arg(gmsh_stages)
        .arg(out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn();
    let mut child = match spawned {
        Ok(c) => c,
        Err(e) => return Run { failure: Some(format!("cannot start python3: {e}")), ..Run::default() },
    };
    let (stdout, stderr) = (child.stdout.take(), child.stderr.take());
    let stdout = std::thread::spawn(move || read_pipe(stdout));
    let stderr = std::thread::spawn(move || read_pipe(stderr));
    let status = wait_at_most(&mut child, Duration::from_secs_f64(timeout_s.max(0.0)));
    let mut run = Run { wall: start.elapsed().as_secs_f64(), ..Run::default() };
    for line in stdout.join().unwrap_or_default().lines() {
        let Ok(v) = serde_json::from_str::<Value>(line) else { continue };
        if let (Some(step), Some(s)) = (v["step"].as_str(), v["seconds"].as_f64()) {
            run.steps.push((step.to_string(), s));
        }
        run.peak_rss_kb = run.peak_rss_kb.or(v["peak_rss_kb"].as_u64());
        run.n_triangles = run.n_triangles.or(v["n_triangles"].as_u64());
        run.mesh_size = run.mesh_size.or(v["mesh_size"].as_f64());
    }
    let err = stderr.join().unwrap_or_default();
    run.failure = match status {
        None => Some(format!("hang > {timeout_s} s")),
        Some(s) if !s.success() => {
            let last = err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("").trim().to_string();
            Some(format!("gmsh {s} {last}"))
        }
        Some(_) => None,
    };
    run
}

/// The side of one tool in the quads table: its MSH file when it exists.
fn quads_side<'a>(run: &'a Run, msh: PathBuf) -> quads::Side<'a> {
    quads::Side {
        msh: msh.is_file().then_some(msh),
        wall: run.wall,
        step: run.steps.iter().find(|(s, _)| s == "quads").map(|(_, v)| *v),
        failure: run.failure.as_deref(),
        report: run.quads_report.as_ref(),
    }
}

/// Writes the mesh described by `spec` (`KIND:N:PATH`) and returns its path.
fn generate(spec: &str) -> Result<PathBuf, String> {
    let mut parts = spec.splitn(3, ':');
    let (kind, n, path) = match (parts.next(), parts.next(), parts.next()) {
        (Some(k), Some(n), Some(p)) => (k, n, PathBuf::from(p)),
        _ => return Err(format!("--generate {spec}: expected KIND:N:PATH")),
    };
    let n: f64 = n.parse().map_err(|_| format!("--generate {spec}: N must be a number"))?;
    let mesh = match kind {
        "sphere" => {
            let k = ((n / 12.0).sqrt().round() as usize).max(1);
            let mut m = meshatlas::mesh::fixtures::cube(k);
            for p in &mut m.positions {
                *p = p.normalize();
            }
            m
        }
        "torus" => {
            let k = ((n / 6.0).sqrt().round() as usize).max(3);
            meshatlas::mesh::fixtures::torus(1.0, 0.3, 3 * k, k)
        }
        other => return Err(format!("--generate {spec}: unknown kind `{other}` (sphere or torus)")),
    };
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let file = std::fs::File::create(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    meshatlas::io::stl_write::write_stl_binary(file, &mesh).map_err(|e| format!("{}: {e}", path.display()))?;
    eprintln!("generated {} ({} triangles)", path.display(), mesh.n_faces());
    Ok(path)
}

/// One row per artifact (`bytes NAME`, in MB: on disk, then as a download
/// with `Content-Encoding: gzip` and `zstd`, made by the server's own
/// encoders) and their totals.
fn print_artifacts(name: &str, tris: &str, out: &Path, artifacts: &[(String, u64)]) {
    let mb = |b: u64| format!("{:.2} MB", b as f64 / 1e6);
    let tmp = out.join(".wire.tmp");
    let encoded = |file: &str, gzip: bool| {
        let src = out.join(file);
        let made = if gzip {
            meshatlas::io::gzip::gzip_file(&src, &tmp)
        } else {
            meshatlas::io::zstandard::zstd_file(&src, &tmp, meshatlas::io::zstandard::pool_workers())
        };
        made.ok()
    };
    let (mut total, mut total_gz, mut total_zst) = (0, 0, 0);
    for (file, bytes) in artifacts {
        let (gz, zst) = (encoded(file, true), encoded(file, false));
        total += bytes;
        total_gz += gz.unwrap_or(*bytes);
        total_zst += zst.unwrap_or(*bytes);
        let wire = |b: Option<u64>| b.map_or_else(|| "-".into(), mb);
        println!(
            "{name:<28} {tris:>10} {:<30} {:>14} gzip {:>10} zstd {:>10}",
            format!("bytes {file}"),
            mb(*bytes),
            wire(gz),
            wire(zst)
        );
    }
    let _ = std::fs::remove_file(&tmp);
    println!(
        "{name:<28} {tris:>10} {:<30} {:>14} gzip {:>10} zstd {:>10}",
        "bytes (all artifacts)",
        mb(total),
        mb(total_gz),
        mb(total_zst)
    );
}

/// A `meshatlas serve` child on a free loopback port with its own data
/// directory; killed on drop.
struct Server {
    child: std::process::Child,
    base: String,
    data_dir: PathBuf,
}

impl Server {
    /// Starts the server and waits for its `listening on ADDR` line.
    fn start(out: &Path) -> Result<Self, String> {
        use std::io::BufRead;
        let data_dir = out.join("service-data");
        let _ = std::fs::remove_dir_all(&data_dir);
        let mut child = Command::new(env!("CARGO_BIN_EXE_meshatlas"))
            .args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
            .arg(&data_dir)
            .env("MESHATLAS_LOG", "warn")
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot start meshatlas serve: {e}"))?;
        let stdout = child.stdout.take().ok_or("no stdout")?;
        let mut line = String::new();
        std::io::BufReader::new(stdout).read_line(&mut line).map_err(|e| e.to_string())?;
        let addr = line.trim().strip_prefix("listening on ").ok_or_else(|| format!("unexpected line `{line}`"))?;
        Ok(Self { child, base: format!("http://{addr}"), data_dir })
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.data_dir);
    }
}

/// Result of one job through the service.
struct ServiceRun {
    /// Seconds from sending the POST to reading `succeeded`.
    wall: f64,
    /// The pipeline's own step timings inside the job.
    steps: Vec<(String, f64)>,
    /// The pipeline's total inside the job.
    pipeline_total: Option<f64>,
}

/// Posts `file` raw (the body read beforehand) and polls the job every 5 ms
/// until it ends.
fn run_service(server: &Server, file: &Path, stages: &str) -> Result<ServiceRun, String> {
    let body = std::fs::read(file).map_err(|e| format!("{}: {e}", file.display()))?;
    let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(|e| e.to_string())?;
    rt.block_on(service_job(&server.base, body, &name, stages))
}

/// The POST and the polling of [`run_service`].
async fn service_job(base: &str, body: Vec<u8>, name: &str, stages: &str) -> Result<ServiceRun, String> {
    {
        let client = reqwest::Client::new();
        let url = format!("{base}/v1/jobs?stages={stages}&filename={name}");
        let start = Instant::now();
        let resp = client.post(url).body(body).send().await.map_err(|e| e.to_string())?;
        let job: Value = resp.json().await.map_err(|e| e.to_string())?;
        let id = job["id"].as_str().ok_or_else(|| format!("no job id in {job}"))?.to_string();
        loop {
            let job: Value = client
                .get(format!("{base}/v1/jobs/{id}"))
                .send()
                .await
                .map_err(|e| e.to_string())?
                .json()
                .await
                .map_err(|e| e.to_string())?;
            match job["state"].as_str() {
                Some("succeeded") => {
                    let wall = start.elapsed().as_secs_f64();
                    let report = &job["summary"];
                    let steps = report["timings"]
                        .as_array()
                        .map(|ts| {
                            ts.iter()
                                .filter_map(|t| Some((t["step"].as_str()?.to_string(), t["seconds"].as_f64()?)))
                                .collect()
                        })
                        .unwrap_or_default();
                    return Ok(ServiceRun { wall, steps, pipeline_total: report["total_seconds"].as_f64() });
                }
                Some("failed" | "cancelled") => return Err(format!("job {id} ended: {}", job["error"])),
                _ => tokio::time::sleep(std::time::Duration::from_millis(5)).await,
            }
        }
    }
}

/// Prints the service rows of one file: every pipeline step inside the job
/// against the CLI's, the pipeline total, and the whole job (POST to
/// `succeeded`) against the CLI process.
fn print_service_rows(name: &str, tris: &str, cli: &Run, service: &Result<ServiceRun, String>) {
    let svc = match service {
        Ok(s) => s,
        Err(e) => {
            println!("{name:<28} service FAILED: {e}");
            return;
        }
    };
    let cli_steps: BTreeMap<&str, f64> = cli.steps.iter().map(|(s, v)| (s.as_str(), *v)).collect();
    let row = |step: &str, a: Option<f64>, b: Option<f64>| {
        let fmt = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into());
        let ratio = match (a, b) {
            (Some(a), Some(b)) if a > 0.0 => format!("{:.3}", b / a),
            _ => "-".into(),
        };
        println!("{name:<28} {tris:>10} {step:<16} {:>10} {:>10} {ratio:>8}", fmt(a), fmt(b));
    };
    println!(
        "{:<28} {:>10} {:<16} {:>10} {:>10} {:>8}",
        "file", "triangles", "service step", "cli s", "service s", "ratio"
    );
    for (step, secs) in &svc.steps {
        row(step.as_str(), cli_steps.get(step.as_str()).copied(), Some(*secs));
    }
    let cli_total: f64 = cli.steps.iter().map(|(_, v)| v).sum();
    let svc_total: f64 = svc.steps.iter().map(|(_, v)| v).sum();
    row("steps total", Some(cli_total), Some(svc_total));
    row("pipeline", None, svc.pipeline_total);
    row("job (POST→done)", Some(cli.wall), Some(svc.wall));
}

fn mib(kb: Option<u64>) -> String {
    kb.map(|k| format!("{:.1}", k as f64 / 1024.0)).unwrap_or_else(|| "-".into())
}

fn main() {
    let mut args = Args::parse();
    for spec in &args.generate {
        match generate(spec) {
            Ok(p) => args.files.push(p),
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(2);
            }
        }
    }
    if args.files.is_empty() {
        eprintln!("usage: cargo bench --bench pipeline -- [--gmsh] [--gmsh-timeout SECS] [--stages LIST] FILE...");
        std::process::exit(2);
    }
    let server = if args.service {
        match Server::start(&args.out) {
            Ok(s) => Some(s),
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(2);
            }
        }
    } else {
        None
    };
    println!("{:<28} {:>10} {:<12} {:>12} {:>12} {:>8}", "file", "triangles", "step", "meshatlas s", "gmsh s", "ratio");
    for file in &args.files {
        let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let out = args.out.join(file.file_stem().unwrap_or_default());
        let with_quads = args.stages.split(',').any(|s| s.trim() == "quads");
        // a mesh left by an earlier run must not stand in for a failed one
        for stale in [quads::QUADS_MSH, quads::GMSH_QUADS_MSH] {
            let _ = std::fs::remove_file(out.join(stale));
        }
        let ours = run_meshatlas(file, &args.stages, &out);
        let gmsh = args.gmsh.then(|| run_gmsh(file, &args.stages, &out, args.gmsh_timeout));
        let theirs: BTreeMap<String, f64> =
            gmsh.as_ref().map(|g| g.steps.iter().cloned().collect()).unwrap_or_default();
        let tris = ours.n_triangles.or(gmsh.as_ref().and_then(|g| g.n_triangles));
        let tris = tris.map(|t| t.to_string()).unwrap_or_else(|| "-".into());
        let mut names: Vec<String> = ours.steps.iter().map(|(s, _)| s.clone()).collect();
        for (s, _) in gmsh.iter().flat_map(|g| g.steps.iter()) {
            if !names.contains(s) {
                names.push(s.clone());
            }
        }
        let ours_map: BTreeMap<String, f64> = ours.steps.iter().cloned().collect();
        for step in &names {
            let a = ours_map.get(step).copied();
            let b = theirs.get(step).copied();
            let fmt = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into());
            let ratio = match (a, b) {
                (Some(a), Some(b)) if b > 0.0 => format!("{:.2}", a / b),
                _ => "-".into(),
            };
            println!("{name:<28} {tris:>10} {step:<12} {:>12} {:>12} {ratio:>8}", fmt(a), fmt(b));
        }
        if let Some(t) = ours.total_seconds {
            println!("{name:<28} {tris:>10} {:<12} {t:>12.4} {:>12} {:>8}", "total", "-", "");
        }
        print_artifacts(&name, &tris, &out, &ours.artifacts);
        println!(
            "{name:<28} {tris:>10} {:<12} {:>12.4} {:>12} {:>8}",
            "wall",
            ours.wall,
            gmsh.as_ref().map(|g| format!("{:.4}", g.wall)).unwrap_or_else(|| "-".into()),
            ""
        );
        println!(
            "{name:<28} {tris:>10} {:<12} {:>12} {:>12} {:>8}",
            "peak MiB",
            mib(ours.peak_rss_kb),
            gmsh.as_ref().map(|g| mib(g.peak_rss_kb)).unwrap_or_else(|| "-".into()),
            ""
        );
        if let Some(f) = &ours.failure {
            println!("{name:<28} meshatlas FAILED: {f}");
        }
        if let Some(f) = gmsh.as_ref().and_then(|g| g.failure.as_ref()) {
            println!("{name:<28} gmsh FAILED: {f}");
        }
        if with_quads {
            let theirs = gmsh.as_ref().map(|g| quads_side(g, out.join(quads::GMSH_QUADS_MSH)));
            let size = gmsh.as_ref().and_then(|g| g.mesh_size);
            quads::print_quads_table(&name, size, &quads_side(&ours, out.join(quads::QUADS_MSH)), theirs.as_ref());
        }
        if let Some(server) = &server {
            print_service_rows(&name, &tris, &ours, &run_service(server, file, &args.stages));
        }
    }
}
