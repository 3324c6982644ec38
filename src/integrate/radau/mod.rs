//! Radau IIA of order 5 (s = 3 stages) on the index-3 equations of a
//! [`SecondOrderDae`], fixed step (docs/radau.md).
//!
//! Hairer & Wanner, Solving ODEs II, §IV.5, §IV.8 (RADAU5) and §VII.4;
//! Hairer, Lubich & Roche, LNM 1409 (1989): on index-3 problems the
//! positions converge with order `2s − 1 = 5`, the velocities with order
//! `s = 3`, the multipliers with order `s − 1 = 2`; the method is
//! L-stable (its stability function is the (2,3) Padé approximant of eᶻ,
//! error constant `3!2!/(5!6!) ≈ 1.4e-4`).
//!
//! The stage loop (`Run`: state, Newton, error estimate, dense output)
//! is written for any odd number of stages `S` and a tableau of them
//! (`stages::Tableau`); it serves [`Radau9`] (S = 5) and [`Radau13`]
//! (S = 7) as well, and [`Radau59`] switches between three and five
//! stages between steps.
//!
//! # Stages
//!
//! Unknowns: stage accelerations `A_i` and multipliers `Λ_i`, i = 1..3, at
//! `t_i = t_n + c_i h`, `c = ((4 − √6)/10, (4 + √6)/10, 1)`:
//!
//! ```text
//! Q_i = q_n + c_i h v_n + h² Σ_j (𝔄²)_ij A_j,     V_i = v_n + h Σ_j 𝔄_ij A_j
//! M A_i + Φ_qᵀ(Q_i) Λ_i − g(Q_i, V_i, t_i) = 0,    Φ(Q_i, t_i) = 0
//! ```
//!
//! (Radau IIA applied to `q̇ = v`, `v̇ = a` with `𝔄` the Radau IIA matrix:
//! `Q_i = q_n + h Σ 𝔄_ij V_j` gives the form above since `Σ_j 𝔄_ij = c_i`.)
//! Stiffly accurate: `q_{n+1} = Q_3`, `v_{n+1} = V_3`, `q̈_{n+1} = A_3`,
//! `λ_{n+1} = Λ_3`. Dense output: the collocation polynomials — `V` of
//! degree 3 with `V(t_n) = v_n`, `V̇(t_i) = A_i`, and `Q` the cubic through
//! `q_n` and the `Q_i`.
//!
//! # Simplified Newton
//!
//! The Jacobians are frozen at the predictor's middle stage
//! `(t_n + c_m h, Q_m, V_m, Λ_m)`, `c_m` the node nearest `h/2`
//! (`newton::middle`; c₂ = 0.645 here): every stage lies within
//! `0.65 h` of it, where the step's start `(t_n, q_n, v_n, λ_n)` lies up
//! to `h` away, and the contraction of the simplified Newton iteration
//! grows with that distance (the bodies turn within the step;
//! docs/radau.md, "The Newton matrices at the middle stage"). With
//! `T⁻¹ 𝔄 T = diag(γ, [α −β; β α])` (γ real, `μ = α + iβ` the complex
//! eigenvalue pair of 𝔄) and the transformed unknowns `(T⁻¹ ⊗ I) ΔA`,
//! `(T⁻¹ ⊗ I) ΔΛ`, the `3(n + m)` Newton system splits into one real
//! system and one complex system, each of the form
//!
//! ```text
//! [ M + hμ C_t + h²μ² K_t   Φ_qᵀ ] [ΔÂ]   [ −F̂        ]
//! [ Φ_q                     0    ] [ΔΛ̂] = [ −Φ̂/(h²μ²) ]
//! ```
//!
//! (the constraint rows divided by `h²μ²`: the same balance of blocks as
//! the scaled matrix of [`SecondOrderDae::factorize`], Bottasso, Bauchau &
//! Cardona 2007). The real one (μ = γ) is
//! `SecondOrderDae::factorize(c = [1, hγ, h²γ²])`, the complex one
//! [`ComplexNewton::factorize_complex`]. Factorisations are kept across
//! iterations and steps while Newton contracts fast (θ ≤
//! [`THETA_REFACTOR`](super::THETA_REFACTOR)); convergence test as generalized-α's, the one
//! [`Convergence`](super::implicit::Convergence) (Hairer &
//! Wanner II, eq. (8.10)) on the position-equivalent corrections
//! `h² ΔA_i` against `h² newton_tol`, a body angle's at the body's radius
//! of gyration (`h² newton_tol / ρ`; [`SecondOrderDae::correction_lengths`]),
//! floored at [`ROUNDING_ULPS`] of `q`;
//! the first correction of an attempt is judged with RADAU5's rate
//! estimate `η₀ = max(η_prev, ε)^0.8` from the last converged attempt
//! (not raised to 1), so a good predictor on a contracting matrix
//! converges in one correction.
//! The predictor extrapolates the previous step's stage polynomials
//! (`A`, `Λ`) to the new stage times.
//!
//! **Renewal.** The matrices are renewed at the predictor when the step
//! differs from the factorised one by more than [`SAME_STEP`] (relative),
//! after a contraction θ > [`THETA_REFACTOR`](super::THETA_REFACTOR), and — once per attempt —
//! at the last stage's current iterate `(t_n + h, Q₃, V₃, Λ₃)` when the
//! iteration diverges (θ ≥ 1 above [`STAGNATION`](super::STAGNATION) tolerances): the
//! diverging correction is undone and Newton goes on with the renewed
//! matrices instead of halving the step at once (fewer failed attempts
//! from the stiff chain's kinked start; docs/scaling.md, "Measurements
//! behind the defaults"). The matrix frozen at the predictor carries the multipliers' geometric
//! stiffness `(Φ_qᵀλ)_q` of the predicted kink's spring forces, which the
//! first step relaxes. The same renewal (without the undo; one renewal per
//! attempt in all) is taken when `max_newton` corrections did not suffice
//! but the iteration still contracts (as generalized-α's). An
//! iteration that stops contracting with position corrections `h² ΔA`
//! below [`NOISE_REL`](super::NOISE_REL) of `max(|q|, 1)` has reached the noise of the
//! solve and counts as converged (as generalized-α's), so that a tight
//! `newton_tol` does not cut the step at the start for iterations that
//! only "diverge" within the rounding noise.
//!
//! # Step size
//!
//! Fixed ([`OdeOptions::fixed_step`]), on the grid `t_0 + k h`; a Newton
//! failure (after one retry on fresh factorisations) halves the step and
//! the grid point is reached by sub-steps that double again. The first
//! step is the smaller of `h` and the adaptive mode's first-step guess
//! (`½ h² q̈_0` at 1 % of `atol + rtol |q_0|`, `common::
//! initial_step_from_accelerations`, with the [`OdeOptions`] tolerances),
//! and the steps double from there: a start from rest with stiff springs
//! (the stiff chain: `q̈_0 ≈ 1e10`) ramps up instead of halving down from
//! `h` through Newton failures (N = 10 000, h = 4e-4: 11 failures to
//! 3.9e-7 s before, 1 now; −16 % CPU over 0.1 s). A gentle start (the
//! falling rod at h ≤ 4e-4) takes a few doublings at most.
//!
//! **Flight step** ([`ImplicitOptions::flight_step`] `H = k h`): from a
//! grid point, at the full step, the attempt spans `k` grid steps when
//! no force element foresees an onset — a contact's start, or one
//! running — within [`FLIGHT_LOOKAHEAD`] `H`
//! ([`SecondOrderDae::onset_within`]: gaps over speeds across the walls at
//! the step's start). Its matrices are factorised for `H` (a change of
//! the step renews them, as any); a flight step that Newton fails is
//! retried from the same point at `h`. A flight step after a shorter
//! step starts Newton from the constant predictor (`flight.rs`).
//!
//! **Adaptive** ([`ImplicitOptions::adaptive`]; `rtol`, `atol`,
//! `max_step`, `initial_step` of [`OdeOptions`]): RADAU5's embedded error
//! estimate of the positions (`Run::error_norm`: Hairer & Wanner II,
//! §IV.8, eqs. (8.19)–(8.20), filtered through the real stage's Newton
//! matrix, with RADAU5's tolerance transformation `rtol' = 0.1 rtol^{2/3}`)
//! in the largest-component norm, and RADAU5's step control: `h_new = h /
//! quot` with `quot = err^{1/4} / fac`, `fac = SAFETY · (1 + 2 k_max) /
//! (k + 2 k_max)` (k Newton corrections of the step, `k_max` =
//! `max_newton` for three stages; for S stages RADAU's limit
//! `max_newton + 5 (S − 3)/2`, `newton_limit`), `quot ∈ [1/MAX_GROWTH, MAX_SHRINK]`, Gustafsson's
//! predictive controller on accepted steps, no growth right after a
//! rejection, a first step rejected is retried at h/10, and a new step
//! within `[1, KEEP_STEP]` times the old one keeps it (and the
//! factorisations; a step within [`ADAPTIVE_REUSE_BAND`] of the factorised
//! one reuses them). Newton stops, where that is looser than
//! `newton_tol`, at RADAU5's tolerance: the stage position corrections
//! `ΔQ_i = h² Σ_j (𝔄²)_ij ΔA_j` (RADAU5 tests the stage increments `ΔZ`)
//! below `fnewt = max(10 ε / rtol', min(0.03, √rtol'))` times the error
//! test's weights (the tip errors this gives against rtol: docs/radau.md).
#![warn(unreachable_pub)]
// 3×3 tableau algebra reads clearest with indices
#![allow(clippy::needless_range_loop)]

