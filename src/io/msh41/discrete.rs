//! Build an [`MshModel`] of a discrete atlas from a triangle mesh: corner
//! points, feature curves as vertex chains, patches as face sets with an
//! optional `(u, v)` per patch vertex.
//!
//! What the builder produces (the layout Gmsh writes after
//! `classifySurfaces` + `createGeometry`):
//! - point entity `k + 1` for the `k`-th corner, curve `k + 1` for the
//!   `k`-th curve, surface `k + 1` for the `k`-th patch;
//! - every vertex used by an entity is classified on the lowest-dimensional
//!   one: a corner on its point, an interior curve vertex on its curve, any
//!   other vertex on the first patch that uses it; node tag = vertex index + 1;
//! - element tags: the triangle of face `f` has tag `f + 1` (as in
//!   [`MshModel::from_surface`], so per-face views use the same tags), then
//!   come the corner points and the curve segments;
//! - when any patch has a `(u, v)` map: a curve parametrization for every
//!   curve (its chain, `u = 0, 1, …`) and a surface parametrization for every
//!   patch with a map, its triangles in the order of the patch's faces (the
//!   order of its element block, which Gmsh uses to match them).
//!
//! Curves must start and end at corners (a closed curve starts and ends at
//! the same corner), so Gmsh can bound them; a vertex may lie inside at
//! most one curve.

use super::model::{
    CurveEntity, CurveParametrization, ElementBlock, ElementType, EntityTag, MshModel, NodeBlock, PointEntity,
    SurfaceEntity, SurfaceParametrization,
};
use crate::geom::{Vec2, Vec3};
use crate::io::write_error::WriteError;
use crate::mesh::{FaceId, TriMesh, VertexId};

/// The `(u, v)` map of one patch.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PatchUv {
    /// The patch's vertices (each once), in any order: the parametrization's
    /// point list.
    pub vertices: Vec<VertexId>,
    /// `(u, v)` of each vertex, parallel to `vertices`.
    pub uv: Vec<Vec2>,
    /// Optional `[kmax, kmin]` (principal directions scaled by curvature)
    /// per vertex; empty for none.
    pub curvature: Vec<[Vec3; 2]>,
}

/// Collects corners, curves and patches of `mesh`; [`Self::build`] makes the model.
#[derive(Debug, Clone)]
pub struct DiscreteModelBuilder<'m> {
    mesh: &'m TriMesh,
    corners: Vec<VertexId>,
    curves: Vec<Vec<VertexId>>,
    patches: Vec<(Vec<FaceId>, Vec<EntityTag>, Option<PatchUv>)>,
}

impl<'m> DiscreteModelBuilder<'m> {
    /// An empty model over `mesh`.
    pub fn new(mesh: &'m TriMesh) -> Self {
        Self { mesh, corners: Vec::new(), curves: Vec::new(), patches: Vec::new() }
    }

    /// Add a corner at vertex `v`; returns its point entity tag.
    ///
    /// # Errors
    /// [`WriteError::IndexOutOfRange`] when `v` is not a vertex of the mesh,
    /// [`WriteError::Invalid`] when it already is a corner.
    pub fn add_corner(&mut self, v: VertexId) -> Result<EntityTag, WriteError> {
        self.check_vertex(v, "corner")?;
        if self.corners.contains(&v) {
            return Err(WriteError::Invalid(format!("vertex {v} is already a corner")));
        }
        self.corners.push(v);
        Ok(self.corners.len() as EntityTag)
    }

