//! Initial state by joint coordinates (`[[initial.joint]]`): assembled by the
//! Newton of `formulation::initial` with relative-angle and slide lock rows,
//! checked against closed forms (a double pendulum, Freudenstein's equation
//! of the four-bar, a slider) and the branch-flip refusal.

use mbsolve::scenario::{self, Scenario, FOURBAR_TOML};
use std::f64::consts::PI;

fn load(
    dir: &std::path::Path,
    name: &str,
    text: &str,
) -> Result<Scenario, scenario::ScenarioError> {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    scenario::load(&path, &[])
}

/// Two uniform links of length 1 (pins at local (∓½, 0)), the first on a
/// ground pivot at the origin; `bodies`: the `[[body]]` tables' position
/// keys, `initial`: the `[initial]` section.
fn double_pendulum(bodies: [&str; 2], initial: &str) -> String {
    format!(
        r#"gravity = [0.0, -9.81]
[[body]]
name = "upper"
mass = 1.0
inertia = 0.0833333333333333
{}
[[body]]
name = "lower"
mass = 1.0
inertia = 0.0833333333333333
{}
[[joint]]
type = "revolute"
name = "A"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "upper"
point_j = [-0.5, 0.0]
[[joint]]
type = "revolute"
name = "B"
body_i = "upper"
point_i = [0.5, 0.0]
body_j = "lower"
point_j = [-0.5, 0.0]
[time]
end = 1.0
{initial}
"#,
        bodies[0], bodies[1]
    )
}

#[test]
fn double_pendulum_by_joint_angles_equals_the_one_by_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    let (ta, tb, wa, wb) = (-60f64.to_radians(), 45f64.to_radians(), 1.0, -0.5);
    // closed form: φ1 = θA, φ2 = θA + θB, centres of mass along the links
    let (p1, p2, w1, w2) = (ta, ta + tb, wa, wa + wb);
    let q = [
        0.5 * p1.cos(),
        0.5 * p1.sin(),
        p1,
        p1.cos() + 0.5 * p2.cos(),
        p1.sin() + 0.5 * p2.sin(),
        p2,
    ];
    let qd = [
        -0.5 * w1 * p1.sin(),
        0.5 * w1 * p1.cos(),
        w1,
        -w1 * p1.sin() - 0.5 * w2 * p2.sin(),
        w1 * p1.cos() + 0.5 * w2 * p2.cos(),
        w2,
    ];
    let body = |k: usize| {
        format!(
            "x = {}\ny = {}\nphi = {}\nvx = {}\nvy = {}\nomega = {}",
            q[3 * k],
            q[3 * k + 1],
            q[3 * k + 2],
            qd[3 * k],
            qd[3 * k + 1],
            qd[3 * k + 2]
        )
    };
    let by_coords = load(
        dir.path(),
        "coords",
        &double_pendulum([&body(0), &body(1)], ""),
    )
    .unwrap();
    // by joint angles from bodies piled at the origin (far from assembled)
    let joints = format!(
        "[[initial.joint]]\nname = \"A\"\nangle_deg = {}\nrate = {wa}\n\
         [[initial.joint]]\nname = \"B\"\nangle_deg = {}\nrate_deg = {}\n",
        ta.to_degrees(),
        tb.to_degrees(),
        wb.to_degrees()
    );
    let by_joints = load(dir.path(), "joints", &double_pendulum(["", ""], &joints)).unwrap();
    for k in 0..6 {
        assert!((by_joints.q0[k] - q[k]).abs() < 1e-12, "q[{k}]");
        assert!((by_joints.qd0[k] - qd[k]).abs() < 1e-12, "qd[{k}]");
        assert!((by_joints.q0[k] - by_coords.q0[k]).abs() < 1e-12);
        assert!((by_joints.qd0[k] - by_coords.qd0[k]).abs() < 1e-12);
    }
    // the report: the lower body's centre moved from the origin to q[3..5]
    let a = by_joints.assembly.as_ref().unwrap();
    assert!((a.body_moves[1][0] - q[3].hypot(q[4])).abs() < 1e-12);
    assert!((a.body_moves[1][1] - p2.abs()).abs() < 1e-12);
    assert!(by_coords.assembly.as_ref().unwrap().body_moves[1][0] < 1e-12);
}

/// Freudenstein: the rocker angle ψ of the four-bar with ground link d,
/// crank a, coupler b, rocker c at crank angle θ, on the branch `upper`
/// (C left of the line B → D) or the other.
fn freudenstein(theta: f64, upper: bool) -> f64 {
    let (a, b, c, d) = (0.2, 0.4, 0.25, 0.4);
    let (k1, k2, k3) = (
        d / a,
        d / c,
        (a * a - b * b + c * c + d * d) / (2.0 * a * c),
    );
    // K1 cos ψ − K2 cos θ + K3 = cos(θ − ψ)  ⇔  P cos ψ + Q sin ψ = R
    let (p, q, r) = (theta.cos() - k1, theta.sin(), k3 - k2 * theta.cos());
    let base = q.atan2(p);
    let spread = (r / p.hypot(q)).acos();
    let pick = |psi: f64| {
        let bx = [a * theta.cos(), a * theta.sin()];
        let cx = [d + c * psi.cos(), c * psi.sin()];
        let cross = (d - bx[0]) * (cx[1] - bx[1]) - (0.0 - bx[1]) * (cx[0] - bx[0]);
        cross > 0.0
    };
    let psi = base + spread;
    if pick(psi) == upper {
        psi
    } else {
        base - spread
    }
}

fn wrap(a: f64) -> f64 {
    (a + PI).rem_euclid(2.0 * PI) - PI
}

