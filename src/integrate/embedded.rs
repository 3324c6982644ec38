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
//! per attempted step (the FSAL stage is reused as the next first stage),
//! plus 1 per step whose end state [`OdeSystem::post_step`] moved.

use super::common::{
    self, call_rhs, error_norm, eval_stages, lincomb, post_step, weighted_sum, MatlabSteps,
    RunSpan, StepEnds,
};
use super::driver::{Failure, Stepper};
use super::tableau::{EmbeddedTableau, MAX_STAGES};
use super::{OdeSystem, Stats};

/// One run of the embedded pair: the system, MATLAB's step-control state
/// and the work arrays (allocated once).
pub(crate) struct EmbeddedStepper<'a> {
    sys: &'a mut dyn OdeSystem,
    tab: &'static EmbeddedTableau,
    /// MATLAB's step sizes.
    steps: MatlabSteps,
    /// Start and end of the last accepted step (the current state).
    ends: StepEnds,
    /// Its (purified) size.
    h: f64,
    /// `post_step` changed `ynew`: `f(tnew, ynew)` is in `f_post`, not in
    /// the last stage.
    post_changed: bool,
    ytmp: Vec<f64>,
    f_post: Vec<f64>,
    k: Vec<f64>,
    pub(crate) stats: Stats,
}

impl<'a> EmbeddedStepper<'a> {
    /// The stepper of one run of the pair `tab` (`n` = `sys.dim()`).
    pub(crate) fn new(
        sys: &'a mut dyn OdeSystem,
        run: &RunSpan<'_>,
        tab: &'static EmbeddedTableau,
    ) -> Self {
        let (t0, y0, n) = (run.t0, run.y0, run.n);
        Self {
            sys,
            tab,
            steps: MatlabSteps::new(run),
            ends: StepEnds::new(t0, y0),
            h: 0.0,
            post_changed: false,
            ytmp: vec![0.0; n],
            f_post: vec![0.0; n],
            k: vec![0.0; tab.stages() * n],
            stats: Stats::default(),
        }
    }
}

impl Stepper for EmbeddedStepper<'_> {
    fn start(&mut self) -> Result<(), Failure> {
        let n = self.ends.y.len();
        let t = self.ends.t;
        call_rhs(
            self.sys,
            t,
            &self.ends.y,
            &mut self.k[..n],
            &mut self.stats,
            None,
        )?;
        let scale = 0.8 * self.steps.rtol.powf(self.tab.pow);
        self.steps.first(t, &self.k[..n], &self.ends.y, scale);
        Ok(())
    }

    fn step(&mut self) -> Result<bool, Failure> {
        let tab = self.tab;
        let (n, s, pow, rtol) = (self.ends.y.len(), tab.stages(), tab.pow, self.steps.rtol);
        if self.ends.advance() {
            // reuse f(tnew, ynew) as the first stage (FSAL)
            if self.post_changed {
                self.k[..n].copy_from_slice(&self.f_post);
            } else {
                self.k.copy_within((s - 1) * n.., 0);
            }
        }
        let t = self.ends.t;
        let mut a = self.steps.attempt(t);

        // Attempt the step until the error test passes.
        let mut nofailed = true;
        let (tnew, err) = loop {
            let k = &mut self.k;
            eval_stages(
                self.sys,
                t,
                a.h,
                &self.ends.y,
                tab.c,
                tab.a,
                1..=s - 2,
                k,
                &mut self.ytmp,
                &mut self.stats,
            )?;
            let tnew = if a.done { self.steps.t_end } else { t + a.h };
            a.h = tnew - t; // purify h
            lincomb(&mut self.ends.ynew, &self.ends.y, a.h, tab.b(), k);
            common::step_end(
                self.sys,
                t,
                tnew,
                &self.ends.ynew,
                &mut k[(s - 1) * n..],
                &mut self.stats,
            )?;

            weighted_sum(&mut self.ytmp, 1.0, tab.e, k);
            let thr = &self.steps.threshold;
            let err = a.absh * error_norm(&self.ytmp, &self.ends.y, &self.ends.ynew, thr);

            if err > rtol {
                self.stats.failed_steps += 1;
                a.check_cut(t, err, rtol)?;
                let absh = if nofailed {
                    nofailed = false;
                    let cut = tab.first_failure_floor.max(0.8 * (rtol / err).powf(pow));
                    a.hmin.max(a.absh * cut)
                } else {
                    a.hmin.max(0.5 * a.absh)
                };
                a.retry(absh);
            } else {
                break (tnew, err);
            }
        };
        self.stats.steps += 1;
        // If there were no failures compute a new h.
        let mut absh = a.absh;
        if nofailed && !a.done {
            let temp = 1.25 * (err / rtol).powf(pow);
            absh = if temp > 0.2 { absh / temp } else { 5.0 * absh };
        }
        self.steps.absh = absh;
        self.h = a.h;
        self.post_changed = post_step(
            self.sys,
            tnew,
            &mut self.ends.ynew,
            &mut self.f_post,
            &mut self.stats,
        )?;
        self.ends.accept(tnew);
        Ok(a.done)
    }

    fn state(&self) -> (f64, &[f64]) {
        self.ends.current()
    }

    /// The continuous extension of `ntrp23.m` / `ntrp45.m`.
    fn interpolate(&self, tk: f64, out: &mut [f64]) {
        let tab = self.tab;
        let deg = tab.interp_degree();
        let sigma = (tk - self.ends.t) / self.h;
        let mut w = [0.0; MAX_STAGES];
        for (wj, row) in w.iter_mut().zip(tab.bi) {
            // Σ_p BI[j][p]·σ^(p+1), as cumprod([σ;σ;…]) in ntrp23/ntrp45.
            let mut sp = 1.0;
            for &bjp in &row[..deg] {
                sp *= sigma;
                *wj += bjp * sp;
            }
        }
        lincomb(out, &self.ends.y, self.h, &w[..tab.stages()], &self.k);
    }

    fn warnings(&self) -> &[String] {
        &self.steps.warnings
    }

    fn stats(&self) -> Stats {
        self.stats.clone()
    }
}
