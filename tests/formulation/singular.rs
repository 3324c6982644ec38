//! Rank loss of Φ_q along a run is reported — the time
//! of the singular configuration and a method that handles it — and
//! redundant joints are reported as redundant, not as a singularity.

use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::scenario::{self, FOURBAR_TOML};
use mbsolve::simulation::{simulate, RunConfig, Summary};

fn extra(s: &Summary, key: &str) -> f64 {
    s.extra
        .get(key)
        .and_then(|v| v.as_f64())
        .unwrap_or_else(|| panic!("no {key} in {:?}", s.extra))
}

fn has(s: &Summary, words: &[&str]) -> bool {
    s.warnings
        .iter()
        .any(|w| words.iter().all(|x| w.contains(x)))
}

#[test]
fn parallelogram_chain_crossing_is_reported_with_its_time() {
    // The case: one parallelogram loop, ode45 at rtol 1e-8, no
    // stabilization. The run leaves its branch (the marked point ends far
    // from the 1-DOF reference) and still "completes" — but the summary and
    // the console now say when Φ_q lost rank and what to use instead, and
    // the energy balance shows the branch switch.
    let p = ParallelogramChain::default();
    let sys = parallelogram_chain(&p).unwrap();
    let (q0, v0) = sys.initial_state();
    let mut cfg = RunConfig {
        method: Method::Ode45,
        t_end: 10.0,
        output_dt: 0.005,
        ..Default::default()
    };
    cfg.ode.rtol = 1e-8;
    cfg.ode.atol = Tolerance::Scalar(1e-10);
    cfg.outputs.energy = true;
    let (traj, s) = simulate(&sys, &q0, &v0, &cfg, &mut []).unwrap();
    for w in &s.warnings {
        eprintln!("  - {w}");
    }
    // the reference's first singular position: θ through π (θ̇₀ > 0)
    let times: Vec<f64> = (0..=10_000).map(|k| k as f64 * 1e-4).collect();
    let th = p.reference(&times, 1e-5);
    let k = th
        .iter()
        .position(|(t, _)| *t >= std::f64::consts::PI)
        .unwrap();
    let t_sing = times[k];
    let t_found = extra(&s, "first_singular_t");
    eprintln!(
        "first singular position: reference {t_sing:.4} s, reported {t_found:.6} s; {} crossings",
        extra(&s, "singular_crossings")
    );
    assert!((t_found - t_sing).abs() < 2e-4, "{t_found} vs {t_sing}");
    assert!(extra(&s, "singular_crossings") >= 4.0);
    assert_eq!(extra(&s, "redundant_rows"), 0.0);
    assert!(has(
        &s,
        &["Φ_q lost rank at t ≈ 2.129", "partitioned", "projection"]
    ));
    // it did leave the branch, and the energy balance tells
    let last = traj.q.last().unwrap();
    let a = p.marked_point_of(last);
    let b = p.marked_point(p.reference(&[10.0], 1e-5)[0].0);
    let off = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    assert!(off > 1e-2, "still on the branch ({off:e} m)");
    assert!(has(&s, &["energy balance broken"]));
}

#[test]
fn projected_chain_crossing_is_reported_as_kept() {
    let p = ParallelogramChain::default();
    let sys = parallelogram_chain(&p).unwrap();
    let (q0, v0) = sys.initial_state();
    let mut cfg = RunConfig {
        method: Method::Ode45,
        t_end: 1.0,
        ..Default::default()
    };
    cfg.ode.rtol = 1e-8;
    cfg.ode.atol = Tolerance::Scalar(1e-10);
    cfg.formulation.projection.enabled = true;
    let (_, s) = simulate(&sys, &q0, &v0, &cfg, &mut []).unwrap();
    assert!(
        has(&s, &["lost rank", "keeps it on its branch"]),
        "{:?}",
        s.warnings
    );
    assert!(extra(&s, "singular_crossings") >= 1.0);
}

