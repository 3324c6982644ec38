//! Rheonomic driving constraints: a coordinate or a relative angle
//! prescribed as a function of time.

use super::{angle, check_bodies, Constraint};
use crate::model::{BodyRef, ModelError, TimeFunction};

/// One body coordinate follows a prescribed function:
/// `Φ = q_k − f(t)`, so `Φ_t = −f'(t)` and `γ = f''(t)`.
#[derive(Debug, Clone)]
pub struct DriveCoordinate {
    /// Name used in messages.
    pub name: String,
    /// Body index.
    pub body: usize,
    /// 0 = x, 1 = y, 2 = φ.
    pub coordinate: usize,
    /// Prescribed motion.
    pub f: TimeFunction,
}

impl DriveCoordinate {
    /// Drive coordinate `coordinate` (0 = x, 1 = y, 2 = φ) of `body` along `f`.
    pub fn new(name: impl Into<String>, body: usize, coordinate: usize, f: TimeFunction) -> Self {
        Self {
            name: name.into(),
            body,
            coordinate,
            f,
        }
    }
    fn index(&self) -> usize {
        3 * self.body + self.coordinate
    }
}

impl Drive for DriveCoordinate {
    fn label(&self) -> String {
        format!("coordinate drive '{}'", self.name)
    }
    fn unit(&self) -> &'static str {
        if self.coordinate == 2 {
            "N m"
        } else {
            "N"
        }
    }
    fn driven_bodies(&self) -> Vec<BodyRef> {
        vec![BodyRef::Body(self.body)]
    }
    fn pattern(&self) -> Vec<(usize, usize)> {
        vec![(0, self.index())]
    }
    fn driven(&self, q: &[f64]) -> f64 {
        q[self.index()]
    }
    fn coefficients(&self, vals: &mut [f64]) {
        vals[0] = 1.0;
    }
    fn motion(&self) -> &TimeFunction {
        &self.f
    }
    fn check(&self) -> Result<(), ModelError> {
        if self.coordinate > 2 {
            return Err(ModelError::InvalidParameter {
                element: self.label(),
                field: "coordinate".into(),
                value: self.coordinate.to_string(),
                why: "must be 0 (x), 1 (y) or 2 (phi)".into(),
            });
        }
        Ok(())
    }
}

/// The angle of body j relative to body i follows a prescribed function:
/// `Φ = φ_j − φ_i − f(t)` (the ground's angle is 0).
#[derive(Debug, Clone)]
pub struct DriveRelativeAngle {
    /// Name used in messages.
    pub name: String,
    /// Reference body.
    pub body_i: BodyRef,
    /// Driven body.
    pub body_j: BodyRef,
    /// Prescribed relative angle \[rad\].
    pub f: TimeFunction,
}

impl DriveRelativeAngle {
    /// Drive `φ_j − φ_i` along `f`.
    pub fn new(name: impl Into<String>, body_i: BodyRef, body_j: BodyRef, f: TimeFunction) -> Self {
        Self {
            name: name.into(),
            body_i,
            body_j,
            f,
        }
    }
}

impl Drive for DriveRelativeAngle {
    fn label(&self) -> String {
        format!("relative-angle drive '{}'", self.name)
    }
    fn unit(&self) -> &'static str {
        "N m"
    }
    fn driven_bodies(&self) -> Vec<BodyRef> {
        vec![self.body_i, self.body_j]
    }
    fn pattern(&self) -> Vec<(usize, usize)> {
        [self.body_i, self.body_j]
            .iter()
            .filter_map(|b| b.offset().map(|o| (0, o + 2)))
            .collect()
    }
    fn driven(&self, q: &[f64]) -> f64 {
        angle(q, self.body_j) - angle(q, self.body_i)
    }
    fn coefficients(&self, vals: &mut [f64]) {
        let mut k = 0;
        for (b, v) in [(self.body_i, -1.0), (self.body_j, 1.0)] {
            if b != BodyRef::Ground {
                vals[k] = v;
                k += 1;
            }
        }
    }
    fn motion(&self) -> &TimeFunction {
        &self.f
    }
}

