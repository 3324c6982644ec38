//! Generalized-α for constrained mechanical systems in index-3 form, with
//! HHT-α and Newmark as parameter choices.
//!
//! Split by idea: `params` (the method's parameters from ρ∞, the options),
//! `newton` (Newton iteration and factorisation reuse), `step` (error
//! estimate and step-size choice), `augmented` (the augmented Lagrangian:
//! the same scheme on a system with a multiplier update,
//! [`SecondOrderDae::multiplier_update`]); this module holds the
//! integrator and its run loop.
//!
//! # The scheme
//!
//! Chung & Hulbert, "A time integration algorithm for structural dynamics
//! with improved numerical dissipation: the generalized-α method", J. Appl.
//! Mech. 60 (1993), in the form of Arnold & Brüls, "Convergence of the
//! generalized-α scheme for constrained mechanical systems", Multibody
//! Syst. Dyn. 18 (2007), eq. (9)–(10), applied to
//! `M q̈ + Φ_qᵀ λ = g(q, q̇, t)`, `Φ(q, t) = 0`:
//!
//! ```text
//! q_{n+1} = q_n + h q̇_n + h² (½ − β) a_n + h² β a_{n+1}
//! q̇_{n+1} = q̇_n + h (1 − γ) a_n + h γ a_{n+1}
//! (1 − α_m) a_{n+1} + α_m a_n = (1 − α_f) q̈_{n+1} + α_f q̈_n
//! M q̈_{n+1} + Φ_qᵀ(q_{n+1}) λ_{n+1} = g(q_{n+1}, q̇_{n+1}, t_{n+1}),   Φ(q_{n+1}, t_{n+1}) = 0
//! ```
//!
//! `a_n` is an auxiliary acceleration-like variable (`a_0 = q̈_0`, the
//! consistent accelerations at `t_0`). Positions and velocities converge
//! with order 2; the constraints hold at every step to the Newton
//! tolerance (no drift-off, unlike the index-1 form of eq. (5)).
//!
//! # Parameters from the spectral radius at infinity ρ∞ ([`AlphaParameters`])
//!
//! * generalized-α (Chung & Hulbert 1993, eq. (25), (17), (20)):
//!   `α_m = (2ρ∞ − 1)/(ρ∞ + 1)`, `α_f = ρ∞/(ρ∞ + 1)`,
//!   `γ = ½ + α_f − α_m`, `β = ¼ (γ + ½)²`; ρ∞ ∈ [0, 1];
//! * HHT-α (Hilber, Hughes & Taylor, Earthquake Eng. Struct. Dyn. 5
//!   (1977)) as the special case `α_m = 0`, `α_f = (1 − ρ∞)/(1 + ρ∞)`,
//!   `γ = ½ + α_f`, `β = ¼ (1 + α_f)²`; ρ∞ ∈ [½, 1];
//! * Newmark (α_m = α_f = 0) with `γ = (3 − ρ∞)/(2 (1 + ρ∞))`,
//!   `β = ¼ (γ + ½)²` (its amplification matrix has the double eigenvalue
//!   `(γ − 3/2)/(γ + ½) = −ρ∞` at `ωh → ∞`); ρ∞ = 1 is the trapezoidal
//!   rule, every ρ∞ < 1 makes it only first-order accurate.
//!
//! In all cases the algorithmic dissipation is that of the linear analysis:
//! high-frequency components are multiplied by ρ∞ per step.
//!
//! # Newton iteration
//!
//! The unknowns are the positions: with the predictor `q̈_{n+1} = q̈_n`
//! (or, with [`ImplicitOptions::extrapolate`], extrapolated linearly from
//! `q̈_{n−1}, q̈_n` when that predicted the last step better,
//! `Run::choose_predictor`), `λ_{n+1} = 0`
//! the formulas above give `q`, `q̇`, `a`, and every Newton correction
//! `Δq` moves `q̇` by `γ' Δq`, `q̈` by `β' Δq`, `a` by `Δq/(β h²)`, with
//! `γ' = γ/(β h)`, `β' = (1 − α_m)/(β h² (1 − α_f))` (Arnold & Brüls 2007,
//! Algorithm 1). The linear systems are those of the scaled iteration
//! matrix of [`SecondOrderDae::factorize`] (constraint rows and λ scaled
//! by `β h²`, Bottasso, Bauchau & Cardona 2007).
//!
//! **Multipliers from zero.** The residual is linear in λ, so the first
//! correction gives λ_{n+1} whole whatever λ it starts from; starting from
//! 0 (the matrix, when factorised at the predictor, still takes its
//! geometric stiffness `(Φ_qᵀλ)_q` at λ_n) makes λ_{n+1} the
//! representative of one regularised solve. Starting from λ_n instead
//! accumulated, step after step, the components of the corrections in the
//! null space of Φ_qᵀ — the unreachable constraint residual (rounding of Φ)
//! of a redundant row divided by the regularised pivot and by `β h²`, which
//! grows as h shrinks, and near a singular position by a pivot just above
//! the threshold: carried across steps, λ's null-space part grows without
//! bound on a redundant chain and the changing Φ_qᵀ turns it into residual
//! at every predictor; from zero, |λ| stays physical
//! (tests/formulation/redundant.rs; figures in docs/constraint_methods.md).
//!
//! **Reuse (modified Newton).** A factorisation is kept across iterations
//! and steps while the iteration contracts fast enough. It is renewed
//! * at the predictor, when the step size moved by more than
//!   [`REUSE_BAND`] since it was computed, or when the previous step saw a
//!   contraction factor `θ = ‖Δq_k‖/‖Δq_{k−1}‖` above [`THETA_REFACTOR`] or
//!   needed more than [`SLOW_ITERATIONS`] corrections, or when renewing
//!   it at every predictor saves at least `RENEW_SAVING` (= 2, about one
//!   factorisation) corrections per step: the fewer corrections of the
//!   last two attempts on a matrix factorised at their predictor against
//!   those of the last attempt on an older one (every `QUAD_REUSE`-th
//!   renewal in a row is skipped to measure the latter again). On the
//!   stiff chain a reused matrix contracts by θ ≈ 0.025 per step of its
//!   age (3–5 corrections) where a fresh one converges quadratically in
//!   1–2: N = 1000, h = 1e-5, 3.38 → 2.48 corrections per step, 869 →
//!   4651 factorisations, less CPU time; problem C keeps its reuse;
//! * at the current iterate, once per attempt, when `max_newton`
//!   corrections did not suffice but the iteration still contracts;
//! * at the predictor, retrying the step once, when a stale factorisation
//!   made the iteration diverge (`θ ≥ 1`) or fail.
//!
//! Only then is the step cut. With `reuse = false` every correction gets a
//! fresh factorisation (full Newton up to the symmetrisation).
//!
//! **Convergence test** (Hairer & Wanner, Solving ODEs II, §IV.8, eq. (8.10)):
//! with `η = θ/(1 − θ)` (from the previous step, at least 1, for the first
//! correction) the iteration stops when `η ‖Δq‖_w ≤ 1` in the norm
//! `‖Δq‖_w = max_i |Δq_i| / (newton_tol / max(1, γ', β') + 20 ε max(|q_i|, 1))`:
//! the *acceleration* corrections `β' Δq` (and the velocity corrections
//! `γ' Δq`, the positions) are below `newton_tol`, unless that is below
//! the rounding noise of the positions (20 ulps, [`ROUNDING_ULPS`]; an
//! iteration that stops contracting with corrections below
//! [`STAGNATION`] such units has reached the noise of the linear solve
//! and counts as converged).
//! The tolerance is on accelerations on purpose: a Newton remainder `e`
//! in `q` perturbs `q̇` by `γ' e ~ e/h` and `a` by `e/(βh²)` at every step,
//! which sums to a global position error `~ T² e / h²` — a fixed position
//! tolerance would put a floor under the accuracy as `h → 0` (the bending
//! rod's case: docs/scaling.md, "Measurements behind the defaults"), while
//! `|β' e| ≤ newton_tol` bounds it by `~ T² newton_tol` for every h.
//! **Single correction.** On a matrix factorised at the predictor Newton
//! converges quadratically, `‖Δq₂‖ ≈ C ‖Δq₁‖²`; `C` is measured whenever
//! such an attempt makes a second correction (at the same step size; again
//! after `QUAD_REUSE` = 10 uses), and the first correction alone is
//! accepted when `C ‖Δq₁‖_w² ≤ 1` — the second would only iterate into
//! the rounding floor; `≤ 4` where the tolerance unit is the rounding floor itself
//! (`SINGLE_CORRECTION_AT_FLOOR`: a remainder of 80 ulps).
//! Optionally also `‖Φ(q_{n+1})‖∞` must be below the position-equivalent
//! tolerance ([`ImplicitOptions::check_constraints`]).
//! **Noise near a singular position.** Where Φ_q is close to losing rank
//! (smallest singular value σ, left and right singular vectors u, v), the
//! constraint rows of the solve turn the rounding of Φ (a few ulps of the
//! positions) into a correction `(uᵀΦ)/σ` along v, and the multipliers
//! into its `1/σ²`: the corrections stop contracting (θ = 1, 2, 3, 1.5 …:
//! ratios of rounding quanta) at a size set by σ, not by the tolerance,
//! and a smaller step — whose grid comes closer to the singular position —
//! only makes them larger relative to the tolerance. So before an attempt
//! fails by divergence (θ ≥ 1), the residual itself is asked
//! (`Run::at_constraint_noise`): if `‖Φ‖∞` at the iterate is at its
//! rounding floor (20 ulps of `max(|q|, 1)`) and the correction the
//! dynamic rows alone ask for is within the tolerance, the iterate solves
//! the equations to working precision and the attempt converges (with
//! that last correction applied, and λ computed whole from zero at the
//! accepted positions, as every attempt's first correction computes it:
//! the sum over the non-contracting corrections carries their noise, and
//! the next predictor's matrix takes λ in its geometric stiffness).
//!
//! # Step size
//!
//! * **Fixed** ([`OdeOptions::fixed_step`]): steps on the grid
//!   `t_0 + k h`, the last one shortened to end on `t_end`. When Newton
//!   fails (e.g. at a contact onset) the step is halved and the grid point
//!   reached by sub-steps that double again after each success.
//! * **Adaptive** ([`ImplicitOptions::adaptive`]): local error estimate of
//!   the positions (Géradin & Cardona, Flexible Multibody Dynamics, Wiley
//!   2001, §10; Zienkiewicz & Xie, Earthquake Eng. Struct. Dyn. 20 (1991) for
//!   Newmark): with `a_n ≈ q̈(t_n + (α_m − α_f) h)` the local truncation
//!   error of `q_{n+1}` is `(β − γ/2 + 1/12) h³ q⃛`, estimated as
//!   `e = (β − γ/2 + 1/12) h² (a_{n+1} − a_n)`; optionally (default)
//!   filtered through the iteration matrix, `[ẽ; ·] = K⁻¹ [c_m M e; 0]`,
//!   which leaves non-stiff components unchanged and damps the stiff ones
//!   and the constraint-normal ones (as the error filter of Hairer &
//!   Wanner's RADAU5). Error norm `max_i |e_i| / (atol_i + rtol max(|q_i^n|,
//!   |q_i^{n+1}|))` times `√(1e-3/rtol)` below rtol 1e-3 (tolerance
//!   proportionality, `step::proportionality`), accepted for ≤ 1; new
//!   step `h · min(2, max(0.2, 0.9 err^{−1/3}))` (no growth right after a
//!   rejection; changes below 20 % upwards are not made, to keep the
//!   factorisation), after an accepted step limited further by
//!   Gustafsson's predictive controller
//!   `0.9 (h_n/h_{n−1}) (err_{n−1}/err_n²)^{1/3}` (Hairer & Wanner II,
//!   eq. (8.21)), which damps the accept/reject cycles of an oscillating
//!   error. A Newton failure halves the step.
//!
//! A run that cannot proceed (step below the minimum, `max_steps`, a
//! non-finite state or a failing linear solve) ends with
//! [`Termination::Failed`] after every output up to the last accepted
//! step was delivered.

