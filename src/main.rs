//! Command-line entry point: `meshatlas serve`, `meshatlas worker` and `meshatlas run`.
//!
//! Parses flags (each also readable from a `MESHATLAS_*` environment
//! variable), builds the configuration and calls the library.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use clap::builder::RangedU64ValueParser;
use clap::{Args, Parser, Subcommand, value_parser};

use meshatlas::http::auth::Auth;
use meshatlas::http::{AppState, HttpLimits};
use meshatlas::jobs::artifact_store::ArtifactLocation;
use meshatlas::jobs::{
    Delayed, Executor, JobService, JobsConfig, Quotas, Retention, Stalled, StoreLocation, parse_retention,
    pipeline_executor::PipelineExecutor,
};
use meshatlas::pipeline::{PipelineParams, StageName, parse_params, run_pipeline};
use meshatlas::progress::{Progress, ProgressSink};

#[derive(Parser)]
#[command(name = "meshatlas", version, about = "Atlas, crossfield and 3D frames of surface triangulations")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the HTTP job service (and, unless --no-worker, a worker).
    Serve(ServeArgs),
    /// Run a worker: claims and runs jobs from the shared store; serves only
    /// /healthz and /metrics.
    Worker(WorkerArgs),
    /// Run the pipeline on one file, offline.
    Run(RunArgs),
}

/// Settings of the job machinery, shared by `serve` and `worker`.
#[derive(Args)]
struct JobArgs {
    /// Directory for uploads and artifacts (and the embedded job database);
    /// every API and worker process sharing a store must see the same one.
    #[arg(long, env = "MESHATLAS_DATA_DIR", default_value = "./data")]
    data_dir: PathBuf,
    /// The job store: `sqlite://DIR` (embedded; default: the data
    /// directory) or `postgres://USER@HOST:PORT/DB` (shared by any number of
    /// API and worker processes).
    #[arg(long, env = "MESHATLAS_STORE", value_parser = StoreLocation::parse)]
    store: Option<StoreLocation>,
    /// Where uploads and artifacts are kept for good: `file://` (the data
    /// directory, which every process must then share) or
    /// `s3://BUCKET/PREFIX` (any S3-compatible store; AWS_ENDPOINT_URL,
    /// AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY, AWS_REGION), when each
    /// process's data directory holds only working copies.
    #[arg(long, env = "MESHATLAS_ARTIFACTS", default_value = "file://", value_parser = ArtifactLocation::parse)]
    artifacts: ArtifactLocation,
    /// Jobs run at the same time (1–1024).
    #[arg(
        long, env = "MESHATLAS_WORKERS", default_value_t = 1,
        value_parser = RangedU64ValueParser::<usize>::new().range(1..=1024)
    )]
    workers: usize,
    /// Threads of the numerical pool, shared by the running jobs: one job
    /// alone uses them all (0 = one per core; at least --workers; 0–1024).
    #[arg(
        long, env = "MESHATLAS_THREADS", default_value_t = 0,
        value_parser = RangedU64ValueParser::<usize>::new().range(0..=1024)
    )]
    threads: usize,
    /// Server-wide triangle cap (jobs above fail with too-many-triangles;
    /// 1–4294967295).
    #[arg(
        long, env = "MESHATLAS_MAX_TRIANGLES", default_value_t = 5_000_000,
        value_parser = RangedU64ValueParser::<usize>::new().range(1..=u32::MAX as u64)
    )]
    max_triangles: usize,
    /// Server-wide cap on the frames stage's tetrahedra (a job's own
    /// `frames.max_tets` is clamped to it).
    #[arg(long, env = "MESHATLAS_MAX_TETS", default_value_t = 2_000_000, value_parser = clap::value_parser!(u64).range(1..))]
    max_tets: u64,
    /// Memory the running jobs' estimated peaks may add up to (e.g. 16GiB,
    /// 512MiB, bytes). A process that runs jobs claims only jobs that fit
    /// it; `serve` refuses with 422 a job estimated above it. Default: 75 %
    /// of physical memory (or of the cgroup limit if smaller); unlimited for
    /// `serve --no-worker`, which leaves the choice to the workers.
    #[arg(long, env = "MESHATLAS_MEMORY_BUDGET", value_parser = meshatlas::jobs::memory::parse_byte_size)]
    memory_budget: Option<u64>,
    /// Wall-time limit of one job, in seconds (0 < secs <= 31536000, one year).
    #[arg(long, env = "MESHATLAS_JOB_TIMEOUT_SECS", default_value_t = 3600.0, value_parser = parse_job_timeout)]
    job_timeout_secs: f64,
    /// Times a job may be claimed before an interruption fails it (1–100).
    #[arg(long, env = "MESHATLAS_MAX_ATTEMPTS", default_value_t = 3, value_parser = value_parser!(u32).range(1..=100))]
    max_attempts: u32,
    /// Seconds a worker holds a job without a heartbeat before another
    /// worker may take it (0.1–3600).
    #[arg(long, env = "MESHATLAS_LEASE_SECS", default_value_t = 30.0, value_parser = parse_lease)]
    lease_secs: f64,
    /// Seconds between two heartbeats of a running job, which renew its
    /// lease and read cancel requests (at most a third of the lease).
    #[arg(long, env = "MESHATLAS_HEARTBEAT_SECS", default_value_t = 3.0, value_parser = parse_lease)]
    heartbeat_secs: f64,
    /// Testing only: wait this long (cancellably) before each job, so tests
    /// can kill the server mid-job.
    #[arg(long, env = "MESHATLAS_TEST_JOB_DELAY_MS", hide = true)]
    test_job_delay_ms: Option<u64>,
    /// Testing only: ignore cancellation this long at the start of each job,
    /// so tests see a stop that is pending.
    #[arg(long, env = "MESHATLAS_TEST_STALL_MS", hide = true)]
    test_stall_ms: Option<u64>,
}

