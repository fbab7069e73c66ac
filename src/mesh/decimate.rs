//! Coarsening of a triangle surface by half-edge collapses, for multilevel
//! solvers (the crossfield stage solves its large-ε stages on the coarse copy).
//!
//! A half-edge collapse `u → v` removes vertex `u`, deletes the two triangles
//! on edge `uv` and reconnects the other triangles of `u` to `v`, which keeps
//! its position; the coarse vertices are therefore a subset of the input
//! vertices and triangle orientation is inherited (`u` is replaced in place).
//!
//! **Cost.** Each vertex carries a Garland–Heckbert quadric (Garland &
//! Heckbert 1997, "Surface simplification using quadric error metrics"):
//! for a triangle with unit normal `n` through point `p`, the plane
//! `(n, d = −n·p)` gives `Q = [n; d][n; d]ᵀ` (a symmetric 4×4, unweighted, so
//! `Q(x) = (n·x + d)²` is a squared length). A vertex's quadric is the sum
//! over its triangles; on collapse `Q_v ← Q_u + Q_v`. The cost of `u → v` is
//!
//! ```text
//! cost(u → v) = |p_u − p_v|² + (Q_u + Q_v)(p_v)
//! ```
//!
//! On smooth regions the length term dominates, so the shortest edges go
//! first and the coarsening is roughly uniform; the quadric term grows where
//! collapsing would cut across curvature or a sharp crease.
//!
//! **Validity** of `u → v` (checked when the collapse is taken):
//! - `u` is not locked: no endpoint of a locked, boundary or non-manifold
//!   edge, and no non-manifold vertex. Locked vertices never move, so every
//!   locked edge (and every boundary edge) survives unchanged and the number
//!   of boundary loops is kept;
//! - link condition (Dey, Edelsbrunner, Guha, Nekhayev 1999, "Topology
//!   preserving edge contraction"): `u` is interior, so `uv` has two
//!   triangles, and the common neighbours of `u` and `v` must be exactly
//!   their two apexes; together with "no apex has only three triangles"
//!   (which excludes collapsing a tetrahedron) this keeps the surface a
//!   manifold of the same Euler characteristic `χ = V − E + F`
//!   (one vertex, three edges and two triangles go: `Δχ = −1 + 3 − 2 = 0`);
//! - no moved triangle flips: `n_new · n_old > 0.2 |n_new| |n_old|`;
//! - shape: the worst moved triangle keeps quality
//!   `q = 4√3·A / Σℓ² ≥ min(0.2, worst q of u's triangles before)`
//!   (`q = 1` equilateral, `0` degenerate; the mesh feeds Crouzeix–Raviart
//!   elements);
//! - `v` gets at most 12 neighbours.
//!
//! **Queue.** Each unlocked vertex `u` holds one candidate, its cheapest
//! neighbour `v`, in a binary heap with lazy deletion (a per-vertex stamp
//! invalidates older entries). Validity is checked only when an entry is
//! popped; if the cheapest target is invalid, the cheapest valid one is
//! queued instead. After a collapse the candidates of `v` and its
//! neighbours are recomputed. Cost `O(n log n)` for `n` collapses.

use super::components::nonmanifold_vertices;
use super::{EdgeId, MeshError, Topology, TriMesh, VertexId};
use crate::geom::{Vec3, triangle_area_vector, triangle_quality};

/// The coarse mesh and where its vertices come from.
#[derive(Debug, Clone, PartialEq)]
pub struct Decimated {
    /// The coarse mesh (compacted: only surviving vertices, renumbered).
    pub mesh: TriMesh,
    /// Input vertex id of each coarse vertex.
    pub fine_vertex: Vec<VertexId>,
}

/// Quality `4√3·A/Σℓ²` below which a collapse may not push a triangle
/// (unless the triangles around `u` were already worse).
const MIN_QUALITY: f64 = 0.2;
/// Smallest cosine between a moved triangle's old and new normals.
const MIN_NORMAL_COS: f64 = 0.2;
/// Largest number of neighbours the kept vertex may end up with.
const MAX_VALENCE: usize = 12;
/// "No vertex" marker in `u32` slots.
const NONE: u32 = u32::MAX;

/// Collapse edges of `mesh` until at most `target_faces` triangles remain (or no valid collapse is left).
/// `locked_edges`: one flag per edge of `topo`; their endpoints are never removed (boundary edges are treated as locked too).
/// `max_edge_length`: no collapse creates an edge longer than this
/// (`f64::INFINITY` for none). Locked curves keep their fine vertices, so
/// when they hold many of them the face target alone would over-coarsen the
/// interior to make up for them (far coarser than the rest of the level:
/// `docs/decisions.md`); the length bound keeps the coarsening uniform.
///
/// The input must be a valid mesh with `topo` its topology; it should be
/// manifold and consistently oriented (non-manifold vertices and edges are
/// locked, so they are kept as they are).
///
/// # Errors
/// [`MeshError::LengthMismatch`] when `locked_edges` does not have one flag
/// per edge, [`MeshError::Inconsistent`] when `topo` is not the topology of
/// a mesh of this size.
pub fn decimate(
    mesh: &TriMesh,
    topo: &Topology,
    locked_edges: &[bool],
    target_faces: usize,
    max_edge_length: f64,
) -> Result<Decimated, MeshError> {
    check_inputs(mesh, topo, locked_edges)?;
    let locked = locked_vertices(mesh, topo, locked_edges);
    let mut collapser = Collapser::new(mesh, topo, locked);
    collapser.max_edge_sq = max_edge_length * max_edge_length;
    collapser.run(target_faces);
    let out = collapser.compact();
    debug_assert!(out.mesh.validate().is_ok());
    Ok(out)
}