mod augmented;
mod newton;
mod params;
mod step;

pub use super::implicit::{NOISE_REL, ROUNDING_ULPS, STAGNATION, THETA_REFACTOR};
pub use augmented::{ALM_MAX_NEWTON, MAX_PENALTY_FACTOR, SLOW_CONTRACTION};
pub use newton::{REUSE_BAND, SLOW_ITERATIONS};
pub use params::AlphaParameters;
pub use step::SAFETY;

use super::driver::{Failure, StepCut, Stepper};
use super::hermite::cubic;
use super::implicit::{
    attempt_or_cut, implicit_entry, implicit_outputs, implicit_stepper, validate_run, Attempted,
    CutRules, Cuts, ImplicitStats, Renewal, RenewalOptions, SecondOrderDae, Shrink, Span,
    StateView, StepTry, Warn,
};
use super::Tolerance;
use super::{common, ImplicitOptions, IntegratorError, Method, OdeOptions, SystemError};

/// The generalized-α integrator (module docs) with its parameters and options.
#[derive(Debug, Clone)]
pub struct GenAlpha {
    method: Method,
    params: AlphaParameters,
    opts: ImplicitOptions,
    ode: OdeOptions,
    h_fixed: f64,
    stats: ImplicitStats,
}

/// State at one time point: positions, velocities, true accelerations,
/// auxiliary accelerations, multipliers.
#[derive(Debug, Clone)]
struct State {
    q: Vec<f64>,
    v: Vec<f64>,
    qdd: Vec<f64>,
    a: Vec<f64>,
    lam: Vec<f64>,
}

