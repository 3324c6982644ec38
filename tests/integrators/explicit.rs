//! Tests of the explicit integrators (`mbsolve::integrate`): convergence
//! order, MATLAB-style step statistics and step control, dense output,
//! failure modes, option validation and observer control.

use std::f64::consts::PI;
use std::ops::ControlFlow;

use mbsolve::integrate::{
    integrator, Failure, FnSystem, IntegratorError, Method, Observer, OdeOptions, OdeSystem,
    Recorder, Report, StepCut, SystemError, Termination, Tolerance,
};

// ---------------------------------------------------------------- helpers

/// Records both the requested outputs and the accepted steps.
#[derive(Default)]
struct Log {
    out_t: Vec<f64>,
    out_y: Vec<Vec<f64>>,
    step_t: Vec<f64>,
    step_y: Vec<Vec<f64>>,
}

impl Observer for Log {
    fn output(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        self.out_t.push(t);
        self.out_y.push(y.to_vec());
        ControlFlow::Continue(())
    }
    fn step(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        self.step_t.push(t);
        self.step_y.push(y.to_vec());
        ControlFlow::Continue(())
    }
}

fn opts(rtol: f64, atol: f64) -> OdeOptions {
    OdeOptions {
        rtol,
        atol: Tolerance::Scalar(atol),
        ..OdeOptions::default()
    }
}

fn rk4_opts(h: f64) -> OdeOptions {
    OdeOptions {
        fixed_step: Some(h),
        ..OdeOptions::default()
    }
}

/// Default options for the adaptive methods, a 0.25 step for rk4.
fn integ_opts(method: Method) -> OdeOptions {
    if method == Method::Rk4 {
        rk4_opts(0.25)
    } else {
        OdeOptions::default()
    }
}

fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            if i + 1 == n {
                b
            } else {
                a + (b - a) * i as f64 / (n - 1) as f64
            }
        })
        .collect()
}

/// Runs `sys` and returns the report and the log.
fn run(
    method: Method,
    o: OdeOptions,
    sys: &mut dyn OdeSystem,
    t0: f64,
    tf: f64,
    y0: &[f64],
    out: &[f64],
) -> (Report, Log) {
    let mut integ = integrator(method, o).expect("valid options");
    let mut log = Log::default();
    let rep = integ
        .integrate(sys, t0, tf, y0, out, &mut log)
        .expect("valid inputs");
    (rep, log)
}

/// Max over outputs and components of |y - exact(t)|.
fn max_err(log_t: &[f64], log_y: &[Vec<f64>], exact: impl Fn(f64) -> Vec<f64>) -> f64 {
    let mut m: f64 = 0.0;
    for (t, y) in log_t.iter().zip(log_y) {
        for (a, b) in y.iter().zip(exact(*t)) {
            m = m.max((a - b).abs());
        }
    }
    m
}

fn decay() -> FnSystem<impl FnMut(f64, &[f64], &mut [f64])> {
    FnSystem::new(1, |_t, y: &[f64], d: &mut [f64]| d[0] = -y[0])
}

fn oscillator() -> FnSystem<impl FnMut(f64, &[f64], &mut [f64])> {
    FnSystem::new(2, |_t, y: &[f64], d: &mut [f64]| {
        d[0] = y[1];
        d[1] = -y[0];
    })
}

fn oscillator_exact(t: f64) -> Vec<f64> {
    vec![t.cos(), -t.sin()]
}

// Kepler problem, a = 1, mu = 1 (period 2π), eccentricity 0.5, start at perihelion.
const ECC: f64 = 0.5;

fn kepler() -> FnSystem<impl FnMut(f64, &[f64], &mut [f64])> {
    FnSystem::new(4, |_t, y: &[f64], d: &mut [f64]| {
        let r2 = y[0] * y[0] + y[1] * y[1];
        let r3 = r2 * r2.sqrt();
        d[0] = y[2];
        d[1] = y[3];
        d[2] = -y[0] / r3;
        d[3] = -y[1] / r3;
    })
}

fn kepler_y0() -> [f64; 4] {
    [1.0 - ECC, 0.0, 0.0, ((1.0 + ECC) / (1.0 - ECC)).sqrt()]
}

/// Exact Kepler orbit: solve E - e sin E = t by Newton's method.
fn kepler_exact(t: f64) -> Vec<f64> {
    let m = t;
    let mut e_anom = m + ECC * m.sin();
    for _ in 0..50 {
        let f = e_anom - ECC * e_anom.sin() - m;
        let step = f / (1.0 - ECC * e_anom.cos());
        e_anom -= step;
        if step.abs() < 1e-16 {
            break;
        }
    }
    let b = (1.0 - ECC * ECC).sqrt();
    let edot = 1.0 / (1.0 - ECC * e_anom.cos());
    vec![
        e_anom.cos() - ECC,
        b * e_anom.sin(),
        -e_anom.sin() * edot,
        b * e_anom.cos() * edot,
    ]
}

/// Asserts that the errors fall with the tolerances (10× apart) at a rate
/// "roughly proportional to rtol": each 10× tightening reduces the error
/// by a factor in [lo, hi], and the overall log-log slope is in [0.7, 1.5].
fn assert_tolerance_proportional(label: &str, tols: &[f64], errs: &[f64], lo: f64, hi: f64) {
    for w in 0..errs.len() - 1 {
        let ratio = errs[w] / errs[w + 1];
        assert!(
            ratio >= lo && ratio <= hi,
            "{label}: error ratio {ratio:.3} between rtol {:e} and {:e} not in [{lo}, {hi}] (errors {errs:?})",
            tols[w],
            tols[w + 1]
        );
    }
    let k = errs.len() - 1;
    let slope = (errs[0] / errs[k]).log10() / (tols[0] / tols[k]).log10();
    assert!(
        (0.7..=1.5).contains(&slope),
        "{label}: log-log slope {slope:.3} (errors {errs:?})"
    );
}

// ---------------------------------------------------------------- convergence

#[test]
fn exponential_decay_error_proportional_to_rtol() {
    let out = linspace(0.0, 5.0, 11);
    for (method, tols) in [
        (Method::Ode23, vec![1e-3, 1e-4, 1e-5, 1e-6, 1e-7]),
        (Method::Ode45, vec![1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]),
    ] {
        let errs: Vec<f64> = tols
            .iter()
            .map(|&tol| {
                let (rep, log) = run(
                    method,
                    opts(tol, tol * 1e-3),
                    &mut decay(),
                    0.0,
                    5.0,
                    &[1.0],
                    &out,
                );
                assert_eq!(rep.termination, Termination::Completed);
                max_err(&log.out_t, &log.out_y, |t| vec![(-t).exp()])
            })
            .collect();
        assert_tolerance_proportional(method.name(), &tols, &errs, 3.0, 40.0);
    }
}

