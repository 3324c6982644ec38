//! Switching method from the command line: `--unset KEY`, and the file's
//! keys of another method dropped with a note when an override chose the
//! method (still errors when the file itself is inconsistent or when an
//! override wrote them).

use mbsolve::integrate::Method;
use mbsolve::scenario::{self, Override, UNSET};
use std::path::{Path, PathBuf};
use std::process::Command;

fn quarter_car() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quarter_car.toml")
}

fn load(unset: &[&str], set: &[&str]) -> Result<scenario::Scenario, String> {
    let unset: Vec<String> = unset.iter().map(|s| s.to_string()).collect();
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    scenario::load_with(&quarter_car(), &scenario::overrides(&unset, &set))
        .map_err(|e| e.to_string())
}

#[test]
fn a_method_from_set_drops_the_files_keys_of_other_methods() {
    // quarter_car.toml: ode45 with rtol and atol
    let sc = load(&[], &["integrator.method=rk4", "integrator.step=1e-3"]).unwrap();
    assert_eq!(sc.run.method, Method::Rk4);
    assert_eq!(sc.run.ode.fixed_step, Some(1e-3));
    assert_eq!(sc.notes.len(), 2, "{:?}", sc.notes);
    for (n, k) in sc
        .notes
        .iter()
        .zip(["integrator.atol = 1e-10", "integrator.rtol = 1e-8"])
    {
        assert!(
            n.contains(k) && n.contains("quarter_car.toml") && n.contains("\"rk4\""),
            "{n}"
        );
    }
    // the same as removing them by hand
    let by_hand = load(
        &["integrator.rtol", "integrator.atol"],
        &["integrator.method=rk4", "integrator.step=1e-3"],
    )
    .unwrap();
    assert!(by_hand.notes.is_empty());
    assert_eq!(format!("{:?}", sc.run), format!("{:?}", by_hand.run));
    // a key an override wrote stays an error
    let e = load(
        &[],
        &[
            "integrator.method=rk4",
            "integrator.step=1e-3",
            "integrator.rtol=1e-6",
        ],
    )
    .unwrap_err();
    assert!(
        e.contains("(--set integrator.rtol)") && e.contains("adaptive methods"),
        "{e}"
    );
    // no note when the method is the file's
    assert!(load(&[], &["time.end=1"]).unwrap().notes.is_empty());
}

#[test]
fn an_index3_method_drops_baumgarte_and_index1_formulations() {
    let text = format!(
        "formulation = \"eliminated\"\n{}",
        std::fs::read_to_string(quarter_car()).unwrap().replace(
            "[integrator]",
            "[stabilization]\nalpha = 5.0\nbeta = 5.0\n[integrator]"
        )
    );
    // the file is consistent (ode45, eliminated, Baumgarte)
    let o = |s: &'static str| Override {
        flag: "--set",
        spec: s,
    };
    scenario::parse_with(&text, "q.toml", "q", &[]).unwrap();
    let sc = scenario::parse_with(
        &text,
        "q.toml",
        "q",
        &[o("integrator.method=genalpha"), o("integrator.step=1e-3")],
    )
    .unwrap();
    let keys: Vec<&str> = sc
        .notes
        .iter()
        .map(|n| {
            n.split(" = ")
                .next()
                .unwrap()
                .trim_start_matches("q.toml: ")
        })
        .collect();
    assert_eq!(
        keys,
        [
            "integrator.atol",
            "integrator.rtol",
            "stabilization.alpha",
            "stabilization.beta",
            "formulation"
        ]
    );
    // the file itself inconsistent: still an error, nothing dropped
    let bad = text.replace("method = \"ode45\"", "method = \"genalpha\"\nstep = 1e-3");
    let e = scenario::parse_with(&bad, "q.toml", "q", &[])
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("q.toml: integrator.rtol"), "{e}");
}

#[test]
fn unset_removes_a_key_and_names_a_missing_one() {
    let sc = load(&["integrator.rtol"], &[]).unwrap();
    assert_eq!(
        sc.run.ode.rtol,
        mbsolve::integrate::OdeOptions::default().rtol
    );
    assert_eq!(load(&[], &[]).unwrap().run.ode.rtol, 1e-8);
    let e = load(&["integrator.foo"], &[]).unwrap_err();
    assert!(
        e.contains(UNSET) && e.contains("'integrator.foo' is not set"),
        "{e}"
    );
    let e = load(&["force[7]"], &[]).unwrap_err();
    assert!(e.contains("'force[7]' is not set"), "{e}");
    // an element removed: the suspension gone, the tyre kept
    let sc = load(&["force[1]"], &[]).unwrap();
    let full = load(&[], &[]).unwrap();
    assert!(sc.system.forces().len() < full.system.forces().len());
    let e = load(&["time.end=1"], &[]).unwrap_err();
    assert!(e.contains("KEY, not KEY=VALUE"), "{e}");
}

#[test]
fn the_cli_prints_the_notes_and_takes_unset() {
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_mbsolve"))
            .args(args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap()
    };
    let o = run(&[
        "check",
        "scenarios/quarter_car.toml",
        "--set",
        "integrator.method=rk4",
        "--set",
        "integrator.step=1e-3",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("note: ") && err.contains("integrator.rtol = 1e-8 dropped"),
        "{err}"
    );
    let o = run(&[
        "check",
        "scenarios/quarter_car.toml",
        "--unset",
        "integrator.atol",
    ]);
    assert!(o.status.success());
    let o = run(&[
        "check",
        "scenarios/quarter_car.toml",
        "--unset",
        "integrator.nope",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("'integrator.nope' is not set"));
}