#[derive(Args)]
struct WorkerArgs {
    /// Address of /healthz and /metrics (port 0 picks a free port; the bound
    /// address is printed as `listening on ADDR`). They show no job data.
    #[arg(long, env = "MESHATLAS_WORKER_ADDR", default_value = "127.0.0.1:9090", value_parser = parse_addr)]
    addr: String,
    #[command(flatten)]
    jobs: JobArgs,
}

#[derive(Args)]
struct ServeArgs {
    /// Address to listen on (port 0 picks a free port; the bound address is
    /// printed as `listening on ADDR`).
    #[arg(long, env = "MESHATLAS_ADDR", default_value = "127.0.0.1:8080", value_parser = parse_addr)]
    addr: String,
    #[command(flatten)]
    jobs: JobArgs,
    /// Serve the API only: run no jobs (workers started with `meshatlas
    /// worker` on the same store run them).
    #[arg(long, env = "MESHATLAS_NO_WORKER", value_parser = clap::builder::BoolishValueParser::new())]
    no_worker: bool,
    /// Largest accepted upload in bytes (413 beyond; at least 1).
    #[arg(
        long, env = "MESHATLAS_MAX_UPLOAD_BYTES", default_value_t = 512 * 1024 * 1024,
        value_parser = value_parser!(u64).range(1..)
    )]
    max_upload_bytes: u64,
    /// Most jobs waiting in the queue (429 beyond; 1–1000000).
    #[arg(
        long, env = "MESHATLAS_MAX_QUEUED", default_value_t = 64,
        value_parser = RangedU64ValueParser::<usize>::new().range(1..=1_000_000)
    )]
    max_queued: usize,
    /// Retry-After seconds sent with 429 (0–86400).
    #[arg(
        long, env = "MESHATLAS_RETRY_AFTER_SECS", default_value_t = 10,
        value_parser = value_parser!(u64).range(0..=86_400)
    )]
    retry_after_secs: u64,
    /// Seconds for a request head to arrive; also how long an idle
    /// keep-alive connection stays open (1–3600).
    #[arg(
        long, env = "MESHATLAS_HEADER_TIMEOUT_SECS", default_value_t = 10,
        value_parser = value_parser!(u64).range(1..=3600)
    )]
    header_timeout_secs: u64,
    /// Seconds an upload may send nothing before it is dropped (408; 1–3600).
    #[arg(
        long, env = "MESHATLAS_BODY_IDLE_TIMEOUT_SECS", default_value_t = 30,
        value_parser = value_parser!(u64).range(1..=3600)
    )]
    body_idle_timeout_secs: u64,
    /// Seconds in-flight requests may run after SIGTERM/Ctrl-C before their
    /// connections are dropped and running jobs requeued (0–3600).
    #[arg(
        long, env = "MESHATLAS_SHUTDOWN_GRACE_SECS", default_value_t = 10,
        value_parser = value_parser!(u64).range(0..=3600)
    )]
    shutdown_grace_secs: u64,
    /// File of `token tenant` lines: every route but /healthz then needs
    /// `Authorization: Bearer TOKEN`, and jobs belong to the token's tenant.
    /// Reloaded on SIGHUP.
    #[arg(long, env = "MESHATLAS_AUTH_TOKENS")]
    auth_tokens: Option<PathBuf>,
    /// /metrics needs a token too (with --auth-tokens).
    #[arg(long, env = "MESHATLAS_METRICS_AUTH", value_parser = clap::builder::BoolishValueParser::new())]
    metrics_auth: bool,
    /// Serve a non-loopback --addr without --auth-tokens.
    #[arg(long, env = "MESHATLAS_INSECURE_NO_AUTH", value_parser = clap::builder::BoolishValueParser::new())]
    insecure_no_auth: bool,
    /// Most queued jobs per tenant (429 beyond; with --auth-tokens).
    #[arg(long, env = "MESHATLAS_TENANT_MAX_QUEUED")]
    tenant_max_queued: Option<usize>,
    /// Most bytes of uploads and artifacts per tenant (507 beyond; with --auth-tokens).
    #[arg(long, env = "MESHATLAS_TENANT_MAX_STORED_BYTES")]
    tenant_max_stored_bytes: Option<u64>,
    /// Most bytes of uploads and artifacts stored in all (507 beyond).
    #[arg(long, env = "MESHATLAS_MAX_STORED_BYTES")]
    max_stored_bytes: Option<u64>,
    /// Delete finished jobs this long after they end (`7d`, `12h`, `30m`, `45s`, or seconds).
    #[arg(long, env = "MESHATLAS_RETENTION", value_parser = parse_retention)]
    retention: Option<Duration>,
    /// Testing only: milliseconds between two retention sweeps (default 60 s).
    #[arg(long, env = "MESHATLAS_TEST_RETENTION_SWEEP_MS", hide = true)]
    test_retention_sweep_ms: Option<u64>,
}

