//! A general Gmsh model: entities, nodes and elements classified on them,
//! post-processing views and discrete parametrizations.
//!
//! This is the data the MSH writers ([`super::write`], [`crate::io::msh22::write`])
//! serialize. The stages fill it; the writers never invent data.
//!
//! # Conventions (those of Gmsh's MSH 4.1 format)
//! - **Entities** are points (dim 0), curves (1), surfaces (2) and volumes
//!   (3), each with a positive `i32` tag unique within its dimension. A curve
//!   is bounded by points (`+start`, `−end`; a closed curve names its single
//!   point twice, `[p, -p]`), a surface by curves, a volume by surfaces; a
//!   negative bounding tag means "reversed".
//! - **Nodes and elements** carry positive `u64` tags, unique across the
//!   model, not necessarily contiguous. Nodes live in blocks, one block per
//!   entity they are classified on (a node on a feature curve belongs to the
//!   curve, not to the surfaces it bounds); elements live in blocks of one
//!   [`ElementType`] on one entity of the same dimension.
//! - **Views** ([`DataView`]) hold 1, 3 or 9 values per node or element tag.
//! - **Parametrizations** (Gmsh's `$Parametrizations`) are piecewise-linear
//!   maps of discrete curves and surfaces: a curve is a polyline whose `k`-th
//!   point has parameter `u = k` (Gmsh's `discreteEdge` fixes its parameter
//!   range to `[0, N−1]`, so no other `u` is accepted); a surface is a
//!   triangulation with `(u, v)` per point, read by Gmsh as the inverse map
//!   `(u, v) → xyz` used to remesh the surface.
//!
//! [`MshModel::validate`] checks every cross reference, so a writer never
//! produces a file that Gmsh would reject or misread.

use crate::geom::{BoundingBox, Vec2, Vec3};
use crate::io::write_error::WriteError;
use crate::mesh::{TetMesh, TriMesh};
use std::collections::{HashMap, HashSet};

/// Tag of a model entity: positive, unique within its dimension (Gmsh `int`).
pub type EntityTag = i32;

/// The element types the writers support, with their Gmsh type codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ElementType {
    /// 1-node point (Gmsh type 15).
    Point,
    /// 2-node line (type 1).
    Line,
    /// 3-node triangle (type 2).
    Triangle,
    /// 4-node tetrahedron (type 4).
    Tetrahedron,
    /// 4-node quadrangle (type 3).
    Quadrangle,
    /// 3-node second-order line (type 8): end points, then the mid node.
    Line3,
    /// 9-node second-order quadrangle (type 10): 4 corners, the nodes of
    /// edges 01, 12, 23, 30, then the centre.
    Quadrangle9,
}

impl ElementType {
    /// Gmsh's element type number.
    pub fn gmsh_code(self) -> i32 {
        match self {
            Self::Point => 15,
            Self::Line => 1,
            Self::Triangle => 2,
            Self::Tetrahedron => 4,
            Self::Quadrangle => 3,
            Self::Line3 => 8,
            Self::Quadrangle9 => 10,
        }
    }

    /// Nodes per element.
    pub fn n_nodes(self) -> usize {
        match self {
            Self::Point => 1,
            Self::Line => 2,
            Self::Triangle => 3,
            Self::Tetrahedron => 4,
            Self::Quadrangle => 4,
            Self::Line3 => 3,
            Self::Quadrangle9 => 9,
        }
    }

    /// Topological dimension (that of the entity it must be placed on).
    pub fn dim(self) -> u8 {
        match self {
            Self::Point => 0,
            Self::Line | Self::Line3 => 1,
            Self::Triangle | Self::Quadrangle | Self::Quadrangle9 => 2,
            Self::Tetrahedron => 3,
        }
    }

    /// Lower-case name for messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Point => "point",
            Self::Line => "line",
            Self::Triangle => "triangle",
            Self::Tetrahedron => "tetrahedron",
            Self::Quadrangle => "quadrangle",
            Self::Line3 => "3-node line",
            Self::Quadrangle9 => "9-node quadrangle",
        }
    }
}

/// A model vertex (dimension 0).
#[derive(Debug, Clone, PartialEq)]
pub struct PointEntity {
    /// Entity tag.
    pub tag: EntityTag,
    /// Its position.
    pub position: Vec3,
    /// Physical groups it belongs to (positive tags), usually empty.
    pub physical_tags: Vec<i32>,
}

