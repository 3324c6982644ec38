//! `integrator.method = "auto"` (`mbsolve::simulation::choice`): the
//! choice follows ode45's stability bound against the closed-form
//! frequency of a stiff spring, and whatever it chooses, the achieved error
//! on the shipped scenarios stays within 10 rtol of a reference run with
//! another method at a much tighter tolerance.

use mbsolve::scenario;
use mbsolve::simulation::choice::{choose, radau5_rtol, STIFF_STEPS};
use mbsolve::simulation::{simulate, MethodChoice};
use std::path::{Path, PathBuf};

fn path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(format!("{name}.toml"))
}

fn load(name: &str, overrides: &[&str]) -> scenario::Scenario {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    scenario::load(&path(name), &o).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The spring pendulum with the spring at its free length (so the motion
/// is the swing) and stiffness `k`: its fastest mode is the spring's
/// √(k/m) (m = 1 kg; the swing's √(g/r) and the tension's √(T/(m r)) are
/// far slower), so ode45's stability bound is `h = 3.3/√k` and the span of
/// 1 s needs `√k/3.3` steps for stability alone.
fn stiff_spring(k: f64) -> scenario::Scenario {
    load(
        "spring_pendulum",
        &[
            "integrator.method=auto",
            "integrator.rtol=1e-6",
            "integrator.atol=1e-9",
            "time.end=1.0",
            "force[0].free_length=0.8",
            &format!("force[0].stiffness={k}"),
        ],
    )
}

#[test]
fn auto_chooses_radau5_where_ode45_would_be_bound_by_stability() {
    let steps = |k: f64| k.sqrt() / 3.3; // the closed form above
    for (k, expect) in [(60.0, "ode45"), (1e7, "ode45"), (1e8, "radau5")] {
        let sc = stiff_spring(k);
        assert_eq!(sc.run.choice, MethodChoice::Auto);
        let (run, reason) = choose(&sc.system, &sc.run, &sc.q0, &sc.qd0).unwrap();
        assert_eq!(run.method.name(), expect, "k = {k}: {reason}");
        assert_eq!(
            steps(k) > STIFF_STEPS,
            expect == "radau5",
            "k = {k}: the closed form gives {:.0} stability steps",
            steps(k)
        );
        assert!(reason.starts_with(expect), "{reason}");
        assert_eq!(run.choice, MethodChoice::Given);
        if expect == "radau5" {
            // at the tighter tolerance that keeps its error near rtol
            assert!(run.implicit.adaptive);
            assert_eq!(run.ode.rtol, radau5_rtol(1e-6));
            assert!((radau5_rtol(1e-6) / 1e-10 - 1.0).abs() < 1e-12);
        }
    }
    // the run reports the choice and its reason
    let sc = stiff_spring(1e8);
    let (_, summary) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(summary.status, "completed");
    assert_eq!(summary.method, "radau5");
    assert_eq!(summary.extra["method_choice"], "radau5");
    let reason = summary.extra["method_choice_reason"].as_str().unwrap();
    assert!(reason.contains("stiff"), "{reason}");
}

#[test]
fn auto_takes_only_the_step_control_keys() {
    for bad in [
        "integrator.step=1e-3",
        "stabilization.alpha=10",
        "formulation=penalty",
    ] {
        let o = vec![
            "integrator.method=auto".to_string(),
            "integrator.rtol=1e-6".to_string(),
            bad.to_string(),
        ];
        let e = scenario::load(&path("fourbar"), &o)
            .unwrap_err()
            .to_string();
        let key = bad.split('=').next().unwrap();
        assert!(e.contains(key) && e.contains("auto"), "{bad}: {e}");
    }
    // from the command line, the file's keys of another method are dropped
    // with a note (here genalpha's step, ρ∞ and Newton settings)
    let sc = load("parallelogram_chain", &["integrator.method=auto"]);
    assert_eq!(sc.run.choice, MethodChoice::Auto);
}

/// Largest error over the output rows of `q` against `reference`, each
/// coordinate scaled by its largest magnitude in the reference run (at
/// least `floor`).
fn scaled_error(q: &[Vec<f64>], reference: &[Vec<f64>], floor: f64) -> f64 {
    assert_eq!(q.len(), reference.len());
    let n = reference[0].len();
    let scale: Vec<f64> = (0..n)
        .map(|k| reference.iter().fold(floor, |m, r| m.max(r[k].abs())))
        .collect();
    q.iter()
        .zip(reference)
        .flat_map(|(a, b)| (0..n).map(move |k| (a[k] - b[k]).abs()))
        .enumerate()
        .fold(0.0, |m, (i, d)| m.max(d / scale[i % n]))
}

#[test]
fn auto_errors_stay_within_ten_rtol_on_the_shipped_scenarios() {
    // (scenario, span, expected choice, tolerances): spans that keep the
    // test short; the falling rod's contact walls and segment springs make
    // ode45 need 8.7e3 steps per second for stability (radau5's case)
    let cases = [
        ("spring_pendulum", 2.0, "ode45", [1e-4, 1e-6]),
        ("slider_crank", 0.5, "ode45", [1e-4, 1e-6]),
        ("fourbar", 0.5, "ode45", [1e-4, 1e-6]),
        ("quarter_car", 1.0, "ode45", [1e-4, 1e-6]),
        ("two_rods", 0.2, "ode45", [1e-4, 1e-6]),
        ("falling_rod", 0.25, "radau5", [1e-3, 1e-4]),
    ];
    for (name, end, expect, rtols) in cases {
        for rtol in rtols {
            let run = |method: &str, rtol: f64, extra: &[&str]| {
                let mut o = vec![
                    format!("integrator.method={method}"),
                    format!("integrator.rtol={rtol:e}"),
                    format!("integrator.atol={:e}", rtol * 1e-3),
                    format!("time.end={end}"),
                    format!("output.dt={}", end / 20.0),
                ];
                o.extend(extra.iter().map(|s| s.to_string()));
                let sc = scenario::load(&path(name), &o).unwrap_or_else(|e| panic!("{name}: {e}"));
                let (traj, summary) =
                    simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
                assert_eq!(summary.status, "completed", "{name} {method}: {summary:?}");
                (traj, summary)
            };
            let (traj, summary) = run("auto", rtol, &[]);
            let chosen = summary.extra["method_choice"].as_str().unwrap().to_string();
            assert_eq!(chosen, expect, "{name}");
            // the reference: another method (ode113's error stays within
            // 2 rtol on these scenarios, docs/accuracy.md), 10⁴ times
            // tighter; or ode45 at 1e-8 for radau5's choice
            let (reference, _) = if chosen == "ode45" {
                run("ode113", rtol * 1e-4, &[])
            } else {
                run("ode45", 1e-8, &[])
            };
            let err = scaled_error(&traj.q, &reference.q, 1e-2);
            eprintln!(
                "{name} rtol {rtol:e}: {chosen}, {} steps, error {err:.2e} ({:.2} rtol)",
                summary.steps,
                err / rtol
            );
            assert!(
                err <= 10.0 * rtol,
                "{name} at rtol {rtol:e} ({chosen}): error {err:.3e} > 10 rtol"
            );
        }
    }
}
