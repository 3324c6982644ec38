//! The one core of the implicit (index-3) schemes — generalized-α (with
//! HHT, Newmark and the trapezoidal rule), BDF/NDF, Radau IIA and the
//! augmented Lagrangian: the problem they solve (with the augmented
//! Lagrangian's multiplier update as a hook), their statistics, the one
//! path of a failed Newton attempt, the convergence test of their
//! Newton iterations, the policy for renewing the Newton matrix and the
//! run skeleton on `drive`.

mod convergence;
mod dense;
mod failure;
mod problem;
mod renewal;
mod run;
mod stats;

pub use convergence::{
    Assessment, Convergence, ConvergenceOptions, Next, Remainder, NOISE_REL, ROUNDING_ULPS,
    STAGNATION, THETA_REFACTOR,
};
pub(crate) use dense::settle_output;
pub(crate) use failure::{attempt_or_cut, Attempted, CutRules, Cuts, Shrink, StepTry, Warn};
pub use problem::{DaeResult, MultiplierUpdate, SecondOrderDae, StateView};
pub use renewal::{Renewal, RenewalOptions};
pub use run::Span;
pub(crate) use run::{
    implicit_entry, implicit_outputs, implicit_stepper, run, validate_run, ImplicitStepper,
};
pub use stats::{ImplicitStats, COUNTED_ORDERS};
