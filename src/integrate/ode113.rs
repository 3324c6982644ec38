//! `ode113`: variable-order (1–12, PECE with local extrapolation, i.e.
//! corrector orders up to 13), variable-step Adams–Bashforth–Moulton in the
//! modified-divided-difference form of Shampine & Gordon ("Computer
//! Solution of Ordinary Differential Equations: the Initial Value Problem",
//! Freeman 1975, subroutines STEP and INTRP), with the step control of
//! MATLAB's `ode113.m` (Shampine & Reichelt 1997):
//!
//! * tolerances, `hmax`, `hmin = 16·eps(t)`, step stretching to `t_end` as
//!   in `ode23`/`ode45` ([`super::common::MatlabTolerances`]);
//! * initial step: `rh = ‖f0 ./ max(|y0|, threshold)‖∞ / (0.25·√rtol)`,
//!   `absh = min(hmax, |tf − t0|)`, `1/rh` if `absh·rh > 1`;
//! * the weights `max(|y|, threshold)` are fixed at the start of the step;
//!   the local error of the order-k corrector is
//!   `err = |h|·(g_k − g_{k+1})·‖(f(p) − φ*_1) ./ wt‖∞` and the step is
//!   accepted iff `err ≤ rtol`;
//! * a failed step halves `|h|`, the third failure in a row drops to order
//!   1, later ones use `min(½, √(½ rtol / erk))`;
//! * order: raised in the start phase until an estimate says otherwise,
//!   then lowered/raised by comparing the error estimates at orders
//!   k − 2 … k + 1 (STEP, blocks 2 and 4); step: doubled while
//!   `½ rtol ≥ 2^{k+1}·erk`, kept while `½ rtol ≥ erk`, else scaled by
//!   `max(½, min(0.9, (½ rtol / erk)^{1/(k+1)}))`;
//! * dense output: the interpolating polynomial of the last step
//!   (`ntrp113.m`, INTRP).
//!
//! `rhs_evals` counts as MATLAB's `nfevals`: 1 for `f(t0, y0)`, 2 per
//! accepted step (predictor evaluation and the final evaluation of PECE),
//! 1 per rejected attempt. The compensated summation of STEP (`nornd`) is
//! not done (MATLAB does not either).
//!
//! A [`OdeSystem::post_step`] that moves `y_n` replaces `f_n` by
//! `f(t_n, y_n)` in the history: every modified divided difference
//! `φ_i(n)` (i = 1 … k + 2) contains `f_n` with coefficient 1, so the
//! change `δ = f_new − f_n` is added to each of them.

#![allow(clippy::needless_range_loop)] // 1-based transcription of STEP/INTRP

use super::common::{self, call_rhs, post_step, MatlabSteps, RunSpan};
use super::driver::{Failure, Stepper};
use super::{OdeSystem, Stats};

/// Highest order of the predictor (the corrector is one higher).
const MAXK: usize = 12;
/// Columns of φ (1-based: 1 … k + 2 ≤ 14).
const NPHI: usize = MAXK + 3;
/// `gstar(k)`: the error constants of STEP (1-based, `[0]` unused).
const GSTAR: [f64; 14] = [
    0.0, 0.5, 0.0833, 0.0417, 0.0264, 0.0188, 0.0143, 0.0114, 0.00936, 0.00789, 0.00679, 0.00592,
    0.00524, 0.00468,
];

/// `max_i |x_i| · invwt_i` (a `0·∞` term — `atol = 0`, `y_i = 0` — is
/// ignored as MATLAB's `max` ignores NaN).
fn wnorm(x: &[f64], invwt: &[f64]) -> f64 {
    let mut m: f64 = 0.0;
    for (xi, wi) in x.iter().zip(invwt) {
        let r = xi.abs() * wi;
        if r > m {
            m = r;
        }
    }
    m
}