#[test]
fn harmonic_oscillator_rk4_is_fourth_order_and_adaptive_converge() {
    // RK4: halving h divides the global error by ~2^4 = 16.
    let tf = 10.0;
    let errs: Vec<f64> = [0.1, 0.05, 0.025]
        .iter()
        .map(|&h| {
            let (rep, log) = run(
                Method::Rk4,
                rk4_opts(h),
                &mut oscillator(),
                0.0,
                tf,
                &[1.0, 0.0],
                &[tf],
            );
            assert_eq!(rep.termination, Termination::Completed);
            assert_eq!(rep.stats.steps, (tf / h).round() as usize);
            max_err(&log.out_t, &log.out_y, oscillator_exact)
        })
        .collect();
    for w in errs.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (14.0..=18.0).contains(&ratio),
            "rk4 ratio {ratio} ({errs:?})"
        );
    }

    // ode23 / ode45 on the same problem: error roughly proportional to rtol.
    let out = linspace(0.0, tf, 21);
    for (method, tols) in [
        (Method::Ode23, vec![1e-4, 1e-5, 1e-6, 1e-7]),
        (Method::Ode45, vec![1e-5, 1e-6, 1e-7, 1e-8, 1e-9]),
    ] {
        let errs: Vec<f64> = tols
            .iter()
            .map(|&tol| {
                let (rep, log) = run(
                    method,
                    opts(tol, tol * 1e-3),
                    &mut oscillator(),
                    0.0,
                    tf,
                    &[1.0, 0.0],
                    &out,
                );
                assert_eq!(rep.termination, Termination::Completed);
                max_err(&log.out_t, &log.out_y, oscillator_exact)
            })
            .collect();
        assert_tolerance_proportional(method.name(), &tols, &errs, 3.0, 40.0);
    }
}

#[test]
fn kepler_orbit_converges_and_ode45_is_cheaper() {
    let period = 2.0 * PI;
    let out = linspace(0.0, period, 41);
    let y0 = kepler_y0();

    // The exact solution itself is consistent (closed orbit, correct start).
    let e0 = kepler_exact(0.0);
    let e1 = kepler_exact(period);
    for i in 0..4 {
        assert!((e0[i] - y0[i]).abs() < 1e-14 && (e1[i] - y0[i]).abs() < 1e-12);
    }

    let mut steps_at_1e6 = [0usize; 2];
    for (idx, (method, tols)) in [
        (Method::Ode23, vec![1e-4, 1e-5, 1e-6, 1e-7]),
        (Method::Ode45, vec![1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]),
    ]
    .into_iter()
    .enumerate()
    {
        let errs: Vec<f64> = tols
            .iter()
            .map(|&tol| {
                let (rep, log) = run(
                    method,
                    opts(tol, tol * 1e-3),
                    &mut kepler(),
                    0.0,
                    period,
                    &y0,
                    &out,
                );
                assert_eq!(rep.termination, Termination::Completed);
                if tol == 1e-6 {
                    steps_at_1e6[idx] = rep.stats.steps;
                }
                max_err(&log.out_t, &log.out_y, kepler_exact)
            })
            .collect();
        assert_tolerance_proportional(method.name(), &tols, &errs, 2.5, 40.0);
    }
    let [s23, s45] = steps_at_1e6;
    assert!(
        5 * s45 < s23,
        "ode45 should take far fewer steps than ode23 at rtol 1e-6: {s45} vs {s23}"
    );

    // RK4 on the orbit: fourth order.
    let errs: Vec<f64> = [400.0, 800.0, 1600.0]
        .iter()
        .map(|&m| {
            let (_, log) = run(
                Method::Rk4,
                rk4_opts(period / m),
                &mut kepler(),
                0.0,
                period,
                &y0,
                &out,
            );
            max_err(&log.out_t, &log.out_y, kepler_exact)
        })
        .collect();
    for w in errs.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (13.0..=19.0).contains(&ratio),
            "rk4 Kepler ratio {ratio} ({errs:?})"
        );
    }
}

// ---------------------------------------------------------------- statistics & step control

#[test]
fn rhs_evaluation_counts_follow_matlab() {
    let y0 = kepler_y0();
    let mut total_failed = 0;
    for tol in [1e-3, 1e-6, 1e-9] {
        for (method, per_attempt) in [(Method::Ode23, 3), (Method::Ode45, 6)] {
            // The second variant starts with a far too large step, which
            // forces rejected attempts (counted in rhs_evals as in MATLAB).
            for initial_step in [None, Some(1.0)] {
                let o = OdeOptions {
                    initial_step,
                    ..opts(tol, tol * 1e-3)
                };
                let (rep, _) = run(method, o, &mut kepler(), 0.0, 2.0 * PI, &y0, &[]);
                assert_eq!(rep.termination, Termination::Completed);
                let s = &rep.stats;
                assert_eq!(
                    s.rhs_evals,
                    per_attempt * (s.steps + s.failed_steps) + 1,
                    "{method} {tol} {s:?}"
                );
                assert!(s.steps > 0);
                if initial_step.is_some() {
                    assert!(s.failed_steps > 0, "{method} {tol} {s:?}");
                }
                total_failed += s.failed_steps;
            }
        }
    }
    assert!(total_failed > 0);
    // RK4: 4 evaluations per step plus f(t0, y0).
    let (rep, _) = run(
        Method::Rk4,
        rk4_opts(0.01),
        &mut kepler(),
        0.0,
        1.0,
        &y0,
        &[],
    );
    assert_eq!(rep.stats.steps, 100);
    assert_eq!(rep.stats.rhs_evals, 4 * 100 + 1);
    assert_eq!(rep.stats.failed_steps, 0);
}

#[test]
fn step_sequence_on_linear_problem_matches_matlab_rules() {
    // y' = 1, y(0) = 0 on [0, 1]: the error estimate vanishes (up to
    // round-off), so after MATLAB's initial step absh = 1/rh,
    // rh = |f0|/max(|y0|, atol/rtol) / (0.8 rtol^pow), every step grows 5×
    // until hmax = 0.1, and the last step is stretched once 1.1·h ≥ tf - t.
    //  ode45: h0 = 0.8·1e-3^(1/5)/1000 = 2.0095e-4; 4 growing steps reach
    //         t = 0.03135, then 9 steps of 0.1 (to 0.93135), then the stretched one: 14.
    //  ode23: h0 = 0.8·1e-3^(1/3)/1000 = 8e-5; 5 growing steps reach
    //         t = 0.06248, then 9 steps of 0.1 (to 0.96248), then one more: 15.
    let sys = || FnSystem::new(1, |_t, _y: &[f64], d: &mut [f64]| d[0] = 1.0);
    for (method, pow, expected_steps) in [(Method::Ode45, 0.2, 14), (Method::Ode23, 1.0 / 3.0, 15)]
    {
        let (rep, log) = run(
            method,
            OdeOptions::default(),
            &mut sys(),
            0.0,
            1.0,
            &[0.0],
            &[1.0],
        );
        assert_eq!(rep.termination, Termination::Completed);
        assert_eq!(rep.stats.steps, expected_steps, "{method}");
        assert_eq!(rep.stats.failed_steps, 0);
        let h0 = 0.8 * 1e-3f64.powf(pow) / 1000.0;
        assert!(
            (log.step_t[0] - h0).abs() < 1e-15,
            "{method}: first step {}",
            log.step_t[0]
        );
        assert!((log.step_t[1] - log.step_t[0] - 5.0 * h0).abs() < 1e-15);
        assert_eq!(*log.step_t.last().unwrap(), 1.0);
        assert!((log.out_y[0][0] - 1.0).abs() < 1e-14);
    }
}