/// Reject inputs whose sizes disagree, before anything is indexed with them.
fn check_inputs(mesh: &TriMesh, topo: &Topology, locked_edges: &[bool]) -> Result<(), MeshError> {
    if topo.face_edges.len() != mesh.n_faces() {
        return Err(MeshError::Inconsistent(format!(
            "topology has {} triangles, the mesh {}",
            topo.face_edges.len(),
            mesh.n_faces()
        )));
    }
    if locked_edges.len() != topo.n_edges() {
        return Err(MeshError::LengthMismatch {
            what: "locked_edges",
            per: "edge",
            expected: topo.n_edges(),
            found: locked_edges.len(),
        });
    }
    Ok(())
}

/// Vertices that must not be collapsed away: endpoints of locked, boundary
/// and non-manifold edges, and non-manifold vertices (several fans), where
/// the link condition of a manifold would not protect the topology.
fn locked_vertices(mesh: &TriMesh, topo: &Topology, locked_edges: &[bool]) -> Vec<bool> {
    let mut locked = vec![false; mesh.n_vertices()];
    for (e, &[a, b]) in topo.edges.iter().enumerate() {
        if locked_edges[e] || topo.edge_valence(EdgeId::new(e)) != 2 {
            locked[a.idx()] = true;
            locked[b.idx()] = true;
        }
    }
    for v in nonmanifold_vertices(mesh, topo) {
        locked[v.idx()] = true;
    }
    locked
}

/// A symmetric 4×4 plane quadric, upper triangle row by row:
/// `[a00 a01 a02 b0, a11 a12 b1, a22 b2, c]`, so `Q(x) = xᵀAx + 2b·x + c`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Quadric([f64; 10]);

impl Quadric {
    /// `(n·x + d)²` for the plane with unit normal `n` and offset `d`.
    fn of_plane(n: &Vec3, d: f64) -> Self {
        let (x, y, z) = (n.x, n.y, n.z);
        Self([x * x, x * y, x * z, x * d, y * y, y * z, y * d, z * z, z * d, d * d])
    }

    /// The sum of two quadrics (planes of both).
    fn add(&self, other: &Self) -> Self {
        let mut q = *self;
        for (a, b) in q.0.iter_mut().zip(other.0.iter()) {
            *a += b;
        }
        q
    }

    /// The sum of squared plane distances of point `p`.
    fn eval(&self, p: &Vec3) -> f64 {
        let q = &self.0;
        let (x, y, z) = (p.x, p.y, p.z);
        q[0] * x * x
            + q[4] * y * y
            + q[7] * z * z
            + 2.0 * (q[1] * x * y + q[2] * x * z + q[5] * y * z)
            + 2.0 * (q[3] * x + q[6] * y + q[8] * z)
            + q[9]
    }
}

/// A queued collapse of `from` into its queued target, valid while `stamp`
/// is `from`'s stamp. 16 bytes, ordered by (cost, from, stamp): `cost_bits`
/// are the bits of a finite non-negative `f64`, whose integer order is the
/// numeric order. Ties go to the smaller ids, so the result depends on
/// nothing but the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Candidate {
    cost_bits: u64,
    from: u32,
    stamp: u32,
}

impl Candidate {
    /// The heap entry of `from`'s candidate with this cost and stamp.
    fn new(cost: f64, from: usize, stamp: u32) -> Self {
        let cost = if cost.is_finite() { cost.max(0.0) } else { f64::MAX };
        Self { cost_bits: cost.to_bits(), from: from as u32, stamp }
    }
}

/// A 4-ary min-heap of candidates. Why not `BinaryHeap`: on large meshes
/// popping was a large part of the run (cache misses down a deep binary
/// tree, `docs/decisions.md`); four children per node halve the depth and
/// sit next to each other in memory.
#[derive(Debug, Default)]
struct MinHeap4 {
    items: Vec<Candidate>,
}

impl MinHeap4 {
    /// A heap of `items`, built bottom-up in `O(n)`.
    fn from_vec(items: Vec<Candidate>) -> Self {
        let mut heap = Self { items };
        for i in (0..heap.items.len().div_ceil(4)).rev() {
            heap.sift_down(i);
        }
        heap
    }

    /// Number of entries (live and stale).
    #[cfg(test)]
    fn len(&self) -> usize {
        self.items.len()
    }

    /// Insert a candidate.
    fn push(&mut self, c: Candidate) {
        self.items.push(c);
        self.sift_up(self.items.len() - 1);
    }

