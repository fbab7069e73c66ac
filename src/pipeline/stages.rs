//! The stage arms of the pipeline: each runs one stage on the products of
//! the earlier steps, writes its artifacts into the output directory and
//! returns a JSON summary. Stages never reach into each other's internals:
//! they share only the repaired surface, the optional volume and the feature
//! edges (computed once, by whichever stage needs them first).

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use crate::atlas::features::{Features, detect_features};
use crate::atlas::{AtlasError, build_atlas, write_atlas_msh_as, write_atlas_uv_vtu, write_atlas_vtu};
use crate::crossfield::{
    CrossfieldError, compute_crossfield, write_crossfield_msh_as, write_crossfield_vtu, write_singularities_json,
};
use crate::failure::FailureKind;
use crate::frames::{FramesError, compute_frame_field, write_frames_vtu, write_singular_edges_vtu};
use crate::io::WriteError;
use crate::mesh::{Topology, TriMesh};
use crate::preview;
use crate::progress::Progress;
use crate::quads::{QuadsError, build_quads, write_quads_msh, write_quads_vtu};

use super::durable::Syncer;
use super::error::PipelineError;
use super::params::{PipelineParams, StageName};
use super::previews::Previews;
use super::report::StageReport;
use super::run::{Products, StageOutput};

/// Write `out_dir/name` with `f` through a buffer, flush it and hand it to
/// `syncer` (on disk before the pipeline returns).
fn write_artifact(
    out_dir: &Path,
    syncer: &Syncer,
    name: &str,
    f: impl FnOnce(&mut BufWriter<File>) -> Result<(), WriteError>,
) -> Result<String, PipelineError> {
    let path = out_dir.join(name);
    let err = |source: WriteError| PipelineError::Write { path: path.clone(), source };
    let mut w = BufWriter::new(File::create(&path).map_err(|e| err(e.into()))?);
    f(&mut w).map_err(err)?;
    let file = w.into_inner().map_err(|e| err(e.into_error().into()))?;
    syncer.sync(path.clone(), file).map_err(|e| err(e.into()))?;
    Ok(name.to_string())
}

/// Feature edges of the surface (computed once per job).
fn features<'a>(products: &'a mut Products, topo: &Topology, feature_angle_deg: f64) -> &'a Features {
    products.features.get_or_insert_with(|| detect_features(&products.surface, topo, feature_angle_deg))
}

/// Stage 1: the atlas; artifacts `atlas.msh`, `atlas.vtu`, `atlas_uv.vtu`
/// and the preview `atlas.png`.
pub fn run_atlas(
    params: &PipelineParams,
    products: &mut Products,
    out_dir: &Path,
    syncer: &Syncer,
    progress: &Progress,
) -> Result<StageOutput, PipelineError> {
    let atlas = build_atlas(&products.surface, &params.atlas, progress).map_err(|e| match e {
        AtlasError::Cancelled => PipelineError::Cancelled,
        AtlasError::NoValidMap { .. } => PipelineError::stage("atlas", FailureKind::NoValidMap, e.to_string()),
        other => PipelineError::stage("atlas", FailureKind::StageFailed, other.to_string()),
    })?;
    progress.check()?;
    let write_start = std::time::Instant::now();
    // The MSH file (with the parametrizations) takes as long as both VTU
    // files together: write it beside them on the pool.
    let (msh, (vtu, uv)) = rayon::join(
        || write_artifact(out_dir, syncer, "atlas.msh", |w| write_atlas_msh_as(&atlas, w, &params.output)),
        || {
            rayon::join(
                || write_artifact(out_dir, syncer, "atlas.vtu", |w| write_atlas_vtu(&atlas, w)),
                || write_artifact(out_dir, syncer, "atlas_uv.vtu", |w| write_atlas_uv_vtu(&atlas, w)),
            )
        },
    );
    let artifacts = vec![msh?, vtu?, uv?];
    let write_seconds = write_start.elapsed().as_secs_f64();
    let mut previews = Previews::default();
    if params.output.previews {
        let start = std::time::Instant::now();
        let patch_color = preview::atlas_patch_colors(&atlas);
        let face_colors = atlas.patch_per_face.iter().map(|&p| patch_color[p as usize]).collect();
        products.patch_colors = Some((atlas.mesh.clone(), face_colors));
        previews.seconds += start.elapsed().as_secs_f64();
        previews.draw(&params.output, out_dir, syncer, "atlas.png", |size| {
            preview::atlas_preview(&atlas, &patch_color, size)
        });
    }
    let report = StageReport::Atlas(Box::new(atlas.report.clone()));
    products.features = Some(atlas.features.clone());
    // Later stages (quads) read the atlas; without them it is dropped now.
    if params.stages_to_run().0.contains(&StageName::Quads) {
        products.atlas = Some(atlas);
    }
    Ok(StageOutput { report, artifacts, write_seconds, previews })
}