#[test]
fn last_step_is_stretched_within_ten_percent_of_t_end() {
    // Same step sequence as above with max_step = 0.1 on [0, 1.036]: after the
    // 13th step t = 0.93135 and 0.10465 remain, which is within 10% of the
    // 0.1 step, so MATLAB stretches the step to land on t_end (14 steps, not 15).
    let sys = || FnSystem::new(1, |_t, _y: &[f64], d: &mut [f64]| d[0] = 1.0);
    let o = OdeOptions {
        max_step: Some(0.1),
        ..OdeOptions::default()
    };
    let (rep, log) = run(Method::Ode45, o, &mut sys(), 0.0, 1.036, &[0.0], &[]);
    assert_eq!(rep.stats.steps, 14);
    let n = log.step_t.len();
    assert!((log.step_t[n - 1] - log.step_t[n - 2] - 0.10465).abs() < 1e-4);
    assert_eq!(log.step_t[n - 1], 1.036);
}

#[test]
fn rejected_steps_shrink_as_in_matlab() {
    // y' = cos(50 t) with a far too large initial step and a tight rtol: the
    // first rejection is limited by MATLAB's lower bound on the reduction
    // factor (0.5 in ode23.m, 0.1 in ode45.m), later rejections of the same
    // step halve it; after a step with rejections the step is not enlarged.
    for (method, floor) in [(Method::Ode23, 0.5), (Method::Ode45, 0.1)] {
        let mut sys = FnSystem::new(1, |t: f64, _y: &[f64], d: &mut [f64]| {
            d[0] = (50.0 * t).cos()
        });
        let o = OdeOptions {
            initial_step: Some(1.0),
            ..opts(1e-8, 1e-11)
        };
        let mut integ = integrator(method, o).unwrap();
        let mut log = Log::default();
        struct FirstSteps<'a>(&'a mut Log);
        impl Observer for FirstSteps<'_> {
            fn step(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
                let _ = self.0.step(t, y);
                if self.0.step_t.len() == 3 {
                    ControlFlow::Break("three steps".into())
                } else {
                    ControlFlow::Continue(())
                }
            }
        }
        let rep = integ
            .integrate(&mut sys, 0.0, 10.0, &[0.0], &[], &mut FirstSteps(&mut log))
            .unwrap();
        let failed = rep.stats.failed_steps as i32;
        assert!(failed >= 3, "{method}: {:?}", rep.stats);
        let h1 = log.step_t[0];
        let expected = floor * 0.5f64.powi(failed - 1);
        assert_eq!(
            h1, expected,
            "{method}: first step {h1} after {failed} rejections"
        );
        let h2 = log.step_t[1] - log.step_t[0];
        assert!(
            (h2 - h1).abs() < 1e-15,
            "{method}: second step {h2} vs {h1}"
        );
        let h3 = log.step_t[2] - log.step_t[1];
        assert!(
            (h3 - h2).abs() > 1e-9,
            "{method}: third step {h3} should be re-estimated, not {h2}"
        );
    }
}

#[test]
fn steady_step_size_follows_matlab_update() {
    // y' = t^p with p = 2 (ode23) or p = 4 (ode45): f depends on t only, so
    // the error estimate is exactly |Σ E_j k_j| = C·h^p with
    // C = |Σ E_j c_j^p| (1/24 for Bogacki–Shampine, 71/270000 for
    // Dormand–Prince), and with atol = rtol (threshold 1 > |y|) MATLAB's norm
    // gives err = C·h^(p+1). The update absh /= 1.25·(err/rtol)^pow then
    // drives every step to h* = 0.8·(rtol/C)^pow after a successful step.
    for (method, p, c, pow, tol, tf) in [
        (Method::Ode23, 2, 1.0 / 24.0, 1.0 / 3.0, 1e-6, 1.4),
        (Method::Ode45, 4, 71.0 / 270000.0, 0.2, 1e-8, 1.3),
    ] {
        let mut sys = FnSystem::new(1, move |t: f64, _y: &[f64], d: &mut [f64]| d[0] = t.powi(p));
        let (rep, log) = run(method, opts(tol, tol), &mut sys, 0.0, tf, &[0.0], &[]);
        assert_eq!(rep.termination, Termination::Completed);
        let h_star = 0.8 * (tol / c).powf(pow);
        let t = &log.step_t;
        let n = t.len();
        assert!(n > 10, "{method}: {n} steps");
        for k in 2..n - 2 {
            let h = t[k] - t[k - 1];
            assert!(
                ((h - h_star) / h_star).abs() < 1e-7,
                "{method}: step {k} is {h}, expected {h_star}"
            );
        }
    }
}

#[test]
fn max_step_defaults_to_a_tenth_of_the_span() {
    // A smooth, slowly varying problem whose steps would grow beyond hmax.
    let sys = || {
        FnSystem::new(1, |t: f64, _y: &[f64], d: &mut [f64]| {
            d[0] = (0.01 * t).cos()
        })
    };
    let (t0, tf) = (2.0, 52.0);
    for method in [Method::Ode23, Method::Ode45] {
        for (max_step, cap) in [(None, 0.1 * (tf - t0)), (Some(1.5), 1.5)] {
            let o = OdeOptions {
                max_step,
                ..OdeOptions::default()
            };
            let (rep, log) = run(method, o, &mut sys(), t0, tf, &[0.0], &[]);
            assert_eq!(rep.termination, Termination::Completed);
            let mut prev = t0;
            let mut largest: f64 = 0.0;
            for &t in &log.step_t {
                largest = largest.max(t - prev);
                prev = t;
            }
            assert!(
                largest <= cap * (1.0 + 1e-12),
                "{method}: step {largest} > {cap}"
            );
            // The cap is actually reached, so the check is meaningful.
            assert!(
                largest >= cap * (1.0 - 1e-9),
                "{method}: largest step {largest} < {cap}"
            );
            assert_eq!(prev, tf);
        }
    }
}

