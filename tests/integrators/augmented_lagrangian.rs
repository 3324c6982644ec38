//! The index-3 augmented Lagrangian with mass-orthogonal
//! projections (ALI3-P, Bayo & Ledesma 1996) with the trapezoidal rule and
//! generalized-α — through singular configurations, with redundant
//! constraints, and converging to ode45 with order 2.

use crate::common::fourbar::DOUBLED_B;
use crate::common::parallelogram::{branch_errors, crossings};
use crate::common::trajectory::max_diff;
use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::formulation::Formulation;
use mbsolve::integrate::Method;
use mbsolve::scenario::{Scenario, FOURBAR_TOML};
use mbsolve::simulation::{simulate, RunConfig, Summary, Trajectory};

fn parse(text: &str, overrides: &[&str]) -> Result<Scenario, String> {
    crate::common::setup::parse(text, overrides).map_err(|e| e.to_string())
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
    cfg.formulation.formulation = Formulation::AugmentedLagrangian;
    cfg.implicit.rho_inf = rho_inf;
    cfg.implicit.newton_tol = 1e-8;
    cfg.implicit.max_newton = 20;
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
    branch_errors(p, &parallelogram_chain(p).unwrap(), traj)
}

#[test]
fn parallelogram_chain_keeps_its_branch_through_singular_configurations() {
    // One loop, two loops, and two loops with one redundant coupler (12
    // rows of rank 11), over 10 s (49 singular crossings): trapezoidal and
    // generalized-α at h = 5e-4 follow the independent 1-DOF reference.
    // Two separate loops: at their crossings the multiplier iteration
    // contracts by only θ ≈ 0.87 … 0.99 per iteration (a nearly lost
    // constraint direction); the integrator raises the penalty within the
    // attempt (without that, Newton failed for every step size at
    // newton_tol 1e-8 … 1e-2 and needed 0.1).
    let t_end = 10.0;
    for (loops, redundant, tol) in [(1, false, 1e-8), (2, true, 1e-8), (2, false, 1e-8)] {
        let p = ParallelogramChain {
            loops,
            redundant,
            ..Default::default()
        };
        let n_cross = crossings(&p, t_end);
        assert!(n_cross >= 4, "{n_cross}");
        for (method, rho) in [(Method::Newmark, 1.0), (Method::GenAlpha, 0.9)] {
            let mut cfg = alm(method, rho, 5e-4, t_end, 0.005);
            cfg.implicit.newton_tol = tol;
            cfg.implicit.max_newton = 50;
            let (traj, s) = chain_run(&p, &cfg);
            let (worst, de) = chain_errors(&p, &traj);
            eprintln!(
                "k = {loops}, redundant {redundant}, {} ρ∞ = {rho}, newton_tol {tol:e}: {n_cross} \
                 crossings, point error {worst:.3e} m, energy {de:.3e} relative, max‖Φ‖ {:.2e}",
                method.name(),
                s.max_constraint_norm
            );
            assert_eq!(s.status, "completed", "{:?}", s.message);
            assert_eq!(s.formulation, "augmented_lagrangian");
            assert!(worst < 1e-3, "point error {worst:e} m");
            assert!(de < 1e-4, "energy error {de:e}");
            assert!(s.max_constraint_norm < 1e-8, "{}", s.max_constraint_norm);
            // the summary's penalty is the step's, not a value raised at a
            // crossing: that of a short run before the first crossing
            let (_, s0) = chain_run(&p, &alm(method, rho, 5e-4, 0.01, 0.005));
            assert_eq!(s.extra["penalty"], s0.extra["penalty"]);
            if loops == 2 && !redundant {
                assert!(s.extra["penalty_increases"].as_u64().unwrap() > 0);
                assert!(s.extra["max_penalty_factor"].as_f64().unwrap() > 1.0);
            }
        }
    }
}

