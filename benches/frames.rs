//! Benchmark of the frames stage on balls: tetrahedra per second of the
//! whole stage (volume, field, singular edges) and peak memory.
//!
//! ```text
//! cargo bench --bench frames -- [target_tets ...]
//! ```
//! Default targets: 100000 1000000. The lattice spacing is chosen from the
//! estimate `12 V / h³` tetrahedra. Peak memory is `VmHWM` of
//! `/proc/self/status` (Linux), so run one target per process to measure
//! each one's peak (`-- 1000000`). `FRAMES_SOLVER=cholesky` or `pcg` forces
//! the linear solver.

use meshatlas::frames::{FramesOptions, compute_frame_field};
use meshatlas::mesh::fixtures;
use meshatlas::progress::Progress;
use std::time::Instant;

fn vm_hwm_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

fn main() {
    let targets: Vec<f64> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let targets = if targets.is_empty() { vec![1e5, 1e6] } else { targets };
    meshatlas::linalg::use_sequential_kernels();
    let sphere = fixtures::icosphere(5);
    let volume = sphere.signed_volume().abs();
    println!("rayon threads: {}", rayon::current_num_threads());
    for n in targets {
        let h = (12.0 * volume / n).cbrt();
        // FRAMES_SOLVER=cholesky|pcg forces the linear solver (default: automatic).
        let linear_solver =
            std::env::var("FRAMES_SOLVER").ok().and_then(|s| serde_json::from_str(&format!("\"{s}\"")).ok());
        let opts =
            FramesOptions { target_size: Some(h), max_tets: (2.0 * n) as usize, linear_solver, ..Default::default() };
        let t = Instant::now();
        let field = match compute_frame_field(&sphere, None, &opts, &Progress::none()) {
            Ok(f) => f,
            Err(e) => {
                eprintln!("target {n}: {e}");
                continue;
            }
        };
        let secs = t.elapsed().as_secs_f64();
        let r = &field.report;
        println!(
            "target {n:>9.0}: {} tets, {} vertices, {:.2} s, {:.0} tets/s, VmHWM {:.0} MB",
            r.tets,
            r.vertices,
            secs,
            r.tets as f64 / secs,
            vm_hwm_mb().unwrap_or(f64::NAN)
        );
        let s = &r.seconds;
        println!(
            "  volume {:.2} s, constraints {:.2}, operators {:.2}, field {:.2} (factor {:.2}, solve {:.2}, project {:.2}), invariants {:.2}, tet frames {:.2}, singular {:.2}",
            s.volume,
            s.constraints,
            s.operators,
            s.field,
            s.factor,
            s.solve,
            s.project,
            s.invariants,
            s.tet_frames,
            s.singular
        );
        println!(
            "  {:?}, {} PCG iterations, {} levels, {} steps, energy {:.4} -> {:.4}; singular: {} valence 3, {} valence 5, {} complex, {} curves, {} dangling; min dihedral {:.1} deg",
            r.linear_solver,
            r.pcg_iterations,
            r.levels,
            r.iterations,
            r.energy_before,
            r.energy_after,
            r.singular.n_valence3,
            r.singular.n_valence5,
            r.singular.n_complex,
            r.singular.n_curves,
            r.singular.n_dangling_interior_ends,
            r.volume.min_dihedral_deg
        );
    }
}
