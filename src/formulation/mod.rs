//! From a [`System`](crate::model::System) to what an integrator consumes.
//!
//! * [`Index1`]: the index-1 DAE of eq. (5) written as the first-order ODE
//!   `y = [q; q̇]`, `ẏ = [q̇; q̈]`, with `q̈` from the saddle-point system
//!   (default) or from the Schur complement with λ eliminated, eq. (9);
//!   Baumgarte stabilization eq. (10)–(11) replaces γ by
//!   `γ̄ = γ − 2αΦ̇ − β²Φ`, `Φ̇ = Φ_q q̇ + Φ_t`.
//! * [`Index3`]: the index-3 residual `M q̈ + Φ_qᵀ λ − g`, `Φ` and the
//!   scaled, symmetrised Newton matrix of implicit integrators
//!   (generalized-α, [`crate::integrate::GenAlpha`]).
//! * [`Penalty`]: the penalty formulation of Bayo, García de Jalón & Serna
//!   (1988), `(M + Φ_qᵀαΦ_q) q̈ = g + Φ_qᵀα(γ − 2ξωΦ̇ − ω²Φ)`, as the same
//!   first-order ODE ([`Formulation::Penalty`]).
//! * [`Augmented`]: the index-3 augmented Lagrangian with mass-orthogonal
//!   projections (Bayo & Ledesma 1996; [`Formulation::AugmentedLagrangian`]),
//!   `M q̈ + Φ_qᵀ(αΦ + λ*) = g`, `λ*_{i+1} = λ*_i + αΦ_{i+1}`, for
//!   [`crate::integrate::GenAlpha`] (a system with a multiplier update).
//! * [`ExplicitForm`]: whichever of the two the options choose, for the
//!   explicit integrators.
//! * [`Projection`]: the mass-orthogonal projection of positions and
//!   velocities onto the manifold after each accepted step
//!   ([`Index1::project`], [`crate::integrate::OdeSystem::post_step`]).
//! * [`Partitioned`]: generalized coordinate partitioning (Wehage & Haug
//!   1982), only the independent coordinates integrated
//!   ([`Formulation::Partitioned`]).
//! * [`consistent_initial_state`]: positions on Φ(q, t₀) = 0 and velocities
//!   on Φ_q q̇ = −Φ_t, given the independent coordinates.
//!
//! Formulas and references: docs/constraint_methods.md.

mod augmented;
pub(crate) mod dynamic_blocks;
mod index1;
mod index3;
mod index3_complex;
mod initial;
mod partitioning;
mod penalty;
mod singularity;
mod stability;
mod state_border;

pub use augmented::{Augmented, AugmentedFormStats, AugmentedParams, PENALTY_SCALE};
pub use index1::{Index1, Index1Options, RhsStats};
pub use index3::{Index3, Index3Stats, NewtonSolverKind};
pub use index3_complex::{ComplexSolverKind, Index3Complex};
pub(crate) use initial::consistent_initial_state_locked;
pub use initial::{
    consistent_initial_state, ConsistentState, InitialOptions, Lock, LockKind, StartCorrection,
    START_MAX_ITER, START_TOL,
};
pub use partitioning::{PartitionOptions, PartitionStats, Partitioned, MAX_PARTITION_COORDS};
pub use penalty::{ExplicitForm, Penalty, PenaltyParams};
pub use singularity::{SingularCrossing, SingularityMonitor, MONITOR_MAX_COORDS, SINGULAR_RATIO};
pub use stability::{explicit_reach, fastest_modes, FastestModes};

use crate::linalg::{LinalgError, SaddleMatrix, SaddlePointSolver};
use crate::words::from_words;
use serde::Serialize;

/// One minimum-mass-norm correction onto `Φ_q Δ = −r` (the projections of
/// [`Index1`] and [`Index3`]): with `[M Φ_qᵀ; Φ_q 0]` factorised in
/// `solver`, solve `[M Φ_qᵀ; Φ_q 0][Δ; μ] = [0; −r]` — so `M Δ = −Φ_qᵀμ`,
/// `Δ = −M⁻¹Φ_qᵀ(Φ_q M⁻¹Φ_qᵀ)⁻¹ r`, the smallest `‖Δ‖_M` — and add `Δ` to
/// `v`. `x`: scratch of length `n + m`.
fn mass_orthogonal_step(
    solver: &mut dyn SaddlePointSolver,
    k: &SaddleMatrix,
    r: &[f64],
    x: &mut [f64],
    v: &mut [f64],
) -> Result<(), LinalgError> {
    let n = v.len();
    x[..n].fill(0.0);
    for (xi, ri) in x[n..].iter_mut().zip(r) {
        *xi = -ri;
    }
    solver.solve_in_place(k, x)?;
    for (vi, d) in v.iter_mut().zip(&x[..n]) {
        *vi += d;
    }
    Ok(())
}

