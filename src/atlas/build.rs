//! The atlas stage driver: features → model faces → parameterizable patches
//! → refinement of coarse patches → mean value maps → verification → BREP
//! curves and corners (thesis ch. 2 §4).
//!
//! Patches are processed generation by generation, in parallel on the rayon
//! pool: a patch that is not a disk with holes, or is larger than
//! `max_patch_triangles`, is bisected (METIS) and its pieces go to the next
//! generation; a patch whose map fails verification is bisected too, at most
//! `max_split_depth` times, after which the stage fails naming the patch. So
//! a broken map is never returned. Results are ordered by their smallest
//! input triangle, so the output does not depend on the thread count.

use super::creases::cut_along_inner_creases;
use super::curvature::{Curvature, principal_curvatures};
use super::error::AtlasError;
use super::features::{FeatureCurve, Features, detect_features, edge_chains_with_corners, model_faces};
use super::mvc::{MvcSolver, PatchParameterization, mean_value_parameterization, mean_value_parameterization_unless};
use super::options::AtlasOptions;
use super::partition::{parts_for_distortion, parts_for_size, split_patch, split_patch_into};
use super::patch::PatchMesh;
use super::refine::bisect_inner_edges;
use super::report::{AtlasReport, PatchReport, SplitCounts, SplitReason};
use super::verify::{MapCheck, area_distortion, check_map, min_and_median, sigma_ratios};
use crate::geom::Vec2;
use crate::mesh::boundary::BoundaryLoop;
use crate::mesh::summary::topology_summary;
use crate::mesh::{EdgeId, FaceId, Topology, TriMesh, VertexId};
use crate::progress::Progress;
use rayon::prelude::*;
use std::time::Instant;

/// One parameterized patch of the atlas.
#[derive(Debug, Clone)]
pub struct AtlasPatch {
    /// Atlas-mesh vertex of each local vertex.
    pub vertices: Vec<VertexId>,
    /// Atlas-mesh triangle of each local triangle.
    pub faces: Vec<FaceId>,
    /// Triangles as local vertex indices (counter-clockwise in `(u, v)`).
    pub triangles: Vec<[u32; 3]>,
    /// `(u, v)` of each local vertex; the outer loop lies on the unit circle.
    pub uv: Vec<Vec2>,
    /// σ2/σ1 of each local triangle.
    pub sigma_ratio: Vec<f64>,
    /// Bounding curves (indices into [`Atlas::curves`]) with orientation:
    /// `true` when the curve runs like the patch boundary (interior on the left).
    pub curves: Vec<(u32, bool)>,
    /// Summary numbers.
    pub report: PatchReport,
}

/// A curve of the atlas boundary representation: a chain of edges between
/// two corners along which patches meet (or the mesh ends).
#[derive(Debug, Clone)]
pub struct AtlasCurve {
    /// The chain (vertices and edges of the atlas mesh).
    pub chain: FeatureCurve,
    /// True when the curve lies on a feature edge of the input (not a cut).
    pub is_feature: bool,
}

/// The atlas: a triangulation of the input (refined where coarse), split
/// into patches, each with a one-to-one map to the unit disk.
#[derive(Debug, Clone)]
pub struct Atlas {
    /// The atlas triangulation: input vertices first, then bisection midpoints.
    pub mesh: TriMesh,
    /// Input triangle containing each atlas triangle.
    pub source_face: Vec<FaceId>,
    /// Patch of each atlas triangle.
    pub patch_per_face: Vec<u32>,
    /// The patches, ordered by their smallest input triangle.
    pub patches: Vec<AtlasPatch>,
    /// Curves of the boundary representation.
    pub curves: Vec<AtlasCurve>,
    /// Corner vertices (atlas mesh), sorted.
    pub corners: Vec<VertexId>,
    /// Feature edges of the input.
    pub features: Features,
    /// Curvature at every atlas-mesh vertex.
    pub curvature: Curvature,
    /// Summary for `report.json`.
    pub report: AtlasReport,
}

impl Atlas {
    /// The patch of each of the input's `n_input_faces` triangles (all the
    /// atlas triangles cut from one input triangle lie in one patch).
    pub fn patch_per_input_face(&self, n_input_faces: usize) -> Vec<u32> {
        let mut out = vec![u32::MAX; n_input_faces];
        for (s, &p) in self.source_face.iter().zip(&self.patch_per_face) {
            if let Some(slot) = out.get_mut(s.idx()) {
                *slot = p;
            }
        }
        out
    }
}

/// A patch that has been parameterized, in local numbering.
struct DonePatch {
    input_faces: Vec<FaceId>,
    /// Input vertex of each local vertex, `None` for bisection midpoints.
    input_vertex: Vec<Option<VertexId>>,
    mesh: TriMesh,
    source_local_face: Vec<u32>,
    uv: Vec<Vec2>,
    sigma: Vec<f64>,
    report: PatchReport,
}

