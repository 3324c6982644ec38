//! Torsional spring–damper between two bodies (bending of the rod, problem B (docs/problems.md)).

use super::{check_coordinates, FdWorkspace, ForceElement};
use crate::model::{BodyRef, ModelError};

/// Linear torsional spring–damper acting on the relative angle of two bodies
/// (docs/problems.md, problem B, "bending"; also the base spring of the cantilever of D).
///
/// With `Δφ = φ_j − φ_i` and `Δφ̇ = φ̇_j − φ̇_i` it applies the torque
/// `T = −k (Δφ − rest_angle) − c Δφ̇` to body j and `−T` to body i.
/// Either side may be [`BodyRef::Ground`], whose angle and rate are 0 (the
/// rod builders use a ground `body_i` for the clamped cantilever base).
/// Potential energy `½ k (Δφ − rest_angle)²`. Jacobians are analytic and
/// constant: `∂g/∂φ = ∓k`, `∂g/∂φ̇ = ∓c`.
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

    /// The torque `T` on body j (body i receives `−T`).
    pub fn torque(&self, q: &[f64], qd: &[f64]) -> f64 {
        let ang = |b: BodyRef, v: &[f64]| b.offset().map_or(0.0, |o| v[o + 2]);
        let dphi = ang(self.body_j, q) - ang(self.body_i, q);
        let drate = ang(self.body_j, qd) - ang(self.body_i, qd);
        -self.k * (dphi - self.rest_angle) - self.c * drate
    }

    /// `(position in the footprint, sign)` of each non-ground side:
    /// sign −1 for body i, +1 for body j.
    fn slots(&self) -> [Option<(usize, f64)>; 2] {
        let ci = self.body_i.offset().map(|o| o + 2);
        let cj = self.body_j.offset().map(|o| o + 2);
        match (ci, cj) {
            (Some(a), Some(b)) => {
                let (pi, pj) = if a < b { (0, 1) } else { (1, 0) };
                [Some((pi, -1.0)), Some((pj, 1.0))]
            }
            (Some(_), None) => [Some((0, -1.0)), None],
            (None, Some(_)) => [None, Some((0, 1.0))],
            (None, None) => [None, None],
        }
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
        let mut c: Vec<usize> = [self.body_i, self.body_j]
            .iter()
            .filter_map(|b| b.offset().map(|o| o + 2))
            .collect();
        c.sort_unstable();
        c.dedup();
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
        _q: &[f64],
        _qd: &[f64],
        dq: &mut [f64],
        dqd: &mut [f64],
        _ws: &mut FdWorkspace,
    ) {
        // g_j = −k(φ_j − φ_i − r) − c(φ̇_j − φ̇_i), g_i = −g_j:
        // ∂g_a/∂φ_b = −k s_a s_b with s_i = −1, s_j = +1.
        let slots = self.slots();
        let n = slots.iter().flatten().count();
        for (ra, sa) in slots.iter().flatten() {
            for (cb, sb) in slots.iter().flatten() {
                dq[ra * n + cb] -= self.k * sa * sb;
                dqd[ra * n + cb] -= self.c * sa * sb;
            }
        }
    }

    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        let ang = |b: BodyRef| b.offset().map_or(0.0, |o| q[o + 2]);
        let e = ang(self.body_j) - ang(self.body_i) - self.rest_angle;
        Some(0.5 * self.k * e * e)
    }

    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let bad = |field: &str, value: String, why: &str| ModelError::InvalidParameter {
            element: self.name(),
            field: field.into(),
            value,
            why: why.into(),
        };
        if self.body_i == self.body_j {
            return Err(bad(
                "bodies",
                format!("{:?}", self.body_i),
                "a spring-damper must connect two different bodies",
            ));
        }
        if !(self.k.is_finite() && self.k >= 0.0) {
            return Err(bad("k", self.k.to_string(), "must be finite and >= 0"));
        }
        if !(self.c.is_finite() && self.c >= 0.0) {
            return Err(bad("c", self.c.to_string(), "must be finite and >= 0"));
        }
        if !self.rest_angle.is_finite() {
            return Err(bad(
                "rest_angle",
                self.rest_angle.to_string(),
                "must be finite",
            ));
        }
        check_coordinates(&self.name(), &self.coordinates(), n_coords)
    }
}
