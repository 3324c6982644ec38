//! The analyses of scenarios with `[[state]]` controller states against
//! closed forms: a pendulum under a PID joint torque with an integral
//! state (equilibrium, linearisation, eigenvalues), a state without an
//! equilibrium, and inverse dynamics of a driven crank whose state
//! integrates its angle.
//!
//! The PID pendulum: a body of mass m, centroidal inertia I_c, pinned to
//! the ground at its local point (0, d), so θ = φ = 0 hangs straight down
//! and gravity's torque about the pin is −m g d sin θ. The joint torque is
//! `τ = K_p e + K_i z − K_d ω` with `e = θ_r − θ`, `ω = θ̇`, and the
//! integral state `ż = e`. With `I = I_c + m d²` about the pin:
//!
//! ```text
//! I θ̈ = K_p (θ_r − θ) + K_i z − K_d θ̇ − m g d sin θ,      ż = θ_r − θ
//! ```
//!
//! Equilibrium: `θ* = θ_r`, `K_i z* = m g d sin θ_r`. Perturbing it
//! (`δż = −δθ`, so `δz = −δθ / s`) gives `I s² + K_d s + (K_p + m g d
//! cos θ*) + K_i / s = 0`, i.e. the characteristic polynomial
//! `I s³ + K_d s² + (K_p + m g d cos θ*) s + K_i`.

// matrices are indexed by row and column throughout
#![allow(clippy::needless_range_loop)]

use crate::common::linear::{assert_odd_part_is_linear, expm_times};
use mbsolve::analysis::linearize::{linearize, LinearizeOptions, Method, Output};
use mbsolve::analysis::{static_equilibrium, StaticError, StaticOptions};
use mbsolve::scenario;

const G: f64 = 9.81;
const M: f64 = 1.0;
const IC: f64 = 0.01;
const D: f64 = 0.5;
const KP: f64 = 20.0;
const KD: f64 = 4.0;
const KI: f64 = 15.0;
const THR: f64 = 0.4;

/// The PID pendulum as a scenario (module docs), starting hanging at rest
/// with z = `z0`; `extra` is appended (more states).
fn pid_pendulum(z0: f64, extra: &str) -> String {
    format!(
        "name = \"pid_pendulum\"\ngravity = [0.0, -{G}]\n\
         [parameters]\nkp = {KP}\nkd = {KD}\nki = {KI}\nthr = {THR}\n\
         [[body]]\nname = \"bob\"\nmass = {M}\ninertia = {IC}\nx = 0.0\ny = -{D}\n\
         [[joint]]\ntype = \"revolute\"\nname = \"pin\"\nbody_i = \"ground\"\n\
         point_i = [0.0, 0.0]\nbody_j = \"bob\"\npoint_j = [0.0, {D}]\n\
         [[state]]\nname = \"z\"\ninitial = {z0}\nderivative = \"thr - bob.phi\"\n\
         [[force]]\ntype = \"joint_torque\"\nname = \"pid\"\njoint = \"pin\"\n\
         torque = \"kp*(thr - angle) - kd*rate + ki*z\"\n\
         {extra}\
         [integrator]\nmethod = \"ode45\"\nrtol = 1e-10\natol = 1e-12\n\
         [time]\nend = 1.0\n"
    )
}

fn parse(text: &str) -> scenario::Scenario {
    scenario::parse(text, "pid_pendulum.toml", "pid_pendulum", &[]).unwrap()
}

/// Equilibrium angle = the target, `K_i z = m g d sin θ_r` (closed form),
/// whichever z the search starts from; the state file's velocities hold z.
#[test]
fn pid_pendulum_rests_at_its_target_with_the_integral_carrying_gravity() {
    let z_star = M * G * D * THR.sin() / KI;
    for z0 in [0.0, -1.0, 2.0] {
        let sc = parse(&pid_pendulum(z0, ""));
        let eq = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default()).unwrap();
        assert_eq!(eq.states.len(), 1);
        assert!((eq.q[2] - THR).abs() < 1e-12, "θ = {}", eq.q[2]);
        assert!(
            (eq.q[0] - D * THR.sin()).abs() < 1e-12 && (eq.q[1] + D * THR.cos()).abs() < 1e-12,
            "{:?}",
            eq.q
        );
        assert!(
            (eq.states[0] - z_star).abs() < 1e-12 * (1.0 + z_star),
            "z = {} vs {z_star}",
            eq.states[0]
        );
        // the pin carries the weight
        let r = eq.lambda.iter().map(|l| l * l).sum::<f64>().sqrt();
        assert!((r - M * G).abs() < 1e-9, "reaction {r}");
        let qd = eq.velocities();
        assert_eq!(&qd[..3], &[0.0; 3]);
        assert_eq!(qd[3], eq.states[0]);
        // the mechanism-only stability counts refuse a system with states
        let e = mbsolve::analysis::stability(&sc.system, 0.0, &eq.q, &eq.lambda, 1e-3)
            .unwrap_err()
            .to_string();
        assert!(e.contains("first-order") && e.contains("'z'"), "{e}");
    }
}

