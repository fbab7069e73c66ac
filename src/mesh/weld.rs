//! Vertex welding: merge vertices that coincide exactly, then vertices
//! closer than a tolerance relative to the model size.
//!
//! **Exact weld.** Two vertices merge when their coordinates are bitwise
//! equal after mapping `−0.0` to `0.0` (NaN cannot occur: readers reject it).
//! Grouping equal coordinate bits ([`super::equal_keys`], partitioned hash
//! tables on the pool) finds them in `O(n)`; the merged vertex keeps its
//! first occurrence's position and ids follow the order of first occurrence.
//!
//! **Tolerance weld.** With `δ = tolerance_rel · D`, `D` the bounding-box
//! diagonal of the exactly-welded vertices, vertices `p`, `q` with
//! `|p − q| ≤ δ` are joined, and welding takes the transitive closure of that
//! relation (union–find): a cluster is a connected component of the graph
//! "closer than δ". Only **candidates** take part: the vertices of an edge
//! that an odd number of triangles use (after the exact weld: the open
//! sides of a crack, and boundaries) and the ends of edges no longer than δ
//! ([`tolerance_candidates`]). A vertex all of whose edges are shared by two
//! triangles lies inside a surface that is already closed around it; joining
//! it to a vertex of another sheet that merely comes within δ (two parts
//! touching) would make a non-manifold vertex, not close a crack. This is
//! also how mesh-repair tools close cracks (admesh's `--nearby` matches only
//! unconnected facet edges), and it makes the tolerance weld of a closed
//! upload one pass over its triangles.
//! Close pairs among the candidates come from a spatial hash grid of cell size
//! `h = 8δ`: for a point only the cells overlapping the box `p ± 1.01δ` are
//! visited (one to eight, about two on average). The cells are matched by
//! grouping equal cell keys, not by one lookup per point in a global table,
//! and the pairs are checked on the pool ([`weld_within`]). The cost is
//! `O(n)` for meshes whose vertices are not much denser than δ; there is no
//! `O(n²)` pass.
//! Each cluster keeps the position of its lowest-index vertex, so welding
//! never moves a vertex to a place that was not in the input.
//!
//! **Work bound.** Real meshes have a few candidates per vertex. A file
//! whose vertices are packed much closer than δ (hundreds of thousands within
//! a few δ of each other) would make the pair scan quadratic; to keep a
//! hostile upload from stalling a worker, the scan stops after
//! `64·n + 10⁶` distance checks and the tolerance weld is abandoned (the
//! exact weld stands) and reported as such ([`Weld::abandoned`]).
//!
//! A relative tolerance below 1e-14 (or not finite) is treated as 0: such a
//! δ is below the resolution of `f64` coordinates at model scale, where only
//! the exact weld is meaningful.
//!
//! Why relative to `D`: the corpus has models 0.05 units across and
//! geological models in UTM metres (10⁵ across, coordinates near 4·10⁶);
//! cracks from coordinate noise (1e-16 … 1e-15 absolute) close with
//! `1e-6 · D` in both.

use crate::geom::{BoundingBox, Vec3};
use crate::mesh::components::DisjointSets;
use crate::mesh::equal_keys::first_index_of_equal_key;
use rayon::prelude::*;
use std::hash::BuildHasher;

/// Smallest relative tolerance applied (see the module doc).
pub const MIN_RELATIVE_TOLERANCE: f64 = 1e-14;

/// The result of [`weld_by_tolerance`].
#[derive(Debug, Clone, PartialEq)]
pub struct Weld {
    /// New index of every vertex given.
    pub new_index: Vec<u32>,
    /// Positions of the welded vertices (each its cluster's lowest-index position).
    pub positions: Vec<Vec3>,
    /// Vertices removed by the tolerance weld.
    pub n_welded: usize,
    /// Absolute tolerance δ used; 0 when the relative tolerance is below
    /// [`MIN_RELATIVE_TOLERANCE`] (nothing is welded).
    pub tolerance: f64,
    /// True when the tolerance weld hit its work bound and was not applied.
    pub abandoned: bool,
}

