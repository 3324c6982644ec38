//! Rotational spring–damper between two bodies or a body and the ground,
//! with linear or tabulated laws (docs/scenarios.md, `[[force]]`).

use super::relative_angle::AnglePair;
use super::{check_coordinates, Check, ForceElement, ForceJacobians, Law};
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
/// The rod's [`super::TorsionalSpringDamper`] is the linear case under
/// its own name and parameters (`k`, `c`).
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

    /// The two bodies.
    fn pair(&self) -> AnglePair {
        AnglePair::new(self.body_i, self.body_j)
    }

    /// `(Δφ − rest_angle, Δφ̇)`.
    fn relative(&self, q: &[f64], qd: &[f64]) -> (f64, f64) {
        let (d, r) = self.pair().relative(q, qd);
        (d - self.rest_angle, r)
    }

    /// The torque `T` on body j \[N m\] (body i receives `−T`).
    pub fn torque(&self, q: &[f64], qd: &[f64]) -> f64 {
        let (d, r) = self.relative(q, qd);
        -self.stiffness.value(d) - self.damping.value(r)
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
        self.pair().coordinates()
    }

    fn add_forces(&self, _t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        self.pair().add_torque(self.torque(q, qd), g);
    }

    fn add_jacobians(&self, _t: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        let ForceJacobians { dq, dqd, .. } = out;
        // g_a = s_a T, Δφ = Σ_b s_b φ_b: ∂g_a/∂φ_b = −k' s_a s_b.
        let (d, r) = self.relative(q, qd);
        let (ks, cs) = (self.stiffness.slope(d), self.damping.slope(r));
        self.pair().add_jacobians(ks, cs, dq, dqd);
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
        let check = Check { element: &name };
        check.two_bodies(self.body_i, self.body_j)?;
        check.finite("rest_angle", self.rest_angle)?;
        self.stiffness.validate(&name, "stiffness", true)?;
        self.damping.validate(&name, "damping", true)?;
        check_coordinates(&name, &self.coordinates(), n_coords)
    }
}
