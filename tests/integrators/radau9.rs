//! radau9 (Radau IIA, five stages, order 9) on the index-3 equations: the
//! observed order of the positions on the pendulum against an independent
//! minimal-coordinate solution, the stiff chain against the peers'
//! reference, dense output on the constraints, bad input.

use crate::common::stiff_chain::{tip_after, T_END};
use mbsolve::builders::{n_link_pendulum, stiff_chain, stiff_chain_reference_tip};
use mbsolve::integrate::Method;
use mbsolve::simulation::{simulate, RunConfig};

/// Gravity of the pendulum \[m/s²\].
const G: f64 = 9.81;

/// The slender pendulum (length 1 m, pinned at its top end) released at
/// `theta0` from rest, in its one angle: `θ̈ = −(3g/2l) sin θ`, by RK4 at
/// 2·10⁵ steps per second (its error ≈ 1e-18 rad, far below radau9's at
/// the steps tested). Returns θ(t).
fn pendulum_angle(theta0: f64, t: f64) -> f64 {
    let k = 1.5 * G;
    let f = |y: [f64; 2]| [y[1], -k * y[0].sin()];
    let steps = (t * 2e5).round() as usize;
    let h = t / steps as f64;
    let mut y = [theta0, 0.0];
    for _ in 0..steps {
        let k1 = f(y);
        let k2 = f([y[0] + 0.5 * h * k1[0], y[1] + 0.5 * h * k1[1]]);
        let k3 = f([y[0] + 0.5 * h * k2[0], y[1] + 0.5 * h * k2[1]]);
        let k4 = f([y[0] + h * k3[0], y[1] + h * k3[1]]);
        for i in 0..2 {
            y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    y[0]
}

/// The largest position error of the pendulum (x, y, φ of its body)
/// released at `theta0` from rest, at `cfg.t_end` against
/// [`pendulum_angle`], and the run's accepted steps.
pub(crate) fn pendulum_run(cfg: &RunConfig, theta0: f64) -> (f64, usize) {
    let (sys, _) = n_link_pendulum(1, 1.0, 1.0, theta0, G).unwrap();
    let (q0, qd0) = sys.initial_state();
    let (traj, s) = simulate(&sys, &q0, &qd0, cfg, &mut []).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    let q = traj.q.last().unwrap();
    let th = pendulum_angle(theta0, cfg.t_end);
    let exact = [0.5 * th.sin(), -0.5 * th.cos(), th];
    let e = q
        .iter()
        .zip(&exact)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    (e, s.steps)
}

/// The largest position error of the pendulum (x, y, φ of its body) at
/// t = 1 s after `method` with the fixed step `h`.
pub(crate) fn pendulum_error(method: Method, h: f64, theta0: f64) -> f64 {
    let mut cfg = RunConfig {
        method,
        t_end: 1.0,
        output_dt: 1.0,
        ..Default::default()
    };
    cfg.ode.fixed_step = Some(h);
    cfg.implicit.newton_tol = 1e-10;
    pendulum_run(&cfg, theta0).0
}

/// The positions converge with order 9 (2s − 1 for s = 5 on index-3
/// problems): on the pendulum released at 70° the observed order from
/// h = 0.1 s to 0.0625 and to 0.05 s is above 7.5 (order 5 would give 5).
/// Larger steps are not yet asymptotic, and at h = 0.025 s the error is at
/// the rounding floor (docs/radau.md).
#[test]
fn pendulum_positions_converge_with_order_nine() {
    let th0 = 70f64.to_radians();
    let hs = [0.1, 0.0625, 0.05];
    let e: Vec<f64> = hs
        .iter()
        .map(|&h| pendulum_error(Method::Radau9, h, th0))
        .collect();
    println!("radau9 pendulum errors at h = {hs:?}: {e:?}");
    for k in 1..3 {
        let order = (e[0] / e[k]).ln() / (hs[0] / hs[k]).ln();
        assert!(
            order > 7.5,
            "observed order {order} from h = 0.1 to {} ({:e} → {:e})",
            hs[k],
            e[0],
            e[k]
        );
    }
    assert!(e[2] < 1e-10, "error at h = 0.05: {:e}", e[2]);
}

/// The stiff chain at N = 100 against the peers' independent reference
/// (SciPy Radau at rtol 1e-10): within 2e-7 m at h = 5e-4 with
/// `newton_tol` = 1e-2 (at `newton_tol` = 1 the Newton remainders
/// dominate the error; docs/radau.md), and the constraints held
/// (‖Φ‖ < 1e-9).
#[test]
fn stiff_chain_n100_against_reference() {
    let r = stiff_chain_reference_tip(100).unwrap();
    let mut cfg = RunConfig {
        method: Method::Radau9,
        t_end: T_END,
        output_dt: T_END / 4.0,
        ..Default::default()
    };
    cfg.ode.fixed_step = Some(5e-4);
    cfg.implicit.newton_tol = 1e-2;
    let (tip, s, _) = tip_after(100, &cfg);
    println!(
        "radau9 N = 100: tip error {:e}, {} steps, {} Newton iterations",
        (tip - r).abs(),
        s.steps,
        s.extra["newton_iterations"]
    );
    assert!((tip - r).abs() < 2e-7, "tip error {:e}", (tip - r).abs());
    assert!(
        s.max_constraint_norm < 1e-9,
        "‖Φ‖ {}",
        s.max_constraint_norm
    );
}

/// Bad input is a clear error: radau9 or radau13 without a step and
/// without `adaptive`, a step with `adaptive`, and in a scenario
/// `integrator.rtol` with a fixed step.
#[test]
fn radau9_and_radau13_take_a_step_or_tolerances() {
    let (sys, q0, qd0, _) = stiff_chain(3, 0.1).unwrap();
    for method in [Method::Radau9, Method::Radau13] {
        let name = method.to_string();
        let mut cfg = RunConfig {
            method,
            t_end: 0.01,
            ..Default::default()
        };
        let e = simulate(&sys, &q0, &qd0, &cfg, &mut [])
            .unwrap_err()
            .to_string();
        assert!(e.contains("fixed_step") && e.contains(&name), "{e}");
        cfg.implicit.adaptive = true;
        cfg.ode.fixed_step = Some(1e-3);
        let e = simulate(&sys, &q0, &qd0, &cfg, &mut [])
            .unwrap_err()
            .to_string();
        assert!(e.contains("fixed_step") && e.contains(&name), "{e}");
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml");
        let set = [
            format!("integrator.method=\"{name}\""),
            "integrator.step=1e-3".to_string(),
            "integrator.rtol=1e-4".to_string(),
        ];
        let Err(e) = mbsolve::scenario::load(&path, &set) else {
            panic!("rtol with {name}");
        };
        let e = e.to_string();
        assert!(e.contains("integrator.rtol") && e.contains(&name), "{e}");
    }
}

/// The Newton matrices are factorised at the predictor's middle stage
/// (module docs of radau, "Simplified Newton"), not at the step's start:
/// on the four-bar (problem A, 2 s, the crank turning at 2π rad/s and
/// faster) at h = 5e-3 the stages lie up to a step's turn of the bodies
/// from the step's start, where simplified Newton at the default
/// tolerance fails more often than the bounds below allow, each failure
/// cutting the step (counts before and after: docs/radau.md, "The Newton
/// matrices at the middle stage"). The run stays on the constraints: the
/// largest ‖Φ‖ over the output rows below 1e-9 m.
#[test]
fn fourbar_newton_failures_with_matrices_at_the_middle_stage() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml");
    for (name, bound) in [("radau9", 45), ("radau5", 90)] {
        let set = [
            format!("integrator.method=\"{name}\""),
            "integrator.step=5e-3".to_string(),
        ];
        let sc = mbsolve::scenario::load(&path, &set).unwrap();
        let (_, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
        assert_eq!(s.status, "completed", "{name}: {:?}", s.message);
        let fails = s.extra["newton_failures"].as_u64().unwrap();
        assert!(fails <= bound, "{name}: {fails} Newton failures");
        assert!(
            s.max_constraint_norm < 1e-9,
            "{name}: ‖Φ‖ = {:e}",
            s.max_constraint_norm
        );
    }
}
