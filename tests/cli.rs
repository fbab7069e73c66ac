//! `meshatlas run`: the offline pipeline from the command line.

use std::process::Command;

fn write_obj(path: &std::path::Path) {
    let m = meshatlas::mesh::fixtures::icosphere(1);
    let mut s = String::new();
    for p in &m.positions {
        s.push_str(&format!("v {:?} {:?} {:?}\n", p.x, p.y, p.z));
    }
    for t in &m.triangles {
        s.push_str(&format!("f {} {} {}\n", t[0].idx() + 1, t[1].idx() + 1, t[2].idx() + 1));
    }
    std::fs::write(path, s).unwrap();
}

fn meshatlas() -> Command {
    Command::new(env!("CARGO_BIN_EXE_meshatlas"))
}

#[test]
fn run_writes_artifacts_and_prints_summary_timings_and_peak_rss() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("sphere.obj");
    write_obj(&input);
    let out = dir.path().join("out");
    let o = meshatlas().arg("run").arg(&input).arg("--out").arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("42 vertices, 80 triangles"), "{stdout}");
    assert!(stdout.lines().any(|l| l.starts_with("time") && l.contains("load")), "{stdout}");
    let rss: u64 = stdout
        .lines()
        .find_map(|l| l.strip_prefix("peak_rss_kb "))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no peak_rss_kb line: {stdout}"));
    assert!(rss > 100, "{rss}");
    for f in ["mesh.msh", "mesh.vtu", "report.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    // No progress bar when stderr is not a terminal.
    assert!(!String::from_utf8_lossy(&o.stderr).contains('%'));
    // --json: the report plus peak RSS.
    let o = meshatlas().arg("run").arg(&input).arg("--out").arg(&out).arg("--json").output().unwrap();
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["input"]["n_triangles"], 80);
    assert!(v["peak_rss_kb"].as_u64().is_some_and(|k| k > 100));
    assert_eq!(v["timings"][0]["step"], "load");
}

#[test]
fn run_reports_bad_params_stages_and_inputs_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("sphere.obj");
    write_obj(&input);
    let params = dir.path().join("p.json");
    std::fs::write(&params, r#"{"load": {"wobble": 1}}"#).unwrap();
    let o = meshatlas()
        .arg("run")
        .arg(&input)
        .args(["--out"])
        .arg(dir.path().join("o"))
        .arg("--params")
        .arg(&params)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("load.wobble"), "{err}");
    std::fs::write(&params, r#"[["crossfield"]]"#).unwrap();
    let o = meshatlas()
        .arg("run")
        .arg(&input)
        .args(["--out"])
        .arg(dir.path().join("o"))
        .arg("--params")
        .arg(&params)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("parameters must be a JSON object, got an array"), "{err}");
    let o = meshatlas()
        .arg("run")
        .arg(&input)
        .args(["--out"])
        .arg(dir.path().join("o"))
        .args(["--stages", "bogus"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("unknown stage `bogus`"));
    let empty = dir.path().join("empty.stl");
    std::fs::write(&empty, b"").unwrap();
    let o = meshatlas().arg("run").arg(&empty).args(["--out"]).arg(dir.path().join("o")).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("[empty-file]"), "{}", String::from_utf8_lossy(&o.stderr));
}
