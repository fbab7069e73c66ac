//! The atlas artifacts open in Gmsh and meshio, and Gmsh remeshes `atlas.msh`.
//!
//! For each surface: build the atlas, write `atlas.msh`, `atlas.vtu` and
//! `atlas_uv.vtu`, then in a fresh Python process (a) open `atlas.msh` with
//! Gmsh, count its entities, clear the mesh and generate a new one with
//! `Mesh.MeshSizeMax = h` — it must succeed, cover every patch, and put its
//! nodes on the original surface; (b) read both VTU files with meshio.

mod common;

use common::{path_str, python, scratch};
use meshatlas::atlas::{Atlas, AtlasOptions, build_atlas, write_atlas_msh_as, write_atlas_uv_vtu, write_atlas_vtu};
use meshatlas::io::msh_output::OutputOptions;
use meshatlas::mesh::{TriMesh, fixtures};
use meshatlas::progress::Progress;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

const REMESH: &str = r#"
path, h = sys.argv[1], float(sys.argv[2])
gmsh.initialize(["-nt", "1"])
gmsh.option.setNumber("General.Terminal", 0)
gmsh.open(path)
ent = {d: len(gmsh.model.getEntities(d)) for d in range(3)}
gmsh.model.mesh.clear()
gmsh.option.setNumber("Mesh.MeshSizeMax", h)
gmsh.option.setNumber("Mesh.MeshSizeMin", 0.25 * h)
gmsh.model.mesh.generate(2)
tags, xyz, _ = gmsh.model.mesh.getNodes()
xyz = np.array(xyz).reshape(-1, 3)
per_surface = []
for (_, s) in gmsh.model.getEntities(2):
    types, etags, _ = gmsh.model.mesh.getElements(2, s)
    per_surface.append(int(sum(len(t) for t in etags)))
qual = []
for (_, s) in gmsh.model.getEntities(2):
    types, etags, _ = gmsh.model.mesh.getElements(2, s)
    for t in etags:
        if len(t):
            qual.extend(gmsh.model.mesh.getElementQualities(list(t), "minSICN"))
print(json.dumps({"entities": ent, "nodes": xyz.tolist(), "triangles_per_surface": per_surface,
                  "min_quality": float(min(qual)) if qual else -1.0}))
gmsh.finalize()
"#;

const MESHIO: &str = r#"
out = {}
for p in sys.argv[1:]:
    m = meshio.read(p)
    out[p] = {"points": len(m.points), "cells": {c.type: len(c.data) for c in m.cells},
              "cell_data": sorted(m.cell_data.keys()), "point_data": sorted(m.point_data.keys())}
print(json.dumps(out))
"#;

fn write_all(atlas: &Atlas, dir: &Path, opts: &OutputOptions) {
    write_atlas_msh_as(atlas, BufWriter::new(File::create(dir.join("atlas.msh")).unwrap()), opts).unwrap();
    write_atlas_vtu(atlas, BufWriter::new(File::create(dir.join("atlas.vtu")).unwrap())).unwrap();
    write_atlas_uv_vtu(atlas, BufWriter::new(File::create(dir.join("atlas_uv.vtu")).unwrap())).unwrap();
}

/// Build, write and remesh; `on_surface` is the distance of a point to the
/// exact surface. Returns the atlas for further checks.
fn remesh_check(name: &str, mesh: &TriMesh, h: f64, on_surface: impl Fn([f64; 3]) -> f64, tol: f64) -> Atlas {
    remesh_check_as(name, mesh, h, on_surface, tol, &OutputOptions::default())
}

