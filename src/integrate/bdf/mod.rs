//! `bdf`: variable-order (1–5), variable-step BDF on the index-3
//! equations of motion of a [`SecondOrderDae`]
//! (`M q̈ + Φ_qᵀλ = g(t, q, q̇)`, `Φ(q, t) = 0`), the method family of
//! DASSL (Brenan, Campbell & Petzold 1996) and MATLAB's `ode15s`
//! (Shampine & Reichelt 1997) in the variable-coefficient form.
//!
//! **Formula.** On the nodes `τ_0 = t_{n+1}, τ_j = t_{n+1−j}` (j = 1 … k)
//! the BDF of order k replaces a derivative at `t_{n+1}` by that of the
//! interpolating polynomial, `ẏ_{n+1} ≈ Σ_j a_j y_{n+1−j}` with
//! `a_j = ℓ_j′(τ_0)` (Lagrange basis). Applied to `q̇ = v`, `v̇ = q̈`:
//! `v = a_0 q + r_q`, `q̈ = a_0 v + r_v` with the history sums `r_q, r_v`,
//! and the unknowns `q_{n+1}, λ_{n+1}` solve
//! `M q̈ + Φ_qᵀλ − g = 0`, `Φ(q, t_{n+1}) = 0` by (modified) Newton with the
//! iteration matrix of [`SecondOrderDae::factorize`] at
//! `c = [1, 1/a_0, 1/a_0²]` — the residual rows and λ scaled by `1/a_0²`
//! (Bottasso, Bauchau & Cardona 2007), so the matrix stays `O(1)` as
//! `h → 0`: the same sparse pattern, solver and assembly as
//! generalized-α. Why the index-3 form and not GGL: docs/bdf.md.
//!
//! **NDF** ([`OdeOptions::ndf`], `ode15s`'s default; Shampine & Reichelt
//! 1997): the derivative of order k becomes
//! `Σ_j a_j y_{n+1−j} − κ_k γ_k (y_{n+1} − ŷ_{n+1})/h` with
//! `γ_k = Σ_{i≤k} 1/i`, κ = [`NDF_KAPPA`] and ŷ the predictor below (at a
//! constant step `y_{n+1} − ŷ = ∇^{k+1} y_{n+1}`, ode15s's backward-
//! difference form; on an uneven grid the term still vanishes on
//! polynomials of degree k, so the order stays k). It changes `a_0` by
//! `−κγ/h` and adds `κγ/h·ŷ` to the history sums — nothing else — and
//! multiplies the error constant `1/(k+1)` by `1 + (k+1)κ_kγ_k`
//! (0.63, 0.50, 0.40, 0.57, 1 for k = 1 … 5; tests/integrators/bdf.rs measures 0.630
//! and 0.505 at k = 1, 2). **Highest order** [`OdeOptions::max_order`]
//! (`ode15s`'s `MaxOrder`).
//!
//! **Predictor**: the polynomial through the last `k + 1` accepted
//! points (at the first step `y_0 + h ẏ_0`), λ kept constant.
//! **Newton**: corrections `Δq` (`Δv = a_0 Δq`, `Δλ`), measured in the
//! error test's norm of the positions, `max(1, h a_0)·‖Δq ./ w_q‖∞` (a
//! position error δ makes the velocity error `a_0 δ`, which the test
//! weighs as `h a_0 δ`); with ode15s's convergence logic (Shampine &
//! Reichelt 1997): one correction suffices if `θ/(1 − θ)·‖Δ‖ ≤
//! κ_1 rtol` with the rate θ measured before on the same matrix (at least
//! [`THETA_FIRST`]), later ones when `θ/(1 − θ)·‖Δ‖ ≤ κ rtol`
//! (κ_1 = [`NEWTON_KAPPA_FIRST`], κ = [`NEWTON_KAPPA`]); θ > [`DIVERGE_ABOVE`], or a
//! rate that cannot reach the tolerance within [`MAX_NEWTON`] iterations,
//! is a failure; a correction at the rounding floor of `q` or below
//! [`NEWTON_FLOOR`]·rtol ends it. The velocity weights `a_0 Δq ./ w_v`
//! used before asked 3.8 iterations per step of the stiff chain
//! (N = 1000) against 2.1 now, at the same tip error, and at N = 10 000
//! made the rounding noise of the angles (×`a_0` ≈ 3e9 at the first
//! steps) look like divergence (docs/bdf.md). The factorisation is kept across
//! steps while `a_0` stays within [`REUSE_BAND`] of the one it was made
//! for and the iteration contracts (θ ≤ [`THETA_REFACTOR`]); a failed
//! attempt on a stale matrix is retried at once with a fresh one, and
//! only a failure on a fresh matrix cuts the step (×0.3, counted in
//! `newton_failures`).
//!
//! **Error control** in MATLAB's norm on the positions, the differential
//! variables of the index-3 form:
//! `err = ‖est ./ max(|q_n|, |q_{n+1}|, atol/rtol)‖∞ ≤ rtol`, with the
//! local error of order p estimated from the divided difference of the
//! accepted values, `est_p = p!·h^{p+1}·q[τ_0, …, τ_{p+1}]` (for a constant
//! step `= (q_{n+1} − q̂)/(p+1)`, q̂ the predictor; Hairer & Wanner II §III.5).
//! The velocities `q̇ = a_0 q + r_q` are an index-2 variable: their
//! estimate enters times `h` (the position error it makes over the step)
//! in the positions' weights, as index-2 components are scaled by `h`
//! (Hairer & Wanner II §VII.3; Brenan, Campbell & Petzold §5.4);
//! unscaled, the step of an index-3 pendulum collapses to `16 eps(t)`.
//! λ, the index-3 variable, is left out (the velocity term's effect on
//! the stiff chain: docs/scaling.md, "Measurements behind the defaults").
//! **First step**: the Euler error `½h²q̈_0` of the positions at a quarter
//! of rtol in that norm. MATLAB's rule (`‖[q̇; q̈] ./ [q; q̇]‖`) fails on a
//! stiff chain at rest (q̈_0 large, the velocity weights at their
//! threshold): it chooses a first step at which `v = a_0 q + r_q` is
//! rounding noise of q (docs/scaling.md, "Measurements behind the
//! defaults").
//! **Order and step**: after k + 1 steps at order k the orders k − 1, k,
//! k + 1 (≤ `max_order`) are compared (their estimates computed with the
//! error test's, one norm pass for all) by the steps they allow,
//! `h_p = h·(rtol/est_p)^{1/(p+1)}/s_p` (s = 1.3, 1.2, 1.4 as `ode15s`),
//! and the largest wins; the step grows at most 5×, is kept if it would grow
//! by less than 20 %. A rejected step is cut by
//! `max(0.1, 0.8 (rtol/err)^{1/(k+1)})`, the second rejection in a row
//! halves it and lowers the order.
//!
//! Dense output: the interpolating polynomial of the last step (through
//! `t_{n+1}` and the k points before it).

