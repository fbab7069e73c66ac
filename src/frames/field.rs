//! The frames stage: from a closed surface (or an uploaded tetrahedral
//! mesh) to a smooth octahedral frame field on the enclosed volume, its
//! SU(2) invariants and its singular edges.
//!
//! Steps (each timed in the report):
//! 1. **Volume** ([`super::volume`]): the uploaded tetrahedral mesh as is,
//!    or isosurface stuffing of the closed surface at `target_size`.
//! 2. **Boundary constraints**: every boundary vertex of the tetrahedral
//!    mesh gets a frame axis along the surface normal (the normal of the
//!    input triangle it lies on for stuffed meshes; the area-weighted normal
//!    of its boundary faces for uploaded ones). On an uploaded mesh, a
//!    vertex whose boundary face normals spread more than
//!    `feature_angle_deg` from their mean (a sharp edge or corner) gets the
//!    frame fixed to the one best aligned with all of them.
//! 3. **Field** ([`super::mbo`]): the MBO scheme of Palmer et al. 2020 on
//!    the degree-4 spherical-harmonic 9-vectors, minimizing the P1 Dirichlet
//!    energy under the constraints: boundary frames start as the
//!    normal-aligned frames closest to the single frame that best fits all
//!    boundary normals (the projection of `Σ Y4(n_v)`), the interior starts
//!    as their harmonic extension, then diffuse–project steps with a
//!    shrinking time step. Diffusions use sparse Cholesky on small meshes
//!    and Jacobi-preconditioned CG above `direct_solver_max_vertices`.
//! 4. **Outputs**: per vertex the rotation as a quaternion, its three axes,
//!    its 9-vector and its octahedral invariants `(h0, h1, h2)` (4.23) with
//!    the model-surface residual; singular edges ([`super::singular`]).
//!
//! The thesis's own schemes (§4.4: smoothing `h` in `C³`) are not used,
//! because the Euclidean metric of `C³` is not a distance between frames
//! (§4.1); the SU(2) invariants are outputs and a diagnostic here.