/// The tolerance weld of the module doc: joins the candidates of
/// `triangles` (indices into `positions`, which are exactly welded, the
/// triangles without repeated vertices or duplicates — a duplicate would
/// make the edges of a crack look shared) within `tolerance_rel · D`.
pub fn weld_by_tolerance(positions: Vec<Vec3>, triangles: &[[u32; 3]], tolerance_rel: f64) -> Weld {
    let diagonal = BoundingBox::of_points(&positions).map_or(0.0, |b| b.diagonal());
    let tolerance = if tolerance_rel.is_finite() && tolerance_rel >= MIN_RELATIVE_TOLERANCE && diagonal.is_finite() {
        tolerance_rel * diagonal
    } else {
        0.0
    };
    let unchanged = |positions: Vec<Vec3>, tolerance, abandoned| Weld {
        new_index: (0..positions.len() as u32).collect(),
        positions,
        n_welded: 0,
        tolerance,
        abandoned,
    };
    if tolerance <= 0.0 {
        return unchanged(positions, 0.0, false);
    }
    let candidates = tolerance_candidates(triangles, &positions, tolerance);
    if candidates.is_empty() {
        return unchanged(positions, tolerance, false);
    }
    let candidate_positions: Vec<Vec3> = candidates.iter().map(|&v| positions[v as usize]).collect();
    let Some((cluster_of_candidate, _)) = weld_within(&candidate_positions, tolerance) else {
        return unchanged(positions, tolerance, true);
    };
    // The lowest id of each cluster (candidates are increasing, so its first
    // candidate) represents it.
    let mut representative = vec![u32::MAX; candidates.len()];
    for (&c, &v) in cluster_of_candidate.iter().zip(&candidates) {
        if representative[c as usize] == u32::MAX {
            representative[c as usize] = v;
        }
    }
    let mut first: Vec<u32> = (0..positions.len() as u32).collect();
    for (&c, &v) in cluster_of_candidate.iter().zip(&candidates) {
        first[v as usize] = representative[c as usize];
    }
    let (new_index, kept) = dense_ids_of_firsts(&first);
    Weld {
        new_index,
        n_welded: positions.len() - kept.len(),
        positions: kept.iter().map(|&v| positions[v as usize]).collect(),
        tolerance,
        abandoned: false,
    }
}

/// The vertices the tolerance weld may join, increasing: those with an edge
/// that an odd number of `triangles` use, and the ends of edges no longer
/// than `tolerance`.
///
/// Odd use is found without an edge table: every triangle XORs, for each of
/// its edges `{a, b}`, `h(b)` into `a`'s word and `h(a)` into `b`'s, with `h`
/// a bijection of the id salted by a random seed. An edge used twice cancels,
/// so a word is non-zero exactly when some edge of the vertex is used an odd
/// number of times — always for one or two such edges (the usual boundary
/// vertex: `h` is a bijection that is never 0 on ids), and but for a 2⁻⁶⁴
/// coincidence that an upload cannot aim at (the seed is random) for more.
/// XOR is associative, so the answer does not depend on the thread count.
pub fn tolerance_candidates(triangles: &[[u32; 3]], positions: &[Vec3], tolerance: f64) -> Vec<u32> {
    let n = positions.len();
    // High bits set: `seed ^ v` is never 0 for a 32-bit id, and `mix(0) = 0` only.
    let seed = foldhash::fast::RandomState::default().hash_one(0u64) | (1 << 63);
    let h = |v: u32| mix64(seed ^ u64::from(v));
    let tol2 = tolerance * tolerance;
    // One word array per chunk: at most MAX_PARITY_CHUNKS of them (memory
    // is 8 bytes per vertex each), and at least PARITY_CHUNK_MIN triangles
    // per chunk.
    let chunks = rayon::current_num_threads().clamp(1, MAX_PARITY_CHUNKS);
    let per = triangles.len().div_ceil(chunks).max(PARITY_CHUNK_MIN);
    let (words, mut short) = triangles
        .par_chunks(per)
        .map(|chunk| {
            let mut words = vec![0u64; n];
            let mut short = Vec::new();
            for t in chunk {
                for i in 0..3 {
                    let (a, b) = (t[i], t[(i + 1) % 3]);
                    words[a as usize] ^= h(b);
                    words[b as usize] ^= h(a);
                    if a != b && (positions[a as usize] - positions[b as usize]).norm_squared() <= tol2 {
                        short.extend([a, b]);
                    }
                }
            }
            (words, short)
        })
        .reduce(
            || (Vec::new(), Vec::new()),
            |(mut w, mut s), (w2, s2)| {
                if w.is_empty() {
                    w = w2;
                } else if !w2.is_empty() {
                    w.par_iter_mut().zip(&w2).for_each(|(x, y)| *x ^= y);
                }
                s.extend(s2);
                (w, s)
            },
        );
    let mut out: Vec<u32> = words.par_iter().enumerate().filter(|&(_, &w)| w != 0).map(|(v, _)| v as u32).collect();
    if !short.is_empty() {
        out.append(&mut short);
        out.par_sort_unstable();
        out.dedup();
    }
    out
}

