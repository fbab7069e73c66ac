//! MSH 2.2 ASCII writer for [`MshModel`].
//!
//! Layout: `$MeshFormat` (`2.2 0 8`), `$PhysicalNames` (when named),
//! `$Nodes` (count, then `tag x y z` in increasing tag order), `$Elements`
//! (count, then `tag type 2 physical elementary node…`, block by block with
//! tags sorted within a block), then `$NodeData` / `$ElementData` views.
//!
//! MSH 2.2 has no entities section and no parametrizations: the entity of an
//! element becomes its *elementary* tag, and its *physical* tag is the first
//! physical tag of that entity, or 0 when it has none (MSH 2.2 can hold only
//! one per element line; Gmsh itself repeats the element for each extra
//! physical group, which would change element counts for other readers).
//! pyGIMLi reads the physical tag as the region marker.
//!
//! The model is validated in full before the first byte is written; output
//! is buffered internally (no `BufWriter` needed).

use crate::io::msh41::model::{DataView, EntityTag, MshModel, unpack};
use crate::io::text_out::{CHUNK, flush_if_full, push_f64, push_f64s, push_u64};
use crate::io::write_error::WriteError;
use crate::mesh::{TetMesh, TriMesh};
use std::collections::HashMap;
use std::io::Write;

/// Write `model` as MSH 2.2 ASCII to `w`.
///
/// # Errors
/// A validation error (nothing written) or [`WriteError::Io`].
pub fn write_msh22(mut w: impl Write, model: &MshModel) -> Result<(), WriteError> {
    let index = model.index()?;
    let mut buf = Vec::with_capacity(CHUNK + 4096);
    buf.extend_from_slice(b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n");
    if !model.physical_names.is_empty() {
        buf.extend_from_slice(format!("$PhysicalNames\n{}\n", model.physical_names.len()).as_bytes());
        for n in &model.physical_names {
            buf.extend_from_slice(format!("{} {} \"{}\"\n", n.dim, n.tag, n.name).as_bytes());
        }
        buf.extend_from_slice(b"$EndPhysicalNames\n");
    }

    buf.extend_from_slice(format!("$Nodes\n{}\n", model.n_nodes()).as_bytes());
    for &(tag, slot) in index.nodes.sorted() {
        let (b, i) = unpack(slot);
        push_u64(&mut buf, tag);
        buf.push(b' ');
        push_f64s(&mut buf, model.node_blocks[b].positions[i].as_slice());
        buf.push(b'\n');
        flush_if_full(&mut w, &mut buf, CHUNK)?;
    }
    buf.extend_from_slice(b"$EndNodes\n");

    let physical = first_physical_per_entity(model);
    buf.extend_from_slice(format!("$Elements\n{}\n", model.n_elements()).as_bytes());
    for block in &model.element_blocks {
        let code = block.element_type.gmsh_code() as u64;
        let phys = physical.get(&(block.entity_dim, block.entity_tag)).copied().unwrap_or(0);
        let k = block.element_type.n_nodes();
        let mut order: Vec<usize> = (0..block.tags.len()).collect();
        if !block.tags.is_sorted() {
            order.sort_unstable_by_key(|&i| block.tags[i]);
        }
        for i in order {
            push_u64(&mut buf, block.tags[i]);
            buf.push(b' ');
            push_u64(&mut buf, code);
            buf.extend_from_slice(b" 2 ");
            push_u64(&mut buf, phys as u64);
            buf.push(b' ');
            push_u64(&mut buf, block.entity_tag as u64);
            for &n in &block.nodes[k * i..k * (i + 1)] {
                buf.push(b' ');
                push_u64(&mut buf, n);
            }
            buf.push(b'\n');
            flush_if_full(&mut w, &mut buf, CHUNK)?;
        }
    }
    buf.extend_from_slice(b"$EndElements\n");

    for v in &model.node_data {
        write_view(&mut w, &mut buf, "NodeData", v)?;
    }
    for v in &model.element_data {
        write_view(&mut w, &mut buf, "ElementData", v)?;
    }
    w.write_all(&buf)?;
    w.flush()?;
    Ok(())
}

/// Write `mesh` as MSH 2.2: nodes `i + 1`, triangles `f + 1` on elementary
/// entity 1 with physical tag 0.
///
/// # Errors
/// A validation error or [`WriteError::Io`].
pub fn write_surface_msh22(w: impl Write, mesh: &TriMesh) -> Result<(), WriteError> {
    write_msh22(w, &MshModel::from_surface(mesh))
}

/// Write `mesh` as MSH 2.2: nodes `i + 1`, tetrahedra `t + 1` on elementary
/// entity 1 with physical tag 0.
///
/// # Errors
/// A validation error or [`WriteError::Io`].
pub fn write_volume_msh22(w: impl Write, mesh: &TetMesh) -> Result<(), WriteError> {
    write_msh22(w, &MshModel::from_volume(mesh))
}

/// `(dim, entity tag) → first physical tag` for entities that have one.
fn first_physical_per_entity(model: &MshModel) -> HashMap<(u8, EntityTag), i32> {
    model.entity_rows().filter_map(|r| r.physical_tags.first().map(|&p| ((r.dim, r.tag), p))).collect()
}

/// A data section: name, time, then step, components, count (3 integer tags).
fn write_view(w: &mut impl Write, buf: &mut Vec<u8>, section: &str, view: &DataView) -> Result<(), WriteError> {
    buf.extend_from_slice(format!("${section}\n1\n\"{}\"\n1\n", view.name).as_bytes());
    push_f64(buf, view.time);
    buf.extend_from_slice(format!("\n3\n{}\n{}\n{}\n", view.step, view.n_components, view.tags.len()).as_bytes());
    let nc = view.n_components;
    for (i, &tag) in view.tags.iter().enumerate() {
        push_u64(buf, tag);
        buf.push(b' ');
        push_f64s(buf, &view.values[nc * i..nc * (i + 1)]);
        buf.push(b'\n');
        flush_if_full(w, buf, CHUNK)?;
    }
    buf.extend_from_slice(format!("$End{section}\n").as_bytes());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::msh41::model::SurfaceEntity;
    use crate::mesh::fixtures;

    fn section<'a>(text: &'a str, name: &str) -> Vec<&'a str> {
        let start = format!("${name}");
        let end = format!("$End{name}");
        let mut lines = text.lines().skip_while(|l| *l != start);
        lines.next().expect("section present");
        lines.take_while(|l| *l != end).collect()
    }

    #[test]
    fn structure_and_tags() {
        let mesh = fixtures::square(2);
        let mut m = MshModel::from_surface(&mesh);
        m.surfaces[0] = SurfaceEntity { tag: 1, bounding_curves: vec![], physical_tags: vec![7, 8] };
        m.element_data.push(DataView::contiguous("marker", 1, (0..8).map(f64::from).collect(), 1));
        let mut v = Vec::new();
        write_msh22(&mut v, &m).unwrap();
        let text = String::from_utf8(v).unwrap();
        assert_eq!(section(&text, "MeshFormat"), ["2.2 0 8"]);
        let nodes = section(&text, "Nodes");
        assert_eq!(nodes.len(), 1 + 9);
        assert_eq!(nodes[0], "9");
        assert_eq!(nodes[2], "2 0.5 0.0 0.0");
        let els = section(&text, "Elements");
        assert_eq!(els[0], "8");
        let t = mesh.triangles[0].map(|v| v.0 + 1);
        assert_eq!(els[1], format!("1 2 2 7 1 {} {} {}", t[0], t[1], t[2]));
        let ed = section(&text, "ElementData");
        assert_eq!(&ed[..8], ["1", "\"marker\"", "1", "0.0", "3", "0", "1", "8"]);
        assert_eq!(ed[8 + 7], "8 7.0");
    }

    #[test]
    fn volume_and_validation() {
        let tets = crate::mesh::TetMesh {
            positions: vec![
                crate::geom::Vec3::zeros(),
                crate::geom::Vec3::x(),
                crate::geom::Vec3::y(),
                crate::geom::Vec3::z(),
            ],
            tets: vec![[0, 1, 2, 3].map(crate::mesh::VertexId)],
        };
        let mut v = Vec::new();
        write_volume_msh22(&mut v, &tets).unwrap();
        let text = String::from_utf8(v).unwrap();
        assert_eq!(section(&text, "Elements"), ["1", "1 4 2 0 1 1 2 3 4"]);
        let mut bad = tets;
        bad.tets[0][3] = crate::mesh::VertexId(9);
        let mut v = Vec::new();
        assert!(matches!(write_volume_msh22(&mut v, &bad), Err(WriteError::MissingNode { node: 10, .. })));
        assert!(v.is_empty());
    }
}
