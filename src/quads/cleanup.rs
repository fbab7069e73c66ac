//! Step 5a of the quads stage: topological cleanup, as Gmsh's
//! `removeTwoQuadsNodes` and `removeDiamonds` (research `quad-meshing.md`
//! §1.2 "Afterwards").
//!
//! - **Valence-2 vertex**: an interior vertex `v` in exactly two quads
//!   `[v, a, b, c]` and `[v, c, d, a]` is removed and the two quads become
//!   `[a, b, c, d]`.
//! - **3-3 diamond**: a quad `[p0, p1, p2, p3]` whose opposite corners `p0`
//!   and `p2` are interior vertices in three quads each is removed by
//!   collapsing its diagonal `p0 p2` to its midpoint (projected onto the
//!   model face); the merged vertex is in four quads, `p1` and `p3` lose one.
//!
//! Only face vertices are removed or merged, so curve edges and corners are
//! never touched; a vertex placed at a crossfield singularity is never
//! removed. An operation is applied only when every quad it creates or
//! moves has a positive scaled Jacobian and it does not raise the
//! *irregularity* `Σ |ideal − quads(v)|` of the vertices it touches (a
//! diamond must lower it, so a collapse never merely moves valence-3
//! vertices around). The ideal number of quads is 4 inside a face, `4 − k`
//! at a singularity of index `k` quarter turns, and on a curve or corner
//! `Σ_faces max(1, round(θ / (π/2)))` with `θ` the angle the quads span in
//! each model face (2 on a straight boundary, 1 per face at a cube
//! corner). Passes over all vertices and quads repeat until none applies
//! (each operation removes a quad, so this ends); then the vertex arrays
//! are compacted and every index list renumbered.

use std::collections::BTreeSet;
use std::time::Instant;

use serde::Serialize;

use super::projection::SurfaceProjector;
use super::smooth::quad_scaled_jacobian;
use super::surface_mesh::{ModelEntity, QuadMesh};
use crate::geom::angle_between;

/// What cleanup did (for the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct CleanupStats {
    /// Valence-2 vertices removed.
    pub valence2_removed: u64,
    /// 3-3 diamonds collapsed.
    pub diamonds_collapsed: u64,
    /// Candidate operations refused because a quad would not be valid.
    pub rejected_invalid: u64,
    /// Candidate operations refused because irregularity would not improve.
    pub rejected_irregularity: u64,
    /// Passes over the mesh until nothing applied.
    pub passes: usize,
    /// Vertices whose quad count differs from their ideal, before.
    pub irregular_before: u64,
    /// The same after.
    pub irregular_after: u64,
    /// `Σ |ideal − quads(v)|` before.
    pub irregularity_before: u64,
    /// The same after.
    pub irregularity_after: u64,
    /// Wall seconds of the step.
    pub seconds: f64,
}

/// Removes valence-2 vertices and 3-3 diamonds from `mesh` (to a
/// fixpoint), then compacts it. Any order-2 nodes are dropped (this step
/// runs before they are added).
pub fn clean_up(mesh: &mut QuadMesh, projector: &SurfaceProjector) -> CleanupStats {
    let t = Instant::now();
    let mut work = Work::new(mesh);
    let mut stats = CleanupStats::default();
    (stats.irregular_before, stats.irregularity_before) = work.irregularity_totals();
    loop {
        stats.passes += 1;
        let mut changed = false;
        for v in 0..work.mesh.vertices.len() {
            changed |= work.remove_valence2(v as u32, projector, &mut stats);
        }
        for q in 0..work.mesh.quads.len() {
            for r in 0..2 {
                changed |= work.collapse_diamond(q as u32, r, projector, &mut stats);
            }
        }
        if !changed {
            break;
        }
    }
    (stats.irregular_after, stats.irregularity_after) = work.irregularity_totals();
    work.compact();
    stats.seconds = t.elapsed().as_secs_f64();
    stats
}

/// The mesh being edited, with incidences kept up to date.
struct Work<'m> {
    mesh: &'m mut QuadMesh,
    alive_quad: Vec<bool>,
    alive_vertex: Vec<bool>,
    /// Alive quads around each vertex.
    quads_of: Vec<Vec<u32>>,
    /// Ideal number of quads of each vertex.
    ideal: Vec<i64>,
    /// Vertex placed at a singularity (never removed).
    singular: Vec<bool>,
}

