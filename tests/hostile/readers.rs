//! Reader consistency (issue 11 item 7): an MSH 4.1 file whose node tag 3
//! is given twice with different coordinates must fail the job, naming the
//! tag, instead of silently using the first coordinates.

use std::time::Duration;

use crate::common::Server;

/// The reproduction from the issue: tag 3 at (0, 1, 0) and again at (5, 5, 5).
const DUP_MSH: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 3\n2 1 0 4\n1\n2\n3\n3\n0 0 0\n1 0 0\n0 1 0\n5 5 5\n$EndNodes\n$Elements\n1 1 1 1\n2 1 2 1\n1 1 2 3\n$EndElements\n";

/// Submits `text` as `name` and waits for the job's final state.
async fn run(s: &Server, name: &str, text: &str) -> serde_json::Value {
    let resp = s.submit_bytes(name, text.as_bytes().to_vec(), None).await;
    assert_eq!(resp.status(), 202, "submission of {name} refused");
    let job: serde_json::Value = resp.json().await.unwrap();
    let id = job["id"].as_str().unwrap().to_string();
    s.wait_final(&id, Duration::from_secs(20)).await
}

#[tokio::test]
async fn msh41_duplicate_node_tag_with_other_coordinates_fails_the_job() {
    let s = Server::start(&[]);
    let j = run(&s, "dup.msh", DUP_MSH).await;
    assert_eq!(j["state"], "failed", "{j:#}");
    assert_eq!(j["error"]["type"], "urn:meshatlas:problem:parse-error", "{j:#}");
    let detail = j["error"]["detail"].as_str().unwrap_or_default();
    assert!(detail.contains("node tag 3") && detail.contains("line 14"), "{detail}");
}

#[tokio::test]
async fn msh41_unknown_element_type_is_unsupported_not_truncated() {
    let s = Server::start(&[]);
    // Block 2 has type 999 (no such Gmsh type) and its element on one line.
    let text = DUP_MSH
        .replace("5 5 5", "0 1 0")
        .replace("$Elements\n1 1 1 1\n", "$Elements\n2 2 1 2\n")
        .replace("1 1 2 3\n$EndElements", "1 1 2 3\n2 1 999 1\n2 1 2 3 1 2\n$EndElements");
    let j = run(&s, "odd.msh", &text).await;
    assert_eq!(j["state"], "failed", "{j:#}");
    assert_eq!(j["error"]["type"], "urn:meshatlas:problem:unsupported", "{j:#}");
    let detail = j["error"]["detail"].as_str().unwrap_or_default();
    assert!(detail.contains("element type 999") && detail.contains("block 2"), "{detail}");
}

// Boundary loops of odd surfaces (issue 11 item 12): the frames stage's
// `open-surface` detail must count the loops repair reports.

/// ASCII STL of `tris` over `pts`.
fn ascii_stl(pts: &[[f64; 3]], tris: &[[usize; 3]]) -> String {
    let mut s = String::from("solid t\n");
    for t in tris {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for &i in t {
            s.push_str(&format!("vertex {} {} {}\n", pts[i][0], pts[i][1], pts[i][2]));
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid t\n");
    s
}

/// OBJ of a half-twisted strip of `n` quads (two triangles each).
fn moebius_obj(n: usize) -> String {
    let mut s = String::new();
    for i in 0..n {
        let t = std::f64::consts::TAU * i as f64 / n as f64;
        for w in [-0.3, 0.3] {
            let r = 1.0 + w * (t / 2.0).cos();
            s.push_str(&format!("v {} {} {}\n", r * t.cos(), r * t.sin(), w * (t / 2.0).sin()));
        }
    }
    for i in 0..n {
        let (a, b) = (2 * i + 1, 2 * i + 2);
        let (c, d) = if i + 1 == n { (2, 1) } else { (2 * i + 3, 2 * i + 4) };
        s.push_str(&format!("f {a} {c} {b}\nf {b} {c} {d}\n"));
    }
    s
}

/// The first `n_boundary_loops` anywhere in `v`.
fn find_loops(v: &serde_json::Value) -> Option<u64> {
    match v {
        serde_json::Value::Object(m) => {
            m.get("n_boundary_loops").and_then(|x| x.as_u64()).or_else(|| m.values().find_map(find_loops))
        }
        serde_json::Value::Array(a) => a.iter().find_map(find_loops),
        _ => None,
    }
}

/// Repair's loop count (a job without stages) and the frames detail's.
async fn loops_by_repair_and_frames(s: &Server, name: &str, text: &str) -> (u64, u64, String) {
    let submit = |params: &'static str| {
        let bytes = text.as_bytes().to_vec();
        async move {
            let resp = s.submit_bytes(name, bytes, Some(params)).await;
            assert_eq!(resp.status(), 202);
            let id = resp.json::<serde_json::Value>().await.unwrap()["id"].as_str().unwrap().to_string();
            s.wait_final(&id, Duration::from_secs(20)).await
        }
    };
    let plain = submit(r#"{"stages":[]}"#).await;
    assert_eq!(plain["state"], "succeeded", "{plain:#}");
    let repair = find_loops(&plain["summary"]).unwrap_or_else(|| panic!("no n_boundary_loops: {plain:#}"));
    let frames = submit(r#"{"stages":["frames"]}"#).await;
    assert_eq!(frames["error"]["type"], "urn:meshatlas:problem:open-surface", "{frames:#}");
    let detail = frames["error"]["detail"].as_str().unwrap_or_default().to_string();
    let n = detail
        .split("it has ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no loop count in {detail}"));
    (repair, n, detail)
}

#[tokio::test]
async fn frames_open_surface_counts_the_loops_repair_counts() {
    let s = Server::start(&[]);
    let fin_pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.5, -1.0, 0.0], [0.5, 0.0, 1.0]];
    let fin = ascii_stl(&fin_pts, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
    let (repair, frames, detail) = loops_by_repair_and_frames(&s, "fin.stl", &fin).await;
    assert_eq!(frames, repair, "fin: {detail}");
    assert!(detail.contains("non-manifold"), "fin: {detail}");
    let (repair, frames, detail) = loops_by_repair_and_frames(&s, "moebius.obj", &moebius_obj(12)).await;
    assert_eq!((frames, repair), (1, 1), "Möbius strip: {detail}");
}
