//! The one run skeleton of the implicit schemes: input validation, the
//! run loop [`driver::drive`] and the [`Report`] with the counters.

use super::super::driver::{self, Stepper};
use super::super::{common, IntegratorError, Observer, OdeOptions, Report, SystemError, Tolerance};
use super::{Cuts, ImplicitStats, Renewal};

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

/// Drive `st` through [`driver::drive`] to `t_end`, delivering
/// `output_times` to `obs` with at most `max_steps` steps: the report
/// (a failure midway is [`super::super::Termination::Failed`]) and the
/// counters of the run (`min_step_taken` = 0 without an accepted step).
pub(crate) fn run<S: ImplicitStepper>(
    st: &mut S,
    output_times: &[f64],
    max_steps: usize,
    t_end: f64,
    obs: &mut dyn Observer,
) -> (Report, ImplicitStats) {
    let (termination, t_reached) = driver::drive(st, output_times, max_steps, t_end, obs);
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
#[allow(clippy::too_many_arguments)]
pub(crate) fn validate_run(
    n: usize,
    t0: f64,
    t_end: f64,
    q0: &[f64],
    qd0: &[f64],
    output_times: &[f64],
    ode: &OdeOptions,
    adaptive: bool,
) -> Result<(), IntegratorError> {
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