#[test]
fn two_loops_crossing_together_are_reported() {
    // Two identical loops lose rank together: det of the split changes sign
    // twice between two steps (an even crossing), which the sign test cannot
    // see; the local minimum of |det| finds it. The time must be the
    // 1-DOF reference's first singular position.
    let p = ParallelogramChain {
        loops: 2,
        ..Default::default()
    };
    let sys = parallelogram_chain(&p).unwrap();
    let (q0, v0) = sys.initial_state();
    let mut cfg = RunConfig {
        method: Method::Ode45,
        t_end: 2.0,
        ..Default::default()
    };
    cfg.ode.rtol = 1e-8;
    cfg.ode.atol = Tolerance::Scalar(1e-10);
    cfg.formulation.projection.enabled = true;
    let (_, s) = simulate(&sys, &q0, &v0, &cfg, &mut []).unwrap();
    let times: Vec<f64> = (0..=20_000).map(|k| k as f64 * 1e-4).collect();
    let th = p.reference(&times, 1e-5);
    let k = th
        .iter()
        .position(|(t, _)| *t >= std::f64::consts::PI)
        .unwrap();
    let t_found = extra(&s, "first_singular_t");
    eprintln!(
        "two loops: reference {:.4} s, reported {t_found:.6} s, {} crossings",
        times[k],
        extra(&s, "singular_crossings")
    );
    assert!(
        (t_found - times[k]).abs() < 1e-3,
        "{t_found} vs {}",
        times[k]
    );
    assert!(extra(&s, "singular_crossings") >= 2.0);
    assert!(has(&s, &["lost rank"]), "{:?}", s.warnings);
}

#[test]
fn four_bar_through_full_turns_reports_no_rank_loss() {
    // Full crank revolutions: the monitor's split goes singular and is
    // re-chosen, Φ_q never loses rank — no warning.
    let o: Vec<String> = [
        "integrator.method=\"ode45\"",
        "integrator.rtol=1e-8",
        "integrator.atol=1e-10",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let sc = scenario::parse(FOURBAR_TOML, "fourbar.toml", "fourbar", &o).unwrap();
    let (traj, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    let turns = (traj.q.last().unwrap()[2] - sc.q0[2]) / std::f64::consts::TAU;
    assert!(turns > 2.0, "{turns}");
    assert_eq!(extra(&s, "singular_crossings"), 0.0);
    assert_eq!(extra(&s, "redundant_rows"), 0.0);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn doubled_joint_is_reported_as_redundant_not_singular() {
    let text = format!(
        "{FOURBAR_TOML}\n[[joint]]\ntype = \"revolute\"\nname = \"B2\"\nbody_i = \"crank\"\n\
         point_i = [0.1, 0.0]\nbody_j = \"coupler\"\npoint_j = [-0.2, 0.0]\n"
    );
    let o = ["integrator.method=\"ode45\"".to_string()];
    let sc = scenario::parse(&text, "test.toml", "test", &o).unwrap();
    let (_, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    for w in &s.warnings {
        eprintln!("  - {w}");
    }
    assert_eq!(s.status, "completed");
    assert_eq!(extra(&s, "redundant_rows"), 2.0);
    assert_eq!(extra(&s, "singular_crossings"), 0.0);
    assert!(has(
        &s,
        &["2 of the 10 constraint rows are redundant", "least-squares"]
    ));
    assert!(has(&s, &["regularised pivots", "the redundant rows above"]));
    assert!(!has(&s, &["lost rank at"]), "{:?}", s.warnings);
}

/// A Newton collapse of an index-3 run where Φ_q kept its rank (the
/// four-bar, far from its singular positions, with one Newton iteration
/// allowed per attempt) is not blamed on a singular position: the message
/// says no pivot was regularised and does not recommend the augmented
/// Lagrangian (it did, with "0 regularised pivots", before).
#[test]
fn newton_collapse_without_rank_loss_is_not_called_singular() {
    let o: Vec<String> = [
        "integrator.method=\"genalpha\"",
        "integrator.step=1e-2",
        "integrator.max_newton=1",
        "integrator.newton_tol=1e-12",
        "integrator.min_step=1e-4",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let sc = scenario::parse(FOURBAR_TOML, "fourbar.toml", "fourbar", &o).unwrap();
    let (_, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "failed", "{:?}", s.message);
    let m = s.message.unwrap();
    assert!(m.contains("no regularised pivot"), "{m}");
    assert!(!m.contains("augmented_lagrangian"), "{m}");
}