/// What became of one patch in one generation.
enum Outcome {
    Done(Box<DonePatch>),
    Split { pieces: Vec<Vec<FaceId>>, reason: SplitReason, depth: usize },
}

/// Build the atlas of `mesh` (welded and consistently oriented).
///
/// # Errors
/// [`AtlasError`] for an empty mesh, bad options, a patch without a valid
/// map after `max_split_depth` splits, or cancellation.
pub fn build_atlas(mesh: &TriMesh, opts: &AtlasOptions, progress: &Progress) -> Result<Atlas, AtlasError> {
    opts.validate()?;
    if mesh.n_faces() == 0 {
        return Err(AtlasError::EmptyMesh);
    }
    let t0 = Instant::now();
    let topo = Topology::new(mesh);
    let ((features, (faces_of_model_face, n_model_faces, n_crease_cuts)), summary) = rayon::join(
        || {
            let mut features = detect_features(mesh, &topo, opts.feature_angle_deg);
            let faces = model_faces(&topo, &features).faces_per_component();
            let n_faces = faces.len();
            let cut = cut_along_inner_creases(mesh, &topo, &features, faces);
            features.is_cut_crease = cut.is_cut_crease;
            (features, (cut.pieces, n_faces, cut.n_faces_cut))
        },
        || topology_summary(mesh, &topo),
    );
    // Without a non-manifold vertex in the input, a patch can only be
    // pinched at its boundary ([`PatchMesh::defect_of_manifold_piece`]).
    let manifold_input = summary.n_nonmanifold_vertices == 0;
    let feature_pairs = feature_vertex_pairs(&topo, &features.is_feature_edge);
    let cut_pairs = feature_vertex_pairs(&topo, &features.is_cut_crease);
    let t_features = t0.elapsed().as_secs_f64();
    progress.set(0.05);

    // The curvature of the input runs beside the patch phase, whose first
    // split of a closed surface leaves the second core idle; it is the
    // atlas mesh's unless a patch gets refined (same vertices, same
    // triangles in another order).
    let t1 = Instant::now();
    let (patches, input_curvature) = rayon::join(
        || parameterize_patches(mesh, &topo, faces_of_model_face, manifold_input, opts, progress),
        || principal_curvatures(mesh, &topo),
    );
    let (mut done, mut splits) = patches?;
    splits.inner_crease = n_crease_cuts;
    drop(topo);
    done.sort_by_key(|p| p.input_faces.iter().min().copied());
    let t_patches = t1.elapsed().as_secs_f64();

    let t2 = Instant::now();
    let refined = done.iter().any(|p| p.report.n_bisections > 0);
    let mut atlas = assemble(mesh, done, features);
    let atlas_topo = Topology::new(&atlas.mesh);
    attach_curves(&mut atlas, &atlas_topo, &feature_pairs, &cut_pairs);
    progress.check()?;
    atlas.curvature = if refined { principal_curvatures(&atlas.mesh, &atlas_topo) } else { input_curvature };
    let t_curves = t2.elapsed().as_secs_f64();
    atlas.report = AtlasReport::new(mesh, &summary, &atlas, n_model_faces, splits, [t_features, t_patches, t_curves]);
    progress.set(1.0);
    Ok(atlas)
}

/// Parameterize every model face, splitting patches (in parallel, level by
/// level) until each has a valid map; the done patches and why splits happened.
fn parameterize_patches(
    mesh: &TriMesh,
    topo: &Topology,
    faces_of_model_face: Vec<Vec<FaceId>>,
    manifold_input: bool,
    opts: &AtlasOptions,
    progress: &Progress,
) -> Result<(Vec<DonePatch>, SplitCounts), AtlasError> {
    let ctx = PatchContext { mesh, topo, manifold_input, opts, progress };
    let mut pending: Vec<(Vec<FaceId>, usize)> = faces_of_model_face.into_iter().map(|f| (f, 0)).collect();
    let mut done: Vec<DonePatch> = Vec::new();
    let mut splits = SplitCounts::default();
    let n_total = mesh.n_faces() as f64;
    let mut n_done = 0usize;
    while !pending.is_empty() {
        progress.check()?;
        let outcomes: Vec<Result<Outcome, AtlasError>> =
            pending.into_par_iter().map(|(faces, depth)| process_patch(&ctx, faces, depth)).collect();
        pending = Vec::new();
        for o in outcomes {
            match o? {
                Outcome::Done(p) => {
                    n_done += p.input_faces.len();
                    done.push(*p);
                }
                Outcome::Split { pieces, reason, depth } => {
                    splits.count(reason);
                    pending.extend(pieces.into_iter().map(|p| (p, depth)));
                }
            }
        }
        progress.set(0.05 + 0.85 * n_done as f64 / n_total);
    }
    Ok((done, splits))
}

