//! Every input that crashed, looped or named the
//! wrong thing is a clear error from `mbsolve run`/`sweep` naming the file
//! (or the flag), the key and the value, with exit status 2 (or the run's
//! own status) — never a panic (101), an abort (134) or a hang — and bounded
//! work is checked before anything large is allocated.

use crate::common::cli::{exe, mbsolve, scenario, stderr};
use crate::common::process;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Runs `args`; asserts exit status 2 after at most `cpu_limit_s` CPU
/// seconds (the work the binary did, whatever the machine's load), no
/// panic, and every needle in the message.
fn rejects(args: &[&str], needles: &[&str], cpu_limit_s: f64) {
    let (o, usage) = process::output_with_usage(exe().args(args));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    assert!(!e.contains("panicked"), "{args:?}: {e}");
    for n in needles {
        assert!(e.contains(n), "{args:?}: the error lacks '{n}': {e}");
    }
    assert!(
        usage.cpu_s < cpu_limit_s,
        "{args:?}: {} CPU-s (the check must come before the work): {e}",
        usage.cpu_s
    );
}

/// The inputs that once crashed: each is rejected before the model is built
/// or the output times are allocated (an allocation of 16 GB or a capacity
/// overflow before; a loop of zero-length steps for the tiny span).
#[test]
fn crash_inputs_are_errors_naming_key_and_limit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let fourbar = scenario("fourbar.toml");
    let rod = scenario("falling_rod.toml");
    let quick = 20.0;
    for (file, set, needles) in [
        (
            &fourbar,
            "time.end=1e308",
            &["fourbar.toml", "output.dt", "1e308", "limit is 1e8"][..],
        ),
        (
            &fourbar,
            "output.dt=5e-324",
            &["--set output.dt", "output.dt: 5e-324", "limit is 1e8"],
        ),
        (
            &fourbar,
            "output.dt=1e-9",
            &[
                "--set output.dt",
                "output.dt: 1e-9",
                "2.0000e9",
                "limit is 1e8",
            ],
        ),
        (
            &fourbar,
            "time.end=5e-324",
            &["--set time.end", "time.end: 5e-324", "t + h == t"],
        ),
        (
            &fourbar,
            "integrator.max_step=1e-20",
            &["integrator.max_step: 1e-20", "would not advance t"],
        ),
        (
            &rod,
            "rod.segments=1000000000",
            &[
                "--set rod.segments",
                "rod.segments: 1000000000",
                "1000000 bodies",
            ],
        ),
    ] {
        rejects(&["run", file, "--set", set, "--out", out], needles, quick);
    }
    // One segment past the limit is refused before the rod is built.
    rejects(
        &["run", &rod, "--set", "rod.segments=1000001", "--out", out],
        &["rod.segments: 1000001", "limit is 1000000"],
        quick,
    );
    assert!(
        std::fs::read_dir(dir.path()).unwrap().next().is_none(),
        "a rejected run wrote files"
    );
}

