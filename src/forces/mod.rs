//! Force elements: contributions to the generalized forces g(q, q̇, t) of
//! eq. (5), each with its sparse footprint and (for implicit methods) its
//! Jacobians ∂g/∂q and ∂g/∂q̇.
//!
//! Users add their own forces by implementing [`ForceElement`] (defined in
//! [`crate::model`] with [`FdWorkspace`] and [`Gravity`], re-exported here),
//! or as a closure in a [`CallbackForce`] (also on a built system:
//! [`crate::model::System::add_force`]).

mod applied;
mod buoyancy;
mod callback;
mod contact;
mod drag;
mod expression;
mod half_plane;
mod law;
mod relative_angle;
mod road;
mod rotational;
mod spring;
mod torsional;

pub use applied::{AppliedForce, AppliedTorque};
pub use buoyancy::Buoyancy;
pub use callback::{CallbackError, CallbackForce, CallbackLaw};
pub(crate) use contact::Clearance;
pub use contact::{ContactLaw, CornerState, Wall, WallContact};
pub(crate) use drag::drag_force;
pub use drag::Drag;
pub use expression::{ExpressionError, ExpressionLoad, ExpressionLoadBuilder, LinePoint};
pub use half_plane::HalfPlaneContact;
pub use law::Law;
pub use road::RoadContact;
pub use rotational::RotationalSpringDamper;
pub use spring::PointSpringDamper;
pub use torsional::TorsionalSpringDamper;

pub use crate::model::{
    check_coordinates, BodyLoads, FdWorkspace, ForceElement, ForceJacobians, Gravity,
};

use crate::model::{BodyRef, ModelError};

/// The parameter checks of one force element's `validate`: each failure is
/// a [`ModelError::InvalidParameter`] naming the element, field and value.
pub(crate) struct Check<'a> {
    /// The element's name ([`ForceElement::name`]).
    pub(crate) element: &'a str,
}

impl Check<'_> {
    /// The error for `field` = `value`, invalid because `why`.
    pub(crate) fn fail(&self, field: &str, value: String, why: &str) -> ModelError {
        ModelError::InvalidParameter {
            element: self.element.to_string(),
            field: field.into(),
            value,
            why: why.into(),
        }
    }

    /// `v` is finite.
    pub(crate) fn finite(&self, field: &str, v: f64) -> Result<(), ModelError> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(self.fail(field, v.to_string(), "must be finite"))
        }
    }

    /// Both coordinates of the point `p` are finite.
    pub(crate) fn finite_point(&self, field: &str, p: [f64; 2]) -> Result<(), ModelError> {
        if p.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(self.fail(field, format!("{p:?}"), "must be finite"))
        }
    }

    /// `v` is finite and `> 0` (`strict`) or `>= 0`.
    pub(crate) fn sign(&self, field: &str, v: f64, strict: bool) -> Result<(), ModelError> {
        if v.is_finite() && if strict { v > 0.0 } else { v >= 0.0 } {
            Ok(())
        } else if strict {
            Err(self.fail(field, v.to_string(), "must be finite and > 0"))
        } else {
            Err(self.fail(field, v.to_string(), "must be finite and >= 0"))
        }
    }

    /// Each `(field, value)` is finite and `> 0`, checked in order.
    pub(crate) fn positive(&self, fields: &[(&str, f64)]) -> Result<(), ModelError> {
        fields.iter().try_for_each(|&(f, v)| self.sign(f, v, true))
    }

    /// Each `(field, value)` is finite and `>= 0`, checked in order.
    pub(crate) fn non_negative(&self, fields: &[(&str, f64)]) -> Result<(), ModelError> {
        fields.iter().try_for_each(|&(f, v)| self.sign(f, v, false))
    }

    /// A spring–damper's two bodies differ.
    pub(crate) fn two_bodies(&self, i: BodyRef, j: BodyRef) -> Result<(), ModelError> {
        if i == j {
            Err(self.fail(
                "bodies",
                format!("{i:?}"),
                "a spring-damper must connect two different bodies",
            ))
        } else {
            Ok(())
        }
    }
}
