//! Linearisation (`mbsolve::analysis::linearize`) against references
//! mbsolve did not compute: the physical pendulum's A, B, C in closed form
//! (at rest and swinging), and the nonlinear runs from perturbed states
//! (assembled by hand, or by the scenario's own initial-state code)
//! against the linear model's prediction.

use crate::common::linear::{assert_odd_part_is_linear, expm_times};
use faer::Mat;
use mbsolve::analysis::linearize::{
    linearize, Input, LinearizeOptions, Method, Output, StateSpace,
};
use mbsolve::constraints::{DriveCoordinate, Revolute};
use mbsolve::forces::{PointSpringDamper, RotationalSpringDamper};
use mbsolve::integrate::{Method as IntegrationMethod, Tolerance};
use mbsolve::model::{Body, BodyPoint, BodyRef, System, SystemBuilder, TimeFunction};
use mbsolve::scenario;
use mbsolve::simulation::{simulate, RunConfig};
use std::path::Path;

const G: f64 = 9.81;

/// Physical pendulum: body (m, I about its centre) pinned to the ground
/// origin at its local point (0, d); φ = 0 hangs straight down, centre
/// at (d sin φ, −d cos φ). Closed form: I_O φ̈ = −m g d sin φ + τ,
/// I_O = I + m d².
fn pendulum(m: f64, i: f64, d: f64, phi: f64) -> System {
    let mut b = SystemBuilder::new();
    b.add_body(Body::new("bob", m, i, [d * phi.sin(), -d * phi.cos(), phi]));
    b.add_constraint(Revolute::new(
        "pin",
        BodyRef::Ground,
        [0.0, 0.0],
        BodyRef::Body(0),
        [0.0, d],
    ));
    b.gravity([0.0, -G]);
    b.build().unwrap()
}

fn state(phi: f64, omega: f64, d: f64) -> (Vec<f64>, Vec<f64>) {
    let (s, c) = phi.sin_cos();
    (
        vec![d * s, -d * c, phi],
        vec![d * c * omega, d * s * omega, omega],
    )
}

#[test]
fn pendulum_matches_closed_form_at_rest_and_swinging() {
    let (m, i, d) = (1.5, 0.02, 0.4);
    let io = i + m * d * d;
    let c = m * G * d / io;
    let opts = LinearizeOptions {
        independent: Some(vec![2]),
        ..Default::default()
    };
    let inputs = [
        Input::Force { coordinate: 2 },
        Input::Force { coordinate: 0 },
    ];
    let outputs = [Output::Coordinate(0), Output::Velocity(0)];
    for (phi, omega) in [(0.0, 0.0), (0.7, 1.3), (2.0, -0.5)] {
        let sys = pendulum(m, i, d, phi);
        let (q, qd) = state(phi, omega, d);
        let ss = linearize(&sys, &[], 0.0, &q, &qd, &inputs, &outputs, &opts).unwrap();
        let expect_method = if omega == 0.0 && phi == 0.0 {
            Method::Tangent
        } else {
            Method::FiniteDifferences
        };
        assert_eq!(ss.method, expect_method, "phi = {phi}");
        let tol = if expect_method == Method::Tangent {
            1e-12
        } else {
            1e-6
        };
        let a = [[0.0, 1.0], [-c * phi.cos(), 0.0]];
        // B: a torque τ gives τ / I_O; a force along x at the centre
        // gives its moment about the pin, d cos φ F_x, over I_O
        let b = [[0.0, 0.0], [1.0 / io, d * phi.cos() / io]];
        // C: x = d sin φ, ẋ = d cos φ φ̇
        let cc = [
            [d * phi.cos(), 0.0],
            [-d * phi.sin() * omega, d * phi.cos()],
        ];
        for r in 0..2 {
            for k in 0..2 {
                assert!(
                    (ss.a[(r, k)] - a[r][k]).abs() <= tol * c,
                    "A[{r},{k}] = {} vs {} at phi = {phi}",
                    ss.a[(r, k)],
                    a[r][k]
                );
                assert!(
                    (ss.b[(r, k)] - b[r][k]).abs() <= tol / io,
                    "B[{r},{k}] = {} vs {} at phi = {phi}",
                    ss.b[(r, k)],
                    b[r][k]
                );
                assert!(
                    (ss.c[(r, k)] - cc[r][k]).abs() <= tol,
                    "C[{r},{k}] = {} vs {} at phi = {phi}",
                    ss.c[(r, k)],
                    cc[r][k]
                );
            }
        }
        assert_eq!(ss.states[0].0, "bob.phi");
        assert_eq!(ss.inputs[0].0, "bob.mz");
    }
    // hanging at rest with the independent coordinate chosen by pivoting:
    // the frequency √(m g d / I_O) whatever the coordinate
    let sys = pendulum(m, i, d, 0.0);
    let (q, qd) = state(0.0, 0.0, d);
    let ss = linearize(&sys, &[], 0.0, &q, &qd, &[], &[], &Default::default()).unwrap();
    assert_eq!(ss.independent.len(), 1);
    assert!((ss.a[(1, 0)] + c).abs() < 1e-12 * c, "{}", ss.a[(1, 0)]);
}