impl State {
    fn new(n: usize, m: usize) -> Self {
        Self {
            q: vec![0.0; n],
            v: vec![0.0; n],
            qdd: vec![0.0; n],
            a: vec![0.0; n],
            lam: vec![0.0; m],
        }
    }

    /// `(t, q, q̇)` of this state at `t`.
    fn at(&self, t: f64) -> StateView<'_> {
        StateView {
            t,
            q: &self.q,
            qd: &self.v,
        }
    }
}

impl GenAlpha {
    /// Validate the options and set up the parameters of `method`
    /// ([`Method::GenAlpha`], [`Method::Hht`] or [`Method::Newmark`]).
    pub fn new(
        method: Method,
        opts: ImplicitOptions,
        ode: OdeOptions,
    ) -> Result<Self, IntegratorError> {
        ode.validate(method, opts.adaptive)?;
        opts.validate(method, ode.fixed_step)?;
        let params = AlphaParameters::for_method(method, opts.rho_inf)?;
        // `OdeOptions::validate` guarantees a step when not adaptive
        let h_fixed = if opts.adaptive {
            0.0
        } else {
            ode.fixed_step.unwrap_or(0.0)
        };
        Ok(Self {
            method,
            params,
            opts,
            ode,
            h_fixed,
            stats: ImplicitStats::default(),
        })
    }