mod flight;
mod newton;
mod radau9;
mod stages;
mod states;
mod tableau;
mod variable;

pub use radau9::{Radau13, Radau9, RadauHigh};
use stages::cmul;
pub use stages::RadauStages;
use stages::{dot, Tableau};
use states::{stage_rows, StageBase};
use tableau::ClosedForm;
pub use tableau::RadauTableau;
pub use variable::{OrderCounts, Radau59};

use super::driver::{Failure, Stepper};
use super::implicit::{
    attempt_or_cut, implicit_outputs, run as run_implicit, validate_run, Assessment, Attempted,
    Convergence, ConvergenceOptions, CutRules, Cuts, ImplicitStats, ImplicitStepper, Next,
    Remainder, Renewal, RenewalOptions, Shrink, StepTry, Warn,
};
use super::{
    common, ImplicitOptions, IntegratorError, Method, OdeOptions, Report, SecondOrderDae, Span,
    StateView, SystemError, Tolerance, ROUNDING_ULPS,
};

/// Relative difference below which a step counts as the one the Newton
/// matrices were factorised for: the fixed steps computed as `target − t`
/// on the grid differ from `h` in their last bits, and an exact comparison
/// would renew both factorisations at every such step.
pub(super) const SAME_STEP: f64 = 1e-9;

