//! [`run_pipeline`]: load → repair → selected stages → write artifacts and
//! `report.json`, timing every step and reporting progress.
//!
//! Progress ranges of the overall fraction: load `[0, 0.1]`, repair
//! `[0.1, 0.2]` (the readers' welding and repair), the
//! selected stages share `[0.2, 0.9]` equally, writing `[0.9, 1]`. The
//! pipeline calls `progress.check()` between steps, so a cancel stops it at
//! the next boundary at the latest (stages check more often inside).
//!
//! Stages run in [`StageName`] order; a requested stage's dependencies
//! ([`StageName::dependencies`]: quads needs atlas and crossfield) run
//! first when not requested, and the report lists them (`stages_added`).
//!
//! Adding a stage: a [`StageName`] variant, an options field in
//! [`PipelineParams`], an output field in [`Products`] if later stages need
//! it, and one arm in [`run_stage`] calling the stage's function, which
//! writes its artifact files into `out_dir` and returns its typed report
//! (a [`StageReport`] variant, stored in [`StageReports`]).

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::io::glb::{GlbScene, write_glb};
use crate::io::load::{finish, read_raw};
use crate::io::msh_output::write_msh;
use crate::io::msh41::model::MshModel;
use crate::io::vtu::write_surface_vtu;
use crate::io::{Format, IoError, LoadOptions, LoadedMesh, RawMesh, WriteError};
use crate::mesh::{TetMesh, TriMesh};
use crate::progress::Progress;

use super::durable::Syncer;
use super::error::PipelineError;
use super::media_type_for;
use super::params::{PipelineParams, StageName};
use super::previews::Previews;
use super::report::{ArtifactInfo, InputInfo, PipelineReport, PreviewOutcome, StageReport, StageReports, StepTiming};

/// Name of the report artifact.
pub const REPORT_NAME: &str = "report.json";

/// What one stage hands back: its typed report (numbers a user wants to
/// see: patch counts, χ, singularities, energies) and the names of the
/// files it wrote into `out_dir`.
#[derive(Debug, Clone)]
pub struct StageOutput {
    /// Report shown in the job resource and `report.json`.
    pub report: StageReport,
    /// Files written into the output directory.
    pub artifacts: Vec<String>,
    /// Wall seconds spent writing those files (reported as the separate step
    /// `<stage>.write`, so the stage's own time compares with other tools'
    /// computation times).
    pub write_seconds: f64,
    /// The stage's preview images (step `<stage>.preview`).
    pub previews: Previews,
}

/// Data a stage reads: the repaired input and the products of earlier
/// stages. Each stage that feeds a later one adds an `Option` field here.
#[derive(Debug)]
pub struct Products {
    /// The repaired surface.
    pub surface: TriMesh,
    /// The volume mesh, when the input carried one (tetrahedral MSH).
    pub volume: Option<TetMesh>,
    /// Feature edges of the surface, once a stage has detected them.
    pub features: Option<crate::atlas::features::Features>,
    /// The atlas, kept when a later stage (quads) reads it.
    pub atlas: Option<crate::atlas::Atlas>,
    /// The crossfield, kept when a later stage (quads) reads it.
    pub crossfield: Option<crate::crossfield::Crossfield>,
    /// The atlas triangulation and the preview colour of each of its
    /// triangles (its patch's), for `surface.glb`.
    pub patch_colors: Option<(TriMesh, Vec<[u8; 3]>)>,
    /// The crossfield singularities and their index colours, for `surface.glb`.
    pub singular_points: Vec<(crate::geom::Vec3, [u8; 3])>,
}

/// Runs one stage.
fn run_stage(
    stage: StageName,
    params: &PipelineParams,
    products: &mut Products,
    out_dir: &Path,
    syncer: &Syncer,
    progress: &Progress,
) -> Result<StageOutput, PipelineError> {
    match stage {
        StageName::Atlas => super::stages::run_atlas(params, products, out_dir, syncer, progress),
        StageName::Crossfield => super::stages::run_crossfield(params, products, out_dir, syncer, progress),
        StageName::Frames => super::stages::run_frames(params, products, out_dir, syncer, progress),
        StageName::Quads => super::stages::run_quads(params, products, out_dir, syncer, progress),
    }
}