#![allow(clippy::needless_range_loop)] // index loops over parallel arrays (q, v, history)

use std::collections::VecDeque;

mod newton;

use super::common;
use super::driver::{Failure, StepCut, Stepper};
use super::implicit::{
    attempt_or_cut, implicit_entry, implicit_outputs, implicit_stepper, validate_run, Attempted,
    CutRules, Cuts, ImplicitStats, Renewal, RenewalOptions, Shrink, Span, StateView, StepTry, Warn,
};
use super::{
    IntegratorError, Method, OdeOptions, SecondOrderDae, SystemError, Tolerance, REUSE_BAND,
    ROUNDING_ULPS,
};
use crate::parallel::{split_pass, PARALLEL_MIN_COORDS};

/// Highest order.
pub const MAX_ORDER: usize = 5;
/// κ_k of the NDF of order k = 1 … 5 (Shampine & Reichelt 1997, as
/// `ode15s`; index 0 unused): κ_5 = 0 is BDF5.
pub const NDF_KAPPA: [f64; MAX_ORDER + 1] = [0.0, -0.1850, -1.0 / 9.0, -0.0823, -0.0415, 0.0];

/// `κ_k γ_k` with `γ_k = Σ_{j=1}^k 1/j`: the NDF of order k is the BDF's
/// derivative minus `κ_k γ_k (y_{n+1} − ŷ_{n+1}) / h` (ŷ the predictor).
fn ndf_shift(k: usize) -> f64 {
    NDF_KAPPA[k] * (1..=k).map(|j| 1.0 / j as f64).sum::<f64>()
}

