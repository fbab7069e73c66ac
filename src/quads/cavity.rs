//! Step 5a′ of the quads stage (after cleanup, before smoothing):
//! irregular vertices removed by remeshing quad cavities with patterns
//! (Gmsh's quasi-structured mesher, `qmtQuadCavityRemeshing`; research
//! `quad-meshing.md` §1.2; Takayama et al. 2014 for the patterns).
//!
//! A *cavity* is a set of quads of one model face forming a topological
//! disk. Each vertex `v` on its boundary loop lies in `k(v)` of its quads;
//! the cavity is *convex* when every `k(v) ≤ 2`, and its *corners* are the
//! vertices with `k(v) = 1`. For a quad disk with `n` corners,
//! `Σ_inside (4 − valence) = 4 − n` (the disk's index theorem), so a convex
//! cavity with
//! - 4 corners and equal opposite sides is a regular grid (nothing
//!   irregular inside);
//! - 3 or 5 corners is `n` grids around one vertex of valence `n`, when its
//!   side lengths `l_i` split as `l_i = s_{i−1} + s_{i+1}` with every spoke
//!   `s_j ≥ 1` (the spoke from that vertex to side `j`).
//!
//! Replacing a cavity by its pattern keeps every boundary vertex's quad
//! count, so the mesh outside is untouched, and leaves at most one
//! irregular vertex inside. From each irregular vertex a cavity is grown
//! ring by ring (made convex after each ring by taking in every boundary
//! vertex with `k ≥ 3`) until a pattern applies with fewer irregular
//! vertices inside than before; the new vertices are placed by transfinite
//! interpolation of the boundary, relaxed towards their neighbours'
//! centroid on the model face, and the pattern is kept only when its worst
//! scaled Jacobian is at least `min(MIN_SCALED_JACOBIAN, the cavity's old
//! worst)`.
//!
//! A vertex placed at a crossfield singularity is only replaced by the
//! centre of a pattern of its own valence, which first stays where the
//! singularity was and relaxes with the others only when that shape is
//! refused (the spoke lengths fix where the centre fits best). Two phases
//! run: in the first, a pattern with a centre must be grown from the
//! singular vertex it replaces and its relaxed centre must stay within an
//! edge length of it; the second drops both rules. Each phase repeats
//! passes until none applies ([`MAX_PASSES`] at most); seeds are taken in
//! vertex order, so the result does not depend on the thread count. The
//! growths of a batch of seeds are first tried side by side against the
//! mesh as it is; a growth that finds no pattern is kept for its seed
//! unless a cavity replaced before that seed touched what it read
//! ([`Cavities::batch`]), which gives the one-by-one result.

use std::collections::{BTreeMap, BTreeSet};

use foldhash::{HashMap, HashSet};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use super::cleanup::{compact, quads_around_vertices};
use super::projection::SurfaceProjector;
use super::smooth::quad_scaled_jacobian;
use super::surface_mesh::{ModelEntity, QuadMesh, single_boundary_loop};
use crate::geom::Vec3;

/// Largest cavity, in quads, a seed may grow to.
const MAX_CAVITY_QUADS: usize = 2000;

/// Rings grown around a seed before giving up on it.
const MAX_RINGS: usize = 25;

/// Passes over all irregular vertices, in each of the two phases.
const MAX_PASSES: usize = 3;

/// Seeds whose growth is tried side by side on the pool before they are
/// taken in order ([`Cavities::batch`]).
const SEEDS_PER_BATCH: u32 = 256;

/// Relaxation rounds of a new pattern's inside vertices, each a projection
/// onto the face after [`SWEEPS_PER_ROUND`] centroid sweeps.
const RELAX_ROUNDS: usize = 3;

/// Centroid sweeps per relaxation round.
const SWEEPS_PER_ROUND: usize = 10;

/// A new pattern must reach this worst scaled Jacobian (or the cavity's
/// old worst, when that was lower).
const MIN_SCALED_JACOBIAN: f64 = 0.3;

/// What cavity remeshing did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct CavityStats {
    /// Cavities replaced by a pattern.
    pub remeshed: u64,
    /// The same, per number of pattern corners (3, 4 or 5).
    pub remeshed_by_corners: BTreeMap<usize, u64>,
    /// Patterns that applied topologically but were refused for their shape.
    pub rejected_shape: u64,
    /// Vertices inside model faces whose quad count is not their ideal
    /// (4, or `4 − index` at a singularity), before.
    pub irregular_before: u64,
    /// The same after.
    pub irregular_after: u64,
    /// Passes over the mesh until nothing applied.
    pub passes: usize,
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// Replaces cavities of `mesh` by patterns with fewer irregular vertices
/// (to a fixpoint or [`MAX_PASSES`]), then compacts it.
pub fn remesh_cavities(mesh: &mut QuadMesh, projector: &SurfaceProjector) -> CavityStats {
    remesh_cavities_in_batches(mesh, projector, SEEDS_PER_BATCH)
}

/// [`remesh_cavities`] taking the seeds in batches of `seeds_per_batch`
/// ([`Cavities::batch`]); the result does not depend on the batch size.
fn remesh_cavities_in_batches(mesh: &mut QuadMesh, projector: &SurfaceProjector, seeds_per_batch: u32) -> CavityStats {
    let t = Instant::now();
    let mut work = Cavities::new(mesh, projector);
    let mut stats = CavityStats { irregular_before: work.n_irregular(), ..CavityStats::default() };
    for centre_needs_singularity in [true, false] {
        work.centre_needs_singularity = centre_needs_singularity;
        work.failed.iter_mut().for_each(|f| *f = None);
        for _ in 0..MAX_PASSES {
            stats.passes += 1;
            let mut changed = false;
            let mut v = 0;
            while v < work.quads_of.len() as u32 {
                let end = (v + seeds_per_batch.max(1)).min(work.quads_of.len() as u32);
                changed |= work.batch(v..end, &mut stats);
                v = end;
            }
            if !changed {
                break;
            }
        }
    }
    stats.irregular_after = work.n_irregular();
    let Cavities { mesh, alive_vertex, alive_quad, .. } = work;
    compact(mesh, &alive_vertex, &alive_quad);
    stats.seconds = t.elapsed().as_secs_f64();
    stats
}