impl<'m> Work<'m> {
    fn new(mesh: &'m mut QuadMesh) -> Self {
        let n = mesh.vertices.len();
        let quads_of = quads_around_vertices(mesh);
        let mut singular = vec![false; n];
        let mut ideal = ideal_quad_counts(mesh, &quads_of);
        for &(v, index) in &mesh.singular_vertices {
            if let Some(s) = singular.get_mut(v as usize) {
                *s = true;
                if matches!(mesh.vertices.entity[v as usize], ModelEntity::Face(_)) {
                    ideal[v as usize] = (4 - i64::from(index)).max(1);
                }
            }
        }
        let alive_quad = vec![true; mesh.quads.len()];
        // A vertex in no quad (a midpoint of a strip that was refused) is dropped.
        let alive_vertex = quads_of.iter().map(|q| !q.is_empty()).collect();
        Self { mesh, alive_quad, alive_vertex, quads_of, ideal, singular }
    }

    /// `|ideal − quads|` of vertex `v` if it had `count` quads.
    fn off(&self, v: u32, count: usize) -> i64 {
        (self.ideal[v as usize] - count as i64).abs()
    }

    /// (irregular vertices, total irregularity) over the alive vertices.
    fn irregularity_totals(&self) -> (u64, u64) {
        let mut out = (0, 0);
        for v in 0..self.quads_of.len() {
            if self.alive_vertex[v] && !self.quads_of[v].is_empty() {
                let d = self.off(v as u32, self.quads_of[v].len()) as u64;
                out.0 += u64::from(d > 0);
                out.1 += d;
            }
        }
        out
    }

    /// True when `v` may be removed or merged: an alive, non-singular
    /// vertex inside a model face.
    fn removable(&self, v: u32) -> Option<u32> {
        match self.mesh.vertices.entity[v as usize] {
            ModelEntity::Face(f) if self.alive_vertex[v as usize] && !self.singular[v as usize] => Some(f),
            _ => None,
        }
    }

    /// Quad `q` rotated so that it starts at `v`.
    fn rotated(&self, q: u32, v: u32) -> Option<[u32; 4]> {
        let quad = self.mesh.quads[q as usize];
        let k = quad.iter().position(|&w| w == v)?;
        Some([quad[k], quad[(k + 1) % 4], quad[(k + 2) % 4], quad[(k + 3) % 4]])
    }

    /// Removes vertex `v` if it is an interior valence-2 vertex and the
    /// merged quad is valid and no more irregular. Returns whether it did.
    fn remove_valence2(&mut self, v: u32, projector: &SurfaceProjector, stats: &mut CleanupStats) -> bool {
        if self.removable(v).is_none() || self.quads_of[v as usize].len() != 2 {
            return false;
        }
        let (q1, q2) = (self.quads_of[v as usize][0], self.quads_of[v as usize][1]);
        let (Some([_, a, b, c]), Some([_, c2, d, a2])) = (self.rotated(q1, v), self.rotated(q2, v)) else {
            return false;
        };
        let faces = &self.mesh.model_face_per_quad;
        if c2 != c || a2 != a || b == d || faces[q1 as usize] != faces[q2 as usize] {
            return false;
        }
        let merged = [a, b, c, d];
        if self.quad_exists(&merged, &[q1, q2]) {
            return false;
        }
        let (na, nc) = (self.quads_of[a as usize].len(), self.quads_of[c as usize].len());
        let before = self.off(v, 2) + self.off(a, na) + self.off(c, nc);
        let after = self.off(a, na - 1) + self.off(c, nc - 1);
        if after > before {
            stats.rejected_irregularity += 1;
            return false;
        }
        if !(quad_scaled_jacobian(&self.mesh.vertices, projector.face_normals(), &merged) > 0.0) {
            stats.rejected_invalid += 1;
            return false;
        }
        self.mesh.quads[q1 as usize] = merged;
        self.alive_quad[q2 as usize] = false;
        self.alive_vertex[v as usize] = false;
        self.quads_of[v as usize].clear();
        for w in [a, c] {
            self.quads_of[w as usize].retain(|&q| q != q2);
        }
        for q in &mut self.quads_of[d as usize] {
            if *q == q2 {
                *q = q1;
            }
        }
        self.quads_of[d as usize].sort_unstable();
        stats.valence2_removed += 1;
        true
    }

    /// True when an alive quad other than `except` has the corners of `quad`.
    fn quad_exists(&self, quad: &[u32; 4], except: &[u32]) -> bool {
        let mut key = *quad;
        key.sort_unstable();
        self.quads_of[quad[0] as usize].iter().any(|&q| {
            let mut other = self.mesh.quads[q as usize];
            other.sort_unstable();
            !except.contains(&q) && other == key
        })
    }

