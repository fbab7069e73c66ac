//! Max-min vertex moves on the surface: each vertex of a set of quads is
//! moved, one at a time, to the candidate point that most raises the worst
//! scaled Jacobian of all its quads (then lowers their summed shortfall
//! below a threshold), until no candidate does: for a face vertex its
//! neighbours' mean or a step in one of [`N_DIRECTIONS`] tangent
//! directions at each of [`RADII`], projected onto the face; for a curve
//! vertex a step along its curve, between its curve neighbours
//! (untangling by maximizing the minimum, the criterion quadqs'
//! `smoothThePool` guards). A move never lowers the worst scaled Jacobian
//! of the vertex's quads (issue 13 §4).
//!
//! Two steps use it. Pillowing ([`super::pillow`]) untangles the region it
//! rewrote, up to [`super::pillow::ACCEPTED_SCALED_JACOBIAN`].
//! [`raise_worst_quads`], before and after pillowing, moves the vertices of
//! every quad below [`RAISED_SCALED_JACOBIAN`], counting shortfalls below 1
//! (a square), so each keeps raising the worst quad around it for as long
//! as a candidate does: the smoothing before it moves a vertex towards the
//! centre of its neighbours and keeps only what does not lower the worst
//! quad, which leaves the worst quads where the mean leaves them;
//! maximizing their minimum directly lifts them. There a curve vertex
//! keeps its chords: a slide along a curved curve that cuts more of the
//! face than before is not a candidate (the coverage check counts that
//! area), while on a straight curve it is free.
//!
//! Vertices are visited in index order on one thread, so the output does
//! not depend on the thread count.

use std::time::Instant;

use serde::Serialize;

use super::cleanup::quads_around_vertices;
use super::projection::{Projection, SurfaceProjector};
use super::smooth::quad_scaled_jacobian;
use super::surface_mesh::{ModelEntity, QuadMesh};
use crate::geom::Vec3;

/// Sweeps over the free vertices at most.
const MAX_SWEEPS: usize = 40;

/// Distance, as a fraction of the mean edge length at a vertex, within
/// which a candidate counts as landing on another corner of its quads
/// ([`lands_on_a_corner`]).
const COINCIDENT: f64 = 1e-9;

/// Tangent directions tried per radius.
const N_DIRECTIONS: usize = 12;

/// Step radii tried, as fractions of the mean edge length at the vertex.
const RADII: [f64; 4] = [0.4, 0.2, 0.1, 0.05];

/// Chord area a curve vertex's move may add when its chords are kept, as a
/// fraction of the square of its mean edge length: round-off only.
const CHORD_AREA_ROUND_OFF: f64 = 1e-12;

/// Quads below this scaled Jacobian have their vertices moved by
/// [`raise_worst_quads`]; the benchmark asks 99 % of quads at
/// least this good.
pub const RAISED_SCALED_JACOBIAN: f64 = 0.5;

/// Scaled Jacobian below which [`raise_worst_quads`] counts a shortfall:
/// a square's, so the moves go on raising the worst quad past
/// [`RAISED_SCALED_JACOBIAN`].
const RAISE_GOAL: f64 = 1.0;

/// What the vertex moves aim at.
#[derive(Debug, Clone, Copy)]
pub(super) struct Goal {
    /// Shortfalls are counted below this scaled Jacobian.
    pub threshold: f64,
    /// A curve vertex may not cut more of the face with its two chords.
    pub keep_chord_area: bool,
}

/// What raising the worst quads did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct RaiseStats {
    /// Quads below [`RAISED_SCALED_JACOBIAN`] when the step started.
    pub n_below_before: usize,
    /// Such quads when it ended.
    pub n_below_after: usize,
    /// Worst scaled Jacobian before (null for no quads).
    pub worst_before: Option<f64>,
    /// Worst scaled Jacobian after (null for no quads).
    pub worst_after: Option<f64>,
    /// Runs of the step (before and after pillowing).
    pub passes: usize,
    /// Wall seconds of the step.
    pub seconds: f64,
}

impl RaiseStats {
    /// The stats of this run followed by `later`: counts before from this
    /// one, after from `later`, seconds and passes summed.
    pub fn then(self, later: RaiseStats) -> RaiseStats {
        RaiseStats {
            n_below_before: self.n_below_before,
            n_below_after: later.n_below_after,
            worst_before: self.worst_before,
            worst_after: later.worst_after,
            passes: self.passes + later.passes,
            seconds: self.seconds + later.seconds,
        }
    }
}

