//! Classic four-stage, fourth-order Runge–Kutta method with a fixed step.

use super::hermite::cubic;
use std::ops::ControlFlow;

use super::common::{self, call_rhs, eval_stages, lincomb};
use super::{
    Integrator, IntegratorError, Method, Observer, OdeOptions, OdeSystem, Report, Stats,
    Termination,
};

const RK4_C: [f64; 4] = [0.0, 0.5, 0.5, 1.0];
const RK4_A: [&[f64]; 4] = [&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]];
const RK4_B: [f64; 4] = [1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0];

/// Fixed-step classic RK4.
///
/// The step is `fixed_step`; the span is covered by `N = ceil((t_end - t0)/h)`
/// steps ending at `t0 + i·h` (no accumulated round-off), the last one
/// shortened to end exactly on `t_end` (a span within a relative `1e-9`
/// of an integer multiple of `h` uses exactly that many steps).
///
/// Dense output is the cubic Hermite interpolant of `y` and `f = y'` at both
/// ends of the step; `f(t_{i+1}, y_{i+1})` is evaluated after each step and
/// reused as the first stage of the next one, so a run costs
/// `rhs_evals = 4·steps + 1` evaluations.
pub(crate) struct Rk4 {
    options: OdeOptions,
}

impl Rk4 {
    pub fn new(options: OdeOptions) -> Self {
        Self { options }
    }
}

/// Number of fixed steps of size `h` covering `span`.
fn step_count(span: f64, h: f64) -> usize {
    let r = span / h;
    let nearest = r.round();
    let n = if nearest >= 1.0 && (r - nearest).abs() <= 1e-9 * r {
        nearest
    } else {
        r.ceil()
    };
    (n.max(1.0)).min(usize::MAX as f64) as usize
}

impl Integrator for Rk4 {
    fn method(&self) -> Method {
        Method::Rk4
    }

    fn integrate(
        &mut self,
        sys: &mut dyn OdeSystem,
        t0: f64,
        t_end: f64,
        y0: &[f64],
        output_times: &[f64],
        obs: &mut dyn Observer,
    ) -> Result<Report, IntegratorError> {
        let opts = &self.options;
        let mut run = common::validate_run(sys, opts, t0, t_end, y0, output_times)?;
        let h = opts
            .fixed_step
            .expect("validated by integrator(): rk4 has a fixed_step");
        let n = run.n;
        let nsteps = step_count(run.t_end - run.t0, h);

        let mut y = y0.to_vec();
        let mut ynew = vec![0.0; n];
        let mut ytmp = vec![0.0; n];
        let mut yout = vec![0.0; n];
        // k_1..k_4 followed by f(t_new, y_new).
        let mut k = vec![0.0; 5 * n];
        let mut stats = Stats::default();
        let warnings = Vec::new();

        let mut t = run.t0;
        if let ControlFlow::Break((ts, reason)) = run.outputs.deliver_initial(t, &y, obs) {
            return Ok(common::report(
                stats,
                Termination::Stopped { t: ts, reason },
                t,
                warnings,
            ));
        }
        let failed = |stats: Stats, t: f64, reason: String| {
            common::report(stats, Termination::Failed { t, reason }, t, Vec::new())
        };
        if let Err(r) = call_rhs(sys, t, &y, &mut k[..n], &mut stats) {
            return Ok(failed(stats, t, r));
        }

        for i in 0..nsteps {
            if stats.steps >= opts.max_steps {
                let r = format!(
                    "maximum number of steps (max_steps = {}) reached at t = {t:e} before t_end = {:e}",
                    opts.max_steps, run.t_end
                );
                return Ok(failed(stats, t, r));
            }
            let tnew = if i + 1 == nsteps {
                run.t_end
            } else {
                run.t0 + (i + 1) as f64 * h
            };
            let hs = tnew - t;
            if let Err(r) = eval_stages(
                sys,
                t,
                hs,
                &y,
                &RK4_C,
                &RK4_A,
                1..=3,
                &mut k[..4 * n],
                &mut ytmp,
                &mut stats,
            ) {
                let r = format!("{r} (in the step from t = {t:e})");
                return Ok(failed(stats, t, r));
            }
            lincomb(&mut ynew, &y, hs, &RK4_B, &k[..4 * n]);
            if let Some((c, v)) = common::first_non_finite(&ynew) {
                let r = format!(
                    "non-finite state ({v}) in component {c} at t = {tnew:e} (step from t = {t:e})"
                );
                return Ok(failed(stats, t, r));
            }
            if let Err(r) = call_rhs(sys, tnew, &ynew, &mut k[4 * n..], &mut stats) {
                let r = format!("{r} (in the step from t = {t:e})");
                return Ok(failed(stats, t, r));
            }
            stats.steps += 1;

            let (f0, rest) = k.split_at(n);
            let f1 = &rest[3 * n..];
            let flow = run.outputs.deliver_step(
                tnew,
                &ynew,
                &mut yout,
                |tk, out| cubic(out, (tk - t) / hs, hs, &y, f0, &ynew, f1),
                obs,
            );
            if let ControlFlow::Break((ts, reason)) = flow {
                return Ok(common::report(
                    stats,
                    Termination::Stopped { t: ts, reason },
                    tnew,
                    warnings,
                ));
            }
            if let ControlFlow::Break(reason) = obs.step(tnew, &ynew) {
                return Ok(common::report(
                    stats,
                    Termination::Stopped { t: tnew, reason },
                    tnew,
                    warnings,
                ));
            }
            t = tnew;
            std::mem::swap(&mut y, &mut ynew);
            k.copy_within(4 * n.., 0);
        }
        Ok(common::report(stats, Termination::Completed, t, warnings))
    }
}