/// Adaptive mode: the matrices factorised for a step `h_f` serve a step
/// within this relative distance of it (a simplified Newton on a matrix
/// of a nearby step, as generalized-α's `REUSE_BAND`): fewer
/// factorisations than renewing at every change of the step
/// (docs/scaling.md, "Measurements behind the defaults").
pub(super) const ADAPTIVE_REUSE_BAND: f64 = 0.2;

/// Safety factor of the step-size controller (RADAU5's `SAFE`).
pub(super) const SAFETY: f64 = 0.9;
/// Largest growth of the step after an accepted one (RADAU5: `1/FACR`).
pub(super) const MAX_GROWTH: f64 = 8.0;
/// Largest reduction after a rejected one (RADAU5: `FACL`).
pub(super) const MAX_SHRINK: f64 = 5.0;
/// A new step within `[1, KEEP_STEP]` times the last one keeps it, and
/// with it the factorisations (RADAU5's `QUOT2`).
pub(super) const KEEP_STEP: f64 = 1.2;

/// Fixed steps with [`ImplicitOptions::flight_step`] `H`: the flight step
/// is taken only when no force element foresees an onset within this many
/// times `H` from the step's start (the extrapolation by the current
/// velocities looks past the step, for the accelerations it leaves out;
/// 4 and 2 compared on the falling rod in docs/scaling.md, "The falling
/// rod with a flight step").
pub const FLIGHT_LOOKAHEAD: f64 = 4.0;

/// RADAU's tolerance transformation for `S` stages, `rtol' = 0.1
/// rtol^{(S+1)/(2S)}` (radau5: `0.1 rtol^{2/3}`): the error estimate is
/// O(h^{S+1}) for a method of order 2S − 1, and with `rtol'` the global
/// error follows `rtol` (Hairer & Wanner II, §IV.8; RADAU's `EXPMNS`).
pub(super) fn transformed_rtol<const S: usize>(rtol: f64) -> f64 {
    0.1 * rtol.powf((S + 1) as f64 / (2 * S) as f64)
}

/// The exponent `1/(S + 1)` of the step-size controller (the error
/// estimate is O(h^{S+1}); RADAU's `EXPO`).
pub(super) fn error_exponent<const S: usize>() -> f64 {
    1.0 / (S + 1) as f64
}

/// RADAU's Newton tolerance as a fraction of the error test's weights,
/// `fnewt = max(10 ε / rtol', min(0.03, rtol'^{(S−1)/(S+1)}))` (radau5:
/// `√rtol'`).
pub(super) fn newton_fraction<const S: usize>(rtol_t: f64) -> f64 {
    let p = if S == 3 {
        rtol_t.sqrt()
    } else {
        rtol_t.powf((S - 1) as f64 / (S + 1) as f64)
    };
    (10.0 * f64::EPSILON / rtol_t).max(0.03f64.min(p))
}

/// RADAU's limit of Newton corrections for `S` stages, `max_newton + 5 (S
/// − 3)/2` (RADAU's `NIT` raised by 5 per two stages: 7, 12, 17 at its
/// default; Hairer & Wanner, J. Comput. Appl. Math. 111, 1999): the
/// corrections allowed per round on one factorisation and the `k_max` of
/// the step controller's factor (module docs, "Step size"). The predictor
/// of S stages is further from the converged stages in units of the
/// tighter Newton tolerance of S stages ([`newton_fraction`]), so a step
/// takes more corrections, and with radau5's limit the controller's factor
/// would shrink the steps of five and seven stages.
pub(super) fn newton_limit<const S: usize>(max_newton: usize) -> usize {
    max_newton + 5 * (S - 3) / 2
}

/// The complex Newton matrix of the transformed Radau stages:
/// `[c₀ M + c₁ C_t + c₂ K_t, Φ_qᵀ; Φ_q, 0]` with complex coefficients `c`
/// (`[re, im]`, `c₀` real), factorised and solved (implemented for
/// multibody systems by [`crate::formulation::Index3Complex`]).
pub trait ComplexNewton {
    /// Assemble and factorise at `x = (t, q, q̇)` and `λ`.
    fn factorize_complex(
        &mut self,
        x: StateView<'_>,
        lambda: &[f64],
        c: [[f64; 2]; 3],
    ) -> Result<(), SystemError>;
    /// Overwrite `re + i·im` (each of length n + m) with the solution.
    fn solve_complex(&mut self, t: f64, re: &mut [f64], im: &mut [f64]) -> Result<(), SystemError>;
}