/// Moves the vertices of every quad of `mesh` below
/// [`RAISED_SCALED_JACOBIAN`] by [`untangle`] towards [`RAISE_GOAL`],
/// curve vertices keeping their chords (module documentation).
pub fn raise_worst_quads(mesh: &mut QuadMesh, projector: &SurfaceProjector) -> RaiseStats {
    let t = Instant::now();
    let sj = |mesh: &QuadMesh| -> Vec<f64> {
        mesh.quads.iter().map(|q| quad_scaled_jacobian(&mesh.vertices, projector.face_normals(), q)).collect()
    };
    let worst = |j: &[f64]| j.iter().copied().reduce(f64::min);
    let before = sj(mesh);
    let low: Vec<u32> = (0..mesh.quads.len() as u32).filter(|&q| before[q as usize] < RAISED_SCALED_JACOBIAN).collect();
    if !low.is_empty() {
        untangle(mesh, projector, &low, Goal { threshold: RAISE_GOAL, keep_chord_area: true });
    }
    let after = sj(mesh);
    RaiseStats {
        n_below_before: low.len(),
        n_below_after: after.iter().filter(|&&j| j < RAISED_SCALED_JACOBIAN).count(),
        worst_before: worst(&before),
        worst_after: worst(&after),
        passes: 1,
        seconds: t.elapsed().as_secs_f64(),
    }
}

/// Moves the vertices of `quads` (all but corners; a curve vertex along
/// its curve), each to the candidate that most lowers the shortfall of its
/// quads below `goal.threshold` ([`is_better`]), until a sweep lowers none;
/// returns the worst scaled Jacobian of every quad at those vertices.
pub(super) fn untangle(mesh: &mut QuadMesh, projector: &SurfaceProjector, quads: &[u32], goal: Goal) -> f64 {
    let all = quads_around_vertices(mesh);
    let mut free: Vec<u32> = quads.iter().flat_map(|&q| mesh.quads[q as usize]).collect();
    free.sort_unstable();
    free.dedup();
    free.retain(|&v| !matches!(mesh.vertices.entity[v as usize], ModelEntity::Corner(_)));
    let curve_neighbours = curve_neighbours(mesh, &free);
    for _ in 0..MAX_SWEEPS {
        let mut moved = false;
        for (i, &v) in free.iter().enumerate() {
            moved |= move_to_best_candidate(mesh, projector, v, &all[v as usize], &curve_neighbours[i], goal);
        }
        if !moved {
            break;
        }
    }
    let mut around: Vec<u32> =
        free.iter().flat_map(|&v| all[v as usize].iter().copied()).chain(quads.iter().copied()).collect();
    around.sort_unstable();
    around.dedup();
    worst_of(mesh, projector, &around)
}

/// For each vertex of `vertices` (ascending) on a curve, its neighbours
/// along curve edges of that curve (empty for other vertices), in the
/// order of `mesh.curve_edges`: one pass over the curve edges.
fn curve_neighbours(mesh: &QuadMesh, vertices: &[u32]) -> Vec<Vec<u32>> {
    let mut out = vec![Vec::new(); vertices.len()];
    let on_curve = |v: u32, c: u32| matches!(mesh.vertices.entity[v as usize], ModelEntity::Curve(d) if d == c);
    for &(c, [a, b]) in &mesh.curve_edges {
        for (v, w) in [(a, b), (b, a)] {
            if on_curve(v, c)
                && let Ok(i) = vertices.binary_search(&v)
            {
                out[i].push(w);
            }
        }
    }
    out
}

/// Worst scaled Jacobian of `quads` of `mesh`.
pub(super) fn worst_of(mesh: &QuadMesh, projector: &SurfaceProjector, quads: &[u32]) -> f64 {
    quads
        .iter()
        .map(|&q| quad_scaled_jacobian(&mesh.vertices, projector.face_normals(), &mesh.quads[q as usize]))
        .fold(f64::INFINITY, f64::min)
}

/// How far `quads` fall short: the sum of their shortfalls below
/// `threshold` and their worst scaled Jacobian.
fn shortfall(mesh: &QuadMesh, projector: &SurfaceProjector, quads: &[u32], threshold: f64) -> (f64, f64) {
    let sj =
        quads.iter().map(|&q| quad_scaled_jacobian(&mesh.vertices, projector.face_normals(), &mesh.quads[q as usize]));
    sj.fold((0.0, f64::INFINITY), |(sum, worst), j| (sum + (threshold - j).max(0.0), worst.min(j)))
}

