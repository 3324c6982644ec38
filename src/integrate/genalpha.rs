//! Generalized-α for constrained mechanical systems in index-3 form, with
//! HHT-α and Newmark as parameter choices.
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
//! (or extrapolated, [`ImplicitOptions::extrapolate`]), `λ_{n+1} = λ_n`
//! the formulas above give `q`, `q̇`, `a`, and every Newton correction
//! `Δq` moves `q̇` by `γ' Δq`, `q̈` by `β' Δq`, `a` by `Δq/(β h²)`, with
//! `γ' = γ/(β h)`, `β' = (1 − α_m)/(β h² (1 − α_f))` (Arnold & Brüls 2007,
//! Algorithm 1). The linear systems are those of the scaled iteration
//! matrix of [`SecondOrderDae::factorize`] (constraint rows and λ scaled
//! by `β h²`, Bottasso, Bauchau & Cardona 2007).
//!
//! **Reuse (modified Newton).** A factorisation is kept across iterations
//! and steps while the iteration contracts fast enough. It is renewed
//! * at the predictor, when the step size moved by more than
//!   [`REUSE_BAND`] since it was computed, or when the previous step saw a
//!   contraction factor `θ = ‖Δq_k‖/‖Δq_{k−1}‖` above [`THETA_REFACTOR`] or
//!   needed more than [`SLOW_ITERATIONS`] corrections;
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
//! tolerance would put a floor under the accuracy as `h → 0` (measured:
//! 1e-8 m stalled the error of the bending rod at 1e-5 m), while
//! `|β' e| ≤ newton_tol` bounds it by `~ T² newton_tol` for every h.
//! Optionally also `‖Φ(q_{n+1})‖∞` must be below the position-equivalent
//! tolerance ([`ImplicitOptions::check_constraints`]).
//!
//! # Step size
//!
//! * **Fixed** ([`ImplicitOptions::step`]): steps on the grid
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
//!   |q_i^{n+1}|))`, accepted for ≤ 1; new step `h · min(2, max(0.2,
//!   0.9 err^{−1/3}))` (no growth right after a rejection; changes below
//!   20 % upwards are not made, to keep the factorisation), after an
//!   accepted step limited further by Gustafsson's predictive controller
//!   `0.9 (h_n/h_{n−1}) (err_{n−1}/err_n²)^{1/3}` (Hairer & Wanner II,
//!   eq. (8.21)), which damps the accept/reject cycles of an oscillating
//!   error. A Newton failure halves the step.
//!
//! A run that cannot proceed (step below the minimum, `max_steps`, a
//! non-finite state or a failing linear solve) ends with
//! [`Termination::Failed`] after every output up to the last accepted
//! step was delivered.

use super::hermite::cubic;
use super::Tolerance;
use super::{common, IntegratorError, Method, Observer, OdeOptions, Report, Stats, Termination};
use serde::Serialize;
use std::ops::ControlFlow;

/// A constrained second-order system `M q̈ + Φ_qᵀ λ = g(q, q̇, t)`,
/// `Φ(q, t) = 0` with a diagonal mass matrix, as the implicit integrators
/// see it (implemented for multibody systems by
/// [`crate::formulation::Index3`]).
///
/// Every method returns `Err(reason)` on failure (non-finite values, a
/// singular matrix); the integrator then cuts the step or stops.
pub trait SecondOrderDae {
    /// Number of coordinates n.
    fn n(&self) -> usize;
    /// Number of constraint equations m.
    fn m(&self) -> usize;
    /// Diagonal of M.
    fn mass_diagonal(&self) -> &[f64];
    /// Consistent accelerations and multipliers at `(t, q, q̇)`:
    /// `M q̈ + Φ_qᵀ λ = g`, `Φ_q q̈ = γ`.
    fn accelerations(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &mut [f64],
        lambda: &mut [f64],
    ) -> Result<(), String>;
    /// Scaled residual: `r[..n] = scale (M q̈ + Φ_qᵀ λ − g)`, `r[n..] = Φ(q, t)`.
    #[allow(clippy::too_many_arguments)]
    fn residual(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        lambda: &[f64],
        scale: f64,
        r: &mut [f64],
    ) -> Result<(), String>;
    /// Φ(q, t) into `phi`.
    fn constraints(&mut self, t: f64, q: &[f64], phi: &mut [f64]);
    /// Assemble and factorise the iteration matrix
    /// `[c₀ M + c₁ C_t + c₂ K_t, Φ_qᵀ; Φ_q, 0]` at `(t, q, q̇, λ)` with
    /// `C_t = −∂g/∂q̇`, `K_t = −∂g/∂q + (Φ_qᵀ λ)_q` (or an approximation
    /// of it, e.g. its symmetric part).
    fn factorize(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lambda: &[f64],
        c: [f64; 3],
    ) -> Result<(), String>;
    /// Overwrite `rhs` (length n + m) with the solution of the last factorised matrix.
    fn solve(&mut self, t: f64, rhs: &mut [f64]) -> Result<(), String>;
    /// Project `(q, q̇)` onto `Φ = 0`, `Φ_q q̇ + Φ_t = 0`.
    fn project(&mut self, t: f64, q: &mut [f64], qd: &mut [f64]) -> Result<(), String>;
}