use super::error::FramesError;
use super::invariants::{frame_invariants, model_surface_relative_residual};
use super::mbo::{EnergyRecord, LinearSolverKind, MboParams, MboResult, VertexConstraint, smooth_octahedral_field};
use super::quaternion::{Mat3, Quat};
use super::sh4::{nearest_frame, sh4_basis, sh9_from_rotation};
use super::singular::{SingularEdge, SingularReport, singular_edges, tet_frames};
use super::sizing::SizingParams;
use super::stuffing::NO_TRIANGLE;
use super::su2::C64;
use super::volume::{
    VolumeReport, WarpThresholds, boundary_vertex_normals, boundary_vertices_of_faces, check_closed,
    dihedral_angle_range, enclosed_volume_mesh, tet_boundary_faces,
};
use crate::fem::tet_p1::tet_p1_operators;
use crate::geom::Vec3;
use crate::mesh::{FaceId, TetMesh, TriMesh};
use crate::progress::Progress;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Options of the frames stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FramesOptions {
    /// Lattice spacing of the generated volume mesh, model units (interior
    /// edges are `h` and `0.87 h` long), the same for every part of the
    /// surface. Default `None`: per part (connected closed surface, see
    /// [`super::parts`]) the finer of the size its thickness needs for
    /// `volume_tolerance` and its mean edge length, within
    /// `default_max_tets` ([`super::sizing`]). Ignored for an uploaded
    /// tetrahedral mesh.
    pub target_size: Option<f64>,
    /// Largest number of tetrahedra for a generated volume, whatever the
    /// size (the estimate `12 V / h³ + 4 A / h²` and the mesh made; also
    /// bounds the lattices over the parts' boxes to 4 cells per tet, i.e.
    /// the mesher's memory). Default 2 000 000.
    pub max_tets: usize,
    /// Tet budget of the default sizes (`target_size` null), shared by the
    /// parts; `max_tets` caps it. Default 400 000 (about 13 s for the
    /// stage, see `docs/decisions.md`).
    pub default_max_tets: usize,
    /// Relative volume error each part's default size aims at
    /// (dimensionless); parts beyond it are counted and named in the
    /// report. Default 0.01.
    pub volume_tolerance: f64,
    /// Isosurface-stuffing warp threshold on long lattice edges, fraction of
    /// the edge length. Default 0.24999 (Labelle & Shewchuk).
    pub alpha_long: f64,
    /// Warp threshold on short lattice edges, fraction of the edge length.
    /// Default 0.41189 (Labelle & Shewchuk).
    pub alpha_short: f64,
    /// On uploaded volumes, a boundary vertex whose face normals spread more
    /// than this from their mean is a feature vertex with a fixed frame,
    /// degrees. Default 40.
    pub feature_angle_deg: f64,
    /// First MBO time step, as a multiple of the squared mean edge length of
    /// the tetrahedral mesh (dimensionless; of the squared bounding-box
    /// diagonal when `harmonic_start` is false). Default 16 (diffusion length
    /// about 4 edges).
    pub tau_initial: f64,
    /// Last MBO time step as a multiple of the squared mean edge length of
    /// the tetrahedral mesh (dimensionless). Default 1.
    pub tau_final: f64,
    /// Factor applied to the time step between levels, in (0, 1).
    /// Default 0.25.
    pub tau_shrink: f64,
    /// Largest number of diffuse–project steps at one time step. Default 20.
    pub max_steps_per_level: usize,
    /// A level stops when no vertex 9-vector changes by more than this in a
    /// step (9-vectors have unit norm). Default 1e-3.
    pub step_tolerance: f64,
    /// A level also stops when a step lowers the Dirichlet energy by less
    /// than this fraction (dimensionless). Default 1e-3.
    pub energy_tolerance: f64,
    /// A warm-started projection aligned within this relative gap of the
    /// target's norm skips the global search (dimensionless). Default 0.3
    /// (measured: 0.02 gave the same field at 4× the projection time).
    pub projection_accept: f64,
    /// Start the smoothing from the harmonic extension of the boundary frames
    /// (Dirichlet problem, projected onto the variety). Default true.
    pub harmonic_start: bool,
    /// Hold the boundary frames fixed during each diffusion and update them
    /// by their local energy minimizer afterwards (strong anchoring), rather
    /// than diffusing them with natural boundary conditions. Default true.
    pub dirichlet_diffusion: bool,
    /// Linear solver of the diffusions: `"cholesky"` (sparse direct, one
    /// factorization per time step), `"pcg"` (Jacobi-preconditioned
    /// conjugate gradients), or `null` (default) for Cholesky up to
    /// `direct_solver_max_vertices` vertices and PCG above. Measured on the
    /// ball at 1M tets (179k vertices): one Cholesky numeric factorization
    /// 12.7 s with a METIS nested-dissection ordering (132M nonzeros in L;
    /// AMD is slower), one PCG solve of the 9 components 0.7–2.2 s depending
    /// on the time step; the stage needs 4 matrices.
    pub linear_solver: Option<LinearSolverKind>,
    /// Largest vertex count for which the default solver is Cholesky.
    /// Default 5 000 (measured on balls: PCG was faster from 6k vertices on,
    /// 0.68 s against 0.86 s for the whole stage at 6k, 2.6 s against 4.6 s
    /// and 43 MB against 237 MB peak at 19k, same field).
    pub direct_solver_max_vertices: usize,
    /// Relative residual at which PCG stops (dimensionless). Default 1e-5.
    pub pcg_tolerance: f64,
    /// Largest angle between a quarter-turn holonomy axis and its edge for a
    /// valence-3/5 singular edge, degrees (the sign of the turn about the
    /// edge gives the valence). Default 75: singular curves crossing the
    /// lattice obliquely are carried by edges up to 55° off their tangent.
    pub singular_axis_tolerance_deg: f64,
}

impl Default for FramesOptions {
    fn default() -> Self {
        Self {
            target_size: None,
            max_tets: 2_000_000,
            default_max_tets: 400_000,
            volume_tolerance: 0.01,
            alpha_long: 0.24999,
            alpha_short: 0.41189,
            feature_angle_deg: 40.0,
            tau_initial: 16.0,
            tau_final: 1.0,
            tau_shrink: 0.25,
            max_steps_per_level: 20,
            step_tolerance: 1e-3,
            energy_tolerance: 1e-3,
            projection_accept: 0.3,
            harmonic_start: true,
            dirichlet_diffusion: true,
            linear_solver: None,
            direct_solver_max_vertices: 5_000,
            pcg_tolerance: 1e-5,
            singular_axis_tolerance_deg: 75.0,
        }
    }
}

