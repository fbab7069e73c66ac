//! The pipeline report: what was read, what repair did, what each stage
//! produced, how long each step took, and which files were written. It is
//! written as `report.json` and shown as the job summary.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::mesh::repair::RepairReport;

/// What was read.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InputInfo {
    /// File name of the input (no directories).
    pub name: String,
    /// Format read (`stl`, `obj`, `ply`, `msh`).
    pub format: &'static str,
    /// File size in bytes.
    pub bytes: u64,
    /// Vertices of the repaired surface.
    pub n_vertices: usize,
    /// Triangles of the repaired surface.
    pub n_triangles: usize,
    /// Tetrahedra, when the input carried a volume mesh.
    pub n_tets: Option<usize>,
}

/// Wall time of one pipeline step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepTiming {
    /// Step name: `load`, a stage name, or `write`.
    pub step: String,
    /// Wall seconds.
    pub seconds: f64,
}

/// A file written into the output directory.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ArtifactInfo {
    /// File name.
    pub name: String,
    /// Size in bytes.
    pub bytes: u64,
    /// Media type.
    pub media_type: String,
}

/// Everything a pipeline run reports.
#[derive(Debug, Clone, Serialize)]
pub struct PipelineReport {
    /// meshatlas version that produced the report.
    pub version: &'static str,
    /// What was read.
    pub input: InputInfo,
    /// What load-time repair did (welds, removed and flipped triangles, …).
    pub repair: RepairReport,
    /// Summary of each stage run, by stage name.
    pub stages: BTreeMap<String, serde_json::Value>,
    /// Wall seconds per step, in the order run.
    pub timings: Vec<StepTiming>,
    /// Files written (besides `report.json` itself).
    pub artifacts: Vec<ArtifactInfo>,
    /// Wall seconds of the whole run.
    pub total_seconds: f64,
}

impl PipelineReport {
    /// Per-step seconds by name (what the job service stores).
    pub fn seconds_by_step(&self) -> BTreeMap<String, f64> {
        self.timings.iter().map(|t| (t.step.clone(), t.seconds)).collect()
    }
}