/// A state whose rate cannot vanish (`ż = 1`) is an error naming it.
#[test]
fn a_state_without_equilibrium_is_named() {
    let extra = "[[state]]\nname = \"drift\"\nderivative = \"1.0\"\n";
    let sc = parse(&pid_pendulum(0.0, extra));
    let e = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, StaticError::NoEquilibrium { .. }), "{msg}");
    assert!(msg.contains("'drift'") && msg.contains("ż = 1e0"), "{msg}");
    // a rate that depends on z but never vanishes: the search fails and
    // lists the states' rates
    let extra = "[[state]]\nname = \"drift\"\ninitial = 0.5\nderivative = \"1.0 + drift*drift\"\n";
    let sc = parse(&pid_pendulum(0.0, extra));
    let msg = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("drift = "), "{msg}");
}

/// The equilibrium's positions and velocities (z in the state's velocity).
fn pid_equilibrium() -> (scenario::Scenario, Vec<f64>, Vec<f64>) {
    let sc = parse(&pid_pendulum(0.0, ""));
    let eq = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default()).unwrap();
    let qd = eq.velocities();
    (sc, eq.q, qd)
}

/// The closed-form A of the PID pendulum in x = (θ, ω, z) (module docs).
fn closed_form_a() -> [[f64; 3]; 3] {
    let io = IC + M * D * D;
    let kt = KP + M * G * D * THR.cos();
    [
        [0.0, 1.0, 0.0],
        [-kt / io, -KD / io, KI / io],
        [-1.0, 0.0, 0.0],
    ]
}

/// The coefficients (c₂, c₁, c₀) of det(sI − A) = s³ + c₂ s² + c₁ s + c₀
/// of a 3 × 3 matrix: −trace, the sum of the principal 2 × 2 minors, −det.
fn char_poly(a: &dyn Fn(usize, usize) -> f64) -> [f64; 3] {
    let tr = a(0, 0) + a(1, 1) + a(2, 2);
    let minor = |i: usize, j: usize| a(i, i) * a(j, j) - a(i, j) * a(j, i);
    let det = a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1))
        - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0))
        + a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
    [-tr, minor(0, 1) + minor(0, 2) + minor(1, 2), -det]
}

