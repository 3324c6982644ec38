//! Generalized-α on the index-3 equations: order, dissipation, agreement
//! with ode45 on problem B, constraint drift, failure semantics.

use mbsolve::builders::{build_rod, n_link_pendulum, RodParams};
use mbsolve::events::ContactMonitor;
use mbsolve::forces::TorsionalSpringDamper;
use mbsolve::formulation::{consistent_initial_state, InitialOptions};
use mbsolve::integrate::{
    integrator, AlphaParameters, ImplicitOptions, IntegratorError, Method, OdeOptions, Tolerance,
};
use mbsolve::model::{Body, BodyRef, System, SystemBuilder};
use mbsolve::simulation::{simulate, Monitor, RunConfig, Trajectory};

fn implicit(method: Method, h: f64, t_end: f64, dt: f64, opts: ImplicitOptions) -> RunConfig {
    RunConfig {
        method,
        t_end,
        output_dt: dt,
        ode: OdeOptions {
            fixed_step: Some(h),
            ..Default::default()
        },
        implicit: opts,
        ..Default::default()
    }
}

fn ode45(rtol: f64, atol: f64, t_end: f64, dt: f64) -> RunConfig {
    crate::common::setup::adaptive(Method::Ode45, rtol, atol, t_end, dt)
}

/// max over output times and the given coordinates of |a − b|.
fn max_diff(a: &Trajectory, b: &Trajectory, coords: &[usize]) -> f64 {
    assert_eq!(a.t.len(), b.t.len());
    let mut e: f64 = 0.0;
    for k in 0..a.t.len() {
        assert!((a.t[k] - b.t[k]).abs() < 1e-12);
        for &c in coords {
            e = e.max((a.q[k][c] - b.q[k][c]).abs());
        }
    }
    e
}

fn run(sys: &System, q0: &[f64], qd0: &[f64], cfg: &RunConfig) -> Trajectory {
    crate::common::setup::completed(sys, q0, qd0, cfg).0
}

/// Errors for h, h/2, h/4, … against a reference, and their ratios.
#[allow(clippy::too_many_arguments)]
fn convergence(
    sys: &System,
    q0: &[f64],
    qd0: &[f64],
    reference: &Trajectory,
    h0: f64,
    levels: usize,
    t_end: f64,
    dt: f64,
    opts: &ImplicitOptions,
) -> Vec<f64> {
    let all: Vec<usize> = (0..sys.n_coords()).collect();
    (0..levels)
        .map(|l| {
            let h = h0 / f64::from(1u32 << l);
            let cfg = implicit(Method::GenAlpha, h, t_end, dt, opts.clone());
            max_diff(&run(sys, q0, qd0, &cfg), reference, &all)
        })
        .collect()
}

/// Ratios of consecutive errors as h halves.
fn ratios(e: &[f64]) -> Vec<f64> {
    e.windows(2).map(|w| w[0] / w[1]).collect()
}

#[test]
fn second_order_on_the_n_link_pendulum() {
    // problem D (docs/problems.md), 3 links swinging from 0.5 rad; reference ode45 at rtol 1e-11.
    let (sys, _) = n_link_pendulum(3, 0.5, 1.0, 0.5, 9.81).unwrap();
    let (q0, qd0) = sys.initial_state();
    let reference = run(&sys, &q0, &qd0, &ode45(1e-11, 1e-13, 1.0, 0.05));
    for rho in [1.0, 0.8, 0.5] {
        let o = ImplicitOptions {
            rho_inf: rho,
            ..Default::default()
        };
        let e = convergence(&sys, &q0, &qd0, &reference, 0.01, 4, 1.0, 0.05, &o);
        let r = ratios(&e);
        assert!(e[0] < 5e-3, "rho {rho}: {e:?}");
        for x in &r {
            assert!(
                (3.6..4.4).contains(x),
                "rho {rho}: errors {e:?}, ratios {r:?}"
            );
        }
    }
}

