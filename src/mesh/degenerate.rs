//! Zero-area triangles resolved without opening the surface.
//!
//! Deleting a zero-area triangle from a closed surface leaves a hole: its
//! three edges are shared with neighbours, which then have an unmatched
//! edge each. Mesh-repair libraries instead change the connectivity so that
//! the degenerate triangle disappears together with a neighbour (or is
//! replaced), keeping closedness, orientation and χ:
//!
//! - a **needle** has a vanishing edge (its two ends coincide up to
//!   round-off): the edge is collapsed, i.e. one end is merged into the
//!   other. The needle and the triangle across the vanishing edge then
//!   repeat a vertex and are dropped; every other edge keeps its two
//!   triangles, and χ is unchanged (`V − 1`, `E − 3`, `F − 2`).
//! - a **cap** has three distinct corners on one line, the middle one `m`
//!   strictly inside the long edge `ab`: the long edge is flipped. With the
//!   neighbour `u` across `ab` and its far corner `d`, the pair (cap, `u`)
//!   becomes `(cap with b → d)` and `(u with a → m)`, i.e. the triangles
//!   `{m, a, d}` and `{m, d, b}`: the same four outer edges, the new edge
//!   `md`, two triangles for two, each keeping its own orientation.
//!
//! A flip can leave a new zero-area triangle (when `d` is on the same line
//! too), so caps are resolved in a few rounds. A cap whose short edges are
//! not both shared is removed, as that opens no hole; so is a triangle
//! that neither operation applies to (its long edge on the boundary or
//! non-manifold, or the flip's new edge existing already). Each is counted.
//!
//! Zero area and "vanishing" use the same threshold as the rest of repair:
//! height (or length) at most `ZERO_AREA_RELATIVE_HEIGHT · D` relative to
//! the longest edge, `D` the bounding-box diagonal.

use hashbrown::HashMap;
use rayon::prelude::*;
use serde::Serialize;

use super::repair::ZERO_AREA_RELATIVE_HEIGHT;
use crate::geom::Vec3;

/// Rounds of cap flips before the remaining zero-area triangles are removed.
const MAX_FLIP_ROUNDS: usize = 4;

/// How the zero-area triangles of a soup were resolved.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ZeroAreaResolution {
    /// Vanishing edges of needles collapsed (one vertex merged into another).
    pub n_needle_edges_collapsed: usize,
    /// Triangles dropped by those collapses (each needle and the triangle
    /// across its vanishing edge).
    pub n_triangles_removed_by_collapse: usize,
    /// Long edges of caps flipped (the cap and its neighbour replaced by two
    /// triangles).
    pub n_cap_edges_flipped: usize,
    /// Zero-area triangles that could be neither collapsed nor flipped and
    /// were removed.
    pub n_removed: usize,
}

/// Twice the area and the edge lengths of `t`.
fn shape(positions: &[Vec3], t: &[u32; 3]) -> (f64, [f64; 3]) {
    let [a, b, c] = t.map(|v| positions[v as usize]);
    let twice_area = (b - a).cross(&(c - a)).norm();
    // Edge k is opposite corner k: (1,2), (2,0), (0,1).
    (twice_area, [(c - b).norm(), (a - c).norm(), (b - a).norm()])
}

/// True when `t` has zero area up to round-off (see the module doc).
pub(super) fn is_zero_area(positions: &[Vec3], t: &[u32; 3], diagonal: f64) -> bool {
    let (twice_area, lengths) = shape(positions, t);
    let longest = lengths[0].max(lengths[1]).max(lengths[2]);
    twice_area <= ZERO_AREA_RELATIVE_HEIGHT * diagonal * longest
}

