//! Revolute joint: a point of body i coincides with a point of body j.

use super::{
    angular_velocity, check_bodies, check_finite, point, two_body_pattern, Constraint,
    JointGeometry,
};
use crate::model::FdWorkspace;
use crate::model::{perp, BodyPoint, BodyRef, ModelError};

/// Revolute joint, 2 equations (paper eq. (14) for the rod):
/// `Φ = r_i + R(φ_i) s_i − r_j − R(φ_j) s_j = 0`.
/// Either side may be the ground, whose point is then global.
#[derive(Debug, Clone)]
pub struct Revolute {
    /// Name used in messages.
    pub name: String,
    /// First body.
    pub body_i: BodyRef,
    /// Point on the first body (body frame; global for the ground).
    pub s_i: [f64; 2],
    /// Second body.
    pub body_j: BodyRef,
    /// Point on the second body.
    pub s_j: [f64; 2],
}

impl Revolute {
    /// Joint between `s_i` on `body_i` and `s_j` on `body_j`.
    pub fn new(
        name: impl Into<String>,
        body_i: BodyRef,
        s_i: [f64; 2],
        body_j: BodyRef,
        s_j: [f64; 2],
    ) -> Self {
        Self {
            name: name.into(),
            body_i,
            s_i,
            body_j,
            s_j,
        }
    }
}

impl Constraint for Revolute {
    fn geometry(&self) -> JointGeometry {
        JointGeometry::Revolute {
            i: BodyPoint::new(self.body_i, self.s_i),
            j: BodyPoint::new(self.body_j, self.s_j),
        }
    }

    fn name(&self) -> String {
        format!("revolute joint '{}'", self.name)
    }
    fn n_eq(&self) -> usize {
        2
    }
    fn bodies(&self) -> Vec<BodyRef> {
        vec![self.body_i, self.body_j]
    }
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        two_body_pattern([self.body_i, self.body_j], [(0, 0), (1, 1), (0, 2), (1, 2)])
    }
    fn phi(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        let (pi, _) = point(q, self.body_i, self.s_i);
        let (pj, _) = point(q, self.body_j, self.s_j);
        out[0] = pi[0] - pj[0];
        out[1] = pi[1] - pj[1];
    }
    fn jacobian(&self, q: &[f64], _t: f64, vals: &mut [f64]) {
        let mut k = 0;
        for (b, s, sign) in [(self.body_i, self.s_i, 1.0), (self.body_j, self.s_j, -1.0)] {
            if b != BodyRef::Ground {
                let (_, rs) = point(q, b, s);
                let d = perp(rs);
                vals[k..k + 4].copy_from_slice(&[sign, sign, sign * d[0], sign * d[1]]);
                k += 4;
            }
        }
    }
    fn gamma(&self, q: &[f64], qd: &[f64], _t: f64, out: &mut [f64]) {
        // γ = R_i s_i φ̇_i² − R_j s_j φ̇_j²
        let (_, rsi) = point(q, self.body_i, self.s_i);
        let (_, rsj) = point(q, self.body_j, self.s_j);
        let wi = angular_velocity(qd, self.body_i);
        let wj = angular_velocity(qd, self.body_j);
        out[0] = rsi[0] * wi * wi - rsj[0] * wj * wj;
        out[1] = rsi[1] * wi * wi - rsj[1] * wj * wj;
    }
    fn hessian_pattern(&self) -> Vec<(usize, usize)> {
        [self.body_i, self.body_j]
            .iter()
            .filter_map(|b| b.offset().map(|o| (o + 2, o + 2)))
            .collect()
    }
    fn add_hessian(
        &self,
        q: &[f64],
        _t: f64,
        lambda: &[f64],
        vals: &mut [f64],
        _ws: &mut FdWorkspace,
    ) {
        // ∂/∂φ_i (λ · J R_i s_i) = −λ · R_i s_i, and +λ · R_j s_j for body j.
        let mut k = 0;
        for (b, s, sign) in [(self.body_i, self.s_i, -1.0), (self.body_j, self.s_j, 1.0)] {
            if b != BodyRef::Ground {
                let (_, rs) = point(q, b, s);
                vals[k] += sign * (lambda[0] * rs[0] + lambda[1] * rs[1]);
                k += 1;
            }
        }
    }
    fn validate(&self, n_bodies: usize) -> Result<(), ModelError> {
        check_finite(&self.name(), "point i", &self.s_i)?;
        check_finite(&self.name(), "point j", &self.s_j)?;
        check_bodies(&self.name(), &self.bodies(), n_bodies)
    }
}
