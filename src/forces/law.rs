//! Scalar force laws `f(x)` shared by the force elements: linear or
//! tabulated (piecewise linear), with slope and exact integral.

use crate::model::ModelError;

/// A scalar law `f(x)` (force of a deflection, force of a velocity, torque
/// of an angle, …).
///
/// Tabulated laws interpolate piecewise linearly between the points and
/// extrapolate linearly with the end segments' slopes. Piecewise linear is
/// chosen over monotone cubic interpolation because it preserves monotonicity
/// of the data exactly, its slope is bounded by the largest segment slope
/// (Newton's iteration matrix never sees an overshooting derivative), and its
/// integral (the potential energy) is exact in closed form; the price is a
/// slope that jumps at the knots, which the step-size control of the
/// integrators handles like any kink.
#[derive(Debug, Clone, PartialEq)]
pub enum Law {
    /// `f(x) = slope · x`.
    Linear(f64),
    /// Piecewise linear through the points `(x[i], f[i])`, `x` strictly
    /// increasing, at least two points.
    Table {
        /// Abscissae, strictly increasing.
        x: Vec<f64>,
        /// Values at the abscissae.
        f: Vec<f64>,
    },
}

impl Law {
    /// Segment index `i` such that `x` is interpolated on `[x[i], x[i+1]]`
    /// (end segments extended).
    fn segment(xs: &[f64], x: f64) -> usize {
        // first knot strictly greater than x, minus one, clamped to a segment
        let p = xs.partition_point(|&k| k <= x);
        p.saturating_sub(1).min(xs.len() - 2)
    }

    /// `f(x)`.
    pub fn value(&self, x: f64) -> f64 {
        match self {
            Law::Linear(k) => k * x,
            Law::Table { x: xs, f } => {
                let i = Self::segment(xs, x);
                let s = (f[i + 1] - f[i]) / (xs[i + 1] - xs[i]);
                f[i] + s * (x - xs[i])
            }
        }
    }

    /// `f'(x)` (on a knot: the slope of the segment to its right).
    pub fn slope(&self, x: f64) -> f64 {
        match self {
            Law::Linear(k) => *k,
            Law::Table { x: xs, f } => {
                let i = Self::segment(xs, x);
                (f[i + 1] - f[i]) / (xs[i + 1] - xs[i])
            }
        }
    }

    /// `∫₀ˣ f(s) ds`, exact (trapezoids of the piecewise-linear law): the
    /// potential energy of an elastic law.
    pub fn integral(&self, x: f64) -> f64 {
        match self {
            Law::Linear(k) => 0.5 * k * x * x,
            Law::Table { .. } => self.integral_from_zero_knotwise(x),
        }
    }

    /// `F(x) − F(0)` with `F` the antiderivative summed over the segments.
    fn integral_from_zero_knotwise(&self, x: f64) -> f64 {
        self.antiderivative(x) - self.antiderivative(0.0)
    }

    /// An antiderivative of the tabulated law, zero at `x[0]`.
    fn antiderivative(&self, x: f64) -> f64 {
        let Law::Table { x: xs, f } = self else {
            unreachable!("only tables are integrated knotwise")
        };
        let i = Self::segment(xs, x);
        // whole segments left of segment i
        let mut sum = 0.0;
        for j in 0..i {
            sum += 0.5 * (f[j] + f[j + 1]) * (xs[j + 1] - xs[j]);
        }
        // from x[i] to x (may be negative, or beyond the last knot)
        let fx = self.value(x);
        sum + 0.5 * (f[i] + fx) * (x - xs[i])
    }

    /// Check the law: finite numbers, a table of ≥ 2 points with the same
    /// number of values and strictly increasing abscissae; with `monotone`,
    /// `f` non-decreasing (a law that must store or dissipate energy, e.g. a
    /// spring's force–deflection or a damper's force–velocity law, whose
    /// force opposes the motion). `element`/`field` name the law in errors.
    pub fn validate(&self, element: &str, field: &str, monotone: bool) -> Result<(), ModelError> {
        let bad = |sub: &str, value: String, why: &str| ModelError::InvalidParameter {
            element: element.to_string(),
            field: format!("{field}{sub}"),
            value,
            why: why.to_string(),
        };
        match self {
            Law::Linear(k) => {
                if !k.is_finite() {
                    return Err(bad("", k.to_string(), "slope must be finite"));
                }
                if monotone && *k < 0.0 {
                    return Err(bad("", k.to_string(), "slope must be >= 0"));
                }
            }
            Law::Table { x, f } => {
                if x.len() < 2 {
                    return Err(bad(
                        ".x",
                        format!("{x:?}"),
                        "a table needs at least two points",
                    ));
                }
                if x.len() != f.len() {
                    return Err(bad(
                        ".f",
                        format!("{f:?}"),
                        &format!("needs as many values as abscissae ({})", x.len()),
                    ));
                }
                for (name, v) in [("x", x), ("f", f)] {
                    if let Some(i) = v.iter().position(|v| !v.is_finite()) {
                        return Err(bad(
                            &format!(".{name}[{i}]"),
                            v[i].to_string(),
                            "must be finite",
                        ));
                    }
                }
                // entry i of `v` (`name`) against its predecessor
                let step = |name: &str, v: &[f64], i: usize, rule: &str| {
                    let before = format!("{rule} ({name}[{}] = {})", i - 1, v[i - 1]);
                    bad(&format!(".{name}[{i}]"), v[i].to_string(), &before)
                };
                for i in 1..x.len() {
                    if x[i] <= x[i - 1] {
                        return Err(step("x", x, i, "abscissae must increase strictly"));
                    }
                    if monotone && f[i] < f[i - 1] {
                        return Err(step("f", f, i, "the law must be non-decreasing"));
                    }
                }
            }
        }
        Ok(())
    }
}