/// Resolves the zero-area triangles of `triangles` in place (module doc):
/// needles are collapsed, caps flipped, the rest removed. Triangles that
/// repeat a vertex must already be gone. Costs nothing beyond one area test
/// per triangle when there is no zero-area triangle.
pub fn resolve_zero_area_triangles(
    positions: &[Vec3],
    triangles: &mut Vec<[u32; 3]>,
    diagonal: f64,
) -> ZeroAreaResolution {
    let mut out = ZeroAreaResolution::default();
    let eps = ZERO_AREA_RELATIVE_HEIGHT * diagonal;
    if !triangles.par_iter().any(|t| is_zero_area(positions, t, diagonal)) {
        return out;
    }
    collapse_needles(positions, triangles, eps, &mut out);
    for _ in 0..MAX_FLIP_ROUNDS {
        let flipped = flip_caps(positions, triangles, diagonal);
        out.n_cap_edges_flipped += flipped;
        if flipped == 0 {
            break;
        }
    }
    let before = triangles.len();
    triangles.retain(|t| !is_zero_area(positions, t, diagonal));
    out.n_removed = before - triangles.len();
    out
}

/// Representative of `v` in the union–find forest `parent` (path halving).
fn find(parent: &mut [u32], mut v: u32) -> u32 {
    while parent[v as usize] != v {
        parent[v as usize] = parent[parent[v as usize] as usize];
        v = parent[v as usize];
    }
    v
}

/// Merges the ends of every vanishing edge of a zero-area triangle (the
/// smaller index survives, so the result does not depend on the order) and
/// drops the triangles that then repeat a vertex.
fn collapse_needles(positions: &[Vec3], triangles: &mut Vec<[u32; 3]>, eps: f64, out: &mut ZeroAreaResolution) {
    let mut parent: Option<Vec<u32>> = None;
    for t in triangles.iter() {
        let (twice_area, lengths) = shape(positions, t);
        let longest = lengths[0].max(lengths[1]).max(lengths[2]);
        if twice_area > eps * longest {
            continue;
        }
        for k in 0..3 {
            if lengths[k] > eps {
                continue;
            }
            let p = parent.get_or_insert_with(|| (0..positions.len() as u32).collect());
            let (x, y) = (find(p, t[(k + 1) % 3]), find(p, t[(k + 2) % 3]));
            if x != y {
                p[x.max(y) as usize] = x.min(y);
                out.n_needle_edges_collapsed += 1;
            }
        }
    }
    let Some(mut parent) = parent else { return };
    for t in triangles.iter_mut() {
        *t = t.map(|v| find(&mut parent, v));
    }
    let before = triangles.len();
    triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0]);
    out.n_triangles_removed_by_collapse = before - triangles.len();
}

