//! `[[sensor]]` columns, drive forces and the energy split in the CSV of
//! `mbsolve run`, each against an independent computation: closed forms of
//! the four-bar's geometry, finite differences of the position sensors, the
//! laws of springs and contacts at the measured state, a double pendulum's
//! minimal-coordinate ODE integrated here, and inverse dynamics of a
//! driven crank.

use std::collections::HashMap;
use std::process::Command;

/// A run's CSV, columns by name, and the units of `<stem>.columns.json`.
struct Table {
    col: HashMap<String, usize>,
    rows: Vec<Vec<f64>>,
    units: HashMap<String, String>,
}

impl Table {
    fn get(&self, r: usize, name: &str) -> f64 {
        let c = *self
            .col
            .get(name)
            .unwrap_or_else(|| panic!("no column {name}: {:?}", self.col.keys()));
        self.rows[r][c]
    }
}

fn run(dir: &std::path::Path, name: &str, text: &str) -> Table {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .arg("run")
        .arg(&path)
        .args(["--progress", "off", "--out"])
        .arg(dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(dir.join(format!("{name}.csv"))).unwrap();
    let mut lines = csv.lines();
    let col = lines
        .next()
        .unwrap()
        .split(',')
        .enumerate()
        .map(|(i, h)| (h.to_string(), i))
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join(format!("{name}.columns.json"))).unwrap(),
    )
    .unwrap();
    let units = json
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["name"].as_str().unwrap().to_string(),
                c["unit"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    Table { col, rows, units }
}

const DT: f64 = 1e-3;

/// Central difference of column `name` at row `r` over the output times.
fn fd(t: &Table, r: usize, name: &str) -> f64 {
    (t.get(r + 1, name) - t.get(r - 1, name)) / (2.0 * DT)
}

#[test]
fn point_joint_angle_and_distance_sensors_on_the_four_bar() {
    let dir = tempfile::tempdir().unwrap();
    let text = mbsolve::scenario::FOURBAR_TOML
        .replace(
            "method = \"ode23\"",
            "method = \"ode45\"\nrtol = 1e-10\natol = 1e-12",
        )
        .replace("end = 2.0", "end = 0.15")
        .replace(
            "dt = 0.002",
            &format!("dt = {DT}\nquantities = [\"velocities\"]"),
        )
        + r#"
[[sensor]]
name = "B"
type = "point"
body = "crank"
point = [0.1, 0.0]

[[sensor]]
name = "C"
type = "joint_angle"
joint = "C"

[[sensor]]
name = "BD"
type = "distance"
body_i = "crank"
point_i = [0.1, 0.0]
body_j = "ground"
point_j = [0.4, 0.0]
"#;
    let t = run(dir.path(), "fourbar", &text);
    for (c, u) in [
        ("B.x", "m"),
        ("B.vy", "m/s"),
        ("C.angle", "rad"),
        ("C.rate", "rad/s"),
        ("BD.distance", "m"),
        ("BD.rate", "m/s"),
    ] {
        assert_eq!(t.units[c], u, "{c}");
    }
    let (a, d) = (0.2, 0.4);
    let mut worst = [0.0f64; 4];
    for r in 1..t.rows.len() - 1 {
        let (th, w) = (t.get(r, "crank.phi"), t.get(r, "crank.omega"));
        // B = a (cos θ, sin θ) from the ground pivot A = 0
        worst[0] = worst[0]
            .max((t.get(r, "B.x") - a * th.cos()).abs())
            .max((t.get(r, "B.y") - a * th.sin()).abs());
        // velocity sensor against the motion of the position sensor
        worst[1] = worst[1]
            .max((t.get(r, "B.vx") - fd(&t, r, "B.x")).abs())
            .max((t.get(r, "B.vy") - fd(&t, r, "B.y")).abs());
        // the joint's relative angle and rate
        let rel = t.get(r, "rocker.phi") - t.get(r, "coupler.phi");
        worst[2] = worst[2]
            .max((t.get(r, "C.angle") - rel).abs())
            .max((t.get(r, "C.rate") - fd(&t, r, "C.angle")).abs());
        // |BD|² = a² + d² − 2ad cos θ (law of cosines) and its rate
        let bd = (a * a + d * d - 2.0 * a * d * th.cos()).sqrt();
        worst[3] = worst[3]
            .max((t.get(r, "BD.distance") - bd).abs())
            .max((t.get(r, "BD.rate") - a * d * th.sin() * w / bd).abs());
    }
    // positions to the constraint drift; rates to the O(dt²) of the differences
    for (what, e, tol) in [
        ("point position", worst[0], 1e-8),
        ("point velocity", worst[1], 1e-4),
        ("joint angle and rate", worst[2], 1e-4),
        ("distance and rate", worst[3], 1e-7),
    ] {
        assert!(e < tol, "{what}: {e:e}");
    }
}

