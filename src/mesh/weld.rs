//! Vertex welding: merge vertices that coincide exactly, then vertices
//! closer than a tolerance relative to the model size.
//!
//! **Exact weld.** Two vertices merge when their coordinates are bitwise
//! equal after mapping `−0.0` to `0.0` (NaN cannot occur: readers reject it).
//! A hash table of vertex indices keyed by the coordinate bits finds them in
//! one `O(n)` pass; the merged vertex keeps its first occurrence's position.
//!
//! **Tolerance weld.** With `δ = tolerance_rel · D`, `D` the bounding-box
//! diagonal of the exactly-welded vertices, vertices `p`, `q` with
//! `|p − q| ≤ δ` are joined, and welding takes the transitive closure of that
//! relation (union–find): a cluster is a connected component of the graph
//! "closer than δ". Candidates come from a spatial hash grid of cell size
//! `h = 8δ`: for a point only the cells overlapping the box `p ± 1.01δ` are
//! visited (one to eight, about two on average); its own cell needs no
//! lookup (points are chained per cell in insertion order). The cost is
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
//! exact weld stands) and reported as such ([`Weld::tolerance_weld_abandoned`]).
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
use hashbrown::HashTable;
use hashbrown::hash_table::Entry;
use std::hash::BuildHasher;

/// Smallest relative tolerance applied (see the module doc).
pub const MIN_RELATIVE_TOLERANCE: f64 = 1e-14;

/// The result of [`weld_vertices`].
#[derive(Debug, Clone, PartialEq)]
pub struct Weld {
    /// New index of every input vertex.
    pub new_index: Vec<u32>,
    /// Positions of the welded vertices (each its cluster's first input position).
    pub positions: Vec<Vec3>,
    /// Vertices removed because they coincided exactly with an earlier one.
    pub n_welded_exact: usize,
    /// Further vertices removed by the tolerance weld.
    pub n_welded_tolerance: usize,
    /// Absolute tolerance δ used; 0 when only the exact weld ran.
    pub tolerance: f64,
    /// True when the tolerance weld hit its work bound and was not applied.
    pub tolerance_weld_abandoned: bool,
}

/// Weld exactly, then within `tolerance_rel · D` (see the module doc).
pub fn weld_vertices(positions: &[Vec3], tolerance_rel: f64) -> Weld {
    let (exact_index, exact_positions) = weld_exact(positions);
    let n_welded_exact = positions.len() - exact_positions.len();
    let diagonal = BoundingBox::of_points(&exact_positions).map_or(0.0, |b| b.diagonal());
    let tolerance = if tolerance_rel.is_finite() && tolerance_rel >= MIN_RELATIVE_TOLERANCE && diagonal.is_finite() {
        tolerance_rel * diagonal
    } else {
        0.0
    };
    if tolerance <= 0.0 {
        return Weld {
            new_index: exact_index,
            positions: exact_positions,
            n_welded_exact,
            n_welded_tolerance: 0,
            tolerance: 0.0,
            tolerance_weld_abandoned: false,
        };
    }
    let Some((cluster_index, cluster_positions)) = weld_within(&exact_positions, tolerance) else {
        return Weld {
            new_index: exact_index,
            positions: exact_positions,
            n_welded_exact,
            n_welded_tolerance: 0,
            tolerance,
            tolerance_weld_abandoned: true,
        };
    };
    let n_welded_tolerance = exact_positions.len() - cluster_positions.len();
    let new_index = exact_index.iter().map(|&i| cluster_index[i as usize]).collect();
    Weld {
        new_index,
        positions: cluster_positions,
        n_welded_exact,
        n_welded_tolerance,
        tolerance,
        tolerance_weld_abandoned: false,
    }
}

/// Coordinate bits with `−0.0` mapped to `0.0`.
#[inline]
fn exact_key(p: &Vec3) -> [u64; 3] {
    [p.x, p.y, p.z].map(|c| if c == 0.0 { 0u64 } else { c.to_bits() })
}

/// Merge bitwise-equal vertices. Returns the new index of every vertex and
/// the distinct positions in order of first occurrence.
pub fn weld_exact(positions: &[Vec3]) -> (Vec<u32>, Vec<Vec3>) {
    let state = foldhash::fast::RandomState::default();
    let hash = |k: &[u64; 3]| state.hash_one(k);
    // Keys live in the table entries: one memory access per probe.
    let mut table: HashTable<([u64; 3], u32)> = HashTable::with_capacity(positions.len() / 4 + 16);
    let mut unique: Vec<Vec3> = Vec::with_capacity(positions.len() / 4 + 16);
    let mut new_index = Vec::with_capacity(positions.len());
    for p in positions {
        let k = exact_key(p);
        let id = match table.entry(hash(&k), |e| e.0 == k, |e| hash(&e.0)) {
            Entry::Occupied(o) => o.get().1,
            Entry::Vacant(v) => {
                let id = unique.len() as u32;
                v.insert((k, id));
                unique.push(*p);
                id
            }
        };
        new_index.push(id);
    }
    (new_index, unique)
}

