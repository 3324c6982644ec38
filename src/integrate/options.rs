//! Integrator options: one struct per concern, one validator per struct.
//!
//! * [`OdeOptions`]: tolerances, step sizes and the step cap of every
//!   method (MATLAB's `odeset` names); [`OdeOptions::validate`].
//! * [`ImplicitOptions`]: what only the generalized-α family uses
//!   (ρ∞, Newton, projection, adaptivity); [`ImplicitOptions::validate`].
//!
//! Validators return [`IntegratorError::InvalidOption`] (field, value, what
//! is required) or [`IntegratorError::NotApplicable`] (a field set for a
//! method that does not use it); callers that read the options from
//! elsewhere (the scenario loader) map the field to their own key.

use super::genalpha::AlphaParameters;
use super::{Family, IntegratorError, Method, Stepping};
use serde::Serialize;

/// Absolute tolerance: one value for all components or one per component.
#[derive(Debug, Clone)]
pub enum Tolerance {
    /// Same absolute tolerance for every component.
    Scalar(f64),
    /// One absolute tolerance per component (length must equal the system dimension).
    Vector(Vec<f64>),
}

/// Integration options, named and defaulted as MATLAB's `odeset`.
#[derive(Debug, Clone)]
pub struct OdeOptions {
    /// Relative tolerance (`RelTol`), default 1e-3. Values below `100·eps`
    /// are raised to `100·eps` (reported in [`Report::warnings`](super::Report::warnings)).
    pub rtol: f64,
    /// Absolute tolerance (`AbsTol`), default `Scalar(1e-6)`; must be ≥ 0.
    pub atol: Tolerance,
    /// Maximal step (`MaxStep`, step-controlled methods only); `None` => MATLAB default `0.1·|t_end - t0|`.
    /// Always limited to `|t_end - t0|`.
    pub max_step: Option<f64>,
    /// First step to try (`InitialStep`, step-controlled methods only); `None` => MATLAB's automatic choice.
    pub initial_step: Option<f64>,
    /// The one home of a fixed step size (scenario key `integrator.step`):
    /// the step of [`Method::Rk4`] and of the implicit methods without
    /// [`ImplicitOptions::adaptive`] (required there; the last step is
    /// shortened to end exactly on `t_end`). Setting it for a
    /// step-controlled method is an [`IntegratorError::NotApplicable`].
    pub fixed_step: Option<f64>,
    /// Safety cap on accepted steps; reaching it ends the run with
    /// [`Termination::Failed`](super::Termination::Failed). Default 50 000 000.
    pub max_steps: usize,
    /// Highest order of [`Method::Bdf`], 1 … 5 (`ode15s`'s `MaxOrder`;
    /// scenario key `integrator.max_order`). Default 5. BDF3–5 are not
    /// A-stable: lightly damped oscillations in their instability wedge
    /// make the error test cut the step (docs/bdf.md).
    pub max_order: usize,
    /// [`Method::Bdf`] with the numerical differentiation formulas of
    /// `ode15s` (NDF; Shampine & Reichelt 1997) instead of the BDF
    /// (scenario key `integrator.ndf`; MATLAB's `BDF` option the other way
    /// round). Default false.
    pub ndf: bool,
}

impl Default for OdeOptions {
    fn default() -> Self {
        Self {
            rtol: 1e-3,
            atol: Tolerance::Scalar(1e-6),
            max_step: None,
            initial_step: None,
            fixed_step: None,
            max_steps: 50_000_000,
            max_order: 5,
            ndf: false,
        }
    }
}

/// Options of the implicit integrators (scenario keys `integrator.<field>`);
/// their step, tolerances and step limits live in [`OdeOptions`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImplicitOptions {
    /// Spectral radius at infinity ρ∞ ∈ [0, 1] (HHT: [½, 1]): the factor by
    /// which unresolved high-frequency components shrink per step.
    /// Default 0.8.
    pub rho_inf: f64,
    /// Adapt the step to the local error estimate with `rtol`/`atol` of
    /// [`OdeOptions`] (also `max_step`, `max_steps`, `initial_step`):
    /// generalized-α, HHT, Newmark and radau5. Default false.
    pub adaptive: bool,
    /// Newton tolerance on the acceleration corrections `Δq̈ = β' Δq`
    /// (m/s², rad/s²; also bounds the velocity and position corrections),
    /// floored at the rounding noise of q (module docs); Radau IIA
    /// measures a body angle's correction at the body's radius of
    /// gyration `√(I/m)`, in m/s² as the translations'. Unconverged
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
    /// `hmin`). Must not exceed [`OdeOptions::fixed_step`].
    pub min_step: Option<f64>,
    /// Factorise the full unsymmetric iteration matrix with a sparse LU
    /// (exact Newton) instead of a symmetric approximation with the LDLᵀ
    /// saddle-point solver (modified Newton). Read by the caller that builds
    /// the [`SecondOrderDae`](super::SecondOrderDae) (`simulation::simulate`:
    /// [`crate::formulation::NewtonSolverKind`]). Default false.
    pub lu: bool,
    /// Newton predictor of generalized-α and its family: `q̈_{n+1}` chosen
    /// at every step from the history (true): extrapolated linearly from
    /// the last two steps when that would have predicted the last step's
    /// `q̈` better than the constant, else kept constant; or always kept
    /// constant (false, as `λ_{n+1}` always is; Arnold & Brüls 2007).
    /// Off by default: it saves Newton corrections but renews the matrix
    /// at the predictor more often, which cost more CPU time than it saved
    /// on the stiff chain and problem C (docs/scaling.md, "Measurements
    /// behind the defaults").
    pub extrapolate: bool,
    /// Radau IIA with a fixed step `h`: a larger step `H = k h` (k an
    /// integer ≥ 2) taken from a grid point when no force element
    /// foresees an onset (a contact's start, or one running) within
    /// [`FLIGHT_LOOKAHEAD`](super::FLIGHT_LOOKAHEAD) `H` of it
    /// ([`crate::model::ForceElement::onset_within`]), ending on the grid
    /// of `h`: the contact-free flight of a body between walls at the
    /// larger step, its contacts at `h` (docs/scenarios.md). `None`
    /// (default): every step is `h`.
    pub flight_step: Option<f64>,
}

