//! The closed surface split into *parts* that can be tetrahedralized
//! independently, each with its own lattice spacing.
//!
//! A part is one edge-connected component of the surface, or several whose
//! bounding boxes overlap (transitively): nested shells (a hollow ball),
//! interlocked rings, a cavity inside a body. Crossing parity inside one
//! part's box does not depend on the triangles of another part (the inside
//! of a closed surface lies in its box, so a point outside that box crosses
//! it an even number of times), so stuffing the parts one by one gives
//! exactly the inside set of stuffing the whole surface at once.
//!
//! **Enclosed volume of a part** (the reference of the volume error): the
//! divergence theorem `V_i = ⅙ Σ a·(b × c)` per component, signed by nesting,
//! `V = Σ_i (−1)^{d_i} |V_i|` with `d_i` the number of other components of
//! the part that contain component `i` (crossing parity of a ray from one of
//! its vertices). This is the volume that crossing parity encloses for
//! components that do not cross each other, whatever their orientation.

use super::bvh::TriangleBvh;
use crate::geom::{BoundingBox, Vec3};
use crate::mesh::components::{DisjointSets, connected_components};
use crate::mesh::{Topology, TriMesh, VertexId};

/// One independently meshed part of a closed surface.
#[derive(Debug, Clone)]
pub struct SurfacePart {
    /// Indices of the connected components it holds (components are numbered
    /// by their smallest triangle id, see [`crate::mesh::components`]).
    pub components: Vec<u32>,
    /// Input triangle id of each triangle of `surface`.
    pub triangle_ids: Vec<u32>,
    /// The part's triangles, with its own vertex numbering.
    pub surface: TriMesh,
    /// Enclosed volume (divergence theorem, signed by nesting; see the
    /// module docs), model units cubed, non-negative.
    pub enclosed_volume: f64,
    /// Surface area, model units squared.
    pub area: f64,
    /// Bounding box of the part.
    pub bounds: BoundingBox,
}

impl SurfacePart {
    /// Characteristic thickness `2 V / A` (model units): the thickness of a
    /// wide slab, the radius of a long rod, ⅔ of a ball's radius. It is the
    /// quantity the volume error of a boundary layer of fixed depth scales
    /// with (see [`super::sizing`]).
    pub fn thickness(&self) -> f64 {
        if self.area > 0.0 { 2.0 * self.enclosed_volume / self.area } else { 0.0 }
    }
}

/// Split `surface` into parts (see the module docs), ordered by their
/// smallest component index. The surface should be closed (the caller
/// checks); an open one still splits, with a meaningless volume.
pub fn closed_parts(surface: &TriMesh) -> Vec<SurfacePart> {
    let topo = Topology::new(surface);
    let comps = connected_components(&topo);
    let faces = comps.faces_per_component();
    let boxes: Vec<BoundingBox> = faces
        .iter()
        .map(|fs| {
            let pts = fs.iter().flat_map(|f| surface.triangles[f.idx()].iter().map(|v| &surface.positions[v.idx()]));
            BoundingBox::of_points(pts).unwrap_or(BoundingBox { min: Vec3::zeros(), max: Vec3::zeros() })
        })
        .collect();
    let (label, n_parts) = overlapping_box_groups(&boxes);
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); n_parts];
    for (c, &l) in label.iter().enumerate() {
        members[l as usize].push(c as u32);
    }
    members
        .into_iter()
        .map(|cs| {
            let mut triangle_ids: Vec<u32> = cs.iter().flat_map(|&c| faces[c as usize].iter().map(|f| f.0)).collect();
            triangle_ids.sort_unstable();
            let part_surface = sub_surface(surface, &triangle_ids);
            let component_per_triangle: Vec<u32> =
                triangle_ids.iter().map(|&t| comps.component_per_face[t as usize]).collect();
            let enclosed_volume = nested_enclosed_volume(&part_surface, &component_per_triangle, &cs);
            let bounds = cs.iter().skip(1).fold(boxes[cs[0] as usize], |b, &c| BoundingBox {
                min: b.min.inf(&boxes[c as usize].min),
                max: b.max.sup(&boxes[c as usize].max),
            });
            SurfacePart {
                area: part_surface.area(),
                components: cs,
                triangle_ids,
                surface: part_surface,
                enclosed_volume,
                bounds,
            }
        })
        .collect()
}

/// Group labels (`0..k`, in order of first appearance) of boxes that
/// overlap transitively (closed boxes: touching counts), and `k`. Sweep over
/// the boxes sorted by `min.x`, so only boxes overlapping in `x` are tested.
pub fn overlapping_box_groups(boxes: &[BoundingBox]) -> (Vec<u32>, usize) {
    let mut sets = DisjointSets::new(boxes.len());
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by(|&a, &b| boxes[a].min.x.total_cmp(&boxes[b].min.x));
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if boxes[j].min.x > boxes[i].max.x {
                break;
            }
            let (a, b) = (&boxes[i], &boxes[j]);
            if a.min.y <= b.max.y && b.min.y <= a.max.y && a.min.z <= b.max.z && b.min.z <= a.max.z {
                sets.union(i as u32, j as u32);
            }
        }
    }
    sets.labels()
}

/// The triangles `triangle_ids` of `surface` with their vertices renumbered
/// in order of first use.
fn sub_surface(surface: &TriMesh, triangle_ids: &[u32]) -> TriMesh {
    let mut new_id = vec![u32::MAX; surface.n_vertices()];
    let mut positions = Vec::new();
    let triangles = triangle_ids
        .iter()
        .map(|&t| {
            surface.triangles[t as usize].map(|v| {
                if new_id[v.idx()] == u32::MAX {
                    new_id[v.idx()] = positions.len() as u32;
                    positions.push(surface.positions[v.idx()]);
                }
                VertexId(new_id[v.idx()])
            })
        })
        .collect();
    TriMesh { positions, triangles }
}

