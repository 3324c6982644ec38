//! Problem D's cantilever (docs/problems.md, §D): the rod of problem B
//! (`RodParams::problem_b`) pinned to the ground at the bottom of segment 1
//! with a torsional spring of the joints' stiffness, no fluid, contact or
//! gravity (`builders::cantilever`).

use mbsolve::builders::{cantilever, RodParams};
use mbsolve::model::System;

/// The `n`-segment cantilever standing straight along `tilt` \[rad\]
/// (0: up, π: hanging down, −π/2: along +x) with the constant global force
/// `tip_load` \[N\] at its free end: the system, its straight rest state q0
/// and the parameters.
pub fn cantilever_at(n: usize, tilt: f64, tip_load: [f64; 2]) -> (System, Vec<f64>, RodParams) {
    let mut p = RodParams::problem_b(n);
    p.tilt = tilt;
    let (sys, _) = cantilever(&p, tip_load).unwrap();
    let (q0, _) = sys.initial_state();
    (sys, q0, p)
}
