//! The volume mesh of the frames stage: isosurface stuffing of closed
//! surfaces, checked against the input (boundary vertices on the surface,
//! surface within one lattice spacing of the mesh boundary, enclosed volume,
//! dihedral angles, orientation), the errors for inputs without a volume,
//! and the whole stage on real closed surfaces of the corpus.

use meshatlas::frames::bvh::TriangleBvh;
use meshatlas::frames::volume::{tet_boundary_faces, tetrahedralize_enclosed_volume};
use meshatlas::frames::{FramesError, FramesOptions, compute_frame_field};
use meshatlas::geom::Vec3;
use meshatlas::io::{LoadOptions, load_path};
use meshatlas::mesh::fixtures::{self, placed, union};
use meshatlas::mesh::{TetMesh, TriMesh, VertexId};
use meshatlas::progress::Progress;

/// Largest distance from the vertices of `surface` to the boundary of `mesh`.
fn surface_to_boundary_distance(surface: &TriMesh, mesh: &TetMesh) -> f64 {
    let faces: Vec<[u32; 3]> = tet_boundary_faces(mesh);
    let boundary = TriMesh::from_raw(mesh.positions.clone(), &faces);
    let bvh = TriangleBvh::new(&boundary);
    surface.positions.iter().map(|p| bvh.closest_point(p).map_or(f64::INFINITY, |c| c.0)).fold(0.0, f64::max)
}

/// Stuff `surface` at spacing `h` and check the stated tolerances:
/// boundary vertices on the surface to 1e-10 of its size (round-off of the
/// segment–triangle intersections), surface within `h` of the mesh
/// boundary, volume within `vol_tol`, dihedral angles within [10°, 165°]
/// (measured, not guaranteed: see `stuffing`).
fn check_stuffing(name: &str, surface: &TriMesh, h: f64, vol_tol: f64) {
    let (vol, rep) = tetrahedralize_enclosed_volume(surface, h, 0.24999, 0.41189).unwrap();
    assert!(vol.mesh.validate().is_ok(), "{name}");
    let diag = surface.bounding_box().unwrap().diagonal();
    assert!(
        rep.max_boundary_vertex_distance <= 1e-10 * diag,
        "{name}: boundary vertex off the surface by {}",
        rep.max_boundary_vertex_distance
    );
    let back = surface_to_boundary_distance(surface, &vol.mesh);
    assert!(back <= h, "{name}: surface {back} away from the mesh boundary (h = {h})");
    assert!(rep.volume_relative_error.abs() <= vol_tol, "{name}: volume error {}", rep.volume_relative_error);
    assert!(
        rep.min_dihedral_deg >= 10.0 && rep.max_dihedral_deg <= 165.0,
        "{name}: dihedral range {}..{}",
        rep.min_dihedral_deg,
        rep.max_dihedral_deg
    );
    println!(
        "{name}: h {h}, {} tets, volume error {:.2e}, surface→boundary {:.3} h, dihedral {:.1}..{:.1}°, {} warped, {} Steiner, {} fallbacks",
        rep.n_tets,
        rep.volume_relative_error,
        back / h,
        rep.min_dihedral_deg,
        rep.max_dihedral_deg,
        rep.n_warped,
        rep.n_steiner,
        rep.n_cut_fallbacks
    );
}

#[test]
fn stuffing_follows_cube_sphere_and_torus() {
    check_stuffing("cube", &fixtures::cube(6), 0.15, 0.03);
    check_stuffing("sphere", &fixtures::icosphere(3), 0.12, 0.03);
    check_stuffing("torus", &fixtures::torus(1.0, 0.4, 48, 24), 0.08, 0.03);
    // Orientation of the input does not matter (crossing parity).
    let mut flipped = fixtures::icosphere(3);
    for t in &mut flipped.triangles {
        t.swap(1, 2);
    }
    check_stuffing("flipped sphere", &flipped, 0.12, 0.03);
}