/// How λ is obtained at each right-hand-side evaluation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Formulation {
    /// Saddle-point system `[M Φ_qᵀ; Φ_q 0][q̈; λ] = [g; γ̄]`, eq. (5),
    /// solved by a [`crate::linalg::SaddlePointSolver`] (sparse-ready).
    #[default]
    Saddle,
    /// λ eliminated, eq. (9): `(Φ_q M⁻¹ Φ_qᵀ) λ = Φ_q M⁻¹ g − γ̄`,
    /// `q̈ = M⁻¹ (g − Φ_qᵀ λ)`. The m × m Schur complement is formed and
    /// Cholesky-factorised densely: O(m³), for small systems and cross-checks.
    Eliminated,
    /// No multipliers: the penalty formulation [`Penalty`] (Bayo, García de
    /// Jalón & Serna 1988), parameters [`PenaltyParams`].
    Penalty,
    /// The index-3 augmented Lagrangian with projections (ALI3-P, Bayo &
    /// Ledesma 1996): [`Augmented`], integrated by
    /// [`crate::integrate::GenAlpha`] (generalized-α, HHT, Newmark and the
    /// trapezoidal rule only).
    AugmentedLagrangian,
    /// Generalized coordinate partitioning ([`Partitioned`], Wehage & Haug
    /// 1982): the independent coordinates integrated, the dependent ones
    /// solved; parameters [`PartitionOptions`].
    Partitioned,
}

from_words!(Formulation, "formulation", "saddle" => Saddle, "eliminated" => Eliminated,
    "penalty" => Penalty, "augmented_lagrangian" => AugmentedLagrangian,
    "partitioned" => Partitioned);

/// Baumgarte parameters (α, β) of eq. (10): `Φ̈ + 2αΦ̇ + β²Φ = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Baumgarte {
    /// Damping parameter α ≥ 0 \[1/s\].
    pub alpha: f64,
    /// Stiffness parameter β ≥ 0 \[1/s\].
    pub beta: f64,
}

impl Default for Baumgarte {
    /// No stabilization (α = β = 0).
    fn default() -> Self {
        Self {
            alpha: 0.0,
            beta: 0.0,
        }
    }
}

/// The parameter rules of the paper (§3) for choosing β from α.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BaumgarteRule {
    /// α and β given explicitly.
    Explicit,
    /// β = α (critically damped response of eq. (10)).
    Equal,
    /// β = α √2.
    AlphaSqrt2,
    /// β = √(2α).
    Sqrt2Alpha,
    /// α = β = 1/h from the integration step h ([`Baumgarte::from_step`]).
    Step,
}

from_words!(BaumgarteRule, "Baumgarte rule", "explicit" => Explicit, "equal" => Equal,
    "alpha_sqrt2" => AlphaSqrt2, "sqrt_2alpha" => Sqrt2Alpha, "step" => Step);

impl BaumgarteRule {
    /// The scenario name: `explicit`, `equal`, `alpha_sqrt2`, `sqrt_2alpha`
    /// or `step`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Explicit => "explicit",
            Self::Equal => "equal",
            Self::AlphaSqrt2 => "alpha_sqrt2",
            Self::Sqrt2Alpha => "sqrt_2alpha",
            Self::Step => "step",
        }
    }
}

impl Baumgarte {
    /// Parameters from a rule: `beta` is used only by
    /// [`BaumgarteRule::Explicit`]; for [`BaumgarteRule::Step`] `alpha` is
    /// the `1/h` of [`Baumgarte::from_step`] (β = α).
    pub fn from_rule(rule: BaumgarteRule, alpha: f64, beta: f64) -> Self {
        let beta = match rule {
            BaumgarteRule::Explicit => beta,
            BaumgarteRule::Equal | BaumgarteRule::Step => alpha,
            BaumgarteRule::AlphaSqrt2 => alpha * std::f64::consts::SQRT_2,
            BaumgarteRule::Sqrt2Alpha => (2.0 * alpha).sqrt(),
        };
        Self { alpha, beta }
    }

