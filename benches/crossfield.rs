//! Crossfield timings and singularity counts, side by side with Gmsh.
//!
//! ```text
//! cargo bench --bench crossfield -- [--gmsh] [-v] [--eps X] [--eps-h X] [--eps0 X]
//!     [--factor X] [--ctol X] [--n 6] [--weak] [--max-its N] [--single-level] INPUT...
//! ```
//! `-v` prints the levels, every Newton iteration and the singularities;
//! `--single-level` turns the multilevel continuation off.
//! INPUT is an STL/OBJ path or a fixture: `disk:RINGS`, `sphere:LEVEL`,
//! `torus:NMAJOR:NMINOR` (R = 1, r = 0.4), `lshape:N`, `square:N`.
//! With `--gmsh`, also times `gmsh.model.mesh.computeCrossField()` on the
//! same file (python3 with the gmsh module) and prints the ratio.

#[path = "../tests/crossfield_common/mod.rs"]
mod common;

use meshatlas::atlas::features::detect_features;
use meshatlas::crossfield::{BoundaryCondition, CrossfieldOptions, compute_crossfield};
use meshatlas::mesh::{Topology, TriMesh, fixtures};
use meshatlas::progress::Progress;
use std::path::Path;
use std::time::Instant;

fn load(spec: &str) -> TriMesh {
    let parts: Vec<&str> = spec.split(':').collect();
    let num = |i: usize| parts[i].parse::<usize>().expect("number");
    match parts[0] {
        "disk" => fixtures::disk(num(1)),
        "sphere" => fixtures::icosphere(num(1)),
        "torus" => fixtures::torus(1.0, 0.4, num(1), num(2)),
        "lshape" => fixtures::l_shape(num(1)),
        "square" => fixtures::square(num(1)),
        _ => common::load(Path::new(spec)),
    }
}

/// Seconds Gmsh 4.15 spends in `computeCrossField()` on `path`. Gmsh's
/// Python API segfaults right after the computation here (after its
/// "NL smooth" iterations converge), so the time is measured from a stamp
/// printed just before the call to the end of the process (marked `*`).
fn gmsh_seconds(path: &str) -> Option<(f64, bool)> {
    let script = format!(
        "import gmsh, time\ngmsh.initialize()\ngmsh.option.setNumber('General.Terminal', 0)\ngmsh.merge({path:?})\nprint('GMSH_START', time.time(), flush=True)\nt = time.time()\ngmsh.model.mesh.computeCrossField()\nprint('GMSH_SECONDS', time.time() - t, flush=True)\ngmsh.finalize()\n"
    );
    let out = std::process::Command::new("python3").arg("-c").arg(script).output().ok()?;
    let end = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).ok()?.as_secs_f64();
    let text = String::from_utf8_lossy(&out.stdout);
    let field = |key: &str| -> Option<f64> { text.lines().find_map(|l| l.strip_prefix(key))?.trim().parse().ok() };
    match field("GMSH_SECONDS ") {
        Some(s) => Some((s, false)),
        None => field("GMSH_START ").map(|s| (end - s, true)),
    }
}

fn main() {
    meshatlas::linalg::use_sequential_kernels();
    // `cargo bench` passes `--bench`; it is not ours.
    let mut args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    let mut opts = CrossfieldOptions::default();
    let mut gmsh = false;
    let mut verbose = false;
    let mut inputs = Vec::new();
    while !args.is_empty() {
        let a = args.remove(0);
        match a.as_str() {
            "--gmsh" => gmsh = true,
            "-v" => verbose = true,
            "--weak" => opts.boundary = BoundaryCondition::Weak,
            "--eps" => opts.epsilon = Some(args.remove(0).parse().expect("eps")),
            "--eps-h" => opts.epsilon_per_edge_length = args.remove(0).parse().expect("eps-h"),
            "--eps0" => opts.epsilon_start = Some(args.remove(0).parse().expect("eps0")),
            "--factor" => opts.continuation_factor = args.remove(0).parse().expect("factor"),
            "--ctol" => opts.continuation_tolerance = args.remove(0).parse().expect("ctol"),
            "--n" => opts.symmetry = args.remove(0).parse().expect("n"),
            "--max-its" => opts.max_newton_iterations = args.remove(0).parse().expect("max-its"),
            "--single-level" => opts.multilevel = false,
            _ => inputs.push(a),
        }
    }
    println!("| input | triangles | meshatlas s | Newton its | singularities | χ | index sum | gmsh s | ratio |");
    println!("|---|---:|---:|---:|---|---:|---:|---:|---:|");
    for input in inputs {
        let mesh = load(&input);
        let t0 = Instant::now();
        let topo = Topology::new(&mesh);
        let features = detect_features(&mesh, &topo, 40.0);
        let field =
            compute_crossfield(&mesh, &topo, &features.is_feature_edge, &opts, &Progress::none()).expect("crossfield");
        let secs = t0.elapsed().as_secs_f64();
        let counts: Vec<String> = field.report.singularity_counts.iter().map(|(k, v)| format!("{v}×{k}")).collect();
        let (g, ratio) = if gmsh && !input.contains(':') {
            match gmsh_seconds(&input) {
                Some((g, crashed)) => {
                    (format!("{g:.2}{}", if crashed { "*" } else { "" }), format!("{:.0}×", g / secs))
                }
                None => ("n/a".into(), "".into()),
            }
        } else {
            ("".into(), "".into())
        };
        println!(
            "| {input} | {} | {secs:.3} | {} | {} | {} | {} | {g} | {ratio} |",
            mesh.n_faces(),
            field.report.iterations,
            counts.join(" "),
            field.euler_characteristic,
            field.index_sum
        );
        if verbose {
            eprintln!(
                "eps schedule {:?}, init {}, modified steps {}, factorizations {}, CG iterations {}, candidates {:?} anisotropy {:.3}",
                field.report.epsilon_schedule,
                field.report.initial_guess,
                field.report.n_modified_steps,
                field.report.n_factorizations,
                field.report.n_krylov_iterations,
                field.report.candidate_energies,
                field.report.curvature_anisotropy
            );
            for l in &field.report.levels {
                eprintln!(
                    "  level {} faces {} edges {} eps {:?} its {} factorizations {} {:.3} s",
                    l.level, l.n_faces, l.n_edges, l.epsilon_schedule, l.iterations, l.n_factorizations, l.seconds
                );
            }
            for h in &field.report.history {
                eprintln!(
                    "  L{} eps {:.4} it {:2} res {:.3e} E {:.9} step {:.3} mu {:.0e} {} {}",
                    h.level,
                    h.epsilon,
                    h.iteration,
                    h.residual,
                    h.energy,
                    h.step,
                    h.shift,
                    h.hessian,
                    h.krylov_iterations
                );
            }
            for s in &field.singularities {
                eprintln!(
                    "  sing {:+.4} at ({:.4}, {:.4}, {:.4}) r={:.4}",
                    s.index,
                    s.position.x,
                    s.position.y,
                    s.position.z,
                    s.position.norm()
                );
            }
        }
    }
}
