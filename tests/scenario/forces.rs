//! `[[force]]` types of scenario files: each table builds the
//! library element it names (forces compared with the element built
//! directly), and bad input is an error naming file, key and value.

use mbsolve::forces::{
    Buoyancy, ContactLaw, Drag, ExpressionLoadBuilder, ForceElement, HalfPlaneContact, Law,
    LinePoint, PointSpringDamper, RotationalSpringDamper,
};
use mbsolve::model::{BodyPoint, BodyRef, TimeFunction};
use mbsolve::scenario::{self, Scenario, ScenarioError};

const HEAD: &str = r#"
gravity = [0.0, -9.81]
[[body]]
name = "a"
mass = 1.0
inertia = 0.1
[[body]]
name = "b"
mass = 2.0
inertia = 0.3
x = 1.0
[time]
end = 0.1
"#;

fn parse(forces: &str) -> Result<Scenario, ScenarioError> {
    scenario::parse(&format!("{HEAD}{forces}"), "f.toml", "f", &[])
}

fn g_of(e: &dyn ForceElement, t: f64, q: &[f64], qd: &[f64]) -> Vec<f64> {
    let mut g = vec![0.0; q.len()];
    e.add_forces(t, q, qd, &mut g);
    g
}

/// The scenario's element `k` gives the forces of `want` at a few states.
fn same(sc: &Scenario, k: usize, want: &dyn ForceElement) {
    let e = &sc.system.forces()[k];
    assert_eq!(e.coordinates(), want.coordinates(), "{}", e.name());
    let states = [
        (
            [0.1, -0.2, 0.3, 0.9, 0.4, -0.5],
            [0.5, -1.0, 2.0, -0.3, 0.2, 0.7],
        ),
        (
            [-0.3, -1.1, 1.3, 1.5, 0.1, 2.5],
            [-0.5, 0.4, -1.0, 1.3, -0.8, 0.1],
        ),
        (
            [0.0, -1.02, 0.0, 1.0, 0.0, 0.0],
            [0.2, -0.1, 0.0, 0.0, 0.0, 0.0],
        ),
    ];
    for (q, qd) in states {
        let (a, b) = (g_of(e.as_ref(), 0.3, &q, &qd), g_of(want, 0.3, &q, &qd));
        for (x, y) in a.iter().zip(&b) {
            assert!(
                (x - y).abs() <= 1e-12 * (1.0 + y.abs()),
                "{}: {a:?} vs {b:?}",
                e.name()
            );
        }
        assert_eq!(e.potential_energy(&q), want.potential_energy(&q));
    }
}

#[test]
fn spring_tables_build_point_spring_dampers() {
    let sc = parse(
        r#"
[[force]]
type = "spring"
body_i = "a"
point_i = [0.1, 0.2]
body_j = "b"
point_j = [-0.3, 0.0]
free_length = 0.6
stiffness = 120.0
damping = 3.0
preload = 5.0
actuator = { amplitude = 2.0, omega = 3.0 }
[[force]]
type = "spring"
body_i = "ground"
point_i = [0.0, 1.0]
body_j = "b"
force_deflection = { x = [-1.0, 0.0, 0.5], f = [-50.0, 0.0, 80.0] }
force_velocity = { x = [-1.0, 1.0], f = [-4.0, 6.0] }
"#,
    )
    .unwrap();
    let mut s = PointSpringDamper::linear(
        BodyPoint::new(BodyRef::Body(0), [0.1, 0.2]),
        BodyPoint::new(BodyRef::Body(1), [-0.3, 0.0]),
        0.6,
        120.0,
        3.0,
    );
    s.preload = 5.0;
    s.actuator = Some(TimeFunction::Harmonic {
        amplitude: 2.0,
        omega: 3.0,
        phase: 0.0,
        offset: 0.0,
    });
    same(&sc, 0, &s); // gravity comes after the [[force]] elements
    let mut s = PointSpringDamper::linear(
        BodyPoint::new(BodyRef::Ground, [0.0, 1.0]),
        BodyPoint::new(BodyRef::Body(1), [0.0; 2]),
        0.0,
        0.0,
        0.0,
    );
    s.stiffness = Law::Table {
        x: vec![-1.0, 0.0, 0.5],
        f: vec![-50.0, 0.0, 80.0],
    };
    s.damping = Law::Table {
        x: vec![-1.0, 1.0],
        f: vec![-4.0, 6.0],
    };
    same(&sc, 1, &s);
}

