//! Checks before a run against the system's own rates at t0: an explicit
//! method's stability limit, Baumgarte's rate, loads out of scale and
//! statically unstable modes ([`crate::formulation::fastest_modes`]).

use super::watch::{norm2, Watch};
use super::{RunConfig, SimulationError};
use crate::formulation::Formulation;
use crate::model::System;

/// Explicit methods against the fastest modes at t0
/// ([`crate::formulation::fastest_modes`]): a fixed step above the
/// stability limit cannot run; an adaptive method that will need more
/// than 10⁵ steps for stability alone gets a warning that the problem is
/// stiff for it, more than `max_steps` a refusal. Every method against a
/// statically unstable mode growing at γ (steps below 1/γ to follow it):
/// a warning above 10⁵ steps, a refusal above `max_steps`.
pub(super) fn stability_check(
    sys: &System,
    cfg: &RunConfig,
    q0: &[f64],
    qd0: &[f64],
    watch: &mut Watch<'_, '_, '_, '_>,
) -> Result<(), SimulationError> {
    let span = cfg.t_end - cfg.t0;
    let cap = cfg.ode.max_steps as f64;
    let Some(reach) = crate::formulation::explicit_reach(cfg.method) else {
        if let Ok(modes) = crate::formulation::fastest_modes(sys, cfg.t0, q0, qd0, 60) {
            growth_check(sys, cfg, q0, qd0, &modes, watch)?;
        }
        return Ok(());
    };
    // Baumgarte's terms, eq. (10), make the constraint violation a mode of
    // its own: Φ̈ + 2αΦ̇ + β²Φ = 0 decays at rates α ± √(α² − β²) (or
    // oscillates at β), stiff for the explicit methods when α or β is large
    let f = cfg.formulation.formulation;
    let bg = cfg.formulation.baumgarte;
    let baumgarte_rate =
        if sys.n_constraints() > 0 && matches!(f, Formulation::Saddle | Formulation::Eliminated) {
            let (a, b) = (bg.alpha.abs(), bg.beta.abs());
            if a >= b {
                a + (a * a - b * b).sqrt()
            } else {
                b
            }
        } else {
            0.0
        };
    let baumgarte_limit = if baumgarte_rate > 0.0 {
        reach / baumgarte_rate
    } else {
        f64::INFINITY
    };
    let baumgarte_steps = span / baumgarte_limit;
    if baumgarte_steps > cap && cfg.ode.fixed_step.is_none() {
        return Err(SimulationError::TooStiff(format!(
            "stabilization.alpha = {:e}, beta = {:e}: Baumgarte's terms decay the constraint \
             violation at a rate of {baumgarte_rate:.3e} 1/s, which limits the step of {} to \
             about {baumgarte_limit:.2e} s: {baumgarte_steps:.1e} steps over the span, more \
             than the cap of {cap:.1e}; use a smaller stabilization.alpha and beta (of the \
             order of the mechanism's own frequencies) or stabilization.projection",
            bg.alpha,
            bg.beta,
            cfg.method.name()
        )));
    }
    if baumgarte_steps > 1e5 || cfg.ode.fixed_step.is_some_and(|h| h > baumgarte_limit) {
        watch.warn(format!(
            "the problem is stiff for {} through its stabilization: Baumgarte's terms \
             (stabilization.alpha = {:e}, beta = {:e}) decay the constraint violation at a rate of \
             {baumgarte_rate:.3e} 1/s, which limits the step to about {baumgarte_limit:.2e} s \
             ({baumgarte_steps:.1e} steps over the span); use a smaller stabilization.alpha and \
             beta (of the order of the mechanism's own frequencies) or stabilization.projection",
            cfg.method.name(),
            bg.alpha,
            bg.beta
        ));
    }
    let Ok(modes) = crate::formulation::fastest_modes(sys, cfg.t0, q0, qd0, 60) else {
        return Ok(()); // the run itself will report a singular matrix
    };
    growth_check(sys, cfg, q0, qd0, &modes, watch)?;
    let limit = modes.step_limit(reach);
    let fastest = if modes.sigma > modes.omega {
        modes.sources[1]
    } else {
        modes.sources[0]
    };
    if let (None, true) = (cfg.ode.fixed_step, span / limit > cap) {
        return Err(SimulationError::TooStiff(format!(
            "the force elements make the problem too stiff for {}: its stability limits the \
             step to about {limit:.2e} s (fastest mode ω = {:.3e} rad/s, damping rate σ = \
             {:.3e} 1/s at t0{}), {:.1e} steps over the span, more than the cap of {cap:.1e}; \
             check that element's values, or use an implicit method (genalpha), whose steps \
             are set by accuracy",
            cfg.method.name(),
            modes.omega,
            modes.sigma,
            element_note(sys, cfg.t0, q0, qd0, fastest),
            span / limit
        )));
    }
    if let Some(h) = cfg.ode.fixed_step {
        if h > limit {
            return Err(SimulationError::Unstable {
                method: cfg.method.name(),
                h,
                limit,
                reach,
                omega: modes.omega,
                sigma: modes.sigma,
            });
        }
    } else {
        let steps = (cfg.t_end - cfg.t0) / limit;
        if steps > 1e5 {
            watch.warn(format!(
                "the problem is stiff for {}: its stability limits the step to about {limit:.2e} s \
                 (fastest mode ω = {:.3e} rad/s, damping rate σ = {:.3e} 1/s{}), at least \
                 {steps:.1e} steps over the span; an implicit method (genalpha) takes steps set \
                 by accuracy",
                cfg.method.name(),
                modes.omega,
                modes.sigma,
                element_note(sys, cfg.t0, q0, qd0, fastest)
            ));
        }
    }
    Ok(())
}

