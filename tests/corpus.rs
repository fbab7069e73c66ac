//! Every file of the real-mesh corpus loads, and what loading and repair
//! report matches `/work/shared/data/corpus/INDEX.md` (computed there by an
//! independent tool). The expectations are one table below; the corpus
//! directory can be moved with `MESHATLAS_CORPUS`.

use meshatlas::io::{Format, LoadOptions, load_path};
use meshatlas::mesh::Topology;
use meshatlas::mesh::orientation::n_inconsistent_edges;
use std::path::PathBuf;

/// Expected state after loading with the default options (tolerance weld 1e-6·D).
struct Expect {
    file: &'static str,
    format: Format,
    /// INDEX "Tris" (no corpus triangle is removed by repair).
    tris: usize,
    /// INDEX "Verts" (referenced ones; after the tolerance weld where INDEX gives it).
    verts: usize,
    closed: bool,
    loops: usize,
    comps: usize,
    chi: i64,
    genus: Option<i64>,
    /// INDEX notes: unreferenced vertices, non-manifold vertices, reversed-outward components.
    unreferenced: usize,
    nm_vertices: usize,
    reversed: usize,
    /// Vertices merged by the tolerance weld (0 unless INDEX reports cracks).
    tol_welded: usize,
}

#[rustfmt::skip]
const CORPUS: &[Expect] = &[
    Expect { file: "gmsh_t13.stl",               format: Format::Stl, tris: 1580,  verts: 788,   closed: true,  loops: 0,  comps: 1,  chi: -2,  genus: Some(2),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "gmsh_lever.stl",             format: Format::Stl, tris: 774,   verts: 377,   closed: true,  loops: 0,  comps: 1,  chi: -10, genus: Some(6),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "gmsh_object.stl",            format: Format::Stl, tris: 710,   verts: 357,   closed: true,  loops: 0,  comps: 1,  chi: 2,   genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 2 },
    Expect { file: "fandisk.obj",                format: Format::Obj, tris: 12946, verts: 6475,  closed: true,  loops: 0,  comps: 1,  chi: 2,   genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "featuretype.stl",            format: Format::Stl, tris: 3476,  verts: 1722,  closed: true,  loops: 0,  comps: 1,  chi: -16, genus: Some(9),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 288 },
    Expect { file: "plate_holes.stl",            format: Format::Stl, tris: 1252,  verts: 618,   closed: true,  loops: 0,  comps: 1,  chi: -8,  genus: Some(5),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "adis16480.stl",              format: Format::Stl, tris: 7436,  verts: 3672,  closed: true,  loops: 0,  comps: 1,  chi: -46, genus: Some(24), unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "cylinder_coarse.stl",        format: Format::Stl, tris: 416,   verts: 210,   closed: true,  loops: 0,  comps: 1,  chi: 2,   genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "bunny.obj",                  format: Format::Obj, tris: 69451, verts: 34834, closed: false, loops: 5,  comps: 1,  chi: -3,  genus: Some(0),  unreferenced: 1113, nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "spot.obj",                   format: Format::Obj, tris: 5856,  verts: 2930,  closed: true,  loops: 0,  comps: 1,  chi: 2,   genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "camelhead.obj",              format: Format::Obj, tris: 22704, verts: 11381, closed: false, loops: 1,  comps: 1,  chi: 1,   genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "cow.obj",                    format: Format::Obj, tris: 5804,  verts: 2903,  closed: false, loops: 0,  comps: 1,  chi: 1,   genus: None,     unreferenced: 0,    nm_vertices: 1, reversed: 0, tol_welded: 0 },
    Expect { file: "aorta_closed.stl",           format: Format::Stl, tris: 12932, verts: 6468,  closed: true,  loops: 0,  comps: 1,  chi: 2,   genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 1, tol_welded: 0 },
    Expect { file: "gmsh_aorta2.stl",            format: Format::Stl, tris: 12455, verts: 6278,  closed: false, loops: 5,  comps: 1,  chi: -3,  genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "gmsh_terrain.stl",           format: Format::Stl, tris: 3498,  verts: 1813,  closed: false, loops: 1,  comps: 1,  chi: 1,   genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "fault_santa_monica_bay.obj", format: Format::Obj, tris: 22596, verts: 11395, closed: false, loops: 1,  comps: 1,  chi: 1,   genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "fault_ridgecrest_2019.obj",  format: Format::Obj, tris: 25006, verts: 13389, closed: false, loops: 16, comps: 16, chi: 16,  genus: Some(0),  unreferenced: 0,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
    Expect { file: "fault_opal_mound.obj",       format: Format::Obj, tris: 3834,  verts: 2026,  closed: false, loops: 1,  comps: 1,  chi: 1,   genus: Some(0),  unreferenced: 3,    nm_vertices: 0, reversed: 0, tol_welded: 0 },
];

/// The two files whose cracks close only with the tolerance weld, as INDEX
/// describes them after an exact weld: (file, verts, boundary loops, χ, genus).
const EXACT_ONLY: &[(&str, usize, usize, i64, i64)] =
    &[("gmsh_object.stl", 359, 2, 0, 0), ("featuretype.stl", 2010, 16, -16, 1)];

fn corpus_dir() -> PathBuf {
    let dir = PathBuf::from(std::env::var("MESHATLAS_CORPUS").unwrap_or_else(|_| "/work/shared/data/corpus".into()));
    assert!(dir.join("INDEX.md").is_file(), "corpus not found at {} (set MESHATLAS_CORPUS)", dir.display());
    dir
}

#[test]
fn the_table_covers_every_corpus_file() {
    let dir = corpus_dir();
    let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "INDEX.md")
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = CORPUS.iter().map(|e| e.file.to_string()).collect();
    listed.sort();
    assert_eq!(on_disk, listed);
}