/// The mesh being edited, with incidences kept up to date.
struct Cavities<'m, 'p> {
    mesh: &'m mut QuadMesh,
    projector: &'p SurfaceProjector<'p>,
    alive_quad: Vec<bool>,
    alive_vertex: Vec<bool>,
    /// Alive quads around each vertex.
    quads_of: Vec<Vec<u32>>,
    /// Per quad, the quad across each of its edges ([`Self::across`] of
    /// edge `k`, from corner `k` to `k + 1`; `u32::MAX` for none), kept
    /// for alive quads: a cavity's boundary reads every edge of every
    /// member at every ring, and the lists behind `across` are scattered.
    across_edge: Vec<[u32; 4]>,
    /// Index (quarter turns) of each vertex placed at a singularity.
    singular: Vec<Option<i32>>,
    /// Edges on feature curves, as sorted vertex pairs.
    curve_edges: HashSet<[u32; 2]>,
    /// When set, a pattern with a centre (3 or 5 corners) must replace a
    /// vertex placed at a singularity of the centre's index, grown from
    /// that vertex (so the cavity is centred on it).
    centre_needs_singularity: bool,
    /// Vertices whose quads a replaced cavity changed since the current
    /// batch's growths were tried (its boundary and inside vertices).
    dirty: Vec<bool>,
    /// The vertices set in `dirty`.
    dirty_list: Vec<u32>,
    /// Per vertex that failed as a seed in this phase: the number of
    /// cavities replaced before, and the centre and radius of a ball
    /// holding its largest cavity.
    failed: Vec<Option<(usize, Vec3, f64)>>,
    /// Every replaced cavity: the centre and radius of a ball holding it.
    commits: Vec<(Vec3, f64)>,
    /// The set the current cavity grows in, reused from seed to seed (a
    /// fresh one per seed costs a pass over every quad and vertex).
    scratch: QuadSet,
}

/// A set of quads: its members in the order they joined, a flag per quad
/// of the mesh for membership, and how many members each vertex is in.
#[derive(Default)]
struct QuadSet {
    list: Vec<u32>,
    member: Vec<bool>,
    /// Members around each vertex of the mesh.
    count: Vec<u32>,
    /// The vertices of the members, in the order they were first reached.
    vertices: Vec<u32>,
}

impl QuadSet {
    /// Empties the set, now over a mesh of `n_quads` quads and `n_vertices`
    /// vertices, resetting only the entries its members touched.
    fn clear(&mut self, n_quads: usize, n_vertices: usize) {
        for &q in &self.list {
            self.member[q as usize] = false;
        }
        for &v in &self.vertices {
            self.count[v as usize] = 0;
        }
        self.list.clear();
        self.vertices.clear();
        self.member.resize(n_quads, false);
        self.count.resize(n_vertices, 0);
    }

    /// Adds quad `q` with corners `quad` (no effect when it is already in).
    fn insert(&mut self, q: u32, quad: [u32; 4]) {
        if self.member[q as usize] {
            return;
        }
        self.member[q as usize] = true;
        self.list.push(q);
        for v in quad {
            if self.count[v as usize] == 0 {
                self.vertices.push(v);
            }
            self.count[v as usize] += 1;
        }
    }

    /// True when `q` is in the set.
    fn contains(&self, q: u32) -> bool {
        self.member[q as usize]
    }

    /// Number of quads in the set.
    fn len(&self) -> usize {
        self.list.len()
    }

    /// The members in the order they joined.
    fn iter(&self) -> impl Iterator<Item = u32> + '_ {
        self.list.iter().copied()
    }

    /// Members around vertex `v`.
    fn count(&self, v: u32) -> usize {
        self.count[v as usize] as usize
    }

    /// `(vertex, members around it)` for every vertex of the members, in
    /// the order they were first reached.
    fn counts(&self) -> impl Iterator<Item = (u32, usize)> + '_ {
        self.vertices.iter().map(|&v| (v, self.count(v)))
    }
}

/// A convex disk cavity and the pattern that replaces it.
struct Plan {
    /// Model face of the cavity.
    face: u32,
    /// Its quads.
    quads: Vec<u32>,
    /// Vertices inside it (removed).
    inside: Vec<u32>,
    /// Its sides, corner to corner in boundary order (each includes both corners).
    sides: Vec<Vec<u32>>,
    /// The singular vertex inside, if any, with its index.
    singular: Option<(u32, i32)>,
}

/// The replacement of a cavity before it is applied: new vertices (ids
/// from `base` on) and quads over old and new vertices.
struct Pattern {
    base: u32,
    positions: Vec<Vec3>,
    quads: Vec<[u32; 4]>,
    /// New vertices that do not move while relaxing (a singular centre).
    pinned: Vec<u32>,
    /// The pattern's centre vertex (3 and 5 corners).
    centre: Option<u32>,
}

/// How a seed's growth ends, tried before the seeds ahead of it in its
/// batch are taken ([`Cavities::speculate`]).
enum Growth {
    /// No ring had a pattern: every vertex the growth read (the largest
    /// cavity's) and the radius of the ball around the seed holding them.
    Failed { vertices: Vec<u32>, reach: f64 },
    /// A ring had a pattern (or the seed's quads cross faces): grown again
    /// in order.
    Unknown,
}

impl<'m, 'p> Cavities<'m, 'p> {
    fn new(mesh: &'m mut QuadMesh, projector: &'p SurfaceProjector<'p>) -> Self {
        let n = mesh.vertices.len();
        let quads_of = quads_around_vertices(mesh);
        let mut singular = vec![None; n];
        for &(v, index) in &mesh.singular_vertices {
            if let Some(s) = singular.get_mut(v as usize) {
                *s = Some(index);
            }
        }
        let curve_edges = mesh.curve_edges.iter().map(|(_, [a, b])| [*a.min(b), *a.max(b)]).collect();
        let alive_quad = vec![true; mesh.quads.len()];
        let mut work = Self {
            mesh,
            projector,
            alive_quad,
            alive_vertex: vec![true; n],
            quads_of,
            across_edge: Vec::new(),
            singular,
            curve_edges,
            centre_needs_singularity: true,
            dirty: vec![false; n],
            dirty_list: Vec::new(),
            failed: vec![None; n],
            commits: Vec::new(),
            scratch: QuadSet::default(),
        };
        let this = &work;
        work.across_edge = (0..this.mesh.quads.len() as u32).into_par_iter().map(|q| this.across_edges_of(q)).collect();
        work
    }