/// Undirected edge key.
fn edge(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Triangles per undirected edge.
type EdgeMap = HashMap<(u32, u32), Vec<u32>, foldhash::fast::FixedState>;

/// Adds (`add`) or removes triangle `f` with corners `t` to or from the
/// entries of its three edges.
fn link(map: &mut EdgeMap, f: u32, t: &[u32; 3], add: bool) {
    for k in 0..3 {
        let list = map.entry(edge(t[k], t[(k + 1) % 3])).or_default();
        if add {
            list.push(f);
        } else {
            list.retain(|&g| g != f);
        }
    }
}

/// One round of long-edge flips over the current zero-area caps; returns
/// how many were flipped.
fn flip_caps(positions: &[Vec3], triangles: &mut [[u32; 3]], diagonal: f64) -> usize {
    let caps: Vec<u32> =
        (0..triangles.len() as u32).filter(|&f| is_zero_area(positions, &triangles[f as usize], diagonal)).collect();
    if caps.is_empty() {
        return 0;
    }
    let mut map = EdgeMap::with_capacity_and_hasher(triangles.len() * 3 / 2, foldhash::fast::FixedState::default());
    for (f, t) in triangles.iter().enumerate() {
        link(&mut map, f as u32, t, true);
    }
    let mut n = 0;
    for f in caps {
        let t = triangles[f as usize];
        if !is_zero_area(positions, &t, diagonal) {
            continue; // an earlier flip changed it
        }
        let (_, lengths) = shape(positions, &t);
        // Corner `k` is the middle vertex: it is opposite the longest edge.
        let k = (0..3).max_by(|&i, &j| lengths[i].total_cmp(&lengths[j])).unwrap_or(0);
        let (m, a, b) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        let others: Vec<u32> = map.get(&edge(a, b)).into_iter().flatten().copied().filter(|&g| g != f).collect();
        let [g] = others[..] else { continue }; // boundary or non-manifold long edge
        // Removing a cap opens a hole only when both short edges have a
        // triangle on their other side; otherwise it is simply removed.
        let shared = |x: u32, y: u32| map.get(&edge(x, y)).is_some_and(|l| l.iter().any(|&h| h != f));
        if !(shared(m, a) && shared(m, b)) {
            continue;
        }
        let u = triangles[g as usize];
        let Some(&d) = u.iter().find(|&&v| v != a && v != b) else { continue };
        if d == m || map.get(&edge(m, d)).is_some_and(|l| !l.is_empty()) {
            continue; // the new edge exists already: flipping would make it non-manifold
        }
        // Cap: b → d; neighbour: a → m (each keeps its orientation).
        let (t2, u2) = (t.map(|v| if v == b { d } else { v }), u.map(|v| if v == a { m } else { v }));
        link(&mut map, f, &t, false);
        link(&mut map, g, &u, false);
        link(&mut map, f, &t2, true);
        link(&mut map, g, &u2, true);
        triangles[f as usize] = t2;
        triangles[g as usize] = u2;
        n += 1;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every directed edge is matched by exactly one opposite edge.
    fn closed_and_consistent(t: &[[u32; 3]]) -> bool {
        let mut e = std::collections::BTreeMap::<(u32, u32), i32>::new();
        for t in t {
            for k in 0..3 {
                *e.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        e.values().all(|&c| c == 1) && e.keys().all(|&(a, b)| e.contains_key(&(b, a)))
    }

    #[test]
    fn a_cap_in_a_closed_surface_is_flipped_away() {
        // An outward tetrahedron whose face (0, 1, 3) is split at the
        // midpoint 4 of edge 01; the cap (0, 1, 4) closes the T-junction.
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.5, 0.0, 0.0),
        ];
        let mut tris = vec![[0, 2, 1], [0, 4, 3], [4, 1, 3], [1, 2, 3], [0, 3, 2], [0, 1, 4]];
        assert!(closed_and_consistent(&tris));
        let diagonal = 3f64.sqrt();
        let r = resolve_zero_area_triangles(&positions, &mut tris, diagonal);
        assert_eq!(r, ZeroAreaResolution { n_cap_edges_flipped: 1, ..Default::default() });
        assert_eq!(tris.len(), 6);
        assert!(closed_and_consistent(&tris), "{tris:?}");
        assert!(tris.iter().all(|t| !is_zero_area(&positions, t, diagonal)));
    }

    #[test]
    fn a_needle_is_collapsed_with_its_neighbour_across_the_vanishing_edge() {
        // The same tetrahedron with vertex 0 doubled as 4 (1e-14 away): the
        // fan of 0 is split between 0 and 4, and two needles fill the seams.
        let mut positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        positions.push(positions[0] + Vec3::new(1e-14, 0.0, 0.0));
        // Fan of 0: (0,2,1), (0,1,3), (0,3,2); (0,2,1) uses 4 instead.
        let mut tris = vec![[4, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [4, 1, 0], [0, 2, 4]];
        assert!(closed_and_consistent(&tris), "{tris:?}");
        let r = resolve_zero_area_triangles(&positions, &mut tris, 3f64.sqrt());
        assert_eq!(r.n_needle_edges_collapsed, 1);
        assert_eq!(r.n_triangles_removed_by_collapse, 2);
        assert_eq!((r.n_cap_edges_flipped, r.n_removed), (0, 0));
        let mut sorted: Vec<[u32; 3]> = tris.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, vec![[0, 1, 3], [0, 2, 1], [0, 3, 2], [1, 2, 3]]);
        assert!(closed_and_consistent(&tris));
    }

    #[test]
    fn a_cap_on_the_boundary_is_removed_and_counted() {
        let positions = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.5, 0.0, 0.0)];
        let mut tris = vec![[0, 1, 2]];
        let r = resolve_zero_area_triangles(&positions, &mut tris, 1.0);
        assert_eq!(r, ZeroAreaResolution { n_removed: 1, ..Default::default() });
        assert!(tris.is_empty());
    }
}