/// [`remesh_check`] with `atlas.msh` written as `opts` say (binary or ASCII).
fn remesh_check_as(
    name: &str,
    mesh: &TriMesh,
    h: f64,
    on_surface: impl Fn([f64; 3]) -> f64,
    tol: f64,
    opts: &OutputOptions,
) -> Atlas {
    let atlas = build_atlas(mesh, &AtlasOptions::default(), &Progress::none()).unwrap();
    let dir = scratch("atlas_gmsh", name);
    write_all(&atlas, &dir, opts);
    let msh = dir.join("atlas.msh");
    let head = std::fs::read(&msh).unwrap()[..20].to_vec();
    let binary = opts.msh_binary == Some(true);
    assert_eq!(head.starts_with(b"$MeshFormat\n4.1 1 8\n"), binary, "{name}: binary header");
    let r = python(REMESH, &[path_str(&msh), &h.to_string()]);
    assert_eq!(r["entities"]["2"].as_u64().unwrap() as usize, atlas.patches.len(), "{name}: surfaces");
    assert_eq!(r["entities"]["1"].as_u64().unwrap() as usize, atlas.curves.len(), "{name}: curves");
    assert_eq!(r["entities"]["0"].as_u64().unwrap() as usize, atlas.corners.len(), "{name}: points");
    let per_surface: Vec<u64> =
        r["triangles_per_surface"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
    assert!(per_surface.iter().all(|&n| n > 0), "{name}: a patch was not remeshed: {per_surface:?}");
    let worst = r["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let c: Vec<f64> = p.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
            on_surface([c[0], c[1], c[2]])
        })
        .fold(0.0, f64::max);
    assert!(worst < tol, "{name}: remeshed node {worst} away from the surface");
    assert!(r["min_quality"].as_f64().unwrap() > 0.0, "{name}: inverted remeshed triangle");

    let vtu = dir.join("atlas.vtu");
    let uv = dir.join("atlas_uv.vtu");
    let m = python(MESHIO, &[path_str(&vtu), path_str(&uv)]);
    let a = &m[path_str(&vtu)];
    assert_eq!(a["cells"]["triangle"].as_u64().unwrap() as usize, atlas.mesh.n_faces());
    assert_eq!(a["points"].as_u64().unwrap() as usize, atlas.mesh.n_vertices());
    for key in ["patch", "sigma_ratio", "feature_curve"] {
        assert!(a["cell_data"].as_array().unwrap().iter().any(|k| k == key), "{name}: missing cell data {key}");
    }
    for key in ["curvature_max", "curvature_min", "direction_max", "direction_min"] {
        assert!(a["point_data"].as_array().unwrap().iter().any(|k| k == key), "{name}: missing point data {key}");
    }
    let u = &m[path_str(&uv)];
    let n_uv: usize = atlas.patches.iter().map(|p| p.uv.len()).sum();
    assert_eq!(u["points"].as_u64().unwrap() as usize, n_uv);
    assert_eq!(u["cells"]["triangle"].as_u64().unwrap() as usize, atlas.mesh.n_faces());
    atlas
}

#[test]
fn sphere_atlas_is_remeshed_by_gmsh() {
    let m = fixtures::icosphere(4);
    let a = remesh_check("sphere", &m, 0.15, |p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs(), 0.01);
    assert!(a.patches.len() >= 2);
}

#[test]
fn torus_atlas_is_remeshed_by_gmsh() {
    let (major, minor) = (1.0, 0.4);
    let m = fixtures::torus(major, minor, 60, 24);
    remesh_check(
        "torus",
        &m,
        0.12,
        |p| {
            let rho = (p[0] * p[0] + p[1] * p[1]).sqrt() - major;
            ((rho * rho + p[2] * p[2]).sqrt() - minor).abs()
        },
        0.01,
    );
}

#[test]
fn cube_atlas_is_remeshed_by_gmsh() {
    let m = fixtures::cube(6);
    let a = remesh_check("cube", &m, 0.3, |p| (p.iter().fold(0.0f64, |a, x| a.max(x.abs())) - 1.0).abs(), 1e-9);
    assert_eq!((a.patches.len(), a.curves.len(), a.corners.len()), (6, 12, 8));
}

#[test]
fn annulus_atlas_with_a_hole_is_remeshed_by_gmsh() {
    let m = fixtures::annulus(0.35, 1.0, 48, 8);
    remesh_check("annulus", &m, 0.08, |p| p[2].abs(), 1e-9);
}

#[test]
fn binary_atlas_msh_is_read_and_remeshed_by_gmsh() {
    // Gmsh reads `$Parametrizations` of a binary file (size_t counts, int
    // tags and triangle indices, double coordinates): the same checks as the
    // ASCII files above pass on the binary variant.
    let binary = OutputOptions { msh_binary: Some(true), ..OutputOptions::default() };
    let m = fixtures::cube(6);
    let a = remesh_check_as(
        "cube_binary",
        &m,
        0.3,
        |p| (p.iter().fold(0.0f64, |a, x| a.max(x.abs())) - 1.0).abs(),
        1e-9,
        &binary,
    );
    assert_eq!((a.patches.len(), a.curves.len(), a.corners.len()), (6, 12, 8));
    let m = fixtures::icosphere(4);
    remesh_check_as(
        "sphere_binary",
        &m,
        0.15,
        |p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs(),
        0.01,
        &binary,
    );
}