/// Double pendulum of two bars (m, l, I = m l²/12) hanging from the ground,
/// rotational spring-dampers at both pins (rest angle 0): straight down at
/// rest is an equilibrium. Pins at local (0, ±l/2).
fn double_pendulum(m: f64, l: f64, k: f64, c: f64) -> System {
    let mut b = SystemBuilder::new();
    let i = m * l * l / 12.0;
    b.add_body(Body::new("upper", m, i, [0.0, -l / 2.0, 0.0]));
    b.add_body(Body::new("lower", m, i, [0.0, -1.5 * l, 0.0]));
    b.add_constraint(Revolute::new(
        "top",
        BodyRef::Ground,
        [0.0, 0.0],
        BodyRef::Body(0),
        [0.0, l / 2.0],
    ));
    b.add_constraint(Revolute::new(
        "middle",
        BodyRef::Body(0),
        [0.0, -l / 2.0],
        BodyRef::Body(1),
        [0.0, l / 2.0],
    ));
    b.add_force(RotationalSpringDamper::linear(
        BodyRef::Ground,
        BodyRef::Body(0),
        0.0,
        k,
        c,
    ));
    b.add_force(RotationalSpringDamper::linear(
        BodyRef::Body(0),
        BodyRef::Body(1),
        0.0,
        k,
        c,
    ));
    b.gravity([0.0, -G]);
    b.build().unwrap()
}

/// The double pendulum's consistent state from its angles and rates (by
/// hand: r1 = (l/2 sin φ1, −l/2 cos φ1), r2 = (l sin φ1 + l/2 sin φ2,
/// −l cos φ1 − l/2 cos φ2)).
fn double_state(l: f64, p: [f64; 4]) -> (Vec<f64>, Vec<f64>) {
    let [a, b, ad, bd] = p;
    let h = l / 2.0;
    let q = vec![
        h * a.sin(),
        -h * a.cos(),
        a,
        l * a.sin() + h * b.sin(),
        -l * a.cos() - h * b.cos(),
        b,
    ];
    let qd = vec![
        h * a.cos() * ad,
        h * a.sin() * ad,
        ad,
        l * a.cos() * ad + h * b.cos() * bd,
        l * a.sin() * ad + h * b.sin() * bd,
        bd,
    ];
    (q, qd)
}

fn run_config(tau: f64) -> RunConfig {
    let mut cfg = RunConfig {
        method: IntegrationMethod::Ode45,
        t0: 0.0,
        t_end: tau,
        output_dt: tau,
        ..Default::default()
    };
    cfg.ode.rtol = 1e-12;
    cfg.ode.atol = Tolerance::Scalar(1e-14);
    cfg
}

/// Angles and rates of the double pendulum at τ after starting from `p`.
fn double_run(sys: &System, l: f64, p: [f64; 4], tau: f64) -> [f64; 4] {
    let (q, qd) = double_state(l, p);
    let (traj, summary) = simulate(sys, &q, &qd, &run_config(tau), &mut []).unwrap();
    assert_eq!(summary.status, "completed");
    let (q, qd) = (traj.q.last().unwrap(), traj.qd.last().unwrap());
    [q[2], q[5], qd[2], qd[5]]
}