    /// Add a curve through the vertex chain `chain` (consecutive vertices
    /// joined by mesh edges, first and last at corners; equal for a closed
    /// curve); returns its curve entity tag.
    ///
    /// # Errors
    /// [`WriteError::Invalid`] for fewer than two vertices, a repeated
    /// consecutive vertex or an end that is not a corner;
    /// [`WriteError::IndexOutOfRange`] for a vertex not in the mesh.
    pub fn add_curve(&mut self, chain: Vec<VertexId>) -> Result<EntityTag, WriteError> {
        let tag = self.curves.len() as EntityTag + 1;
        if chain.len() < 2 {
            return Err(WriteError::Invalid(format!("curve {tag} has {} vertex(es), needs 2", chain.len())));
        }
        for &v in &chain {
            self.check_vertex(v, &format!("curve {tag}"))?;
        }
        if let Some(w) = chain.windows(2).find(|w| w[0] == w[1]) {
            return Err(WriteError::Invalid(format!("curve {tag} repeats vertex {} consecutively", w[0])));
        }
        for end in [chain[0], chain[chain.len() - 1]] {
            if !self.corners.contains(&end) {
                return Err(WriteError::Invalid(format!("curve {tag} ends at vertex {end}, which is not a corner")));
            }
        }
        self.curves.push(chain);
        Ok(tag)
    }

    /// Add a patch made of `faces`, bounded by the curves `boundary` (signed
    /// curve tags), with an optional `(u, v)` map; returns its surface tag.
    ///
    /// # Errors
    /// [`WriteError::Invalid`] for an empty patch, an unknown boundary curve
    /// or a map with mismatched lengths; [`WriteError::IndexOutOfRange`] for
    /// a face not in the mesh.
    pub fn add_patch(
        &mut self,
        faces: Vec<FaceId>,
        boundary: Vec<EntityTag>,
        uv: Option<PatchUv>,
    ) -> Result<EntityTag, WriteError> {
        let tag = self.patches.len() as EntityTag + 1;
        if faces.is_empty() {
            return Err(WriteError::Invalid(format!("patch {tag} has no face")));
        }
        if let Some(f) = faces.iter().find(|f| f.idx() >= self.mesh.n_faces()) {
            return Err(WriteError::IndexOutOfRange {
                what: format!("patch {tag}"),
                index: u64::from(f.0),
                n_points: self.mesh.n_faces(),
            });
        }
        if let Some(c) = boundary.iter().find(|c| c.unsigned_abs() as usize > self.curves.len() || **c == 0) {
            return Err(WriteError::Invalid(format!("patch {tag} is bounded by curve {c}, which was not added")));
        }
        if let Some(p) = &uv
            && (p.uv.len() != p.vertices.len() || (!p.curvature.is_empty() && p.curvature.len() != p.vertices.len()))
        {
            return Err(WriteError::LengthMismatch {
                what: format!("patch {tag} (u, v) map"),
                expected: p.vertices.len(),
                got: if p.uv.len() != p.vertices.len() { p.uv.len() } else { p.curvature.len() },
            });
        }
        self.patches.push((faces, boundary, uv));
        Ok(tag)
    }

