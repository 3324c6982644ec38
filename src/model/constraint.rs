//! The [`Constraint`] trait: joints as constraint equations Φ(q, t) = 0 and
//! their derivatives (the joints themselves live in [`crate::constraints`]).
//!
//! Every joint provides Φ, the structural non-zeros of Φ_q (a fixed sparse
//! pattern, values written in pattern order), Φ_t, and
//! γ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt, the right-hand side of the
//! acceleration equation Φ_q q̈ = γ (paper, eq. (4)–(5)). For implicit
//! integrators it also provides (Φ_qᵀ λ)_q.

use super::{BodyRef, FdWorkspace, ModelError};
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
    /// of Φ_qᵀ λ through `ws` (accurate to ~1e-8 relative; no allocation
    /// after the first call per constraint); joints override it exactly.
    fn add_hessian(
        &self,
        q: &[f64],
        t: f64,
        lambda: &[f64],
        vals: &mut [f64],
        ws: &mut FdWorkspace,
    ) {
        ws.constraint_hessian(self, q, t, lambda, vals);
    }
    /// Check parameters and body references against a system of `n_bodies`.
    fn validate(&self, n_bodies: usize) -> Result<(), ModelError> {
        check_bodies(&self.name(), &self.bodies(), n_bodies)
    }
    /// For a drive (one equation prescribing a coordinate or a relative
    /// angle, `Φ = ± q_k − f(t)` with `∂Φ/∂q_k = 1` on the driven
    /// coordinate): the unit of its generalized force `−λ` on that
    /// coordinate, `"N"` or `"N m"`. Default: `None` (not a drive).
    fn drive_unit(&self) -> Option<&'static str> {
        None
    }
    /// What the joint is, as data: lets code generation recognise
    /// topologies ([`crate::generated`]) and drawings show joints, without
    /// knowing the implementing type. Default: [`JointGeometry::Other`].
    fn geometry(&self) -> JointGeometry {
        JointGeometry::Other
    }
}

/// A joint described as data ([`Constraint::geometry`]). Points are in the
/// body frame (global for the ground).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointGeometry {
    /// Revolute joint: `r_i + R(φ_i) s_i = r_j + R(φ_j) s_j`.
    Revolute {
        /// First body.
        body_i: BodyRef,
        /// Pin point on the first body.
        s_i: [f64; 2],
        /// Second body.
        body_j: BodyRef,
        /// Pin point on the second body.
        s_j: [f64; 2],
    },
    /// Translational joint: the point `s_j` of body j slides along the axis
    /// `u_i` through `s_i` on body i.
    Translational {
        /// Body carrying the axis.
        body_i: BodyRef,
        /// Point of the axis.
        s_i: [f64; 2],
        /// Axis direction (unit).
        u_i: [f64; 2],
        /// Sliding body.
        body_j: BodyRef,
        /// Sliding point.
        s_j: [f64; 2],
    },
    /// Anything else (drives, user constraints).
    Other,
}

impl JointGeometry {
    /// The body-fixed points the joint attaches, `(body, point)`.
    pub fn attachment_points(&self) -> Vec<(BodyRef, [f64; 2])> {
        match *self {
            JointGeometry::Revolute {
                body_i,
                s_i,
                body_j,
                s_j,
            }
            | JointGeometry::Translational {
                body_i,
                s_i,
                body_j,
                s_j,
                ..
            } => vec![(body_i, s_i), (body_j, s_j)],
            JointGeometry::Other => Vec::new(),
        }
    }
}

/// Every referenced body exists and the two sides differ (for
/// [`Constraint::validate`]).
pub fn check_bodies(element: &str, bodies: &[BodyRef], n_bodies: usize) -> Result<(), ModelError> {
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
pub(crate) fn touched_columns(pattern: &[(usize, usize)]) -> Vec<usize> {
    let mut cols: Vec<usize> = pattern.iter().map(|&(_, c)| c).collect();
    cols.sort_unstable();
    cols.dedup();
    cols
}