/// Coordinates per chunk of the predictor's pass (`predict`): its partial
/// sums stay in L1 while the history streams by.
const CHUNK: usize = 256;

/// Components side by side in the error estimates' pass
/// ([`EstimateIn::block`]).
const LANES: usize = 8;

/// Newton iterations per attempt.
pub const MAX_NEWTON: usize = 4;
/// Newton stops when the estimated remaining error `θ/(1 − θ)·‖Δ‖` is
/// below `κ·rtol` (ode15s: 0.5; with 0.5 and 0.05 the four-bar of
/// tests/integrators/bdf.rs lost its convergence in rtol, 2.4e-4 off at rtol 1e-9
/// against 2.7e-5 with 0.1 and 0.02).
pub(crate) const NEWTON_KAPPA: f64 = 0.1;
/// κ for a step's first correction, judged with the contraction rate
/// measured on the same matrix before (ode15s: 0.05).
pub(crate) const NEWTON_KAPPA_FIRST: f64 = 0.02;
/// A correction below `NEWTON_FLOOR·rtol` in the error test's norm ends
/// Newton (ode15s's `minnrm` is 100 ulps; this also stops the rounding
/// noise of the chain's angles, ~1e-14 rad at N = 10 000).
pub(crate) const NEWTON_FLOOR: f64 = 1e-4;
/// Contraction assumed for the first correction of a step: at least this
/// (a tiny θ measured at the rounding floor must not accept a large first
/// correction).
pub(crate) const THETA_FIRST: f64 = 0.3;
/// A contraction θ above this fails the attempt (ode15s: 0.9).
pub(crate) const DIVERGE_ABOVE: f64 = 0.9;

/// The BDF integrator (module docs).
#[derive(Debug, Clone)]
pub struct Bdf {
    ode: OdeOptions,
    stats: ImplicitStats,
}

impl Bdf {
    /// Validate the options (step-controlled: `rtol`, `atol`, `max_step`,
    /// `initial_step`, no fixed step).
    pub fn new(ode: OdeOptions) -> Result<Self, IntegratorError> {
        ode.validate(Method::Bdf, true)?;
        Ok(Self {
            ode,
            stats: ImplicitStats::default(),
        })
    }

    implicit_entry! {
        /// Integrate from `(t0, q0, q̇0)` to `t_end`; the observer receives
        /// `y = [q; q̇]` (as [`super::GenAlpha::integrate`]).
        |bdf, sys, span| {
            validate_run(sys.n(), span, &bdf.ode, true)?;
            BdfRun::new(sys, &bdf.ode, span)
        }
    }
}

/// Lagrange weights `ℓ_j(t)` on `nodes`.
fn lagrange(nodes: &[f64], t: f64, w: &mut [f64]) {
    for j in 0..nodes.len() {
        let mut p = 1.0;
        for m in 0..nodes.len() {
            if m != j {
                p *= (t - nodes[m]) / (nodes[j] - nodes[m]);
            }
        }
        w[j] = p;
    }
}

/// `a_j = ℓ_j′(τ_0)`: the BDF coefficients on `nodes = [τ_0, τ_1, …]`.
fn bdf_coefficients(nodes: &[f64], a: &mut [f64]) {
    let t0 = nodes[0];
    a[0] = nodes[1..].iter().map(|&tm| 1.0 / (t0 - tm)).sum();
    for j in 1..nodes.len() {
        let mut num = 1.0;
        let mut den = 1.0;
        for m in 0..nodes.len() {
            if m == j {
                continue;
            }
            den *= nodes[j] - nodes[m];
            if m != 0 {
                num *= t0 - nodes[m];
            }
        }
        a[j] = num / den;
    }
}