/// Problem B's rod without fluid and contact, softened (E = 2.1e7) so that
/// the bending is resolved, started with a bending velocity field.
fn soft_bending_rod(n: usize) -> (System, Vec<f64>, Vec<f64>) {
    let mut p = RodParams::problem_b(n);
    p.fluid = false;
    p.contact = false;
    p.youngs_modulus = 2.1e7;
    let (sys, _) = build_rod(&p).unwrap();
    let (q0, mut qd0) = sys.initial_state();
    for i in 0..n {
        qd0[3 * i + 2] = 2.0 * (1.0 + (i as f64 * 1.7).sin());
    }
    // keep x, y of segment 1 and every φ̇; the joints fix the other velocities
    let mut independent = vec![0, 1];
    independent.extend((0..n).map(|i| 3 * i + 2));
    let c = consistent_initial_state(
        &sys,
        0.0,
        &q0,
        &qd0,
        &independent,
        InitialOptions::default(),
    )
    .unwrap();
    (sys, c.q, c.qd)
}

#[test]
fn second_order_on_the_rod_without_contact_and_fluid() {
    let (sys, q0, qd0) = soft_bending_rod(4);
    let reference = run(&sys, &q0, &qd0, &ode45(1e-11, 1e-13, 0.5, 0.025));
    let o = ImplicitOptions::default();
    let e = convergence(&sys, &q0, &qd0, &reference, 4e-3, 4, 0.5, 0.025, &o);
    let r = ratios(&e);
    assert!(e[0] < 1e-2, "{e:?}");
    for x in &r {
        assert!((3.5..4.5).contains(x), "errors {e:?}, ratios {r:?}");
    }
}

/// One body on a torsional spring to the ground: φ̈ = −ω² φ with ω = 1e5 rad/s.
fn oscillator() -> System {
    let mut b = SystemBuilder::new();
    let body = b.add_body(Body::new("rotor", 1.0, 1.0, [0.0, 0.0, 1e-3]));
    b.add_force(TorsionalSpringDamper::new(
        BodyRef::Ground,
        BodyRef::Body(body),
        1e10,
        0.0,
    ));
    b.build().unwrap()
}

/// Decay per step of φ at ωh = 1e5, from the envelope (max |φ| over 10
/// steps) between steps 100 and 200, and the envelope after step 3.
fn decay_per_step(method: Method, rho: f64) -> (f64, f64) {
    let sys = oscillator();
    let (q0, qd0) = sys.initial_state();
    let cfg = implicit(
        method,
        1.0,
        220.0,
        1.0,
        ImplicitOptions {
            rho_inf: rho,
            ..Default::default()
        },
    );
    let traj = run(&sys, &q0, &qd0, &cfg);
    let phi: Vec<f64> = traj.q.iter().map(|q| q[2].abs()).collect();
    let env = |k: usize| phi[k..k + 10].iter().cloned().fold(0.0, f64::max);
    let rate = if env(100) > 0.0 {
        (env(200) / env(100)).powf(0.01)
    } else {
        0.0
    };
    (rate, phi[3..].iter().cloned().fold(0.0, f64::max) / phi[0])
}

#[test]
fn numerical_dissipation_follows_rho_inf() {
    for rho in [0.5, 0.8] {
        let (rate, _) = decay_per_step(Method::GenAlpha, rho);
        // the triple eigenvalue −ρ∞ adds a factor n² (~1.4 % per step here)
        assert!(
            rate >= rho * 0.99 && rate <= rho * 1.03,
            "generalized-α rho {rho}: decay per step {rate}"
        );
    }
    // ρ∞ = 0 annihilates the unresolved mode within a few steps
    let (rate, after3) = decay_per_step(Method::GenAlpha, 0.0);
    assert!(after3 < 1e-8 && rate < 0.05, "rho 0: {after3:e}, {rate}");
    // the HHT and Newmark members have the same high-frequency limit
    for (method, rho) in [(Method::Hht, 0.6), (Method::Newmark, 0.5)] {
        let (rate, _) = decay_per_step(method, rho);
        assert!(
            rate >= rho * 0.99 && rate <= rho * 1.03,
            "{method} rho {rho}: decay per step {rate}"
        );
    }
    // no dissipation at ρ∞ = 1 (trapezoidal limit)
    let (rate, _) = decay_per_step(Method::GenAlpha, 1.0);
    assert!((rate - 1.0).abs() < 1e-3, "rho 1: {rate}");
}