/// The four parameters of the generalized-α family (Chung & Hulbert 1993;
/// Arnold & Brüls 2007, eq. (9)–(10)); see the module docs for the formulas.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AlphaParameters {
    /// α_m: weight of the old auxiliary acceleration.
    pub alpha_m: f64,
    /// α_f: weight of the old true acceleration.
    pub alpha_f: f64,
    /// Newmark γ.
    pub gamma: f64,
    /// Newmark β.
    pub beta: f64,
}

impl AlphaParameters {
    /// Generalized-α with spectral radius ρ∞ at infinity (Chung & Hulbert
    /// 1993, eq. (25), (17), (20)): second order, minimal low-frequency
    /// dissipation for the given high-frequency dissipation.
    pub fn generalized_alpha(rho_inf: f64) -> Self {
        let alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0);
        let alpha_f = rho_inf / (rho_inf + 1.0);
        let gamma = 0.5 + alpha_f - alpha_m;
        Self {
            alpha_m,
            alpha_f,
            gamma,
            beta: 0.25 * (gamma + 0.5) * (gamma + 0.5),
        }
    }

    /// HHT-α (Hilber, Hughes & Taylor 1977) as generalized-α with α_m = 0,
    /// `α_f = (1 − ρ∞)/(1 + ρ∞)` (ρ∞ ∈ [½, 1]), `γ = ½ + α_f`,
    /// `β = ¼ (1 + α_f)²`.
    pub fn hht(rho_inf: f64) -> Self {
        let alpha_f = (1.0 - rho_inf) / (1.0 + rho_inf);
        Self {
            alpha_m: 0.0,
            alpha_f,
            gamma: 0.5 + alpha_f,
            beta: 0.25 * (1.0 + alpha_f) * (1.0 + alpha_f),
        }
    }

    /// Newmark (α_m = α_f = 0) with `γ = (3 − ρ∞)/(2 (1 + ρ∞))`,
    /// `β = ¼ (γ + ½)²`: spectral radius ρ∞ at infinity; the trapezoidal
    /// rule for ρ∞ = 1, first order for ρ∞ < 1.
    pub fn newmark(rho_inf: f64) -> Self {
        let gamma = (3.0 - rho_inf) / (2.0 * (1.0 + rho_inf));
        Self {
            alpha_m: 0.0,
            alpha_f: 0.0,
            gamma,
            beta: 0.25 * (gamma + 0.5) * (gamma + 0.5),
        }
    }

    /// Parameters of an implicit `method` for `rho_inf`, validated
    /// (ρ∞ ∈ [0, 1]; HHT needs ρ∞ ∈ [½, 1]).
    pub fn for_method(method: Method, rho_inf: f64) -> Result<Self, IntegratorError> {
        let bad = |reason: &str| IntegratorError::InvalidOption {
            option: "rho_inf",
            value: rho_inf.to_string(),
            reason: reason.to_string(),
        };
        if !(rho_inf.is_finite() && (0.0..=1.0).contains(&rho_inf)) {
            return Err(bad("must be in [0, 1]"));
        }
        match method {
            Method::GenAlpha => Ok(Self::generalized_alpha(rho_inf)),
            Method::Hht => {
                if rho_inf < 0.5 {
                    Err(bad("HHT-α needs rho_inf in [0.5, 1] (α_f ≤ 1/3)"))
                } else {
                    Ok(Self::hht(rho_inf))
                }
            }
            Method::Newmark => Ok(Self::newmark(rho_inf)),
            other => Err(IntegratorError::InvalidOption {
                option: "method",
                value: other.name().to_string(),
                reason: "not an implicit (generalized-α family) method".into(),
            }),
        }
    }

    /// Error constant `C = β − γ/2 + 1/12` of the position local
    /// truncation error `C h³ q⃛` (module docs; `β − 1/6` for γ = ½,
    /// Zienkiewicz & Xie 1991).
    pub fn error_constant(&self) -> f64 {
        self.beta - 0.5 * self.gamma + 1.0 / 12.0
    }
}