#[test]
fn genalpha_small_step_passes_singular_positions() {
    // Generalized-α (index 3) at h = 1e-4 once stopped at a
    // singular position: its Newton corrections stagnated at the noise of
    // the regularised solve (~1e-11 m), above `STAGNATION` tolerances, and
    // each step cut shrank the tolerance further. Now the driven two-loop
    // chain and the free three-loop chain run through 10 s. The redundant
    // chain at h = 1e-4 and 5e-4: tests/formulation/redundant.rs.
    for (loops, driven) in [(2, true), (3, false)] {
        let p = ParallelogramChain {
            loops,
            driven,
            ..Default::default()
        };
        let mut cfg = RunConfig {
            method: Method::GenAlpha,
            t_end: 10.0,
            output_dt: 0.005,
            ..Default::default()
        };
        cfg.ode.fixed_step = Some(1e-4);
        let (traj, s) = chain_run(&p, &cfg);
        let (worst, _) = chain_errors(&p, &traj);
        eprintln!("genalpha k = {loops}, driven {driven}: point error {worst:.3e} m");
        assert_eq!(s.status, "completed", "{:?}", s.message);
        assert!(worst < 1e-3, "point error {worst:e} m");
    }
}

fn run(sc: &Scenario) -> (Trajectory, Summary) {
    crate::common::setup::completed(&sc.system, &sc.q0, &sc.qd0, &sc.run)
}

fn reference(text: &str) -> Trajectory {
    let sc = parse(
        text,
        &[
            "integrator.method=ode45",
            "integrator.rtol=1e-12",
            "integrator.atol=1e-14",
            "time.end=1.0",
            "output.dt=0.01",
        ],
    )
    .unwrap();
    run(&sc).0
}

#[test]
fn converges_to_ode45_with_order_two() {
    // The four-bar (free, crank with its initial rate) from scenario keys:
    // trapezoidal and generalized-α against ode45 at rtol 1e-12; the
    // observed order log2(e(h)/e(h/2)) of the largest position error.
    let reference = reference(FOURBAR_TOML);
    for (method, extra) in [
        ("trapezoidal", None),
        ("genalpha", Some("integrator.rho_inf=0.9")),
    ] {
        let mut errs = Vec::new();
        for h in [4e-4, 2e-4, 1e-4, 5e-5] {
            let step = format!("integrator.step={h}");
            let m = format!("integrator.method={method}");
            let mut o = vec![
                "formulation=augmented_lagrangian",
                m.as_str(),
                step.as_str(),
                "integrator.newton_tol=1e-9",
                "integrator.max_newton=20",
                "time.end=1.0",
                "output.dt=0.01",
            ];
            o.extend(extra);
            let sc = parse(FOURBAR_TOML, &o).unwrap();
            let (t, s) = run(&sc);
            assert_eq!(s.formulation, "augmented_lagrangian");
            errs.push(max_diff(&t, &reference));
        }
        let orders: Vec<f64> = errs.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
        eprintln!("four-bar {method}: errors {errs:?}, observed orders {orders:.3?}");
        // pre-asymptotic above 2 at the largest steps, then 2
        for p in &orders {
            assert!(*p > 1.8, "order {p} ({errs:?})");
        }
        let last = orders[orders.len() - 1];
        assert!((1.8..2.5).contains(&last), "order {last} ({errs:?})");
    }
}

#[test]
fn slider_crank_follows_its_closed_form_kinematics() {
    // Driven at φ = 10 t: the slider's x = r cos φ + √(l² − r² sin² φ)
    // (r = 0.1, l = 0.3) and its rate, at every output time, for every
    // step: positions held to the Newton tolerance, velocities by the
    // projection.
    // the shipped file's ode45 tolerances do not apply to a fixed step
    let text = include_str!("../../scenarios/slider_crank.toml")
        .replace("rtol = 1e-10\n", "")
        .replace("atol = 1e-12\n", "");
    let text = text.as_str();
    for h in [2e-3, 5e-4] {
        let step = format!("integrator.step={h}");
        let sc = parse(
            text,
            &[
                "formulation=augmented_lagrangian",
                "integrator.method=trapezoidal",
                step.as_str(),
                "output.quantities=[]",
            ],
        )
        .unwrap();
        let (t, _) = run(&sc);
        let (r, l) = (0.1_f64, 0.3_f64);
        let (mut ex, mut ev) = (0.0_f64, 0.0_f64);
        for ((tk, q), qd) in t.t.iter().zip(&t.q).zip(&t.qd) {
            let phi = 10.0 * tk;
            let root = (l * l - r * r * phi.sin().powi(2)).sqrt();
            let x = r * phi.cos() + root;
            let xd = -10.0 * r * phi.sin() - 10.0 * r * r * phi.sin() * phi.cos() / root;
            ex = ex.max((q[6] - x).abs());
            ev = ev.max((qd[6] - xd).abs());
        }
        eprintln!(
            "slider-crank h = {h:e}: |x − x_exact| ≤ {ex:.3e} m, |ẋ − ẋ_exact| ≤ {ev:.3e} m/s"
        );
        assert!(ex < 1e-9, "{ex:e}");
        assert!(ev < 1e-6, "{ev:e}");
    }
}

