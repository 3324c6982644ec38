//! Linear solves of the saddle-point matrix of eq. (5),
//!
//! ```text
//! K = [ A    Φ_qᵀ ]      A = M (index-1 form), or M·c_m + C·c_c + K_t (Newton
//!     [ Φ_q  D    ]      matrix of implicit methods); D = 0 or a regularisation
//! ```
//!
//! [`SaddleMatrix`] owns the fixed sparse pattern (built once per system) and
//! the values that each evaluation refills, in the [`Storage`] its solver
//! needs (lower triangle of a symmetric matrix, or every entry); formulations
//! register their `A` blocks once ([`APattern`], with their [`Symmetry`]) and
//! assemble through the same calls whatever the storage. Every solver
//! implements [`SaddlePointSolver`]: `analyze` once per pattern,
//! `factorize` per evaluation, `solve_in_place` per right-hand side, scratch
//! memory owned by the solver. [`solver_for`] is the one place a solver is
//! chosen:
//!
//! | [`SolverKind`] | solver | storage | use |
//! | --- | --- | --- | --- |
//! | `Auto`, `Sparse` | [`SparseLdlt`] (regularised sparse LDLᵀ) | symmetric | default everywhere |
//! | `Chain` | [`ChainLdlt`] (envelope LDLᵀ for chain patterns, else [`SparseLdlt`]) | symmetric | Newton matrix of `Index3` |
//! | `Dense` | [`DenseLu`] | symmetric | cross-checks |
//! | `SparseLu` | [`SparseLu`] | full | exact Newton with unsymmetric Jacobians |
//! | `ChainLu` | [`ChainLu`] (band LU with partial pivoting for chain patterns, else [`SparseLu`]) | full | static equilibrium, eigenmodes |
//! | `Schur` | [`SchurComplement`] (eq. (9), dense Cholesky) | symmetric | diagonal `A`, λ eliminated |
//!
//! Outside the trait, [`ComplexChainLdlt`] factorises the complex
//! symmetric matrices `K_r + i K_i` of a chain pattern (Radau IIA's
//! complex stage system, `Index3Complex`).
//!
//! Sign convention: we solve `M q̈ + Φ_qᵀ λ = g`, `Φ_q q̈ = γ`, i.e. the
//! unknown vector is `[q̈; λ]`. The paper's eq. (5) writes the same system
//! with unknowns `[q̈; −λ]`, so its multipliers are our `−λ`.

mod chain;
mod chain_complex;
mod dense;
mod lu;
mod pattern;
mod saddle;
mod schur;
mod sparse;

pub use chain::{
    ChainLdlt, ChainLu, DEFAULT_GROWTH_LIMIT, MAX_BANDWIDTH, PARALLEL_MIN_DIM, SPLIT_MIN_DIM,
};
pub use chain_complex::ComplexChainLdlt;
pub use dense::{full_pivot_order, DenseLu, PivotOrder};
pub use lu::SparseLu;
pub use pattern::CscPattern;
pub use saddle::{APattern, SaddleMatrix, Storage, Symmetry};
pub use schur::SchurComplement;
pub(crate) use sparse::{amd_permutation, postpone_multipliers};
pub use sparse::{
    chain_order, Ordering, SparseLdlt, DEFAULT_DELTA, DEFAULT_EPSILON, REFINE_THRESHOLD,
};

use crate::words::from_words;
use serde::Serialize;