#[test]
fn output_at_exactly_the_requested_times() {
    let out = vec![0.0, 0.1, 0.1000001, 0.37, 1.0, 2.5, PI, 5.999, 6.0];
    for method in [Method::Ode23, Method::Ode45, Method::Rk4] {
        let mut integ = integrator(method, integ_opts(method)).unwrap();
        let mut rec = Recorder::default();
        let rep = integ
            .integrate(&mut oscillator(), 0.0, 6.0, &[1.0, 0.0], &out, &mut rec)
            .unwrap();
        assert_eq!(rep.termination, Termination::Completed);
        assert_eq!(rep.t_reached, 6.0);
        assert_eq!(rec.t, out, "{method}");
        assert_eq!(rec.y[0], vec![1.0, 0.0]);

        // The final output is the exact final step state.
        let (_, log) = run(
            method,
            integ_opts(method),
            &mut oscillator(),
            0.0,
            6.0,
            &[1.0, 0.0],
            &out,
        );
        assert_eq!(log.out_y.last(), log.step_y.last());
        // Output times between steps are not step times (dense output used).
        assert!(!log.step_t.contains(&0.1000001));
    }
    // No requested times: no output calls, but steps are reported.
    let (_, log) = run(
        Method::Ode45,
        OdeOptions::default(),
        &mut oscillator(),
        0.0,
        1.0,
        &[1.0, 0.0],
        &[],
    );
    assert!(log.out_t.is_empty() && !log.step_t.is_empty());
}

#[test]
fn dense_output_is_as_accurate_as_the_steps() {
    let tf = 2.0 * PI;
    let out = linspace(0.0, tf, 2001);
    let y0 = kepler_y0();
    for (method, o) in [
        (Method::Ode23, opts(1e-5, 1e-8)),
        (Method::Ode45, opts(1e-5, 1e-8)),
        (Method::Ode45, opts(1e-8, 1e-11)),
        (Method::Rk4, rk4_opts(tf / 500.0)),
    ] {
        let (rep, log) = run(method, o, &mut kepler(), 0.0, tf, &y0, &out);
        assert_eq!(rep.termination, Termination::Completed);
        assert!(
            log.step_t.len() * 4 < out.len(),
            "outputs must fall between steps"
        );
        let e_steps = max_err(&log.step_t, &log.step_y, kepler_exact);
        let e_dense = max_err(&log.out_t, &log.out_y, kepler_exact);
        assert!(
            e_dense <= 3.0 * e_steps,
            "{method}: dense error {e_dense:e} vs step error {e_steps:e}"
        );
    }
}

/// Exact flow of the oscillator over a time `d`: a rotation of (y, y').
fn rotate(d: f64, y: &[f64]) -> [f64; 2] {
    [
        d.cos() * y[0] + d.sin() * y[1],
        -d.sin() * y[0] + d.cos() * y[1],
    ]
}

#[test]
fn dense_output_local_error_is_within_the_step_accuracy() {
    // Compare each output with the exact solution through the state at the
    // start of its step (local error), so that the interpolant is judged
    // on its own rather than through the accumulated global error.
    let tf = 10.0;
    let out: Vec<f64> = (1..4000).map(|i| tf * i as f64 / 4000.0).collect();
    for (method, o, bound) in [
        // Adaptive methods: the interpolant keeps the local error within rtol.
        (Method::Ode23, opts(1e-5, 1e-8), 1e-5),
        (Method::Ode45, opts(1e-5, 1e-8), 1e-5),
        (Method::Ode45, opts(1e-8, 1e-11), 1e-8),
        // RK4 + cubic Hermite: O(h^4) interpolation error, ~ the step's O(h^5) error × a few.
        (Method::Rk4, rk4_opts(0.1), 5e-7),
    ] {
        let (rep, log) = run(method, o, &mut oscillator(), 0.0, tf, &[1.0, 0.0], &out);
        assert_eq!(rep.termination, Termination::Completed);
        let mut st = vec![0.0];
        st.extend(&log.step_t);
        let mut sy = vec![vec![1.0, 0.0]];
        sy.extend(log.step_y.iter().cloned());
        let dist = |a: &[f64], b: &[f64]| (a[0] - b[0]).abs().max((a[1] - b[1]).abs());
        let mut step_err: f64 = 0.0;
        for k in 0..st.len() - 1 {
            step_err = step_err.max(dist(&rotate(st[k + 1] - st[k], &sy[k]), &sy[k + 1]));
        }
        let mut dense_err: f64 = 0.0;
        for (t, y) in log.out_t.iter().zip(&log.out_y) {
            let k = st.iter().rposition(|s| s < t).unwrap();
            dense_err = dense_err.max(dist(&rotate(t - st[k], &sy[k]), y));
        }
        assert!(
            step_err > 0.0 && step_err <= bound,
            "{method}: local step error {step_err:e}"
        );
        assert!(
            dense_err <= bound,
            "{method}: local dense error {dense_err:e} (step {step_err:e}, bound {bound:e})"
        );
    }
}

// ---------------------------------------------------------------- failures

#[test]
fn finite_time_blow_up_fails_near_one() {
    // y' = y², y(0) = 1: y = 1/(1 - t) blows up at t = 1. The step size
    // collapses to hmin = 16 eps(t) near the pole. (With default tolerances
    // ode23's solution lags the exact one and its own pole lies slightly
    // beyond t = 1; MATLAB's algorithm behaves the same way.)
    let out = linspace(0.0, 2.0, 21);
    for (method, rtol, window) in [
        (Method::Ode45, 1e-3, (0.999, 1.0)),
        (Method::Ode23, 1e-3, (0.99, 1.01)),
        (Method::Ode23, 1e-6, (0.999, 1.001)),
    ] {
        let mut sys = FnSystem::new(1, |_t, y: &[f64], d: &mut [f64]| d[0] = y[0] * y[0]);
        let (rep, log) = run(method, opts(rtol, 1e-6), &mut sys, 0.0, 2.0, &[1.0], &out);
        let Termination::Failed { t, reason } = &rep.termination else {
            panic!("{method}: expected failure, got {:?}", rep.termination);
        };
        assert!(
            matches!(
                reason,
                Failure::StepTooSmall {
                    cause: StepCut::ErrorTest { .. },
                    ..
                }
            ),
            "{reason:?}"
        );
        let reason = reason.to_string();
        assert!(
            *t > window.0 && *t < window.1,
            "{method} rtol {rtol}: failed at {t}"
        );
        assert!(
            reason.contains("unable to meet integration tolerances"),
            "{reason}"
        );
        assert!(crate::common::names_time(&reason, *t), "{reason}");
        assert_eq!(rep.t_reached, *t);
        assert!(rep.stats.steps > 10);
        // Every output up to the failure was delivered, none after.
        let expected: Vec<f64> = out.iter().copied().filter(|&s| s <= *t).collect();
        assert_eq!(log.out_t, expected);
        assert!(log.out_t.len() >= 10);
        for (s, y) in log.out_t.iter().zip(&log.out_y).filter(|(s, _)| **s <= 0.9) {
            let exact = 1.0 / (1.0 - s);
            assert!(
                ((y[0] - exact) / exact).abs() < 30.0 * rtol,
                "{method} at {s}: {} vs {exact}",
                y[0]
            );
        }
    }
}