/// Most word arrays [`tolerance_candidates`] fills side by side.
const MAX_PARITY_CHUNKS: usize = 4;

/// Fewest triangles per chunk of [`tolerance_candidates`] (below, one array
/// is cheaper than combining several).
const PARITY_CHUNK_MIN: usize = 1 << 16;

/// The 64-bit finalizer of SplitMix64: a bijection with good avalanche,
/// `mix64(0) = 0`.
#[inline]
fn mix64(mut x: u64) -> u64 {
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// Coordinate bits with `−0.0` mapped to `0.0`.
#[inline]
fn exact_key(p: &Vec3) -> [u64; 3] {
    [p.x, p.y, p.z].map(|c| if c == 0.0 { 0u64 } else { c.to_bits() })
}

/// A coordinate key hashed as its words, one `write_u64`/`write_u32` each:
/// the derived `Hash` of an array hashes a length and a byte slice, which
/// costs more than the grouping's table probe itself.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Words<T, const N: usize>([T; N]);

impl<const N: usize> std::hash::Hash for Words<u64, N> {
    #[inline]
    fn hash<H: std::hash::Hasher>(&self, h: &mut H) {
        self.0.iter().for_each(|&w| h.write_u64(w));
    }
}

impl<const N: usize> std::hash::Hash for Words<u32, N> {
    #[inline]
    fn hash<H: std::hash::Hasher>(&self, h: &mut H) {
        self.0.iter().for_each(|&w| h.write_u32(w));
    }
}

/// The key of [`exact_key`] in 12 bytes for a coordinate exact in `f32`
/// (`−0.0` mapped to `0.0`): equal exactly when the `f64` keys are.
#[inline]
fn exact_key_f32(p: &Vec3) -> [u32; 3] {
    [p.x, p.y, p.z].map(|c| if c == 0.0 { 0u32 } else { (c as f32).to_bits() })
}

/// Merge bitwise-equal vertices. Returns the new index of every vertex and
/// the distinct positions in order of first occurrence.
///
/// When every coordinate is exactly an `f32` (binary STL, the common large
/// input) the keys are the 12 bytes of the `f32` bits instead of 24: the
/// grouping moves every key twice, so half the key is less memory traffic,
/// with the same answer.
pub fn weld_exact(positions: &[Vec3]) -> (Vec<u32>, Vec<Vec3>) {
    let first = if crate::geom::every_coordinate_is_f32(positions) {
        first_index_of_equal_key(positions.len(), |i| Words(exact_key_f32(&positions[i])))
    } else {
        first_index_of_equal_key(positions.len(), |i| Words(exact_key(&positions[i])))
    };
    let (new_index, kept) = dense_ids_of_firsts(&first);
    (new_index, kept.par_iter().map(|&i| positions[i as usize]).collect())
}

/// Items per chunk of the parallel numbering of first occurrences.
const DENSE_CHUNK: usize = 1 << 16;

/// Dense ids `0..k`, numbered in order of first occurrence, from
/// first-occurrence indices (`first[i] <= i`, `first[first[i]] == first[i]`).
/// Returns the id of every item and the first item of every id. Chunk by
/// chunk on the pool: each chunk lists its first occurrences, a running
/// count gives each chunk its first id, and each chunk numbers its own.
fn dense_ids_of_firsts(first: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let firsts_per_chunk: Vec<Vec<u32>> = first
        .par_chunks(DENSE_CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let base = c * DENSE_CHUNK;
            (base..base + chunk.len()).filter(|&i| first[i] as usize == i).map(|i| i as u32).collect()
        })
        .collect();
    let mut start = 0u32;
    let starts: Vec<u32> = firsts_per_chunk
        .iter()
        .map(|f| {
            let s = start;
            start += f.len() as u32;
            s
        })
        .collect();
    // Only the entries of first occurrences are written and read.
    let mut id_of_first = vec![u32::MAX; first.len()];
    id_of_first.par_chunks_mut(DENSE_CHUNK).zip(&firsts_per_chunk).zip(&starts).enumerate().for_each(
        |(c, ((ids, firsts), &s))| {
            for (k, &i) in firsts.iter().enumerate() {
                ids[i as usize - c * DENSE_CHUNK] = s + k as u32;
            }
        },
    );
    let new_index = first.par_iter().map(|&f| id_of_first[f as usize]).collect();
    (new_index, firsts_per_chunk.concat())
}

