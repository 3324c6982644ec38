//! Ready-made models: the falling flexible rod of PROBLEMS.md B (segments,
//! joints, bending springs, buoyancy, drag, wall contact) and the known-answer
//! chains of PROBLEMS.md D (finite-segment cantilever, N-link pendulum).

mod rod;
pub use rod::*;
