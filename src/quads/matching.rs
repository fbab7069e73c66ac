//! Completion of the greedy pairing to a maximum matching of the candidate
//! pairs, by augmenting paths on local windows (research quad-meshing §1.2,
//! §2.1, §5.1 step 4).
//!
//! A triangle greedy left free is the root of a search for an augmenting
//! path: an alternating path (free edge, matched edge, …, free edge) from it
//! to another free triangle; flipping the path pairs both ends and keeps
//! every other triangle paired. The dual graph is not bipartite (odd cycles
//! of triangles), so the search is Edmonds' blossom search (Edmonds 1965;
//! the e-maxx formulation: BFS over outer vertices, odd cycles contracted to
//! their base). By Berge's theorem a matching is maximum exactly when no
//! augmenting path exists, and a vertex from which none exists stays free in
//! every later augmentation, so one search per root suffices.
//!
//! The search runs on a window: the dual k-ring of the root inside its model
//! face (with the partners of every triangle in it, so no pair is cut), the
//! ring doubling (4, 8, 16, …) until a path is found, the window is the
//! root's whole connected part of the face (no path exists: the face needs
//! subdivision) or it holds [`MAX_WINDOW`] triangles ([`SMALL_WINDOW`] once
//! two roots of the face failed at that size). A root whose windows
//! hold no path stays free for the strips ([`super::strip`]) and the search
//! goes on with the face's other roots, up to [`MAX_FAILED_ROOTS_PER_FACE`]
//! failures (beyond that the face is left to subdivision unsearched).
//! Neighbours are tried cheapest pair first. Everything is sequential in
//! index order, so the result is deterministic.

use std::collections::VecDeque;

use super::pairing::{DualGraph, NONE};
use crate::progress::{Cancelled, Progress};

/// First ring radius of a window (in dual edges).
const FIRST_RADIUS: u32 = 4;

/// Largest window searched (triangles). As the matching fills up, the
/// free triangles left are far apart: on a 100k-triangle sphere the last
/// roots needed windows beyond 4096 triangles, and the strips that joined
/// them instead were long and often invalid (decisions, session 15). A face
/// this big with a triangle no window can pair is not searched whole, as
/// an unbounded search would cost `O(n²)`.
pub const MAX_WINDOW: usize = 65536;

/// Window cap of a face's roots once [`MAX_LARGE_FAILURES_PER_FACE`] of its
/// roots found no path in windows of [`MAX_WINDOW`]: a failed search of
/// that size costs about a second (200k-triangle sphere), so a face with
/// many roots nothing can pair does not pay it per root.
pub const SMALL_WINDOW: usize = 4096;

/// Failed searches in windows of [`MAX_WINDOW`] per face before its later
/// roots are searched in windows of [`SMALL_WINDOW`] only.
pub const MAX_LARGE_FAILURES_PER_FACE: usize = 2;

/// Roots of one model face whose windows hold no augmenting path before the
/// face's remaining roots are left unsearched: a few such roots are the
/// strips' work (a face of 100k triangles had one), many mean the face will
/// be subdivided anyway, and each costs a full window search.
pub const MAX_FAILED_ROOTS_PER_FACE: usize = 64;

/// What the completion did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Completion {
    /// Windows searched (each growth of a window counts).
    pub n_windows: usize,
    /// Augmenting paths applied.
    pub n_augmentations: usize,
    /// The roots with no augmenting path within their windows.
    pub unmatched: Vec<u32>,
}

