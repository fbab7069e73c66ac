//! Known answers of the frames stage (issue 5): cube and rotated cube give
//! a constant axis-aligned field with zero energy and no singular edge; the
//! ball gives singular curves that end on the boundary or close up; the
//! invariants of every computed frame lie on the model surface.

use meshatlas::frames::groups::cube_rotations;
use meshatlas::frames::quaternion::{Mat3, Quat};
use meshatlas::frames::{FramesError, FramesOptions, SingularKind, compute_frame_field};
use meshatlas::geom::Vec3;
use meshatlas::mesh::{TetMesh, TriMesh, VertexId, fixtures};
use meshatlas::progress::Progress;

/// Largest angle (degrees) between the frames of `q` and the frame `r`,
/// up to the 24 cube rotations.
fn max_deviation_deg(quats: &[[f64; 4]], r: &Mat3) -> f64 {
    let rots = cube_rotations();
    quats
        .iter()
        .map(|q| {
            let m = Quat(*q).to_matrix();
            // Quaternion angle: accurate for small angles (acos of the
            // trace is not below ~1e-6°).
            rots.iter()
                .map(|o| Quat::from_matrix(&(r.transpose() * m * o)).angle().to_degrees())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

fn rotate(mesh: &TriMesh, r: &Mat3) -> TriMesh {
    TriMesh { positions: mesh.positions.iter().map(|p| r * p).collect(), triangles: mesh.triangles.clone() }
}

#[test]
fn cube_gives_the_axis_aligned_field() {
    let cube = fixtures::cube(4);
    let opts = FramesOptions { target_size: Some(0.3), ..Default::default() };
    let field = compute_frame_field(&cube, None, &opts, &Progress::none()).unwrap();
    let rep = &field.report;
    assert!(field.volume.validate().is_ok());
    let dev = max_deviation_deg(&field.quaternion_per_vertex, &Mat3::identity());
    assert!(dev < 1e-6, "max deviation from the axes {dev}°");
    assert!(rep.energy_after.abs() < 1e-9, "energy {}", rep.energy_after);
    assert!(field.singular_edges.is_empty());
    assert!(rep.model_surface_residual_max < 1e-12);
    assert!(rep.boundary_alignment_max_deg < 1e-6);
    // Volume: boundary vertices on the surface, volume close to 8.
    assert!(rep.volume.max_boundary_vertex_distance < 1e-12);
    assert!(rep.volume.volume_relative_error.abs() < 0.05, "{}", rep.volume.volume_relative_error);
    println!("cube: {} tets, energy {:e}, deviation {dev:e}°", rep.tets, rep.energy_after);
}

#[test]
fn rotated_cube_frames_follow_the_rotation() {
    let r = Quat::from_axis_angle(&Vec3::new(1.0, 2.0, 3.0), 0.7).to_matrix();
    let cube = rotate(&fixtures::cube(4), &r);
    let opts = FramesOptions { target_size: Some(0.3), ..Default::default() };
    let field = compute_frame_field(&cube, None, &opts, &Progress::none()).unwrap();
    let dev = max_deviation_deg(&field.quaternion_per_vertex, &r);
    assert!(dev < 1e-6, "max deviation from the rotated axes {dev}°");
    assert!(field.report.energy_after.abs() < 1e-9, "energy {}", field.report.energy_after);
    assert!(field.singular_edges.is_empty());
}

/// Structured tetrahedral mesh of the cube `[-1, 1]³`, `n` cells per side,
/// 6 tets per cell (Kuhn).
fn structured_cube(n: usize) -> TetMesh {
    let id = |i: usize, j: usize, k: usize| (i + (n + 1) * (j + (n + 1) * k)) as u32;
    let mut positions = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                positions.push(Vec3::new(i as f64, j as f64, k as f64) * (2.0 / n as f64) - Vec3::repeat(1.0));
            }
        }
    }
    let mut tets = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let v = |a, b, c| VertexId(id(i + a, j + b, k + c));
                let ring = [v(1, 0, 0), v(1, 1, 0), v(0, 1, 0), v(0, 1, 1), v(0, 0, 1), v(1, 0, 1)];
                for r in 0..6 {
                    tets.push([v(0, 0, 0), ring[r], ring[(r + 1) % 6], v(1, 1, 1)]);
                }
            }
        }
    }
    let mut m = TetMesh { positions, tets };
    m.orient_positive();
    m
}

