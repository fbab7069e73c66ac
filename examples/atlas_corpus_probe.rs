use meshatlas::atlas::{AtlasOptions, build_atlas, write_atlas_msh};
use meshatlas::io::{LoadOptions, load_path};
use meshatlas::progress::Progress;
use std::time::Instant;
fn main() {
    meshatlas::linalg::use_sequential_kernels();
    let dir = std::path::Path::new("/work/shared/data/corpus");
    let mut files: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).filter(|p| p.extension().unwrap() != "md").collect();
    files.sort();
    for f in files {
        let m = load_path(&f, None, &LoadOptions::default()).unwrap().surface;
        let t = Instant::now();
        let a = build_atlas(&m, &AtlasOptions::default(), &Progress::none());
        let dt = t.elapsed().as_secs_f64();
        match a {
            Ok(a) => {
                let r = &a.report;
                let name = f.file_name().unwrap().to_str().unwrap();
                let out = std::path::Path::new("/tmp/probe").join(name);
                std::fs::create_dir_all(&out).unwrap();
                write_atlas_msh(&a, std::fs::File::create(out.join("atlas.msh")).unwrap()).unwrap();
                let minrel = r.patches.iter().map(|p| p.min_relative_uv_area).fold(f64::INFINITY, f64::min);
                println!("{name:32} tris {:7} -> {:7} patches {:4} curves {:4} corners {:4} refined {:3} splits {:?} sigma_min {:.2e} minrel {:.1e} {:.3}s",
                    m.n_faces(), a.mesh.n_faces(), r.n_patches, r.n_curves, r.n_corners, r.n_refined_patches, r.splits, r.sigma_ratio_min, minrel, dt);
            }
            Err(e) => println!("{:?}: ERROR {e}", f.file_name().unwrap()),
        }
    }
}
