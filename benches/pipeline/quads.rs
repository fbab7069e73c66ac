//! The quads stage side by side with Gmsh's quasi-structured quad mesher
//! (issue 13, "Benchmark"): one table per input with, for meshatlas (its
//! `quads.msh` scored by `benches/quad_metrics.py`, and the numbers of its
//! own `report.json`) and for Gmsh (its `gmsh_quads.msh` scored by the same
//! script), the quads, triangles, irregular vertices (interior; boundary
//! corner-aware), inverted quads (scaled Jacobian ≤ 0 against the surface
//! normal, and Gmsh's SICN ≤ 0), min scaled Jacobian, the share of quads
//! with scaled Jacobian ≥ 0.5, and seconds (the whole process as the user
//! waits, and the meshing step alone). A Gmsh run killed at the time limit
//! shows as `hang > N s`.
//!
//! One script scores both files so the numbers share one definition; the
//! report's own numbers are read tolerantly (their field names belong to
//! the stage) and shown beside the script's as a cross-check.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// Name of Gmsh's quad mesh in a bench output directory
/// (`benches/gmsh_reference.py` writes it there).
pub const GMSH_QUADS_MSH: &str = "gmsh_quads.msh";

/// Name of meshatlas's quad mesh artifact.
pub const QUADS_MSH: &str = "quads.msh";

/// What one tool produced for the quads table.
pub struct Side<'a> {
    /// The tool's MSH file, when it wrote one.
    pub msh: Option<PathBuf>,
    /// Seconds of the whole process (the user's wait).
    pub wall: f64,
    /// Seconds of the meshing step alone (`quads` in the step timings).
    pub step: Option<f64>,
    /// Why there is no mesh: a failure or `hang > N s`.
    pub failure: Option<&'a str>,
    /// The stage's own report (`stages.quads` of `report.json`), meshatlas only.
    pub report: Option<&'a Value>,
}

/// Scores `files` with `benches/quad_metrics.py` in one Python process;
/// returns each file's JSON object (or why there is none) by path.
pub fn quad_metrics(files: &[&Path]) -> BTreeMap<PathBuf, Result<Value, String>> {
    let mut out = BTreeMap::new();
    if files.is_empty() {
        return out;
    }
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/quad_metrics.py");
    let output = match Command::new("python3").arg(script).args(files).output() {
        Ok(o) => o,
        Err(e) => {
            for f in files {
                out.insert(f.to_path_buf(), Err(format!("cannot start python3: {e}")));
            }
            return out;
        }
    };
    for line in String::from_utf8_lossy(&output.stdout).lines() {
        let Ok(v) = serde_json::from_str::<Value>(line) else { continue };
        let Some(file) = v["file"].as_str().map(PathBuf::from) else { continue };
        let r = match v["error"].as_str() {
            Some(e) => Err(e.to_string()),
            None => Ok(v),
        };
        out.insert(file, r);
    }
    let err = String::from_utf8_lossy(&output.stderr);
    let last = err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("no output").trim().to_string();
    for f in files {
        out.entry(f.to_path_buf()).or_insert_with(|| Err(format!("quad_metrics.py: {last}")));
    }
    out
}

/// The first value under `key` in `v` searched depth first through nested
/// objects (the report's layout is the stage's to choose).
fn find<'a>(v: &'a Value, key: &str) -> Option<&'a Value> {
    let map = v.as_object()?;
    map.get(key).or_else(|| map.values().find_map(|child| find(child, key)))
}

/// The first number in `report` at one of `paths` (`a.b`: `a` found at any
/// depth, then `b` directly under it).
pub fn report_number(report: &Value, paths: &[&str]) -> Option<f64> {
    paths.iter().find_map(|path| {
        let mut parts = path.split('.');
        let mut v = find(report, parts.next()?)?;
        for p in parts {
            v = v.get(p)?;
        }
        v.as_f64()
    })
}

/// A metrics cell: the integer or 3-decimal number at `key`.
fn cell(m: &Value, key: &str) -> String {
    match &m[key] {
        Value::Number(n) if n.is_i64() || n.is_u64() => n.to_string(),
        Value::Number(n) => n.as_f64().map(|x| format!("{x:.3}")).unwrap_or_default(),
        Value::Object(o) => {
            o.iter().map(|(k, v)| format!("{k}:{v}")).collect::<Vec<_>>().join(" ").chars().take(22).collect()
        }
        _ => "-".into(),
    }
}