#[test]
fn uploaded_volume_is_used_as_is() {
    let vol = structured_cube(4);
    let field =
        compute_frame_field(&fixtures::cube(4), Some(&vol), &FramesOptions::default(), &Progress::none()).unwrap();
    assert_eq!(field.volume, vol);
    assert_eq!(field.report.volume.source, "uploaded");
    // Edges and corners of the cube are feature vertices with fixed frames.
    assert!(field.report.fixed_vertices > 0);
    let dev = max_deviation_deg(&field.quaternion_per_vertex, &Mat3::identity());
    assert!(dev < 1e-6, "{dev}");
    assert!(field.singular_edges.is_empty());
}

#[test]
fn uploaded_volume_with_an_unused_vertex_or_no_tet() {
    let mut vol = structured_cube(3);
    vol.positions.push(Vec3::new(5.0, 5.0, 5.0));
    let field =
        compute_frame_field(&fixtures::cube(3), Some(&vol), &FramesOptions::default(), &Progress::none()).unwrap();
    assert_eq!(field.quaternion_per_vertex.len(), vol.n_vertices());
    assert!(max_deviation_deg(&field.quaternion_per_vertex, &Mat3::identity()) < 1e-6);
    let empty = TetMesh { positions: vol.positions.clone(), tets: Vec::new() };
    let err = compute_frame_field(&fixtures::cube(3), Some(&empty), &FramesOptions::default(), &Progress::none())
        .unwrap_err();
    assert!(matches!(err, FramesError::EmptyVolume));
}

