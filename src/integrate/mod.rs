//! Integrators: explicit ODE methods for first-order systems
//! `y' = f(t, y)` ([`OdeSystem`]) and the implicit generalized-α family
//! for constrained second-order systems ([`SecondOrderDae`]).
//!
//! Every method is a [`Stepper`] (start, one accepted step at a time,
//! its dense output) and [`drive`] is the one run loop: outputs at the
//! requested times, the step cap, the observer, how the run ended
//! ([`Termination`], with a typed [`Failure`]). After each accepted step
//! the system may move the state ([`OdeSystem::post_step`],
//! [`SecondOrderDae::project`]).
//!
//! * [`Method::Ode23`]: Bogacki–Shampine 3(2) pair (Bogacki & Shampine,
//!   Appl. Math. Lett. 2 (1989)), FSAL, 3 evaluations per step.
//! * [`Method::Ode45`]: Dormand–Prince 5(4) pair (Dormand & Prince,
//!   J. Comput. Appl. Math. 6 (1980)), FSAL, 6 evaluations per step.
//! * [`Method::Rk4`]: classic fixed-step fourth-order Runge–Kutta.
//! * [`Method::Ode113`]: variable-order Adams–Bashforth–Moulton PECE
//!   (Shampine & Gordon 1975) with MATLAB's `ode113` step and order
//!   control and its interpolant (see the `ode113` submodule).
//! * [`Method::Bdf`]: variable-order (1–5) BDF on the index-3 equations
//!   of a [`SecondOrderDae`] ([`Bdf`]; docs/bdf.md).
//!
//! `ode23` and `ode45` follow MATLAB's `ode23.m` / `ode45.m` and their
//! interpolants `ntrp23.m` / `ntrp45.m` (Shampine & Reichelt, "The MATLAB ODE
//! Suite", SIAM J. Sci. Comput. 18 (1997)): same error norm (NormControl
//! off), initial step, step-size update, minimal step `16·eps(t)`, step
//! stretching to hit `t_end`, continuous extension and function-evaluation
//! count. Both share one engine parametrised by the tableau (see the
//! `embedded` submodule for the exact rules).
//!
//! Differences from MATLAB (all outside the step-size logic):
//! * Only forward integration (`t_end > t0`).
//! * `atol = 0` is accepted (MATLAB requires `atol > 0`); a component whose
//!   weight is then `0/0` is ignored by the error norm, as MATLAB's `max`
//!   ignores NaN.
//! * A right-hand side returning an error or a non-finite value, or a
//!   non-finite state, ends the run with [`Termination::Failed`] (MATLAB
//!   would carry NaN/Inf along).
//! * [`OdeSystem::post_step`] may move the accepted state (projection);
//!   `f` is then evaluated anew at the moved state (one more evaluation per
//!   step), outputs at the step end show the moved state and those inside
//!   the step the method's continuous extension.
//! * No events, mass matrix, NonNegative or NormControl options.
//! * A cap on the number of steps ([`OdeOptions::max_steps`]).

mod bdf;
mod common;
mod driver;
mod embedded;
mod genalpha;
mod hermite;
pub mod implicit;
mod method;
mod ode113;
mod options;
mod radau;
mod rk4;
mod tableau;

pub use bdf::NDF_KAPPA;
pub use bdf::{Bdf, MAX_NEWTON as BDF_MAX_NEWTON, MAX_ORDER as BDF_MAX_ORDER};
pub use driver::{drive, Failure, StepCut, Stepper};
pub use genalpha::{
    AlphaParameters, GenAlpha, ALM_MAX_NEWTON, MAX_PENALTY_FACTOR, NOISE_REL, REUSE_BAND,
    ROUNDING_ULPS, SAFETY, SLOW_CONTRACTION, SLOW_ITERATIONS, STAGNATION, THETA_REFACTOR,
};
pub use implicit::{DaeResult, ImplicitStats, MultiplierUpdate, SecondOrderDae, Span, StateView};
pub(crate) use method::methods_taking;
pub use method::{
    alias as method_alias, markdown_table as method_table_markdown, Alias, Equations, Family,
    KeyUse, Method, MethodInfo, Stepping, METHODS, STEP_CONTROL_KEYS,
};
pub use options::{ImplicitOptions, OdeOptions, Tolerance};
pub use radau::{
    ComplexNewton, OrderCounts, Radau13, Radau5, Radau59, Radau9, RadauHigh, RadauStages,
    RadauTableau, FLIGHT_LOOKAHEAD,
};