/// x of segments 1, N/2 and N of problem B, N = 10.
fn problem_b_x(info: &mbsolve::builders::RodInfo) -> Vec<usize> {
    let n = info.bodies.len();
    [0, n / 2 - 1, n - 1]
        .iter()
        .map(|&i| 3 * info.bodies[i])
        .collect()
}

#[test]
fn agrees_with_ode45_on_problem_b() {
    let (sys, info) = build_rod(&RodParams::problem_b(10)).unwrap();
    let (q0, qd0) = sys.initial_state();
    let t_end = 0.3;
    let reference = run(&sys, &q0, &qd0, &ode45(1e-9, 1e-12, t_end, 0.01));
    let xs = problem_b_x(&info);
    // fixed step
    let cfg = implicit(
        Method::GenAlpha,
        1e-4,
        t_end,
        0.01,
        ImplicitOptions::default(),
    );
    let mut mon = ContactMonitor::new(info.clone());
    let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut [&mut mon as &mut dyn Monitor]).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    let e = max_diff(&traj, &reference, &xs);
    assert!(e < 3e-4, "fixed h = 1e-4: max |Δx| = {e:e}");
    assert!(mon.first_contact().is_some(), "the rod reaches a wall");
    // adaptive steps
    let mut cfg = implicit(
        Method::GenAlpha,
        1e-4,
        t_end,
        0.01,
        ImplicitOptions {
            adaptive: true,
            ..Default::default()
        },
    );
    cfg.ode.fixed_step = None;
    cfg.ode.rtol = 1e-5;
    cfg.ode.atol = Tolerance::Scalar(1e-8);
    let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    let e = max_diff(&traj, &reference, &xs);
    assert!(e < 3e-4, "adaptive rtol 1e-5: max |Δx| = {e:e}");
}