/// A system whose right-hand side fails after `t_fail`.
struct FailingRhs {
    t_fail: f64,
    nan: bool,
}

impl OdeSystem for FailingRhs {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<(), SystemError> {
        if t > self.t_fail {
            if self.nan {
                dydt[0] = f64::NAN;
                return Ok(());
            }
            return Err(SystemError::msg(format!(
                "model undefined beyond {}",
                self.t_fail
            )));
        }
        dydt[0] = -y[0];
        Ok(())
    }
}

#[test]
fn rhs_error_or_non_finite_value_fails_at_that_time() {
    let out = linspace(0.0, 1.0, 11);
    for nan in [false, true] {
        for method in [Method::Ode23, Method::Ode45, Method::Rk4] {
            let o = if method == Method::Rk4 {
                rk4_opts(0.1)
            } else {
                OdeOptions::default()
            };
            let mut sys = FailingRhs { t_fail: 0.55, nan };
            let (rep, log) = run(method, o, &mut sys, 0.0, 1.0, &[1.0], &out);
            let Termination::Failed { t, reason } = &rep.termination else {
                panic!("{method}: expected failure, got {:?}", rep.termination);
            };
            if nan {
                assert!(matches!(reason, Failure::NonFinite { .. }), "{reason:?}");
            } else {
                let Failure::System { source, .. } = reason else {
                    panic!("{method}: expected the system's error, got {reason:?}");
                };
                // the system's own error is kept
                assert_eq!(source.to_string(), "model undefined beyond 0.55");
            }
            let reason = reason.to_string();
            assert!(*t <= 0.55 && *t >= 0.45 - 1e-12, "{method}: failed at {t}");
            if method == Method::Rk4 {
                assert!((t - 0.5).abs() < 1e-12);
            }
            if nan {
                assert!(reason.contains("non-finite"), "{reason}");
            } else {
                assert!(reason.contains("model undefined beyond 0.55"), "{reason}");
            }
            assert!(
                crate::common::names_time(&reason, *t),
                "reason must name the time: {reason}"
            );
            let expected: Vec<f64> = out.iter().copied().filter(|&s| s <= *t).collect();
            assert_eq!(log.out_t, expected);
            assert_eq!(rep.t_reached, *t);
        }
    }
    // Failure at the very first evaluation.
    let mut sys = FailingRhs {
        t_fail: -1.0,
        nan: false,
    };
    let (rep, log) = run(
        Method::Ode45,
        OdeOptions::default(),
        &mut sys,
        0.0,
        1.0,
        &[1.0],
        &[0.0, 0.5],
    );
    assert!(matches!(rep.termination, Termination::Failed { t, .. } if t == 0.0));
    assert_eq!(log.out_t, vec![0.0]);
    assert_eq!(rep.stats.rhs_evals, 1);
}

#[test]
fn max_steps_cap_fails() {
    for (method, o) in [
        (
            Method::Ode45,
            OdeOptions {
                max_steps: 5,
                ..OdeOptions::default()
            },
        ),
        (
            Method::Rk4,
            OdeOptions {
                max_steps: 5,
                ..rk4_opts(0.01)
            },
        ),
    ] {
        let (rep, log) = run(method, o, &mut oscillator(), 0.0, 10.0, &[1.0, 0.0], &[]);
        assert!(
            matches!(
                &rep.termination,
                Termination::Failed {
                    reason: Failure::MaxSteps { max_steps: 5, .. },
                    ..
                }
            ),
            "{:?}",
            rep.termination
        );
        assert_eq!(rep.stats.steps, 5);
        assert_eq!(log.step_t.len(), 5);
    }
}

#[test]
fn invalid_options_and_inputs_are_errors() {
    let bad_opts: Vec<(Method, OdeOptions, &str)> = vec![
        (Method::Ode45, opts(0.0, 1e-6), "rtol"),
        (Method::Ode45, opts(-1e-3, 1e-6), "rtol"),
        (Method::Ode23, opts(f64::NAN, 1e-6), "rtol"),
        (Method::Ode45, opts(1e-3, -1e-6), "atol"),
        (Method::Ode45, opts(1e-3, f64::INFINITY), "atol"),
        (
            Method::Ode45,
            OdeOptions {
                atol: Tolerance::Vector(vec![1e-6, -1.0]),
                ..OdeOptions::default()
            },
            "atol",
        ),
        (
            Method::Ode45,
            OdeOptions {
                max_step: Some(0.0),
                ..OdeOptions::default()
            },
            "max_step",
        ),
        (
            Method::Ode23,
            OdeOptions {
                max_step: Some(f64::NAN),
                ..OdeOptions::default()
            },
            "max_step",
        ),
        (
            Method::Ode45,
            OdeOptions {
                initial_step: Some(-0.1),
                ..OdeOptions::default()
            },
            "initial_step",
        ),
        (
            Method::Ode45,
            OdeOptions {
                max_steps: 0,
                ..OdeOptions::default()
            },
            "max_steps",
        ),
        (Method::Rk4, OdeOptions::default(), "fixed_step"),
        (Method::Rk4, rk4_opts(0.0), "fixed_step"),
        (Method::Rk4, rk4_opts(f64::INFINITY), "fixed_step"),
    ];
    for (method, o, name) in bad_opts {
        let err = integrator(method, o.clone())
            .err()
            .unwrap_or_else(|| panic!("{method} {o:?} accepted"));
        assert!(
            matches!(err, IntegratorError::InvalidOption { .. }),
            "{err:?}"
        );
        assert!(err.to_string().contains(name), "{err}");
    }
    // Options unused by a method are not checked: rk4 ignores rtol.
    assert!(integrator(
        Method::Rk4,
        OdeOptions {
            rtol: -1.0,
            ..rk4_opts(0.1)
        }
    )
    .is_ok());

    // Per-run inputs.
    let mut integ = integrator(Method::Ode45, OdeOptions::default()).unwrap();
    let mut sys = oscillator();
    let y0 = [1.0, 0.0];
    let mut call = |t0: f64, tf: f64, y0: &[f64], out: &[f64]| {
        integ
            .integrate(&mut sys, t0, tf, y0, out, &mut ())
            .unwrap_err()
    };
    let e = call(1.0, 1.0, &y0, &[]);
    assert!(
        matches!(e, IntegratorError::InvalidTimeSpan { .. }) && e.to_string().contains("forward"),
        "{e}"
    );
    assert!(matches!(
        call(1.0, 0.0, &y0, &[]),
        IntegratorError::InvalidTimeSpan { .. }
    ));
    assert!(matches!(
        call(0.0, f64::INFINITY, &y0, &[]),
        IntegratorError::InvalidTimeSpan { .. }
    ));
    assert!(matches!(
        call(0.0, 1.0, &[1.0], &[]),
        IntegratorError::DimensionMismatch { what: "y0", .. }
    ));
    let e = call(0.0, 1.0, &[1.0, f64::NAN], &[]);
    assert!(
        matches!(e, IntegratorError::NonFiniteInitialState { index: 1, .. }),
        "{e}"
    );
    assert!(matches!(
        call(0.0, 1.0, &y0, &[-0.1]),
        IntegratorError::InvalidOutputTimes { index: 0, .. }
    ));
    assert!(matches!(
        call(0.0, 1.0, &y0, &[0.5, 1.5]),
        IntegratorError::InvalidOutputTimes { index: 1, .. }
    ));
    let e = call(0.0, 1.0, &y0, &[0.5, 0.2]);
    assert!(
        matches!(e, IntegratorError::InvalidOutputTimes { index: 1, .. })
            && e.to_string().contains("increasing")
    );
    assert!(matches!(
        call(0.0, 1.0, &y0, &[0.5, 0.5]),
        IntegratorError::InvalidOutputTimes { .. }
    ));
    assert!(matches!(
        call(0.0, 1.0, &y0, &[f64::NAN]),
        IntegratorError::InvalidOutputTimes { .. }
    ));

    let mut integ = integrator(
        Method::Ode45,
        OdeOptions {
            atol: Tolerance::Vector(vec![1e-6; 3]),
            ..OdeOptions::default()
        },
    )
    .unwrap();
    let e = integ
        .integrate(&mut oscillator(), 0.0, 1.0, &y0, &[], &mut ())
        .unwrap_err();
    assert!(
        matches!(
            e,
            IntegratorError::DimensionMismatch {
                what: "atol",
                expected: 2,
                got: 3
            }
        ),
        "{e}"
    );
}