impl FramesOptions {
    /// Check every option's domain.
    ///
    /// # Errors
    /// [`FramesError::InvalidOption`] naming the first bad option.
    pub fn validate(&self) -> Result<(), FramesError> {
        let bad = |name: &'static str, reason: String| Err(FramesError::InvalidOption { name, reason });
        if let Some(h) = self.target_size
            && !(h > 0.0 && h.is_finite())
        {
            return bad("target_size", format!("must be a positive length, got {h}"));
        }
        if self.max_tets == 0 {
            return bad("max_tets", "must be positive".into());
        }
        if self.default_max_tets == 0 {
            return bad("default_max_tets", "must be positive".into());
        }
        if !(self.volume_tolerance > 0.0 && self.volume_tolerance < 1.0) {
            return bad("volume_tolerance", format!("must be in (0, 1), got {}", self.volume_tolerance));
        }
        for (name, v) in [("alpha_long", self.alpha_long), ("alpha_short", self.alpha_short)] {
            if !(0.0..0.5).contains(&v) {
                return bad(name, format!("must be in [0, 0.5), got {v}"));
            }
        }
        if !(self.feature_angle_deg > 0.0 && self.feature_angle_deg <= 180.0) {
            return bad("feature_angle_deg", format!("must be in (0, 180], got {}", self.feature_angle_deg));
        }
        for (name, v) in [("tau_initial", self.tau_initial), ("tau_final", self.tau_final)] {
            if !(v > 0.0 && v.is_finite()) {
                return bad(name, format!("must be positive, got {v}"));
            }
        }
        if !(self.tau_shrink > 0.0 && self.tau_shrink < 1.0) {
            return bad("tau_shrink", format!("must be in (0, 1), got {}", self.tau_shrink));
        }
        if self.max_steps_per_level == 0 {
            return bad("max_steps_per_level", "must be positive".into());
        }
        if !(self.step_tolerance > 0.0) {
            return bad("step_tolerance", format!("must be positive, got {}", self.step_tolerance));
        }
        if !(0.0..1.0).contains(&self.energy_tolerance) {
            return bad("energy_tolerance", format!("must be in [0, 1), got {}", self.energy_tolerance));
        }
        if !(0.0..1.0).contains(&self.projection_accept) {
            return bad("projection_accept", format!("must be in [0, 1), got {}", self.projection_accept));
        }
        if !(self.pcg_tolerance > 0.0 && self.pcg_tolerance < 1.0) {
            return bad("pcg_tolerance", format!("must be in (0, 1), got {}", self.pcg_tolerance));
        }
        if !(self.singular_axis_tolerance_deg > 0.0 && self.singular_axis_tolerance_deg < 90.0) {
            return bad(
                "singular_axis_tolerance_deg",
                format!("must be in (0, 90), got {}", self.singular_axis_tolerance_deg),
            );
        }
        Ok(())
    }
}

/// Wall time of each step, seconds.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FramesTimings {
    /// Volume mesh (stuffing or validation of the upload).
    pub volume: f64,
    /// Boundary constraints and initial frame.
    pub constraints: f64,
    /// P1 operators.
    pub operators: f64,
    /// MBO iteration (total).
    pub field: f64,
    /// Of which numeric factorizations (Cholesky) or matrix setup (PCG).
    pub factor: f64,
    /// Of which triangular solves (Cholesky) or CG iterations (PCG).
    pub solve: f64,
    /// Of which projections onto the variety.
    pub project: f64,
    /// Quaternions, axes and invariants per vertex.
    pub invariants: f64,
    /// Frames per tet (projections of the barycentre values).
    pub tet_frames: f64,
    /// Singular edges (rings and holonomies).
    pub singular: f64,
    /// Whole stage.
    pub total: f64,
}

