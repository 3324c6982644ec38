//! The adaptive embedded Runge–Kutta engine shared by `ode23` and `ode45`.
//!
//! The step-size control is a transcription of the main loop of MATLAB's
//! `ode23.m` / `ode45.m` (Shampine & Reichelt, "The MATLAB ODE Suite",
//! SIAM J. Sci. Comput. 18 (1997)), parametrised by an [`EmbeddedTableau`]:
//!
//! * `threshold = atol / rtol`; `hmax = min(|tf - t0|, MaxStep)` with
//!   `MaxStep` defaulting to `0.1·|tf - t0|`; `hmin = 16·eps(t)` recomputed
//!   at the start of every step.
//! * Initial step: `absh = min(hmax, |tf - t0|)`,
//!   `rh = ‖f0 ./ max(|y0|, threshold)‖∞ / (0.8·rtol^pow)`, `absh = 1/rh` if
//!   `absh·rh > 1`, then `absh = max(absh, hmin)`; a user `initial_step`
//!   gives `absh = min(hmax, max(hmin, initial_step))`.
//! * Each step: `absh = min(hmax, max(hmin, absh))`; if `1.1·absh ≥ |tf - t|`
//!   the step is stretched to end exactly on `tf`.
//! * Error: `err = absh·‖(Σ_j E_j k_j) ./ max(|y|, |y_new|, threshold)‖∞`
//!   (NormControl off); accept iff `err ≤ rtol`.
//! * Failure: if `absh ≤ hmin` the run fails; otherwise the first failure of
//!   the step sets `absh = max(hmin, absh·max(floor, 0.8·(rtol/err)^pow))`
//!   (`floor` = 0.5 in `ode23.m`, 0.1 in `ode45.m`), later failures halve `absh`.
//! * Success without failure: `temp = 1.25·(err/rtol)^pow`,
//!   `absh = temp > 0.2 ? absh/temp : 5·absh`.
//! * Output at requested times by the continuous extension of `ntrp23.m` /
//!   `ntrp45.m`; a requested time equal to the step end gets the step's `y_new`.
//!
//! `rhs_evals` counts as MATLAB's `nfevals`: 1 for `f(t0, y0)` plus `s - 1`
//! per attempted step (the FSAL stage is reused as the next first stage).

use std::ops::ControlFlow;

use super::common::{self, call_rhs, eval_stages, lincomb, weighted_sum};
use super::tableau::{EmbeddedTableau, MAX_STAGES};
use super::{
    Integrator, IntegratorError, Method, Observer, OdeOptions, OdeSystem, Report, Stats,
    Termination, Tolerance,
};

/// Adaptive embedded RK integrator with MATLAB's step-size control.
pub(crate) struct EmbeddedRk {
    method: Method,
    options: OdeOptions,
    tableau: &'static EmbeddedTableau,
}

impl EmbeddedRk {
    pub fn new(method: Method, options: OdeOptions, tableau: &'static EmbeddedTableau) -> Self {
        Self {
            method,
            options,
            tableau,
        }
    }
}

/// Weighted infinity norm of MATLAB's error estimate (without the `absh`
/// factor): `max_i |est_i| / max(|y_i|, |ynew_i|, thr_i)`. A component with
/// `0/0` (possible only with `atol = 0`) contributes 0, as MATLAB's `max`
/// ignores the NaN it produces.
fn error_norm(est: &[f64], y: &[f64], ynew: &[f64], thr: &[f64]) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..est.len() {
        let r = est[i].abs() / y[i].abs().max(ynew[i].abs()).max(thr[i]);
        if r > m {
            m = r;
        }
    }
    m
}

