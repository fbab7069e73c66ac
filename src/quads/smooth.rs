//! Step 5b of the quads stage: every vertex projected onto the input, then
//! guarded smoothing (issue 13 §4; research `quad-meshing.md` §1.1
//! "Validity guard", §5.1 step 5).
//!
//! 1. Every vertex is projected onto its model entity
//!    ([`SurfaceProjector::project`]): this fixes the approximate surface
//!    points of midpoint-subdivision vertices.
//! 2. `iterations` Gauss–Seidel sweeps, colour class by colour class: the
//!    vertices are coloured greedily in index order so that no two of a
//!    class share a quad; a class's moves read only vertices of other
//!    classes, so they are decided on the pool and applied together, and
//!    the result does not depend on the thread count:
//!    - a face vertex moves towards the mean of its edge neighbours, the
//!      displacement taken in the tangent plane of the input triangle under
//!      it, then projected onto its model face;
//!    - a curve vertex moves along its curve to the arc-length midpoint of
//!      its two curve neighbours (so a curve vertex at a bend of a smooth
//!      curve stays at the bend);
//!    - corners do not move.
//!
//!    A move is accepted only when the worst scaled Jacobian of the quads
//!    around the vertex does not decrease and no quad that was valid
//!    (scaled Jacobian > 0) becomes invalid (quadqs restores the geometry
//!    when the minimum SICN decreased, `smoothThePool`). A rejected full
//!    step is retried at half and a quarter of its length. Sweeps stop
//!    early when a sweep accepts no move.

use std::time::Instant;

use serde::Serialize;

use super::error::QuadsError;
use super::jacobian::{corner_of, scaled_jacobian_of_corners, scaled_jacobian_of_corners_until};
use super::projection::{Projection, SurfaceProjector};
use super::surface_mesh::{ModelEntity, QuadMesh, SurfaceVertices};
use crate::geom::Vec3;
use crate::progress::Progress;
use rayon::prelude::*;

/// Fractions of the full step tried, in order, until one is accepted.
const STEP_FRACTIONS: [f64; 3] = [1.0, 0.5, 0.25];

/// A move shorter than this fraction of the mean distance to the vertex's
/// neighbours is not made (it cannot change the shape measurably), so
/// sweeps stop once the mesh has settled.
const MIN_STEP: f64 = 1e-3;

/// What smoothing did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct SmoothStats {
    /// Sweeps run (at most the iterations asked; fewer when a sweep moved
    /// nothing).
    pub sweeps: usize,
    /// Vertex moves accepted over all sweeps.
    pub moves_accepted: u64,
    /// Vertex moves rejected by the validity guard (all step fractions).
    pub moves_rejected: u64,
    /// Largest distance a vertex moved when first projected onto the input.
    pub max_projection_distance: f64,
    /// Worst quad scaled Jacobian after the projection, before smoothing
    /// (`None`: no quad; measured after the projection because the normal
    /// under a quad comes from its vertices' surface points).
    pub min_scaled_jacobian_before: Option<f64>,
    /// Worst quad scaled Jacobian after projection and smoothing.
    pub min_scaled_jacobian_after: Option<f64>,
    /// Mean quad scaled Jacobian after the projection, before smoothing.
    pub mean_scaled_jacobian_before: Option<f64>,
    /// Mean quad scaled Jacobian after projection and smoothing.
    pub mean_scaled_jacobian_after: Option<f64>,
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// Projects every vertex onto the input, then smooths `iterations` sweeps.
///
/// # Errors
/// [`QuadsError::Cancelled`] (checked between sweeps).
pub fn smooth(
    mesh: &mut QuadMesh,
    projector: &SurfaceProjector,
    iterations: usize,
    progress: &Progress,
) -> Result<SmoothStats, QuadsError> {
    let t = Instant::now();
    let max_projection_distance = project_all(mesh, projector);
    let mut sj = quad_scaled_jacobians(mesh, projector.face_normals());
    let (min_before, mean_before) = sj_summary(&sj);
    let rings = Rings::new(mesh);
    let mut stats = SmoothStats {
        max_projection_distance,
        min_scaled_jacobian_before: min_before,
        mean_scaled_jacobian_before: mean_before,
        ..SmoothStats::default()
    };
    let mut stays = Stays::new(mesh.vertices.len());
    for sweep in 0..iterations {
        progress.check()?;
        let (accepted, rejected) = sweep_once(mesh, projector, &rings, &mut sj, &mut stays);
        stats.sweeps += 1;
        stats.moves_accepted += accepted;
        stats.moves_rejected += rejected;
        progress.set((sweep + 1) as f64 / iterations as f64);
        if accepted == 0 {
            break;
        }
    }
    (stats.min_scaled_jacobian_after, stats.mean_scaled_jacobian_after) = sj_summary(&sj);
    stats.seconds = t.elapsed().as_secs_f64();
    Ok(stats)
}