#[derive(Args)]
struct RunArgs {
    /// Input mesh (STL, OBJ, PLY, MSH).
    input: PathBuf,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Comma-separated stages to run (overrides `stages` in --params).
    #[arg(long, value_delimiter = ',')]
    stages: Option<Vec<String>>,
    /// Pipeline parameters as a JSON file (same schema as the API's `params`).
    #[arg(long)]
    params: Option<PathBuf>,
    /// Input format (stl, obj, ply, msh); detected when omitted.
    #[arg(long)]
    format: Option<String>,
    /// Print the whole report as JSON instead of the text summary.
    #[arg(long)]
    json: bool,
}

fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_env("MESHATLAS_LOG")
        .or_else(|_| tracing_subscriber::EnvFilter::try_from_default_env())
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .fmt_fields(meshatlas::log_format::escaping_fields())
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .init();
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    meshatlas::linalg::use_sequential_kernels();
    let result = match cli.command {
        Command::Serve(args) => {
            init_logging();
            meshatlas::jobs::install_panic_hook();
            serve(args)
        }
        Command::Worker(args) => {
            init_logging();
            meshatlas::jobs::install_panic_hook();
            worker(args)
        }
        Command::Run(args) => {
            if std::env::var_os("MESHATLAS_LOG").is_some() || std::env::var_os("RUST_LOG").is_some() {
                init_logging();
            }
            run(args)
        }
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("meshatlas: {msg}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// The job configuration of the shared flags; `run_jobs` says whether this
/// process claims jobs.
fn jobs_config(args: &JobArgs, run_jobs: bool) -> Result<JobsConfig, String> {
    let lease = Duration::from_secs_f64(args.lease_secs);
    let heartbeat = Duration::from_secs_f64(args.heartbeat_secs);
    if heartbeat * 3 > lease {
        return Err(format!(
            "--heartbeat-secs {} must be at most a third of --lease-secs {}, so one late heartbeat does not lose the lease",
            args.heartbeat_secs, args.lease_secs
        ));
    }
    let store = args.store.clone().unwrap_or_else(|| StoreLocation::Sqlite(args.data_dir.clone()));
    // A notification wakes PostgreSQL workers, so they need not poll often.
    let poll_interval = Duration::from_millis(if matches!(store, StoreLocation::Postgres(_)) { 1000 } else { 100 });
    let memory_budget = match args.memory_budget {
        Some(b) => b,
        None if run_jobs => meshatlas::jobs::memory::default_memory_budget(),
        None => u64::MAX,
    };
    Ok(JobsConfig {
        workers: args.workers.max(1),
        threads: args.threads,
        job_timeout: Duration::from_secs_f64(args.job_timeout_secs),
        max_attempts: args.max_attempts.max(1),
        max_triangles: args.max_triangles,
        max_tets: usize::try_from(args.max_tets).unwrap_or(usize::MAX),
        memory_budget,
        store,
        run_jobs,
        lease,
        heartbeat,
        poll_interval,
        artifacts: args.artifacts.clone(),
        ..JobsConfig::new(&args.data_dir)
    })
}

/// The executor jobs run: the pipeline, wrapped by the testing-only delays.
fn executor(args: &JobArgs) -> Arc<dyn Executor> {
    let executor: Arc<dyn Executor> = match args.test_job_delay_ms {
        Some(ms) => Arc::new(Delayed { inner: PipelineExecutor, delay: Duration::from_millis(ms) }),
        None => Arc::new(PipelineExecutor),
    };
    match args.test_stall_ms {
        Some(ms) => {
            let inner = move |job: &meshatlas::jobs::JobInput, p: &Progress| executor.execute(job, p);
            Arc::new(Stalled { inner, stall: Duration::from_millis(ms) })
        }
        None => executor,
    }
}

/// A multi-threaded tokio runtime.
fn runtime() -> Result<tokio::runtime::Runtime, String> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|e| format!("cannot start the async runtime: {e}"))
}