/// Reads `input` without repairing it: the format from `format`, else the
/// file extension, else the content (as [`crate::io::load_path`] does).
fn read_input(input: &Path, format: Option<Format>, opts: &LoadOptions) -> Result<(RawMesh, Format), IoError> {
    use std::io::BufRead;
    opts.validate()?;
    let file = File::open(input)?;
    let len = file.metadata()?.len();
    if len == 0 {
        return Err(IoError::EmptyFile);
    }
    let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
    let ext = input.extension().and_then(|e| e.to_str());
    let format = match format.or_else(|| ext.and_then(Format::from_extension)) {
        Some(f) => f,
        None => Format::sniff(reader.fill_buf()?, Some(len)).ok_or_else(|| IoError::UnknownFormat {
            reason: "the content is not recognised as STL, OBJ, PLY or MSH".to_string(),
        })?,
    };
    Ok((read_raw(reader, format, Some(len), &opts.limits())?, format))
}

/// Times `f` and records it as step `name`.
fn timed<T>(timings: &mut Vec<StepTiming>, name: &str, f: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let out = f();
    timings.push(StepTiming { step: name.to_string(), seconds: start.elapsed().as_secs_f64() });
    out
}

/// Writes `out_dir/name` with `f` (the writers buffer internally), hands it
/// to `syncer` (or syncs it now when `syncer` is `None`) and returns its size.
fn write_file(
    out_dir: &Path,
    syncer: Option<&Syncer>,
    name: &str,
    f: impl FnOnce(&mut File) -> Result<(), WriteError>,
) -> Result<ArtifactInfo, PipelineError> {
    let path = out_dir.join(name);
    let err = |source: WriteError| PipelineError::Write { path: path.clone(), source };
    let mut file = File::create(&path).map_err(|e| err(e.into()))?;
    f(&mut file).map_err(err)?;
    let bytes = file.metadata().map_err(|e| err(e.into()))?.len();
    let synced = match syncer {
        Some(s) => s.sync(path.clone(), file),
        None => file.sync_all(),
    };
    synced.map_err(|e| err(e.into()))?;
    Ok(ArtifactInfo { name: name.to_string(), bytes, media_type: media_type_for(name).to_string() })
}

/// Size and media type of a file a stage wrote.
fn artifact_info(out_dir: &Path, name: &str) -> Result<ArtifactInfo, PipelineError> {
    let path: PathBuf = out_dir.join(name);
    let bytes =
        std::fs::metadata(&path).map_err(|e| PipelineError::Write { path: path.clone(), source: e.into() })?.len();
    Ok(ArtifactInfo { name: name.to_string(), bytes, media_type: media_type_for(name).to_string() })
}