/// Stage 2: the crossfield, aligned with boundary and feature edges
/// (those of the atlas when it ran, with the same angle threshold);
/// artifacts `crossfield.vtu`, `singularities.json`, `crossfield.msh` and
/// the preview `crossfield.png`.
pub fn run_crossfield(
    params: &PipelineParams,
    products: &mut Products,
    out_dir: &Path,
    syncer: &Syncer,
    progress: &Progress,
) -> Result<StageOutput, PipelineError> {
    let topo = Topology::new(&products.surface);
    let aligned = features(products, &topo, params.atlas.feature_angle_deg).is_feature_edge.clone();
    let surface: &TriMesh = &products.surface;
    let field = compute_crossfield(surface, &topo, &aligned, &params.crossfield, progress).map_err(|e| match e {
        CrossfieldError::Cancelled(_) => PipelineError::Cancelled,
        CrossfieldError::InconsistentOrientation { .. } => {
            PipelineError::stage("crossfield", FailureKind::NonOrientableSurface, e.to_string())
        }
        other => PipelineError::stage("crossfield", FailureKind::StageFailed, other.to_string()),
    })?;
    progress.check()?;
    let write_start = std::time::Instant::now();
    let artifacts = vec![
        write_artifact(out_dir, syncer, "crossfield.vtu", |w| write_crossfield_vtu(&field, surface, w))?,
        write_artifact(out_dir, syncer, "singularities.json", |w| Ok(write_singularities_json(&field, w)?))?,
        write_artifact(out_dir, syncer, "crossfield.msh", |w| {
            write_crossfield_msh_as(&field, surface, w, &params.output)
        })?,
    ];
    let write_seconds = write_start.elapsed().as_secs_f64();
    let mut previews = Previews::default();
    previews.draw(&params.output, out_dir, syncer, "crossfield.png", |size| {
        preview::crossfield_preview(surface, &field, size)
    });
    products.singular_points = field
        .singularities
        .iter()
        .map(|s| (s.position, preview::palette::index_color(s.index, field.symmetry)))
        .collect();
    let report = StageReport::Crossfield(Box::new(field.report.clone()));
    if params.stages_to_run().0.contains(&StageName::Quads) {
        products.crossfield = Some(field);
    }
    Ok(StageOutput { report, artifacts, write_seconds, previews })
}

/// Stage 3: the volume (the uploaded tetrahedra, or a mesh of the enclosed
/// volume) and its frame field; artifacts `frames.vtu`, `frames_singular.vtu`
/// and the preview `frames.png`.
pub fn run_frames(
    params: &PipelineParams,
    products: &mut Products,
    out_dir: &Path,
    syncer: &Syncer,
    progress: &Progress,
) -> Result<StageOutput, PipelineError> {
    let field = compute_frame_field(&products.surface, products.volume.as_ref(), &params.frames, progress).map_err(
        |e| match e {
            FramesError::Cancelled(_) => PipelineError::Cancelled,
            FramesError::OpenSurface { .. } => PipelineError::stage("frames", FailureKind::OpenSurface, e.to_string()),
            FramesError::TooManyTets { .. } | FramesError::NoInterior { .. } => {
                PipelineError::stage("frames", FailureKind::InvalidTargetSize, e.to_string())
            }
            other => PipelineError::stage("frames", FailureKind::StageFailed, other.to_string()),
        },
    )?;
    progress.check()?;
    let write_start = std::time::Instant::now();
    let artifacts = vec![
        write_artifact(out_dir, syncer, "frames.vtu", |w| write_frames_vtu(&field, w))?,
        write_artifact(out_dir, syncer, "frames_singular.vtu", |w| write_singular_edges_vtu(&field, w))?,
    ];
    let write_seconds = write_start.elapsed().as_secs_f64();
    let mut previews = Previews::default();
    previews.draw(&params.output, out_dir, syncer, "frames.png", |size| {
        preview::frames_preview(&products.surface, &field, size)
    });
    let report = StageReport::Frames(Box::new(field.report));
    Ok(StageOutput { report, artifacts, write_seconds, previews })
}