#[test]
fn spring_rotational_spring_and_contact_sensors_follow_their_laws() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"
gravity = [0.0, -9.81]
[[body]]
name = "bob"
mass = 1.0
inertia = 0.01
x = 0.4
y = -0.6
[[body]]
name = "bar"
mass = 1.0
inertia = 0.05
phi = 0.3
[[body]]
name = "ball"
mass = 0.5
inertia = 0.002
y = 0.15
vx = 0.3
[[joint]]
type = "revolute"
name = "pin"
body_i = "ground"
point_i = [2.0, 0.0]
body_j = "bar"
point_j = [0.0, 0.0]
[[force]]
type = "spring"
name = "spring"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "bob"
point_j = [0.0, 0.0]
free_length = 0.5
stiffness = 60.0
damping = 0.8
preload = 2.0
[[force]]
type = "rotational_spring"
name = "torsion"
body_i = "ground"
body_j = "bar"
rest_angle = 0.1
stiffness = 5.0
damping = 0.3
[[force]]
type = "contact"
name = "floor"
body = "ball"
radius = 0.1
wall_point = [0.0, 0.0]
wall_normal_deg = 90.0
stiffness = 1e5
damping = 0.5
friction = 0.3
[integrator]
method = "ode45"
rtol = 1e-8
atol = 1e-10
[time]
end = 0.6
[output]
dt = 0.001
quantities = ["velocities", "energy"]
[[sensor]]
name = "s"
type = "force_element"
force = "spring"
[[sensor]]
name = "r"
type = "force_element"
force = "torsion"
[[sensor]]
name = "c"
type = "contact"
force = "floor"
"#;
    let t = run(dir.path(), "laws", text);
    assert_eq!(t.units["s.force"], "N");
    assert_eq!(t.units["r.torque"], "N m");
    assert_eq!(t.units["c.penetration"], "m");
    let mut contact_rows = 0;
    let mut worst = [0.0f64; 3];
    for r in 0..t.rows.len() {
        let g = |n: &str| t.get(r, n);
        // spring: length and rate from the bob's state, F = P + k (L − L0) + c L̇
        let (x, y, vx, vy) = (g("bob.x"), g("bob.y"), g("bob.vx"), g("bob.vy"));
        let len = x.hypot(y);
        let rate = (x * vx + y * vy) / len;
        let f = 2.0 + 60.0 * (len - 0.5) + 0.8 * rate;
        worst[0] = worst[0]
            .max((g("s.length") - len).abs())
            .max((g("s.deflection") - (len - 0.5)).abs())
            .max((g("s.rate") - rate).abs())
            .max((g("s.force") - f).abs() / 10.0);
        // rotational spring: T = −k (φ − φ0) − c φ̇ on the bar
        let (p, w) = (g("bar.phi"), g("bar.omega"));
        worst[1] = worst[1]
            .max((g("r.deflection") - (p - 0.1)).abs())
            .max((g("r.rate") - w).abs())
            .max((g("r.torque") + 5.0 * (p - 0.1) + 0.3 * w).abs());
        // contact: δ = R − y, F_n = k δ^{3/2} (1 + χ δ̇) with δ̇ = −v_y
        let delta = 0.1 - g("ball.y");
        let fn_ = if delta > 0.0 {
            contact_rows += 1;
            (1e5 * delta.powf(1.5) * (1.0 - 0.5 * g("ball.vy"))).max(0.0)
        } else {
            0.0
        };
        worst[2] = worst[2]
            .max((g("c.penetration") - delta).abs())
            .max((g("c.normal_force") - fn_).abs() / 10.0);
        // friction opposes the slip and is bounded by μ F_n
        assert!(g("c.friction_force").abs() <= 0.3 * g("c.normal_force") * (1.0 + 1e-9) + 1e-12);
        // the split of the potential: no elastic energy without deflection
        assert!(g("potential_elastic") >= 0.0);
    }
    assert!(contact_rows > 10, "the ball must hit the floor");
    for (what, e) in ["spring", "rotational spring", "contact"].iter().zip(worst) {
        assert!(e < 1e-10, "{what}: {e:e}");
    }
}

