//! Integration tests of the analyses: statics, eigenmodes, linearisation, inverse
//! dynamics, partitioning and the tangent matrices, against independent references.

#[path = "../common/mod.rs"]
mod common;

mod chain_lu;
mod inverse;
mod linearize;
mod modes;
mod partitioning;
mod states;
mod statics;
mod tangent;
