//! Balanced minimum edge-cut partitions of a patch's dual graph (thesis ch. 2
//! §4.2, which uses METIS).
//!
//! The dual graph has one node per triangle and one edge per interior
//! (valence-2) edge of the patch. `METIS_PartGraphRecursive` with two parts
//! gives a balanced cut of (near-)minimal length; each part is then split
//! into its edge-connected components, since a bisection need not keep the
//! parts connected. METIS gave the best cut among the partitioners tried,
//! in tens of milliseconds (`docs/decisions.md`). A patch far above
//! the size cap is cut once with `METIS_PartGraphKway` into as many parts
//! as needed ([`parts_for_size`]) rather than bisected level by level.

use super::error::AtlasError;
use super::patch::PatchMesh;
use crate::mesh::components::face_components;
use crate::mesh::{EdgeId, FaceId};

/// Local triangle part (0 or 1) of a balanced minimum edge-cut bisection.
///
/// # Errors
/// [`AtlasError::Partition`] when METIS fails or the patch has < 2 triangles.
pub fn bisect_dual_graph(patch: &PatchMesh) -> Result<Vec<i32>, AtlasError> {
    partition_dual_graph(patch, 2)
}

/// Local triangle part (`0..k`) of a balanced minimum edge-cut partition
/// into `k ≥ 2` parts: recursive bisection for two parts (METIS's tightest
/// balance, 0.1 %), multilevel k-way beyond (one coarsening for all parts;
/// balance within 3 %).
///
/// # Errors
/// [`AtlasError::Partition`] when METIS fails or the patch has < 2 triangles.
pub fn partition_dual_graph(patch: &PatchMesh, k: usize) -> Result<Vec<i32>, AtlasError> {
    let n = patch.n_faces();
    let fail = |message: String| AtlasError::Partition { n_faces: n, message };
    if n < 2 {
        return Err(fail("a single triangle cannot be split".into()));
    }
    let k = k.clamp(2, n);
    let (xadj, adjncy) = dual_graph_csr(patch);
    let mut part = vec![0i32; n];
    if adjncy.is_empty() {
        // No dual edges: split by index ranges; components are separated below anyway.
        for (f, p) in part.iter_mut().enumerate() {
            *p = (f * k / n) as i32;
        }
        return Ok(part);
    }
    // METIS (GKlib) keeps its random generator in global state: one lock
    // for every METIS call of the crate.
    let _guard = crate::linalg::ordering::METIS_LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let graph = metis::Graph::new(1, k as i32, &xadj, &adjncy).map_err(|e| fail(format!("{e:?}")))?;
    if k == 2 { graph.part_recursive(&mut part) } else { graph.part_kway(&mut part) }
        .map_err(|e| fail(format!("{e:?}")))?;
    Ok(part)
}

/// How many parts a patch of `n` triangles is cut into for the size cap
/// `cap`: two (a bisection) when halves fit, else enough k-way parts that
/// METIS's 3 % imbalance stays under the cap. One k-way cut replaces
/// several levels of bisection (METIS calls, which the METIS lock
/// serializes, and the extraction and topology of every intermediate piece).
pub fn parts_for_size(n: usize, cap: usize) -> usize {
    let cap = cap.max(1);
    if n.div_ceil(cap) <= 2 {
        2
    } else {
        // Even, so the parts pair up on two cores (11 parts left one idle
        // for the last solve).
        let k = (n as f64 * KWAY_IMBALANCE / cap as f64).ceil() as usize;
        k + k % 2
    }
}

/// How many parts a patch whose map has area distortion `d` is cut into so
/// that each part's falls under `limit`. The distortion of a tube (a cut
/// torus, a long protrusion) grows exponentially with its length over its
/// girth, so `k` pieces of it have about `d^(1/k)`: `k = ⌈ln d / ln limit⌉`
/// (at least 2, at most [`MAX_DISTORTION_PARTS`]), instead of bisecting
/// level by level, each level paying a factorization per piece.
pub fn parts_for_distortion(d: f64, limit: f64) -> usize {
    if !(d > limit && limit > 1.0) {
        return 2;
    }
    let k = (d.ln() / limit.ln()).ceil();
    if k.is_finite() { (k as usize).clamp(2, MAX_DISTORTION_PARTS) } else { MAX_DISTORTION_PARTS }
}

/// Most parts of one distortion cut (a few levels of recursion handle worse).
const MAX_DISTORTION_PARTS: usize = 16;

/// METIS's default load imbalance tolerance for k-way partitions (ufactor 30).
const KWAY_IMBALANCE: f64 = 1.03;

/// Dual graph of the patch in METIS CSR form (`xadj`, `adjncy`).
fn dual_graph_csr(patch: &PatchMesh) -> (Vec<i32>, Vec<i32>) {
    let n = patch.n_faces();
    let mut xadj = Vec::with_capacity(n + 1);
    let mut adjncy = Vec::with_capacity(3 * n);
    xadj.push(0);
    for f in 0..n {
        for i in 0..3 {
            if let Some(g) = patch.topo.face_across(FaceId::new(f), i) {
                adjncy.push(g.0 as i32);
            }
        }
        xadj.push(adjncy.len() as i32);
    }
    (xadj, adjncy)
}