/// Options of the implicit integrators (scenario keys `integrator.<field>`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImplicitOptions {
    /// Spectral radius at infinity ρ∞ ∈ [0, 1] (HHT: [½, 1]): the factor by
    /// which unresolved high-frequency components shrink per step.
    /// Default 0.8.
    pub rho_inf: f64,
    /// Fixed step h; `None` falls back to [`OdeOptions::fixed_step`]. With
    /// `adaptive` it is the initial step (else [`OdeOptions::initial_step`]
    /// or an automatic guess).
    pub step: Option<f64>,
    /// Adapt the step to the local error estimate with `rtol`/`atol` of
    /// [`OdeOptions`] (also `max_step`, `max_steps`). Default false.
    pub adaptive: bool,
    /// Newton tolerance on the acceleration corrections `Δq̈ = β' Δq`
    /// (m/s², rad/s²; also bounds the velocity and position corrections),
    /// floored at the rounding noise of q (module docs). Unconverged
    /// remainders add up to a position error of about `T² newton_tol`
    /// over a run of length T. Default 1e-6.
    pub newton_tol: f64,
    /// Newton iterations per attempt before the step is retried (fresh
    /// factorisation) or cut. Default 8.
    pub max_newton: usize,
    /// Project positions and velocities onto the constraint manifold after
    /// every step (mass-weighted, one extra factorisation per step).
    /// Default false.
    pub project: bool,
    /// Keep factorisations across iterations and steps (modified Newton);
    /// false: a fresh factorisation at every iteration (full Newton up to
    /// the symmetrisation). Default true.
    pub reuse: bool,
    /// Filter the error estimate through the iteration matrix (adaptive
    /// only; module docs). Default true.
    pub filter_error: bool,
    /// Also require `‖Φ(q_{n+1})‖∞` below the position-equivalent Newton
    /// tolerance `newton_tol / max(1, γ', β')` (floored at 20 ulps of
    /// `max |q_i|`) after the last correction (one more evaluation of Φ
    /// per iteration). Off by default: after a
    /// correction `Φ_q Δq = −Φ` holds exactly for the factorised Φ_q, so
    /// the remaining `Φ` is `O(‖Δq‖²) + O(‖Φ_q − Φ_q^fact‖ ‖Δq‖)`, far
    /// below the tolerance once `‖Δq‖` is.
    pub check_constraints: bool,
    /// Smallest step before the run fails; `None`: `16 eps(t)` (MATLAB's
    /// `hmin`).
    pub min_step: Option<f64>,
    /// Factorise the full unsymmetric iteration matrix with a sparse LU
    /// (exact Newton) instead of its symmetric part with the LDLᵀ
    /// saddle-point solver (modified Newton). Read by the caller that builds
    /// the [`SecondOrderDae`] (`simulation::simulate`:
    /// [`crate::formulation::NewtonSolverKind`]). Default false.
    pub lu: bool,
    /// Newton predictor: `q̈_{n+1}` extrapolated linearly from the last
    /// two steps (true) or kept constant (false, as `λ_{n+1}` always is;
    /// Arnold & Brüls 2007). Measured on problem C at h = 2.5e-5 over
    /// 0.3 s: −16 % Newton iterations at N = 1000, +14 % at N = 100, and
    /// twice the iterations in free fall (where the constant predictor is
    /// exact); hence off by default.
    pub extrapolate: bool,
}

impl Default for ImplicitOptions {
    fn default() -> Self {
        Self {
            rho_inf: 0.8,
            step: None,
            adaptive: false,
            newton_tol: 1e-6,
            max_newton: 8,
            project: false,
            reuse: true,
            filter_error: true,
            check_constraints: false,
            min_step: None,
            lu: false,
            extrapolate: false,
        }
    }
}

/// A factorisation is reused while the step size stays within this
/// relative distance of the one it was computed for.
pub const REUSE_BAND: f64 = 0.25;
/// Contraction factor θ above which the factorisation is renewed at the
/// next step.
pub const THETA_REFACTOR: f64 = 0.2;
/// Iterations per step after which the factorisation is renewed at the
/// next step.
pub const SLOW_ITERATIONS: usize = 4;

/// Floor of the Newton tolerance on a position correction, in ulps of
/// `max(|q_i|, 1)`: below it corrections are rounding noise.
pub const ROUNDING_ULPS: f64 = 20.0;

/// A Newton iteration that stops contracting (θ ≥ 1) with corrections
/// below this many tolerances (`‖Δq‖_w ≤ STAGNATION`) has reached the
/// rounding noise of the linear solve and counts as converged (the noise
/// of the angle corrections of a chain grows like 1/segment length: at
/// N = 10 000, ~1e-14 rad, 50 ulps); above it, it diverges.
pub const STAGNATION: f64 = 100.0;

/// Safety factor of the step-size controller.
pub const SAFETY: f64 = 0.9;

/// Work counters of a generalized-α run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct GenAlphaStats {
    /// Accepted steps.
    pub steps: usize,
    /// Steps rejected by the error test (adaptive).
    pub error_rejections: usize,
    /// Step attempts abandoned because Newton did not converge.
    pub newton_failures: usize,
    /// Newton corrections (linear solves of the iteration matrix).
    pub newton_iterations: usize,
    /// Factorisations of the iteration matrix.
    pub factorizations: usize,
    /// Residual evaluations.
    pub residual_evaluations: usize,
    /// Projections onto the constraint manifold.
    pub projections: usize,
    /// Smallest accepted step.
    pub min_step_taken: f64,
    /// Largest accepted step.
    pub max_step_taken: f64,
}

/// The generalized-α integrator (module docs) with its parameters and options.
#[derive(Debug, Clone)]
pub struct GenAlpha {
    method: Method,
    params: AlphaParameters,
    opts: ImplicitOptions,
    ode: OdeOptions,
    h_fixed: f64,
    stats: GenAlphaStats,
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
}

/// How a step attempt ended.
enum Attempt {
    Converged,
    /// Newton did not converge (reason).
    Failed(String),
}

