//! Grouping of equal keys on the pool: for every item, the index of the
//! first item whose key is equal to its own.
//!
//! Welding (equal coordinates, equal grid cells) and duplicate-triangle
//! removal (equal vertex triples) ask exactly this. One hash table over
//! millions of keys misses the cache on nearly every probe, and it is
//! sequential. Instead the items are split by the top bits of their key's
//! hash into buckets of a few thousand (a radix partition: each chunk of
//! the input counting-sorts its indices by bucket), and every bucket is
//! grouped in its own small table, which stays in cache, buckets in
//! parallel.
//!
//! **Determinism.** A bucket receives its items chunk by chunk in input
//! order, so within a bucket indices increase and the first index a table
//! stores for a key is the key's first occurrence in the whole input. The
//! result is a property of the keys alone: the same for every thread count,
//! chunk size and hash seed (the seed is random per call, so a crafted
//! input cannot aim all its keys at one bucket).
//!
//! Cost: `O(n)` expected, the key function evaluated twice per item, about
//! `4n` bytes per pass of index scratch.

use hashbrown::HashTable;
use hashbrown::hash_table::Entry;
use rayon::prelude::*;
use std::hash::{BuildHasher, Hash};

/// Items per partition chunk (a unit of parallel work; no effect on results).
const CHUNK: usize = 1 << 16;
/// Below this many items one table is faster than partitioning.
const SEQUENTIAL_BELOW: usize = 1 << 15;
/// Target number of items per bucket (its table then fits in L2).
const ITEMS_PER_BUCKET: usize = 4096;

/// For every item `i < n`, the smallest `j` with `key(j) == key(i)` (so
/// `j == i` exactly for first occurrences). `key` must be a pure function
/// of the index.
///
/// # Panics
/// When `n` exceeds `u32::MAX` (callers hold 32-bit ids).
pub fn first_index_of_equal_key<K, F>(n: usize, key: F) -> Vec<u32>
where
    K: Eq + Hash + Copy + Send + Sync,
    F: Fn(usize) -> K + Sync,
{
    assert!(n <= u32::MAX as usize, "{n} items do not fit 32-bit ids");
    let state = foldhash::fast::RandomState::default();
    if n < SEQUENTIAL_BELOW {
        return first_in_one_table(0..n, &key, &state);
    }
    let bits = bucket_bits(n);
    let n_buckets = 1usize << bits;
    let bucket_of = |i: usize| (state.hash_one(key(i)) >> (64 - bits)) as usize;
    let parts: Vec<ChunkPartition> =
        (0..n.div_ceil(CHUNK)).into_par_iter().map(|c| partition_chunk(c, n, n_buckets, &bucket_of)).collect();
    let firsts: Vec<Vec<u32>> = (0..n_buckets)
        .into_par_iter()
        .map(|b| first_in_one_table(parts.iter().flat_map(|p| p.items(b)).map(|&i| i as usize), &key, &state))
        .collect();
    scatter_to_items(n, n_buckets, &parts, &firsts)
}

/// The indices of one chunk, counting-sorted by bucket.
struct ChunkPartition {
    /// The chunk's item indices, bucket by bucket, increasing within a bucket.
    order: Vec<u32>,
    /// `order[offsets[b]..offsets[b + 1]]` are the items of bucket `b`.
    offsets: Vec<u32>,
}

impl ChunkPartition {
    /// The chunk's items that fall in bucket `b`.
    fn items(&self, b: usize) -> &[u32] {
        &self.order[self.offsets[b] as usize..self.offsets[b + 1] as usize]
    }
}

/// Number of hash bits that select a bucket: about [`ITEMS_PER_BUCKET`]
/// items per bucket, between 2 and 2^14 buckets.
fn bucket_bits(n: usize) -> u32 {
    (n / ITEMS_PER_BUCKET).max(1).next_power_of_two().trailing_zeros().clamp(1, 14)
}

