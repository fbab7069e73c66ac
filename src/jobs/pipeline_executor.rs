//! The executor the service runs: [`crate::pipeline::run_pipeline`] on the
//! job's upload, with the server's triangle and tetrahedron caps applied on top of the
//! job's.

use crate::failure::FailureKind;
use crate::io::Format;
use crate::pipeline::{PipelineError, PipelineParams, run_pipeline};
use crate::progress::Progress;

use super::executor::{ExecError, Executor, JobInput, JobOutcome};
use super::model::{Artifact, JobError};

/// Runs the meshatlas pipeline for a job.
#[derive(Debug, Clone, Copy, Default)]
pub struct PipelineExecutor;

impl Executor for PipelineExecutor {
    fn execute(&self, job: &JobInput, progress: &Progress) -> Result<JobOutcome, ExecError> {
        let mut params: PipelineParams = serde_json::from_value(job.params.clone()).map_err(|e| {
            ExecError::Failed(JobError::new(FailureKind::InternalError, format!("stored parameters do not parse: {e}")))
        })?;
        params.load.max_triangles = params.load.max_triangles.min(job.max_triangles);
        params.frames.max_tets = params.frames.max_tets.min(job.max_tets);
        let format = match job.format.as_deref() {
            Some(name) => Some(Format::from_name(name).ok_or_else(|| {
                ExecError::Failed(JobError::new(FailureKind::UnknownFormat, format!("unknown input format `{name}`")))
            })?),
            None => None,
        };
        match run_pipeline(&job.input, format, &params, &job.out_dir, progress) {
            Ok(report) => {
                let summary = serde_json::to_value(&report).map_err(|e| {
                    ExecError::Failed(JobError::new(
                        FailureKind::InternalError,
                        format!("report does not serialize: {e}"),
                    ))
                })?;
                let mut artifacts: Vec<Artifact> = report
                    .artifacts
                    .iter()
                    .map(|a| Artifact { name: a.name.clone(), bytes: a.bytes, media_type: a.media_type.clone() })
                    .collect();
                artifacts.push(Artifact {
                    name: crate::pipeline::REPORT_NAME.to_string(),
                    bytes: 0,
                    media_type: "application/json".to_string(),
                });
                Ok(JobOutcome { summary, stage_seconds: report.seconds_by_step(), artifacts })
            }
            Err(PipelineError::Cancelled) => Err(ExecError::Cancelled),
            Err(e) => Err(ExecError::Failed(JobError::new(e.kind(), e.to_string()))),
        }
    }
}