/// The grid of the tolerance weld: cells of size `h` from the box corner.
struct Grid {
    origin: Vec3,
    h: f64,
}

impl Grid {
    /// Cell coordinate of `c` along `axis`.
    #[inline]
    fn coord(&self, c: f64, axis: usize) -> i64 {
        ((c - self.origin[axis]) / self.h).floor() as i64
    }

    /// The cell containing `p`.
    #[inline]
    fn cell(&self, p: &Vec3) -> [i64; 3] {
        [self.coord(p.x, 0), self.coord(p.y, 1), self.coord(p.z, 2)]
    }

    /// The cells other than `p`'s own that the box `p ± pad` overlaps (at
    /// most 7, as `pad` is below `h / 2`), in a fixed order, and their count.
    #[inline]
    fn other_cells(&self, p: &Vec3, pad: f64) -> ([[i64; 3]; 8], usize) {
        let own = self.cell(p);
        let lo = [self.coord(p.x - pad, 0), self.coord(p.y - pad, 1), self.coord(p.z - pad, 2)];
        let hi = [self.coord(p.x + pad, 0), self.coord(p.y + pad, 1), self.coord(p.z + pad, 2)];
        let mut out = [[0i64; 3]; 8];
        let mut k = 0;
        for cx in lo[0]..=hi[0] {
            for cy in lo[1]..=hi[1] {
                for cz in lo[2]..=hi[2] {
                    let c = [cx, cy, cz];
                    if c != own && k < 8 {
                        out[k] = c;
                        k += 1;
                    }
                }
            }
        }
        (out, k)
    }
}