/// Summary of the frames stage (the `frames` entry of `report.json`).
#[derive(Debug, Clone, Default, Serialize)]
pub struct FramesReport {
    /// Tetrahedra.
    pub tets: usize,
    /// Vertices.
    pub vertices: usize,
    /// Vertices on the boundary (normal-aligned or fixed).
    pub boundary_vertices: usize,
    /// Boundary vertices with a fixed frame (features of uploaded volumes).
    pub fixed_vertices: usize,
    /// The volume mesh.
    pub volume: VolumeReport,
    /// Dirichlet energy `∫|∇s|²` of the initial field (model units: length).
    pub energy_before: f64,
    /// Dirichlet energy of the final field.
    pub energy_after: f64,
    /// Diffuse–project steps done (the harmonic start counts as one).
    pub iterations: usize,
    /// Matrices set up: harmonic start plus one per time step (numeric
    /// factorizations with Cholesky).
    pub levels: usize,
    /// Linear solver used for the diffusions.
    pub linear_solver: Option<LinearSolverKind>,
    /// Conjugate-gradient iterations in total (0 with Cholesky).
    pub pcg_iterations: usize,
    /// Energy after each step, with its time step (`tau` = 0: harmonic start).
    pub energy_history: Vec<EnergyRecord>,
    /// Singular edges by type and their curve structure.
    pub singular: SingularReport,
    /// Largest relative model-surface residual
    /// `|h2² − h1(h0³ − 108 h1²)| / (|h2|² + |h1||h0|³ + 108|h1|³)` over vertices.
    pub model_surface_residual_max: f64,
    /// Largest angle between a boundary normal and the nearest axis of its
    /// vertex frame, degrees.
    pub boundary_alignment_max_deg: f64,
    /// Wall time per step.
    pub seconds: FramesTimings,
}

/// The frame field on the volume.
#[derive(Debug, Clone)]
pub struct FrameField {
    /// The tetrahedral mesh carrying the field.
    pub volume: TetMesh,
    /// Frame quaternion per vertex `[q0, q1, q2, q3]` (unit, `q0 ≥ 0`):
    /// the frame axes are the columns of its rotation matrix.
    pub quaternion_per_vertex: Vec<[f64; 4]>,
    /// Degree-4 spherical-harmonic 9-vector per vertex (unit norm, `m = −4..4`).
    pub sh9_per_vertex: Vec<[f64; 9]>,
    /// The three orthonormal frame axes per vertex.
    pub axes_per_vertex: Vec<[Vec3; 3]>,
    /// Octahedral invariants `(h0, h1, h2)` (4.23) per vertex.
    pub invariants_per_vertex: Vec<[C64; 3]>,
    /// Whether each vertex is on the boundary of the volume.
    pub boundary_per_vertex: Vec<bool>,
    /// Frame per tetrahedron (quaternion), used for the singular edges.
    pub quaternion_per_tet: Vec<[f64; 4]>,
    /// Singular edges.
    pub singular_edges: Vec<SingularEdge>,
    /// Summary.
    pub report: FramesReport,
}

/// Compute the frame field of the volume enclosed by `surface`, or of the
/// uploaded tetrahedral mesh `volume` (used as is).
///
/// Progress: volume 0–20 %, field 25–90 %, singular edges 90–100 %.
///
/// # Errors
/// [`FramesError::OpenSurface`] (naming the boundary loops) or
/// [`FramesError::EmptySurface`] when there is no closed surface to fill,
/// [`FramesError::InvalidSurface`] for an invalid surface,
/// [`FramesError::InvalidVolume`] or [`FramesError::EmptyVolume`] for an
/// invalid uploaded mesh,
/// [`FramesError::NoInterior`], [`FramesError::TooManyTets`],
/// [`FramesError::InvalidOption`], [`FramesError::Linalg`],
/// [`FramesError::Cancelled`].
pub fn compute_frame_field(
    surface: &TriMesh,
    volume: Option<&TetMesh>,
    opts: &FramesOptions,
    progress: &Progress,
) -> Result<FrameField, FramesError> {
    opts.validate()?;
    let t_total = Instant::now();
    let mut seconds = FramesTimings::default();

    let t = Instant::now();
    let vol = volume_step(surface, volume, opts, &progress.sub(0.0, 0.2))?;
    progress.check()?;
    seconds.volume = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let bc = constraint_step(&vol, surface, opts.feature_angle_deg, progress)?;
    seconds.constraints = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let ops = tet_p1_operators(&vol.mesh);
    progress.check()?;
    seconds.operators = t.elapsed().as_secs_f64();
    progress.sub(0.2, 0.25).set(1.0);
    let params = mbo_params(opts, &vol.mesh);
    let t = Instant::now();
    let init = vec![bc.initial; vol.mesh.n_vertices()];
    let field = smooth_octahedral_field(&ops, &bc.constraints, &init, &params, &progress.sub(0.25, 0.9))?;
    seconds.field = t.elapsed().as_secs_f64();
    seconds.factor = field.factor_seconds;
    seconds.solve = field.solve_seconds;
    seconds.project = field.project_seconds;

    let t = Instant::now();
    let out = vertex_outputs(&field, &bc.constraints);
    seconds.invariants = t.elapsed().as_secs_f64();
    progress.check()?;

    let t = Instant::now();
    let frames_t = tet_frames(&vol.mesh, &field.sh9_per_vertex, &field.rotation_per_vertex, progress)?;
    seconds.tet_frames = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (singular, singular_report) =
        singular_edges(&vol.mesh, &frames_t, &bc.boundary, opts.singular_axis_tolerance_deg, progress)?;
    let quaternion_per_tet = frames_t.par_iter().map(|r| Quat::from_matrix(r).0).collect();
    seconds.singular = t.elapsed().as_secs_f64();
    progress.set(1.0);
    seconds.total = t_total.elapsed().as_secs_f64();

    let report = frames_report(&vol, &bc, &field, &params, &out, singular_report, seconds);
    Ok(FrameField {
        volume: vol.mesh,
        quaternion_per_vertex: out.quats.iter().map(|q| q.0).collect(),
        sh9_per_vertex: field.sh9_per_vertex,
        axes_per_vertex: out.axes,
        invariants_per_vertex: out.invariants,
        boundary_per_vertex: bc.boundary,
        quaternion_per_tet,
        singular_edges: singular,
        report,
    })
}

