//! The joints: constraint equations Φ(q, t) = 0 and their derivatives.
//!
//! Every joint implements [`Constraint`] (defined in [`crate::model`], beside
//! [`crate::model::System`], and re-exported here): Φ, the structural
//! non-zeros of Φ_q (a fixed sparse pattern, values written in pattern
//! order), Φ_t, and γ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt, the right-hand side
//! of the acceleration equation Φ_q q̈ = γ (paper, eq. (4)–(5)); for implicit
//! integrators also (Φ_qᵀ λ)_q.

mod driving;
mod revolute;
mod translational;

pub use driving::{expression_motion, spline_motion, DriveCoordinate, DriveRelativeAngle, Spline};
pub use revolute::Revolute;
pub use translational::Translational;

pub(crate) use crate::model::check_bodies;
use crate::model::{BodyRef, ModelError};
pub use crate::model::{Constraint, JointGeometry};

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

/// The Φ_q pattern of a joint between two bodies: for each body that is
/// not the ground (`bodies[0]` first), the entries `(row, o + k)` of
/// `entries = [(row, k); 4]`, `o` the body's first coordinate.
pub(crate) fn two_body_pattern(
    bodies: [BodyRef; 2],
    entries: [(usize, usize); 4],
) -> Vec<(usize, usize)> {
    let mut p = Vec::with_capacity(8);
    for o in bodies.iter().filter_map(|b| b.offset()) {
        p.extend(entries.iter().map(|&(row, k)| (row, o + k)));
    }
    p
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