#[test]
fn rotational_contact_fluid_and_expression_tables_build_their_elements() {
    let sc = parse(
        r#"
[[force]]
type = "rotational_spring"
body_i = "b"
body_j = "a"
rest_angle_deg = 30.0
stiffness = 15.0
damping = 0.4
[[force]]
type = "rotational_spring"
body_i = "ground"
body_j = "b"
torque_angle = { x = [-1.0, 1.0], f = [-3.0, 5.0] }
[[force]]
type = "contact"
body = "a"
point = [0.2, -0.1]
radius = 0.05
wall_point = [0.0, -1.0]
wall_normal_deg = 80.0
stiffness = 1e6
damping = 0.5
friction = 0.3
slip_velocity = 0.01
[[force]]
type = "fluid"
body = "b"
fluid_density = 1000.0
volume = 0.002
width = 0.05
length = 0.4
end_face = true
[[force]]
type = "expression"
body = "a"
torque = "-3*(a.phi - b.phi) - 0.5*a.omega + sin(t)"
[[force]]
type = "expression"
body_i = "ground"
point_i = [0.0, 2.0]
body_j = "b"
point_j = [0.1, 0.0]
force = "10*(length - 1) + 2*length_rate"
[[force]]
type = "expression"
body = "b"
point = [0.0, 0.1]
fx = "-b.vx"
fy = "a.y"
"#,
    )
    .unwrap();
    same(
        &sc,
        0,
        &RotationalSpringDamper::linear(
            BodyRef::Body(1),
            BodyRef::Body(0),
            30f64.to_radians(),
            15.0,
            0.4,
        ),
    );
    let mut r = RotationalSpringDamper::linear(BodyRef::Ground, BodyRef::Body(1), 0.0, 0.0, 0.0);
    r.stiffness = Law::Table {
        x: vec![-1.0, 1.0],
        f: vec![-3.0, 5.0],
    };
    same(&sc, 1, &r);
    let n = [80f64.to_radians().cos(), 80f64.to_radians().sin()];
    same(
        &sc,
        2,
        &HalfPlaneContact::new(
            0,
            [0.2, -0.1],
            0.05,
            [0.0, -1.0],
            n,
            ContactLaw {
                stiffness: 1e6,
                damping: 0.5,
                friction: 0.3,
                slip_velocity: 0.01,
            },
        ),
    );
    same(
        &sc,
        3,
        &Buoyancy {
            fluid_density: 1000.0,
            gravity: 9.81,
            bodies: vec![(1, 0.002)],
        },
    );
    same(
        &sc,
        4,
        &Drag {
            body: 1,
            width: 0.05,
            length: 0.4,
            fluid_density: 1000.0,
            c_transverse: 1.2,
            c_skin: 0.02,
            c_end: 1.0,
            end_face: true,
        },
    );
    let e = ExpressionLoadBuilder::new("x", &[("a", 0), ("b", 1)])
        .torque("a", "-3*(a.phi - b.phi) - 0.5*a.omega + sin(t)")
        .unwrap()
        .build();
    same(&sc, 5, &e);
    let e = ExpressionLoadBuilder::new("x", &[("b", 1)])
        .line_force(
            &LinePoint {
                body: None,
                point: [0.0, 2.0],
            },
            &LinePoint {
                body: Some("b".into()),
                point: [0.1, 0.0],
            },
            "10*(length - 1) + 2*length_rate",
        )
        .unwrap()
        .build();
    same(&sc, 6, &e);
    let e = ExpressionLoadBuilder::new("x", &[("a", 0), ("b", 1)])
        .force("b", [0.0, 0.1], "-b.vx", "a.y")
        .unwrap()
        .build();
    same(&sc, 7, &e);
    assert_eq!(sc.system.forces().len(), 9); // and gravity
}