    /// Collapses the diagonal `r, r + 2` of quad `q` if it is a 3-3
    /// diamond whose collapse is valid and lowers the irregularity.
    fn collapse_diamond(&mut self, q: u32, r: usize, projector: &SurfaceProjector, stats: &mut CleanupStats) -> bool {
        if !self.alive_quad[q as usize] {
            return false;
        }
        let quad = self.mesh.quads[q as usize];
        let (p0, p1, p2, p3) = (quad[r], quad[r + 1], quad[(r + 2) % 4], quad[(r + 3) % 4]);
        let (Some(f0), Some(f2)) = (self.removable(p0), self.removable(p2)) else { return false };
        if f0 != f2 || self.quads_of[p0 as usize].len() != 3 || self.quads_of[p2 as usize].len() != 3 {
            return false;
        }
        if !self.diamond_is_simple(q, p0, p1, p2, p3) {
            return false;
        }
        let (n1, n3) = (self.quads_of[p1 as usize].len(), self.quads_of[p3 as usize].len());
        let before = self.off(p0, 3) + self.off(p2, 3) + self.off(p1, n1) + self.off(p3, n3);
        let after = self.off(p0, 4) + self.off(p1, n1 - 1) + self.off(p3, n3 - 1);
        if after >= before {
            stats.rejected_irregularity += 1;
            return false;
        }
        let verts = &self.mesh.vertices;
        let mid = (verts.positions[p0 as usize] + verts.positions[p2 as usize]) / 2.0;
        let Some(m) = projector.project_to_face(f0, &mid) else { return false };
        let around: Vec<u32> =
            self.quads_of[p0 as usize].iter().chain(&self.quads_of[p2 as usize]).copied().filter(|&x| x != q).collect();
        let old = (verts.positions[p0 as usize], verts.on_surface[p0 as usize]);
        self.mesh.vertices.positions[p0 as usize] = m.position;
        self.mesh.vertices.on_surface[p0 as usize] = m.on_surface;
        let valid = around.iter().all(|&x| {
            let moved = self.mesh.quads[x as usize].map(|w| if w == p2 { p0 } else { w });
            quad_scaled_jacobian(&self.mesh.vertices, projector.face_normals(), &moved) > 0.0
        });
        if !valid {
            (self.mesh.vertices.positions[p0 as usize], self.mesh.vertices.on_surface[p0 as usize]) = old;
            stats.rejected_invalid += 1;
            return false;
        }
        for &x in &around {
            for w in &mut self.mesh.quads[x as usize] {
                if *w == p2 {
                    *w = p0;
                }
            }
        }
        self.alive_quad[q as usize] = false;
        self.alive_vertex[p2 as usize] = false;
        self.quads_of[p2 as usize].clear();
        let mut merged = around;
        merged.sort_unstable();
        self.quads_of[p0 as usize] = merged;
        for w in [p1, p3] {
            self.quads_of[w as usize].retain(|&x| x != q);
        }
        stats.diamonds_collapsed += 1;
        true
    }

    /// True when merging `p2` into `p0` keeps the mesh a manifold: apart
    /// from `q` the quads around `p0` and around `p2` share no vertex other
    /// than `p1` and `p3`.
    fn diamond_is_simple(&self, q: u32, p0: u32, p1: u32, p2: u32, p3: u32) -> bool {
        let ring = |p: u32| -> BTreeSet<u32> {
            self.quads_of[p as usize]
                .iter()
                .filter(|&&x| x != q)
                .flat_map(|&x| self.mesh.quads[x as usize])
                .filter(|&w| w != p)
                .collect()
        };
        let (r0, r2) = (ring(p0), ring(p2));
        !r0.contains(&p2) && !r2.contains(&p0) && r0.intersection(&r2).all(|&w| w == p1 || w == p3)
    }

    /// Drops the dead quads and vertices and renumbers every index list.
    fn compact(self) {
        compact(self.mesh, &self.alive_vertex, &self.alive_quad);
    }
}

/// The quads around each vertex of `mesh`, in quad order.
pub(super) fn quads_around_vertices(mesh: &QuadMesh) -> Vec<Vec<u32>> {
    let mut quads_of = vec![Vec::new(); mesh.vertices.len()];
    for (qi, q) in mesh.quads.iter().enumerate() {
        for &v in q {
            quads_of[v as usize].push(qi as u32);
        }
    }
    quads_of
}

