//! Step 4 of the quads stage: the triangles paired into quads (research
//! quad-meshing §1.1, §1.2, §2.1, §5.1 step 4).
//!
//! 1. [`super::pairing`]: the candidate pairs (two triangles of one model
//!    face across a non-curve edge, strictly convex) costed by shape and
//!    alignment with the cross, taken greedily cheapest first.
//! 2. [`super::matching`]: every triangle greedy left free is the root of an
//!    augmenting-path (blossom) search on a growing window of its face, so
//!    the pairing becomes a maximum matching of the candidate pairs.
//! 3. [`super::strip`]: triangles still free are joined in pairs through a
//!    strip of quads split at the midpoints of the edges it crosses.
//! 4. In a face where triangles stay free after that, the matching is
//!    completed again over the poor pairs as well (quads convex but with a
//!    corner flatter than the candidates allow,
//!    [`super::pairing::MIN_POOR_PAIR_SCALED_JACOBIAN`]), and the strips
//!    are made again: such a face would otherwise be subdivided whole,
//!    with every face next to it, at half the size asked for. The later
//!    steps (smoothing, pillowing) open the flat corners.
//! 5. [`super::transition`]: the triangles that remain (odd count, or no
//!    valid strip) are midpoint-subdivided into quads alone, the midpoints
//!    they leave on their neighbours' edges joined through strips; where
//!    those cannot all be joined, their model faces alone; where neither
//!    can, their faces with every face sharing an edge with them
//!    ([`SubdivisionScope`], [`super::subdivision`]).
//!
//! Feature-curve edges are never removed (no pair crosses one). The vertex
//! set is the triangulation's plus the subdivision's new vertices, appended,
//! so `singular_vertices` and `seam_vertices` keep their indices.

use std::time::Instant;

use serde::Serialize;

use super::error::QuadsError;
use super::matching::complete_matching;
use super::pairing::{DualGraph, MIN_PAIR_SCALED_JACOBIAN, MIN_POOR_PAIR_SCALED_JACOBIAN, NONE, greedy_partners};
use super::strip::{StripStats, join_free_triangles};
use super::subdivision::{Element, faces_to_subdivide, subdivide};
use super::surface_mesh::{QuadMesh, SurfaceTriangulation};
use super::transition::subdivide_alone;
use crate::progress::Progress;

/// What recombination did (for the report).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RecombineStats {
    /// Triangles in.
    pub n_triangles_in: usize,
    /// Candidate pairs (convex quads across non-curve edges).
    pub n_candidate_pairs: usize,
    /// Pairs made by the greedy pass.
    pub n_greedy_pairs: usize,
    /// Triangles the greedy pass left free.
    pub n_unmatched_after_greedy: usize,
    /// Pairs of the final matching that greedy had not made (changed or
    /// added by augmenting paths).
    pub n_matching_pairs: usize,
    /// Augmenting paths applied.
    pub n_augmenting_paths: usize,
    /// Windows searched for augmenting paths.
    pub n_windows: usize,
    /// Triangles left free by the completion (no augmenting path, or in a
    /// face already known to need subdivision).
    pub n_unmatched_after_matching: usize,
    /// Free triangles joined in pairs through strips of split quads.
    pub strips: StripStats,
    /// Model faces whose matching was completed again with the poor pairs
    /// (module doc, step 4).
    pub n_faces_with_poor_pairs: usize,
    /// Poor pairs in the final matching (quads not above the candidates'
    /// floor).
    pub n_poor_pairs: usize,
    /// Model faces where midpoint subdivision was used (the last resort;
    /// should be 0): faces holding a triangle split alone, or every face
    /// subdivided whole.
    pub n_subdivided_faces: usize,
    /// Free triangles split alone into three quads ([`super::transition`]).
    pub n_triangles_subdivided: usize,
    /// What subdivision split.
    pub subdivision_scope: SubdivisionScope,
    /// Narrower scopes whose mesh the later steps could not untangle (the
    /// stage recombined again with a wider one).
    pub scopes_refused: Vec<RefusedScope>,
    /// Strips that join the midpoints the elements split alone left on
    /// their neighbours' edges.
    pub n_transition_strips: usize,
    /// Quads those strips split.
    pub n_transition_quads_split: usize,
    /// Quads made by subdivision.
    pub n_subdivision_quads: usize,
    /// Quads out.
    pub n_quads: usize,
    /// Wall seconds of the candidate pairs and the greedy pass.
    pub greedy_seconds: f64,
    /// Wall seconds of the completion.
    pub matching_seconds: f64,
    /// Wall seconds of the subdivision and the output assembly.
    pub subdivision_seconds: f64,
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// What midpoint subdivision split, from the most local to the widest.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SubdivisionScope {
    /// Nothing: no triangle was left free.
    #[default]
    None,
    /// The free triangles alone, the midpoints they left on the quads
    /// around joined through strips ([`super::transition`]).
    Triangles,
    /// The model faces holding free triangles, alone (their greedy pairs and
    /// triangles split), where the midpoints of the triangles alone could
    /// not all be joined.
    Faces,
    /// Those faces with every face sharing an edge with them, transitively
    /// (their whole component), where neither could.
    FacesWithNeighbours,
}