    /// Ideal quad count of face vertex `v`: 4, or `4 − index` at a singularity.
    fn ideal(&self, v: u32) -> usize {
        (4 - self.singular[v as usize].unwrap_or(0)).max(1) as usize
    }

    /// The model face `v` is inside, if it is a face vertex.
    fn face_of(&self, v: u32) -> Option<u32> {
        match self.mesh.vertices.entity[v as usize] {
            ModelEntity::Face(f) => Some(f),
            _ => None,
        }
    }

    /// True when `v` is an alive face vertex off its ideal quad count.
    fn is_irregular_seed(&self, v: u32) -> bool {
        let n = self.quads_of[v as usize].len();
        self.alive_vertex[v as usize] && n > 0 && self.face_of(v).is_some() && n != self.ideal(v)
    }

    /// Face vertices off their ideal quad count.
    fn n_irregular(&self) -> u64 {
        (0..self.quads_of.len() as u32).filter(|&v| self.is_irregular_seed(v)).count() as u64
    }

    /// Takes the seeds of `range` in order, as one by one would
    /// ([`Self::grow_and_remesh`] on each irregular seed worth retrying),
    /// with the growths that find no pattern tried first side by side on
    /// the pool against the mesh as it is ([`Self::speculate`]): a seed
    /// whose growth found none, over vertices no replacement in this batch
    /// has touched since, would grow the same and fail the same, so its
    /// failure is recorded without growing it again. Every other seed is
    /// grown in order. Returns whether a cavity was replaced; the result is
    /// the one-by-one result, whatever the thread count.
    fn batch(&mut self, range: std::ops::Range<u32>, stats: &mut CavityStats) -> bool {
        // Speculation only pays on a pool of two or more threads: on one it
        // would grow every seed that finds a pattern twice.
        let seeds: Vec<u32> = if rayon::current_num_threads() > 1 {
            range.clone().filter(|&s| self.is_irregular_seed(s) && self.worth_retrying(s)).collect()
        } else {
            Vec::new()
        };
        let (n_quads, n_vertices) = (self.mesh.quads.len(), self.mesh.vertices.len());
        let this = &*self;
        let guesses: Vec<Growth> = seeds
            .par_iter()
            .map_init(QuadSet::default, |set, &s| {
                set.clear(n_quads, n_vertices);
                this.speculate(set, s)
            })
            .collect();
        for v in self.dirty_list.drain(..) {
            self.dirty[v as usize] = false;
        }
        let mut guesses = seeds.into_iter().zip(guesses).peekable();
        let mut changed = false;
        for s in range {
            let guess = guesses.next_if(|(g, _)| *g == s).map(|(_, growth)| growth);
            if !(self.is_irregular_seed(s) && self.worth_retrying(s)) {
                continue;
            }
            match guess {
                Some(Growth::Failed { vertices, reach }) if !vertices.iter().any(|&v| self.dirty[v as usize]) => {
                    let centre = self.mesh.vertices.positions[s as usize];
                    self.failed[s as usize] = Some((self.commits.len(), centre, reach));
                }
                _ => changed |= self.grow_and_remesh(s, stats),
            }
        }
        changed
    }

    /// How growing a cavity from `seed` in `cavity` (empty) would end, as
    /// [`Self::grow_and_remesh_in`] grows it but without applying anything:
    /// [`Growth::Failed`] when no ring has a pattern, else
    /// [`Growth::Unknown`] (applying the pattern decides).
    fn speculate(&self, cavity: &mut QuadSet, seed: u32) -> Growth {
        let Some(face) = self.face_of(seed) else { return Growth::Unknown };
        for &q in &self.quads_of[seed as usize] {
            cavity.insert(q, self.mesh.quads[q as usize]);
        }
        if cavity.iter().any(|q| self.mesh.model_face_per_quad[q as usize] != face) {
            return Growth::Unknown;
        }
        for _ in 0..MAX_RINGS {
            if !self.make_convex(cavity, face) {
                break;
            }
            if self.plan(cavity, face, seed).is_some() {
                return Growth::Unknown;
            }
            if !self.add_ring(cavity, face) {
                break;
            }
        }
        let centre = self.mesh.vertices.positions[seed as usize];
        Growth::Failed {
            vertices: cavity.vertices.clone(),
            reach: self.reach(cavity.vertices.iter().copied(), &centre),
        }
    }

    /// Grows cavities around `seed` ring by ring and replaces the first one
    /// whose pattern has fewer irregular vertices and a good shape.
    fn grow_and_remesh(&mut self, seed: u32, stats: &mut CavityStats) -> bool {
        let Some(face) = self.face_of(seed) else { return false };
        let mut cavity = std::mem::take(&mut self.scratch);
        cavity.clear(self.mesh.quads.len(), self.mesh.vertices.len());
        let done = self.grow_and_remesh_in(&mut cavity, seed, face, stats);
        self.scratch = cavity;
        done
    }

    /// [`Self::grow_and_remesh`] with the cavity grown in `cavity` (empty).
    fn grow_and_remesh_in(&mut self, cavity: &mut QuadSet, seed: u32, face: u32, stats: &mut CavityStats) -> bool {
        for &q in &self.quads_of[seed as usize] {
            cavity.insert(q, self.mesh.quads[q as usize]);
        }
        if cavity.iter().any(|q| self.mesh.model_face_per_quad[q as usize] != face) {
            return false;
        }
        for _ in 0..MAX_RINGS {
            if !self.make_convex(cavity, face) {
                break;
            }
            if let Some(plan) = self.plan(cavity, face, seed) {
                if self.apply(&plan) {
                    *stats.remeshed_by_corners.entry(plan.sides.len()).or_default() += 1;
                    stats.remeshed += 1;
                    return true;
                }
                stats.rejected_shape += 1;
            }
            if !self.add_ring(cavity, face) {
                break;
            }
        }
        let centre = self.mesh.vertices.positions[seed as usize];
        let reach = self.reach(cavity.vertices.iter().copied(), &centre);
        self.failed[seed as usize] = Some((self.commits.len(), centre, reach));
        false
    }