/// A in (θ, ω, z) against the closed form, exactly on the tangent path and
/// by central differences; with the chart's own choice of independent
/// coordinate the characteristic polynomial `I s³ + K_d s² + (K_p + m g d
/// cos θ*) s + K_i` (chart-independent); the state as an output.
#[test]
fn pid_pendulum_linearisation_matches_the_closed_form() {
    let (sc, q, qd) = pid_equilibrium();
    let sys = &sc.system;
    let want = closed_form_a();
    for method in [Method::Tangent, Method::FiniteDifferences] {
        let opts = LinearizeOptions {
            independent: Some(vec![2]),
            method,
            ..Default::default()
        };
        let outs = [Output::State(0), Output::Coordinate(2)];
        let ss = linearize(sys, &[], 0.0, &q, &qd, &[], &outs, &opts).unwrap();
        assert_eq!(ss.method, method);
        assert_eq!(ss.controller_states, 1);
        let names: Vec<&str> = ss.states.iter().map(|s| s.0.as_str()).collect();
        assert_eq!(names, ["bob.phi", "bob.omega", "z"]);
        let tol = if method == Method::Tangent {
            1e-10
        } else {
            1e-6
        };
        for i in 0..3 {
            for j in 0..3 {
                assert!(
                    (ss.a[(i, j)] - want[i][j]).abs() < tol * (1.0 + want[i][j].abs()),
                    "{method:?} A[{i},{j}] = {} vs {}",
                    ss.a[(i, j)],
                    want[i][j]
                );
            }
        }
        assert_eq!(ss.outputs[0].0, "z");
        for j in 0..3 {
            let (cz, cphi) = (ss.c[(0, j)], ss.c[(1, j)]);
            assert!((cz - [0.0, 0.0, 1.0][j]).abs() < tol, "C z {j}: {cz}");
            assert!((cphi - [1.0, 0.0, 0.0][j]).abs() < tol, "C phi {j}: {cphi}");
        }
    }
    // the velocity of the state's coordinate is the state; its position
    // is not an output
    let ss = linearize(
        sys,
        &[],
        0.0,
        &q,
        &qd,
        &[],
        &[Output::Velocity(3)],
        &Default::default(),
    )
    .unwrap();
    assert_eq!(ss.outputs[0].0, "z");
    assert_eq!((ss.c[(0, 0)], ss.c[(0, 1)], ss.c[(0, 2)]), (0.0, 0.0, 1.0));
    let e = linearize(
        sys,
        &[],
        0.0,
        &q,
        &qd,
        &[],
        &[Output::Coordinate(3)],
        &Default::default(),
    );
    assert!(e.is_err());
    // the chart's own independent coordinate: same polynomial
    let ss = linearize(sys, &[], 0.0, &q, &qd, &[], &[], &Default::default()).unwrap();
    assert_eq!(ss.method, Method::Tangent);
    let got = char_poly(&|i, j| ss.a[(i, j)]);
    let io = IC + M * D * D;
    let want = [KD / io, (KP + M * G * D * THR.cos()) / io, KI / io];
    for k in 0..3 {
        assert!(
            (got[k] - want[k]).abs() < 1e-9 * want[k],
            "coefficient {k}: {} vs {}",
            got[k],
            want[k]
        );
    }
}

/// The linear model predicts nonlinear runs from ± a small perturbation
/// of (θ, ω, z) (their half difference, free of the quadratic terms).
#[test]
fn pid_pendulum_linearisation_predicts_the_nonlinear_run() {
    use mbsolve::integrate::{Method as IntegrationMethod, Tolerance};
    use mbsolve::simulation::{simulate, RunConfig};
    let (sc, q, qd) = pid_equilibrium();
    let sys = &sc.system;
    let opts = LinearizeOptions {
        independent: Some(vec![2]),
        ..Default::default()
    };
    let ss = linearize(sys, &[], 0.0, &q, &qd, &[], &[], &opts).unwrap();
    let tau = 0.3;
    let mut cfg = RunConfig {
        method: IntegrationMethod::Ode45,
        t0: 0.0,
        t_end: tau,
        output_dt: tau,
        ..Default::default()
    };
    cfg.ode.rtol = 1e-12;
    cfg.ode.atol = Tolerance::Scalar(1e-14);
    let run = |dx: [f64; 3]| -> [f64; 3] {
        let (th, om, z) = (q[2] + dx[0], dx[1], qd[3] + dx[2]);
        let (s, c) = th.sin_cos();
        let q0 = [D * s, -D * c, th, 0.0];
        let qd0 = [D * c * om, D * s * om, om, z];
        let (traj, summary) = simulate(sys, &q0, &qd0, &cfg, &mut []).unwrap();
        assert_eq!(summary.status, "completed");
        let (ql, qdl) = (traj.q.last().unwrap(), traj.qd.last().unwrap());
        [ql[2], qdl[2], qdl[3]]
    };
    let dx = [1e-4, -2e-4, 0.5e-4];
    let (p, m) = (run(dx), run(dx.map(|v| -v)));
    let linear = expm_times(&ss.a, tau, &dx);
    assert_odd_part_is_linear("PID pendulum", &p, &m, &linear);
}

