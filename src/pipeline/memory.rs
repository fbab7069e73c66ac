//! Peak-memory estimate of a pipeline run from the input's sizes and the
//! parameters, used by the job service to admit jobs against a memory
//! budget before they run.
//!
//! Model: stages run one after the other and free their working memory
//! when they end, so the peak is a fixed base plus the largest stage peak,
//! each stage peak linear in its size (triangles for load, atlas and
//! crossfield; tetrahedra plus the resident surface for frames). The
//! coefficients are the measured peaks per element rounded up; the
//! measurements are the benchmark table of `README.md` (section
//! Benchmarks, produced by `benches/pipeline.rs` and `benches/frames.rs`)
//! and the solver choice documented on
//! [`crate::frames::FramesOptions::direct_solver_max_vertices`]. An
//! estimate errs high: a refused job names its numbers so the client can
//! lower its sizes.

use serde::Serialize;

use super::params::{PipelineParams, StageName};
use crate::frames::mbo::LinearSolverKind;
use crate::io::InputSizes;

/// Resident memory of the service around one job (runtime, buffers, the
/// pipeline's 1 MiB read buffer). README: the whole process peaked at
/// 16 MiB on the 10k-triangle atlas row.
pub const BASE_BYTES: u64 = 16 << 20;
/// Load and repair, per triangle: bounded by the atlas row, which includes
/// them (README: atlas on the 1M-triangle sphere peaked at 560 MiB).
pub const LOAD_BYTES_PER_TRIANGLE: u64 = 800;
/// Atlas, per triangle (README: 560 MiB at 1M triangles, i.e. about
/// 590 bytes, rounded up).
pub const ATLAS_BYTES_PER_TRIANGLE: u64 = 800;
/// Crossfield, per triangle (README: 3.7 GB on the 1M-triangle sphere and
/// torus, 3.4 GB on the disk, rounded up).
pub const CROSSFIELD_BYTES_PER_TRIANGLE: u64 = 4096;
/// Frames with the iterative solver, per tetrahedron, lattice and mesher
/// included (README: 367 MiB for the 1M-tetrahedron ball, rounded up).
pub const FRAMES_BYTES_PER_TET: u64 = 400;
/// Frames with the sparse Cholesky solver, per tetrahedron (the
/// `direct_solver_max_vertices` documentation: 237 MB at 19k vertices, about
/// 110k tetrahedra, rounded up).
pub const FRAMES_CHOLESKY_BYTES_PER_TET: u64 = 2560;
/// Tetrahedra per vertex of a stuffed mesh (a BCC lattice has 6), to bound
/// the tets solved by Cholesky under the default solver choice.
const TETS_PER_VERTEX: u64 = 6;

/// The estimate, per step, in bytes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct MemoryEstimate {
    /// [`BASE_BYTES`].
    pub base: u64,
    /// Load and repair.
    pub load: u64,
    /// Atlas stage (0 when not run).
    pub atlas: u64,
    /// Crossfield stage (0 when not run).
    pub crossfield: u64,
    /// Frames stage (0 when not run).
    pub frames: u64,
    /// `base` plus the largest of the others.
    pub peak: u64,
}

