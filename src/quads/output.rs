//! `quads.msh` and `quads.vtu`, the artifacts of the quads stage.
//!
//! `quads.msh` (MSH 4.1, or 2.2 when `output.msh_version` asks; binary or
//! ASCII as [`OutputOptions`] decides) carries the feature model as
//! `$Entities`: point `i + 1` is model corner `i`, curve `c + 1` is feature
//! curve `c` bounded by its end corners (`+start, −end`; `[p, −p]` for a
//! closed curve), surface `f + 1` is model face `f` bounded by the curves
//! on its border. Each node is classified on the entity of its vertex
//! ([`ModelEntity`]), with node tag `vertex index + 1`; quadrangles (type
//! 3, or 10 for order 2) lie on their model face with element tag
//! `quad index + 1` (the VTU cell order), then come the curve edges as
//! lines (type 1, or 8) on their curve, then one point element (type 15)
//! per corner, as Gmsh's own meshes have.
//!
//! `quads.vtu`: VTK_QUAD (9) or VTK_BIQUADRATIC_QUAD (28) cells, one per
//! quad in quad order, with cell data `scaled_jacobian`,
//! `max_angle_deviation` (degrees) and `model_face`, and point data
//! `valence` (0 for order-2 nodes) and `irregular` (1 for an irregular
//! vertex, [`super::quality`]).

use std::collections::{BTreeMap, HashMap};
use std::io::Write;

use super::model::QuadModel;
use super::quality::QuadQuality;
use super::surface_mesh::{ModelEntity, QuadMesh};
use crate::io::WriteError;
use crate::io::msh_output::{OutputOptions, write_msh};
use crate::io::msh41::model::{
    CurveEntity, ElementBlock, ElementType, EntityTag, MshModel, NodeBlock, PointEntity, SurfaceEntity,
};
use crate::io::vtu::{CellBlock, DataArray, VtuMesh, VtuOptions, write_vtu};
use crate::mesh::VertexId;

/// Entity `(dim, tag)` of a vertex classified on `e`.
fn entity_key(e: ModelEntity) -> (u8, EntityTag) {
    match e {
        ModelEntity::Corner(i) => (0, i as EntityTag + 1),
        ModelEntity::Curve(c) => (1, c as EntityTag + 1),
        ModelEntity::Face(f) => (2, f as EntityTag + 1),
    }
}

/// Point, curve and surface entities of a model.
type Entities = (Vec<PointEntity>, Vec<CurveEntity>, Vec<SurfaceEntity>);

/// The point, curve and surface entities of `model`, with the positions of
/// the mesh vertices at its corners.
///
/// # Errors
/// [`WriteError::Invalid`] when a corner has no mesh vertex.
fn entities(mesh: &QuadMesh, model: &QuadModel) -> Result<Entities, WriteError> {
    let mut corner_position = vec![None; model.corners.len()];
    for (v, e) in mesh.vertices.entity.iter().enumerate() {
        if let ModelEntity::Corner(i) = *e
            && let Some(slot) = corner_position.get_mut(i as usize)
        {
            slot.get_or_insert(mesh.vertices.positions[v]);
        }
    }
    let points = corner_position
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let position = p.ok_or_else(|| WriteError::Invalid(format!("model corner {i} has no mesh vertex")))?;
            Ok(PointEntity { tag: i as EntityTag + 1, position, physical_tags: Vec::new() })
        })
        .collect::<Result<Vec<_>, WriteError>>()?;
    let point_tag = |v: VertexId| model.corner_of(v).map(|i| i as EntityTag + 1);
    let curves = model
        .features
        .curves
        .iter()
        .enumerate()
        .map(|(c, curve)| {
            let ends = curve
                .vertices
                .first()
                .copied()
                .and_then(point_tag)
                .zip(curve.vertices.last().copied().and_then(point_tag));
            CurveEntity {
                tag: c as EntityTag + 1,
                bounding_points: ends.map_or_else(Vec::new, |(a, b)| vec![a, -b]),
                physical_tags: Vec::new(),
            }
        })
        .collect();
    let mut bounding: Vec<Vec<EntityTag>> = vec![Vec::new(); model.n_faces];
    for (c, faces) in model.faces_per_curve.iter().enumerate() {
        for &f in faces {
            bounding[f as usize].push(c as EntityTag + 1);
        }
    }
    let surfaces = bounding
        .into_iter()
        .enumerate()
        .map(|(f, bounding_curves)| SurfaceEntity {
            tag: f as EntityTag + 1,
            bounding_curves,
            physical_tags: Vec::new(),
        })
        .collect();
    Ok((points, curves, surfaces))
}