/// Scaled Jacobian of quad `quad` of `vertices` against the input surface's
/// normal under it (`normals`: the unit normal of every input triangle,
/// [`SurfaceProjector::face_normals`]).
pub fn quad_scaled_jacobian(vertices: &SurfaceVertices, normals: &[Vec3], quad: &[u32; 4]) -> f64 {
    scaled_jacobian_of_corners(normals, &quad.map(|v| corner_of(vertices, v)))
}

/// Scaled Jacobian of every quad of `mesh`, in quad order.
fn quad_scaled_jacobians(mesh: &QuadMesh, normals: &[Vec3]) -> Vec<f64> {
    mesh.quads.par_iter().map(|q| quad_scaled_jacobian(&mesh.vertices, normals, q)).collect()
}

/// Worst and mean of the quads' scaled Jacobians `sj` (`None` without quads).
fn sj_summary(sj: &[f64]) -> (Option<f64>, Option<f64>) {
    if sj.is_empty() {
        return (None, None);
    }
    let min = sj.iter().copied().fold(f64::INFINITY, f64::min);
    (Some(min), Some(sj.iter().sum::<f64>() / sj.len() as f64))
}

/// Projects every vertex of `mesh` onto its model entity (from its current
/// surface point) and returns the largest distance moved.
pub fn project_all(mesh: &mut QuadMesh, projector: &SurfaceProjector) -> f64 {
    let v = &mut mesh.vertices;
    let projected: Vec<Projection> = (0..v.len())
        .into_par_iter()
        .map(|i| projector.project(v.entity[i], &v.positions[i], &v.on_surface[i]))
        .collect();
    let mut worst: f64 = 0.0;
    for (i, p) in projected.into_iter().enumerate() {
        worst = worst.max((p.position - v.positions[i]).norm());
        v.positions[i] = p.position;
        v.on_surface[i] = p.on_surface;
    }
    worst
}

/// Per vertex: the quads around it and its edge neighbours; per curve
/// vertex: its neighbours along curve edges of its own curve; the colour
/// classes of the sweeps.
struct Rings {
    quads: Vec<Vec<u32>>,
    neighbours: Vec<Vec<u32>>,
    curve_neighbours: Vec<Vec<u32>>,
    /// Vertices with quads, by colour, increasing ids within a class.
    classes: Vec<Vec<u32>>,
}

impl Rings {
    fn new(mesh: &QuadMesh) -> Self {
        let n = mesh.vertices.len();
        let mut quads = vec![Vec::new(); n];
        let mut neighbours = vec![Vec::new(); n];
        for (qi, q) in mesh.quads.iter().enumerate() {
            for k in 0..4 {
                let v = q[k] as usize;
                quads[v].push(qi as u32);
                neighbours[v].push(q[(k + 1) % 4]);
                neighbours[v].push(q[(k + 3) % 4]);
            }
        }
        for list in &mut neighbours {
            list.sort_unstable();
            list.dedup();
        }
        let mut curve_neighbours = vec![Vec::new(); n];
        for &(c, [a, b]) in &mesh.curve_edges {
            for (x, y) in [(a, b), (b, a)] {
                if mesh.vertices.entity[x as usize] == ModelEntity::Curve(c) {
                    curve_neighbours[x as usize].push(y);
                }
            }
        }
        for list in &mut curve_neighbours {
            list.sort_unstable();
            list.dedup();
        }
        let classes = colour_classes(mesh, &quads);
        Self { quads, neighbours, curve_neighbours, classes }
    }
}