/// Drops the quads and vertices of `mesh` whose flag is not set in
/// `alive_quad` / `alive_vertex` (quads and vertices appended after the
/// flags were made are kept) and renumbers every index list; the dead
/// vertices leave the singular and seam lists. Any order-2 nodes are
/// dropped (the steps that edit topology run before they are added).
pub(super) fn compact(mesh: &mut QuadMesh, alive_vertex: &[bool], alive_quad: &[bool]) {
    let flags: Vec<bool> = (0..mesh.vertices.len()).map(|v| alive_vertex.get(v).copied().unwrap_or(true)).collect();
    let mut new_index = vec![u32::MAX; flags.len()];
    for (next, (slot, _)) in new_index.iter_mut().zip(&flags).filter(|(_, alive)| **alive).enumerate() {
        *slot = next as u32;
    }
    let verts = &mut mesh.vertices;
    retain_alive(&mut verts.positions, &flags);
    retain_alive(&mut verts.on_surface, &flags);
    retain_alive(&mut verts.entity, &flags);
    let map = |v: u32| new_index[v as usize];
    let (mut quads, mut faces) = (Vec::new(), Vec::new());
    for (q, quad) in mesh.quads.iter().enumerate() {
        if alive_quad.get(q).copied().unwrap_or(true) {
            quads.push(quad.map(map));
            faces.push(mesh.model_face_per_quad[q]);
        }
    }
    mesh.quads = quads;
    mesh.model_face_per_quad = faces;
    for (_, e) in &mut mesh.curve_edges {
        *e = e.map(map);
    }
    mesh.singular_vertices.retain(|&(v, _)| flags[v as usize]);
    for (v, _) in &mut mesh.singular_vertices {
        *v = map(*v);
    }
    mesh.seam_vertices.retain(|&v| flags[v as usize]);
    for v in &mut mesh.seam_vertices {
        *v = map(*v);
    }
    mesh.high_order_nodes = None;
}

/// Keeps the items of `items` whose flag in `alive` is set.
fn retain_alive<T>(items: &mut Vec<T>, alive: &[bool]) {
    let mut i = 0;
    items.retain(|_| {
        i += 1;
        alive[i - 1]
    });
}

