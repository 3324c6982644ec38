//! The `mbsolve` binary: outputs of `run`, `--set`, and clear errors for bad input.

use crate::common::cli::{mbsolve, stderr};
use std::path::{Path, PathBuf};
use std::process::Command;

fn fourbar_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml")
}

/// Write a variant of the four-bar scenario with `from` replaced by `to`.
fn variant(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(fourbar_path()).unwrap();
    assert!(
        text.contains(from),
        "fixture text '{from}' not in fourbar.toml"
    );
    let p = dir.join(name);
    std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
    p
}

#[test]
fn run_writes_csv_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = mbsolve(&[
        "run",
        fourbar_path().to_str().unwrap(),
        "--set",
        "stabilization.alpha=10",
        "--set",
        "stabilization.beta=10",
        "--set",
        "integrator.method=ode45",
        "--set",
        "time.end=0.5",
        "--set",
        "output.dt=0.01",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(dir.path().join("fourbar.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,crank.x,crank.y,crank.phi,coupler.x,coupler.y,coupler.phi,rocker.x,rocker.y,\
         rocker.phi,constraint_norm"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 51);
    assert!((rows.last().unwrap()[0] - 0.5).abs() < 1e-12);
    assert!((rows[0][3] - 60f64.to_radians()).abs() < 1e-12);
    let s: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("fourbar.summary.json")).unwrap(),
    )
    .unwrap();
    for key in [
        "steps",
        "failed_steps",
        "rhs_evals",
        "wall_s",
        "max_constraint_norm",
        "final_constraint_norm",
    ] {
        assert!(s[key].is_number(), "summary lacks {key}: {s}");
    }
    assert_eq!(s["method"], "ode45");
    assert_eq!(s["alpha"], 10.0);
    assert_eq!(
        s["rhs_evals"].as_u64().unwrap(),
        6 * (s["steps"].as_u64().unwrap() + s["failed_steps"].as_u64().unwrap()) + 1
    );
}