/// Whether shortfall `a` is better than `b`: a larger worst, or the same
/// worst and a smaller sum (so a move that mends one quad counts while
/// another stays the worst). Worst first: on cow it left 39 bad quads where
/// the sum first left 47 (`docs/decisions.md`).
fn is_better(a: (f64, f64), b: (f64, f64)) -> bool {
    a.1 > b.1 + 1e-9 || (a.1 >= b.1 - 1e-9 && a.0 < b.0 - 1e-12)
}

/// Candidate positions of vertex `v`: for a face vertex its neighbours'
/// mean (full and half step) and steps in [`N_DIRECTIONS`] tangent
/// directions at each of [`RADII`]; for a curve vertex steps along its
/// curve at each of [`RADII`] both ways, kept strictly between its two
/// curve neighbours (and, with `keep_chord_area`, cutting no more of the
/// face's area with its two chords than where it is). Each is projected onto the vertex's entity; a face
/// candidate whose projection lands farther from it than half its step is
/// left out (it fell onto another sheet of the face), and so is one that
/// lands on another corner of the vertex's quads ([`lands_on_a_corner`]).
fn candidates(
    mesh: &QuadMesh,
    projector: &SurfaceProjector,
    v: u32,
    quads: &[u32],
    curve_neighbours: &[u32],
    keep_chord_area: bool,
) -> Vec<Projection> {
    let verts = &mesh.vertices;
    let x = verts.positions[v as usize];
    let mut neighbours: Vec<u32> = Vec::new();
    for &q in quads {
        let quad = mesh.quads[q as usize];
        let k = quad.iter().position(|&w| w == v).unwrap_or(0);
        neighbours.extend([quad[(k + 1) % 4], quad[(k + 3) % 4]]);
    }
    neighbours.sort_unstable();
    neighbours.dedup();
    let positions: Vec<Vec3> = neighbours.iter().map(|&w| verts.positions[w as usize]).collect();
    let scale = positions.iter().map(|p| (p - x).norm()).sum::<f64>() / positions.len().max(1) as f64;
    if scale <= 0.0 {
        return Vec::new();
    }
    match verts.entity[v as usize] {
        ModelEntity::Corner(_) => Vec::new(),
        ModelEntity::Curve(c) => {
            let arc = |w: u32| {
                projector.curve_arc_length(c, &verts.positions[w as usize], Some(&verts.on_surface[w as usize]))
            };
            let (Some(s), [a, b]) = (arc(v), curve_neighbours) else { return Vec::new() };
            let (Some(sa), Some(sb)) = (arc(*a), arc(*b)) else { return Vec::new() };
            let (lo, hi) = (sa.min(sb), sa.max(sb));
            // A curve wrapping through its start between the neighbours: not moved.
            if !(lo < s && s < hi) || hi - lo > 0.5 * projector.curve_length(c) {
                return Vec::new();
            }
            let cut = |t: f64| projector.chord_area(c, lo, t) + projector.chord_area(c, t, hi);
            let most = if keep_chord_area { cut(s) + CHORD_AREA_ROUND_OFF * scale * scale } else { f64::INFINITY };
            RADII
                .iter()
                .flat_map(|r| [s + r * scale, s - r * scale])
                .filter(|t| lo < *t && *t < hi && (!keep_chord_area || cut(*t) <= most))
                .filter_map(|t| projector.curve_point_at(c, t))
                .collect()
        }
        ModelEntity::Face(face) => {
            let n = projector.normal_at(&verts.on_surface[v as usize]);
            let t1 = tangent(&n);
            let t2 = n.cross(&t1);
            let to_mean = positions.iter().sum::<Vec3>() / positions.len() as f64 - x;
            let to_mean = to_mean - n * to_mean.dot(&n);
            let mut steps: Vec<Vec3> = vec![to_mean, to_mean * 0.5];
            for r in RADII {
                for k in 0..N_DIRECTIONS {
                    let a = std::f64::consts::TAU * k as f64 / N_DIRECTIONS as f64;
                    steps.push((t1 * a.cos() + t2 * a.sin()) * (r * scale));
                }
            }
            steps
                .into_iter()
                .filter(|d| d.norm() > 1e-6 * scale)
                .filter_map(|d| {
                    let p = projector.project_to_face(face, &(x + d))?;
                    ((p.position - (x + d)).norm() <= 0.5 * d.norm()).then_some(p)
                })
                .filter(|p| !lands_on_a_corner(mesh, v, quads, &p.position, scale))
                .collect()
        }
    }
}

