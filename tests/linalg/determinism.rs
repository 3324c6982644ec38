//! Same input, same output, whatever the thread count.

use mbsolve::builders::{build_rod, RodParams};
use mbsolve::integrate::{Method, OdeOptions};
use mbsolve::model::System;
use mbsolve::parallel::PARALLEL_MIN_COORDS;
use mbsolve::simulation::{simulate, RunConfig, Summary, Trajectory};

/// `simulate` in a rayon pool of `threads` threads; the run must complete.
fn run_in_pool(threads: usize, sys: &System, cfg: &RunConfig) -> (Trajectory, Summary) {
    let (q0, qd0) = sys.initial_state();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (traj, s) = pool.install(|| simulate(sys, &q0, &qd0, cfg, &mut []).unwrap());
    assert_eq!(s.status, "completed", "{:?}", s.message);
    (traj, s)
}

/// The same output times and the same bits of every q and q̇.
fn assert_same_bits(a: &Trajectory, b: &Trajectory) {
    assert_eq!(a.t, b.t);
    for (qa, qb) in a.q.iter().zip(&b.q).chain(a.qd.iter().zip(&b.qd)) {
        for (x, y) in qa.iter().zip(qb) {
            assert_eq!(x.to_bits(), y.to_bits());
        }
    }
}

#[test]
fn rod_trajectory_is_bit_identical_with_one_and_two_threads() {
    // Large enough that forces and constraint terms run concurrently.
    let n = PARALLEL_MIN_COORDS / 3 + 10;
    let (sys, _) = build_rod(&RodParams::problem_b(n)).unwrap();
    let cfg = RunConfig {
        method: Method::Rk4,
        ode: OdeOptions {
            // Stable for RK4: at N ≈ 2000 the joint damping c = 1e-5 s·k gives
            // the zig-zag mode a real eigenvalue ≈ −4e9 /s, so h < 6.5e-10.
            fixed_step: Some(2.5e-10),
            ..Default::default()
        },
        t0: 0.0,
        t_end: 2e-9,
        output_dt: 1e-9,
        formulation: Default::default(),
        ..Default::default()
    };
    let ((a, _), (b, _)) = (run_in_pool(1, &sys, &cfg), run_in_pool(2, &sys, &cfg));
    assert_same_bits(&a, &b);
    // and the run moved: the rod's centre started to fall at about
    // g (1 − ρ_w/ρ) (drag from the 0.1 m/s sideways motion adds ~1e-5)
    let mean_vy = (0..n).map(|i| a.qd.last().unwrap()[3 * i + 1]).sum::<f64>() / n as f64;
    let expect = -9.81 * (1.0 - 1000.0 / 7850.0) * 2e-9;
    assert!(
        (mean_vy / expect - 1.0).abs() < 1e-3,
        "{mean_vy:e} vs {expect:e}"
    );
}

/// radau5 with a flight step on the rod (its contact onsets asked at every
/// grid point, the flight steps' Newton matrices besides the step's): the
/// same bits with one and two threads, and flight steps were taken.
#[test]
fn rod_radau5_with_a_flight_step_is_bit_identical_with_one_and_two_threads() {
    let n = PARALLEL_MIN_COORDS / 3 + 10;
    let (sys, _) = build_rod(&RodParams::problem_b(n)).unwrap();
    let mut cfg = RunConfig {
        method: Method::Radau5,
        ode: OdeOptions {
            fixed_step: Some(1e-4),
            ..Default::default()
        },
        t_end: 4e-3,
        output_dt: 1e-3,
        ..Default::default()
    };
    cfg.implicit.flight_step = Some(5e-4);
    let ((a, sa), (b, sb)) = (run_in_pool(1, &sys, &cfg), run_in_pool(2, &sys, &cfg));
    let (steps_a, steps_b) = (sa.steps, sb.steps);
    assert_eq!(steps_a, steps_b);
    // 40 steps of 1e-4 without the flight step
    assert!(steps_a < 20, "{steps_a} steps");
    assert_same_bits(&a, &b);
}

/// The stability check's power iteration (`fastest_modes`) on a chain
/// whose element-wise passes run in two halves (3·2000 coordinates, at
/// least `PARALLEL_MIN_COORDS`) and whose chain solves are two-sided
/// (dimension 10 000): the same bits of every rate in a pool of one
/// thread and of two, and a positive, finite stiffest mode.
#[test]
fn fastest_modes_are_bit_identical_with_one_and_two_threads() {
    let (sys, q0, qd0, _) = mbsolve::builders::stiff_chain(2000, 5f64.to_radians()).unwrap();
    assert!(sys.n_coords() >= PARALLEL_MIN_COORDS);
    let modes = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| mbsolve::formulation::fastest_modes(&sys, 0.0, &q0, &qd0, 60).unwrap())
    };
    let (a, b) = (modes(1), modes(2));
    assert!(a.omega > 0.0 && a.omega.is_finite(), "{a:?}");
    for (x, y) in [(a.omega, b.omega), (a.sigma, b.sigma), (a.growth, b.growth)] {
        assert_eq!(x.to_bits(), y.to_bits(), "{a:?} {b:?}");
    }
    assert_eq!(a.sources, b.sources);
}