/// A subdivision scope whose mesh failed the stage's checks.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RefusedScope {
    /// The scope.
    pub scope: SubdivisionScope,
    /// The check that failed, as the stage's error says it.
    pub reason: String,
}

/// All-quad mesh from the triangles of `tri` (module doc), with what was
/// done; subdivision, if needed, splits no less than `narrowest` (the
/// stage widens it when the later steps cannot untangle a narrower one).
///
/// # Errors
/// [`QuadsError::CheckFailed`] when `tri`'s arrays disagree in length or
/// name a vertex that does not exist (a bug of the triangulation step),
/// [`QuadsError::Cancelled`].
pub fn recombine(
    tri: &SurfaceTriangulation,
    narrowest: SubdivisionScope,
    progress: &Progress,
) -> Result<(QuadMesh, RecombineStats), QuadsError> {
    let start = Instant::now();
    check_input(tri)?;
    // The vertices and curve edges grow with strips and subdivision; the
    // rest is only read (the stage may recombine the same `tri` again).
    let mut vertices = tri.vertices.clone();
    let mut curve_edges = tri.curve_edges.clone();
    let mut stats = RecombineStats { n_triangles_in: tri.triangles.len(), ..RecombineStats::default() };

    let graph = DualGraph::new(tri);
    let mut partner = greedy_partners(&graph);
    let greedy = partner.clone();
    stats.n_candidate_pairs = graph.pairs.len();
    stats.n_greedy_pairs = n_pairs(&partner);
    stats.n_unmatched_after_greedy = partner.iter().filter(|&&p| p == NONE).count();
    stats.greedy_seconds = start.elapsed().as_secs_f64();
    progress.set(0.2);
    progress.check()?;

    let t = Instant::now();
    let completion =
        complete_matching(&graph, &tri.model_face_per_triangle, &mut partner, &|_| true, &progress.sub(0.2, 0.9))?;
    stats.n_windows = completion.n_windows;
    stats.n_augmenting_paths = completion.n_augmentations;
    let n_faces = tri.model_face_per_triangle.iter().map(|&f| f as usize + 1).max().unwrap_or(0);
    // The strips: a face they leave with free triangles is completed again
    // with the poor pairs (step 4), and the strips are made again after
    // their midpoints (only ever appended) are dropped.
    let (elements, face_per_element) =
        matching_elements(&tri.triangles, &tri.model_face_per_triangle, &graph, &partner, |_| true);
    let n_vertices = vertices.len();
    let mut joined = join_free_triangles(&mut vertices, &elements, &face_per_element, &curve_edges);
    let unpaired = faces_with_triangles(n_faces, &joined.0, &joined.1);
    let graph = if unpaired.contains(&true) {
        vertices.truncate(n_vertices);
        let floor = |f: u32| {
            if unpaired[f as usize] { MIN_POOR_PAIR_SCALED_JACOBIAN } else { MIN_PAIR_SCALED_JACOBIAN }
        };
        let wide = DualGraph::with_floor(tri, &floor);
        let searched = |f: u32| unpaired[f as usize];
        let poor =
            complete_matching(&wide, &tri.model_face_per_triangle, &mut partner, &searched, &progress.sub(0.9, 0.95))?;
        stats.n_windows += poor.n_windows;
        stats.n_augmenting_paths += poor.n_augmentations;
        stats.n_faces_with_poor_pairs = unpaired.iter().filter(|&&u| u).count();
        stats.n_poor_pairs = (0..partner.len() as u32)
            .filter(|&t| {
                let u = partner[t as usize];
                u != NONE && t < u && graph.pair_of(t, u).is_none()
            })
            .count();
        let (elements, face_per_element) =
            matching_elements(&tri.triangles, &tri.model_face_per_triangle, &wide, &partner, |_| true);
        joined = join_free_triangles(&mut vertices, &elements, &face_per_element, &curve_edges);
        wide
    } else {
        graph
    };
    stats.n_unmatched_after_matching = partner.iter().filter(|&&p| p == NONE).count();
    stats.n_matching_pairs = (0..partner.len())
        .filter(|&t| partner[t] != NONE && (t as u32) < partner[t] && greedy[t] != partner[t])
        .count();
    stats.matching_seconds = t.elapsed().as_secs_f64();
    progress.check()?;

    let t = Instant::now();
    let (triangles, model_face_per_triangle) = (&tri.triangles, &tri.model_face_per_triangle);
    let (elements, face_per_element, strips) = joined;
    stats.strips = strips;
    let failing: Vec<u32> = elements
        .iter()
        .zip(&face_per_element)
        .filter(|(e, _)| matches!(e, Element::Triangle(_)))
        .map(|(_, &f)| f)
        .collect();
    // A face that is subdivided is split from the greedy pairs, the
    // cheapest (best-shaped) ones, rather than from the pairs augmenting
    // paths forced (on fandisk those gave 165 irregular vertices and a quad
    // of scaled Jacobian 10⁻⁵ against 132 and 0.036).
    let split_from_greedy = |flagged: &[bool]| -> (Vec<Element>, Vec<u32>) {
        let inside = matching_elements(triangles, model_face_per_triangle, &graph, &greedy, |f| flagged[f as usize]);
        let outside = elements.iter().zip(&face_per_element).filter(|(_, f)| !flagged[**f as usize]);
        outside.map(|(e, f)| (*e, *f)).chain(inside.0.into_iter().zip(inside.1)).unzip()
    };
    // Free triangles split alone; if the midpoints they leave cannot all be
    // joined, their faces alone; else their faces with every face around.
    let mut faces_failing = vec![false; n_faces];
    for &f in &failing {
        faces_failing[f as usize] = true;
    }
    let alone = if failing.is_empty() || narrowest > SubdivisionScope::Faces {
        None
    } else {
        let triangles_alone = if narrowest <= SubdivisionScope::Triangles {
            let split: Vec<bool> = elements.iter().map(|e| matches!(e, Element::Triangle(_))).collect();
            subdivide_alone(&mut vertices, &elements, &face_per_element, &split, &mut curve_edges)
        } else {
            None
        };
        triangles_alone.map(|a| (a, SubdivisionScope::Triangles)).or_else(|| {
            let (elements, faces) = split_from_greedy(&faces_failing);
            let split: Vec<bool> = faces.iter().map(|&f| faces_failing[f as usize]).collect();
            let faces_alone = subdivide_alone(&mut vertices, &elements, &faces, &split, &mut curve_edges);
            faces_alone.map(|a| (a, SubdivisionScope::Faces))
        })
    };
    let (quads, model_face_per_quad) = match alone {
        Some((alone, scope)) => {
            stats.subdivision_scope = scope;
            stats.n_subdivided_faces = faces_failing.iter().filter(|&&f| f).count();
            if scope == SubdivisionScope::Triangles {
                stats.n_triangles_subdivided = failing.len();
            }
            stats.n_subdivision_quads = alone.n_subdivision_quads;
            stats.n_transition_strips = alone.n_strips;
            stats.n_transition_quads_split = alone.n_quads_split;
            (alone.quads, alone.faces)
        }
        None => {
            let flagged = faces_to_subdivide(n_faces, &failing, &graph.face_links);
            stats.n_subdivided_faces = flagged.iter().filter(|&&f| f).count();
            if flagged.contains(&true) {
                stats.subdivision_scope = SubdivisionScope::FacesWithNeighbours;
            }
            let from_greedy;
            let (elements, face_per_element) = if flagged.contains(&true) {
                from_greedy = split_from_greedy(&flagged);
                (&from_greedy.0, &from_greedy.1)
            } else {
                (&elements, &face_per_element)
            };
            let split: Vec<bool> = face_per_element.iter().map(|&f| flagged[f as usize]).collect();
            let subdivided = subdivide(&mut vertices, elements, face_per_element, &split, &mut curve_edges);
            stats.n_subdivision_quads = subdivided.n_subdivision_quads;
            (subdivided.quads, subdivided.faces)
        }
    };
    stats.n_quads = quads.len();
    stats.subdivision_seconds = t.elapsed().as_secs_f64();
    stats.seconds = start.elapsed().as_secs_f64();
    progress.set(1.0);
    let mesh = QuadMesh {
        vertices,
        quads,
        model_face_per_quad,
        curve_edges,
        high_order_nodes: None,
        singular_vertices: tri.singular_vertices.clone(),
        seam_vertices: tri.seam_vertices.clone(),
    };
    Ok((mesh, stats))
}