#[test]
fn stuffing_is_valid_for_any_lattice_offset() {
    use meshatlas::frames::stuffing::{StuffingParams, isosurface_stuffing};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};
    let mut rng = StdRng::seed_from_u64(81);
    for (name, s, h) in [("torus", fixtures::torus(1.0, 0.4, 32, 16), 0.12), ("cube", fixtures::cube(4), 0.25)] {
        let bvh = TriangleBvh::new(&s);
        for _ in 0..4 {
            let mut p = StuffingParams::new(h, 0.24999, 0.41189);
            p.lattice_offset = [rng.random_range(0.0..1.0), rng.random_range(0.0..1.0), rng.random_range(0.0..1.0)];
            let v = isosurface_stuffing(&s, &bvh, &p);
            assert!(v.mesh.validate().is_ok(), "{name} {:?}", p.lattice_offset);
            let (lo, hi) = meshatlas::frames::volume::dihedral_angle_range(&v.mesh);
            assert!(lo >= 10.0 && hi <= 165.0, "{name} {:?}: {lo}..{hi}", p.lattice_offset);
        }
    }
}

#[test]
fn thin_walls_need_a_fine_lattice() {
    // gmsh_t13 is a thin-walled part: at diag/20 walls thinner than about
    // two lattice spacings are lost (the report says so), at diag/80 the
    // volume is within 5 % (tets whose four vertices all warped onto the
    // surface are dropped, which thins the thinnest walls a little).
    let dir = std::path::PathBuf::from(
        std::env::var("MESHATLAS_CORPUS").unwrap_or_else(|_| "/work/shared/data/corpus".into()),
    );
    let s = load_path(&dir.join("gmsh_t13.stl"), None, &LoadOptions::default()).unwrap().surface;
    let diag = s.bounding_box().unwrap().diagonal();
    let (_, coarse) = tetrahedralize_enclosed_volume(&s, diag / 20.0, 0.24999, 0.41189).unwrap();
    assert!(coarse.volume_relative_error < -0.3, "{}", coarse.volume_relative_error);
    assert!(coarse.warnings.iter().any(|w| w.contains("thinner")), "{:?}", coarse.warnings);
    check_stuffing("gmsh_t13", &s, diag / 80.0, 0.05);
}

#[test]
fn inputs_without_a_volume_fail_clearly() {
    // A flat box thinner than the lattice spacing.
    let mut slab = fixtures::cube(2);
    for p in &mut slab.positions {
        p.z *= 0.01;
    }
    let err = compute_frame_field(
        &slab,
        None,
        &FramesOptions { target_size: Some(0.5), ..Default::default() },
        &Progress::none(),
    )
    .unwrap_err();
    assert!(matches!(err, FramesError::NoInterior { .. }), "{err:?}");
    // Too small a target size.
    let err = compute_frame_field(
        &fixtures::cube(2),
        None,
        &FramesOptions { target_size: Some(1e-4), ..Default::default() },
        &Progress::none(),
    )
    .unwrap_err();
    assert!(matches!(err, FramesError::TooManyTets { .. }), "{err:?}");
    // An uploaded volume with an inverted tet.
    let bad = TetMesh {
        positions: vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
        tets: vec![[VertexId(0), VertexId(2), VertexId(1), VertexId(3)]],
    };
    let err = compute_frame_field(&fixtures::tetrahedron(), Some(&bad), &FramesOptions::default(), &Progress::none())
        .unwrap_err();
    assert!(matches!(err, FramesError::InvalidVolume(_)), "{err:?}");
    assert!(err.to_string().contains("tetrahedron 0"), "{err}");
}