/// Weights of the divided difference `y[τ_0, …, τ_p] = Σ_j w_j y_j`.
fn divided_difference(nodes: &[f64], w: &mut [f64]) {
    for j in 0..nodes.len() {
        let mut den = 1.0;
        for m in 0..nodes.len() {
            if m != j {
                den *= nodes[j] - nodes[m];
            }
        }
        w[j] = 1.0 / den;
    }
}

/// One BDF run: the history of accepted `(t, [q; v])`, newest first.
struct BdfRun<'s> {
    sys: &'s mut dyn SecondOrderDae,
    n: usize,
    rtol: f64,
    threshold: Vec<f64>,
    /// Highest order ([`OdeOptions::max_order`]).
    max_order: usize,
    /// NDF instead of BDF ([`OdeOptions::ndf`]).
    ndf: bool,
    initial_step: Option<f64>,
    hmax: f64,
    t_end: f64,
    /// Accepted points, newest first (at most `MAX_ORDER + 2`).
    ts: VecDeque<f64>,
    ys: VecDeque<Vec<f64>>,
    /// `[v; q̈]` at `t0` (the first step's predictor).
    f0: Vec<f64>,
    lam: Vec<f64>,
    k: usize,
    /// Order of the last accepted step (dense output).
    klast: usize,
    steps_at_k: usize,
    absh: f64,
    /// When the Newton matrix is renewed (band on the `a_0` it was made
    /// for).
    renewal: Renewal,
    /// The failure path's state.
    cuts: Cuts,
    /// Contraction rate measured on the current matrix (ode15s's `rate`).
    rate: Option<f64>,
    // Newton buffers
    q: Vec<f64>,
    v: Vec<f64>,
    qdd: Vec<f64>,
    lam_new: Vec<f64>,
    rq: Vec<f64>,
    rv: Vec<f64>,
    r: Vec<f64>,
    /// `1 / max(|q_n|, |q̂|, atol/rtol)`: the Newton norm's weights.
    inv_w: Vec<f64>,
    /// The new point `[q; q̇]` of the step being tried.
    ynew: Vec<f64>,
    stats: ImplicitStats,
    warnings: Vec<String>,
}

impl<'s> BdfRun<'s> {
    fn new(sys: &'s mut dyn SecondOrderDae, ode: &OdeOptions, span: &Span<'_>) -> Self {
        let (n, m) = (sys.n(), sys.m());
        let Span {
            t0, t_end, q0, qd0, ..
        } = *span;
        let mut tol = common::MatlabTolerances::new(ode, 2 * n, t0, t_end);
        if let Tolerance::Vector(v) = &ode.atol {
            if v.len() == n {
                // one atol per coordinate, for q and q̇ alike
                tol.threshold = v.iter().chain(v).map(|a| a / tol.rtol).collect();
            }
        }
        let mut y0 = q0.to_vec();
        y0.extend_from_slice(qd0);
        Self {
            sys,
            n,
            rtol: tol.rtol,
            threshold: tol.threshold,
            max_order: ode.max_order.clamp(1, MAX_ORDER),
            ndf: ode.ndf,
            initial_step: ode.initial_step,
            hmax: tol.hmax,
            t_end,
            ts: VecDeque::from([t0]),
            ys: VecDeque::from([y0]),
            f0: vec![0.0; 2 * n],
            lam: vec![0.0; m],
            k: 1,
            klast: 1,
            steps_at_k: 0,
            absh: 0.0,
            renewal: Renewal::new(RenewalOptions {
                band: REUSE_BAND,
                across_attempts: true,
                every_correction: false,
            }),
            // ode15s: Newton failures are counted, not warned of
            cuts: Cuts::new(CutRules {
                shrink: Shrink::Ode15s,
                warn: Warn::Never,
                first_cause: false,
            }),
            rate: None,
            q: vec![0.0; n],
            v: vec![0.0; n],
            qdd: vec![0.0; n],
            lam_new: vec![0.0; m],
            rq: vec![0.0; n],
            rv: vec![0.0; n],
            r: vec![0.0; n + m],
            inv_w: vec![0.0; n],
            ynew: vec![0.0; 2 * n],
            stats: ImplicitStats::default(),
            warnings: tol.warnings,
        }
    }