#[test]
fn equilibrium_model_predicts_the_nonlinear_run() {
    let (m, l, k, c) = (0.8, 0.5, 3.0, 0.05);
    let sys = double_pendulum(m, l, k, c);
    let (q, qd) = double_state(l, [0.0; 4]);
    let opts = LinearizeOptions {
        independent: Some(vec![2, 5]),
        ..Default::default()
    };
    let ss: StateSpace = linearize(&sys, &[], 0.0, &q, &qd, &[], &[], &opts).unwrap();
    assert_eq!(ss.method, Method::Tangent);
    // the same point by central differences of the reduced dynamics
    let fd = linearize(
        &sys,
        &[],
        0.0,
        &q,
        &qd,
        &[],
        &[],
        &LinearizeOptions {
            method: Method::FiniteDifferences,
            ..opts.clone()
        },
    )
    .unwrap();
    let scale = (0..4)
        .flat_map(|i| (0..4).map(move |j| (i, j)))
        .fold(0.0_f64, |s, (i, j)| s.max(ss.a[(i, j)].abs()));
    for i in 0..4 {
        for j in 0..4 {
            assert!(
                (ss.a[(i, j)] - fd.a[(i, j)]).abs() < 1e-6 * scale,
                "A[{i},{j}]: tangent {} vs differences {}",
                ss.a[(i, j)],
                fd.a[(i, j)]
            );
        }
    }
    // nonlinear runs from ±δ x0 over τ = 0.4 s (about half a period of the
    // slow mode) against exp(A τ) δ x0
    let tau = 0.4;
    let dx = [1.0e-4, -0.6e-4, 0.5e-4, 2.0e-4];
    let plus = double_run(&sys, l, dx, tau);
    let minus = double_run(&sys, l, dx.map(|v| -v), tau);
    let linear = expm_times(&ss.a, tau, &dx);
    assert_odd_part_is_linear("equilibrium", &plus, &minus, &linear);
}

#[test]
fn moving_four_bar_model_matches_the_nonlinear_run_from_perturbed_starts() {
    // the four-bar at its initial state (crank at 60°, 2π rad/s: moving,
    // not in equilibrium): finite-difference path in the crank angle
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml");
    let base = scenario::load(&p, &[]).unwrap();
    let sys = &base.system;
    let opts = LinearizeOptions {
        independent: Some(vec![2]),
        ..Default::default()
    };
    let ss = linearize(sys, &[], 0.0, &base.q0, &base.qd0, &[], &[], &opts).unwrap();
    assert_eq!(ss.method, Method::FiniteDifferences);
    // perturbed starts assembled by the scenario's own initial-state code
    let (dphi_deg, domega): (f64, f64) = (0.01, 1e-3);
    let start = |phi: f64, omega: f64| {
        scenario::load(
            &p,
            &[
                format!("body[0].phi_deg={phi}"),
                format!("body[0].omega={omega}"),
            ],
        )
        .unwrap()
    };
    let w0 = base.qd0[2];
    let at = |sc: &scenario::Scenario, tau: f64| {
        let (traj, summary) = simulate(sys, &sc.q0, &sc.qd0, &run_config(tau), &mut []).unwrap();
        assert_eq!(summary.status, "completed");
        let (q, qd) = (traj.q.last().unwrap(), traj.qd.last().unwrap());
        [q[2], qd[2]]
    };
    // (∂ż(τ)/∂x0_j − δ_1j)/τ by central differences of the runs is the
    // second row of A plus O(τ) (the Taylor term of A² and of A's change
    // along the motion): Richardson's 2 D(τ) − D(2τ) removes it
    let dphi = dphi_deg.to_radians();
    let rows = [
        (start(60.0 + dphi_deg, w0), start(60.0 - dphi_deg, w0), dphi),
        (start(60.0, w0 + domega), start(60.0, w0 - domega), domega),
    ];
    for (j, (sp, sm, h)) in rows.iter().enumerate() {
        // the perturbed starts differ only in x0_j
        assert!((sp.q0[2] - sm.q0[2] - if j == 0 { 2.0 * h } else { 0.0 }).abs() < 1e-12);
        assert!((sp.qd0[2] - sm.qd0[2] - if j == 1 { 2.0 * h } else { 0.0 }).abs() < 1e-12);
        let identity = if j == 1 { 1.0 } else { 0.0 };
        let slope = |tau: f64| {
            let (yp, ym) = (at(sp, tau), at(sm, tau));
            ((yp[1] - ym[1]) / (2.0 * h) - identity) / tau
        };
        let tau = 1e-4;
        let (d1, d2) = (slope(tau), slope(2.0 * tau));
        let measured = 2.0 * d1 - d2;
        let a = ss.a[(1, j)];
        eprintln!(
            "four-bar A[1,{j}] = {a:.6e}; nonlinear runs: {d1:.6e} (tau), {d2:.6e} (2 tau), extrapolated {measured:.6e}"
        );
        assert!(
            (measured - a).abs() < 2e-5 * a.abs().max(1.0),
            "A[1,{j}] = {a} vs runs {measured}"
        );
    }
}

