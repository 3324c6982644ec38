//! Integration tests of the formulations and joints: constraint Jacobians, the
//! constraint-enforcement methods, initial states by joint coordinates, redundant
//! and singular configurations, coordinate partitioning, the four-bar of problem A.

#[path = "../common/mod.rs"]
mod common;

mod constraint_methods;
mod constraints;
mod fourbar;
mod initial_joints;
mod partitioning;
mod redundant;
mod singular;
mod singular_small_steps;