    /// Largest distance from `centre` to one of `vertices`.
    fn reach(&self, vertices: impl Iterator<Item = u32>, centre: &Vec3) -> f64 {
        vertices.map(|v| (self.mesh.vertices.positions[v as usize] - centre).norm()).fold(0.0, f64::max)
    }

    /// False when seed `v` failed in this phase and no cavity replaced
    /// since then reaches into the region its largest cavity covered (the
    /// same growth would fail again).
    fn worth_retrying(&self, v: u32) -> bool {
        let Some((since, centre, reach)) = self.failed[v as usize] else { return true };
        self.commits[since..].iter().any(|(c, r)| (c - centre).norm() <= reach + r)
    }

    /// Takes into `cavity` every quad around a vertex that the cavity
    /// surrounds on three or more quads but not all (a concave boundary
    /// vertex), until there is none. False when that needs a quad of
    /// another face, a vertex off the face, or more than
    /// [`MAX_CAVITY_QUADS`].
    fn make_convex(&self, cavity: &mut QuadSet, face: u32) -> bool {
        loop {
            let concave: Vec<u32> = cavity
                .counts()
                .filter(|&(v, k)| k >= 3 && (k < self.quads_of[v as usize].len() || self.face_of(v) != Some(face)))
                .map(|(v, _)| v)
                .collect();
            if concave.is_empty() {
                return true;
            }
            for v in concave {
                if !self.take_all_quads_of(cavity, v, face) {
                    return false;
                }
            }
            if cavity.len() > MAX_CAVITY_QUADS {
                return false;
            }
        }
    }

    /// Adds every quad around `v` to `cavity`; false when `v` is not a
    /// vertex of `face` or one of its quads is in another face.
    fn take_all_quads_of(&self, cavity: &mut QuadSet, v: u32, face: u32) -> bool {
        if self.face_of(v) != Some(face) {
            return false;
        }
        let quads = &self.quads_of[v as usize];
        if quads.iter().any(|&q| self.mesh.model_face_per_quad[q as usize] != face) {
            return false;
        }
        for &q in quads {
            cavity.insert(q, self.mesh.quads[q as usize]);
        }
        true
    }

    /// Adds the quads of `face` around every boundary vertex of `cavity`
    /// (one ring); false when nothing was added or it grew too large.
    fn add_ring(&self, cavity: &mut QuadSet, face: u32) -> bool {
        let before = cavity.len();
        let ring: Vec<u32> = cavity
            .counts()
            .filter(|&(v, k)| k < self.quads_of[v as usize].len())
            .flat_map(|(v, _)| self.quads_of[v as usize].iter().copied())
            .filter(|&q| self.mesh.model_face_per_quad[q as usize] == face)
            .collect();
        for q in ring {
            cavity.insert(q, self.mesh.quads[q as usize]);
        }
        cavity.len() > before && cavity.len() <= MAX_CAVITY_QUADS
    }

    /// The alive quad other than `q` with the edge `a b`.
    fn across(&self, q: u32, a: u32, b: u32) -> Option<u32> {
        self.quads_of[a as usize].iter().copied().find(|&o| o != q && self.mesh.quads[o as usize].contains(&b))
    }

    /// [`Self::across`] of each edge of quad `q` (`u32::MAX` for none).
    fn across_edges_of(&self, q: u32) -> [u32; 4] {
        let quad = self.mesh.quads[q as usize];
        std::array::from_fn(|k| self.across(q, quad[k], quad[(k + 1) % 4]).unwrap_or(u32::MAX))
    }

    /// The boundary loop of `cavity` with the cavity on its left (quad
    /// order), or `None` unless the cavity is a disk with one simple loop.
    fn boundary_loop(&self, cavity: &QuadSet) -> Option<Vec<u32>> {
        let mut next: HashMap<u32, u32> = HashMap::default();
        let mut first = None;
        for q in cavity.iter() {
            let quad = self.mesh.quads[q as usize];
            for k in 0..4 {
                let (a, b) = (quad[k], quad[(k + 1) % 4]);
                let o = self.across_edge[q as usize][k];
                let inner = o != u32::MAX && cavity.contains(o);
                if inner {
                    if self.curve_edges.contains(&[a.min(b), a.max(b)]) {
                        return None;
                    }
                    continue;
                }
                if next.insert(a, b).is_some() {
                    return None;
                }
                first.get_or_insert(a);
            }
        }
        let lp = single_boundary_loop(first?, next.len(), |v| next.get(&v).copied())?;
        let n_vertices = cavity.vertices.len() as i64;
        let (f, nb) = (cavity.len() as i64, next.len() as i64);
        let disk = n_vertices - (4 * f + nb) / 2 + f == 1;
        disk.then_some(lp)
    }

