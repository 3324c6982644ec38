//! Ready-made models: the falling flexible rod of problem B (docs/problems.md) (segments,
//! joints, bending springs, buoyancy, drag, wall contact) and the known-answer
//! chains of problem D (docs/problems.md) (finite-segment cantilever, N-link pendulum);
//! the parallelogram-loop chain through singular configurations with its
//! one-degree-of-freedom reference (docs/constraint_methods.md); a chain
//! of N uniform links with torsional springs and an optional ground pivot
//! (`add_link_chain`, the scenario's `[[chain]]`).

mod chain;
mod known_answer;
mod parallelogram;
mod rod;
mod stiff_chain;
pub use chain::{add_link_chain, ChainInfo, LinkChain};
pub use known_answer::{add_cantilever, cantilever, n_link_pendulum};
pub use parallelogram::{parallelogram_chain, ParallelogramChain};
pub use rod::*;
pub use stiff_chain::{stiff_chain, stiff_chain_reference_tip, stiff_chain_tip_x};