    /// The model: entities, classified nodes, elements and parametrizations.
    ///
    /// # Errors
    /// [`WriteError::Invalid`] when the mesh is invalid ([`TriMesh::validate`]),
    /// a face is in two patches, a vertex lies inside two curves, or a patch
    /// face has a vertex missing from its map; then any error of
    /// [`MshModel::validate`].
    pub fn build(&self) -> Result<MshModel, WriteError> {
        let mesh = self.mesh;
        mesh.validate().map_err(|e| WriteError::Invalid(format!("mesh: {e}")))?;
        let n_faces = mesh.n_faces() as u64;
        // Classification: (dim, entity tag) per vertex, lowest dimension wins.
        let mut class: Vec<Option<(u8, EntityTag)>> = vec![None; mesh.n_vertices()];
        for (k, &v) in self.corners.iter().enumerate() {
            class[v.idx()] = Some((0, k as EntityTag + 1));
        }
        for (k, chain) in self.curves.iter().enumerate() {
            for &v in &chain[1..chain.len() - 1] {
                match class[v.idx()] {
                    None => class[v.idx()] = Some((1, k as EntityTag + 1)),
                    Some((0, _)) => {}
                    Some((_, other)) => {
                        return Err(WriteError::Invalid(format!(
                            "vertex {v} lies inside curves {other} and {} without being a corner",
                            k + 1
                        )));
                    }
                }
            }
        }
        let mut face_patch = vec![0 as EntityTag; mesh.n_faces()];
        for (k, (faces, _, _)) in self.patches.iter().enumerate() {
            let tag = k as EntityTag + 1;
            for &f in faces {
                if face_patch[f.idx()] != 0 {
                    return Err(WriteError::Invalid(format!(
                        "face {f} is in patches {} and {tag}",
                        face_patch[f.idx()]
                    )));
                }
                face_patch[f.idx()] = tag;
                for v in mesh.triangles[f.idx()] {
                    class[v.idx()].get_or_insert((2, tag));
                }
            }
        }

        let points = self
            .corners
            .iter()
            .enumerate()
            .map(|(k, &v)| PointEntity {
                tag: k as EntityTag + 1,
                position: mesh.positions[v.idx()],
                physical_tags: vec![],
            })
            .collect();
        let curves = self
            .curves
            .iter()
            .enumerate()
            .map(|(k, chain)| {
                let corner = |v: &VertexId| self.corners.iter().position(|c| c == v).map_or(0, |i| i as EntityTag + 1);
                CurveEntity {
                    tag: k as EntityTag + 1,
                    bounding_points: vec![corner(&chain[0]), -corner(&chain[chain.len() - 1])],
                    physical_tags: vec![],
                }
            })
            .collect();
        let surfaces = self
            .patches
            .iter()
            .enumerate()
            .map(|(k, (_, boundary, _))| SurfaceEntity {
                tag: k as EntityTag + 1,
                bounding_curves: boundary.clone(),
                physical_tags: vec![],
            })
            .collect();

        let node_blocks = node_blocks(mesh, &class, self.corners.len(), self.curves.len(), self.patches.len());
        let mut model = MshModel { points, curves, surfaces, node_blocks, ..Default::default() };

        let mut next_tag = n_faces + 1;
        let mut take = |n: usize| {
            let tags: Vec<u64> = (next_tag..next_tag + n as u64).collect();
            next_tag += n as u64;
            tags
        };
        for (k, &v) in self.corners.iter().enumerate() {
            model.element_blocks.push(ElementBlock {
                entity_dim: 0,
                entity_tag: k as EntityTag + 1,
                element_type: ElementType::Point,
                tags: take(1),
                nodes: vec![u64::from(v.0) + 1],
            });
        }
        for (k, chain) in self.curves.iter().enumerate() {
            model.element_blocks.push(ElementBlock {
                entity_dim: 1,
                entity_tag: k as EntityTag + 1,
                element_type: ElementType::Line,
                tags: take(chain.len() - 1),
                nodes: chain.windows(2).flat_map(|w| [u64::from(w[0].0) + 1, u64::from(w[1].0) + 1]).collect(),
            });
        }
        for (k, (faces, _, _)) in self.patches.iter().enumerate() {
            let mut faces = faces.clone();
            faces.sort_unstable();
            model.element_blocks.push(ElementBlock {
                entity_dim: 2,
                entity_tag: k as EntityTag + 1,
                element_type: ElementType::Triangle,
                tags: faces.iter().map(|f| u64::from(f.0) + 1).collect(),
                nodes: faces.iter().flat_map(|f| mesh.triangles[f.idx()].map(|v| u64::from(v.0) + 1)).collect(),
            });
        }

        if self.patches.iter().any(|p| p.2.is_some()) {
            model.curve_parametrizations = self
                .curves
                .iter()
                .enumerate()
                .map(|(k, chain)| CurveParametrization {
                    curve: k as EntityTag + 1,
                    points: chain.iter().map(|v| mesh.positions[v.idx()]).collect(),
                })
                .collect();
            for (k, (faces, _, uv)) in self.patches.iter().enumerate() {
                if let Some(uv) = uv {
                    model.surface_parametrizations.push(surface_parametrization(mesh, k as EntityTag + 1, faces, uv)?);
                }
            }
        }
        model.validate()?;
        Ok(model)
    }