    /// [`GenAlpha::new`] for the augmented Lagrangian (a system with a
    /// [`SecondOrderDae::multiplier_update`]): a fixed step;
    /// `adaptive`, `project`, `reuse`, `filter_error`,
    /// `check_constraints`, `lu`, `extrapolate` do not apply
    /// ([`IntegratorError::NotApplicable`]).
    pub(crate) fn for_augmented_lagrangian(
        method: Method,
        opts: ImplicitOptions,
        ode: OdeOptions,
    ) -> Result<Self, IntegratorError> {
        augmented::check_options(method, &opts)?;
        Self::new(method, opts, ode)
    }

    /// The method.
    pub fn method(&self) -> Method {
        self.method
    }
    /// Its parameters.
    pub fn params(&self) -> AlphaParameters {
        self.params
    }
    /// The options in force.
    pub fn options(&self) -> &ImplicitOptions {
        &self.opts
    }

    implicit_entry! {
        /// Integrate from `(t0, q0, q̇0)` to `t_end` (with the augmented
        /// Lagrangian's [`SecondOrderDae::multiplier_update`]: `(q0, q̇0)`
        /// consistent, fixed step; `adaptive`, `project`, `reuse`,
        /// `filter_error`, `check_constraints`, `lu`, `extrapolate` are
        /// [`IntegratorError::NotApplicable`]).
        ///
        /// The observer receives `y = [q; q̇]`: `output` at each requested time
        /// (exact at step ends, else cubic Hermite interpolation of q with q̇
        /// and of q̇ with q̈ between the two step ends), `step` after every
        /// accepted step. `output_times` must be strictly increasing within
        /// `[t0, t_end]`. Inputs are validated as for the explicit integrators;
        /// a failure midway is `Ok` with [`Termination::Failed`](super::Termination::Failed).
        |g, sys, span| {
            if sys.multiplier_update().is_some() {
                augmented::check_options(g.method, &g.opts)?;
            }
            validate_run(sys.n(), span, &g.ode, g.opts.adaptive)?;
            Run::new(g, sys, span)
        }
    }
}

