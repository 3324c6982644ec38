//! The one integration driver: every method, explicit or implicit, is a
//! [`Stepper`] (start, one accepted step at a time, dense output), and
//! [`drive`] is the one loop that runs it — output delivery, the step cap,
//! observer calls, how the run ended. Run validation is in `common`.

use std::ops::ControlFlow;
use std::sync::Arc;

use super::common::OutputCursor;
use super::{Observer, Stats, SystemError, Termination};
use crate::numeric::Time;

/// A method bound to its system and initial state, advanced one accepted
/// step at a time.
///
/// The state `y` is what the observer sees: `[q; q̇]` for the second-order
/// systems. A step that is rejected (error test, Newton failure) is retried
/// inside [`Stepper::step`] with a smaller step; only accepted steps come
/// out. A post-step change of the state (projection onto the constraint
/// manifold, [`super::OdeSystem::post_step`] or
/// [`super::SecondOrderDae::project`]) happens inside the step, before the
/// step's outputs are delivered.
pub trait Stepper {
    /// Evaluate what the first step needs at `t0` (first stage, consistent
    /// accelerations, initial step size).
    fn start(&mut self) -> Result<(), Failure>;
    /// Take one accepted step; `Ok(true)` when it ended on `t_end`.
    fn step(&mut self) -> Result<bool, Failure>;
    /// Time and state of the last accepted step (`t0, y0` before the first).
    fn state(&self) -> (f64, &[f64]);
    /// The method's continuous extension inside the last accepted step, at
    /// `t` in `(t_prev, t_new)`, into `out`.
    fn interpolate(&self, t: f64, out: &mut [f64]);
    /// Bring the interpolated output row `out` at `t` (from
    /// [`Stepper::interpolate`]) onto the constraint manifold where the
    /// method can (the implicit schemes: a projection that leaves their
    /// steps unchanged); a failure leaves the row and a warning. Default:
    /// the row as interpolated.
    fn settle(&mut self, t: f64, out: &mut [f64]) {
        let _ = (t, out);
    }
    /// A requested output time within this distance of the step end is
    /// taken as the step end (the fixed grid of generalized-α lands on the
    /// output times up to rounding); 0 for the explicit methods.
    fn output_snap(&self) -> f64 {
        0.0
    }
    /// Work so far (accepted and rejected steps, evaluations).
    fn stats(&self) -> Stats;
    /// Notices so far (e.g. a Newton failure that cut the step); the
    /// driver hands each new one to [`Observer::warning`] as it appears.
    fn warnings(&self) -> &[String] {
        &[]
    }
}

/// Why a run could not continue ([`Termination::Failed`]): typed, with the
/// time and the system's own error where there is one.
#[derive(Debug, Clone, thiserror::Error)]
pub enum Failure {
    /// The system failed: a right-hand side, residual, Newton matrix,
    /// solve or projection ([`SystemError`], downcastable to its type).
    #[error("{what} failed at t = {}{}: {source}", Time(*.t), in_step(*.step_from))]
    System {
        /// What was evaluated ("right-hand side", "projection", …).
        what: &'static str,
        /// Time of the evaluation.
        t: f64,
        /// Start of the step in which it happened, if inside a step.
        step_from: Option<f64>,
        /// The system's error.
        source: Arc<SystemError>,
    },
    /// A value came out NaN or infinite.
    #[error(
        "{what} returned a non-finite value ({value}) in component {index} at t = {}{}",
        Time(*.t),
        in_step(*.step_from)
    )]
    NonFinite {
        /// Which value ("right-hand side", "step").
        what: &'static str,
        /// Time of the value.
        t: f64,
        /// Start of the step in which it happened, if inside a step.
        step_from: Option<f64>,
        /// Component index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// The step size fell below the smallest allowed.
    #[error("step size {h:.3e} below the smallest allowed ({h_min:.3e}) at t = {}: {cause}", Time(*.t))]
    StepTooSmall {
        /// Time of the last accepted state.
        t: f64,
        /// The step that would have been needed.
        h: f64,
        /// The smallest step allowed (`16·eps(t)` or the user's `min_step`).
        h_min: f64,
        /// What kept cutting the step.
        cause: StepCut,
    },
    /// The cap on accepted steps was reached.
    #[error(
        "maximum number of steps (max_steps = {max_steps}) reached at t = {} before t_end = {}",
        Time(*.t),
        Time(*.t_end)
    )]
    MaxSteps {
        /// The cap ([`super::OdeOptions::max_steps`]).
        max_steps: usize,
        /// Time reached.
        t: f64,
        /// Requested end.
        t_end: f64,
    },
}

impl Failure {
    /// The [`Failure::System`] of `what` evaluated at `t` (inside the step
    /// from `step_from`), made from the system's error: for `map_err`.
    pub(crate) fn system(
        what: &'static str,
        t: f64,
        step_from: Option<f64>,
    ) -> impl FnOnce(SystemError) -> Self {
        move |e| Self::System {
            what,
            t,
            step_from,
            source: Arc::new(e),
        }
    }
}