/// A drive `Φ = a(q) − f(t)` with `a` linear in q (constant
/// coefficients): Φ_q is constant, `Φ_t = −f′(t)`, `γ = f″(t)` and
/// `(Φ_qᵀλ)_q = 0`. Each drive supplies `a` and its coefficients; the
/// rest of [`Constraint`] is the one impl below.
pub(crate) trait Drive: Send + Sync + std::fmt::Debug {
    /// Description used in messages ([`Constraint::name`]).
    fn label(&self) -> String;
    /// Unit of the drive's generalized force ([`Constraint::drive_unit`]).
    fn unit(&self) -> &'static str;
    /// The bodies it connects ([`Constraint::bodies`]).
    fn driven_bodies(&self) -> Vec<BodyRef>;
    /// Structural non-zeros of Φ_q ([`Constraint::jacobian_pattern`]).
    fn pattern(&self) -> Vec<(usize, usize)>;
    /// `a(q)`, the driven coordinate or combination of coordinates.
    fn driven(&self, q: &[f64]) -> f64;
    /// The constant values of Φ_q in pattern order.
    fn coefficients(&self, vals: &mut [f64]);
    /// The prescribed motion f(t).
    fn motion(&self) -> &TimeFunction;
    /// Checks of the drive's own parameters (before the body references).
    fn check(&self) -> Result<(), ModelError> {
        Ok(())
    }
}

impl<D: Drive> Constraint for D {
    fn name(&self) -> String {
        self.label()
    }
    fn drive_unit(&self) -> Option<&'static str> {
        Some(self.unit())
    }
    fn n_eq(&self) -> usize {
        1
    }
    fn bodies(&self) -> Vec<BodyRef> {
        self.driven_bodies()
    }
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        self.pattern()
    }
    fn phi(&self, q: &[f64], t: f64, out: &mut [f64]) {
        out[0] = self.driven(q) - self.motion().value(t);
    }
    fn jacobian(&self, _q: &[f64], _t: f64, vals: &mut [f64]) {
        self.coefficients(vals);
    }
    fn phi_t(&self, _q: &[f64], t: f64, out: &mut [f64]) {
        out[0] = -self.motion().eval(t)[1];
    }
    fn gamma(&self, _q: &[f64], _qd: &[f64], t: f64, out: &mut [f64]) {
        out[0] = self.motion().eval(t)[2];
    }
    fn hessian_pattern(&self) -> Vec<(usize, usize)> {
        Vec::new()
    }
    fn add_hessian(
        &self,
        _q: &[f64],
        _t: f64,
        _lambda: &[f64],
        _vals: &mut [f64],
        _ws: &mut crate::model::FdWorkspace,
    ) {
    }
    fn validate(&self, n_bodies: usize) -> Result<(), ModelError> {
        self.check()?;
        check_bodies(&self.label(), &self.driven_bodies(), n_bodies)
    }
}

/// A motion written as an expression of `t` \[s\] (the language of
/// docs/expressions.md), with its first and second time derivatives from
/// the symbolic engine, compiled into one allocation-free tape. The only
/// variable is `t`; any other name is a parse error.
pub fn expression_motion(text: &str) -> Result<TimeFunction, mbsolve_codegen::ParseError> {
    use mbsolve_codegen::{parse, Ctx, Tape};
    let mut ctx = Ctx::new();
    let t = ctx.var("t");
    ctx.set_time(t);
    let f = parse(&mut ctx, text, |n, _| (n == "t").then_some(t))?;
    let d1 = ctx.diff(f, t);
    let d2 = ctx.diff(d1, t);
    let tape = std::sync::Mutex::new(Tape::new(&ctx, &[f, d1, d2]));
    Ok(TimeFunction::Custom(std::sync::Arc::new(move |t| {
        let mut out = [0.0; 3];
        tape.lock()
            .unwrap_or_else(|e| e.into_inner())
            .eval(&[t], &mut out);
        out
    })))
}

/// How a tabulated motion ([`spline_motion`]) passes through its points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spline {
    /// Natural cubic spline (second derivative 0 at the end points):
    /// position, velocity and acceleration continuous.
    Cubic,
    /// Straight segments: the velocity jumps at the points, the
    /// acceleration is 0 between them.
    Linear,
}

