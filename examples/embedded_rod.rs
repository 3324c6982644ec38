//! Embedding the finite-segment rod in a larger model (library API):
//!
//! * a carriage body driven along a prescribed path (rheonomic drives of
//!   x, y and φ),
//! * the rod of problem B (docs/problems.md) (20 segments, in water, no walls) hanging from
//!   the carriage by a revolute joint,
//! * a tip mass pinned to the rod's free end,
//! * a user-written force element: a linear tether spring–damper pulling the
//!   tip mass towards a ground anchor.
//!
//! `cargo run --release --example embedded_rod`

use mbsolve::builders::{add_rod, RodParams};
use mbsolve::constraints::{DriveCoordinate, Revolute};
use mbsolve::forces::ForceElement;
use mbsolve::formulation::{consistent_initial_state, InitialOptions};
use mbsolve::integrate::Method;
use mbsolve::model::{Body, BodyRef, SystemBuilder, TimeFunction};
use mbsolve::simulation::{simulate, RunConfig};
use std::f64::consts::PI;

/// A user force element: spring–damper between a body's centre and a fixed
/// anchor, `F = −k (r − a) − c ṙ`.
#[derive(Debug)]
struct Tether {
    body: usize,
    anchor: [f64; 2],
    k: f64,
    c: f64,
}

impl ForceElement for Tether {
    fn name(&self) -> String {
        "tether".into()
    }
    fn coordinates(&self) -> Vec<usize> {
        vec![3 * self.body, 3 * self.body + 1]
    }
    fn add_forces(&self, _t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let o = 3 * self.body;
        for d in 0..2 {
            g[o + d] += -self.k * (q[o + d] - self.anchor[d]) - self.c * qd[o + d];
        }
    }
    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        let o = 3 * self.body;
        let d2: f64 = (0..2).map(|d| (q[o + d] - self.anchor[d]).powi(2)).sum();
        Some(0.5 * self.k * d2)
    }
}

fn main() {
    let mut b = SystemBuilder::new();
    // The carriage oscillates horizontally at the top of the rod.
    let carriage = b.add_body(Body::new("carriage", 2.0, 0.01, [0.0, 0.5, 0.0]));
    b.add_constraint(DriveCoordinate::new(
        "carriage x",
        carriage,
        0,
        TimeFunction::Harmonic {
            amplitude: 0.05,
            omega: 2.0 * PI,
            phase: 0.0,
            offset: 0.0,
        },
    ));
    b.add_constraint(DriveCoordinate::new(
        "carriage y",
        carriage,
        1,
        TimeFunction::Constant(0.5),
    ));
    b.add_constraint(DriveCoordinate::new(
        "carriage φ",
        carriage,
        2,
        TimeFunction::Constant(0.0),
    ));

    // The rod hangs down: φ = π turns the local y axis downwards, so
    // segment 1 is at the top, its "bottom" end at (0, 0.5).
    let mut p = RodParams::problem_b(20);
    p.tilt = PI;
    p.initial_velocity = [0.0, 0.0];
    p.contact = false;
    p.channel_width = 1.0;
    p.gravity = 9.81; // buoyancy
    let rod = add_rod(&mut b, &p).expect("rod parameters are valid");
    let ls = rod.segment_length;
    let (top, bottom) = (rod.bodies[0], *rod.bodies.last().unwrap());
    b.add_constraint(Revolute::new(
        "hanger",
        BodyRef::Body(carriage),
        [0.0, 0.0],
        BodyRef::Body(top),
        [0.0, -ls / 2.0],
    ));
    // Tip mass at the free end (0, −0.5).
    let tip = b.add_body(Body::new("tip", 0.5, 1e-4, [0.0, -0.5, 0.0]));
    b.add_constraint(Revolute::new(
        "tip pin",
        BodyRef::Body(bottom),
        [0.0, ls / 2.0],
        BodyRef::Body(tip),
        [0.0, 0.0],
    ));
    b.add_force(Tether {
        body: tip,
        anchor: [0.1, -0.6],
        k: 50.0,
        c: 2.0,
    });
    b.gravity([0.0, -9.81]);
    let sys = b.build().expect("the model is valid");

    // Consistent start: the carriage drives fix its state; everything else
    // is corrected onto Φ = 0, Φ_q q̇ = −Φ_t.
    let (q, qd) = sys.initial_state();
    let ic = consistent_initial_state(&sys, 0.0, &q, &qd, &[], InitialOptions::default())
        .expect("assembles");
    println!(
        "assembled: ‖Φ‖ = {:.1e}, ‖Φ_q q̇ + Φ_t‖ = {:.1e}",
        ic.position_residual, ic.velocity_residual
    );

    let cfg = RunConfig {
        method: Method::Ode45,
        t0: 0.0,
        t_end: 1.0,
        output_dt: 0.1,
        ode: Default::default(),
        formulation: Default::default(),
        ..Default::default()
    };
    let (traj, s) = simulate(&sys, &ic.q, &ic.qd, &cfg, &mut []).expect("runs");
    for (k, t) in traj.t.iter().enumerate() {
        let q = &traj.q[k];
        println!(
            "t = {t:.1} s: carriage x = {:+.4} m, tip at ({:+.4}, {:+.4}) m, ‖Φ‖ = {:.1e}",
            q[3 * carriage],
            q[3 * tip],
            q[3 * tip + 1],
            traj.constraint_norm[k]
        );
    }
    println!(
        "{}: {} steps ({} failed), {} RHS evaluations, {:.3} s",
        s.status, s.steps, s.failed_steps, s.rhs_evals, s.wall_s
    );
}
