//! The parameters of generalized-α, HHT and Newmark from ρ∞ (module docs
//! of [`super`]); the options are [`crate::integrate::ImplicitOptions`].

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
    pub(crate) fn for_method(method: Method, rho_inf: f64) -> Result<Self, IntegratorError> {
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
    pub(crate) fn error_constant(&self) -> f64 {
        self.beta - 0.5 * self.gamma + 1.0 / 12.0
    }
}
