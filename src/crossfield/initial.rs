//! Initial field of the continuation: the smoothest field compatible with
//! the constraints, normalized to `|f| = 1`.
//!
//! - Components with aligned edges: the minimizer of the Dirichlet energy
//!   (plus the weak term, if any) with the aligned values, i.e. the
//!   "Laplacian smoothing" of thesis §4.2 with the connection Laplacian of
//!   the CR discretization. One linear solve.
//! - Components without any aligned edge (closed surfaces without
//!   features): the Dirichlet energy has no preferred field and `f = 0` is a
//!   critical point of the GL energy, so we take the eigenvector of the
//!   smallest eigenvalue of the connection Laplacian (`A x = λ M x`, `M` the
//!   CR mass): the globally smoothest unit-L² field (Knöppel et al. 2013).
//!   Inverse iteration reuses the factorization of the Laplace solve. It
//!   needs no pinned edge, so no edge is privileged (the thesis pins a
//!   random one).
//!
//! Both are good starting points for the continuation: at large ε the GL
//! minimizer is close to a scaled smoothest field, and the zeros of that
//! field are where the singularities are born.

use super::CrossfieldError;
use super::energy::{EnergyParams, HessianKind};
use super::frames::{C64, Discretization};
use super::newton::NewtonSolver;
use crate::mesh::Topology;
use crate::mesh::components::face_components;

/// Maximum inverse iterations for the eigenvector.
const MAX_INVERSE_ITERATIONS: usize = 50;
/// Relative change of the Rayleigh quotient that stops the inverse iteration.
/// The quotient converges like the square of the vector, so 10⁻⁵ leaves the
/// starting field within ~0.3 % of the eigenspace, plenty for an initial
/// guess; a tighter value spends every solve on a nearly degenerate lowest
/// eigenspace for the same result (`docs/decisions.md`).
const RAYLEIGH_TOLERANCE: f64 = 1e-5;

/// Which initial field was computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitialKind {
    /// Constrained Laplace solve everywhere.
    Laplace,
    /// Smallest eigenvector everywhere (no aligned edge at all), with its
    /// eigenvalue `λ₁` (1/length²).
    Eigenvector(f64),
    /// Laplace on constrained components, eigenvector on the others (`λ₁`).
    Mixed(f64),
}

