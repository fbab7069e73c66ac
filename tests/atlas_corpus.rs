//! The atlas of every real mesh in `../shared/data/corpus`: every input
//! triangle lies in exactly one patch, every patch map is one-to-one, and a
//! fresh Gmsh process remeshes `atlas.msh`. Plus the coarse cylinder of
//! thesis ch. 2 §5.1: longest-edge bisection makes σ2/σ1 smooth.

mod common;

use common::{path_str, python, scratch, shared_data};
use meshatlas::atlas::{Atlas, AtlasOptions, build_atlas, write_atlas_msh};
use meshatlas::geom::orient2d;
use meshatlas::io::{LoadOptions, load_path};
use meshatlas::mesh::{FaceId, TriMesh};
use meshatlas::progress::Progress;
use std::fs::File;

const REMESH: &str = r#"
path, h = sys.argv[1], float(sys.argv[2])
gmsh.initialize(["-nt", "1"])
gmsh.option.setNumber("General.Terminal", 0)
gmsh.open(path)
n_surf = len(gmsh.model.getEntities(2))
gmsh.model.mesh.clear()
gmsh.option.setNumber("Mesh.MeshSizeMax", h)
gmsh.option.setNumber("Mesh.MeshSizeMin", 0.1 * h)
gmsh.model.mesh.generate(2)
empty = 0
n_tri = 0
for (_, s) in gmsh.model.getEntities(2):
    types, etags, _ = gmsh.model.mesh.getElements(2, s)
    n = int(sum(len(t) for t in etags))
    n_tri += n
    empty += (n == 0)
print(json.dumps({"surfaces": n_surf, "triangles": n_tri, "empty_surfaces": empty}))
gmsh.finalize()
"#;

/// Every input triangle is covered by atlas triangles of exactly one patch
/// with the same area, and every parametric triangle is positive.
fn check_atlas(name: &str, input: &TriMesh, a: &Atlas) {
    let mut patch_of_input = vec![u32::MAX; input.n_faces()];
    let mut area = vec![0.0; input.n_faces()];
    for (f, s) in a.source_face.iter().enumerate() {
        let p = a.patch_per_face[f];
        assert!(
            patch_of_input[s.idx()] == u32::MAX || patch_of_input[s.idx()] == p,
            "{name}: input triangle {s} in two patches"
        );
        patch_of_input[s.idx()] = p;
        area[s.idx()] += a.mesh.face_area(FaceId::new(f));
    }
    for f in 0..input.n_faces() {
        assert_ne!(patch_of_input[f], u32::MAX, "{name}: input triangle {f} in no patch");
        let a0 = input.face_area(FaceId::new(f));
        assert!((area[f] - a0).abs() <= 1e-9 * a0.max(1e-300) + 1e-300, "{name}: area of triangle {f} changed");
    }
    for p in &a.patches {
        for t in &p.triangles {
            let [x, y, z] = t.map(|v| p.uv[v as usize]);
            assert!(orient2d(&x, &y, &z) > 0.0, "{name}: flipped (u, v) triangle in patch {}", p.report.id);
        }
    }
}

/// Load, build the atlas, check it, write it and let Gmsh remesh it.
fn corpus_case(file: &str) {
    let path = shared_data().join("corpus").join(file);
    let loaded = load_path(&path, None, &LoadOptions::default()).unwrap_or_else(|e| panic!("{file}: {e}"));
    let mesh = loaded.surface;
    let atlas =
        build_atlas(&mesh, &AtlasOptions::default(), &Progress::none()).unwrap_or_else(|e| panic!("{file}: {e}"));
    check_atlas(file, &mesh, &atlas);
    let dir = scratch("atlas_corpus", file);
    let msh = dir.join("atlas.msh");
    write_atlas_msh(&atlas, File::create(&msh).unwrap()).unwrap();
    let diag = mesh.bounding_box().unwrap().diagonal();
    let r = python(REMESH, &[path_str(&msh), &(diag / 30.0).to_string()]);
    assert_eq!(r["surfaces"].as_u64().unwrap() as usize, atlas.patches.len(), "{file}");
    assert!(r["triangles"].as_u64().unwrap() > 0, "{file}: Gmsh produced no triangle");
    assert_eq!(r["empty_surfaces"].as_u64().unwrap(), 0, "{file}: Gmsh left a patch empty: {r}");
}