    /// The step rule ([`BaumgarteRule::Step`]): `α = β = 1/h`. Eq. (10)
    /// then has the double root `−1/h`: the violation left by one step of
    /// size h decays with time constant h (critically damped), and `h·λ =
    /// −1` lies inside the stability regions of rk4, ode23 and ode45, so
    /// the feedback neither lags the step nor destabilises it
    /// (docs/constraint_methods.md: why this rule, and what was looked up).
    pub fn from_step(h: f64) -> Self {
        Self::from_rule(BaumgarteRule::Step, 1.0 / h, 0.0)
    }

    /// Checks α and β: finite and ≥ 0
    /// ([`FormulationError::InvalidOption`] names the field).
    pub fn validate(&self) -> Result<(), FormulationError> {
        for (option, v) in [("alpha", self.alpha), ("beta", self.beta)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FormulationError::InvalidOption {
                    option,
                    value: v.to_string(),
                    reason: "must be finite and ≥ 0".into(),
                });
            }
        }
        Ok(())
    }

    /// True for α = β = 0.
    pub fn is_off(&self) -> bool {
        self.alpha == 0.0 && self.beta == 0.0
    }
}

/// The state handed to a right-hand side must be finite: else
/// [`FormulationError::Unstable`] naming the component (`q = y[..n]`,
/// `q̇ = y[n..]`).
pub(crate) fn check_state(t: f64, q: &[f64], qd: &[f64]) -> Result<(), FormulationError> {
    match non_finite_state(q, qd) {
        None => Ok(()),
        Some(component) => Err(FormulationError::Unstable { t, component }),
    }
}

/// The name of the first non-finite component of the state `(q, q̇)`
/// (e.g. `phi12` or `dx3/dt`), or `None` when all are finite.
pub(crate) fn non_finite_state(q: &[f64], qd: &[f64]) -> Option<String> {
    let name = crate::model::System::coordinate_name;
    match crate::numeric::first_non_finite(q) {
        Some((k, _)) => Some(name(k)),
        None => crate::numeric::first_non_finite(qd).map(|(k, _)| format!("d{}/dt", name(k))),
    }
}

/// Constraint feedback on the acceleration right-hand side:
/// `γ̄ = γ − c₁ Φ̇ − c₀ Φ` with `Φ̇ = Φ_q q̇ + Φ_t` (`phid` = Φ_q q̇) —
/// Baumgarte's eq. (11) (`c₁ = 2α`, `c₀ = β²`) and the penalty
/// formulation's (`c₁ = 2ξω`, `c₀ = ω²`).
pub(crate) fn feedback(
    gamma: &mut [f64],
    phid: &[f64],
    phi_t: &[f64],
    phi: &[f64],
    c1: f64,
    c0: f64,
) {
    for r in 0..gamma.len() {
        let phidot = phid[r] + phi_t[r];
        gamma[r] -= c1 * phidot + c0 * phi[r];
    }
}

/// The first non-finite entry of the named vectors, as a
/// [`FormulationError::NonFinite`] at time `t` (one pass, no allocation).
pub(crate) fn all_finite(t: f64, parts: &[(&'static str, &[f64])]) -> Result<(), FormulationError> {
    for &(what, v) in parts {
        if let Some((index, value)) = crate::numeric::first_non_finite(v) {
            return Err(FormulationError::NonFinite {
                what,
                index,
                value,
                t,
            });
        }
    }
    Ok(())
}

/// Mass-orthogonal projection onto the constraint manifold after each
/// accepted step of an explicit integrator ([`Index1::project`]): Newton on
/// `Φ(q, t) = 0` with the corrections `Δq = −M⁻¹Φ_qᵀ(Φ_q M⁻¹Φ_qᵀ)⁻¹Φ`,
/// then the velocities onto `Φ_q q̇ = −Φ_t` the same way.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Projection {
    /// Project after each accepted step (off: the run is bit-identical to
    /// one without projection).
    pub enabled: bool,
    /// Newton tolerance on ‖Φ‖∞ (constraint units, m for joints) \[m\].
    pub tol: f64,
    /// Newton iterations allowed per projection (then
    /// [`FormulationError::Projection`]).
    pub max_iter: usize,
    /// Iterate to `tol` ([`Correction::Newton`], default) or take one
    /// correction per step ([`Correction::Direct`]).
    pub correction: Correction,
}

/// How the positions are corrected after a step ([`Projection`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Correction {
    /// Newton on `Φ(q, t) = 0` until `‖Φ‖∞ ≤ tol`.
    #[default]
    Newton,
    /// Direct violation correction (Yu & Chen 2000): one correction
    /// `δq = −M⁻¹Φ_qᵀ(Φ_q M⁻¹Φ_qᵀ)⁻¹Φ` per step, no iteration and no
    /// tolerance — the remaining violation is quadratic in the one
    /// corrected (one Newton step); velocities as for [`Correction::Newton`].
    Direct,
}

