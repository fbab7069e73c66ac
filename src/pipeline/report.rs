//! The pipeline report: what was read, what repair did, what each stage
//! produced, how long each step took, and which files were written. It is
//! written as `report.json` and shown as the job summary.
//!
//! Every part is a typed struct, serialized once (into `report.json`, the
//! CLI's `--json` and the job summary); the CLI's text summary
//! ([`PipelineReport::summary_lines`]) reads the same types.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::atlas::AtlasReport;
use crate::crossfield::CrossfieldReport;
use crate::frames::FramesReport;
use crate::mesh::repair::RepairReport;
use crate::quads::QuadsReport;

use super::params::StageName;

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

/// One preview image: drawn and written, or why not (a failed preview
/// never fails the job).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PreviewOutcome {
    /// Artifact name (`preview.png`, `atlas.png`, …).
    pub name: String,
    /// Wall seconds to draw, encode and write it.
    pub seconds: f64,
    /// Why it was not written, when it was not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
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
    pub stages: StageReports,
    /// Stages that ran without being requested because a requested stage
    /// needs them (`quads` adds `atlas` and `crossfield`), in pipeline order.
    pub stages_added: Vec<StageName>,
    /// Wall seconds per step, in the order run.
    pub timings: Vec<StepTiming>,
    /// Files written (besides `report.json` itself).
    pub artifacts: Vec<ArtifactInfo>,
    /// The preview images, in the order drawn (empty with `output.previews`
    /// off).
    pub previews: Vec<PreviewOutcome>,
    /// Wall seconds of the whole run.
    pub total_seconds: f64,
}

/// The report of one stage, as the stage returns it.
#[derive(Debug, Clone)]
pub enum StageReport {
    /// The atlas stage.
    Atlas(Box<AtlasReport>),
    /// The crossfield stage.
    Crossfield(Box<CrossfieldReport>),
    /// The frames stage.
    Frames(Box<FramesReport>),
    /// The quads stage.
    Quads(Box<QuadsReport>),
}

/// The reports of the stages that ran, serialized as an object keyed by
/// stage name (`atlas`, `crossfield`, `frames`, `quads`; absent when the stage did
/// not run), in pipeline order.
#[derive(Debug, Clone, Default, Serialize)]
pub struct StageReports {
    /// The atlas stage's report.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub atlas: Option<AtlasReport>,
    /// The crossfield stage's report.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crossfield: Option<CrossfieldReport>,
    /// The frames stage's report.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frames: Option<FramesReport>,
    /// The quads stage's report.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quads: Option<QuadsReport>,
}

impl StageReports {
    /// Stores `report` in its stage's slot (replacing an earlier one).
    pub fn insert(&mut self, report: StageReport) {
        match report {
            StageReport::Atlas(r) => self.atlas = Some(*r),
            StageReport::Crossfield(r) => self.crossfield = Some(*r),
            StageReport::Frames(r) => self.frames = Some(*r),
            StageReport::Quads(r) => self.quads = Some(*r),
        }
    }

    /// True when no stage ran.
    pub fn is_empty(&self) -> bool {
        self.atlas.is_none() && self.crossfield.is_none() && self.frames.is_none() && self.quads.is_none()
    }
}

impl PipelineReport {
    /// Per-step seconds by name (what the job service stores).
    pub fn seconds_by_step(&self) -> BTreeMap<String, f64> {
        self.timings.iter().map(|t| (t.step.clone(), t.seconds)).collect()
    }

    /// The text summary the CLI prints: input, surface, volume (if any),
    /// repair, topology and one line per stage that ran, each starting with
    /// a left-aligned label of 10 columns.
    pub fn summary_lines(&self) -> Vec<String> {
        let i = &self.input;
        let mut lines = vec![
            format!("input      {} ({}, {} bytes)", i.name, i.format, i.bytes),
            format!("surface    {} vertices, {} triangles", i.n_vertices, i.n_triangles),
        ];
        if let Some(n) = i.n_tets {
            lines.push(format!("volume     {n} tetrahedra"));
        }
        lines.push(repair_line(&self.repair));
        lines.push(topology_line(&self.repair));
        let s = &self.stages;
        lines.extend(s.atlas.as_ref().map(atlas_line));
        lines.extend(s.crossfield.as_ref().map(crossfield_line));
        lines.extend(s.frames.as_ref().map(frames_line));
        lines.extend(s.quads.as_ref().map(quads_line));
        if !self.stages_added.is_empty() {
            let added: Vec<&str> = self.stages_added.iter().map(|s| s.as_str()).collect();
            lines.push(format!("added      {} (needed by the requested stages)", added.join(", ")));
        }
        lines
    }
}

