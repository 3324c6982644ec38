//! Prescribed functions of time for driving constraints and applied loads.

use std::fmt;
use std::sync::Arc;

/// A function of time with its first two derivatives, as driving constraints
/// need them (Φ_t and Φ_tt enter γ).
#[derive(Clone)]
pub enum TimeFunction {
    /// `c`.
    Constant(f64),
    /// `Σ c_k t^k` (coefficients from the constant term up).
    Polynomial(Vec<f64>),
    /// `offset + amplitude · sin(ω t + phase)`.
    Harmonic {
        /// Amplitude.
        amplitude: f64,
        /// Angular frequency ω \[rad/s\].
        omega: f64,
        /// Phase \[rad\].
        phase: f64,
        /// Constant offset.
        offset: f64,
    },
    /// A user function returning `[f(t), f'(t), f''(t)]`.
    Custom(Arc<dyn Fn(f64) -> [f64; 3] + Send + Sync>),
}

impl fmt::Debug for TimeFunction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Constant(c) => write!(f, "Constant({c})"),
            Self::Polynomial(c) => write!(f, "Polynomial({c:?})"),
            Self::Harmonic {
                amplitude,
                omega,
                phase,
                offset,
            } => write!(
                f,
                "Harmonic {{ amplitude: {amplitude}, omega: {omega}, phase: {phase}, offset: {offset} }}"
            ),
            Self::Custom(_) => write!(f, "Custom(..)"),
        }
    }
}

impl TimeFunction {
    /// `[f(t), f'(t), f''(t)]`.
    pub fn eval(&self, t: f64) -> [f64; 3] {
        match self {
            Self::Constant(c) => [*c, 0.0, 0.0],
            Self::Polynomial(c) => {
                // Horner for the value and both derivatives.
                let (mut p, mut dp, mut ddp) = (0.0, 0.0, 0.0);
                for &ck in c.iter().rev() {
                    ddp = ddp * t + 2.0 * dp;
                    dp = dp * t + p;
                    p = p * t + ck;
                }
                [p, dp, ddp]
            }
            Self::Harmonic {
                amplitude,
                omega,
                phase,
                offset,
            } => {
                let (s, c) = (omega * t + phase).sin_cos();
                [
                    offset + amplitude * s,
                    amplitude * omega * c,
                    -amplitude * omega * omega * s,
                ]
            }
            Self::Custom(f) => f(t),
        }
    }

    /// `f(t)`.
    pub fn value(&self, t: f64) -> f64 {
        self.eval(t)[0]
    }

    /// True when the function does not depend on time.
    pub fn is_constant(&self) -> bool {
        match self {
            Self::Constant(_) => true,
            Self::Polynomial(c) => c.iter().skip(1).all(|&x| x == 0.0),
            Self::Harmonic {
                amplitude, omega, ..
            } => *amplitude == 0.0 || *omega == 0.0,
            Self::Custom(_) => false,
        }
    }

    /// All parameters finite (custom functions are trusted).
    pub fn is_finite(&self) -> bool {
        match self {
            Self::Constant(c) => c.is_finite(),
            Self::Polynomial(c) => c.iter().all(|x| x.is_finite()),
            Self::Harmonic {
                amplitude,
                omega,
                phase,
                offset,
            } => [amplitude, omega, phase, offset]
                .iter()
                .all(|x| x.is_finite()),
            Self::Custom(_) => true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_finite_differences() {
        let fs = [
            TimeFunction::Polynomial(vec![0.3, -1.0, 2.0, 0.5]),
            TimeFunction::Harmonic {
                amplitude: 0.7,
                omega: 3.0,
                phase: 0.2,
                offset: 1.0,
            },
        ];
        for f in &fs {
            let t = 0.37;
            let h = 1e-4;
            let [_, d1, d2] = f.eval(t);
            let fd1 = (f.value(t + h) - f.value(t - h)) / (2.0 * h);
            let fd2 = (f.value(t + h) - 2.0 * f.value(t) + f.value(t - h)) / (h * h);
            assert!((d1 - fd1).abs() < 1e-7, "{f:?}");
            assert!((d2 - fd2).abs() < 1e-5, "{f:?}");
        }
    }
}