/// Radau IIA, s = 3, fixed step, on the index-3 equations (module docs).
#[derive(Debug, Clone)]
pub struct Radau5 {
    opts: ImplicitOptions,
    ode: OdeOptions,
    tab: ClosedForm,
    stats: ImplicitStats,
}

impl Radau5 {
    /// Validate the options: a fixed step ([`OdeOptions::fixed_step`]),
    /// or with [`ImplicitOptions::adaptive`] the tolerances `rtol`, `atol`
    /// (and `max_step`, `initial_step`); of [`ImplicitOptions`] it reads
    /// `newton_tol`, `max_newton`, `reuse`, `project`, `min_step` and
    /// `adaptive` ([`ImplicitOptions::validate`]).
    pub fn new(opts: ImplicitOptions, ode: OdeOptions) -> Result<Self, IntegratorError> {
        ode.validate(Method::Radau5, opts.adaptive)?;
        opts.validate(Method::Radau5, ode.fixed_step)?;
        Ok(Self {
            opts,
            ode,
            tab: ClosedForm::new(),
            stats: ImplicitStats::default(),
        })
    }

    /// Counters of the last run.
    pub fn stats(&self) -> ImplicitStats {
        self.stats
    }

    /// Integrate from `(t0, q0, q̇0)` to `t_end`; `cplx` is the complex
    /// Newton matrix of the same system. Outputs as [`super::GenAlpha::integrate`]
    /// (`y = [q; q̇]`, dense output from the collocation polynomials).
    pub fn integrate(
        &mut self,
        sys: &mut dyn SecondOrderDae,
        cplx: &mut dyn ComplexNewton,
        span: Span<'_>,
    ) -> Result<Report, IntegratorError> {
        let (tab, opts, ode) = (&self.tab, &self.opts, &self.ode);
        let (report, stats) = integrate_stages(tab, opts, ode, sys, vec![cplx], span)?;
        self.stats = stats;
        Ok(report)
    }
}

/// Integrate with the stages of `tab` from `(t0, q0, q̇0)` to `t_end`
/// (radau5's and radau9's `integrate`); `cplx` holds one complex Newton
/// matrix per complex pair of 𝔄.
fn integrate_stages<'s, const S: usize, T: Tableau<S>>(
    tab: &T,
    opts: &ImplicitOptions,
    ode: &OdeOptions,
    sys: &'s mut dyn SecondOrderDae,
    cplx: Vec<&'s mut dyn ComplexNewton>,
    run_span: Span<'_>,
) -> Result<(Report, ImplicitStats), IntegratorError> {
    let mut run = Run::new(tab, opts, ode, sys, cplx, &run_span)?;
    Ok(run_implicit(&mut run, run_span, ode.max_steps))
}

/// The Newton-matrix policy of a Radau IIA run: the matrices of a step
/// within [`ADAPTIVE_REUSE_BAND`] (adaptive) or [`SAME_STEP`] (fixed) of
/// the factorised one serve it.
fn renewal(opts: &ImplicitOptions) -> Renewal {
    Renewal::new(RenewalOptions {
        band: if opts.adaptive {
            ADAPTIVE_REUSE_BAND
        } else {
            SAME_STEP
        },
        across_attempts: opts.reuse,
        every_correction: !opts.reuse,
    })
}

/// The next attempt of a Radau IIA run from `t`: the step `h` (the
/// current one, cut to reach `target` — the next grid point of a fixed
/// step, or `t_end` — and stretched to it when within `1e-9 scale`), its
/// end (exactly `t_end` at the last grid point) and the smallest step
/// (`min_step`, at least 16 ulps of `t`), below which the run fails.
fn step_try(
    t: f64,
    h: f64,
    target: f64,
    scale: f64,
    t_end: f64,
    opts: &ImplicitOptions,
    cuts: &Cuts,
) -> Result<StepTry, Failure> {
    let mut h = h.min(target - t);
    if target - (t + h) <= 1e-9 * scale {
        h = target - t;
    }
    let floor = 16.0 * common::eps(t);
    let h_min = opts.min_step.map_or(floor, |m| m.max(floor));
    if h < h_min && t + h < t_end {
        return Err(Failure::StepTooSmall {
            t,
            h,
            h_min,
            cause: cuts.cause(),
        });
    }
    let t_new = if (target - t_end).abs() <= 1e-9 * scale && (t + h - target).abs() <= 1e-9 * scale
    {
        t_end
    } else {
        t + h
    };
    Ok(StepTry {
        t,
        t_new,
        h,
        h_ctl: h,
        h_min,
    })
}

