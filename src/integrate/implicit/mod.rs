//! The one core of the implicit (index-3) schemes — generalized-α (with
//! HHT, Newmark and the trapezoidal rule), BDF/NDF, Radau IIA and the
//! augmented Lagrangian: their statistics and the convergence test of
//! their Newton iterations.

mod convergence;
mod stats;

pub use convergence::{
    Assessment, Convergence, ConvergenceOptions, Next, NOISE_REL, ROUNDING_ULPS, STAGNATION,
    THETA_REFACTOR,
};
pub use stats::{ImplicitStats, COUNTED_ORDERS};
