//! `integrator.method = "auto"`: the method chosen at t0 from the system's
//! own rates.
//!
//! An explicit method's step is bounded by its stability region: with the
//! fastest mode `ω` and damping rate `σ` of the constrained, linearised
//! system at t0 ([`crate::formulation::fastest_modes`]), ode45 can take no
//! step above `h_s = 3.3 / max(ω, σ)` (Hairer & Wanner II, §IV.2). Over the
//! span that is at least `n_s = (t_end − t0) / h_s` steps, whatever the
//! tolerance. The rule:
//!
//! * `n_s ≤` [`STIFF_STEPS`]: the problem is not stiff for ode45 — its
//!   steps are set by accuracy, or stability costs at most that many
//!   cheap steps: **ode45** on the index-1 equations (eq. (5)), with the
//!   projection onto `Φ = 0`, `Φ̇ = 0` after each step so the constraints
//!   hold to the projection's tolerance instead of drifting.
//! * otherwise: **radau5**, adaptive (Radau IIA of order 5, L-stable, on the
//!   index-3 equations): its steps are set by accuracy alone. Of the
//!   stiff methods it needs the fewest Newton iterations per unit of
//!   accuracy on the stiff chain (docs/scaling.md). Its achieved error
//!   does not shrink in proportion to `rtol` (about `0.1 √rtol` at worst on
//!   the shipped scenarios, docs/accuracy.md), so `auto` runs it at
//!   [`radau5_rtol`]`(rtol) = min(rtol, 100 rtol²)`, with `atol` scaled
//!   alike, for an error within a few `rtol`.
//!
//! ode45 takes `rtol`, `atol`, `max_step` and `initial_step` as given. The
//! rates are those at t0: a contact not touching at t0 adds no stiffness
//! to the estimate, so a model that becomes stiff only on impact gets the
//! explicit method (correct, with small steps while in contact); set the
//! method to choose otherwise. The choice and its reason are in the
//! summary (`method_choice`, `method_choice_reason`).

use super::{RunConfig, SimulationError};
use crate::formulation::{explicit_reach, fastest_modes};
use crate::integrate::{Method, Tolerance};
use crate::model::System;

/// Stability-bound steps of ode45 over the span above which `auto`
/// chooses the stiff method. An ode45 step (six right-hand sides, one
/// saddle-point factorisation and solve each) costs about as much as a
/// radau5 step (three to four Newton iterations on kept factorisations),
/// and radau5 needs a few hundred to a few thousand steps at the
/// tolerances of [`radau5_rtol`] on the shipped scenarios (docs/accuracy.md).
pub const STIFF_STEPS: f64 = 2e3;

/// The relative tolerance `auto` gives radau5 for a requested `rtol`:
/// `min(rtol, 100 rtol²)` (module docs; the falling rod's error
/// `≈ 0.1 √rtol` then stays near `rtol`).
pub fn radau5_rtol(rtol: f64) -> f64 {
    rtol.min(100.0 * rtol * rtol)
}

/// How a run's integration method is chosen ([`RunConfig::choice`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MethodChoice {
    /// [`RunConfig::method`] as given.
    #[default]
    Given,
    /// Chosen at t0 by [`choose`] (scenario `integrator.method = "auto"`);
    /// [`RunConfig::method`] is ignored.
    Auto,
}

/// The method `auto` chooses for `sys` from `(q0, q̇0)` (module docs), the
/// settings of the run with it, and the reason in words.
///
/// `cfg` must have the index-1 defaults (saddle point, no Baumgarte
/// terms, no projection) and the implicit defaults: `auto` sets what the
/// chosen method needs.
pub fn choose(
    sys: &System,
    cfg: &RunConfig,
    q0: &[f64],
    qd0: &[f64],
) -> Result<(RunConfig, String), SimulationError> {
    let span = cfg.t_end - cfg.t0;
    let reach = explicit_reach(Method::Ode45).unwrap_or(3.3);
    let mut run = cfg.clone();
    run.choice = MethodChoice::Given;
    let (stiff, reason) = match fastest_modes(sys, cfg.t0, q0, qd0, 60) {
        Ok(modes) => {
            let h = modes.step_limit(reach);
            let steps = span / h;
            let rates = format!(
                "fastest mode ω = {:.3e} rad/s, damping rate σ = {:.3e} 1/s at t0",
                modes.omega, modes.sigma
            );
            if steps > STIFF_STEPS {
                (
                    true,
                    format!(
                        "stiff: ode45's stability would limit its steps to {h:.2e} s, at least \
                         {steps:.1e} steps over the span (more than {STIFF_STEPS:.0e}; {rates}); \
                         radau5 takes steps set by accuracy"
                    ),
                )
            } else if h.is_finite() {
                (
                    false,
                    format!(
                        "not stiff: ode45's stability allows steps up to {h:.2e} s, at most \
                         {steps:.1e} steps over the span for stability ({rates})"
                    ),
                )
            } else {
                (
                    false,
                    "not stiff: no stiffness or damping at t0 bounds ode45's steps".to_string(),
                )
            }
        }
        Err(e) => (
            false,
            format!("the fastest mode at t0 could not be estimated ({e}): ode45 by default"),
        ),
    };
    let mut reason = reason;
    if stiff {
        run.method = Method::Radau5;
        run.implicit.adaptive = true;
        let rtol = radau5_rtol(cfg.ode.rtol);
        let factor = rtol / cfg.ode.rtol;
        if factor < 1.0 {
            run.ode.rtol = rtol;
            run.ode.atol = match &cfg.ode.atol {
                Tolerance::Scalar(a) => Tolerance::Scalar(a * factor),
                Tolerance::Vector(v) => Tolerance::Vector(v.iter().map(|a| a * factor).collect()),
            };
            reason.push_str(&format!(
                ", at rtol = {rtol:.1e} and atol scaled alike for an error near the requested rtol"
            ));
        }
        run.implicit.validate(run.method, run.ode.fixed_step)?;
    } else {
        run.method = Method::Ode45;
        run.index1.projection.enabled = sys.n_constraints() > 0;
    }
    run.ode.validate(run.method, run.implicit.adaptive)?;
    let reason = format!("{} chosen: {reason}", run.method.name());
    Ok((run, reason))
}
