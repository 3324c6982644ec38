//! Analyses beside time integration, on the same [`crate::model::System`]
//! and saddle-point solves: the linearised state-space model about a state
//! ([`linearize`]) and kinematics with inverse dynamics of fully driven
//! mechanisms ([`inverse`]).

pub mod inverse;
pub mod linearize;
