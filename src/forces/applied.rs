//! Applied loads prescribed in time.

use super::{Check, ForceElement, ForceJacobians};
use crate::model::{rotate, ModelError, TimeFunction};

/// A torque `T(t)` on one body (counter-clockwise positive).
#[derive(Debug, Clone)]
pub struct AppliedTorque {
    /// Name used in messages.
    pub name: String,
    /// Body index.
    pub body: usize,
    /// Torque \[N m\].
    pub torque: TimeFunction,
}

impl ForceElement for AppliedTorque {
    fn name(&self) -> String {
        format!("applied torque '{}'", self.name)
    }
    fn coordinates(&self) -> Vec<usize> {
        vec![3 * self.body + 2]
    }
    fn add_forces(&self, t: f64, _q: &[f64], _qd: &[f64], g: &mut [f64]) {
        g[3 * self.body + 2] += self.torque.value(t);
    }
    fn jacobian_coordinates(&self) -> Vec<usize> {
        Vec::new()
    }
    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        if !self.torque.is_finite() {
            let check = Check {
                element: &self.name(),
            };
            return Err(check.fail("torque", format!("{:?}", self.torque), "must be finite"));
        }
        super::check_coordinates(&self.name(), &self.coordinates(), n_coords)
    }
}

/// A force `(F_x(t), F_y(t))`, fixed in the global frame, applied at a
/// body-fixed point `s`: generalized force `[F_x, F_y, (R s) × F]`.
#[derive(Debug, Clone)]
pub struct AppliedForce {
    /// Name used in messages.
    pub name: String,
    /// Body index.
    pub body: usize,
    /// Point of application in the body frame.
    pub point: [f64; 2],
    /// Global x component \[N\].
    pub fx: TimeFunction,
    /// Global y component \[N\].
    pub fy: TimeFunction,
}

impl ForceElement for AppliedForce {
    fn name(&self) -> String {
        format!("applied force '{}'", self.name)
    }
    fn coordinates(&self) -> Vec<usize> {
        let o = 3 * self.body;
        vec![o, o + 1, o + 2]
    }
    fn add_forces(&self, t: f64, q: &[f64], _qd: &[f64], g: &mut [f64]) {
        let o = 3 * self.body;
        let (fx, fy) = (self.fx.value(t), self.fy.value(t));
        let rs = rotate(q[o + 2], self.point);
        g[o] += fx;
        g[o + 1] += fy;
        g[o + 2] += rs[0] * fy - rs[1] * fx;
    }
    fn jacobian_coordinates(&self) -> Vec<usize> {
        vec![3 * self.body + 2]
    }
    fn add_jacobians(&self, t: f64, q: &[f64], _qd: &[f64], out: ForceJacobians<'_>) {
        let ForceJacobians { dq, .. } = out;
        // ∂/∂φ of (R s) × F = (J R s) × F = −(R s)·F
        let rs = rotate(q[3 * self.body + 2], self.point);
        dq[0] -= rs[0] * self.fx.value(t) + rs[1] * self.fy.value(t);
    }
    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        if !(self.fx.is_finite() && self.fy.is_finite() && self.point.iter().all(|v| v.is_finite()))
        {
            let check = Check {
                element: &self.name(),
            };
            let value = format!("{:?}, {:?} at {:?}", self.fx, self.fy, self.point);
            return Err(check.fail("force/point", value, "must be finite"));
        }
        super::check_coordinates(&self.name(), &self.coordinates(), n_coords)
    }
}
