//! Names everywhere: output columns named by body and coordinate, elements
//! addressed by name in overrides, every body of a chain nameable in
//! expressions and under each of its aliases, bad names listing the valid
//! ones.

use mbsolve::output::{columns, find_column};
use mbsolve::scenario::{overrides, parse, parse_with, Scenario};
use mbsolve::simulation::simulate;

/// A chain of three links hanging from a pivot, a free block, and two
/// forces: an expression torque on a chain link (its text `TORQUE`) and a
/// damper on the block.
fn model(torque: &str) -> String {
    format!(
        r#"
gravity = [0.0, -9.81]

[[body]]
name = "block"
mass = 2.0
inertia = 0.1
x = 1.0
y = -0.5
vx = 0.3

[[chain]]
name = "arm"
links = 3
length = 0.4
mass = 0.5
angle_deg = 150.0
pivot = true

[[force]]
type = "expression"
name = "motor"
body = "arm.link[2]"
torque = "{torque}"

[[force]]
type = "spring"
name = "shock"
body_i = "ground"
point_i = [1.0, 0.0]
body_j = "block"
point_j = [0.0, 0.0]
stiffness = 200.0
damping = 3.0
free_length = 0.4

[integrator]
method = "ode45"
rtol = 1e-9
atol = 1e-11

[time]
end = 0.3

[output]
dt = 0.01
quantities = ["velocities", "accelerations"]
"#
    )
}

fn load(text: &str, sets: &[&str]) -> Scenario {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    parse(text, "names.toml", "names", &sets).unwrap_or_else(|e| panic!("{e}"))
}

fn load_err(text: &str, sets: &[&str]) -> String {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    match parse(text, "names.toml", "names", &sets) {
        Ok(_) => panic!("accepted: {sets:?}"),
        Err(e) => e.to_string(),
    }
}

/// The positions of a run, bit for bit.
fn positions(sc: &Scenario) -> Vec<Vec<u64>> {
    let (traj, summary) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(summary.status, "completed");
    traj.q
        .iter()
        .map(|q| q.iter().map(|v| v.to_bits()).collect())
        .collect()
}

#[test]
fn columns_carry_the_names_of_bodies_and_chain_links_with_units() {
    let sc = load(&model("-2*arm.link[2].omega"), &[]);
    let cols = columns(&sc.system, &sc.run.outputs, &sc.sensors);
    let names: Vec<&str> = cols.iter().map(|c| c.name.as_str()).collect();
    let unit = |n: &str| cols.iter().find(|c| c.name == n).unwrap().unit.to_string();
    // bodies in order: the [[body]]s, then the chain's links 1-based
    assert_eq!(
        &names[..8],
        [
            "t",
            "block.x",
            "block.y",
            "block.phi",
            "arm.link[1].x",
            "arm.link[1].y",
            "arm.link[1].phi",
            "arm.link[2].x"
        ]
    );
    assert_eq!(names[12], "arm.link[3].phi");
    assert_eq!(names[13], "constraint_norm");
    for (n, u) in [
        ("arm.link[3].phi", "rad"),
        ("block.y", "m"),
        ("arm.link[2].omega", "rad/s"),
        ("block.vx", "m/s"),
        ("arm.link[1].alpha", "rad/s^2"),
        ("block.ay", "m/s^2"),
    ] {
        assert_eq!(unit(n), u, "{n}");
    }
    // the positional names of earlier versions find the same columns
    for (old, new) in [
        ("x1", "block.x"),
        ("phi4", "arm.link[3].phi"),
        ("vy2", "arm.link[1].vy"),
        ("omega3", "arm.link[2].omega"),
        ("alpha4", "arm.link[3].alpha"),
    ] {
        assert_eq!(
            find_column(&names, old).map(|k| names[k]),
            Some(new),
            "{old}"
        );
    }
    // the shipped falling rod's segments by the names expressions use
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/falling_rod.toml");
    let rod = mbsolve::scenario::load(std::path::Path::new(path), &[]).unwrap();
    let rc = columns(&rod.system, &rod.run.outputs, &rod.sensors);
    assert_eq!(rc[1].name, "rod.segment[1].x");
    let n = rod.system.bodies().len();
    assert_eq!(rc[3 * n].name, format!("rod.segment[{n}].phi"));
    // no fifth body, no such coordinate
    for bad in ["x5", "x0", "theta1", "block.theta"] {
        assert_eq!(find_column(&names, bad), None, "{bad}");
    }
}