fn fourbar(angle_deg: f64, rate: f64, extra: &str) -> String {
    FOURBAR_TOML.replace(
        "independent = [\"crank.phi\"]   # position and rate kept as given",
        &format!("{extra}\njoint = [{{ name = \"A\", angle_deg = {angle_deg}, rate = {rate} }}]"),
    )
}

#[test]
fn four_bar_from_its_crank_angle_reaches_freudensteins_position() {
    let dir = tempfile::tempdir().unwrap();
    for deg in [60.0, 120.0, 170.0] {
        let sc = load(dir.path(), "fourbar", &fourbar(deg, 2.0, "")).unwrap();
        let theta = f64::to_radians(deg);
        assert!((sc.q0[2] - theta).abs() < 1e-12, "crank angle at {deg}°");
        let psi = freudenstein(theta, true);
        assert!(
            wrap(sc.q0[8] - psi).abs() < 1e-10,
            "rocker at {deg}°: {} vs {psi}",
            sc.q0[8]
        );
        // rate: ψ̇ = dψ/dθ θ̇ (central difference of the closed form)
        let h = 1e-6;
        let dpsi = wrap(freudenstein(theta + h, true) - freudenstein(theta - h, true)) / (2.0 * h);
        assert!((sc.qd0[2] - 2.0).abs() < 1e-12);
        assert!(
            (sc.qd0[8] - 2.0 * dpsi).abs() < 1e-7,
            "rocker rate at {deg}°"
        );
    }
}

#[test]
fn a_start_that_flips_the_branch_is_refused_unless_allowed() {
    let dir = tempfile::tempdir().unwrap();
    // the sketch is on the upper branch at θ = 60°; a lock at θ = −60°
    // pulls Newton onto the mirror image, the other branch
    let e = load(dir.path(), "flip", &fourbar(300.0, 0.0, "")).unwrap_err();
    assert_eq!(e.key, "initial.allow_branch_flip");
    assert!(
        e.message.contains("other branch") && e.message.contains("'C'"),
        "{e}"
    );
    assert!(e.to_string().contains("flip.toml"), "{e}");
    // allowed: it is really the other branch (the second Freudenstein root)
    let sc = load(
        dir.path(),
        "flip",
        &fourbar(300.0, 0.0, "allow_branch_flip = true"),
    )
    .unwrap();
    let theta = f64::to_radians(300.0);
    assert!(wrap(sc.q0[8] - freudenstein(theta, false)).abs() < 1e-10);
    assert!(wrap(sc.q0[8] - freudenstein(theta, true)).abs() > 0.1);
}

#[test]
fn slider_by_its_displacement_and_bad_joint_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    let slider = |init: &str| {
        format!(
            r#"[[body]]
name = "block"
mass = 1.0
inertia = 0.1
phi_deg = 30.0
[[joint]]
type = "translational"
name = "P"
body_i = "ground"
point_i = [1.0, 2.0]
axis_i = [0.8660254037844387, 0.5]
body_j = "block"
point_j = [0.1, 0.0]
[[body]]
name = "wheel"
mass = 1.0
inertia = 0.1
[[joint]]
type = "revolute"
name = "W"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "wheel"
point_j = [0.0, 0.0]
[[joint]]
type = "drive_angle"
name = "spin"
body_i = "ground"
body_j = "wheel"
motion = 0.0
[time]
end = 1.0
{init}
"#
        )
    };
    // the block keeps φ = 30° (the joint's relative angle); its point
    // (0.1, 0) in body frame is at (1, 2) + 0.3 u
    let sc = load(
        dir.path(),
        "slider",
        &slider("[[initial.joint]]\nname = \"P\"\ndisplacement = 0.3\nvelocity = -0.2"),
    );
    let sc = sc.unwrap();
    let u = [3f64.sqrt() / 2.0, 0.5];
    let (sn, cs) = sc.q0[2].sin_cos();
    let p = [sc.q0[0] + 0.1 * cs, sc.q0[1] + 0.1 * sn];
    assert!((p[0] - (1.0 + 0.3 * u[0])).abs() < 1e-12);
    assert!((p[1] - (2.0 + 0.3 * u[1])).abs() < 1e-12);
    assert!((sc.qd0[0] + 0.2 * u[0]).abs() < 1e-12 && (sc.qd0[1] + 0.2 * u[1]).abs() < 1e-12);

    for (init, key, text) in [
        (
            "[[initial.joint]]\nname = \"Q\"\ndisplacement = 0.1",
            "initial.joint[0].name",
            "no joint named 'Q'",
        ),
        (
            "[[initial.joint]]\nname = \"P\"\nangle_deg = 10",
            "initial.joint[0].angle_deg",
            "not a key of a translational joint",
        ),
        (
            "[[initial.joint]]\nname = \"spin\"\nangle = 1.0",
            "initial.joint[0].name",
            "only revolute and translational",
        ),
        (
            "[[initial.joint]]\nname = \"P\"",
            "initial.joint[0].displacement",
            "missing",
        ),
    ] {
        let e = load(dir.path(), "bad", &slider(init)).unwrap_err();
        assert_eq!(e.key, key, "{e}");
        assert!(e.message.contains(text), "{e}");
    }
    // a joint coordinate the constraints fix: the relative angle of a
    // revolute joint in a locked (zero-dof) four-bar
    let e = load(
        dir.path(),
        "locked",
        &FOURBAR_TOML.replace(
            "independent = [\"crank.phi\"]   # position and rate kept as given",
            "independent = [\"crank.phi\"]\njoint = [{ name = \"C\", angle_deg = 10 }]",
        ),
    )
    .unwrap_err();
    assert!(e.key.starts_with("initial"), "{e}");
}
