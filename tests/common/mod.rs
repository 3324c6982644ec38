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

/// Whether `msg` names the time `t` as the library's messages print times
/// (`t = ` and `t` rounded to 12 significant digits): some `t = NUMBER`
/// in it within 1e-11 of `t`, relative.
pub fn names_time(msg: &str, t: f64) -> bool {
    msg.split("t = ").skip(1).any(|rest| {
        let number: String = rest
            .chars()
            .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | '-' | '+'))
            .collect();
        number
            .parse::<f64>()
            .is_ok_and(|v| (v - t).abs() <= 1e-11 * t.abs())
    })
}

/// `max |x − y| / max |y|`.
pub fn rel_diff(x: &[f64], y: &[f64]) -> f64 {
    let d = x
        .iter()
        .zip(y)
        .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
    d / y.iter().fold(0.0f64, |a, v| a.max(v.abs()))
}