/// What repair changed: welded vertices, triangles removed (by any rule) or
/// flipped, unreferenced vertices dropped.
fn repair_line(r: &RepairReport) -> String {
    let welded = r.n_vertices_welded_exact + r.n_vertices_welded_tolerance;
    let removed = r.n_triangles_removed_by_collapse
        + r.n_zero_area_triangles_removed
        + r.n_degenerate_triangles_removed
        + r.n_duplicate_triangles_removed;
    format!(
        "repair     welded {welded} vertices, removed {removed} triangles, flipped {} (and {} cap edges), \
         dropped {} unreferenced vertices",
        r.n_triangles_flipped,
        r.n_zero_area_edges_flipped + r.n_folded_caps_flipped,
        r.n_unreferenced_vertices_dropped,
    )
}

/// The repaired surface's topology: components, boundary loops, χ, genus
/// (`-` when some component is not a manifold), non-manifold elements.
fn topology_line(r: &RepairReport) -> String {
    let genus = r.genus.map_or_else(|| "-".to_string(), |g| g.to_string());
    format!(
        "topology   {} components, {} boundary loops, χ = {}, genus {genus}, {} non-manifold edges, \
         {} non-manifold vertices",
        r.n_components, r.n_boundary_loops, r.euler_characteristic, r.n_nonmanifold_edges, r.n_nonmanifold_vertices,
    )
}

/// Patches, curves and corners of the atlas, and its worst map quality.
fn atlas_line(a: &AtlasReport) -> String {
    format!(
        "atlas      {} patches ({} model faces), {} curves, {} corners, {} triangles, σ2/σ1 min {:.3} median {:.3}",
        a.n_patches, a.n_model_faces, a.n_curves, a.n_corners, a.n_triangles, a.sigma_ratio_min, a.sigma_ratio_median,
    )
}

/// Singularities (their index sum equals χ on a manifold), energy and
/// convergence of the crossfield.
fn crossfield_line(c: &CrossfieldReport) -> String {
    format!(
        "crossfield {} singularities, index sum {} (χ = {}), energy {:.6e}, {} Newton iterations, {}",
        c.n_singularities,
        c.index_sum,
        c.euler_characteristic,
        c.energy,
        c.iterations,
        if c.converged { "converged" } else { "not converged" },
    )
}

/// Size of the volume mesh, energy decrease and singular edges of the frames.
fn frames_line(f: &FramesReport) -> String {
    let s = &f.singular;
    format!(
        "frames     {} tetrahedra, {} vertices, energy {:.6e} -> {:.6e}, singular edges: {} valence 3, \
         {} valence 5, {} other, in {} curves",
        f.tets, f.vertices, f.energy_before, f.energy_after, s.n_valence3, s.n_valence5, s.n_complex, s.n_curves,
    )
}