fn invalid(option: &'static str, value: impl std::fmt::Display, reason: &str) -> IntegratorError {
    IntegratorError::InvalidOption {
        option,
        value: value.to_string(),
        reason: reason.to_string(),
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
        let params = AlphaParameters::for_method(method, opts.rho_inf)?;
        if !(opts.newton_tol > 0.0 && opts.newton_tol.is_finite()) {
            return Err(invalid(
                "newton_tol",
                opts.newton_tol,
                "must be positive and finite",
            ));
        }
        if opts.max_newton == 0 {
            return Err(invalid("max_newton", 0, "must be at least 1"));
        }
        if ode.max_steps == 0 {
            return Err(invalid("max_steps", 0, "must be at least 1"));
        }
        if let Some(h) = opts.min_step {
            if !(h > 0.0 && h.is_finite()) {
                return Err(invalid("min_step", h, "must be positive and finite"));
            }
        }
        let step = opts.step.or(ode.fixed_step);
        if let Some(h) = step {
            if !(h > 0.0 && h.is_finite()) {
                return Err(invalid("step", h, "must be positive and finite"));
            }
        }
        let h_fixed = if opts.adaptive {
            if !(ode.rtol > 0.0 && ode.rtol.is_finite()) {
                return Err(invalid("rtol", ode.rtol, "must be positive and finite"));
            }
            match &ode.atol {
                Tolerance::Scalar(a) if !(*a >= 0.0 && a.is_finite()) => {
                    return Err(invalid("atol", a, "must be non-negative and finite"))
                }
                Tolerance::Vector(v) if v.iter().any(|a| !(*a >= 0.0 && a.is_finite())) => {
                    return Err(invalid(
                        "atol",
                        "vector",
                        "every component must be non-negative and finite",
                    ))
                }
                _ => {}
            }
            if let Some(h) = ode.max_step {
                if h.is_nan() || h <= 0.0 {
                    return Err(invalid("max_step", h, "must be positive"));
                }
            }
            if let Some(h) = ode.initial_step {
                if !(h > 0.0 && h.is_finite()) {
                    return Err(invalid("initial_step", h, "must be positive and finite"));
                }
            }
            0.0
        } else {
            match step {
                Some(h) => h,
                None => {
                    return Err(invalid(
                        "step",
                        "None",
                        &format!(
                            "{} with a fixed step needs a step (or adaptive = true)",
                            method.name()
                        ),
                    ))
                }
            }
        };
        if let (Some(hmin), false) = (opts.min_step, opts.adaptive) {
            if hmin > h_fixed {
                return Err(invalid(
                    "min_step",
                    hmin,
                    &format!("must not exceed the fixed step {h_fixed}"),
                ));
            }
        }
        Ok(Self {
            method,
            params,
            opts,
            ode,
            h_fixed,
            stats: GenAlphaStats::default(),
        })
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
    /// Counters of the last run.
    pub fn stats(&self) -> GenAlphaStats {
        self.stats
    }

    /// Integrate from `(t0, q0, q̇0)` to `t_end`.
    ///
    /// The observer receives `y = [q; q̇]`: `output` at each requested time
    /// (exact at step ends, else cubic Hermite interpolation of q with q̇
    /// and of q̇ with q̈ between the two step ends), `step` after every
    /// accepted step. `output_times` must be strictly increasing within
    /// `[t0, t_end]`. Inputs are validated as for the explicit integrators;
    /// a failure midway is `Ok` with [`Termination::Failed`].
    #[allow(clippy::too_many_arguments)]
    pub fn integrate(
        &mut self,
        sys: &mut dyn SecondOrderDae,
        t0: f64,
        t_end: f64,
        q0: &[f64],
        qd0: &[f64],
        output_times: &[f64],
        obs: &mut dyn Observer,
    ) -> Result<Report, IntegratorError> {
        let (n, m) = (sys.n(), sys.m());
        validate_run(
            n,
            t0,
            t_end,
            q0,
            qd0,
            output_times,
            &self.ode,
            self.opts.adaptive,
        )?;
        self.stats = GenAlphaStats {
            min_step_taken: f64::INFINITY,
            ..Default::default()
        };
        let mut run = Run::new(self, sys, n, m, t0, t_end, q0, qd0);
        let termination = run.go(obs, output_times);
        let t_reached = run.t;
        let mut stats = run.stats;
        if stats.steps == 0 {
            stats.min_step_taken = 0.0;
        }
        let warnings = run.warnings;
        self.stats = stats;
        Ok(common::report(
            Stats {
                steps: stats.steps,
                failed_steps: stats.error_rejections + stats.newton_failures,
                rhs_evals: stats.residual_evaluations,
            },
            termination,
            t_reached,
            warnings,
        ))
    }
}

#[allow(clippy::too_many_arguments)]
fn validate_run(
    n: usize,
    t0: f64,
    t_end: f64,
    q0: &[f64],
    qd0: &[f64],
    output_times: &[f64],
    ode: &OdeOptions,
    adaptive: bool,
) -> Result<(), IntegratorError> {
    if !(t0.is_finite() && t_end.is_finite() && t_end > t0) {
        return Err(IntegratorError::InvalidTimeSpan {
            t0,
            t_end,
            reason: "t0 and t_end must be finite with t_end > t0 (only forward integration)".into(),
        });
    }
    for (what, v) in [("q0", q0), ("qd0", qd0)] {
        if v.len() != n {
            return Err(IntegratorError::DimensionMismatch {
                what,
                expected: n,
                got: v.len(),
            });
        }
    }
    if let Some((index, value)) = q0
        .iter()
        .chain(qd0)
        .enumerate()
        .find(|(_, v)| !v.is_finite())
    {
        return Err(IntegratorError::NonFiniteInitialState {
            index,
            value: *value,
        });
    }
    if adaptive {
        if let Tolerance::Vector(v) = &ode.atol {
            if v.len() != n && v.len() != 2 * n {
                return Err(IntegratorError::DimensionMismatch {
                    what: "atol",
                    expected: n,
                    got: v.len(),
                });
            }
        }
    }
    for (i, &tk) in output_times.iter().enumerate() {
        let bad = |reason: String| IntegratorError::InvalidOutputTimes {
            index: i,
            value: tk,
            reason,
        };
        if !tk.is_finite() {
            return Err(bad("not finite".into()));
        }
        if tk < t0 || tk > t_end {
            return Err(bad(format!("outside the time span [{t0}, {t_end}]")));
        }
        if i > 0 && tk <= output_times[i - 1] {
            return Err(bad(format!(
                "output times must be strictly increasing (previous is {})",
                output_times[i - 1]
            )));
        }
    }
    Ok(())
}

/// One run: the integrator's settings, the system and all buffers.
struct Run<'g, 's> {
    p: AlphaParameters,
    opts: &'g ImplicitOptions,
    ode: &'g OdeOptions,
    h_fixed: f64,
    sys: &'s mut dyn SecondOrderDae,
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
    ybuf: Vec<f64>,
    /// Step the current factorisation was computed for (None: none valid).
    h_fact: Option<f64>,
    /// Renew the factorisation at the next attempt.
    refactor: bool,
    /// η = θ/(1 − θ) of the last converged iteration.
    eta: f64,
    /// Whether the last attempt computed its own factorisation.
    last_attempt_fresh: bool,
    /// q̈ and step of the previous accepted step (predictor).
    prev_qdd: Vec<f64>,
    h_prev: Option<f64>,
    stats: GenAlphaStats,
    warnings: Vec<String>,
}

impl<'g, 's> Run<'g, 's> {
    #[allow(clippy::too_many_arguments)]
    fn new(
        g: &'g GenAlpha,
        sys: &'s mut dyn SecondOrderDae,
        n: usize,
        m: usize,
        t0: f64,
        t_end: f64,
        q0: &[f64],
        qd0: &[f64],
    ) -> Self {
        let mut cur = State::new(n, m);
        cur.q.copy_from_slice(q0);
        cur.v.copy_from_slice(qd0);
        Self {
            p: g.params,
            opts: &g.opts,
            ode: &g.ode,
            h_fixed: g.h_fixed,
            sys,
            n,
            t0,
            t_end,
            t: t0,
            new: cur.clone(),
            cur,
            r: vec![0.0; n + m],
            phi: vec![0.0; m],
            err: vec![0.0; n + m],
            y: vec![0.0; 2 * n],
            ybuf: vec![0.0; 2 * n],
            h_fact: None,
            refactor: true,
            eta: 1.0,
            last_attempt_fresh: false,
            prev_qdd: vec![0.0; n],
            h_prev: None,
            stats: GenAlphaStats {
                min_step_taken: f64::INFINITY,
                ..Default::default()
            },
            warnings: Vec::new(),
        }
    }

    fn min_step(&self, t: f64) -> f64 {
        let floor = 16.0 * common::eps(t);
        self.opts.min_step.map_or(floor, |h| h.max(floor))
    }

    fn fail(&self, reason: String) -> Termination {
        Termination::Failed { t: self.t, reason }
    }

    /// Absolute tolerance of component i (adaptive error norm).
    fn atol(&self, i: usize) -> f64 {
        match &self.ode.atol {
            Tolerance::Scalar(a) => *a,
            Tolerance::Vector(v) => v[i],
        }
    }

    /// The main loop; returns how the run ended.
    fn go(&mut self, obs: &mut dyn Observer, times: &[f64]) -> Termination {
        let (n, t0) = (self.n, self.t0);
        let mut next_out = 0;
        // Output at t0.
        self.y[..n].copy_from_slice(&self.cur.q);
        self.y[n..].copy_from_slice(&self.cur.v);
        if times.first() == Some(&t0) {
            next_out = 1;
            if let ControlFlow::Break(r) = obs.output(t0, &self.y) {
                return Termination::Stopped { t: t0, reason: r };
            }
        }
        // Consistent accelerations and multipliers at t0; a_0 = q̈_0.
        self.stats.residual_evaluations += 1;
        let (q, v) = (&self.cur.q, &self.cur.v);
        if let Err(e) = self
            .sys
            .accelerations(t0, q, v, &mut self.cur.qdd, &mut self.cur.lam)
        {
            return self.fail(format!("initial accelerations at t = {t0}: {e}"));
        }
        self.cur.a.copy_from_slice(&self.cur.qdd);

        let span = self.t_end - t0;
        let adaptive = self.opts.adaptive;
        let max_step = if adaptive {
            self.ode.max_step.unwrap_or(0.1 * span).min(span)
        } else {
            self.h_fixed
        };
        let mut h = if adaptive {
            self.opts
                .step
                .or(self.ode.initial_step)
                .unwrap_or_else(|| self.initial_step_guess(span))
                .min(max_step)
        } else {
            self.h_fixed
        };
        // Fixed-step grid: index of the next grid point.
        let mut k_grid: u64 = 1;
        let mut no_growth = false;
        // last accepted (h, err), for the predictive controller
        let mut last_acc: Option<(f64, f64)> = None;
        let err_exp = 1.0 / 3.0;

        while self.t < self.t_end {
            if self.stats.steps >= self.ode.max_steps {
                return self.fail(format!(
                    "maximum number of steps ({}) reached at t = {}",
                    self.ode.max_steps, self.t
                ));
            }
            // Step to attempt.
            let target = if adaptive {
                self.t_end
            } else {
                (t0 + k_grid as f64 * self.h_fixed).min(self.t_end)
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
                return self.fail(format!(
                    "step size {h_try:.3e} below the minimum {hmin:.3e} at t = {}: \
                     Newton does not converge (last: {})",
                    self.t,
                    self.warnings.last().map_or("", |s| s.as_str())
                ));
            }
            let t_new = if h_try == self.t_end - self.t {
                self.t_end
            } else {
                self.t + h_try
            };
            // Attempt, with one retry on a fresh factorisation.
            let mut outcome = self.attempt(t_new, h_try);
            if let Attempt::Failed(_) = &outcome {
                if !self.last_attempt_fresh {
                    self.refactor = true;
                    outcome = self.attempt(t_new, h_try);
                }
            }
            if let Attempt::Failed(reason) = outcome {
                self.stats.newton_failures += 1;
                let msg = format!("Newton failed at t = {t_new} with h = {h_try:.3e}: {reason}");
                if self.warnings.len() < 20 {
                    self.warnings.push(msg.clone());
                } else if let Some(last) = self.warnings.last_mut() {
                    *last = msg.clone();
                }
                if h_try * 0.5 < self.min_step(self.t) {
                    return self.fail(format!(
                        "step size {:.3e} below the minimum {:.3e} at t = {}: {msg}",
                        h_try * 0.5,
                        self.min_step(self.t),
                        self.t
                    ));
                }
                h = h_try * 0.5;
                no_growth = true;
                continue;
            }
            // Error control.
            let mut fac = 1.0;
            if adaptive {
                let err = match self.error_norm(t_new, h_try) {
                    Ok(e) => e,
                    Err(e) => return self.fail(e),
                };
                fac = (SAFETY * err.powf(-err_exp)).clamp(0.2, if no_growth { 1.0 } else { 2.0 });
                if !err.is_finite() {
                    fac = 0.2;
                }
                if err <= 1.0 {
                    // Gustafsson's predictive controller (Hairer & Wanner
                    // II, §IV.8, eq. (8.21), as in RADAU5): damps the
                    // accept/reject cycles of an oscillating error.
                    if let Some((h_acc, err_acc)) = last_acc {
                        let e = err.max(1e-10);
                        let g =
                            SAFETY * (h_try / h_acc) * (err_acc.max(1e-10) / (e * e)).powf(err_exp);
                        fac = fac.min(g.clamp(0.2, 2.0));
                    }
                    last_acc = Some((h_try, err));
                }
                if err > 1.0 || !err.is_finite() {
                    self.stats.error_rejections += 1;
                    let hn = h_try * fac;
                    if hn < self.min_step(self.t) {
                        return self.fail(format!(
                            "step size {hn:.3e} below the minimum {:.3e} at t = {}: \
                             the error test fails (err = {err:.3e})",
                            self.min_step(self.t),
                            self.t
                        ));
                    }
                    h = hn;
                    no_growth = true;
                    continue;
                }
            }
            // Accept.
            if self.opts.project {
                self.stats.projections += 1;
                let (q, v) = (&mut self.new.q, &mut self.new.v);
                if let Err(e) = self.sys.project(t_new, q, v) {
                    return self.fail(format!("projection at t = {t_new}: {e}"));
                }
            }
            let t_old = self.t;
            self.prev_qdd.copy_from_slice(&self.cur.qdd);
            self.h_prev = Some(h_try);
            std::mem::swap(&mut self.cur, &mut self.new);
            self.t = t_new;
            self.stats.steps += 1;
            self.stats.min_step_taken = self.stats.min_step_taken.min(h_try);
            self.stats.max_step_taken = self.stats.max_step_taken.max(h_try);
            // Outputs in (t_old, t_new].
            while let Some(&tk) = times.get(next_out) {
                let exact =
                    (tk - t_new).abs() <= 1e-9 * h_try || self.t >= self.t_end && tk >= t_new;
                if tk > t_new && !exact {
                    break;
                }
                next_out += 1;
                if exact {
                    self.y[..n].copy_from_slice(&self.cur.q);
                    self.y[n..].copy_from_slice(&self.cur.v);
                } else {
                    hermite(
                        (tk - t_old) / h_try,
                        h_try,
                        &self.new,
                        &self.cur,
                        &mut self.ybuf,
                    );
                    self.y.copy_from_slice(&self.ybuf);
                }
                if let ControlFlow::Break(r) = obs.output(tk, &self.y) {
                    return Termination::Stopped { t: tk, reason: r };
                }
            }
            self.y[..n].copy_from_slice(&self.cur.q);
            self.y[n..].copy_from_slice(&self.cur.v);
            if let ControlFlow::Break(r) = obs.step(t_new, &self.y) {
                return Termination::Stopped {
                    t: t_new,
                    reason: r,
                };
            }
            // Next step size.
            if adaptive {
                let mut hn = (h_try * fac).min(max_step);
                if (1.0..1.2).contains(&fac) && h_try >= h * 0.999 {
                    hn = h_try; // keep the factorisation
                }
                if h_try < h * 0.999 && fac >= 1.0 {
                    // a shortened final step: do not let it shrink the step
                    hn = h.max(hn);
                }
                h = hn;
            } else {
                if (self.t - target).abs() <= 1e-9 * self.h_fixed || self.t >= target {
                    k_grid += 1;
                }
                h = (2.0 * h).min(self.h_fixed);
            }
            no_growth = false;
        }
        Termination::Completed
    }

    /// Factorise the iteration matrix at the current iterate.
    fn factor(&mut self, t1: f64, h: f64, c: [f64; 3]) -> Result<(), String> {
        self.stats.factorizations += 1;
        self.h_fact = None;
        self.sys
            .factorize(t1, &self.new.q, &self.new.v, &self.new.lam, c)?;
        self.h_fact = Some(h);
        self.refactor = false;
        self.last_attempt_fresh = true;
        Ok(())
    }

    /// One step attempt from `(self.t, self.cur)` to `t1 = self.t + h`
    /// into `self.new`: predictor, then (modified) Newton.
    fn attempt(&mut self, t1: f64, h: f64) -> Attempt {
        let p = self.p;
        let (n, tol) = (self.n, self.opts.newton_tol);
        let s = p.beta * h * h;
        let c_m = (1.0 - p.alpha_m) / (1.0 - p.alpha_f);
        let c = [c_m, p.gamma * h, s];
        let gp = p.gamma / (p.beta * h); // ∂q̇/∂q
        let bp = c_m / s; // ∂q̈/∂q
        let ap = 1.0 / s; // ∂a/∂q
        {
            let (cur, new) = (&self.cur, &mut self.new);
            let (am, af, g, b) = (p.alpha_m, p.alpha_f, p.gamma, p.beta);
            // q̈_{n+1} predicted constant or extrapolated linearly from the
            // last two steps; λ_{n+1} constant
            let r = match self.h_prev {
                Some(hp) if self.opts.extrapolate => h / hp,
                _ => 0.0,
            };
            for i in 0..n {
                let qdd0 = cur.qdd[i] + r * (cur.qdd[i] - self.prev_qdd[i]);
                new.qdd[i] = qdd0;
                new.a[i] = ((1.0 - af) * qdd0 + af * cur.qdd[i] - am * cur.a[i]) / (1.0 - am);
                new.v[i] = cur.v[i] + h * ((1.0 - g) * cur.a[i] + g * new.a[i]);
                new.q[i] = cur.q[i] + h * cur.v[i] + h * h * ((0.5 - b) * cur.a[i] + b * new.a[i]);
            }
            new.lam.copy_from_slice(&cur.lam);
        }
        self.last_attempt_fresh = false;
        let stale = match self.h_fact {
            None => true,
            Some(hf) => (h / hf - 1.0).abs() > REUSE_BAND,
        };
        if self.refactor || stale || !self.opts.reuse {
            if let Err(e) = self.factor(t1, h, c) {
                return Attempt::Failed(e);
            }
        }
        // position-equivalent tolerance of the acceleration (and velocity)
        // corrections, floored at a few ulps of the positions
        let tol_q = tol / gp.max(bp).max(1.0);
        let mut prev = f64::NAN;
        let mut theta: f64;
        let mut eta = self.eta.max(1.0);
        // iterations since the last factorisation, refactorisations at an
        // iterate within this attempt
        let (mut round, mut refreshed) = (0usize, false);
        let mut it = 0;
        loop {
            if round > 0 && !self.opts.reuse {
                if let Err(e) = self.factor(t1, h, c) {
                    return Attempt::Failed(e);
                }
            }
            self.stats.residual_evaluations += 1;
            let new = &self.new;
            if let Err(e) =
                self.sys
                    .residual(t1, &new.q, &new.v, &new.qdd, &new.lam, s, &mut self.r)
            {
                return Attempt::Failed(e);
            }
            for x in self.r.iter_mut() {
                *x = -*x;
            }
            if let Err(e) = self.sys.solve(t1, &mut self.r) {
                return Attempt::Failed(e);
            }
            self.stats.newton_iterations += 1;
            it += 1;
            let dnorm = self.r[..n]
                .iter()
                .zip(&self.new.q)
                .fold(0.0_f64, |a, (d, q)| {
                    a.max(d.abs() / (tol_q + ROUNDING_ULPS * f64::EPSILON * q.abs().max(1.0)))
                });
            if !dnorm.is_finite() {
                return Attempt::Failed("non-finite Newton correction".into());
            }
            {
                let (new, dx) = (&mut self.new, &self.r);
                for (i, &d) in dx[..n].iter().enumerate() {
                    new.q[i] += d;
                    new.v[i] += gp * d;
                    new.qdd[i] += bp * d;
                    new.a[i] += ap * d;
                }
                for (l, d) in new.lam.iter_mut().zip(&dx[n..]) {
                    *l += d / s;
                }
            }
            let mut done = if round == 0 {
                theta = f64::NAN;
                dnorm * eta <= 1.0
            } else {
                theta = dnorm / prev;
                if theta >= 1.0 {
                    if dnorm > STAGNATION {
                        return Attempt::Failed(format!(
                            "Newton diverges (contraction θ = {theta:.3}, correction {:.3e} × tol)",
                            dnorm
                        ));
                    }
                    // no contraction among corrections this small: the
                    // iteration has reached the noise floor of the solve
                    true
                } else {
                    eta = theta / (1.0 - theta);
                    if theta > THETA_REFACTOR {
                        self.refactor = true;
                    }
                    eta * dnorm <= 1.0
                }
            };
            prev = dnorm;
            round += 1;
            if done && self.opts.check_constraints {
                self.sys.constraints(t1, &self.new.q, &mut self.phi);
                let phi = self.phi.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
                let scale = self.new.q.iter().fold(1.0_f64, |a, x| a.max(x.abs()));
                done = phi <= tol_q + ROUNDING_ULPS * f64::EPSILON * scale;
            }
            if done {
                if theta.is_finite() && theta < 1.0 {
                    self.eta = eta;
                }
                if it > SLOW_ITERATIONS {
                    self.refactor = true;
                }
                return Attempt::Converged;
            }
            if round >= self.opts.max_newton {
                // Still contracting: renew the matrix at this (much better)
                // iterate once and carry on; otherwise give up.
                if self.opts.reuse && !refreshed && theta < 1.0 {
                    refreshed = true;
                    if let Err(e) = self.factor(t1, h, c) {
                        return Attempt::Failed(e);
                    }
                    round = 0;
                    eta = 1.0;
                    continue;
                }
                return Attempt::Failed(format!(
                    "no convergence in {it} iterations (last correction {prev:.3e} × tol, θ = {theta:.3})"
                ));
            }
        }
    }

    /// Norm of the local error estimate of the attempt in `self.new`
    /// (module docs); ≤ 1 passes.
    fn error_norm(&mut self, t1: f64, h: f64) -> Result<f64, String> {
        let p = self.p;
        let n = self.n;
        // Position LTE constant; for the first-order Newmark members the
        // velocity LTE (γ − ½) h² q⃛ is added (a heuristic for their
        // dominant error).
        let newmark = p.alpha_m == 0.0 && p.alpha_f == 0.0;
        let extra = if newmark {
            (p.gamma - 0.5).max(0.0)
        } else {
            0.0
        };
        let cst = (p.error_constant() + extra).abs() * h * h;
        for i in 0..n {
            self.err[i] = cst * (self.new.a[i] - self.cur.a[i]);
        }
        if self.opts.filter_error && self.h_fact.is_some() {
            let c_m = (1.0 - p.alpha_m) / (1.0 - p.alpha_f);
            let mass = self.sys.mass_diagonal();
            for (e, m) in self.err[..n].iter_mut().zip(mass) {
                *e *= c_m * m;
            }
            self.err[n..].fill(0.0);
            self.sys
                .solve(t1, &mut self.err)
                .map_err(|e| format!("error filter at t = {t1}: {e}"))?;
        }
        let mut norm: f64 = 0.0;
        for i in 0..n {
            let w = self.atol(i) + self.ode.rtol * self.cur.q[i].abs().max(self.new.q[i].abs());
            let e = self.err[i].abs();
            norm = norm.max(if w > 0.0 {
                e / w
            } else if e > 0.0 {
                f64::INFINITY
            } else {
                0.0
            });
        }
        Ok(norm)
    }

    fn initial_step_guess(&mut self, span: f64) -> f64 {
        // position change ½ h² q̈ at 1 % of the tolerance
        let mut acc: f64 = 0.0;
        for i in 0..self.n {
            let w = self.atol(i) + self.ode.rtol * self.cur.q[i].abs();
            if w > 0.0 {
                acc = acc.max(self.cur.qdd[i].abs() / w);
            }
        }
        let h = if acc > 0.0 {
            (0.02 / acc).sqrt()
        } else {
            0.01 * span
        };
        h.min(0.01 * span).max(1e-6 * span)
    }
}

/// Cubic Hermite interpolation between two step ends `a` (s = 0) and `b`
/// (s = 1): q from (q, q̇), q̇ from (q̇, q̈). Writes `[q; q̇]` into `out`.
fn hermite(s: f64, h: f64, a: &State, b: &State, out: &mut [f64]) {
    let n = a.q.len();
    let (q, v) = out.split_at_mut(n);
    cubic(q, s, h, &a.q, &a.v, &b.q, &b.v);
    cubic(v, s, h, &a.v, &a.qdd, &b.v, &b.qdd);
}