/// What every patch of one atlas build shares.
struct PatchContext<'a> {
    mesh: &'a TriMesh,
    topo: &'a Topology,
    /// No non-manifold vertex in the input: a patch can only be pinched at
    /// its boundary ([`PatchMesh::defect_of_manifold_piece`]).
    manifold_input: bool,
    opts: &'a AtlasOptions,
    progress: &'a Progress,
}

/// A coarse patch refined by bisection before its map is computed.
struct Refined {
    /// The refined mesh (no global numbering: a patch of its own).
    patch: PatchMesh,
    /// Patch triangle containing each refined triangle.
    source_face: Vec<u32>,
    n_bisections: usize,
}

/// A one-to-one mean value map of a patch and its checks.
struct VerifiedMap {
    param: PatchParameterization,
    check: MapCheck,
    /// Area distortion of the map ([`area_distortion`]).
    distortion: f64,
    /// Boundary loops of the mapped mesh.
    n_loops: usize,
}

/// What [`mean_value_map`] found.
enum MapAttempt {
    /// A map that passed [`check_map`], and the check.
    Valid(PatchParameterization, MapCheck),
    /// Abandoned early: the first approximation's area distortion (this
    /// value) is far beyond the limit.
    Hopeless(f64),
    /// Not one-to-one, even by the pivoting LU.
    Invalid(MapCheck),
}

/// Check, refine, parameterize and verify one patch (the input triangles
/// `faces`, split `depth` times for its map so far), or split it: thesis
/// ch. 2 §4, a patch must be a disk with holes whose mean value map (2.4)
/// is one-to-one (§3) and not too compressed for a mesh generator.
fn process_patch(ctx: &PatchContext, faces: Vec<FaceId>, depth: usize) -> Result<Outcome, AtlasError> {
    ctx.progress.check()?;
    let opts = ctx.opts;
    let patch = extract_patch(ctx, &faces);
    if let Some(split) = split_unless_small_disk(ctx, &patch, depth)? {
        return Ok(split);
    }
    let start = Instant::now();
    let refined = refine_if_coarse(&patch, opts);
    let work = refined.as_ref().map_or(&patch, |r| &r.patch);
    let loops = work.loops_longest_first();
    let may_split = depth < opts.max_split_depth && patch.n_faces() >= 2;
    let (param, check) = match mean_value_map(work, &loops, may_split, opts)? {
        MapAttempt::Valid(param, check) => (param, check),
        MapAttempt::Hopeless(preview_distortion) => {
            let k = parts_for_distortion(preview_distortion, opts.max_area_distortion);
            let pieces = split_patch_into(&patch, k)?;
            return Ok(Outcome::Split { pieces, reason: SplitReason::Distortion, depth: depth + 1 });
        }
        MapAttempt::Invalid(check) => return unmappable_patch(&patch, &check, depth, opts),
    };
    let distortion = area_distortion(work, &param.uv);
    if distortion > opts.max_area_distortion && may_split {
        // One-to-one but too compressed somewhere for a mesh generator: split.
        let pieces = split_patch(&patch)?;
        return Ok(Outcome::Split { pieces, reason: SplitReason::Distortion, depth: depth + 1 });
    }
    let map = VerifiedMap { param, check, distortion, n_loops: loops.len() };
    Ok(Outcome::Done(Box::new(done_patch(patch, refined, faces, map, depth, start))))
}

/// The patch of the input triangles `faces`: the input itself (its
/// topology reused) when `faces` is every triangle in order, else an
/// extracted copy.
fn extract_patch(ctx: &PatchContext, faces: &[FaceId]) -> PatchMesh {
    let is_whole = faces.len() == ctx.mesh.n_faces() && faces.iter().enumerate().all(|(i, f)| f.idx() == i);
    is_whole
        .then(|| PatchMesh::whole(ctx.mesh, ctx.topo))
        .flatten()
        .unwrap_or_else(|| PatchMesh::extract(ctx.mesh, faces))
}

/// The split of a patch that is not a disk with holes (DESIGN stage 1
/// step 3: connected, orientable, genus 0, a boundary) or has more than
/// `max_patch_triangles`: one k-way cut into enough pieces for the cap
/// (at least two), at the same `depth`. `None` for a patch to map.
fn split_unless_small_disk(ctx: &PatchContext, patch: &PatchMesh, depth: usize) -> Result<Option<Outcome>, AtlasError> {
    let max = ctx.opts.max_patch_triangles;
    let defect = if ctx.manifold_input { patch.defect_of_manifold_piece() } else { patch.defect() };
    if defect.is_none() && patch.n_faces() <= max {
        return Ok(None);
    }
    let pieces = split_patch_into(patch, parts_for_size(patch.n_faces(), max))?;
    Ok(Some(Outcome::Split { pieces, reason: defect.map_or(SplitReason::Size, SplitReason::Topology), depth }))
}

