//! `mbsolve sweep` beyond one machine: `--shard I/N` and `--merge` give the
//! table of one unsharded sweep; bad sharding and parameter requests are
//! clear errors.

use crate::common::cli::{mbsolve, stderr};
use std::path::Path;
use std::process::{Command, Output};

/// The sweep's arguments with `extra` appended.
fn sweep(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "sweep",
        "scenarios/fourbar.toml",
        "--param",
        "stabilization.alpha=0,1,5",
        "--param",
        "initial.incorrect=false,true",
        "--set",
        "stabilization.rule=equal",
        "--set",
        "time.end=0.2",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    mbsolve(&args)
}

/// The table's rows without the wall-time column.
fn rows_without_wall_time(path: &Path) -> Vec<Vec<String>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let h = r.headers().unwrap().clone();
    let wall = h.iter().position(|c| c == "wall_s").unwrap();
    let mut out = vec![h
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != wall)
        .map(|(_, c)| c.to_string())
        .collect::<Vec<_>>()];
    for rec in r.records() {
        out.push(
            rec.unwrap()
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != wall)
                .map(|(_, c)| c.to_string())
                .collect(),
        );
    }
    out
}

#[test]
fn shards_merge_into_the_table_of_one_sweep() {
    let whole = tempfile::tempdir().unwrap();
    let o = sweep(whole.path(), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let expected = rows_without_wall_time(&whole.path().join("fourbar_sweep.csv"));
    assert_eq!(expected.len(), 1 + 6);

    let parts = tempfile::tempdir().unwrap();
    for i in ["2/2", "1/2"] {
        let o = sweep(parts.path(), &["--shard", i]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("shard {i}: 3/3 runs done")),
            "{}",
            stderr(&o)
        );
    }
    // shard 2 of 2 holds runs 1, 3, 5 of the product, each with its summary
    let s2 = std::fs::read_to_string(parts.path().join("fourbar_sweep.shard-2-of-2.csv")).unwrap();
    let runs: Vec<&str> = s2
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(runs, ["1", "3", "5"]);
    for k in 0..6 {
        assert!(parts
            .path()
            .join(format!("fourbar_sweep{k}.summary.json"))
            .exists());
    }
    let o = sweep(parts.path(), &["--merge"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let merged = rows_without_wall_time(&parts.path().join("fourbar_sweep.csv"));
    assert_eq!(merged, expected);
}

#[test]
fn merge_refuses_missing_and_stale_shards() {
    let dir = tempfile::tempdir().unwrap();
    let o = sweep(dir.path(), &["--merge"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no shard tables"), "{}", stderr(&o));

    let o = sweep(dir.path(), &["--shard", "1/3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = sweep(dir.path(), &["--merge"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("shard(s) 2, 3 of 3 missing"),
        "{}",
        stderr(&o)
    );

    let o = sweep(dir.path(), &["--shard", "2/2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = sweep(dir.path(), &["--merge"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("remove stale tables"), "{}", stderr(&o));
}

#[test]
fn bad_shards_and_parameters_are_named() {
    let dir = tempfile::tempdir().unwrap();
    for bad in ["0/2", "3/2", "1/0", "x/2", "2"] {
        let o = sweep(dir.path(), &["--shard", bad]);
        assert_eq!(o.status.code(), Some(2), "{bad}");
        assert!(
            stderr(&o).contains(&format!("--shard {bad}: expected I/N")),
            "{}",
            stderr(&o)
        );
    }
    let o = sweep(dir.path(), &["--param", "stabilization.alpha=7"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--param stabilization.alpha: the key is given twice"),
        "{}",
        stderr(&o)
    );
    let o = sweep(dir.path(), &["--set", "initial.incorrect=true"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--param initial.incorrect: the key is also fixed by --set"),
        "{}",
        stderr(&o)
    );
}

/// A sweep that runs its runs side by side (two threads) runs each of them
/// on one thread, not with a team per run as well; a scenario that forces
/// two threads keeps them. Read from the runs' summaries.
#[test]
fn runs_side_by_side_each_run_on_one_thread() {
    for (set, expect) in [(None, "1"), (Some("integrator.threads=2"), "2")] {
        let dir = tempfile::tempdir().unwrap();
        let mut args = vec![
            "sweep",
            "scenarios/fourbar.toml",
            "--param",
            "stabilization.alpha=0,1",
            "--set",
            "time.end=0.05",
            "--out",
            dir.path().to_str().unwrap(),
        ];
        if let Some(s) = set {
            args.extend(["--set", s]);
        }
        let o = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
            .args(&args)
            .env("RAYON_NUM_THREADS", "2")
            .env_remove("MBSOLVE_THREADS")
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("binary runs");
        assert!(o.status.success(), "{}", stderr(&o));
        for k in 0..2 {
            let p = dir.path().join(format!("fourbar_sweep{k}.summary.json"));
            let s: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
            assert_eq!(s["threads_setting"], expect, "{set:?} run {k}");
            if expect == "1" {
                assert_eq!(s["halves_split"], 0);
                assert_eq!(s["threads_rule"]["decision"], "one");
            }
        }
    }
}

/// SIGTERM on a sweep (and SIGINT, the same handler) ends the runs in
/// progress at their next step, starts no new ones and still writes the
/// table with every finished run (exit 130). The signal is sent after the
/// first run reported done on stderr (an event, not a sleep); 400 runs of
/// ~0.05 s each on two threads cannot all finish in between.
#[test]
fn sigterm_on_a_sweep_keeps_finished_runs_and_the_table() {
    use std::io::BufRead;
    let dir = tempfile::tempdir().unwrap();
    let values: Vec<String> = (0..400)
        .map(|k| format!("{}", 1.0 + k as f64 * 1e-3))
        .collect();
    let param = format!("body[0].mass={}", values.join(","));
    let mut child = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .args([
            "sweep",
            "scenarios/fourbar.toml",
            "--param",
            &param,
            "--set",
            "time.end=1.0",
            "--out",
            dir.path().to_str().unwrap(),
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RAYON_NUM_THREADS", "2")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    let mut seen = Vec::new();
    for l in lines.by_ref() {
        let l = l.unwrap();
        let done = l.contains("runs done");
        seen.push(l);
        if done {
            break;
        }
    }
    let kill = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let status = child.wait().unwrap();
    let all = [seen, rest].concat().join("\n");
    assert_eq!(status.code(), Some(130), "{all}");
    assert!(all.contains("sweep interrupted by a signal"), "{all}");
    // a run not started is said so once, not as an error
    for twice in ["not run: not run", "error: not run"] {
        assert!(!all.contains(twice), "'{twice}' in:\n{all}");
    }
    let table = std::fs::read_to_string(dir.path().join("fourbar_sweep.csv")).unwrap();
    let rows: Vec<&str> = table.lines().skip(1).collect();
    assert_eq!(rows.len(), 400, "every run has its row");
    let completed = rows.iter().filter(|r| r.contains(",completed,")).count();
    let not_run = rows.iter().filter(|r| r.contains("not run")).count();
    assert!(completed >= 1, "{table}");
    assert!(not_run >= 1, "{table}");
    // every completed run has its summary
    let summaries = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".summary.json")
        })
        .count();
    assert!(summaries >= completed, "{summaries} < {completed}");
}

/// `--param` by parameter name, as a range and as a TOML array whose
/// element is an expression with a comma inside `max(…)`: 3 × 2 runs in
/// product order, each with its values.
#[test]
fn parameters_swept_by_name_ranges_and_arrays() {
    let dir = tempfile::tempdir().unwrap();
    let o = mbsolve(&[
        "sweep",
        "scenarios/quarter_car_parameters.toml",
        "--param",
        "c_s=linspace(500, 1500, 3)",
        "--param",
        "road_a=[0.01, \"max(0.02, r/10)\"]",
        "--set",
        "time.end=0.05",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = rows_without_wall_time(&dir.path().join("quarter_car_parameters_sweep.csv"));
    assert_eq!(rows[0][..3], ["c_s", "road_a", "status"]);
    let got: Vec<(&str, &str, &str)> = rows[1..]
        .iter()
        .map(|r| (r[0].as_str(), r[1].as_str(), r[2].as_str()))
        .collect();
    let a = "\"max(0.02, r/10)\"";
    assert_eq!(
        got,
        [
            ("500", "0.01", "completed"),
            ("500", a, "completed"),
            ("1000", "0.01", "completed"),
            ("1000", a, "completed"),
            ("1500", "0.01", "completed"),
            ("1500", a, "completed"),
        ]
    );
    // the road amplitude reached the model: r/10 = 0.03 > 0.02 differs
    // from 0.01 in the run's steps or constraint history
    assert_ne!(rows[1][3..], rows[2][3..]);
    for (p, needle) in [
        ("c_s=linspace(1, 2)", "linspace(a, b, n)"),
        ("c_s=[1, 2", "not a TOML array"),
        ("c_s=max(1, 2", "missing ')'"),
        ("c_s=1,\"2", "unclosed"),
        ("c_s=logspace(0, 1, 3)", "a, b > 0"),
    ] {
        let o = mbsolve(&[
            "sweep",
            "scenarios/quarter_car_parameters.toml",
            "--param",
            p,
            "--out",
            dir.path().to_str().unwrap(),
        ]);
        assert!(!o.status.success());
        assert!(stderr(&o).contains(needle), "{p}: {}", stderr(&o));
    }
}
