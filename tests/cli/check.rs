//! `mbsolve check`: the size of the system of a scenario (degrees of
//! freedom and redundant equations from the rank of Φ_q, checked against
//! Grübler's count and a deliberately doubled joint) and clear errors.

use std::path::Path;

use crate::common::cli::{exe, mbsolve};
use crate::common::process;

/// The value printed after `label` in the report.
fn field(out: &str, label: &str) -> usize {
    let line = out
        .lines()
        .find(|l| l.starts_with(label))
        .unwrap_or_else(|| panic!("no '{label}' in {out}"));
    line[label.len()..]
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

fn check(path: &str, set: &[&str]) -> (Option<i32>, String, String) {
    let mut args = vec!["check", path];
    for s in set {
        args.extend(["--set", s]);
    }
    let o = mbsolve(&args);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// (file, overrides, bodies, constraint equations, dof, redundant).
type Case<'a> = (&'a str, Vec<&'a str>, usize, usize, usize, usize);

#[test]
fn check_reports_size_dof_and_redundancy() {
    // (file, overrides, bodies, constraint equations, dof, redundant)
    // (file, overrides, bodies, constraint equations, dof, redundant);
    // "" is the four-bar with joint B doubled: 10 equations, rank 8
    let cases: Vec<Case> = vec![
        // four-bar: Grübler 3·3 − 2·4 = 1
        ("scenarios/fourbar.toml", vec![], 3, 8, 1, 0),
        // rod of 5 segments, 4 revolute joints: 15 − 8 = 7
        (
            "scenarios/falling_rod.toml",
            vec!["rod.segments=5"],
            5,
            8,
            7,
            0,
        ),
        // one free body on a spring
        ("scenarios/spring_pendulum.toml", vec![], 1, 0, 3, 0),
        ("", vec!["linear_solver=sparse"], 3, 10, 1, 2),
    ];
    let dir = tempfile::tempdir().unwrap();
    // the four-bar with joint B doubled: 10 equations, rank 8
    let doubled = dir.path().join("doubled.toml");
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml"))
        .unwrap()
        + "\n[[joint]]\ntype = \"revolute\"\nname = \"B2\"\nbody_i = \"crank\"\npoint_i = [0.1, 0.0]\nbody_j = \"coupler\"\npoint_j = [-0.2, 0.0]\n";
    std::fs::write(&doubled, text).unwrap();
    let doubled = doubled.to_str().unwrap().to_string();
    for (file, set, bodies, m, dof, redundant) in cases {
        let file = if file.is_empty() { &doubled } else { file };
        let (code, out, err) = check(file, &set);
        assert_eq!(code, Some(0), "{file}: {err}");
        assert!(out.trim_end().ends_with("valid"), "{out}");
        assert_eq!(field(&out, "bodies"), bodies, "{out}");
        assert_eq!(field(&out, "coordinates"), 3 * bodies, "{out}");
        assert_eq!(field(&out, "constraint equations"), m, "{out}");
        assert_eq!(field(&out, "degrees of freedom"), dof, "{out}");
        assert_eq!(field(&out, "redundant equations"), redundant, "{out}");
    }
    // controller states are coordinates but not degrees of freedom: the
    // three-link arm has 3 of each besides its 9 body coordinates
    let (code, out, err) = check("scenarios/pid_arm.toml", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(field(&out, "coordinates"), 12, "{out}");
    assert_eq!(field(&out, "degrees of freedom"), 3, "{out}");
    assert!(
        out.contains("(9 of the bodies, 3 controller states)"),
        "{out}"
    );
    // element counts by kind
    let (_, out, _) = check("scenarios/falling_rod.toml", &["rod.segments=5"]);
    assert!(out.contains("4 revolute joint"), "{out}");
    assert!(
        out.contains("5 drag") && out.contains("4 torsional spring-damper"),
        "{out}"
    );
    let (_, out, _) = check("scenarios/spring_pendulum.toml", &[]);
    assert!(out.contains("1 point spring-damper"), "{out}");
    assert!(out.contains("ode45"), "{out}");
}

#[test]
fn check_rejects_bad_scenarios_with_exit_1() {
    let (code, out, err) = check("scenarios/fourbar.toml", &["body.mass=1"]);
    assert_eq!(code, Some(1), "{out}");
    assert!(err.contains("--set"), "{err}");
    assert!(!out.contains("valid"), "{out}");
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.toml");
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/spring_pendulum.toml"),
    )
    .unwrap()
    .replace("stiffness = 60.0", "stiffness = -60.0");
    std::fs::write(&p, text).unwrap();
    let (code, _, err) = check(p.to_str().unwrap(), &[]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("bad.toml") && err.contains("force[0].stiffness") && err.contains("-60"),
        "{err}"
    );
    let (code, _, err) = check("no/such.toml", &[]);
    assert_eq!(code, Some(1));
    assert!(err.contains("no/such.toml"), "{err}");
}

/// The rank of Φ_q comes from a sparse factorisation, O(N): a rod of
/// 10 000 segments (2·10⁴ − 2 independent rows: 9 999 revolute joints of
/// two rows each, no ground joint) is checked in seconds, where the dense
/// SVD of the 19 998 × 30 000 Φ_q did not end. Grübler: N + 2 degrees of
/// freedom.
#[test]
fn check_rank_is_sparse_and_scales_to_ten_thousand_bodies() {
    // CPU seconds, not wall time: a loaded machine does not move them
    let (o, usage) = process::output_with_usage(exe().args([
        "check",
        "scenarios/falling_rod.toml",
        "--set",
        "rod.segments=10000",
    ]));
    let took = usage.cpu_s;
    let (code, out, err) = (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    );
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(field(&out, "rank of Phi_q"), 19_998, "{out}");
    assert_eq!(field(&out, "degrees of freedom"), 10_002, "{out}");
    assert_eq!(field(&out, "redundant equations"), 0, "{out}");
    assert!(out.contains("sparse LDLᵀ"), "{out}");
    assert!(took < 10.0, "{took} s of CPU");
}
