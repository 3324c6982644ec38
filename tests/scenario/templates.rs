//! `[[repeat]]` templates and `include`: the 40-loop parallelogram chain
//! from its 50-line template is the model written out body by body (the
//! generated long file) and the builder's; includes merge files and refuse
//! cycles; errors in a copy name the template and the index.

use crate::common::setup::docs_example;
use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::scenario;
use mbsolve::simulation::simulate;
use std::fmt::Write;
use std::path::Path;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The chain written out body by body and joint by joint, with the
/// numbers of the builder's state (what a generator script writes).
fn long_file(p: &ParallelogramChain, settings: &str) -> String {
    let (q, v) = p.state(p.theta0, p.rate0);
    let (k, r, l) = (p.loops, p.crank_length, p.spacing);
    let mut s = format!(
        "name = \"parallelogram_chain\"\ngravity = [0.0, {:?}]\nformulation = \"augmented_lagrangian\"\n",
        -p.gravity
    );
    let body = |s: &mut String, name: String, m: f64, len: f64, b: usize| {
        write!(
            s,
            "\n[[body]]\nname = \"{name}\"\nmass = {m:?}\ninertia = {:?}\nx = {:?}\ny = {:?}\n\
             phi = {:?}\nvx = {:?}\nvy = {:?}\nomega = {:?}\n",
            m * len * len / 12.0,
            q[3 * b],
            q[3 * b + 1],
            q[3 * b + 2],
            v[3 * b],
            v[3 * b + 1],
            v[3 * b + 2]
        )
        .unwrap();
    };
    for i in 0..=k {
        body(&mut s, format!("crank{i}"), p.crank_mass, r, i);
    }
    for j in 0..k {
        body(&mut s, format!("coupler{j}"), p.coupler_mass, l, k + 1 + j);
    }
    let joint = |s: &mut String, name: String, bi: String, pi: f64, bj: String, pj: f64| {
        write!(
            s,
            "\n[[joint]]\ntype = \"revolute\"\nname = \"{name}\"\nbody_i = \"{bi}\"\n\
             point_i = [{pi:?}, 0.0]\nbody_j = \"{bj}\"\npoint_j = [{pj:?}, 0.0]\n"
        )
        .unwrap();
    };
    for i in 0..=k {
        let g = "ground".to_string();
        joint(
            &mut s,
            format!("pivot{i}"),
            g,
            i as f64 * l,
            format!("crank{i}"),
            -0.5 * r,
        );
    }
    for j in 0..k {
        let c = format!("coupler{j}");
        let b = k + 1 + j;
        joint(
            &mut s,
            format!("pin{j}-body{b}"),
            format!("crank{j}"),
            0.5 * r,
            c.clone(),
            -0.5 * l,
        );
        let n = format!("pin{}-body{b}", j + 1);
        joint(&mut s, n, format!("crank{}", j + 1), 0.5 * r, c, 0.5 * l);
    }
    s + settings
}

const SETTINGS: &str = "
[integrator]
method = \"genalpha\"
rho_inf = 0.9
step = 5e-4
newton_tol = 1e-8
max_newton = 50

[time]
end = 1.0

[output]
dt = 0.01
";

#[test]
fn parallelogram_chain_template_is_the_long_file_and_the_builder() {
    let p = ParallelogramChain {
        loops: 40,
        ..Default::default()
    };
    let long = long_file(&p, SETTINGS);
    let path = root().join("scenarios/parallelogram_chain.toml");
    let short = std::fs::read_to_string(&path).unwrap();
    let (nl, ns) = (long.lines().count(), short.lines().count());
    eprintln!("long file {nl} lines, template {ns} lines");
    assert!(ns < 60 && nl > 1400, "{ns} vs {nl}");
    // short runs: 20 steps
    let set = ["time.end=0.01".to_string(), "output.dt=0.005".to_string()];
    let a = scenario::load(&path, &set).unwrap();
    let b = scenario::parse(&long, "long.toml", "long", &set).unwrap();
    assert_eq!(a.name, b.name);
    assert_eq!(a.q0, b.q0);
    assert_eq!(a.qd0, b.qd0);
    let (ba, bb) = (a.system.bodies(), b.system.bodies());
    assert_eq!(ba.len(), 81);
    for (x, y) in ba.iter().zip(bb) {
        assert_eq!(
            (&x.name, x.mass, x.inertia, x.q0, x.v0),
            (&y.name, y.mass, y.inertia, y.q0, y.v0)
        );
    }
    assert_eq!(a.system.n_constraints(), 242);
    assert_eq!(a.system.n_constraints(), b.system.n_constraints());
    // the constraints are the same functions: equal residuals away from
    // the initial state
    let q: Vec<f64> =
        a.q0.iter()
            .enumerate()
            .map(|(i, x)| x + 1e-3 * (i as f64).sin())
            .collect();
    let (mut pa, mut pb) = (vec![0.0; 242], vec![0.0; 242]);
    a.system.phi(&q, 0.3, &mut pa);
    b.system.phi(&q, 0.3, &mut pb);
    assert_eq!(pa, pb);
    let (ta, sa) = simulate(&a.system, &a.q0, &a.qd0, &a.run, &mut []).unwrap();
    let (tb, sb) = simulate(&b.system, &b.q0, &b.qd0, &b.run, &mut []).unwrap();
    assert_eq!(sa.status, "completed", "{:?}", sa.message);
    assert_eq!(
        (sa.steps, &ta.t, &ta.q, &ta.qd),
        (sb.steps, &tb.t, &tb.q, &tb.qd)
    );
    // and the builder's chain: same bodies, same initial state
    let sys = parallelogram_chain(&p).unwrap();
    let (q0, v0) = p.state(p.theta0, p.rate0);
    assert_eq!(a.q0, q0);
    assert_eq!(a.qd0, v0);
    for (x, y) in ba.iter().zip(sys.bodies()) {
        assert_eq!((&x.name, x.mass, x.inertia), (&y.name, y.mass, y.inertia));
    }
    let mut pc = vec![0.0; 242];
    sys.phi(&q, 0.3, &mut pc);
    assert_eq!(pa, pc);
}