/// One run of ode113: the state, the modified divided differences and
/// the coefficient arrays of STEP (1-based, index 0 unused).
pub(crate) struct Ode113Stepper<'a> {
    sys: &'a mut dyn OdeSystem,
    /// MATLAB's step sizes.
    steps: MatlabSteps,
    t: f64,
    y: Vec<f64>,
    /// `f(t, y)` at the current state.
    yp: Vec<f64>,
    /// φ, column `i` at `i·n`.
    phi: Vec<f64>,
    psi: [f64; NPHI],
    alpha: [f64; NPHI],
    beta: [f64; NPHI],
    sig: [f64; NPHI],
    v: [f64; NPHI],
    w: [f64; NPHI],
    g: [f64; NPHI],
    /// Current order.
    k: usize,
    /// Order and step of the last accepted step.
    klast: usize,
    hlast: f64,
    ns: usize,
    phase1: bool,
    p: Vec<f64>,
    phikp1: Vec<f64>,
    invwt: Vec<f64>,
    f_post: Vec<f64>,
    pub(crate) stats: Stats,
}

impl<'a> Ode113Stepper<'a> {
    /// The stepper of one run (`n` = `sys.dim()`).
    pub(crate) fn new(sys: &'a mut dyn OdeSystem, run: &RunSpan<'_>) -> Self {
        let (t0, y0, n) = (run.t0, run.y0, run.n);
        let mut g = [0.0; NPHI];
        g[1] = 1.0;
        g[2] = 0.5;
        let mut sig = [0.0; NPHI];
        sig[1] = 1.0;
        Self {
            sys,
            steps: MatlabSteps::new(run),
            t: t0,
            y: y0.to_vec(),
            yp: vec![0.0; n],
            phi: vec![0.0; NPHI * n],
            psi: [0.0; NPHI],
            alpha: [0.0; NPHI],
            beta: [0.0; NPHI],
            sig,
            v: [0.0; NPHI],
            w: [0.0; NPHI],
            g,
            k: 1,
            klast: 0,
            hlast: 0.0,
            ns: 0,
            phase1: true,
            p: vec![0.0; n],
            phikp1: vec![0.0; n],
            invwt: vec![0.0; n],
            f_post: vec![0.0; n],
            stats: Stats::default(),
        }
    }

    fn n(&self) -> usize {
        self.y.len()
    }

    /// Column `i` of φ.
    fn col(&self, i: usize) -> &[f64] {
        let n = self.n();
        &self.phi[i * n..(i + 1) * n]
    }

    /// The coefficients α, β, ψ, σ, g of the step of size `h` at order k
    /// (STEP block 1); only those that change when the step size did.
    fn coefficients(&mut self, h: f64) {
        let k = self.k;
        if h != self.hlast {
            self.ns = 0;
        }
        if self.ns <= self.klast {
            self.ns += 1;
        }
        let ns = self.ns;
        if k < ns {
            return;
        }
        self.beta[ns] = 1.0;
        self.alpha[ns] = 1.0 / ns as f64;
        let mut temp1 = h * ns as f64;
        self.sig[ns + 1] = 1.0;
        for i in ns + 1..=k {
            let temp2 = self.psi[i - 1];
            self.psi[i - 1] = temp1;
            temp1 = temp2 + h;
            self.beta[i] = self.beta[i - 1] * self.psi[i - 1] / temp2;
            self.alpha[i] = h / temp1;
            self.sig[i + 1] = i as f64 * self.alpha[i] * self.sig[i];
        }
        self.psi[k] = temp1;
        if ns == 1 {
            for iq in 1..=k {
                self.v[iq] = 1.0 / (iq * (iq + 1)) as f64;
                self.w[iq] = self.v[iq];
            }
        } else {
            if k > self.klast {
                self.v[k] = 1.0 / (k * (k + 1)) as f64;
                for j in 1..=ns.saturating_sub(2) {
                    self.v[k - j] -= self.alpha[j + 1] * self.v[k - j + 1];
                }
            }
            for iq in 1..=k + 1 - ns {
                self.v[iq] -= self.alpha[ns] * self.v[iq + 1];
                self.w[iq] = self.v[iq];
            }
            self.g[ns + 1] = self.w[1];
        }
        for i in ns + 2..=k + 1 {
            for iq in 1..=k + 2 - i {
                self.w[iq] -= self.alpha[i - 1] * self.w[iq + 1];
            }
            self.g[i] = self.w[1];
        }
    }
}

