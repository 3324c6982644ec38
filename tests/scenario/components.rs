//! Rods (`[[rod]]`) and chains (`[[chain]]`) as
//! scenario components — against the same systems built independently
//! (the library builders, `[[body]]`/`[[joint]]`/`[[force]]`), the shipped
//! two-rod assembly through generalized-α at N = 100 per rod, the generated
//! kernels, and bad input naming file, key and value.

use crate::common::cli::mbsolve;
use mbsolve::builders::{add_named_rod, n_link_pendulum, RodParams};
use mbsolve::constraints::Revolute;
use mbsolve::forces::{Law, PointSpringDamper};
use mbsolve::model::{BodyPoint, BodyRef, SystemBuilder};
use mbsolve::scenario;
use mbsolve::simulation::{simulate, Trajectory};
use std::path::Path;

fn shipped(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// Largest difference of positions and velocities of two trajectories on
/// the same output times.
fn max_difference(a: &Trajectory, b: &Trajectory) -> f64 {
    assert_eq!(a.t, b.t);
    let mut worst: f64 = 0.0;
    for (qa, qb) in a.q.iter().zip(&b.q).chain(a.qd.iter().zip(&b.qd)) {
        for (x, y) in qa.iter().zip(qb) {
            worst = worst.max((x - y).abs());
        }
    }
    worst
}

/// A CSV written by the CLI: header and rows.
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (head, rows)
}

/// Body-frame point `s` of body `b` (0-based) in row `r` (columns
/// `t, B.x, B.y, B.phi, …`): `r_b + A(φ_b) s`.
fn point(r: &[f64], b: usize, s: [f64; 2]) -> [f64; 2] {
    let (x, y, phi) = (r[1 + 3 * b], r[2 + 3 * b], r[3 + 3 * b]);
    let (sn, c) = phi.sin_cos();
    [x + c * s[0] - sn * s[1], y + sn * s[0] + c * s[1]]
}