#[test]
fn an_element_by_name_is_the_element_by_index() {
    let text = model("-2*arm.link[2].omega");
    let by_name = load(
        &text,
        &[
            "force[shock].damping=40",
            "force[motor].torque=\"-arm.link[2].phi\"",
        ],
    );
    let by_index = load(
        &text,
        &[
            "force[1].damping=40",
            "force[0].torque=\"-arm.link[2].phi\"",
        ],
    );
    let untouched = load(&text, &[]);
    let a = positions(&by_name);
    assert_eq!(a, positions(&by_index));
    // the override changed something
    assert_ne!(a, positions(&untouched));
    // a component by name too
    let longer = load(&text, &["chain[arm].links=4"]);
    assert_eq!(longer.system.bodies().len(), 5);
    // --unset by name: the damper's damping back to its default 0
    let (unset, none) = (vec!["force[shock].damping".to_string()], Vec::new());
    let removed = parse_with(&text, "names.toml", "names", &overrides(&unset, &none)).unwrap();
    assert_eq!(
        positions(&removed),
        positions(&load(&text, &["force[1].damping=0"]))
    );
}

#[test]
fn expressions_name_every_link_and_every_alias_of_a_body() {
    // arm.last is arm.link[3]; arm.first is arm.link[1]
    let indexed = load(
        &model("-4*(arm.link[2].phi - arm.link[1].phi) + 2*(arm.link[3].phi - arm.link[2].phi)"),
        &[],
    );
    let aliased = load(
        &model("-4*(arm.link[2].phi - arm.first.phi) + 2*(arm.last.phi - arm.link[2].phi)"),
        &[],
    );
    // both names of one body in the same text
    let both = load(
        &model("-4*(arm.link[2].phi - arm.link[1].phi) + 2*(arm.last.phi - arm.link[2].phi) + 0*arm.first.phi + 0*arm.link[3].omega"),
        &[],
    );
    let a = positions(&indexed);
    assert_eq!(a, positions(&aliased));
    assert_eq!(a, positions(&both));
    // the torque acts: the run differs from one without it
    assert_ne!(a, positions(&load(&model("0"), &[])));
}

#[test]
fn bad_names_list_the_valid_ones() {
    let text = model("-2*arm.link[2].omega");
    let e = load_err(&text, &["force[damper].damping=1"]);
    assert!(e.contains("no [[force]] named 'damper'"), "{e}");
    assert!(e.contains("names: motor, shock"), "{e}");
    let e = load_err(&text, &["chain[rope].links=4"]);
    assert!(e.contains("no [[chain]] named 'rope' (names: arm)"), "{e}");
    let e = load_err(&model("-arm.link[4].phi"), &[]);
    assert!(e.contains("arm.link[4]"), "{e}");
    assert!(e.contains("arm.link[k] with k = 1 .. 3"), "{e}");
    let e = load_err(&model("-hand.phi"), &[]);
    assert!(e.contains("no body named 'hand'"), "{e}");
    assert!(e.contains("arm.link[1..3]"), "{e}");
    assert!(e.contains("block"), "{e}");
    let e = load_err(&model("-arm.link[2].theta"), &[]);
    assert!(e.contains("arm.link[2].theta"), "{e}");
    assert!(e.contains("arm.link[2].omega"), "{e}");
}

/// Two joints or two forces of one name would make `force[name]` address
/// only the first and give two output columns one name: an error at the
/// second, naming the first.
#[test]
fn duplicate_joint_and_force_names_are_errors() {
    let text = model("0").replace("name = \"shock\"", "name = \"motor\"");
    let e = load_err(&text, &[]);
    assert!(e.contains("force[1].name"), "{e}");
    assert!(
        e.contains("duplicate force name 'motor': force[0] has it"),
        "{e}"
    );
    let joint = |name: &str, y: f64| {
        format!(
            "\n[[joint]]\ntype = \"revolute\"\nname = \"{name}\"\nbody_i = \"ground\"\n\
             point_i = [1.0, {y}]\nbody_j = \"block\"\npoint_j = [0.0, 0.0]\n"
        )
    };
    let two = format!("{}{}{}", model("0"), joint("pin", -0.5), joint("pin", -0.5));
    let e = load_err(&two, &[]);
    assert!(e.contains("joint[1].name"), "{e}");
    assert!(
        e.contains("duplicate joint name 'pin': joint[0] has it"),
        "{e}"
    );
    // distinct names load
    let two = format!("{}{}", model("0"), joint("pin", -0.5));
    load(&two, &[]);
}
