//! Sweeps that record results: `[[metric]]` and `--metric` columns of the
//! sweep table against the same reductions computed here from each run's
//! kept table (`--keep runs`); bad metrics are errors naming the key.

use crate::common::cli::{mbsolve, stderr};
use crate::common::setup::docs_example;
use std::collections::HashMap;
use std::path::Path;

/// The metric example of docs/scenarios.md.
fn example() -> String {
    docs_example("metric example")
}

/// A CSV table as (header, columns of numbers; empty cells NaN).
fn table(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let h: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    let rows = r
        .records()
        .map(|x| x.unwrap().iter().map(String::from).collect())
        .collect();
    (h, rows)
}

fn columns(path: &Path) -> HashMap<String, Vec<f64>> {
    let (h, rows) = table(path);
    h.iter()
        .enumerate()
        .map(|(k, n)| {
            let v = rows
                .iter()
                .map(|r: &Vec<String>| r[k].parse().unwrap())
                .collect();
            (n.clone(), v)
        })
        .collect()
}

/// Trapezoidal time average of `v` over the rows with t in [a, b].
fn time_average(t: &[f64], v: &[f64], a: f64, b: f64) -> f64 {
    let rows: Vec<(f64, f64)> = t
        .iter()
        .zip(v)
        .filter(|(t, _)| **t >= a - 1e-9 && **t <= b + 1e-9)
        .map(|(t, v)| (*t, *v))
        .collect();
    let integral: f64 = rows
        .windows(2)
        .map(|w| 0.5 * (w[1].0 - w[0].0) * (w[0].1 + w[1].1))
        .sum();
    integral / (rows.last().unwrap().0 - rows[0].0)
}

fn close(got: f64, want: f64, what: &str) {
    // the kept table holds 13 significant digits
    assert!(
        (got - want).abs() <= 1e-10 * want.abs().max(1e-3),
        "{what}: sweep {got:e}, from the kept table {want:e}"
    );
}