/// `Σ_i (−1)^{d_i} |V_i|` over the components `components` of `part`
/// (`component_per_triangle` labels its triangles), with `d_i` the nesting
/// depth of component `i` (module docs); `|V|` for a single component.
fn nested_enclosed_volume(part: &TriMesh, component_per_triangle: &[u32], components: &[u32]) -> f64 {
    let mut volume_of = vec![0.0f64; components.len()];
    let slot = |c: u32| components.binary_search(&c).unwrap_or(0);
    for (t, &c) in part.triangles.iter().zip(component_per_triangle) {
        let [a, b, d] = t.map(|v| part.positions[v.idx()]);
        volume_of[slot(c)] += a.dot(&b.cross(&d)) / 6.0;
    }
    if components.len() == 1 {
        return volume_of[0].abs();
    }
    let bvh = TriangleBvh::new(part);
    let reach = part.bounding_box().map_or(1.0, |b| 2.0 * b.diagonal() + 1.0);
    let mut first_vertex = vec![None; components.len()];
    for (t, &c) in part.triangles.iter().zip(component_per_triangle) {
        first_vertex[slot(c)].get_or_insert(part.positions[t[0].idx()]);
    }
    let total: f64 = (0..components.len())
        .map(|i| {
            let p = first_vertex[i].unwrap_or_else(Vec3::zeros);
            let depth = containing_components(&bvh, &p, reach, components[i], component_per_triangle, components);
            if depth.is_multiple_of(2) { volume_of[i].abs() } else { -volume_of[i].abs() }
        })
        .sum();
    total.max(0.0)
}

/// How many components other than `own` contain `p`: crossing parity per
/// component along a ray of length `reach`, recast in a perturbed direction
/// while a crossing is ambiguous.
fn containing_components(
    bvh: &TriangleBvh,
    p: &Vec3,
    reach: f64,
    own: u32,
    component_per_triangle: &[u32],
    components: &[u32],
) -> usize {
    let mut hits = Vec::new();
    let mut parity = vec![false; components.len()];
    for attempt in 0..8 {
        let e = attempt as f64 * 0.137;
        let dir = Vec3::new(1.0, 0.302_775_638 + e, 0.207_879_576 - 0.5 * e).normalize();
        bvh.segment_hits(p, &(p + dir * reach), &mut hits);
        let others = || hits.iter().filter(|h| component_per_triangle[h.triangle as usize] != own);
        if others().any(|h| h.ambiguous) && attempt < 7 {
            continue;
        }
        for h in others().filter(|h| !h.ambiguous) {
            let c = component_per_triangle[h.triangle as usize];
            let s = components.binary_search(&c).unwrap_or(0);
            parity[s] = !parity[s];
        }
        break;
    }
    parity.iter().filter(|x| **x).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::{self, placed, union};

    #[test]
    fn far_apart_components_are_separate_parts_with_their_own_volume() {
        let a = fixtures::icosphere(2);
        let b = placed(&fixtures::cube(2), Vec3::repeat(0.5), Vec3::new(10.0, 0.0, 0.0));
        let parts = closed_parts(&union(&[a.clone(), b.clone()]));
        assert_eq!(parts.len(), 2);
        assert_eq!((parts[0].components.clone(), parts[1].components.clone()), (vec![0], vec![1]));
        assert!((parts[0].enclosed_volume - a.signed_volume()).abs() < 1e-12);
        // The cube [-0.5, 0.5]³ + (10, 0, 0): volume 1, area 6, thickness 1/3.
        assert!((parts[1].enclosed_volume - 1.0).abs() < 1e-12 && (parts[1].area - 6.0).abs() < 1e-12);
        assert!((parts[1].thickness() - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(parts[1].surface.n_faces(), b.n_faces());
        assert!(parts[1].triangle_ids.iter().all(|&t| t as usize >= a.n_faces()));
    }

    #[test]
    fn a_nested_shell_is_one_part_whose_cavity_is_subtracted() {
        // Outer cube [-1, 1]³ (volume 8) around a ball of radius 0.5, both
        // outward oriented: parity encloses the shell, 8 − V_ball.
        let ball = placed(&fixtures::icosphere(2), Vec3::repeat(0.5), Vec3::zeros());
        let far = placed(&fixtures::icosphere(1), Vec3::repeat(0.1), Vec3::new(0.0, 5.0, 0.0));
        let parts = closed_parts(&union(&[fixtures::cube(3), ball.clone(), far]));
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0].components, vec![0, 1]);
        let expected = 8.0 - ball.signed_volume();
        assert!((parts[0].enclosed_volume - expected).abs() < 1e-12, "{}", parts[0].enclosed_volume);
    }

    #[test]
    fn boxes_group_transitively() {
        let b =
            |x0: f64, x1: f64, y0: f64| BoundingBox { min: Vec3::new(x0, y0, 0.0), max: Vec3::new(x1, y0 + 1.0, 1.0) };
        // 0–1 overlap, 1–2 overlap, 3 overlaps 0 in x only.
        let (labels, n) =
            overlapping_box_groups(&[b(0.0, 1.0, 0.0), b(0.5, 2.0, 0.0), b(1.5, 3.0, 0.5), b(0.2, 0.4, 5.0)]);
        assert_eq!((labels, n), (vec![0, 0, 0, 1], 2));
    }
}