from_words!(Correction, "correction", "newton" => Newton, "direct" => Direct);

impl Default for Projection {
    /// Off; tolerance 1e-10, 10 iterations, Newton.
    fn default() -> Self {
        Self {
            enabled: false,
            tol: 1e-10,
            max_iter: 10,
            correction: Correction::Newton,
        }
    }
}

impl Projection {
    /// Checks the tolerance (finite, > 0) and `max_iter` (≥ 1)
    /// ([`FormulationError::InvalidOption`] names the field).
    pub fn validate(&self) -> Result<(), FormulationError> {
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return Err(FormulationError::InvalidOption {
                option: "tol",
                value: self.tol.to_string(),
                reason: "must be finite and > 0".into(),
            });
        }
        if self.max_iter == 0 {
            return Err(FormulationError::InvalidOption {
                option: "max_iter",
                value: "0".into(),
                reason: "must be ≥ 1".into(),
            });
        }
        Ok(())
    }
}

/// A linear-solver failure of an evaluation at `t` as a
/// [`FormulationError::Linear`] (`t` = NaN: before any evaluation).
pub(crate) fn linear_at(t: f64) -> impl Fn(LinalgError) -> FormulationError + Copy {
    move |source| FormulationError::Linear { t, source }
}

/// Failures of a formulation.
#[derive(Debug, Clone, thiserror::Error)]
pub enum FormulationError {
    /// The saddle-point (or Schur) solve failed.
    #[error("at t = {t}: {source}")]
    Linear {
        /// Time of the failing evaluation.
        t: f64,
        /// The linear-algebra failure.
        source: LinalgError,
    },
    /// The state handed to the right-hand side is not finite.
    #[error(
        "at t = {t}: state component {component} is not finite: the integration became \
         unstable (step too large for the system's stiffness, or tolerances too loose)"
    )]
    Unstable {
        /// Time of the evaluation.
        t: f64,
        /// The first non-finite component (e.g. `phi12` or `dx3/dt`).
        component: String,
    },
    /// A quantity of the model evaluation (forces, Φ, Φ_q, γ, force
    /// Jacobians) is not finite: an overflow or an invalid value of the
    /// model at this state, found before it reaches a factorisation (where
    /// it would look like a singular matrix).
    #[error(
        "at t = {t}: {what} is not finite in component {index} ({value}): the model \
         overflows or is undefined at this state (check the magnitudes of the scenario's \
         values: forces, motions, geometry)"
    )]
    NonFinite {
        /// What was evaluated, e.g. `the forces g`.
        what: &'static str,
        /// The first non-finite component.
        index: usize,
        /// Its value.
        value: f64,
        /// Time of the evaluation.
        t: f64,
    },
    /// Invalid parameters.
    #[error("{0}")]
    Invalid(String),
    /// The projection onto the constraint manifold did not converge.
    #[error(
        "at t = {t}: projection onto the constraint manifold did not converge in \
         {iterations} Newton iterations (‖Φ‖∞ = {residual:.3e} > tol {tol:.1e}); the step \
         left the manifold too far (tighten the tolerances) or the position is singular"
    )]
    Projection {
        /// Time of the step.
        t: f64,
        /// ‖Φ‖∞ after the last iteration.
        residual: f64,
        /// The tolerance.
        tol: f64,
        /// Iterations done.
        iterations: usize,
    },
    /// Newton iteration for consistent initial conditions failed.
    #[error("consistent initial conditions: {0}")]
    Initial(String),
    /// An option has an invalid value.
    #[error("invalid option {option} = {value}: {reason}")]
    InvalidOption {
        /// Option name (field of the options struct).
        option: &'static str,
        /// Offending value.
        value: String,
        /// What is required.
        reason: String,
    },
}

impl FormulationError {
    /// The rule of a projection's Newton iteration that has not reached
    /// `tol` at `t` (‖Φ‖ = `residual`) after `iterations`: it gives up at
    /// `max_iter` or at a non-finite residual
    /// ([`FormulationError::Projection`]).
    pub(crate) fn check_projection(
        t: f64,
        residual: f64,
        tol: f64,
        iterations: usize,
        max_iter: usize,
    ) -> Result<(), Self> {
        if iterations == max_iter || !residual.is_finite() {
            return Err(FormulationError::Projection {
                t,
                residual,
                tol,
                iterations,
            });
        }
        Ok(())
    }
}