use std::ops::ControlFlow;

pub use crate::numeric::first_non_finite;
pub use common::eps;

/// A first-order system y' = f(t, y).
pub trait OdeSystem {
    /// Number of state components.
    fn dim(&self) -> usize;
    /// Evaluate f(t, y) into dydt. An Err aborts the integration (reported as Termination::Failed at the current time).
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<(), SystemError>;
    /// Called after every accepted step with the step's end state: the
    /// system may move `y` (e.g. project it onto the constraint manifold)
    /// and returns `Ok(true)` if it did; the integrator then re-evaluates
    /// what it keeps of the old state (the first stage `f(t, y)` of the
    /// next step). An `Err` ends the run as a failure at `t`. Default: no
    /// change.
    fn post_step(&mut self, _t: f64, _y: &mut [f64]) -> Result<bool, SystemError> {
        Ok(false)
    }
}

/// Failure of the system an integrator drives — a right-hand side
/// ([`OdeSystem::rhs`]), or a residual, Newton matrix, solve or projection
/// of a [`SecondOrderDae`]: the system's own typed error, kept as the
/// source (recover it with [`SystemError::downcast_ref`], e.g. a
/// `formulation::FormulationError`).
#[derive(Debug, thiserror::Error)]
#[error(transparent)]
pub struct SystemError(Box<dyn std::error::Error + Send + Sync + 'static>);

/// A failure described by a message only (see [`SystemError::msg`]).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct Message(String);

impl SystemError {
    /// Wrap the system's error.
    pub fn new(e: impl std::error::Error + Send + Sync + 'static) -> Self {
        Self(Box::new(e))
    }
    /// A failure with a message only (simple systems, tests).
    pub fn msg(m: impl Into<String>) -> Self {
        Self(Box::new(Message(m.into())))
    }
    /// The system's error as `T`, if it is one.
    pub fn downcast_ref<T: std::error::Error + 'static>(&self) -> Option<&T> {
        self.0.downcast_ref::<T>()
    }
}

/// An [`OdeSystem`] made of a dimension and an infallible closure
/// `f(t, y, dydt)`; convenient for simple problems and tests.
pub struct FnSystem<F> {
    dim: usize,
    f: F,
}

impl<F: FnMut(f64, &[f64], &mut [f64])> FnSystem<F> {
    /// Wraps `f` as a system of dimension `dim`.
    pub fn new(dim: usize, f: F) -> Self {
        Self { dim, f }
    }
}