#[test]
fn method_names_parse() {
    for m in [Method::Ode23, Method::Ode45, Method::Rk4, Method::Ode113] {
        assert_eq!(m.name().parse::<Method>().unwrap(), m);
        assert_eq!(m.to_string(), m.name());
    }
    assert_eq!(" ODE45 ".parse::<Method>().unwrap(), Method::Ode45);
    let e = "ode15x".parse::<Method>().unwrap_err().to_string();
    assert!(
        e.contains("ode15x")
            && e.contains("ode113")
            && e.contains("ode23")
            && e.contains("ode45")
            && e.contains("rk4"),
        "{e}"
    );
}

#[test]
fn tiny_rtol_is_raised_like_matlab_and_tolerance_variants_work() {
    let (rep, log) = run(
        Method::Ode45,
        opts(1e-20, 1e-20),
        &mut decay(),
        0.0,
        1.0,
        &[1.0],
        &[1.0],
    );
    assert_eq!(rep.termination, Termination::Completed);
    assert_eq!(rep.warnings.len(), 1, "{:?}", rep.warnings);
    assert!(rep.warnings[0].contains("100*eps"));
    assert!((log.out_y[0][0] - (-1.0f64).exp()).abs() < 1e-13);

    // atol = 0 (pure relative control) and a per-component atol.
    let (rep, log) = run(
        Method::Ode45,
        opts(1e-6, 0.0),
        &mut oscillator(),
        0.0,
        5.0,
        &[1.0, 0.0],
        &[5.0],
    );
    assert_eq!(rep.termination, Termination::Completed);
    assert!(rep.warnings.is_empty());
    assert!(max_err(&log.out_t, &log.out_y, oscillator_exact) < 1e-4);
    let o = OdeOptions {
        rtol: 1e-6,
        atol: Tolerance::Vector(vec![1e-9, 1e-9]),
        ..OdeOptions::default()
    };
    let (rep, log) = run(
        Method::Ode23,
        o,
        &mut oscillator(),
        0.0,
        5.0,
        &[1.0, 0.0],
        &[5.0],
    );
    assert_eq!(rep.termination, Termination::Completed);
    assert!(max_err(&log.out_t, &log.out_y, oscillator_exact) < 1e-4);
}

#[test]
fn rk4_last_step_is_shortened_to_hit_t_end() {
    let (rep, log) = run(
        Method::Rk4,
        rk4_opts(0.3),
        &mut decay(),
        0.0,
        1.0,
        &[1.0],
        &[],
    );
    assert_eq!(rep.stats.steps, 4);
    assert_eq!(rep.stats.rhs_evals, 17);
    assert_eq!(log.step_t.len(), 4);
    for (t, e) in log.step_t.iter().zip([0.3, 0.6, 0.9, 1.0]) {
        assert!((t - e).abs() < 1e-15);
    }
    assert_eq!(*log.step_t.last().unwrap(), 1.0);
    // A span that is a multiple of h up to round-off gets no sliver step.
    let (rep, _) = run(
        Method::Rk4,
        rk4_opts(0.1),
        &mut decay(),
        0.0,
        0.7,
        &[1.0],
        &[],
    );
    assert_eq!(rep.stats.steps, 7);
}

// ---------------------------------------------------------------- observer control

/// Stops at the first output at or after `at`, or after `steps` steps.
struct Stopper {
    at: f64,
    steps: usize,
    seen_steps: usize,
    outputs: usize,
}

impl Observer for Stopper {
    fn output(&mut self, t: f64, _y: &[f64]) -> ControlFlow<String> {
        self.outputs += 1;
        if t >= self.at {
            ControlFlow::Break(format!("enough at {t}"))
        } else {
            ControlFlow::Continue(())
        }
    }
    fn step(&mut self, _t: f64, _y: &[f64]) -> ControlFlow<String> {
        self.seen_steps += 1;
        if self.seen_steps >= self.steps {
            ControlFlow::Break("step limit".into())
        } else {
            ControlFlow::Continue(())
        }
    }
}

#[test]
fn observer_break_stops_the_run() {
    let out = linspace(0.0, 10.0, 101);
    for method in [Method::Ode23, Method::Ode45, Method::Rk4] {
        let o = integ_opts(method);
        // Stop from output().
        let mut integ = integrator(method, o.clone()).unwrap();
        let mut obs = Stopper {
            at: 0.5,
            steps: usize::MAX,
            seen_steps: 0,
            outputs: 0,
        };
        let rep = integ
            .integrate(&mut oscillator(), 0.0, 10.0, &[1.0, 0.0], &out, &mut obs)
            .unwrap();
        let Termination::Stopped { t, reason } = &rep.termination else {
            panic!("{method}: {:?}", rep.termination);
        };
        assert_eq!(*t, 0.5);
        assert!(reason.contains("enough"));
        assert_eq!(obs.outputs, 6);
        assert!(rep.t_reached >= 0.5 && rep.t_reached < 10.0);

        // Stop from step().
        let mut integ = integrator(method, o.clone()).unwrap();
        let mut obs = Stopper {
            at: f64::INFINITY,
            steps: 3,
            seen_steps: 0,
            outputs: 0,
        };
        let rep = integ
            .integrate(&mut oscillator(), 0.0, 10.0, &[1.0, 0.0], &out, &mut obs)
            .unwrap();
        assert!(
            matches!(&rep.termination, Termination::Stopped { t, reason } if *t == rep.t_reached && reason == "step limit"),
            "{:?}",
            rep.termination
        );
        assert_eq!(rep.stats.steps, 3);
        assert_eq!(obs.seen_steps, 3);

        // Stop at t0 (output at t0 is delivered before any step).
        let mut integ = integrator(method, o).unwrap();
        let mut obs = Stopper {
            at: 0.0,
            steps: usize::MAX,
            seen_steps: 0,
            outputs: 0,
        };
        let rep = integ
            .integrate(&mut oscillator(), 0.0, 10.0, &[1.0, 0.0], &out, &mut obs)
            .unwrap();
        assert!(matches!(rep.termination, Termination::Stopped { t, .. } if t == 0.0));
        assert_eq!(rep.stats.steps, 0);
    }
}