/// The shipped two-rod assembly at N = 100 per rod (set by `--set` on the
/// `[[rod]]` elements, one by name, one by index) runs through generalized-α and completes; from the
/// CLI's own CSV: the pivot stays at the origin and the pin joins rod1's
/// last end to rod2's first end (‖Φ‖-level), the assembly really moved, and
/// the energy balance of the undamped system holds to 1e-3 of the largest
/// kinetic energy (the remainder is generalized-α's numerical dissipation).
#[test]
fn two_rods_at_100_segments_each_run_through_generalized_alpha() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = mbsolve(&[
        "run",
        &shipped("two_rods.toml"),
        "--set",
        "rod[rod1].segments=100",
        "--set",
        "rod[1].segments=100",
        "--out",
        out,
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = std::fs::read_to_string(dir.path().join("two_rods.summary.json")).unwrap();
    assert!(summary.contains("\"status\": \"completed\""), "{summary}");
    assert!(summary.contains("\"method\": \"genalpha\""), "{summary}");
    let (head, rows) = read_csv(&dir.path().join("two_rods.csv"));
    // 200 bodies, named by rod and segment (1-based from the first end)
    assert_eq!(head[1], "rod1.segment[1].x");
    assert_eq!(head[1 + 3 * 99 + 2], "rod1.segment[100].phi");
    assert_eq!(head[1 + 3 * 199], "rod2.segment[100].x");
    assert_eq!(rows.len(), 101);
    let half = 0.5 * 0.5 / 100.0; // l_s / 2
    let col = |n: &str| head.iter().position(|h| h == n).unwrap();
    let (ke, err) = (col("kinetic_energy"), col("energy_balance_error"));
    let mut worst_pin: f64 = 0.0;
    let mut worst_pivot: f64 = 0.0;
    let mut ke_max: f64 = 0.0;
    let mut balance: f64 = 0.0;
    for r in &rows {
        let a = point(r, 99, [0.0, half]); // rod1.last, last end
        let b = point(r, 100, [0.0, -half]); // rod2.first, first end
        worst_pin = worst_pin.max((a[0] - b[0]).hypot(a[1] - b[1]));
        let p = point(r, 0, [0.0, -half]); // rod1.first, first end
        worst_pivot = worst_pivot.max(p[0].hypot(p[1]));
        ke_max = ke_max.max(r[ke]);
        balance = balance.max(r[err].abs());
    }
    // the tip of rod2 swung down: the assembly moved
    let tip = point(rows.last().unwrap(), 199, [0.0, half]);
    eprintln!(
        "pin {worst_pin:.3e} m, pivot {worst_pivot:.3e} m, max T {ke_max:.4} J, \
         balance {balance:.3e} J, tip {tip:?}"
    );
    assert!(worst_pin < 1e-6, "pin gap {worst_pin}");
    assert!(worst_pivot < 1e-6, "pivot gap {worst_pivot}");
    assert!(ke_max > 0.05, "largest kinetic energy {ke_max}");
    assert!(tip[1] < -0.55, "rod2's tip did not swing down: {tip:?}");
    assert!(balance < 1e-3 * ke_max, "energy balance error {balance}");
}

/// `scenarios/two_rods.toml` equals the same system built through the
/// library (two `add_named_rod`, two `Revolute`, a `PointSpringDamper`,
/// gravity) to 1e-12, at N = 12 and 7 segments, with generalized-α.
#[test]
fn two_rods_scenario_equals_the_library_assembly() {
    let text = std::fs::read_to_string(shipped("two_rods.toml")).unwrap();
    let (n1, n2) = (12usize, 7usize);
    let set = strings(&[
        &format!("rod[0].segments={n1}"),
        &format!("rod[1].segments={n2}"),
        "time.end=0.3",
    ]);
    let sc = scenario::parse(&text, "two_rods.toml", "two_rods", &set).unwrap();
    let rod = |n: usize| RodParams {
        n_segments: n,
        length: 0.5,
        width: 0.01,
        density: 7850.0,
        youngs_modulus: 2.0e8,
        damping_time: 0.0,
        initial_velocity: [0.0, 0.0],
        fluid: false,
        contact: false,
        gravity: 9.81,
        ..RodParams::problem_b(n)
    };
    let mut b = SystemBuilder::new();
    let p1 = RodParams {
        tilt: 180f64.to_radians(),
        ..rod(n1)
    };
    let p2 = RodParams {
        tilt: 90f64.to_radians(),
        ..rod(n2)
    };
    let r1 = add_named_rod(&mut b, &p1, "rod1", Some([0.0, 0.0])).unwrap();
    let r2 = add_named_rod(&mut b, &p2, "rod2", Some([0.0, -0.5])).unwrap();
    let (h1, h2) = (0.25 / n1 as f64, 0.25 / n2 as f64);
    b.add_constraint(Revolute::new(
        "pivot",
        BodyRef::Ground,
        [0.0, 0.0],
        BodyRef::Body(r1.bodies[0]),
        [0.0, -h1],
    ));
    b.add_constraint(Revolute::new(
        "pin",
        BodyRef::Body(r1.bodies[n1 - 1]),
        [0.0, h1],
        BodyRef::Body(r2.bodies[0]),
        [0.0, -h2],
    ));
    b.add_force(PointSpringDamper {
        i: BodyPoint::new(BodyRef::Body(r1.bodies[0]), [0.0, -h1]),
        j: BodyPoint::new(BodyRef::Body(r2.bodies[n2 - 1]), [0.0, h2]),
        free_length: std::f64::consts::FRAC_1_SQRT_2,
        stiffness: Law::Linear(200.0),
        damping: Law::Linear(0.0),
        preload: 0.0,
        actuator: None,
    });
    b.gravity([0.0, -9.81]);
    let sys = b.build().unwrap();
    assert_eq!(sys.evaluation_name(), sc.system.evaluation_name());
    let (mine, s1) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    let (q0, qd0) = sys.initial_state();
    assert_eq!(q0, sc.q0, "the same initial positions");
    let (lib, s2) = simulate(&sys, &q0, &qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s1.status, "completed");
    assert_eq!(s2.status, "completed");
    let d = max_difference(&mine, &lib);
    assert!(d <= 1e-12, "scenario vs library: {d}");
    // and it moved
    let last = mine.q.last().unwrap();
    assert!((last[3 * (n1 + n2) - 2] - sc.q0[3 * (n1 + n2) - 2]).abs() > 1e-3);
}

/// A `[[chain]]` of 3 links (pivot, torsional springs) equals the same
/// chain written out as `[[body]]`, `[[joint]]`, `[[force]]`
/// (`rotational_spring`), with rk4 and with generalized-α, to 1e-12.
#[test]
fn three_link_chain_equals_bodies_joints_and_forces() {
    let (l, m, k, c, deg) = (0.4f64, 0.5f64, 2.0f64, 0.01f64, 150.0f64);
    let run = "[initial]\nconsistent = false\n[time]\nend = 1.0\n[output]\ndt = 0.01\n";
    let chain = format!(
        "gravity = [0.0, -9.81]\n[[chain]]\nname = \"c\"\nlinks = 3\nlength = {l}\nmass = {m}\nposition = [0.0, 0.0]\n\
         angle_deg = {deg}\nstiffness = {k}\ndamping = {c}\npivot = true\n{run}"
    );
    let (sn, cs) = deg.to_radians().sin_cos();
    let e = [-sn, cs];
    let mut long = String::from("gravity = [0.0, -9.81]\n");
    for i in 0..3 {
        let a = (i as f64 + 0.5) * l;
        long += &format!(
            "[[body]]\nname = \"L{i}\"\nmass = {m}\ninertia = {}\nx = {}\ny = {}\nphi_deg = {deg}\n",
            m * l * l / 12.0,
            a * e[0],
            a * e[1]
        );
    }
    for i in 0..2 {
        long += &format!(
            "[[joint]]\ntype = \"revolute\"\nbody_i = \"L{i}\"\npoint_i = [0.0, {h}]\n\
             body_j = \"L{j}\"\npoint_j = [0.0, -{h}]\n\
             [[force]]\ntype = \"rotational_spring\"\nbody_i = \"L{i}\"\nbody_j = \"L{j}\"\n\
             stiffness = {k}\ndamping = {c}\n",
            h = 0.5 * l,
            j = i + 1
        );
    }
    long += &format!(
        "[[joint]]\ntype = \"revolute\"\nbody_i = \"ground\"\npoint_i = [0.0, 0.0]\n\
         body_j = \"L0\"\npoint_j = [0.0, -{}]\n{run}",
        0.5 * l
    );
    for method in [
        ["integrator.method=rk4", "integrator.step=1e-3"],
        ["integrator.method=genalpha", "integrator.step=1e-3"],
    ] {
        let set = strings(&method);
        let a = scenario::parse(&chain, "chain.toml", "chain", &set).unwrap();
        let b = scenario::parse(&long, "long.toml", "long", &set).unwrap();
        assert_eq!(a.q0, b.q0, "{method:?}: initial positions");
        assert!(a.system.evaluation_name().contains("generated"));
        let (ta, sa) = simulate(&a.system, &a.q0, &a.qd0, &a.run, &mut []).unwrap();
        let (tb, sb) = simulate(&b.system, &b.q0, &b.qd0, &b.run, &mut []).unwrap();
        assert_eq!(
            (sa.status.as_str(), sb.status.as_str()),
            ("completed", "completed")
        );
        let d = max_difference(&ta, &tb);
        let moved = (ta.q.last().unwrap()[2] - a.q0[2]).abs();
        eprintln!("{method:?}: difference {d:.3e}, link 1 turned {moved:.3} rad");
        assert!(d <= 1e-12, "{method:?}: chain vs bodies {d}");
        assert!(moved > 0.1, "{method:?}: the chain did not swing");
    }
}

/// A 50-link `[[chain]]` (no springs, pivot) is the library's 50-link
/// pendulum of problem D (`n_link_pendulum`, built independently with the
/// opposite body frames: φ differs by π, positions agree), uses the
/// generated kernels (the `evaluation` of `mbsolve check`), and runs.
#[test]
fn fifty_link_chain_is_the_n_link_pendulum_with_generated_kernels() {
    let (n, l, m, a) = (50usize, 0.02f64, 0.01f64, 0.3f64);
    let text = format!(
        "gravity = [0.0, -9.81]\n[[chain]]\nname = \"rope\"\nlinks = {n}\nlength = {l}\n\
         density = 1000.0\narea = {area}\nangle_deg = {deg}\npivot = true\n\
         [initial]\nconsistent = false\n[integrator]\nmethod = \"rk4\"\nstep = 1e-4\n\
         [time]\nend = 0.1\n[output]\ndt = 0.01\n",
        area = m / (1000.0 * l),
        deg = 180.0 + a.to_degrees()
    );
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("rope.toml");
    std::fs::write(&file, &text).unwrap();
    let o = mbsolve(&["check", file.to_str().unwrap()]);
    let report = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let evaluation = report
        .lines()
        .find(|l| l.starts_with("evaluation"))
        .unwrap();
    assert!(
        evaluation.contains("generated:") && !evaluation.contains("generic"),
        "{report}"
    );
    assert!(report.contains("degrees of freedom    50"), "{report}");

    let sc = scenario::parse(&text, "rope.toml", "rope", &[]).unwrap();
    let (mine, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "completed");
    let (sys, _) = n_link_pendulum(n, l, m, a, 9.81).unwrap();
    let (q0, qd0) = sys.initial_state();
    let (lib, _) = simulate(&sys, &q0, &qd0, &sc.run, &mut []).unwrap();
    let mut worst: f64 = 0.0;
    for (qa, qb) in mine.q.iter().zip(&lib.q) {
        for i in 0..n {
            worst = worst
                .max((qa[3 * i] - qb[3 * i]).abs())
                .max((qa[3 * i + 1] - qb[3 * i + 1]).abs())
                .max((qa[3 * i + 2] - qb[3 * i + 2] - std::f64::consts::PI).abs());
        }
    }
    let swing = (mine.q.last().unwrap()[3 * (n - 1)] - sc.q0[3 * (n - 1)]).abs();
    eprintln!("chain vs n-link pendulum: {worst:.3e}; tip moved {swing:.3e} m");
    assert!(worst < 1e-9, "chain vs pendulum {worst}");
    assert!(swing > 1e-3, "the chain did not move");
}

/// A 5000-link chain is a few lines of TOML: it loads with the generated
/// chain and spring kernels on its ranges.
#[test]
fn five_thousand_link_chain_loads_with_generated_kernels() {
    let text = "[[chain]]\nname = \"long\"\nlinks = 5000\nlength = 0.001\nmass = 1e-3\n\
                stiffness = 0.1\ndamping = 1e-4\npivot = true\n\
                [time]\nend = 0.001\n";
    let sc = scenario::parse(text, "long.toml", "long", &[]).unwrap();
    assert_eq!(sc.system.bodies().len(), 5000);
    assert_eq!(sc.system.constraints().len(), 5000);
    assert_eq!(sc.system.evaluation_name(), "generated:pendulum_chain");
    assert_eq!(
        sc.system.force_kernel_names(),
        vec!["generated:torsional_chain"]
    );
    assert_eq!(sc.chains[0].1.bodies.len(), 5000);
}

/// Component bodies are named `C.first`, `C.last`, `C.segment[k]`,
/// `C.link[k]` (1-based) wherever a body is named: here in
/// `initial.independent` and a `drive_coordinate`.
#[test]
fn component_bodies_are_addressable_by_name() {
    let text = "[[chain]]\nname = \"c\"\nlinks = 4\nlength = 1.0\nmass = 1.0\n\
                [[joint]]\ntype = \"drive_coordinate\"\nbody = \"c.link[3]\"\ncoordinate = \"x\"\n\
                motion = 0.0\n\
                [[joint]]\ntype = \"drive_coordinate\"\nbody = \"c.last\"\ncoordinate = \"phi\"\n\
                motion = 0.0\n\
                [initial]\nindependent = [\"c.first.y\"]\n[time]\nend = 0.1\n";
    let sc = scenario::parse(text, "c.toml", "c", &[]).unwrap();
    let names: Vec<String> = sc.system.constraints().iter().map(|c| c.name()).collect();
    for (k, n) in names[..3].iter().enumerate() {
        assert!(n.contains(&format!("'c.joint[{}]'", k + 1)), "{names:?}");
    }
    assert_eq!(sc.system.bodies()[2].name, "c.link[3]");
    // the drives (Φ = q_k − 0) act on link 3's x (coordinate 6) and link
    // 4's φ (coordinate 11)
    let rows = sc.system.n_constraints();
    let mut phi = vec![0.0; rows];
    let mut q = sc.q0.clone();
    q[6] = 0.25;
    q[11] = 0.5;
    sc.system.phi(&q, 0.0, &mut phi);
    assert_eq!([phi[rows - 2], phi[rows - 1]], [0.25, 0.5]);
}

/// Runs `args`; asserts exit status 2, no panic, and every needle in the
/// message (the CLI bad-input style of tests/cli/bad_input.rs).
fn rejects(args: &[&str], needles: &[&str]) {
    let o = mbsolve(args);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    assert!(!e.contains("panicked"), "{args:?}: {e}");
    for n in needles {
        assert!(e.contains(n), "{args:?}: the error lacks '{n}': {e}");
    }
}

/// Bad component input is an error naming the file (or the override), the
/// key and the value: a segment or link that does not exist, an unknown
/// rod, duplicate names, an end point on a plain body, a missing name, a
/// chain without links, `rod.*` overrides on a scenario without `[rod]`.
#[test]
fn bad_component_input_names_file_key_and_value() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let rods = shipped("two_rods.toml");
    let fourbar = shipped("fourbar.toml");
    for (file, set, needles) in [
        (
            &rods,
            "joint[1].body_j=rod2.segment[11]",
            &[
                "two_rods.toml (--set joint[1].body_j)",
                "joint[1].body_j",
                "'rod2.segment[11]'",
                "rod2 has 10 segments",
                "k = 1 .. 10",
            ][..],
        ),
        (
            &rods,
            "joint[1].body_j=rod2.segment[0]",
            &["joint[1].body_j", "'rod2.segment[0]'", "k = 1 .. 10"],
        ),
        (
            &rods,
            "force[0].body_j=rodX.last",
            &[
                "force[0].body_j",
                "'rodX.last'",
                "no rod or chain named 'rodX'",
                "rod1.segment[1..10]",
            ],
        ),
        (
            &rods,
            "rod[1].name=rod1",
            &["rod[1].name", "duplicate name 'rod1'", "rod[0] has it"],
        ),
        (
            &rods,
            "rod[1].name=a.b",
            &["rod[1].name", "'a.b' is invalid"],
        ),
        (
            &rods,
            "rod[2].segments=5",
            &["--set", "rod[2] does not exist", "2 elements"],
        ),
        (
            &rods,
            "rod.segments=5",
            &["--set", "rod.segments=5", "[[rod]]", "rod[0].segments"],
        ),
        (
            &rods,
            "rod[0].segments=0",
            &["rod[0].segments", "0 is invalid", "at least one segment"],
        ),
        (
            &rods,
            "rod[0].angle_deg=nan",
            &["rod[0].angle_deg", "NaN is not a finite number"],
        ),
        (
            &fourbar,
            "rod.segments=5",
            &[
                "--set",
                "rod.segments=5",
                "fourbar.toml has no [rod] table",
                "cannot add one",
            ],
        ),
    ] {
        rejects(&["run", file, "--set", set, "--out", out], needles);
    }
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.to_string_lossy().into_owned()
    };
    let body = "[[body]]\nname = \"b\"\nmass = 1.0\ninertia = 1.0\n";
    let chain = "[[chain]]\nname = \"c\"\nlinks = 2\nlength = 1.0\nmass = 1.0\n";
    let time = "[time]\nend = 0.1\n";
    for (name, text, needles) in [
        (
            "end_on_body.toml",
            format!(
                "{body}{chain}[[joint]]\ntype = \"revolute\"\nbody_i = \"b\"\npoint_i = \"last_end\"\n\
                 body_j = \"c.first\"\npoint_j = \"first_end\"\n{time}"
            ),
            &[
                "end_on_body.toml",
                "joint[0].point_i",
                "\"last_end\" is an end of a rod segment or chain link",
            ][..],
        ),
        (
            "bad_point.toml",
            format!(
                "{chain}[[force]]\ntype = \"torque\"\nbody = \"c.link[3]\"\ntorque = 1.0\n{time}"
            ),
            &["force[0].body", "'c.link[3]'", "c has 2 links", "k = 1 .. 2"],
        ),
        (
            "dup.toml",
            format!("{body}{}{time}", chain.replace("\"c\"", "\"b\"")),
            &["dup.toml", "chain[0].name", "duplicate name 'b': a body has it"],
        ),
        (
            "noname.toml",
            format!("[[rod]]\nsegments = 3\n{time}"),
            &["noname.toml", "rod[0].name", "missing"],
        ),
        (
            "nolinks.toml",
            format!("{}{time}", chain.replace("links = 2", "links = 0")),
            &["chain[0].links", "0 is invalid", "at least one link"],
        ),
        (
            "nomass.toml",
            format!("{}{time}", chain.replace("mass = 1.0", "density = 1.0")),
            &["chain[0].area", "density and area go together"],
        ),
        (
            "badlength.toml",
            format!("{}{time}", chain.replace("length = 1.0", "length = -1.0")),
            &["chain[0].length", "-1", "must be finite and > 0"],
        ),
        (
            "endword.toml",
            format!(
                "{chain}[[joint]]\ntype = \"revolute\"\nbody_i = \"ground\"\npoint_i = \"middle\"\n\
                 body_j = \"c.first\"\n{time}"
            ),
            &["joint[0].point_i", "invalid point \"middle\"", "first_end"],
        ),
    ] {
        let f = write(name, &text);
        rejects(&["run", &f, "--out", out], needles);
    }
    assert!(
        std::fs::read_dir(dir.path()).unwrap().all(|e| e
            .unwrap()
            .path()
            .extension()
            .is_some_and(|x| x == "toml")),
        "a rejected run wrote files"
    );
}