/// Pairs in `partner`.
fn n_pairs(partner: &[u32]) -> usize {
    (0..partner.len()).filter(|&t| partner[t] != NONE && (t as u32) < partner[t]).count()
}

/// Per model face (of `n_faces`): whether one of `elements` (model faces
/// `faces`) in it is still a triangle.
fn faces_with_triangles(n_faces: usize, elements: &[Element], faces: &[u32]) -> Vec<bool> {
    let mut out = vec![false; n_faces];
    for (e, &f) in elements.iter().zip(faces) {
        if matches!(e, Element::Triangle(_)) {
            out[f as usize] = true;
        }
    }
    out
}

/// The elements of the matching `partner` in the model faces `keep`
/// accepts, in order of their lowest triangle: the pairs' quads and the
/// free triangles, with their model faces (a pair never spans two faces).
fn matching_elements(
    triangles: &[[u32; 3]],
    model_face_per_triangle: &[u32],
    graph: &DualGraph,
    partner: &[u32],
    keep: impl Fn(u32) -> bool,
) -> (Vec<Element>, Vec<u32>) {
    let mut elements = Vec::with_capacity(triangles.len() / 2 + 1);
    let mut faces = Vec::with_capacity(triangles.len() / 2 + 1);
    for (t, &u) in partner.iter().enumerate() {
        let t32 = t as u32;
        let face = model_face_per_triangle[t];
        if !keep(face) {
            continue;
        }
        let element = if u == NONE {
            Element::Triangle(triangles[t])
        } else if t32 < u {
            match graph.pair_of(t32, u) {
                Some(p) => Element::Quad(p.quad),
                None => continue,
            }
        } else {
            continue;
        };
        elements.push(element);
        faces.push(face);
    }
    (elements, faces)
}

