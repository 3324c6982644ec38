//! Problem A (four-bar, paper §4.1): physics checks of the whole pipeline.

use crate::common::fourbar::fourbar;
use mbsolve::formulation::{Baumgarte, Formulation, Index1, Index1Options};
use mbsolve::integrate::{Method, Tolerance};

use mbsolve::scenario::Scenario;
use mbsolve::simulation::simulate;

fn tight(sc: &mut Scenario) {
    sc.run.method = Method::Ode45;
    sc.run.ode.rtol = 1e-11;
    sc.run.ode.atol = Tolerance::Scalar(1e-13);
}

#[test]
fn assembly_keeps_the_crank_and_closes_the_loop() {
    let sc = fourbar(&[]);
    let a = sc.assembly.as_ref().unwrap();
    assert!(a.position_residual < 1e-12, "{}", a.position_residual);
    assert!(a.velocity_residual < 1e-12, "{}", a.velocity_residual);
    assert!((sc.q0[2] - 60f64.to_radians()).abs() < 1e-15);
    assert!((sc.qd0[2] - 2.0 * std::f64::consts::PI).abs() < 1e-12);
    // C above the ground line: rocker centre y > 0 and angle in (0, π)
    assert!(sc.q0[7] > 0.0 && sc.q0[8] > 0.0 && sc.q0[8] < std::f64::consts::PI);
    // crank pin velocities from Φ_q q̇ = 0: centre of the crank moves at ω × r
    let w = sc.qd0[2];
    let (c, s) = (sc.q0[2].cos(), sc.q0[2].sin());
    assert!((sc.qd0[0] + w * 0.1 * s).abs() < 1e-12 && (sc.qd0[1] - w * 0.1 * c).abs() < 1e-12);
}

#[test]
fn incorrect_state_is_not_fixed() {
    let good = fourbar(&[]);
    let bad = fourbar(&["initial.incorrect=true"]);
    for k in 0..9 {
        let d = bad.q0[k] - good.q0[k];
        let expect = if k == 5 { 0.05 } else { 0.0 };
        assert!((d - expect).abs() < 1e-15, "coordinate {k}: {d}");
    }
    assert_eq!(bad.qd0, good.qd0);
    let norm = bad.system.constraint_norm(&bad.q0, 0.0);
    // both pins B and C open by about 1 cm
    assert!(norm > 0.01 && norm < 0.03, "{norm}");
}

#[test]
fn energy_balance_and_freudenstein_closure() {
    let mut sc = fourbar(&[]);
    tight(&mut sc);
    let (traj, summary) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(summary.status, "completed");
    let sys = &sc.system;
    let e0 = sys.kinetic_energy(&traj.qd[0]) + sys.potential_energy(&traj.q[0]);
    let (l1, l2, l3, d) = (0.2, 0.4, 0.25, 0.4);
    let (k1, k2, k3) = (
        d / l1,
        d / l3,
        (l1 * l1 - l2 * l2 + l3 * l3 + d * d) / (2.0 * l1 * l3),
    );
    let mut max_work_err: f64 = 0.0;
    let mut max_freud: f64 = 0.0;
    for (k, q) in traj.q.iter().enumerate() {
        // work of the constant driving torque M = 0.5 N·m
        let work = 0.5 * (q[2] - traj.q[0][2]);
        let e = sys.kinetic_energy(&traj.qd[k]) + sys.potential_energy(q);
        max_work_err = max_work_err.max((e - e0 - work).abs());
        // Freudenstein: K1 cos θ3 − K2 cos θ1 + K3 = cos(θ1 − θ3)
        let (t1, t3) = (q[2], q[8]);
        let f = k1 * t3.cos() - k2 * t1.cos() + k3 - (t1 - t3).cos();
        max_freud = max_freud.max(f.abs());
    }
    let scale = 0.5 * (traj.q.last().unwrap()[2] - traj.q[0][2]);
    assert!(scale > 1.0, "the crank turns ({scale} J of work)");
    assert!(
        max_work_err < 1e-7 * scale,
        "energy balance error {max_work_err:e} J (work {scale} J)"
    );
    assert!(max_freud < 1e-8, "Freudenstein residual {max_freud:e}");
    // the crank turns fully (Grashof): more than one revolution in 2 s
    assert!(traj.q.last().unwrap()[2] - traj.q[0][2] > 2.0 * std::f64::consts::PI);
}

#[test]
fn baumgarte_decay_of_an_incorrect_state() {
    // eq. (10) with α = β = 10 is critically damped: ‖Φ‖ ~ (1 + 10 t) e^(−10 t).
    let mut sc = fourbar(&[
        "initial.incorrect=true",
        "stabilization.alpha=10",
        "stabilization.beta=10",
    ]);
    tight(&mut sc);
    let (traj, _) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    let n0 = traj.constraint_norm[0];
    let n_end = *traj.constraint_norm.last().unwrap();
    assert!(
        n_end < 1e-6 * n0,
        "‖Φ‖ from {n0:e} to {n_end:e}: less than six orders"
    );
    // and it follows the predicted envelope at t = 0.5 and 1 s within a factor 3
    for (k, t) in traj.t.iter().enumerate() {
        if (*t - 0.5).abs() < 1e-9 || (*t - 1.0).abs() < 1e-9 {
            let pred = n0 * (1.0 + 10.0 * t) * (-10.0 * t).exp();
            let r = traj.constraint_norm[k] / pred;
            assert!(
                r > 1.0 / 3.0 && r < 3.0,
                "t = {t}: ‖Φ‖ = {:e}, predicted {pred:e}",
                traj.constraint_norm[k]
            );
        }
    }

    let mut sc = fourbar(&["initial.incorrect=true"]);
    tight(&mut sc);
    let (traj, _) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    let n0 = traj.constraint_norm[0];
    let n_end = *traj.constraint_norm.last().unwrap();
    assert!(
        n_end > 0.1 * n0,
        "without stabilization ‖Φ‖ must not decay: {n0:e} → {n_end:e}"
    );
}