/// Times the loads at t0 move a body by the mechanism's size over the span
/// above which a run gets a warning that its loads are out of scale:
/// 10⁴ (each crossing takes several steps); above the step cap, a refusal.
pub const LOAD_CROSSINGS: f64 = 1e4;

/// The loads' time scale at t0 (above [`LOAD_CROSSINGS`]) and a
/// statically unstable mode growing at γ ([`crate::formulation::FastestModes::growth`]):
/// following it takes steps below 1/γ with any method; a warning above 10⁵
/// such steps over the span, a refusal above `max_steps`.
fn growth_check(
    sys: &System,
    cfg: &RunConfig,
    q0: &[f64],
    qd0: &[f64],
    modes: &crate::formulation::FastestModes,
    watch: &mut Watch<'_, '_, '_, '_>,
) -> Result<(), SimulationError> {
    let span = cfg.t_end - cfg.t0;
    let cap = cfg.ode.max_steps as f64;
    // the loads' time scale: from rest, a body at the largest acceleration
    // crosses the mechanism's size in τ = √(2 L / a)
    let qb = &q0[..sys.n_body_coords()];
    let (lo, hi) = qb.chunks(3).fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), b| {
            (
                [lo[0].min(b[0]), lo[1].min(b[1])],
                [hi[0].max(b[0]), hi[1].max(b[1])],
            )
        },
    );
    let largest = qb
        .chunks(3)
        .flat_map(|b| b[..2].iter())
        .fold(1e-3, |a: f64, v| a.max(v.abs()));
    let size = largest.max((hi[0] - lo[0]).hypot(hi[1] - lo[1]));
    let tau = (2.0 * size / modes.accel).sqrt();
    let crossings = span / tau;
    if crossings > LOAD_CROSSINGS || crossings.is_nan() {
        let (body, element) = modes.accel_source;
        let name = sys.bodies().get(body).map_or("?", |b| b.name.as_str());
        let text = format!(
            "the loads at t0 accelerate body '{name}' at {:.3e} m/s²{}: from rest it would \
             cross the mechanism's size {size:.3e} m in τ = √(2 L / a) = {tau:.3e} s, {crossings:.1e} \
             times over the span, each taking several steps",
            modes.accel,
            element_note(sys, cfg.t0, q0, qd0, element).replacen(';', " —", 1)
        );
        if crossings > cap || crossings.is_nan() {
            return Err(SimulationError::TooStiff(format!(
                "{text}: more than the cap of {cap:.1e} steps; check that element's values"
            )));
        }
        watch.warn(format!("{text}; check that element's values"));
    }
    let steps = span * modes.growth;
    if steps <= 1e5 {
        return Ok(());
    }
    let text = format!(
        "the force elements make the initial state statically unstable: a mode grows like \
         exp(γ t), γ = {:.3e} 1/s (a negative stiffness at t0{}), so following it takes steps \
         below about {:.2e} s, at least {steps:.1e} over the span",
        modes.growth,
        element_note(sys, cfg.t0, q0, qd0, modes.sources[2]),
        1.0 / modes.growth
    );
    if steps > cfg.ode.max_steps as f64 {
        return Err(SimulationError::TooStiff(format!(
            "{text}, more than the cap of {:.1e}; check that element's values (a compressed \
             spring's force over its length is a negative stiffness)",
            cfg.ode.max_steps as f64
        )));
    }
    watch.warn(format!(
        "{text}; check that element's values (a compressed spring's force over its length is a \
         negative stiffness)"
    ));
    Ok(())
}

/// "; mostly from LABEL, whose generalized force at t0 has norm |g|" for
/// the element a rate comes from ([`System::force_label`]: its scenario
/// name), or "".
fn element_note(sys: &System, t: f64, q: &[f64], qd: &[f64], i: Option<usize>) -> String {
    let Some(e) = i.and_then(|i| sys.forces().get(i).map(|e| (i, e))) else {
        return String::new();
    };
    let mut g = vec![0.0; q.len()];
    e.1.add_forces(t, q, qd, &mut g);
    let force = match norm2(&g) {
        f if f > 0.0 => format!(", whose generalized force at t0 has norm {f:.3e}"),
        _ => String::new(),
    };
    format!("; mostly from {}{force}", sys.force_label(e.0))
}