    /// Remove and return the smallest candidate.
    fn pop(&mut self) -> Option<Candidate> {
        let last = self.items.pop()?;
        if self.items.is_empty() {
            return Some(last);
        }
        let top = std::mem::replace(&mut self.items[0], last);
        self.sift_down(0);
        Some(top)
    }

    /// Move the entry at `i` up until its parent is not larger.
    fn sift_up(&mut self, mut i: usize) {
        let x = self.items[i];
        while i > 0 {
            let parent = (i - 1) / 4;
            if self.items[parent] <= x {
                break;
            }
            self.items[i] = self.items[parent];
            i = parent;
        }
        self.items[i] = x;
    }

    /// Move the entry at `i` down until no child is smaller.
    fn sift_down(&mut self, mut i: usize) {
        let n = self.items.len();
        let x = self.items[i];
        loop {
            let first = 4 * i + 1;
            if first >= n {
                break;
            }
            let mut m = first;
            for j in first + 1..(first + 4).min(n) {
                if self.items[j] < self.items[m] {
                    m = j;
                }
            }
            if self.items[m] >= x {
                break;
            }
            self.items[i] = self.items[m];
            i = m;
        }
        self.items[i] = x;
    }
}

/// What a vertex has in the queue: target (`NONE`: nothing), cost, and
/// whether it is a fallback (not the cheapest target).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Queued {
    target: u32,
    cost: f64,
    fallback: bool,
}

impl Queued {
    /// Nothing queued.
    const EMPTY: Self = Self { target: NONE, cost: 0.0, fallback: false };
}

/// The mutable state of the decimation: triangles, incidences, quadrics, queue.
struct Collapser<'a> {
    positions: &'a [Vec3],
    triangles: Vec<[u32; 3]>,
    face_alive: Vec<bool>,
    n_faces_alive: usize,
    faces_per_vertex: Vec<Vec<u32>>,
    locked: Vec<bool>,
    removed: Vec<bool>,
    quadric_per_vertex: Vec<Quadric>,
    /// `Q_v(p_v)`, cached: it changes only when `v` receives a collapse.
    own_error_per_vertex: Vec<f64>,
    /// Bumped whenever a vertex's queued candidate is replaced.
    stamp_per_vertex: Vec<u32>,
    /// The live queued candidate of each vertex.
    queued_per_vertex: Vec<Queued>,
    heap: MinHeap4,
    /// Scratch marks for neighbourhood tests, compared against `mark_stamp`.
    mark: Vec<u32>,
    mark_stamp: u32,
    /// Scratch list of (cost, target) or touched vertices.
    scratch_costs: Vec<(f64, u32)>,
    scratch_vertices: Vec<u32>,
    /// Squared bound on the length of the edges a collapse creates.
    max_edge_sq: f64,
}

impl<'a> Collapser<'a> {
    /// Incidences and quadrics of the input; nothing queued yet.
    fn new(mesh: &'a TriMesh, topo: &Topology, locked: Vec<bool>) -> Self {
        let n_v = mesh.n_vertices();
        let triangles: Vec<[u32; 3]> = mesh.triangles.iter().map(|t| t.map(|v| v.0)).collect();
        let quadric_per_face: Vec<Quadric> = triangles.iter().map(|t| face_quadric(&mesh.positions, t)).collect();
        let mut faces_per_vertex = Vec::with_capacity(n_v);
        let mut quadric_per_vertex = Vec::with_capacity(n_v);
        let mut own_error_per_vertex = Vec::with_capacity(n_v);
        for v in 0..n_v {
            let faces = topo.vertex_faces(VertexId::new(v));
            let q = faces.iter().fold(Quadric::default(), |q, f| q.add(&quadric_per_face[f.idx()]));
            faces_per_vertex.push(faces.iter().map(|f| f.0).collect::<Vec<u32>>());
            quadric_per_vertex.push(q);
            own_error_per_vertex.push(q.eval(&mesh.positions[v]));
        }
        Self {
            positions: &mesh.positions,
            n_faces_alive: triangles.len(),
            face_alive: vec![true; triangles.len()],
            triangles,
            faces_per_vertex,
            locked,
            removed: vec![false; n_v],
            quadric_per_vertex,
            own_error_per_vertex,
            stamp_per_vertex: vec![0; n_v],
            queued_per_vertex: vec![Queued::EMPTY; n_v],
            heap: MinHeap4::default(),
            mark: vec![0; n_v],
            mark_stamp: 0,
            scratch_costs: Vec::new(),
            scratch_vertices: Vec::new(),
            max_edge_sq: f64::INFINITY,
        }
    }

    /// Collapse the cheapest valid edges until `target_faces` is reached or
    /// the queue runs dry.
    fn run(&mut self, target_faces: usize) {
        self.queue_all();
        while self.n_faces_alive > target_faces {
            let Some(c) = self.heap.pop() else {
                break;
            };
            let u = c.from as usize;
            if self.removed[u] || self.stamp_per_vertex[u] != c.stamp {
                continue;
            }
            let Queued { target, fallback, .. } = std::mem::replace(&mut self.queued_per_vertex[u], Queued::EMPTY);
            let v = target as usize;
            if self.collapse_is_valid(u, v) {
                self.collapse(u, v);
                self.requeue_around(u, v);
            } else if !fallback {
                self.queue_cheapest_valid(u);
            }
        }
    }

