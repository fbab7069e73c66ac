//! Sequences load, repair and the selected stages, writes the artifacts and
//! the report, and reports progress.
//!
//! [`run_pipeline`] is the one entry point, shared by the job service and the
//! CLI: `load` (read the file) → `repair` (weld and repair, with a
//! [`crate::mesh::repair::RepairReport`]) → the selected stages in pipeline
//! order → `write` (`mesh.msh` MSH 4.1, `mesh.vtu`) → `report.json`. Every
//! step is timed and reported through the [`crate::progress::Progress`]
//! handle, which is checked for cancellation between steps.
//!
//! This module knows nothing of jobs, HTTP or async runtimes.

pub mod durable;
pub mod error;
pub mod memory;
pub mod params;
pub mod previews;
pub mod report;
pub mod run;
pub mod stages;

pub use error::PipelineError;
pub use memory::{MemoryEstimate, peak_memory_estimate};
pub use params::{ParamsError, PipelineParams, StageName, parse_params};
pub use report::{ArtifactInfo, InputInfo, PipelineReport, PreviewOutcome, StageReport, StageReports, StepTiming};
pub use run::{Products, REPORT_NAME, StageOutput, run_pipeline};

/// Media type of an artifact by file extension (`.json`, `.msh`, `.vtu`,
/// `.stl`, `.png`, `.glb`; anything else is `application/octet-stream`).
pub fn media_type_for(name: &str) -> &'static str {
    match std::path::Path::new(name).extension().and_then(|e| e.to_str()) {
        Some("json") => "application/json",
        Some("msh") => "application/x-gmsh",
        Some("vtu") => "application/vnd.vtk.vtu+xml",
        Some("stl") => "model/stl",
        Some("png") => "image/png",
        Some("glb") => "model/gltf-binary",
        _ => "application/octet-stream",
    }
}

#[cfg(test)]
mod tests;
