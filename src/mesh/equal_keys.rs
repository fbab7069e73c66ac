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
//! Cost: `O(n)` expected, the key function evaluated once per item, and
//! scratch of one key and index per item.

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
    let parts: Vec<ChunkPartition<K>> =
        (0..n.div_ceil(CHUNK)).into_par_iter().map(|c| partition_chunk(c, n, bits, &key, &state)).collect();
    let firsts: Vec<Vec<u32>> = (0..n_buckets)
        .into_par_iter()
        .map(|b| first_of_entries(parts.iter().flat_map(|p| p.items(b)).copied(), &state))
        .collect();
    scatter_to_items(n, n_buckets, &parts, &firsts)
}

/// The keys and indices of one chunk, counting-sorted by bucket. The keys
/// travel with the indices, so a bucket reads its items contiguously
/// instead of gathering them from the whole input.
struct ChunkPartition<K> {
    /// The chunk's items, bucket by bucket, indices increasing within a bucket.
    order: Vec<(K, u32)>,
    /// `order[offsets[b]..offsets[b + 1]]` are the items of bucket `b`.
    offsets: Vec<u32>,
}

impl<K> ChunkPartition<K> {
    /// The chunk's items that fall in bucket `b`.
    fn items(&self, b: usize) -> &[(K, u32)] {
        &self.order[self.offsets[b] as usize..self.offsets[b + 1] as usize]
    }
}

/// Number of hash bits that select a bucket: about [`ITEMS_PER_BUCKET`]
/// items per bucket, between 2 and 2^14 buckets.
fn bucket_bits(n: usize) -> u32 {
    (n / ITEMS_PER_BUCKET).max(1).next_power_of_two().trailing_zeros().clamp(1, 14)
}

/// Counting sort of chunk `c`'s items by bucket (the top `bits` bits of
/// the key's hash).
fn partition_chunk<K: Hash + Copy>(
    c: usize,
    n: usize,
    bits: u32,
    key: &impl Fn(usize) -> K,
    state: &foldhash::fast::RandomState,
) -> ChunkPartition<K> {
    let n_buckets = 1usize << bits;
    let range = c * CHUNK..((c + 1) * CHUNK).min(n);
    let keyed: Vec<(K, u32)> = range.map(|i| (key(i), i as u32)).collect();
    let buckets: Vec<u32> = keyed.iter().map(|e| (state.hash_one(e.0) >> (64 - bits)) as u32).collect();
    let mut offsets = vec![0u32; n_buckets + 1];
    for &b in &buckets {
        offsets[b as usize + 1] += 1;
    }
    for b in 0..n_buckets {
        offsets[b + 1] += offsets[b];
    }
    let mut fill = offsets.clone();
    let mut order = keyed.clone();
    for (e, &b) in keyed.iter().zip(&buckets) {
        order[fill[b as usize] as usize] = *e;
        fill[b as usize] += 1;
    }
    ChunkPartition { order, offsets }
}

/// First index of each item's key among the items `range`, in order.
fn first_in_one_table<K, F>(range: std::ops::Range<usize>, key: &F, state: &foldhash::fast::RandomState) -> Vec<u32>
where
    K: Eq + Hash + Copy,
    F: Fn(usize) -> K,
{
    first_of_entries(range.map(|i| (key(i), i as u32)), state)
}

/// First index of each entry's key among `entries` (keys with their
/// indices, indices increasing), in the order of `entries`.
fn first_of_entries<K: Eq + Hash + Copy>(
    entries: impl Iterator<Item = (K, u32)> + Clone,
    state: &foldhash::fast::RandomState,
) -> Vec<u32> {
    let n = entries.clone().count();
    // Keys live in the table entries: one memory access per probe.
    let mut table: HashTable<(K, u32)> = HashTable::with_capacity(n);
    let mut out = Vec::with_capacity(n);
    for (k, i) in entries {
        let first = match table.entry(state.hash_one(k), |e| e.0 == k, |e| state.hash_one(e.0)) {
            Entry::Occupied(o) => o.get().1,
            Entry::Vacant(v) => {
                v.insert((k, i));
                i
            }
        };
        out.push(first);
    }
    out
}

/// Puts each bucket's answers back in item order: chunk `c` reads, for
/// every bucket, the run of answers that bucket produced for its items.
fn scatter_to_items<K: Sync>(n: usize, n_buckets: usize, parts: &[ChunkPartition<K>], firsts: &[Vec<u32>]) -> Vec<u32> {
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
            for (&(_, i), &first) in p.items(b).iter().zip(answers) {
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