/// A physical pendulum as a scenario file: bob (m = 1.5, I = 0.02) pinned
/// at its local (0, 0.4) to the ground origin, hanging at rest, with a
/// point sensor at the bob's centre.
const PENDULUM_TOML: &str = r#"
name = "pendulum"
gravity = [0.0, -9.81]
[[body]]
name = "bob"
mass = 1.5
inertia = 0.02
x = 0.0
y = -0.4
[[joint]]
type = "revolute"
name = "pin"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "bob"
point_j = [0.0, 0.4]
[[sensor]]
type = "point"
name = "tip"
body = "bob"
point = [0.0, 0.0]
[time]
end = 1.0
"#;

#[test]
fn cli_writes_the_model_and_names_bad_arguments() {
    let dir = tempfile::tempdir().unwrap();
    let scen = dir.path().join("pendulum.toml");
    std::fs::write(&scen, PENDULUM_TOML).unwrap();
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_mbsolve"))
            .arg("linearize")
            .arg(&scen)
            .args(["--out", dir.path().to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap()
    };
    let o = run(&[
        "--independent",
        "bob.phi",
        "--inputs",
        "bob.mz",
        "--outputs",
        "tip.x,bob.omega",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(dir.path().join("pendulum.linear.json")).unwrap();
    let j: serde_json::Value = serde_json::from_str(&text).unwrap();
    let (m, i, d) = (1.5, 0.02, 0.4);
    let io = i + m * d * d;
    let c = m * G * d / io;
    assert_eq!(j["method"], "tangent");
    assert!((j["A"][1][0].as_f64().unwrap() + c).abs() < 1e-12 * c);
    assert!((j["B"][1][0].as_f64().unwrap() - 1.0 / io).abs() < 1e-12 / io);
    // the sensor's x = d sin φ by differences, the rate exactly
    assert!((j["C"][0][0].as_f64().unwrap() - d).abs() < 1e-8);
    assert_eq!(j["C"][1][1].as_f64().unwrap(), 1.0);
    assert_eq!(j["outputs"][0]["name"], "tip.x");
    // the undamped pair ±i√c
    let im = j["eigenvalues"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["im"].as_f64().unwrap())
        .fold(0.0_f64, f64::max);
    assert!((im - c.sqrt()).abs() < 1e-10 * c.sqrt(), "{im}");
    let csv = std::fs::read_to_string(dir.path().join("pendulum.linear.A.csv")).unwrap();
    assert!(csv.starts_with("row,bob.phi,bob.omega\n"), "{csv}");
    let npy = std::fs::read(dir.path().join("pendulum.linear.A.npy")).unwrap();
    assert_eq!(&npy[..6], b"\x93NUMPY");
    // at the static equilibrium (found from a displaced start by the
    // static solver): the same closed form
    let o = run(&["--at", "static", "--set", "body[0].phi=0.3"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(dir.path().join("pendulum.linear.json")).unwrap();
    let j: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(j["method"], "tangent");
    let im = j["eigenvalues"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["im"].as_f64().unwrap())
        .fold(0.0_f64, f64::max);
    assert!((im - c.sqrt()).abs() < 1e-8 * c.sqrt(), "static: {im}");
    // bad arguments are named
    for (args, needle) in [
        (vec!["--inputs", "nobody.fx"], "no body named 'nobody'"),
        (
            vec!["--outputs", "tip.z"],
            "sensor 'tip' has no quantity 'z'",
        ),
        (vec!["--at", "t=abc"], "'abc' is not a number"),
        (
            vec!["--method", "tangent", "--set", "body[0].omega=1.0"],
            "at rest in equilibrium",
        ),
    ] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(needle),
            "{args:?}: {err}"
        );
        assert!(err.contains("pendulum.toml"), "{err}");
    }
}

/// A pendulum (m, I about its centre) hanging at its local (0, d) from a
/// cart whose x follows the drive `cart_x` (`f(t)`; y and φ held by
/// drives), with a horizontal spring-damper (k, c, free length `span`)
/// from the ground point (−span, −d) to the bob's centre. Coordinates:
/// cart 0..3, bob 3..6.
fn cart_pendulum(m: f64, i: f64, d: f64, k: f64, c: f64, motion: TimeFunction) -> System {
    let span = 1.0;
    let mut b = SystemBuilder::new();
    b.add_body(Body::new("cart", 2.0, 0.1, [0.0, 0.0, 0.0]));
    b.add_body(Body::new("bob", m, i, [0.0, -d, 0.0]));
    b.add_constraint(DriveCoordinate::new("cart_x", 0, 0, motion));
    b.add_constraint(DriveCoordinate::new(
        "cart_y",
        0,
        1,
        TimeFunction::Constant(0.0),
    ));
    b.add_constraint(DriveCoordinate::new(
        "cart_phi",
        0,
        2,
        TimeFunction::Constant(0.0),
    ));
    b.add_constraint(Revolute::new(
        "pivot",
        BodyRef::Body(0),
        [0.0, 0.0],
        BodyRef::Body(1),
        [0.0, d],
    ));
    b.add_force(PointSpringDamper::linear(
        BodyPoint::new(BodyRef::Ground, [-span, -d]),
        BodyPoint::new(BodyRef::Body(1), [0.0, 0.0]),
        span,
        k,
        c,
    ));
    b.gravity([0.0, -G]);
    b.build().unwrap()
}

/// The cart pendulum's consistent state (by hand): cart at (s, 0), bob
/// centre at (s + d sin θ, −d cos θ).
fn cart_state(d: f64, s: f64, sd: f64, th: f64, om: f64) -> (Vec<f64>, Vec<f64>) {
    let (sn, cs) = th.sin_cos();
    (
        vec![s, 0.0, 0.0, s + d * sn, -d * cs, th],
        vec![sd, 0.0, 0.0, sd + d * cs * om, d * sn * om, om],
    )
}

#[test]
fn drive_acceleration_input_matches_the_cart_pendulum_closed_form() {
    // Lagrange with x_b = s + d sin θ, y_b = −d cos θ and the cart's
    // acceleration s̈ = u: I_O θ̈ = −m g d sin θ − m d cos θ s̈ − F d cos θ,
    // F = k (x_b − x_b⁰) + c ẋ_b the spring-damper's pull (horizontal to
    // first order at the free length)
    let (m, i, d) = (1.5, 0.02, 0.4);
    let io = i + m * d * d;
    let cart = [Input::Drive { joint: 0 }];
    let outputs = [Output::Coordinate(3), Output::Velocity(3)];
    let opts = LinearizeOptions {
        independent: Some(vec![5]),
        ..Default::default()
    };
    // hanging at rest, spring-damper on: the exact tangent path
    let (k, c) = (40.0, 3.0);
    let sys = cart_pendulum(m, i, d, k, c, TimeFunction::Constant(0.0));
    let (q, qd) = cart_state(d, 0.0, 0.0, 0.0, 0.0);
    let ss = linearize(&sys, &[], 0.0, &q, &qd, &cart, &outputs, &opts).unwrap();
    assert_eq!(ss.method, Method::Tangent);
    let names: Vec<_> = ss.states.iter().map(|s| (s.0.as_str(), s.1)).collect();
    assert_eq!(
        names,
        [
            ("bob.phi", "rad"),
            ("bob.omega", "rad/s"),
            ("cart_x.offset", "m"),
            ("cart_x.rate", "m/s")
        ]
    );
    assert_eq!(ss.inputs[0], ("cart_x.acc".to_string(), "m/s^2"));
    let a = [
        [0.0, 1.0, 0.0, 0.0],
        [
            -(m * G * d + k * d * d) / io,
            -c * d * d / io,
            -k * d / io,
            -c * d / io,
        ],
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 4],
    ];
    let b = [0.0, -m * d / io, 0.0, 1.0];
    let cc = [[d, 0.0, 1.0, 0.0], [0.0, d, 0.0, 1.0]];
    let check = |ss: &StateSpace, a: &[[f64; 4]; 4], b: &[f64; 4], cc: &[[f64; 4]; 2], tol: f64| {
        let scale = a.iter().flatten().fold(1.0_f64, |s, v| s.max(v.abs()));
        for (r, (row, &br)) in a.iter().zip(b).enumerate() {
            for (j, &v) in row.iter().enumerate() {
                let got = ss.a[(r, j)];
                assert!((got - v).abs() <= tol * scale, "A[{r},{j}] = {got} vs {v}");
            }
            let got = ss.b[(r, 0)];
            assert!((got - br).abs() <= tol, "B[{r}] = {got} vs {br}");
        }
        for (r, row) in cc.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                let got = ss.c[(r, j)];
                assert!((got - v).abs() <= tol, "C[{r},{j}] = {got} vs {v}");
            }
        }
    };
    check(&ss, &a, &b, &cc, 1e-12);
    // the same point by central differences through the chart
    let fd = linearize(
        &sys,
        &[],
        0.0,
        &q,
        &qd,
        &cart,
        &outputs,
        &LinearizeOptions {
            method: Method::FiniteDifferences,
            ..opts.clone()
        },
    )
    .unwrap();
    check(&fd, &a, &b, &cc, 1e-6);
    // swinging on a cart that moves and accelerates (f = v₀ t + a₀ t²/2,
    // no spring): θ̈ = −(m g d sin θ + m d cos θ a₀)/I_O, differences path
    let (v0, a0, th, om) = (0.7, 1.9, 0.6, -1.1);
    let sys = cart_pendulum(
        m,
        i,
        d,
        0.0,
        0.0,
        TimeFunction::Polynomial(vec![0.0, v0, 0.5 * a0]),
    );
    let (q, qd) = cart_state(d, 0.0, v0, th, om);
    let ss = linearize(&sys, &[], 0.0, &q, &qd, &cart, &outputs, &opts).unwrap();
    assert_eq!(ss.method, Method::FiniteDifferences);
    let (sn, cs) = th.sin_cos();
    let a = [
        [0.0, 1.0, 0.0, 0.0],
        [(-m * G * d * cs + m * d * sn * a0) / io, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 4],
    ];
    let b = [0.0, -m * d * cs / io, 0.0, 1.0];
    let cc = [[d * cs, 0.0, 1.0, 0.0], [-d * sn * om, d * cs, 0.0, 1.0]];
    check(&ss, &a, &b, &cc, 1e-6);
    // a joint that is not a drive, and a drive named twice, are refused
    let err = |inputs: &[Input]| {
        linearize(&sys, &[], 0.0, &q, &qd, inputs, &[], &opts)
            .unwrap_err()
            .to_string()
    };
    assert!(
        err(&[Input::Drive { joint: 3 }]).contains("'pivot' is not a drive"),
        "{}",
        err(&[Input::Drive { joint: 3 }])
    );
    assert!(err(&[cart[0], cart[0]]).contains("'cart_x' is an input twice"));
}