impl Default for ImplicitOptions {
    fn default() -> Self {
        Self {
            rho_inf: 0.8,
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
            flight_step: None,
        }
    }
}

fn invalid(option: &'static str, value: impl std::fmt::Display, reason: &str) -> IntegratorError {
    IntegratorError::InvalidOption {
        option,
        value: value.to_string(),
        reason: reason.to_string(),
    }
}

fn not_applicable(option: &'static str, method: Method, reason: &str) -> IntegratorError {
    IntegratorError::NotApplicable {
        option,
        method: method.name(),
        reason: reason.to_string(),
    }
}

/// `Some(h)` must be positive and finite.
fn check_positive(option: &'static str, v: Option<f64>) -> Result<(), IntegratorError> {
    match v {
        Some(h) if !(h > 0.0 && h.is_finite()) => {
            Err(invalid(option, h, "must be positive and finite"))
        }
        _ => Ok(()),
    }
}

impl Tolerance {
    /// Every component non-negative and finite.
    fn validate(&self) -> Result<(), IntegratorError> {
        match self {
            Tolerance::Scalar(a) if !(*a >= 0.0 && a.is_finite()) => {
                Err(invalid("atol", a, "must be non-negative and finite"))
            }
            Tolerance::Vector(v) => match v
                .iter()
                .enumerate()
                .find(|(_, a)| !(**a >= 0.0 && a.is_finite()))
            {
                Some((i, a)) => Err(IntegratorError::InvalidOption {
                    option: "atol",
                    value: format!("{a} (component {i})"),
                    reason: "every component must be non-negative and finite".into(),
                }),
                None => Ok(()),
            },
            Tolerance::Scalar(_) => Ok(()),
        }
    }
}

impl OdeOptions {
    /// Checks the options for `method` (`adaptive`: the implicit methods'
    /// [`ImplicitOptions::adaptive`], ignored by the explicit methods):
    /// `max_steps ≥ 1`; for step-controlled runs (ode23, ode45, adaptive
    /// implicit) `rtol > 0`, `atol ≥ 0`, `max_step > 0`, `initial_step > 0`
    /// and no `fixed_step`; for fixed-step runs (rk4, implicit without
    /// `adaptive`) a positive, finite `fixed_step` and neither `max_step`
    /// nor `initial_step`. (`rtol`/`atol` always have values, so their
    /// presence under a fixed-step method cannot be detected here.)
    /// `max_order` in 1 … 5 and `ndf` only for [`Method::Bdf`] (elsewhere
    /// they must keep their defaults).
    pub fn validate(&self, method: Method, adaptive: bool) -> Result<(), IntegratorError> {
        if self.max_steps == 0 {
            return Err(invalid("max_steps", 0, "must be at least 1"));
        }
        let d = Self::default();
        if method.info().key_use("max_order").is_some() {
            if !(1..=5).contains(&self.max_order) {
                return Err(invalid(
                    "max_order",
                    self.max_order,
                    "must be 1, 2, 3, 4 or 5 (the highest BDF/NDF order)",
                ));
            }
        } else if self.max_order != d.max_order || self.ndf != d.ndf {
            let option = if self.max_order != d.max_order {
                "max_order"
            } else {
                "ndf"
            };
            return Err(not_applicable(
                option,
                method,
                &format!(
                    "only {} has an order cap and the NDF variant",
                    super::methods_taking(option)
                ),
            ));
        }
        let step_controlled = match method.info().stepping {
            Stepping::Adaptive => true,
            Stepping::Fixed => false,
            Stepping::FixedOrAdaptive => adaptive,
        };
        if step_controlled {
            if !(self.rtol > 0.0 && self.rtol.is_finite()) {
                return Err(invalid("rtol", self.rtol, "must be positive and finite"));
            }
            self.atol.validate()?;
            if let Some(h) = self.max_step {
                if h.is_nan() || h <= 0.0 {
                    return Err(invalid("max_step", h, "must be positive"));
                }
            }
            check_positive("initial_step", self.initial_step)?;
            if self.fixed_step.is_some() {
                return Err(not_applicable(
                    "fixed_step",
                    method,
                    "the step size is controlled by rtol/atol (use initial_step for the first step)",
                ));
            }
        } else {
            let need = if method.info().stepping == Stepping::Fixed {
                format!("{} requires a positive, finite fixed_step", method.name())
            } else {
                format!(
                    "{} with a fixed step needs a positive, finite fixed_step (or adaptive = true)",
                    method.name()
                )
            };
            match self.fixed_step {
                None => return Err(invalid("fixed_step", "None", &need)),
                Some(h) if !(h > 0.0 && h.is_finite()) => {
                    return Err(invalid("fixed_step", h, &need))
                }
                Some(_) => {}
            }
            for (option, v) in [
                ("max_step", self.max_step),
                ("initial_step", self.initial_step),
            ] {
                if v.is_some() {
                    return Err(not_applicable(
                        option,
                        method,
                        "the method takes a fixed step",
                    ));
                }
            }
        }
        Ok(())
    }
}

