//! Rotational spring–damper between two bodies or a body and the ground,
//! with linear or tabulated laws (docs/scenarios.md, `[[force]]`).

use super::{check_coordinates, FdWorkspace, ForceElement, Law};
use crate::model::{BodyRef, ModelError};

/// Rotational spring–damper on the relative angle `Δφ = φ_j − φ_i` (the
/// ground's angle and rate are 0).
///
/// It applies the torque
///
/// `T = −stiffness(Δφ − rest_angle) − damping(Δφ̇)`
///
/// to body j and `−T` to body i, with `stiffness` and `damping` linear or
/// tabulated [`Law`]s (both non-decreasing, so the spring stores and the
/// damper dissipates energy). Jacobians (analytic): `∂T/∂φ_j = −k'`,
/// `∂T/∂φ̇_j = −c'` (`k'`, `c'` the law slopes), with the opposite signs
/// for body i. Potential energy `V = ∫₀^{Δφ − rest_angle} stiffness`.
///
/// The rod's [`super::TorsionalSpringDamper`] is the linear case with
/// its own (generated-kernel) bookkeeping; it is kept as it is.
#[derive(Debug, Clone, PartialEq)]
pub struct RotationalSpringDamper {
    /// First body (receives `−T`); may be the ground.
    pub body_i: BodyRef,
    /// Second body (receives `T`); may be the ground.
    pub body_j: BodyRef,
    /// Relative angle at which the spring is relaxed \[rad\].
    pub rest_angle: f64,
    /// Restoring torque as a function of `Δφ − rest_angle` \[N m\]; non-decreasing.
    pub stiffness: Law,
    /// Damping torque as a function of `Δφ̇` \[N m\]; non-decreasing.
    pub damping: Law,
}

impl RotationalSpringDamper {
    /// Linear stiffness `k` \[N m/rad\] and damping `c` \[N m s/rad\].
    pub fn linear(body_i: BodyRef, body_j: BodyRef, rest_angle: f64, k: f64, c: f64) -> Self {
        Self {
            body_i,
            body_j,
            rest_angle,
            stiffness: Law::Linear(k),
            damping: Law::Linear(c),
        }
    }

    /// `(Δφ − rest_angle, Δφ̇)`.
    fn relative(&self, q: &[f64], qd: &[f64]) -> (f64, f64) {
        let ang = |b: BodyRef, v: &[f64]| b.offset().map_or(0.0, |o| v[o + 2]);
        (
            ang(self.body_j, q) - ang(self.body_i, q) - self.rest_angle,
            ang(self.body_j, qd) - ang(self.body_i, qd),
        )
    }

    /// The torque `T` on body j \[N m\] (body i receives `−T`).
    pub fn torque(&self, q: &[f64], qd: &[f64]) -> f64 {
        let (d, r) = self.relative(q, qd);
        -self.stiffness.value(d) - self.damping.value(r)
    }

    /// Signs (−1 for body i, +1 for body j) of the non-ground sides, in the
    /// order of [`ForceElement::coordinates`].
    fn signs(&self) -> ([f64; 2], usize) {
        match (self.body_i.offset(), self.body_j.offset()) {
            (Some(a), Some(b)) if a < b => ([-1.0, 1.0], 2),
            (Some(_), Some(_)) => ([1.0, -1.0], 2),
            (Some(_), None) => ([-1.0, 0.0], 1),
            (None, Some(_)) => ([1.0, 0.0], 1),
            (None, None) => ([0.0; 2], 0),
        }
    }
}

impl ForceElement for RotationalSpringDamper {
    fn name(&self) -> String {
        format!(
            "rotational spring-damper {:?}-{:?}",
            self.body_i, self.body_j
        )
    }

    fn coordinates(&self) -> Vec<usize> {
        let mut c: Vec<usize> = [self.body_i, self.body_j]
            .iter()
            .filter_map(|b| b.offset().map(|o| o + 2))
            .collect();
        c.sort_unstable();
        c
    }

    fn add_forces(&self, _t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let t = self.torque(q, qd);
        if let Some(o) = self.body_j.offset() {
            g[o + 2] += t;
        }
        if let Some(o) = self.body_i.offset() {
            g[o + 2] -= t;
        }
    }

    fn add_jacobians(
        &self,
        _t: f64,
        q: &[f64],
        qd: &[f64],
        dq: &mut [f64],
        dqd: &mut [f64],
        _ws: &mut FdWorkspace,
    ) {
        // g_a = s_a T, Δφ = Σ_b s_b φ_b: ∂g_a/∂φ_b = −k' s_a s_b.
        let (d, r) = self.relative(q, qd);
        let (ks, cs) = (self.stiffness.slope(d), self.damping.slope(r));
        let (s, n) = self.signs();
        for a in 0..n {
            for b in 0..n {
                dq[a * n + b] -= ks * s[a] * s[b];
                dqd[a * n + b] -= cs * s[a] * s[b];
            }
        }
    }

    fn readings(&self) -> &'static [(&'static str, &'static str)] {
        &[("torque", "N m"), ("deflection", "rad"), ("rate", "rad/s")]
    }

    /// Torque `T` on body j, deflection `Δφ − rest_angle`, rate `Δφ̇`.
    fn read(&self, _t: f64, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let (d, r) = self.relative(q, qd);
        out[0] = self.torque(q, qd);
        out[1] = d;
        out[2] = r;
    }

    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        let (d, _) = self.relative(q, q);
        Some(self.stiffness.integral(d))
    }

    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let name = self.name();
        if self.body_i == self.body_j {
            return Err(ModelError::InvalidParameter {
                element: name,
                field: "bodies".into(),
                value: format!("{:?}", self.body_i),
                why: "a spring-damper must connect two different bodies".into(),
            });
        }
        if !self.rest_angle.is_finite() {
            return Err(ModelError::InvalidParameter {
                element: name,
                field: "rest_angle".into(),
                value: self.rest_angle.to_string(),
                why: "must be finite".into(),
            });
        }
        self.stiffness.validate(&name, "stiffness", true)?;
        self.damping.validate(&name, "damping", true)?;
        check_coordinates(&name, &self.coordinates(), n_coords)
    }
}