#[test]
fn corpus_closed_surfaces_give_valid_fields() {
    let dir = std::path::PathBuf::from(
        std::env::var("MESHATLAS_CORPUS").unwrap_or_else(|_| "/work/shared/data/corpus".into()),
    );
    for (file, cells) in
        [("fandisk.obj", 22.0), ("aorta_closed.stl", 30.0), ("spot.obj", 20.0), ("plate_holes.stl", 30.0)]
    {
        let loaded = load_path(&dir.join(file), None, &LoadOptions::default()).unwrap();
        let s = &loaded.surface;
        let h = s.bounding_box().unwrap().diagonal() / cells;
        let field = compute_frame_field(
            s,
            None,
            &FramesOptions { target_size: Some(h), ..Default::default() },
            &Progress::none(),
        )
        .unwrap_or_else(|e| panic!("{file}: {e}"));
        let r = &field.report;
        assert!(field.volume.validate().is_ok(), "{file}");
        assert!(r.volume.max_boundary_vertex_distance <= 1e-10 * h * cells, "{file}");
        assert!(r.volume.volume_relative_error.abs() < 0.1, "{file}: volume error {}", r.volume.volume_relative_error);
        assert!(r.model_surface_residual_max < 1e-12, "{file}");
        assert!(r.boundary_alignment_max_deg < 1e-6, "{file}");
        assert_eq!(r.singular.n_dangling_interior_ends, 0, "{file}");
        assert!(r.energy_after <= r.energy_before, "{file}");
        println!(
            "{file}: {} tets, volume error {:.3}, dihedral {:.1}..{:.1}°, energy {:.3e} → {:.3e}, singular {} v3 / {} v5 / {} complex, {} curves",
            r.tets,
            r.volume.volume_relative_error,
            r.volume.min_dihedral_deg,
            r.volume.max_dihedral_deg,
            r.energy_before,
            r.energy_after,
            r.singular.n_valence3,
            r.singular.n_valence5,
            r.singular.n_complex,
            r.singular.n_curves
        );
    }
}

/// 12 bone-like closed parts (elongated ellipsoids of 320 triangles, lengths
/// 0.6 to 6, slenderness 2 to 6) on a grid 8 apart: 3840 triangles.
fn bones() -> Vec<TriMesh> {
    (0..12)
        .map(|i| {
            let len = 0.3 + 2.7 * (i as f64 / 11.0);
            let slender = 2.0 + (i % 5) as f64;
            let r = len / slender;
            let d = Vec3::new(8.0 * (i % 4) as f64, 8.0 * (i / 4) as f64, 0.0);
            placed(&fixtures::icosphere(2), Vec3::new(len, r, 0.8 * r), d)
        })
        .collect()
}

/// A big ball (radius 1), a small ball (0.05), a thin disk (radius 0.5,
/// thickness 0.16), a thin rod (length 2, radius 0.1) and a small cube
/// (edge 0.2), far apart.
fn mixed_sizes() -> Vec<TriMesh> {
    let ball = fixtures::icosphere(4);
    vec![
        ball.clone(),
        placed(&fixtures::icosphere(2), Vec3::repeat(0.05), Vec3::new(4.0, 0.0, 0.0)),
        placed(&ball, Vec3::new(0.5, 0.5, 0.08), Vec3::new(0.0, 4.0, 0.0)),
        placed(&fixtures::icosphere(3), Vec3::new(1.0, 0.1, 0.1), Vec3::new(0.0, 0.0, 4.0)),
        placed(&fixtures::cube(2), Vec3::repeat(0.1), Vec3::new(-4.0, 0.0, 0.0)),
    ]
}

/// Every part's tet volume against the divergence-theorem volume of the
/// mesh it was made from (computed here, independently of the stage), and
/// the report's own per-part error; returns the largest |error|.
fn check_parts(name: &str, pieces: &[TriMesh], rep: &meshatlas::frames::volume::VolumeReport, tol: f64) -> f64 {
    assert_eq!(rep.parts.len(), pieces.len(), "{name}");
    let mut worst = 0.0f64;
    for (p, m) in rep.parts.iter().zip(pieces) {
        let enclosed = m.signed_volume();
        assert!((p.enclosed_volume - enclosed).abs() <= 1e-12 * enclosed, "{name} part {}", p.part);
        let e = (p.volume - enclosed) / enclosed;
        assert!((e - p.relative_error).abs() < 1e-12, "{name} part {}", p.part);
        worst = worst.max(e.abs());
        println!(
            "{name} part {:2}: V {:.4e} thickness {:.3e} h {:.3e} (wanted {:.3e}) {:6} tets, error {:+.3}%",
            p.part,
            enclosed,
            p.thickness,
            p.target_size,
            p.accurate_size,
            p.n_tets,
            100.0 * e
        );
        assert!(e.abs() < tol, "{name} part {}: volume error {e} at h {}", p.part, p.target_size);
    }
    worst
}