#[test]
fn doubled_joint_runs_like_the_plain_four_bar() {
    // Joint B doubled: 10 rows of rank 8. The augmented Lagrangian needs
    // no regularisation (the penalty term is semi-definite) and gives the
    // plain four-bar's motion.
    let o = [
        "formulation=augmented_lagrangian",
        "integrator.method=trapezoidal",
        "integrator.step=1e-4",
        "integrator.newton_tol=1e-9",
        "time.end=1.0",
        "output.dt=0.01",
    ];
    let text = format!("{FOURBAR_TOML}\n{DOUBLED_B}");
    let red = parse(&text, &o).unwrap();
    assert_eq!(red.system.n_constraints(), 10);
    let plain = parse(FOURBAR_TOML, &o).unwrap();
    let (tr, sr) = run(&red);
    let (tp, _) = run(&plain);
    let d = max_diff(&tr, &tp);
    let e = max_diff(&tr, &reference(FOURBAR_TOML));
    eprintln!(
        "doubled B: {} steps, |Δq| vs plain {d:.3e}, vs ode45 {e:.3e}",
        sr.steps
    );
    // the doubled rows double the penalty weight of B in the projections:
    // a difference well inside the discretisation error
    assert!(d < 0.2 * e, "{d:e}");
    assert!(e < 1e-3, "{e:e}");
    assert!(sr.max_constraint_norm < 1e-10);
}

#[test]
fn scenario_keys_are_checked() {
    let ok = parse(
        FOURBAR_TOML,
        &[
            "formulation=augmented_lagrangian",
            "integrator.method=trapezoidal",
            "integrator.step=1e-3",
            "stabilization.penalty=1e9",
        ],
    )
    .unwrap();
    assert_eq!(ok.run.method, Method::Newmark);
    assert_eq!(ok.run.implicit.rho_inf, 1.0);
    assert_eq!(ok.run.augmented.alpha, Some(1e9));
    for (o, key, value) in [
        (
            vec!["integrator.method=ode45"],
            "formulation",
            "augmented_lagrangian",
        ),
        (
            vec![
                "integrator.method=trapezoidal",
                "integrator.step=1e-3",
                "integrator.project=true",
            ],
            "integrator.project",
            "",
        ),
        (
            vec![
                "integrator.method=trapezoidal",
                "integrator.step=1e-3",
                "integrator.rho_inf=0.5",
            ],
            "integrator.rho_inf",
            "0.5",
        ),
        (
            vec![
                "integrator.method=genalpha",
                "integrator.step=1e-3",
                "stabilization.penalty=-1",
            ],
            "stabilization.penalty",
            "-1",
        ),
        (
            vec![
                "integrator.method=genalpha",
                "integrator.step=1e-3",
                "linear_solver=schur",
            ],
            "linear_solver",
            "schur",
        ),
        (
            vec![
                "integrator.method=genalpha",
                "integrator.step=1e-3",
                "stabilization.penalty_xi=1",
            ],
            "stabilization.penalty_xi",
            "",
        ),
    ] {
        let mut all = vec!["formulation=augmented_lagrangian"];
        all.extend(o);
        let e = parse(FOURBAR_TOML, &all).unwrap_err();
        assert!(
            e.contains("test.toml") && e.contains(key) && e.contains(value),
            "{e}"
        );
    }
    // not with the other formulations
    let e = parse(
        FOURBAR_TOML,
        &["integrator.method=ode45", "stabilization.penalty=1e8"],
    )
    .unwrap_err();
    assert!(e.contains("stabilization.penalty"), "{e}");
}

