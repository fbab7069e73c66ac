//! Known answers of the bench's quad-mesh metrics script
//! (`benches/quad_metrics.py`), which scores meshatlas's `quads.msh` and
//! Gmsh's quad meshes the same way: small meshes written here by hand
//! (MSH 2.2 and 4.1, 4- and 9-node quads), whose valences, irregular
//! vertices and scaled Jacobians follow from their construction.

mod common;

use common::{path_str, scratch};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A mesh to write: nodes, 2D elements as `(Gmsh type, nodes)` and
/// line elements (curve edges).
#[derive(Default, Clone)]
struct Msh {
    nodes: Vec<[f64; 3]>,
    elems: Vec<(u32, Vec<usize>)>,
    lines: Vec<[usize; 2]>,
}

impl Msh {
    /// Adds a node, returning its index.
    fn node(&mut self, p: [f64; 3]) -> usize {
        self.nodes.push(p);
        self.nodes.len() - 1
    }

    /// Adds a 4-node quad.
    fn quad(&mut self, q: [usize; 4]) {
        self.elems.push((3, q.to_vec()));
    }

    /// MSH 2.2 ASCII: lines on curve 1, 2D elements on surface 1.
    fn msh2(&self) -> String {
        let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
        writeln!(s, "{}", self.nodes.len()).unwrap();
        for (i, p) in self.nodes.iter().enumerate() {
            writeln!(s, "{} {} {} {}", i + 1, p[0], p[1], p[2]).unwrap();
        }
        writeln!(s, "$EndNodes\n$Elements\n{}", self.lines.len() + self.elems.len()).unwrap();
        let mut id = 0;
        let all = self.lines.iter().map(|l| (1, l.to_vec())).chain(self.elems.iter().cloned());
        for (t, nodes) in all {
            id += 1;
            let ns: Vec<String> = nodes.iter().map(|n| (n + 1).to_string()).collect();
            writeln!(s, "{id} {t} 2 1 1 {}", ns.join(" ")).unwrap();
        }
        s.push_str("$EndElements\n");
        s
    }

    /// MSH 4.1 ASCII with `$Entities` (one curve, one surface bounded by
    /// it), quads of one type only.
    fn msh41(&self) -> String {
        let (n, t) = (self.nodes.len(), self.elems[0].0);
        assert!(self.elems.iter().all(|(e, _)| *e == t));
        let mut s = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 1 1 0\n");
        s.push_str("1 0 0 0 1 1 1 0 0\n1 0 0 0 1 1 1 0 1 1\n$EndEntities\n$Nodes\n");
        writeln!(s, "1 {n} 1 {n}\n2 1 0 {n}").unwrap();
        for i in 1..=n {
            writeln!(s, "{i}").unwrap();
        }
        for p in &self.nodes {
            writeln!(s, "{} {} {}", p[0], p[1], p[2]).unwrap();
        }
        let (nl, ne) = (self.lines.len(), self.elems.len());
        writeln!(s, "$EndNodes\n$Elements\n2 {} 1 {}\n1 1 1 {nl}", nl + ne, nl + ne).unwrap();
        for (i, l) in self.lines.iter().enumerate() {
            writeln!(s, "{} {} {}", i + 1, l[0] + 1, l[1] + 1).unwrap();
        }
        writeln!(s, "2 1 {t} {ne}").unwrap();
        for (i, (_, nodes)) in self.elems.iter().enumerate() {
            let ns: Vec<String> = nodes.iter().map(|n| (n + 1).to_string()).collect();
            writeln!(s, "{} {}", nl + i + 1, ns.join(" ")).unwrap();
        }
        s.push_str("$EndElements\n");
        s
    }
}