    /// The initial candidate of every unlocked vertex, heapified at once (`O(n)`).
    fn queue_all(&mut self) {
        let mut entries = Vec::with_capacity(self.positions.len());
        for u in 0..self.positions.len() {
            if let Some((cost, v)) = self.cheapest_target(u) {
                self.queued_per_vertex[u] = Queued { target: v, cost, fallback: false };
                entries.push(Candidate::new(cost, u, 0));
            }
        }
        self.heap = MinHeap4::from_vec(entries);
    }

    /// Cost of collapsing `u` into `v` (see the module doc), with
    /// `(Q_u + Q_v)(p_v) = Q_u(p_v) + Q_v(p_v)` and the second term cached.
    fn cost(&self, u: usize, v: usize) -> f64 {
        let (pu, pv) = (&self.positions[u], &self.positions[v]);
        let quadric = self.quadric_per_vertex[u].eval(pv) + self.own_error_per_vertex[v];
        (pu - pv).norm_squared() + quadric.max(0.0)
    }

    /// The neighbour `u` is cheapest to collapse into, ignoring validity;
    /// `None` for locked, removed or isolated vertices. The neighbours of an
    /// interior manifold vertex are the corners following it in its triangles.
    fn cheapest_target(&self, u: usize) -> Option<(f64, u32)> {
        if self.locked[u] || self.removed[u] {
            return None;
        }
        let mut best: Option<(f64, u32)> = None;
        for &f in &self.faces_per_vertex[u] {
            let v = next_corner(&self.triangles[f as usize], u as u32);
            let cost = self.cost(u, v as usize);
            if best.is_none_or(|(c, w)| (cost, v) < (c, w)) {
                best = Some((cost, v));
            }
        }
        best
    }

    /// Replace `u`'s queued candidate by `(cost, v)` (or by nothing); a
    /// candidate equal to the live one is left alone, sparing a heap push.
    fn set_candidate(&mut self, u: usize, best: Option<(f64, u32)>, fallback: bool) {
        let q = self.queued_per_vertex[u];
        match best {
            Some((cost, v)) if !fallback && !q.fallback && (q.target, q.cost) == (v, cost) => {}
            Some((cost, v)) => {
                self.stamp_per_vertex[u] = self.stamp_per_vertex[u].wrapping_add(1);
                self.queued_per_vertex[u] = Queued { target: v, cost, fallback };
                self.heap.push(Candidate::new(cost, u, self.stamp_per_vertex[u]));
            }
            None => {
                self.stamp_per_vertex[u] = self.stamp_per_vertex[u].wrapping_add(1);
                self.queued_per_vertex[u] = Queued::EMPTY;
            }
        }
    }

    /// After the cheapest target of `u` proved invalid: queue the cheapest
    /// valid one (marked as a fallback), or nothing.
    fn queue_cheapest_valid(&mut self, u: usize) {
        let mut costs = std::mem::take(&mut self.scratch_costs);
        costs.clear();
        for &f in &self.faces_per_vertex[u] {
            let v = next_corner(&self.triangles[f as usize], u as u32);
            costs.push((self.cost(u, v as usize), v));
        }
        costs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let best = costs.iter().copied().find(|&(_, v)| self.collapse_is_valid(u, v as usize));
        self.scratch_costs = costs;
        self.set_candidate(u, best, true);
    }

    /// Update the candidates of `v` and of its neighbours after `u → v`.
    ///
    /// Only `v`'s quadric changed, and a neighbour `w` of `v` lost `u` and
    /// may have gained `v`, so `w`'s other costs are unchanged: unless its
    /// queued target was `u` or `v` (or none, or a fallback), its new best
    /// is the cheaper of the queued one and `w → v` — one cost instead of
    /// a full recomputation, and no push when the queued one stays.
    fn requeue_around(&mut self, u: usize, v: usize) {
        let best = self.cheapest_target(v);
        self.set_candidate(v, best, false);
        let mut touched = std::mem::take(&mut self.scratch_vertices);
        touched.clear();
        for &f in &self.faces_per_vertex[v] {
            touched.extend(self.triangles[f as usize]);
        }
        touched.sort_unstable();
        touched.dedup();
        for &w in &touched {
            let w = w as usize;
            if w == v || self.locked[w] {
                continue;
            }
            let q = self.queued_per_vertex[w];
            if q.target == NONE || q.fallback || q.target as usize == u || q.target as usize == v {
                let best = self.cheapest_target(w);
                self.set_candidate(w, best, false);
            } else {
                let cost = self.cost(w, v);
                if (cost, v as u32) < (q.cost, q.target) {
                    self.set_candidate(w, Some((cost, v as u32)), false);
                }
            }
        }
        self.scratch_vertices = touched;
    }

    /// A fresh pair of mark values (`s`, `s + 1`), clearing the marks on wrap-around.
    fn fresh_marks(&mut self) -> u32 {
        if self.mark_stamp >= u32::MAX - 2 {
            self.mark.fill(0);
            self.mark_stamp = 0;
        }
        self.mark_stamp += 2;
        self.mark_stamp - 1
    }