#[test]
fn bad_force_tables_name_file_key_and_value() {
    let cases: &[(&str, &[&str])] = &[
        ("type = \"sprung\"\nbody = \"a\"", &["force[0].type", "sprung", "spring"]),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"c\"\nstiffness = 1.0",
            &["force[0].body_j", "'c'"],
        ),
        ("type = \"spring\"\nbody_i = \"a\"", &["force[0].body_j", "missing"]),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"b\"\nforce_deflection = { x = [0.0, 1.0, 2.0], f = [0.0, 5.0, 4.0] }",
            &["force[0].force_deflection.f[2]", "4", "non-decreasing"],
        ),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"b\"\nforce_velocity = { x = [0.0, 0.0], f = [0.0, 1.0] }",
            &["force[0].force_velocity.x[1]", "increase"],
        ),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"b\"\nstiffness = 1.0\nforce_deflection = { x = [0.0, 1.0], f = [0.0, 1.0] }",
            &["force[0].force_deflection", "not both"],
        ),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"b\"\nstiffness = -3.0",
            &["force[0].stiffness", "-3", ">= 0"],
        ),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"b\"\nfree_length = -0.5",
            &["force[0].free_length", "-0.5"],
        ),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"a\"",
            &["force[0].body_j", "two different bodies"],
        ),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"b\"\npoint_j = [nan, 0.0]",
            &["force[0].point_j", "NaN"],
        ),
        (
            "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"b\"\nradius = 0.1",
            &["force[0].radius", "not a key of a spring"],
        ),
        (
            "type = \"rotational_spring\"\nbody_i = \"a\"\nbody_j = \"ground\"\ntorque_angle = { x = [0.0, 1.0], f = [0.0, -1.0] }",
            &["force[0].torque_angle.f[1]", "-1"],
        ),
        (
            "type = \"contact\"\nbody = \"a\"\nstiffness = 1e5",
            &["force[0].wall_normal", "missing"],
        ),
        (
            "type = \"contact\"\nbody = \"a\"\nstiffness = 1e5\nwall_normal = [0.0, 0.0]",
            &["force[0].wall_normal", "non-zero"],
        ),
        (
            "type = \"contact\"\nbody = \"a\"\nstiffness = 1e5\nwall_normal_deg = 90.0\nradius = -1.0",
            &["force[0].radius", "-1", ">= 0"],
        ),
        (
            "type = \"contact\"\nbody = \"ground\"\nstiffness = 1e5\nwall_normal_deg = 90.0",
            &["force[0].body", "ground"],
        ),
        ("type = \"fluid\"\nbody = \"a\"\nfluid_density = 1000.0", &["force[0].volume", "missing"]),
        (
            "type = \"fluid\"\nbody = \"a\"\nfluid_density = 1000.0\nwidth = 0.1",
            &["force[0].length", "missing"],
        ),
        (
            "type = \"fluid\"\nbody = \"a\"\nfluid_density = 1000.0\nvolume = -1.0",
            &["force[0].volume", "-1"],
        ),
        (
            "type = \"torque\"\nbody = \"a\"\ntorque = \"2*a.phi\"",
            &["force[0].torque", "type = \"expression\""],
        ),
        (
            "type = \"expression\"\nbody = \"a\"\ntorque = \"2*a.phii\"",
            &["force[0].torque", "a.phii"],
        ),
        (
            "type = \"expression\"\nbody = \"a\"\ntorque = \"2*c.phi\"",
            &["force[0].torque", "c.phi"],
        ),
        (
            "type = \"expression\"\nbody = \"a\"\ntorque = 2.0",
            &["force[0].torque", "expression string"],
        ),
        (
            "type = \"expression\"\nbody = \"a\"\ntorque = \"1\"\nfx = \"1\"",
            &["force[0].fx", "not a key"],
        ),
    ];
    for (table, needles) in cases {
        let e = parse(&format!("[[force]]\n{table}\n"))
            .expect_err(table)
            .to_string();
        assert!(e.starts_with("f.toml: "), "{e}");
        for n in *needles {
            assert!(e.contains(n), "{table}\n→ {e}\nlacks '{n}'");
        }
    }
}

/// Every `[[joint]]`/`[[force]]` example of docs/scenarios.md builds, and
/// the complete example there is the shipped spring pendulum's model.
#[test]
fn examples_of_the_scenario_reference_build() {
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/scenarios.md")).unwrap();
    let blocks: Vec<&str> = doc
        .split("```toml\n")
        .skip(1)
        .map(|b| b.split("```").next().unwrap())
        .collect();
    let mut head = String::from("gravity = [0.0, -9.81]\n[time]\nend = 1.0\n");
    for (i, b) in [
        "a", "b", "bob", "link1", "link2", "wheel", "float", "crank", "coupler", "slider",
    ]
    .iter()
    .enumerate()
    {
        head +=
            &format!("[[body]]\nname = \"{b}\"\nmass = 1.0\ninertia = 0.1\nx = {i}.0\ny = 0.5\n");
    }
    head += "[initial]\nconsistent = false\n";
    let mut n = 0;
    for b in &blocks {
        if b.starts_with("[[force]]") || b.starts_with("[[joint]]") {
            scenario::parse(&format!("{head}{b}"), "doc.toml", "doc", &[])
                .unwrap_or_else(|e| panic!("{b}\n→ {e}"));
            n += 1;
        }
    }
    assert_eq!(n, 10, "examples found");
    let complete = blocks
        .iter()
        .find(|b| b.starts_with("name = \"spring_pendulum\""))
        .unwrap();
    let doc_sc = scenario::parse(complete, "doc.toml", "doc", &[]).unwrap();
    let shipped = scenario::load(
        std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenarios/spring_pendulum.toml"
        )),
        &[],
    )
    .unwrap();
    assert_eq!(doc_sc.q0, shipped.q0);
    let q = [0.3, -0.9, 0.2];
    let mut g1 = vec![0.0; 3];
    let mut g2 = vec![0.0; 3];
    doc_sc
        .system
        .forces_into(0.0, &q, &[0.1, 0.2, 0.3], &mut g1);
    shipped
        .system
        .forces_into(0.0, &q, &[0.1, 0.2, 0.3], &mut g2);
    assert_eq!(g1, g2);
}

