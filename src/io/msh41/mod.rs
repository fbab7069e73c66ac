//! Gmsh MSH 4.1: the general model ([`model::MshModel`]), a builder for
//! discrete atlases ([`discrete::DiscreteModelBuilder`]), the writer
//! ([`write::write_msh41`]; layout in [`write`]) and the reader ([`read`],
//! ASCII and binary, parametric and partitioned files; shared reading code
//! in [`crate::io::msh_common`]).
//!
//! # Writing an atlas that Gmsh remeshes
//! ```
//! use meshatlas::geom::Vec2;
//! use meshatlas::io::msh41::discrete::{DiscreteModelBuilder, PatchUv};
//! use meshatlas::io::msh41::model::DataView;
//! use meshatlas::io::msh41::write::{write_msh41, Msh41Options};
//! use meshatlas::mesh::{fixtures, FaceId, VertexId};
//!
//! # fn main() -> Result<(), meshatlas::io::WriteError> {
//! let mesh = fixtures::disk(4); // unit disk, boundary ring at radius 1
//! let ring: Vec<VertexId> = (0..mesh.n_vertices())
//!     .filter(|&v| (mesh.positions[v].norm() - 1.0).abs() < 1e-12)
//!     .map(VertexId::new)
//!     .collect();
//! let mut b = DiscreteModelBuilder::new(&mesh);
//! b.add_corner(ring[0])?; // point 1
//! let mut loop_ = ring.clone();
//! loop_.push(ring[0]); // closed: starts and ends at the corner
//! let curve = b.add_curve(loop_)?; // curve 1, bounded by [1, -1]
//! // (u, v) per patch vertex: here the disk itself (boundary on the unit circle).
//! let vertices: Vec<VertexId> = (0..mesh.n_vertices()).map(VertexId::new).collect();
//! let uv: Vec<Vec2> = vertices.iter().map(|v| mesh.positions[v.idx()].xy()).collect();
//! let faces: Vec<FaceId> = (0..mesh.n_faces()).map(FaceId::new).collect();
//! b.add_patch(faces, vec![curve], Some(PatchUv { vertices, uv, curvature: vec![] }))?;
//! let mut model = b.build()?;
//! // Per-triangle data: triangle of face f has element tag f + 1.
//! let sigma = vec![1.0; mesh.n_faces()];
//! model.element_data.push(DataView::contiguous("sigma2/sigma1", 1, sigma, 1));
//! let mut out = Vec::new(); // or a File: output is buffered internally
//! write_msh41(&mut out, &model, &Msh41Options::default())?;
//! # assert!(String::from_utf8(out).unwrap().contains("$Parametrizations\n1 1\n"));
//! # Ok(())
//! # }
//! ```
//!
//! # Gmsh 4.15.2 behaviour found while testing (`tests/io_writers.rs`)
//! - **Curve maps are required.** `gmsh.open(f); gmsh.model.mesh.clear();
//!   gmsh.model.mesh.generate(2)` meshes the curves from their
//!   `$Parametrizations` polylines; without them every surface is skipped
//!   with only a *warning* ("only 0 nodes on the boundary") and no triangle.
//!   [`model::MshModel::validate`] therefore rejects a surface map whose
//!   bounding curves have none. Check triangle counts, not just errors.
//! - **Curve parameter = point index.** `discreteEdge` fixes its range to
//!   `[0, N−1]`; the writer writes `u = 0, 1, …`.
//! - **Planar patches lose their map.** On load, a discrete surface whose
//!   points all lie on their mean plane (within `Geometry.MatchMeshTolerance`
//!   × bbox diagonal) gets Gmsh's own plane projection instead of the stored
//!   `(u, v)` (also for Gmsh's own `disk_tiny_atlas.msh`): `getValue(2, s,
//!   our_uv)` no longer reproduces the points, but remeshing works. Curved
//!   patches keep the stored map exactly (`getValue` error 0).
//! - **The `(u, v)` domain is free.** The unit circle is not required:
//!   scaled and shifted maps, mirrored (clockwise) maps and annuli (a patch
//!   with a hole, two bounding loops) all remesh. The map must be
//!   injective; Gmsh does not check it.
//! - **Closed curves** are bounded by `[p, −p]` (one corner named twice);
//!   `gmsh.model.getBoundary([(1, c)], combined=False)` then returns
//!   `[(0, p), (0, p)]`, and `combined=True` returns nothing. Gmsh writes
//!   `+c` for every bounding curve of a discrete surface (both caps of its
//!   sphere atlas name `+3`), so signs there carry no information.
//! - **Two patches sharing a curve** are meshed on the same curve nodes:
//!   the remeshed sphere of two caps is watertight (every edge in exactly
//!   two triangles).
//! - **Data sections end Gmsh's mesh pass**, so they come last; a view
//!   written with time step `s` has empty steps before `s` in
//!   `gmsh.view.getModelData`. Binary data entries have `int` tags.
//! - **Parametric node blocks** (`NodeBlock::parametric`) are accepted by
//!   Gmsh but make the file unreadable by meshio 5.3; the builder never
//!   writes them.
//! - Gmsh writes element tags unsorted inside a block and floats with
//!   `%.16g`; we write them sorted and with shortest round-trip precision.

pub mod discrete;
pub mod model;
pub mod read;
pub mod write;