/// A motion through the points `(ts[i], values[i])` (at least 2, `ts`
/// strictly increasing, all finite), with exact first and second
/// derivatives of the interpolant. Beyond the ends it continues along the
/// tangent line at the end point (for [`Spline::Cubic`] the natural end
/// condition makes that C²). Natural cubic spline: the moments `M_i = s''(t_i)`
/// solve the tridiagonal system
/// `h_{i−1} M_{i−1} + 2 (h_{i−1} + h_i) M_i + h_i M_{i+1} = 6 (Δ_i − Δ_{i−1})`,
/// `M_0 = M_n = 0` (`Δ_i` the slope of segment i; de Boor, *A Practical
/// Guide to Splines*, ch. IV). Errors: a message naming the entry.
pub fn spline_motion(ts: &[f64], values: &[f64], kind: Spline) -> Result<TimeFunction, String> {
    let n = ts.len();
    if n < 2 {
        return Err(format!(
            "a tabulated motion needs at least 2 points, got {n}"
        ));
    }
    if values.len() != n {
        return Err(format!("{} values for {n} times", values.len()));
    }
    if let Some(v) = ts.iter().chain(values).find(|v| !v.is_finite()) {
        return Err(format!("the entry {v} is not finite"));
    }
    if let Some(k) = (1..n).find(|&k| ts[k] <= ts[k - 1]) {
        return Err(format!(
            "the times must increase strictly (t[{}] = {} is followed by t[{k}] = {})",
            k - 1,
            ts[k - 1],
            ts[k]
        ));
    }
    let (ts, ys) = (ts.to_vec(), values.to_vec());
    let mut m = vec![0.0; n];
    if kind == Spline::Cubic && n > 2 {
        // Thomas algorithm on the interior moments M_1 … M_{n−2}.
        let h: Vec<f64> = ts.windows(2).map(|w| w[1] - w[0]).collect();
        let slope: Vec<f64> = (0..n - 1).map(|i| (ys[i + 1] - ys[i]) / h[i]).collect();
        let k = n - 2;
        let (mut diag, mut rhs) = (vec![0.0; k], vec![0.0; k]);
        for j in 0..k {
            diag[j] = 2.0 * (h[j] + h[j + 1]);
            rhs[j] = 6.0 * (slope[j + 1] - slope[j]);
            if j > 0 {
                let w = h[j] / diag[j - 1];
                diag[j] -= w * h[j];
                rhs[j] -= w * rhs[j - 1];
            }
        }
        for j in (0..k).rev() {
            let upper = if j + 1 < k { h[j + 1] * m[j + 2] } else { 0.0 };
            m[j + 1] = (rhs[j] - upper) / diag[j];
        }
    }
    Ok(TimeFunction::Custom(std::sync::Arc::new(move |t| {
        // segment i: [ts[i], ts[i+1]], clamped to the end segments
        let i = ts.partition_point(|&x| x <= t).clamp(1, n - 1) - 1;
        let h = ts[i + 1] - ts[i];
        let eval = |t: f64| {
            let (a, b) = ((ts[i + 1] - t) / h, (t - ts[i]) / h);
            let (mi, mj) = (m[i], m[i + 1]);
            [
                a * ys[i]
                    + b * ys[i + 1]
                    + ((a * a * a - a) * mi + (b * b * b - b) * mj) * h * h / 6.0,
                (ys[i + 1] - ys[i]) / h - (3.0 * a * a - 1.0) / 6.0 * h * mi
                    + (3.0 * b * b - 1.0) / 6.0 * h * mj,
                a * mi + b * mj,
            ]
        };
        // beyond the ends: the tangent line at the end point
        let end = if t < ts[0] {
            Some(ts[0])
        } else if t > ts[n - 1] {
            Some(ts[n - 1])
        } else {
            None
        };
        match end {
            None => eval(t),
            Some(te) => {
                let [y, v, _] = eval(te);
                [y + v * (t - te), v, 0.0]
            }
        }
    })))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The natural spline through (0, 0), (1, 1), (2, 0): M₁ = −3 by hand
    /// (4 M₁ = 6 (−1 − 1)), so s(0.5) = 0.5 + (0.125 − 0.5)(−3)/6 = 0.6875,
    /// s'(0.5) = 1 − (3/4 − 1)(−3)/6 … = 1.125, s''(0.5) = −1.5.
    #[test]
    fn natural_spline_against_a_hand_computed_one() {
        let f = spline_motion(&[0.0, 1.0, 2.0], &[0.0, 1.0, 0.0], Spline::Cubic).unwrap();
        let [y, v, a] = f.eval(0.5);
        assert!((y - 0.6875).abs() < 1e-15, "{y}");
        assert!((v - 1.125).abs() < 1e-15, "{v}");
        assert!((a + 1.5).abs() < 1e-15, "{a}");
        // symmetric: s(1.5) = s(0.5), s'(1.5) = −s'(0.5)
        let [y2, v2, _] = f.eval(1.5);
        assert!((y2 - y).abs() < 1e-15 && (v2 + v).abs() < 1e-15);
        // natural ends, and the tangent line beyond them
        assert_eq!(f.eval(0.0)[2], 0.0);
        let [y3, v3, a3] = f.eval(-1.0);
        let v0 = f.eval(0.0)[1];
        assert!((y3 + v0).abs() < 1e-15 && v3 == v0 && a3 == 0.0);
    }

    /// Through the knots, C² across them, derivatives against finite
    /// differences, on an irregular grid; a straight line is reproduced.
    #[test]
    fn splines_interpolate_and_are_smooth() {
        let ts = [0.0, 0.3, 0.45, 1.0, 1.7, 2.0];
        let ys = [0.1, -0.4, 0.2, 0.9, 0.0, 0.3];
        let f = spline_motion(&ts, &ys, Spline::Cubic).unwrap();
        for (&t, &y) in ts.iter().zip(&ys) {
            assert!((f.value(t) - y).abs() < 1e-14, "knot {t}");
            let e = 1e-9;
            let (l, r) = (f.eval(t - e), f.eval(t + e));
            for k in 0..3 {
                assert!((l[k] - r[k]).abs() < 1e-6, "derivative {k} jumps at {t}");
            }
        }
        for k in 0..40 {
            let t = -0.2 + 0.06 * k as f64;
            let h = 1e-5;
            let [_, v, a] = f.eval(t);
            let fd1 = (f.value(t + h) - f.value(t - h)) / (2.0 * h);
            let fd2 = (f.eval(t + h)[1] - f.eval(t - h)[1]) / (2.0 * h);
            assert!((v - fd1).abs() < 1e-7 * (1.0 + v.abs()), "v at {t}");
            assert!((a - fd2).abs() < 1e-5 * (1.0 + a.abs()), "a at {t}");
        }
        let line = spline_motion(&ts, &ts.map(|t| 2.0 - 3.0 * t), Spline::Cubic).unwrap();
        for t in [-0.5, 0.2, 1.2, 3.0] {
            let [y, v, a] = line.eval(t);
            assert!(
                (y - (2.0 - 3.0 * t)).abs() < 1e-14 && (v + 3.0).abs() < 1e-13 && a.abs() < 1e-12
            );
        }
        let lin = spline_motion(&ts, &ys, Spline::Linear).unwrap();
        let [y, v, a] = lin.eval(0.6);
        let s = (0.9 - 0.2) / (1.0 - 0.45);
        assert!((y - (0.2 + s * 0.15)).abs() < 1e-15 && (v - s).abs() < 1e-14 && a == 0.0);
    }

    #[test]
    fn bad_tables_are_errors() {
        let e = spline_motion(&[0.0, 1.0, 1.0], &[0.0; 3], Spline::Cubic).unwrap_err();
        assert!(e.contains("t[1] = 1 is followed by t[2] = 1"), "{e}");
        assert!(spline_motion(&[0.0], &[0.0], Spline::Cubic).is_err());
        assert!(spline_motion(&[0.0, 1.0], &[0.0], Spline::Cubic).is_err());
        assert!(spline_motion(&[0.0, f64::NAN], &[0.0, 1.0], Spline::Cubic).is_err());
    }

    /// An expression motion and its symbolic derivatives against the closed
    /// form.
    #[test]
    fn expression_motion_against_its_closed_form() {
        let f = expression_motion("0.1*sin(6*t) + 0.5*t^2 + exp(-t)").unwrap();
        for t in [0.0, 0.3, 1.7] {
            let [y, v, a] = f.eval(t);
            let want = [
                0.1 * (6.0 * t).sin() + 0.5 * t * t + (-t).exp(),
                0.6 * (6.0 * t).cos() + t - (-t).exp(),
                -3.6 * (6.0 * t).sin() + 1.0 + (-t).exp(),
            ];
            for (g, w) in [y, v, a].iter().zip(want) {
                assert!((g - w).abs() < 1e-14, "{g} vs {w} at {t}");
            }
        }
        let e = expression_motion("crank.phi + t").err().unwrap();
        assert_eq!(e.to_string(), "unknown name 'crank.phi' at 0");
    }
}