/// Split a patch into the connected pieces of a bisection: global triangle
/// sets, each edge-connected, largest first.
///
/// # Errors
/// [`AtlasError::Partition`] when the bisection fails.
pub fn split_patch(patch: &PatchMesh) -> Result<Vec<Vec<FaceId>>, AtlasError> {
    split_patch_into(patch, 2)
}

/// Split a patch into the connected pieces of a `k`-part partition
/// ([`partition_dual_graph`]): global triangle sets, each edge-connected,
/// largest first.
///
/// # Errors
/// [`AtlasError::Partition`] when the partition fails.
pub fn split_patch_into(patch: &PatchMesh, k: usize) -> Result<Vec<Vec<FaceId>>, AtlasError> {
    let part = partition_dual_graph(patch, k)?;
    let topo = &patch.topo;
    let comps = face_components(topo, |e: EdgeId| {
        let faces = topo.edge_faces(e);
        faces.len() != 2 || part[faces[0].idx()] != part[faces[1].idx()]
    });
    let mut pieces: Vec<Vec<FaceId>> = vec![Vec::new(); comps.n_components];
    for (f, &c) in comps.component_per_face.iter().enumerate() {
        pieces[c as usize].push(patch.global_faces[f]);
    }
    pieces.sort_by_key(|p| std::cmp::Reverse(p.len()));
    Ok(pieces)
}

/// Number of dual edges cut by a part assignment (for reports and tests).
pub fn cut_size(patch: &PatchMesh, part: &[i32]) -> usize {
    (0..patch.topo.n_edges())
        .filter(|&e| match patch.topo.edge_faces(EdgeId::new(e)) {
            [a, b] => part[a.idx()] != part[b.idx()],
            _ => false,
        })
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn size_splits_use_as_few_parts_as_fit() {
        assert_eq!(parts_for_size(199_692, 100_000), 2);
        assert_eq!(parts_for_size(250_000, 100_000), 4);
        assert_eq!(parts_for_size(1_002_252, 100_000), 12);
        assert_eq!(parts_for_size(10, 1), 12);
    }

    #[test]
    fn distortion_cuts_aim_at_the_limit() {
        assert_eq!(parts_for_distortion(2e4, 1e4), 2);
        assert_eq!(parts_for_distortion(8e5, 1e4), 2);
        assert_eq!(parts_for_distortion(1e11, 1e4), 3);
        assert_eq!(parts_for_distortion(f64::INFINITY, 1e4), MAX_DISTORTION_PARTS);
        assert_eq!(parts_for_distortion(f64::NAN, 1e4), 2);
    }

    #[test]
    fn kway_parts_are_balanced() {
        let m = fixtures::icosphere(4); // 5120 triangles
        let faces: Vec<FaceId> = (0..m.n_faces()).map(FaceId::new).collect();
        let p = PatchMesh::extract(&m, &faces);
        let part = partition_dual_graph(&p, 6).unwrap();
        for k in 0..6 {
            let size = part.iter().filter(|&&x| x == k).count();
            assert!(size as f64 <= 1.03 * 5120.0 / 6.0 + 1.0, "part {k}: {size}");
            assert!(size > 0);
        }
        let pieces = split_patch_into(&p, 6).unwrap();
        assert!(pieces.len() >= 6);
        assert_eq!(pieces.iter().map(Vec::len).sum::<usize>(), 5120);
    }

    #[test]
    fn sphere_bisection_is_balanced_with_a_short_cut() {
        let m = fixtures::icosphere(4); // 5120 triangles
        let faces: Vec<FaceId> = (0..m.n_faces()).map(FaceId::new).collect();
        let p = PatchMesh::extract(&m, &faces);
        let part = bisect_dual_graph(&p).unwrap();
        let n1 = part.iter().filter(|&&x| x == 1).count();
        assert!((n1 as f64 - 2560.0).abs() <= 0.02 * 5120.0, "unbalanced: {n1}");
        // A great circle crosses about π·sqrt(n) dual edges; stay within 2× of that.
        let cut = cut_size(&p, &part);
        let great_circle = std::f64::consts::PI * (5120f64 / 2.0).sqrt() * 1.2;
        assert!((cut as f64) < 2.0 * great_circle, "cut {cut}");
        let pieces = split_patch(&p).unwrap();
        assert!(pieces.len() >= 2);
        assert_eq!(pieces.iter().map(|x| x.len()).sum::<usize>(), 5120);
    }

    #[test]
    fn single_triangle_cannot_be_split() {
        let m = fixtures::tetrahedron();
        let p = PatchMesh::extract(&m, &[FaceId(0)]);
        assert!(matches!(bisect_dual_graph(&p), Err(AtlasError::Partition { n_faces: 1, .. })));
    }
}