/// The first-order modes of the PID pendulum (eigenvalues of its A) are
/// the roots of `I s³ + K_d s² + (K_p + m g d cos θ*) s + K_i`, found here
/// independently as the eigenvalues of the cubic's companion matrix; the
/// undamped mode about the equilibrium holds the state fixed:
/// `ω² = (K_p + m g d cos θ*) / I`.
#[test]
fn pid_pendulum_modes_are_the_roots_of_the_cubic() {
    use mbsolve::analysis::{eigenmodes, first_order_modes, ModeOptions, Tangent};
    let (sc, q, qd) = pid_equilibrium();
    let sys = &sc.system;
    let ss = linearize(sys, &[], 0.0, &q, &qd, &[], &[], &Default::default()).unwrap();
    let modes = first_order_modes(&ss.a).unwrap();
    let io = IC + M * D * D;
    let kt = KP + M * G * D * THR.cos();
    // companion matrix of s³ + c₂ s² + c₁ s + c₀
    let (c2, c1, c0) = (KD / io, kt / io, KI / io);
    let comp = faer::Mat::<f64>::from_fn(3, 3, |i, j| match (i, j) {
        (0, _) => [-c2, -c1, -c0][j],
        (1, 0) | (2, 1) => 1.0,
        _ => 0.0,
    });
    let e = comp.eigen().unwrap();
    let roots: Vec<(f64, f64)> = (0..3)
        .map(|k| (e.S().column_vector()[k].re, e.S().column_vector()[k].im))
        .collect();
    // each root (a pair once) among the modes
    let listed: usize = modes
        .iter()
        .map(|m| if m.oscillatory { 2 } else { 1 })
        .sum();
    assert_eq!(listed, 3, "{modes:?}");
    for (re, im) in roots {
        let mag = re.hypot(im);
        let hit = modes
            .iter()
            .any(|m| (m.re - re).abs() < 1e-9 * mag && (m.im - im.abs()).abs() < 1e-9 * mag);
        assert!(hit, "root {re} + {im} i not in {modes:?}");
    }
    for m in &modes {
        if m.oscillatory {
            let mag = m.re.hypot(m.im);
            assert!((m.damping_ratio.unwrap() + m.re / mag).abs() < 1e-14);
            assert!((m.damped_frequency_hz - m.im / std::f64::consts::TAU).abs() < 1e-14);
        } else {
            assert!(m.damping_ratio.is_none() && m.time_constant_s.unwrap() > 0.0);
        }
    }
    // the undamped mechanism mode with z held: ω² = (K_p + m g d cos θ*)/I
    let eq = static_equilibrium(sys, &sc.q0, StaticOptions::default()).unwrap();
    let mut tan = Tangent::new(sys);
    tan.evaluate(0.0, &eq.q, &eq.velocities(), &eq.lambda)
        .unwrap();
    let um = eigenmodes(&tan, ModeOptions::default()).unwrap();
    assert_eq!(um.modes.len(), 1);
    let w2 = um.modes[0].omega_squared;
    assert!(
        (w2 - kt / io).abs() < 1e-9 * kt / io,
        "ω² {w2} vs {}",
        kt / io
    );
    assert_eq!(um.modes[0].shape[3], 0.0);
    // its damping with z held: ζ = K_d / (2 √(k_t I))
    let zeta = KD / (2.0 * (kt * io).sqrt());
    assert!(
        (um.modes[0].damping_ratio - zeta).abs() < 1e-9,
        "{}",
        um.modes[0].damping_ratio
    );
}

/// A crank of inertia I about its centre, pinned there and driven at
/// `θ = a sin(Ω t)`; a state integrates its angle (`ż = θ`, z(0) = 0, so
/// `z = a (1 − cos Ω t) / Ω`) and a joint torque `k z` acts on it. The
/// drive torque must supply `I θ̈ − k z` (closed form).
fn integrating_crank(k: f64) -> String {
    format!(
        "name = \"crank\"\n[parameters]\nk = {k}\n\
         [[body]]\nname = \"crank\"\nmass = 2.0\ninertia = 0.05\n\
         [[joint]]\ntype = \"revolute\"\nname = \"pin\"\nbody_i = \"ground\"\n\
         point_i = [0.0, 0.0]\nbody_j = \"crank\"\npoint_j = [0.0, 0.0]\n\
         [[joint]]\ntype = \"drive_angle\"\nname = \"motor\"\nbody_i = \"ground\"\n\
         body_j = \"crank\"\nmotion = \"0.7*sin(3*t)\"\n\
         [[state]]\nname = \"area\"\nderivative = \"crank.phi\"\n\
         [[force]]\ntype = \"joint_torque\"\nname = \"feedback\"\njoint = \"pin\"\n\
         torque = \"k*area\"\n\
         [time]\nend = 2.0\n[output]\ndt = 0.1\n"
    )
}