#[test]
fn constraints_hold_to_the_newton_tolerance() {
    let (sys, _) = build_rod(&RodParams::problem_b(10)).unwrap();
    let (q0, qd0) = sys.initial_state();
    let h = 2.5e-4;
    for (tol, project, check) in [
        (1e-6, false, false),
        (1e-2, false, false),
        (1e-2, false, true),
        (1e-6, true, false),
    ] {
        let o = ImplicitOptions {
            newton_tol: tol,
            project,
            check_constraints: check,
            ..Default::default()
        };
        let p = AlphaParameters::generalized_alpha(o.rho_inf);
        // the Newton tolerance in position units: tol / β' plus the rounding floor
        let tol_q =
            tol * p.beta * h * h * (1.0 - p.alpha_f) / (1.0 - p.alpha_m) + 20.0 * f64::EPSILON;
        let cfg = implicit(Method::GenAlpha, h, 0.3, 0.005, o);
        let (_, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
        assert_eq!(s.status, "completed", "{:?}", s.message);
        // max over every accepted step and output time (index 3: no drift)
        assert!(
            s.max_constraint_norm <= 10.0 * tol_q,
            "tol {tol:e}: max ‖Φ‖ = {:e} > 10 × {tol_q:e}",
            s.max_constraint_norm
        );
        if project {
            assert!(
                s.max_velocity_constraint_norm < 1e-10,
                "projected: max ‖Φ̇‖ = {:e}",
                s.max_velocity_constraint_norm
            );
            assert!(s.extra["projections"].as_u64().unwrap() >= 1200);
        }
    }
}

#[test]
fn exact_newton_with_sparse_lu_reaches_the_same_solution() {
    // The symmetrised LDLᵀ is a modified Newton method with an exact
    // residual: it converges to the same discrete solution as full Newton
    // on the unsymmetric matrix (faer's sparse LU), through wall contacts.
    let (sys, info) = build_rod(&RodParams::problem_b(10)).unwrap();
    let (q0, qd0) = sys.initial_state();
    let all: Vec<usize> = (0..sys.n_coords()).collect();
    let mut runs = Vec::new();
    for (lu, reuse) in [(false, true), (true, true), (true, false)] {
        let cfg = implicit(
            Method::GenAlpha,
            2.5e-4,
            0.15,
            0.005,
            ImplicitOptions {
                lu,
                reuse,
                ..Default::default()
            },
        );
        let mut mon = ContactMonitor::new(info.clone());
        let (traj, s) =
            simulate(&sys, &q0, &qd0, &cfg, &mut [&mut mon as &mut dyn Monitor]).unwrap();
        assert_eq!(s.status, "completed", "{:?}", s.message);
        assert_eq!(s.linear_solver, if lu { "sparse-lu" } else { "chain-ldlt" });
        assert!(mon.first_contact().is_some());
        runs.push(traj);
    }
    for k in 1..runs.len() {
        let d = max_diff(&runs[0], &runs[k], &all);
        assert!(d < 1e-8, "run {k}: max |Δq| = {d:e}");
    }
}

#[test]
fn a_run_that_cannot_proceed_fails_cleanly_and_keeps_its_output() {
    let (sys, info) = build_rod(&RodParams::problem_b(10)).unwrap();
    let (q0, qd0) = sys.initial_state();
    // step limit
    let mut cfg = implicit(
        Method::GenAlpha,
        1e-3,
        0.04,
        0.005,
        ImplicitOptions::default(),
    );
    cfg.ode.max_steps = 20;
    let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
    assert_eq!(s.status, "failed");
    let msg = s.message.unwrap();
    assert!(msg.contains("maximum number of steps"), "{msg}");
    assert!((s.t_reached - 0.02).abs() < 1e-12, "{}", s.t_reached);
    assert_eq!(traj.t.len(), 5, "{:?}", traj.t);
    assert!((traj.t[4] - 0.02).abs() < 1e-12);
    // Newton limited to one correction at a tolerance below the rounding
    // floor: steps converge only where the predictor is nearly exact, so
    // the step is cut again and again, and at t ≈ 0.048 s it is cut below
    // the minimum; the run stops there with everything before it kept.
    // (At h = 1e-3 the same run crawls at a mean step of 1.2e-5 s and the
    // stall guard stops it first, at 10 × the nominal steps:
    // tests/cli/stream.rs.)
    let cfg = implicit(
        Method::GenAlpha,
        2e-4,
        0.1,
        0.005,
        ImplicitOptions {
            newton_tol: 1e-30,
            max_newton: 1,
            min_step: Some(1e-6),
            // constant-acceleration predictor: exact in free fall
            extrapolate: false,
            ..Default::default()
        },
    );
    let mut mon = ContactMonitor::new(info);
    let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut [&mut mon as &mut dyn Monitor]).unwrap();
    assert_eq!(s.status, "failed");
    let msg = s.message.unwrap();
    assert!(
        msg.contains("below the smallest allowed") && msg.contains("Newton does not converge"),
        "{msg}"
    );
    assert!(s.t_reached > 0.04 && s.t_reached < 0.06, "{}", s.t_reached);
    assert!(crate::common::names_time(&msg, s.t_reached), "{msg}");
    assert_eq!(
        traj.t.len(),
        (s.t_reached / 0.005) as usize + 1,
        "{:?}",
        traj.t
    );
    assert!(*traj.t.last().unwrap() <= s.t_reached);
    assert!(s.failed_steps >= 10, "{}", s.failed_steps);
    // The history-chosen predictor (`extrapolate`) keeps the constant one
    // in the free fall, where extrapolating would only amplify rounding:
    // the run gets as far (before it predicted by extrapolation always,
    // and the free fall took twice the corrections).
    let mut cfg = cfg;
    cfg.implicit.extrapolate = true;
    let (_, s2) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
    assert_eq!(s2.status, "failed");
    assert!(
        s2.t_reached > 0.04,
        "{} (constant: {})",
        s2.t_reached,
        s.t_reached
    );
}

