//! Ready-made models: the falling flexible rod of problem B (docs/problems.md) (segments,
//! joints, bending springs, buoyancy, drag, wall contact) and the known-answer
//! chains of problem D (docs/problems.md) (finite-segment cantilever, N-link pendulum).

mod rod;
pub use rod::*;