    /// True when `u → v` keeps a manifold of the same topology with
    /// unflipped, well-shaped triangles (the conditions of the module doc).
    fn collapse_is_valid(&mut self, u: usize, v: usize) -> bool {
        if self.locked[u] || self.removed[u] || self.removed[v] || u == v {
            return false;
        }
        let Some(apexes) = self.edge_apexes(u, v) else {
            return false;
        };
        if apexes.iter().any(|&w| self.faces_per_vertex[w as usize].len() <= 3) {
            return false;
        }
        self.new_edges_short_enough(u, v) && self.link_condition_holds(u, v) && self.shapes_stay_valid(u, v)
    }

    /// Every edge `u → v` creates (from `v` to a neighbour of `u`) is at
    /// most the length bound.
    fn new_edges_short_enough(&self, u: usize, v: usize) -> bool {
        let pv = &self.positions[v];
        self.faces_per_vertex[u].iter().all(|&f| {
            self.triangles[f as usize]
                .iter()
                .all(|&w| (self.positions[w as usize] - pv).norm_squared() <= self.max_edge_sq)
        })
    }

    /// The third corners of the two triangles on edge `uv`, or `None` when
    /// the edge does not have exactly two triangles around `u`.
    fn edge_apexes(&self, u: usize, v: usize) -> Option<[u32; 2]> {
        let mut apexes = [NONE; 2];
        let mut n = 0;
        for &f in &self.faces_per_vertex[u] {
            let t = &self.triangles[f as usize];
            if t.contains(&(v as u32)) {
                if n == 2 {
                    return None;
                }
                apexes[n] = third_corner(t, u as u32, v as u32);
                n += 1;
            }
        }
        (n == 2).then_some(apexes)
    }

    /// Link condition and valence bound: `u` and `v` share exactly two
    /// neighbours (the apexes), and `v` ends with at most [`MAX_VALENCE`]
    /// neighbours, `|N(u) ∪ N(v)| − 2`.
    fn link_condition_holds(&mut self, u: usize, v: usize) -> bool {
        let s = self.fresh_marks();
        let (uu, vv) = (u as u32, v as u32);
        let mut n_u = 0usize;
        for &f in &self.faces_per_vertex[u] {
            for w in self.triangles[f as usize] {
                if w != uu && w != vv && self.mark[w as usize] != s {
                    self.mark[w as usize] = s;
                    n_u += 1;
                }
            }
        }
        let (mut n_common, mut n_v_only) = (0usize, 0usize);
        for &f in &self.faces_per_vertex[v] {
            for w in self.triangles[f as usize] {
                if w == uu || w == vv {
                    continue;
                }
                let m = &mut self.mark[w as usize];
                if *m == s {
                    n_common += 1;
                    *m = s + 1;
                } else if *m != s + 1 {
                    n_v_only += 1;
                    *m = s + 1;
                }
            }
        }
        n_common == 2 && n_u + n_v_only <= MAX_VALENCE
    }

    /// No triangle of `u` that moves (does not contain `v`) flips or falls
    /// below `min(MIN_QUALITY, worst quality around u before)`.
    fn shapes_stay_valid(&self, u: usize, v: usize) -> bool {
        let p = self.positions;
        let (uu, vv) = (u as u32, v as u32);
        let mut worst_old = f64::INFINITY;
        let mut worst_new = f64::INFINITY;
        for &f in &self.faces_per_vertex[u] {
            let t = self.triangles[f as usize];
            let [a, b, c] = t.map(|w| p[w as usize]);
            worst_old = worst_old.min(triangle_quality(&a, &b, &c));
            if t.contains(&vv) {
                continue;
            }
            let [a2, b2, c2] = t.map(|w| p[if w == uu { v } else { w as usize }]);
            let n_old = triangle_area_vector(&a, &b, &c);
            let n_new = triangle_area_vector(&a2, &b2, &c2);
            if n_new.dot(&n_old) <= MIN_NORMAL_COS * n_new.norm() * n_old.norm() {
                return false;
            }
            worst_new = worst_new.min(triangle_quality(&a2, &b2, &c2));
        }
        worst_new > 0.0 && worst_new >= MIN_QUALITY.min(worst_old)
    }

    /// Perform `u → v`: delete the triangles on `uv`, move `u`'s other
    /// triangles to `v` (corner replaced in place, so orientation is kept)
    /// and give `v` the summed quadric.
    fn collapse(&mut self, u: usize, v: usize) {
        let (uu, vv) = (u as u32, v as u32);
        let faces = std::mem::take(&mut self.faces_per_vertex[u]);
        for &f in &faces {
            let t = self.triangles[f as usize];
            if t.contains(&vv) {
                self.face_alive[f as usize] = false;
                self.n_faces_alive -= 1;
                for w in t.into_iter().filter(|&w| w != uu) {
                    remove_face(&mut self.faces_per_vertex[w as usize], f);
                }
            } else {
                self.triangles[f as usize] = t.map(|w| if w == uu { vv } else { w });
                self.faces_per_vertex[v].push(f);
            }
        }
        self.quadric_per_vertex[v] = self.quadric_per_vertex[v].add(&self.quadric_per_vertex[u]);
        self.own_error_per_vertex[v] = self.quadric_per_vertex[v].eval(&self.positions[v]);
        self.removed[u] = true;
    }

