//! Preview bench (issue 15): wall time and PNG bytes of `preview.png` and
//! `atlas.png` on spheres of about 200k and 1M triangles, drawn whole (what
//! the pipeline does) and, for comparison, from a `mesh::decimate` copy of
//! 100k triangles (decimation time shown on its own row).
//!
//! ```sh
//! cargo bench --bench previews -- [N_TRIANGLES ...]   # default 200000 1000000
//! ```
//!
//! Each timing is the best of three runs (the host is shared). The
//! pipeline bench (`benches/pipeline.rs`) prints every stage's
//! `<stage>.preview` row from a whole job.

use std::time::Instant;

use meshatlas::atlas::{AtlasOptions, build_atlas};
use meshatlas::mesh::decimate::decimate;
use meshatlas::mesh::{Topology, TriMesh, fixtures};
use meshatlas::preview::{Image, PreviewSize, atlas_patch_colors, atlas_preview, input_preview};
use meshatlas::progress::Progress;

/// Triangles of the decimated copy timed for comparison.
const DECIMATED_FACES: usize = 100_000;

/// A cube grid projected on the unit sphere, `12·k²` triangles near `n`.
fn sphere(n: usize) -> TriMesh {
    let k = ((n as f64 / 12.0).sqrt().round() as usize).max(1);
    let mut m = fixtures::cube(k);
    for p in &mut m.positions {
        *p = p.normalize();
    }
    m
}

/// Best wall seconds of three runs of `f`, and its last result.
fn best_of_three<T>(mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..3 {
        let start = Instant::now();
        out = Some(f());
        best = best.min(start.elapsed().as_secs_f64());
    }
    (best, out.expect("three runs"))
}

/// PNG bytes of `img`.
fn png_bytes(img: &Image) -> usize {
    let mut v = Vec::new();
    img.write_png(&mut v).expect("encode");
    v.len()
}

/// Prints one row.
fn row(tris: usize, what: &str, seconds: f64, bytes: Option<usize>) {
    let size = bytes.map_or_else(String::new, |b| format!("{:.2} MB", b as f64 / 1e6));
    println!("{tris:>9} {what:<34} {seconds:>9.3} s {size:>10}");
}

fn main() {
    let sizes: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let sizes = if sizes.is_empty() { vec![200_000, 1_000_000] } else { sizes };
    let size = PreviewSize::default();
    println!("{:>9} {:<34} {:>11} {:>10}", "triangles", "step", "wall", "png");
    for n in sizes {
        let mesh = sphere(n);
        let tris = mesh.n_faces();
        let (t, img) = best_of_three(|| input_preview(&mesh, &[], size).expect("preview"));
        let (te, bytes) = best_of_three(|| png_bytes(&img));
        row(tris, "preview.png draw (whole)", t, None);
        row(tris, "preview.png encode", te, Some(bytes));

        let topo = Topology::new(&mesh);
        let locked = vec![false; topo.n_edges()];
        let (td, coarse) = best_of_three(|| decimate(&mesh, &topo, &locked, DECIMATED_FACES, f64::INFINITY).unwrap());
        row(tris, "mesh::decimate to 100k", td, None);
        let (tc, _) = best_of_three(|| input_preview(&coarse.mesh, &[], size).expect("preview"));
        row(tris, "preview.png draw (decimated)", tc, None);

        let atlas = build_atlas(&mesh, &AtlasOptions::default(), &Progress::none()).expect("atlas");
        let (tp, colors) = best_of_three(|| atlas_patch_colors(&atlas));
        row(tris, "atlas patch colours", tp, None);
        let (ta, img) = best_of_three(|| atlas_preview(&atlas, &colors, size).expect("atlas preview"));
        row(tris, "atlas.png draw (whole)", ta, Some(png_bytes(&img)));
    }
}