/// The peak memory of running `params` on an input of `sizes`, with the
/// parameters' own caps applied (`load.max_triangles`, `frames.max_tets`;
/// the caller applies the server's caps to `params` first). An uploaded
/// volume is bounded by its element count; a generated one by the limit
/// the frames stage holds the mesh it makes to
/// ([`crate::frames::volume::enclosed_volume_mesh`]): `max_tets` for an
/// explicit `target_size` (admission does not know the enclosed volume, so
/// the size alone bounds nothing), `min(default_max_tets, max_tets)` for
/// the default sizes.
pub fn peak_memory_estimate(sizes: &InputSizes, params: &PipelineParams) -> MemoryEstimate {
    let triangles = sizes.n_triangles.min(params.load.max_triangles as u64);
    let stages = params.stages_to_run().0;
    let runs = |s: StageName| stages.contains(&s);
    let per = |n: u64, bytes: u64| n.saturating_mul(bytes);
    let load = per(triangles, LOAD_BYTES_PER_TRIANGLE);
    let atlas = if runs(StageName::Atlas) { per(triangles, ATLAS_BYTES_PER_TRIANGLE) } else { 0 };
    let crossfield = if runs(StageName::Crossfield) { per(triangles, CROSSFIELD_BYTES_PER_TRIANGLE) } else { 0 };
    let frames = if runs(StageName::Frames) {
        let tets = sizes.n_tets.max(generated_tets_bound(&params.frames));
        let direct_tets = match params.frames.linear_solver {
            Some(LinearSolverKind::Cholesky) => tets,
            Some(LinearSolverKind::Pcg) => 0,
            None => tets.min((params.frames.direct_solver_max_vertices as u64).saturating_mul(TETS_PER_VERTEX)),
        };
        per(tets, FRAMES_BYTES_PER_TET).max(per(direct_tets, FRAMES_CHOLESKY_BYTES_PER_TET)).saturating_add(load)
    } else {
        0
    };
    let peak = BASE_BYTES.saturating_add(load.max(atlas).max(crossfield).max(frames));
    MemoryEstimate { base: BASE_BYTES, load, atlas, crossfield, frames, peak }
}

/// Most tetrahedra the frames stage generates with `opts` (see
/// [`peak_memory_estimate`]).
pub fn generated_tets_bound(opts: &crate::frames::FramesOptions) -> u64 {
    match opts.target_size {
        Some(_) => opts.max_tets as u64,
        None => opts.default_max_tets.min(opts.max_tets) as u64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::parse_params;

    fn est(tris: u64, json: &str) -> MemoryEstimate {
        peak_memory_estimate(&InputSizes { n_triangles: tris, n_tets: 0 }, &parse_params(json.as_bytes()).unwrap())
    }

    #[test]
    fn the_estimate_follows_the_benchmark_figures() {
        // Crossfield on 1M triangles: the measured 3.7 GB, not less.
        let e = est(1_000_000, r#"{"stages":["crossfield"]}"#);
        assert!(e.peak >= 3_700_000_000 && e.peak < 5_000_000_000, "{e:?}");
        // Atlas on 1M triangles: at least the measured 560 MiB.
        let e = est(1_000_000, r#"{"stages":["atlas"]}"#);
        assert!(e.peak >= 560 << 20 && e.peak < 1 << 30, "{e:?}");
        // Frames bounded by max_tets whatever the surface for an explicit
        // size, by the default budget (400k tets) for the default sizes.
        let small = est(100, r#"{"stages":["frames"],"frames":{"max_tets":1000000,"target_size":0.1}}"#);
        assert!(small.peak >= 367 << 20, "{small:?}");
        let default = est(100, r#"{"stages":["frames"]}"#);
        assert_eq!(default.frames, 400_000 * FRAMES_BYTES_PER_TET + 100 * LOAD_BYTES_PER_TRIANGLE, "{default:?}");
        let budget = est(100, r#"{"stages":["frames"],"frames":{"default_max_tets":1000000}}"#);
        assert!(budget.peak >= 367 << 20, "{budget:?}");
        let capped = est(100, r#"{"stages":["frames"],"frames":{"max_tets":1000}}"#);
        assert!(capped.peak < 32 << 20, "{capped:?}");
        // Quads run the crossfield first: at least its peak.
        let quads = est(1_000_000, r#"{"stages":["quads"]}"#);
        assert!(quads.peak >= est(1_000_000, r#"{"stages":["crossfield"]}"#).peak, "{quads:?}");
        // The largest stage, not the sum; the triangle cap applies.
        let both = est(1_000_000, r#"{"stages":["atlas","crossfield"]}"#);
        assert_eq!(both.peak, est(1_000_000, r#"{"stages":["crossfield"]}"#).peak);
        let capped = est(u64::MAX, r#"{"stages":["crossfield"],"load":{"max_triangles":1000}}"#);
        assert_eq!(capped.crossfield, 1000 * CROSSFIELD_BYTES_PER_TRIANGLE);
    }
}
