//! Translational (prismatic) joint: body j slides along an axis of body i.

use super::{
    angle, angular_velocity, check_bodies, check_finite, point, two_body_pattern, velocity,
    Constraint, JointGeometry,
};
use crate::model::{perp, rotate, BodyPoint, BodyRef, ModelError, Slide};

/// Translational joint, 2 equations:
///
/// * `Φ₁ = n · d = 0` with `n = R(φ_i) J u_i` the normal of the sliding axis
///   `u_i` (body frame of i) and `d = r_j + R(φ_j) s_j − r_i − R(φ_i) s_i`;
/// * `Φ₂ = φ_j − φ_i − θ₀ = 0` (no relative rotation).
///
/// Either side may be the ground (then `s`, `u` are global).
#[derive(Debug, Clone)]
pub struct Translational {
    /// Name used in messages.
    pub name: String,
    /// Body carrying the axis.
    pub body_i: BodyRef,
    /// Point of the axis on body i.
    pub s_i: [f64; 2],
    /// Direction of the axis on body i (normalised on construction).
    pub u_i: [f64; 2],
    /// Sliding body.
    pub body_j: BodyRef,
    /// Point on body j that stays on the axis.
    pub s_j: [f64; 2],
    /// Constant relative angle θ₀ = φ_j − φ_i.
    pub theta0: f64,
}

impl Translational {
    /// Joint with axis `u_i` through `s_i` on body i, point `s_j` on body j.
    pub fn new(
        name: impl Into<String>,
        body_i: BodyRef,
        s_i: [f64; 2],
        u_i: [f64; 2],
        body_j: BodyRef,
        s_j: [f64; 2],
        theta0: f64,
    ) -> Self {
        let len = (u_i[0] * u_i[0] + u_i[1] * u_i[1]).sqrt();
        Self {
            name: name.into(),
            body_i,
            s_i,
            u_i: [u_i[0] / len, u_i[1] / len],
            body_j,
            s_j,
            theta0,
        }
    }

    /// n, d, R_i s_i, R_j s_j.
    fn geometry(&self, q: &[f64]) -> ([f64; 2], [f64; 2], [f64; 2], [f64; 2]) {
        let n = rotate(angle(q, self.body_i), perp(self.u_i));
        let (pi, rsi) = point(q, self.body_i, self.s_i);
        let (pj, rsj) = point(q, self.body_j, self.s_j);
        (n, [pj[0] - pi[0], pj[1] - pi[1]], rsi, rsj)
    }
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

impl Constraint for Translational {
    fn geometry(&self) -> JointGeometry {
        JointGeometry::Translational(Slide {
            i: BodyPoint::new(self.body_i, self.s_i),
            u_i: self.u_i,
            j: BodyPoint::new(self.body_j, self.s_j),
        })
    }

    fn name(&self) -> String {
        format!("translational joint '{}'", self.name)
    }
    fn n_eq(&self) -> usize {
        2
    }
    fn bodies(&self) -> Vec<BodyRef> {
        vec![self.body_i, self.body_j]
    }
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        two_body_pattern([self.body_i, self.body_j], [(0, 0), (0, 1), (0, 2), (1, 2)])
    }
    fn phi(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        let (n, d, _, _) = self.geometry(q);
        out[0] = dot(n, d);
        out[1] = angle(q, self.body_j) - angle(q, self.body_i) - self.theta0;
    }
    fn jacobian(&self, q: &[f64], _t: f64, vals: &mut [f64]) {
        let (n, d, rsi, rsj) = self.geometry(q);
        let mut k = 0;
        if self.body_i != BodyRef::Ground {
            // ∂Φ₁/∂φ_i = (J n)·d − n·(J R_i s_i)
            let dphi = dot(perp(n), d) - dot(n, perp(rsi));
            vals[k..k + 4].copy_from_slice(&[-n[0], -n[1], dphi, -1.0]);
            k += 4;
        }
        if self.body_j != BodyRef::Ground {
            vals[k..k + 4].copy_from_slice(&[n[0], n[1], dot(n, perp(rsj)), 1.0]);
        }
    }
    fn gamma(&self, q: &[f64], qd: &[f64], _t: f64, out: &mut [f64]) {
        let (n, d, rsi, rsj) = self.geometry(q);
        let wi = angular_velocity(qd, self.body_i);
        let wj = angular_velocity(qd, self.body_j);
        let vi = velocity(qd, self.body_i);
        let vj = velocity(qd, self.body_j);
        let jpi = perp(rsi);
        let jpj = perp(rsj);
        let dd = [
            vj[0] + wj * jpj[0] - vi[0] - wi * jpi[0],
            vj[1] + wj * jpj[1] - vi[1] - wi * jpi[1],
        ];
        // γ₁ = φ̇_i² n·d − 2 φ̇_i (J n)·ḋ + φ̇_j² n·R_j s_j − φ̇_i² n·R_i s_i
        out[0] = wi * wi * dot(n, d) - 2.0 * wi * dot(perp(n), dd) + wj * wj * dot(n, rsj)
            - wi * wi * dot(n, rsi);
        out[1] = 0.0;
    }
    fn validate(&self, n_bodies: usize) -> Result<(), ModelError> {
        check_finite(&self.name(), "point i", &self.s_i)?;
        check_finite(&self.name(), "point j", &self.s_j)?;
        check_finite(&self.name(), "axis", &self.u_i)?;
        check_finite(&self.name(), "theta0", &[self.theta0])?;
        check_bodies(&self.name(), &self.bodies(), n_bodies)
    }
}