/// One run: the integrator's settings, the system and all buffers.
struct Run<'g, 's> {
    p: AlphaParameters,
    opts: &'g ImplicitOptions,
    ode: &'g OdeOptions,
    h_fixed: f64,
    sys: &'s mut dyn SecondOrderDae,
    /// The system iterates its multipliers (the augmented Lagrangian,
    /// [`SecondOrderDae::multiplier_update`]): they are no Newton unknowns.
    augmented: bool,
    n: usize,
    t0: f64,
    t_end: f64,
    t: f64,
    cur: State,
    new: State,
    r: Vec<f64>,
    phi: Vec<f64>,
    err: Vec<f64>,
    y: Vec<f64>,
    /// When the Newton matrix is renewed (the step it was made for, a
    /// renewal asked for, whether this attempt made its own).
    renewal: Renewal,
    /// η = θ/(1 − θ) of the last converged iteration.
    eta: f64,
    /// Quadratic convergence constant `C = ‖Δq₂‖/‖Δq₁‖²` (tolerance units)
    /// of the last attempt on a matrix factorised at its predictor, the
    /// step it was measured at and the single-correction acceptances made
    /// on it since.
    quad: Option<(f64, f64, usize)>,
    /// Corrections of the last converged attempt on a matrix factorised at
    /// its predictor (and the smaller of the last two such), of the last
    /// on an older one; renewals at consecutive predictors.
    newton_its: (Option<(usize, usize)>, Option<usize>),
    renewals: usize,
    /// q̈ and step of the previous accepted step (predictor).
    prev_qdd: Vec<f64>,
    h_prev: Option<f64>,
    /// With [`ImplicitOptions::extrapolate`]: whether the next predictor
    /// extrapolates q̈ (it predicted the last accepted step better than the
    /// constant one, [`Run::choose_predictor`]).
    extrapolate_next: bool,
    stats: ImplicitStats,
    warnings: Vec<String>,
    /// Step control: the step to try next, the largest step, the index of
    /// the next point of the fixed grid, no growth after a cut, the last
    /// accepted (h, err) for the predictive controller.
    h: f64,
    max_step: f64,
    k_grid: u64,
    no_growth: bool,
    last_acc: Option<(f64, f64)>,
    /// Start and size of the last accepted step (dense output).
    t_old: f64,
    h_last: f64,
    /// The failure path's state (the cause named when the step collapses).
    cuts: Cuts,
}

impl<'g, 's> Run<'g, 's> {
    fn new(g: &'g GenAlpha, sys: &'s mut dyn SecondOrderDae, span: &Span<'_>) -> Self {
        let (n, m) = (sys.n(), sys.m());
        let Span {
            t0, t_end, q0, qd0, ..
        } = *span;
        let mut cur = State::new(n, m);
        cur.q.copy_from_slice(q0);
        cur.v.copy_from_slice(qd0);
        let augmented = sys.multiplier_update().is_some();
        // the augmented Lagrangian's Newton system has no multiplier rows;
        // its matrix is renewed at every predictor
        let rows = if augmented { n } else { n + m };
        let renewal = if augmented {
            RenewalOptions {
                band: 0.0,
                across_attempts: false,
                every_correction: false,
            }
        } else {
            RenewalOptions {
                band: REUSE_BAND,
                across_attempts: g.opts.reuse,
                every_correction: !g.opts.reuse,
            }
        };
        Self {
            p: g.params,
            opts: &g.opts,
            ode: &g.ode,
            h_fixed: g.h_fixed,
            sys,
            augmented,
            n,
            t0,
            t_end,
            t: t0,
            new: cur.clone(),
            cur,
            r: vec![0.0; rows],
            phi: vec![0.0; m],
            err: vec![0.0; rows],
            y: [q0, qd0].concat(),
            renewal: Renewal::new(renewal),
            eta: 1.0,
            quad: None,
            newton_its: (None, None),
            renewals: 0,
            prev_qdd: vec![0.0; n],
            h_prev: None,
            extrapolate_next: false,
            stats: ImplicitStats::default(),
            warnings: Vec::new(),
            h: 0.0,
            max_step: 0.0,
            k_grid: 1,
            no_growth: false,
            last_acc: None,
            t_old: t0,
            h_last: 0.0,
            // the augmented Lagrangian names the first failure of a
            // collapse and keeps the first warnings
            cuts: Cuts::new(CutRules {
                shrink: Shrink::Halve,
                warn: if augmented {
                    Warn::First
                } else {
                    Warn::FirstAndLatest
                },
                first_cause: augmented,
            }),
        }
    }