impl Stepper for Ode113Stepper<'_> {
    fn start(&mut self) -> Result<(), Failure> {
        let n = self.n();
        let t = self.t;
        call_rhs(self.sys, t, &self.y, &mut self.yp, &mut self.stats, None)?;
        self.phi[n..2 * n].copy_from_slice(&self.yp);
        let scale = 0.25 * self.steps.rtol.sqrt();
        self.steps.first(t, &self.yp, &self.y, scale);
        Ok(())
    }

    fn step(&mut self) -> Result<bool, Failure> {
        let n = self.n();
        let rtol = self.steps.rtol;
        let tlast = self.t;
        let mut a = self.steps.attempt(tlast);
        for i in 0..n {
            self.invwt[i] = 1.0 / self.y[i].abs().max(self.steps.threshold[i]);
        }
        let mut failed = 0;
        let (knew, erkm1, mut erk) = loop {
            self.coefficients(a.h);
            let (k, ns) = (self.k, self.ns);
            // φ → φ* (β_i φ_i for i > ns).
            for i in ns + 1..=k {
                let b = self.beta[i];
                self.phi[i * n..(i + 1) * n]
                    .iter_mut()
                    .for_each(|x| *x *= b);
            }
            // Predict: p = y + h Σ g_i φ*_i; φ_i ← φ*_i + φ_{i+1} (the
            // differences of the predicted derivative).
            self.phi.copy_within((k + 1) * n..(k + 2) * n, (k + 2) * n);
            self.phi[(k + 1) * n..(k + 2) * n].fill(0.0);
            self.p.fill(0.0);
            for i in (1..=k).rev() {
                let gi = self.g[i];
                let (lo, hi) = self.phi.split_at_mut((i + 1) * n);
                let ci = &mut lo[i * n..];
                for l in 0..n {
                    self.p[l] += gi * ci[l];
                    ci[l] += hi[l];
                }
            }
            for l in 0..n {
                self.p[l] = self.y[l] + a.h * self.p[l];
            }
            let tnew = if a.done {
                self.steps.t_end
            } else {
                tlast + a.h
            };
            call_rhs(
                self.sys,
                tnew,
                &self.p,
                &mut self.yp,
                &mut self.stats,
                Some(tlast),
            )?;
            // Errors at orders k, k − 1, k − 2.
            for l in 0..n {
                self.phikp1[l] = self.yp[l] - self.phi[n + l];
            }
            let sum_norm = |c: &[f64], d: &[f64], w: &[f64]| {
                let mut m: f64 = 0.0;
                for l in 0..c.len() {
                    let r = (c[l] + d[l]).abs() * w[l];
                    if r > m {
                        m = r;
                    }
                }
                m
            };
            let erkm2 = if k > 2 {
                a.absh
                    * self.sig[k - 1]
                    * GSTAR[k - 2]
                    * sum_norm(self.col(k - 1), &self.phikp1, &self.invwt)
            } else {
                0.0
            };
            let erkm1 = if k > 1 {
                a.absh
                    * self.sig[k]
                    * GSTAR[k - 1]
                    * sum_norm(self.col(k), &self.phikp1, &self.invwt)
            } else {
                0.0
            };
            let nrm = wnorm(&self.phikp1, &self.invwt);
            let erk = a.absh * self.sig[k + 1] * GSTAR[k] * nrm;
            let err = a.absh * (self.g[k] - self.g[k + 1]) * nrm;
            let mut knew = k;
            if (k == 2 && erkm1 <= 0.5 * erk) || (k > 2 && erkm1.max(erkm2) <= erk) {
                knew = k - 1;
            }
            if err <= rtol {
                break (knew, erkm1, erk);
            }
            // Failed: restore φ and ψ, cut the step.
            self.stats.failed_steps += 1;
            a.check_cut(tlast, err, rtol)?;
            self.phase1 = false;
            for i in 1..=k {
                let b = 1.0 / self.beta[i];
                let (lo, hi) = self.phi.split_at_mut((i + 1) * n);
                for (x, y) in lo[i * n..].iter_mut().zip(&hi[..n]) {
                    *x = (*x - *y) * b;
                }
            }
            for i in 2..=k {
                self.psi[i - 1] = self.psi[i] - a.h;
            }
            failed += 1;
            let mut reduce: f64 = 0.5;
            if failed == 3 {
                knew = 1;
            } else if failed > 3 {
                reduce = reduce.min((0.5 * rtol / erk).sqrt());
            }
            a.retry((reduce * a.absh).max(a.hmin));
            self.k = knew;
        };
        self.stats.steps += 1;
        let k = self.k;
        self.klast = k;
        self.hlast = a.h;
        let tnew = if a.done {
            self.steps.t_end
        } else {
            tlast + a.h
        };
        // Correct and evaluate.
        let gk1 = a.h * self.g[k + 1];
        for l in 0..n {
            self.y[l] = self.p[l] + gk1 * self.phikp1[l];
        }
        common::step_end(
            self.sys,
            tlast,
            tnew,
            &self.y,
            &mut self.yp,
            &mut self.stats,
        )?;
        // Update the differences.
        for l in 0..n {
            let d = self.yp[l] - self.phi[n + l];
            self.phi[(k + 1) * n + l] = d;
            self.phi[(k + 2) * n + l] = d - self.phi[(k + 2) * n + l];
        }
        for i in 1..=k {
            let (lo, hi) = self.phi.split_at_mut((k + 1) * n);
            for (x, d) in lo[i * n..(i + 1) * n].iter_mut().zip(&hi[..n]) {
                *x += *d;
            }
        }
        if knew + 1 == k || k == MAXK {
            self.phase1 = false;
        }
        // A new order.
        if self.phase1 {
            self.k = k + 1;
        } else if knew + 1 == k {
            self.k = k - 1;
            erk = erkm1;
        } else if k < self.ns {
            let erkp1 = a.absh * GSTAR[k + 1] * wnorm(self.col(k + 2), &self.invwt);
            if k == 1 {
                if erkp1 < 0.5 * erk {
                    self.k = 2;
                    erk = erkp1;
                }
            } else if erkm1 <= erk.min(erkp1) {
                self.k = k - 1;
                erk = erkm1;
            } else if k < MAXK && erkp1 < erk {
                self.k = k + 1;
                erk = erkp1;
            }
        }
        // A new step size.
        if self.phase1 || 0.5 * rtol >= erk * 2f64.powi(self.k as i32 + 1) {
            a.absh *= 2.0;
        } else if 0.5 * rtol < erk {
            let reduce = (0.5 * rtol / erk).powf(1.0 / (self.k + 1) as f64);
            a.absh *= reduce.clamp(0.5, 0.9);
        }
        self.steps.absh = a.absh;
        self.t = tnew;
        if post_step(
            self.sys,
            tnew,
            &mut self.y,
            &mut self.f_post,
            &mut self.stats,
        )? {
            for l in 0..n {
                let d = self.f_post[l] - self.yp[l];
                for i in 1..=k + 2 {
                    self.phi[i * n + l] += d;
                }
            }
            self.yp.copy_from_slice(&self.f_post);
        }
        Ok(a.done)
    }

    fn state(&self) -> (f64, &[f64]) {
        (self.t, &self.y)
    }

    /// The interpolating polynomial of the last step (`ntrp113.m`, INTRP):
    /// `y(t) = y_n + (t − t_n) Σ_{j ≤ k+1} g_j(t) φ_j(n)`.
    fn interpolate(&self, tk: f64, out: &mut [f64]) {
        let hi = tk - self.t;
        let ki = self.klast + 1;
        let mut w = [0.0; NPHI];
        let mut g = [0.0; NPHI];
        for (i, wi) in w.iter_mut().enumerate().take(ki + 1).skip(1) {
            *wi = 1.0 / i as f64;
        }
        g[1] = 1.0;
        let mut term = 0.0;
        for j in 2..=ki {
            let psijm1 = self.psi[j - 1];
            let gamma = (hi + term) / psijm1;
            let eta = hi / psijm1;
            for i in 1..=ki + 1 - j {
                w[i] = gamma * w[i] - eta * w[i + 1];
            }
            g[j] = w[1];
            term = psijm1;
        }
        let n = self.n();
        out.fill(0.0);
        for (j, &gj) in g.iter().enumerate().take(ki + 1).skip(1) {
            for (o, x) in out.iter_mut().zip(&self.phi[j * n..(j + 1) * n]) {
                *o += gj * x;
            }
        }
        for (o, yl) in out.iter_mut().zip(&self.y) {
            *o = yl + hi * *o;
        }
    }

    fn warnings(&self) -> &[String] {
        &self.steps.warnings
    }

    fn stats(&self) -> Stats {
        self.stats.clone()
    }
}