#[test]
fn every_corpus_file_loads_as_indexed() {
    let dir = corpus_dir();
    let mut failures = Vec::new();
    for e in CORPUS {
        let l = match load_path(&dir.join(e.file), None, &LoadOptions::default()) {
            Ok(l) => l,
            Err(err) => {
                failures.push(format!("{}: {err}", e.file));
                continue;
            }
        };
        let r = &l.repair;
        let got = (
            l.format,
            l.surface.n_faces(),
            l.surface.n_vertices(),
            r.closed,
            r.n_boundary_loops,
            r.n_components,
            r.euler_characteristic,
            r.genus,
            r.n_unreferenced_vertices_dropped,
            r.n_nonmanifold_vertices,
            r.n_components_reversed_outward,
            r.n_vertices_welded_tolerance,
        );
        let want = (
            e.format,
            e.tris,
            e.verts,
            e.closed,
            e.loops,
            e.comps,
            e.chi,
            e.genus,
            e.unreferenced,
            e.nm_vertices,
            e.reversed,
            e.tol_welded,
        );
        if got != want {
            failures.push(format!("{}: got {got:?}, want {want:?}", e.file));
        }
        // Nothing removed, everything consistent, closed surfaces outward.
        let removed =
            r.n_zero_area_triangles_removed + r.n_degenerate_triangles_removed + r.n_duplicate_triangles_removed;
        let topo = Topology::new(&l.surface);
        if removed != 0 || r.n_input_triangles != e.tris || n_inconsistent_edges(&l.surface, &topo) != 0 {
            failures.push(format!(
                "{}: removed {removed}, inconsistent orientation or input count {}",
                e.file, r.n_input_triangles
            ));
        }
        if e.closed && l.surface.signed_volume() <= 0.0 {
            failures.push(format!("{}: closed but signed volume {}", e.file, l.surface.signed_volume()));
        }
        if r.n_nonmanifold_edges != 0 || r.n_nonorientable_components != 0 || r.tolerance_weld_abandoned {
            failures.push(format!("{}: unexpected report {r:?}", e.file));
        }
        assert!(l.surface.validate().is_ok());
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn cracks_stay_open_with_the_exact_weld_only() {
    let dir = corpus_dir();
    let exact = LoadOptions { weld_tolerance: 0.0, ..LoadOptions::default() };
    for &(file, verts, loops, chi, genus) in EXACT_ONLY {
        let l = load_path(&dir.join(file), None, &exact).unwrap();
        let r = &l.repair;
        assert_eq!(
            (
                l.surface.n_vertices(),
                r.n_boundary_loops,
                r.euler_characteristic,
                r.genus,
                r.closed,
                r.weld_tolerance_abs
            ),
            (verts, loops, chi, Some(genus), false, 0.0),
            "{file}"
        );
    }
}

#[test]
fn stl_corner_counts_and_exact_welds_add_up() {
    let dir = corpus_dir();
    for e in CORPUS.iter().filter(|e| e.format == Format::Stl) {
        let l = load_path(&dir.join(e.file), None, &LoadOptions::default()).unwrap();
        let r = &l.repair;
        assert_eq!(r.n_input_vertices, 3 * e.tris, "{}", e.file);
        assert_eq!(
            r.n_input_vertices - r.n_vertices_welded_exact - r.n_vertices_welded_tolerance,
            e.verts,
            "{}",
            e.file
        );
    }
}