    /// The surviving triangles over the vertices they use, renumbered in
    /// input order, with the input id of each kept vertex.
    fn compact(&self) -> Decimated {
        let mut new_id = vec![NONE; self.positions.len()];
        for (t, _) in self.alive_triangles() {
            for w in t {
                new_id[w as usize] = 0;
            }
        }
        let mut positions = Vec::new();
        let mut fine_vertex = Vec::new();
        for (w, id) in new_id.iter_mut().enumerate() {
            if *id != NONE {
                *id = positions.len() as u32;
                positions.push(self.positions[w]);
                fine_vertex.push(VertexId::new(w));
            }
        }
        let triangles: Vec<[u32; 3]> = self.alive_triangles().map(|(t, _)| t.map(|w| new_id[w as usize])).collect();
        Decimated { mesh: TriMesh::from_raw(positions, &triangles), fine_vertex }
    }

    /// Surviving triangles with their input face index, in input order.
    fn alive_triangles(&self) -> impl Iterator<Item = ([u32; 3], usize)> + '_ {
        self.triangles.iter().enumerate().filter(|(f, _)| self.face_alive[*f]).map(|(f, t)| (*t, f))
    }
}

/// The plane quadric of triangle `t` (zero for a degenerate triangle).
fn face_quadric(positions: &[Vec3], t: &[u32; 3]) -> Quadric {
    let [a, b, c] = t.map(|w| positions[w as usize]);
    let n = triangle_area_vector(&a, &b, &c);
    let len = n.norm();
    if len > 0.0 && len.is_finite() {
        let n = n / len;
        Quadric::of_plane(&n, -n.dot(&a))
    } else {
        Quadric::default()
    }
}

/// The corner after `u` in triangle `t` (counter-clockwise).
#[inline]
fn next_corner(t: &[u32; 3], u: u32) -> u32 {
    if t[0] == u {
        t[1]
    } else if t[1] == u {
        t[2]
    } else {
        t[0]
    }
}

/// The corner of `t` that is neither `u` nor `v`.
#[inline]
fn third_corner(t: &[u32; 3], u: u32, v: u32) -> u32 {
    t.iter().copied().find(|&w| w != u && w != v).unwrap_or(NONE)
}