/// The shipped falling rod's `[rod]` is the rod named `rod`: its segments
/// are `rod.first`, `rod.segment[k]`, `rod.last` — here a pin of its top
/// end to the ground, which holds that end in place while the rod swings.
#[test]
fn the_falling_rod_table_is_the_rod_named_rod() {
    let text = std::fs::read_to_string(shipped("falling_rod.toml")).unwrap();
    let text = format!(
        "{}\n[[joint]]\ntype = \"revolute\"\nbody_i = \"ground\"\npoint_i = [-0.005236, 0.499993]\n\
         body_j = \"rod.last\"\npoint_j = \"last_end\"\n",
        text.replace("[initial]\nconsistent = false", "[initial]\nconsistent = true")
    );
    // the top end of the tilted rod is (−0.5 sin 0.6°, 0.5 cos 0.6°) ≈ above
    let set = strings(&[
        "rod.segments=4",
        "rod.fluid=false",
        "rod.contact=false",
        "rod.velocity=[0.0, 0.0]",
        "time.end=0.2",
    ]);
    let sc = scenario::parse(&text, "pinned.toml", "pinned", &set).unwrap();
    assert_eq!(sc.rods.len(), 1);
    assert_eq!(sc.rods[0].0, "rod");
    let (traj, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "completed");
    let q = traj.q.last().unwrap();
    let (sn, c) = q[11].sin_cos();
    let top = [q[9] - sn * 0.125, q[10] + c * 0.125];
    assert!(
        (top[0] + 0.005236).abs() < 1e-5 && (top[1] - 0.499993).abs() < 1e-5,
        "top end {top:?}"
    );
    // the rod fell around its pin: the bottom moved
    assert!((q[0] - sc.q0[0]).abs() > 1e-3, "{} vs {}", q[0], sc.q0[0]);
}
