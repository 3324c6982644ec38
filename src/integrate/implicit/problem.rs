//! The one problem of the implicit (index-3) schemes: the constrained
//! second-order DAE `M q̈ + Φ_qᵀ λ = g(q, q̇, t)`, `Φ(q, t) = 0`
//! ([`SecondOrderDae`]), with the augmented Lagrangian's multiplier
//! iteration as an optional hook ([`MultiplierUpdate`]).

use super::super::SystemError;
pub use crate::model::StateView;

/// What an evaluation of a [`SecondOrderDae`] returns: nothing, or the
/// system's typed failure.
pub type DaeResult = Result<(), SystemError>;

/// A constrained second-order system `M q̈ + Φ_qᵀ λ = g(q, q̇, t)`,
/// `Φ(q, t) = 0` with a diagonal mass matrix, as the implicit integrators
/// see it (implemented for multibody systems by
/// [`crate::formulation::Index3`]).
///
/// With a [`MultiplierUpdate`] ([`SecondOrderDae::multiplier_update`],
/// the augmented Lagrangian of [`crate::formulation::Augmented`]) the
/// multipliers are no unknowns of the Newton system: `residual` writes
/// and `solve` solves the n rows of the coordinates only, and λ is the
/// iterated λ* of the hook.
///
/// Every method returns `Err` with the system's typed error
/// ([`SystemError`]) on failure (non-finite values, a
/// singular matrix); the integrator then cuts the step or stops.
pub trait SecondOrderDae {
    /// Number of coordinates n.
    fn n(&self) -> usize;
    /// Number of constraint equations m.
    fn m(&self) -> usize;
    /// Diagonal of M.
    fn mass_diagonal(&self) -> &[f64];
    /// The length \[m\] at which Radau IIA's Newton test measures each
    /// coordinate's correction against `newton_tol` (m/s²): 1 for a
    /// translation and a controller state, a body angle's radius of
    /// gyration `ρ = √(I/m)` (m/rad), so that an angular acceleration
    /// correction `Δφ̈` counts as `ρ Δφ̈`, the root-mean-square acceleration
    /// correction it gives the body's mass (`I Δφ̈² = m (ρ Δφ̈)²`). `None`
    /// (the default): 1 for every coordinate.
    fn correction_lengths(&self) -> Option<&[f64]> {
        None
    }
    /// Consistent accelerations and multipliers at `x = (t, q, q̇)`:
    /// `M q̈ + Φ_qᵀ λ = g`, `Φ_q q̈ = γ`.
    fn accelerations(&mut self, x: StateView<'_>, qdd: &mut [f64], lam: &mut [f64]) -> DaeResult;
    /// Scaled residual at `x` with the accelerations `qdd` and multipliers
    /// `lambda`: `r[..n] = scale (M q̈ + Φ_qᵀ λ − g)`, `r[n..] = Φ(q, t)`.
    fn residual(
        &mut self,
        x: StateView<'_>,
        qdd: &[f64],
        lambda: &[f64],
        scale: f64,
        r: &mut [f64],
    ) -> Result<(), SystemError>;
    /// Φ(q, t) into `phi`.
    fn constraints(&mut self, t: f64, q: &[f64], phi: &mut [f64]);
    /// Assemble and factorise the iteration matrix
    /// `[c₀ M + c₁ C_t + c₂ K_t, Φ_qᵀ; Φ_q, 0]` at `x = (t, q, q̇)` and `λ` with
    /// `C_t = −∂g/∂q̇`, `K_t = −∂g/∂q + (Φ_qᵀ λ)_q` (or an approximation
    /// of them, e.g. [`crate::formulation::Index3`]'s reciprocal part of
    /// unsymmetric force Jacobians).
    fn factorize(&mut self, x: StateView<'_>, lambda: &[f64], c: [f64; 3]) -> DaeResult;
    /// Overwrite `rhs` (length n + m) with the solution of the last factorised matrix.
    fn solve(&mut self, t: f64, rhs: &mut [f64]) -> Result<(), SystemError>;
    /// Project `(q, q̇)` onto `Φ = 0`, `Φ_q q̇ + Φ_t = 0`.
    fn project(&mut self, t: f64, q: &mut [f64], qd: &mut [f64]) -> Result<(), SystemError>;
    /// Project the positions `q` of an interpolated output row at `t` onto
    /// `Φ(q, t) = 0` without touching the Newton matrix or its
    /// factorisation, so the steps that follow are the same bits;
    /// `Ok(false)` (the default) when this system cannot. On `Err` and on
    /// `Ok(false)` the row is left as interpolated.
    fn project_output(&mut self, t: f64, q: &mut [f64]) -> Result<bool, SystemError> {
        let _ = (t, q);
        Ok(false)
    }
    /// The earliest time from `x` to the onset of a force (a contact's
    /// start) within `horizon` \[s\] that the system foresees
    /// ([`crate::model::ForceElement::onset_within`]); `Some(0.0)` while one
    /// is on; `None` (the default) when none lies within `horizon`.
    fn onset_within(&mut self, x: StateView<'_>, horizon: f64) -> Option<f64> {
        let _ = (x, horizon);
        None
    }
    /// The augmented Lagrangian's multiplier iteration, if this system is
    /// one ([`MultiplierUpdate`]); `None` (the default): the multipliers
    /// are unknowns of the Newton system.
    fn multiplier_update(&mut self) -> Option<&mut dyn MultiplierUpdate> {
        None
    }
}

/// The augmented Lagrangian's side of a [`SecondOrderDae`] (Bayo &
/// Ledesma, Nonlinear Dyn. 9 (1996) 113–130; the scheme in the module docs
/// of `integrate::genalpha`, "Augmented Lagrangian"): the residual carries
/// the constraint forces as `Φ_qᵀ(αΦ + λ*)`, the Newton matrix
/// `W = c₀ M + c₁ C + c₂ (K + Φ_qᵀαΦ_q)` has no constraint rows, and the
/// multipliers are iterated, `λ*_{i+1} = λ*_i + αΦ(q_{i+1})`, after every
/// Newton correction; each accepted step ends with the mass-orthogonal
/// projections of q̇ and q̈.
pub trait MultiplierUpdate {
    /// The Newton scale `s = β h²` of the step about to be attempted (the
    /// default penalty follows it; this also undoes
    /// [`MultiplierUpdate::scale_penalty`]).
    fn set_step_scale(&mut self, s: f64);
    /// Multiply the penalty α by `factor` for the rest of the attempt: the
    /// integrator's answer to a slowly contracting multiplier iteration.
    fn scale_penalty(&mut self, factor: f64);
    /// The multiplier update `λ* += αΦ(q, t)`.
    fn update_multipliers(&mut self, t: f64, q: &[f64], lam: &mut [f64])
        -> Result<(), SystemError>;
    /// Project `q̇` (`W Δ = −s Φ_qᵀα(Φ_q q̇ + Φ_t)`) and then `q̈`
    /// (`W Δ = −s Φ_qᵀα(Φ_q q̈ − γ)`, γ at the projected q̇) with the last
    /// factorisation of `W`.
    fn project_motion(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &mut [f64],
        qdd: &mut [f64],
        s: f64,
    ) -> Result<(), SystemError>;
}