/// A model curve (dimension 1).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CurveEntity {
    /// Entity tag.
    pub tag: EntityTag,
    /// Bounding points: `+start`, `−end`; `[p, -p]` for a closed curve through
    /// corner `p`; empty for a closed curve without a corner.
    pub bounding_points: Vec<EntityTag>,
    /// Physical groups it belongs to.
    pub physical_tags: Vec<i32>,
}

/// A model surface (dimension 2).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SurfaceEntity {
    /// Entity tag.
    pub tag: EntityTag,
    /// Bounding curves, signed by orientation (Gmsh itself writes `+` for
    /// discrete surfaces).
    pub bounding_curves: Vec<EntityTag>,
    /// Physical groups it belongs to.
    pub physical_tags: Vec<i32>,
}

/// A model volume (dimension 3).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VolumeEntity {
    /// Entity tag.
    pub tag: EntityTag,
    /// Bounding surfaces, signed by orientation.
    pub bounding_surfaces: Vec<EntityTag>,
    /// Physical groups it belongs to.
    pub physical_tags: Vec<i32>,
}

/// A name for a physical group (`$PhysicalNames`).
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalName {
    /// Dimension of the group.
    pub dim: u8,
    /// Physical tag (positive).
    pub tag: i32,
    /// Name, without quotes or line breaks.
    pub name: String,
}

/// Nodes classified on one entity.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NodeBlock {
    /// Dimension of the entity (0..=3).
    pub entity_dim: u8,
    /// Tag of the entity.
    pub entity_tag: EntityTag,
    /// Node tags (positive, unique across the model; any order, written sorted).
    pub tags: Vec<u64>,
    /// Node positions, parallel to `tags`.
    pub positions: Vec<Vec3>,
    /// Parametric coordinates on the entity, `entity_dim` values per node
    /// (`u` on a curve, `u v` on a surface); `None` writes a non-parametric
    /// block. Gmsh itself writes zeros here for discrete entities and keeps
    /// the real maps in `$Parametrizations`; Gmsh accepts real values too,
    /// but meshio 5.3 cannot read parametric blocks at all ("parametric
    /// nodes not implemented"), so leave this `None` for discrete atlases.
    pub parametric: Option<Vec<f64>>,
}

/// Elements of one type on one entity.
#[derive(Debug, Clone, PartialEq)]
pub struct ElementBlock {
    /// Dimension of the entity; must equal `element_type.dim()`.
    pub entity_dim: u8,
    /// Tag of the entity.
    pub entity_tag: EntityTag,
    /// Element type.
    pub element_type: ElementType,
    /// Element tags (positive, unique across the model; written sorted).
    pub tags: Vec<u64>,
    /// Node tags, `element_type.n_nodes()` per element, parallel to `tags`.
    pub nodes: Vec<u64>,
}

/// A post-processing view: values per node (`$NodeData`) or per element
/// (`$ElementData`).
#[derive(Debug, Clone, PartialEq)]
pub struct DataView {
    /// View name (no `"` or line break).
    pub name: String,
    /// Time value of this step.
    pub time: f64,
    /// Time step index.
    pub step: i32,
    /// Components per value: 1 (scalar), 3 (vector) or 9 (tensor, row-major).
    pub n_components: usize,
    /// Node or element tags the values belong to.
    pub tags: Vec<u64>,
    /// Values, `n_components` per tag, parallel to `tags`.
    pub values: Vec<f64>,
}

impl DataView {
    /// A view at time 0, step 0 over the contiguous tags
    /// `first_tag, first_tag + 1, …` (one per `n_components` values), the
    /// numbering of [`MshModel::from_surface`] and [`MshModel::from_volume`]
    /// with `first_tag = 1`.
    pub fn contiguous(name: impl Into<String>, n_components: usize, values: Vec<f64>, first_tag: u64) -> Self {
        let n = values.len().checked_div(n_components).unwrap_or(0) as u64;
        Self { name: name.into(), time: 0.0, step: 0, n_components, tags: (first_tag..first_tag + n).collect(), values }
    }
}

/// `x` rounded to the nearest `f32`, still as an `f64` (values outside the
/// `f32` range are kept as they are).
///
/// For estimates written into MSH's `f64` fields (crossfield directions and
/// norms, curvatures) whose error is orders of magnitude above `f32`'s
/// 6·10⁻⁸: their low 29 mantissa bits become zero, which the artifact's gzip
/// representation compresses, while every reader still gets a plain `f64`.
pub fn f32_precision(x: f64) -> f64 {
    let r = x as f32;
    if r.is_finite() || !x.is_finite() { f64::from(r) } else { x }
}