/// Whether `x` is within [`COINCIDENT`] × `scale` of another corner of
/// `v`'s `quads`. Such a move collapses a quad edge or diagonal, and a
/// degenerate quad (scaled Jacobian 0) would count as better than an
/// inverted one, though no later move of one vertex can open it again: on
/// a sharp cone tip (cow's horns, 101° of total angle) every nearby
/// candidate projects onto the tip, where a singular vertex sits.
fn lands_on_a_corner(mesh: &QuadMesh, v: u32, quads: &[u32], x: &Vec3, scale: f64) -> bool {
    quads
        .iter()
        .flat_map(|&q| mesh.quads[q as usize])
        .any(|w| w != v && (mesh.vertices.positions[w as usize] - x).norm() <= COINCIDENT * scale)
}

/// Moves vertex `v` (whose quads are `quads`) to the best of its
/// [`candidates`] when that is better by [`is_better`] (shortfalls below
/// `goal.threshold`); returns whether it moved.
fn move_to_best_candidate(
    mesh: &mut QuadMesh,
    projector: &SurfaceProjector,
    v: u32,
    quads: &[u32],
    curve_neighbours: &[u32],
    goal: Goal,
) -> bool {
    let current = shortfall(mesh, projector, quads, goal.threshold);
    if current.0 == 0.0 {
        return false;
    }
    let old = (mesh.vertices.positions[v as usize], mesh.vertices.on_surface[v as usize]);
    let mut best = (current, None);
    for p in candidates(mesh, projector, v, quads, curve_neighbours, goal.keep_chord_area) {
        mesh.vertices.positions[v as usize] = p.position;
        mesh.vertices.on_surface[v as usize] = p.on_surface;
        let s = shortfall(mesh, projector, quads, goal.threshold);
        if is_better(s, best.0) {
            best = (s, Some(p));
        }
    }
    match best.1 {
        Some(p) => {
            mesh.vertices.positions[v as usize] = p.position;
            mesh.vertices.on_surface[v as usize] = p.on_surface;
            true
        }
        None => {
            (mesh.vertices.positions[v as usize], mesh.vertices.on_surface[v as usize]) = old;
            false
        }
    }
}