/// Join vertices closer than `tolerance` (absolute, > 0), transitively.
/// Returns the new index of every vertex and one position per cluster (its
/// lowest-index vertex's), clusters numbered by their lowest index; `None`
/// when the work bound of the module doc is exceeded.
pub fn weld_within(positions: &[Vec3], tolerance: f64) -> Option<(Vec<u32>, Vec<Vec3>)> {
    let n = positions.len();
    let Some(bbox) = BoundingBox::of_points(positions) else { return Some((Vec::new(), Vec::new())) };
    let h = 8.0 * tolerance;
    // Cells per axis must fit i64 comfortably; a tolerance that fine welds nothing new.
    if h.is_nan() || h <= 0.0 || (bbox.max - bbox.min).max() / h > 1e15 {
        return Some(((0..n as u32).collect(), positions.to_vec()));
    }
    let mut budget = 64 * n as u64 + 1_000_000;
    let cell_of = |c: f64, axis: usize| ((c - bbox.min[axis]) / h).floor() as i64;
    let cell = |p: &Vec3| [cell_of(p.x, 0), cell_of(p.y, 1), cell_of(p.z, 2)];

    // Grid: cell → first point, `next` links the points of a cell.
    let state = foldhash::fast::RandomState::default();
    let hash = |k: &[i64; 3]| state.hash_one(k);
    let mut heads: HashTable<([i64; 3], u32)> = HashTable::with_capacity(n);
    let mut next = vec![u32::MAX; n];
    for (i, p) in positions.iter().enumerate() {
        let c = cell(p);
        match heads.entry(hash(&c), |e| e.0 == c, |e| hash(&e.0)) {
            Entry::Occupied(mut o) => {
                next[i] = o.get().1;
                o.get_mut().1 = i as u32;
            }
            Entry::Vacant(v) => {
                v.insert((c, i as u32));
            }
        }
    }

    let mut sets = DisjointSets::new(n);
    let tol2 = tolerance * tolerance;
    let pad = 1.01 * tolerance;
    for (i, p) in positions.iter().enumerate() {
        let own = cell(p);
        let lo = [cell_of(p.x - pad, 0), cell_of(p.y - pad, 1), cell_of(p.z - pad, 2)];
        let hi = [cell_of(p.x + pad, 0), cell_of(p.y + pad, 1), cell_of(p.z + pad, 2)];
        for cx in lo[0]..=hi[0] {
            for cy in lo[1]..=hi[1] {
                for cz in lo[2]..=hi[2] {
                    let c = [cx, cy, cz];
                    // In its own cell, the earlier points follow `i` in the chain.
                    let mut q = if c == own {
                        next[i]
                    } else {
                        match heads.find(hash(&c), |e| e.0 == c) {
                            Some(&(_, head)) => head,
                            None => continue,
                        }
                    };
                    while q != u32::MAX {
                        // Each pair once: q < i.
                        if (q as usize) < i {
                            if budget == 0 {
                                return None;
                            }
                            budget -= 1;
                            if (positions[q as usize] - p).norm_squared() <= tol2 {
                                sets.union(q, i as u32);
                            }
                        }
                        q = next[q as usize];
                    }
                }
            }
        }
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
        let w = weld_vertices(&p, 0.0);
        assert_eq!((w.n_welded_exact, w.n_welded_tolerance, w.tolerance), (2, 0, 0.0));
        let w = weld_vertices(&p, 1e-6);
        assert_eq!((w.n_welded_exact, w.n_welded_tolerance), (2, 1));
        assert!((w.tolerance - 1e-6 * 2f64.sqrt()).abs() < 1e-18);
        assert_eq!(w.new_index, vec![0, 0, 0, 0, 1]);
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

    #[test]
    fn tiny_or_invalid_tolerances_only_weld_exactly() {
        let p = vec![Vec3::zeros(), Vec3::new(1e-20, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)];
        for rel in [0.0, 1e-16, f64::NAN, -1.0, f64::INFINITY] {
            let w = weld_vertices(&p, rel);
            assert_eq!((w.positions.len(), w.tolerance), (3, 0.0), "{rel}");
        }
        assert_eq!(weld_vertices(&p, 1e-6).positions.len(), 2);
        assert!(weld_vertices(&[], 1e-6).positions.is_empty());
    }

    #[test]
    fn packed_clusters_hit_the_work_bound() {
        // 4000 distinct points within 1e-9 of each other plus one far point:
        // 8 million pairs are within the tolerance.
        let mut p: Vec<Vec3> = (0..4000).map(|i| Vec3::new(i as f64 * 1e-13, 0.0, 0.0)).collect();
        p.push(Vec3::new(1.0, 1.0, 1.0));
        let w = weld_vertices(&p, 1e-6);
        assert!(w.tolerance_weld_abandoned);
        assert_eq!((w.positions.len(), w.n_welded_tolerance), (4001, 0));
        // Fewer points stay within the bound and weld.
        let w = weld_vertices(&p[3900..], 1e-6);
        assert!(!w.tolerance_weld_abandoned);
        assert_eq!(w.positions.len(), 2);
    }
}