#[test]
fn ball_has_singular_curves_ending_on_the_boundary() {
    let sphere = fixtures::icosphere(3);
    let opts = FramesOptions { target_size: Some(0.16), ..Default::default() };
    let field = compute_frame_field(&sphere, None, &opts, &Progress::none()).unwrap();
    let rep = &field.report;
    let s = &rep.singular;
    println!(
        "ball: {} tets, energy {:.4} → {:.4} in {} steps; singular: {} valence 3, {} valence 5, {} complex, {} curves, {} branch vertices",
        rep.tets,
        rep.energy_before,
        rep.energy_after,
        rep.iterations,
        s.n_valence3,
        s.n_valence5,
        s.n_complex,
        s.n_curves,
        s.n_branch_vertices
    );
    assert!(!field.singular_edges.is_empty(), "a ball must have singular edges");
    assert_eq!(s.n_dangling_interior_ends, 0);
    assert_eq!(s.n_isolated_edges, 0);
    assert!(s.n_valence3 + s.n_valence5 > 0);
    assert!(
        field.singular_edges.iter().filter(|e| e.kind != SingularKind::Complex).count() >= s.n_valence3 + s.n_valence5
    );
    assert!(rep.model_surface_residual_max < 1e-12, "{}", rep.model_surface_residual_max);
    assert!(rep.boundary_alignment_max_deg < 1e-6);
    assert!(rep.energy_after < rep.energy_before);
    // The frames are unit and orthonormal, the 9-vectors unit.
    for (q, s9) in field.quaternion_per_vertex.iter().zip(&field.sh9_per_vertex) {
        assert!((Quat(*q).norm() - 1.0).abs() < 1e-12);
        assert!((s9.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn direct_and_iterative_solvers_give_the_same_field() {
    use meshatlas::frames::mbo::LinearSolverKind;
    let sphere = fixtures::icosphere(2);
    let run = |kind| {
        let opts = FramesOptions {
            target_size: Some(0.25),
            linear_solver: Some(kind),
            pcg_tolerance: 1e-10,
            ..Default::default()
        };
        compute_frame_field(&sphere, None, &opts, &Progress::none()).unwrap()
    };
    let (a, b) = (run(LinearSolverKind::Cholesky), run(LinearSolverKind::Pcg));
    assert!(b.report.pcg_iterations > 0 && a.report.pcg_iterations == 0);
    assert!(
        (a.report.energy_after - b.report.energy_after).abs() < 1e-6 * a.report.energy_after,
        "{} vs {}",
        a.report.energy_after,
        b.report.energy_after
    );
    assert_eq!(a.singular_edges.len(), b.singular_edges.len());
}

#[test]
fn open_surface_fails_with_its_loops() {
    let err =
        compute_frame_field(&fixtures::cylinder(1.0, 1.0, 12, 3), None, &FramesOptions::default(), &Progress::none())
            .unwrap_err();
    match &err {
        FramesError::OpenSurface { loops, .. } => assert_eq!(loops.len(), 2),
        other => panic!("{other:?}"),
    }
    assert!(err.to_string().contains("boundary loop"));
}

#[test]
fn cancellation_stops_the_stage() {
    let p = Progress::none();
    p.cancel_flag().store(true, std::sync::atomic::Ordering::Relaxed);
    let err = compute_frame_field(
        &fixtures::icosphere(2),
        None,
        &FramesOptions { target_size: Some(0.3), ..Default::default() },
        &p,
    )
    .unwrap_err();
    assert!(matches!(err, FramesError::Cancelled(_)));
}

#[test]
fn options_reject_unknown_fields_and_bad_values() {
    assert!(serde_json::from_str::<FramesOptions>(r#"{"bogus": 1}"#).is_err());
    let o: FramesOptions = serde_json::from_str(r#"{"target_size": 0.5}"#).unwrap();
    assert_eq!(o.target_size, Some(0.5));
    let bad = FramesOptions { tau_shrink: 1.5, ..Default::default() };
    assert!(matches!(
        compute_frame_field(&fixtures::icosphere(1), None, &bad, &Progress::none()),
        Err(FramesError::InvalidOption { name: "tau_shrink", .. })
    ));
}

#[test]
fn report_serializes_and_progress_is_monotone() {
    use meshatlas::progress::ProgressSink;
    use std::sync::{Arc, Mutex, atomic::AtomicBool};
    struct Rec(Mutex<Vec<f64>>);
    impl ProgressSink for Rec {
        fn report(&self, _stage: &str, fraction: f64) {
            self.0.lock().unwrap().push(fraction);
        }
    }
    let rec = Arc::new(Rec(Mutex::new(Vec::new())));
    let p = Progress::new(rec.clone(), Arc::new(AtomicBool::new(false)));
    let field = compute_frame_field(
        &fixtures::icosphere(2),
        None,
        &FramesOptions { target_size: Some(0.3), ..Default::default() },
        &p,
    )
    .unwrap();
    let f = rec.0.lock().unwrap().clone();
    assert!(f.len() > 3 && f.windows(2).all(|w| w[1] >= w[0]), "{f:?}");
    assert_eq!(f.last(), Some(&1.0));
    let v = serde_json::to_value(&field.report).unwrap();
    for key in [
        "tets",
        "vertices",
        "energy_before",
        "energy_after",
        "iterations",
        "energy_history",
        "singular",
        "model_surface_residual_max",
        "seconds",
        "volume",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert!(v["energy_history"].as_array().is_some_and(|h| !h.is_empty() && h.iter().all(|r| r["energy"].is_f64())));
    assert!(v["singular"]["n_valence3"].is_u64() && v["seconds"]["total"].is_f64());
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    use meshatlas::frames::mbo::LinearSolverKind;
    let sphere = fixtures::icosphere(2);
    let opts =
        FramesOptions { target_size: Some(0.2), linear_solver: Some(LinearSolverKind::Pcg), ..Default::default() };
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| compute_frame_field(&sphere, None, &opts, &Progress::none()).unwrap())
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a.volume, b.volume);
    assert_eq!(a.quaternion_per_vertex, b.quaternion_per_vertex);
    assert_eq!(a.singular_edges, b.singular_edges);
    assert_eq!(a.report.energy_after.to_bits(), b.report.energy_after.to_bits());
}