/// Failure of a saddle-point factorisation or solve.
#[derive(Debug, Clone, thiserror::Error)]
pub enum LinalgError {
    /// The matrix is numerically singular (or the solution is not finite).
    #[error("saddle-point matrix is singular: {0}")]
    Singular(String),
    /// The solve produced a non-finite solution from a finite matrix and
    /// right-hand side: the matrix is singular or nearly so, or the
    /// solution overflows (the solver cannot tell these apart).
    #[error(
        "{0} produced a non-finite solution: the saddle-point matrix is singular or nearly so, \
         or the solution overflows (forces or accelerations beyond the range of doubles)"
    )]
    NonFiniteSolution(&'static str),
    /// A non-finite value was written into the matrix.
    #[error("non-finite entry in the saddle-point matrix at ({row}, {col})")]
    NonFinite {
        /// Row of the offending entry.
        row: usize,
        /// Column of the offending entry.
        col: usize,
    },
    /// `factorize`/`solve_in_place` called out of order.
    #[error("saddle-point solver used before {0}")]
    NotReady(&'static str),
    /// The matrix is not stored the way the solver needs.
    #[error("{solver} needs a matrix in {needs:?} storage")]
    Storage {
        /// The solver.
        solver: &'static str,
        /// The storage it needs.
        needs: Storage,
    },
    /// A length does not match the matrix.
    #[error("dimension mismatch: expected {expected}, got {got}")]
    Dimension {
        /// Expected length.
        expected: usize,
        /// Length received.
        got: usize,
    },
}

impl LinalgError {
    /// The checks before a solve: a factorisation in place (`factorized`,
    /// else [`LinalgError::NotReady`]) and `rhs` and `k` of the factorised
    /// dimension `dim` (else [`LinalgError::Dimension`] with `rhs`'s length).
    pub(crate) fn check_solve(
        factorized: bool,
        dim: usize,
        k: &SaddleMatrix,
        rhs: &[f64],
    ) -> Result<(), LinalgError> {
        if !factorized {
            return Err(LinalgError::NotReady("factorize"));
        }
        if rhs.len() != dim || k.dim() != dim {
            return Err(LinalgError::Dimension {
                expected: dim,
                got: rhs.len(),
            });
        }
        Ok(())
    }

    /// [`LinalgError::NonFiniteSolution`] of `solver` when the solution `x`
    /// has an entry that is not finite.
    pub(crate) fn check_solution(x: &[f64], solver: &'static str) -> Result<(), LinalgError> {
        match crate::numeric::first_non_finite(x) {
            Some(_) => Err(LinalgError::NonFiniteSolution(solver)),
            None => Ok(()),
        }
    }
}

/// What one numeric factorisation reports.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct FactorInfo {
    /// Pivots that had to be regularised (rank-deficient Φ_q, singular
    /// positions; or an indefinite `A`, below).
    pub regularized_pivots: usize,
    /// A pivot of a coordinate row had the wrong sign: the `A` block
    /// (`M` or the Newton matrix's `c_m M − c_c ∂g/∂q̇ − c_k ∂g/∂q + …`)
    /// was not positive definite, and the multipliers' pivots after it lose
    /// their expected sign too — not a sign of Φ_q losing rank. Reported
    /// by [`ChainLdlt`]; the other solvers leave it false.
    pub indefinite: bool,
}

/// Running counters of a solver.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct SolverStats {
    /// Symbolic analyses performed (should be 1 per pattern).
    pub analyses: usize,
    /// Numeric factorisations performed.
    pub factorizations: usize,
    /// Right-hand sides solved.
    pub solves: usize,
    /// Sum of regularised pivots over all factorisations.
    pub regularized_pivots: usize,
    /// Those of them in factorisations whose `A` block was indefinite
    /// ([`FactorInfo::indefinite`]).
    pub indefinite_pivots: usize,
    /// Steps of iterative refinement applied.
    pub refinements: usize,
}

/// A direct solver for the symmetric saddle-point matrix [`SaddleMatrix`].
///
/// The pattern is fixed: `analyze` is called once, then `factorize` whenever
/// the values change and `solve_in_place` for each right-hand side.
pub trait SaddlePointSolver: Send {
    /// Short name for summaries ("dense-lu", "sparse-ldlt", …).
    fn name(&self) -> &'static str;
    /// The [`Storage`] of the matrices this solver factorises (build the
    /// [`SaddleMatrix`] with it).
    fn storage(&self) -> Storage {
        Storage::SymmetricLower
    }
    /// Symbolic work for the pattern of `k` (orderings, elimination tree).
    fn analyze(&mut self, k: &SaddleMatrix) -> Result<(), LinalgError>;
    /// Numeric factorisation of the current values of `k`.
    fn factorize(&mut self, k: &SaddleMatrix) -> Result<FactorInfo, LinalgError>;
    /// Overwrite `rhs` with `K⁻¹ rhs` using the last factorisation of `k`.
    fn solve_in_place(&mut self, k: &SaddleMatrix, rhs: &mut [f64]) -> Result<(), LinalgError>;
    /// Counters since construction.
    fn stats(&self) -> SolverStats;
    /// Factorisations the solver handed to another one after rejecting its
    /// own ([`ChainLu`]'s fallback to [`SparseLu`]); 0 for the others.
    fn fallbacks(&self) -> usize {
        0
    }
}

/// Which saddle-point solver to use (scenario key `linear_solver`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// Dense below the measured [`AUTO_DENSE_MAX_DIM`], sparse from it on
    /// (the measurement found no size where dense wins: currently sparse).
    #[default]
    Auto,
    /// Dense LU with partial pivoting (faer); for cross-checks.
    Dense,
    /// Sparse LDLᵀ (faer) with symbolic analysis once per pattern.
    Sparse,
    /// Sparse LU (faer) of the full matrix: unsymmetric Newton matrices.
    SparseLu,
    /// [`ChainLu`]: LU with partial pivoting inside the band of the
    /// body-by-body order when the pattern is a chain, [`SparseLu`]
    /// otherwise; full storage, unsymmetric and indefinite matrices.
    ChainLu,
    /// λ eliminated by the Schur complement of a diagonal `A`, eq. (9).
    Schur,
    /// [`ChainLdlt`]: the envelope LDLᵀ when the pattern is a chain in
    /// body order, [`SparseLdlt`] otherwise (chosen at `analyze`).
    Chain,
}