/// What made a step size collapse ([`Failure::StepTooSmall`]).
#[derive(Debug, Clone, thiserror::Error)]
pub enum StepCut {
    /// The local error test kept failing (MATLAB: "unable to meet
    /// integration tolerances").
    #[error(
        "unable to meet integration tolerances (last error estimate {err:.3e} of the allowed)"
    )]
    ErrorTest {
        /// Last error norm relative to the tolerance (1 passes).
        err: f64,
    },
    /// The step no longer advances the time (`t + h == t`: the span or the
    /// step underflows against `t`).
    #[error("the step does not advance t (t + h == t)")]
    NoProgress,
    /// Newton kept failing.
    #[error("Newton does not converge (at t = {} with h = {h:.3e}: {source})", Time(*.t))]
    Newton {
        /// Time the failed attempt aimed at.
        t: f64,
        /// Its step.
        h: f64,
        /// Why the iteration failed.
        source: Arc<SystemError>,
    },
}

fn in_step(from: Option<f64>) -> String {
    from.map_or(String::new(), |t| {
        format!(" (in the step from t = {})", Time(t))
    })
}

impl PartialEq for Failure {
    /// Same kind, same time and same message (the system's error compares
    /// by its message).
    fn eq(&self, other: &Self) -> bool {
        std::mem::discriminant(self) == std::mem::discriminant(other)
            && self.to_string() == other.to_string()
    }
}

/// Run `st` to its end: output at `t0`, [`Stepper::start`], then accepted
/// steps until `t_end`, a failure, `max_steps`, or the observer stops it.
/// Every requested time in `times` (validated) up to the last accepted step
/// is delivered, in order: the step end's state where a time falls on it
/// (within [`Stepper::output_snap`], or any remaining time after the last
/// step), else the continuous extension. Returns how the run ended and
/// the time reached.
///
/// A run whose state has at least `2·PARALLEL_MIN_COORDS` entries (`q` and
/// `q̇` of a system large enough for concurrent passes) runs with a
/// two-thread team when the rayon pool has a second thread
/// (`parallel::team`); the results do not depend on it.
pub fn drive(
    st: &mut dyn Stepper,
    times: &[f64],
    max_steps: usize,
    t_end: f64,
    obs: &mut dyn Observer,
) -> (Termination, f64) {
    let state = st.state().1.len();
    // the loop runs on the run's thread team (`parallel::run_with_team`)
    crate::parallel::run_with_team(state, || {
        let mut outputs = OutputCursor::new(times);
        let (t0, y0) = st.state();
        let mut buf = vec![0.0; y0.len()];
        if let ControlFlow::Break((t, reason)) = outputs.deliver_initial(t0, y0, obs) {
            return (Termination::Stopped { t, reason }, t0);
        }
        let mut warned = 0;
        for msg in st.warnings() {
            obs.warning(msg);
            warned += 1;
        }
        if let Err(reason) = st.start() {
            return (Termination::Failed { t: t0, reason }, t0);
        }
        loop {
            let t = st.state().0;
            if st.stats().steps >= max_steps {
                let reason = Failure::MaxSteps {
                    max_steps,
                    t,
                    t_end,
                };
                return (Termination::Failed { t, reason }, t);
            }
            let outcome = st.step();
            let w = st.warnings();
            for msg in w.iter().skip(warned) {
                obs.warning(msg);
            }
            warned = warned.max(w.len());
            let done = match outcome {
                Ok(done) => done,
                Err(reason) => {
                    let t = st.state().0;
                    return (Termination::Failed { t, reason }, t);
                }
            };
            let t_new = st.state().0;
            if t_new <= t {
                let reason = Failure::StepTooSmall {
                    t,
                    h: t_new - t,
                    h_min: super::common::eps(t),
                    cause: StepCut::NoProgress,
                };
                return (Termination::Failed { t, reason }, t);
            }
            let flow = outputs.deliver_step_snapped(t_new, done, &mut *st, &mut buf, obs);
            let w = st.warnings();
            for msg in w.iter().skip(warned) {
                obs.warning(msg);
            }
            warned = warned.max(w.len());
            if let ControlFlow::Break((t, reason)) = flow {
                return (Termination::Stopped { t, reason }, t_new);
            }
            if let ControlFlow::Break(reason) = obs.step(t_new, st.state().1) {
                return (Termination::Stopped { t: t_new, reason }, t_new);
            }
            if let ControlFlow::Break(reason) = obs.progress(t_new, &st.stats()) {
                return (Termination::Stopped { t: t_new, reason }, t_new);
            }
            if done {
                return (Termination::Completed, t_new);
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Failure::system` makes the `Failure::System` of its arguments,
    /// with the system's error as the source, worded as the enum says.
    #[test]
    fn failure_system_keeps_what_time_step_and_source() {
        let f = Failure::system("projection", 0.5, Some(0.25))(SystemError::msg("singular"));
        let Failure::System {
            what,
            t,
            step_from,
            ref source,
        } = f
        else {
            panic!("{f:?}");
        };
        assert_eq!((what, t, step_from), ("projection", 0.5, Some(0.25)));
        assert_eq!(source.to_string(), "singular");
        assert_eq!(
            f.to_string(),
            "projection failed at t = 5e-1 (in the step from t = 2.5e-1): singular"
        );
        let g = Failure::system("right-hand side", 2.0, None)(SystemError::msg("nan"));
        assert_eq!(g.to_string(), "right-hand side failed at t = 2e0: nan");
    }
}