/// Points of every occupied cell as compressed rows indexed by the cell's
/// first point: `members[offsets[r]..offsets[r + 1]]`, increasing, for a
/// first point `r` (empty rows for the other points).
fn members_by_first_point(first: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let n = first.len();
    let mut offsets = vec![0u32; n + 1];
    for &f in first {
        offsets[f as usize + 1] += 1;
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut members = vec![0u32; n];
    for (p, &f) in first.iter().enumerate() {
        members[fill[f as usize] as usize] = p as u32;
        fill[f as usize] += 1;
    }
    (offsets, members)
}

/// Join vertices closer than `tolerance` (absolute, > 0), transitively.
/// Returns the new index of every vertex and one position per cluster (its
/// lowest-index vertex's), clusters numbered by their lowest index; `None`
/// when the work bound of the module doc is exceeded.
///
/// The candidates of a point `p` are the points of lower index in the cells
/// its box `p ± 1.01δ` overlaps. Cells are found by grouping equal keys
/// ([`first_index_of_equal_key`]) over the points' own cells followed by the
/// other cells their boxes overlap ("visits"): a visit whose first equal key
/// is a point's own cell finds that cell's points. Each pair is a candidate
/// once (from the point of higher index). Counting, checking and grouping
/// run on the pool; the result does not depend on the thread count.
pub fn weld_within(positions: &[Vec3], tolerance: f64) -> Option<(Vec<u32>, Vec<Vec3>)> {
    let n = positions.len();
    let Some(bbox) = BoundingBox::of_points(positions) else { return Some((Vec::new(), Vec::new())) };
    let h = 8.0 * tolerance;
    // Cells per axis must fit i64 comfortably; a tolerance that fine welds nothing new.
    if h.is_nan() || h <= 0.0 || (bbox.max - bbox.min).max() / h > 1e15 {
        return Some(((0..n as u32).collect(), positions.to_vec()));
    }
    let budget = 64 * n as u64 + 1_000_000;
    let grid = Grid { origin: bbox.min, h };
    let pad = 1.01 * tolerance;
    let visits: Vec<([i64; 3], u32)> = positions
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, p)| {
            let (cells, k) = grid.other_cells(p, pad);
            cells.into_iter().take(k).map(move |c| (c, i as u32))
        })
        .collect();
    let first = first_index_of_equal_key(n + visits.len(), |j| {
        let cell = if j < n { grid.cell(&positions[j]) } else { visits[j - n].0 };
        Words(cell.map(|c| c as u64))
    });
    let (offsets, members) = members_by_first_point(&first[..n]);
    let cell_points = |r: u32| &members[offsets[r as usize] as usize..offsets[r as usize + 1] as usize];
    // Candidates of point `p` in the cell whose first point is `r`: its points below `p`.
    let below = |r: u32, p: u32| {
        let pts = cell_points(r);
        &pts[..pts.partition_point(|&q| q < p)]
    };
    // A visit finds points only when its cell is some point's own cell.
    let visited_cell = |j: usize| Some(first[n + j]).filter(|&r| (r as usize) < n);

    let n_checks: u64 = (0..n as u32).into_par_iter().map(|p| below(first[p as usize], p).len() as u64).sum::<u64>()
        + (0..visits.len())
            .into_par_iter()
            .map(|j| visited_cell(j).map_or(0, |r| below(r, visits[j].1).len() as u64))
            .sum::<u64>();
    if n_checks > budget {
        return None;
    }
    let tol2 = tolerance * tolerance;
    let close = |p: u32, q: u32| (positions[q as usize] - positions[p as usize]).norm_squared() <= tol2;
    let mut pairs: Vec<(u32, u32)> = (0..n as u32)
        .into_par_iter()
        .flat_map_iter(|p| below(first[p as usize], p).iter().filter(move |&&q| close(p, q)).map(move |&q| (q, p)))
        .collect();
    pairs.par_extend((0..visits.len()).into_par_iter().flat_map_iter(|j| {
        let p = visits[j].1;
        visited_cell(j).map(|r| below(r, p)).unwrap_or(&[]).iter().filter(move |&&q| close(p, q)).map(move |&q| (q, p))
    }));
    if pairs.is_empty() {
        return Some(((0..n as u32).collect(), positions.to_vec()));
    }

    let mut sets = DisjointSets::new(n);
    for &(q, p) in &pairs {
        sets.union(q, p);
    }
    let mut label_of_root = vec![u32::MAX; n];
    let mut new_index = Vec::with_capacity(n);
    let mut out = Vec::new();
    for (i, p) in positions.iter().enumerate() {
        let r = sets.find(i as u32) as usize;
        if label_of_root[r] == u32::MAX {
            label_of_root[r] = out.len() as u32;
            out.push(*p);
        }
        new_index.push(label_of_root[r]);
    }
    Some((new_index, out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// Numbered chunk by chunk, the ids are the one-pass numbering in order
    /// of first occurrence, also where groups straddle chunks.
    #[test]
    fn dense_ids_over_many_chunks_are_numbered_in_order_of_first_occurrence() {
        let mut rng = StdRng::seed_from_u64(3);
        let n = 5 * DENSE_CHUNK + 123;
        let keys: Vec<u32> = (0..n).map(|_| rng.random_range(0..150_000u32)).collect();
        let mut first_of_key = std::collections::HashMap::new();
        let first: Vec<u32> = (0..n).map(|i| *first_of_key.entry(keys[i]).or_insert(i as u32)).collect();
        let (ids, kept) = dense_ids_of_firsts(&first);
        let (mut want_ids, mut want_kept, mut id_of_key) = (Vec::new(), Vec::new(), std::collections::HashMap::new());
        for (i, k) in keys.iter().enumerate() {
            let id = *id_of_key.entry(k).or_insert_with(|| {
                want_kept.push(i as u32);
                want_kept.len() as u32 - 1
            });
            want_ids.push(id);
        }
        assert_eq!(ids, want_ids);
        assert_eq!(kept, want_kept);
    }

    /// Triangles `[3k, 3k + 1, 3k + 2]` over `n ≥ 3` points, the last one
    /// wrapping around to points 0 and 1: every point has an edge used once,
    /// so every point is a tolerance-weld candidate.
    fn soup(n: usize) -> Vec<[u32; 3]> {
        let n = n as u32;
        (0..n.div_ceil(3)).map(|k| [3 * k, (3 * k + 1) % n, (3 * k + 2) % n]).collect()
    }

    #[test]
    fn exact_weld_merges_bitwise_equal_and_signed_zeros() {
        let p = vec![
            Vec3::new(0.0, 1.0, 2.0),
            Vec3::new(-0.0, 1.0, 2.0),
            Vec3::new(0.0, 1.0, 2.0 + 1e-15),
            Vec3::new(0.0, 1.0, 2.0),
            Vec3::new(1.0, 0.0, 2.0),
        ];
        let (idx, uniq) = weld_exact(&p);
        assert_eq!(idx, vec![0, 0, 1, 0, 2]);
        assert_eq!(uniq.len(), 3);
        // The three exact vertices as one open triangle: all are candidates.
        let w = weld_by_tolerance(uniq.clone(), &[[0, 1, 2]], 0.0);
        assert_eq!((w.n_welded, w.tolerance), (0, 0.0));
        let w = weld_by_tolerance(uniq.clone(), &[[0, 1, 2]], 1e-6);
        assert_eq!(w.n_welded, 1);
        assert!((w.tolerance - 1e-6 * 2f64.sqrt()).abs() < 1e-18);
        assert_eq!(w.new_index, vec![0, 0, 1]);
        assert_eq!(w.positions, vec![p[0], p[4]]);
    }

    /// The tolerance weld equals the brute-force transitive closure.
    #[test]
    fn tolerance_weld_matches_brute_force() {
        let mut rng = StdRng::seed_from_u64(7);
        for trial in 0..20 {
            let tol = 0.02;
            let mut pts: Vec<Vec3> = (0..300)
                .map(|_| Vec3::new(rng.random::<f64>(), rng.random::<f64>(), rng.random::<f64>() * 0.1))
                .collect();
            // Near-duplicates, some exactly at the tolerance, some in chains.
            for k in 0..60 {
                let base = pts[k * 3];
                let d = if k % 3 == 0 { tol } else { tol * rng.random::<f64>() };
                let dir = Vec3::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5)
                    .normalize();
                pts.push(base + dir * d * 0.999_999);
            }
            let (idx, out) = weld_within(&pts, tol).unwrap();
            let n = pts.len();
            let mut sets = DisjointSets::new(n);
            for i in 0..n {
                for j in 0..i {
                    if (pts[i] - pts[j]).norm_squared() <= tol * tol {
                        sets.union(i as u32, j as u32);
                    }
                }
            }
            let (labels, k) = sets.labels();
            assert_eq!(out.len(), k, "trial {trial}");
            for i in 0..n {
                for j in 0..i {
                    assert_eq!(idx[i] == idx[j], labels[i] == labels[j], "trial {trial}: {i} {j}");
                }
                assert_eq!(out[idx[i] as usize], pts[(0..n).find(|&j| idx[j] == idx[i]).unwrap()]);
            }
        }
    }

    /// Clusters by an independent method: a sweep over points sorted by x,
    /// checking every pair whose x differ by at most the tolerance.
    fn sweep_clusters(pts: &[Vec3], tol: f64) -> Vec<u32> {
        let mut order: Vec<usize> = (0..pts.len()).collect();
        order.sort_by(|&a, &b| pts[a].x.total_cmp(&pts[b].x));
        let mut sets = DisjointSets::new(pts.len());
        for (k, &i) in order.iter().enumerate() {
            for &j in order[k + 1..].iter().take_while(|&&j| pts[j].x - pts[i].x <= tol) {
                if (pts[i] - pts[j]).norm_squared() <= tol * tol {
                    sets.union(i as u32, j as u32);
                }
            }
        }
        sets.labels().0
    }

    /// Above the partitioning threshold of the grouping, with near
    /// duplicates on cell faces, and identical on one and two threads.
    #[test]
    fn tolerance_weld_of_many_points_matches_a_sweep_on_any_thread_count() {
        let mut rng = StdRng::seed_from_u64(11);
        let tol = 1e-4;
        let mut pts: Vec<Vec3> =
            (0..40_000).map(|_| Vec3::new(rng.random::<f64>(), rng.random::<f64>(), rng.random::<f64>())).collect();
        for k in 0..8000 {
            let d = Vec3::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5);
            pts.push(pts[k * 5] + d.normalize() * tol * 0.999 * rng.random::<f64>());
        }
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| weld_within(&pts, tol).unwrap())
        };
        let (idx, out) = run(2);
        assert_eq!((idx.clone(), out.clone()), run(1));
        let labels = sweep_clusters(&pts, tol);
        let n_clusters = labels.iter().max().map_or(0, |&m| m as usize + 1);
        assert_eq!(out.len(), n_clusters);
        assert!(out.len() <= 40_000 && out.len() >= 32_000, "{}", out.len());
        // Same partition: the label maps agree both ways.
        let mut to_label = vec![u32::MAX; out.len()];
        for (i, &c) in idx.iter().enumerate() {
            assert!(to_label[c as usize] == u32::MAX || to_label[c as usize] == labels[i], "point {i}");
            to_label[c as usize] = labels[i];
        }
        let mut first_of_cluster = vec![usize::MAX; out.len()];
        for (i, &c) in idx.iter().enumerate().rev() {
            first_of_cluster[c as usize] = i;
        }
        for (c, &i) in first_of_cluster.iter().enumerate() {
            assert_eq!(out[c], pts[i], "cluster {c} keeps its lowest-index position");
        }
    }

    /// Both key widths: `f64` coordinates, and coordinates exact in `f32`
    /// (with signed zeros) as from binary STL.
    #[test]
    fn exact_weld_of_many_points_numbers_by_first_occurrence() {
        let mut rng = StdRng::seed_from_u64(12);
        let doubles: Vec<Vec3> = (0..20_000).map(|_| Vec3::new(rng.random(), rng.random(), rng.random())).collect();
        let mut singles: Vec<Vec3> = doubles.iter().map(|p| p.map(|c| f64::from(c as f32))).collect();
        singles[7].x = -0.0;
        singles[8].x = 0.0;
        singles[8].y = singles[7].y;
        singles[8].z = singles[7].z;
        for distinct in [doubles, singles] {
            check_exact_weld_numbering(&distinct, &mut rng);
        }
    }

    /// 90000 draws from `distinct`, welded, against a hash map numbering.
    fn check_exact_weld_numbering(distinct: &[Vec3], rng: &mut StdRng) {
        let pts: Vec<Vec3> = (0..90_000).map(|_| distinct[rng.random_range(0..distinct.len())]).collect();
        let (idx, uniq) = weld_exact(&pts);
        let mut seen: std::collections::HashMap<[u64; 3], u32> = Default::default();
        let mut expected = Vec::new();
        for p in &pts {
            let next = seen.len() as u32;
            expected.push(*seen.entry(exact_key(p)).or_insert(next));
        }
        assert_eq!(idx, expected);
        assert_eq!(uniq.len(), seen.len());
        assert!(idx.iter().zip(&pts).all(|(&i, p)| uniq[i as usize] == *p));
    }

    #[test]
    fn tiny_or_invalid_tolerances_only_weld_exactly() {
        let p = vec![Vec3::zeros(), Vec3::new(1e-20, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)];
        for rel in [0.0, 1e-16, f64::NAN, -1.0, f64::INFINITY] {
            let w = weld_by_tolerance(p.clone(), &soup(p.len()), rel);
            assert_eq!((w.positions.len(), w.tolerance), (3, 0.0), "{rel}");
        }
        assert_eq!(weld_by_tolerance(p.clone(), &soup(p.len()), 1e-6).positions.len(), 2);
        assert!(weld_by_tolerance(Vec::new(), &[], 1e-6).positions.is_empty());
    }

    #[test]
    fn packed_clusters_hit_the_work_bound() {
        // 4000 distinct points within 1e-9 of each other plus one far point:
        // 8 million pairs are within the tolerance.
        let mut p: Vec<Vec3> = (0..4000).map(|i| Vec3::new(i as f64 * 1e-13, 0.0, 0.0)).collect();
        p.push(Vec3::new(1.0, 1.0, 1.0));
        let w = weld_by_tolerance(p.clone(), &soup(p.len()), 1e-6);
        assert!(w.abandoned);
        assert_eq!((w.positions.len(), w.n_welded), (4001, 0));
        // Fewer points stay within the bound and weld.
        let w = weld_by_tolerance(p[3900..].to_vec(), &soup(101), 1e-6);
        assert!(!w.abandoned);
        assert_eq!(w.positions.len(), 2);
    }

    /// Only the vertices of a crack (edges used once) and of edges shorter
    /// than the tolerance are candidates; a closed surface has none, and a
    /// vertex of it that comes within δ of another sheet is not joined.
    #[test]
    fn candidates_are_crack_sides_and_short_edges() {
        let m = crate::mesh::fixtures::icosphere(2);
        let tris: Vec<[u32; 3]> = m.triangles.iter().map(|t| t.map(|v| v.0)).collect();
        assert!(tolerance_candidates(&tris, &m.positions, 1e-6).is_empty());
        // A second sphere whose first vertex lies 1e-9 from the first's: both
        // closed, so nothing is welded.
        let n = m.positions.len() as u32;
        let mut p = m.positions.clone();
        let shift = m.positions[0] * 2.0 + Vec3::new(1e-9, 0.0, 0.0);
        p.extend(m.positions.iter().map(|q| -q + shift));
        let mut t = tris.clone();
        t.extend(tris.iter().map(|t| [t[0] + n, t[2] + n, t[1] + n]));
        let w = weld_by_tolerance(p.clone(), &t, 1e-6);
        assert_eq!((w.n_welded, w.positions.len()), (0, p.len()));
        // Cut the first sphere open along a triangle's edge (its last vertex
        // replaced by a copy 1e-9 away in one triangle): the copy and the
        // edge's vertices are candidates, and the weld closes the crack.
        let [a, b, c] = tris[0];
        let mut p2 = m.positions.clone();
        p2.push(m.positions[c as usize] + Vec3::new(1e-9, 0.0, 0.0));
        let mut t2 = tris.clone();
        t2[0] = [a, b, n];
        let cand = tolerance_candidates(&t2, &p2, 1e-6);
        assert_eq!(cand, {
            let mut v = vec![a, b, c, n];
            v.sort();
            v
        });
        let w = weld_by_tolerance(p2, &t2, 1e-6);
        assert_eq!((w.n_welded, w.new_index[n as usize]), (1, w.new_index[c as usize]));
        // An edge shorter than the tolerance inside a closed surface: its ends.
        let mut p3 = m.positions.clone();
        p3[b as usize] = p3[a as usize] + Vec3::new(1e-9, 0.0, 0.0);
        assert_eq!(tolerance_candidates(&tris, &p3, 1e-6), {
            let mut v = vec![a, b];
            v.sort();
            v
        });
    }
}