/// Counting sort of chunk `c`'s indices by bucket.
fn partition_chunk(
    c: usize,
    n: usize,
    n_buckets: usize,
    bucket_of: &(impl Fn(usize) -> usize + Sync),
) -> ChunkPartition {
    let range = c * CHUNK..((c + 1) * CHUNK).min(n);
    let buckets: Vec<u32> = range.clone().map(|i| bucket_of(i) as u32).collect();
    let mut offsets = vec![0u32; n_buckets + 1];
    for &b in &buckets {
        offsets[b as usize + 1] += 1;
    }
    for b in 0..n_buckets {
        offsets[b + 1] += offsets[b];
    }
    let mut fill = offsets.clone();
    let mut order = vec![0u32; buckets.len()];
    for (i, &b) in range.zip(&buckets) {
        order[fill[b as usize] as usize] = i as u32;
        fill[b as usize] += 1;
    }
    ChunkPartition { order, offsets }
}

/// First index of each item's key among `items` (taken in the given,
/// increasing order), in the order of `items`.
fn first_in_one_table<K, F>(
    items: impl Iterator<Item = usize> + Clone,
    key: &F,
    state: &foldhash::fast::RandomState,
) -> Vec<u32>
where
    K: Eq + Hash + Copy,
    F: Fn(usize) -> K,
{
    let n = items.clone().count();
    // Keys live in the table entries: one memory access per probe.
    let mut table: HashTable<(K, u32)> = HashTable::with_capacity(n);
    let mut out = Vec::with_capacity(n);
    for i in items {
        let k = key(i);
        let first = match table.entry(state.hash_one(k), |e| e.0 == k, |e| state.hash_one(e.0)) {
            Entry::Occupied(o) => o.get().1,
            Entry::Vacant(v) => {
                v.insert((k, i as u32));
                i as u32
            }
        };
        out.push(first);
    }
    out
}

/// Puts each bucket's answers back in item order: chunk `c` reads, for
/// every bucket, the run of answers that bucket produced for its items.
fn scatter_to_items(n: usize, n_buckets: usize, parts: &[ChunkPartition], firsts: &[Vec<u32>]) -> Vec<u32> {
    // start[c][b]: where chunk c's items begin in bucket b's answers.
    let mut running = vec![0u32; n_buckets];
    let starts: Vec<Vec<u32>> = parts
        .iter()
        .map(|p| {
            let s = running.clone();
            for (b, r) in running.iter_mut().enumerate() {
                *r += p.offsets[b + 1] - p.offsets[b];
            }
            s
        })
        .collect();
    let mut out = vec![0u32; n];
    out.par_chunks_mut(CHUNK).zip(parts.par_iter().zip(&starts)).enumerate().for_each(|(c, (out, (p, start)))| {
        let base = c * CHUNK;
        for b in 0..n_buckets {
            let answers = &firsts[b][start[b] as usize..];
            for (&i, &first) in p.items(b).iter().zip(answers) {
                out[i as usize - base] = first;
            }
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// The definition, quadratic.
    fn brute_force(keys: &[u32]) -> Vec<u32> {
        keys.iter().map(|k| keys.iter().position(|j| j == k).unwrap() as u32).collect()
    }

    #[test]
    fn matches_the_definition_below_and_above_the_partition_threshold() {
        let mut rng = StdRng::seed_from_u64(3);
        for n in [0usize, 1, 7, 1000, SEQUENTIAL_BELOW + 17] {
            let keys: Vec<u32> = (0..n).map(|_| rng.random_range(0..(n as u32 / 3).max(1))).collect();
            let got = first_index_of_equal_key(n, |i| keys[i]);
            if n <= 1000 {
                assert_eq!(got, brute_force(&keys), "n = {n}");
            } else {
                // Linear check of the definition: first[i] has i's key, is
                // not after i, and is its own first.
                let mut seen = std::collections::HashMap::new();
                for (i, &k) in keys.iter().enumerate() {
                    let first = *seen.entry(k).or_insert(i as u32);
                    assert_eq!(got[i], first, "n = {n}, item {i}");
                }
            }
        }
    }

    #[test]
    fn is_the_same_on_one_and_two_threads() {
        let mut rng = StdRng::seed_from_u64(4);
        let n = 5 * CHUNK + 123;
        let keys: Vec<[u64; 2]> = (0..n).map(|_| [rng.random_range(0..50_000), rng.random_range(0..3)]).collect();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| first_index_of_equal_key(n, |i| keys[i]))
        };
        let one = run(1);
        assert_eq!(one, run(2));
        assert!(one.iter().enumerate().all(|(i, &f)| f as usize <= i && keys[f as usize] == keys[i]));
    }
}