/// The tetrahedral mesh of the stage and what is known of its boundary.
struct VolumeStep {
    /// The mesh carrying the field.
    mesh: TetMesh,
    /// Its report.
    report: VolumeReport,
    /// Surface triangle per vertex of a stuffed mesh (`None` when uploaded).
    surface_triangle: Option<Vec<u32>>,
}

/// Step 1: the uploaded volume checked and measured, or the enclosed volume
/// of `surface` stuffed part by part at the sizes of the options.
fn volume_step(
    surface: &TriMesh,
    volume: Option<&TetMesh>,
    opts: &FramesOptions,
    progress: &Progress,
) -> Result<VolumeStep, FramesError> {
    let step = match volume {
        Some(m) => uploaded_volume(m)?,
        None => {
            surface.validate().map_err(FramesError::InvalidSurface)?;
            check_closed(surface)?;
            let sizing = SizingParams {
                target_size: opts.target_size,
                max_tets: opts.max_tets,
                default_max_tets: opts.default_max_tets,
                volume_tolerance: opts.volume_tolerance,
            };
            let warp = WarpThresholds { alpha_long: opts.alpha_long, alpha_short: opts.alpha_short };
            let (stuffed, report) = enclosed_volume_mesh(surface, &sizing, warp, progress)?;
            VolumeStep { mesh: stuffed.mesh, report, surface_triangle: Some(stuffed.surface_triangle_per_vertex) }
        }
    };
    progress.set(1.0);
    Ok(step)
}

/// An uploaded tetrahedral mesh, validated, with its quality measures.
fn uploaded_volume(m: &TetMesh) -> Result<VolumeStep, FramesError> {
    if m.tets.is_empty() {
        return Err(FramesError::EmptyVolume);
    }
    m.validate()?;
    let (min_d, max_d) = dihedral_angle_range(m);
    let b = boundary_vertices_of_faces(m.n_vertices(), &tet_boundary_faces(m));
    let report = VolumeReport {
        source: "uploaded".into(),
        n_tets: m.n_tets(),
        n_vertices: m.n_vertices(),
        n_boundary_vertices: b.iter().filter(|x| **x).count(),
        min_dihedral_deg: min_d,
        max_dihedral_deg: max_d,
        volume: m.volume(),
        ..Default::default()
    };
    Ok(VolumeStep { mesh: m.clone(), report, surface_triangle: None })
}

/// Boundary data and constraints of the field.
struct ConstraintStep {
    /// Whether each vertex is on the boundary.
    boundary: Vec<bool>,
    /// Constraint per vertex ([`boundary_constraints`]).
    constraints: Vec<VertexConstraint>,
    /// The frame that best fits all boundary constraints ([`best_fit_frame`]).
    initial: Mat3,
}

/// Step 2: boundary faces and vertices, the constraint per vertex and the
/// initial frame.
fn constraint_step(
    vol: &VolumeStep,
    surface: &TriMesh,
    feature_angle_deg: f64,
    progress: &Progress,
) -> Result<ConstraintStep, FramesError> {
    let faces = tet_boundary_faces(&vol.mesh);
    progress.check()?;
    let boundary = boundary_vertices_of_faces(vol.mesh.n_vertices(), &faces);
    let constraints =
        boundary_constraints(&vol.mesh, &faces, &boundary, surface, vol.surface_triangle.as_deref(), feature_angle_deg);
    progress.check()?;
    let initial = best_fit_frame(&constraints);
    Ok(ConstraintStep { boundary, constraints, initial })
}