/// Completes `partner` (the partner of each triangle or [`NONE`]) by
/// augmenting paths over the pairs of `graph`, roots taken in index order
/// among the free triangles of the model faces (`model_face_per_triangle`)
/// that `searched` accepts. Once [`MAX_FAILED_ROOTS_PER_FACE`] roots of a
/// model face have failed, its later roots are not searched.
///
/// # Errors
/// [`Cancelled`] when `progress` is cancelled.
pub fn complete_matching(
    graph: &DualGraph,
    model_face_per_triangle: &[u32],
    partner: &mut [u32],
    searched: &dyn Fn(u32) -> bool,
    progress: &Progress,
) -> Result<Completion, Cancelled> {
    let n_faces = model_face_per_triangle.iter().map(|&f| f as usize + 1).max().unwrap_or(0);
    let mut failures_per_face = vec![0usize; n_faces];
    let roots: Vec<u32> = (0..partner.len() as u32)
        .filter(|&t| partner[t as usize] == NONE && searched(model_face_per_triangle[t as usize]))
        .collect();
    let mut out = Completion::default();
    let mut window = Window::new(partner.len());
    for (i, &root) in roots.iter().enumerate() {
        if i % 64 == 0 {
            progress.check()?;
            progress.set(i as f64 / roots.len() as f64);
        }
        let face = model_face_per_triangle[root as usize];
        let failures = failures_per_face[face as usize];
        if partner[root as usize] != NONE || failures >= MAX_FAILED_ROOTS_PER_FACE {
            continue;
        }
        let cap = if failures < MAX_LARGE_FAILURES_PER_FACE { MAX_WINDOW } else { SMALL_WINDOW };
        let mut radius = FIRST_RADIUS;
        loop {
            let whole = window.gather(graph, partner, root, radius, cap);
            out.n_windows += 1;
            if window.augment(graph, partner, root) {
                out.n_augmentations += 1;
                break;
            }
            if whole || window.members.len() >= cap {
                out.unmatched.push(root);
                failures_per_face[face as usize] += 1;
                break;
            }
            radius = radius.saturating_mul(2);
        }
        window.clear();
    }
    Ok(out)
}

/// A window of the dual graph: its triangles and their local indices.
struct Window {
    /// Triangles in the window, in the order they were reached.
    members: Vec<u32>,
    /// Local index of each triangle of the mesh ([`NONE`] outside).
    local: Vec<u32>,
}

impl Window {
    /// An empty window over `n` triangles.
    fn new(n: usize) -> Window {
        Window { members: Vec::new(), local: vec![NONE; n] }
    }

    /// Empties the window.
    fn clear(&mut self) {
        for &t in &self.members {
            self.local[t as usize] = NONE;
        }
        self.members.clear();
    }

    /// Adds `t` (and its partner) if not yet in.
    fn insert(&mut self, t: u32, partner: &[u32]) {
        for u in [t, partner[t as usize]] {
            if u != NONE && self.local[u as usize] == NONE {
                self.local[u as usize] = self.members.len() as u32;
                self.members.push(u);
            }
        }
    }

    /// Fills the window with the dual `radius`-ring of `root`, capped at
    /// `cap` triangles. Returns true when the ring reached the
    /// whole connected part of the root's face.
    fn gather(&mut self, graph: &DualGraph, partner: &[u32], root: u32, radius: u32, cap: usize) -> bool {
        self.clear();
        self.insert(root, partner);
        let mut frontier = vec![root];
        let mut ring = 0;
        while !frontier.is_empty() {
            if ring == radius || self.members.len() >= cap {
                return false;
            }
            // Partners count as reached: grow from them too.
            let mut next = Vec::new();
            for &t in &frontier {
                for u in [t, partner[t as usize]] {
                    if u == NONE {
                        continue;
                    }
                    for &v in graph.neighbours_per_triangle[u as usize].iter().filter(|&&v| v != NONE) {
                        if self.local[v as usize] == NONE {
                            self.insert(v, partner);
                            next.push(v);
                        }
                    }
                }
            }
            frontier = next;
            ring += 1;
        }
        true
    }

    /// Searches the window for an augmenting path from `root` and applies
    /// it to `partner`. Returns true when one was found.
    fn augment(&self, graph: &DualGraph, partner: &mut [u32], root: u32) -> bool {
        let adjacency: Vec<[u32; 3]> = self
            .members
            .iter()
            .map(|&t| {
                let mut slots = [NONE; 3];
                let pairs = graph.pairs_per_triangle[t as usize].iter().take_while(|&&p| p != NONE);
                let others = pairs.map(|&p| {
                    let [a, b] = graph.pairs[p as usize].triangles;
                    let other = if a == t { b } else { a };
                    self.local[other as usize]
                });
                for (slot, u) in slots.iter_mut().zip(others.filter(|&u| u != NONE)) {
                    *slot = u;
                }
                slots
            })
            .collect();
        let mate: Vec<u32> = self
            .members
            .iter()
            .map(|&t| match partner[t as usize] {
                NONE => NONE,
                u => self.local[u as usize],
            })
            .collect();
        let mut search = BlossomSearch::new(&adjacency, mate);
        let local_root = self.local[root as usize];
        let Some(end) = search.augmenting_path_end(local_root) else {
            return false;
        };
        search.augment(end);
        for (i, &m) in search.mate.iter().enumerate() {
            if m != NONE {
                partner[self.members[i] as usize] = self.members[m as usize];
            }
        }
        true
    }
}