/// The refined copy of a coarse patch (too few interior vertices for a
/// smooth map, and not planar): interior edges bisected towards the mean
/// boundary edge length, geometry unchanged (thesis ch. 2 §5.1). `None`
/// when the patch is mapped as it is (no copy: a patch is ~50 bytes per
/// triangle).
fn refine_if_coarse(patch: &PatchMesh, opts: &AtlasOptions) -> Option<Refined> {
    let interior_fraction = patch.n_interior_vertices() as f64 / patch.mesh.n_vertices() as f64;
    let coarse = interior_fraction < opts.refine_below_interior_fraction && !is_planar(&patch.mesh);
    if !coarse {
        return None;
    }
    let target = mean_boundary_edge_length(patch);
    let r = bisect_inner_edges(&patch.mesh, target, opts.refine_max_passes, refined_size_cap(patch.n_faces(), opts));
    let refined =
        PatchMesh { global_vertices: Vec::new(), global_faces: Vec::new(), topo: Topology::new(&r.mesh), mesh: r.mesh };
    Some(Refined { patch: refined, source_face: r.source_face, n_bisections: r.n_bisections })
}

/// The mean value map (2.4 with 2.7) of `work` with its boundary `loops`,
/// checked for injectivity ([`check_map`]). When the patch may still be
/// split, a first approximation compressed far beyond the distortion limit
/// is abandoned (it would be split anyway: do not solve it to the end).
/// A map that fails the check is solved again by the pivoting LU: a
/// solution to 10⁻¹⁰ may still miss a tiny triangle that a pivoting direct
/// solve gets right.
fn mean_value_map(
    work: &PatchMesh,
    loops: &[BoundaryLoop],
    may_split: bool,
    opts: &AtlasOptions,
) -> Result<MapAttempt, AtlasError> {
    let preview_distortion = std::cell::Cell::new(0.0);
    let hopeless = |uv: &[Vec2]| {
        may_split && {
            preview_distortion.set(area_distortion(work, uv));
            preview_distortion.get() > PREVIEW_DISTORTION_MARGIN * opts.max_area_distortion
        }
    };
    let first = mean_value_parameterization_unless(work, loops, opts.max_hole_fill_vertices, opts.solver, &hopeless)?;
    let Some(mut param) = first else {
        return Ok(MapAttempt::Hopeless(preview_distortion.get()));
    };
    let mut check = check_map(work, &param.uv, opts.min_relative_uv_area);
    if !check.is_valid() && param.solver != MvcSolver::PivotingLu {
        param = mean_value_parameterization(work, loops, opts.max_hole_fill_vertices, MvcSolver::PivotingLu)?;
        check = check_map(work, &param.uv, opts.min_relative_uv_area);
    }
    Ok(if check.is_valid() { MapAttempt::Valid(param, check) } else { MapAttempt::Invalid(check) })
}

/// A patch without a one-to-one map: split in two (`depth + 1`), or, when
/// it may not be split any more, [`AtlasError::NoValidMap`] naming where it
/// is and what failed, so a broken map is never returned.
fn unmappable_patch(
    patch: &PatchMesh,
    check: &MapCheck,
    depth: usize,
    opts: &AtlasOptions,
) -> Result<Outcome, AtlasError> {
    if depth >= opts.max_split_depth || patch.n_faces() < 2 {
        let c = patch.mesh.positions.iter().sum::<crate::geom::Vec3>() / patch.mesh.n_vertices() as f64;
        return Err(AtlasError::NoValidMap {
            n_faces: patch.n_faces(),
            x: c.x,
            y: c.y,
            z: c.z,
            attempts: depth,
            reason: format!(
                "{} flipped and {} near-zero-area parametric triangles (min relative area {:.3e})",
                check.n_flipped, check.n_tiny, check.min_relative_area
            ),
        });
    }
    let pieces = split_patch(patch)?;
    Ok(Outcome::Split { pieces, reason: SplitReason::MapFailed, depth: depth + 1 })
}