/// Dense Gaussian elimination with partial pivoting (test-local: independent
/// of the library's solvers).
fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for k in 0..n {
        let p = (k..n)
            .max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))
            .unwrap();
        a.swap(k, p);
        b.swap(k, p);
        for i in k + 1..n {
            let f = a[i][k] / a[k][k];
            let (top, bottom) = a.split_at_mut(i);
            for (x, y) in bottom[0][k..].iter_mut().zip(&top[k][k..]) {
                *x -= f * y;
            }
            b[i] -= f * b[k];
        }
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        let s: f64 = (k + 1..n).map(|j| a[k][j] * x[j]).sum();
        x[k] = (b[k] - s) / a[k][k];
    }
    x
}

/// `[M Φ_qᵀ; Φ_q 0]` at `q` (dense).
fn kkt(sys: &mbsolve::model::System, q: &[f64], t: f64) -> Vec<Vec<f64>> {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let mut vals = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, t, &mut vals);
    let mut a = vec![vec![0.0; n + m]; n + m];
    for (i, mi) in sys.mass_diagonal().iter().enumerate() {
        a[i][i] = *mi;
    }
    for (&(r, c), v) in sys.jacobian_pattern().iter().zip(&vals) {
        a[n + r][c] += v;
        a[c][n + r] += v;
    }
    a
}

/// The closest consistent state in the mass norm, computed densely by
/// Gauss–Newton on the KKT conditions `M(q − q₀) + Φ_qᵀμ = 0`, `Φ = 0`,
/// then `M(q̇ − q̇₀) + Φ_qᵀν = 0`, `Φ_q q̇ + Φ_t = 0`.
fn closest_consistent(
    sys: &mbsolve::model::System,
    q0: &[f64],
    qd0: &[f64],
    t: f64,
) -> (Vec<f64>, Vec<f64>) {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let mass = sys.mass_diagonal();
    let mut q = q0.to_vec();
    let mut phi = vec![0.0; m];
    for _ in 0..50 {
        sys.phi(&q, t, &mut phi);
        let mut b: Vec<f64> = (0..n).map(|i| -mass[i] * (q[i] - q0[i])).collect();
        b.extend(phi.iter().map(|p| -p));
        let x = solve_dense(kkt(sys, &q, t), b);
        for (qi, d) in q.iter_mut().zip(&x[..n]) {
            *qi += d;
        }
    }
    sys.phi_t(&q, t, &mut phi);
    let mut b: Vec<f64> = (0..n).map(|i| mass[i] * qd0[i]).collect();
    b.extend(phi.iter().map(|p| -p));
    let x = solve_dense(kkt(sys, &q, t), b);
    (q, x[..n].to_vec())
}

