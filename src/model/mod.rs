//! The multibody model: what is simulated, independent of how.
//!
//! Planar rigid bodies in reference-point coordinates `q_i = [x_i, y_i, φ_i]`
//! (centre of mass and rotation of the body frame), the [`Constraint`]
//! trait of joints that become constraint equations Φ(q, t) = 0 (the joints:
//! [`crate::constraints`]), the [`ForceElement`] trait of elements that
//! contribute to the generalized forces g(q, q̇, t) (the elements:
//! [`crate::forces`]), uniform [`Gravity`], and the [`System`] that fixes
//! their numbering, and the terms of the energy balance (`energy.rs`:
//! [`System::mechanical_energy`], [`System::nonconservative_power`],
//! [`System::constraint_power`]). `model` imports nothing from the rest of the crate:
//! joints and forces build on it, not the other way round.

mod body;
mod constraint;
mod energy;
mod force;
mod gravity;
mod reaction;
mod sensor;
mod system;
mod time_function;

pub use body::{Body, BodyPoint, BodyRef};
pub(crate) use constraint::touched_columns;
pub use constraint::{check_bodies, Constraint, JointGeometry, Slide};
pub use energy::EnergyWorkspace;
pub use force::{
    check_coordinates, BodyLoads, FdWorkspace, ForceElement, ForceGeometry, ForceJacobians,
};
pub use gravity::Gravity;
pub use reaction::ReactionMap;
pub(crate) use sensor::evaluate_sensors;
pub use sensor::joint_short_name;
pub use sensor::{drives, Drive, Sensor, SensorKind};
pub use system::{
    BodyTrig, ConstraintKernels, ConstraintTerms, Evaluation, ForceKernels, HalfTask,
    ResidualHalves, State, StateView, System, SystemBuilder,
};
pub use time_function::TimeFunction;

/// Rotation matrix R(φ) applied to a body-fixed vector `s`: `R(φ) s`.
#[inline]
pub fn rotate(phi: f64, s: [f64; 2]) -> [f64; 2] {
    let (sn, cs) = phi.sin_cos();
    [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]]
}

/// `J v` with `J = [[0, −1], [1, 0]]` (rotation by +90°): `∂(R(φ)s)/∂φ = J R(φ) s`.
#[inline]
pub(crate) fn perp(v: [f64; 2]) -> [f64; 2] {
    [-v[1], v[0]]
}

/// Errors in building a model.
#[derive(Debug, Clone, thiserror::Error)]
pub enum ModelError {
    /// A body parameter is invalid.
    #[error("body '{body}': {field} = {value} is invalid: {why}")]
    InvalidBody {
        /// Body name.
        body: String,
        /// Offending field.
        field: &'static str,
        /// Offending value.
        value: f64,
        /// Why it is invalid.
        why: &'static str,
    },
    /// A joint or force element refers to a body that does not exist.
    #[error("{element}: refers to body index {index}, but the system has {n_bodies} bodies")]
    MissingBody {
        /// Element description.
        element: String,
        /// The index referred to.
        index: usize,
        /// Bodies in the system.
        n_bodies: usize,
    },
    /// A model parameter is invalid.
    #[error("{element}: {field} = {value} is invalid: {why}")]
    InvalidParameter {
        /// Element description.
        element: String,
        /// Offending field.
        field: String,
        /// Offending value.
        value: String,
        /// Why it is invalid.
        why: String,
    },
    /// The system has no bodies.
    #[error("the system has no bodies")]
    Empty,
}