/// Quads, irregular vertices against the singularities, worst shape.
fn quads_line(q: &QuadsReport) -> String {
    format!(
        "quads      {} quads (order {}), {} triangles, {} vertices, {} irregular ({} singularities, excess {}), \
         scaled Jacobian min {:.3} p5 {:.3}, {} inverted",
        q.n_quads,
        q.order,
        q.n_triangles,
        q.n_vertices,
        q.n_irregular_vertices,
        q.n_singularities,
        q.irregular_excess,
        q.scaled_jacobian_min,
        q.scaled_jacobian_p5,
        q.n_inverted,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(repair: RepairReport, stages: StageReports) -> PipelineReport {
        PipelineReport {
            version: "0",
            input: InputInfo {
                name: "a.stl".into(),
                format: "stl",
                bytes: 84,
                n_vertices: 4,
                n_triangles: 4,
                n_tets: None,
            },
            repair,
            stages,
            stages_added: vec![],
            timings: vec![],
            artifacts: vec![],
            previews: vec![],
            total_seconds: 0.0,
        }
    }

    #[test]
    fn stage_reports_serialize_as_an_object_keyed_by_the_stages_that_ran() {
        let mut stages = StageReports::default();
        assert!(stages.is_empty());
        stages.insert(StageReport::Frames(Box::new(FramesReport { tets: 7, ..FramesReport::default() })));
        stages.insert(StageReport::Atlas(Box::new(AtlasReport { n_patches: 3, ..AtlasReport::default() })));
        let v = serde_json::to_value(&stages).unwrap();
        // The shape stored jobs and clients know: `{name: report}` for the stages run.
        let mut expected = serde_json::Map::new();
        expected
            .insert("atlas".into(), serde_json::to_value(AtlasReport { n_patches: 3, ..Default::default() }).unwrap());
        expected.insert("frames".into(), serde_json::to_value(FramesReport { tets: 7, ..Default::default() }).unwrap());
        assert_eq!(v, serde_json::Value::Object(expected));
        assert_eq!(v["atlas"]["n_patches"], 3);
        assert_eq!(v["frames"]["tets"], 7);
    }

    #[test]
    fn text_summary_counts_every_kind_of_removed_triangle() {
        let repair = RepairReport {
            n_vertices_welded_exact: 3,
            n_vertices_welded_tolerance: 2,
            n_triangles_removed_by_collapse: 2,
            n_zero_area_triangles_removed: 1,
            n_degenerate_triangles_removed: 1,
            n_duplicate_triangles_removed: 4,
            n_triangles_flipped: 6,
            n_components: 2,
            euler_characteristic: -2,
            genus: None,
            ..RepairReport::default()
        };
        let mut stages = StageReports::default();
        stages.insert(StageReport::Crossfield(Box::new(CrossfieldReport {
            n_singularities: 8,
            index_sum: 2.0,
            euler_characteristic: 2,
            converged: true,
            ..CrossfieldReport::default()
        })));
        let lines = report(repair, stages).summary_lines();
        let repair_line = lines.iter().find(|l| l.starts_with("repair ")).unwrap();
        assert!(repair_line.contains("welded 5 vertices, removed 8 triangles, flipped 6"), "{repair_line}");
        let topology = lines.iter().find(|l| l.starts_with("topology ")).unwrap();
        assert!(topology.contains("2 components") && topology.contains("χ = -2, genus -"), "{topology}");
        let cf = lines.iter().find(|l| l.starts_with("crossfield ")).unwrap();
        assert!(cf.contains("8 singularities, index sum 2 (χ = 2)") && cf.ends_with(", converged"), "{cf}");
        assert!(!lines.iter().any(|l| l.starts_with("atlas ") || l.starts_with("frames ")), "{lines:?}");
        assert!(!lines.iter().any(|l| l.starts_with("quads ") || l.starts_with("added ")), "{lines:?}");
    }

    #[test]
    fn quads_get_a_summary_line_and_added_stages_are_named() {
        let mut stages = StageReports::default();
        let q = QuadsReport {
            n_quads: 96,
            order: 1,
            n_vertices: 98,
            n_irregular_vertices: 8,
            n_singularities: 8,
            ..Default::default()
        };
        stages.insert(StageReport::Quads(Box::new(q)));
        let mut r = report(RepairReport::default(), stages);
        r.stages_added = vec![StageName::Atlas, StageName::Crossfield];
        let lines = r.summary_lines();
        let quads = lines.iter().find(|l| l.starts_with("quads ")).unwrap();
        assert!(
            quads.contains("96 quads (order 1), 0 triangles, 98 vertices, 8 irregular (8 singularities, excess 0)"),
            "{quads}"
        );
        assert!(
            lines.iter().any(|l| l == "added      atlas, crossfield (needed by the requested stages)"),
            "{lines:?}"
        );
        let v = serde_json::to_value(&r).unwrap();
        assert_eq!(v["stages_added"], serde_json::json!(["atlas", "crossfield"]));
        assert_eq!(v["stages"]["quads"]["n_quads"], 96);
    }
}