    /// The pattern plan for convex `cavity`, when it is a disk whose
    /// pattern applies and has fewer irregular vertices inside.
    fn plan(&self, cavity: &QuadSet, face: u32, seed: u32) -> Option<Plan> {
        // A vertex in one quad of the cavity is a corner of its loop: no
        // pattern has other than 3 to 5, and counting them needs no loop.
        if !(3..=5).contains(&cavity.counts().filter(|&(_, k)| k == 1).count()) {
            return None;
        }
        let lp = self.boundary_loop(cavity)?;
        let on_loop: HashSet<u32> = lp.iter().copied().collect();
        let inside: Vec<u32> = cavity.vertices.iter().copied().filter(|v| !on_loop.contains(v)).collect();
        if inside.iter().any(|&v| self.face_of(v) != Some(face)) {
            return None;
        }
        let corners: Vec<usize> = (0..lp.len()).filter(|&i| cavity.count(lp[i]) == 1).collect();
        let n = corners.len();
        if !(3..=5).contains(&n) {
            return None;
        }
        let singular: Vec<(u32, i32)> =
            inside.iter().filter_map(|&v| self.singular[v as usize].map(|i| (v, i))).collect();
        let centre_index = 4 - n as i32;
        match singular.as_slice() {
            [] if n == 4 || !self.centre_needs_singularity => {}
            [(v, i)] if *i == centre_index && (!self.centre_needs_singularity || *v == seed) => {}
            _ => return None,
        }
        let old = inside.iter().filter(|&&v| self.quads_of[v as usize].len() != 4).count();
        let new = usize::from(n != 4);
        if new >= old {
            return None;
        }
        let sides: Vec<Vec<u32>> = (0..n)
            .map(|c| {
                let (from, to) = (corners[c], corners[(c + 1) % n]);
                let len = (to + lp.len() - from) % lp.len();
                let len = if len == 0 { lp.len() } else { len };
                (0..=len).map(|i| lp[(from + i) % lp.len()]).collect()
            })
            .collect();
        let lengths: Vec<usize> = sides.iter().map(|s| s.len() - 1).collect();
        let fits =
            if n == 4 { lengths[0] == lengths[2] && lengths[1] == lengths[3] } else { spokes(&lengths).is_some() };
        fits.then(|| Plan { face, quads: cavity.iter().collect(), inside, sides, singular: singular.first().copied() })
    }

    /// Builds the pattern of `plan`, relaxes it and, when its shape is good
    /// enough, replaces the cavity by it. Returns whether it did.
    fn apply(&mut self, plan: &Plan) -> bool {
        let base = self.mesh.vertices.len() as u32;
        let mut pattern = Pattern { base, positions: Vec::new(), quads: Vec::new(), pinned: Vec::new(), centre: None };
        if plan.sides.len() == 4 {
            let sides: [Vec<u32>; 4] = std::array::from_fn(|i| plan.sides[i].clone());
            pattern.fill_grid(&self.mesh.vertices.positions, sides);
        } else {
            let centre_at = plan.singular.map(|(v, _)| self.mesh.vertices.positions[v as usize]);
            pattern.fill_star(&self.mesh.vertices.positions, &plan.sides, centre_at);
        }
        let old: Vec<[u32; 4]> = plan.quads.iter().map(|&q| self.mesh.quads[q as usize]).collect();
        let floor = self.worst_scaled_jacobian(&old).min(MIN_SCALED_JACOBIAN);
        let good = |worst: f64| worst > 0.0 && worst >= floor;
        if !self.place(&pattern, plan.face) {
            self.mesh.vertices.truncate(base as usize);
            return false;
        }
        self.relax(&pattern, plan.face);
        let mut accepted = good(self.worst_scaled_jacobian(&pattern.quads));
        if !accepted && !pattern.pinned.is_empty() {
            pattern.pinned.clear();
            self.relax(&pattern, plan.face);
            accepted = good(self.worst_scaled_jacobian(&pattern.quads))
                && (!self.centre_needs_singularity || self.centre_stays_near(plan, &pattern));
        }
        if !accepted {
            self.mesh.vertices.truncate(base as usize);
            return false;
        }
        self.commit(plan, &pattern);
        true
    }

    /// True when the centre of `pattern` lies within one boundary edge
    /// length (mean over the cavity's loop) of the singular vertex it
    /// replaces, so that relaxing it did not carry the singularity away.
    fn centre_stays_near(&self, plan: &Plan, pattern: &Pattern) -> bool {
        let (Some((s, _)), Some(c)) = (plan.singular, pattern.centre) else { return true };
        let p = &self.mesh.vertices.positions;
        let edges: Vec<f64> = plan
            .sides
            .iter()
            .flat_map(|side| side.windows(2).map(|w| (p[w[1] as usize] - p[w[0] as usize]).norm()))
            .collect();
        let h = edges.iter().sum::<f64>() / edges.len().max(1) as f64;
        (p[c as usize] - p[s as usize]).norm() <= h
    }

    /// Worst scaled Jacobian of `quads`.
    fn worst_scaled_jacobian(&self, quads: &[[u32; 4]]) -> f64 {
        quads
            .iter()
            .map(|q| quad_scaled_jacobian(&self.mesh.vertices, self.projector.face_normals(), q))
            .fold(f64::INFINITY, f64::min)
    }

    /// Appends the pattern's new vertices, projected onto model face `face`.
    fn place(&mut self, pattern: &Pattern, face: u32) -> bool {
        for x in &pattern.positions {
            let Some(p) = self.projector.project_to_face(face, x) else { return false };
            self.mesh.vertices.push(p.position, p.on_surface, ModelEntity::Face(face));
        }
        true
    }

    /// Moves each new, unpinned vertex to the centroid of its edge
    /// neighbours, [`RELAX_ROUNDS`] rounds of [`SWEEPS_PER_ROUND`] sweeps in
    /// order, projecting the moved vertices onto the face after each round
    /// (one projection per round instead of per sweep: the centroid of
    /// neighbours on the surface leaves it by second order only).
    fn relax(&mut self, pattern: &Pattern, face: u32) {
        let mut neighbours: BTreeMap<u32, BTreeSet<u32>> = BTreeMap::new();
        for q in &pattern.quads {
            for k in 0..4 {
                let (a, b) = (q[k], q[(k + 1) % 4]);
                if b >= pattern.base {
                    neighbours.entry(b).or_default().insert(a);
                }
                if a >= pattern.base {
                    neighbours.entry(a).or_default().insert(b);
                }
            }
        }
        let moving: Vec<(u32, Vec<u32>)> = neighbours
            .into_iter()
            .filter(|(v, _)| !pattern.pinned.contains(v))
            .map(|(v, around)| (v, around.into_iter().collect()))
            .collect();
        for _ in 0..RELAX_ROUNDS {
            let p = &mut self.mesh.vertices.positions;
            for _ in 0..SWEEPS_PER_ROUND {
                for (v, around) in &moving {
                    let sum = around.iter().fold(Vec3::zeros(), |acc, &w| acc + p[w as usize]);
                    p[*v as usize] = sum / around.len() as f64;
                }
            }
            for (v, _) in &moving {
                let x = self.mesh.vertices.positions[*v as usize];
                if let Some(proj) = self.projector.project_to_face(face, &x) {
                    self.mesh.vertices.positions[*v as usize] = proj.position;
                    self.mesh.vertices.on_surface[*v as usize] = proj.on_surface;
                }
            }
        }
    }

