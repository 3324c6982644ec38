//! Torsional spring–damper between two bodies (bending of the rod, problem B (docs/problems.md)).

use super::{check_coordinates, Check, ForceElement, ForceJacobians, RotationalSpringDamper};
use crate::model::{BodyRef, ModelError};

/// Linear torsional spring–damper acting on the relative angle of two bodies
/// (docs/problems.md, problem B, "bending"; also the base spring of the cantilever of D).
///
/// With `Δφ = φ_j − φ_i` and `Δφ̇ = φ̇_j − φ̇_i` it applies the torque
/// `T = −k (Δφ − rest_angle) − c Δφ̇` to body j and `−T` to body i.
/// Either side may be [`BodyRef::Ground`], whose angle and rate are 0 (the
/// rod builders use a ground `body_i` for the clamped cantilever base).
/// Potential energy `½ k (Δφ − rest_angle)²`. Jacobians are analytic and
/// constant: `∂g/∂φ = ∓k`, `∂g/∂φ̇ = ∓c`. The law is that of a
/// [`RotationalSpringDamper`] with linear stiffness and damping.
#[derive(Debug, Clone, PartialEq)]
pub struct TorsionalSpringDamper {
    /// First body (receives `−T`); may be the ground.
    pub body_i: BodyRef,
    /// Second body (receives `T`); may be the ground.
    pub body_j: BodyRef,
    /// Stiffness k ≥ 0 \[N m/rad\] (rod: `E w⁴ / (12 l_s)`).
    pub k: f64,
    /// Damping c ≥ 0 \[N m s/rad\] (rod: `1e-5 s · k`).
    pub c: f64,
    /// Relative angle at which the spring is relaxed \[rad\].
    pub rest_angle: f64,
}

impl TorsionalSpringDamper {
    /// A spring–damper relaxed at `Δφ = 0`.
    pub fn new(body_i: BodyRef, body_j: BodyRef, k: f64, c: f64) -> Self {
        Self {
            body_i,
            body_j,
            k,
            c,
            rest_angle: 0.0,
        }
    }

    /// A spring–damper `k`, `c` in every joint of a chain of `bodies`
    /// (between consecutive ones), relaxed at `Δφ = 0`.
    pub(crate) fn in_chain(bodies: &[usize], k: f64, c: f64) -> Vec<Self> {
        bodies
            .windows(2)
            .map(|b| Self::new(BodyRef::Body(b[0]), BodyRef::Body(b[1]), k, c))
            .collect()
    }

    /// The same element as a [`RotationalSpringDamper`] with linear laws,
    /// whose torque, Jacobians and energy it uses.
    fn law(&self) -> RotationalSpringDamper {
        RotationalSpringDamper::linear(self.body_i, self.body_j, self.rest_angle, self.k, self.c)
    }

    /// The torque `T` on body j (body i receives `−T`).
    pub fn torque(&self, q: &[f64], qd: &[f64]) -> f64 {
        self.law().torque(q, qd)
    }
}

impl ForceElement for TorsionalSpringDamper {
    fn name(&self) -> String {
        format!(
            "torsional spring-damper {:?}-{:?}",
            self.body_i, self.body_j
        )
    }

    fn coordinates(&self) -> Vec<usize> {
        self.law().coordinates()
    }

    fn add_forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        self.law().add_forces(t, q, qd, g)
    }

    fn add_jacobians(&self, t: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        self.law().add_jacobians(t, q, qd, out)
    }

    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        self.law().potential_energy(q)
    }

    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let name = self.name();
        let check = Check { element: &name };
        check.two_bodies(self.body_i, self.body_j)?;
        check.sign("k", self.k, false)?;
        check.sign("c", self.c, false)?;
        check.finite("rest_angle", self.rest_angle)?;
        check_coordinates(&name, &self.coordinates(), n_coords)
    }
}