/// Greedy colouring in index order of the vertices that have quads: each
/// takes the smallest colour no vertex of its quads has yet, so no two
/// vertices of a class share a quad (a move changes only its own quads and
/// reads only their corners, so a class's moves are independent).
fn colour_classes(mesh: &QuadMesh, quads_of: &[Vec<u32>]) -> Vec<Vec<u32>> {
    let mut colour = vec![u32::MAX; quads_of.len()];
    let mut classes: Vec<Vec<u32>> = Vec::new();
    let mut taken: Vec<bool> = Vec::new();
    for (v, quads) in quads_of.iter().enumerate() {
        if quads.is_empty() {
            continue;
        }
        taken.clear();
        for &q in quads {
            for &w in &mesh.quads[q as usize] {
                let c = colour[w as usize];
                if c != u32::MAX {
                    if taken.len() <= c as usize {
                        taken.resize(c as usize + 1, false);
                    }
                    taken[c as usize] = true;
                }
            }
        }
        let c = taken.iter().position(|t| !t).unwrap_or(taken.len());
        colour[v] = c as u32;
        if classes.len() <= c {
            classes.resize(c + 1, Vec::new());
        }
        classes[c].push(v as u32);
    }
    classes
}

/// One Gauss–Seidel sweep, class by class; returns `(accepted, rejected)`
/// move counts. `sj` holds every quad's scaled Jacobian and is kept up to
/// date: a move's guard has evaluated the moved vertex's quads at the new
/// position, the same corners the quads then have. A vertex that stayed,
/// none of whose quads' corners has moved since, is not decided again
/// ([`Stays`]): its decision reads only those corners.
fn sweep_once(
    mesh: &mut QuadMesh,
    projector: &SurfaceProjector,
    rings: &Rings,
    sj: &mut [f64],
    stays: &mut Stays,
) -> (u64, u64) {
    let (mut accepted, mut rejected) = (0, 0);
    for class in &rings.classes {
        stays.step += 1;
        // Per vertex: its move, the fractions rejected, whether it was skipped.
        let decided: Vec<(Option<Move>, u64, bool)> = class
            .par_iter()
            .map(|&v| match stays.unchanged_since_it_stayed(mesh, rings, v) {
                Some(n_rejected) => (None, n_rejected, true),
                None => {
                    let (moved, n_rejected) = decide_move(mesh, projector, rings, sj, v as usize);
                    (moved, n_rejected, false)
                }
            })
            .collect();
        for (&v, (moved, n_rejected, skipped)) in class.iter().zip(decided) {
            rejected += n_rejected;
            if let Some(Move { to, sj_after }) = moved {
                mesh.vertices.positions[v as usize] = to.position;
                mesh.vertices.on_surface[v as usize] = to.on_surface;
                for (&q, after) in rings.quads[v as usize].iter().zip(sj_after) {
                    sj[q as usize] = after;
                }
                stays.moved_at[v as usize] = stays.step;
                stays.stayed[v as usize] = None;
                accepted += 1;
            } else if !skipped {
                stays.stayed[v as usize] = Some((stays.step, n_rejected));
            }
        }
    }
    (accepted, rejected)
}

/// What lets a sweep skip a vertex whose decision cannot have changed:
/// class steps are numbered from 1 over all sweeps; per vertex, the step
/// it last moved at (0: never) and, while it stays, the step it was last
/// decided (not skipped) to stay at with the step fractions rejected then.
struct Stays {
    step: u32,
    moved_at: Vec<u32>,
    stayed: Vec<Option<(u32, u64)>>,
}

impl Stays {
    fn new(n_vertices: usize) -> Self {
        Self { step: 0, moved_at: vec![0; n_vertices], stayed: vec![None; n_vertices] }
    }

    /// The rejections of `v`'s last decision when it stayed then and no
    /// corner of its quads has moved since (a class's vertices share no
    /// quad, so none moved at that step either).
    fn unchanged_since_it_stayed(&self, mesh: &QuadMesh, rings: &Rings, v: u32) -> Option<u64> {
        let (since, n_rejected) = self.stayed[v as usize]?;
        let moved = rings.quads[v as usize]
            .iter()
            .flat_map(|&q| mesh.quads[q as usize])
            .any(|w| self.moved_at[w as usize] >= since);
        (!moved).then_some(n_rejected)
    }
}

/// An accepted move: where the vertex goes, and the scaled Jacobians its
/// quads have there (in the order of its ring).
struct Move {
    to: Projection,
    sj_after: Vec<f64>,
}

