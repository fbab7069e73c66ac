//! Step 5c of the quads stage: quads still inverted, degenerate or nearly
//! flat (below [`ACCEPTED_SCALED_JACOBIAN`]) after smoothing are repaired
//! by pillowing a small region around them and untangling its inside
//! (issue 13 §5: no inverted quad on any output). A repair of a quad that
//! was valid is kept only when it raises the worst scaled Jacobian there:
//! the nearly flat ones are mostly the poor pairs recombination takes in a
//! face it cannot otherwise pair all-quad ([`super::recombine`]).
//!
//! Why moving vertices is not enough. The quads that survive smoothing have
//! too few corners somewhere: a vertex on a straight curve that lies in one
//! quad only (an ear of three curve points, midpoint-subdivided) has a 180°
//! corner whatever its neighbours do, and a corner of the boundary whose fan
//! was squeezed by a fold of the patch triangulation cannot open without a
//! further quad. Pillowing (Mitchell & Tautges, "Pillowing doublets:
//! refining a mesh to ensure that faces share at most one edge", 1995)
//! changes exactly that:
//!
//! - A region `R` (quads of one model face) has boundary edges, each used by
//!   one quad of `R`. Every vertex `w` on that boundary gets a copy `w'`
//!   inside the face; the quads of `R` are rewritten on the copies, and each
//!   boundary edge `(a, b)`, oriented as its quad of `R` runs it, gets the
//!   layer quad `(a, b, b', a')`. Every quad outside `R` is unchanged, every
//!   edge of `R`'s boundary is still used as before (by the layer quad
//!   instead of `R`'s), so conformity, the classification on the model
//!   faces and the valence identity hold by construction; a vertex on the
//!   boundary of `R` gains one quad (the 180° vertex gets two of about 90°).
//! - The copies start halfway between their vertex and the mean centre of
//!   its quads in `R`; then every vertex of `R` and its layer but the
//!   corners is moved by [`super::untangle`] (max-min moves, one vertex at
//!   a time) until no quad there is below [`ACCEPTED_SCALED_JACOBIAN`] or
//!   no move raises the worst.
//!
//! The region grows from the cluster of bad quads (joined through shared
//! vertices, per model face) ring by ring until its worst quad reaches
//! [`ACCEPTED_SCALED_JACOBIAN`]; failed attempts are undone. The vertices
//! of pinches (a vertex the boundary of `R` passes twice) get all their
//! quads of the face into `R`, so each boundary vertex needs one copy. The
//! step runs in index order on one thread, so the output does not depend
//! on the thread count. It adds irregular vertices (the region's corners
//! gain a quad), which the report counts; it exists to turn a failed job
//! into a valid mesh where earlier steps left a defect.

use std::collections::BTreeMap;
use std::time::Instant;

use serde::Serialize;

use super::cleanup::quads_around_vertices;
use super::projection::SurfaceProjector;
use super::quality::is_inverted_or_degenerate;
use super::smooth::quad_scaled_jacobian;
use super::surface_mesh::{ModelEntity, QuadMesh};
use super::untangle::{Goal, untangle};
use crate::geom::Vec3;

/// Quads below this scaled Jacobian are repaired, and a repaired region is
/// accepted when its worst quad reaches it: a margin over 0 that Gmsh's
/// `minSICN` also sees as valid, high enough to catch the nearly flat
/// corners of poor pairs (at most 0.02).
pub const ACCEPTED_SCALED_JACOBIAN: f64 = 0.1;

/// Rings of quads around a cluster tried before it is left as it is.
const MAX_RINGS: usize = 3;

/// Rings tried around a cluster whose quads are all valid (nearly flat, not
/// inverted): they do not fail the stage, and on a mesh with hundreds of
/// them that no region repairs (gmsh_lever) the wider regions cost seconds.
const MAX_RINGS_VALID: usize = 1;

/// Largest region (quads) pillowed at once.
const MAX_REGION_QUADS: usize = 400;

/// Rounds over the remaining bad quads (a repair can leave a neighbour's
/// cluster changed).
const MAX_ROUNDS: usize = 3;

/// Where a copy starts: this fraction of the way from its vertex to the
/// mean centre of the vertex's quads in the region.
const COPY_FRACTION: f64 = 0.5;