// ------------------------------------------------------------ post-step hook

/// Rotation y' = (−y₁, y₀) on the unit circle, with a `post_step` that
/// rescales y back onto |y| = 1 (a projection onto the invariant), or
/// fails after `fail_after`.
struct Circle {
    project: bool,
    calls: usize,
    fail_after: Option<f64>,
}

impl OdeSystem for Circle {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], d: &mut [f64]) -> Result<(), SystemError> {
        d[0] = -y[1];
        d[1] = y[0];
        Ok(())
    }
    fn post_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        self.calls += 1;
        if self.fail_after.is_some_and(|tf| t > tf) {
            return Err(SystemError::msg("projection did not converge"));
        }
        if !self.project {
            return Ok(false);
        }
        let r = y[0].hypot(y[1]);
        y[0] /= r;
        y[1] /= r;
        Ok(true)
    }
}

/// Every method calls `post_step` once per accepted step; a moved state is
/// what the next step starts from and what the step-end output shows (|y|
/// = 1 to rounding where the unprojected run drifts), and it costs one
/// more evaluation of f per step; a failing hook ends the run at the last
/// accepted step with the system's error.
#[test]
fn post_step_moves_the_state_and_is_counted() {
    let out = linspace(0.0, 20.0, 41);
    for (method, o) in [
        (Method::Ode23, opts(1e-3, 1e-6)),
        (Method::Ode45, opts(1e-3, 1e-6)),
        (Method::Rk4, rk4_opts(0.5)),
    ] {
        let mut free = Circle {
            project: false,
            calls: 0,
            fail_after: None,
        };
        let (rep0, log0) = run(method, o.clone(), &mut free, 0.0, 20.0, &[1.0, 0.0], &out);
        assert_eq!(rep0.termination, Termination::Completed);
        assert_eq!(free.calls, rep0.stats.steps, "{method}: one call per step");
        let drift0 = log0
            .step_y
            .iter()
            .map(|y| (y[0].hypot(y[1]) - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(drift0 > 1e-6, "{method}: the free run drifts ({drift0})");

        let mut proj = Circle {
            project: true,
            calls: 0,
            fail_after: None,
        };
        let (rep, log) = run(method, o.clone(), &mut proj, 0.0, 20.0, &[1.0, 0.0], &out);
        assert_eq!(rep.termination, Termination::Completed);
        assert_eq!(proj.calls, rep.stats.steps);
        for y in &log.step_y {
            assert!(
                (y[0].hypot(y[1]) - 1.0).abs() < 4.0 * f64::EPSILON,
                "{method}: {y:?}"
            );
        }
        // f per attempt (FSAL: s − 1 for the pairs, 4 for rk4), plus one
        // per step for the moved state, plus f(t0, y0)
        let per_attempt = match method {
            Method::Ode23 => 3,
            Method::Ode45 => 6,
            _ => 4,
        };
        let attempts = rep.stats.steps + rep.stats.failed_steps;
        assert_eq!(
            rep.stats.rhs_evals,
            1 + per_attempt * attempts + rep.stats.steps,
            "{method}"
        );
        // the projected solution is still the rotation
        let err = max_err(&log.out_t, &log.out_y, |t| vec![t.cos(), t.sin()]);
        let err0 = max_err(&log0.out_t, &log0.out_y, |t| vec![t.cos(), t.sin()]);
        assert!(err < 2.0 * err0 + 1e-12, "{method}: {err} vs {err0}");

        let mut failing = Circle {
            project: true,
            calls: 0,
            fail_after: Some(5.0),
        };
        let (rep, log) = run(method, o, &mut failing, 0.0, 20.0, &[1.0, 0.0], &out);
        let Termination::Failed { t, reason } = &rep.termination else {
            panic!("{method}: expected failure, got {:?}", rep.termination);
        };
        let Failure::System { what, source, .. } = reason else {
            panic!("{method}: {reason:?}");
        };
        assert_eq!(*what, "post-step projection");
        assert_eq!(source.to_string(), "projection did not converge");
        assert!(*t <= 5.0 && *t > 3.0, "{method}: failed at {t}");
        assert!(log.out_t.iter().all(|s| s <= t));
        assert_eq!(rep.t_reached, *t);
    }
}

/// A span so short that `0.1·span` (MATLAB's default hmax) underflows: the
/// steps would not advance t; the run fails at once instead of looping to
/// `max_steps`.
#[test]
fn a_step_that_does_not_advance_t_fails() {
    for method in [Method::Ode23, Method::Ode45] {
        let (rep, _) = run(
            method,
            OdeOptions::default(),
            &mut decay(),
            0.0,
            5e-324,
            &[1.0],
            &[],
        );
        let Termination::Failed { reason, .. } = &rep.termination else {
            panic!("{method}: {:?}", rep.termination);
        };
        assert!(
            matches!(
                reason,
                Failure::StepTooSmall {
                    cause: StepCut::NoProgress,
                    ..
                }
            ),
            "{reason:?}"
        );
        assert!(rep.stats.steps <= 1, "{method}: {} steps", rep.stats.steps);
    }
}

/// The fast finiteness scan finds the first NaN or ±inf at every position
/// and length (the 8-lane pass and the remainder), and none in finite data
/// with extreme values.
#[test]
fn first_non_finite_finds_every_position() {
    use mbsolve::integrate::first_non_finite;
    for len in 0..25 {
        let v: Vec<f64> = (0..len)
            .map(|i| [1e308, -1e308, 0.0, -0.0, 5e-324][i % 5])
            .collect();
        assert_eq!(first_non_finite(&v), None, "len {len}");
        for pos in 0..len {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut w = v.clone();
                w[pos] = bad;
                if pos + 1 < len {
                    w[len - 1] = f64::NAN; // a later one must not win
                }
                let (i, x) = first_non_finite(&w).expect("found");
                assert_eq!(i, pos);
                assert!(x.is_nan() == bad.is_nan() && (bad.is_nan() || x == bad));
            }
        }
    }
}

// ---------------------------------------------------------------- ode113

/// ode113 on y' = −y and the harmonic oscillator: the error at the
/// (interpolated) outputs against the exact solution falls in proportion
/// to rtol, and stays within a small multiple of it.
#[test]
fn ode113_error_proportional_to_rtol_on_decay_and_oscillator() {
    let tols = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10];
    let out = linspace(0.0, 10.0, 51);
    let errs: Vec<f64> = tols
        .iter()
        .map(|&tol| {
            let (rep, log) = run(
                Method::Ode113,
                opts(tol, tol * 1e-3),
                &mut decay(),
                0.0,
                10.0,
                &[1.0],
                &out,
            );
            assert_eq!(rep.termination, Termination::Completed);
            let e = max_err(&log.out_t, &log.out_y, |t| vec![(-t).exp()]);
            assert!(e < 20.0 * tol, "decay: error {e:e} at rtol {tol:e}");
            e
        })
        .collect();
    assert_tolerance_proportional("ode113 decay", &tols, &errs, 2.5, 40.0);

    let out = linspace(0.0, 4.0 * PI, 81);
    let errs: Vec<f64> = tols
        .iter()
        .map(|&tol| {
            let (rep, log) = run(
                Method::Ode113,
                opts(tol, tol * 1e-3),
                &mut oscillator(),
                0.0,
                4.0 * PI,
                &[1.0, 0.0],
                &out,
            );
            assert_eq!(rep.termination, Termination::Completed);
            max_err(&log.out_t, &log.out_y, oscillator_exact)
        })
        .collect();
    assert_tolerance_proportional("ode113 oscillator", &tols, &errs, 2.5, 40.0);
}