/// Two uniform links (m = 1, L = 1, I = 1/12) in absolute angles: the
/// minimal-coordinate equations `M(φ) φ̈ = Q(φ, φ̇)` from the Lagrangian.
fn double_pendulum_rhs(y: [f64; 4]) -> [f64; 4] {
    let (m, l, i, g) = (1.0, 1.0, 1.0 / 12.0, 9.81);
    let [p1, p2, w1, w2] = y;
    let c = m * l * l / 2.0;
    let m11 = m * l * l / 4.0 + i + m * l * l;
    let m12 = c * (p1 - p2).cos();
    let m22 = m * l * l / 4.0 + i;
    let q1 = -c * (p1 - p2).sin() * w2 * w2 - (m * l / 2.0 + m * l) * g * p1.cos();
    let q2 = c * (p1 - p2).sin() * w1 * w1 - m * l / 2.0 * g * p2.cos();
    let det = m11 * m22 - m12 * m12;
    [
        w1,
        w2,
        (m22 * q1 - m12 * q2) / det,
        (m11 * q2 - m12 * q1) / det,
    ]
}

#[test]
fn double_pendulum_matches_its_minimal_coordinate_ode_and_conserves_energy() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"
gravity = [0.0, -9.81]
[[body]]
name = "upper"
mass = 1.0
inertia = 0.08333333333333333
[[body]]
name = "lower"
mass = 1.0
inertia = 0.08333333333333333
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
[[initial.joint]]
name = "A"
angle_deg = -30.0
rate = 0.5
[[initial.joint]]
name = "B"
angle_deg = 60.0
[integrator]
method = "ode45"
rtol = 1e-11
atol = 1e-12
[time]
end = 2.0
[output]
dt = 0.01
quantities = ["energy"]
"#;
    let t = run(dir.path(), "double", text);
    // RK4 on the minimal coordinates, h = 1e-4 (error ~ h⁴)
    let mut y = [-30f64.to_radians(), 30f64.to_radians(), 0.5, 0.5];
    let h = 1e-4;
    let mut worst = 0.0f64;
    for r in 0..t.rows.len() {
        let tr = t.get(r, "t");
        let steps = ((tr - (r as f64 - 1.0).max(0.0) * 0.01) / h).round() as usize;
        if r > 0 {
            for _ in 0..steps {
                let k1 = double_pendulum_rhs(y);
                let s = |k: [f64; 4], a: f64| std::array::from_fn(|i| y[i] + a * h * k[i]);
                let k2 = double_pendulum_rhs(s(k1, 0.5));
                let k3 = double_pendulum_rhs(s(k2, 0.5));
                let k4 = double_pendulum_rhs(s(k3, 1.0));
                for i in 0..4 {
                    y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
                }
            }
        }
        worst = worst
            .max((t.get(r, "upper.phi") - y[0]).abs())
            .max((t.get(r, "lower.phi") - y[1]).abs());
    }
    assert!(
        worst < 1e-6,
        "angles vs the minimal-coordinate ODE: {worst:e}"
    );
    // energy from the CLI's own columns: conserved; V is all gravity
    let e0 = t.get(0, "total_energy");
    let last = t.rows.len() - 1;
    let mut drift = 0.0f64;
    for r in 0..=last {
        drift = drift.max((t.get(r, "total_energy") - e0).abs());
        let (p1, p2) = (t.get(r, "upper.phi"), t.get(r, "lower.phi"));
        let v = 9.81 * (0.5 * p1.sin() + p1.sin() + 0.5 * p2.sin());
        assert!((t.get(r, "potential_gravity") - v).abs() < 1e-6);
        assert_eq!(t.get(r, "potential_elastic"), 0.0);
        assert!(t.get(r, "work_forces").abs() < 1e-8);
        assert!(t.get(r, "work_drives").abs() < 1e-6);
        assert!(t.get(r, "energy_balance_error").abs() < 1e-6);
    }
    assert!(drift < 1e-7, "energy drift {drift:e}");
    assert_eq!(t.units["work_drives"], "J");
    // the assembly report: both bodies started at the origin; the lower
    // one's centre went to (cos φ1 + ½ cos φ2, sin φ1 + ½ sin φ2)
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("double.summary.json")).unwrap(),
    )
    .unwrap();
    let a = &summary["initial_assembly"];
    let (p1, p2) = (-30f64.to_radians(), 30f64.to_radians());
    let moved = (p1.cos() + 0.5 * p2.cos()).hypot(p1.sin() + 0.5 * p2.sin());
    let got = a["body_moves"]["lower"][0].as_f64().unwrap();
    assert!((got - moved).abs() < 1e-12, "{got} vs {moved}");
    assert_eq!(a["max_displacement_body"], "lower");
    assert!((a["max_rotation_rad"].as_f64().unwrap() - p1.abs().max(p2.abs())).abs() < 1e-12);
    let check = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .arg("check")
        .arg(dir.path().join("double.toml"))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&check.stdout);
    assert!(
        out.contains("assembly moved") && out.contains("(body 'lower')"),
        "{out}"
    );
}

