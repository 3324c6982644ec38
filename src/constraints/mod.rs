//! Joints as constraint equations Φ(q, t) = 0 and their derivatives.
//!
//! Every joint implements [`Constraint`]: Φ, the structural non-zeros of Φ_q
//! (a fixed sparse pattern, values written in pattern order), Φ_t, and
//! γ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt, the right-hand side of the
//! acceleration equation Φ_q q̈ = γ (paper, eq. (4)–(5)). For implicit
//! integrators it also provides (Φ_qᵀ λ)_q.

mod driving;
mod revolute;
mod translational;

pub use driving::{DriveCoordinate, DriveRelativeAngle};
pub use revolute::Revolute;
pub use translational::Translational;

use crate::model::{BodyRef, ModelError};
use std::fmt::Debug;

/// A holonomic (possibly rheonomic) constraint block of `n_eq` equations.
///
/// Coordinates are global indices into q (body i at `3i..3i+3`); rows are
/// local (`0..n_eq`); the [`crate::model::System`] offsets them.
pub trait Constraint: Send + Sync + Debug {
    /// Description used in messages, e.g. "revolute joint 'B'".
    fn name(&self) -> String;
    /// Number of scalar equations.
    fn n_eq(&self) -> usize;
    /// The bodies the constraint connects (for validation).
    fn bodies(&self) -> Vec<BodyRef>;
    /// Structural non-zeros of Φ_q as `(local row, global column)`; the order
    /// fixes the order of the values written by [`Constraint::jacobian`].
    fn jacobian_pattern(&self) -> Vec<(usize, usize)>;
    /// Φ(q, t) into `out` (length `n_eq`).
    fn phi(&self, q: &[f64], t: f64, out: &mut [f64]);
    /// Values of Φ_q(q, t) in the order of [`Constraint::jacobian_pattern`].
    fn jacobian(&self, q: &[f64], t: f64, vals: &mut [f64]);
    /// Φ_t(q, t) (zero for scleronomic constraints).
    fn phi_t(&self, q: &[f64], t: f64, out: &mut [f64]) {
        let _ = (q, t);
        out.fill(0.0);
    }
    /// γ(q, q̇, t) = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt.
    fn gamma(&self, q: &[f64], qd: &[f64], t: f64, out: &mut [f64]);
    /// Structural non-zeros `(row, col)` with `row ≥ col` of the symmetric
    /// (Φ_qᵀ λ)_q. Default: the dense block over the touched columns.
    fn hessian_pattern(&self) -> Vec<(usize, usize)> {
        let cols = touched_columns(&self.jacobian_pattern());
        let mut p = Vec::new();
        for (a, &ca) in cols.iter().enumerate() {
            for &cb in &cols[..=a] {
                p.push((ca.max(cb), ca.min(cb)));
            }
        }
        p
    }
    /// Add (Φ_qᵀ λ)_q (λ local to this constraint) in the order of
    /// [`Constraint::hessian_pattern`]. Default: central finite differences
    /// of Φ_qᵀ λ (accurate to ~1e-8 relative); joints override it exactly.
    fn add_hessian(&self, q: &[f64], t: f64, lambda: &[f64], vals: &mut [f64]) {
        let pattern = self.jacobian_pattern();
        let cols = touched_columns(&pattern);
        let hp = self.hessian_pattern();
        let mut qp = q.to_vec();
        let mut jp = vec![0.0; pattern.len()];
        let mut jm = vec![0.0; pattern.len()];
        for &c in &cols {
            let h = 1e-6 * (1.0 + q[c].abs());
            qp[c] = q[c] + h;
            self.jacobian(&qp, t, &mut jp);
            qp[c] = q[c] - h;
            self.jacobian(&qp, t, &mut jm);
            qp[c] = q[c];
            // d/dq_c of (Φ_qᵀλ)_{c'} = Σ_r λ_r dΦ_q[r, c'] / dq_c
            for (k, &(r, cp)) in pattern.iter().enumerate() {
                let d = lambda[r] * (jp[k] - jm[k]) / (2.0 * h);
                if cp >= c {
                    if let Some(pos) = hp.iter().position(|&e| e == (cp, c)) {
                        vals[pos] += d;
                    }
                }
            }
        }
    }
    /// Check parameters and body references against a system of `n_bodies`.
    fn validate(&self, n_bodies: usize) -> Result<(), ModelError> {
        check_bodies(&self.name(), &self.bodies(), n_bodies)
    }
    /// The points this constraint attaches to its bodies, `(body, point in
    /// the body frame — global for the ground)`: what a drawing of the
    /// mechanism shows as joints. Default: none (e.g. driving constraints).
    fn attachment_points(&self) -> Vec<(BodyRef, [f64; 2])> {
        Vec::new()
    }
    /// The joint as a [`Revolute`], if it is one (lets generated kernels
    /// recognise a topology; see `crate::generated`).
    fn as_revolute(&self) -> Option<&Revolute> {
        None
    }
}

/// Every referenced body exists and the two sides differ.
pub(crate) fn check_bodies(
    element: &str,
    bodies: &[BodyRef],
    n_bodies: usize,
) -> Result<(), ModelError> {
    for b in bodies {
        if let BodyRef::Body(i) = *b {
            if i >= n_bodies {
                return Err(ModelError::MissingBody {
                    element: element.to_string(),
                    index: i,
                    n_bodies,
                });
            }
        }
    }
    if bodies.len() == 2 && bodies[0] == bodies[1] {
        return Err(ModelError::InvalidParameter {
            element: element.to_string(),
            field: "bodies".into(),
            value: format!("{:?}", bodies[0]),
            why: "a joint must connect two different bodies".into(),
        });
    }
    Ok(())
}

/// Sorted distinct columns of a pattern.
pub fn touched_columns(pattern: &[(usize, usize)]) -> Vec<usize> {
    let mut cols: Vec<usize> = pattern.iter().map(|&(_, c)| c).collect();
    cols.sort_unstable();
    cols.dedup();
    cols
}

/// Global position of a body-fixed point and its rotated offset `R(φ) s`.
/// For the ground, `s` is a global point and the offset is zero-motion.
#[inline]
pub(crate) fn point(q: &[f64], body: BodyRef, s: [f64; 2]) -> ([f64; 2], [f64; 2]) {
    match body {
        BodyRef::Ground => (s, [0.0, 0.0]),
        BodyRef::Body(i) => {
            let rs = crate::model::rotate(q[3 * i + 2], s);
            ([q[3 * i] + rs[0], q[3 * i + 1] + rs[1]], rs)
        }
    }
}

/// Angle of a body (0 for the ground).
#[inline]
pub(crate) fn angle(q: &[f64], body: BodyRef) -> f64 {
    body.offset().map_or(0.0, |o| q[o + 2])
}

/// Angular velocity of a body (0 for the ground).
#[inline]
pub(crate) fn angular_velocity(qd: &[f64], body: BodyRef) -> f64 {
    body.offset().map_or(0.0, |o| qd[o + 2])
}

/// Linear velocity of a body's reference point (0 for the ground).
#[inline]
pub(crate) fn velocity(qd: &[f64], body: BodyRef) -> [f64; 2] {
    body.offset().map_or([0.0, 0.0], |o| [qd[o], qd[o + 1]])
}

pub(crate) fn check_finite(element: &str, field: &str, v: &[f64]) -> Result<(), ModelError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(ModelError::InvalidParameter {
            element: element.to_string(),
            field: field.to_string(),
            value: format!("{v:?}"),
            why: "must be finite".into(),
        })
    }
}
