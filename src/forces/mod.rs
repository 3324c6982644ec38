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
mod rotational;
mod spring;
mod torsional;

pub use applied::{AppliedForce, AppliedTorque};
pub use buoyancy::Buoyancy;
pub use callback::{CallbackError, CallbackForce, CallbackLaw};
pub(crate) use contact::Clearance;
pub use contact::{CornerState, Wall, WallContact};
pub(crate) use drag::drag_force;
pub use drag::Drag;
pub use expression::{ExpressionError, ExpressionLoad, ExpressionLoadBuilder, LinePoint};
pub use half_plane::HalfPlaneContact;
pub use law::Law;
pub use rotational::RotationalSpringDamper;
pub use spring::PointSpringDamper;
pub use torsional::TorsionalSpringDamper;

pub use crate::model::{check_coordinates, FdWorkspace, ForceElement, Gravity};
