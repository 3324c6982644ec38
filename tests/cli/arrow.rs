//! `output.format = "arrow"`: the run's table as an Apache Arrow IPC file,
//! read back with arrow's own reader — the same values as the CSV run
//! (to the CSV's 13 digits), units in the field metadata, a valid file
//! also after SIGINT, and a clear error for an unknown format.
#![cfg(feature = "arrow")]

use crate::common::cli::{exe, mbsolve as run};
use crate::common::process;
use arrow_array::{Array, Float64Array};
use arrow_ipc::reader::FileReader;
use std::path::Path;
use std::process::{Command, Stdio};

/// Columns (name, unit, values) of an Arrow IPC file.
fn read_arrow(path: &Path) -> Vec<(String, String, Vec<f64>)> {
    let f = std::fs::File::open(path).unwrap();
    let reader = FileReader::try_new(f, None).unwrap();
    let schema = reader.schema();
    let mut cols: Vec<(String, String, Vec<f64>)> = schema
        .fields()
        .iter()
        .map(|f| (f.name().clone(), f.metadata()["unit"].clone(), Vec::new()))
        .collect();
    for batch in reader {
        let batch = batch.unwrap();
        for (k, c) in cols.iter_mut().enumerate() {
            let a = batch
                .column(k)
                .as_any()
                .downcast_ref::<Float64Array>()
                .unwrap();
            c.2.extend((0..a.len()).map(|i| a.value(i)));
        }
    }
    cols
}

#[test]
fn arrow_table_equals_the_csv_table() {
    let dir = tempfile::tempdir().unwrap();
    let common = [
        "run",
        "scenarios/fourbar.toml",
        "--progress",
        "off",
        "--set",
        "output.quantities=[\"velocities\",\"reactions\",\"energy\"]",
    ];
    let (a, c) = (dir.path().join("a"), dir.path().join("c"));
    let mut args = common.to_vec();
    args.extend([
        "--set",
        "output.format=\"arrow\"",
        "--out",
        a.to_str().unwrap(),
    ]);
    let o = run(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut args = common.to_vec();
    args.extend(["--out", c.to_str().unwrap()]);
    assert!(run(&args).status.success());
    assert!(!a.join("fourbar.csv").exists() && !a.join("fourbar.arrow.part").exists());
    let cols = read_arrow(&a.join("fourbar.arrow"));
    let text = std::fs::read_to_string(c.join("fourbar.csv")).unwrap();
    let mut lines = text.lines();
    let names: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(cols.len(), names.len());
    assert_eq!(rows.len(), 1001);
    let units: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("fourbar.columns.json")).unwrap())
            .unwrap();
    for (k, (name, unit, values)) in cols.iter().enumerate() {
        assert_eq!(name, names[k]);
        assert_eq!(unit, units[k]["unit"].as_str().unwrap(), "{name}");
        assert_eq!(values.len(), rows.len());
        for (v, r) in values.iter().zip(&rows) {
            let w = r[k];
            assert!(
                (v - w).abs() <= 1e-12 * v.abs().max(1e-300) || (v.is_nan() && w.is_nan()),
                "{name}: {v} vs {w}"
            );
        }
    }
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("fourbar.summary.json")).unwrap())
            .unwrap();
    assert_eq!(s["output_rows"].as_u64().unwrap() as usize, rows.len());
}

#[test]
fn an_interrupted_arrow_run_leaves_a_valid_file_with_its_rows() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    let mut child = exe()
        .args([
            "run",
            "scenarios/fourbar.toml",
            "--set",
            "time.end=1e5",
            "--set",
            "output.dt=0.01",
            "--set",
            "output.format=\"arrow\"",
            "--set",
            "stabilization.alpha=10",
            "--set",
            "stabilization.beta=10",
            "--progress",
            "plain",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // An event, not a sleep: the plain progress line (every 10 s) states
    // the simulated time; interrupt once the run is past t = 0.2 s, so at
    // least 21 rows at dt = 0.01 were computed whatever the machine's load.
    use std::io::BufRead as _;
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    let mut seen = Vec::new();
    loop {
        let line = lines
            .next()
            .unwrap_or_else(|| panic!("the run ended before t = 0.2 s: {seen:?}"))
            .unwrap();
        let t = line
            .split("t = ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|v| v.parse::<f64>().ok());
        seen.push(line);
        if t.is_some_and(|t| t >= 0.2) {
            break;
        }
    }
    assert!(Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{rest:?}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("fourbar.summary.json")).unwrap())
            .unwrap();
    assert_eq!(s["status"], "interrupted");
    let cols = read_arrow(&out.join("fourbar.arrow"));
    let t = &cols[0].2;
    assert!(t.len() > 20, "{} rows", t.len());
    assert_eq!(s["output_rows"].as_u64().unwrap() as usize, t.len());
    for (k, v) in t.iter().enumerate() {
        assert!(
            (v - 0.01 * k as f64).abs() < 1e-9 * (1.0 + v),
            "row {k}: {v}"
        );
    }
}

#[test]
fn unknown_format_is_a_clear_error() {
    let o = run(&[
        "run",
        "scenarios/fourbar.toml",
        "--set",
        "output.format=\"parquet\"",
        "--out",
        tempfile::tempdir().unwrap().path().to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("output.format") && e.contains("'parquet'") && e.contains("csv or arrow"),
        "{e}"
    );
}

/// A SIGKILLed Arrow run leaves `.arrow.part` without a footer (no reader
/// opens it); `mbsolve recover` writes its complete batches as a finished
/// file: the output grid from t = 0, every row flushed before the kill.
#[test]
fn a_killed_arrow_run_is_recovered() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    let mut child = exe()
        .args([
            "run",
            "scenarios/fourbar.toml",
            "--set",
            "time.end=5e3",
            "--set",
            "output.dt=1e-4",
            "--set",
            "output.format=\"arrow\"",
            "--set",
            "stabilization.alpha=10",
            "--set",
            "stabilization.beta=10",
            "--progress",
            "off",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // the first record batch (8 MB of values) is on disk
    let part = out.join("fourbar.arrow.part");
    // an event, bounded by the run's CPU time (not the wall clock)
    let batch = || std::fs::metadata(&part).map_or(0, |m| m.len()) >= 1 << 23;
    if let Err(e) = process::wait_for(&mut child, "a batch written", 120.0, batch) {
        panic!("{e}");
    }
    assert!(Command::new("kill")
        .args(["-KILL", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    let _ = child.wait();
    assert!(
        FileReader::try_new(std::fs::File::open(&part).unwrap(), None).is_err(),
        "a killed file has no footer"
    );
    // the lock of the killed run does not stop the recovery or a new run
    let o = run(&["recover", part.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let cols = read_arrow(&out.join("fourbar.arrow"));
    let t = &cols[0].2;
    assert!(t.len() > 1000, "{} rows", t.len());
    assert!(
        stdout.contains(&format!("({} rows recovered)", t.len())),
        "{stdout}"
    );
    for (k, v) in t.iter().enumerate() {
        assert!(
            (v - 1e-4 * k as f64).abs() < 1e-9 * (1.0 + v),
            "row {k}: {v}"
        );
    }
    // a file that is not Arrow: a clear error
    std::fs::write(out.join("x.part"), "t,x\n0,1\n").unwrap();
    let o = run(&["recover", out.join("x.part").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not an Arrow IPC file"));
}
