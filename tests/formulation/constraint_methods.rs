//! The mass-orthogonal projection of the index-1 integrators, the
//! penalty formulation, and the parallelogram-loop chain through its
//! singular configurations against its one-degree-of-freedom reference.

use crate::common::fourbar::fourbar;
use crate::common::parallelogram::{crossings, departure as chain_error, energy_drift};
use crate::common::trajectory::max_diff;
use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::formulation::{
    Baumgarte, Formulation, FormulationError, Index1, Index1Options, Penalty, PenaltyParams,
    Projection,
};
use mbsolve::integrate::{Method, OdeSystem, StateView, Tolerance};
use mbsolve::model::System;
use mbsolve::scenario::{self, Scenario, FOURBAR_TOML};
use mbsolve::simulation::{simulate, RunConfig, Summary, Trajectory};

fn norm_inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0_f64, |a, b| a.max(b.abs()))
}

fn velocity_residual(sys: &System, q: &[f64], qd: &[f64], t: f64) -> f64 {
    let m = sys.n_constraints();
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    let (mut a, mut b) = (vec![0.0; m], vec![0.0; m]);
    sys.jacobian_values(q, t, &mut jac);
    sys.jacobian_mul(&jac, qd, &mut a);
    sys.phi_t(q, t, &mut b);
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x + y).abs())
        .fold(0.0, f64::max)
}

/// `xᵀ M y`.
fn m_dot(sys: &System, x: &[f64], y: &[f64]) -> f64 {
    sys.mass_diagonal()
        .iter()
        .zip(x.iter().zip(y))
        .map(|(m, (a, b))| m * a * b)
        .sum()
}

