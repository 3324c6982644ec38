//! The energy balance `E(t) − E(0) = ∫ (P_nc + P_c) dt` (model/energy.rs)
//! along tight ode45 runs, and each power term against an independent
//! formula.

use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::constraints::Revolute;
use mbsolve::forces::PointSpringDamper;
use mbsolve::formulation::{Index1, Index1Options};
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::model::{Body, BodyPoint, BodyRef, EnergyWorkspace, System, SystemBuilder};
use mbsolve::scenario::{self, FOURBAR_TOML};
use mbsolve::simulation::{simulate, RunConfig, Trajectory};

const L: f64 = 0.5;
const K: f64 = 50.0;
const C: f64 = 0.8;
const ANCHOR: [f64; 2] = [0.5, 0.5];

/// A bar pinned at one end to the ground, a linear spring–damper from its
/// other end to a ground anchor, gravity.
fn spring_pendulum() -> (System, Vec<f64>, Vec<f64>) {
    let (phi, w) = (-0.5_f64, 2.0);
    let (s, c) = phi.sin_cos();
    let mut b = SystemBuilder::new();
    b.add_body(
        Body::new("bar", 1.0, L * L / 12.0, [0.5 * L * c, 0.5 * L * s, phi]).with_velocity([
            -0.5 * L * s * w,
            0.5 * L * c * w,
            w,
        ]),
    );
    b.add_constraint(Revolute::new(
        "pivot",
        BodyRef::Ground,
        [0.0, 0.0],
        BodyRef::Body(0),
        [-0.5 * L, 0.0],
    ));
    b.add_force(PointSpringDamper::linear(
        BodyPoint::new(BodyRef::Body(0), [0.5 * L, 0.0]),
        BodyPoint::new(BodyRef::Ground, ANCHOR),
        0.3,
        K,
        C,
    ));
    b.gravity([0.0, -9.81]);
    let sys = b.build().unwrap();
    let (q, v) = sys.initial_state();
    (sys, q, v)
}

fn tight(t_end: f64) -> RunConfig {
    let mut cfg = RunConfig {
        method: Method::Ode45,
        t_end,
        output_dt: 1e-3,
        ..Default::default()
    };
    cfg.ode.rtol = 1e-11;
    cfg.ode.atol = Tolerance::Scalar(1e-13);
    cfg
}

/// The powers `(P_nc, P_c)` at every output (λ from eq. (5) at that state).
fn powers(sys: &System, traj: &Trajectory) -> Vec<(f64, f64)> {
    let mut f = Index1::new(sys, Index1Options::default()).unwrap();
    let mut ws = EnergyWorkspace::default();
    let mut qdd = vec![0.0; sys.n_coords()];
    traj.t
        .iter()
        .zip(traj.q.iter().zip(&traj.qd))
        .map(|(&t, (q, qd))| {
            f.accelerations(t, q, qd, &mut qdd).unwrap();
            (
                sys.nonconservative_power(t, q, qd, &mut ws),
                sys.constraint_power(q, t, f.lambda(), &mut ws),
            )
        })
        .collect()
}