    fn min_step(&self, t: f64) -> f64 {
        let floor = 16.0 * common::eps(t);
        self.opts.min_step.map_or(floor, |h| h.max(floor))
    }

    /// The step collapsed below `h_min` on the way to `h`.
    fn too_small(&self, h: f64, h_min: f64, cause: StepCut) -> Failure {
        Failure::StepTooSmall {
            t: self.t,
            h,
            h_min,
            cause,
        }
    }

    /// Absolute tolerance of component i (adaptive error norm).
    fn atol(&self, i: usize) -> f64 {
        match &self.ode.atol {
            Tolerance::Scalar(a) => *a,
            Tolerance::Vector(v) => v[i],
        }
    }
}

implicit_stepper!(Run<'_, '_>);

impl Stepper for Run<'_, '_> {
    /// Consistent accelerations and multipliers at t0 (`a_0 = q̈_0`) and
    /// the first step.
    fn start(&mut self) -> Result<(), Failure> {
        let t0 = self.t0;
        self.stats.residual_evaluations += 1;
        let x = StateView {
            t: t0,
            q: &self.cur.q,
            qd: &self.cur.v,
        };
        self.sys
            .accelerations(x, &mut self.cur.qdd, &mut self.cur.lam)
            .map_err(Failure::system("initial accelerations", t0, None))?;
        self.cur.a.copy_from_slice(&self.cur.qdd);

        let span = self.t_end - t0;
        self.max_step = if self.opts.adaptive {
            self.ode.max_step.unwrap_or(0.1 * span).min(span)
        } else {
            self.h_fixed
        };
        self.h = if self.opts.adaptive {
            self.ode
                .initial_step
                .unwrap_or_else(|| self.initial_step_guess(span))
                .min(self.max_step)
        } else {
            self.h_fixed
        };
        Ok(())
    }