/// A Radau IIA run of `S` stages with the tableau `T` (radau5: S = 3,
/// radau9: S = 5).
struct Run<'g, 's, const S: usize, T: Tableau<S>> {
    tab: &'g T,
    opts: &'g ImplicitOptions,
    ode: &'g OdeOptions,
    sys: &'s mut dyn SecondOrderDae,
    /// One complex Newton matrix per complex pair μ_p of 𝔄.
    cplx: Vec<&'s mut dyn ComplexNewton>,
    n: usize,
    m: usize,
    t0: f64,
    t_end: f64,
    h_fixed: f64,
    h: f64,
    /// Largest step of the adaptive mode.
    h_max: f64,
    /// The last attempt was rejected by the error test (adaptive mode).
    rejected: bool,
    /// Step and error norm (at least 1e-2) of the last accepted step of
    /// the adaptive mode (the predictive controller).
    accepted: Option<(f64, f64)>,
    /// Newton corrections of the last converged attempt.
    last_its: usize,
    k_grid: u64,
    /// Grid steps of `h_fixed` in one flight step (1: no flight step).
    flight_stride: u64,
    /// The last attempt was a flight step that Newton failed: the retry
    /// from the same grid point takes `h_fixed`.
    flight_failed: bool,
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
    qdd: Vec<f64>,
    lam: Vec<f64>,
    /// State at the start of the last accepted step (dense output).
    q_old: Vec<f64>,
    v_old: Vec<f64>,
    /// Stage accelerations and multipliers of the current attempt.
    a: [Vec<f64>; S],
    l: [Vec<f64>; S],
    /// Those of the last accepted step (predictor, dense output).
    a_prev: [Vec<f64>; S],
    l_prev: [Vec<f64>; S],
    qs: Vec<f64>,
    vs: Vec<f64>,
    /// Every stage's position and velocity of the current correction.
    qst: [Vec<f64>; S],
    vst: [Vec<f64>; S],
    r: [Vec<f64>; S],
    x: [Vec<f64>; S],
    y: Vec<f64>,
    /// When the Newton matrices are renewed.
    renewal: Renewal,
    eta: f64,
    h_last: f64,
    h_prev: Option<f64>,
    stats: ImplicitStats,
    warnings: Vec<String>,
    /// The failure path's state (the cause named when the step collapses).
    cuts: Cuts,
    /// The contraction θ of the last converged attempt's last correction
    /// (None: it converged in one correction; radau59's order rule).
    last_theta: Option<f64>,
    /// Per coordinate, the Newton test's tolerance factor: `1/ℓ` of
    /// [`SecondOrderDae::correction_lengths`] (`newton::tolerance_factors`).
    tol_factor: Vec<f64>,
}

impl<'g, 's, const S: usize, T: Tableau<S>> Run<'g, 's, S, T> {
    /// A run from the start of `run_span` with the stages of `tab`; `cplx`
    /// holds one complex Newton matrix per complex pair of 𝔄 (more are
    /// left unused).
    fn new(
        tab: &'g T,
        opts: &'g ImplicitOptions,
        ode: &'g OdeOptions,
        sys: &'s mut dyn SecondOrderDae,
        cplx: Vec<&'s mut dyn ComplexNewton>,
        run_span: &Span<'_>,
    ) -> Result<Self, IntegratorError> {
        let (n, m) = (sys.n(), sys.m());
        validate_run(n, run_span, ode, opts.adaptive)?;
        let &Span {
            t0, t_end, q0, qd0, ..
        } = run_span;
        let span = t_end - t0;
        let h_max = ode.max_step.unwrap_or(0.1 * span).min(span);
        // 0: chosen in `start` from the initial accelerations
        let h = match (opts.adaptive, ode.fixed_step) {
            (false, h) => h.unwrap_or(0.0),
            (true, _) => ode.initial_step.map_or(0.0, |h| h.min(h_max)),
        };
        let tol_factor = newton::tolerance_factors(&*sys);
        let vn = || std::array::from_fn(|_| vec![0.0; n]);
        let vm = || std::array::from_fn(|_| vec![0.0; m]);
        let vnm = || std::array::from_fn(|_| vec![0.0; n + m]);
        Ok(Run {
            tab,
            opts,
            sys,
            cplx,
            n,
            m,
            t0,
            t_end,
            h_fixed: h,
            h,
            h_max,
            rejected: false,
            accepted: None,
            last_its: 0,
            k_grid: 1,
            flight_stride: match (opts.adaptive, opts.flight_step, ode.fixed_step) {
                (false, Some(big), Some(h)) => (big / h).round() as u64,
                _ => 1,
            },
            flight_failed: false,
            t: t0,
            q: q0.to_vec(),
            v: qd0.to_vec(),
            qdd: vec![0.0; n],
            lam: vec![0.0; m],
            q_old: q0.to_vec(),
            v_old: qd0.to_vec(),
            a: vn(),
            l: vm(),
            a_prev: vn(),
            l_prev: vm(),
            qs: vec![0.0; n],
            vs: vec![0.0; n],
            qst: vn(),
            vst: vn(),
            r: vnm(),
            x: vnm(),
            y: [q0, qd0].concat(),
            renewal: renewal(opts),
            eta: 1.0,
            h_last: 0.0,
            h_prev: None,
            stats: ImplicitStats::default(),
            ode,
            warnings: Vec::new(),
            cuts: Cuts::new(CutRules {
                shrink: Shrink::Halve,
                warn: Warn::First,
                first_cause: false,
            }),
            last_theta: None,
            tol_factor,
        })
    }
}