/// The finished patch: local mesh (refined or not), `(u, v)`, the
/// conformity indicator σ2/σ1 per triangle (thesis ch. 2 §2) and the
/// summary numbers, `start` being when its mapping began.
fn done_patch(
    patch: PatchMesh,
    refined: Option<Refined>,
    faces: Vec<FaceId>,
    map: VerifiedMap,
    depth: usize,
    start: Instant,
) -> DonePatch {
    let work = refined.as_ref().map_or(&patch, |r| &r.patch);
    let n_original = patch.mesh.n_vertices();
    let sigma = sigma_ratios(work, &map.param.uv);
    let (sigma_min, sigma_median) = min_and_median(&sigma);
    let input_vertex =
        (0..work.mesh.n_vertices()).map(|v| (v < n_original).then(|| patch.global_vertices[v])).collect();
    let param = &map.param;
    let report = PatchReport {
        id: 0,
        n_input_triangles: faces.len(),
        n_triangles: work.n_faces(),
        n_vertices: work.mesh.n_vertices(),
        n_boundary_loops: map.n_loops,
        n_holes_filled: param.n_holes_filled,
        n_holes_neumann: param.n_holes_neumann,
        n_bisections: refined.as_ref().map_or(0, |r| r.n_bisections),
        sigma_ratio_min: sigma_min,
        sigma_ratio_median: sigma_median,
        sigma_ratio_jump_median: sigma_jump_median(work, &sigma),
        min_relative_uv_area: map.check.min_relative_area,
        area_distortion: map.distortion,
        n_map_splits: depth,
        solver: param.solver,
        krylov_iterations: param.iterations,
        solve_seconds: start.elapsed().as_secs_f64(),
    };
    let (mesh, source_local_face) = match refined {
        Some(r) => (r.patch.mesh, r.source_face),
        None => (patch.mesh, (0..faces.len() as u32).collect()),
    };
    DonePatch { input_faces: faces, input_vertex, mesh, source_local_face, uv: map.param.uv, sigma, report }
}

/// A patch whose first approximate map (symmetrized weights) exceeds the
/// area distortion limit by this factor is split without finishing the
/// solve. Distortion grows exponentially with a tube's length over its
/// girth, so a rejected patch is usually far beyond the limit, its halves
/// well below it (`docs/decisions.md`).
const PREVIEW_DISTORTION_MARGIN: f64 = 10.0;

/// Relative flatness under which a patch counts as planar: the tolerance
/// Gmsh uses (`Geometry.MatchMeshTolerance`, 1e-8 of the bounding-box
/// diagonal) to replace a discrete surface's map by a plane projection.
const PLANAR_TOLERANCE: f64 = 1e-8;

/// True when every vertex lies within `PLANAR_TOLERANCE` × diagonal of the
/// plane through the centroid normal to the summed area vector. Gmsh meshes
/// such patches by projection and ignores their `(u, v)`, so refining a
/// coarse planar patch would only inflate the atlas.
fn is_planar(mesh: &TriMesh) -> bool {
    let Some(bbox) = mesh.bounding_box() else { return true };
    let n: crate::geom::Vec3 = (0..mesh.n_faces()).map(|f| mesh.face_area_vector(FaceId::new(f))).sum();
    let Some(n) = n.try_normalize(0.0) else { return false };
    let c = mesh.positions.iter().sum::<crate::geom::Vec3>() / mesh.n_vertices() as f64;
    let tol = PLANAR_TOLERANCE * bbox.diagonal();
    mesh.positions.iter().all(|p| (p - c).dot(&n).abs() <= tol)
}

/// Most triangles a coarse patch of `n_faces` triangles may have after
/// bisection: `refine_max_growth` times more (at least 64), never above
/// `max_patch_triangles`. The target length alone does not bound the work: a
/// large flat face with a finely sampled hole has a tiny mean boundary edge.
fn refined_size_cap(n_faces: usize, opts: &AtlasOptions) -> usize {
    n_faces.saturating_mul(opts.refine_max_growth).max(64).min(opts.max_patch_triangles.max(n_faces))
}

/// Mean length of the patch's boundary edges: the target length of refinement.
fn mean_boundary_edge_length(patch: &PatchMesh) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for e in 0..patch.topo.n_edges() {
        if patch.topo.is_boundary_edge(EdgeId::new(e)) {
            let [a, b] = patch.topo.edges[e];
            sum += (patch.mesh.positions[b.idx()] - patch.mesh.positions[a.idx()]).norm();
            n += 1;
        }
    }
    if n == 0 { patch.mesh.mean_edge_length() } else { sum / n as f64 }
}

