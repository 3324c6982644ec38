//! The relative angle `Δφ = φ_j − φ_i` of two bodies, either of them
//! possibly the ground (angle and rate 0): the bookkeeping of the
//! rotational spring–damper (and so of the torsional one, its linear case).

use crate::model::BodyRef;

/// Two bodies whose relative angle `Δφ = φ_j − φ_i` a torque acts on:
/// `T` on body j, `−T` on body i.
#[derive(Debug, Clone, Copy)]
pub(super) struct AnglePair {
    /// First body (receives `−T`).
    pub(super) body_i: BodyRef,
    /// Second body (receives `T`).
    pub(super) body_j: BodyRef,
}

impl AnglePair {
    /// The pair `(body_i, body_j)`.
    pub(super) fn new(body_i: BodyRef, body_j: BodyRef) -> Self {
        Self { body_i, body_j }
    }

    /// `(Δφ, Δφ̇)` \[rad, rad/s\].
    pub(super) fn relative(&self, q: &[f64], qd: &[f64]) -> (f64, f64) {
        let ang = |b: BodyRef, v: &[f64]| b.offset().map_or(0.0, |o| v[o + 2]);
        (
            ang(self.body_j, q) - ang(self.body_i, q),
            ang(self.body_j, qd) - ang(self.body_i, qd),
        )
    }

    /// The angle coordinates of the non-ground sides (sorted, distinct).
    pub(super) fn coordinates(&self) -> Vec<usize> {
        let mut c: Vec<usize> = [self.body_i, self.body_j]
            .iter()
            .filter_map(|b| b.offset().map(|o| o + 2))
            .collect();
        c.sort_unstable();
        c.dedup();
        c
    }

    /// Add the torque `t` to body j and `−t` to body i.
    pub(super) fn add_torque(&self, t: f64, g: &mut [f64]) {
        if let Some(o) = self.body_j.offset() {
            g[o + 2] += t;
        }
        if let Some(o) = self.body_i.offset() {
            g[o + 2] -= t;
        }
    }

    /// Add the Jacobians of `T = −k Δφ − c Δφ̇ + const` over
    /// [`Self::coordinates`]: with `s_i = −1`, `s_j = +1`, `g_a = s_a T`,
    /// `∂g_a/∂φ_b = −k s_a s_b`, `∂g_a/∂φ̇_b = −c s_a s_b`.
    pub(super) fn add_jacobians(&self, k: f64, c: f64, dq: &mut [f64], dqd: &mut [f64]) {
        let (s, n) = self.signs();
        for a in 0..n {
            for b in 0..n {
                dq[a * n + b] -= k * s[a] * s[b];
                dqd[a * n + b] -= c * s[a] * s[b];
            }
        }
    }

    /// Signs (−1 for body i, +1 for body j) of the non-ground sides, in the
    /// order of [`Self::coordinates`], and how many there are.
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