fn projected(enabled: bool) -> Index1Options {
    Index1Options {
        projection: Projection {
            enabled,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn projection_lands_on_the_manifold_mass_orthogonally() {
    // The incorrect four-bar: pins B and C open by ~1 cm, velocities
    // inconsistent with the perturbed positions.
    let sc = fourbar(&["initial.incorrect=true"]);
    let sys = &sc.system;
    let n = sys.n_coords();
    let mut f = Index1::new(sys, projected(true)).unwrap();
    let mut y: Vec<f64> = sc.q0.iter().chain(&sc.qd0).cloned().collect();
    // perturb the velocities off the manifold as well
    y[n + 5] += 0.7;
    let y0 = y.clone();
    assert!(f.post_step(0.0, &mut y).unwrap());
    let (q, qd) = y.split_at(n);
    let mut phi = vec![0.0; sys.n_constraints()];
    sys.phi(q, 0.0, &mut phi);
    assert!(norm_inf(&phi) <= 1e-10, "‖Φ‖∞ = {:e}", norm_inf(&phi));
    let vr = velocity_residual(sys, q, qd, 0.0);
    assert!(vr < 1e-12, "‖Φ_q q̇‖∞ = {vr:e}");
    let s = f.stats();
    assert_eq!(s.projections, 1);
    assert!(
        s.projection_iterations >= 2 && s.projection_iterations <= 6,
        "Newton iterations {}",
        s.projection_iterations
    );
    // Velocities: the correction is M-orthogonal to the new tangent space,
    // which contains q̇* (scleronomic: Φ_q q̇* = 0): Pythagoras in the M-norm.
    let dv: Vec<f64> = (0..n).map(|i| y0[n + i] - qd[i]).collect();
    let cos_v = m_dot(sys, &dv, qd) / (m_dot(sys, &dv, &dv) * m_dot(sys, qd, qd)).sqrt();
    assert!(
        cos_v.abs() < 1e-10,
        "velocity correction not M-orthogonal: {cos_v:e}"
    );
    // An identity-weighted correction would not be: the masses differ.
    let euclid: f64 = dv.iter().zip(qd).map(|(a, b)| a * b).sum::<f64>()
        / (dv.iter().map(|a| a * a).sum::<f64>() * qd.iter().map(|a| a * a).sum::<f64>()).sqrt();
    assert!(euclid.abs() > 1e-3, "Euclidean cosine {euclid:e}");
    // Positions: Newton with Φ_q at the iterates is the M-closest point to
    // second order in the ~1 cm correction.
    let dq: Vec<f64> = (0..n).map(|i| y0[i] - q[i]).collect();
    let cos_q = m_dot(sys, &dq, qd) / (m_dot(sys, &dq, &dq) * m_dot(sys, qd, qd)).sqrt();
    assert!(
        cos_q.abs() < 0.02,
        "position correction not M-orthogonal: {cos_q:e}"
    );

    // Off (the default): post_step leaves the state alone.
    let mut g = Index1::new(sys, Index1Options::default()).unwrap();
    let mut z = y0.clone();
    assert!(!g.post_step(0.0, &mut z).unwrap());
    assert_eq!(z, y0);
}

#[test]
fn projection_that_cannot_converge_is_a_typed_error() {
    let sc = fourbar(&["initial.incorrect=true"]);
    let sys = &sc.system;
    let opts = Index1Options {
        projection: Projection {
            enabled: true,
            tol: 1e-10,
            max_iter: 1,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut f = Index1::new(sys, opts).unwrap();
    let mut y: Vec<f64> = sc.q0.iter().chain(&sc.qd0).cloned().collect();
    let e = f.post_step(0.25, &mut y).unwrap_err();
    match e.downcast_ref::<FormulationError>() {
        Some(FormulationError::Projection {
            t,
            residual,
            iterations,
            ..
        }) => {
            assert_eq!((*t, *iterations), (0.25, 1));
            assert!(*residual > 1e-10 && *residual < 1e-2, "{residual:e}");
        }
        other => panic!("expected a projection error, got {other:?}"),
    }
    let bad = Index1Options {
        projection: Projection {
            enabled: true,
            tol: -1.0,
            max_iter: 3,
            ..Default::default()
        },
        ..Default::default()
    };
    let msg = Index1::new(sys, bad).err().unwrap().to_string();
    assert!(msg.contains("tol") && msg.contains("-1"), "{msg}");
}

fn run(sc: &Scenario, cfg: &RunConfig) -> (Trajectory, Summary) {
    crate::common::setup::completed(&sc.system, &sc.q0, &sc.qd0, cfg)
}

#[test]
fn projected_runs_stay_on_the_manifold_and_on_the_reference() {
    // The four-bar over 2 s: ode45 at rtol 1e-12 as the reference; each
    // explicit method at loose tolerances with and without projection.
    let sc = fourbar(&[]);
    let mut reference = sc.run.clone();
    reference.method = Method::Ode45;
    reference.ode.rtol = 1e-12;
    reference.ode.atol = Tolerance::Scalar(1e-14);
    let (tr, _) = run(&sc, &reference);
    for (method, rtol, step) in [
        (Method::Ode23, 1e-5, None),
        (Method::Ode45, 1e-6, None),
        (Method::Rk4, 0.0, Some(5e-4)),
    ] {
        run_projected(&sc, &tr, method, rtol, step, Index1Options::default());
    }
    // with Baumgarte terms, and with λ eliminated
    let baumgarte = Index1Options {
        baumgarte: Baumgarte {
            alpha: 10.0,
            beta: 10.0,
        },
        ..Default::default()
    };
    run_projected(&sc, &tr, Method::Ode45, 1e-6, None, baumgarte);
    let eliminated = Index1Options {
        formulation: Formulation::Eliminated,
        ..Default::default()
    };
    run_projected(&sc, &tr, Method::Ode23, 1e-5, None, eliminated);
}

fn run_projected(
    sc: &Scenario,
    tr: &Trajectory,
    method: Method,
    rtol: f64,
    step: Option<f64>,
    index1: Index1Options,
) {
    {
        let mut cfg = sc.run.clone();
        cfg.method = method;
        cfg.formulation = index1;
        if let Some(h) = step {
            cfg.ode.fixed_step = Some(h);
        } else {
            cfg.ode.rtol = rtol;
            cfg.ode.atol = Tolerance::Scalar(rtol * 1e-2);
        }
        let (t0, s0) = run(sc, &cfg);
        cfg.formulation.projection.enabled = true;
        let (t1, s1) = run(sc, &cfg);
        let (e0, e1) = (max_diff(&t0, tr), max_diff(&t1, tr));
        eprintln!(
            "{method:?} {:?} α = {}: max‖Φ‖ {:.2e} → {:.2e}, max‖Φ̇‖ {:.2e} → {:.2e}, error {e0:.2e} → {e1:.2e}, \
             steps {} → {}, projections {:?}",
            index1.formulation,
            index1.baumgarte.alpha,
            s0.max_constraint_norm,
            s1.max_constraint_norm,
            s0.max_velocity_constraint_norm,
            s1.max_velocity_constraint_norm,
            s0.steps,
            s1.steps,
            s1.extra.get("projections"),
        );
        // on the manifold at the step ends (the last output is one); the
        // dense output between two projected ends deviates by the local error
        assert!(s1.final_constraint_norm < 1e-10, "{method:?}: {s1:?}");
        let (q, qd) = (t1.q.last().unwrap(), t1.qd.last().unwrap());
        let vr = velocity_residual(&sc.system, q, qd, 2.0);
        assert!(vr < 1e-10, "{method:?}: ‖Φ_q q̇‖∞ = {vr:e}");
        // (Baumgarte terms already keep the drift small)
        let gain = if index1.baumgarte.is_off() {
            100.0
        } else {
            2.0
        };
        assert!(s0.max_constraint_norm > gain * s1.max_constraint_norm);
        if index1.baumgarte.is_off() {
            assert!(s0.max_velocity_constraint_norm > s1.max_velocity_constraint_norm);
        }
        assert_eq!(s1.extra["projections"], s1.steps);
        // projection does not make the trajectory worse than the method's error
        assert!(e1 < 2.0 * e0 + 1e-9, "{method:?}: error {e0:e} → {e1:e}");
    }
}

#[test]
fn penalty_violation_falls_like_one_over_alpha() {
    // Φ̈ + 2ξωΦ̇ + ω²Φ = λ/α: the violation is O(λ/(αω²)).
    let sc = fourbar(&[]);
    let mut reference = sc.run.clone();
    reference.method = Method::Ode45;
    reference.ode.rtol = 1e-11;
    reference.ode.atol = Tolerance::Scalar(1e-13);
    reference.t_end = 1.0;
    let (tr, _) = run(&sc, &reference);
    let alphas = [1e4, 1e5, 1e6, 1e7];
    let mut viol = Vec::new();
    let mut err = Vec::new();
    for &alpha in &alphas {
        let mut cfg = reference.clone();
        cfg.formulation.formulation = Formulation::Penalty;
        cfg.formulation.penalty = PenaltyParams {
            alpha,
            ..Default::default()
        };
        let (t, s) = run(&sc, &cfg);
        assert_eq!(s.formulation, "penalty");
        viol.push(s.max_constraint_norm);
        err.push(max_diff(&t, &tr));
        eprintln!(
            "α = {alpha:e}: max‖Φ‖ = {:.3e}, max |q − q_index1| = {:.3e}, steps {}",
            s.max_constraint_norm,
            err.last().unwrap(),
            s.steps
        );
    }
    // least-squares slope of log max‖Φ‖ against log α
    let xs: Vec<f64> = alphas.iter().map(|a| a.log10()).collect();
    let ys: Vec<f64> = viol.iter().map(|v| v.log10()).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / 4.0, ys.iter().sum::<f64>() / 4.0);
    let slope = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (x - mx) * (y - my))
        .sum::<f64>()
        / xs.iter().map(|x| (x - mx) * (x - mx)).sum::<f64>();
    eprintln!("slope of log max‖Φ‖ vs log α: {slope:.3}");
    assert!((slope + 1.0).abs() < 0.1, "slope {slope}");
    // and the trajectory converges to the index-1 one
    for w in err.windows(2) {
        assert!(w[1] < 0.5 * w[0], "{err:?}");
    }
    assert!(err[3] < 1e-4, "{err:?}");
}

#[test]
fn penalty_accelerations_satisfy_the_penalty_equations() {
    // Checked in dense arithmetic against the formula
    // M q̈ + αΦ_qᵀ(Φ_q q̈ − γ + 2ξω(Φ_q q̇ + Φ_t) + ω²Φ) = g, off the manifold
    // (incorrect four-bar, perturbed velocities) and with a rheonomic drive.
    let fb = fourbar(&["initial.incorrect=true"]);
    let chain = parallelogram_chain(&ParallelogramChain {
        loops: 2,
        driven: true,
        ..Default::default()
    })
    .unwrap();
    let (cq, cv) = chain.initial_state();
    for (sys, q, mut qd, t) in [
        (&fb.system, fb.q0.clone(), fb.qd0.clone(), 0.3),
        (&chain, cq, cv, 0.7),
    ] {
        qd[1] += 0.2;
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let p = PenaltyParams {
            alpha: 1e5,
            xi: 0.7,
            omega: 12.0,
        };
        let opts = Index1Options {
            formulation: Formulation::Penalty,
            penalty: p,
            ..Default::default()
        };
        let mut f = Penalty::new(sys, opts).unwrap();
        let mut qdd = vec![0.0; n];
        let x = StateView { t, q: &q, qd: &qd };
        f.accelerations(x, &mut qdd).unwrap();
        let mut jac = vec![0.0; sys.jacobian_pattern().len()];
        sys.jacobian_values(&q, t, &mut jac);
        let mut dense = vec![vec![0.0; n]; m];
        for (&(r, c), v) in sys.jacobian_pattern().iter().zip(&jac) {
            dense[r][c] += v;
        }
        let (mut phi, mut phi_t, mut gamma, mut g) =
            (vec![0.0; m], vec![0.0; m], vec![0.0; m], vec![0.0; n]);
        sys.phi(&q, t, &mut phi);
        sys.phi_t(&q, t, &mut phi_t);
        sys.gamma(&q, &qd, t, &mut gamma);
        sys.forces_into(t, &q, &qd, &mut g);
        let mul = |row: &[f64], x: &[f64]| row.iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
        let lam: Vec<f64> = (0..m)
            .map(|r| {
                let phidot = mul(&dense[r], &qd) + phi_t[r];
                p.alpha
                    * (mul(&dense[r], &qdd) - gamma[r]
                        + 2.0 * p.xi * p.omega * phidot
                        + p.omega * p.omega * phi[r])
            })
            .collect();
        let scale = g.iter().map(|v| v.abs()).fold(1.0, f64::max)
            + lam.iter().map(|v| v.abs()).fold(0.0, f64::max);
        for i in 0..n {
            let ft: f64 = (0..m).map(|r| dense[r][i] * lam[r]).sum();
            let res = sys.mass_diagonal()[i] * qdd[i] + ft - g[i];
            assert!(
                res.abs() < 1e-9 * scale,
                "row {i}: residual {res:e} (scale {scale:e})"
            );
        }
        for (a, b) in f.lambda().iter().zip(&lam) {
            assert!((a - b).abs() < 1e-9 * scale, "λ {a} vs {b}");
        }
    }
}

#[test]
fn penalty_and_projection_from_scenario_keys() {
    let sc = fourbar(&[
        "formulation=penalty",
        "stabilization.penalty=1e6",
        "stabilization.penalty_omega=20",
    ]);
    assert_eq!(sc.run.formulation.formulation, Formulation::Penalty);
    assert_eq!(sc.run.formulation.penalty.alpha, 1e6);
    assert_eq!(sc.run.formulation.penalty.omega, 20.0);
    assert_eq!(sc.run.formulation.penalty.xi, 1.0);
    let (_, s) = run(&sc, &sc.run);
    assert_eq!(s.formulation, "penalty");
    assert_eq!(s.extra["penalty"], 1e6);
    assert_eq!(s.extra["penalty_omega"], 20.0);
    let sc = fourbar(&["stabilization.projection=true"]);
    assert!(sc.run.formulation.projection.enabled);
    let (_, s) = run(&sc, &sc.run);
    assert!(s.final_constraint_norm < 1e-10, "{s:?}");
    assert_eq!(s.extra["projections"], s.steps);

    let o = |sets: &[&str]| {
        let o: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        scenario::parse(FOURBAR_TOML, "f.toml", "f", &o)
            .expect_err("must be rejected")
            .to_string()
    };
    for (sets, key, word) in [
        (
            &["stabilization.penalty=1e6"][..],
            "stabilization.penalty",
            "penalty",
        ),
        (
            &["formulation=penalty", "stabilization.penalty=-3"][..],
            "stabilization.penalty",
            "-3",
        ),
        (
            &["formulation=penalty", "stabilization.penalty_xi=nan"][..],
            "stabilization.penalty_xi",
            "NaN",
        ),
        (
            &["formulation=penalty", "stabilization.alpha=5"][..],
            "stabilization.alpha",
            "penalty",
        ),
        (
            &["formulation=penalty", "stabilization.projection=true"][..],
            "stabilization.projection",
            "penalty",
        ),
        (
            &[
                "integrator.method=genalpha",
                "integrator.step=1e-3",
                "stabilization.projection=true",
            ][..],
            "stabilization.projection",
            "integrator.project",
        ),
    ] {
        let m = o(sets);
        assert!(m.contains(key) && m.contains(word), "{sets:?}: {m}");
    }
}

/// Runs the chain from the builder's exact initial state.
fn chain_run(p: &ParallelogramChain, cfg: &RunConfig) -> (Trajectory, String, f64) {
    let (traj, s) = chain_summary(p, cfg);
    (traj, s.status, s.t_reached)
}

fn chain_summary(p: &ParallelogramChain, cfg: &RunConfig) -> (Trajectory, Summary) {
    let sys = parallelogram_chain(p).unwrap();
    let (q0, v0) = sys.initial_state();
    let (traj, s) = simulate(&sys, &q0, &v0, cfg, &mut []).unwrap();
    eprintln!(
        "  status {} ({:?}), steps {}, regularised pivots {}, max‖Φ‖ {:.2e}",
        s.status, s.message, s.steps, s.regularized_pivots, s.max_constraint_norm
    );
    (traj, s)
}

#[test]
fn parallelogram_reference_is_the_builders_mechanism() {
    // The minimal-coordinate energy equals the multibody energy of the
    // builder's state, the state satisfies Φ = 0 and Φ_q q̇ = −Φ_t, and the
    // reference conserves ½Iθ̇² + C sin θ.
    for (loops, redundant) in [(1, false), (3, false), (3, true)] {
        let p = ParallelogramChain {
            loops,
            redundant,
            ..Default::default()
        };
        let sys = parallelogram_chain(&p).unwrap();
        if redundant {
            assert_eq!(sys.n_coords(), 3 * (loops + 2));
            assert_eq!(sys.n_constraints(), 4 * (loops + 1));
        } else {
            assert_eq!(sys.n_coords(), 3 * (2 * loops + 1));
            assert_eq!(sys.n_constraints(), 2 * (3 * loops + 1));
        }
        for th in [0.3, 1.0, 2.5, 4.0] {
            let (q, v) = p.state(th, 7.0);
            let e = sys.kinetic_energy(&v) + sys.potential_energy(&q);
            assert!((e - p.reduced_energy(th, 7.0)).abs() < 1e-12, "{e}");
            assert!(sys.constraint_norm(&q, 0.0) < 1e-15);
            assert!(velocity_residual(&sys, &q, &v, 0.0) < 1e-14);
            let a = p.marked_point_of(&q);
            let b = p.marked_point(th);
            assert!((a[0] - b[0]).abs() < 1e-15 && (a[1] - b[1]).abs() < 1e-15);
        }
        let times: Vec<f64> = (0..=100).map(|k| k as f64 * 0.1).collect();
        let e0 = p.reduced_energy(p.theta0, p.rate0);
        for (th, w) in p.reference(&times, 1e-4) {
            assert!((p.reduced_energy(th, w) - e0).abs() < 1e-10 * e0);
        }
    }
    let bad = ParallelogramChain {
        crank_length: -0.1,
        ..Default::default()
    };
    let msg = parallelogram_chain(&bad).unwrap_err().to_string();
    assert!(
        msg.contains("crank_length") && msg.contains("-0.1"),
        "{msg}"
    );
}

#[test]
fn parallelogram_chain_keeps_its_branch_with_projection() {
    // ode45 with projection against the 1-DOF reference over 10 s (49
    // singular crossings): one loop at rtol 1e-10, two loops at rtol 1e-6.
    // Two loops at rtol 1e-10 stop near the third crossing (step-size
    // collapse, reported as "failed", printed below); the unprojected runs
    // leave the branch at the first crossing and still "complete" (printed).
    let t_end = 10.0;
    for (loops, rtol) in [(1, 1e-10), (2, 1e-6)] {
        let p = ParallelogramChain {
            loops,
            ..Default::default()
        };
        let n_cross = crossings(&p, t_end);
        assert!(n_cross >= 4, "{n_cross} singular crossings");
        let mut cfg = RunConfig {
            method: Method::Ode45,
            t_end,
            output_dt: 0.005,
            ..Default::default()
        };
        cfg.ode.rtol = rtol;
        cfg.ode.atol = Tolerance::Scalar(rtol * 1e-2);
        let unprojected = cfg.clone();
        cfg.formulation.projection.enabled = true;
        let (traj, status, t_reached) = chain_run(&p, &cfg);
        let (worst, first) = chain_error(&p, &traj, 1e-3);
        eprintln!(
            "k = {loops}, rtol {rtol:e}, projected: {status} to t = {t_reached}, {n_cross} \
             crossings, max point error {worst:.3e} m (first > 1 mm at {first:?})"
        );
        assert_eq!(status, "completed");
        assert!(worst < 1e-3, "point error {worst:e} m, first at {first:?}");
        // the energy (no dissipation) within 1e-4 relative
        let sys = parallelogram_chain(&p).unwrap();
        let e0 = p.reduced_energy(p.theta0, p.rate0);
        let de = energy_drift(&p, &sys, &traj);
        eprintln!("  max |E − E0| = {de:.3e} J of {e0:.3} J");
        assert!(de < 1e-4 * e0, "energy drift {de:e} J");
        // Report (not assert) what the unprojected run does.
        let (traj, status, t_reached) = chain_run(&p, &unprojected);
        let (worst, first) = chain_error(&p, &traj, 1e-3);
        eprintln!(
            "k = {loops}, rtol {rtol:e}, unprojected: {status} to t = {t_reached}, max point \
             error {worst:.3e} m (first > 1 mm at {first:?})"
        );
    }
    let p = ParallelogramChain {
        loops: 2,
        ..Default::default()
    };
    let mut cfg = RunConfig {
        method: Method::Ode45,
        t_end,
        output_dt: 0.005,
        ..Default::default()
    };
    cfg.ode.rtol = 1e-10;
    cfg.ode.atol = Tolerance::Scalar(1e-12);
    cfg.formulation.projection.enabled = true;
    let (traj, status, t_reached) = chain_run(&p, &cfg);
    let (worst, first) = chain_error(&p, &traj, 1e-3);
    eprintln!(
        "k = 2, rtol 1e-10, projected: {status} to t = {t_reached}, max point error {worst:.3e} m \
         (first > 1 mm at {first:?})"
    );
}

#[test]
fn redundant_parallelogram_chain_follows_the_reference() {
    // One coupler over three cranks (k = 2): 12 rows of rank 11. With
    // projection, ode45 at rtol 1e-5 follows the reference through all 49
    // singular crossings of 10 s, the regularised LDLᵀ solving the redundant
    // rows in the least-squares sense. Tighter tolerances stop at a singular
    // position (step-size collapse, "failed": printed, not asserted).
    let p = ParallelogramChain {
        loops: 2,
        redundant: true,
        ..Default::default()
    };
    let mut cfg = RunConfig {
        method: Method::Ode45,
        t_end: 10.0,
        output_dt: 0.005,
        ..Default::default()
    };
    cfg.formulation.projection.enabled = true;
    for rtol in [1e-5, 1e-6] {
        cfg.ode.rtol = rtol;
        cfg.ode.atol = Tolerance::Scalar(rtol * 1e-2);
        let (traj, s) = chain_summary(&p, &cfg);
        let (worst, first) = chain_error(&p, &traj, 1e-3);
        eprintln!(
            "redundant, rtol {rtol:e}, projected: {} to t = {}, max point error {worst:.3e} m \
             (first > 1 mm at {first:?}), regularised pivots {}",
            s.status, s.t_reached, s.regularized_pivots
        );
        if rtol == 1e-5 {
            assert_eq!(s.status, "completed", "{:?}", s.message);
            assert!(s.regularized_pivots > 0, "{s:?}");
            assert!(worst < 1e-3, "point error {worst:e} m, first at {first:?}");
        }
    }
}