#[test]
fn drive_torque_of_a_driven_crank_matches_inverse_dynamics_and_the_work_of_the_drive() {
    let dir = tempfile::tempdir().unwrap();
    // a uniform bar (m = 2, L = 0.6) pinned at one end, turned at a constant
    // rate ω: τ = I_A θ̈ + m g (L/2) cos θ = m g (L/2) cos θ
    let (m, l, w, th0): (f64, f64, f64, f64) = (2.0, 0.6, 3.0, 0.2);
    let text = format!(
        r#"
gravity = [0.0, -9.81]
[[body]]
name = "crank"
mass = {m}
inertia = {i}
x = {x}
y = {y}
phi = {th0}
[[joint]]
type = "revolute"
name = "A"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "crank"
point_j = [-{h}, 0.0]
[[joint]]
type = "drive_angle"
name = "motor"
body_i = "ground"
body_j = "crank"
motion = {{ polynomial = [{th0}, {w}] }}
[integrator]
method = "ode45"
rtol = 1e-10
atol = 1e-12
[time]
end = 2.0
[output]
dt = 0.001
quantities = ["drives", "energy"]
"#,
        i = m * l * l / 12.0,
        h = l / 2.0,
        x = l / 2.0 * th0.cos(),
        y = l / 2.0 * th0.sin(),
    );
    let t = run(dir.path(), "crank", &text);
    assert_eq!(t.units["motor.drive"], "N m");
    let mut worst = 0.0f64;
    let mut work = 0.0;
    let e0 = t.get(0, "total_energy");
    for r in 0..t.rows.len() {
        let th = th0 + w * t.get(r, "t");
        let tau = m * 9.81 * l / 2.0 * th.cos();
        worst = worst.max((t.get(r, "motor.drive") - tau).abs());
        if r > 0 {
            // trapezoid of the drive's power τ ω
            work += 0.5 * w * (t.get(r, "motor.drive") + t.get(r - 1, "motor.drive")) * DT;
        }
        // the work of the drive is the change of the energy
        let de = t.get(r, "total_energy") - e0;
        // (trapezoid error h²/12 max|P''| T ≈ 3e-5 J at h = 1 ms)
        assert!(
            (work - de).abs() < 1e-4,
            "∫τω = {work} vs ΔE = {de} at row {r}"
        );
        // the run's own W_d, by the trapezoid over its ~150 steps of ~13 ms
        assert!((t.get(r, "work_drives") - de).abs() < 5e-3);
    }
    assert!(worst < 1e-6, "drive torque vs inverse dynamics: {worst:e}");
}

#[test]
fn bad_sensors_name_their_key() {
    let dir = tempfile::tempdir().unwrap();
    let base = mbsolve::scenario::FOURBAR_TOML;
    for (sensor, key, text) in [
        (
            "name = \"s\"\ntype = \"gauge\"",
            "sensor[0].type",
            "unknown sensor type 'gauge'",
        ),
        (
            "name = \"s\"\ntype = \"point\"\nbody = \"wheel\"",
            "sensor[0].body",
            "no body named 'wheel'",
        ),
        (
            "name = \"s\"\ntype = \"joint_angle\"\njoint = \"Z\"",
            "sensor[0].joint",
            "no joint named 'Z'",
        ),
        (
            "name = \"s\"\ntype = \"force_element\"\nforce = \"M\"",
            "sensor[0].force",
            "not a spring",
        ),
        (
            "name = \"s\"\ntype = \"contact\"\nforce = \"X\"",
            "sensor[0].force",
            "no [[force]] named 'X'",
        ),
        (
            "name = \"s\"\ntype = \"distance\"\nbody_i = \"crank\"",
            "sensor[0].body_j",
            "missing",
        ),
        (
            "name = \"a.b\"\ntype = \"point\"\nbody = \"crank\"",
            "sensor[0].name",
            "not a sensor name",
        ),
        (
            "name = \"s\"\ntype = \"point\"\nbody = \"crank\"\njoint = \"A\"",
            "sensor[0].joint",
            "not a key",
        ),
    ] {
        let path = dir.path().join("bad.toml");
        std::fs::write(&path, format!("{base}\n[[sensor]]\n{sensor}\n")).unwrap();
        let e = mbsolve::scenario::load(&path, &[]).unwrap_err();
        assert_eq!(e.key, key, "{e}");
        assert!(e.message.contains(text), "{e}");
        assert!(e.file.ends_with("bad.toml"));
    }
}