/// Options passed to the solver [`solver_for`] creates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// Check the relative residual of each solve (and refine or reject);
    /// off for Newton corrections, which tolerate an inexact solve (the
    /// Newton residual is exact). Applies to [`SparseLdlt`].
    pub residual_check: bool,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            residual_check: true,
        }
    }
}

from_words!(SolverKind, "linear solver", "auto" => Auto, "sparse" => Sparse, "chain" => Chain,
    "dense" => Dense);

/// `SolverKind::Auto` uses the dense LU for saddle-point matrices of
/// dimension `n + m` below this and the sparse LDLᵀ from it on.
///
/// `cargo bench --bench saddle_point -- breakeven` finds no break-even:
/// `SparseLdlt` was faster than `DenseLu` at every size measured, from
/// dim 5 up (docs/linear_solvers.md). `DenseLu` pays an allocation and a
/// dense copy per factorisation that the sparse path has not, and it
/// rejects rank-deficient `Φ_q` where the sparse path regularises. So
/// `Auto` is sparse for every dimension (threshold 0); the constant stays
/// so that a faster dense kernel can reclaim tiny systems by re-measuring.
pub const AUTO_DENSE_MAX_DIM: usize = 0;

/// Create the solver of `kind` for a saddle-point matrix of dimension
/// `dim`: the one place a solver is chosen. Build the matrix in the
/// solver's [`SaddlePointSolver::storage`].
// The measured threshold is currently 0, which makes the `Auto` comparison
// always false; keep it so that re-measuring only changes the constant.
#[allow(clippy::absurd_extreme_comparisons)]
pub fn solver_for(kind: SolverKind, dim: usize, opts: SolverOptions) -> Box<dyn SaddlePointSolver> {
    let ldlt = || Box::new(SparseLdlt::default().with_residual_check(opts.residual_check));
    match kind {
        SolverKind::Dense => Box::new(DenseLu::default()),
        SolverKind::Sparse => ldlt(),
        SolverKind::Auto if dim < AUTO_DENSE_MAX_DIM => Box::new(DenseLu::default()),
        SolverKind::Auto => ldlt(),
        SolverKind::SparseLu => Box::new(SparseLu::default()),
        SolverKind::ChainLu => Box::new(ChainLu::default()),
        SolverKind::Schur => Box::new(SchurComplement::default()),
        SolverKind::Chain => {
            Box::new(ChainLdlt::default().with_residual_check(opts.residual_check))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every solver [`solver_for`] makes checks a solve alike: before a
    /// factorisation `NotReady("factorize")`, a right-hand side of another
    /// length `Dimension` with the expected and the given length, and
    /// after a factorisation the solution of `[diag(2, 1, 3), Φ_qᵀ; Φ_q, 0]`
    /// with `Φ_q = [1 0 1]` (by hand: `x = (−0.1, 2, 0.6)`, `λ = 1.2` for
    /// the right-hand side `(1, 2, 3, 0.5)`); a non-finite solution is
    /// `NonFiniteSolution` naming the solver.
    #[test]
    fn every_solver_checks_its_solves_alike() {
        use SolverKind::*;
        for kind in [Dense, Sparse, SparseLu, ChainLu, Schur, Chain] {
            let mut s = solver_for(kind, 4, SolverOptions::default());
            let mut k =
                SaddleMatrix::with_storage(3, 1, &APattern::new(), &[(0, 0), (0, 2)], s.storage());
            k.set_a_diagonal(&[2.0, 1.0, 3.0]);
            k.set_jacobian(&[1.0, 1.0]);
            s.analyze(&k).unwrap();
            let mut x = vec![1.0, 2.0, 3.0, 0.5];
            let early = s.solve_in_place(&k, &mut x);
            assert!(
                matches!(early, Err(LinalgError::NotReady("factorize"))),
                "{kind:?}: {early:?}"
            );
            s.factorize(&k).unwrap();
            let short = s.solve_in_place(&k, &mut [1.0; 3]);
            assert!(
                matches!(
                    short,
                    Err(LinalgError::Dimension {
                        expected: 4,
                        got: 3
                    })
                ),
                "{kind:?}: {short:?}"
            );
            s.solve_in_place(&k, &mut x).unwrap();
            for (xi, want) in x.iter().zip([-0.1, 2.0, 0.6, 1.2]) {
                assert!((xi - want).abs() < 1e-12, "{kind:?}: {x:?}");
            }
        }
        assert!(LinalgError::check_solution(&[1.0, -2.0], "lu").is_ok());
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let e = LinalgError::check_solution(&[1.0, bad, 3.0], "lu");
            assert!(
                matches!(e, Err(LinalgError::NonFiniteSolution("lu"))),
                "{e:?}"
            );
        }
    }
}
