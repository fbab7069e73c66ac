//! The quads stage: an all-quadrilateral surface mesh aligned with the
//! crossfield, conforming across the atlas (thesis introduction and ch. 3:
//! "how to spawn vertices to merge them into quadrangles").
//!
//! Steps, each in its own module:
//! 1. [`model`]: the feature model the mesh is classified on (corners,
//!    feature curves, model faces bounded by them); atlas seams are not part
//!    of it, and curve vertices a chord would visibly cut are corners.
//! 2. [`curves`]: every feature curve discretized once at the target size,
//!    shared by the faces it bounds, segment counts chosen so every model
//!    face has an even number of boundary segments (parity) and, by
//!    [`sides`], so four-sided faces get as many on opposite sides.
//! 3. [`triangulation`]: in each atlas patch's `(u, v)` plane, points placed
//!    frontally along the cross at the target size, a vertex at every
//!    crossfield singularity, and a constrained Delaunay triangulation
//!    ([`conformal_chart`]: a patch the atlas' disk map distorts is
//!    triangulated in its plane or its conformal map instead);
//!    the patches' triangulations joined into one [`SurfaceTriangulation`];
//!    [`slivers`]: regions of slivers (fans a distorted chart leaves)
//!    re-triangulated in 3D.
//! 4. [`recombine`]: triangles paired into quads by alignment and shape,
//!    completed to a perfect matching, midpoint subdivision as last resort
//!    ([`transition`]: of the failing faces alone where it can).
//! 5. [`cleanup`], [`cavity`] and [`smooth`]: valence-2 vertices and 3-3
//!    diamonds removed; cavities around irregular vertices replaced by
//!    patterns with fewer of them; smoothing that never lowers a neighbourhood's worst scaled
//!    Jacobian, every vertex projected back onto the input ([`projection`]);
//!    [`untangle`]: the vertices of the quads below 0.5 moved to raise
//!    their worst scaled Jacobian, before and after [`pillow`]: a quad
//!    still inverted gets a layer of quads pillowed around it and its
//!    region untangled.
//! 6. [`order2`]: optional 9-node quadrangles, new nodes on the input.
//! 7. [`quality`] and [`check`]: scaled Jacobians, valences, the valence
//!    identity and conformity, asserted on every output; [`report`].
//! 8. [`output`]: `quads.msh` and `quads.vtu`.

pub mod cavity;
pub mod check;
pub mod cleanup;
pub mod conformal_chart;
pub mod curves;
pub mod error;
pub mod fixtures;
pub mod flips;
pub mod insertion;
pub mod jacobian;
pub mod matching;
pub mod model;
pub mod options;
pub mod order2;
pub mod output;
pub mod pairing;
pub mod parity;
pub mod patch_chart;
pub mod pillow;
pub mod projection;
pub mod quality;
pub mod recombine;
pub mod report;
pub mod sides;
pub mod size_map;
pub mod slivers;
pub mod smooth;
pub mod strip;
pub mod subdivision;
pub mod surface_mesh;
pub mod transition;
pub mod triangulation;
pub mod untangle;

pub use error::QuadsError;
pub use model::{QuadModel, quad_model};
pub use options::QuadsOptions;
pub use output::{write_quads_msh, write_quads_vtu};
pub use quality::QuadQuality;
pub use report::QuadsReport;
pub use surface_mesh::{ModelEntity, QuadMesh, SurfacePoint, SurfaceTriangulation};

use std::time::Instant;

use crate::atlas::Atlas;
use crate::crossfield::Crossfield;
use crate::mesh::{Topology, TriMesh};
use crate::progress::Progress;

/// Quads the default size may ask for before the stage refuses the job
/// (about 1.5 GB of working memory).
pub const MAX_QUADS: u64 = 10_000_000;

/// What the stage produces: the mesh, the model it is classified on, its
/// measures and the report.
#[derive(Debug, Clone)]
pub struct QuadsResult {
    /// The quad mesh.
    pub mesh: QuadMesh,
    /// The feature model.
    pub model: QuadModel,
    /// Its measures.
    pub quality: QuadQuality,
    /// The report.
    pub report: QuadsReport,
}

