//! The [`Constraint`] trait: joints as constraint equations Φ(q, t) = 0 and
//! their derivatives (the joints themselves live in [`crate::constraints`]).
//!
//! Every joint provides Φ, the structural non-zeros of Φ_q (a fixed sparse
//! pattern, values written in pattern order), Φ_t, and
//! γ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt, the right-hand side of the
//! acceleration equation Φ_q q̈ = γ (paper, eq. (4)–(5)). For implicit
//! integrators it also provides (Φ_qᵀ λ)_q.

use super::{perp, rotate, BodyPoint, BodyRef, FdWorkspace, ModelError};
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

/// A joint described as data ([`Constraint::geometry`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointGeometry {
    /// Revolute joint: the two points coincide,
    /// `r_i + R(φ_i) s_i = r_j + R(φ_j) s_j`.
    Revolute {
        /// The pin point on the first body.
        i: BodyPoint,
        /// The pin point on the second body.
        j: BodyPoint,
    },
    /// Translational joint: the point `j` slides along the axis `u_i`
    /// through the point `i`.
    Translational(Slide),
    /// Anything else (drives, user constraints).
    Other,
}

impl JointGeometry {
    /// The body-fixed points the joint attaches.
    pub fn attachment_points(&self) -> Vec<BodyPoint> {
        match *self {
            JointGeometry::Revolute { i, j } | JointGeometry::Translational(Slide { i, j, .. }) => {
                vec![i, j]
            }
            JointGeometry::Other => Vec::new(),
        }
    }
}

/// A translational joint as data: the point `j` slides along the unit
/// axis `u_i` (body i frame; global on the ground) through the point `i`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slide {
    /// Point of the axis, on the body carrying it.
    pub i: BodyPoint,
    /// Unit axis (body i frame).
    pub u_i: [f64; 2],
    /// Sliding point, on the sliding body.
    pub j: BodyPoint,
}

impl Slide {
    /// The coordinates the slide depends on: x, y, φ of body i, then of
    /// body j (none for the ground); the order of [`Slide::eval`]'s
    /// gradient.
    pub fn columns(&self) -> Vec<usize> {
        [self.i.body, self.j.body]
            .iter()
            .filter_map(|b| b.offset())
            .flat_map(|o| [o, o + 1, o + 2])
            .collect()
    }

    /// The slide `d = (r_Pj − r_Pi) · R(φ_i) u_i` \[m\] at `q`, and its
    /// gradient over [`Slide::columns`] into `grad` (exact).
    pub fn eval(&self, q: &[f64], grad: &mut [f64]) -> f64 {
        let (ri, rj) = (origin(q, self.i.body), origin(q, self.j.body));
        let (ai, dai) = rotated(q, self.i.body, self.i.point);
        let (aj, daj) = rotated(q, self.j.body, self.j.point);
        let (u, du) = rotated(q, self.i.body, self.u_i);
        let d = [rj[0] + aj[0] - ri[0] - ai[0], rj[1] + aj[1] - ri[1] - ai[1]];
        let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
        let mut k = 0;
        if self.i.body.offset().is_some() {
            grad[0] = -u[0];
            grad[1] = -u[1];
            grad[2] = -dot(u, dai) + dot(d, du);
            k = 3;
        }
        if self.j.body.offset().is_some() {
            grad[k] = u[0];
            grad[k + 1] = u[1];
            grad[k + 2] = dot(u, daj);
        }
        dot(d, u)
    }
}

/// `R(φ) s` and `∂(R(φ) s)/∂φ` (the ground: `s` and 0).
fn rotated(q: &[f64], b: BodyRef, s: [f64; 2]) -> ([f64; 2], [f64; 2]) {
    match b.offset() {
        None => (s, [0.0; 2]),
        Some(o) => {
            let a = rotate(q[o + 2], s);
            (a, perp(a))
        }
    }
}

/// The position of body `b`'s origin (the ground's: 0).
fn origin(q: &[f64], b: BodyRef) -> [f64; 2] {
    b.offset().map_or([0.0; 2], |o| [q[o], q[o + 1]])
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The slide from its definition, `(r_j + R(φ_j) s_j − r_i − R(φ_i) s_i) · R(φ_i) u_i`.
    fn slide_by_definition(s: &Slide, q: &[f64]) -> f64 {
        let point = |b: BodyRef, p: [f64; 2]| match b.offset() {
            None => p,
            Some(o) => {
                let a = rotate(q[o + 2], p);
                [q[o] + a[0], q[o + 1] + a[1]]
            }
        };
        let u = s.i.body.offset().map_or(s.u_i, |o| rotate(q[o + 2], s.u_i));
        let (pi, pj) = (point(s.i.body, s.i.point), point(s.j.body, s.j.point));
        u[0] * (pj[0] - pi[0]) + u[1] * (pj[1] - pi[1])
    }

    #[test]
    fn slide_and_its_gradient_match_the_definition_and_central_differences() {
        let q = [0.3, -0.2, 0.7, 1.1, 0.4, -1.3];
        let (sn, cs) = 0.4_f64.sin_cos();
        for body_i in [BodyRef::Body(0), BodyRef::Ground] {
            let s = Slide {
                i: BodyPoint::new(body_i, [0.25, -0.1]),
                u_i: [cs, sn],
                j: BodyPoint::new(BodyRef::Body(1), [-0.15, 0.05]),
            };
            let cols = s.columns();
            let mut grad = [0.0; 6];
            let d = s.eval(&q, &mut grad);
            assert!((d - slide_by_definition(&s, &q)).abs() < 1e-15);
            let h = 1e-6;
            for (k, &c) in cols.iter().enumerate() {
                let (mut up, mut dn) = (q, q);
                up[c] += h;
                dn[c] -= h;
                let fd = (slide_by_definition(&s, &up) - slide_by_definition(&s, &dn)) / (2.0 * h);
                assert!(
                    (grad[k] - fd).abs() < 1e-9,
                    "column {c}: {} vs {fd}",
                    grad[k]
                );
            }
            assert_eq!(cols.len(), if body_i == BodyRef::Ground { 3 } else { 6 });
        }
    }
}