#[test]
fn saddle_and_eliminated_formulations_agree() {
    let sc = fourbar(&["initial.incorrect=true"]);
    let sys = &sc.system;
    let mk = |formulation| Index1Options {
        formulation,
        baumgarte: Baumgarte {
            alpha: 3.0,
            beta: 4.0,
        },
        ..Default::default()
    };
    let mut a = Index1::new(sys, mk(Formulation::Saddle)).unwrap();
    let mut b = Index1::new(sys, mk(Formulation::Eliminated)).unwrap();
    let n = sys.n_coords();
    let mut seed = 7u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    for _ in 0..10 {
        let q: Vec<f64> = sc.q0.iter().map(|v| v + 0.05 * rnd()).collect();
        let qd: Vec<f64> = sc.qd0.iter().map(|v| v + rnd()).collect();
        let (mut qa, mut qb) = (vec![0.0; n], vec![0.0; n]);
        a.accelerations(0.1, &q, &qd, &mut qa).unwrap();
        b.accelerations(0.1, &q, &qd, &mut qb).unwrap();
        let scale = qa.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        for i in 0..n {
            assert!(
                (qa[i] - qb[i]).abs() < 1e-11 * scale,
                "q̈[{i}]: {} vs {}",
                qa[i],
                qb[i]
            );
        }
        for (la, lb) in a.lambda().iter().zip(b.lambda()) {
            assert!(
                (la - lb).abs() < 1e-10 * (1.0 + la.abs()),
                "λ: {la} vs {lb}"
            );
        }
    }
}

#[test]
fn ode23_at_matlab_defaults_runs_the_paper_case() {
    let sc = fourbar(&[]);
    let (traj, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "completed");
    assert_eq!(s.rhs_evals, 3 * (s.steps + s.failed_steps) + 1);
    assert!((traj.t.last().unwrap() - 2.0).abs() < 1e-15);
    // drift without stabilization at RelTol 1e-3 is visible but bounded
    assert!(
        s.max_constraint_norm > 1e-6 && s.max_constraint_norm < 0.05,
        "{}",
        s.max_constraint_norm
    );
}

/// `integrator.method = "ode113"` on the four-bar (index-1 path, the
/// scenario's Baumgarte): against ode45 at rtol 1e-11 the deviation of
/// positions (and velocities / 10) over the run falls with rtol and is
/// no larger than ode45's own at the same rtol.
#[test]
fn ode113_agrees_with_tight_ode45() {
    let mut reference = fourbar(&[]);
    tight(&mut reference);
    let (tr, sr) = simulate(
        &reference.system,
        &reference.q0,
        &reference.qd0,
        &reference.run,
        &mut [],
    )
    .unwrap();
    assert_eq!(sr.status, "completed");
    let mut errs = Vec::new();
    for (rtol, atol) in [("1e-6", "1e-9"), ("1e-8", "1e-11"), ("1e-10", "1e-13")] {
        for m in ["ode113", "ode45"] {
            let rt = format!("integrator.rtol={rtol}");
            let at = format!("integrator.atol={atol}");
            let me = format!("integrator.method=\"{m}\"");
            let sc = fourbar(&[&me, &rt, &at]);
            let (tj, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
            assert_eq!(s.status, "completed");
            assert_eq!(tj.t, tr.t);
            let mut e: f64 = 0.0;
            for (k, (q, qd)) in tj.q.iter().zip(&tj.qd).enumerate() {
                for i in 0..q.len() {
                    e = e
                        .max((q[i] - tr.q[k][i]).abs())
                        .max((qd[i] - tr.qd[k][i]).abs() / 10.0);
                }
            }
            eprintln!(
                "four-bar {m} rtol {rtol}: max deviation from ode45 1e-11 {e:.2e}, {} evaluations",
                s.rhs_evals
            );
            errs.push(e);
        }
    }
    // errs = [ode113, ode45] per rtol. Measured: ode113 6.7e-3, 3.3e-5,
    // 5.2e-7 with 3900, 5648, 8001 evaluations; ode45 4.5e-2, 2.0e-4,
    // 7.1e-7 with 5707, 13897, 35455.
    for w in errs.chunks(2) {
        assert!(w[0] <= 2.0 * w[1], "ode113 {} vs ode45 {}", w[0], w[1]);
    }
    assert!(errs[0] > errs[2] && errs[2] > errs[4], "{errs:?}");
    assert!(errs[4] < 2e-6, "{errs:?}");
}