#[test]
fn inconsistent_start_is_projected_and_follows_ode45() {
    // The four-bar's incorrect start (coupler 0.05 rad off, ‖Φ‖∞ ≈ 1e-2):
    // Newton failed at t0 before (θ ≈ 2 for every step). Now the start is
    // projected onto the manifold; the projection is the closest
    // consistent state in the mass norm (checked against a dense KKT
    // solve), and the run from it follows ode45 started from that state.
    use mbsolve::formulation::{Augmented, AugmentedParams};
    use mbsolve::linalg::SolverKind;
    let sc = parse(FOURBAR_TOML, &["initial.incorrect=true"]).unwrap();
    let sys = &sc.system;
    let t0 = sc.run.t0;
    let mut phi = vec![0.0; sys.n_constraints()];
    sys.phi(&sc.q0, t0, &mut phi);
    let phi0 = phi.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    assert!(phi0 > 1e-3, "{phi0}");
    let (qs, qds) = closest_consistent(sys, &sc.q0, &sc.qd0, t0);
    // the library's augmented-Lagrangian projection
    let h = 5e-5;
    let mut f = Augmented::new(
        sys,
        AugmentedParams::default(),
        SolverKind::Auto,
        0.25 * h * h,
    )
    .unwrap();
    let (mut q, mut qd) = (sc.q0.clone(), sc.qd0.clone());
    let c = f.consistent_start(t0, &mut q, &mut qd).unwrap();
    let dq = q
        .iter()
        .zip(&qs)
        .fold(0.0_f64, |a, (x, y)| a.max((x - y).abs()));
    let dv = qd
        .iter()
        .zip(&qds)
        .fold(0.0_f64, |a, (x, y)| a.max((x - y).abs()));
    eprintln!("start: {c:?}; from the dense KKT solve: |Δq| {dq:.2e}, |Δq̇| {dv:.2e}");
    assert!(c.changed() && c.phi == phi0);
    assert!(dq < 1e-9 && dv < 1e-9, "{dq:e} {dv:e}");
    // a consistent state is left alone, bit for bit
    let (q1, qd1) = (q.clone(), qd.clone());
    let c1 = f.consistent_start(t0, &mut q, &mut qd).unwrap();
    assert!(!c1.changed() && q == q1 && qd == qd1);

    // the run from the incorrect start against ode45 from the dense start
    let t_end = 1.0;
    let mut cfg = alm(Method::Newmark, 1.0, h, t_end, 0.01);
    cfg.t0 = t0;
    let (traj, s) = simulate(sys, &sc.q0, &sc.qd0, &cfg, &mut []).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    assert!(
        s.warnings.iter().any(|w| w.contains("projected at t")),
        "{:?}",
        s.warnings
    );
    let mut rc = RunConfig {
        method: Method::Ode45,
        t0,
        t_end,
        output_dt: 0.01,
        ..Default::default()
    };
    rc.ode.rtol = 1e-12;
    rc.ode.atol = mbsolve::integrate::Tolerance::Scalar(1e-14);
    let (reference, _) = simulate(sys, &qs, &qds, &rc, &mut []).unwrap();
    assert_eq!(traj.t.len(), reference.t.len());
    let mut worst: f64 = 0.0;
    for (a, b) in traj.q.iter().zip(&reference.q).skip(1) {
        for (x, y) in a.iter().zip(b) {
            worst = worst.max((x - y).abs());
        }
    }
    let mut phi_end = vec![0.0; sys.n_constraints()];
    sys.phi(traj.q.last().unwrap(), t_end, &mut phi_end);
    let phi_end = phi_end.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    eprintln!("incorrect start, trapezoidal h = {h:e}: max |q − q_ode45| {worst:.3e}, ‖Φ(t_end)‖ {phi_end:.1e}");
    // 3.6e-5 is the trapezoidal error at this step from a consistent start
    // (converges_to_ode45_with_order_two)
    assert!(worst < 1e-4, "{worst:e}");
    assert!(phi_end < 1e-10, "{phi_end:e}");
}

#[test]
fn start_that_cannot_be_made_consistent_is_a_clear_error() {
    // A rod of length 1 pinned to ground points 3 m apart: no consistent
    // configuration exists. The run must fail at t0 saying so, not as a
    // Newton failure.
    use mbsolve::constraints::Revolute;
    use mbsolve::model::{Body, BodyRef, SystemBuilder};
    let mut b = SystemBuilder::new();
    b.add_body(Body::new("rod", 1.0, 1.0 / 12.0, [0.5, 0.0, 0.0]));
    b.add_constraint(Revolute::new(
        "a",
        BodyRef::Body(0),
        [-0.5, 0.0],
        BodyRef::Ground,
        [0.0, 0.0],
    ));
    b.add_constraint(Revolute::new(
        "b",
        BodyRef::Body(0),
        [0.5, 0.0],
        BodyRef::Ground,
        [3.0, 0.0],
    ));
    let sys = b.build().unwrap();
    // The start projection runs before the first step, for the augmented
    // Lagrangian and for the plain index-3 methods (generalized-α, bdf):
    // an error of the initial state, not a run that fails.
    let mut plain = alm(Method::GenAlpha, 0.8, 1e-3, 0.1, 0.01);
    plain.formulation.formulation = Formulation::default();
    let bdf = RunConfig {
        method: Method::Bdf,
        t_end: 0.1,
        output_dt: 0.01,
        ..Default::default()
    };
    for (what, cfg) in [
        (
            "augmented Lagrangian",
            alm(Method::Newmark, 1.0, 1e-3, 0.1, 0.01),
        ),
        ("generalized-α", plain),
        ("bdf", bdf),
    ] {
        let err = simulate(&sys, &[0.5, 0.0, 0.0], &[0.0; 3], &cfg, &mut [])
            .err()
            .unwrap_or_else(|| panic!("{what}: the run must not start"));
        let msg = err.to_string();
        eprintln!("{what}: {msg}");
        assert!(msg.contains("violate"), "{what}: {msg}");
        assert!(msg.contains("no consistent configuration"), "{what}: {msg}");
    }
}