    fn check_vertex(&self, v: VertexId, what: &str) -> Result<(), WriteError> {
        if v.idx() < self.mesh.n_vertices() {
            Ok(())
        } else {
            Err(WriteError::IndexOutOfRange {
                what: what.to_string(),
                index: u64::from(v.0),
                n_points: self.mesh.n_vertices(),
            })
        }
    }
}

/// One node block per entity that has classified vertices, points first.
fn node_blocks(
    mesh: &TriMesh,
    class: &[Option<(u8, EntityTag)>],
    n_points: usize,
    n_curves: usize,
    n_patches: usize,
) -> Vec<NodeBlock> {
    let offsets = [0, n_points, n_points + n_curves, n_points + n_curves + n_patches];
    let mut blocks: Vec<NodeBlock> = (0..offsets[3])
        .map(|i| {
            let (dim, tag) = if i < offsets[1] {
                (0, i + 1)
            } else if i < offsets[2] {
                (1, i - offsets[1] + 1)
            } else {
                (2, i - offsets[2] + 1)
            };
            NodeBlock { entity_dim: dim, entity_tag: tag as EntityTag, ..Default::default() }
        })
        .collect();
    for (v, c) in class.iter().enumerate() {
        if let Some((dim, tag)) = *c {
            let b = &mut blocks[offsets[usize::from(dim)] + tag as usize - 1];
            b.tags.push(v as u64 + 1);
            b.positions.push(mesh.positions[v]);
        }
    }
    blocks.retain(|b| !b.tags.is_empty());
    blocks
}