    /// Error constant of order `p` relative to the BDF's `1/(p+1)`: 1 for
    /// the BDF, `1 + (p+1) κ_p γ_p` for the NDF (`ode15s`'s
    /// `erconst = κγ + 1/(p+1)`; Shampine & Reichelt 1997).
    fn error_factor(&self, p: usize) -> f64 {
        if self.ndf {
            1.0 + (p as f64 + 1.0) * ndf_shift(p)
        } else {
            1.0
        }
    }

    /// The weights of the error estimates of the orders `ps` (at most
    /// three, each `≤ ts.len() − 1`; module docs): the local error of
    /// order p is `p!·h^{p+1}·y[τ_0 … τ_{p+1}]` on the new point and the
    /// last `p + 1` accepted ones, times [`Self::error_factor`]; `w[o][j]`
    /// weighs the new point (`j = 0`) and history point `j − 1` in it
    /// ([`EstimateIn`]).
    fn estimate_weights(&self, ps: &[usize], t1: f64, h: f64) -> [[f64; MAX_ORDER + 3]; 3] {
        let mut w = [[0.0; MAX_ORDER + 3]; 3];
        for (o, &p) in ps.iter().enumerate() {
            let mut nodes = [0.0; MAX_ORDER + 3];
            nodes[0] = t1;
            for j in 0..=p {
                nodes[j + 1] = self.ts[j];
            }
            divided_difference(&nodes[..p + 2], &mut w[o][..p + 2]);
            let fact: f64 = (1..=p).map(|i| i as f64).product();
            let c = fact * h.powi(p as i32 + 1) * self.error_factor(p);
            w[o][..p + 2].iter_mut().for_each(|x| *x *= c);
        }
        w
    }

    /// The step's end in one pass over the components, in two fixed halves
    /// concurrently for large n (one hand-over): `[q; q̇]` copied into
    /// `ynew` and checked finite, and with `est` (the orders `ps` and
    /// their weights, [`Self::estimate_weights`]) the error estimates
    /// `‖est_p ./ max(|y_n|, |y_new|, thr)‖∞` of those orders
    /// ([`EstimateIn`]; zero without). The max is order-free: the same
    /// bits in one piece or in halves.
    fn step_end(
        &mut self,
        est: Option<(&[usize], &[[f64; MAX_ORDER + 3]; 3])>,
        h: f64,
    ) -> (bool, [f64; 3]) {
        let n = self.n;
        let mut hist: [&[f64]; MAX_ORDER + 2] = [&[]; MAX_ORDER + 2];
        for (hj, y) in hist.iter_mut().zip(&self.ys) {
            *hj = y;
        }
        let (hist, threshold) = (&hist, &self.threshold[..]);
        let (yq, yv) = self.ynew.split_at_mut(n);
        let pass = |base: usize, (yq, yv, q, v): (&mut [f64], &mut [f64], &[f64], &[f64])| {
            let mut finite = true;
            for (d, &x) in yq.iter_mut().zip(q).chain(yv.iter_mut().zip(v)) {
                *d = x;
                finite &= x.is_finite();
            }
            let e = est.map_or([0.0; 3], |(ps, w)| {
                let (yq, yv) = (&*yq, &*yv);
                let src = EstimateIn {
                    n,
                    ps,
                    w,
                    hist,
                    base,
                    yq,
                    yv,
                    threshold,
                    h,
                };
                src.range(base, base + yq.len())
            });
            (finite, e)
        };
        split_pass(
            n >= PARALLEL_MIN_COORDS,
            n,
            (yq, yv, &self.q[..n], &self.v[..n]),
            pass,
            |(fa, ea), (fb, eb)| (fa && fb, std::array::from_fn(|o| ea[o].max(eb[o]))),
        )
    }
}

