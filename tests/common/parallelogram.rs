//! The parallelogram-loop chain (`builders::parallelogram_chain`) judged
//! against its one-degree-of-freedom reference (`ParallelogramChain::
//! reference`, a quadrature of the reduced equation, independent of the
//! multibody formulation): distance of the marked point, energy, and the
//! singular crossings the reference passes.

use mbsolve::builders::ParallelogramChain;
use mbsolve::model::System;
use mbsolve::simulation::Trajectory;

/// Step of the reference's quadrature \[s\].
const REFERENCE_STEP: f64 = 1e-4;

/// Singular crossings of the reference (θ through a multiple of π) on a
/// 1 ms grid over `[0, t_end]`.
pub fn crossings(p: &ParallelogramChain, t_end: f64) -> usize {
    let times: Vec<f64> = (0..=(t_end * 1000.0) as usize)
        .map(|k| k as f64 * 1e-3)
        .collect();
    let th = p.reference(&times, REFERENCE_STEP);
    th.windows(2)
        .filter(|w| {
            (w[0].0 / std::f64::consts::PI).floor() != (w[1].0 / std::f64::consts::PI).floor()
        })
        .count()
}

/// Largest distance \[m\] of the marked point from the reference over the
/// trajectory, and the first output time where it exceeds `tol` (if any).
pub fn departure(p: &ParallelogramChain, traj: &Trajectory, tol: f64) -> (f64, Option<f64>) {
    let reference = p.reference(&traj.t, REFERENCE_STEP);
    let mut worst: f64 = 0.0;
    let mut first = None;
    for ((q, t), (th, _)) in traj.q.iter().zip(&traj.t).zip(&reference) {
        let (a, b) = (p.marked_point_of(q), p.marked_point(*th));
        let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
        worst = worst.max(d);
        if d > tol && first.is_none() {
            first = Some(*t);
        }
    }
    (worst, first)
}

/// Largest |E − E₀| \[J\] of the mechanical energy over the trajectory,
/// E₀ the reference's conserved `½ I θ̇₀² + C sin θ₀`
/// (`ParallelogramChain::reduced_energy`).
pub fn energy_drift(p: &ParallelogramChain, sys: &System, traj: &Trajectory) -> f64 {
    let e0 = p.reduced_energy(p.theta0, p.rate0);
    traj.q
        .iter()
        .zip(&traj.qd)
        .map(|(q, qd)| (sys.mechanical_energy(q, qd) - e0).abs())
        .fold(0.0, f64::max)
}

/// Largest distance \[m\] of the marked point from the reference over the
/// trajectory, and the largest relative error of the mechanical energy
/// against the reference's conserved `½ I θ̇₀² + C sin θ₀`.
pub fn branch_errors(p: &ParallelogramChain, sys: &System, traj: &Trajectory) -> (f64, f64) {
    let reference = p.reference(&traj.t, REFERENCE_STEP);
    let e0 = p.reduced_energy(p.theta0, p.rate0);
    let (mut worst, mut de) = (0.0_f64, 0.0_f64);
    for ((q, qd), (th, _)) in traj.q.iter().zip(&traj.qd).zip(&reference) {
        let (a, b) = (p.marked_point_of(q), p.marked_point(*th));
        worst = worst.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
        de = de.max((sys.mechanical_energy(q, qd) - e0).abs() / e0.abs());
    }
    (worst, de)
}
