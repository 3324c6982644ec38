//! Fixtures and helpers shared by the test binaries. Each `tests/AREA/main.rs`
//! includes this module with `#[path = "../common/mod.rs"] mod common;`;
//! a binary uses only part of it.
//!
//! `counting.rs` (the counting global allocator) is not part of it: a binary
//! that wants it includes it once, in its `main.rs`.
#![allow(dead_code)]

pub mod cli;
pub mod fourbar;
pub mod linear;
pub mod parallelogram;
pub mod process;
pub mod rod;
pub mod setup;
pub mod stiff_chain;
pub mod trajectory;

/// `max |x − y| / max |y|`.
pub fn rel_diff(x: &[f64], y: &[f64]) -> f64 {
    let d = x
        .iter()
        .zip(y)
        .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
    d / y.iter().fold(0.0f64, |a, v| a.max(v.abs()))
}