/// What the error estimates' pass reads ([`BdfRun::step_end`]): the
/// orders `ps`, their weights `w[o][j]` on the new point (`j = 0`) and the
/// history points `hist[j − 1]` (newest first, each `[q; q̇]` of length
/// `2n`), the new point's positions `yq` and velocities `yv` of the
/// components from `base` on, the weights' thresholds and the step.
struct EstimateIn<'a> {
    n: usize,
    ps: &'a [usize],
    w: &'a [[f64; MAX_ORDER + 3]; 3],
    hist: &'a [&'a [f64]; MAX_ORDER + 2],
    base: usize,
    yq: &'a [f64],
    yv: &'a [f64],
    threshold: &'a [f64],
    h: f64,
}

impl EstimateIn<'_> {
    /// The weighted max-norms of the estimates over the coordinates
    /// `lo..hi`: per component, `Σ_j w_oj y_j` for each order o over its
    /// p + 2 nodes (t1 and p + 1 history points), then the weighted max;
    /// [`LANES`] components side by side, their sums in registers (no
    /// stores of partial sums), the terms in the same order as one
    /// component at a time.
    fn range(&self, lo: usize, hi: usize) -> [f64; 3] {
        let mut m = [0.0f64; 3];
        let body = lo + (hi - lo) / LANES * LANES;
        for i0 in (lo..body).step_by(LANES) {
            let b = self.block::<LANES>(i0);
            for (mo, bo) in m.iter_mut().zip(b) {
                *mo = mo.max(bo);
            }
        }
        for i in body..hi {
            let b = self.block::<1>(i);
            for (mo, bo) in m.iter_mut().zip(b) {
                *mo = mo.max(bo);
            }
        }
        m
    }

    /// The weighted maxima of components `i0 .. i0 + B` per order: the
    /// weights' inverse, then each order's sums `Σ_j w_oj y_j` in
    /// registers (the terms in the order j = 0, 1, …, as one component at
    /// a time), B components side by side.
    #[inline(always)]
    fn block<const B: usize>(&self, i0: usize) -> [f64; 3] {
        let (n, h, hist) = (self.n, self.h, self.hist);
        let j0 = i0 - self.base;
        let (yq, yv) = (&self.yq[j0..j0 + B], &self.yv[j0..j0 + B]);
        // the newest history point: y_n of the weights
        let (ynq, thr) = (&hist[0][i0..i0 + B], &self.threshold[i0..i0 + B]);
        let inv: [f64; B] =
            std::array::from_fn(|l| 1.0 / ynq[l].abs().max(yq[l].abs()).max(thr[l]));
        let mut m = [0.0f64; 3];
        for (o, &p) in self.ps.iter().enumerate() {
            let wo = &self.w[o];
            let mut dq: [f64; B] = std::array::from_fn(|l| wo[0] * yq[l]);
            let mut dv: [f64; B] = std::array::from_fn(|l| wo[0] * yv[l]);
            for j in 1..p + 2 {
                let (y, wj) = (hist[j - 1], wo[j]);
                let (hq, hv) = (&y[i0..i0 + B], &y[n + i0..n + i0 + B]);
                for l in 0..B {
                    dq[l] += wj * hq[l];
                    dv[l] += wj * hv[l];
                }
            }
            // velocities, an index-2 variable of the index-3 form:
            // `h·est_v`, the position error they make over the step, in
            // the positions' weights (Hairer & Wanner II §VII.3; Brenan,
            // Campbell & Petzold §5.4 scale index-2 components by h)
            let e: [f64; B] = std::array::from_fn(|l| dq[l].abs().max(h * dv[l].abs()) * inv[l]);
            m[o] = e.iter().fold(0.0, |a: f64, &b| a.max(b));
        }
        m
    }
}

