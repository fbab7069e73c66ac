//! Dependency direction: the numerical core never names the service layers.
//!
//! Scans the source of the core modules for identifiers of the HTTP/async
//! stack and of the `jobs`/`http`/`pipeline` modules. A failure names the file
//! and line so the offending `use` is easy to find.

use std::path::{Path, PathBuf};

const CORE: &[&str] = &[
    "src/geom",
    "src/mesh",
    "src/linalg",
    "src/fem",
    "src/io",
    "src/atlas",
    "src/crossfield",
    "src/frames",
    "src/quads",
    "src/preview",
    "src/progress.rs",
    "src/failure.rs",
];
const FORBIDDEN_IN_CORE: &[&str] =
    &["axum", "tokio", "tower", "hyper", "reqwest", "rusqlite", "crate::jobs", "crate::http", "crate::pipeline"];

fn rust_files(root: &Path) -> Vec<PathBuf> {
    if root.is_file() {
        return vec![root.to_path_buf()];
    }
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("readable source dir") {
            let p = entry.expect("dir entry").path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    out
}

/// Lines of `files` that mention any of `words` outside comments.
fn offending_lines(files: &[PathBuf], words: &[&str]) -> Vec<String> {
    let mut bad = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(f).expect("readable source file");
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            for w in words {
                let hit = code.match_indices(w).any(|(k, _)| {
                    let before = code[..k].chars().next_back();
                    let after = code[k + w.len()..].chars().next();
                    let ident = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
                    !ident(before) && !ident(after)
                });
                if hit {
                    bad.push(format!("{}:{}: `{}` in: {}", f.display(), i + 1, w, line.trim()));
                }
            }
        }
    }
    bad
}

#[test]
fn core_does_not_depend_on_service_layers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files: Vec<PathBuf> = CORE.iter().flat_map(|c| rust_files(&root.join(c))).collect();
    assert!(files.len() >= 9, "core sources found: {}", files.len());
    let bad = offending_lines(&files, FORBIDDEN_IN_CORE);
    assert!(bad.is_empty(), "core modules name service layers:\n{}", bad.join("\n"));
}

#[test]
fn only_http_knows_axum_and_only_jobs_touch_both_pools() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let pipeline = rust_files(&root.join("src/pipeline"));
    let bad = offending_lines(&pipeline, &["axum", "tokio", "crate::jobs", "crate::http"]);
    assert!(bad.is_empty(), "pipeline names the service layers:\n{}", bad.join("\n"));
    let jobs = rust_files(&root.join("src/jobs"));
    let bad = offending_lines(&jobs, &["axum", "crate::http"]);
    assert!(bad.is_empty(), "jobs names the HTTP layer:\n{}", bad.join("\n"));
}

#[test]
fn the_scanner_finds_a_planted_violation() {
    let dir = std::env::temp_dir().join(format!("meshatlas-arch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("x.rs");
    std::fs::write(&f, "use axum::Router; // fine in comment: tokio\nlet tokio_like = 1;\n").unwrap();
    let bad = offending_lines(&[f], &["axum", "tokio"]);
    assert_eq!(bad.len(), 1, "{bad:?}");
    std::fs::remove_dir_all(&dir).ok();
}