/// The MBO parameters of the options on `mesh`: time steps scaled by its
/// squared mean edge length (or squared diagonal for the first step
/// without a harmonic start), and the solver by its vertex count.
fn mbo_params(opts: &FramesOptions, mesh: &TetMesh) -> MboParams {
    let diag = mesh_diagonal(mesh);
    let h_mean = mean_tet_edge_length(mesh);
    let h2 = h_mean * h_mean;
    MboParams {
        tau_initial: if opts.harmonic_start { opts.tau_initial * h2 } else { opts.tau_initial * diag * diag }
            .max(opts.tau_final * h2),
        tau_final: opts.tau_final * h2,
        tau_shrink: opts.tau_shrink,
        max_steps_per_level: opts.max_steps_per_level,
        step_tolerance: opts.step_tolerance,
        energy_tolerance: opts.energy_tolerance,
        projection_accept: opts.projection_accept,
        harmonic_start: opts.harmonic_start,
        dirichlet_diffusion: opts.dirichlet_diffusion,
        solver: opts.linear_solver.unwrap_or(if mesh.n_vertices() <= opts.direct_solver_max_vertices {
            LinearSolverKind::Cholesky
        } else {
            LinearSolverKind::Pcg
        }),
        pcg_tolerance: opts.pcg_tolerance,
    }
}

/// Per-vertex outputs of the field.
struct VertexOutputs {
    /// Frame quaternion per vertex.
    quats: Vec<Quat>,
    /// Octahedral invariants (4.23) per vertex.
    invariants: Vec<[C64; 3]>,
    /// Largest relative model-surface residual.
    residual_max: f64,
    /// Frame axes per vertex.
    axes: Vec<[Vec3; 3]>,
    /// Largest angle between a boundary normal and the nearest frame axis, degrees.
    alignment_max_deg: f64,
}

/// Step 4: quaternions, invariants (4.23) with their model-surface
/// residual, axes, and the boundary alignment of the smoothed field.
fn vertex_outputs(field: &MboResult, constraints: &[VertexConstraint]) -> VertexOutputs {
    let quats: Vec<Quat> = field.rotation_per_vertex.par_iter().map(Quat::from_matrix).collect();
    let invariants: Vec<[C64; 3]> = quats.par_iter().map(frame_invariants).collect();
    let residual_max = invariants.par_iter().map(model_surface_relative_residual).reduce(|| 0.0, f64::max);
    let axes: Vec<[Vec3; 3]> = field
        .rotation_per_vertex
        .iter()
        .map(|r| [r.column(0).into_owned(), r.column(1).into_owned(), r.column(2).into_owned()])
        .collect();
    let alignment_max_deg = boundary_alignment_max_deg(constraints, &axes);
    VertexOutputs { quats, invariants, residual_max, axes, alignment_max_deg }
}

/// Largest angle between a normal constraint and the nearest of its
/// vertex's axes, degrees (atan2 of `|a × n|` and `|a · n|`: accurate for
/// tiny angles).
fn boundary_alignment_max_deg(constraints: &[VertexConstraint], axes: &[[Vec3; 3]]) -> f64 {
    constraints
        .par_iter()
        .zip(axes)
        .map(|(c, a)| match c {
            VertexConstraint::Normal(n) => {
                a.iter().map(|x| x.cross(n).norm().atan2(x.dot(n).abs())).fold(f64::INFINITY, f64::min).to_degrees()
            }
            _ => 0.0,
        })
        .reduce(|| 0.0, f64::max)
}

/// The stage report from the results of its steps.
fn frames_report(
    vol: &VolumeStep,
    bc: &ConstraintStep,
    field: &MboResult,
    params: &MboParams,
    out: &VertexOutputs,
    singular: SingularReport,
    seconds: FramesTimings,
) -> FramesReport {
    FramesReport {
        tets: vol.mesh.n_tets(),
        vertices: vol.mesh.n_vertices(),
        boundary_vertices: bc.boundary.iter().filter(|b| **b).count(),
        fixed_vertices: bc.constraints.iter().filter(|c| matches!(c, VertexConstraint::Fixed(_))).count(),
        volume: vol.report.clone(),
        energy_before: field.energy_initial,
        energy_after: field.energy_final,
        iterations: field.history.len(),
        levels: field.n_factorizations,
        linear_solver: Some(params.solver),
        pcg_iterations: field.pcg_iterations,
        energy_history: field.history.clone(),
        singular,
        model_surface_residual_max: out.residual_max,
        boundary_alignment_max_deg: out.alignment_max_deg,
        seconds,
    }
}

