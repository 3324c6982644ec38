//! The user models written the long way reproduce the shipped scenarios
//! written with parameters, templates, expression motions, joint loads and
//! `[[state]]`s: the PID arm and the shaker built with the library's
//! `SystemBuilder` — bodies, joints, gravity on the links, a drive whose
//! motion is a hand-written closure with its derivatives, and every load
//! (the PID torques, the integrals' rates, the payload's spring-damper) in
//! one `CallbackForce` closure — none of the scenario reader's expression,
//! joint-load or state code. The PID's integrals are the velocities of an
//! extra free body of unit mass and inertia without gravity (the same
//! coordinates a `[[state]]` adds, got the ordinary way). The runs agree
//! to rounding: the same accepted steps, every output value within 1e-10
//! of its scale. (The quarter car: `parameters.rs`.)

use mbsolve::constraints::{DriveRelativeAngle, Revolute, Translational};
use mbsolve::forces::CallbackForce;
use mbsolve::model::{Body, BodyRef, Gravity, System, SystemBuilder, TimeFunction};
use mbsolve::scenario;
use mbsolve::simulation::{simulate, Trajectory};
use std::sync::Arc;

fn shipped(file: &str) -> scenario::Scenario {
    let path = format!("{}/scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
    scenario::load(std::path::Path::new(&path), &[]).unwrap_or_else(|e| panic!("{e}"))
}

/// Lines of `text` that are neither blank nor only a comment (`#` or `//`).
fn code_lines(text: &str) -> usize {
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#') && !l.starts_with("//"))
        .count()
}

/// The lines of the function `name` of this file (its signature to its
/// closing brace at column 0), counted by [`code_lines`].
fn function_lines(name: &str) -> usize {
    let src = include_str!("long_way.rs");
    let start = src.find(&format!("fn {name}(")).expect("the function");
    let body = &src[start..];
    let end = body.find("\n}\n").expect("its end");
    code_lines(&body[..end + 2])
}

/// The three-link PID arm of `scenarios/pid_arm.toml`, the long way.
fn pid_arm_long() -> System {
    let (kp, kd, ki) = (200.0, 20.0, 150.0);
    let target = [0.6, -0.4, 0.3];
    let mut b = SystemBuilder::new();
    for (i, x) in [0.25, 0.75, 1.25].into_iter().enumerate() {
        b.add_body(Body::new(
            format!("link{}", i + 1),
            1.0,
            0.0208333333333,
            [x, 0.0, 0.0],
        ));
    }
    // the integrals of the three joint errors: its vx, vy, omega
    b.add_body(Body::new("integrals", 1.0, 1.0, [0.0; 3]));
    let (g, r) = (BodyRef::Ground, BodyRef::Body);
    b.add_constraint(Revolute::new("joint1", g, [0.0, 0.0], r(0), [-0.25, 0.0]));
    b.add_constraint(Revolute::new(
        "joint2",
        r(0),
        [0.25, 0.0],
        r(1),
        [-0.25, 0.0],
    ));
    b.add_constraint(Revolute::new(
        "joint3",
        r(1),
        [0.25, 0.0],
        r(2),
        [-0.25, 0.0],
    ));
    b.add_force(Gravity {
        g: [0.0, -9.81],
        bodies: vec![(0, 1.0), (1, 1.0), (2, 1.0)],
    });
    // coordinates: φ1, φ2, φ3 and the integrals' x, y, φ
    let pid = move |_t: f64, q: &[f64], v: &[f64], f: &mut [f64]| {
        let angle = [q[0], q[1] - q[0], q[2] - q[1]];
        let rate = [v[0], v[1] - v[0], v[2] - v[1]];
        let mut tau = [0.0; 3];
        for j in 0..3 {
            tau[j] = kp * (target[j] - angle[j]) - kd * rate[j] + ki * v[3 + j];
            f[3 + j] = target[j] - angle[j];
        }
        f[0] = tau[0] - tau[1];
        f[1] = tau[1] - tau[2];
        f[2] = tau[2];
        Ok::<(), String>(())
    };
    b.add_force(CallbackForce::new("pid", vec![2, 5, 8, 9, 10, 11], pid));
    b.build().unwrap()
}

/// The crank-driven shaker of `scenarios/shaker.toml`, the long way.
fn shaker_long() -> System {
    let (w, tau, k, c) = (30.0, 0.3, 2000.0, 8.0);
    let mut b = SystemBuilder::new();
    b.gravity([0.0, -9.81]);
    b.add_body(Body::new("crank", 0.3, 6.25e-5, [0.025, 0.0, 0.0]));
    b.add_body(Body::new("rod", 0.6, 4.5e-3, [0.025, 0.1479, 1.7382]));
    b.add_body(Body::new("table", 2.0, 0.02, [0.0, 0.2958, 0.0]));
    b.add_body(Body::new("payload", 0.5, 0.002, [0.0, 0.2958, 0.0]));
    let (g, r) = (BodyRef::Ground, BodyRef::Body);
    b.add_constraint(Revolute::new("O", g, [0.0, 0.0], r(0), [-0.025, 0.0]));
    // φ = w (t − τ (1 − e^{−t/τ})): spun up from rest to w
    let spin = move |t: f64| {
        let e = (-t / tau).exp();
        [w * (t - tau * (1.0 - e)), w * (1.0 - e), w / tau * e]
    };
    let spin = TimeFunction::Custom(Arc::new(spin));
    b.add_constraint(DriveRelativeAngle::new("motor", g, r(0), spin));
    b.add_constraint(Revolute::new("A", r(0), [0.025, 0.0], r(1), [-0.15, 0.0]));
    b.add_constraint(Revolute::new("B", r(1), [0.15, 0.0], r(2), [0.0, 0.0]));
    let up = [0.0, 1.0];
    let rail = Translational::new("rail", g, [0.0, 0.0], up, r(2), [0.0, 0.0], 0.0);
    b.add_constraint(rail);
    let mount = Translational::new("mount", r(2), [0.0, 0.0], up, r(3), [0.0, 0.0], 0.0);
    b.add_constraint(mount);
    // the payload's spring-damper along the mount: table y, payload y
    let spring = move |_t: f64, q: &[f64], v: &[f64], f: &mut [f64]| {
        let force = -k * (q[1] - q[0]) - c * (v[1] - v[0]);
        f[0] = -force;
        f[1] = force;
        Ok::<(), String>(())
    };
    b.add_force(CallbackForce::new("spring", vec![7, 10], spring));
    b.build().unwrap()
}

/// Runs `long` with the settings of `short` from the same initial state
/// (the scenario's, assembled onto the joints by the reader: within 1e-4
/// of the long way's rounded numbers); asserts the same steps and every
/// value within `1e-10` of its scale.
fn agree(short: &scenario::Scenario, long: &System) -> (Trajectory, Trajectory) {
    let (q0, v0) = long.initial_state();
    for (x, y) in short.q0.iter().zip(&q0).chain(short.qd0.iter().zip(&v0)) {
        assert!(
            (x - y).abs() < 1e-4,
            "initial states {:?} vs {q0:?}",
            short.q0
        );
    }
    let (q0, v0) = (&short.q0, &short.qd0);
    let (a, sa) = simulate(&short.system, q0, v0, &short.run, &mut []).unwrap();
    let (b, sb) = simulate(long, q0, v0, &short.run, &mut []).unwrap();
    assert_eq!(
        (sa.status.as_str(), sb.status.as_str()),
        ("completed", "completed")
    );
    assert_eq!((sa.steps, sa.failed_steps), (sb.steps, sb.failed_steps));
    assert_eq!(a.t, b.t);
    for (name, x, y) in [("q", &a.q, &b.q), ("q'", &a.qd, &b.qd)] {
        for k in 0..x[0].len() {
            let scale = x.iter().map(|r| r[k].abs()).fold(1e-3, f64::max);
            let d = x
                .iter()
                .zip(y)
                .map(|(r, s)| (r[k] - s[k]).abs())
                .fold(0.0, f64::max);
            assert!(
                d <= 1e-10 * scale,
                "{name}[{k}]: differs by {d:e} (scale {scale:e})"
            );
        }
    }
    (a, b)
}

/// The PID arm: shipped file (parameters, `[[repeat]]`, `joint_torque`,
/// `[[state]]`) and the long way agree to rounding, and the arm reaches
/// its targets; the line counts of both ways are printed.
#[test]
fn the_pid_arm_written_the_long_way_is_the_shipped_one() {
    let short = shipped("pid_arm.toml");
    let (a, _) = agree(&short, &pid_arm_long());
    let last = a.q.last().unwrap();
    assert!((last[2] - 0.6).abs() < 5e-3 && (last[8] - last[5] - 0.3).abs() < 5e-3);
    let file = include_str!("../../scenarios/pid_arm.toml");
    eprintln!(
        "pid_arm: scenario {} lines ({} without comments and blank lines), long way {} lines",
        file.lines().count(),
        code_lines(file),
        function_lines("pid_arm_long")
    );
}

/// The shaker: shipped file (parameters, an expression motion,
/// `joint_force`) and the long way agree to rounding; the table's stroke
/// is the crank's diameter.
#[test]
fn the_shaker_written_the_long_way_is_the_shipped_one() {
    let short = shipped("shaker.toml");
    let (a, _) = agree(&short, &shaker_long());
    let ys = a.q.iter().map(|r| r[7]);
    let stroke = ys.clone().fold(f64::MIN, f64::max) - ys.fold(f64::MAX, f64::min);
    assert!((stroke - 0.1).abs() < 1e-3, "stroke {stroke}");
    let file = include_str!("../../scenarios/shaker.toml");
    eprintln!(
        "shaker: scenario {} lines ({} without comments and blank lines), long way {} lines",
        file.lines().count(),
        code_lines(file),
        function_lines("shaker_long")
    );
}