/// Deterministic pseudo-random value in `[-1, 1)` (splitmix64 of `i`).
fn hash_unit(i: u64) -> f64 {
    let mut z = i.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// Compute the initial field into `f` (fixed edges must already hold their
/// value; free edges are overwritten). `constrained[e]` marks edges that are
/// fixed or carry the weak term.
///
/// # Errors
/// Linear-solver failures.
pub fn initial_field(
    solver: &mut NewtonSolver,
    f: &mut [C64],
    params: &EnergyParams,
    constrained: &[bool],
) -> Result<InitialKind, CrossfieldError> {
    let topo: &Topology = solver.topo;
    let disc: &Discretization = solver.disc;
    let sys = solver.sys;
    let n = sys.n_dofs();
    for &e in &sys.free_edges {
        f[e as usize] = C64::new(0.0, 0.0);
    }
    // Which faces belong to a component with a constraint.
    let comps = face_components(topo, |_| false);
    let mut comp_constrained = vec![false; comps.n_components];
    for (e, &c) in constrained.iter().enumerate() {
        if c {
            for &fc in topo.edge_faces(crate::mesh::EdgeId::new(e)) {
                comp_constrained[comps.component_per_face[fc.idx()] as usize] = true;
            }
        }
    }
    let edge_constrained_comp = |e: usize| {
        topo.edge_faces(crate::mesh::EdgeId::new(e))
            .first()
            .is_some_and(|fc| comp_constrained[comps.component_per_face[fc.idx()] as usize])
    };
    let quad = EnergyParams { inv_eps2: 0.0, ..*params };
    // Dirichlet (+ weak) Hessian and gradient at f_free = 0: one Newton step solves the quadratic.
    let asm = sys.assemble(topo, disc, f, &quad, HessianKind::Exact);
    // Shifted by a small multiple of the mass so that unconstrained components are regular.
    let values = asm.hess_values;
    let mass = solver.dof_mass();
    let diag = sys.diagonal(&values);
    let mean_diag = diag.iter().sum::<f64>() / diag.len().max(1) as f64;
    let mean_mass = mass.iter().sum::<f64>() / mass.len().max(1) as f64;
    let sigma = 1e-6 * mean_diag / mean_mass.max(f64::MIN_POSITIVE);
    solver.factor(values, &mass, sigma)?;
    let mut x: Vec<f64> = asm.grad.iter().map(|g| -g).collect();
    solver.solve(&mut x)?;
    let any_constrained = comp_constrained.iter().any(|&c| c);
    let any_free = comp_constrained.iter().any(|&c| !c);
    let mut lambda1 = 0.0;
    if any_free {
        // Inverse iteration on the unconstrained components only (the
        // operator is block diagonal across components, so the iterate stays there).
        let mut y: Vec<f64> = (0..n)
            .map(|i| {
                let e = sys.free_edges[i / 2] as usize;
                if edge_constrained_comp(e) { 0.0 } else { hash_unit(i as u64) }
            })
            .collect();
        let norm_m = |v: &[f64]| v.iter().zip(&mass).map(|(a, m)| a * a * m).sum::<f64>().sqrt();
        let mut rq_old = f64::INFINITY;
        let mut rq = f64::INFINITY;
        for _ in 0..MAX_INVERSE_ITERATIONS {
            let nm = norm_m(&y);
            if nm == 0.0 {
                break;
            }
            let mut z: Vec<f64> = y.iter().zip(&mass).map(|(a, m)| a * m / nm).collect();
            solver.solve(&mut z)?;
            // Rayleigh quotient estimate of the shifted operator: ‖y‖²_M / ⟨y, z⟩_M-ish.
            let yz: f64 = y.iter().zip(&z).zip(&mass).map(|((a, b), m)| a * b * m).sum::<f64>() / nm;
            rq = if yz != 0.0 { 1.0 / yz } else { f64::INFINITY };
            y = z;
            if (rq - rq_old).abs() <= RAYLEIGH_TOLERANCE * rq.abs() {
                break;
            }
            rq_old = rq;
        }
        for (xi, yi) in x.iter_mut().zip(&y) {
            *xi += yi;
        }
        lambda1 = (rq - sigma).max(0.0);
    }
    for (i, &e) in sys.free_edges.iter().enumerate() {
        let z = C64::new(x[2 * i], x[2 * i + 1]);
        let m = z.norm();
        f[e as usize] = if m > 0.0 { z / m } else { C64::new(1.0, 0.0) };
    }
    Ok(match (any_constrained, any_free) {
        (true, false) => InitialKind::Laplace,
        (false, _) => InitialKind::Eigenvector(lambda1),
        (true, true) => InitialKind::Mixed(lambda1),
    })
}

/// A field aligned with the principal curvature directions, per edge
/// (normalized; `1` where the curvature is isotropic to round-off).
///
/// Per triangle the discrete curvature tensor is the sum over its edges of
/// `β_e ℓ_e ê⊗ê` (signed dihedral angle `β_e`, the edge-based tensor of
/// Cohen-Steiner & Morvan); its anisotropic part is the complex number
/// `z = Σ_e β_e ℓ_e exp(2iα_e)` in the triangle frame, whose argument is
/// twice a principal angle. A cross (N = 4) or asterisk (N = 6) with one
/// branch along that axis is `exp(i N arg(z)/2)`; it is weighted by `|z|`,
/// averaged over the two triangles of each edge (transported to the edge
/// frame) and normalized. Used as a second candidate on closed surfaces
/// without features, where it has no singularity when the surface has no
/// umbilic (a torus), unlike the smoothest eigenvector.
///
/// Also returns the anisotropy `Σ_T |z_T| / Σ_T Σ_e |β_e| ℓ_e ∈ [0, 1]`: 0 on
/// an umbilic surface (sphere, where the directions are discretization
/// noise), large when the principal directions are well defined.
pub fn principal_curvature_field(
    mesh: &crate::mesh::TriMesh,
    topo: &Topology,
    disc: &Discretization,
) -> (Vec<C64>, f64) {
    use crate::mesh::{EdgeId, FaceId};
    let n_half = disc.symmetry / 2;
    // Signed dihedral angle per edge (0 on boundary and non-manifold edges).
    let beta: Vec<f64> = (0..topo.n_edges())
        .map(|e| {
            let e = EdgeId::new(e);
            let [f, g] = match topo.edge_faces(e) {
                [f, g] => [*f, *g],
                _ => return 0.0,
            };
            let (nf, ng) = (mesh.face_normal(f), mesh.face_normal(g));
            let i = topo.local_edge(f, e).unwrap_or(0);
            let t = mesh.triangles[f.idx()];
            let d = mesh.positions[t[(i + 1) % 3].idx()] - mesh.positions[t[i].idx()];
            let l = d.norm();
            if l == 0.0 {
                return 0.0;
            }
            nf.cross(&ng).dot(&(d / l)).atan2(nf.dot(&ng))
        })
        .collect();
    let mut q = vec![C64::new(0.0, 0.0); topo.n_edges()];
    let (mut sum_z, mut sum_b) = (0.0, 0.0);
    for (t, fe) in topo.face_edges.iter().enumerate() {
        let (r, nrm) = super::frames::face_frame(mesh, FaceId::new(t));
        let tt = nrm.cross(&r);
        let mut z = C64::new(0.0, 0.0);
        for e in fe {
            let d = super::frames::edge_direction(mesh, topo, *e);
            let a = C64::new(d.dot(&r), d.dot(&tt));
            z += a * a * (beta[e.idx()] * disc.length_per_edge[e.idx()]);
            sum_b += (beta[e.idx()] * disc.length_per_edge[e.idx()]).abs();
        }
        let m = z.norm();
        sum_z += m;
        if m == 0.0 {
            continue;
        }
        let cross = super::frames::complex_pow(z / m, n_half) * m;
        for (k, e) in fe.iter().enumerate() {
            q[e.idx()] += disc.faces[t].rot[k].conj() * cross;
        }
    }
    let max = q.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let field = q
        .iter()
        .map(|z| {
            let m = z.norm();
            if m > 1e-12 * max && m > 0.0 { z / m } else { C64::new(1.0, 0.0) }
        })
        .collect();
    (field, if sum_b > 0.0 { sum_z / sum_b } else { 0.0 })
}