/// The documented example swept over two lengths with two `--metric`s:
/// every metric cell equals the reduction of that run's kept table.
#[test]
fn metrics_equal_the_reductions_of_the_kept_runs() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("pendulum.toml");
    std::fs::write(&file, example()).unwrap();
    let out = dir.path().join("out");
    let o = mbsolve(&[
        "sweep",
        file.to_str().unwrap(),
        "--param",
        "l=0.5,1",
        "--metric",
        "final(bob.phi)",
        "--metric",
        // a positional name of earlier versions in an expression: bob.phi
        "swing=max(abs(phi1 + 1), 0.2, 0.8)",
        "--keep",
        "runs",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (h, rows) = table(&out.join("pendulum_sweep.csv"));
    let at = |n: &str| {
        h.iter()
            .position(|c| c == n)
            .unwrap_or_else(|| panic!("{n}: {h:?}"))
    };
    assert_eq!(h.last().map(String::as_str), Some("message"));
    assert_eq!(rows.len(), 2);
    for (k, l) in [0.5, 1.0].into_iter().enumerate() {
        let row = &rows[k];
        assert_eq!(row[at("status")], "completed");
        assert_eq!(row[at("message")], "");
        let cell = |n: &str| -> f64 { row[at(n)].parse().unwrap() };
        let kept = out.join(format!("pendulum_sweep{k}.csv"));
        assert!(out.join(format!("pendulum_sweep{k}.columns.json")).exists());
        assert!(out.join(format!("pendulum_sweep{k}.summary.json")).exists());
        let c = columns(&kept);
        let (t, y, phi) = (&c["t"], &c["bob.y"], &c["bob.phi"]);
        let min_y = y.iter().cloned().fold(f64::INFINITY, f64::min);
        close(cell("lowest_y"), min_y, "lowest_y");
        // the bob falls from y = 0: it must have swung down
        assert!(min_y < -0.4 * l, "{min_y}");
        // first downward crossing of y + l/4 = 0, interpolated
        let s: Vec<f64> = y.iter().map(|y| y + l / 4.0).collect();
        let i = (1..s.len())
            .find(|&i| s[i - 1] > 0.0 && s[i] <= 0.0)
            .unwrap();
        let cross = t[i - 1] + (0.0 - s[i - 1]) / (s[i] - s[i - 1]) * (t[i] - t[i - 1]);
        close(cell("first_below"), cross, "first_below");
        let sq: Vec<f64> = phi.iter().map(|p| p * p).collect();
        close(
            cell("rms(bob.phi)"),
            time_average(t, &sq, 0.5, 1.0).sqrt(),
            "rms(bob.phi)",
        );
        close(
            cell("final(bob.phi)"),
            *phi.last().unwrap(),
            "final(bob.phi)",
        );
        let swing = t
            .iter()
            .zip(phi)
            .filter(|(t, _)| (0.2 - 1e-9..=0.8 + 1e-9).contains(*t))
            .map(|(_, p)| (p + 1.0).abs())
            .fold(f64::NEG_INFINITY, f64::max);
        close(cell("swing"), swing, "swing");
    }
    // the two lengths give two different motions
    assert_ne!(rows[0][at("lowest_y")], rows[1][at("lowest_y")]);
}

/// A bad metric is an error naming the key (in the file) or the flag (on
/// the command line), before anything runs.
#[test]
fn bad_metrics_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let base = example();
    let cases = [
        (
            "column = \"bob.y\"",
            "column = \"chassis_y\"",
            "metric[0].column",
            "chassis_y",
        ),
        (
            "reduce = \"min\"",
            "reduce = \"median\"",
            "metric[0].reduce",
            "median",
        ),
        (
            "reduce = \"min\"",
            "reduce = \"min\"\nwindow = [0.5, 0.5]",
            "metric[0].window",
            "empty",
        ),
        (
            "reduce = \"min\"",
            "reduce = \"min\"\nwindow = [2.0, 3.0]",
            "metric[0].window",
            "no output time",
        ),
        (
            "threshold = 0.0\n",
            "",
            "metric[1].threshold",
            "needs a threshold",
        ),
        (
            "expression = \"bob.y + l/4\"",
            "expression = \"bob.y + q/4\"",
            "metric[1].expression",
            "'q'",
        ),
        (
            "name = \"lowest_y\"",
            "name = \"first_below\"",
            "metric[1].name",
            "also the name",
        ),
    ];
    for (from, to, key, needle) in cases {
        assert!(base.contains(from), "{from}");
        let file = dir.path().join("bad.toml");
        std::fs::write(&file, base.replacen(from, to, 1)).unwrap();
        let o = mbsolve(&["check", file.to_str().unwrap()]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{to}: {e}");
        assert!(
            e.contains(&format!("{key}:")) && e.contains(needle),
            "{to}: {e}"
        );
    }
    let file = dir.path().join("good.toml");
    std::fs::write(&file, &base).unwrap();
    for (metric, needle) in [
        ("rms(nope)", "no column 'nope'"),
        ("median(y1)", "not a reduction"),
        ("mean(y1, 3, 4)", "no output time"),
        ("mean(y1, 0.5)", "both ends"),
        ("lowest_y=max(y1)", "another column"),
    ] {
        let o = mbsolve(&[
            "sweep",
            file.to_str().unwrap(),
            "--param",
            "l=0.5",
            "--metric",
            metric,
            "--out",
            dir.path().join("out").to_str().unwrap(),
        ]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{metric}: {e}");
        assert!(
            e.contains("--metric") || e.contains("metric '"),
            "{metric}: {e}"
        );
        assert!(e.contains(needle), "{metric}: {e}");
        assert!(
            !dir.path().join("out/good_sweep.csv").exists(),
            "{metric}: nothing ran"
        );
    }
}