    /// Replaces the cavity of `plan` by `pattern` (whose vertices are
    /// already appended) and updates the incidences.
    fn commit(&mut self, plan: &Plan, pattern: &Pattern) {
        let boundary: Vec<u32> = plan.sides.iter().flatten().copied().collect();
        let centre = boundary.iter().fold(Vec3::zeros(), |acc, &v| acc + self.mesh.vertices.positions[v as usize])
            / boundary.len().max(1) as f64;
        let reach = self.reach(boundary.iter().copied(), &centre);
        self.commits.push((centre, reach));
        let dead: HashSet<u32> = plan.quads.iter().copied().collect();
        for &v in plan.sides.iter().flatten().chain(&plan.inside) {
            if !std::mem::replace(&mut self.dirty[v as usize], true) {
                self.dirty_list.push(v);
            }
        }
        for &q in &plan.quads {
            self.alive_quad[q as usize] = false;
        }
        for &v in &plan.inside {
            self.alive_vertex[v as usize] = false;
            self.quads_of[v as usize].clear();
            self.singular[v as usize] = None;
        }
        for side in &plan.sides {
            for &v in side {
                self.quads_of[v as usize].retain(|q| !dead.contains(q));
            }
        }
        let n_new = pattern.positions.len();
        self.alive_vertex.extend(std::iter::repeat_n(true, n_new));
        self.quads_of.extend(std::iter::repeat_n(Vec::new(), n_new));
        self.singular.extend(std::iter::repeat_n(None, n_new));
        self.failed.extend(std::iter::repeat_n(None, n_new));
        self.dirty.extend(std::iter::repeat_n(false, n_new));
        for quad in &pattern.quads {
            let q = self.mesh.quads.len() as u32;
            self.mesh.quads.push(*quad);
            self.mesh.model_face_per_quad.push(plan.face);
            self.alive_quad.push(true);
            for &v in quad {
                self.quads_of[v as usize].push(q);
            }
        }
        if let (Some((_, index)), Some(c)) = (plan.singular, pattern.centre) {
            self.singular[c as usize] = Some(index);
            self.mesh.singular_vertices.push((c, index));
        }
        // `across` changed only for quads at a vertex whose list changed:
        // the loop's vertices and the new ones (every new quad has one).
        self.across_edge.resize(self.mesh.quads.len(), [u32::MAX; 4]);
        let changed = plan.sides.iter().flatten().copied().chain(pattern.base..pattern.base + n_new as u32);
        for v in changed {
            for i in 0..self.quads_of[v as usize].len() {
                let q = self.quads_of[v as usize][i];
                self.across_edge[q as usize] = self.across_edges_of(q);
            }
        }
    }
}

impl Pattern {
    /// A new vertex at `x`.
    fn vertex(&mut self, x: Vec3) -> u32 {
        self.positions.push(x);
        self.base + self.positions.len() as u32 - 1
    }

    /// Position of `v`, old (`old`) or new.
    fn position(&self, old: &[Vec3], v: u32) -> Vec3 {
        if v < self.base { old[v as usize] } else { self.positions[(v - self.base) as usize] }
    }

    /// A structured grid inside four sides, `sides[k]` running from corner
    /// `k` to corner `k + 1` (opposite sides of equal length), inside
    /// vertices by transfinite (Coons) interpolation of the sides.
    fn fill_grid(&mut self, old: &[Vec3], sides: [Vec<u32>; 4]) {
        let (a, b) = (sides[0].len() - 1, sides[1].len() - 1);
        let mut grid = vec![vec![u32::MAX; b + 1]; a + 1];
        for i in 0..=a {
            grid[i][0] = sides[0][i];
            grid[a - i][b] = sides[2][i];
        }
        for j in 0..=b {
            grid[a][j] = sides[1][j];
            grid[0][b - j] = sides[3][j];
        }
        for i in 1..a {
            for j in 1..b {
                let (u, v) = (i as f64 / a as f64, j as f64 / b as f64);
                let p = |i: usize, j: usize| self.position(old, grid[i][j]);
                let x = p(i, 0) * (1.0 - v) + p(i, b) * v + p(0, j) * (1.0 - u) + p(a, j) * u
                    - (p(0, 0) * ((1.0 - u) * (1.0 - v))
                        + p(a, 0) * (u * (1.0 - v))
                        + p(0, b) * ((1.0 - u) * v)
                        + p(a, b) * (u * v));
                grid[i][j] = self.vertex(x);
            }
        }
        for i in 0..a {
            for j in 0..b {
                self.quads.push([grid[i][j], grid[i + 1][j], grid[i + 1][j + 1], grid[i][j + 1]]);
            }
        }
    }

    /// `n` grids (n = 3 or 5) around one centre vertex, with spoke `j` from
    /// the centre to side `j`; the centre sits at `centre_at` (pinned) or
    /// at the mean of the boundary.
    fn fill_star(&mut self, old: &[Vec3], sides: &[Vec<u32>], centre_at: Option<Vec3>) {
        let n = sides.len();
        let lengths: Vec<usize> = sides.iter().map(|s| s.len() - 1).collect();
        let Some(s) = spokes(&lengths) else { return };
        let boundary: Vec<Vec3> = sides.iter().flat_map(|side| side[1..].iter().map(|&v| old[v as usize])).collect();
        let mean = boundary.iter().fold(Vec3::zeros(), |acc, x| acc + x) / boundary.len() as f64;
        let centre = self.vertex(centre_at.unwrap_or(mean));
        self.centre = Some(centre);
        if centre_at.is_some() {
            self.pinned.push(centre);
        }
        let centre_x = self.position(old, centre);
        let spokes: Vec<Vec<u32>> = (0..n)
            .map(|j| {
                let foot = sides[j][s[(j + n - 1) % n]];
                let foot_x = old[foot as usize];
                let mut spoke = vec![foot];
                for t in 1..s[j] {
                    let w = t as f64 / s[j] as f64;
                    spoke.push(self.vertex(foot_x * (1.0 - w) + centre_x * w));
                }
                spoke.push(centre);
                spoke
            })
            .collect();
        for i in 0..n {
            let prev = (i + n - 1) % n;
            let along = sides[i][..=s[prev]].to_vec();
            let inward = spokes[i].clone();
            let outward: Vec<u32> = spokes[prev].iter().rev().copied().collect();
            let back = sides[prev][s[(prev + n - 1) % n]..].to_vec();
            self.fill_grid(old, [along, inward, outward, back]);
        }
    }
}