/// Ideal number of quads at each vertex: 4 inside a face; on a curve or a
/// corner, per model face around it, the angle its quads span there in
/// quarter turns (at least 1).
fn ideal_quad_counts(mesh: &QuadMesh, quads_of: &[Vec<u32>]) -> Vec<i64> {
    let p = &mesh.vertices.positions;
    (0..mesh.vertices.len())
        .map(|v| {
            if matches!(mesh.vertices.entity[v], ModelEntity::Face(_)) {
                return 4;
            }
            let mut per_face: Vec<(u32, f64)> = Vec::new();
            for &q in &quads_of[v] {
                let quad = mesh.quads[q as usize];
                let Some(k) = quad.iter().position(|&w| w as usize == v) else { continue };
                let (a, b) = (p[quad[(k + 1) % 4] as usize] - p[v], p[quad[(k + 3) % 4] as usize] - p[v]);
                let f = mesh.model_face_per_quad[q as usize];
                match per_face.iter_mut().find(|(g, _)| *g == f) {
                    Some(slot) => slot.1 += angle_between(&a, &b),
                    None => per_face.push((f, angle_between(&a, &b))),
                }
            }
            per_face.iter().map(|(_, theta)| ((theta / std::f64::consts::FRAC_PI_2).round() as i64).max(1)).sum()
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geom::Vec3;
    use crate::mesh::FaceId;
    use crate::mesh::fixtures;
    use crate::quads::smooth::project_all;
    use crate::quads::smooth::tests::{Input, classify, finish, grid_mesh};
    use crate::quads::surface_mesh::SurfacePoint;
    use std::collections::HashMap;

    /// Every edge in one quad (on a curve) or two (inside), and no quad
    /// repeating a vertex.
    pub(crate) fn assert_conforming(mesh: &QuadMesh) {
        let mut count: HashMap<[u32; 2], usize> = HashMap::new();
        for q in &mesh.quads {
            let mut s = *q;
            s.sort_unstable();
            assert!(s.windows(2).all(|w| w[0] != w[1]), "quad repeats a vertex: {q:?}");
            for k in 0..4 {
                let (a, b) = (q[k], q[(k + 1) % 4]);
                *count.entry([a.min(b), a.max(b)]).or_default() += 1;
            }
        }
        let curve: std::collections::HashSet<[u32; 2]> = mesh.curve_edges.iter().map(|e| e.1).collect();
        for (e, n) in count {
            let boundary = curve.contains(&e);
            assert!(if boundary { n == 1 } else { n == 2 }, "edge {e:?} in {n} quads (curve: {boundary})");
        }
        let used: std::collections::HashSet<u32> = mesh.quads.iter().flatten().copied().collect();
        assert_eq!(used.len(), mesh.vertices.len(), "every vertex is used");
    }

    pub(crate) fn square_grid(input: &Input, n: usize) -> QuadMesh {
        grid_mesh(input, n, n, false, |i, j| Vec3::new(i as f64 / n as f64, j as f64 / n as f64, 0.0))
    }

    /// Adds a vertex inside quad `q` of `mesh`, joined to its corners 0 and
    /// 2: two quads around a valence-2 vertex.
    fn insert_doublet(mesh: &mut QuadMesh, q: usize) -> u32 {
        let [a, b, c, d] = mesh.quads[q];
        let p = &mesh.vertices.positions;
        let x = (p[a as usize] + p[b as usize] + p[c as usize] + p[d as usize]) / 4.0;
        let f = mesh.model_face_per_quad[q];
        let v = mesh.vertices.push(x, SurfacePoint { face: FaceId(0), bary: [1.0, 0.0, 0.0] }, ModelEntity::Face(f));
        mesh.quads[q] = [v, a, b, c];
        mesh.quads.push([v, c, d, a]);
        mesh.model_face_per_quad.push(f);
        v
    }

    /// Splits interior grid vertex `(i, j)` of an `n × n` grid mesh into a
    /// 3-3 diamond `[down, right, up, left]`: the vertex moves up by 0.3 of
    /// a cell, a new one sits 0.3 below, and the left and right neighbours
    /// end up in 5 quads (the inverse of a diamond collapse).
    pub(crate) fn insert_diamond(mesh: &mut QuadMesh, n: usize, i: usize, j: usize) -> (u32, u32) {
        let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        let (up, e_r, e_t, e_l, e_b) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i - 1, j), id(i, j - 1));
        let (c_tr, c_tl, c_bl, c_br) = (id(i + 1, j + 1), id(i - 1, j + 1), id(i - 1, j - 1), id(i + 1, j - 1));
        let block: Vec<usize> = (0..mesh.quads.len()).filter(|&q| mesh.quads[q].contains(&up)).collect();
        assert_eq!(block.len(), 4);
        let (pc, s, e) = (
            mesh.vertices.positions[up as usize],
            mesh.vertices.on_surface[up as usize],
            mesh.vertices.entity[up as usize],
        );
        let h = 1.0 / n as f64;
        mesh.vertices.positions[up as usize] = pc + Vec3::new(0.0, 0.3 * h, 0.0);
        let down = mesh.vertices.push(pc - Vec3::new(0.0, 0.3 * h, 0.0), s, e);
        let quads = [
            [up, e_r, c_tr, e_t],
            [e_l, up, e_t, c_tl],
            [c_bl, e_b, down, e_l],
            [e_b, c_br, e_r, down],
            [down, e_r, up, e_l],
        ];
        let face = mesh.model_face_per_quad[block[0]];
        for (k, &q) in block.iter().enumerate() {
            mesh.quads[q] = quads[k];
        }
        mesh.quads.push(quads[4]);
        mesh.model_face_per_quad.push(face);
        (up, down)
    }

    #[test]
    fn a_valence2_vertex_is_removed_and_the_mesh_stays_conforming() {
        let input = Input::new(fixtures::square(4));
        let proj = input.projector();
        let mut mesh = square_grid(&input, 4);
        project_all(&mut mesh, &proj);
        let (n_v, n_q) = (mesh.vertices.len(), mesh.quads.len());
        let doomed = insert_doublet(&mut mesh, 5);
        project_all(&mut mesh, &proj);
        let seam = mesh.vertices.len() as u32 - 1;
        mesh.seam_vertices = vec![seam, 7];
        assert_conforming(&mesh);
        let stats = clean_up(&mut mesh, &proj);
        assert_eq!(stats.valence2_removed, 1, "{stats:?}");
        assert_eq!((mesh.vertices.len(), mesh.quads.len()), (n_v, n_q));
        assert!(stats.irregularity_after < stats.irregularity_before);
        assert_conforming(&mesh);
        assert_eq!(mesh.seam_vertices, vec![7], "the removed vertex {doomed} leaves the seam list");
        let normals = input.surface.face_normals();
        assert!(mesh.quads.iter().all(|q| quad_scaled_jacobian(&mesh.vertices, &normals, q) > 0.9));
    }

    #[test]
    fn a_singular_valence2_vertex_is_kept() {
        let input = Input::new(fixtures::square(4));
        let proj = input.projector();
        let mut mesh = square_grid(&input, 4);
        let v = insert_doublet(&mut mesh, 5);
        project_all(&mut mesh, &proj);
        mesh.singular_vertices = vec![(v, 2)];
        let stats = clean_up(&mut mesh, &proj);
        assert_eq!(stats.valence2_removed, 0);
        assert_eq!(mesh.quads.len(), 17);
        assert_eq!(mesh.singular_vertices, vec![(v, 2)]);
        assert_conforming(&mesh);
    }

    #[test]
    fn a_3_3_diamond_is_collapsed_and_the_mesh_stays_conforming() {
        let input = Input::new(fixtures::square(6));
        let proj = input.projector();
        let n = 6;
        let mut mesh = square_grid(&input, n);
        project_all(&mut mesh, &proj);
        let (c, c2) = insert_diamond(&mut mesh, n, 3, 3);
        project_all(&mut mesh, &proj);
        assert_conforming(&mesh);
        let count = |m: &QuadMesh, v: u32| m.quads.iter().filter(|q| q.contains(&v)).count();
        assert_eq!((count(&mesh, c), count(&mesh, c2)), (3, 3));
        let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        // Both other corners of the diamond are in 5 quads: a collapse
        // leaves the whole mesh regular.
        assert_eq!((count(&mesh, id(4, 3)), count(&mesh, id(2, 3))), (5, 5));
        let (n_v, n_q) = (mesh.vertices.len(), mesh.quads.len());
        let mut singular_elsewhere = mesh.clone();
        let stats = clean_up(&mut mesh, &proj);
        assert_eq!(stats.diamonds_collapsed, 1, "{stats:?}");
        assert_eq!((mesh.vertices.len(), mesh.quads.len()), (n_v - 1, n_q - 1));
        assert_eq!(stats.irregular_after, 0);
        assert_conforming(&mesh);
        for v in 0..mesh.vertices.len() as u32 {
            if matches!(mesh.vertices.entity[v as usize], ModelEntity::Face(_)) {
                assert_eq!(count(&mesh, v), 4, "vertex {v}");
            }
        }
        let normals = input.surface.face_normals();
        assert!(mesh.quads.iter().all(|q| quad_scaled_jacobian(&mesh.vertices, &normals, q) > 0.0));
        // With c2 a singular vertex, nothing is collapsed.
        singular_elsewhere.singular_vertices = vec![(c2, 1)];
        let stats = clean_up(&mut singular_elsewhere, &proj);
        assert_eq!(stats.diamonds_collapsed, 0);
        assert_eq!(singular_elsewhere.quads.len(), n_q);
        assert_eq!(count(&singular_elsewhere, c2), 3);
    }

    #[test]
    fn a_regular_grid_and_a_cube_are_left_alone() {
        let input = Input::new(fixtures::square(4));
        let proj = input.projector();
        let mut mesh = square_grid(&input, 5);
        project_all(&mut mesh, &proj);
        let before = mesh.quads.clone();
        let stats = clean_up(&mut mesh, &proj);
        assert_eq!(mesh.quads, before);
        assert_eq!((stats.irregular_before, stats.irregular_after), (0, 0));
        // A cube's corners are in 3 quads, their ideal: no operation applies.
        let cube = Input::new(fixtures::cube(2));
        let cproj = cube.projector();
        let mut mesh = QuadMesh::default();
        let rough = SurfacePoint { face: FaceId(0), bary: [1.0, 0.0, 0.0] };
        for p in &cube.surface.positions {
            let e = classify(&cube, &cproj, p);
            mesh.vertices.push(*p, rough, e);
        }
        for t in cube.surface.triangles.chunks(2) {
            let ([a, b, c], [_, _, d]) = (t[0].map(|v| v.0), t[1].map(|v| v.0));
            mesh.quads.push([a, b, c, d]);
        }
        finish(&cube, &cproj, &mut mesh);
        project_all(&mut mesh, &cproj);
        let stats = clean_up(&mut mesh, &cproj);
        assert_eq!((stats.valence2_removed, stats.diamonds_collapsed), (0, 0));
        assert_eq!(stats.irregular_before, 0, "corners at 3 quads are ideal");
        assert_eq!(mesh.quads.len(), 24);
    }
}