/// One node block per entity, vertices in index order, node tag = index + 1.
fn node_blocks(mesh: &QuadMesh) -> Vec<NodeBlock> {
    let mut by_entity: BTreeMap<(u8, EntityTag), Vec<usize>> = BTreeMap::new();
    for (v, &e) in mesh.vertices.entity.iter().enumerate() {
        by_entity.entry(entity_key(e)).or_default().push(v);
    }
    by_entity
        .into_iter()
        .map(|((entity_dim, entity_tag), vs)| NodeBlock {
            entity_dim,
            entity_tag,
            tags: vs.iter().map(|&v| v as u64 + 1).collect(),
            positions: vs.iter().map(|&v| mesh.vertices.positions[v]).collect(),
            parametric: None,
        })
        .collect()
}

/// Node tags of quad `k`: its corners, then for order 2 its edge and centre nodes.
fn quad_nodes(mesh: &QuadMesh, k: usize) -> impl Iterator<Item = u64> + '_ {
    let high = mesh.high_order_nodes.as_ref().map(|h| &h[k][..]).unwrap_or(&[]);
    mesh.quads[k].iter().chain(high).map(|&v| u64::from(v) + 1)
}

/// The mid node of each quad edge `[min, max]` of an order-2 mesh.
fn mid_nodes(mesh: &QuadMesh, high: &[[u32; 5]]) -> HashMap<[u32; 2], u32> {
    let mut mid = HashMap::with_capacity(2 * mesh.quads.len());
    for (q, h) in mesh.quads.iter().zip(high) {
        for i in 0..4 {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            mid.insert([a.min(b), a.max(b)], h[i]);
        }
    }
    mid
}