/// Energy balance along `traj` with the powers weighted by `w`: the
/// largest |E(t) − E(0) − ∫(w_nc P_nc + w_c P_c)| over the outputs (trapezoid
/// rule on the output grid), the largest |E(t) − E(0)|, and the largest
/// Richardson estimate |T_h − T_2h| / 3 of the trapezoid's own error (at
/// every second output), and the largest |E(t) − E(0) − (T_h + (T_h − T_2h)/3)|
/// (the Richardson-extrapolated integral, at every second output).
fn balance(
    sys: &System,
    traj: &Trajectory,
    p: &[(f64, f64)],
    w: (f64, f64),
) -> (f64, f64, f64, f64) {
    let e0 = sys.mechanical_energy(&traj.q[0], &traj.qd[0]);
    let pk = |i: usize| w.0 * p[i].0 + w.1 * p[i].1;
    let (mut work, mut work2) = (0.0, 0.0);
    let (mut worst, mut change, mut quad, mut rich) = (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    for k in 0..traj.t.len() {
        if k > 0 {
            work += 0.5 * (traj.t[k] - traj.t[k - 1]) * (pk(k - 1) + pk(k));
        }
        if k > 0 && k % 2 == 0 {
            work2 += 0.5 * (traj.t[k] - traj.t[k - 2]) * (pk(k - 2) + pk(k));
            quad = quad.max((work - work2).abs() / 3.0);
        }
        let de = sys.mechanical_energy(&traj.q[k], &traj.qd[k]) - e0;
        if k % 2 == 0 {
            rich = rich.max((de - work - (work - work2) / 3.0).abs());
        }
        change = change.max(de.abs());
        worst = worst.max((de - work).abs());
    }
    (worst, change, quad, rich)
}

/// The balance holds to within the quadrature error (which is small), and
/// fails without the term `drop` removes.
fn check(name: &str, sys: &System, traj: &Trajectory, p: &[(f64, f64)], drop: (f64, f64)) {
    let (err, change, quad, rich) = balance(sys, traj, p, (1.0, 1.0));
    eprintln!(
        "{name}: max |ΔE − ∫P| = {err:.3e} J, trapezoid error estimate {quad:.3e} J, \
         extrapolated {rich:.3e} J, max |ΔE| = {change:.3e} J"
    );
    assert!(
        rich < 1e-8 * change,
        "extrapolated balance error {rich:e} J"
    );
    assert!(change > 0.5, "{change}");
    assert!(quad < 1e-4 * change, "quadrature too coarse: {quad:e}");
    assert!(
        err < 1.5 * quad + 1e-8 * change,
        "balance error {err:e} J, quadrature {quad:e} J"
    );
    let (err0, _, _, _) = balance(sys, traj, p, drop);
    assert!(err0 > 1e3 * err, "{err0:e} vs {err:e}");
}

#[test]
fn damped_spring_pendulum_balances_its_energy() {
    let (sys, q0, v0) = spring_pendulum();
    let (traj, s) = simulate(&sys, &q0, &v0, &tight(3.0), &mut []).unwrap();
    assert_eq!(s.status, "completed");
    let p = powers(&sys, &traj);
    // independent: the damper's power −c L̇² (gravity and the elastic
    // spring are conservative; the pivot does no work)
    let mut ws = EnergyWorkspace::default();
    for (k, (q, qd)) in traj.q.iter().zip(&traj.qd).enumerate().step_by(97) {
        let (sn, cs) = q[2].sin_cos();
        let tip = [q[0] + 0.5 * L * cs, q[1] + 0.5 * L * sn];
        let vtip = [qd[0] - 0.5 * L * sn * qd[2], qd[1] + 0.5 * L * cs * qd[2]];
        let d = [ANCHOR[0] - tip[0], ANCHOR[1] - tip[1]];
        let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
        let rate = -(d[0] * vtip[0] + d[1] * vtip[1]) / len;
        let expect = -C * rate * rate;
        let got = sys.nonconservative_power(traj.t[k], q, qd, &mut ws);
        assert!(
            (got - expect).abs() < 1e-7 * (1.0 + expect.abs()),
            "t = {}: P_nc = {got}, −c L̇² = {expect}",
            traj.t[k]
        );
        assert!(p[k].1.abs() < 1e-14, "scleronomic joint: P_c = {}", p[k].1);
    }
    let dissipated = -p
        .windows(2)
        .map(|w| 1e-3 * 0.5 * (w[0].0 + w[1].0))
        .sum::<f64>();
    assert!(dissipated > 0.1, "the damper works: {dissipated} J");
    check("spring pendulum", &sys, &traj, &p, (0.0, 1.0));
}

#[test]
fn fourbar_torque_work_balances_its_energy() {
    let mut sc = scenario::parse(FOURBAR_TOML, "fourbar.toml", "fourbar", &[]).unwrap();
    sc.run = tight(2.0);
    sc.run.output_dt = 2.5e-4;
    let sys = &sc.system;
    let (traj, s) = simulate(sys, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "completed");
    let p = powers(sys, &traj);
    // the torque's power τ φ̇₁ (τ = 0.5 N m); gravity's exactly cancels
    for (k, qd) in traj.qd.iter().enumerate().step_by(101) {
        let expect = 0.5 * qd[2];
        assert!(
            (p[k].0 - expect).abs() < 1e-9 * (1.0 + expect.abs()),
            "{} vs {expect}",
            p[k].0
        );
    }
    check("four-bar", sys, &traj, &p, (0.0, 1.0));
}

#[test]
fn drive_power_balances_a_driven_chain() {
    // The parallelogram chain driven at a constant crank rate: T is
    // constant, V = C sin θ changes, and the drive supplies λᵀΦ_t.
    let p = ParallelogramChain {
        loops: 2,
        driven: true,
        rate0: 3.0,
        ..Default::default()
    };
    let sys = parallelogram_chain(&p).unwrap();
    let (q0, v0) = sys.initial_state();
    let (traj, s) = simulate(&sys, &q0, &v0, &tight(0.8), &mut []).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    let pw = powers(&sys, &traj);
    // on the manifold λᵀΦ_t = −q̇ᵀΦ_qᵀλ; and the drive's power is dV/dt =
    // C cos θ θ̇ (T constant)
    let mut f = Index1::new(&sys, Index1Options::default()).unwrap();
    let mut qdd = vec![0.0; sys.n_coords()];
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    let mut ft = vec![0.0; sys.n_coords()];
    for (k, (q, qd)) in traj.q.iter().zip(&traj.qd).enumerate().step_by(53) {
        let t = traj.t[k];
        f.accelerations(t, q, qd, &mut qdd).unwrap();
        sys.jacobian_values(q, t, &mut jac);
        sys.jacobian_tmul(&jac, f.lambda(), &mut ft);
        let other: f64 = -qd.iter().zip(&ft).map(|(a, b)| a * b).sum::<f64>();
        let th = p.theta0 + p.rate0 * t;
        let dv = p.gravity_moment() * th.cos() * p.rate0;
        assert!(
            (pw[k].1 - other).abs() < 1e-8 * (1.0 + other.abs()),
            "{} vs {other}",
            pw[k].1
        );
        assert!(
            (pw[k].1 - dv).abs() < 1e-7 * (1.0 + dv.abs()),
            "{} vs {dv}",
            pw[k].1
        );
    }
    check("driven chain", &sys, &traj, &pw, (1.0, 0.0));
}
