//! `[parameters]`: named values and expressions of them in numeric fields
//! and inside force expressions, overridden by `--set parameters.NAME=` or
//! the bare name, and the errors of unknown, cyclic and misplaced ones.

use crate::common::setup::docs_example;
use mbsolve::scenario;
use mbsolve::simulation::simulate;
use std::path::Path;

fn shipped(name: &str, set: &[&str]) -> scenario::Scenario {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    scenario::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenarios")
            .join(name),
        &set,
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn err(text: &str, set: &[&str]) -> String {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    scenario::parse(text, "p.toml", "p", &set)
        .map(|_| ())
        .expect_err("an error")
        .to_string()
}

/// The quarter car written with parameters (free lengths derived from the
/// masses and rates) runs exactly as the one written with numbers.
#[test]
fn quarter_car_with_parameters_is_the_quarter_car() {
    let set = ["time.end=0.5"];
    let a = shipped("quarter_car.toml", &set);
    let b = shipped("quarter_car_parameters.toml", &set);
    assert_eq!(a.q0, b.q0);
    assert_eq!(a.qd0, b.qd0);
    let (ta, sa) = simulate(&a.system, &a.q0, &a.qd0, &a.run, &mut []).unwrap();
    let (tb, sb) = simulate(&b.system, &b.q0, &b.qd0, &b.run, &mut []).unwrap();
    assert_eq!(sa.status, "completed");
    assert_eq!(sa.steps, sb.steps);
    assert_eq!(ta.t, tb.t);
    assert_eq!(ta.q, tb.q);
    assert_eq!(ta.qd, tb.qd);
}

/// Overriding a parameter changes every field that uses it, as setting
/// those fields does; the bare name is the parameter.
#[test]
fn overriding_a_parameter_is_overriding_its_fields() {
    let p = shipped(
        "quarter_car_parameters.toml",
        &["parameters.k_s=2e4", "c_s=1500"],
    );
    let q = shipped(
        "quarter_car_parameters.toml",
        &[
            "force[1].stiffness=2e4",
            "force[1].damping=1500",
            // the derived free length follows the parameter
            &format!("force[1].free_length={:e}", 0.35 + 250.0 * 9.81 / 2e4),
        ],
    );
    let x = [0.0, -0.02, 0.0, 0.0, 0.43, 0.0, 0.0, 1.2, 0.0];
    let v = [0.0, 0.1, 0.0, 0.0, -0.2, 0.0, 0.0, 0.3, 0.0];
    let (mut g1, mut g2) = (vec![0.0; 9], vec![0.0; 9]);
    p.system.forces_into(0.1, &x, &v, &mut g1);
    q.system.forces_into(0.1, &x, &v, &mut g2);
    assert_eq!(g1, g2);
    // and differs from the file's values (the override did something)
    let o = shipped("quarter_car_parameters.toml", &[]);
    let mut g0 = vec![0.0; 9];
    o.system.forces_into(0.1, &x, &v, &mut g0);
    assert_ne!(g0, g1);
}

const PENDULUM: &str = r#"
gravity = [0.0, "-g"]
[parameters]
g = 9.81
l = 0.5
k = "2 * c"
c = 0.25
n = "2 + 1"
[[body]]
name = "bob"
mass = 1.0
inertia = "l^2 / 12"
y = "-l/2"
[[joint]]
type = "revolute"
body_i = "ground"
point_i = [0.0, 0.0]
body_j = "bob"
point_j = [0.0, "l/2"]
[[force]]
type = "expression"
name = "spring"
body = "bob"
torque = "-k*bob.phi - c*max(bob.omega, -k)"
[time]
end = 0.1
[output]
dt = "0.1 / n"
"#;

/// Parameters inside a force expression are their values: the torque of
/// `-k*bob.phi - c*max(bob.omega, -k)` with k = 0.5, c = 0.25 (k defined
/// through c, after it in the file) is the closed form; an integer
/// expression is taken by an integer-valued key.
#[test]
fn parameters_inside_expressions_and_in_order_of_use() {
    let sc = scenario::parse(PENDULUM, "p.toml", "p", &[]).unwrap();
    let (phi, omega): (f64, f64) = (0.3, 0.7);
    let q = [0.25 * phi.sin(), -0.25 * phi.cos(), phi];
    let qd = [0.0, 0.0, omega];
    let mut g = vec![0.0; 3];
    sc.system.forces_into(0.0, &q, &qd, &mut g);
    let want = -0.5 * phi - 0.25 * f64::max(omega, -0.5);
    assert!((g[2] - want).abs() < 1e-15, "{} vs {want}", g[2]);
    assert_eq!(g[1], -9.81);
    assert_eq!(sc.system.bodies()[0].inertia, 0.25 / 12.0);
    let (traj, _) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(traj.t.len(), 4, "dt = 0.1/3: {:?}", traj.t);
}

#[test]
fn bad_parameters_are_named() {
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "k = \"2 * c\"",
            "k = \"2 * cc\"",
            &["p.toml", "parameters.k", "unknown parameter 'cc'"],
        ),
        (
            "c = 0.25",
            "c = \"k / 2\"",
            &["parameters.", "cyclic definition", "c → k → c"],
        ),
        ("n = \"2 + 1\"", "t = 1.0", &["parameters.t", "reserved"]),
        (
            "inertia = \"l^2 / 12\"",
            "inertia = \"L^2 / 12\"",
            &[
                "body[0].inertia",
                "unknown parameter 'L'",
                "parameters: c, g, k, l, n",
            ],
        ),
    ];
    for (from, to, needles) in cases {
        assert!(PENDULUM.contains(from));
        let e = err(&PENDULUM.replacen(from, to, 1), &[]);
        for n in *needles {
            assert!(e.contains(n), "{to} → {e}\nlacks '{n}'");
        }
    }
    // overrides: an unknown parameter is refused (never added), a cycle
    // made by two overrides names them
    let e = err(PENDULUM, &["parameters.kk=1"]);
    assert!(
        e.contains("no parameter 'kk'") && e.contains("c, g, k, l, n"),
        "{e}"
    );
    let e = err(PENDULUM, &["c=\"k\""]);
    assert!(
        e.contains("--set parameters.c") && e.contains("cyclic"),
        "{e}"
    );
    // a value from a parameter that a field refuses names the field and
    // the expression
    let e = err(PENDULUM, &["l=0"]);
    assert!(
        e.contains("body[0].inertia") && e.contains("(the value of \"l^2 / 12\")"),
        "{e}"
    );
}

/// The parameters example of docs/scenarios.md parses and runs.
#[test]
fn the_documented_example_runs() {
    let block = &docs_example("parameters example");
    let sc = scenario::parse(block, "doc.toml", "doc", &[]).unwrap();
    let (_, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "completed");
}