fn serve(args: ServeArgs) -> Result<(), String> {
    let config = JobsConfig {
        max_queued: args.max_queued,
        quotas: quotas(&args)?,
        retention: Retention {
            max_age: args.retention,
            sweep_interval: Duration::from_millis(args.test_retention_sweep_ms.unwrap_or(60_000).max(1)),
        },
        ..jobs_config(&args.jobs, !args.no_worker)?
    };
    tracing::info!(memory_budget = config.memory_budget, max_tets = config.max_tets, "memory admission");
    let auth = auth_setup(&args)?;
    let executor = executor(&args.jobs);
    let limits = HttpLimits {
        max_upload_bytes: args.max_upload_bytes,
        retry_after_secs: args.retry_after_secs,
        header_timeout: Duration::from_secs(args.header_timeout_secs),
        body_idle_timeout: Duration::from_secs(args.body_idle_timeout_secs),
        shutdown_grace: Duration::from_secs(args.shutdown_grace_secs),
    };
    runtime()?.block_on(async move {
        let jobs = JobService::start(config, executor).map_err(|e| e.to_string())?;
        // Before `listening on` is printed, so a SIGHUP right after start reloads instead of killing.
        if let Some(a) = &auth {
            meshatlas::http::auth::reload_on_sighup(a.clone()).map_err(|e| format!("cannot handle SIGHUP: {e}"))?;
        }
        let listener = tokio::net::TcpListener::bind(&args.addr)
            .await
            .map_err(|e| format!("cannot listen on {}: {e}", args.addr))?;
        let addr = listener.local_addr().map_err(|e| e.to_string())?;
        println!("listening on {addr}");
        tracing::info!(%addr, "listening");
        let state = AppState { jobs: jobs.clone(), limits: Arc::new(limits), auth };
        meshatlas::http::serve(listener, state, shutdown_signal()).await.map_err(|e| e.to_string())?;
        jobs.shutdown(Duration::from_secs(10)).await;
        Ok(())
    })
}