/// Checks that `tri`'s per-triangle arrays match its triangles and that
/// every index names a vertex.
fn check_input(tri: &SurfaceTriangulation) -> Result<(), QuadsError> {
    let n = tri.triangles.len();
    let nv = tri.vertices.len();
    let fail = |detail: String| Err(QuadsError::CheckFailed { check: "recombination input", detail });
    let lengths = [
        ("model_face_per_triangle", tri.model_face_per_triangle.len()),
        ("cross_per_triangle", tri.cross_per_triangle.len()),
        ("normal_per_triangle", tri.normal_per_triangle.len()),
    ];
    for (name, len) in lengths {
        if len != n {
            return fail(format!("{name} has {len} entries for {n} triangles"));
        }
    }
    if tri.vertices.on_surface.len() != nv || tri.vertices.entity.len() != nv {
        return fail(format!("vertex arrays disagree in length ({nv} positions)"));
    }
    if let Some(t) = tri.triangles.iter().position(|t| t.iter().any(|&v| v as usize >= nv)) {
        return fail(format!("triangle {t} {:?} names a vertex beyond {nv}", tri.triangles[t]));
    }
    if let Some(&(c, e)) = tri.curve_edges.iter().find(|(_, e)| e.iter().any(|&v| v as usize >= nv)) {
        return fail(format!("curve {c} edge {e:?} names a vertex beyond {nv}"));
    }
    if u32::try_from(n).is_err() {
        return fail(format!("{n} triangles exceed the u32 indices"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use rand::{Rng, SeedableRng, rngs::StdRng};
    use spade::{DelaunayTriangulation, Point2, Triangulation};

    use super::*;
    use crate::geom::Vec3;
    use crate::quads::fixtures::planar_triangulation;
    use crate::quads::jacobian::scaled_jacobian;
    use crate::quads::surface_mesh::ModelEntity;

    /// The `n × n` grid of unit squares, cell `(i, j)` split along the
    /// diagonal from `(i, j)` to `(i+1, j+1)` when `diagonal(i, j)`, else the
    /// other one. Vertex `(i, j)` is `j (n + 1) + i`; triangles of cell
    /// `(i, j)` are `2 (j n + i)` and the next.
    fn grid(n: u32, diagonal: impl Fn(u32, u32) -> bool) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
        let v = |i: u32, j: u32| j * (n + 1) + i;
        let points = (0..=n).flat_map(|j| (0..=n).map(move |i| [f64::from(i), f64::from(j)])).collect();
        let mut triangles = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
                if diagonal(i, j) {
                    triangles.extend([[a, b, c], [a, c, d]]);
                } else {
                    triangles.extend([[a, b, d], [b, c, d]]);
                }
            }
        }
        (points, triangles)
    }

    /// The Delaunay triangulation of `points` (spade), one model face.
    fn delaunay(points: &[[f64; 2]]) -> SurfaceTriangulation {
        let dt: DelaunayTriangulation<Point2<f64>> =
            DelaunayTriangulation::bulk_load(points.iter().map(|p| Point2::new(p[0], p[1])).collect())
                .expect("finite points");
        let positions: Vec<[f64; 2]> = dt.vertices().map(|v| [v.position().x, v.position().y]).collect();
        let triangles: Vec<[u32; 3]> = dt.inner_faces().map(|f| f.vertices().map(|v| v.fix().index() as u32)).collect();
        let n = triangles.len();
        planar_triangulation(&positions, triangles, vec![0; n])
    }

    /// Grid points with the interior ones jittered by ±0.2 (seeded).
    fn jittered_grid(n: u32, seed: u64) -> Vec<[f64; 2]> {
        let mut rng = StdRng::seed_from_u64(seed);
        let (points, _) = grid(n, |_, _| true);
        points
            .into_iter()
            .map(|[x, y]| {
                let inside = x > 0.0 && y > 0.0 && x < f64::from(n) && y < f64::from(n);
                if inside { [x + rng.random_range(-0.2..0.2), y + rng.random_range(-0.2..0.2)] } else { [x, y] }
            })
            .collect()
    }

    /// Uniform random points in the unit square with its corners, the count
    /// trimmed until the Delaunay triangulation has an even triangle count.
    fn random_even(n: usize, seed: u64) -> SurfaceTriangulation {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut points = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        points.extend((0..n).map(|_| [rng.random_range(0.0..1.0), rng.random_range(0.0..1.0)]));
        loop {
            let tri = delaunay(&points);
            if tri.triangles.len().is_multiple_of(2) {
                return tri;
            }
            points.pop();
        }
    }

    fn run(tri: &SurfaceTriangulation) -> (QuadMesh, RecombineStats) {
        recombine(tri, SubdivisionScope::Triangles, &Progress::none()).expect("recombination succeeds")
    }

    /// Asserts every quad strictly convex against +z, every directed edge
    /// used once, every undirected edge by at most two quads and every
    /// curve edge (and only those) by exactly one quad unless the curve
    /// separates two faces.
    fn assert_valid(mesh: &QuadMesh) {
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for q in &mesh.quads {
            let p = q.map(|v| mesh.vertices.positions[v as usize]);
            assert!(scaled_jacobian(&p, &Vec3::z()) > 0.0, "quad {q:?} not strictly convex");
            for i in 0..4 {
                *directed.entry((q[i], q[(i + 1) % 4])).or_default() += 1;
            }
        }
        assert!(directed.values().all(|&c| c == 1), "a directed edge is used twice (orientation or overlap)");
        let curve: std::collections::HashSet<(u32, u32)> =
            mesh.curve_edges.iter().map(|&(_, [a, b])| (a.min(b), a.max(b))).collect();
        for &(a, b) in directed.keys() {
            if !directed.contains_key(&(b, a)) {
                assert!(curve.contains(&(a.min(b), a.max(b))), "edge ({a}, {b}) is a boundary but no curve");
            }
        }
        for &(a, b) in &curve {
            assert!(
                directed.contains_key(&(a, b)) || directed.contains_key(&(b, a)),
                "curve edge ({a}, {b}) is no quad edge"
            );
        }
        assert_eq!(mesh.model_face_per_quad.len(), mesh.quads.len());
    }

    fn sorted(mut q: [u32; 4]) -> [u32; 4] {
        q.sort_unstable();
        q
    }

    #[test]
    fn a_grid_of_split_squares_gives_back_exactly_its_squares() {
        let n = 8;
        let (points, triangles) = grid(n, |i, j| (i + j) % 2 == 0);
        let tri = planar_triangulation(&points, triangles, vec![0; (2 * n * n) as usize]);
        let (mesh, stats) = run(&tri);
        let mut got: Vec<[u32; 4]> = mesh.quads.iter().map(|&q| sorted(q)).collect();
        got.sort_unstable();
        let v = |i: u32, j: u32| j * (n + 1) + i;
        let mut cells: Vec<[u32; 4]> = (0..n)
            .flat_map(|j| (0..n).map(move |i| sorted([v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)])))
            .collect();
        cells.sort_unstable();
        assert_eq!(got, cells);
        assert_eq!((stats.n_greedy_pairs, stats.n_unmatched_after_greedy, stats.n_matching_pairs), (64, 0, 0));
        assert_eq!(stats.n_subdivided_faces, 0);
        for q in &mesh.quads {
            let p = q.map(|v| mesh.vertices.positions[v as usize]);
            assert!((scaled_jacobian(&p, &Vec3::z()) - 1.0).abs() < 1e-12, "square {q:?} not counter-clockwise");
        }
        assert_valid(&mesh);
        assert_eq!(mesh.vertices.len(), points.len());
    }

    #[test]
    fn a_jittered_grid_becomes_all_quads_without_subdivision() {
        for seed in [1, 2, 3] {
            let tri = delaunay(&jittered_grid(30, seed));
            let (mesh, stats) = run(&tri);
            assert_eq!(stats.n_subdivided_faces, 0, "seed {seed}: {stats:?}");
            assert_eq!(mesh.quads.len(), tri.triangles.len() / 2);
            assert_eq!(stats.n_unmatched_after_matching, 0);
            assert_eq!((stats.n_faces_with_poor_pairs, stats.n_poor_pairs), (0, 0));
            assert_valid(&mesh);
        }
    }

    #[test]
    fn a_face_only_a_nearly_flat_quad_can_pair_takes_it_instead_of_subdivision() {
        // Two triangles whose quad has a 179.4° corner at vertex 3 (scaled
        // Jacobian sin 0.6° ≈ 0.01): no candidate pair, no quad for a strip
        // to cross, so the face used to be midpoint-subdivided into 6 quads.
        let points = [[0.0, 0.0], [2.0, 0.0], [1.0, 1.0], [1.0, -0.005]];
        let tri = planar_triangulation(&points, vec![[0, 1, 2], [1, 0, 3]], vec![0; 2]);
        let p = [3, 1, 2, 0].map(|v: usize| Vec3::new(points[v][0], points[v][1], 0.0));
        let j = scaled_jacobian(&p, &Vec3::z());
        assert!(j > MIN_POOR_PAIR_SCALED_JACOBIAN && j <= MIN_PAIR_SCALED_JACOBIAN, "{j}");
        assert!(DualGraph::new(&tri).pairs.is_empty());
        let (mesh, stats) = run(&tri);
        assert_eq!((stats.n_faces_with_poor_pairs, stats.n_poor_pairs, stats.n_subdivided_faces), (1, 1, 0));
        assert_eq!(stats.n_unmatched_after_matching, 0);
        assert_eq!(mesh.quads.iter().map(|&q| sorted(q)).collect::<Vec<_>>(), vec![[0, 1, 2, 3]]);
        assert_valid(&mesh);
    }

    #[test]
    fn random_points_with_an_even_count_are_completed_to_quads() {
        for seed in [7, 8] {
            let tri = random_even(1500, seed);
            let (mesh, stats) = run(&tri);
            assert!(stats.n_unmatched_after_greedy > 0, "random points should leave greedy leftovers");
            if stats.n_subdivided_faces == 0 {
                assert_eq!(mesh.quads.len(), tri.triangles.len() / 2, "{stats:?}");
                assert_eq!(stats.n_unmatched_after_matching, 0);
            } else {
                assert!(stats.n_unmatched_after_matching > 0);
                assert!(stats.n_subdivision_quads == mesh.quads.len());
            }
            assert_valid(&mesh);
        }
    }

    /// Four triangles in a strip: t0 | t1 t2 | t3 with t1 + t2 the unit
    /// square (cost 0), so greedy pairs it and strands t0 and t3; the only
    /// perfect matching is t0 + t1, t2 + t3, reached by the augmenting path
    /// t0 – t1 = t2 – t3.
    fn strip() -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
        // b0 b1 b2 u0 u1 u2
        let points = vec![[-1.0, 0.5], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [2.0, 0.5]];
        let triangles = vec![[0, 1, 3], [1, 4, 3], [1, 2, 4], [2, 5, 4]];
        (points, triangles)
    }

    #[test]
    fn an_augmenting_path_pairs_what_greedy_stranded() {
        let (points, triangles) = strip();
        let tri = planar_triangulation(&points, triangles, vec![0; 4]);
        let (mesh, stats) = run(&tri);
        assert_eq!((stats.n_greedy_pairs, stats.n_unmatched_after_greedy), (1, 2));
        assert_eq!((stats.n_matching_pairs, stats.n_augmenting_paths, stats.n_subdivided_faces), (2, 1, 0));
        let got: Vec<[u32; 4]> = mesh.quads.iter().map(|&q| sorted(q)).collect();
        assert_eq!(got, vec![[0, 1, 3, 4], [1, 2, 4, 5]]);
        assert_valid(&mesh);
    }

    #[test]
    fn an_odd_face_is_subdivided_into_quads_and_reported() {
        let (points, mut triangles) = strip();
        triangles.pop();
        let tri = planar_triangulation(&points, triangles, vec![0; 3]);
        let n_curve = tri.curve_edges.len();
        let (mesh, stats) = run(&tri);
        // The free triangle alone becomes 3 quads; the midpoint it leaves on
        // the pair's quad is joined to the middle of the quad's opposite
        // boundary edge, cutting it in two.
        assert_eq!((stats.n_subdivided_faces, stats.n_subdivision_quads, stats.n_quads), (1, 3, 5));
        assert_eq!(
            (stats.n_triangles_subdivided, stats.n_transition_strips, stats.subdivision_scope),
            (1, 1, SubdivisionScope::Triangles)
        );
        assert_eq!(stats.n_unmatched_after_matching, 1);
        // 6 vertices (u2 now unused), 3 edge midpoints, 1 centre, and the
        // strip's end on the boundary.
        assert_eq!(mesh.vertices.len(), 11);
        assert_eq!(mesh.curve_edges.len(), n_curve + 3);
        let mut new_on_curve: Vec<u32> = mesh.curve_edges.iter().flat_map(|(_, e)| *e).filter(|&v| v >= 6).collect();
        new_on_curve.sort_unstable();
        new_on_curve.dedup();
        assert_eq!(new_on_curve.len(), 3);
        assert!(new_on_curve.iter().all(|&v| mesh.vertices.entity[v as usize] == ModelEntity::Curve(0)));
        assert_valid(&mesh);
    }

    #[test]
    fn an_odd_face_has_one_triangle_subdivided_alone_and_a_face_apart_untouched() {
        // Face 0: cells x < 2 of a 4 × 4 grid; face 1: cells x ≥ 2 less the
        // upper triangle of cell (3, 3), the last one (15 triangles, odd);
        // face 2: a detached unit square far away.
        let (mut points, mut triangles) = grid(4, |_, _| true);
        let mut faces: Vec<u32> = (0..triangles.len()).map(|t| u32::from((t / 2) % 4 >= 2)).collect();
        triangles.pop();
        faces.pop();
        let base = points.len() as u32;
        points.extend([[10.0, 0.0], [11.0, 0.0], [11.0, 1.0], [10.0, 1.0]]);
        triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        faces.extend([2, 2]);
        assert_eq!(faces.iter().filter(|&&f| f == 1).count() % 2, 1);
        let tri = planar_triangulation(&points, triangles, faces);
        let (mesh, stats) = run(&tri);
        // Face 1's one free triangle becomes 3 quads; the midpoints it leaves
        // on the quads around it are joined by strips; nothing else is split.
        assert_eq!((stats.n_subdivided_faces, stats.n_triangles_subdivided), (1, 1), "{stats:?}");
        assert_eq!((stats.n_subdivision_quads, stats.subdivision_scope), (3, SubdivisionScope::Triangles), "{stats:?}");
        assert!(stats.n_transition_strips >= 1 && stats.n_transition_quads_split >= 1, "{stats:?}");
        let squares_in_face_2 = mesh.model_face_per_quad.iter().filter(|&&f| f == 2).count();
        assert_eq!(squares_in_face_2, 1);
        assert_valid(&mesh);
    }

    #[test]
    fn curve_edges_are_never_crossed() {
        // The grid's main diagonal is a curve between face 0 (below) and
        // face 1 (above); every cell is split along that diagonal's direction.
        let n = 6;
        let (points, triangles) = grid(n, |_, _| true);
        let faces: Vec<u32> = (0..triangles.len())
            .map(|t| {
                let (cell, upper) = (t as u32 / 2, t % 2 == 1);
                let (i, j) = (cell % n, cell / n);
                u32::from(j > i || (j == i && upper))
            })
            .collect();
        let tri = planar_triangulation(&points, triangles, faces);
        let v = |i: u32| i * (n + 1) + i;
        let diagonal: Vec<[u32; 2]> = (0..n).map(|i| [v(i), v(i + 1)]).collect();
        for e in &diagonal {
            assert!(tri.curve_edges.iter().any(|(_, [a, b])| [*a.min(b), *a.max(b)] == *e));
        }
        let (mesh, stats) = run(&tri);
        assert_valid(&mesh);
        // Judged by position: strips add vertices off the grid.
        let p = &mesh.vertices.positions;
        let side = |x: u32| p[x as usize].x - p[x as usize].y;
        assert!(
            mesh.quads.iter().zip(&mesh.model_face_per_quad).all(|(q, &f)| {
                let below = q.iter().all(|&x| side(x) >= -1e-12);
                let above = q.iter().all(|&x| side(x) <= 1e-12);
                if f == 0 { below } else { above }
            }),
            "{stats:?}"
        );
    }

    #[test]
    fn the_same_input_gives_the_same_mesh() {
        let tri = random_even(800, 11);
        let (a, sa) = run(&tri);
        let (b, sb) = run(&tri);
        assert_eq!(a.quads, b.quads);
        assert_eq!(a.vertices.positions, b.vertices.positions);
        assert_eq!(a.curve_edges, b.curve_edges);
        let counts =
            |s: &RecombineStats| (s.n_greedy_pairs, s.n_matching_pairs, s.n_windows, s.n_subdivided_faces, s.n_quads);
        assert_eq!(counts(&sa), counts(&sb));
    }

    #[test]
    fn inconsistent_input_is_an_error_not_a_panic() {
        let (points, triangles) = strip();
        let mut tri = planar_triangulation(&points, triangles, vec![0; 4]);
        tri.cross_per_triangle.pop();
        assert!(matches!(
            recombine(&tri, SubdivisionScope::Triangles, &Progress::none()),
            Err(QuadsError::CheckFailed { .. })
        ));
        let mut tri = planar_triangulation(&points, vec![[0, 1, 3]], vec![0]);
        tri.triangles[0] = [0, 1, 9];
        assert!(matches!(
            recombine(&tri, SubdivisionScope::Triangles, &Progress::none()),
            Err(QuadsError::CheckFailed { .. })
        ));
    }
}