/// Where vertex `v` moves this sweep (the first step fraction the guard
/// accepts; `None`: it stays) and how many fractions were rejected.
fn decide_move(
    mesh: &QuadMesh,
    projector: &SurfaceProjector,
    rings: &Rings,
    sj: &[f64],
    v: usize,
) -> (Option<Move>, u64) {
    let Some(target) = smoothing_target(mesh, projector, rings, v) else { return (None, 0) };
    let x = mesh.vertices.positions[v];
    let ring = &rings.neighbours[v];
    let local: f64 =
        ring.iter().map(|&w| (mesh.vertices.positions[w as usize] - x).norm()).sum::<f64>() / ring.len().max(1) as f64;
    let quads = &rings.quads[v];
    let mut rejected = 0;
    for f in STEP_FRACTIONS {
        let Some(candidate) = candidate_at(mesh, projector, v, &target, f) else { break };
        if (candidate.position - x).norm() <= MIN_STEP * local {
            break;
        }
        if let Some(sj_after) = quality_after_move(mesh, projector.face_normals(), quads, sj, v, &candidate) {
            return (Some(Move { to: candidate, sj_after }), rejected);
        }
        rejected += 1;
    }
    (None, rejected)
}

/// Where a vertex would go with a full step.
enum Target {
    /// A face vertex: towards this point (then onto its face).
    Face(Vec3),
    /// A curve vertex: along `curve` from arc length `from` to `to`.
    Curve { curve: u32, from: f64, to: f64 },
}

/// Where vertex `v` would go with a full step: for a face vertex the mean
/// of its edge neighbours, for a curve vertex the arc length on its curve
/// midway between its two curve neighbours. `None` for a corner or a curve
/// vertex without exactly two curve neighbours.
fn smoothing_target(mesh: &QuadMesh, projector: &SurfaceProjector, rings: &Rings, v: usize) -> Option<Target> {
    let verts = &mesh.vertices;
    match verts.entity[v] {
        ModelEntity::Corner(_) => None,
        ModelEntity::Face(_) => {
            let ring = &rings.neighbours[v];
            let sum: Vec3 = ring.iter().map(|&w| verts.positions[w as usize]).sum();
            Some(Target::Face(sum / ring.len() as f64))
        }
        ModelEntity::Curve(c) => {
            let [a, b] = rings.curve_neighbours[v][..] else { return None };
            let arc = |w: usize| projector.curve_arc_length(c, &verts.positions[w], Some(&verts.on_surface[w]));
            let s = arc(v)?;
            let length = projector.curve_length(c);
            let closed = projector.model.features.curves.get(c as usize).is_some_and(|k| k.is_closed());
            let unwrap = |t: f64| {
                if closed && length > 0.0 { s + (t - s + length / 2.0).rem_euclid(length) - length / 2.0 } else { t }
            };
            let (sa, sb) = (unwrap(arc(a as usize)?), unwrap(arc(b as usize)?));
            Some(Target::Curve { curve: c, from: s, to: 0.5 * (sa + sb) })
        }
    }
}

/// The candidate position of vertex `v` a fraction `f` of the way to
/// `target`, projected onto its entity.
fn candidate_at(
    mesh: &QuadMesh,
    projector: &SurfaceProjector,
    v: usize,
    target: &Target,
    f: f64,
) -> Option<Projection> {
    let verts = &mesh.vertices;
    match *target {
        Target::Face(t) => {
            let ModelEntity::Face(face) = verts.entity[v] else { return None };
            let x = verts.positions[v];
            let n = projector.normal_at(&verts.on_surface[v]);
            let d = (t - x) * f;
            let d = d - n * d.dot(&n);
            projector.project_to_face(face, &(x + d))
        }
        Target::Curve { curve, from, to } => projector.curve_point_at(curve, from + f * (to - from)),
    }
}

/// The scaled Jacobians of `quads` (the quads around `v`; `sj` holds every
/// quad's value now) with `v` moved to `candidate`, when the move keeps
/// their worst from decreasing and makes no valid quad (one whose scaled
/// Jacobian is positive) invalid; `None` otherwise, as soon as one quad
/// shows it. Nothing is moved: the quads are evaluated with `v`'s corner
/// at the candidate.
fn quality_after_move(
    mesh: &QuadMesh,
    normals: &[Vec3],
    quads: &[u32],
    sj: &[f64],
    v: usize,
    candidate: &Projection,
) -> Option<Vec<f64>> {
    let min_before = quads.iter().map(|&q| sj[q as usize]).fold(f64::INFINITY, f64::min);
    let mut after = Vec::with_capacity(quads.len());
    for &q in quads {
        let b = sj[q as usize];
        // Below this the move is rejected whatever the exact value.
        let floor = if b > 0.0 { min_before.max(0.0) } else { min_before };
        let a = quad_scaled_jacobian_with(&mesh.vertices, normals, &mesh.quads[q as usize], v as u32, candidate, floor);
        if (b > 0.0 && a <= 0.0) || a < min_before {
            return None;
        }
        after.push(a);
    }
    Some(after)
}