/// `meshatlas worker`: runs jobs of the shared store and serves /healthz
/// and /metrics until SIGTERM, then puts its running jobs back in the queue.
fn worker(args: WorkerArgs) -> Result<(), String> {
    // A worker serves no downloads: its copies of a job's files are scratch.
    let config = JobsConfig { keep_local_copies: false, ..jobs_config(&args.jobs, true)? };
    tracing::info!(memory_budget = config.memory_budget, store = %config.store.redacted(), "worker");
    let executor = executor(&args.jobs);
    runtime()?.block_on(async move {
        let jobs = JobService::start(config, executor).map_err(|e| e.to_string())?;
        let listener = tokio::net::TcpListener::bind(&args.addr)
            .await
            .map_err(|e| format!("cannot listen on {}: {e}", args.addr))?;
        let addr = listener.local_addr().map_err(|e| e.to_string())?;
        println!("listening on {addr}");
        tracing::info!(%addr, "worker listening (healthz and metrics)");
        let state = AppState { jobs: jobs.clone(), limits: Arc::new(HttpLimits::default()), auth: None };
        meshatlas::http::serve_worker(listener, state, shutdown_signal()).await.map_err(|e| e.to_string())?;
        jobs.shutdown(Duration::from_secs(10)).await;
        Ok(())
    })
}

/// `--lease-secs`, `--heartbeat-secs`: finite seconds in [0.1, 3600].
fn parse_lease(s: &str) -> Result<f64, String> {
    let secs: f64 = s.trim().parse().map_err(|_| format!("`{s}` is not a number"))?;
    if !(secs.is_finite() && (0.1..=3600.0).contains(&secs)) {
        return Err("must be a number of seconds in [0.1, 3600]".into());
    }
    Ok(secs)
}

/// The stored-bytes and per-tenant limits of the flags (per-tenant ones
/// need --auth-tokens; zero limits are refused).
fn quotas(args: &ServeArgs) -> Result<Quotas, String> {
    let per_tenant = args.tenant_max_queued.is_some() || args.tenant_max_stored_bytes.is_some();
    if per_tenant && args.auth_tokens.is_none() {
        return Err("--tenant-max-queued and --tenant-max-stored-bytes need --auth-tokens (tenants)".into());
    }
    if args.tenant_max_queued == Some(0) || args.tenant_max_stored_bytes == Some(0) || args.max_stored_bytes == Some(0)
    {
        return Err("--tenant-max-queued, --tenant-max-stored-bytes and --max-stored-bytes must be positive".into());
    }
    Ok(Quotas {
        max_stored_bytes: args.max_stored_bytes,
        tenant_max_queued: args.tenant_max_queued,
        tenant_max_stored_bytes: args.tenant_max_stored_bytes,
    })
}

/// Loads the token file, and refuses a non-loopback --addr without one
/// unless --insecure-no-auth.
fn auth_setup(args: &ServeArgs) -> Result<Option<Arc<Auth>>, String> {
    let Some(path) = &args.auth_tokens else {
        if args.metrics_auth {
            return Err("--metrics-auth needs --auth-tokens".into());
        }
        if !args.insecure_no_auth {
            refuse_non_loopback(&args.addr)?;
        }
        return Ok(None);
    };
    let auth = Auth::load(path, args.metrics_auth).map_err(|e| e.to_string())?;
    Ok(Some(Arc::new(auth)))
}

/// Errs when `addr` resolves to any address outside loopback.
fn refuse_non_loopback(addr: &str) -> Result<(), String> {
    use std::net::ToSocketAddrs;
    // An address that does not resolve is reported by the bind.
    let Ok(resolved) = addr.to_socket_addrs() else { return Ok(()) };
    match resolved.into_iter().find(|a| !a.ip().is_loopback()) {
        Some(a) => Err(format!(
            "refusing to listen on {addr} ({}, not a loopback address) without authentication: \
             give --auth-tokens FILE, or --insecure-no-auth to serve every client without it",
            a.ip()
        )),
        None => Ok(()),
    }
}

/// `--addr`: an IP socket address or `host:port` (resolved when binding).
fn parse_addr(s: &str) -> Result<String, String> {
    if s.parse::<std::net::SocketAddr>().is_ok() {
        return Ok(s.to_string());
    }
    let (host, port) = s.rsplit_once(':').ok_or("expected HOST:PORT, e.g. 127.0.0.1:8080")?;
    port.parse::<u16>().map_err(|_| format!("port `{port}` is not a number in 0..=65535"))?;
    let host_ok = !host.is_empty() && host.bytes().all(|b| b.is_ascii_alphanumeric() || b"-._".contains(&b));
    if !host_ok {
        return Err(format!("`{host}` is neither an IP address nor a host name"));
    }
    Ok(s.to_string())
}

