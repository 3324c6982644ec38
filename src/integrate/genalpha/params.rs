//! The parameters of generalized-α, HHT and Newmark from ρ∞ (module docs
//! of [`super`]) and the options of the implicit integrators.

use super::super::{IntegratorError, Method};
use serde::Serialize;

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
    /// Fixed step h; `None` falls back to [`OdeOptions::fixed_step`](crate::integrate::OdeOptions::fixed_step). With
    /// `adaptive` it is the initial step (else [`OdeOptions::initial_step`](crate::integrate::OdeOptions::initial_step)
    /// or an automatic guess).
    pub step: Option<f64>,
    /// Adapt the step to the local error estimate with `rtol`/`atol` of
    /// [`OdeOptions`](crate::integrate::OdeOptions) (also `max_step`, `max_steps`). Default false.
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
    /// the [`SecondOrderDae`](super::SecondOrderDae) (`simulation::simulate`:
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