macro_rules! corpus_tests {
    ($($name:ident => $file:literal),* $(,)?) => {
        $(#[test] fn $name() { corpus_case($file); })*
    };
}

corpus_tests! {
    adis16480 => "adis16480.stl",
    aorta_closed => "aorta_closed.stl",
    bunny => "bunny.obj",
    camelhead => "camelhead.obj",
    cow => "cow.obj",
    cylinder_coarse => "cylinder_coarse.stl",
    fandisk => "fandisk.obj",
    fault_opal_mound => "fault_opal_mound.obj",
    fault_ridgecrest_2019 => "fault_ridgecrest_2019.obj",
    fault_santa_monica_bay => "fault_santa_monica_bay.obj",
    featuretype => "featuretype.stl",
    gmsh_aorta2 => "gmsh_aorta2.stl",
    gmsh_lever => "gmsh_lever.stl",
    gmsh_object => "gmsh_object.stl",
    gmsh_t13 => "gmsh_t13.stl",
    gmsh_terrain => "gmsh_terrain.stl",
    plate_holes => "plate_holes.stl",
    spot => "spot.obj",
}

#[test]
fn every_corpus_file_has_a_test() {
    let mut files: Vec<String> = std::fs::read_dir(shared_data().join("corpus"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|f| !f.ends_with(".md"))
        .collect();
    files.sort();
    let src = include_str!("atlas_corpus.rs");
    for f in files {
        assert!(src.contains(&format!("=> \"{f}\"")), "no atlas test for corpus file {f}");
    }
}

#[test]
fn bisection_smooths_the_coarse_cylinder() {
    // Thesis ch. 2 §5.1: a coarse CAD cylinder has no interior vertex, so
    // σ2/σ1 jumps from triangle to triangle; longest-edge bisection first
    // makes it smooth. Smoothness = median |Δ σ2/σ1| across inner edges.
    let path = shared_data().join("corpus/cylinder_coarse.stl");
    let mesh = load_path(&path, None, &LoadOptions::default()).unwrap().surface;
    let run = |refine_below_interior_fraction| {
        let opts = AtlasOptions { refine_below_interior_fraction, ..Default::default() };
        let a = build_atlas(&mesh, &opts, &Progress::none()).unwrap();
        check_atlas("cylinder_coarse", &mesh, &a);
        a
    };
    let before = run(0.0);
    let after = run(AtlasOptions::default().refine_below_interior_fraction);
    assert_eq!(before.patches.len(), after.patches.len());
    assert!(after.report.n_refined_patches > 0);
    // The curved side is the refined patch (the planar caps are left alone:
    // Gmsh meshes planar patches by projection). Patches come in the same
    // order in both runs: refinement happens after splitting.
    let side = after.patches.iter().position(|p| p.report.n_bisections > 0).expect("a refined patch");
    let (b, a) = (&before.patches[side].report, &after.patches[side].report);
    assert_eq!(b.n_input_triangles, a.n_input_triangles);
    let (jb, ja) = (b.sigma_ratio_jump_median, a.sigma_ratio_jump_median);
    eprintln!(
        "cylinder_coarse side: median σ-jump {jb:.4} → {ja:.4}; σ2/σ1 min {:.4} → {:.4}, median {:.4} → {:.4}; triangles {} → {}",
        b.sigma_ratio_min, a.sigma_ratio_min, b.sigma_ratio_median, a.sigma_ratio_median, b.n_triangles, a.n_triangles
    );
    assert!(ja < 0.5 * jb, "bisection did not smooth σ2/σ1: {jb} → {ja}");
}