/// A uniform disc on a 20° incline through a scenario `contact` with
/// friction (μ = 0.5 > tan θ / 3: rolling): the centre accelerates at
/// `(2/3) g sin θ` and turns at `ω = v / R` (rolling without slip), by an
/// explicit and by the implicit method (which uses the contact's
/// Jacobians).
#[test]
fn disc_rolls_down_an_incline_at_two_thirds_g_sin_theta() {
    let (m, r, th, g, kh) = (1.0f64, 0.1f64, 20f64.to_radians(), 9.81, 1e8);
    let n = [-th.sin(), th.cos()];
    let t = [-n[1], n[0]]; // downhill
    let delta0 = (m * g * th.cos() / kh).powf(2.0 / 3.0); // static penetration
    let p0 = [(r - delta0) * n[0], (r - delta0) * n[1]];
    let text = format!(
        r#"
gravity = [0.0, -9.81]
[[body]]
name = "disc"
mass = {m}
inertia = {inertia}
x = {x}
y = {y}
[[force]]
type = "contact"
body = "disc"
radius = {r}
wall_normal_deg = {deg}
stiffness = {kh}
damping = 2.0
friction = 0.5
slip_velocity = 1e-4
[time]
end = 1.0
[output]
dt = 0.1
"#,
        inertia = 0.5 * m * r * r,
        x = p0[0],
        y = p0[1],
        deg = 90.0 + 20.0,
    );
    for set in [
        vec![
            "integrator.method=ode45",
            "integrator.rtol=1e-8",
            "integrator.atol=1e-10",
        ],
        vec!["integrator.method=genalpha", "integrator.step=2e-4"],
    ] {
        let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
        let sc = scenario::parse(&text, "disc.toml", "disc", &set).unwrap();
        let (traj, summary) =
            mbsolve::simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
        assert_eq!(
            summary.status, "completed",
            "{set:?}: {:?}",
            summary.message
        );
        let tf = *traj.t.last().unwrap();
        let q = traj.q.last().unwrap();
        let s = (q[0] - p0[0]) * t[0] + (q[1] - p0[1]) * t[1];
        let want = 0.5 * (2.0 / 3.0) * g * th.sin() * tf * tf;
        eprintln!("{set:?}: s = {s}, want {want}, rolled {}", q[2] * r);
        assert!((s - want).abs() < 1e-4 * want, "{set:?}: s = {s} vs {want}");
        // rolling without slip: rolling down-left (along t) it turns counter-clockwise by s / R
        assert!(
            (q[2] * r - s).abs() < 1e-4 * want,
            "{set:?}: R φ = {} vs s = {s}",
            q[2] * r
        );
        // it stays on the incline: the penetration stays near the static one
        let gap = (q[0] * n[0] + q[1] * n[1]) - (r - delta0);
        assert!(gap.abs() < 0.5 * delta0, "{set:?}: gap {gap}");
    }
}

/// A body on a scenario `rotational_spring` to the ground (stiffness as a
/// table on a straight line, linear damping) is the damped oscillator
/// `I φ̈ + c φ̇ + k (φ − φ0) = 0`: closed form at every output.
#[test]
fn rotational_spring_to_ground_is_a_damped_oscillator() {
    let (inertia, k, c, rest, a0) = (0.02f64, 3.0f64, 0.01f64, 0.2f64, 0.5f64);
    let text = format!(
        r#"
[[body]]
name = "wheel"
mass = 1.0
inertia = {inertia}
phi = {phi}
[[force]]
type = "rotational_spring"
body_i = "ground"
body_j = "wheel"
rest_angle = {rest}
torque_angle = {{ x = [-1.0, 2.0], f = [{f0}, {f1}] }}
damping = {c}
[integrator]
method = "ode45"
rtol = 1e-10
atol = 1e-12
[time]
end = 2.0
[output]
dt = 0.05
"#,
        phi = rest + a0,
        f0 = -k,
        f1 = 2.0 * k,
    );
    let sc = scenario::parse(&text, "osc.toml", "osc", &[]).unwrap();
    let (traj, _) =
        mbsolve::simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    let w = (k / inertia).sqrt();
    let zeta = c / (2.0 * (k * inertia).sqrt());
    let wd = w * (1.0 - zeta * zeta).sqrt();
    let mut worst: f64 = 0.0;
    for (t, q) in traj.t.iter().zip(&traj.q) {
        let want = rest
            + (-zeta * w * t).exp() * (a0 * (wd * t).cos() + zeta * w * a0 / wd * (wd * t).sin());
        worst = worst.max((q[2] - want).abs());
    }
    assert!(
        traj.t.len() == 41 && worst < 1e-7,
        "largest angle error {worst}"
    );
}
