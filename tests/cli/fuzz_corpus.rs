//! The fuzz corpus: every file of `tests/corpus/` is a bad input with its
//! command and the outcome it must give. Each runs the binary under a
//! bound on its CPU time (the work it does, not the wall clock, which a
//! loaded machine stretches) and must end with the stated exit status (never a panic, exit 101,
//! or an abort, exit 134), every expected fragment on stderr and, where
//! stated, the expected status in the run's summary.
//!
//! A corpus file starts with header comments, then (optionally) the
//! scenario text:
//!
//! ```text
//! # args: check {file}                     command line; {file} is this file
//! #                                         (after expansion), {scenarios} the
//! #                                         shipped scenarios, {out} a fresh
//! #                                         output directory
//! # exit: 1                                 expected exit status
//! # expect: a fragment of stderr           (any number)
//! # expect-stdout: a fragment of stdout    (any number)
//! # reject: a fragment in neither          (any number)
//! # summary: <stem> <status>               the summary's status (optional)
//! # within: 20                              CPU-time bound [s] (default 20)
//! ```
//!
//! In the scenario text, `@repeat(N, "text")@` stands for `text` repeated
//! N times (large inputs without large files).

use crate::common::process;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

struct Case {
    args: Vec<String>,
    exit: i32,
    expect: Vec<String>,
    expect_stdout: Vec<String>,
    reject: Vec<String>,
    summary: Option<(String, String)>,
    /// CPU-time bound [s]
    within: f64,
    body: String,
}

fn header(path: &Path, text: &str) -> Case {
    let mut c = Case {
        args: Vec::new(),
        exit: -1,
        expect: Vec::new(),
        expect_stdout: Vec::new(),
        reject: Vec::new(),
        summary: None,
        within: 20.0,
        body: String::new(),
    };
    let mut body_from = 0;
    for line in text.lines() {
        let Some(rest) = line.strip_prefix("# ") else {
            break;
        };
        body_from += line.len() + 1;
        let Some((key, value)) = rest.split_once(": ") else {
            continue;
        };
        match key {
            "args" => c.args = value.split_whitespace().map(String::from).collect(),
            "exit" => c.exit = value.trim().parse().expect("exit status"),
            "expect" => c.expect.push(value.to_string()),
            "expect-stdout" => c.expect_stdout.push(value.to_string()),
            "reject" => c.reject.push(value.to_string()),
            "summary" => {
                let (stem, status) = value.trim().split_once(' ').expect("summary: stem status");
                c.summary = Some((stem.into(), status.into()));
            }
            "within" => c.within = value.trim().parse().expect("seconds"),
            _ => {}
        }
    }
    assert!(
        !c.args.is_empty() && c.exit >= 0,
        "{}: needs '# args:' and '# exit:' lines",
        path.display()
    );
    c.body = expand(&text[body_from.min(text.len())..]);
    c
}

/// Expands `@repeat(N, "text")@`.
fn expand(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(at) = rest.find("@repeat(") {
        out.push_str(&rest[..at]);
        let tail = &rest[at + "@repeat(".len()..];
        let (n, tail) = tail.split_once(", \"").expect("@repeat(N, \"text\")@");
        let (text, tail) = tail.split_once("\")@").expect("@repeat(N, \"text\")@");
        out.push_str(&text.repeat(n.trim().parse().expect("repeat count")));
        rest = tail;
    }
    out.push_str(rest);
    out
}

/// Runs one corpus case; adds the CPU seconds its process used to `cpu_s`.
fn run_case(path: &Path, cpu_s: &mut f64) -> Result<(), String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let case = header(path, &text);
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    let file = dir.path().join(path.file_name().unwrap());
    std::fs::write(&file, &case.body).map_err(|e| e.to_string())?;
    let out = dir.path().join("out");
    let scenarios = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let args: Vec<String> = case
        .args
        .iter()
        .map(|a| {
            a.replace("{file}", &file.to_string_lossy())
                .replace("{out}", &out.to_string_lossy())
                .replace("{scenarios}", &scenarios.to_string_lossy())
        })
        .collect();
    let mut child = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .args(&args)
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| e.to_string())?;
    let reader = process::drain(child.stderr.take().unwrap());
    let out_reader = process::drain(child.stdout.take().unwrap());
    let (status, usage) = process::wait_cpu_bounded(&mut child, case.within)?;
    *cpu_s += usage.cpu_s;
    let err = String::from_utf8_lossy(&reader.join().unwrap()).into_owned();
    let stdout = String::from_utf8_lossy(&out_reader.join().unwrap()).into_owned();
    let short = |s: &str| s.chars().take(2000).collect::<String>();
    if status.code() != Some(case.exit) {
        return Err(format!(
            "exit {:?}, expected {}: {}",
            status.code(),
            case.exit,
            short(&err)
        ));
    }
    if err.contains("panicked") || err.contains("overflowed its stack") {
        return Err(format!("crashed: {}", short(&err)));
    }
    for e in &case.expect {
        if !err.contains(e.as_str()) {
            return Err(format!("stderr lacks '{e}': {}", short(&err)));
        }
    }
    for e in &case.expect_stdout {
        if !stdout.contains(e.as_str()) {
            return Err(format!("stdout lacks '{e}': {}", short(&stdout)));
        }
    }
    for e in &case.reject {
        if stdout.contains(e.as_str()) || err.contains(e.as_str()) {
            return Err(format!(
                "output holds '{e}': {}{}",
                short(&stdout),
                short(&err)
            ));
        }
    }
    if let Some((stem, want)) = &case.summary {
        let p = out.join(format!("{stem}.summary.json"));
        let s = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
        let v: serde_json::Value = serde_json::from_str(&s).map_err(|e| e.to_string())?;
        if v["status"] != serde_json::Value::String(want.clone()) {
            return Err(format!("summary status {}, expected {want}", v["status"]));
        }
    }
    Ok(())
}

/// Every corpus file gives its stated outcome.
#[test]
fn every_corpus_input_gives_its_stated_outcome() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 10, "corpus has {} files", files.len());
    let mut cpu_s = 0.0;
    let failures: Vec<String> = files
        .iter()
        .filter_map(|p| {
            run_case(p, &mut cpu_s)
                .err()
                .map(|e| format!("{}: {e}", p.file_name().unwrap().to_string_lossy()))
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} corpus inputs failed:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
    // the whole corpus is rejected cheaply: CPU seconds, not wall time
    assert!(cpu_s < 90.0, "the corpus used {cpu_s:.1} CPU-s");
}