/// What pillowing did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct PillowStats {
    /// Quads below [`ACCEPTED_SCALED_JACOBIAN`] (or not measurable) when
    /// the step started.
    pub n_bad_before: usize,
    /// Such quads when it ended (a region that could not be raised to it
    /// keeps them; the check fails the stage only for inverted ones).
    pub n_bad_after: usize,
    /// Regions pillowed.
    pub n_regions: usize,
    /// Quads the layers added.
    pub n_quads_added: usize,
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// Pillows and untangles regions around every quad of `mesh` below
/// [`ACCEPTED_SCALED_JACOBIAN`] (module documentation); returns what it did.
pub fn pillow_bad_quads(mesh: &mut QuadMesh, projector: &SurfaceProjector) -> PillowStats {
    let t = Instant::now();
    let mut bad = bad_quads(mesh, projector);
    let mut stats = PillowStats { n_bad_before: bad.len(), n_bad_after: bad.len(), ..PillowStats::default() };
    for _ in 0..MAX_ROUNDS {
        if bad.is_empty() {
            break;
        }
        let mut repaired_any = false;
        for cluster in clusters(mesh, &bad) {
            // An earlier repair of this round may have fixed or rewritten it.
            if !cluster.iter().any(|&q| is_bad(mesh, projector, q)) {
                continue;
            }
            if let Some(added) = repair_cluster(mesh, projector, &cluster) {
                stats.n_regions += 1;
                stats.n_quads_added += added;
                repaired_any = true;
            }
        }
        // Later rounds retry the inverted quads only: a valid quad no region
        // raised in this round would cost the same search again.
        bad = bad_quads(mesh, projector);
        stats.n_bad_after = bad.len();
        bad.retain(|&q| is_inverted(mesh, projector, q));
        if !repaired_any {
            break;
        }
    }
    stats.seconds = t.elapsed().as_secs_f64();
    stats
}

/// Whether quad `q` is inverted or degenerate (or not measurable).
fn is_inverted(mesh: &QuadMesh, projector: &SurfaceProjector, q: u32) -> bool {
    is_inverted_or_degenerate(quad_scaled_jacobian(&mesh.vertices, projector.face_normals(), &mesh.quads[q as usize]))
}

/// Whether quad `q` is below [`ACCEPTED_SCALED_JACOBIAN`] (or not
/// measurable).
fn is_bad(mesh: &QuadMesh, projector: &SurfaceProjector, q: u32) -> bool {
    let j = quad_scaled_jacobian(&mesh.vertices, projector.face_normals(), &mesh.quads[q as usize]);
    is_inverted_or_degenerate(j) || j < ACCEPTED_SCALED_JACOBIAN
}

/// The inverted or degenerate quads of `mesh`, ascending.
fn bad_quads(mesh: &QuadMesh, projector: &SurfaceProjector) -> Vec<u32> {
    (0..mesh.quads.len() as u32).filter(|&q| is_bad(mesh, projector, q)).collect()
}