#[test]
fn rk4_needs_and_uses_a_step() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let f = fourbar_path();
    let o = mbsolve(&[
        "run",
        f.to_str().unwrap(),
        "--set",
        "integrator.method=rk4",
        "--out",
        out,
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("integrator.step"), "{}", stderr(&o));
    let o = mbsolve(&[
        "run",
        f.to_str().unwrap(),
        "--set",
        "integrator.method=rk4",
        "--set",
        "integrator.step=1e-3",
        "--set",
        "time.end=0.1",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("fourbar.summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(s["steps"], 100);
}

#[test]
fn bad_scenarios_name_file_key_and_problem() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let out = out.to_str().unwrap();
    let cases = [
        (
            "negmass.toml",
            "mass = 0.4",
            "mass = -0.4",
            vec!["negmass.toml", "body[1].mass", "-0.4", "> 0"],
        ),
        (
            "unknown.toml",
            "inertia = 5.333333333333333e-3",
            "inertia = 5.3e-3\ncolour = \"red\"",
            vec!["unknown.toml", "body[1]", "colour"],
        ),
        (
            "missing.toml",
            "body_j = \"rocker\"",
            "body_j = \"rockr\"",
            vec!["missing.toml", "joint[2].body_j", "rockr"],
        ),
        (
            "nonnum.toml",
            "torque = 0.5",
            "torque = \"half\"",
            vec!["nonnum.toml", "force[0]", "torque"],
        ),
        (
            "nonnum2.toml",
            "[stabilization]\n",
            "[stabilization]\nalpha = \"ten\"\n",
            vec!["nonnum2.toml", "stabilization.alpha", "invalid type"],
        ),
        (
            "method.toml",
            "method = \"ode23\"",
            "method = \"euler\"",
            vec!["method.toml", "integrator.method", "euler"],
        ),
        (
            "syntax.toml",
            "[time]",
            "[time",
            vec!["syntax.toml", "line"],
        ),
    ];
    for (name, from, to, needles) in cases {
        let p = variant(dir.path(), name, from, to);
        let o = mbsolve(&["run", p.to_str().unwrap(), "--out", out]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        let e = stderr(&o);
        for n in needles {
            assert!(e.contains(n), "{name}: error message lacks '{n}': {e}");
        }
        assert!(!e.contains("panicked"), "{e}");
    }
}

#[test]
fn bad_set_overrides_are_rejected() {
    let f = fourbar_path();
    let f = f.to_str().unwrap();
    for (set, needles) in [
        ("integrator.methd=ode45", vec!["--set", "methd"]),
        (
            "stabilization.alpha=abc",
            vec!["--set", "stabilization.alpha"],
        ),
        ("stabilization.alpha=-1", vec!["stabilization.alpha", "-1"]),
        ("nokey", vec!["--set", "KEY=VALUE"]),
        ("rod.segments=0", vec!["--set", "rod"]),
    ] {
        let o = mbsolve(&["run", f, "--set", set, "--out", "/tmp/mbsolve-cli-unused"]);
        assert_eq!(o.status.code(), Some(2), "{set}: {}", stderr(&o));
        let e = stderr(&o);
        for n in needles {
            assert!(e.contains(n), "--set {set}: error lacks '{n}': {e}");
        }
    }
}

#[test]
fn reproduce_writes_the_four_bar_figures() {
    let dir = tempfile::tempdir().unwrap();
    let o = mbsolve(&["reproduce", "--out", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let fb = dir.path().join("fourbar");
    for f in [
        "fig2_fourbar_correct_phiBx.svg",
        "fig2_fourbar_correct_norm.svg",
        "fig3_fourbar_incorrect_phiBx.svg",
        "fig3_fourbar_incorrect_norm.svg",
        "fourbar_table.md",
        "incorrect_a10.000_b10.000.csv",
    ] {
        let p = fb.join(f);
        let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        assert!(len > 500, "{} missing or tiny", p.display());
    }
    let svg = std::fs::read_to_string(fb.join("fig3_fourbar_incorrect_norm.svg")).unwrap();
    assert!(
        svg.contains("<polyline") || svg.contains("<path"),
        "no curves drawn"
    );
    let table = std::fs::read_to_string(fb.join("fourbar_table.md")).unwrap();
    assert_eq!(table.lines().count(), 2 + 7, "{table}");
    for dir in [fb, dir.path().join("falling_rod")] {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let p = entry.unwrap().path();
            if p.to_str().unwrap().ends_with(".redraw.txt") {
                redraws_identically(&p);
            }
        }
    }
}

/// The figure beside `redraw` (`<stem>.redraw.txt`) is redrawn byte for
/// byte by the `mbsolve plot` command in that file from `<stem>.csv`.
fn redraws_identically(redraw: &Path) {
    let dir = redraw.parent().unwrap();
    let stem = redraw.to_str().unwrap().trim_end_matches(".redraw.txt");
    let line = std::fs::read_to_string(redraw).unwrap();
    // split the shell line: words, 'single-quoted' words, '\'' escapes
    let (mut words, mut cur, mut quoted, mut in_word) = (Vec::new(), String::new(), false, false);
    let mut chars = line.trim_end().chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\'' => {
                quoted = !quoted;
                in_word = true;
            }
            '\\' if !quoted => {
                cur.push(chars.next().unwrap());
                in_word = true;
            }
            ' ' if !quoted => {
                if in_word {
                    words.push(std::mem::take(&mut cur));
                }
                in_word = false;
            }
            c => {
                cur.push(c);
                in_word = true;
            }
        }
    }
    words.push(cur);
    assert_eq!(words[..2], ["mbsolve", "plot"], "{line}");
    let columns = csv::Reader::from_path(format!("{stem}.csv"))
        .unwrap()
        .headers()
        .unwrap()
        .len();
    assert_eq!(
        words.iter().filter(|w| *w == "--y").count(),
        columns - 1,
        "every data column of {stem}.csv is plotted: {line}"
    );
    let redrawn = dir.join("redrawn.svg");
    let mut args: Vec<String> = words[1..].to_vec();
    let out = args.iter().position(|w| w == "--out").unwrap();
    args[out + 1] = redrawn.to_str().unwrap().to_string();
    let o = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .args(&args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{line}: {}", stderr(&o));
    let a = std::fs::read_to_string(format!("{stem}.svg")).unwrap();
    let b = std::fs::read_to_string(&redrawn).unwrap();
    assert!(a == b, "{stem}.svg is not redrawn identically from its CSV");
}

#[test]
fn sweep_runs_the_product_in_order_and_matches_single_runs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let f = fourbar_path();
    let o = mbsolve(&[
        "sweep",
        f.to_str().unwrap(),
        "--param",
        "stabilization.alpha=0,10",
        "--param",
        "initial.incorrect=false,true",
        "--set",
        "stabilization.rule=equal",
        "--set",
        "time.end=0.5",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = std::fs::read_to_string(dir.path().join("fourbar_sweep.csv")).unwrap();
    let rows: Vec<Vec<String>> = table
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    assert_eq!(rows.len(), 4);
    let expect = [
        ("0", "false"),
        ("0", "true"),
        ("10", "false"),
        ("10", "true"),
    ];
    for (row, (a, inc)) in rows.iter().zip(expect) {
        assert_eq!((row[0].as_str(), row[1].as_str()), (a, inc));
        // the same run alone gives the same step count and constraint norm
        let single = dir.path().join("single");
        let o = mbsolve(&[
            "run",
            f.to_str().unwrap(),
            "--set",
            &format!("stabilization.alpha={a}"),
            "--set",
            &format!("initial.incorrect={inc}"),
            "--set",
            "stabilization.rule=equal",
            "--set",
            "time.end=0.5",
            "--out",
            single.to_str().unwrap(),
        ]);
        assert!(o.status.success());
        let s: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(single.join("fourbar.summary.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(row[3], s["steps"].to_string());
        assert_eq!(
            row[8].parse::<f64>().unwrap(),
            format!("{:.6e}", s["final_constraint_norm"].as_f64().unwrap())
                .parse::<f64>()
                .unwrap()
        );
    }
    // a bad key fails before anything runs
    let o = mbsolve(&[
        "sweep",
        f.to_str().unwrap(),
        "--param",
        "stabilization.alpah=1,2",
        "--out",
        out,
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("alpah"), "{}", stderr(&o));
}

/// `mbsolve run … | head -1`: a closed stdout does not crash the run; it
/// writes its files and exits with its own status.
#[test]
fn a_closed_stdout_ends_quietly_with_the_runs_status() {
    use std::process::Stdio;
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .args([
            "run",
            "scenarios/fourbar.toml",
            "--set",
            "time.end=0.2",
            "--out",
        ])
        .arg(dir.path())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader goes away before the first line
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
    assert!(dir.path().join("fourbar.summary.json").exists());
}

/// A locked mechanism (the four-bar's crank angle also held by a drive)
/// cannot take the crank rate given as independent: the velocity residual
/// is an error naming `initial.independent`, not a note.
#[test]
fn an_initial_velocity_residual_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = variant(
        dir.path(),
        "locked.toml",
        "[[force]]",
        "[[joint]]\ntype = \"drive_coordinate\"\nname = \"lock\"\nbody = \"crank\"\ncoordinate = \"phi\"\nmotion = 1.0471975511965976\n\n[[force]]",
    );
    let o = mbsolve(&[
        "run",
        p.to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("locked.toml") && e.contains("initial.independent"),
        "{e}"
    );
    assert!(
        e.contains("phi1 cannot keep its given value") && e.contains("locked"),
        "{e}"
    );
    // the four-bar itself assembles
    let o = mbsolve(&["check", fourbar_path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}