#[test]
fn implicit_methods_parse_validate_and_are_not_ode_integrators() {
    for (name, m) in [
        ("genalpha", Method::GenAlpha),
        ("hht", Method::Hht),
        ("newmark", Method::Newmark),
    ] {
        assert_eq!(name.parse::<Method>().unwrap(), m);
        assert!(
            m.is_generalized_alpha() && Method::ALL.contains(&m) && Method::NAMES.contains(&name)
        );
        assert!(matches!(
            integrator(m, OdeOptions::default()),
            Err(IntegratorError::ImplicitMethod(_))
        ));
    }
    let p = AlphaParameters::generalized_alpha(1.0);
    assert_eq!(
        (p.alpha_m, p.alpha_f, p.gamma, p.beta),
        (0.5, 0.5, 0.5, 0.25)
    );
    let p = AlphaParameters::newmark(1.0);
    assert_eq!(
        (p.alpha_m, p.alpha_f, p.gamma, p.beta),
        (0.0, 0.0, 0.5, 0.25)
    );
    let p = AlphaParameters::hht(0.5);
    assert!((p.alpha_f - 1.0 / 3.0).abs() < 1e-15 && p.alpha_m == 0.0);

    let sys = oscillator();
    let (q0, qd0) = sys.initial_state();
    let bad = |method: Method, (o, h): (ImplicitOptions, Option<f64>)| {
        let cfg = RunConfig {
            method,
            ode: OdeOptions {
                fixed_step: h,
                ..Default::default()
            },
            implicit: o,
            ..Default::default()
        };
        simulate(&sys, &q0, &qd0, &cfg, &mut [])
            .map(|_| ())
            .unwrap_err()
            .to_string()
    };
    let e = bad(Method::GenAlpha, (ImplicitOptions::default(), None));
    assert!(e.contains("step"), "{e}");
    let e = bad(
        Method::GenAlpha,
        (
            ImplicitOptions {
                rho_inf: 1.5,
                ..Default::default()
            },
            Some(1e-3),
        ),
    );
    assert!(e.contains("rho_inf"), "{e}");
    let e = bad(
        Method::Hht,
        (
            ImplicitOptions {
                rho_inf: 0.3,
                ..Default::default()
            },
            Some(1e-3),
        ),
    );
    assert!(e.contains("rho_inf") && e.contains("0.5"), "{e}");
    let e = bad(
        Method::GenAlpha,
        (
            ImplicitOptions {
                newton_tol: 0.0,
                ..Default::default()
            },
            Some(1e-3),
        ),
    );
    assert!(e.contains("newton_tol"), "{e}");
}

#[test]
fn problem_c_at_n_100_runs_the_full_second_with_contacts() {
    // problem C (docs/problems.md) (the rod of B with N = 100 segments); larger N in
    // benches/rod_scaling.rs.
    let (sys, info) = build_rod(&RodParams::problem_b(100)).unwrap();
    let (q0, qd0) = sys.initial_state();
    let cfg = implicit(
        Method::GenAlpha,
        1e-4,
        1.0,
        0.01,
        ImplicitOptions::default(),
    );
    let mut mon = ContactMonitor::new(info);
    let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut [&mut mon as &mut dyn Monitor]).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    assert_eq!(s.steps, 10_000);
    assert_eq!(traj.t.len(), 101);
    assert!(mon.events.iter().filter(|e| e.kind == "start").count() >= 5);
    assert!(s.max_constraint_norm < 1e-12, "{}", s.max_constraint_norm);
    let its = s.extra["newton_iterations"].as_u64().unwrap() as usize;
    assert!(
        its < 4 * s.steps && s.factorizations < s.steps / 10,
        "{its} {}",
        s.factorizations
    );
}
