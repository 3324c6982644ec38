//! The one run skeleton of the implicit schemes: input validation, the
//! run loop [`driver::drive`] and the [`Report`] with the counters.

use super::super::driver::{self, Stepper};
use super::super::{common, IntegratorError, Observer, OdeOptions, Report, SystemError, Tolerance};
use super::{Cuts, ImplicitStats, Renewal};

/// One run of an implicit scheme: from `(t0, q0, q̇0)` to `t_end`, and
/// the output times with the observer that receives them.
pub struct Span<'a> {
    /// Start time t0 \[s\].
    pub t0: f64,
    /// End time \[s\], after `t0` (only forward integration).
    pub t_end: f64,
    /// Initial positions q0, n of them (finite).
    pub q0: &'a [f64],
    /// Initial velocities q̇0, n of them (finite).
    pub qd0: &'a [f64],
    /// Output times, strictly increasing within `[t0, t_end]`.
    pub output_times: &'a [f64],
    /// Receives `y = [q; q̇]`: `output` at each output time, `step` after
    /// every accepted step.
    pub obs: &'a mut dyn Observer,
}

/// A scheme's run as [`run`] drives it: a [`Stepper`] that counts its
/// work in [`ImplicitStats`], collects warnings, and whose step attempts
/// go through the one failure path ([`super::attempt_or_cut`]).
pub(crate) trait ImplicitStepper: Stepper {
    /// The counters so far and the warnings of the run (taken out at its
    /// end).
    fn books(&mut self) -> (&mut ImplicitStats, &mut Vec<String>);
    /// One attempt of the step of size `h` to `t_new`: the scheme's
    /// predictor and Newton iteration; `Err` when Newton fails.
    fn newton_attempt(&mut self, t_new: f64, h: f64) -> Result<(), SystemError>;
    /// The scheme's Newton-matrix policy.
    fn renewal(&mut self) -> &mut Renewal;
    /// The failure path's state.
    fn cuts(&mut self) -> &mut Cuts;
}

/// The [`ImplicitStepper`] of a scheme's run type whose books are its
/// fields `stats`, `warnings`, `renewal` and `cuts` and whose Newton
/// attempt is its method `attempt(t_new, h)`.
macro_rules! implicit_stepper {
    ($run:ty) => {
        impl $crate::integrate::implicit::ImplicitStepper for $run {
            fn books(&mut self) -> (&mut ImplicitStats, &mut Vec<String>) {
                (&mut self.stats, &mut self.warnings)
            }
            fn newton_attempt(&mut self, t_new: f64, h: f64) -> Result<(), SystemError> {
                self.attempt(t_new, h)
            }
            fn renewal(&mut self) -> &mut Renewal {
                &mut self.renewal
            }
            fn cuts(&mut self) -> &mut Cuts {
                &mut self.cuts
            }
        }
    };
}
pub(crate) use implicit_stepper;

/// The [`Stepper`] methods every implicit run has alike, written inside
/// its `impl Stepper` block: the counters (its field `stats`), the
/// warnings (its field `warnings`) and the interpolated output rows
/// projected onto the constraints with its system (field `sys`,
/// [`super::settle_output`]).
macro_rules! implicit_outputs {
    () => {
        /// Interpolated rows projected onto the constraints.
        fn settle(&mut self, t: f64, out: &mut [f64]) {
            $crate::integrate::implicit::settle_output(self.sys, t, out, &mut self.warnings);
        }

        fn warnings(&self) -> &[String] {
            &self.warnings
        }

        fn stats(&self) -> $crate::integrate::Stats {
            self.stats.counts()
        }
    };
}
pub(crate) use implicit_outputs;

/// The public `stats()` and `integrate(sys, span)` of an implicit method
/// whose run needs only the system, written inside its `impl` block: the
/// method keeps its counters in its field `stats` and its [`OdeOptions`]
/// in `ode`. Given `integrate`'s doc comment and `|me, sys, span| body`,
/// where `body` checks the inputs (returning early with `?`) and sets up
/// the run (an [`ImplicitStepper`]) from the method `me`, the system and
/// the span, which [`run`] then drives.
macro_rules! implicit_entry {
    ($(#[$doc:meta])* |$me:ident, $sys:ident, $span:ident| $start:block) => {
        /// Counters of the last run.
        pub fn stats(&self) -> $crate::integrate::implicit::ImplicitStats {
            self.stats
        }

        $(#[$doc])*
        pub fn integrate(
            &mut self,
            sys: &mut dyn $crate::integrate::implicit::SecondOrderDae,
            span: $crate::integrate::implicit::Span<'_>,
        ) -> Result<$crate::integrate::Report, $crate::integrate::IntegratorError> {
            let (report, stats) = {
                let ($me, $sys, $span) = (&*self, sys, &span);
                let mut run = $start;
                $crate::integrate::implicit::run(&mut run, span, self.ode.max_steps)
            };
            self.stats = stats;
            Ok(report)
        }
    };
}
pub(crate) use implicit_entry;

/// Drive `st` through [`driver::drive`] over `span` with at most
/// `max_steps` steps: the report
/// (a failure midway is [`super::super::Termination::Failed`]) and the
/// counters of the run (`min_step_taken` = 0 without an accepted step).
pub(crate) fn run<S: ImplicitStepper>(
    st: &mut S,
    span: Span<'_>,
    max_steps: usize,
) -> (Report, ImplicitStats) {
    let (times, t_end) = (span.output_times, span.t_end);
    let (termination, t_reached) = driver::drive(st, times, max_steps, t_end, span.obs);
    let (stats, warnings) = st.books();
    let stats = stats.finished();
    let report = Report {
        stats: stats.counts(),
        termination,
        t_reached,
        warnings: std::mem::take(warnings),
    };
    (report, stats)
}

/// Check the inputs of an implicit run: the time span, `q0` and `q̇0` of
/// length `n` and finite, with `adaptive` a vector `atol` of length `n`
/// or `2n`, and the output times within the span.
pub(crate) fn validate_run(
    n: usize,
    span: &Span<'_>,
    ode: &OdeOptions,
    adaptive: bool,
) -> Result<(), IntegratorError> {
    let Span {
        t0,
        t_end,
        q0,
        qd0,
        output_times,
        ..
    } = *span;
    common::check_span(t0, t_end)?;
    for (what, v) in [("q0", q0), ("qd0", qd0)] {
        if v.len() != n {
            return Err(IntegratorError::DimensionMismatch {
                what,
                expected: n,
                got: v.len(),
            });
        }
    }
    if let Some((index, value)) = q0
        .iter()
        .chain(qd0)
        .enumerate()
        .find(|(_, v)| !v.is_finite())
    {
        return Err(IntegratorError::NonFiniteInitialState {
            index,
            value: *value,
        });
    }
    if adaptive {
        if let Tolerance::Vector(v) = &ode.atol {
            if v.len() != n && v.len() != 2 * n {
                return Err(IntegratorError::DimensionMismatch {
                    what: "atol",
                    expected: n,
                    got: v.len(),
                });
            }
        }
    }
    common::check_output_times(t0, t_end, output_times)?;
    Ok(())
}