/// The failure of the quads stage: invalid options (only the crossfield's
/// symmetry reaches here, the options are checked with the parameters) as
/// invalid parameters, a size asking for too many quads as the frames
/// stage's too many tetrahedra, everything else (a failed check is a bug)
/// as a stage failure.
fn quads_failure(e: QuadsError) -> PipelineError {
    match e {
        QuadsError::Cancelled(_) => PipelineError::Cancelled,
        QuadsError::InvalidOption { .. } => PipelineError::stage("quads", FailureKind::InvalidParams, e.to_string()),
        QuadsError::TooManyQuads { .. } => PipelineError::stage("quads", FailureKind::InvalidTargetSize, e.to_string()),
        QuadsError::Triangulation { .. } | QuadsError::CheckFailed { .. } => {
            PipelineError::stage("quads", FailureKind::StageFailed, e.to_string())
        }
    }
}

/// Stage 4: the all-quad surface mesh, from the atlas and the crossfield
/// of the earlier stages; artifacts `quads.msh`, `quads.vtu` and the
/// preview `quads.png`.
pub fn run_quads(
    params: &PipelineParams,
    products: &mut Products,
    out_dir: &Path,
    syncer: &Syncer,
    progress: &Progress,
) -> Result<StageOutput, PipelineError> {
    let missing = |what: &str| {
        PipelineError::stage("quads", FailureKind::InternalError, format!("the {what} stage did not run before quads"))
    };
    let atlas = products.atlas.as_ref().ok_or_else(|| missing("atlas"))?;
    let field = products.crossfield.as_ref().ok_or_else(|| missing("crossfield"))?;
    let result = build_quads(&products.surface, atlas, field, &params.quads, progress).map_err(quads_failure)?;
    progress.check()?;
    let write_start = std::time::Instant::now();
    let artifacts = vec![
        write_artifact(out_dir, syncer, "quads.msh", |w| {
            write_quads_msh(&result.mesh, &result.model, w, &params.output)
        })?,
        write_artifact(out_dir, syncer, "quads.vtu", |w| write_quads_vtu(&result.mesh, &result.quality, w))?,
    ];
    let write_seconds = write_start.elapsed().as_secs_f64();
    let mut previews = Previews::default();
    previews.draw(&params.output, out_dir, syncer, "quads.png", |size| {
        preview::quads_preview(&products.surface, &result.mesh, &result.quality, size)
    });
    Ok(StageOutput { report: StageReport::Quads(Box::new(result.report)), artifacts, write_seconds, previews })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_errors_map_to_their_failure_kinds() {
        let kind = |e: QuadsError| quads_failure(e).kind();
        let invalid = QuadsError::InvalidOption { name: "crossfield.symmetry", reason: "6".into() };
        assert_eq!(kind(invalid), FailureKind::InvalidParams);
        assert_eq!(
            kind(QuadsError::TooManyQuads { size: 1e-9, estimated: 1 << 40, limit: 10 }),
            FailureKind::InvalidTargetSize
        );
        let check = QuadsError::CheckFailed { check: "inverted", detail: "quad 3".into() };
        assert_eq!(kind(check), FailureKind::StageFailed);
        assert!(matches!(quads_failure(QuadsError::Cancelled(crate::progress::Cancelled)), PipelineError::Cancelled));
    }
}