impl<F: FnMut(f64, &[f64], &mut [f64])> OdeSystem for FnSystem<F> {
    fn dim(&self) -> usize {
        self.dim
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<(), SystemError> {
        (self.f)(t, y, dydt);
        Ok(())
    }
}

/// Work statistics, counted as MATLAB's `nsteps`, `nfailed`, `nfevals`.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct Stats {
    /// Accepted steps.
    pub steps: usize,
    /// Rejected step attempts.
    pub failed_steps: usize,
    /// Right-hand-side evaluations, including the initial `f(t0, y0)`.
    pub rhs_evals: usize,
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Termination {
    /// Reached `t_end`.
    Completed,
    /// Could not continue past `t` (step size below `hmin`, right-hand-side
    /// error, non-finite value, `max_steps`); `reason` says which.
    Failed {
        /// Time of the last accepted state.
        t: f64,
        /// Why, typed; its message names the time.
        reason: Failure,
    },
    /// The observer asked to stop.
    Stopped {
        /// Time of the output or step at which the observer asked to stop.
        t: f64,
        /// Reason given by the observer.
        reason: String,
    },
}

/// Result of a run that started (invalid inputs are an [`IntegratorError`] instead).
#[derive(Debug, Clone)]
pub struct Report {
    /// Work statistics.
    pub stats: Stats,
    /// How the run ended.
    pub termination: Termination,
    /// End of the last accepted step (`t0` if none).
    pub t_reached: f64,
    /// Non-fatal notices, e.g. `rtol` raised to `100·eps`.
    pub warnings: Vec<String>,
}

/// Receives the solution. Default methods do nothing and continue.
pub trait Observer {
    /// At each requested output time, in increasing order, y from the method's continuous extension
    /// (or the exact step end when a step ends on it). Return ControlFlow::Break(reason) to stop the run.
    fn output(&mut self, _t: f64, _y: &[f64]) -> ControlFlow<String> {
        ControlFlow::Continue(())
    }
    /// After every accepted step, with the step's end state.
    fn step(&mut self, _t: f64, _y: &[f64]) -> ControlFlow<String> {
        ControlFlow::Continue(())
    }
    /// After every accepted step (after [`Observer::step`]), with the work
    /// so far: for progress reports and interrupts.
    fn progress(&mut self, _t: f64, _stats: &Stats) -> ControlFlow<String> {
        ControlFlow::Continue(())
    }
    /// A notice of the integrator as it appears (it is also in
    /// [`Report::warnings`]).
    fn warning(&mut self, _message: &str) {}
}

/// The unit observer ignores everything.
impl Observer for () {}

impl<O: Observer + ?Sized> Observer for &mut O {
    fn output(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        (**self).output(t, y)
    }
    fn step(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        (**self).step(t, y)
    }
    fn progress(&mut self, t: f64, stats: &Stats) -> ControlFlow<String> {
        (**self).progress(t, stats)
    }
    fn warning(&mut self, message: &str) {
        (**self).warning(message)
    }
}

/// Stores all output samples (t, y).
#[derive(Debug, Clone, Default)]
pub struct Recorder {
    /// Output times.
    pub t: Vec<f64>,
    /// States at the output times.
    pub y: Vec<Vec<f64>>,
}

impl Observer for Recorder {
    fn output(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        self.t.push(t);
        self.y.push(y.to_vec());
        ControlFlow::Continue(())
    }
}

/// Invalid options or inputs, detected before integration starts.
#[derive(Debug, Clone, thiserror::Error)]
pub enum IntegratorError {
    /// An option has an invalid value.
    #[error("invalid option {option} = {value}: {reason}")]
    InvalidOption {
        /// Option name (field of [`OdeOptions`] or [`ImplicitOptions`]).
        option: &'static str,
        /// Offending value.
        value: String,
        /// What is required.
        reason: String,
    },
    /// An option is set for a method that does not use it.
    #[error("option {option} does not apply to {method}: {reason}")]
    NotApplicable {
        /// Option name (field of [`OdeOptions`] or [`ImplicitOptions`]).
        option: &'static str,
        /// The chosen method.
        method: &'static str,
        /// Why it does not apply.
        reason: String,
    },
    /// Unknown method name.
    #[error(
        "unknown integration method '{0}'; valid methods are {names}",
        names = Method::NAMES.join(", ")
    )]
    UnknownMethod(String),
    /// The method is implicit (index-3 DAE) and has no [`OdeSystem`]
    /// integrator; run it through `simulation::simulate`, [`GenAlpha`] or
    /// [`Bdf`].
    #[error(
        "'{0}' is an implicit index-3 method, not an ODE integrator: run it through \
         simulation::simulate (or integrate::GenAlpha)"
    )]
    ImplicitMethod(&'static str),
    /// Bad time span.
    #[error("invalid time span t0 = {t0}, t_end = {t_end}: {reason}")]
    InvalidTimeSpan {
        /// Start time.
        t0: f64,
        /// End time.
        t_end: f64,
        /// What is required.
        reason: String,
    },
    /// A vector has the wrong length for the system.
    #[error("{what} has length {got}, but the system dimension is {expected}")]
    DimensionMismatch {
        /// Which input ("y0", "atol").
        what: &'static str,
        /// System dimension.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// The initial state contains NaN or infinity.
    #[error("initial state y0[{index}] = {value} is not finite")]
    NonFiniteInitialState {
        /// Component index.
        index: usize,
        /// Offending value.
        value: f64,
    },
    /// Bad requested output times.
    #[error("invalid output time output_times[{index}] = {value}: {reason}")]
    InvalidOutputTimes {
        /// Index into the output times.
        index: usize,
        /// Offending value.
        value: f64,
        /// What is required.
        reason: String,
    },
}

/// Creates an integrator for `method`, validating the options with
/// [`OdeOptions::validate`] (options the method does not use are an error).
///
/// The index-3 methods ([`Method::is_index3`]) return
/// [`IntegratorError::ImplicitMethod`].
pub fn integrator(method: Method, options: OdeOptions) -> Result<Integrator, IntegratorError> {
    if method.is_index3() {
        return Err(IntegratorError::ImplicitMethod(method.name()));
    }
    options.validate(method, false)?;
    Ok(Integrator { method, options })
}

/// An explicit ODE integrator (ode23, ode45, ode113, rk4) configured with
/// its method and options ([`integrator`]): the inputs checked, the
/// method's [`driver::Stepper`] driven by [`driver::drive`].
pub struct Integrator {
    method: Method,
    options: OdeOptions,
}

impl Integrator {
    /// The method implemented.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Integrate from t0 to t_end (t_end > t0 required — only forward
    /// integration is supported), starting at y0. `output_times`: strictly
    /// increasing, within [t0, t_end]; t0 itself may be included (then
    /// `output(t0, y0)` is called first). A failure midway (step size below
    /// MATLAB's hmin = 16 eps(t), RHS error, non-finite state, max_steps)
    /// does not return `Err`: it returns `Ok(Report { termination:
    /// Failed { t, reason }, .. })` after having delivered every output up
    /// to t.
    pub fn integrate(
        &mut self,
        sys: &mut dyn OdeSystem,
        t0: f64,
        t_end: f64,
        y0: &[f64],
        output_times: &[f64],
        obs: &mut dyn Observer,
    ) -> Result<Report, IntegratorError> {
        let opts = &self.options;
        let n = common::validate_run(sys, opts, t0, t_end, y0, output_times)?;
        let run = common::RunSpan {
            opts,
            t0,
            t_end,
            y0,
            n,
        };
        let mut st: Box<dyn driver::Stepper + '_> = match self.method {
            Method::Ode23 | Method::Ode45 => {
                let tab = if self.method == Method::Ode23 {
                    &tableau::BS23
                } else {
                    &tableau::DP54
                };
                Box::new(embedded::EmbeddedStepper::new(sys, &run, tab))
            }
            Method::Rk4 => Box::new(rk4::Rk4Stepper::new(sys, &run)),
            Method::Ode113 => Box::new(ode113::Ode113Stepper::new(sys, &run)),
            m => return Err(IntegratorError::ImplicitMethod(m.name())),
        };
        let (termination, t_reached) =
            driver::drive(st.as_mut(), output_times, opts.max_steps, t_end, obs);
        Ok(Report {
            stats: st.stats(),
            termination,
            t_reached,
            warnings: st.warnings().to_vec(),
        })
    }
}

#[cfg(test)]
mod system_error_tests {
    use super::SystemError;

    /// The system's error survives the integrator boundary: same message,
    /// recoverable by type.
    #[test]
    fn keeps_the_source_error() {
        let e = SystemError::new(std::io::Error::other("singular at t = 0.5"));
        assert_eq!(e.to_string(), "singular at t = 0.5");
        assert!(e.downcast_ref::<std::io::Error>().is_some());
        let m = SystemError::msg("model undefined");
        assert_eq!(m.to_string(), "model undefined");
        assert!(m.downcast_ref::<std::io::Error>().is_none());
    }
}