/// Remove face `f` from an incidence list (order is not kept).
#[inline]
fn remove_face(faces: &mut Vec<u32>, f: u32) {
    if let Some(i) = faces.iter().position(|&g| g == f) {
        faces.swap_remove(i);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::FaceId;
    use crate::mesh::boundary::boundary_loops;
    use crate::mesh::fixtures;
    use crate::mesh::orientation::n_inconsistent_edges;
    use crate::mesh::summary::topology_summary;

    /// Decimate with the given locked edges and check the invariants every
    /// coarse mesh must satisfy (validity, orientation, topology, subset,
    /// locked edges); returns the result.
    fn decimate_checked(fine: &TriMesh, locked_edges: &[bool], target: usize) -> Decimated {
        let topo = Topology::new(fine);
        let dec = decimate(fine, &topo, locked_edges, target, f64::INFINITY).expect("decimate");
        let coarse = &dec.mesh;
        coarse.validate().expect("valid coarse mesh");
        let ctopo = Topology::new(coarse);
        ctopo.validate(coarse).expect("valid coarse topology");
        assert_eq!(n_inconsistent_edges(coarse, &ctopo), 0, "orientation");
        let (fs, cs) = (topology_summary(fine, &topo), topology_summary(coarse, &ctopo));
        assert_eq!(cs.euler_characteristic, fs.euler_characteristic);
        assert_eq!(cs.n_boundary_loops, fs.n_boundary_loops);
        assert_eq!(cs.n_components(), fs.n_components());
        assert_eq!(cs.n_nonmanifold_edges, fs.n_nonmanifold_edges);
        assert_eq!(cs.n_nonmanifold_vertices, fs.n_nonmanifold_vertices);
        assert_eq!(boundary_loops(coarse, &ctopo).len(), boundary_loops(fine, &topo).len());
        assert_eq!(dec.fine_vertex.len(), coarse.n_vertices());
        for (c, &f) in dec.fine_vertex.iter().enumerate() {
            assert_eq!(coarse.positions[c], fine.positions[f.idx()]);
        }
        let mut coarse_of = vec![None; fine.n_vertices()];
        for (c, &f) in dec.fine_vertex.iter().enumerate() {
            coarse_of[f.idx()] = Some(VertexId::new(c));
        }
        for (e, &[a, b]) in topo.edges.iter().enumerate() {
            if locked_edges[e] || topo.is_boundary_edge(EdgeId::new(e)) {
                let (ca, cb) = (coarse_of[a.idx()], coarse_of[b.idx()]);
                let (Some(ca), Some(cb)) = (ca, cb) else {
                    panic!("endpoint of locked edge ({a}, {b}) removed");
                };
                assert!(ctopo.edge_between(ca, cb).is_some(), "locked edge lost");
            }
        }
        dec
    }

    /// Smallest triangle quality of a mesh.
    fn min_quality(m: &TriMesh) -> f64 {
        (0..m.n_faces())
            .map(|f| {
                let [a, b, c] = m.corners(FaceId::new(f));
                triangle_quality(&a, &b, &c)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Edges whose dihedral angle exceeds 30°, plus nothing else.
    fn sharp_edges(m: &TriMesh, topo: &Topology) -> Vec<bool> {
        (0..topo.n_edges())
            .map(|e| match topo.edge_faces(EdgeId::new(e)) {
                [f, g] => m.face_normal(*f).dot(&m.face_normal(*g)) < 30f64.to_radians().cos(),
                _ => false,
            })
            .collect()
    }

    #[test]
    fn sphere_keeps_topology_orientation_and_volume() {
        let fine = fixtures::icosphere(4);
        let none = vec![false; Topology::new(&fine).n_edges()];
        let dec = decimate_checked(&fine, &none, 500);
        let n = dec.mesh.n_faces();
        assert!((400..=550).contains(&n), "{n} faces");
        let (v_fine, v_coarse) = (fine.signed_volume(), dec.mesh.signed_volume());
        assert!(v_coarse > 0.0 && v_coarse > 0.9 * v_fine, "{v_coarse} vs {v_fine}");

        // Reversed input: normals stay inward.
        let mut inward = fine.clone();
        for f in 0..inward.n_faces() {
            inward.flip_face(FaceId::new(f));
        }
        let dec = decimate_checked(&inward, &none, 500);
        assert!(dec.mesh.signed_volume() < 0.0);
    }

    #[test]
    fn coarsening_is_uniform_and_well_shaped() {
        for (fine, target) in [(fixtures::icosphere(5), 1280), (fixtures::disk(40), 1200)] {
            let none = vec![false; Topology::new(&fine).n_edges()];
            let dec = decimate_checked(&fine, &none, target);
            let q = min_quality(&dec.mesh);
            assert!(q >= MIN_QUALITY, "min quality {q}");
            let expected = (fine.n_faces() as f64 / dec.mesh.n_faces() as f64).sqrt();
            let ratio = dec.mesh.mean_edge_length() / fine.mean_edge_length();
            eprintln!(
                "{} → {} faces: min quality {q:.3}, edge length ratio {ratio:.2} (√ {expected:.2})",
                fine.n_faces(),
                dec.mesh.n_faces()
            );
            assert!(dec.mesh.n_faces() as f64 <= 1.1 * target as f64);
            assert!(ratio > 0.75 * expected && ratio < 1.25 * expected);
        }
    }

    #[test]
    fn the_length_bound_holds_and_keeps_the_interior_uniform() {
        // The boundary keeps its 360 fine vertices; with the face target
        // alone the interior would be coarsened far more to make up for them.
        let fine = fixtures::disk(60);
        let topo = Topology::new(&fine);
        let none = vec![false; topo.n_edges()];
        let bound = 6.0 * fine.mean_edge_length();
        let dec = decimate(&fine, &topo, &none, fine.n_faces() / 64, bound).expect("decimate");
        let ctopo = Topology::new(&dec.mesh);
        ctopo.validate(&dec.mesh).expect("valid");
        let length = |e: usize| {
            let [a, b] = ctopo.edges[e];
            (dec.mesh.positions[a.idx()] - dec.mesh.positions[b.idx()]).norm()
        };
        let longest = (0..ctopo.n_edges()).map(length).fold(0.0, f64::max);
        assert!(longest <= bound * (1.0 + 1e-12), "{longest} > {bound}");
        let on_boundary: Vec<bool> = {
            let mut b = vec![false; dec.mesh.n_vertices()];
            for e in 0..ctopo.n_edges() {
                if ctopo.is_boundary_edge(EdgeId::new(e)) {
                    for v in ctopo.edges[e] {
                        b[v.idx()] = true;
                    }
                }
            }
            b
        };
        let interior: Vec<f64> = (0..ctopo.n_edges())
            .filter(|&e| ctopo.edges[e].iter().all(|v| !on_boundary[v.idx()]))
            .map(length)
            .collect();
        let mean = interior.iter().sum::<f64>() / interior.len() as f64;
        assert!(mean > 0.4 * bound, "interior mean edge {mean} vs bound {bound}");
        let unbounded = decimate(&fine, &topo, &none, fine.n_faces() / 64, f64::INFINITY).expect("decimate");
        assert!(unbounded.mesh.n_faces() < dec.mesh.n_faces());
    }

    #[test]
    fn planar_shapes_keep_their_boundary() {
        for fine in [
            fixtures::l_shape(12),
            fixtures::square(20),
            fixtures::annulus(0.4, 1.0, 48, 10),
            fixtures::l_plate_with_l_hole(24),
        ] {
            let none = vec![false; Topology::new(&fine).n_edges()];
            let dec = decimate_checked(&fine, &none, fine.n_faces() / 4);
            assert!((dec.mesh.area() - fine.area()).abs() < 1e-9 * fine.area());
            assert!(dec.mesh.n_faces() < fine.n_faces() / 2);
        }
    }

    #[test]
    fn torus_and_cylinder_keep_genus_and_loops() {
        for fine in [fixtures::torus(1.0, 0.4, 60, 24), fixtures::cylinder(1.0, 2.0, 48, 24)] {
            let none = vec![false; Topology::new(&fine).n_edges()];
            let dec = decimate_checked(&fine, &none, 400);
            assert!(dec.mesh.n_faces() <= 440, "{} faces", dec.mesh.n_faces());
        }
    }

    #[test]
    fn locked_cube_edges_survive_and_corners_stay_sharp() {
        let fine = fixtures::cube(16);
        let topo = Topology::new(&fine);
        let locked = sharp_edges(&fine, &topo);
        assert_eq!(locked.iter().filter(|&&l| l).count(), 12 * 16);
        // Each face keeps its 64 border edges, so ~100 triangles per face is
        // about as far as shape-preserving collapses can go.
        let dec = decimate_checked(&fine, &locked, 600);
        assert!(dec.mesh.n_faces() <= 660, "{} faces", dec.mesh.n_faces());
        // The surface is still the cube's: every triangle lies in a face plane.
        for f in 0..dec.mesh.n_faces() {
            let [a, b, c] = dec.mesh.corners(FaceId::new(f));
            let on_plane = (0..3).any(|k| [a, b, c].iter().all(|p| (p[k] - a[k]).abs() < 1e-12 && a[k].abs() == 1.0));
            assert!(on_plane, "triangle {f} cuts a cube edge");
        }
    }

    #[test]
    fn quadric_keeps_unlocked_cube_corners() {
        let fine = fixtures::cube(12);
        let none = vec![false; Topology::new(&fine).n_edges()];
        let dec = decimate_checked(&fine, &none, 200);
        for corner in dec.mesh.positions.iter().filter(|p| p.iter().all(|c| c.abs() == 1.0)) {
            assert_eq!(corner.norm_squared(), 3.0);
        }
        let n_corners = dec.mesh.positions.iter().filter(|p| p.iter().all(|c| c.abs() == 1.0)).count();
        assert_eq!(n_corners, 8);
        assert!((dec.mesh.signed_volume() - 8.0).abs() < 0.05 * 8.0);
    }

    #[test]
    fn pinched_cones_keep_the_pinch() {
        // Two cones z = ±r sharing their apex (vertex 0 of each disk).
        let disk = fixtures::disk(8);
        let mut positions = Vec::new();
        let mut tris: Vec<[u32; 3]> = Vec::new();
        for sign in [1.0, -1.0] {
            let base = positions.len() as u32;
            positions.extend(disk.positions.iter().map(|p| Vec3::new(p.x, p.y, sign * p.norm())));
            for t in &disk.triangles {
                let t = t.map(|v| if v.0 == 0 { 0 } else { v.0 + base });
                tris.push(if sign > 0.0 { t } else { [t[0], t[2], t[1]] });
            }
        }
        let fine = fixtures::compact(TriMesh::from_raw(positions, &tris));
        let topo = Topology::new(&fine);
        assert_eq!(topology_summary(&fine, &topo).n_nonmanifold_vertices, 1);
        let none = vec![false; topo.n_edges()];
        let dec = decimate_checked(&fine, &none, fine.n_faces() / 4);
        assert!(dec.fine_vertex.contains(&VertexId(0)));
        assert!(dec.mesh.n_faces() < fine.n_faces() / 2);
    }

    #[test]
    fn unreachable_target_stops_at_a_valid_mesh() {
        for fine in [fixtures::icosphere(3), fixtures::torus(1.0, 0.4, 30, 12)] {
            let none = vec![false; Topology::new(&fine).n_edges()];
            let dec = decimate_checked(&fine, &none, 0);
            assert!(dec.mesh.n_faces() >= 4);
        }
        let tet = fixtures::tetrahedron();
        let dec = decimate_checked(&tet, &[false; 6], 0);
        assert_eq!(dec.mesh, tet);
    }

    #[test]
    fn heap_pops_in_order() {
        let mut state = 12345u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        let items: Vec<Candidate> =
            (0..500).map(|i| Candidate::new((next() % 50) as f64 * 0.5, i, next() % 3)).collect();
        let mut heap = MinHeap4::from_vec(items[..300].to_vec());
        for &c in &items[300..] {
            heap.push(c);
        }
        assert_eq!(heap.len(), 500);
        let mut expected = items.clone();
        expected.sort();
        let popped: Vec<Candidate> = std::iter::from_fn(|| heap.pop()).collect();
        assert_eq!(popped, expected);
    }

    #[test]
    fn wrong_lock_length_is_an_error() {
        let m = fixtures::square(2);
        let topo = Topology::new(&m);
        let err = decimate(&m, &topo, &[false; 3], 2, f64::INFINITY).unwrap_err();
        assert!(matches!(
            err,
            MeshError::LengthMismatch { expected, found: 3, .. } if expected == topo.n_edges()
        ));
    }
}