/// Spoke lengths `s` of an `n`-sided star pattern (`n` odd) with side
/// lengths `l`: `l_i = s_{i−1} + s_{i+1}`, so `2 s_j = Σ_t (−1)^t
/// l_{j+1+2t}`. `None` unless every spoke is a whole number ≥ 1.
fn spokes(l: &[usize]) -> Option<Vec<usize>> {
    let n = l.len();
    if n.is_multiple_of(2) {
        return None;
    }
    (0..n)
        .map(|j| {
            let twice: i64 = (0..n).map(|t| if t % 2 == 0 { 1 } else { -1 } * l[(j + 1 + 2 * t) % n] as i64).sum();
            (twice >= 2 && twice % 2 == 0).then_some((twice / 2) as usize)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;
    use crate::quads::cleanup::tests::{assert_conforming, insert_diamond, square_grid};
    use crate::quads::smooth::project_all;
    use crate::quads::smooth::tests::Input;

    /// Quads around each vertex of `quads`.
    fn quad_counts(quads: &[[u32; 4]]) -> BTreeMap<u32, usize> {
        let mut k = BTreeMap::new();
        for q in quads {
            for &v in q {
                *k.entry(v).or_default() += 1;
            }
        }
        k
    }

    /// Diamonds close enough that replacing one cavity changes the quads
    /// other seeds' failed growths read: batches of 256 seeds (growths tried side
    /// by side, then checked against what the replacements touched) give
    /// the mesh that one seed at a time gives, on any pool.
    #[test]
    fn batched_seeds_give_the_one_by_one_result() {
        let n = 16;
        let input = Input::new(fixtures::square(n));
        let proj = input.projector();
        let run = |seeds_per_batch: u32| {
            let mut mesh = square_grid(&input, n);
            project_all(&mut mesh, &proj);
            let mut singular = Vec::new();
            for (k, (i, j)) in [(4, 4), (4, 7), (7, 5), (11, 11), (11, 4), (8, 12), (6, 9)].into_iter().enumerate() {
                let (up, _) = insert_diamond(&mut mesh, n, i, j);
                // Some diamonds carry a singularity no 4-corner cavity can
                // hold: their seeds' growths fail (the side-by-side case).
                if k % 2 == 1 {
                    singular.push((up, 1));
                }
            }
            mesh.singular_vertices = singular;
            project_all(&mut mesh, &proj);
            let stats = remesh_cavities_in_batches(&mut mesh, &proj, seeds_per_batch);
            (mesh, stats)
        };
        let (one, one_stats) = run(1);
        let (batched, batched_stats) = run(256);
        assert!(one_stats.remeshed >= 2 && one_stats.irregular_after < one_stats.irregular_before, "{one_stats:?}");
        assert_eq!(
            (batched_stats.remeshed, batched_stats.rejected_shape, batched_stats.irregular_after, batched_stats.passes),
            (one_stats.remeshed, one_stats.rejected_shape, one_stats.irregular_after, one_stats.passes)
        );
        assert_eq!(batched.quads, one.quads);
        assert_eq!(batched.vertices.positions, one.vertices.positions);
        // A one-thread pool grows every seed in order without speculating.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let (alone, alone_stats) = pool.install(|| run(256));
        assert_eq!((alone_stats.remeshed, alone_stats.passes), (one_stats.remeshed, one_stats.passes));
        assert_eq!(alone.quads, one.quads);
        assert_eq!(alone.vertices.positions, one.vertices.positions);
    }

    /// The `n × n` grid of the unit square with a diamond inserted at each
    /// of `at`, projected onto the input.
    fn grid_with_diamonds(input: &Input, proj: &SurfaceProjector, n: usize, at: &[(usize, usize)]) -> QuadMesh {
        let mut mesh = square_grid(input, n);
        project_all(&mut mesh, proj);
        for &(i, j) in at {
            insert_diamond(&mut mesh, n, i, j);
        }
        project_all(&mut mesh, proj);
        mesh
    }

    /// The quads across each edge, kept through replacements, are what
    /// the vertices' quad lists give afresh.
    #[test]
    fn the_quads_across_edges_stay_current_through_replacements() {
        let n = 16;
        let input = Input::new(fixtures::square(n));
        let proj = input.projector();
        let mut mesh = grid_with_diamonds(&input, &proj, n, &[(4, 4), (4, 7), (7, 5), (11, 11)]);
        let mut work = Cavities::new(&mut mesh, &proj);
        work.centre_needs_singularity = false;
        let mut stats = CavityStats::default();
        let n_vertices = work.quads_of.len() as u32;
        assert!(work.batch(0..n_vertices, &mut stats));
        assert!(stats.remeshed >= 2, "{stats:?}");
        for q in 0..work.mesh.quads.len() as u32 {
            if work.alive_quad[q as usize] {
                assert_eq!(work.across_edge[q as usize], work.across_edges_of(q), "quad {q}");
            }
        }
    }

    #[test]
    fn a_diamond_in_a_grid_is_remeshed_back_to_the_regular_grid() {
        let n = 8;
        let input = Input::new(fixtures::square(n));
        let proj = input.projector();
        let mut mesh = grid_with_diamonds(&input, &proj, n, &[(4, 4)]);
        let stats = remesh_cavities(&mut mesh, &proj);
        assert_eq!((stats.irregular_before, stats.irregular_after), (4, 0), "{stats:?}");
        assert_eq!(stats.remeshed_by_corners.get(&4), Some(&1));
        assert_conforming(&mesh);
        // With 8 segments on each side and no irregular vertex, the only
        // quad mesh of the square is the 8 × 8 grid.
        assert_eq!((mesh.quads.len(), mesh.vertices.len()), (64, 81));
        let normals = input.surface.face_normals();
        assert!(mesh.quads.iter().all(|q| quad_scaled_jacobian(&mesh.vertices, &normals, q) > 0.9));
    }

    #[test]
    fn a_singular_vertex_stays_when_no_pattern_has_its_valence() {
        let n = 8;
        let input = Input::new(fixtures::square(n));
        let proj = input.projector();
        let mut mesh = square_grid(&input, n);
        project_all(&mut mesh, &proj);
        let (up, _) = insert_diamond(&mut mesh, n, 4, 4);
        project_all(&mut mesh, &proj);
        mesh.singular_vertices = vec![(up, 1)];
        let before = mesh.quads.len();
        let stats = remesh_cavities(&mut mesh, &proj);
        // A 4-corner cavity has no place for the index +1 the vertex carries.
        assert_eq!(stats.remeshed, 0, "{stats:?}");
        assert_eq!(mesh.quads.len(), before);
        assert_eq!(mesh.singular_vertices, vec![(up, 1)]);
    }

    /// The star pattern inside a polygon with `sides` segments per side
    /// (corners on the unit circle): its quads and the boundary loop.
    fn star(sides: &[usize]) -> (Pattern, Vec<Vec3>, Vec<Vec<u32>>) {
        let n = sides.len();
        let corner = |i: usize| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            Vec3::new(a.cos(), a.sin(), 0.0)
        };
        let (mut old, mut side_ids) = (Vec::new(), Vec::new());
        let total: usize = sides.iter().sum();
        for (i, &l) in sides.iter().enumerate() {
            let mut ids = Vec::new();
            for t in 0..=l {
                if t == l {
                    ids.push(((old.len()) % total) as u32);
                    continue;
                }
                ids.push(old.len() as u32);
                let w = t as f64 / l as f64;
                old.push(corner(i) * (1.0 - w) + corner(i + 1) * w);
            }
            side_ids.push(ids);
        }
        let mut pattern =
            Pattern { base: total as u32, positions: Vec::new(), quads: Vec::new(), pinned: Vec::new(), centre: None };
        pattern.fill_star(&old, &side_ids, None);
        (pattern, old, side_ids)
    }

    #[test]
    fn star_patterns_are_conforming_oriented_grids_around_one_vertex_of_valence_n() {
        for sides in [vec![4, 4, 4], vec![3, 5, 4], vec![2; 5], vec![3, 4, 5, 4, 4]] {
            let n = sides.len();
            let s = spokes(&sides).unwrap();
            let (pattern, old, side_ids) = star(&sides);
            // Patch i is an s_{i−1} × s_i grid.
            let expected: usize = (0..n).map(|i| s[(i + n - 1) % n] * s[i]).sum();
            assert_eq!(pattern.quads.len(), expected, "{sides:?}");
            let k = quad_counts(&pattern.quads);
            let centre = pattern.centre.unwrap();
            assert_eq!(k[&centre], n);
            let corners: BTreeSet<u32> = side_ids.iter().map(|side| side[0]).collect();
            let boundary: BTreeSet<u32> = side_ids.iter().flatten().copied().collect();
            for (&v, &count) in &k {
                let want = if v == centre {
                    n
                } else if corners.contains(&v) {
                    1
                } else if boundary.contains(&v) {
                    2
                } else {
                    4
                };
                assert_eq!(count, want, "vertex {v} of {sides:?}");
            }
            // Every edge is used once in each direction inside, once along
            // the boundary in its loop direction.
            let mut directed: BTreeMap<(u32, u32), usize> = BTreeMap::new();
            for q in &pattern.quads {
                for i in 0..4 {
                    *directed.entry((q[i], q[(i + 1) % 4])).or_default() += 1;
                }
            }
            let loop_edges: BTreeSet<(u32, u32)> =
                side_ids.iter().flat_map(|side| side.windows(2).map(|w| (w[0], w[1]))).collect();
            for (&(a, b), &count) in &directed {
                assert_eq!(count, 1, "{sides:?}: edge {a} → {b} used {count} times");
                let inner = directed.contains_key(&(b, a));
                assert!(inner != loop_edges.contains(&(a, b)), "{sides:?}: edge {a} → {b}");
            }
            assert!(loop_edges.iter().all(|e| directed.contains_key(e)));
            // Counter-clockwise like the boundary loop.
            for q in &pattern.quads {
                let p: Vec<Vec3> = q.iter().map(|&v| pattern.position(&old, v)).collect();
                let area: f64 = (0..4).map(|i| p[i].x * p[(i + 1) % 4].y - p[(i + 1) % 4].x * p[i].y).sum();
                assert!(area > 0.0, "{sides:?}: quad {q:?} has area {area}");
            }
        }
    }

    #[test]
    fn spokes_split_each_side_into_its_two_neighbours_spokes() {
        // A triangle of sides 4, 4, 4: spokes 2 each.
        assert_eq!(spokes(&[4, 4, 4]), Some(vec![2, 2, 2]));
        // Sides 3, 5, 4: s0 = (5 + 4 − 3)/2 = 3, s1 = (4 + 3 − 5)/2 = 1, s2 = (3 + 5 − 4)/2 = 2.
        let s = spokes(&[3, 5, 4]).unwrap();
        assert_eq!(s, vec![3, 1, 2]);
        for i in 0..3 {
            assert_eq!([3, 5, 4][i], s[(i + 2) % 3] + s[(i + 1) % 3]);
        }
        // Odd perimeter or a side longer than the two others: no pattern.
        assert_eq!(spokes(&[3, 4, 4]), None);
        assert_eq!(spokes(&[6, 2, 2]), None);
        // A pentagon of sides 2: spokes 1.
        assert_eq!(spokes(&[2; 5]), Some(vec![1; 5]));
        let l = [3, 4, 5, 4, 4];
        let s = spokes(&l).unwrap();
        for i in 0..5 {
            assert_eq!(l[i], s[(i + 4) % 5] + s[(i + 1) % 5], "{s:?}");
        }
        assert_eq!(spokes(&[2; 4]), None);
    }
}