/// The polyline map of a discrete curve: point `k` has parameter `u = k`.
#[derive(Debug, Clone, PartialEq)]
pub struct CurveParametrization {
    /// Tag of the curve.
    pub curve: EntityTag,
    /// Points from the start to the end of the curve (a closed curve repeats
    /// its first point at the end); at least two.
    pub points: Vec<Vec3>,
}

/// The piecewise-linear map of a discrete surface: a triangulation with an
/// `xyz` and a `(u, v)` per point.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceParametrization {
    /// Tag of the surface.
    pub surface: EntityTag,
    /// Point positions.
    pub positions: Vec<Vec3>,
    /// Parametric coordinates, parallel to `positions`. Gmsh expects the
    /// outer boundary on a convex curve (the atlas uses the unit circle) and
    /// no flipped `(u, v)` triangle.
    pub uv: Vec<Vec2>,
    /// Principal curvature directions scaled by the curvatures,
    /// `[kmax, kmin]` per point, or empty (written as zeros, which Gmsh accepts).
    pub curvature: Vec<[Vec3; 2]>,
    /// Triangles as 0-based indices into `positions`. Gmsh matches them to the
    /// surface's mesh triangles by position when they come in the same order
    /// as the (sorted) element block, so keep that order when you can.
    pub triangles: Vec<[u32; 3]>,
}

/// A complete model, as written to MSH 4.1 (and, without entities and
/// parametrizations, MSH 2.2).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MshModel {
    /// Model points.
    pub points: Vec<PointEntity>,
    /// Model curves.
    pub curves: Vec<CurveEntity>,
    /// Model surfaces.
    pub surfaces: Vec<SurfaceEntity>,
    /// Model volumes.
    pub volumes: Vec<VolumeEntity>,
    /// Names of physical groups.
    pub physical_names: Vec<PhysicalName>,
    /// Node blocks.
    pub node_blocks: Vec<NodeBlock>,
    /// Element blocks.
    pub element_blocks: Vec<ElementBlock>,
    /// Views with values per node.
    pub node_data: Vec<DataView>,
    /// Views with values per element.
    pub element_data: Vec<DataView>,
    /// Curve parametrizations.
    pub curve_parametrizations: Vec<CurveParametrization>,
    /// Surface parametrizations.
    pub surface_parametrizations: Vec<SurfaceParametrization>,
}

impl MshModel {
    /// One discrete surface (tag 1) holding every vertex (tag `i + 1`) and
    /// every triangle (tag `f + 1`) of `mesh`.
    pub fn from_surface(mesh: &TriMesh) -> Self {
        let n = mesh.n_vertices() as u64;
        Self {
            surfaces: vec![SurfaceEntity { tag: 1, ..Default::default() }],
            node_blocks: vec![NodeBlock {
                entity_dim: 2,
                entity_tag: 1,
                tags: (1..=n).collect(),
                positions: mesh.positions.clone(),
                parametric: None,
            }],
            element_blocks: vec![ElementBlock {
                entity_dim: 2,
                entity_tag: 1,
                element_type: ElementType::Triangle,
                tags: (1..=mesh.n_faces() as u64).collect(),
                nodes: mesh.triangles.iter().flatten().map(|v| u64::from(v.0) + 1).collect(),
            }],
            ..Default::default()
        }
    }

    /// One discrete volume (tag 1) holding every vertex (tag `i + 1`) and
    /// every tetrahedron (tag `t + 1`) of `mesh`.
    pub fn from_volume(mesh: &TetMesh) -> Self {
        let n = mesh.n_vertices() as u64;
        Self {
            volumes: vec![VolumeEntity { tag: 1, ..Default::default() }],
            node_blocks: vec![NodeBlock {
                entity_dim: 3,
                entity_tag: 1,
                tags: (1..=n).collect(),
                positions: mesh.positions.clone(),
                parametric: None,
            }],
            element_blocks: vec![ElementBlock {
                entity_dim: 3,
                entity_tag: 1,
                element_type: ElementType::Tetrahedron,
                tags: (1..=mesh.n_tets() as u64).collect(),
                nodes: mesh.tets.iter().flatten().map(|v| u64::from(v.0) + 1).collect(),
            }],
            ..Default::default()
        }
    }