/// The rows: label, key of the metrics script's JSON, and the names the
/// field may have in the stage's report (empty: not compared).
const ROWS: [(&str, &str, &[&str]); 14] = [
    ("quads", "n_quads", &["n_quads", "quads"]),
    ("triangles", "n_triangles", &["n_triangles", "triangles"]),
    ("irregular interior", "irregular_interior", &[]),
    ("  valences", "valence_histogram_interior", &[]),
    ("irregular boundary (c-a)", "irregular_boundary", &[]),
    ("irregular total", "irregular", &["n_irregular_vertices", "irregular_vertices", "n_irregular", "irregular"]),
    ("index sum / chi", "index_sum", &[]),
    ("inverted (SJ <= 0)", "inverted_sj", &["n_inverted", "inverted_quads", "inverted"]),
    ("inverted (SICN <= 0)", "inverted_sicn", &[]),
    ("min SJ", "sj_min", &["scaled_jacobian.min", "scaled_jacobian_min", "min_scaled_jacobian"]),
    ("SJ >= 0.5 %", "sj_frac_ge_0_5", &[]),
    ("SJ < 0.3", "sj_below_0_3", &["n_below_0_3", "scaled_jacobian.below_0_3", "below_0_3"]),
    ("min SICN", "sicn_min", &[]),
    ("max angle dev deg", "max_angle_deviation_deg", &["max_angle_deviation.max", "max_angle_deviation_deg"]),
];

/// Names the crossfield's singularity count may have in the report.
const SINGULARITIES: &[&str] = &["n_singularities", "singularities"];

/// The cell of one side in a metrics row.
fn metric_cell(side: &Side, scored: Option<&Result<Value, String>>, key: &str) -> String {
    match (side.failure, scored) {
        (_, Some(Ok(m))) => match key {
            "sj_frac_ge_0_5" => m[key].as_f64().map(|f| format!("{:.2}", 100.0 * f)).unwrap_or_else(|| "-".into()),
            "index_sum" => format!("{} / {}", cell(m, "index_sum"), cell(m, "euler_characteristic")),
            _ => cell(m, key),
        },
        (Some(f), _) if f.starts_with("hang") => f.to_string(),
        _ => "-".into(),
    }
}

/// Prints the side-by-side quads table of one input.
pub fn print_quads_table(name: &str, mesh_size: Option<f64>, ours: &Side, gmsh: Option<&Side>) {
    let files: Vec<&Path> = [Some(ours), gmsh].into_iter().flatten().filter_map(|s| s.msh.as_deref()).collect();
    let scored = quad_metrics(&files);
    let score = |s: &Side| s.msh.as_ref().and_then(|p| scored.get(p));
    let size = mesh_size.map(|h| format!(" (size {h:.4})")).unwrap_or_default();
    println!("{name}: quads{size}");
    println!("{:<44} {:>24} {:>14} {:>24}", "metric", "meshatlas", "ours (report)", "gmsh quasi-structured");
    for (label, key, paths) in ROWS {
        let a = metric_cell(ours, score(ours), key);
        let r = ours.report.and_then(|rep| report_number(rep, paths));
        let g = gmsh.map(|g| metric_cell(g, score(g), key)).unwrap_or_else(|| "-".into());
        println!("{:<44} {a:>24} {:>14} {g:>24}", row_label(name, label), fmt_opt(r));
    }
    let secs = |s: &Side, v: Option<f64>| match (s.failure, v) {
        (Some(f), _) if f.starts_with("hang") => f.to_string(),
        (_, Some(v)) => format!("{v:.3}"),
        _ => "-".into(),
    };
    let singularities = ours.report.and_then(|r| report_number(r, SINGULARITIES));
    println!("{:<44} {:>24} {:>14} {:>24}", row_label(name, "singularities"), "-", fmt_opt(singularities), "-");
    let gw = gmsh.map(|g| secs(g, Some(g.wall))).unwrap_or_else(|| "-".into());
    println!("{:<44} {:>24} {:>14} {gw:>24}", row_label(name, "seconds (job)"), secs(ours, Some(ours.wall)), "");
    let gs = gmsh.map(|g| secs(g, g.step)).unwrap_or_else(|| "-".into());
    println!("{:<44} {:>24} {:>14} {gs:>24}", row_label(name, "seconds (quads step)"), secs(ours, ours.step), "");
    for (tool, side) in [("meshatlas", Some(ours)), ("gmsh", gmsh)] {
        if let Some(Some(Err(e))) = side.map(score) {
            println!("{name} {tool} quads.msh unreadable: {e}");
        }
    }
}

/// A number (integers without decimals), or `-`.
fn fmt_opt(v: Option<f64>) -> String {
    match v {
        Some(x) if x.fract() == 0.0 && x.abs() < 1e15 => format!("{x}"),
        Some(x) => format!("{x:.3}"),
        None => "-".into(),
    }
}

/// The first column: the input's name and the row's label.
fn row_label(name: &str, label: &str) -> String {
    format!("{name} {label}")
}