/// Quadrangles per model face, lines per curve, a point per corner.
///
/// # Errors
/// [`WriteError::Invalid`] when an order-2 curve edge is no quad edge.
fn element_blocks(mesh: &QuadMesh) -> Result<Vec<ElementBlock>, WriteError> {
    let order2 = mesh.high_order_nodes.as_deref();
    let (quad_type, line_type) = if order2.is_some() {
        (ElementType::Quadrangle9, ElementType::Line3)
    } else {
        (ElementType::Quadrangle, ElementType::Line)
    };
    let mut blocks = Vec::new();
    let mut quads_by_face: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (k, &f) in mesh.model_face_per_quad.iter().enumerate() {
        quads_by_face.entry(f).or_default().push(k);
    }
    for (f, ks) in quads_by_face {
        blocks.push(ElementBlock {
            entity_dim: 2,
            entity_tag: f as EntityTag + 1,
            element_type: quad_type,
            tags: ks.iter().map(|&k| k as u64 + 1).collect(),
            nodes: ks.iter().flat_map(|&k| quad_nodes(mesh, k)).collect(),
        });
    }
    let mid = order2.map(|h| mid_nodes(mesh, h));
    let mut lines_by_curve: BTreeMap<u32, Vec<[u32; 2]>> = BTreeMap::new();
    for &(c, e) in &mesh.curve_edges {
        lines_by_curve.entry(c).or_default().push(e);
    }
    let mut next_tag = mesh.quads.len() as u64 + 1;
    for (c, edges) in lines_by_curve {
        let mut nodes = Vec::with_capacity(edges.len() * line_type.n_nodes());
        for [a, b] in &edges {
            nodes.extend([u64::from(*a) + 1, u64::from(*b) + 1]);
            if let Some(mid) = &mid {
                let m = mid.get(&[*a.min(b), *a.max(b)]).ok_or_else(|| {
                    WriteError::Invalid(format!("curve edge ({a}, {b}) of curve {c} is not an edge of any quad"))
                })?;
                nodes.push(u64::from(*m) + 1);
            }
        }
        let tags = (next_tag..next_tag + edges.len() as u64).collect();
        next_tag += edges.len() as u64;
        blocks.push(ElementBlock {
            entity_dim: 1,
            entity_tag: c as EntityTag + 1,
            element_type: line_type,
            tags,
            nodes,
        });
    }
    let mut corner_vertex: BTreeMap<u32, usize> = BTreeMap::new();
    for (v, e) in mesh.vertices.entity.iter().enumerate() {
        if let ModelEntity::Corner(i) = *e {
            corner_vertex.entry(i).or_insert(v);
        }
    }
    for (i, v) in corner_vertex {
        blocks.push(ElementBlock {
            entity_dim: 0,
            entity_tag: i as EntityTag + 1,
            element_type: ElementType::Point,
            tags: vec![next_tag],
            nodes: vec![v as u64 + 1],
        });
        next_tag += 1;
    }
    Ok(blocks)
}

/// The MSH model of `mesh` classified on `model` (see the module documentation).
///
/// # Errors
/// [`WriteError::Invalid`] when a model corner has no vertex or an order-2
/// curve edge is no quad edge; [`MshModel::validate`]'s errors.
pub fn quads_msh_model(mesh: &QuadMesh, model: &QuadModel) -> Result<MshModel, WriteError> {
    let (points, curves, surfaces) = entities(mesh, model)?;
    let msh = MshModel {
        points,
        curves,
        surfaces,
        node_blocks: node_blocks(mesh),
        element_blocks: element_blocks(mesh)?,
        ..Default::default()
    };
    msh.validate()?;
    Ok(msh)
}

/// Writes `quads.msh` as `opts` asks (MSH 4.1 binary or ASCII, or 2.2).
///
/// # Errors
/// [`WriteError`] from [`quads_msh_model`] or the sink.
pub fn write_quads_msh(
    mesh: &QuadMesh,
    model: &QuadModel,
    w: impl Write,
    opts: &OutputOptions,
) -> Result<(), WriteError> {
    write_msh(w, &quads_msh_model(mesh, model)?, opts)
}