/// Constraint per vertex: free inside; on the boundary, the normal of the
/// surface triangle the vertex lies on (stuffed meshes) or of its boundary
/// faces (uploaded meshes), fixed frames at features of uploaded meshes.
pub fn boundary_constraints(
    mesh: &TetMesh,
    faces: &[[u32; 3]],
    boundary: &[bool],
    surface: &TriMesh,
    surface_triangle: Option<&[u32]>,
    feature_angle_deg: f64,
) -> Vec<VertexConstraint> {
    let (face_normal, spread) = boundary_vertex_normals(mesh, faces);
    let feature = feature_angle_deg.to_radians();
    // Per-vertex list of incident boundary face normals (area-weighted), only
    // needed at feature vertices.
    let mut incident: Vec<Vec<Vec3>> = vec![Vec::new(); mesh.n_vertices()];
    for f in faces {
        let [a, b, c] = f.map(|v| mesh.positions[v as usize]);
        let an = (b - a).cross(&(c - a)) * 0.5;
        for &v in f {
            if spread[v as usize] > feature {
                incident[v as usize].push(an);
            }
        }
    }
    (0..mesh.n_vertices())
        .map(|v| {
            if !boundary[v] {
                return VertexConstraint::Free;
            }
            if let Some(tris) = surface_triangle {
                let t = tris[v];
                if t != NO_TRIANGLE && (t as usize) < surface.n_faces() {
                    let n = surface.face_normal(FaceId::new(t as usize));
                    if n.norm() > 0.5 {
                        return VertexConstraint::Normal(n);
                    }
                }
            } else if spread[v] > feature {
                let mut s = [0.0; 9];
                for an in &incident[v] {
                    let area = an.norm();
                    if area > 0.0 {
                        let y = sh4_basis(&(an / area));
                        for c in 0..9 {
                            s[c] += area * y[c];
                        }
                    }
                }
                return VertexConstraint::Fixed(nearest_frame(&s, None, 0.0).rotation);
            }
            if face_normal[v].norm() > 0.5 { VertexConstraint::Normal(face_normal[v]) } else { VertexConstraint::Free }
        })
        .collect()
}

/// The single frame that best fits all boundary constraints: the projection
/// of `Σ Y4(n_v) + Σ sh9(R_fixed)` onto the variety (identity when the sum
/// vanishes, as for a sphere).
pub fn best_fit_frame(constraints: &[VertexConstraint]) -> Mat3 {
    let mut s = [0.0; 9];
    let mut count = 0.0;
    for c in constraints {
        let y = match c {
            VertexConstraint::Normal(n) => sh4_basis(n),
            VertexConstraint::Fixed(r) => sh9_from_rotation(r),
            VertexConstraint::Free => continue,
        };
        count += 1.0;
        for k in 0..9 {
            s[k] += y[k];
        }
    }
    let norm = s.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(norm > 1e-6 * count) {
        return Mat3::identity();
    }
    nearest_frame(&s, None, 0.0).rotation
}

fn mesh_diagonal(mesh: &TetMesh) -> f64 {
    crate::geom::BoundingBox::of_points(&mesh.positions).map_or(1.0, |b| b.diagonal())
}

/// Mean edge length over the 6 edges of every tet (partial sums over fixed
/// chunks, added in order: independent of the thread count).
pub fn mean_tet_edge_length(mesh: &TetMesh) -> f64 {
    if mesh.tets.is_empty() {
        return 0.0;
    }
    let partial: Vec<f64> = mesh
        .tets
        .par_chunks(4096)
        .map(|chunk| {
            chunk
                .iter()
                .map(|t| {
                    let p = t.map(|v| mesh.positions[v.idx()]);
                    crate::fem::tet_p1::TET_EDGES.iter().map(|[i, j]| (p[*i] - p[*j]).norm()).sum::<f64>()
                })
                .sum::<f64>()
        })
        .collect();
    partial.iter().sum::<f64>() / (6.0 * mesh.tets.len() as f64)
}