impl<'g, 's, const S: usize, T: Tableau<S>> Run<'g, 's, S, T> {
    /// This run continued with the `R` stages of `tab` (radau59's change of
    /// order, between steps): state, counters, step, books and the Newton
    /// rate carry over; the last step's stage polynomials `A(τ)`, `Λ(τ)`
    /// are evaluated at the new nodes (the next predictor extrapolates
    /// them); the matrices are factorised anew for the new eigenvalues, and
    /// the predictive controller starts over (the error norms of two
    /// orders do not compare).
    fn into_stages<const R: usize, U: Tableau<R>>(self, tab: &'g U) -> Run<'g, 's, R, U> {
        let (n, m) = (self.n, self.m);
        let nodes = tab.stages().c;
        let w: [[f64; S]; R] = std::array::from_fn(|i| self.tab.basis(nodes[i]));
        let at_nodes = |p: &[Vec<f64>; S], len: usize| -> [Vec<f64>; R] {
            std::array::from_fn(|i| (0..len).map(|k| dot(&w[i], |j| p[j][k])).collect())
        };
        let (a_prev, l_prev) = (at_nodes(&self.a_prev, n), at_nodes(&self.l_prev, m));
        Run {
            tab,
            opts: self.opts,
            ode: self.ode,
            sys: self.sys,
            cplx: self.cplx,
            n,
            m,
            t0: self.t0,
            t_end: self.t_end,
            h_fixed: self.h_fixed,
            h: self.h,
            h_max: self.h_max,
            rejected: self.rejected,
            accepted: None,
            last_its: self.last_its,
            k_grid: self.k_grid,
            flight_stride: self.flight_stride,
            flight_failed: self.flight_failed,
            t: self.t,
            q: self.q,
            v: self.v,
            qdd: self.qdd,
            lam: self.lam,
            q_old: self.q_old,
            v_old: self.v_old,
            a: std::array::from_fn(|_| vec![0.0; n]),
            l: std::array::from_fn(|_| vec![0.0; m]),
            a_prev,
            l_prev,
            qs: self.qs,
            vs: self.vs,
            qst: std::array::from_fn(|_| vec![0.0; n]),
            vst: std::array::from_fn(|_| vec![0.0; n]),
            r: std::array::from_fn(|_| vec![0.0; n + m]),
            x: std::array::from_fn(|_| vec![0.0; n + m]),
            y: self.y,
            renewal: renewal(self.opts),
            eta: self.eta,
            h_last: self.h_last,
            h_prev: self.h_prev,
            stats: self.stats,
            warnings: self.warnings,
            cuts: self.cuts,
            last_theta: self.last_theta,
            tol_factor: self.tol_factor,
        }
    }

    /// What radau59's order rule reads after an accepted step.
    fn signals(&self) -> variable::Signals {
        variable::Signals {
            corrections: self.last_its,
            theta: self.last_theta,
            h: self.h_last,
            h_next: self.h,
            newton_failures: self.stats.newton_failures,
        }
    }
}

impl<const S: usize, T: Tableau<S>> Run<'_, '_, S, T> {
    /// `atol` of coordinate `i`.
    fn atol(&self, i: usize) -> f64 {
        match &self.ode.atol {
            Tolerance::Scalar(a) => *a,
            Tolerance::Vector(v) => v[i],
        }
    }

    /// First step of the adaptive mode without `initial_step`: the
    /// position change `½ h² q̈` of the start at 1 % of the tolerance,
    /// within `[1e-6, 1e-2]` of the span and at most `h_max`.
    fn initial_step_guess(&self) -> f64 {
        common::initial_step_from_accelerations(
            &self.qdd[..self.n],
            |i| self.atol(i) + self.ode.rtol * self.q[i].abs(),
            self.t_end - self.t0,
        )
        .min(self.h_max)
    }