    /// Attempts until one is accepted: Newton (with one retry on a fresh
    /// factorisation), halving on failure; the error test when adaptive;
    /// projection; the next step size.
    fn step(&mut self) -> Result<bool, Failure> {
        let (n, t0) = (self.n, self.t0);
        let adaptive = self.opts.adaptive;
        let err_exp = 1.0 / 3.0;
        loop {
            let h = self.h;
            // Step to attempt.
            let target = if adaptive {
                self.t_end
            } else {
                (t0 + self.k_grid as f64 * self.h_fixed).min(self.t_end)
            };
            let mut h_try = h.min(self.t_end - self.t);
            if adaptive {
                if self.t + 1.1 * h_try >= self.t_end {
                    h_try = self.t_end - self.t;
                }
            } else {
                h_try = h_try.min(target - self.t);
                // snap the last piece of a grid interval (or of the span)
                if target - (self.t + h_try) <= 1e-9 * self.h_fixed {
                    h_try = target - self.t;
                }
                if self.t_end - target <= 1e-9 * self.h_fixed {
                    // the grid point is t_end up to rounding
                    if (self.t + h_try - target).abs() <= 1e-9 * self.h_fixed {
                        h_try = self.t_end - self.t;
                    }
                }
            }
            let hmin = self.min_step(self.t);
            if h_try < hmin && self.t + h_try < self.t_end {
                return Err(self.too_small(h_try, hmin, self.cuts.cause()));
            }
            let t_new = if h_try == self.t_end - self.t {
                self.t_end
            } else {
                self.t + h_try
            };
            let x = StepTry {
                t: self.t,
                t_new,
                h: h_try,
                h_ctl: h_try,
                h_min: hmin,
            };
            if let Attempted::Cut(h) = attempt_or_cut(self, x)? {
                self.h = h;
                self.no_growth = true;
                continue;
            }
            // Error control.
            let mut fac = 1.0;
            if adaptive {
                let err = self.error_norm(t_new, h_try)?;
                fac = (SAFETY * err.powf(-err_exp))
                    .clamp(0.2, if self.no_growth { 1.0 } else { 2.0 });
                if !err.is_finite() {
                    fac = 0.2;
                }
                if err <= 1.0 {
                    // Gustafsson's predictive controller (Hairer & Wanner
                    // II, §IV.8, eq. (8.21), as in RADAU5): damps the
                    // accept/reject cycles of an oscillating error.
                    if let Some((h_acc, err_acc)) = self.last_acc {
                        let e = err.max(1e-10);
                        let g =
                            SAFETY * (h_try / h_acc) * (err_acc.max(1e-10) / (e * e)).powf(err_exp);
                        fac = fac.min(g.clamp(0.2, 2.0));
                    }
                    self.last_acc = Some((h_try, err));
                }
                if err > 1.0 || !err.is_finite() {
                    self.stats.error_rejections += 1;
                    let hn = h_try * fac;
                    let h_min = self.min_step(self.t);
                    if hn < h_min {
                        return Err(self.too_small(hn, h_min, StepCut::ErrorTest { err }));
                    }
                    self.h = hn;
                    self.no_growth = true;
                    continue;
                }
            }
            // Accept.
            if self.opts.project {
                self.stats.projections += 1;
                let (q, v) = (&mut self.new.q, &mut self.new.v);
                let failed = Failure::system("projection", t_new, Some(self.t));
                self.sys.project(t_new, q, v).map_err(failed)?;
            }
            if self.augmented {
                self.project_motion(t_new, h_try)?;
            }
            self.cuts.accepted();
            self.t_old = self.t;
            self.h_last = h_try;
            if self.opts.extrapolate {
                self.choose_predictor(h_try);
            }
            self.h_prev = Some(h_try);
            std::mem::swap(&mut self.cur, &mut self.new);
            self.t = t_new;
            self.stats.accept(h_try);
            // the step's start's q̈ becomes the history and the state the
            // output: copies, in two halves for a large run
            {
                let (y_q, y_v) = self.y.split_at_mut(n);
                let (old, cur) = (&self.new.qdd[..n], &self.cur);
                crate::parallel::split_pass(
                    n >= crate::parallel::PARALLEL_MIN_COORDS,
                    n,
                    (
                        [&mut self.prev_qdd[..n], y_q, &mut y_v[..n]],
                        [old, &cur.q[..n], &cur.v[..n]],
                    ),
                    |_, ([p, yq, yv], [o, q, v])| {
                        p.copy_from_slice(o);
                        yq.copy_from_slice(q);
                        yv.copy_from_slice(v);
                    },
                    |(), ()| (),
                );
            }
            // Next step size.
            if adaptive {
                let mut hn = (h_try * fac).min(self.max_step);
                if (1.0..1.2).contains(&fac) && h_try >= h * 0.999 {
                    hn = h_try; // keep the factorisation
                }
                if h_try < h * 0.999 && fac >= 1.0 {
                    // a shortened final step: do not let it shrink the step
                    hn = h.max(hn);
                }
                self.h = hn;
            } else {
                if (self.t - target).abs() <= 1e-9 * self.h_fixed || self.t >= target {
                    self.k_grid += 1;
                }
                self.h = (2.0 * h).min(self.h_fixed);
            }
            self.no_growth = false;
            return Ok(self.t >= self.t_end);
        }
    }

    fn state(&self) -> (f64, &[f64]) {
        (self.t, &self.y)
    }

    /// Cubic Hermite between the two ends of the last step.
    fn interpolate(&self, tk: f64, out: &mut [f64]) {
        let h = self.h_last;
        hermite((tk - self.t_old) / h, h, &self.new, &self.cur, out);
    }

    /// The grid lands on output times only up to rounding: 1e-9 h.
    fn output_snap(&self) -> f64 {
        1e-9 * self.h_last
    }

    implicit_outputs!();
}

/// Cubic Hermite interpolation between two step ends `a` (s = 0) and `b`
/// (s = 1): q from (q, q̇), q̇ from (q̇, q̈). Writes `[q; q̇]` into `out`.
fn hermite(s: f64, h: f64, a: &State, b: &State, out: &mut [f64]) {
    let n = a.q.len();
    let (q, v) = out.split_at_mut(n);
    cubic(q, s, h, &a.q, &a.v, &b.q, &b.v);
    cubic(v, s, h, &a.v, &a.qdd, &b.v, &b.qdd);
}
