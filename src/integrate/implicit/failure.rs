//! The one path of a failed Newton attempt, shared by the implicit
//! schemes' steps ([`attempt_or_cut`]): one retry on a fresh matrix when
//! the attempt ran on an older one (Hairer & Wanner II, §IV.8), then the
//! failure counted (and warned of), the matrix renewed, and the step cut by
//! the scheme's rule — or the run ended when the cut falls below the
//! smallest step. The schemes differ only in [`CutRules`].

use super::super::driver::{Failure, StepCut};
use super::super::SystemError;
use super::run::ImplicitStepper;
use crate::numeric::Time;
use std::sync::Arc;

/// How a scheme's step shrinks after a Newton failure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Shrink {
    /// Halve; the run ends when the half is below the smallest step
    /// (generalized-α, Radau IIA, the augmented Lagrangian).
    Halve,
    /// ode15s's `max(h_min, 0.3 h)`; the run ends when the step is at the
    /// smallest already (BDF/NDF; Shampine & Reichelt 1997).
    Ode15s,
}

/// Which Newton failures become warnings of the run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Warn {
    /// None: they are counted only (BDF/NDF).
    Never,
    /// The first [`WARNED_FAILURES`] (Radau IIA, the augmented Lagrangian).
    First,
    /// The first [`WARNED_FAILURES`] − 1 and the latest (generalized-α).
    FirstAndLatest,
}

/// Newton failures listed among a run's warnings.
pub(crate) const WARNED_FAILURES: usize = 20;

/// Where the failure paths of the schemes differ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CutRules {
    /// The step after a failure.
    pub shrink: Shrink,
    /// The warnings.
    pub warn: Warn,
    /// The cause named when the step collapses: the first failure since
    /// the last accepted step (true: the augmented Lagrangian) or the one
    /// that cut below the smallest step.
    pub first_cause: bool,
}

/// The failure path's state over a run.
#[derive(Debug, Clone)]
pub(crate) struct Cuts {
    rules: CutRules,
    /// The latest cut (Newton failure or, as the scheme records it, error
    /// test).
    latest: Option<StepCut>,
    /// The first Newton failure since the last accepted step.
    first: Option<StepCut>,
}

impl Cuts {
    /// No cut yet.
    pub(crate) fn new(rules: CutRules) -> Self {
        Self {
            rules,
            latest: None,
            first: None,
        }
    }

    /// A step was accepted: the next failure starts a new chain.
    pub(crate) fn accepted(&mut self) {
        self.first = None;
    }

    /// The scheme's error test rejected a step with this error norm.
    pub(crate) fn error_test(&mut self, err: f64) {
        self.latest = Some(StepCut::ErrorTest { err });
    }

    /// The cause to name when the step falls below the smallest before an
    /// attempt: the latest cut (an error test of unknown norm if none).
    pub(crate) fn cause(&self) -> StepCut {
        self.latest
            .clone()
            .unwrap_or(StepCut::ErrorTest { err: f64::NAN })
    }
}

/// A step to attempt, as [`attempt_or_cut`] sees it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StepTry {
    /// The step's start \[s\].
    pub t: f64,
    /// Its end \[s\].
    pub t_new: f64,
    /// Its size `t_new − t` as attempted \[s\].
    pub h: f64,
    /// The step size the controller shrinks (BDF's `|h|`; else `h`) \[s\].
    pub h_ctl: f64,
    /// The smallest step allowed \[s\].
    pub h_min: f64,
}

/// How [`attempt_or_cut`] ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Attempted {
    /// Newton converged: the scheme goes on with its error test.
    Converged,
    /// Newton failed: try again with this step size.
    Cut(f64),
}

/// Attempt the step `x` ([`ImplicitStepper::newton_attempt`]); when Newton
/// fails on a matrix the attempt did not make, renew it and try once more.
/// A failure then is counted, warned of ([`CutRules::warn`]), renews the
/// matrix and cuts the step ([`CutRules::shrink`]); below the smallest
/// step the run ends with [`Failure::StepTooSmall`].
pub(crate) fn attempt_or_cut<S: ImplicitStepper>(
    st: &mut S,
    x: StepTry,
) -> Result<Attempted, Failure> {
    let mut outcome = st.newton_attempt(x.t_new, x.h);
    if outcome.is_err() && !st.renewal().made_own() {
        st.renewal().renew();
        outcome = st.newton_attempt(x.t_new, x.h);
    }
    let Err(reason) = outcome else {
        return Ok(Attempted::Converged);
    };
    st.renewal().renew();
    let rules = st.cuts().rules;
    let (stats, warnings) = st.books();
    stats.newton_failures += 1;
    warn(warnings, rules.warn, &x, &reason);
    let cut = StepCut::Newton {
        t: x.t_new,
        h: x.h,
        source: Arc::new(reason),
    };
    let next = match rules.shrink {
        Shrink::Halve => (0.5 * x.h_ctl >= x.h_min).then_some(0.5 * x.h_ctl),
        Shrink::Ode15s => (x.h_ctl > x.h_min).then(|| x.h_min.max(0.3 * x.h_ctl)),
    };
    let cuts = st.cuts();
    match next {
        Some(h) => {
            cuts.first.get_or_insert_with(|| cut.clone());
            cuts.latest = Some(cut);
            Ok(Attempted::Cut(h))
        }
        None => {
            let cause = match cuts.first.take() {
                Some(first) if rules.first_cause => first,
                _ => cut,
            };
            let h = match rules.shrink {
                Shrink::Halve => 0.5 * x.h_ctl,
                Shrink::Ode15s => x.h_ctl,
            };
            Err(Failure::StepTooSmall {
                t: x.t,
                h,
                h_min: x.h_min,
                cause,
            })
        }
    }
}

/// The warning of a Newton failure, as `rule` keeps them.
fn warn(warnings: &mut Vec<String>, rule: Warn, x: &StepTry, reason: &SystemError) {
    if rule == Warn::Never {
        return;
    }
    let msg = format!(
        "Newton failed at t = {} with h = {:.3e}: {reason}",
        Time(x.t_new),
        x.h
    );
    if warnings.len() < WARNED_FAILURES {
        warnings.push(msg);
    } else if let (Warn::FirstAndLatest, Some(last)) = (rule, warnings.last_mut()) {
        *last = msg;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The warning prints times in scientific notation: a subnormal time
    /// is a few characters, not a 300-digit decimal.
    #[test]
    fn newton_failure_warnings_print_short_times() {
        let x = StepTry {
            t: 0.0,
            t_new: 1.3e-322,
            h: 1.3e-322,
            h_ctl: 1.3e-322,
            h_min: 0.0,
        };
        let mut w = Vec::new();
        warn(&mut w, Warn::First, &x, &SystemError::msg("singular"));
        assert_eq!(w.len(), 1);
        assert!(
            w[0].starts_with("Newton failed at t = 1.3e-322 with h = "),
            "{}",
            w[0]
        );
        assert!(w[0].len() < 80, "{}", w[0]);
    }
}