/// A unit vector perpendicular to the unit vector `n`.
fn tangent(n: &Vec3) -> Vec3 {
    let axis = if n.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
    n.cross(&axis).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;
    use crate::quads::smooth::project_all;
    use crate::quads::smooth::tests::{Input, grid_mesh};

    fn worst(mesh: &QuadMesh, projector: &SurfaceProjector) -> f64 {
        let all: Vec<u32> = (0..mesh.quads.len() as u32).collect();
        worst_of(mesh, projector, &all)
    }

    /// Moves vertex `v` to `x` projected onto its entity.
    fn put(mesh: &mut QuadMesh, projector: &SurfaceProjector, v: usize, x: Vec3) {
        let p = projector.project(mesh.vertices.entity[v], &x, &mesh.vertices.on_surface[v]);
        mesh.vertices.positions[v] = p.position;
        mesh.vertices.on_surface[v] = p.on_surface;
    }

    /// The 6 × 6 grid of cell `h` on `input` (the unit square), projected:
    /// `(n, h, mesh)`.
    fn unit_grid(input: &Input, proj: &SurfaceProjector) -> (usize, f64, QuadMesh) {
        let n = 6;
        let h = 1.0 / n as f64;
        let mut mesh = grid_mesh(input, n, n, false, |i, j| Vec3::new(i as f64 * h, j as f64 * h, 0.0));
        project_all(&mut mesh, proj);
        (n, h, mesh)
    }

    /// A unit grid's quads are squares (scaled Jacobian 1) with every
    /// vertex where it belongs: a vertex pulled 0.45 of a cell diagonally
    /// inside, and the vertex of the straight side below it slid 0.6 of a
    /// cell along the side, are moved back until no quad is below the
    /// threshold.
    #[test]
    fn vertices_pulled_off_a_unit_grid_are_raised_back() {
        let input = Input::new(fixtures::square(6));
        let proj = input.projector();
        let (n, h, mut mesh) = unit_grid(&input, &proj);
        let inside = (n + 1) + 4;
        put(&mut mesh, &proj, inside, Vec3::new(3.55 * h, 1.45 * h, 0.0));
        let on_side = 4;
        assert!(matches!(mesh.vertices.entity[on_side], ModelEntity::Curve(_)));
        put(&mut mesh, &proj, on_side, Vec3::new(4.6 * h, 0.0, 0.0));
        let before = worst(&mesh, &proj);
        assert!(before < 0.5, "the pulled grid's worst quad is {before}");
        let stats = raise_worst_quads(&mut mesh, &proj);
        let after = worst(&mesh, &proj);
        assert_eq!((stats.n_below_after, stats.worst_before, stats.worst_after), (0, Some(before), Some(after)));
        assert!(after > 0.9, "worst after raising: {after}");
        // The side vertex stayed on its side.
        assert!(mesh.vertices.positions[on_side].y.abs() < 1e-12);
    }

    /// On a unit grid whose vertex above `v` is moved to a third of a cell
    /// from `v`, the step of 0.4 mean edge lengths along +y lands on it; no
    /// candidate may (it would collapse the edge between them).
    #[test]
    fn no_candidate_lands_on_another_corner() {
        let input = Input::new(fixtures::square(6));
        let proj = input.projector();
        let (n, h, mut mesh) = unit_grid(&input, &proj);
        let v = 2 * (n + 1) + 3;
        let above = v + n + 1;
        put(&mut mesh, &proj, above, Vec3::new(3.0 * h, (2.0 + 1.0 / 3.0) * h, 0.0));
        let quads: Vec<u32> = quads_around_vertices(&mesh).swap_remove(v);
        let target = mesh.vertices.positions[above];
        let onto = |p: &Projection| (p.position - target).norm() < 1e-6 * h;
        // The step that lands there exists (the tangent frame's first axis is +y).
        let x = mesh.vertices.positions[v];
        let scale = (3.0 * h + h / 3.0) / 4.0;
        assert!((x + Vec3::y() * RADII[0] * scale - target).norm() < 1e-12);
        let found = candidates(&mesh, &proj, v as u32, &quads, &[], false);
        assert!(found.len() > 40, "{} candidates", found.len());
        assert!(!found.iter().any(onto), "a candidate lands on the vertex above");
    }

    /// A ring vertex of a cylinder's rim (a 48-gon) slid along the rim: with
    /// chords kept, no candidate cuts more of the face than where it is,
    /// while without that some do (sliding towards a neighbour lengthens
    /// the other chord, which cuts more of the polygon).
    #[test]
    fn a_curve_vertex_keeping_its_chords_does_not_cut_more_of_the_face() {
        let (r, height) = (1.0, 1.0);
        let input = Input::new(fixtures::cylinder(r, height, 48, 6));
        let proj = input.projector();
        let (n, m) = (12, 3);
        let mut mesh = grid_mesh(&input, n, m, true, |i, j| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            Vec3::new(r * t.cos(), r * t.sin(), height * j as f64 / m as f64)
        });
        project_all(&mut mesh, &proj);
        let v = 3u32;
        let ModelEntity::Curve(c) = mesh.vertices.entity[v as usize] else { panic!("vertex 3 is on the rim") };
        let t = std::f64::consts::TAU * 3.2 / n as f64;
        put(&mut mesh, &proj, v as usize, Vec3::new(r * t.cos(), r * t.sin(), 0.0));
        let quads = quads_around_vertices(&mesh)[v as usize].clone();
        let neighbours = curve_neighbours(&mesh, &[v]).pop().unwrap();
        let arc = |p: &Vec3| proj.curve_arc_length(c, p, None).unwrap();
        let (sa, sb) = (
            arc(&mesh.vertices.positions[neighbours[0] as usize]),
            arc(&mesh.vertices.positions[neighbours[1] as usize]),
        );
        let (lo, hi) = (sa.min(sb), sa.max(sb));
        let cut = |p: &Vec3| proj.chord_area(c, lo, arc(p)) + proj.chord_area(c, arc(p), hi);
        let now = cut(&mesh.vertices.positions[v as usize]);
        let kept = candidates(&mesh, &proj, v, &quads, &neighbours, true);
        let free = candidates(&mesh, &proj, v, &quads, &neighbours, false);
        assert!(!kept.is_empty() && kept.len() < free.len(), "{} kept of {}", kept.len(), free.len());
        assert!(kept.iter().all(|p| cut(&p.position) <= now + 1e-12));
        assert!(free.iter().any(|p| cut(&p.position) > now + 1e-9));
    }
}
