//! Sparse linear algebra: triplet assembly and factorizations reused across
//! right-hand sides and Newton steps.
//!
//! Matrices are assembled from `(row, col, value)` triplets (duplicates are
//! summed) into faer's compressed sparse column format. A [`Pattern`] keeps
//! the symbolic structure and the triplet → slot order, so a matrix with the
//! same triplet sequence but new values is rebuilt without sorting again, and
//! a factorization's symbolic phase is reused ([`CholeskySolver::refactor`]).
//!
//! Solvers (chosen by measurement on 2 cores, `docs/decisions.md`): faer
//! sparse LU for non-symmetric systems (mean value coordinates), faer sparse
//! LLᵀ for SPD systems, both with `Par::Seq` inside job workers; one
//! conjugate-gradient loop ([`cg`]) for every SPD iterative solve and
//! BiCGSTAB ([`krylov`]) for the non-symmetric ones.

pub mod assembly;
pub mod cg;
pub mod error;
pub mod krylov;
pub mod ordering;
pub mod solvers;
pub mod supernodal;
pub mod supernodal_lu;
pub mod trisolve;

pub use assembly::{Pattern, Triplets};
pub use cg::{BlockRow, CgOptions, conjugate_gradients};
pub use error::LinalgError;
pub use krylov::{KrylovReport, bicgstab, bicgstab_block, sparse_matvec};
pub use solvers::{CholeskySolver, LuSolver};
pub use supernodal::{FillOrdering, SupernodalCholesky};
pub use supernodal_lu::SupernodalLu;

/// A sparse matrix in compressed column form.
pub type SparseMatrix = faer::sparse::SparseColMat<usize, f64>;

/// Run faer's sparse kernels sequentially. The job pool already
/// parallelizes across patches and jobs, on two cores the nested parallelism
/// was slower (`docs/decisions.md`), and sequential kernels make every
/// result independent of the thread count (parallel reductions round
/// differently). Called by the solvers themselves before their first
/// factorization; calling it at start-up too is harmless.
pub fn use_sequential_kernels() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| faer::set_global_parallelism(faer::Par::Seq));
}