fn chain(extra_joint: &str) -> String {
    let text = std::fs::read_to_string(root().join("scenarios/parallelogram_chain.toml")).unwrap();
    text.replacen("\n[integrator]", &format!("{extra_joint}\n[integrator]"), 1)
}

fn err(text: &str) -> String {
    scenario::parse(text, "t.toml", "t", &[])
        .map(|_| ())
        .expect_err("an error")
        .to_string()
}

#[test]
fn errors_in_copies_name_the_template_and_the_index() {
    // an index out of range: the last copy names crank41
    let text = chain("").replacen("body_i = \"crank{j+1}\"", "body_i = \"crank{j+2}\"", 1);
    let e = err(&text);
    for n in [
        "t.toml",
        "repeat[1].joint[1] (j = 39).body_i",
        "no body named 'crank41'",
    ] {
        assert!(e.contains(n), "{e}\nlacks {n}");
    }
    let text = chain("").replacen("name = \"crank{i}\"", "name = \"crank{k}\"", 1);
    let e = err(&text);
    assert!(
        e.contains("repeat[0].body[0].name") && e.contains("unknown name 'k'"),
        "{e}"
    );
    let text = chain("").replacen("to = \"loops - 1\"", "to = -2", 1);
    let e = err(&text);
    assert!(e.contains("repeat[1].to") && e.contains("empty"), "{e}");
    let text = chain("").replacen("index = \"j\"", "index = \"L\"", 1);
    assert!(err(&text).contains("'L' is a parameter"));
    let text = chain("").replacen("from = 0", "form = 0", 1);
    assert!(err(&text).contains("repeat[0].form: unknown key"));
}

#[test]
fn includes_merge_and_refuse_cycles() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("parts")).unwrap();
    // the bodies in one file, the joints and run in another, each
    // relative to the file that includes it
    std::fs::write(
        d.join("parts/bodies.toml"),
        "[parameters]\nm = 2.0\nl = 1.0\n[[body]]\nname = \"bob\"\nmass = \"m\"\ninertia = 0.1\ny = \"-l/2\"\n",
    )
    .unwrap();
    std::fs::write(
        d.join("parts/all.toml"),
        "include = [\"bodies.toml\"]\n[[joint]]\ntype = \"revolute\"\nbody_i = \"ground\"\n\
         point_i = [0.0, 0.0]\nbody_j = \"bob\"\npoint_j = [0.0, \"l/2\"]\n[time]\nend = 1.0\n",
    )
    .unwrap();
    std::fs::write(
        d.join("main.toml"),
        "include = [\"parts/all.toml\"]\ngravity = [0.0, -9.81]\n[parameters]\nm = 3.0\n\
         [[body]]\nname = \"other\"\nmass = 1.0\ninertia = 1.0\n[time]\nend = 0.5\n",
    )
    .unwrap();
    let sc = scenario::load(&d.join("main.toml"), &[]).unwrap();
    let names: Vec<&str> = sc.system.bodies().iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["bob", "other"]);
    // the including file's values win, key by key
    assert_eq!(sc.system.bodies()[0].mass, 3.0);
    assert_eq!(sc.q0[1], -0.5);
    assert_eq!(sc.run.t_end, 0.5);
    assert_eq!(sc.system.n_constraints(), 2);
    // a parameter of an included file is overridable
    let sc = scenario::load(&d.join("main.toml"), &["l=4".into()]).unwrap();
    assert_eq!(sc.q0[1], -2.0);
    // a self-include and a cycle name the files
    std::fs::write(
        d.join("self.toml"),
        "include = [\"self.toml\"]\n[time]\nend = 1.0\n",
    )
    .unwrap();
    let e = scenario::load(&d.join("self.toml"), &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("include[0]") && e.contains("includes itself"),
        "{e}"
    );
    assert!(
        e.contains("self.toml → ") && e.matches("self.toml").count() >= 3,
        "{e}"
    );
    std::fs::write(
        d.join("a.toml"),
        "include = [\"b.toml\"]\n[time]\nend = 1.0\n",
    )
    .unwrap();
    std::fs::write(d.join("b.toml"), "include = [\"a.toml\"]\n").unwrap();
    let e = scenario::load(&d.join("a.toml"), &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.toml: include[0]") && e.contains("a.toml → ") && e.contains("b.toml → "),
        "{e}"
    );
    let e = scenario::load(&d.join("missing.toml"), &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot read"), "{e}");
    std::fs::write(
        d.join("m.toml"),
        "include = [\"nothere.toml\"]\n[time]\nend = 1.0\n",
    )
    .unwrap();
    let e = scenario::load(&d.join("m.toml"), &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.toml: include[0]") && e.contains("nothere.toml"),
        "{e}"
    );
}

/// The repeat example of docs/scenarios.md parses and runs.
#[test]
fn the_documented_example_runs() {
    let block = &docs_example("repeat example");
    let sc = scenario::parse(block, "doc.toml", "doc", &[]).unwrap();
    assert_eq!(sc.system.bodies().len(), 5);
    let (_, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "completed");
}