/// The cart pendulum's (θ, θ̇) at τ when its drive follows `f + δ p`
/// (`p` = 1, t or t²/2: an offset, a rate or an acceleration step), from
/// the consistent start of `f + δ p` at t = 0.
#[allow(clippy::too_many_arguments)]
fn cart_run(
    m: f64,
    i: f64,
    d: f64,
    k: f64,
    c: f64,
    f: [f64; 3],
    start: (f64, f64),
    delta: f64,
    which: usize,
    tau: f64,
) -> [f64; 2] {
    let mut coeffs = f.to_vec();
    coeffs[which] += if which == 2 { 0.5 * delta } else { delta };
    let sys = cart_pendulum(m, i, d, k, c, TimeFunction::Polynomial(coeffs.clone()));
    let (q, qd) = cart_state(d, coeffs[0], coeffs[1], start.0, start.1);
    let (traj, summary) = simulate(&sys, &q, &qd, &run_config(tau), &mut []).unwrap();
    assert_eq!(summary.status, "completed");
    let (q, qd) = (traj.q.last().unwrap(), traj.qd.last().unwrap());
    [q[5], qd[5]]
}

#[test]
fn drive_inputs_predict_nonlinear_runs_with_perturbed_drives() {
    let (m, i, d) = (1.5, 0.02, 0.4);
    let cart = [Input::Drive { joint: 0 }];
    let opts = LinearizeOptions {
        independent: Some(vec![5]),
        ..Default::default()
    };
    // at rest, with the spring-damper: runs over τ = 0.3 s with the drive
    // perturbed by ±δ in offset, rate and acceleration against
    // exp(A τ) e_σ, exp(A τ) e_σ̇ and ∫₀^τ exp(A s) B ds
    let (k, c) = (40.0, 3.0);
    let sys = cart_pendulum(m, i, d, k, c, TimeFunction::Constant(0.0));
    let (q, qd) = cart_state(d, 0.0, 0.0, 0.0, 0.0);
    let ss = linearize(&sys, &[], 0.0, &q, &qd, &cart, &[], &opts).unwrap();
    assert_eq!(ss.method, Method::Tangent);
    let tau = 0.3;
    let delta = 1e-4;
    // [A B; 0 0] carries the step input as a fifth state
    let mut aug = Mat::<f64>::zeros(5, 5);
    for r in 0..4 {
        for j in 0..4 {
            aug[(r, j)] = ss.a[(r, j)];
        }
        aug[(r, 4)] = ss.b[(r, 0)];
    }
    for (which, x0) in [
        (0, [0.0, 0.0, 1.0, 0.0, 0.0]),
        (1, [0.0, 0.0, 0.0, 1.0, 0.0]),
        (2, [0.0, 0.0, 0.0, 0.0, 1.0]),
    ] {
        let run = |s: f64| cart_run(m, i, d, k, c, [0.0; 3], (0.0, 0.0), s * delta, which, tau);
        let (p, n) = (run(1.0), run(-1.0));
        let nonlinear = [(p[0] - n[0]) / (2.0 * delta), (p[1] - n[1]) / (2.0 * delta)];
        let linear = expm_times(&aug, tau, &x0);
        let size = nonlinear[0].abs().max(nonlinear[1].abs());
        let err = (nonlinear[0] - linear[0])
            .abs()
            .max((nonlinear[1] - linear[1]).abs());
        eprintln!(
            "drive input {which}: nonlinear {nonlinear:?}, linear [{:.9e}, {:.9e}], error {err:.2e} of {size:.2e}",
            linear[0], linear[1]
        );
        assert!(size > 0.01, "the perturbation moves the pendulum: {size}");
        assert!(err < 1e-6 * size, "{err:.3e} of {size:.3e}");
    }
    // swinging on a moving, accelerating cart (differences path): the θ̇
    // row of A and B from runs over τ and 2τ, Richardson-extrapolated
    let (v0, a0, th, om) = (0.7, 1.9, 0.6, -1.1);
    let f = [0.0, v0, 0.5 * a0];
    let sys = cart_pendulum(m, i, d, 0.0, 0.0, TimeFunction::Polynomial(f.to_vec()));
    let (q, qd) = cart_state(d, 0.0, v0, th, om);
    let ss = linearize(&sys, &[], 0.0, &q, &qd, &cart, &[], &opts).unwrap();
    assert_eq!(ss.method, Method::FiniteDifferences);
    let delta = 1e-3;
    for (which, model) in [(0, ss.a[(1, 2)]), (1, ss.a[(1, 3)]), (2, ss.b[(1, 0)])] {
        let slope = |tau: f64| {
            let run = |s: f64| cart_run(m, i, d, 0.0, 0.0, f, (th, om), s * delta, which, tau);
            let (p, n) = (run(1.0), run(-1.0));
            (p[1] - n[1]) / (2.0 * delta) / tau
        };
        let tau = 1e-4;
        let measured = 2.0 * slope(tau) - slope(2.0 * tau);
        eprintln!("moving cart, drive input {which}: model {model:.6e}, runs {measured:.6e}");
        assert!(
            (measured - model).abs() < 2e-5 * model.abs().max(1.0),
            "{which}: model {model} vs runs {measured}"
        );
    }
}

/// A state of the wrong length or with a non-finite entry is refused with
/// the same reason by the linearisation and by a run.
#[test]
fn bad_states_are_refused_alike_by_linearize_and_simulate() {
    let sys = pendulum(1.5, 0.02, 0.4, 0.3);
    let (q, qd) = state(0.3, 0.0, 0.4);
    let mut nan = qd.clone();
    nan[1] = f64::NAN;
    let cases = [
        (
            q[..2].to_vec(),
            qd.clone(),
            "expected 3 coordinates and velocities, got 2 and 3",
        ),
        (q.clone(), nan, "component 4 of (q, q̇) is not finite"),
    ];
    for (q, qd, why) in cases {
        let e = linearize(
            &sys,
            &[],
            0.0,
            &q,
            &qd,
            &[],
            &[],
            &LinearizeOptions::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains(why), "{e}");
        let e = simulate(&sys, &q, &qd, &run_config(0.1), &mut []).unwrap_err();
        assert!(e.to_string().contains(why), "{e}");
    }
}