/// [`quad_scaled_jacobian`] with vertex `v` (a corner of `quad`) at `at`,
/// exact unless it is below `floor`.
fn quad_scaled_jacobian_with(
    vertices: &SurfaceVertices,
    normals: &[Vec3],
    quad: &[u32; 4],
    v: u32,
    at: &Projection,
    floor: f64,
) -> f64 {
    let corners = quad.map(|w| {
        let (entity, on_surface, position) = corner_of(vertices, w);
        if w == v { (entity, at.on_surface, at.position) } else { (entity, on_surface, position) }
    });
    scaled_jacobian_of_corners_until(normals, &corners, floor)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::atlas::features::detect_features;
    use crate::mesh::{FaceId, Topology, TriMesh, fixtures};
    use crate::quads::model::{QuadModel, quad_model};
    use crate::quads::surface_mesh::SurfacePoint;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// A surface, its topology and model, kept together for tests.
    pub(crate) struct Input {
        pub surface: TriMesh,
        pub topo: Topology,
        pub model: QuadModel,
    }

    impl Input {
        pub(crate) fn new(surface: TriMesh) -> Self {
            let topo = Topology::new(&surface);
            let model = quad_model(&surface, &topo, &detect_features(&surface, &topo, 30.0));
            Self { surface, topo, model }
        }

        pub(crate) fn projector(&self) -> SurfaceProjector<'_> {
            SurfaceProjector::new(&self.surface, &self.topo, &self.model)
        }
    }

    /// The structured `n × m` quad mesh of a grid of points `point(i, j)`
    /// (`i` along, `j` across; `wrap` closes it in `i`), classified on
    /// `input`'s model: a point on an input feature curve or corner gets
    /// that entity, others the model face under them. The surface point of
    /// every vertex is left deliberately rough (the first triangle of its
    /// model face), so the step's projection must fix it.
    pub(crate) fn grid_mesh(
        input: &Input,
        n: usize,
        m: usize,
        wrap: bool,
        point: impl Fn(usize, usize) -> Vec3,
    ) -> QuadMesh {
        let proj = input.projector();
        let ni = if wrap { n } else { n + 1 };
        let id = |i: usize, j: usize| (j * ni + i % ni) as u32;
        let mut mesh = QuadMesh::default();
        let rough = SurfacePoint { face: FaceId(0), bary: [1.0, 0.0, 0.0] };
        for j in 0..=m {
            for i in 0..ni {
                let x = point(i, j);
                let entity = classify(input, &proj, &x);
                mesh.vertices.push(x, rough, entity);
            }
        }
        for j in 0..m {
            for i in 0..n {
                mesh.quads.push([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        finish(input, &proj, &mut mesh);
        mesh
    }

    /// Classification of a point of a test mesh: the corner, curve or face
    /// of `input` it lies on (within 1e-9).
    pub(crate) fn classify(input: &Input, proj: &SurfaceProjector, x: &Vec3) -> ModelEntity {
        if let Some(i) = input.model.corners.iter().position(|&c| (input.surface.positions[c.idx()] - x).norm() < 1e-9)
        {
            return ModelEntity::Corner(i as u32);
        }
        for c in 0..input.model.features.curves.len() as u32 {
            if let Some(p) = proj.project_to_curve(c, x, None)
                && (p.position - x).norm() < 1e-9
            {
                return ModelEntity::Curve(c);
            }
        }
        let f = (0..input.model.n_faces as u32)
            .min_by(|&a, &b| {
                let d = |f| proj.project_to_face(f, x).map_or(f64::INFINITY, |p| (p.position - x).norm());
                d(a).total_cmp(&d(b))
            })
            .unwrap_or(0);
        ModelEntity::Face(f)
    }

    /// Fills the model face per quad and the curve edges of a test mesh.
    pub(crate) fn finish(input: &Input, proj: &SurfaceProjector, mesh: &mut QuadMesh) {
        mesh.model_face_per_quad = mesh
            .quads
            .iter()
            .map(|q| {
                q.iter()
                    .find_map(|&v| match mesh.vertices.entity[v as usize] {
                        ModelEntity::Face(f) => Some(f),
                        _ => None,
                    })
                    .unwrap_or_else(|| {
                        let c: Vec3 = q.iter().map(|&v| mesh.vertices.positions[v as usize]).sum::<Vec3>() / 4.0;
                        match classify(input, proj, &c) {
                            ModelEntity::Face(f) => f,
                            _ => 0,
                        }
                    })
            })
            .collect();
        // An edge is on curve `c` when both its ends are (a corner counts
        // for the curves it ends): true of the grids these tests build.
        let on = |v: u32, c: u32| match mesh.vertices.entity[v as usize] {
            ModelEntity::Curve(d) => d == c,
            ModelEntity::Corner(i) => {
                let k = &input.model.features.curves[c as usize].vertices;
                let corner = input.model.corners[i as usize];
                k.first() == Some(&corner) || k.last() == Some(&corner)
            }
            ModelEntity::Face(_) => false,
        };
        let mut edges = Vec::new();
        for q in &mesh.quads {
            for k in 0..4 {
                let (a, b) = (q[k], q[(k + 1) % 4]);
                for c in 0..input.model.features.curves.len() as u32 {
                    if on(a, c) && on(b, c) {
                        edges.push((c, [a.min(b), a.max(b)]));
                    }
                }
            }
        }
        edges.sort_unstable();
        edges.dedup();
        mesh.curve_edges = edges;
    }

    /// Largest distance of a vertex of `mesh` from the plane `z = 0`.
    fn plane_distance(mesh: &QuadMesh) -> f64 {
        mesh.vertices.positions.iter().map(|p| p.z.abs()).fold(0.0, f64::max)
    }

    /// The `n × n` grid of the unit square with its face vertices moved by
    /// up to `fraction` of a cell along x and y ([`jitter`]).
    fn jittered_grid(input: &Input, n: usize, rng: &mut StdRng, fraction: f64) -> QuadMesh {
        let mut mesh = grid_mesh(input, n, n, false, |i, j| Vec3::new(i as f64 / n as f64, j as f64 / n as f64, 0.0));
        jitter(&mut mesh, rng, fraction / n as f64);
        mesh
    }

    fn jitter(mesh: &mut QuadMesh, rng: &mut StdRng, amount: f64) {
        for v in 0..mesh.vertices.len() {
            if matches!(mesh.vertices.entity[v], ModelEntity::Face(_)) {
                let d = Vec3::new(rng.random_range(-amount..amount), rng.random_range(-amount..amount), 0.0);
                mesh.vertices.positions[v] += d;
            }
        }
    }

    fn all_sj(mesh: &QuadMesh, surface: &TriMesh) -> Vec<f64> {
        let normals = surface.face_normals();
        mesh.quads.iter().map(|q| quad_scaled_jacobian(&mesh.vertices, &normals, q)).collect()
    }

    #[test]
    fn smoothing_a_jittered_grid_on_a_square_raises_its_worst_quad_and_keeps_it_flat() {
        let input = Input::new(fixtures::square(8));
        let proj = input.projector();
        let n = 10;
        let mut rng = StdRng::seed_from_u64(13);
        let mut mesh = jittered_grid(&input, n, &mut rng, 0.35);
        project_all(&mut mesh, &proj);
        let fixed: Vec<(usize, Vec3)> = (0..mesh.vertices.len())
            .filter(|&v| matches!(mesh.vertices.entity[v], ModelEntity::Corner(_)))
            .map(|v| (v, mesh.vertices.positions[v]))
            .collect();
        assert!(!fixed.is_empty());
        let before = all_sj(&mesh, &input.surface);
        let stats = smooth(&mut mesh, &proj, 40, &Progress::none()).unwrap();
        let after = all_sj(&mesh, &input.surface);
        let min = |s: &[f64]| s.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(min(&after) > min(&before) + 0.05, "{} -> {}", min(&before), min(&after));
        assert!(min(&after) > 0.9, "a jittered grid smooths back to nearly square: {}", min(&after));
        eprintln!("square 10x10, jitter 0.35 h: {stats:?}");
        assert!(stats.moves_accepted > 0 && stats.sweeps > 0);
        assert_eq!(stats.min_scaled_jacobian_after, Some(min(&after)));
        assert_eq!(stats.min_scaled_jacobian_before, Some(min(&before)));
        assert!(plane_distance(&mesh) < 1e-12);
        for (v, x) in fixed {
            assert_eq!(mesh.vertices.positions[v], x, "corner {v} moved");
        }
        for v in 0..mesh.vertices.len() {
            let p = mesh.vertices.positions[v];
            assert!((proj.position_of(&mesh.vertices.on_surface[v]) - p).norm() < 1e-12);
            if let ModelEntity::Curve(_) = mesh.vertices.entity[v] {
                let on_edge =
                    p.x.abs() < 1e-12 || (p.x - 1.0).abs() < 1e-12 || p.y.abs() < 1e-12 || (p.y - 1.0).abs() < 1e-12;
                assert!(on_edge, "curve vertex {v} left the boundary: {p:?}");
            }
        }
    }

    #[test]
    fn an_accepted_move_never_lowers_its_neighbourhoods_worst_quad() {
        let input = Input::new(fixtures::square(6));
        let proj = input.projector();
        let n = 6;
        let mut rng = StdRng::seed_from_u64(21);
        let mut mesh = jittered_grid(&input, n, &mut rng, 0.3);
        project_all(&mut mesh, &proj);
        let rings = Rings::new(&mesh);
        let normals = input.surface.face_normals();
        let (mut accepted, mut rejected) = (0, 0);
        for _ in 0..400 {
            let v = rng.random_range(0..mesh.vertices.len());
            let ModelEntity::Face(f) = mesh.vertices.entity[v] else { continue };
            let x = mesh.vertices.positions[v]
                + Vec3::new(rng.random_range(-0.06..0.06), rng.random_range(-0.06..0.06), 0.0);
            let cand = proj.project_to_face(f, &x).unwrap();
            let worst = |m: &QuadMesh| {
                rings.quads[v]
                    .iter()
                    .map(|&q| quad_scaled_jacobian(&m.vertices, &normals, &m.quads[q as usize]))
                    .fold(f64::INFINITY, f64::min)
            };
            let w0 = worst(&mesh);
            let sj = quad_scaled_jacobians(&mesh, &normals);
            if let Some(after) = quality_after_move(&mesh, &normals, &rings.quads[v], &sj, v, &cand) {
                accepted += 1;
                mesh.vertices.positions[v] = cand.position;
                mesh.vertices.on_surface[v] = cand.on_surface;
                assert!(worst(&mesh) >= w0);
                assert!(worst(&mesh) > 0.0);
                // The values the guard returns are the moved quads' own.
                for (&q, a) in rings.quads[v].iter().zip(after) {
                    assert_eq!(quad_scaled_jacobian(&mesh.vertices, &normals, &mesh.quads[q as usize]), a);
                }
            } else {
                rejected += 1;
            }
        }
        assert!(accepted > 0 && rejected > 0, "{accepted} accepted, {rejected} rejected");
    }

    #[test]
    fn no_two_vertices_of_a_colour_class_share_a_quad() {
        let input = Input::new(fixtures::square(6));
        let n = 7;
        let mesh = grid_mesh(&input, n, n, false, |i, j| Vec3::new(i as f64 / n as f64, j as f64 / n as f64, 0.0));
        let rings = Rings::new(&mesh);
        let mut class_of = vec![None; mesh.vertices.len()];
        for (c, class) in rings.classes.iter().enumerate() {
            for &v in class {
                assert_eq!(class_of[v as usize].replace(c), None, "vertex {v} in two classes");
            }
        }
        assert!(class_of.iter().all(Option::is_some), "every grid vertex has quads and a class");
        for q in &mesh.quads {
            for a in 0..4 {
                for b in a + 1..4 {
                    assert_ne!(class_of[q[a] as usize], class_of[q[b] as usize], "quad {q:?}");
                }
            }
        }
        // A regular grid needs exactly four colours.
        assert_eq!(rings.classes.len(), 4);
    }

    #[test]
    fn smoothing_on_a_cylinder_keeps_vertices_on_it_and_rings_on_their_curves() {
        let (r, h) = (1.0, 2.0);
        let input = Input::new(fixtures::cylinder(r, h, 48, 12));
        assert_eq!(input.model.features.curves.len(), 2, "two boundary circles");
        let proj = input.projector();
        let (n, m) = (24, 8);
        let mut rng = StdRng::seed_from_u64(3);
        // Grid points on the input's facets (so the start is on the input),
        // jittered in angle and height inside the rings.
        let mut mesh = grid_mesh(&input, n, m, true, |i, j| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            Vec3::new(r * t.cos(), r * t.sin(), h * j as f64 / m as f64)
        });
        for v in 0..mesh.vertices.len() {
            if matches!(mesh.vertices.entity[v], ModelEntity::Face(_)) {
                let p = mesh.vertices.positions[v];
                let t = p.y.atan2(p.x) + rng.random_range(-0.4..0.4) * std::f64::consts::TAU / n as f64;
                let z = p.z + rng.random_range(-0.35..0.35) * h / m as f64;
                mesh.vertices.positions[v] = Vec3::new(r * t.cos(), r * t.sin(), z);
            }
        }
        project_all(&mut mesh, &proj);
        let before = all_sj(&mesh, &input.surface);
        let stats = smooth(&mut mesh, &proj, 8, &Progress::none()).unwrap();
        let after = all_sj(&mesh, &input.surface);
        let min = |s: &[f64]| s.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(min(&after) > min(&before), "{} -> {}", min(&before), min(&after));
        assert!(stats.moves_accepted > 0);
        eprintln!("cylinder 24x8 on a 48x12 input, jitter 0.4 / 0.35 cell: {stats:?}");
        // On the input's facets: within the chord sagitta of the 48-gon.
        let sagitta = r * (1.0 - (std::f64::consts::PI / 48.0).cos());
        for v in 0..mesh.vertices.len() {
            let p = mesh.vertices.positions[v];
            let rho = (p.x * p.x + p.y * p.y).sqrt();
            assert!(rho <= r + 1e-12 && rho >= r - sagitta - 1e-12, "vertex {v} off the cylinder: {rho}");
            assert!((proj.position_of(&mesh.vertices.on_surface[v]) - p).norm() < 1e-12);
            assert!((-1e-12..=h + 1e-12).contains(&p.z));
            if let ModelEntity::Curve(_) = mesh.vertices.entity[v] {
                assert!(p.z.abs() < 1e-12 || (p.z - h).abs() < 1e-12, "ring vertex {v} left its ring");
            }
        }
    }

    #[test]
    fn smoothing_is_deterministic() {
        let input = Input::new(fixtures::square(5));
        let proj = input.projector();
        let n = 7;
        let make = || jittered_grid(&input, n, &mut StdRng::seed_from_u64(77), 0.3);
        let (mut a, mut b) = (make(), make());
        smooth(&mut a, &proj, 5, &Progress::none()).unwrap();
        smooth(&mut b, &proj, 5, &Progress::none()).unwrap();
        assert_eq!(a.vertices.positions, b.vertices.positions);
        assert_eq!(a.vertices.on_surface, b.vertices.on_surface);
    }

    /// Skipping the vertices that stayed over an unchanged neighbourhood
    /// gives what deciding every vertex every sweep gives (a fresh record
    /// per sweep skips nothing), and it does skip some.
    #[test]
    fn skipping_unchanged_vertices_changes_nothing() {
        let input = Input::new(fixtures::square(5));
        let proj = input.projector();
        let n = 9;
        let mut mesh = jittered_grid(&input, n, &mut StdRng::seed_from_u64(5), 0.35);
        project_all(&mut mesh, &proj);
        let rings = Rings::new(&mesh);
        let run = |keep: bool| {
            let mut m = mesh.clone();
            let mut sj = quad_scaled_jacobians(&m, proj.face_normals());
            let mut stays = Stays::new(m.vertices.len());
            let mut counts = Vec::new();
            let mut skipped = 0;
            for _ in 0..30 {
                if !keep {
                    stays = Stays::new(m.vertices.len());
                }
                let before = stays.stayed.clone();
                counts.push(sweep_once(&mut m, &proj, &rings, &mut sj, &mut stays));
                skipped += (0..before.len()).filter(|&v| before[v].is_some() && before[v] == stays.stayed[v]).count();
            }
            (m, sj, counts, skipped)
        };
        let (kept, kept_sj, kept_counts, n_skipped) = run(true);
        let (fresh, fresh_sj, fresh_counts, _) = run(false);
        assert_eq!(kept.vertices.positions, fresh.vertices.positions);
        assert_eq!(kept.vertices.on_surface, fresh.vertices.on_surface);
        assert_eq!((kept_sj, kept_counts), (fresh_sj, fresh_counts));
        assert!(n_skipped > 0);
    }

    #[test]
    fn a_cancelled_smoothing_stops() {
        let input = Input::new(fixtures::square(2));
        let proj = input.projector();
        let mut mesh = grid_mesh(&input, 2, 2, false, |i, j| Vec3::new(i as f64 / 2.0, j as f64 / 2.0, 0.0));
        let progress = Progress::none();
        progress.cancel_flag().store(true, std::sync::atomic::Ordering::SeqCst);
        assert!(matches!(smooth(&mut mesh, &proj, 3, &progress), Err(QuadsError::Cancelled(_))));
    }
}