impl Integrator for EmbeddedRk {
    fn method(&self) -> Method {
        self.method
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
        let tab = self.tableau;
        let mut run = common::validate_run(sys, opts, t0, t_end, y0, output_times)?;
        let n = run.n;
        let s = tab.stages();
        let pow = tab.pow;
        let b = tab.b();

        // MATLAB's odearguments: rtol below 100*eps is raised, with a warning.
        let mut warnings = Vec::new();
        let mut rtol = opts.rtol;
        if rtol < 100.0 * f64::EPSILON {
            rtol = 100.0 * f64::EPSILON;
            warnings.push(format!(
                "rtol = {:e} is smaller than 100*eps; raised to {rtol:e} (as MATLAB does)",
                opts.rtol
            ));
        }
        let threshold: Vec<f64> = match &opts.atol {
            Tolerance::Scalar(a) => vec![a / rtol; n],
            Tolerance::Vector(v) => v.iter().map(|a| a / rtol).collect(),
        };

        // All work arrays, allocated once per run.
        let mut y = y0.to_vec();
        let mut ynew = vec![0.0; n];
        let mut ytmp = vec![0.0; n];
        let mut yout = vec![0.0; n];
        let mut k = vec![0.0; s * n];
        let mut stats = Stats::default();

        let stopped = |stats: Stats, t: f64, reason: String, t_reached: f64, w: Vec<String>| {
            common::report(stats, Termination::Stopped { t, reason }, t_reached, w)
        };
        let failed = |stats: Stats, t: f64, reason: String, w: Vec<String>| {
            common::report(stats, Termination::Failed { t, reason }, t, w)
        };

        let mut t = run.t0;
        if let ControlFlow::Break((ts, r)) = run.outputs.deliver_initial(t, &y, obs) {
            return Ok(stopped(stats, ts, r, t, warnings));
        }
        if let Err(r) = call_rhs(sys, t, &y, &mut k[..n], &mut stats) {
            return Ok(failed(stats, t, r, warnings));
        }

        let htspan = (run.t_end - run.t0).abs();
        let hmax = htspan.min(opts.max_step.map_or(0.1 * htspan, f64::abs));
        let mut hmin = 16.0 * common::eps(t);
        let mut absh = match opts.initial_step {
            Some(htry) => hmax.min(hmin.max(htry)),
            None => {
                let mut absh = hmax.min(htspan);
                let rh = error_norm(&k[..n], &y, &y, &threshold) / (0.8 * rtol.powf(pow));
                if absh * rh > 1.0 {
                    absh = 1.0 / rh;
                }
                absh.max(hmin)
            }
        };

        loop {
            if stats.steps >= opts.max_steps {
                let r = format!(
                    "maximum number of steps (max_steps = {}) reached at t = {t:e} before t_end = {:e}",
                    opts.max_steps, run.t_end
                );
                return Ok(failed(stats, t, r, warnings));
            }
            hmin = 16.0 * common::eps(t);
            absh = hmax.min(hmin.max(absh));
            let mut h = absh;
            let mut done = false;
            // Stretch the step if within 10% of t_end - t.
            if 1.1 * absh >= (run.t_end - t).abs() {
                h = run.t_end - t;
                absh = h.abs();
                done = true;
            }

            // Attempt the step until the error test passes.
            let mut nofailed = true;
            let (tnew, err) = loop {
                if let Err(r) = eval_stages(
                    sys,
                    t,
                    h,
                    &y,
                    tab.c,
                    tab.a,
                    1..=s - 2,
                    &mut k,
                    &mut ytmp,
                    &mut stats,
                ) {
                    let r = format!("{r} (in the step from t = {t:e})");
                    return Ok(failed(stats, t, r, warnings));
                }
                let tnew = if done { run.t_end } else { t + h };
                h = tnew - t; // purify h
                lincomb(&mut ynew, &y, h, b, &k);
                if let Some((i, v)) = common::first_non_finite(&ynew) {
                    let r = format!(
                        "non-finite state ({v}) in component {i} at t = {tnew:e} (step from t = {t:e})"
                    );
                    return Ok(failed(stats, t, r, warnings));
                }
                if let Err(r) = call_rhs(sys, tnew, &ynew, &mut k[(s - 1) * n..], &mut stats) {
                    let r = format!("{r} (in the step from t = {t:e})");
                    return Ok(failed(stats, t, r, warnings));
                }

                weighted_sum(&mut ytmp, 1.0, tab.e, &k);
                let err = absh * error_norm(&ytmp, &y, &ynew, &threshold);

                if err > rtol {
                    stats.failed_steps += 1;
                    if absh <= hmin {
                        let r = format!(
                            "failure at t = {t:e}: unable to meet integration tolerances without \
                             reducing the step size below the smallest value allowed \
                             (h = {hmin:e}) at time t"
                        );
                        return Ok(failed(stats, t, r, warnings));
                    }
                    if nofailed {
                        nofailed = false;
                        absh = hmin
                            .max(absh * tab.first_failure_floor.max(0.8 * (rtol / err).powf(pow)));
                    } else {
                        absh = hmin.max(0.5 * absh);
                    }
                    h = absh;
                    done = false;
                } else {
                    break (tnew, err);
                }
            };
            stats.steps += 1;

            // Requested outputs in (t, tnew], by the continuous extension.
            let deg = tab.interp_degree();
            let flow = run.outputs.deliver_step(
                tnew,
                &ynew,
                &mut yout,
                |tk, out| {
                    let sigma = (tk - t) / h;
                    let mut w = [0.0; MAX_STAGES];
                    for (wj, row) in w.iter_mut().zip(tab.bi) {
                        // Σ_p BI[j][p]·σ^(p+1), as cumprod([σ;σ;…]) in ntrp23/ntrp45.
                        let mut sp = 1.0;
                        for &bjp in &row[..deg] {
                            sp *= sigma;
                            *wj += bjp * sp;
                        }
                    }
                    lincomb(out, &y, h, &w[..s], &k);
                },
                obs,
            );
            if let ControlFlow::Break((ts, r)) = flow {
                return Ok(stopped(stats, ts, r, tnew, warnings));
            }
            if let ControlFlow::Break(r) = obs.step(tnew, &ynew) {
                return Ok(stopped(stats, tnew, r, tnew, warnings));
            }
            if done {
                return Ok(common::report(
                    stats,
                    Termination::Completed,
                    tnew,
                    warnings,
                ));
            }

            // If there were no failures compute a new h.
            if nofailed {
                let temp = 1.25 * (err / rtol).powf(pow);
                absh = if temp > 0.2 { absh / temp } else { 5.0 * absh };
            }

            // Advance; reuse f(tnew, ynew) as the first stage (FSAL).
            t = tnew;
            std::mem::swap(&mut y, &mut ynew);
            k.copy_within((s - 1) * n.., 0);
        }
    }
}