/// Runs the pipeline on `input` and writes `mesh.msh` (MSH 4.1), `mesh.vtu`,
/// the stages' artifacts and `report.json` into `out_dir` (created if
/// missing).
///
/// `format` overrides detection from the file name and content.
///
/// # Errors
/// [`PipelineError::Load`] when the input cannot be read (its `kind()` is
/// the reader's: `parse-error`, `too-many-triangles`, …),
/// [`PipelineError::Cancelled`] when `progress` is cancelled,
/// [`PipelineError::Stage`] when a stage fails, [`PipelineError::Write`]
/// when an artifact cannot be written.
pub fn run_pipeline(
    input: &Path,
    format: Option<Format>,
    params: &PipelineParams,
    out_dir: &Path,
    progress: &Progress,
) -> Result<PipelineReport, PipelineError> {
    let start = Instant::now();
    let mut timings = Vec::new();
    std::fs::create_dir_all(out_dir)
        .map_err(|e| PipelineError::Write { path: out_dir.to_path_buf(), source: e.into() })?;
    progress.check()?;
    let syncer = Syncer::start();

    let _span = tracing::info_span!("pipeline", input = %input.display()).entered();
    let load_progress = progress.stage("load", 0.0, 0.1);
    let (raw, format) = timed(&mut timings, "load", || read_input(input, format, &params.load))?;
    load_progress.set(1.0);
    progress.check()?;
    let repair_progress = progress.stage("repair", 0.1, 0.2);
    let loaded: LoadedMesh = timed(&mut timings, "repair", || finish(raw, format, &params.load))?;
    repair_progress.set(1.0);
    tracing::info!(
        n_triangles = loaded.surface.n_faces(),
        n_vertices = loaded.surface.n_vertices(),
        "input loaded and repaired"
    );
    let input_info = InputInfo {
        name: input.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
        format: loaded.format.extension(),
        bytes: std::fs::metadata(input).map(|m| m.len()).unwrap_or(0),
        n_vertices: loaded.surface.n_vertices(),
        n_triangles: loaded.surface.n_faces(),
        n_tets: loaded.volume.as_ref().map(|v| v.tets.len()),
    };
    let repair = loaded.repair;
    let mut products = Products {
        surface: loaded.surface,
        volume: loaded.volume,
        features: None,
        atlas: None,
        crossfield: None,
        patch_colors: None,
        singular_points: Vec::new(),
    };

    let (stages, stages_added) = params.stages_to_run();
    if !stages_added.is_empty() {
        let added: Vec<&str> = stages_added.iter().map(|s| s.as_str()).collect();
        tracing::info!(?added, "stages added because requested stages need them");
    }
    let mut reports = StageReports::default();
    let mut artifacts = Vec::new();
    let mut previews: Vec<PreviewOutcome> = Vec::new();
    let share = 0.7 / stages.len().max(1) as f64;
    for (i, &stage) in stages.iter().enumerate() {
        progress.check()?;
        let name = stage.as_str();
        let lo = 0.2 + share * i as f64;
        let p = progress.stage(name, lo, lo + share);
        let _stage_span = tracing::info_span!("stage", name).entered();
        let out = timed(&mut timings, name, || run_stage(stage, params, &mut products, out_dir, &syncer, &p))?;
        if let Some(t) = timings.last_mut() {
            t.seconds = (t.seconds - out.write_seconds - out.previews.seconds).max(0.0);
        }
        timings.push(StepTiming { step: format!("{name}.write"), seconds: out.write_seconds });
        if !out.previews.outcomes.is_empty() {
            timings.push(StepTiming { step: format!("{name}.preview"), seconds: out.previews.seconds });
        }
        p.set(1.0);
        for file in out.artifacts.iter().chain(&out.previews.artifacts) {
            artifacts.push(artifact_info(out_dir, file)?);
        }
        previews.extend(out.previews.outcomes);
        reports.insert(out.report);
    }

    progress.check()?;
    let wp = progress.stage("write", 0.9, 1.0);
    let surface = &products.surface;
    let written = timed(&mut timings, "write", || -> Result<Vec<ArtifactInfo>, PipelineError> {
        let msh = write_file(out_dir, Some(&syncer), "mesh.msh", |w| {
            write_msh(w, &MshModel::from_surface(surface), &params.output)
        })?;
        wp.set(0.5);
        let vtu = write_file(out_dir, Some(&syncer), "mesh.vtu", |w| write_surface_vtu(w, surface))?;
        Ok(vec![msh, vtu])
    })?;
    let mut input_preview = Previews::default();
    input_preview.draw(&params.output, out_dir, &syncer, "preview.png", |size| {
        // Edges are only extracted when repair found a boundary or a non-manifold edge.
        let defects = if repair.n_boundary_loops + repair.n_nonmanifold_edges > 0 {
            crate::preview::defect_edges(surface)
        } else {
            Vec::new()
        };
        crate::preview::input_preview(surface, &defects, size)
    });
    input_preview.write(&params.output, out_dir, &syncer, "surface.glb", |w| {
        let (positions, triangles, face_colors) = match &products.patch_colors {
            Some((mesh, colors)) => (&mesh.positions, &mesh.triangles, Some(&colors[..])),
            None => (&surface.positions, &surface.triangles, None),
        };
        let scene = GlbScene { positions, triangles, face_colors, points: &products.singular_points };
        write_glb(w, &scene)
    });
    // Steps `preview` (the image) and `glb`, each when written or tried.
    for (step, o) in ["preview", "glb"].iter().zip(&input_preview.outcomes) {
        timings.push(StepTiming { step: step.to_string(), seconds: o.seconds });
    }
    let mut written = written;
    for file in &input_preview.artifacts {
        written.push(artifact_info(out_dir, file)?);
    }
    previews.splice(0..0, input_preview.outcomes);
    // Every artifact on disk before the report says the job succeeded.
    timed(&mut timings, "sync", || syncer.finish())
        .map_err(|(path, e)| PipelineError::Write { path, source: e.into() })?;
    let mut all = written;
    all.extend(artifacts);
    let report = PipelineReport {
        version: env!("CARGO_PKG_VERSION"),
        input: input_info,
        repair,
        stages: reports,
        stages_added,
        timings,
        artifacts: all,
        previews,
        total_seconds: start.elapsed().as_secs_f64(),
    };
    write_file(out_dir, None, REPORT_NAME, |w| {
        let mut text = serde_json::to_vec_pretty(&report).map_err(std::io::Error::other)?;
        text.push(b'\n');
        Ok(w.write_all(&text)?)
    })?;
    wp.set(1.0);
    Ok(report)
}