/// An `n × n` grid of unit quads in the plane z = 0 (counter-clockwise seen
/// from +z), with its boundary as lines when `lines`.
fn grid(n: usize, lines: bool) -> Msh {
    let mut m = Msh::default();
    let id = |i: usize, j: usize| j * (n + 1) + i;
    for j in 0..=n {
        for i in 0..=n {
            m.node([i as f64, j as f64, 0.0]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            m.quad([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    if lines {
        for k in 0..n {
            m.lines.extend([
                [id(k, 0), id(k + 1, 0)],
                [id(n, k), id(n, k + 1)],
                [id(k + 1, n), id(k, n)],
                [id(0, k + 1), id(0, k)],
            ]);
        }
    }
    m
}

/// The 3 × 3 grid as 9-node quads (Gmsh type 10: corners, edge midpoints
/// in the order 01 12 23 30, centre) on a 7 × 7 node lattice.
fn grid_order2() -> Msh {
    let mut m = Msh::default();
    let id = |i: usize, j: usize| j * 7 + i;
    for j in 0..7 {
        for i in 0..7 {
            m.node([i as f64 / 2.0, j as f64 / 2.0, 0.0]);
        }
    }
    for j in 0..3 {
        for i in 0..3 {
            let (x, y) = (2 * i, 2 * j);
            let corners = [id(x, y), id(x + 2, y), id(x + 2, y + 2), id(x, y + 2)];
            let mids = [id(x + 1, y), id(x + 2, y + 1), id(x + 1, y + 2), id(x, y + 1)];
            m.elems.push((10, [&corners[..], &mids[..], &[id(x + 1, y + 1)]].concat()));
        }
    }
    m
}

/// A disk of quads: a 4 × 4 grid on [-1, 1]² whose 16 boundary vertices
/// are joined to their radial projections on the circle of radius 2.5 by a
/// ring of 16 quads. The grid's 4 corners have valence 3 (two grid edges
/// and one spoke); every circle vertex has two quads over an angle of about
/// 157.5°, so the boundary is regular.
fn quad_disk() -> Msh {
    let mut m = grid(4, false);
    for p in &mut m.nodes {
        *p = [p[0] / 2.0 - 1.0, p[1] / 2.0 - 1.0, 0.0];
    }
    let id = |i: usize, j: usize| j * 5 + i;
    // the grid boundary, counter-clockwise from (0, 0)
    let mut ring: Vec<usize> = (0..4).map(|i| id(i, 0)).collect();
    ring.extend((0..4).map(|j| id(4, j)));
    ring.extend((0..4).map(|i| id(4 - i, 4)));
    ring.extend((0..4).map(|j| id(0, 4 - j)));
    let outer: Vec<usize> = ring
        .iter()
        .map(|&v| {
            let p = m.nodes[v];
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            m.node([2.5 * p[0] / r, 2.5 * p[1] / r, 0.0])
        })
        .collect();
    for k in 0..16 {
        let l = (k + 1) % 16;
        m.quad([ring[k], outer[k], outer[l], ring[l]]);
        m.lines.push([outer[k], outer[l]]);
    }
    m
}

/// The surface of the cube [0, n]³ as 6 n² unit quads oriented outwards,
/// with its 12 edges as lines when `lines`.
fn cube(n: usize, lines: bool) -> Msh {
    let mut m = Msh::default();
    let mut index = std::collections::HashMap::new();
    let mut node = |m: &mut Msh, p: [usize; 3]| *index.entry(p).or_insert_with(|| m.node(p.map(|c| c as f64)));
    // each face: a fixed axis at 0 or n, and two in-plane axes (u, v) with
    // u × v along the outward normal
    let faces = [(0, 0, 2, 1), (0, n, 1, 2), (1, 0, 0, 2), (1, n, 2, 0), (2, 0, 1, 0), (2, n, 0, 1)];
    for (axis, level, u, v) in faces {
        let at = |a: usize, b: usize| {
            let mut p = [0; 3];
            p[axis] = level;
            p[u] = a;
            p[v] = b;
            p
        };
        for b in 0..n {
            for a in 0..n {
                let q = [at(a, b), at(a + 1, b), at(a + 1, b + 1), at(a, b + 1)].map(|p| node(&mut m, p));
                m.quad(q);
            }
        }
    }
    if lines {
        let on_edge = |p: &[f64; 3]| p.iter().filter(|&&c| c == 0.0 || c == n as f64).count() >= 2;
        let mut edges = std::collections::BTreeSet::new();
        for (_, q) in &m.elems {
            for k in 0..4 {
                let (a, b) = (q[k], q[(k + 1) % 4]);
                let (pa, pb) = (m.nodes[a], m.nodes[b]);
                let same = (0..3).filter(|&c| pa[c] == pb[c] && (pa[c] == 0.0 || pa[c] == n as f64)).count();
                if on_edge(&pa) && on_edge(&pb) && same == 2 {
                    edges.insert([a.min(b), a.max(b)]);
                }
            }
        }
        m.lines = edges.into_iter().collect();
    }
    m
}

/// Writes each `(name, text)` and runs the metrics script on all of them,
/// returning one JSON object per file, by name.
fn metrics(suite: &str, files: &[(&str, String)]) -> std::collections::HashMap<String, Value> {
    let dir = scratch("quad_metrics", suite);
    let paths: Vec<PathBuf> = files
        .iter()
        .map(|(name, text)| {
            let p = dir.join(name);
            std::fs::write(&p, text).unwrap();
            p
        })
        .collect();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/quad_metrics.py");
    let out =
        Command::new("python3").arg(&script).args(paths.iter().map(|p| path_str(p))).output().unwrap_or_else(|e| {
            panic!("cannot run python3 ({e}); run .ci/run to install python3 with gmsh and meshio")
        });
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "quad_metrics.py failed ({}):\n{}\n{stdout}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let mut by_name = std::collections::HashMap::new();
    for (line, (name, _)) in stdout.lines().filter(|l| l.starts_with('{')).zip(files) {
        let v: Value = serde_json::from_str(line).unwrap();
        assert!(v["file"].as_str().unwrap().ends_with(name), "{line}");
        by_name.insert(name.to_string(), v);
    }
    assert_eq!(by_name.len(), files.len(), "{stdout}");
    by_name
}

fn int(v: &Value, key: &str) -> i64 {
    v[key].as_i64().unwrap_or_else(|| panic!("no integer `{key}` in {v}"))
}

fn num(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("no number `{key}` in {v}"))
}

/// Every quad is a unit square: no irregular vertex, scaled Jacobian and
/// SICN exactly 1, and the index sum is 4χ = 4; the same in MSH 2.2, in
/// MSH 4.1 with entities and with 9-node quads.
#[test]
fn a_structured_grid_is_regular_with_unit_scaled_jacobian() {
    let r = metrics(
        "grid",
        &[
            ("grid22.msh", grid(3, true).msh2()),
            ("grid41.msh", grid(3, true).msh41()),
            ("grid_order2.msh", grid_order2().msh2()),
            ("grid_nolines.msh", grid(3, false).msh2()),
        ],
    );
    for (name, v) in &r {
        assert_eq!(int(v, "n_quads"), 9, "{name}");
        assert_eq!(int(v, "n_triangles"), 0, "{name}");
        assert_eq!(int(v, "n_vertices"), 16, "{name}");
        assert_eq!(int(v, "irregular_interior"), 0, "{name}");
        assert_eq!(int(v, "irregular_boundary"), 0, "{name}");
        assert_eq!(v["valence_histogram_interior"], serde_json::json!({"4": 4}), "{name}");
        assert_eq!(int(v, "euler_characteristic"), 1, "{name}");
        assert_eq!(int(v, "index_sum"), 4, "{name}");
        for key in ["sj_min", "sj_mean", "sicn_min"] {
            assert!((num(v, key) - 1.0).abs() < 1e-9, "{name}: {key} {v}");
        }
        assert_eq!(num(v, "sj_frac_ge_0_5"), 1.0, "{name}");
        assert_eq!(int(v, "inverted_sj") + int(v, "inverted_sicn"), 0, "{name}");
        assert!(num(v, "max_angle_deviation_deg") < 1e-9, "{name}");
    }
    assert!((num(&r["grid22.msh"], "mean_edge_length") - 1.0).abs() < 1e-12);
    assert!((num(&r["grid_order2.msh"], "mean_edge_length") - 1.0).abs() < 1e-12);
    assert_eq!(int(&r["grid_order2.msh"], "n_nodes"), 49);
    assert_eq!(int(&r["grid41.msh"], "n_curve_edges"), 12);
}

/// Moving the grid vertex (1, 1) to (1.9, 1.9), inside the triangle of the
/// far corners of the quad (1,1)-(2,2), makes that one quad non-convex:
/// its corner there has edges (0.1, −0.9) and (−0.9, 0.1), a scaled
/// Jacobian of (0.01 − 0.81) / 0.82, and Gmsh's SICN is negative there too.
/// The three other quads at the vertex stay convex.
#[test]
fn one_non_convex_quad_is_the_one_inverted_quad() {
    let mut m = grid(3, true);
    m.nodes[4 + 1] = [1.9, 1.9, 0.0];
    let r = metrics("inverted", &[("inverted.msh", m.msh2())]);
    let v = &r["inverted.msh"];
    assert_eq!(int(v, "inverted_sj"), 1, "{v}");
    assert_eq!(int(v, "inverted_sicn"), 1, "{v}");
    assert!(num(v, "sicn_min") < 0.0, "{v}");
    assert!((num(v, "sj_min") - (0.01 - 0.81) / 0.82).abs() < 1e-9, "{v}");
    assert_eq!(int(v, "irregular"), 0, "{v}");
}

/// A quad with its corners listed in the opposite order lies flat in the
/// grid but is folded over its neighbours: measured against the surface
/// normal (from the neighbours) its scaled Jacobian is −1.
#[test]
fn a_quad_folded_over_its_neighbours_is_inverted_against_the_surface() {
    let mut m = grid(3, true);
    m.elems[4].1.reverse();
    let r = metrics("folded", &[("folded.msh", m.msh2())]);
    let v = &r["folded.msh"];
    assert_eq!(int(v, "inverted_sj"), 1, "{v}");
    assert!((num(v, "sj_min") + 1.0).abs() < 1e-9, "{v}");
    assert_eq!(int(v, "n_sharp_edges"), 0, "a fold is not a feature: {v}");
}

/// Two quads wrapped around a sharp tip (cow's horns end this way), each
/// with a corner there and sharing both of the tip's edges: their normals
/// are about opposite, like a fold's, but each points away from the
/// other, so the edges are a knife-edge ridge and each quad is measured
/// against its own normal. Gmsh's SICN rates both valid; averaging the two
/// normals as across a fold rated them inverted.
#[test]
fn two_quads_around_a_sharp_tip_are_not_a_fold() {
    let mut m = Msh::default();
    let tip = m.node([0.0, 0.0, 0.0]);
    let (p1, p2) = (m.node([1.0, 0.3, 0.0]), m.node([1.0, -0.3, 0.0]));
    let (a, b) = (m.node([1.2, 0.0, 0.3]), m.node([1.2, 0.0, -0.3]));
    m.quad([tip, p2, a, p1]);
    m.quad([tip, p1, b, p2]);
    let r = metrics("tip", &[("tip.msh", m.msh2())]);
    let v = &r["tip.msh"];
    assert_eq!(int(v, "inverted_sicn"), 0, "{v}");
    assert_eq!(int(v, "inverted_sj"), 0, "{v}");
    assert!(num(v, "sj_min") > 0.3, "{v}");
    assert_eq!(int(v, "n_sharp_edges"), 2, "{v}");
}

/// The quad disk has exactly the 4 valence-3 interior vertices of the
/// grid's corners, a regular boundary, index sum 4χ = 4, and no inverted
/// quad. Splitting one ring quad into two triangles leaves them counted as
/// triangles.
#[test]
fn a_quad_disk_has_four_valence_three_vertices() {
    let disk = quad_disk();
    let mut split = disk.clone();
    let q = split.elems.pop().unwrap().1;
    split.elems.push((2, vec![q[0], q[1], q[2]]));
    split.elems.push((2, vec![q[0], q[2], q[3]]));
    let r = metrics("disk", &[("disk.msh", disk.msh2()), ("split.msh", split.msh2())]);
    let v = &r["disk.msh"];
    assert_eq!(int(v, "n_quads"), 32);
    assert_eq!(int(v, "irregular_interior"), 4, "{v}");
    assert_eq!(v["valence_histogram_interior"]["3"], 4, "{v}");
    assert_eq!(int(v, "irregular_boundary"), 0, "{v}");
    assert_eq!(int(v, "index_sum"), 4 * int(v, "euler_characteristic"), "{v}");
    assert_eq!(int(v, "euler_characteristic"), 1);
    assert!(num(v, "sj_min") > 0.0 && int(v, "inverted_sicn") == 0, "{v}");
    let s = &r["split.msh"];
    assert_eq!((int(s, "n_quads"), int(s, "n_triangles")), (31, 2), "{s}");
}

/// The cube surface of 6·3² quads: without feature lines its 8 corners are
/// its only irregular vertices (valence 3, index sum 8 = 4χ); with its 12
/// edges as lines every corner holds one quad in each of its three 90°
/// sectors, so corner-aware it is regular. The sharp edges do not tilt the
/// reference normals: every scaled Jacobian is 1.
#[test]
fn a_cube_has_eight_valence_three_corners_regular_along_its_features() {
    let r = metrics("cube", &[("bare.msh", cube(3, false).msh2()), ("lined.msh", cube(3, true).msh2())]);
    let bare = &r["bare.msh"];
    assert_eq!(int(bare, "n_quads"), 54);
    assert_eq!(int(bare, "irregular_interior"), 8, "{bare}");
    assert_eq!(bare["valence_histogram_interior"], serde_json::json!({"3": 8, "4": 48}), "{bare}");
    assert_eq!(int(bare, "euler_characteristic"), 2);
    assert_eq!(int(bare, "index_sum"), 8);
    let lined = &r["lined.msh"];
    assert_eq!(int(lined, "n_curve_edges"), 36, "{lined}");
    assert_eq!(int(lined, "irregular_interior"), 0, "{lined}");
    assert_eq!(int(lined, "irregular_boundary"), 0, "{lined}");
    for v in [bare, lined] {
        assert_eq!(int(v, "n_sharp_edges"), 36, "{v}");
        assert!((num(v, "sj_min") - 1.0).abs() < 1e-9, "{v}");
        assert!((num(v, "sicn_min") - 1.0).abs() < 1e-9, "{v}");
    }
}

/// The classic 5-quad square: an inner square [1, 2]² joined to the outer
/// square [0, 3]² by 4 trapezoids. Its 4 inner vertices have valence 3, and
/// each outer corner holds 2 quads over a 90° angle where 1 is due, so it
/// is a boundary irregular vertex corner-aware; the 2 × 2 grid, whose
/// corners hold 1 quad, has none.
#[test]
fn a_corner_with_two_quads_is_a_boundary_irregular_vertex() {
    let mut m = Msh::default();
    let outer = [[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]].map(|p| m.node([p[0], p[1], 0.0]));
    let inner = [[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]].map(|p| m.node([p[0], p[1], 0.0]));
    m.quad(inner);
    for k in 0..4 {
        let l = (k + 1) % 4;
        m.quad([outer[k], outer[l], inner[l], inner[k]]);
        m.lines.push([outer[k], outer[l]]);
    }
    let r = metrics("five", &[("five.msh", m.msh2()), ("grid2.msh", grid(2, true).msh2())]);
    let v = &r["five.msh"];
    assert_eq!(int(v, "irregular_interior"), 4, "{v}");
    assert_eq!(int(v, "irregular_boundary"), 4, "{v}");
    assert_eq!(int(v, "index_sum"), 4, "{v}");
    let g = &r["grid2.msh"];
    assert_eq!(int(g, "irregular"), 0, "{g}");
}