/// The limits never reject the largest documented runs: the rod at
/// N = 10 000 with 10 000 output times passes the checks (its first row
/// is written; the test then stops it), and the shipped scenarios run.
#[test]
fn limits_accept_documented_runs() {
    use mbsolve::scenario::limits::{memory_estimate, memory_limit, MAX_BODIES, MAX_OUTPUT_TIMES};
    const { assert!(10_000 <= MAX_BODIES && 10_001.0 <= MAX_OUTPUT_TIMES) };
    let dir = tempfile::tempdir().unwrap();
    if memory_estimate(10_000, 10_001.0) > memory_limit() {
        eprintln!("this machine has too little memory for the N = 10 000 run; part skipped");
    } else {
        accepted_and_running(dir.path());
    }
    for (name, end) in [("fourbar.toml", "0.05"), ("falling_rod.toml", "0.001")] {
        let o = mbsolve(&[
            "run",
            &scenario(name),
            "--set",
            &format!("time.end={end}"),
            "--set",
            "output.dt=0.0005",
            "--out",
            dir.path().to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
    }
}

/// The rod at N = 10 000 with 10 000 output times (bdf) passes every
/// check: its first output row (t = 0, written after the limits, the
/// method's options and the stability check at t0) reaches the streamed
/// CSV — an event, whatever the machine's load; the run is then stopped.
fn accepted_and_running(dir: &Path) {
    let mut child = exe()
        .args([
            "run",
            &scenario("falling_rod.toml"),
            "--set",
            "rod.segments=10000",
            "--set",
            "output.dt=1e-4",
            // ode23 (the file's method) is refused at this N: its stability
            // limit would take more steps than the cap
            "--set",
            "integrator.method=bdf",
            "--progress",
            "off",
            "--out",
        ])
        .arg(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = process::drain(child.stderr.take().unwrap());
    let part = dir.join("falling_rod.csv.part");
    // bytes after the header line: the t = 0 row is being written
    let first_row = || {
        std::fs::read(&part).is_ok_and(|b| {
            b.iter()
                .position(|&c| c == b'\n')
                .is_some_and(|i| i + 1 < b.len())
        })
    };
    let r = process::wait_for(&mut child, "its first output row", 300.0, first_row);
    let _ = child.kill();
    let _ = child.wait();
    let err = String::from_utf8_lossy(&err.join().unwrap()).into_owned();
    if let Err(e) = r {
        panic!("N = 10 000 with 10 000 outputs: {e}: {err}");
    }
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A four-bar variant with `from` replaced by `to`.
fn fourbar_variant(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(scenario("fourbar.toml")).unwrap();
    assert!(text.contains(from), "'{from}' not in fourbar.toml");
    write(dir, name, &text.replacen(from, to, 1))
}

/// A slider on a translational joint, driven along x, with a perturbation.
const SLIDER: &str = r#"
[[body]]
name = "slider"
mass = 1.0
inertia = 0.1
x = 0.0

[[joint]]
type = "translational"
body_i = "ground"
point_i = [0.0, 0.0]
axis_i = [1.0, 0.0]
body_j = "slider"
point_j = [0.0, 0.0]

[[joint]]
type = "drive_coordinate"
body = "slider"
coordinate = "x"
motion = { amplitude = 0.1, omega = 2.0 }

[initial]
incorrect = true
perturbation = [{ coordinate = "slider.y", delta = 0.001 }]

[time]
end = 0.1
"#;

/// NaN and ±inf anywhere in a scenario are errors naming the key path at
/// parse time (before: a `model:` error without the key, or "saddle-point
/// matrix is singular" for a motion).
#[test]
fn non_finite_values_name_their_key() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let out = out.to_str().unwrap();
    let cases = [
        fourbar_variant(
            dir.path(),
            "point.toml",
            "point_i = [0.1, 0.0]",
            "point_i = [nan, 0.0]",
        ),
        fourbar_variant(
            dir.path(),
            "gravity.toml",
            "gravity = [0.0, -9.81]",
            "gravity = [0.0, -inf]",
        ),
        fourbar_variant(dir.path(), "x.toml", "x = 0.298", "x = nan"),
        fourbar_variant(dir.path(), "torque.toml", "torque = 0.5", "torque = inf"),
        fourbar_variant(dir.path(), "delta.toml", "delta = 0.05", "delta = nan"),
        write(
            dir.path(),
            "axis.toml",
            &SLIDER.replace("axis_i = [1.0, 0.0]", "axis_i = [1.0, nan]"),
        ),
        write(
            dir.path(),
            "motion.toml",
            &SLIDER.replace("amplitude = 0.1", "amplitude = inf"),
        ),
        write(
            dir.path(),
            "poly.toml",
            &SLIDER.replace(
                "{ amplitude = 0.1, omega = 2.0 }",
                "{ polynomial = [0.0, nan] }",
            ),
        ),
    ];
    let expected = [
        (
            "point.toml",
            "joint[1].point_i[0]: NaN is not a finite number",
        ),
        ("gravity.toml", "gravity[1]: -inf is not a finite number"),
        ("x.toml", "body[1].x: NaN is not a finite number"),
        ("torque.toml", "force[0].torque: inf is not a finite number"),
        (
            "delta.toml",
            "initial.perturbation[0].delta: NaN is not a finite number",
        ),
        (
            "axis.toml",
            "joint[0].axis_i[1]: NaN is not a finite number",
        ),
        (
            "motion.toml",
            "joint[1].motion.amplitude: inf is not a finite number",
        ),
        (
            "poly.toml",
            "joint[1].motion.polynomial[1]: NaN is not a finite number",
        ),
    ];
    for (p, (name, needle)) in cases.iter().zip(expected) {
        let o = mbsolve(&["run", p.to_str().unwrap(), "--out", out]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {e}");
        assert!(e.contains(&format!("{name}: {needle}")), "{name}: {e}");
    }
    // The slider itself is a valid scenario: the errors come from the values.
    let ok = write(dir.path(), "slider.toml", SLIDER);
    let o = mbsolve(&["run", ok.to_str().unwrap(), "--out", out]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A model that overflows (a motion whose Φ_t or γ exceeds the doubles, a
/// force growing like t¹¹·1e308) is reported as a non-finite quantity with
/// its name and time, not as a singular matrix.
#[test]
fn overflow_is_reported_as_such_not_as_singular() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let out = out.to_str().unwrap();
    let huge_motion = SLIDER.replace(
        "{ amplitude = 0.1, omega = 2.0 }",
        "{ amplitude = 1e300, omega = 1e10, phase = 1.0 }",
    );
    // Assembled: Φ_t = −Aω cos(φ) overflows in the consistent initial state.
    let p = write(dir.path(), "assembled.toml", &huge_motion);
    let o = mbsolve(&["run", p.to_str().unwrap(), "--out", out]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("Φ_t") && e.contains("not finite"), "{e}");
    assert!(!e.contains("singular"), "{e}");
    // Not assembled: γ = Aω² sin(φ) overflows at the first evaluation.
    let p = write(
        dir.path(),
        "raw.toml",
        &huge_motion.replace(
            "[initial]\nincorrect = true",
            "[initial]\nconsistent = false\nincorrect = true",
        ),
    );
    for method in ["ode23", "genalpha"] {
        let set = format!("integrator.method={method}");
        let mut args = vec!["run", p.to_str().unwrap(), "--out", out, "--set", &set];
        if method == "genalpha" {
            args.extend(["--set", "integrator.step=1e-3"]);
        }
        let o = mbsolve(&args);
        let e = stderr(&o);
        if method == "genalpha" {
            // the index-3 start projection evaluates Φ_t first: an error of
            // the initial state (exit 2), before any step
            assert_eq!(o.status.code(), Some(2), "{method}: {e}");
            assert!(
                e.contains("Φ_t") && e.contains("not finite") && e.contains("t = 0"),
                "{method}: {e}"
            );
            assert!(!e.contains("singular"), "{method}: {e}");
            continue;
        }
        // the first output, at t = 0, already holds ‖Φ_q q̇ + Φ_t‖ = inf
        // (Φ_t = Aω cos φ overflows): the run fails there, nothing written
        assert_eq!(o.status.code(), Some(1), "{method}: {e}");
        assert!(
            e.contains("non-finite output at t = 0e0: ‖Φ̇‖[0] = inf"),
            "{method}: {e}"
        );
        assert!(!e.contains("singular"), "{method}: {e}");
    }
    // Finite inputs whose solution overflows (a torque of 1e307 N·m on a
    // crank of inertia 6.7e-4 kg·m²): the solver cannot tell this from a
    // singular matrix, and its message names both.
    let p = fourbar_variant(dir.path(), "torque.toml", "torque = 0.5", "torque = 1e307");
    let o = mbsolve(&["run", p.to_str().unwrap(), "--out", out]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("non-finite solution") && e.contains("overflows"),
        "{e}"
    );
}

/// Control characters and empty key segments get a message; `--param`
/// errors are labelled `--param`; NaN as a `--set`/`--param` value for a
/// numeric key is an error naming the key.
#[test]
fn bad_keys_and_values_on_the_command_line_and_in_toml() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let out = out.to_str().unwrap();
    let f = scenario("fourbar.toml");
    // A control character in a comment (before: an empty message).
    let p = fourbar_variant(
        dir.path(),
        "ctrl.toml",
        "# none by default",
        "# none \u{1} by default",
    );
    let o = mbsolve(&["run", p.to_str().unwrap(), "--out", out]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("ctrl.toml: line "), "{e}");
    assert!(e.contains("control character U+0001"), "{e}");
    for (set, needles) in [
        (
            "time..end=1",
            &["--set", "time..end", "segment 2 is empty"][..],
        ),
        (".time=1", &["--set", "segment 1 is empty"]),
        ("time.=1", &["--set", "segment 2 is empty"]),
        (
            "time.e\u{1}nd=1",
            &["--set", "\\u{1}", "not allowed in a key"],
        ),
        (
            "body[x].mass=1",
            &["--set", "no [[body]] named 'x'", "crank, coupler, rocker"],
        ),
        ("body[].mass=1", &["--set", "body[]", "array index"]),
        (
            "body[9].mass=1",
            &["--set", "body[9] does not exist", "3 elements"],
        ),
        (
            "stabilization.alpha=nan",
            &[
                "(--set stabilization.alpha)",
                "stabilization.alpha: NaN is not a finite number",
            ],
        ),
        ("gravity=[0, inf]", &["(--set gravity)", "gravity[1]: inf"]),
    ] {
        rejects(&["run", &f, "--set", set, "--out", out], needles, 20.0);
    }
    for (param, needles) in [
        (
            "stabilization.alpha=1,nan",
            &[
                "(--param stabilization.alpha)",
                "stabilization.alpha: NaN is not a finite number",
            ][..],
        ),
        (
            "stabilization.alpha=1,-1",
            &["(--param stabilization.alpha)", "-1 is invalid"],
        ),
        (
            "stabilization..alpha=1,2",
            &["--param", "segment 2 is empty"],
        ),
    ] {
        let args = [
            "sweep",
            &f,
            "--param",
            param,
            "--set",
            "time.end=0.05",
            "--out",
            out,
        ];
        rejects(&args, needles, 20.0);
        let o = mbsolve(&args);
        assert!(
            !stderr(&o).contains("--set stabilization"),
            "{}",
            stderr(&o)
        );
    }
}

/// `mbsolve run … | head -1`: the reader takes one line and goes away; the
/// run ends quietly with its own status and writes its files.
#[test]
fn head_one_ends_quietly() {
    use std::io::{BufRead, BufReader};
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .args([
            "run",
            &scenario("fourbar.toml"),
            "--set",
            "time.end=0.2",
            "--out",
        ])
        .arg(dir.path())
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("assembled initial state"), "{first}");
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
    assert!(dir.path().join("fourbar.summary.json").exists());
}

/// The memory check honours `ulimit -v` (and cgroup limits): 200 000 rod
/// segments (1.6 GB at 8 kB per body) under a 1 GB address-space limit are
/// an error before the model is built, not an abort in the middle of it;
/// without the limit the same check passes on any machine with ≥ 2 GB.
#[test]
fn memory_check_honours_the_address_space_limit() {
    let m = env!("CARGO_BIN_EXE_mbsolve");
    let o = Command::new("sh")
        .args([
            "-c",
            &format!(
                "ulimit -v 1000000 && exec {m} check scenarios/falling_rod.toml \
                 --set rod.segments=200000"
            ),
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("rod.segments: 200000"), "{e}");
    assert!(e.contains("ulimit -v"), "{e}");
    assert!(e.contains("1.600 GB (8 kB per body)"), "{e}");
}
