//! Analyses of a model other than a time integration, about a state:
//! the tangent matrices ([`tangent`]: `M`, `C`, `K`, `Φ_q` and their sign
//! convention), the static equilibrium ([`statics`]: load stepping,
//! Newton), its stability ([`mod@stability`]: by inertia) and the eigenmodes ([`modes`]:
//! shift-invert Lanczos, damped modes in the reduced basis), the sparse
//! choice of independent coordinates ([`partitioning`]).

pub mod inverse;
pub mod linearize;
pub mod modes;
pub mod partitioning;
pub mod stability;
pub mod statics;
pub mod tangent;

pub use modes::{eigenmodes, first_order_modes, FirstOrderMode, Mode, ModeOptions, Modes};
pub use stability::{constrained_inertia, stability, Stability};
pub use statics::{
    static_equilibrium, static_equilibrium_from, Equilibrium, StaticError, StaticOptions,
};
pub use tangent::{Tangent, Triplets};

use crate::linalg::{SaddlePointSolver, SolverKind, Storage};
use serde::Serialize;

/// The factorisations of an analysis's saddle-point matrices
/// ([`Equilibrium::factorizations`], [`Modes::factorizations`]).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Factorizations {
    /// The solver's name for the pattern: `"chain-lu"` (band LU in the
    /// body-by-body order, [`crate::linalg::ChainLu`]) or `"sparse-lu"`
    /// (faer's sparse LU: a pattern that is not a chain, or
    /// [`SolverKind::SparseLu`] asked for).
    pub solver: &'static str,
    /// Numeric factorisations.
    pub count: usize,
    /// Of them, those the chain LU handed to the sparse LU (a pivot at the
    /// rounding level or a large growth).
    pub fallbacks: usize,
}

impl Factorizations {
    /// The counters of `solver` so far.
    fn of(solver: &dyn SaddlePointSolver) -> Self {
        Self {
            solver: solver.name(),
            count: solver.stats().factorizations,
            fallbacks: solver.fallbacks(),
        }
    }
}

/// The solver of `kind` for an analysis's full-storage saddle-point
/// matrix of dimension `dim`; an error naming `what` and the kind when
/// that solver needs another storage.
fn full_storage_solver(
    kind: SolverKind,
    dim: usize,
    what: &str,
) -> Result<Box<dyn SaddlePointSolver>, crate::formulation::FormulationError> {
    let solver = crate::linalg::solver_for(kind, dim, Default::default());
    if solver.storage() != Storage::Full {
        return Err(crate::formulation::FormulationError::Invalid(format!(
            "{what}: linear_solver {kind:?} does not factorise unsymmetric matrices \
             (use ChainLu or SparseLu)"
        )));
    }
    Ok(solver)
}
