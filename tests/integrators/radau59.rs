//! Adaptive radau9 and radau59 (Radau IIA of variable order, 5 and 9) on
//! the index-3 equations: the observed order on the pendulum against an
//! independent minimal-coordinate solution, the stiff chain against the
//! peers' reference, the error over the run against rtol, bad input.

use crate::common::stiff_chain::{tip_after, T_END};
use crate::radau::{largest_errors_over_the_run, outside_a_decade_of_rtol};
use crate::radau9::pendulum_run;
use mbsolve::builders::{stiff_chain, stiff_chain_reference_tip};
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::simulation::{simulate, RunConfig};

/// `method` at adaptive steps of `rtol` (`atol` = 1e-3 rtol) to `t_end`.
fn adaptive(method: Method, rtol: f64, t_end: f64) -> RunConfig {
    let mut cfg = RunConfig {
        method,
        t_end,
        output_dt: t_end,
        ..Default::default()
    };
    // radau59 is always adaptive and takes no `adaptive` key
    cfg.implicit.adaptive = !method.is_adaptive();
    cfg.ode.rtol = rtol;
    cfg.ode.atol = Tolerance::Scalar(1e-3 * rtol);
    cfg
}

/// The position error and accepted steps of the pendulum (released at
/// 70°, 2 s, against RK4 on its angle) with `method` at `rtol`.
fn pendulum(method: Method, rtol: f64) -> (f64, usize) {
    pendulum_run(&adaptive(method, rtol, 2.0), 70f64.to_radians())
}

/// The order shows in how the steps grow with the tolerance: with RADAU's
/// tolerance transformation the steps of S stages scale as
/// `rtol^{-1/(2S)}`, so from rtol 1e-5 to 1e-9 they grow 10^{0.4} ≈ 2.5×
/// at order 9 and 10^{0.67} ≈ 4.6× at order 5. On the pendulum adaptive
/// radau9 grows them less than 3×, adaptive radau5 more than 3.5×, and
/// both stay within 20 rtol of the exact angle's positions (a looser
/// bound than the 10 rtol elsewhere: radau9's error at rtol 1e-9 grows
/// past 10 rtol over the 2 s). radau59 stays
/// at order 5 here (its Newton contraction θ̄ stays above RADAU's 0.002)
/// and is then adaptive radau5 to the bit.
#[test]
fn adaptive_order_nine_on_the_pendulum() {
    let (lo, hi) = (1e-5, 1e-9);
    let mut growth = Vec::new();
    for method in [Method::Radau9, Method::Radau5] {
        let (e_lo, n_lo) = pendulum(method, lo);
        let (e_hi, n_hi) = pendulum(method, hi);
        println!(
            "{method}: rtol {lo:e}: {e_lo:.2e} in {n_lo} steps; {hi:e}: {e_hi:.2e} in {n_hi} steps"
        );
        assert!(
            e_lo < 20.0 * lo && e_hi < 20.0 * hi,
            "{method}: {e_lo:e}, {e_hi:e}"
        );
        growth.push(n_hi as f64 / n_lo as f64);
    }
    assert!(growth[0] < 3.0, "radau9: steps grow {}×", growth[0]);
    assert!(growth[1] > 3.5, "radau5: steps grow {}×", growth[1]);
    for rtol in [lo, hi] {
        let (e59, n59) = pendulum(Method::Radau59, rtol);
        let (e5, n5) = pendulum(Method::Radau5, rtol);
        assert_eq!((e59.to_bits(), n59), (e5.to_bits(), n5), "rtol {rtol:e}");
    }
}

/// The stiff chain at N = 100 against the peers' independent reference
/// (SciPy Radau at rtol 1e-10): adaptive radau9 and radau59 at rtol 1e-5
/// within 10 rtol at 0.1 s, the constraints held (‖Φ‖ < 1e-6), and
/// radau59 took steps at both orders.
#[test]
fn stiff_chain_n100_against_reference() {
    let r = stiff_chain_reference_tip(100).unwrap();
    for method in [Method::Radau9, Method::Radau59] {
        let rtol = 1e-5;
        let (tip, s, _) = tip_after(100, &adaptive(method, rtol, T_END));
        let get = |k: &str| s.extra.get(k).cloned().unwrap_or_default();
        println!(
            "{method} N = 100, rtol {rtol:e}: tip error {:e}, {} steps, {} Newton iterations, \
             order 9: {} steps, {} changes",
            (tip - r).abs(),
            s.steps,
            get("newton_iterations"),
            get("steps_order9"),
            get("order_changes"),
        );
        assert_eq!(s.status, "completed", "{:?}", s.message);
        assert!(
            (tip - r).abs() < 10.0 * rtol,
            "tip error {:e}",
            (tip - r).abs()
        );
        assert!(
            s.max_constraint_norm < 1e-6,
            "‖Φ‖ {}",
            s.max_constraint_norm
        );
        if method == Method::Radau59 {
            let nine = s.extra["steps_order9"].as_u64().unwrap();
            assert!(
                nine > 0 && nine < s.steps as u64,
                "steps at order 9: {nine}"
            );
        }
    }
}

/// Adaptive radau9's and radau59's error estimates are honest on the stiff
/// chain (N = 10, 0.1 s): the largest tip error over 100 output rows lies
/// within [0.05, 10] rtol for rtol 1e-3 … 1e-5 (as radau5's,
/// `radau::adaptive_error_over_the_run_follows_rtol`).
#[test]
fn error_over_the_run_follows_rtol() {
    let rtols = [1e-3, 1e-4, 1e-5];
    let mut bad = Vec::new();
    for method in [Method::Radau9, Method::Radau59] {
        let e = largest_errors_over_the_run(method, &rtols);
        bad.extend(
            outside_a_decade_of_rtol(&rtols, &e)
                .into_iter()
                .map(|b| format!("{method}: {b}")),
        );
    }
    assert!(bad.is_empty(), "{bad:?}");
}

/// Bad input is a clear error: radau59 with `adaptive` (it always is) or
/// with a fixed step, and in a scenario `integrator.step` with radau59.
#[test]
fn radau59_takes_tolerances_only() {
    let (sys, q0, qd0, _) = stiff_chain(3, 0.1).unwrap();
    let mut cfg = adaptive(Method::Radau59, 1e-4, 0.01);
    cfg.implicit.adaptive = true;
    let e = simulate(&sys, &q0, &qd0, &cfg, &mut [])
        .unwrap_err()
        .to_string();
    assert!(e.contains("adaptive") && e.contains("radau59"), "{e}");
    let mut cfg = adaptive(Method::Radau59, 1e-4, 0.01);
    cfg.ode.fixed_step = Some(1e-3);
    let e = simulate(&sys, &q0, &qd0, &cfg, &mut [])
        .unwrap_err()
        .to_string();
    assert!(e.contains("fixed_step") && e.contains("radau59"), "{e}");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml");
    let set = [
        "integrator.method=\"radau59\"".to_string(),
        "integrator.step=1e-3".to_string(),
    ];
    let Err(e) = mbsolve::scenario::load(&path, &set) else {
        panic!("step with radau59");
    };
    let e = e.to_string();
    assert!(
        e.contains("integrator.step") && e.contains("radau59"),
        "{e}"
    );
}