#[test]
fn every_part_is_within_one_percent_at_the_default_size() {
    use meshatlas::frames::sizing::SizingParams;
    use meshatlas::frames::volume::{WarpThresholds, enclosed_volume_mesh};
    let warp = WarpThresholds { alpha_long: 0.24999, alpha_short: 0.41189 };
    let o = FramesOptions::default();
    let sizing = SizingParams {
        target_size: None,
        max_tets: o.max_tets,
        default_max_tets: o.default_max_tets,
        volume_tolerance: o.volume_tolerance,
    };
    for (name, pieces) in [("bones", bones()), ("mixed sizes", mixed_sizes())] {
        let surface = union(&pieces);
        // The old default, one lattice at the mean edge length for all:
        // small and thin parts lose more than 1 %.
        let (_, old) = tetrahedralize_enclosed_volume(&surface, surface.mean_edge_length(), 0.24999, 0.41189).unwrap();
        let old_worst = old.parts.iter().map(|p| p.relative_error.abs()).fold(0.0, f64::max);
        assert!(old_worst > 0.01, "{name}: {old_worst}");
        assert!(old.n_parts_outside_tolerance > 0 && old.warnings.iter().any(|w| w.contains("volume tolerance")));
        let (vol, rep) = enclosed_volume_mesh(&surface, &sizing, warp, &Progress::none()).unwrap();
        assert!(vol.mesh.validate().is_ok(), "{name}");
        let worst = check_parts(name, &pieces, &rep, 0.01);
        assert_eq!(rep.n_parts_outside_tolerance, 0, "{name}");
        assert!(rep.n_tets <= o.default_max_tets, "{name}: {} tets", rep.n_tets);
        println!(
            "{name}: {} triangles, old default {} tets worst {:.2}%, new {} tets worst {:.3}%",
            surface.n_faces(),
            old.n_tets,
            100.0 * old_worst,
            rep.n_tets,
            100.0 * worst
        );
    }
}

#[test]
fn a_small_budget_bounds_the_tets_and_names_the_parts_it_cannot_meet() {
    use meshatlas::frames::sizing::SizingParams;
    use meshatlas::frames::volume::{WarpThresholds, enclosed_volume_mesh};
    let warp = WarpThresholds { alpha_long: 0.24999, alpha_short: 0.41189 };
    let pieces = mixed_sizes();
    let surface = union(&pieces);
    let sizing =
        SizingParams { target_size: None, max_tets: 15_000, default_max_tets: 300_000, volume_tolerance: 0.01 };
    let (_, rep) = enclosed_volume_mesh(&surface, &sizing, warp, &Progress::none()).unwrap();
    assert!(rep.n_tets <= 15_000, "{}", rep.n_tets);
    check_parts("15k budget", &pieces, &rep, 1.0);
    assert!(rep.spacing_capped && rep.n_parts_outside_tolerance > 0);
    assert!(rep.parts.iter().filter(|p| !p.within_tolerance).all(|p| p.capped));
    assert!(rep.warnings.iter().any(|w| w.contains("tet budget")), "{:?}", rep.warnings);
    // An explicit size applies to every part and is refused above max_tets.
    let fixed = SizingParams { target_size: Some(0.2), ..sizing };
    let (_, rep) = enclosed_volume_mesh(&surface, &fixed, warp, &Progress::none()).unwrap();
    assert!(rep.parts.iter().all(|p| p.target_size == 0.2) && rep.n_tets <= 15_000);
    let too_fine = SizingParams { target_size: Some(0.01), ..sizing };
    let err = enclosed_volume_mesh(&surface, &too_fine, warp, &Progress::none()).unwrap_err();
    assert!(matches!(err, FramesError::TooManyTets { .. }), "{err:?}");
}