/// The bad quads grouped into clusters: two bad quads of the same model
/// face sharing a vertex are in one cluster. Each cluster is ascending;
/// clusters are ordered by their first quad.
fn clusters(mesh: &QuadMesh, bad: &[u32]) -> Vec<Vec<u32>> {
    let per_vertex = quads_around_vertices(mesh);
    let index: BTreeMap<u32, usize> = bad.iter().enumerate().map(|(i, &q)| (q, i)).collect();
    let mut parent: Vec<usize> = (0..bad.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (i, &q) in bad.iter().enumerate() {
        for &v in &mesh.quads[q as usize] {
            for &r in &per_vertex[v as usize] {
                let Some(&j) = index.get(&r) else { continue };
                if mesh.model_face_per_quad[r as usize] != mesh.model_face_per_quad[q as usize] {
                    continue;
                }
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut groups: BTreeMap<usize, Vec<u32>> = BTreeMap::new();
    for (i, &q) in bad.iter().enumerate() {
        groups.entry(root(&mut parent, i)).or_default().push(q);
    }
    groups.into_values().collect()
}

/// Repairs one cluster: pillows regions of 0 to [`MAX_RINGS`] rings around
/// it until one reaches [`ACCEPTED_SCALED_JACOBIAN`]; failing that, keeps
/// the best attempt that is valid and raises the cluster's worst scaled
/// Jacobian. Returns the quads added, `None` when no attempt was kept (the
/// mesh is then as before).
fn repair_cluster(mesh: &mut QuadMesh, projector: &SurfaceProjector, cluster: &[u32]) -> Option<usize> {
    let face = mesh.model_face_per_quad[cluster[0] as usize];
    let before = cluster
        .iter()
        .map(|&q| quad_scaled_jacobian(&mesh.vertices, projector.face_normals(), &mesh.quads[q as usize]))
        .fold(f64::INFINITY, f64::min);
    let mut best: Option<(usize, f64)> = None;
    let max_rings = if is_inverted_or_degenerate(before) { MAX_RINGS } else { MAX_RINGS_VALID };
    // Every attempt is undone before the next, so one index serves them all.
    let per_vertex = quads_around_vertices(mesh);
    for rings in 0..=max_rings {
        let Some(region) = region_around(mesh, &per_vertex, cluster, face, rings) else { break };
        let saved = Saved::of(mesh, &region);
        let worst = pillow_and_untangle(mesh, projector, &region, face);
        if worst >= ACCEPTED_SCALED_JACOBIAN {
            return Some(mesh.quads.len() - saved.n_quads);
        }
        if !is_inverted_or_degenerate(worst) && !(worst <= before) && best.is_none_or(|(_, w)| worst > w) {
            best = Some((rings, worst));
        }
        saved.restore(mesh);
    }
    let (rings, _) = best?;
    let region = region_around(mesh, &per_vertex, cluster, face, rings)?;
    let n_quads = mesh.quads.len();
    pillow_and_untangle(mesh, projector, &region, face);
    Some(mesh.quads.len() - n_quads)
}

/// The quads of model face `face` within `rings` rings (through shared
/// vertices) of `cluster`, with the quads of the face at every vertex its
/// boundary passes more than once; ascending. `None` when it exceeds
/// [`MAX_REGION_QUADS`], or when it spans a curve with the face on both
/// sides (a cut crease): pillowing rewrites the region's quads on copies
/// of its boundary vertices, which would take a crease edge inside it off
/// its curve. `per_vertex` is [`quads_around_vertices`] of `mesh`.
fn region_around(
    mesh: &QuadMesh,
    per_vertex: &[Vec<u32>],
    cluster: &[u32],
    face: u32,
    rings: usize,
) -> Option<Vec<u32>> {
    let mut region: Vec<u32> = cluster.to_vec();
    let of_face = |q: &u32| mesh.model_face_per_quad[*q as usize] == face;
    let grow = |region: &[u32], at: &[u32]| -> Vec<u32> {
        let mut out: Vec<u32> = region.to_vec();
        for &v in at {
            out.extend(per_vertex[v as usize].iter().filter(|q| of_face(q)));
        }
        out.sort_unstable();
        out.dedup();
        out
    };
    for _ in 0..rings {
        let vertices: Vec<u32> = region.iter().flat_map(|&q| mesh.quads[q as usize]).collect();
        region = grow(&region, &vertices);
    }
    for _ in 0..8 {
        let pinches = pinched_vertices(mesh, &region);
        if pinches.is_empty() {
            break;
        }
        region = grow(&region, &pinches);
    }
    let fits = region.len() <= MAX_REGION_QUADS && pinched_vertices(mesh, &region).is_empty();
    (fits && !spans_a_curve(mesh, &region)).then_some(region)
}

/// True when a curve edge of `mesh` is used by two quads of `region`.
fn spans_a_curve(mesh: &QuadMesh, region: &[u32]) -> bool {
    let mut uses: BTreeMap<[u32; 2], u32> = BTreeMap::new();
    for &q in region {
        let quad = mesh.quads[q as usize];
        for k in 0..4 {
            let (a, b) = (quad[k], quad[(k + 1) % 4]);
            *uses.entry([a.min(b), a.max(b)]).or_default() += 1;
        }
    }
    mesh.curve_edges.iter().any(|&(_, [a, b])| uses.get(&[a.min(b), a.max(b)]) == Some(&2))
}

/// Edges used by exactly one quad of `region`, each as its quad runs it
/// (`[a, b]`), in the order of the region's quads.
fn boundary_edges(mesh: &QuadMesh, region: &[u32]) -> Vec<[u32; 2]> {
    let mut uses: BTreeMap<[u32; 2], u32> = BTreeMap::new();
    for &q in region {
        let quad = mesh.quads[q as usize];
        for k in 0..4 {
            let (a, b) = (quad[k], quad[(k + 1) % 4]);
            *uses.entry([a.min(b), a.max(b)]).or_default() += 1;
        }
    }
    let mut out = Vec::new();
    for &q in region {
        let quad = mesh.quads[q as usize];
        for k in 0..4 {
            let (a, b) = (quad[k], quad[(k + 1) % 4]);
            if uses[&[a.min(b), a.max(b)]] == 1 {
                out.push([a, b]);
            }
        }
    }
    out
}

/// Vertices on more than two boundary edges of `region` (ascending).
fn pinched_vertices(mesh: &QuadMesh, region: &[u32]) -> Vec<u32> {
    let mut count: BTreeMap<u32, usize> = BTreeMap::new();
    for [a, b] in boundary_edges(mesh, region) {
        *count.entry(a).or_default() += 1;
        *count.entry(b).or_default() += 1;
    }
    count.into_iter().filter(|&(_, n)| n > 2).map(|(v, _)| v).collect()
}

/// What an attempt changes, to undo it.
struct Saved {
    n_quads: usize,
    n_vertices: usize,
    quads: Vec<(u32, [u32; 4])>,
    positions: Vec<(u32, Vec3, super::surface_mesh::SurfacePoint)>,
}

impl Saved {
    /// The state of `mesh` that pillowing `region` may change.
    fn of(mesh: &QuadMesh, region: &[u32]) -> Self {
        let quads: Vec<(u32, [u32; 4])> = region.iter().map(|&q| (q, mesh.quads[q as usize])).collect();
        let mut vertices: Vec<u32> = quads.iter().flat_map(|(_, quad)| *quad).collect();
        vertices.sort_unstable();
        vertices.dedup();
        let positions = vertices
            .into_iter()
            .map(|v| (v, mesh.vertices.positions[v as usize], mesh.vertices.on_surface[v as usize]))
            .collect();
        Saved { n_quads: mesh.quads.len(), n_vertices: mesh.vertices.len(), quads, positions }
    }

    /// Puts `mesh` back as it was.
    fn restore(self, mesh: &mut QuadMesh) {
        mesh.quads.truncate(self.n_quads);
        mesh.model_face_per_quad.truncate(self.n_quads);
        mesh.vertices.truncate(self.n_vertices);
        for (q, quad) in self.quads {
            mesh.quads[q as usize] = quad;
        }
        for (v, x, p) in self.positions {
            mesh.vertices.positions[v as usize] = x;
            mesh.vertices.on_surface[v as usize] = p;
        }
    }
}

/// Pillows `region` (quads of model face `face`) and untangles its inside;
/// returns the worst scaled Jacobian of the region's quads and its layer.
fn pillow_and_untangle(mesh: &mut QuadMesh, projector: &SurfaceProjector, region: &[u32], face: u32) -> f64 {
    let boundary = boundary_edges(mesh, region);
    let mut copy_of: BTreeMap<u32, u32> = BTreeMap::new();
    let mut centres: BTreeMap<u32, (Vec3, usize)> = BTreeMap::new();
    let pos = |mesh: &QuadMesh, v: u32| mesh.vertices.positions[v as usize];
    for &q in region {
        let quad = mesh.quads[q as usize];
        let c = quad.iter().map(|&v| pos(mesh, v)).sum::<Vec3>() / 4.0;
        for v in quad {
            let e = centres.entry(v).or_insert((Vec3::zeros(), 0));
            e.0 += c;
            e.1 += 1;
        }
    }
    for &[a, _] in &boundary {
        if copy_of.contains_key(&a) {
            continue;
        }
        let (sum, n) = centres[&a];
        let x = pos(mesh, a) + (sum / n as f64 - pos(mesh, a)) * COPY_FRACTION;
        let Some(p) = projector.project_to_face(face, &x) else { continue };
        let id = mesh.vertices.push(p.position, p.on_surface, ModelEntity::Face(face));
        copy_of.insert(a, id);
    }
    let copy = |v: u32| copy_of.get(&v).copied().unwrap_or(v);
    for &q in region {
        mesh.quads[q as usize] = mesh.quads[q as usize].map(copy);
    }
    let first_layer = mesh.quads.len();
    for &[a, b] in &boundary {
        mesh.quads.push([a, b, copy(b), copy(a)]);
        mesh.model_face_per_quad.push(face);
    }
    let touched: Vec<u32> = region.iter().copied().chain(first_layer as u32..mesh.quads.len() as u32).collect();
    untangle(mesh, projector, &touched, Goal { threshold: ACCEPTED_SCALED_JACOBIAN, keep_chord_area: false })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;
    use crate::quads::check::check_quad_mesh;
    use crate::quads::cleanup::tests::square_grid;
    use crate::quads::quality::quad_quality;
    use crate::quads::smooth::project_all;
    use crate::quads::smooth::tests::{Input, classify, finish};

    /// The unit square as three quads, the first `[a, v, b, c]` with `v`
    /// the middle of the bottom side: a 180° corner, the shape an ear of
    /// three curve points leaves after subdivision.
    fn square_with_a_flat_corner(input: &Input) -> QuadMesh {
        let proj = input.projector();
        let points = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.5, 0.5, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let mut mesh = QuadMesh::default();
        let rough = crate::quads::SurfacePoint { face: crate::mesh::FaceId(0), bary: [1.0, 0.0, 0.0] };
        for x in points {
            let entity = classify(input, &proj, &x);
            mesh.vertices.push(x, rough, entity);
        }
        mesh.quads = vec![[0, 1, 2, 3], [3, 2, 4, 5], [0, 3, 5, 6]];
        finish(input, &proj, &mut mesh);
        project_all(&mut mesh, &proj);
        mesh
    }

    #[test]
    fn a_flat_corner_on_the_boundary_is_pillowed_into_a_valid_mesh() {
        let input = Input::new(fixtures::square(4));
        let proj = input.projector();
        let mut mesh = square_with_a_flat_corner(&input);
        assert_eq!(bad_quads(&mesh, &proj), vec![0]);
        let stats = pillow_bad_quads(&mut mesh, &proj);
        assert_eq!((stats.n_bad_before, stats.n_bad_after, stats.n_regions), (1, 0, 1));
        let quality = quad_quality(&mesh, &input.surface);
        let worst = quality.scaled_jacobian.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(worst >= ACCEPTED_SCALED_JACOBIAN, "worst scaled Jacobian {worst}");
        // The middle of the bottom side now has two quads, so three edges.
        assert_eq!(quality.valence[1], 3);
        check_quad_mesh(&mesh, &quality, &input.surface, &input.topo, &input.model).unwrap();
    }

    #[test]
    fn an_inverted_inside_vertex_is_repaired_and_the_mesh_passes_its_checks() {
        let input = Input::new(fixtures::square(8));
        let proj = input.projector();
        let mut mesh = square_grid(&input, 6);
        project_all(&mut mesh, &proj);
        // Vertex (2, 2) pulled past (3, 3): four quads inverted or folded.
        let v = 2 * 7 + 2;
        let x = Vec3::new(0.62, 0.62, 0.0);
        let p = proj.project_to_face(0, &x).unwrap();
        mesh.vertices.positions[v] = p.position;
        mesh.vertices.on_surface[v] = p.on_surface;
        assert!(!bad_quads(&mesh, &proj).is_empty());
        let stats = pillow_bad_quads(&mut mesh, &proj);
        assert_eq!(stats.n_bad_after, 0);
        let quality = quad_quality(&mesh, &input.surface);
        check_quad_mesh(&mesh, &quality, &input.surface, &input.topo, &input.model).unwrap();
    }

    #[test]
    fn a_valid_mesh_is_left_as_it_is() {
        let input = Input::new(fixtures::square(4));
        let proj = input.projector();
        let mut mesh = square_grid(&input, 4);
        project_all(&mut mesh, &proj);
        let before = (mesh.quads.clone(), mesh.vertices.positions.clone());
        let stats = pillow_bad_quads(&mut mesh, &proj);
        assert_eq!((stats.n_bad_before, stats.n_regions), (0, 0));
        assert_eq!((mesh.quads.clone(), mesh.vertices.positions.clone()), before);
    }

    #[test]
    fn a_region_across_a_curve_with_its_face_on_both_sides_is_not_pillowed() {
        let input = Input::new(fixtures::square(4));
        let mut mesh = square_grid(&input, 6);
        // The edge from grid vertex (3, 2) to (3, 3) becomes a crease of
        // face 0: both its quads are in face 0.
        let (a, b) = (2 * 7 + 3, 3 * 7 + 3);
        let beside: Vec<u32> = (0..mesh.quads.len() as u32)
            .filter(|&q| [a, b].iter().all(|v| mesh.quads[q as usize].contains(v)))
            .collect();
        assert_eq!(beside.len(), 2);
        mesh.curve_edges.push((0, [a, b]));
        let per_vertex = quads_around_vertices(&mesh);
        assert_eq!(region_around(&mesh, &per_vertex, &beside[..1], 0, 0), Some(beside[..1].to_vec()));
        assert_eq!(region_around(&mesh, &per_vertex, &beside[..1], 0, 1), None);
    }
}