/// Longest accepted `--job-timeout-secs` (one year).
const MAX_JOB_TIMEOUT_SECS: f64 = 365.0 * 24.0 * 3600.0;

/// `--job-timeout-secs`: finite, positive, at most one year (larger values
/// overflow the runner's deadline arithmetic).
fn parse_job_timeout(s: &str) -> Result<f64, String> {
    let secs: f64 = s.trim().parse().map_err(|_| format!("`{s}` is not a number"))?;
    if !(secs.is_finite() && secs > 0.0 && secs <= MAX_JOB_TIMEOUT_SECS) {
        return Err(format!("must be a number of seconds in (0, {MAX_JOB_TIMEOUT_SECS}]"));
    }
    Ok(secs)
}

/// Resolves on Ctrl-C or SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {},
        () = term => {},
    }
    tracing::info!("shutting down");
}

/// Draws an indicatif bar on stderr (only when stderr is a terminal).
struct Bar(indicatif::ProgressBar);

impl ProgressSink for Bar {
    fn report(&self, stage: &str, fraction: f64) {
        self.0.set_message(stage.to_string());
        self.0.set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
    }
}

/// What `meshatlas run --json` prints: the pipeline report and the peak
/// resident set size.
#[derive(serde::Serialize)]
struct JsonOutput<'a> {
    #[serde(flatten)]
    report: &'a meshatlas::pipeline::PipelineReport,
    peak_rss_kb: Option<u64>,
}

/// Peak resident set size of this process in kB (Linux `VmHWM`).
fn peak_rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn run(args: RunArgs) -> Result<(), String> {
    let mut params = match &args.params {
        Some(path) => {
            let text = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
            parse_params(&text).map_err(|e| match &e.field {
                Some(f) => format!("{}: parameter `{f}`: {}", path.display(), e.message),
                None => format!("{}: {}", path.display(), e.message),
            })?
        }
        None => PipelineParams::default(),
    };
    if let Some(stages) = &args.stages {
        params.stages = stages
            .iter()
            .map(|s| s.trim())
            .filter(|s| !s.is_empty())
            .map(StageName::parse)
            .collect::<Result<_, _>>()?;
    }
    let format = match args.format.as_deref() {
        Some(name) => Some(
            meshatlas::io::Format::from_name(name)
                .ok_or_else(|| format!("unknown format `{name}` (expected stl, obj, ply or msh)"))?,
        ),
        None => None,
    };
    let progress = if std::io::stderr().is_terminal() {
        let bar = indicatif::ProgressBar::new(1000);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {percent:>3}% {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar.enable_steady_tick(Duration::from_millis(200));
        Progress::new(Arc::new(Bar(bar)), Arc::new(std::sync::atomic::AtomicBool::new(false)))
    } else {
        Progress::none()
    };
    let result = run_pipeline(&args.input, format, &params, &args.out, &progress);
    drop(progress);
    let report = result.map_err(|e| format!("{}: {e} [{}]", args.input.display(), e.kind()))?;
    let peak = peak_rss_kb();
    if args.json {
        let out = JsonOutput { report: &report, peak_rss_kb: peak };
        println!("{}", serde_json::to_string_pretty(&out).map_err(|e| e.to_string())?);
        return Ok(());
    }
    for line in report.summary_lines() {
        println!("{line}");
    }
    for t in &report.timings {
        println!("time       {:<10} {:>10.3} s", t.step, t.seconds);
    }
    println!("time       {:<10} {:>10.3} s", "total", report.total_seconds);
    for a in &report.artifacts {
        println!("wrote      {} ({} bytes)", args.out.join(&a.name).display(), a.bytes);
    }
    println!("wrote      {}", args.out.join(meshatlas::pipeline::REPORT_NAME).display());
    match peak {
        Some(kb) => println!("peak_rss_kb {kb}"),
        None => println!("peak_rss_kb unknown"),
    }
    Ok(())
}
