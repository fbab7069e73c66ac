use meshatlas::atlas::mvc::{MvcSolver, mean_value_parameterization};
use meshatlas::atlas::patch::PatchMesh;
use meshatlas::mesh::{FaceId, fixtures};
use std::time::Instant;
fn main() {
    meshatlas::linalg::use_sequential_kernels();
    let which = std::env::args().nth(1).unwrap_or_default();
    let m = fixtures::icosphere(7);
    let faces: Vec<FaceId> = (0..m.n_faces())
        .filter(|&f| m.corners(FaceId::new(f)).iter().all(|c| c.z > 0.4))
        .map(FaceId::new)
        .collect();
    let p = PatchMesh::extract(&m, &faces);
    let loops = p.loops_longest_first();
    let solver = if which == "lu" {
        MvcSolver::Lu
    } else {
        MvcSolver::Bicgstab
    };
    if which == "none" {
        return;
    }
    let t = Instant::now();
    let r = mean_value_parameterization(&p, &loops, 100, solver).unwrap();
    println!(
        "{solver:?}: {:.3}s iters {:?}",
        t.elapsed().as_secs_f64(),
        r.iterations
    );
}
