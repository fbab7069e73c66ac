//! Helpers shared by the integration tests: running Python (gmsh, meshio)
//! as a subprocess and scratch directories.
//!
//! Tests fail, never skip, when python3 or a module is missing: `.ci/run`
//! installs them.

#![allow(dead_code)]

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Run `script` with `python3` and `args`; the script prints one JSON
/// document on its last stdout line, which is returned.
pub fn python(script: &str, args: &[&str]) -> Value {
    let prelude = "import sys, json\n\
        try:\n    import numpy as np, meshio, gmsh\n\
        except ImportError as e:\n    sys.stderr.write(f'missing Python module: {e}; run .ci/run to install the test tools\\n'); sys.exit(3)\n";
    let out =
        Command::new("python3").arg("-c").arg(format!("{prelude}{script}")).args(args).output().unwrap_or_else(|e| {
            panic!("cannot run python3 ({e}); run .ci/run to install python3 with gmsh and meshio")
        });
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "python3 failed ({}):\n{stderr}\n{stdout}", out.status);
    let last = stdout
        .lines()
        .rev()
        .find(|l| l.starts_with('{'))
        .unwrap_or_else(|| panic!("no JSON from python:\n{stdout}\n{stderr}"));
    serde_json::from_str(last).unwrap_or_else(|e| panic!("bad JSON from python ({e}): {last}"))
}

/// Spawns `cmd` with stdout piped and reads its first line, which the
/// server prints as `listening on ADDR`; returns the child and `http://ADDR`.
pub fn spawn_listening(mut cmd: Command) -> (std::process::Child, String) {
    use std::io::BufRead;
    let mut child = cmd.stdout(std::process::Stdio::piped()).spawn().expect("start meshatlas");
    let stdout = child.stdout.take().expect("piped stdout");
    let mut line = String::new();
    std::io::BufReader::new(stdout).read_line(&mut line).expect("read the listening line");
    let addr = line.trim().strip_prefix("listening on ").unwrap_or_else(|| panic!("unexpected first line {line:?}"));
    let base = format!("http://{addr}");
    (child, base)
}

/// Like [`spawn_listening`], with the child's stderr going to the file
/// `log`, which a failed start prints (the reason the server gave).
pub fn spawn_listening_logged(mut cmd: Command, log: &Path) -> (std::process::Child, String) {
    use std::io::BufRead;
    let file = std::fs::File::create(log).expect("create the server log");
    let mut child = cmd.stdout(std::process::Stdio::piped()).stderr(file).spawn().expect("start meshatlas");
    let mut line = String::new();
    let _ = std::io::BufReader::new(child.stdout.take().expect("piped stdout")).read_line(&mut line);
    let Some(addr) = line.trim().strip_prefix("listening on ").map(str::to_string) else {
        let _ = child.kill();
        panic!("meshatlas serve did not start: {}", std::fs::read_to_string(log).unwrap_or_default());
    };
    (child, format!("http://{addr}"))
}

/// A fresh directory `<target tmp>/<suite>/<name>` for one test's files.
pub fn scratch(suite: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(suite).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

/// The path as UTF-8 text, for command lines.
pub fn path_str(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// The shared test data directory (`../shared/data` next to the repository).
pub fn shared_data() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    assert!(p.is_dir(), "test data not found at {}: CI clones the repository next to ../shared", p.display());
    p
}