/// Inverse dynamics with a state: z along the prescribed motion and the
/// drive torque against their closed forms; the sub-steps' error falls as
/// h⁴ (fourth order).
#[test]
fn inverse_dynamics_integrates_a_state_along_the_motion() {
    use mbsolve::analysis::inverse::{InverseDynamics, InverseOptions};
    use mbsolve::model::drives;
    let (a, w, k, i) = (0.7, 3.0, 4.0, 0.05);
    let sc = scenario::parse(&integrating_crank(k), "crank.toml", "crank", &[]).unwrap();
    let sys = &sc.system;
    let motor = drives(sys)[0];
    let max_errors = |substeps: usize| -> (f64, f64) {
        let opts = InverseOptions {
            state_substeps: substeps,
            ..Default::default()
        };
        let mut inv = InverseDynamics::new(sys, &sc.q0, 0.0, opts).unwrap();
        let (mut ez, mut et) = (0.0_f64, 0.0_f64);
        for step in 0..=20 {
            let t = 0.1 * step as f64;
            let s = inv.at(t).unwrap();
            let z = a * (1.0 - (w * t).cos()) / w;
            let tau = i * (-a * w * w * (w * t).sin()) - k * z;
            ez = ez.max((s.qd[3] - z).abs());
            et = et.max((motor.force(s.lambda.unwrap()) - tau).abs());
        }
        (ez, et)
    };
    let (ez, et) = max_errors(16);
    eprintln!("16 sub-steps: |z error| {ez:.2e}, |torque error| {et:.2e}");
    assert!(ez < 1e-9 && et < 1e-8, "{ez:e} {et:e}");
    let (e1, _) = max_errors(1);
    let (e2, _) = max_errors(2);
    eprintln!(
        "1 and 2 sub-steps: |z error| {e1:.2e}, {e2:.2e} (ratio {:.1})",
        e1 / e2
    );
    assert!(
        e1 > 1e-9 && (10.0..24.0).contains(&(e1 / e2)),
        "{e1:e} {e2:e}"
    );
}

/// The shipped PID pendulum through the CLI (the worked example of
/// docs/analyses.md): `static` reports z and a stable first-order
/// equilibrium and writes a state file from which `run` stays at rest;
/// `linearize --outputs z` and `modes` name the state and list the cubic's
/// roots.
#[test]
fn cli_analyses_of_the_shipped_pid_pendulum() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let scen = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/pid_pendulum.toml");
    let cli = |args: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_mbsolve"))
            .args(args)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let json = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(name)).unwrap()).unwrap()
    };
    let said = cli(&["static", scen, "--out", out]);
    assert!(said.contains("controller state z ="), "{said}");
    let st = json("pid_pendulum.static.json");
    let z_star = M * G * D * THR.sin() / KI;
    assert!((st["states"]["z"].as_f64().unwrap() - z_star).abs() < 1e-10);
    assert_eq!(st["stability"]["verdict"], "stable");
    assert_eq!(st["stability"]["eigenvalues"].as_array().unwrap().len(), 2);
    // a run from the written state stays there
    let state = dir.path().join("pid_pendulum.equilibrium.json");
    let set = format!("initial.state={}", state.display());
    cli(&[
        "run",
        scen,
        "--set",
        &set,
        "--set",
        "time.end=1.0",
        "--out",
        out,
    ]);
    let csv = std::fs::read_to_string(dir.path().join("pid_pendulum.csv")).unwrap();
    let mut lines = csv.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let (phi, z) = (
        head.iter().position(|h| *h == "bob.phi").unwrap(),
        head.iter().position(|h| *h == "z").unwrap(),
    );
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert!((v[phi] - THR).abs() < 1e-8, "{line}");
        assert!((v[z] - z_star).abs() < 1e-8, "{line}");
    }
    cli(&[
        "linearize",
        scen,
        "--at",
        "static",
        "--outputs",
        "z,bob.phi",
        "--out",
        out,
    ]);
    let lin = json("pid_pendulum.linear.json");
    assert_eq!(lin["method"], "tangent");
    let states: Vec<&str> = lin["states"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(states.len(), 3);
    assert_eq!(states[2], "z");
    assert_eq!(lin["C"][0][2].as_f64().unwrap(), 1.0);
    cli(&["modes", scen, "--at", "static", "--out", out]);
    let md = json("pid_pendulum.modes.json");
    assert!(md["undamped"].as_str().unwrap().contains("held fixed"));
    let fo = md["first_order_modes"].as_array().unwrap();
    let io = IC + M * D * D;
    // the product of the roots is −K_i / I
    let mut prod = 1.0;
    for m in fo {
        let (re, im) = (m["re"].as_f64().unwrap(), m["im"].as_f64().unwrap());
        prod *= if m["oscillatory"].as_bool().unwrap() {
            re * re + im * im
        } else {
            re
        };
    }
    assert!((prod + KI / io).abs() < 1e-9 * KI / io, "{prod}");
}