/// Writes `quads.vtu`.
///
/// # Errors
/// [`WriteError`] from the sink, or a length mismatch between `mesh` and `quality`.
pub fn write_quads_vtu(mesh: &QuadMesh, quality: &QuadQuality, w: impl Write) -> Result<(), WriteError> {
    let corners: Vec<[VertexId; 4]>;
    let nine: Vec<[VertexId; 9]>;
    let cells = match &mesh.high_order_nodes {
        None => {
            corners = mesh.quads.iter().map(|q| q.map(VertexId)).collect();
            CellBlock::Quads(&corners)
        }
        Some(high) => {
            nine = mesh
                .quads
                .iter()
                .zip(high)
                .map(|(q, h)| std::array::from_fn(|i| VertexId(if i < 4 { q[i] } else { h[i - 4] })))
                .collect();
            CellBlock::BiquadraticQuads(&nine)
        }
    };
    let valence: Vec<i32> = quality.valence.iter().map(|&v| v as i32).collect();
    let irregular: Vec<u8> = (0..quality.valence.len()).map(|v| u8::from(quality.is_irregular(v))).collect();
    let model_face: Vec<i32> = mesh.model_face_per_quad.iter().map(|&f| f as i32).collect();
    let vtu = VtuMesh {
        points: &mesh.vertices.positions,
        cells: vec![cells],
        point_data: vec![DataArray::i32("valence", valence), DataArray::u8("irregular", irregular)],
        cell_data: vec![
            DataArray::f64("scaled_jacobian", 1, quality.scaled_jacobian.as_slice()),
            DataArray::f64("max_angle_deviation", 1, quality.max_angle_deviation.as_slice()),
            DataArray::i32("model_face", model_face),
        ],
    };
    write_vtu(w, &vtu, &VtuOptions::default())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::features::detect_features;
    use crate::io::msh_output::MshVersion;
    use crate::io::{Format, LoadOptions};
    use crate::mesh::{Topology, TriMesh, fixtures};
    use crate::quads::fixtures::{add_midpoint_nodes, quads_from_triangle_pairs};
    use crate::quads::model::quad_model;
    use crate::quads::quality::quad_quality;

    fn grid(surface: &TriMesh) -> (QuadMesh, QuadModel) {
        let topo = Topology::new(surface);
        let model = quad_model(surface, &topo, &detect_features(surface, &topo, 30.0));
        (quads_from_triangle_pairs(surface, &topo, &model), model)
    }

    fn read_back(bytes: &[u8]) -> crate::io::RawMesh {
        crate::io::load::read_raw(bytes, Format::Msh, Some(bytes.len() as u64), &LoadOptions::default().limits())
            .unwrap()
    }

    #[test]
    fn the_cube_model_has_its_corners_curves_and_faces() {
        let (mesh, model) = grid(&fixtures::cube(2));
        let msh = quads_msh_model(&mesh, &model).unwrap();
        assert_eq!((msh.points.len(), msh.curves.len(), msh.surfaces.len()), (8, 12, 6));
        assert!(
            msh.curves
                .iter()
                .all(|c| c.bounding_points.len() == 2 && c.bounding_points[0] > 0 && c.bounding_points[1] < 0)
        );
        assert!(msh.surfaces.iter().all(|s| s.bounding_curves.len() == 4));
        let count = |t: ElementType| {
            msh.element_blocks.iter().filter(|b| b.element_type == t).map(|b| b.tags.len()).sum::<usize>()
        };
        assert_eq!((count(ElementType::Quadrangle), count(ElementType::Line), count(ElementType::Point)), (24, 24, 8));
        // Nodes: 8 on points, 12 on curves (one per edge midpoint), 6 on surfaces.
        let on = |d: u8| msh.node_blocks.iter().filter(|b| b.entity_dim == d).map(|b| b.tags.len()).sum::<usize>();
        assert_eq!((on(0), on(1), on(2)), (8, 12, 6));
    }

    #[test]
    fn msh_41_ascii_binary_and_22_read_back_with_every_node_and_element() {
        let (mesh, model) = grid(&fixtures::square_structured(3));
        for opts in [
            OutputOptions::default(),
            OutputOptions { msh_binary: Some(true), ..Default::default() },
            OutputOptions { msh_version: MshVersion::V22, msh_binary: None, ..Default::default() },
        ] {
            let mut bytes = Vec::new();
            write_quads_msh(&mesh, &model, &mut bytes, &opts).unwrap();
            let raw = read_back(&bytes);
            assert_eq!(raw.positions.len(), 16, "{opts:?}");
            // Nodes come in entity blocks: the same points in another order.
            let sorted = |p: &[crate::geom::Vec3]| {
                let mut v: Vec<[f64; 3]> = p.iter().map(|x| [x.x, x.y, x.z]).collect();
                v.sort_by(|a, b| a.partial_cmp(b).unwrap());
                v
            };
            assert_eq!(sorted(&raw.positions), sorted(&mesh.vertices.positions), "{opts:?}");
            // The reader keeps triangles and tetrahedra only; it counts what it skips.
            assert!(raw.triangles.is_empty());
            assert_eq!(raw.skipped.get("Quadrilateral 4"), Some(&9), "{opts:?} {:?}", raw.skipped);
            assert_eq!(raw.skipped.get("Line 2"), Some(&12), "{opts:?} {:?}", raw.skipped);
            // The coarse square's corners stick out of their chords by
            // more than its width allows ([`crate::quads::model`]): 4 points.
            assert_eq!(raw.skipped.get("Point"), Some(&4), "{opts:?} {:?}", raw.skipped);
        }
    }

    #[test]
    fn order_2_writes_9_node_quadrangles_and_3_node_lines() {
        let (mut mesh, model) = grid(&fixtures::square_structured(2));
        add_midpoint_nodes(&mut mesh);
        assert_eq!(mesh.vertices.len(), 25);
        let msh = quads_msh_model(&mesh, &model).unwrap();
        let quad = msh.element_blocks.iter().find(|b| b.element_type == ElementType::Quadrangle9).unwrap();
        assert_eq!(quad.nodes.len(), 4 * 9);
        let lines: Vec<_> = msh.element_blocks.iter().filter(|b| b.element_type == ElementType::Line3).collect();
        assert_eq!(lines.iter().map(|b| b.tags.len()).sum::<usize>(), 8);
        // Every mid node of a boundary line lies halfway between its ends, on its curve's entity.
        for b in lines {
            for l in b.nodes.chunks(3) {
                let p = |t: u64| mesh.vertices.positions[t as usize - 1];
                assert!(((p(l[0]) + p(l[1])) / 2.0 - p(l[2])).norm() < 1e-15);
                assert_eq!(entity_key(mesh.vertices.entity[l[2] as usize - 1]), (1, b.entity_tag));
            }
        }
        let mut bytes = Vec::new();
        write_quads_msh(&mesh, &model, &mut bytes, &OutputOptions::default()).unwrap();
        let raw = read_back(&bytes);
        assert_eq!(raw.positions.len(), 25);
        assert_eq!(raw.skipped.get("Quadrilateral 9"), Some(&4), "{:?}", raw.skipped);
        assert_eq!(raw.skipped.get("Line 3"), Some(&8), "{:?}", raw.skipped);
    }

    #[test]
    fn a_corner_without_a_vertex_is_refused() {
        let (mut mesh, model) = grid(&fixtures::square_structured(2));
        let v = mesh.vertices.entity.iter().position(|e| matches!(e, ModelEntity::Corner(_))).unwrap();
        mesh.vertices.entity[v] = ModelEntity::Curve(0);
        let e = quads_msh_model(&mesh, &model).unwrap_err();
        assert!(e.to_string().contains("has no mesh vertex"), "{e}");
    }

    #[test]
    fn vtu_has_quad_cells_and_the_quality_arrays() {
        let surface = fixtures::square_structured(2);
        let (mut mesh, _) = grid(&surface);
        let q = quad_quality(&mesh, &surface);
        let mut bytes = Vec::new();
        write_quads_vtu(&mesh, &q, &mut bytes).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        for name in ["scaled_jacobian", "max_angle_deviation", "model_face", "valence", "irregular"] {
            assert!(text.contains(&format!("Name=\"{name}\"")), "{name}");
        }
        assert!(text.contains("NumberOfCells=\"4\"") && text.contains("NumberOfPoints=\"9\""));
        add_midpoint_nodes(&mut mesh);
        let q = quad_quality(&mesh, &surface);
        let mut bytes = Vec::new();
        write_quads_vtu(&mesh, &q, &mut bytes).unwrap();
        assert!(String::from_utf8_lossy(&bytes).contains("NumberOfPoints=\"25\""));
        // A quality of another mesh does not fit.
        let other = quad_quality(&grid(&fixtures::square_structured(3)).0, &fixtures::square_structured(3));
        assert!(write_quads_vtu(&mesh, &other, &mut Vec::new()).is_err());
    }
}