    /// Total number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.node_blocks.iter().map(|b| b.tags.len()).sum()
    }

    /// Total number of elements.
    pub fn n_elements(&self) -> usize {
        self.element_blocks.iter().map(|b| b.tags.len()).sum()
    }

    /// Check every invariant the file formats need: positive and unique
    /// tags, consistent array lengths, finite coordinates, every referenced
    /// entity, node and element defined, element types on entities of their
    /// dimension, 1/3/9-component views, quotable names.
    ///
    /// # Errors
    /// The first violation found, naming the item.
    pub fn validate(&self) -> Result<(), WriteError> {
        self.index().map(|_| ())
    }

    /// Every entity as `(dim, tag, physical tags, bounding tags)`, points
    /// first, then curves, surfaces, volumes.
    pub(crate) fn entity_rows(&self) -> impl Iterator<Item = EntityRow<'_>> {
        fn row<'a>(dim: u8, tag: EntityTag, physical_tags: &'a [i32], boundary: &'a [EntityTag]) -> EntityRow<'a> {
            EntityRow { dim, tag, physical_tags, boundary }
        }
        (self.points.iter().map(|e| row(0, e.tag, &e.physical_tags, &[])))
            .chain(self.curves.iter().map(|e| row(1, e.tag, &e.physical_tags, &e.bounding_points)))
            .chain(self.surfaces.iter().map(|e| row(2, e.tag, &e.physical_tags, &e.bounding_curves)))
            .chain(self.volumes.iter().map(|e| row(3, e.tag, &e.physical_tags, &e.bounding_surfaces)))
    }

    /// Validate and build the lookups the writers need.
    pub(crate) fn index(&self) -> Result<ModelIndex, WriteError> {
        let entities = self.check_entities()?;
        let nodes = self.check_nodes(&entities)?;
        let elements = self.check_elements(&entities, &nodes)?;
        self.check_views(&nodes, &elements)?;
        self.check_parametrizations(&entities)?;
        let bboxes = self.entity_bounding_boxes(&nodes);
        Ok(ModelIndex { nodes, bboxes })
    }

    /// Entity tags per dimension; checks tags, bounding references, physicals, names.
    fn check_entities(&self) -> Result<[HashSet<EntityTag>; 4], WriteError> {
        let mut sets: [HashSet<EntityTag>; 4] = Default::default();
        const WHAT: [&str; 4] = ["point entity", "curve entity", "surface entity", "volume entity"];
        for row in self.entity_rows() {
            let what = WHAT[usize::from(row.dim)];
            positive(what, i64::from(row.tag))?;
            if !sets[usize::from(row.dim)].insert(row.tag) {
                return Err(WriteError::DuplicateTag { what, tag: row.tag as u64 });
            }
            for &p in row.physical_tags {
                positive("physical", i64::from(p))?;
            }
        }
        for p in &self.points {
            check_finite(&p.position, || format!("point entity {}", p.tag))?;
        }
        for row in self.entity_rows() {
            for &b in row.boundary {
                let lower = usize::from(row.dim.saturating_sub(1));
                if b == 0 || !sets[lower].contains(&b.abs()) {
                    return Err(WriteError::MissingEntity {
                        referrer: format!(
                            "{} {} boundary",
                            ["point", "curve", "surface", "volume"][usize::from(row.dim)],
                            row.tag
                        ),
                        dim: row.dim - 1,
                        tag: b.abs(),
                    });
                }
            }
        }
        for n in &self.physical_names {
            positive("physical", i64::from(n.tag))?;
            if n.dim > 3 {
                return Err(WriteError::Invalid(format!("physical name {:?} has dimension {}", n.name, n.dim)));
            }
            check_name(&n.name)?;
        }
        Ok(sets)
    }

    /// Node lookup; checks tags, lengths, entities, finiteness.
    fn check_nodes(&self, entities: &[HashSet<EntityTag>; 4]) -> Result<TagLookup, WriteError> {
        let mut all = Vec::with_capacity(self.n_nodes());
        for (b, block) in self.node_blocks.iter().enumerate() {
            check_entity(entities, block.entity_dim, block.entity_tag, "node block")?;
            let label = || format!("node block ({}, {})", block.entity_dim, block.entity_tag);
            same_len(label() + " positions", block.tags.len(), block.positions.len())?;
            if let Some(p) = &block.parametric {
                same_len(
                    label() + " parametric coordinates",
                    block.tags.len() * usize::from(block.entity_dim),
                    p.len(),
                )?;
            }
            for (i, (&tag, p)) in block.tags.iter().zip(&block.positions).enumerate() {
                positive_u64("node", tag)?;
                check_finite(p, || format!("node {tag}"))?;
                all.push((tag, pack(b, i)));
            }
        }
        TagLookup::new(all, "node")
    }

    /// Element lookup; checks tags, lengths, entities, dimensions, node references.
    fn check_elements(&self, entities: &[HashSet<EntityTag>; 4], nodes: &TagLookup) -> Result<TagLookup, WriteError> {
        let mut all = Vec::with_capacity(self.n_elements());
        for (b, block) in self.element_blocks.iter().enumerate() {
            check_entity(entities, block.entity_dim, block.entity_tag, "element block")?;
            let ty = block.element_type;
            if ty.dim() != block.entity_dim {
                return Err(WriteError::DimensionMismatch {
                    element_type: ty.name(),
                    element_dim: ty.dim(),
                    entity_dim: block.entity_dim,
                    entity_tag: block.entity_tag,
                });
            }
            let k = ty.n_nodes();
            same_len(
                format!("element block ({}, {}) node tags", block.entity_dim, block.entity_tag),
                block.tags.len() * k,
                block.nodes.len(),
            )?;
            for (i, (&tag, el)) in block.tags.iter().zip(block.nodes.chunks_exact(k)).enumerate() {
                positive_u64("element", tag)?;
                for &n in el {
                    if nodes.get(n).is_none() {
                        return Err(WriteError::MissingNode { element: tag, node: n });
                    }
                }
                all.push((tag, pack(b, i)));
            }
        }
        TagLookup::new(all, "element")
    }

    /// Views: names, components, lengths, tags defined and not repeated.
    fn check_views(&self, nodes: &TagLookup, elements: &TagLookup) -> Result<(), WriteError> {
        for (views, lookup, what) in [(&self.node_data, nodes, "node"), (&self.element_data, elements, "element")] {
            for view in views {
                check_name(&view.name)?;
                if !matches!(view.n_components, 1 | 3 | 9) {
                    return Err(WriteError::BadComponents {
                        view: view.name.clone(),
                        n_components: view.n_components,
                        allowed: "MSH views take 1, 3 or 9",
                    });
                }
                same_len(
                    format!("view {:?} values", view.name),
                    view.tags.len() * view.n_components,
                    view.values.len(),
                )?;
                let mut seen = vec![false; lookup.len()];
                for &tag in &view.tags {
                    let Some(slot) = lookup.rank(tag) else {
                        return Err(WriteError::UnknownDataTag { view: view.name.clone(), what, tag });
                    };
                    if std::mem::replace(&mut seen[slot], true) {
                        return Err(WriteError::DuplicateTag { what: "data view", tag });
                    }
                }
            }
        }
        Ok(())
    }

    /// Parametrizations: entity defined, one per entity, sizes and indices valid.
    fn check_parametrizations(&self, entities: &[HashSet<EntityTag>; 4]) -> Result<(), WriteError> {
        let mut seen = HashSet::new();
        for p in &self.curve_parametrizations {
            check_entity(entities, 1, p.curve, "curve parametrization")?;
            if !seen.insert((1, p.curve)) {
                return Err(WriteError::DuplicateTag { what: "curve parametrization", tag: p.curve as u64 });
            }
            if p.points.len() < 2 {
                return Err(WriteError::Invalid(format!(
                    "parametrization of curve {} has {} point(s), needs 2",
                    p.curve,
                    p.points.len()
                )));
            }
            for (i, x) in p.points.iter().enumerate() {
                check_finite(x, || format!("parametrization of curve {}, point {i}", p.curve))?;
            }
        }
        for p in &self.surface_parametrizations {
            check_entity(entities, 2, p.surface, "surface parametrization")?;
            if !seen.insert((2, p.surface)) {
                return Err(WriteError::DuplicateTag { what: "surface parametrization", tag: p.surface as u64 });
            }
            let label = |s: &str| format!("parametrization of surface {} {s}", p.surface);
            same_len(label("(u, v)"), p.positions.len(), p.uv.len())?;
            if !p.curvature.is_empty() {
                same_len(label("curvatures"), p.positions.len(), p.curvature.len())?;
            }
            if p.triangles.is_empty() {
                return Err(WriteError::Invalid(label("has no triangle")));
            }
            if p.positions.len() > i32::MAX as usize {
                return Err(WriteError::TooLarge {
                    what: "parametrization points",
                    count: p.positions.len(),
                    max: i32::MAX as u64,
                });
            }
            for (i, x) in p.positions.iter().enumerate() {
                check_finite(x, || label(&format!("point {i}")))?;
                let uv = p.uv[i];
                if !(uv.x.is_finite() && uv.y.is_finite()) {
                    return Err(WriteError::NonFiniteCoordinate {
                        what: label(&format!("(u, v) {i}")),
                        x: uv.x,
                        y: uv.y,
                        z: 0.0,
                    });
                }
            }
            // Without the polyline of each bounding curve Gmsh cannot mesh the
            // boundary after `mesh.clear()`, and then silently skips the surface.
            let boundary =
                self.surfaces.iter().find(|e| e.tag == p.surface).map_or(&[][..], |e| &e.bounding_curves[..]);
            if let Some(c) = boundary.iter().find(|c| !self.curve_parametrizations.iter().any(|q| q.curve == c.abs())) {
                return Err(WriteError::Invalid(format!(
                    "surface {} has a parametrization but its boundary curve {} has none (Gmsh could not remesh it)",
                    p.surface,
                    c.abs()
                )));
            }
            for (t, tri) in p.triangles.iter().enumerate() {
                for &i in tri {
                    if i as usize >= p.positions.len() {
                        return Err(WriteError::IndexOutOfRange {
                            what: label(&format!("triangle {t}")),
                            index: u64::from(i),
                            n_points: p.positions.len(),
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// Bounding box of every entity: its own nodes, the nodes of its
    /// elements, its point position, its parametrization's points, and the
    /// boxes of its bounding entities.
    fn entity_bounding_boxes(&self, nodes: &TagLookup) -> HashMap<(u8, EntityTag), BoundingBox> {
        let mut boxes: HashMap<(u8, EntityTag), BoundingBox> = HashMap::new();
        // Boxes are accumulated per block, then merged once per block.
        let merge = |boxes: &mut HashMap<(u8, EntityTag), BoundingBox>, key, b: Option<BoundingBox>| {
            if let Some(b) = b {
                boxes
                    .entry(key)
                    .and_modify(|a: &mut BoundingBox| {
                        a.min = a.min.inf(&b.min);
                        a.max = a.max.sup(&b.max);
                    })
                    .or_insert(b);
            }
        };
        for p in &self.points {
            merge(&mut boxes, (0, p.tag), BoundingBox::of_points([&p.position]));
        }
        for b in &self.node_blocks {
            merge(&mut boxes, (b.entity_dim, b.entity_tag), BoundingBox::of_points(&b.positions));
        }
        for b in &self.element_blocks {
            let points = b.nodes.iter().filter_map(|&n| nodes.get(n)).map(|slot| {
                let (blk, i) = unpack(slot);
                &self.node_blocks[blk].positions[i]
            });
            merge(&mut boxes, (b.entity_dim, b.entity_tag), BoundingBox::of_points(points));
        }
        for p in &self.curve_parametrizations {
            merge(&mut boxes, (1, p.curve), BoundingBox::of_points(&p.points));
        }
        for p in &self.surface_parametrizations {
            merge(&mut boxes, (2, p.surface), BoundingBox::of_points(&p.positions));
        }
        // Rows come in increasing dimension, so children are complete first.
        for row in self.entity_rows() {
            for &c in row.boundary {
                let child = boxes.get(&(row.dim - 1, c.abs())).copied();
                merge(&mut boxes, (row.dim, row.tag), child);
            }
        }
        boxes
    }
}

/// One entity seen uniformly (see [`MshModel::entity_rows`]).
pub(crate) struct EntityRow<'a> {
    /// Dimension.
    pub(crate) dim: u8,
    /// Tag.
    pub(crate) tag: EntityTag,
    /// Physical tags.
    pub(crate) physical_tags: &'a [i32],
    /// Signed bounding entity tags (empty for points).
    pub(crate) boundary: &'a [EntityTag],
}

/// What validation learned, reused while writing.
pub(crate) struct ModelIndex {
    /// Node tag → (block, index) lookup.
    pub(crate) nodes: TagLookup,
    /// Bounding box per `(dim, tag)` entity (absent when it has no geometry).
    pub(crate) bboxes: HashMap<(u8, EntityTag), BoundingBox>,
}

/// Sorted tags with a packed `(block, index)` payload: dense vector when the
/// tags are dense, binary search otherwise.
pub(crate) struct TagLookup {
    /// Sorted `(tag, payload)`.
    sorted: Vec<(u64, u64)>,
    /// `tag → rank + 1` when the tag range is small enough, else empty.
    dense: Vec<u32>,
}

impl TagLookup {
    /// Sort and reject repeated tags.
    fn new(mut all: Vec<(u64, u64)>, what: &'static str) -> Result<Self, WriteError> {
        all.sort_unstable_by_key(|&(t, _)| t);
        if let Some(w) = all.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(WriteError::DuplicateTag { what, tag: w[0].0 });
        }
        let max = all.last().map_or(0, |&(t, _)| t);
        let dense = if all.len() < u32::MAX as usize && max <= 4 * all.len() as u64 + 1024 {
            let mut d = vec![0u32; max as usize + 1];
            for (r, &(t, _)) in all.iter().enumerate() {
                d[t as usize] = r as u32 + 1;
            }
            d
        } else {
            Vec::new()
        };
        Ok(Self { sorted: all, dense })
    }

    /// `(tag, packed (block, index))` in increasing tag order.
    pub(crate) fn sorted(&self) -> &[(u64, u64)] {
        &self.sorted
    }

    /// Number of tags.
    pub(crate) fn len(&self) -> usize {
        self.sorted.len()
    }

    /// Position of `tag` in sorted order.
    pub(crate) fn rank(&self, tag: u64) -> Option<usize> {
        if !self.dense.is_empty() {
            let r = *self.dense.get(usize::try_from(tag).ok()?)?;
            (r > 0).then(|| r as usize - 1)
        } else {
            self.sorted.binary_search_by_key(&tag, |&(t, _)| t).ok()
        }
    }

    /// Packed `(block, index)` of `tag`.
    pub(crate) fn get(&self, tag: u64) -> Option<u64> {
        self.rank(tag).map(|r| self.sorted[r].1)
    }

    /// Smallest and largest tag (0, 0 when empty).
    pub(crate) fn range(&self) -> (u64, u64) {
        match (self.sorted.first(), self.sorted.last()) {
            (Some(a), Some(b)) => (a.0, b.0),
            _ => (0, 0),
        }
    }
}

/// Pack a `(block, index)` pair into one word.
fn pack(block: usize, index: usize) -> u64 {
    ((block as u64) << 32) | index as u64
}

/// Inverse of [`pack`].
pub(crate) fn unpack(slot: u64) -> (usize, usize) {
    ((slot >> 32) as usize, (slot & 0xffff_ffff) as usize)
}

fn positive(what: &'static str, tag: i64) -> Result<(), WriteError> {
    if tag > 0 { Ok(()) } else { Err(WriteError::NonPositiveTag { what, tag }) }
}

fn positive_u64(what: &'static str, tag: u64) -> Result<(), WriteError> {
    if tag > 0 && tag <= i64::MAX as u64 { Ok(()) } else { Err(WriteError::NonPositiveTag { what, tag: tag as i64 }) }
}

fn same_len(what: String, expected: usize, got: usize) -> Result<(), WriteError> {
    if expected == got { Ok(()) } else { Err(WriteError::LengthMismatch { what, expected, got }) }
}

fn check_entity(entities: &[HashSet<EntityTag>; 4], dim: u8, tag: EntityTag, referrer: &str) -> Result<(), WriteError> {
    if dim <= 3 && entities[usize::from(dim)].contains(&tag) {
        Ok(())
    } else {
        Err(WriteError::MissingEntity { referrer: referrer.to_string(), dim, tag })
    }
}

fn check_finite(p: &Vec3, what: impl FnOnce() -> String) -> Result<(), WriteError> {
    if p.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(WriteError::NonFiniteCoordinate { what: what(), x: p.x, y: p.y, z: p.z })
    }
}

/// Names are written between double quotes on one line.
pub(crate) fn check_name(name: &str) -> Result<(), WriteError> {
    if name.contains(['"', '\n', '\r']) { Err(WriteError::BadName { name: name.to_string() }) } else { Ok(()) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures;

    #[test]
    fn f32_precision_rounds_in_range_and_keeps_the_rest() {
        let x = 0.1_f64;
        assert_eq!(f32_precision(x), f64::from(0.1_f32));
        assert!((f32_precision(x) - x).abs() <= x * f64::from(f32::EPSILON));
        assert_eq!(f32_precision(x).to_bits() & ((1 << 29) - 1), 0);
        assert_eq!(f32_precision(1e300), 1e300);
        assert_eq!(f32_precision(-1e300), -1e300);
        assert_eq!(f32_precision(f64::INFINITY), f64::INFINITY);
        assert!(f32_precision(f64::NAN).is_nan());
        assert_eq!(f32_precision(-0.0).to_bits(), (-0.0_f64).to_bits());
    }

    #[test]
    fn convenience_models_are_valid() {
        let m = MshModel::from_surface(&fixtures::icosphere(1));
        m.validate().unwrap();
        assert_eq!((m.n_nodes(), m.n_elements()), (42, 80));
        let idx = m.index().unwrap();
        let b = idx.bboxes[&(2, 1)];
        assert!((b.max - Vec3::repeat(1.0)).norm() < 1e-12 && (b.min + Vec3::repeat(1.0)).norm() < 1e-12);
    }

    #[test]
    fn validation_names_what_is_broken() {
        let base = MshModel::from_surface(&fixtures::square(2));
        let mut m = base.clone();
        m.element_blocks[0].nodes[4] = 99;
        assert!(matches!(m.validate(), Err(WriteError::MissingNode { element: 2, node: 99 })));
        let mut m = base.clone();
        m.node_blocks[0].tags[3] = 1;
        assert!(matches!(m.validate(), Err(WriteError::DuplicateTag { what: "node", tag: 1 })));
        let mut m = base.clone();
        m.element_blocks[0].entity_tag = 7;
        assert!(matches!(m.validate(), Err(WriteError::MissingEntity { dim: 2, tag: 7, .. })));
        let mut m = base.clone();
        m.element_blocks[0].entity_dim = 1;
        m.curves.push(CurveEntity { tag: 1, ..Default::default() });
        assert!(matches!(m.validate(), Err(WriteError::DimensionMismatch { element_dim: 2, entity_dim: 1, .. })));
        let mut m = base.clone();
        m.surfaces[0].bounding_curves = vec![-4];
        assert!(matches!(m.validate(), Err(WriteError::MissingEntity { dim: 1, tag: 4, .. })));
        let mut m = base.clone();
        m.node_data.push(DataView::contiguous("f", 1, vec![0.0; 9], 1));
        m.validate().unwrap();
        m.node_data[0].values.pop();
        assert!(matches!(m.validate(), Err(WriteError::LengthMismatch { expected: 9, got: 8, .. })));
        let mut m = base.clone();
        m.element_data.push(DataView::contiguous("g", 1, vec![0.0; 9], 1));
        assert!(matches!(m.validate(), Err(WriteError::UnknownDataTag { tag: 9, what: "element", .. })));
        let mut m = base.clone();
        m.element_data.push(DataView::contiguous("g", 2, vec![0.0; 8], 1));
        assert!(matches!(m.validate(), Err(WriteError::BadComponents { n_components: 2, .. })));
        let mut m = base.clone();
        m.element_data.push(DataView::contiguous("a\"b", 1, vec![0.0; 8], 1));
        assert!(matches!(m.validate(), Err(WriteError::BadName { .. })));
        let mut m = base.clone();
        m.node_blocks[0].positions[2].x = f64::NAN;
        assert!(matches!(m.validate(), Err(WriteError::NonFiniteCoordinate { .. })));
        let mut m = base.clone();
        m.surface_parametrizations.push(SurfaceParametrization {
            surface: 1,
            positions: vec![Vec3::zeros(); 3],
            uv: vec![Vec2::zeros(); 3],
            curvature: vec![],
            triangles: vec![[0, 1, 3]],
        });
        assert!(matches!(m.validate(), Err(WriteError::IndexOutOfRange { index: 3, n_points: 3, .. })));
        let mut m = base.clone();
        m.curves.push(CurveEntity { tag: 4, ..Default::default() });
        m.surfaces[0].bounding_curves = vec![4];
        m.surface_parametrizations.push(SurfaceParametrization {
            surface: 1,
            positions: vec![Vec3::zeros(), Vec3::x(), Vec3::y()],
            uv: vec![Vec2::zeros(), Vec2::x(), Vec2::y()],
            curvature: vec![],
            triangles: vec![[0, 1, 2]],
        });
        assert!(matches!(m.validate(), Err(WriteError::Invalid(s)) if s.contains("boundary curve 4 has none")));
        m.curve_parametrizations.push(CurveParametrization { curve: 4, points: vec![Vec3::zeros(), Vec3::x()] });
        m.validate().unwrap();
        let mut m = base;
        m.element_blocks[0].tags[0] = 0;
        assert!(matches!(m.validate(), Err(WriteError::NonPositiveTag { what: "element", tag: 0 })));
    }

    #[test]
    fn sparse_tags_are_found() {
        let l = TagLookup::new(vec![(1 << 40, 5), (3, 7), (1 << 50, 9)], "node").unwrap();
        assert!(l.dense.is_empty());
        assert_eq!(l.get(1 << 40), Some(5));
        assert_eq!(l.get(3), Some(7));
        assert_eq!(l.get(4), None);
        assert_eq!(l.range(), (3, 1 << 50));
        let d = TagLookup::new(vec![(2, 1), (1, 0)], "node").unwrap();
        assert_eq!((d.rank(1), d.rank(2), d.rank(3), d.rank(0)), (Some(0), Some(1), None, None));
    }
}