/// Median over inner edges of |σ2/σ1 difference| between the two triangles:
/// how smooth the conformity indicator is (small for a smooth map).
pub fn sigma_jump_median(patch: &PatchMesh, sigma: &[f64]) -> f64 {
    let mut jumps: Vec<f64> = (0..patch.topo.n_edges())
        .filter_map(|e| match patch.topo.edge_faces(EdgeId::new(e)) {
            [a, b] => Some((sigma[a.idx()] - sigma[b.idx()]).abs()),
            _ => None,
        })
        .collect();
    if jumps.is_empty() {
        return 0.0;
    }
    let mid = jumps.len() / 2;
    *jumps.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Merge the patches into one atlas mesh: input vertices keep their ids,
/// bisection midpoints are appended patch by patch.
fn assemble(mesh: &TriMesh, done: Vec<DonePatch>, features: Features) -> Atlas {
    let mut positions = mesh.positions.clone();
    let mut triangles = Vec::with_capacity(mesh.n_faces());
    let mut source_face = Vec::with_capacity(mesh.n_faces());
    let mut patch_per_face = Vec::with_capacity(mesh.n_faces());
    let mut patches = Vec::with_capacity(done.len());
    for (id, p) in done.into_iter().enumerate() {
        let vertices: Vec<VertexId> = p
            .input_vertex
            .iter()
            .zip(&p.mesh.positions)
            .map(|(iv, x)| {
                iv.unwrap_or_else(|| {
                    positions.push(*x);
                    VertexId::new(positions.len() - 1)
                })
            })
            .collect();
        let first = triangles.len();
        for (t, &s) in p.mesh.triangles.iter().zip(&p.source_local_face) {
            triangles.push(t.map(|v| vertices[v.idx()]));
            source_face.push(p.input_faces[s as usize]);
            patch_per_face.push(id as u32);
        }
        let faces = (first..triangles.len()).map(FaceId::new).collect();
        let mut report = p.report;
        report.id = id;
        patches.push(AtlasPatch {
            vertices,
            faces,
            triangles: p.mesh.triangles.iter().map(|t| t.map(|v| v.0)).collect(),
            uv: p.uv,
            sigma_ratio: p.sigma,
            curves: Vec::new(),
            report,
        });
    }
    let atlas_mesh = TriMesh { positions, triangles };
    debug_assert!(atlas_mesh.validate().is_ok());
    Atlas {
        mesh: atlas_mesh,
        source_face,
        patch_per_face,
        patches,
        curves: Vec::new(),
        corners: Vec::new(),
        features,
        curvature: Curvature::default(),
        report: AtlasReport::default(),
    }
}

/// Compute the BREP curves (chains of edges where patches meet or the mesh
/// ends) and give every patch its bounding curves with orientation.
/// The edges of the input `flagged` (indexed by edge; shorter means
/// unflagged) as `(lo, hi)` vertex pairs, sorted: what [`attach_curves`]
/// needs of the input topology.
fn feature_vertex_pairs(topo: &Topology, flagged: &[bool]) -> Vec<(VertexId, VertexId)> {
    let mut pairs: Vec<(VertexId, VertexId)> = (0..topo.n_edges())
        .filter(|&e| flagged.get(e).copied().unwrap_or(false))
        .map(|e| {
            let [a, b] = topo.edges[e];
            (a.min(b), a.max(b))
        })
        .collect();
    pairs.sort_unstable();
    pairs
}

fn attach_curves(
    atlas: &mut Atlas,
    topo: &Topology,
    feature_pairs: &[(VertexId, VertexId)],
    cut_pairs: &[(VertexId, VertexId)],
) {
    let is_border: Vec<bool> = (0..topo.n_edges())
        .map(|e| match topo.edge_faces(EdgeId::new(e)) {
            [a, b] => atlas.patch_per_face[a.idx()] != atlas.patch_per_face[b.idx()],
            _ => true,
        })
        .collect();
    // A border that runs along a cut crease on one side of a vertex and not
    // on the other (where the crease ends inside its face) is split there,
    // so a curve is all crease or not at all.
    let is_cut_crease = |e: usize| {
        let [a, b] = topo.edges[e];
        cut_pairs.binary_search(&(a.min(b), a.max(b))).is_ok()
    };
    let mut kinds = vec![0u8; topo.n_vertices()];
    for e in (0..topo.n_edges()).filter(|&e| is_border[e]) {
        let kind = if is_cut_crease(e) { 1 } else { 2 };
        for v in topo.edges[e] {
            kinds[v.idx()] |= kind;
        }
    }
    let forced: Vec<bool> = kinds.iter().map(|&k| k == 3).collect();
    let (corners, chains, _) = edge_chains_with_corners(topo, &is_border, &forced);
    let mut curves = Vec::with_capacity(chains.len());
    for (c, chain) in chains.into_iter().enumerate() {
        let e0 = chain.edges[0];
        let (a, b) = (chain.vertices[0], chain.vertices[1]);
        for &f in topo.edge_faces(e0) {
            let t = atlas.mesh.triangles[f.idx()];
            let i = (0..3).find(|&i| t[i] == a && t[(i + 1) % 3] == b || t[i] == b && t[(i + 1) % 3] == a);
            let forward = i.is_some_and(|i| t[i] == a);
            let p = atlas.patch_per_face[f.idx()] as usize;
            if !atlas.patches[p].curves.iter().any(|&(cc, _)| cc == c as u32) {
                atlas.patches[p].curves.push((c as u32, forward));
            }
        }
        // Border edges are never bisected, so both ends are input vertices.
        let is_feature = feature_pairs.binary_search(&(a.min(b), a.max(b))).is_ok();
        curves.push(AtlasCurve { chain, is_feature });
    }
    atlas.curves = curves;
    atlas.corners = corners;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::orient2d;
    use crate::mesh::fixtures;

    fn atlas_of(m: &TriMesh) -> Atlas {
        build_atlas(m, &AtlasOptions::default(), &Progress::none()).unwrap()
    }

    /// Every input triangle is covered by atlas triangles of exactly one patch,
    /// with the same total area, and every map is one-to-one.
    fn check_invariants(input: &TriMesh, a: &Atlas) {
        let mut patch_of_input = vec![u32::MAX; input.n_faces()];
        let mut area = vec![0.0; input.n_faces()];
        for (f, s) in a.source_face.iter().enumerate() {
            let p = a.patch_per_face[f];
            assert!(patch_of_input[s.idx()] == u32::MAX || patch_of_input[s.idx()] == p);
            patch_of_input[s.idx()] = p;
            area[s.idx()] += a.mesh.face_area(FaceId::new(f));
        }
        for f in 0..input.n_faces() {
            assert!(patch_of_input[f] != u32::MAX, "input triangle {f} in no patch");
            assert!((area[f] - input.face_area(FaceId::new(f))).abs() < 1e-12 * (1.0 + area[f]));
        }
        for p in &a.patches {
            for t in &p.triangles {
                let [x, y, z] = t.map(|v| p.uv[v as usize]);
                assert!(orient2d(&x, &y, &z) > 0.0, "flipped parametric triangle in patch {}", p.report.id);
            }
            assert!(!p.curves.is_empty());
        }
        assert!(a.mesh.validate().is_ok());
    }

    #[test]
    fn disk_is_one_patch_on_the_unit_circle_and_nearly_conformal() {
        let m = fixtures::disk(10);
        let a = atlas_of(&m);
        check_invariants(&m, &a);
        assert_eq!(a.patches.len(), 1);
        assert_eq!(a.curves.len(), 1);
        assert_eq!(a.corners.len(), 1);
        let p = &a.patches[0];
        assert!(p.report.sigma_ratio_median > 0.999, "{}", p.report.sigma_ratio_median);
        for (local, v) in p.vertices.iter().enumerate() {
            if m.positions[v.idx()].norm() > 0.999 {
                assert!((p.uv[local].norm() - 1.0).abs() < 1e-14);
            }
        }
    }

    /// Median σ2/σ1 of the triangles whose centroid is within 0.1 of the square's centre.
    fn central_sigma_median(m: &TriMesh) -> f64 {
        let a = atlas_of(m);
        check_invariants(m, &a);
        assert_eq!(a.patches.len(), 1);
        let p = &a.patches[0];
        let mut s: Vec<f64> = p
            .triangles
            .iter()
            .zip(&p.sigma_ratio)
            .filter(|(t, _)| {
                let c: crate::geom::Vec3 = t.iter().map(|&v| a.mesh.positions[p.vertices[v as usize].idx()]).sum();
                (c / 3.0 - crate::geom::Vec3::new(0.5, 0.5, 0.0)).norm() < 0.1
            })
            .map(|(_, s)| *s)
            .collect();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    }

    #[test]
    fn square_maps_conformally_near_its_centre() {
        // By the square's symmetry the harmonic map to the disk is conformal
        // at the centre; on a symmetric mesh MVC approximates it (measured:
        // median 0.991 at n = 12, 0.992 at 36, 0.991 at 72).
        for n in [12, 36] {
            let median = central_sigma_median(&fixtures::square(n));
            assert!(median > 0.98, "n = {n}: median {median}");
        }
    }

    #[test]
    fn mvc_is_not_a_laplacian_on_the_structured_square() {
        // Thesis appendix A.B: with all diagonals in one direction the MVC
        // stencil has a mixed-derivative term, so σ2/σ1 at the centre stays
        // near 0.92 under refinement instead of approaching 1.
        for n in [12, 36] {
            let median = central_sigma_median(&fixtures::square_structured(n));
            assert!(median < 0.95 && median > 0.85, "n = {n}: median {median}");
        }
    }

    #[test]
    fn sphere_is_split_into_disks() {
        let m = fixtures::icosphere(3);
        let a = atlas_of(&m);
        check_invariants(&m, &a);
        assert!(a.patches.len() >= 2);
        assert!(a.report.splits.closed >= 1);
        assert!(a.patches.iter().all(|p| p.report.n_boundary_loops == 1));
        assert_curvature_is_the_atlas_meshs(&a);
    }

    /// The input's curvature, computed beside the patch phase, is the atlas
    /// mesh's (no patch refined): same values, same directions where they
    /// are defined (not at umbilics).
    fn assert_curvature_is_the_atlas_meshs(a: &Atlas) {
        assert!(a.patches.iter().all(|p| p.report.n_bisections == 0));
        let own = principal_curvatures(&a.mesh, &Topology::new(&a.mesh));
        let c = &a.curvature;
        assert_eq!(own.curvature_max.len(), c.curvature_max.len());
        for v in 0..c.curvature_max.len() {
            let (k1, k2) = (own.curvature_max[v], own.curvature_min[v]);
            assert!((k1 - c.curvature_max[v]).abs() < 1e-9 && (k2 - c.curvature_min[v]).abs() < 1e-9);
            if (k1 - k2).abs() > 0.1 * k1.abs().max(k2.abs()) {
                let (x, y) = (own.direction_max[v], c.direction_max[v]);
                assert!((x - y).norm() < 1e-6 || (x + y).norm() < 1e-6, "vertex {v}: {x} {y}");
            }
        }
    }

    #[test]
    fn torus_is_split_until_genus_zero() {
        let m = fixtures::torus(1.0, 0.4, 40, 16);
        let a = atlas_of(&m);
        check_invariants(&m, &a);
        assert!(a.patches.len() >= 2);
        for p in &a.patches {
            let faces: Vec<FaceId> = p.faces.clone();
            let pm = PatchMesh::extract(&a.mesh, &faces);
            assert_eq!(pm.defect(), None);
        }
        assert_curvature_is_the_atlas_meshs(&a);
    }

    #[test]
    fn cube_has_6_patches_12_curves_8_corners() {
        let m = fixtures::cube(4);
        let a = atlas_of(&m);
        check_invariants(&m, &a);
        assert_eq!(a.patches.len(), 6);
        assert_eq!(a.curves.len(), 12);
        assert_eq!(a.corners.len(), 8);
        assert!(a.curves.iter().all(|c| c.is_feature));
        assert!(a.patches.iter().all(|p| p.curves.len() == 4));
        // Each curve bounds two patches with opposite orientations.
        for c in 0..12u32 {
            let uses: Vec<bool> =
                a.patches.iter().flat_map(|p| p.curves.iter().filter(|x| x.0 == c).map(|x| x.1)).collect();
            assert_eq!(uses.len(), 2);
            assert_ne!(uses[0], uses[1]);
        }
    }

    #[test]
    fn filling_a_concave_hole_beats_neumann() {
        // Thesis ch. 2 fig. 2.9: with homogeneous Neumann conditions the hole
        // becomes convex in (u, v) and the map nearly singular along it;
        // the pseudo-centre filling keeps it usable.
        let m = fixtures::l_plate_with_l_hole(24);
        let run = |max_hole_fill_vertices| {
            let opts = AtlasOptions { max_hole_fill_vertices, ..Default::default() };
            let a = build_atlas(&m, &opts, &Progress::none()).unwrap();
            check_invariants(&m, &a);
            assert_eq!(a.patches.len(), 1);
            a.patches[0].report.clone()
        };
        let filled = run(1000);
        let neumann = run(0);
        assert_eq!((filled.n_holes_filled, filled.n_holes_neumann), (1, 0));
        assert_eq!((neumann.n_holes_filled, neumann.n_holes_neumann), (0, 1));
        assert!(
            filled.sigma_ratio_min > 2.0 * neumann.sigma_ratio_min,
            "filled {} vs Neumann {}",
            filled.sigma_ratio_min,
            neumann.sigma_ratio_min
        );
        // Measured: min σ2/σ1 0.151 filled vs 0.0052 Neumann; medians 0.68 vs 0.49.
        assert!(filled.sigma_ratio_median > neumann.sigma_ratio_median);
    }

    #[test]
    fn small_patch_cap_forces_size_splits() {
        let m = fixtures::disk(12);
        let opts = AtlasOptions { max_patch_triangles: 200, ..Default::default() };
        let a = build_atlas(&m, &opts, &Progress::none()).unwrap();
        check_invariants(&m, &a);
        assert!(a.patches.len() >= m.n_faces().div_ceil(200));
        // One k-way cut into enough parts, not a cascade of bisections.
        assert!(a.report.splits.size >= 1 && a.report.splits.size < a.patches.len() - 1);
        assert!(a.patches.iter().all(|p| p.report.n_input_triangles <= 200));
    }

    #[test]
    fn cancellation_stops_the_stage() {
        let m = fixtures::icosphere(3);
        let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
        struct Nop;
        impl crate::progress::ProgressSink for Nop {
            fn report(&self, _: &str, _: f64) {}
        }
        let p = Progress::new(std::sync::Arc::new(Nop), cancel);
        assert_eq!(build_atlas(&m, &AtlasOptions::default(), &p).unwrap_err(), AtlasError::Cancelled);
    }
}