impl ImplicitOptions {
    /// Checks the options for `method` with the fixed step `fixed_step`
    /// ([`OdeOptions::fixed_step`]): every field that the method's row of
    /// [`super::METHODS`] does not list must keep its default
    /// ([`IntegratorError::NotApplicable`] names the first that does not);
    /// for the index-3 methods `newton_tol > 0`, `max_newton ≥ 1`,
    /// `min_step > 0`, for the generalized-α family also ρ∞ in the
    /// method's range (`AlphaParameters::for_method`) and, with a fixed
    /// step, `min_step` not above it.
    pub fn validate(&self, method: Method, fixed_step: Option<f64>) -> Result<(), IntegratorError> {
        // the fields the method's row of the method table reads (adaptive
        // or not: filter_error with a fixed step is the scenario loader's
        // concern)
        let row = method.info();
        if let Some(option) = self.first_non_default_where(|f| row.key_use(f).is_none()) {
            let reads: Vec<&str> = Self::FIELDS
                .iter()
                .copied()
                .filter(|f| row.key_use(f).is_some())
                .collect();
            let reason = if reads.is_empty() {
                format!("only {} use it", super::methods_taking(option))
            } else {
                format!("{} reads {} only", method.name(), reads.join(", "))
            };
            return Err(not_applicable(option, method, &reason));
        }
        if !method.is_index3() {
            return Ok(());
        }
        if method.family() == Family::GeneralizedAlpha {
            AlphaParameters::for_method(method, self.rho_inf)?;
        }
        if !(self.newton_tol > 0.0 && self.newton_tol.is_finite()) {
            return Err(invalid(
                "newton_tol",
                self.newton_tol,
                "must be positive and finite",
            ));
        }
        if self.max_newton == 0 {
            return Err(invalid("max_newton", 0, "must be at least 1"));
        }
        check_positive("min_step", self.min_step)?;
        if let (Some(big), true) = (self.flight_step, self.adaptive) {
            return Err(invalid("flight_step", big, "applies to fixed steps only"));
        }
        if let (Some(big), Some(h)) = (self.flight_step, fixed_step) {
            let k = (big / h).round();
            if !(big.is_finite() && k >= 2.0 && (big - k * h).abs() <= 1e-9 * big) {
                return Err(invalid(
                    "flight_step",
                    big,
                    &format!("must be an integer multiple (2 or more) of the fixed step {h}"),
                ));
            }
        }
        if method.family() != Family::GeneralizedAlpha {
            return Ok(());
        }
        if let (Some(hmin), Some(h), false) = (self.min_step, fixed_step, self.adaptive) {
            if hmin > h {
                return Err(invalid(
                    "min_step",
                    hmin,
                    &format!("must not exceed the fixed step {h}"),
                ));
            }
        }
        Ok(())
    }

    /// The scenario keys of the fields, in declaration order.
    const FIELDS: [&'static str; 12] = [
        "rho_inf",
        "adaptive",
        "newton_tol",
        "max_newton",
        "project",
        "reuse",
        "filter_error",
        "check_constraints",
        "min_step",
        "lu",
        "extrapolate",
        "flight_step",
    ];

    /// The first field (in declaration order) with `filter(field)` whose
    /// value differs from [`ImplicitOptions::default`].
    fn first_non_default_where(&self, filter: impl Fn(&str) -> bool) -> Option<&'static str> {
        let d = Self::default();
        [
            self.rho_inf != d.rho_inf,
            self.adaptive != d.adaptive,
            self.newton_tol != d.newton_tol,
            self.max_newton != d.max_newton,
            self.project != d.project,
            self.reuse != d.reuse,
            self.filter_error != d.filter_error,
            self.check_constraints != d.check_constraints,
            self.min_step != d.min_step,
            self.lu != d.lu,
            self.extrapolate != d.extrapolate,
            self.flight_step != d.flight_step,
        ]
        .into_iter()
        .zip(Self::FIELDS)
        .find(|(differs, f)| *differs && filter(f))
        .map(|(_, f)| f)
    }
}