implicit_stepper!(BdfRun<'_>);

impl Stepper for BdfRun<'_> {
    fn start(&mut self) -> Result<(), Failure> {
        let n = self.n;
        let t = self.ts[0];
        let (q0, v0) = self.ys[0].split_at(n);
        self.stats.residual_evaluations += 1;
        self.sys
            .accelerations(StateView { t, q: q0, qd: v0 }, &mut self.qdd, &mut self.lam)
            .map_err(Failure::system("consistent accelerations", t, None))?;
        self.f0[..n].copy_from_slice(v0);
        self.f0[n..].copy_from_slice(&self.qdd);
        if let Some((index, value)) = common::first_non_finite(&self.f0) {
            return Err(Failure::NonFinite {
                what: "consistent accelerations",
                t,
                step_from: None,
                index,
                value,
            });
        }
        let hmin = 16.0 * common::eps(t);
        self.absh = match self.initial_step {
            Some(htry) => self.hmax.min(hmin.max(htry)),
            None => {
                // the first step's error is the Euler error ½h²q̈ of the
                // positions: at a quarter of rtol in the error test's norm
                let (q0, thr) = (&self.ys[0][..n], &self.threshold[..n]);
                let acc = (0..n)
                    .map(|i| self.f0[n + i].abs() / q0[i].abs().max(thr[i]))
                    .fold(0.0f64, f64::max);
                let mut absh = self.hmax.min(self.t_end - t);
                if acc > 0.0 {
                    absh = absh.min((0.5 * self.rtol / acc).sqrt());
                }
                absh.max(hmin)
            }
        };
        Ok(())
    }

    fn step(&mut self) -> Result<bool, Failure> {
        let n = self.n;
        let t = self.ts[0];
        let hmin = 16.0 * common::eps(t);
        let mut absh = self.hmax.min(hmin.max(self.absh));
        let mut done = false;
        let mut h = absh;
        if 1.1 * absh >= self.t_end - t {
            h = self.t_end - t;
            absh = h;
            done = true;
        }
        let mut rejections = 0;
        let (t1, err, est_lower, est_higher) = loop {
            let t1 = if done { self.t_end } else { t + h };
            h = t1 - t;
            if t1 <= t {
                return Err(Failure::StepTooSmall {
                    t,
                    h,
                    h_min: hmin,
                    cause: StepCut::NoProgress,
                });
            }
            let x = StepTry {
                t,
                t_new: t1,
                h,
                h_ctl: absh,
                h_min: hmin,
            };
            if let Attempted::Cut(next) = attempt_or_cut(self, x)? {
                absh = next;
                h = absh;
                done = false;
                continue;
            }
            // the order k's estimate, and those of k ∓ 1 where the order
            // may change after this step (in the same pass); none at the
            // first step
            let (k, len) = (self.k, self.ts.len());
            let change = rejections == 0 && self.steps_at_k >= k && len > k;
            let lower = change && k > 1;
            let higher = change && k < self.max_order && len > k + 1;
            let mut ps = [k.min(len - 1), 0, 0];
            let mut np = 1;
            if lower {
                ps[np] = k - 1;
                np += 1;
            }
            if higher {
                ps[np] = k + 1;
                np += 1;
            }
            let w = (len > 1).then(|| self.estimate_weights(&ps[..np], t1, h));
            // copy [q; q̇], check it finite (located only on failure) and
            // estimate the errors in one pass
            let (finite, e) = self.step_end(w.as_ref().map(|w| (&ps[..np], w)), h);
            if let Some((index, value)) = (!finite)
                .then(|| common::first_non_finite(&self.ynew))
                .flatten()
            {
                return Err(Failure::NonFinite {
                    what: "step",
                    t: t1,
                    step_from: Some(t),
                    index,
                    value,
                });
            }
            let (err, est_lower, est_higher) = if self.ts.len() == 1 {
                // first step: y − (y_0 + h ẏ_0) estimates the Euler error
                // (velocities times h, as in `EstimateIn::block`)
                let y0 = &self.ys[0];
                let mut m: f64 = 0.0;
                for i in 0..n {
                    let e = self.ynew[i] - (y0[i] + h * self.f0[i]);
                    let ev = self.ynew[n + i] - (y0[n + i] + h * self.f0[n + i]);
                    let w = y0[i].abs().max(self.ynew[i].abs()).max(self.threshold[i]);
                    m = m.max(e.abs().max(h * ev.abs()) / w);
                }
                (m * self.error_factor(1), None, None)
            } else {
                (e[0], lower.then_some(e[1]), higher.then(|| e[np - 1]))
            };
            if err <= self.rtol {
                break (t1, err, est_lower, est_higher);
            }
            self.stats.error_rejections += 1;
            rejections += 1;
            if absh <= hmin {
                return Err(Failure::StepTooSmall {
                    t,
                    h: absh,
                    h_min: hmin,
                    cause: StepCut::ErrorTest {
                        err: err / self.rtol,
                    },
                });
            }
            let k = self.k;
            if rejections == 1 {
                absh *= 0.1f64.max(0.8 * (self.rtol / err).powf(1.0 / (k as f64 + 1.0)));
            } else {
                absh *= 0.5;
                if k > 1 {
                    self.k -= 1;
                    self.steps_at_k = 0;
                }
            }
            absh = absh.max(hmin);
            h = absh;
            done = false;
        };
        // accept
        let k = self.k;
        self.stats.accept(h);
        self.stats.steps_at_order[k] += 1;
        self.steps_at_k += 1;
        // order and step for the next step
        let mut best_p = k;
        let mut best = (self.rtol / err.max(1e-300)).powf(1.0 / (k as f64 + 1.0)) / 1.2;
        if let Some(e) = est_lower {
            let r = (self.rtol / e.max(1e-300)).powf(1.0 / k as f64) / 1.3;
            if r > best {
                best = r;
                best_p = k - 1;
            }
        }
        if let Some(e) = est_higher {
            let r = (self.rtol / e.max(1e-300)).powf(1.0 / (k as f64 + 2.0)) / 1.4;
            if r > best {
                best = r;
                best_p = k + 1;
            }
        }
        if best_p != k {
            self.k = best_p;
            self.steps_at_k = 0;
        }
        let ratio = if rejections > 0 {
            best.min(1.0)
        } else {
            best.min(5.0)
        };
        if !(1.0..1.2).contains(&ratio) {
            absh *= ratio.max(0.2);
        }
        self.absh = absh;
        self.klast = k;
        // push the new point
        let mut slot = if self.ts.len() >= MAX_ORDER + 2 {
            self.ts.pop_back();
            self.ys.pop_back().unwrap_or_default()
        } else {
            vec![0.0; 2 * n]
        };
        std::mem::swap(&mut slot, &mut self.ynew);
        self.ts.push_front(t1);
        self.ys.push_front(slot);
        self.lam.copy_from_slice(&self.lam_new);
        Ok(done)
    }

    fn state(&self) -> (f64, &[f64]) {
        (self.ts[0], &self.ys[0])
    }

    /// The interpolating polynomial of the last step through `t_{n+1}` and
    /// the `k` points before it.
    fn interpolate(&self, t: f64, out: &mut [f64]) {
        let p = (self.klast + 1).min(self.ts.len());
        let mut nodes = [0.0; MAX_ORDER + 2];
        let mut w = [0.0; MAX_ORDER + 2];
        for (j, nj) in nodes[..p].iter_mut().enumerate() {
            *nj = self.ts[j];
        }
        lagrange(&nodes[..p], t, &mut w[..p]);
        out.fill(0.0);
        for (j, wj) in w[..p].iter().enumerate() {
            for (o, y) in out.iter_mut().zip(&self.ys[j]) {
                *o += wj * y;
            }
        }
    }

    implicit_outputs!();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Constant step: the coefficients are those of the classical BDF
    /// (order 2: (3/2, −2, 1/2)/h), and they differentiate polynomials of
    /// degree k exactly on an uneven grid.
    #[test]
    fn coefficients_are_exact_on_polynomials() {
        let mut a = [0.0; 3];
        bdf_coefficients(&[2.0, 1.0, 0.0], &mut a);
        assert!((a[0] - 1.5).abs() < 1e-15 && (a[1] + 2.0).abs() < 1e-15);
        assert!((a[2] - 0.5).abs() < 1e-15);
        let nodes = [1.0, 0.9, 0.75, 0.7, 0.4, 0.35];
        for k in 1..=5 {
            let mut a = [0.0; 6];
            bdf_coefficients(&nodes[..k + 1], &mut a[..k + 1]);
            // y = t^k: y'(1) = k
            let d: f64 = (0..=k).map(|j| a[j] * nodes[j].powi(k as i32)).sum();
            assert!((d - k as f64).abs() < 1e-9, "order {k}: {d}");
        }
    }
}
