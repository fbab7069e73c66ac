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