/// Edmonds' blossom search for one augmenting path in a graph of degree ≤ 3
/// (module doc).
pub struct BlossomSearch<'a> {
    adjacency: &'a [[u32; 3]],
    /// The matching: mate of each vertex or [`NONE`].
    pub mate: Vec<u32>,
    parent: Vec<u32>,
    base: Vec<u32>,
    used: Vec<bool>,
    /// Vertices the search has reached (outer or inner), each once: the
    /// only ones a blossom contraction can relabel.
    reached: Vec<u32>,
    /// Marks of the current blossom and of the current base search are
    /// stamps (equal to `stamp`), so no mark array is cleared per blossom.
    in_blossom: Vec<u32>,
    seen: Vec<u32>,
    stamp: u32,
    queue: VecDeque<u32>,
}

impl<'a> BlossomSearch<'a> {
    /// A search over `adjacency` ([`NONE`]-padded) from the matching `mate`.
    pub fn new(adjacency: &'a [[u32; 3]], mate: Vec<u32>) -> BlossomSearch<'a> {
        let n = adjacency.len();
        BlossomSearch {
            adjacency,
            mate,
            parent: vec![NONE; n],
            base: (0..n as u32).collect(),
            used: vec![false; n],
            reached: Vec::new(),
            in_blossom: vec![0; n],
            seen: vec![0; n],
            stamp: 0,
            queue: VecDeque::new(),
        }
    }

    /// The free vertex an augmenting path from the free vertex `root` ends
    /// at, the path stored in `parent` / `mate`; `None` when there is none.
    ///
    /// A contraction relabels only the reached vertices whose base is in
    /// the blossom, in increasing index order (the order of a scan of all
    /// vertices, so the path found is the same), and marks are stamps:
    /// the search costs `O(reached · blossoms)` instead of
    /// `O(window · blossoms)`, which on windows of 65536 triangles with
    /// few reached was most of the matching's time (`docs/decisions.md`).
    pub fn augmenting_path_end(&mut self, root: u32) -> Option<u32> {
        self.used.fill(false);
        self.parent.fill(NONE);
        for (i, b) in self.base.iter_mut().enumerate() {
            *b = i as u32;
        }
        self.reached.clear();
        self.used[root as usize] = true;
        self.reached.push(root);
        self.queue.clear();
        self.queue.push_back(root);
        let mut relabel = Vec::new();
        while let Some(v) = self.queue.pop_front() {
            for &to in self.adjacency[v as usize].iter().filter(|&&to| to != NONE) {
                if self.base[v as usize] == self.base[to as usize] || self.mate[v as usize] == to {
                    continue;
                }
                let to_is_outer = to == root
                    || (self.mate[to as usize] != NONE && self.parent[self.mate[to as usize] as usize] != NONE);
                if to_is_outer {
                    let base = self.lowest_common_base(v, to);
                    self.next_stamp();
                    self.mark_path(v, base, to);
                    self.mark_path(to, base, v);
                    relabel.clear();
                    relabel.extend(
                        self.reached
                            .iter()
                            .copied()
                            .filter(|&i| self.in_blossom[self.base[i as usize] as usize] == self.stamp),
                    );
                    relabel.sort_unstable();
                    for &i in &relabel {
                        self.base[i as usize] = base;
                        if !self.used[i as usize] {
                            self.used[i as usize] = true;
                            self.queue.push_back(i);
                        }
                    }
                } else if self.parent[to as usize] == NONE {
                    self.parent[to as usize] = v;
                    self.reached.push(to);
                    let m = self.mate[to as usize];
                    if m == NONE {
                        return Some(to);
                    }
                    self.used[m as usize] = true;
                    self.reached.push(m);
                    self.queue.push_back(m);
                }
            }
        }
        None
    }

    /// A fresh stamp for the marks (cleared for real once in 2³² uses).
    fn next_stamp(&mut self) {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.in_blossom.fill(0);
            self.seen.fill(0);
            self.stamp = 1;
        }
    }