    /// Norm of RADAU5's embedded error estimate of the converged attempt
    /// `h` (Hairer & Wanner II, §IV.8, eqs. (8.19)–(8.20)) for the
    /// positions; ≤ 1 passes (module docs, "Step size").
    ///
    /// For `y = (q, q̇)` the raw estimate is
    /// `r = γ h f(y_n) + Σ_i e_i (Y_i − y_n)` (S = 3: `e = γ (−13 − 7√6,
    /// −13 + 7√6, −1)/3`; any S: [`RadauStages::e`]), with `Q_i − q_n`,
    /// `V_i − v_n` from the stages and
    /// `f(y_n) = (v_n, q̈_n)`. The filter `(I − hγJ)⁻¹` that keeps stiff
    /// components from dominating becomes, for the positions, the real
    /// stage's Newton matrix: `[M + hγ C + h²γ² K, Φ_qᵀ; Φ_q, 0]
    /// [e_q; ·] = [M (r_q + hγ r_v); 0]` (the term `hγ C r_q` is left
    /// out; `Φ_q e_q = 0`: the error along the constraint manifold). The
    /// norm is the largest `|e_q,i| / (atol_i + rtol max(|q_n,i|,
    /// |q_{n+1},i|))` times `rtol / rtol'` with RADAU's tolerance
    /// transformation ([`transformed_rtol`]; S = 3: `rtol' = 0.1
    /// rtol^{2/3}`, the estimate is O(h⁴) for a method of order 5: the
    /// global error then follows `rtol`).
    fn error_norm(&mut self, h: f64) -> Result<f64, SystemError> {
        let n = self.n;
        let tab = self.tab.stages();
        let e = &tab.e;
        let g = tab.gamma;
        // r_q = (γ + Σ e_i c_i) h v + h² Σ_j (Σ_i e_i 𝔄²_ij) A_j,
        // r_v = γ h q̈_n + h Σ_j (Σ_i e_i 𝔄_ij) A_j
        let ec: f64 = (0..S).map(|i| e[i] * tab.c[i]).sum();
        let ea2: [f64; S] = std::array::from_fn(|j| (0..S).map(|i| e[i] * tab.a2[i][j]).sum());
        let ea: [f64; S] = std::array::from_fn(|j| (0..S).map(|i| e[i] * tab.a[i][j]).sum());
        let hg = h * g;
        let mass = self.sys.mass_diagonal();
        let x = &mut self.x[0];
        {
            let st: [&[f64]; S] = std::array::from_fn(|j| &self.a[j][..n]);
            let (v, qdd) = (&self.v[..n], &self.qdd[..n]);
            for k in 0..n {
                let rq = (g + ec) * h * v[k] + h * h * dot(&ea2, |j| st[j][k]);
                let rv = g * h * qdd[k] + h * dot(&ea, |j| st[j][k]);
                x[k] = mass[k] * (rq + hg * rv);
            }
        }
        x[n..].fill(0.0);
        self.sys.solve(self.t, x)?;
        // the step's end, Q_S = q_{n+1}, for the weights (an accepted step
        // takes it from `qs`, `vs`)
        self.stage_state(S - 1, h);
        let x = &self.x[0];
        let norm = common::max_weighted(
            n,
            |k| x[k],
            |k| self.atol(k) + self.ode.rtol * self.q[k].abs().max(self.qs[k].abs()),
        );
        Ok(norm * self.ode.rtol / transformed_rtol::<S>(self.ode.rtol))
    }
}

impl<const S: usize, T: Tableau<S>> ImplicitStepper for Run<'_, '_, S, T> {
    fn books(&mut self) -> (&mut ImplicitStats, &mut Vec<String>) {
        (&mut self.stats, &mut self.warnings)
    }
    fn newton_attempt(&mut self, _t_new: f64, h: f64) -> Result<(), SystemError> {
        self.attempt(h)
    }
    fn renewal(&mut self) -> &mut Renewal {
        &mut self.renewal
    }
    fn cuts(&mut self) -> &mut Cuts {
        &mut self.cuts
    }
}

impl<const S: usize, T: Tableau<S>> Stepper for Run<'_, '_, S, T> {
    fn start(&mut self) -> Result<(), Failure> {
        self.stats.residual_evaluations += 1;
        self.sys
            .accelerations(
                StateView {
                    t: self.t0,
                    q: &self.q,
                    qd: &self.v,
                },
                &mut self.qdd,
                &mut self.lam,
            )
            .map_err(Failure::system("initial accelerations", self.t0, None))?;
        if self.opts.adaptive && self.h == 0.0 {
            self.h = self.initial_step_guess();
        } else if !self.opts.adaptive {
            // fixed steps: ramp up from the first-step guess (module docs)
            self.h = self.initial_step_guess().min(self.h_fixed);
        }
        Ok(())
    }

