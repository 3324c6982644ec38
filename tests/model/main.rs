//! Integration tests of the model: force elements and their Jacobians, the rod of
//! problem B, the cantilever of problem D, contact events, expression loads, the
//! generated kernels against the generic evaluation, energies.

#[path = "../common/mod.rs"]
mod common;

// The counting global allocator of the allocation-free tests (one per binary).
#[path = "../common/counting.rs"]
mod counting;

mod beam;
mod codegen;
mod contact_events;
mod contact_onsets;
mod contact_report;
mod energy;
mod expression;
mod force_elements;
mod rod_dynamics;
mod rod_forces;
mod spring_pendulum;