/// ode113 on the Kepler orbit (e = 0.5, one period): the error falls with
/// rtol, and at tight tolerances it needs fewer right-hand-side
/// evaluations than ode45 for a smaller error — the reason to use a
/// high-order multistep method on a smooth, expensive problem.
#[test]
fn ode113_kepler_converges_and_is_cheaper_than_ode45_at_tight_tolerance() {
    let period = 2.0 * PI;
    let out = linspace(0.0, period, 41);
    let y0 = kepler_y0();
    let tols = [1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11];
    let mut evals = Vec::new();
    let errs: Vec<f64> = tols
        .iter()
        .map(|&tol| {
            let (rep, log) = run(
                Method::Ode113,
                opts(tol, tol * 1e-3),
                &mut kepler(),
                0.0,
                period,
                &y0,
                &out,
            );
            assert_eq!(rep.termination, Termination::Completed);
            // MATLAB's count: 1 + 2 per accepted step + 1 per rejection.
            assert_eq!(
                rep.stats.rhs_evals,
                1 + 2 * rep.stats.steps + rep.stats.failed_steps
            );
            evals.push(rep.stats.rhs_evals);
            max_err(&log.out_t, &log.out_y, kepler_exact)
        })
        .collect();
    // At rtol 1e-5 the error is not yet in its asymptotic regime (it is
    // 1.7e-5 there against 2.9e-5 at 1e-6); from 1e-6 on every decade of
    // rtol gains between 4x and 64x (measured), overall about one decade.
    assert!(errs[0] < 1e-4, "{errs:?}");
    assert_tolerance_proportional("ode113 Kepler", &tols[1..], &errs[1..], 2.0, 100.0);
    for tol in [1e-10, 1e-11] {
        let i = tols.iter().position(|&x| x == tol).unwrap();
        let (rep45, log45) = run(
            Method::Ode45,
            opts(tol, tol * 1e-3),
            &mut kepler(),
            0.0,
            period,
            &y0,
            &out,
        );
        let e45 = max_err(&log45.out_t, &log45.out_y, kepler_exact);
        eprintln!(
            "Kepler rtol {tol:e}: ode113 {} evaluations, error {:.2e}; ode45 {} evaluations, error {e45:.2e}",
            evals[i], errs[i], rep45.stats.rhs_evals
        );
        assert!(
            2 * evals[i] < rep45.stats.rhs_evals,
            "ode113 should need under half of ode45's evaluations at rtol {tol:e}: {} vs {}",
            evals[i],
            rep45.stats.rhs_evals
        );
        // Same accuracy class: within 10x of ode45's error.
        assert!(errs[i] < 10.0 * e45, "{} vs {e45}", errs[i]);
    }
}

/// The dense output of ode113 is the step's interpolating polynomial:
/// at many points inside the steps of the oscillator its error is of the
/// size of the error at the step ends.
#[test]
fn ode113_dense_output_is_as_accurate_as_the_steps() {
    let out = linspace(0.0, 2.0 * PI, 2001);
    let (rep, log) = run(
        Method::Ode113,
        opts(1e-9, 1e-12),
        &mut oscillator(),
        0.0,
        2.0 * PI,
        &[1.0, 0.0],
        &out,
    );
    assert!(rep.stats.steps < 400, "{} steps", rep.stats.steps);
    let e_steps = max_err(&log.step_t, &log.step_y, oscillator_exact);
    let e_out = max_err(&log.out_t, &log.out_y, oscillator_exact);
    assert!(e_steps < 1e-8, "{e_steps:e}");
    assert!(
        e_out < 3.0 * e_steps,
        "dense {e_out:e} vs steps {e_steps:e}"
    );
}

/// A post-step hook that moves the state (here: back onto the invariant
/// circle of the oscillator) is taken into ode113's history: the run
/// stays as accurate as without it, and the moved state is what the
/// steps report.
#[test]
fn ode113_post_step_projection_keeps_accuracy() {
    struct Circle;
    impl OdeSystem for Circle {
        fn dim(&self) -> usize {
            2
        }
        fn rhs(&mut self, _t: f64, y: &[f64], d: &mut [f64]) -> Result<(), SystemError> {
            d[0] = y[1];
            d[1] = -y[0];
            Ok(())
        }
        fn post_step(&mut self, _t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
            let r = y[0].hypot(y[1]);
            y[0] /= r;
            y[1] /= r;
            Ok(true)
        }
    }
    let out = linspace(0.0, 20.0, 201);
    let (rep, log) = run(
        Method::Ode113,
        opts(1e-8, 1e-11),
        &mut Circle,
        0.0,
        20.0,
        &[1.0, 0.0],
        &out,
    );
    assert_eq!(rep.termination, Termination::Completed);
    for y in &log.step_y {
        assert!((y[0].hypot(y[1]) - 1.0).abs() < 1e-15);
    }
    let e = max_err(&log.out_t, &log.out_y, oscillator_exact);
    let (_, plain) = run(
        Method::Ode113,
        opts(1e-8, 1e-11),
        &mut oscillator(),
        0.0,
        20.0,
        &[1.0, 0.0],
        &out,
    );
    let e_plain = max_err(&plain.out_t, &plain.out_y, oscillator_exact);
    assert!(e < 2.0 * e_plain && e < 1e-6, "{e:e} vs {e_plain:e}");
    assert_eq!(
        rep.stats.rhs_evals,
        1 + 3 * rep.stats.steps + rep.stats.failed_steps
    );
}
