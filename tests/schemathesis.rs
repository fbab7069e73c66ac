//! `api/openapi.yaml` checked by a client nobody here wrote: schemathesis 4.x
//! (PyPI; `.ci/run` installs it) runs every check, every phase (examples,
//! coverage, fuzzing and the stateful phase that follows the spec's `links`
//! from `POST /v1/jobs`) against the real binary on loopback, with a fixed
//! seed and example count so the run is bounded and reproducible. Any failure
//! (a 5xx, a schema-valid request rejected, a schema-violating one accepted,
//! an undocumented status, header or body) fails the test with
//! schemathesis's report.
//!
//! `tests/schemathesis/hooks.py` registers the mesh media types as raw bytes
//! and keeps the two documented cross-location conflicts of `POST /v1/jobs`
//! out of the schema-valid cases (JSON Schema cannot express them);
//! `schemathesis.toml` beside it accepts the documented 416 for a valid
//! `Range` past the end of an artifact (only the server knows the length).

mod common;

use std::path::Path;
use std::process::{Child, Command};

/// Bearer token of the one tenant of the run (≥ 16 characters).
const TOKEN: &str = "schemathesis-token-0123456789";
/// Test cases per operation and phase: enough to reach every operation and
/// link, small enough for about a minute on 2 cores.
const MAX_EXAMPLES: &str = "20";
/// Fixed seed: the same requests on every run.
const SEED: &str = "20261201";

/// A `meshatlas serve` child on `127.0.0.1:0`, killed on drop.
struct Server {
    child: Child,
    base: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts the binary with a fresh data directory in `dir`, tokens required.
fn start_server(dir: &Path) -> Server {
    let tokens = dir.join("tokens.txt");
    std::fs::write(&tokens, format!("{TOKEN} schemathesis\n")).unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshatlas"));
    cmd.args(["serve", "--addr", "127.0.0.1:0", "--workers", "1", "--threads", "1"])
        // Keep-alive idle time (the header timeout) longer than any pause of the
        // client between two requests on a pooled connection: see docs/decisions.md.
        .args(["--header-timeout-secs", "120"])
        .arg("--data-dir")
        .arg(dir.join("data"))
        .arg("--auth-tokens")
        .arg(&tokens)
        .env("MESHATLAS_LOG", "warn");
    let (child, base) = common::spawn_listening_logged(cmd, &dir.join("server.log"));
    Server { child, base }
}

/// The `API Links: N covered` count of the stateful phase's summary.
fn links_covered(report: &str) -> usize {
    report
        .lines()
        .find_map(|l| l.trim().strip_prefix("API Links:"))
        .and_then(|l| l.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

#[test]
fn schemathesis_finds_no_failure_against_the_real_server() {
    let dir = tempfile::tempdir().unwrap();
    let server = start_server(dir.path());
    let root = env!("CARGO_MANIFEST_DIR");
    let hooks_dir = Path::new(root).join("tests/schemathesis");
    let out = Command::new("python3")
        .args(["-m", "schemathesis.cli", "--config-file"])
        .arg(hooks_dir.join("schemathesis.toml"))
        .arg("run")
        .arg(Path::new(root).join("api/openapi.yaml"))
        .args(["--url", &server.base, "--checks", "all", "--phases", "examples,coverage,fuzzing,stateful"])
        .args(["--max-examples", MAX_EXAMPLES, "--seed", SEED, "--workers", "1", "--generation-database", "none"])
        .args(["--request-timeout", "30", "--no-color", "--output-truncate", "false"])
        .args(["-H", &format!("Authorization: Bearer {TOKEN}")])
        .env("PYTHONPATH", &hooks_dir)
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .env("SCHEMATHESIS_HOOKS", "hooks")
        .current_dir(dir.path())
        .output()
        .unwrap_or_else(|e| panic!("cannot run python3 ({e}); run .ci/run to install schemathesis"));
    let report = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("No module named schemathesis"), "schemathesis is missing; run .ci/run:\n{stderr}");
    assert!(out.status.success(), "schemathesis found failures ({}):\n{report}\n{stderr}", out.status);
    // The stateful phase ran and followed links from the created job.
    assert!(links_covered(&report) >= 3, "the stateful phase followed too few links:\n{report}");
    // Every operation on a job was reached with a real one (schemathesis warns
    // "Missing test data" when an operation only ever answered 404).
    assert!(!report.contains("Missing test data"), "an operation was never reached with a real job:\n{report}");
}
