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

impl Constraint for DriveCoordinate {
    fn name(&self) -> String {
        format!("coordinate drive '{}'", self.name)
    }
    fn drive_unit(&self) -> Option<&'static str> {
        Some(if self.coordinate == 2 { "N m" } else { "N" })
    }
    fn n_eq(&self) -> usize {
        1
    }
    fn bodies(&self) -> Vec<BodyRef> {
        vec![BodyRef::Body(self.body)]
    }
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        vec![(0, self.index())]
    }
    fn phi(&self, q: &[f64], t: f64, out: &mut [f64]) {
        out[0] = q[self.index()] - self.f.value(t);
    }
    fn jacobian(&self, _q: &[f64], _t: f64, vals: &mut [f64]) {
        vals[0] = 1.0;
    }
    fn phi_t(&self, _q: &[f64], t: f64, out: &mut [f64]) {
        out[0] = -self.f.eval(t)[1];
    }
    fn gamma(&self, _q: &[f64], _qd: &[f64], t: f64, out: &mut [f64]) {
        out[0] = self.f.eval(t)[2];
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
        if self.coordinate > 2 {
            return Err(ModelError::InvalidParameter {
                element: self.name(),
                field: "coordinate".into(),
                value: self.coordinate.to_string(),
                why: "must be 0 (x), 1 (y) or 2 (phi)".into(),
            });
        }
        check_bodies(&self.name(), &self.bodies(), n_bodies)
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

impl Constraint for DriveRelativeAngle {
    fn name(&self) -> String {
        format!("relative-angle drive '{}'", self.name)
    }
    fn drive_unit(&self) -> Option<&'static str> {
        Some("N m")
    }
    fn n_eq(&self) -> usize {
        1
    }
    fn bodies(&self) -> Vec<BodyRef> {
        vec![self.body_i, self.body_j]
    }
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        [self.body_i, self.body_j]
            .iter()
            .filter_map(|b| b.offset().map(|o| (0, o + 2)))
            .collect()
    }
    fn phi(&self, q: &[f64], t: f64, out: &mut [f64]) {
        out[0] = angle(q, self.body_j) - angle(q, self.body_i) - self.f.value(t);
    }
    fn jacobian(&self, _q: &[f64], _t: f64, vals: &mut [f64]) {
        let mut k = 0;
        for (b, v) in [(self.body_i, -1.0), (self.body_j, 1.0)] {
            if b != BodyRef::Ground {
                vals[k] = v;
                k += 1;
            }
        }
    }
    fn phi_t(&self, _q: &[f64], t: f64, out: &mut [f64]) {
        out[0] = -self.f.eval(t)[1];
    }
    fn gamma(&self, _q: &[f64], _qd: &[f64], t: f64, out: &mut [f64]) {
        out[0] = self.f.eval(t)[2];
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
}