    fn step(&mut self) -> Result<bool, Failure> {
        let n = self.n;
        let adaptive = self.opts.adaptive;
        loop {
            // fixed: the next grid point, or the flight step's; adaptive:
            // the end
            let stride = if adaptive { 1 } else { self.grid_steps() };
            let target = if adaptive {
                self.t_end
            } else {
                let k = self.k_grid + stride - 1;
                (self.t0 + k as f64 * self.h_fixed).min(self.t_end)
            };
            let scale = if adaptive { self.h } else { self.h_fixed };
            let h_try = if stride > 1 { target - self.t } else { self.h };
            let x = step_try(
                self.t, h_try, target, scale, self.t_end, self.opts, &self.cuts,
            )?;
            let (h, t_new) = (x.h, x.t_new);
            if let Attempted::Cut(h) = attempt_or_cut(self, x)? {
                // a failed flight step is retried at the grid's step
                self.flight_failed = stride > 1;
                self.h = if stride > 1 { h.min(self.h_fixed) } else { h };
                self.rejected = adaptive;
                continue;
            }
            self.flight_failed = false;
            // adaptive: the error test (module docs, "Step size")
            let mut h_next = (2.0 * h).min(self.h_fixed);
            if adaptive {
                let err = self.error_norm(h).map_err(Failure::system(
                    "error estimate",
                    t_new,
                    Some(self.t),
                ))?;
                let nit = newton_limit::<S>(self.opts.max_newton) as f64;
                let fac =
                    SAFETY.min(SAFETY * (1.0 + 2.0 * nit) / (self.last_its as f64 + 2.0 * nit));
                let expo = error_exponent::<S>();
                let mut quot = (err.powf(expo) / fac).clamp(1.0 / MAX_GROWTH, MAX_SHRINK);
                if err > 1.0 {
                    let h_new = h / quot;
                    self.stats.error_rejections += 1;
                    self.rejected = true;
                    self.h = if self.stats.steps == 0 {
                        0.1 * h
                    } else {
                        h_new
                    };
                    self.cuts.error_test(err);
                    continue;
                }
                // Gustafsson's predictive controller (RADAU5's `PRED`):
                // the more cautious of both
                if let Some((h_acc, err_acc)) = self.accepted {
                    let gus = (h_acc / h) * (err * err / err_acc).powf(expo) / SAFETY;
                    quot = quot.max(gus.clamp(1.0 / MAX_GROWTH, MAX_SHRINK));
                }
                self.accepted = Some((h, err.max(1e-2)));
                let h_new = h / quot;
                h_next = if self.rejected { h_new.min(h) } else { h_new };
                // keep the step (and the factorisations) for a small growth
                if (1.0..=KEEP_STEP).contains(&(h_next / h)) {
                    h_next = h;
                }
                h_next = h_next.min(self.h_max);
                self.rejected = false;
            }
            // accept: stiffly accurate, the last stage is the step's end
            // (the converged attempt's last update left it in `qst`,
            // `vst`); `q_old ← q`, `q ← Q_S` by swapping buffers (`qst` is
            // scratch until the next attempt's stage states)
            std::mem::swap(&mut self.q_old, &mut self.q);
            std::mem::swap(&mut self.q, &mut self.qst[S - 1]);
            std::mem::swap(&mut self.v_old, &mut self.v);
            std::mem::swap(&mut self.v, &mut self.vst[S - 1]);
            self.qdd.copy_from_slice(&self.a[S - 1]);
            self.lam.copy_from_slice(&self.l[S - 1]);
            if self.opts.project {
                self.stats.projections += 1;
                let (q, v) = (&mut self.q, &mut self.v);
                self.sys.project(t_new, q, v).map_err(Failure::system(
                    "projection",
                    t_new,
                    Some(self.t),
                ))?;
            }
            // the accepted stages become the history (the next attempt's
            // predictor overwrites every entry of `a`, `l`)
            std::mem::swap(&mut self.a_prev, &mut self.a);
            std::mem::swap(&mut self.l_prev, &mut self.l);
            self.h_prev = Some(h);
            self.h_last = h;
            self.t = t_new;
            self.stats.accept(h);
            self.y[..n].copy_from_slice(&self.q);
            self.y[n..].copy_from_slice(&self.v);
            if !adaptive && ((self.t - target).abs() <= 1e-9 * self.h_fixed || self.t >= target) {
                self.k_grid += stride;
            }
            self.h = h_next;
            return Ok(self.t >= self.t_end);
        }
    }

    fn state(&self) -> (f64, &[f64]) {
        (self.t, &self.y)
    }

    /// The collocation polynomials of the last step: `V` of degree S
    /// with `V̇(t_i) = A_i`, `Q` through `q_n` and the stage positions.
    fn interpolate(&self, t: f64, out: &mut [f64]) {
        let (n, h) = (self.n, self.h_last);
        let th = (t - (self.t - h)) / h;
        let w1 = self.tab.basis_integral(th);
        // Q: the polynomial of degree S through q_old (τ = 0) and the
        // stage positions Q_i at c_i,
        // Q_i = q_old + c_i h v_old + h² Σ_j (𝔄²)_ij A_j
        let tab = self.tab.stages();
        let c = tab.c;
        let node = |k: usize| if k == 0 { 0.0 } else { c[k - 1] };
        let li: [f64; S] = std::array::from_fn(|i| {
            (0..=S)
                .filter(|&k| k != i + 1)
                .map(|k| (th - node(k)) / (c[i] - node(k)))
                .product::<f64>()
        });
        let a2 = &tab.a2;
        let w2: [f64; S] = std::array::from_fn(|j| (0..S).map(|i| li[i] * a2[i][j]).sum());
        let a: [&[f64]; S] = std::array::from_fn(|j| &self.a_prev[j][..n]);
        for k in 0..n {
            out[k] = self.q_old[k] + th * h * self.v_old[k] + h * h * dot(&w2, |j| a[j][k]);
            out[n + k] = self.v_old[k] + h * dot(&w1, |j| a[j][k]);
        }
    }

    fn output_snap(&self) -> f64 {
        1e-9 * self.h_last
    }

    implicit_outputs!();
}