    /// The base of the blossom closed by the edge `a`–`b`: the first common
    /// base on their alternating paths to the root.
    fn lowest_common_base(&mut self, a: u32, b: u32) -> u32 {
        self.next_stamp();
        let mut a = a;
        loop {
            a = self.base[a as usize];
            self.seen[a as usize] = self.stamp;
            let m = self.mate[a as usize];
            if m == NONE {
                break;
            }
            a = self.parent[m as usize];
        }
        let mut b = b;
        loop {
            b = self.base[b as usize];
            if self.seen[b as usize] == self.stamp {
                return b;
            }
            b = self.parent[self.mate[b as usize] as usize];
        }
    }

    /// Marks the blossom path from `v` down to `base`, pointing the inner
    /// vertices' parents across the closing edge (towards `child`).
    fn mark_path(&mut self, mut v: u32, base: u32, mut child: u32) {
        while self.base[v as usize] != base {
            let m = self.mate[v as usize];
            self.in_blossom[self.base[v as usize] as usize] = self.stamp;
            self.in_blossom[self.base[m as usize] as usize] = self.stamp;
            self.parent[v as usize] = child;
            child = m;
            v = self.parent[m as usize];
        }
    }

    /// Flips the augmenting path ending at the free vertex `end`.
    pub fn augment(&mut self, end: u32) {
        let mut v = end;
        while v != NONE {
            let pv = self.parent[v as usize];
            let next = self.mate[pv as usize];
            self.mate[v as usize] = pv;
            self.mate[pv as usize] = v;
            v = next;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Matches greedily then augments from every free vertex.
    fn maximum_matching(adjacency: &[[u32; 3]]) -> Vec<u32> {
        let mut mate = vec![NONE; adjacency.len()];
        for v in 0..adjacency.len() {
            let mut search = BlossomSearch::new(adjacency, mate.clone());
            if mate[v] == NONE
                && let Some(end) = search.augmenting_path_end(v as u32)
            {
                search.augment(end);
                mate = search.mate;
            }
        }
        mate
    }

    fn n_matched(mate: &[u32]) -> usize {
        mate.iter().filter(|&&m| m != NONE).count()
    }

    #[test]
    fn an_odd_cycle_with_a_tail_needs_a_blossom() {
        // Triangle 0-1-2 with tail 2-3 and 0-4, matching {1-2} given: the
        // only augmenting path from 4 goes 4-0-1-2-3 through the blossom.
        let adjacency = [[1, 2, 4], [0, 2, NONE], [0, 1, 3], [2, NONE, NONE], [0, NONE, NONE]];
        let mut mate = vec![NONE; 5];
        mate[1] = 2;
        mate[2] = 1;
        let mut search = BlossomSearch::new(&adjacency, mate);
        let end = search.augmenting_path_end(4).expect("an augmenting path exists");
        search.augment(end);
        assert_eq!(n_matched(&search.mate), 4);
        for v in 0..5 {
            let m = search.mate[v];
            if m != NONE {
                assert_eq!(search.mate[m as usize], v as u32);
                assert!(adjacency[v].contains(&m));
            }
        }
    }

    #[test]
    fn the_petersen_graph_has_a_perfect_matching() {
        // Outer 5-cycle 0..4, inner pentagram 5..9, spokes i — i+5.
        let mut adjacency = [[NONE; 3]; 10];
        for i in 0..5u32 {
            adjacency[i as usize] = [(i + 1) % 5, (i + 4) % 5, i + 5];
            adjacency[(i + 5) as usize] = [(i + 2) % 5 + 5, (i + 3) % 5 + 5, i];
        }
        assert_eq!(n_matched(&maximum_matching(&adjacency)), 10);
    }

    #[test]
    fn two_triangles_joined_by_an_edge_leave_nothing_free_and_a_star_leaves_two() {
        let two_triangles = [[1, 2, NONE], [0, 2, NONE], [0, 1, 3], [2, 4, 5], [3, 5, NONE], [3, 4, NONE]];
        assert_eq!(n_matched(&maximum_matching(&two_triangles)), 6);
        let star = [[1, 2, 3], [0, NONE, NONE], [0, NONE, NONE], [0, NONE, NONE]];
        assert_eq!(n_matched(&maximum_matching(&star)), 2);
    }
}
