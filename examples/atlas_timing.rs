use meshatlas::atlas::mvc::MvcSolver;
use meshatlas::atlas::{AtlasOptions, build_atlas};
use meshatlas::mesh::fixtures;
use meshatlas::progress::Progress;
use std::time::Instant;
fn main() {
    meshatlas::linalg::use_sequential_kernels();
    for (name, m) in [
        ("torus200k", fixtures::torus(1.0, 0.4, 500, 200)),
        ("sphere327k", fixtures::icosphere(7)),
    ] {
        for solver in [MvcSolver::Lu, MvcSolver::Bicgstab] {
            let opts = AtlasOptions {
                solver,
                ..Default::default()
            };
            let t = Instant::now();
            let a = build_atlas(&m, &opts, &Progress::none()).unwrap();
            let r = &a.report;
            println!(
                "{name} {solver:?}: {} tris -> {} patches in {:.3}s (features {:.3} patches {:.3} curves {:.3}); patch solves {:?} iters {:?}",
                m.n_faces(),
                r.n_patches,
                t.elapsed().as_secs_f64(),
                r.features_seconds,
                r.patches_seconds,
                r.curves_seconds,
                r.patches
                    .iter()
                    .map(|p| (p.n_triangles, (p.solve_seconds * 1000.0).round()))
                    .collect::<Vec<_>>(),
                r.patches
                    .iter()
                    .map(|p| p.krylov_iterations)
                    .collect::<Vec<_>>()
            );
        }
    }
    let s = std::fs::read_to_string("/proc/self/status").unwrap();
    println!("{}", s.lines().find(|l| l.starts_with("VmHWM")).unwrap());
}