/// The all-quad mesh of `surface` (the repaired input the atlas and the
/// crossfield were computed on), aligned with `field`, at the size `opts`
/// asks for.
///
/// # Errors
/// [`QuadsError::InvalidOption`] and [`QuadsError::TooManyQuads`] for bad
/// options, [`QuadsError::Triangulation`] when a patch cannot be
/// triangulated, [`QuadsError::CheckFailed`] when the output fails a check
/// (a bug), [`QuadsError::Cancelled`].
pub fn build_quads(
    surface: &TriMesh,
    atlas: &Atlas,
    field: &Crossfield,
    opts: &QuadsOptions,
    progress: &Progress,
) -> Result<QuadsResult, QuadsError> {
    opts.validate()?;
    if field.symmetry != 4 {
        return Err(QuadsError::InvalidOption {
            name: "crossfield.symmetry",
            reason: format!("quads need a cross (symmetry 4), the crossfield has symmetry {}", field.symmetry),
        });
    }
    let topo = Topology::new(surface);
    let model = quad_model(surface, &topo, &atlas.features);
    let diagonal = surface.bounding_box().map_or(0.0, |b| b.diagonal());
    let size = opts.target_size(surface.mean_edge_length(), diagonal);
    let estimated = (surface.area() / (size * size)).ceil();
    if !(estimated <= MAX_QUADS as f64) {
        return Err(QuadsError::TooManyQuads {
            size,
            estimated: estimated.min(u64::MAX as f64) as u64,
            limit: MAX_QUADS,
        });
    }
    let (tri, triangulation) =
        triangulation::surface_triangulation(surface, &topo, atlas, field, &model, size, &progress.sub(0.0, 0.4))?;
    progress.check()?;
    let projector = projection::SurfaceProjector::new(surface, &topo, &model);
    let input = Input { surface, topo: &topo, model: &model, projector: &projector };
    let mut narrowest = recombine::SubdivisionScope::Triangles;
    let mut refused = Vec::new();
    let finished = loop {
        let (mesh, mut recombination) = recombine::recombine(&tri, narrowest, &progress.sub(0.4, 0.6))?;
        progress.check()?;
        let scope = recombination.subdivision_scope;
        recombination.scopes_refused.clone_from(&refused);
        match finish(mesh, recombination, &input, opts, progress) {
            // A narrow subdivision the later steps left tangled: recombine
            // again with a wider one (their output passed these checks
            // before narrow ones existed).
            Err(failed @ QuadsError::CheckFailed { .. })
                if scope > recombine::SubdivisionScope::None
                    && scope < recombine::SubdivisionScope::FacesWithNeighbours =>
            {
                refused.push(recombine::RefusedScope { scope, reason: failed.to_string() });
                narrowest = if scope == recombine::SubdivisionScope::Triangles {
                    recombine::SubdivisionScope::Faces
                } else {
                    recombine::SubdivisionScope::FacesWithNeighbours
                };
            }
            other => break other?,
        }
    };
    let singularity_indices =
        field.singularities.iter().map(|s| (s.index * f64::from(field.symmetry)).round() as i32).collect();
    let report = QuadsReport::new(report::ReportInputs {
        target_size: size,
        order: opts.order,
        mesh: &finished.mesh,
        quality: &finished.quality,
        singularity_indices,
        triangulation,
        recombination: finished.recombination,
        cleanup: finished.cleanup,
        cavities: finished.cavities,
        smoothing: finished.smoothing,
        pillowing: finished.pillowing,
        raising: finished.raising,
        high_order_seconds: finished.high_order_seconds,
        check_seconds: finished.check_seconds,
    });
    Ok(QuadsResult { mesh: finished.mesh, model, quality: finished.quality, report })
}

/// The mesh after the steps that follow recombination, and what they did.
struct Finished {
    mesh: QuadMesh,
    recombination: recombine::RecombineStats,
    cleanup: cleanup::CleanupStats,
    cavities: cavity::CavityStats,
    smoothing: smooth::SmoothStats,
    pillowing: pillow::PillowStats,
    raising: untangle::RaiseStats,
    high_order_seconds: f64,
    quality: QuadQuality,
    check_seconds: f64,
}

/// What the steps after recombination read: the input surface, its
/// topology and feature model, the projector onto it.
struct Input<'a> {
    surface: &'a TriMesh,
    topo: &'a Topology,
    model: &'a QuadModel,
    projector: &'a projection::SurfaceProjector<'a>,
}

/// Cleanup, cavity remeshing, smoothing, pillowing between two raisings of
/// the worst quads, and the optional
/// high-order nodes on the recombined `mesh`, then the checks every output
/// must pass.
fn finish(
    mut mesh: QuadMesh,
    recombination: recombine::RecombineStats,
    input: &Input,
    opts: &QuadsOptions,
    progress: &Progress,
) -> Result<Finished, QuadsError> {
    let Input { surface, topo, model, projector } = *input;
    let cleanup = cleanup::clean_up(&mut mesh, projector);
    let cavities = cavity::remesh_cavities(&mut mesh, projector);
    let smoothing = smooth::smooth(&mut mesh, projector, opts.smoothing_iterations, &progress.sub(0.6, 0.95))?;
    // Raised before pillowing, so that it pillows only what moves cannot
    // mend, and after, to raise the layers it added.
    let raised = untangle::raise_worst_quads(&mut mesh, projector);
    let pillowing = pillow::pillow_bad_quads(&mut mesh, projector);
    let raising = raised.then(untangle::raise_worst_quads(&mut mesh, projector));
    let t = Instant::now();
    if opts.order == 2 {
        order2::add_high_order_nodes(&mut mesh, projector);
    }
    let high_order_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let quality = quality::quad_quality(&mesh, surface);
    check::check_quad_mesh(&mesh, &quality, surface, topo, model)?;
    let check_seconds = t.elapsed().as_secs_f64();
    Ok(Finished {
        mesh,
        recombination,
        cleanup,
        cavities,
        smoothing,
        pillowing,
        raising,
        high_order_seconds,
        quality,
        check_seconds,
    })
}