/// The parametrization of patch `tag`: its map's points, and its faces (sorted
/// like the element block) as local indices.
fn surface_parametrization(
    mesh: &TriMesh,
    tag: EntityTag,
    faces: &[FaceId],
    uv: &PatchUv,
) -> Result<SurfaceParametrization, WriteError> {
    let mut local = std::collections::HashMap::with_capacity(uv.vertices.len());
    for (i, &v) in uv.vertices.iter().enumerate() {
        if v.idx() >= mesh.n_vertices() {
            return Err(WriteError::IndexOutOfRange {
                what: format!("patch {tag} map"),
                index: u64::from(v.0),
                n_points: mesh.n_vertices(),
            });
        }
        if local.insert(v, i as u32).is_some() {
            return Err(WriteError::Invalid(format!("patch {tag} map lists vertex {v} twice")));
        }
    }
    let mut sorted = faces.to_vec();
    sorted.sort_unstable();
    let triangles = sorted
        .iter()
        .map(|f| {
            let t = mesh.triangles[f.idx()];
            let mut out = [0u32; 3];
            for (o, v) in out.iter_mut().zip(t) {
                *o = *local
                    .get(&v)
                    .ok_or_else(|| WriteError::Invalid(format!("patch {tag}: vertex {v} of face {f} has no (u, v)")))?;
            }
            Ok(out)
        })
        .collect::<Result<Vec<_>, WriteError>>()?;
    Ok(SurfaceParametrization {
        surface: tag,
        positions: uv.vertices.iter().map(|v| mesh.positions[v.idx()]).collect(),
        uv: uv.uv.clone(),
        curvature: uv.curvature.clone(),
        triangles,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    /// The unit disk as one patch bounded by one closed curve through corner
    /// vertex of angle 0, `(u, v) = (x, y)`.
    fn disk_model() -> (TriMesh, MshModel) {
        let mesh = fixtures::disk(3);
        let ring: Vec<VertexId> = (0..mesh.n_vertices())
            .filter(|&v| (mesh.positions[v].norm() - 1.0).abs() < 1e-12)
            .map(VertexId::new)
            .collect();
        let mut b = DiscreteModelBuilder::new(&mesh);
        let corner = b.add_corner(ring[0]).unwrap();
        assert_eq!(corner, 1);
        let mut chain = ring.clone();
        chain.push(ring[0]);
        let curve = b.add_curve(chain).unwrap();
        let all: Vec<VertexId> = (0..mesh.n_vertices()).map(VertexId::new).collect();
        let uv = PatchUv {
            uv: all.iter().map(|v| mesh.positions[v.idx()].xy()).collect(),
            vertices: all,
            curvature: vec![],
        };
        b.add_patch((0..mesh.n_faces()).map(FaceId::new).collect(), vec![curve], Some(uv)).unwrap();
        let model = b.build().unwrap();
        (mesh, model)
    }

    #[test]
    fn disk_is_classified_like_gmsh_does() {
        let (mesh, m) = disk_model();
        assert_eq!((m.points.len(), m.curves.len(), m.surfaces.len()), (1, 1, 1));
        assert_eq!(m.curves[0].bounding_points, [1, -1]);
        assert_eq!(m.surfaces[0].bounding_curves, [1]);
        let sizes: Vec<(u8, usize)> = m.node_blocks.iter().map(|b| (b.entity_dim, b.tags.len())).collect();
        assert_eq!(sizes, [(0, 1), (1, 17), (2, 1 + 6 + 12)]);
        let els: Vec<(ElementType, usize)> = m.element_blocks.iter().map(|b| (b.element_type, b.tags.len())).collect();
        assert_eq!(els, [(ElementType::Point, 1), (ElementType::Line, 18), (ElementType::Triangle, mesh.n_faces())]);
        assert_eq!(m.element_blocks[2].tags[0], 1);
        assert_eq!(m.element_blocks[0].tags[0], mesh.n_faces() as u64 + 1);
        assert_eq!(m.curve_parametrizations[0].points.len(), 19);
        assert_eq!(m.curve_parametrizations[0].points[0], m.curve_parametrizations[0].points[18]);
        let p = &m.surface_parametrizations[0];
        assert_eq!((p.positions.len(), p.triangles.len()), (mesh.n_vertices(), mesh.n_faces()));
        // Triangles map back to the mesh's faces, in element-block order.
        for (f, t) in p.triangles.iter().enumerate() {
            assert_eq!(t.map(|i| p.positions[i as usize]), mesh.corners(FaceId::new(f)));
        }
    }

    #[test]
    fn rejects_inconsistent_input() {
        let mesh = fixtures::square(2);
        let mut b = DiscreteModelBuilder::new(&mesh);
        b.add_corner(VertexId(0)).unwrap();
        assert!(b.add_corner(VertexId(0)).is_err());
        assert!(b.add_corner(VertexId(99)).is_err());
        assert!(matches!(b.add_curve(vec![VertexId(0), VertexId(1)]), Err(WriteError::Invalid(_))));
        b.add_corner(VertexId(2)).unwrap();
        b.add_curve(vec![VertexId(0), VertexId(1), VertexId(2)]).unwrap();
        assert!(b.add_patch(vec![], vec![1], None).is_err());
        assert!(b.add_patch(vec![FaceId(0)], vec![2], None).is_err());
        b.add_patch(vec![FaceId(0), FaceId(1)], vec![1], None).unwrap();
        b.add_patch(vec![FaceId(1)], vec![], None).unwrap();
        assert!(matches!(b.build(), Err(WriteError::Invalid(m)) if m.contains("face 1 is in patches 1 and 2")));
        let mut b = DiscreteModelBuilder::new(&mesh);
        let uv = PatchUv { vertices: vec![VertexId(0), VertexId(1)], uv: vec![Vec2::zeros(); 2], curvature: vec![] };
        b.add_patch(vec![FaceId(0)], vec![], Some(uv)).unwrap();
        assert!(matches!(b.build(), Err(WriteError::Invalid(m)) if m.contains("has no (u, v)")));
        let mut broken = fixtures::square(1);
        broken.triangles[1][2] = VertexId(40);
        let mut b = DiscreteModelBuilder::new(&broken);
        b.add_patch(vec![FaceId(0), FaceId(1)], vec![], None).unwrap();
        assert!(matches!(b.build(), Err(WriteError::Invalid(m)) if m.starts_with("mesh: ")));
    }
}
