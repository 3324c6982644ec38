//! `mbsolve run` writes its files as it goes and tells the truth about
//! them: rows streamed, the CSV renamed into place at the end, the summary
//! replaced atomically ("running" → final status), also on SIGINT/SIGTERM;
//! a killed run leaves no file that claims completion; no writing through
//! symlinks; unwritable outputs are refused before the run.

use crate::common::cli::{exe, mbsolve as run};
use crate::common::process;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

fn fourbar() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios/fourbar.toml")
        .display()
        .to_string()
}

/// A four-bar run long enough to be interrupted (10⁵ s simulated, rows
/// every 0.01 s), stabilized so that its drift never trips the "diverged"
/// guard before the signal (unstabilized it does at t ≈ 6.9 s, which a
/// loaded machine can reach before the signal arrives).
fn spawn_long(out: &Path) -> Child {
    exe()
        .args([
            "run",
            &fourbar(),
            "--set",
            "time.end=1e5",
            "--set",
            "output.dt=0.01",
            "--set",
            "stabilization.alpha=10",
            "--set",
            "stabilization.beta=10",
        ])
        .args(["--progress", "off", "--out", out.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary starts")
}

fn summary(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("fourbar.summary.json")).expect("summary exists");
    serde_json::from_str(&text).expect("summary is complete JSON")
}

/// Wait until the streamed CSV has some rows on disk (an event, not a
/// time): fails if the run ends first or uses 60 CPU-s without writing them.
fn wait_for_rows(child: &mut Child, part: &Path) {
    let rows = || std::fs::metadata(part).map_or(0, |m| m.len()) >= 10_000;
    if let Err(e) = process::wait_for(child, "rows streamed", 60.0, rows) {
        panic!("{}: {e}", part.display());
    }
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
}

/// Every CSV row complete: as many numeric fields as the header.
fn complete_rows(csv: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(csv).unwrap();
    assert!(text.ends_with('\n'), "the last row is complete");
    let mut lines = text.lines();
    let width = lines.next().unwrap().split(',').count();
    lines
        .map(|l| {
            let r: Vec<f64> = l.split(',').map(|v| v.parse().expect("a number")).collect();
            assert_eq!(r.len(), width, "row {l}");
            r
        })
        .collect()
}

#[test]
fn sigint_and_sigterm_end_the_run_with_truthful_files() {
    for sig in ["-INT", "-TERM"] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let mut child = spawn_long(out);
        wait_for_rows(&mut child, &out.join("fourbar.csv.part"));
        assert_eq!(summary(out)["status"], "running");
        signal(&child, sig);
        let o = child.wait_with_output().unwrap();
        assert_eq!(
            o.status.code(),
            Some(130),
            "{sig}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let s = summary(out);
        assert_eq!(s["status"], "interrupted", "{sig}: {s}");
        assert!(s["message"].as_str().unwrap().contains("interrupted"));
        let rows = complete_rows(&out.join("fourbar.csv"));
        assert!(rows.len() > 100);
        assert_eq!(s["output_rows"].as_u64().unwrap() as usize, rows.len());
        // rows are the output grid up to the time reached
        let t_reached = s["t_reached"].as_f64().unwrap();
        let last_t = rows.last().unwrap()[0];
        assert!(
            last_t <= t_reached && t_reached - last_t < 0.01 + 1e-9,
            "{last_t} vs {t_reached}"
        );
        for (k, r) in rows.iter().enumerate() {
            assert!(
                (r[0] - 0.01 * k as f64).abs() < 1e-9 * (1.0 + r[0]),
                "row {k}: t = {}",
                r[0]
            );
        }
        assert!(!out.join("fourbar.csv.part").exists());
        assert_eq!(s["scenario"].as_str().unwrap(), fourbar());
        assert_eq!(s["scenario_sha256"].as_str().unwrap().len(), 64);
    }
}

#[test]
fn a_killed_run_leaves_no_file_that_claims_completion() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    // a previous, completed run in the same directory
    let o = run(&["run", &fourbar(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success());
    assert_eq!(summary(out)["status"], "completed");
    assert!(out.join("fourbar.csv").exists());

    let mut child = spawn_long(out);
    wait_for_rows(&mut child, &out.join("fourbar.csv.part"));
    signal(&child, "-KILL");
    let _ = child.wait();
    let s = summary(out);
    assert_eq!(s["status"], "running", "{s}");
    assert!(
        !out.join("fourbar.csv").exists(),
        "the previous run's CSV must not stay beside a newer summary"
    );
}

#[test]
fn a_failed_run_replaces_the_previous_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    assert!(run(&["run", &fourbar(), "--out", out]).status.success());
    // rk4 with h = 1 blows up: failed (or diverged), never "completed"
    let o = run(&[
        "run",
        &fourbar(),
        "--set",
        "integrator.method=rk4",
        "--set",
        "integrator.step=1",
        "--set",
        "time.end=200",
        "--out",
        out,
    ]);
    assert!(!o.status.success());
    let s = summary(dir.path());
    assert_ne!(s["status"], "completed", "{s}");
    let rows = complete_rows(&dir.path().join("fourbar.csv"));
    assert_eq!(s["output_rows"].as_u64().unwrap() as usize, rows.len());
}

#[test]
fn outputs_never_write_through_symlinks() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let victim = dir.path().join("victim.txt");
    std::fs::write(&victim, "keep me").unwrap();
    for name in ["fourbar.csv", "fourbar.summary.json", "fourbar.csv.part"] {
        std::os::unix::fs::symlink(&victim, out.join(name)).unwrap();
    }
    let o = run(&["run", &fourbar(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep me");
    for name in ["fourbar.csv", "fourbar.summary.json"] {
        let m = std::fs::symlink_metadata(out.join(name)).unwrap();
        assert!(m.file_type().is_file(), "{name} is a regular file now");
    }
    assert_eq!(summary(&out)["status"], "completed");
}

#[test]
fn unwritable_outputs_are_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a_file");
    std::fs::write(&file, "x").unwrap();
    let bad: Vec<PathBuf> = vec![file.join("sub"), PathBuf::from("/proc/mbsolve-no")];
    for out in bad {
        let (o, cpu) = process::output_with_usage(exe().args([
            "run",
            &fourbar(),
            "--set",
            "time.end=1e5",
            "--out",
            out.to_str().unwrap(),
        ]));
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(out.to_str().unwrap()), "names the path: {e}");
        // refused before integrating 10⁵ s (minutes of work): the refusal
        // costs the parse and the checks, well under a CPU-second
        assert!(cpu.cpu_s < 20.0, "{} CPU-s before the refusal", cpu.cpu_s);
    }
}

/// The guards: a blown-up rk4 run and a four-bar drifting apart end
/// "diverged" (exit 1) with the warning and the time on the console; the
/// shipped scenarios stay silent and complete.
#[test]
fn guards_trip_on_nonsense_and_stay_silent_on_the_shipped_scenarios() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let cases: [(&[&str], &str); 2] = [
        (
            &["integrator.method=rk4", "integrator.step=1"],
            "position coordinate|constraint violation",
        ),
        (&["time.end=50"], "constraint violation"),
    ];
    for (sets, what) in cases {
        let mut args = vec![
            "run".to_string(),
            fourbar(),
            "--progress".into(),
            "off".into(),
        ];
        for s in sets {
            args.push("--set".into());
            args.push(s.to_string());
        }
        args.extend(["--out".to_string(), out.to_string()]);
        let o = exe().args(&args).output().unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{sets:?}: {e}");
        assert!(e.contains("diverged"), "{sets:?}: {e}");
        assert!(what.split('|').any(|w| e.contains(w)), "{sets:?}: {e}");
        let s = summary(dir.path());
        assert_eq!(s["status"], "diverged");
        let t = s["t_reached"].as_f64().unwrap();
        let m = s["message"].as_str().unwrap();
        if m.contains("in the output at t = ") {
            // an interpolated row between the last steps, before t_reached
            let at: f64 = m
                .split("in the output at t = ")
                .nth(1)
                .and_then(|r| r.split(',').next())
                .and_then(|v| v.parse().ok())
                .expect("the output time");
            assert!(at <= t, "{s}");
        } else {
            assert!(crate::common::names_time(m, t), "{s}");
        }
        if sets[0] == "time.end=50" {
            // warned first, at the time it happened, before stopping
            assert!(e.contains("warning: constraint violation"), "{e}");
            assert!(t > 2.0 && t < 50.0, "{t}");
        }
    }
    // the energy balance breaks loudly when asked for
    let o = run(&[
        "run",
        &fourbar(),
        "--progress",
        "off",
        "--set",
        "integrator.method=rk4",
        "--set",
        "integrator.step=0.02",
        "--set",
        "output.quantities=[\"energy\"]",
        "--out",
        out,
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("warning: energy balance broken"), "{e}");
    // velocities that do not fit the joints (no consistent assembly): the
    // crank turns, the coupler is at rest — ‖Φ̇‖ = 0.89 m/s from t = 0
    let o = run(&[
        "run",
        &fourbar(),
        "--progress",
        "off",
        "--set",
        "initial.consistent=false",
        "--set",
        "time.end=0.01",
        "--out",
        out,
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("warning: velocity constraint violation") && e.contains("at t = 0e0"),
        "{e}"
    );
    for scen in [
        "scenarios/fourbar.toml",
        "scenarios/falling_rod.toml",
        "scenarios/slider_crank.toml",
        "scenarios/spring_pendulum.toml",
    ] {
        let o = run(&["run", scen, "--progress", "off", "--out", out]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{scen}: {e}");
        assert!(!e.contains("warning"), "{scen}: {e}");
        let stem = Path::new(scen).file_stem().unwrap().to_str().unwrap();
        let text =
            std::fs::read_to_string(dir.path().join(format!("{stem}.summary.json"))).unwrap();
        let s: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(s["status"], "completed");
        assert!(s["warnings"].as_array().unwrap().is_empty(), "{scen}: {s}");
    }
}

/// Peak resident memory (kB) of a run, as the run's summary reports it
/// (`peak_memory_kb`: the program's own `VmHWM`), and the rows of its CSV.
/// The kernel's `ru_maxrss` of the reaped child is no measure of the
/// program alone: it also counts this test process's peak up to the
/// child's `exec`, which other tests of this binary running beside it
/// raise; it bounds the summary's figure from above.
fn peak_rss_kb(args: &[&str]) -> (u64, usize) {
    let mut child = exe()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let (status, usage) = process::wait_with_usage(&mut child);
    assert!(status.success(), "{args:?}: {status}");
    let out = Path::new(args[args.len() - 1]);
    let peak = summary(out)["peak_memory_kb"]
        .as_u64()
        .expect("the summary's peak_memory_kb");
    assert!(
        peak <= usage.max_rss_kb,
        "{peak} kB > ru_maxrss {} kB",
        usage.max_rss_kb
    );
    let rows = std::fs::read_to_string(out.join("fourbar.csv"))
        .unwrap()
        .lines()
        .count()
        - 1;
    (peak, rows)
}

/// Streaming keeps memory bounded independently of the number of outputs:
/// 10× the rows, not more memory (a trajectory kept in memory would grow
/// by ≈ 150 B per row: 27 MB more here).
#[test]
fn memory_does_not_grow_with_the_number_of_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let mut peaks = Vec::new();
    for (end, sub) in [("20", "a"), ("200", "b")] {
        let out = dir.path().join(sub);
        let out = out.to_str().unwrap();
        let (kb, rows) = peak_rss_kb(&[
            "run",
            &fourbar(),
            "--progress",
            "off",
            "--set",
            "stabilization.alpha=10",
            "--set",
            "stabilization.beta=10",
            "--set",
            &format!("time.end={end}"),
            "--set",
            "output.dt=0.001",
            "--out",
            out,
        ]);
        peaks.push((kb, rows));
    }
    let ((small, r_small), (big, r_big)) = (peaks[0], peaks[1]);
    assert_eq!(r_small, 20_001);
    assert_eq!(r_big, 200_001);
    assert!(small > 0 && big > 0, "peak_memory_kb: {small} {big}");
    assert!(
        big < small + 8_000,
        "peak RSS {small} kB at {r_small} rows, {big} kB at {r_big} rows"
    );
}

/// The integrator's notices reach the console when they occur (through the
/// observer, before the run ends), each once, and the summary counts them.
#[test]
fn newton_failures_are_printed_as_they_occur() {
    let dir = tempfile::tempdir().unwrap();
    let rod = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/falling_rod.toml");
    let o = exe()
        .arg("run")
        .arg(&rod)
        .args([
            "--set",
            "integrator.method=genalpha",
            "--set",
            "integrator.step=1e-3",
        ])
        .args([
            "--set",
            "integrator.rho_inf=1",
            "--set",
            "time.end=0.2",
            "--progress",
            "off",
        ])
        .args(["--out", dir.path().to_str().unwrap()])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{e}");
    let text = std::fs::read_to_string(dir.path().join("falling_rod.summary.json")).unwrap();
    let s: serde_json::Value = serde_json::from_str(&text).unwrap();
    let failures = s["newton_failures"].as_u64().unwrap() as usize;
    assert!(failures > 0, "the contact onset cuts the step: {s}");
    let printed = e.matches("warning: Newton failed at t = ").count();
    assert_eq!(printed, failures.min(20), "{e}");
    assert!(
        e.contains(&format!("warning: {failures} Newton failures")),
        "{e}"
    );
}

/// A fixed-step implicit run whose step keeps being cut (the trapezoidal
/// rule on the index-3 four-bar at h = 5e-3: its constraint-velocity error
/// is undamped and the energy blows up by t ≈ 0.6 s, after which Newton
/// fails at every attempt) crawled on at h ≈ 6e-10 s for millions of
/// steps, neither finishing nor failing. It must fail, say where and why,
/// and keep the rows computed so far.
#[test]
fn a_fixed_step_run_that_crawls_fails_and_keeps_its_rows() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = run(&[
        "run",
        &fourbar(),
        "--progress",
        "off",
        "--set",
        "integrator.method=\"newmark\"",
        "--set",
        "integrator.rho_inf=1",
        "--set",
        "integrator.step=5e-3",
        "--set",
        "time.end=20",
        "--out",
        out,
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    let s = summary(dir.path());
    assert_eq!(s["status"], "failed", "{s}");
    let msg = s["message"].as_str().unwrap();
    assert!(msg.contains("keeps being cut"), "{msg}");
    let t = s["t_reached"].as_f64().unwrap();
    assert!(t > 0.3 && t < 1.0, "{t}");
    // 10 × the 4000 steps h needs, plus the slack
    assert!(s["steps"].as_u64().unwrap() <= 41_001, "{s}");
    let rows = s["output_rows"].as_u64().unwrap();
    assert!(rows > 30, "{rows}");
    let csv = std::fs::read_to_string(dir.path().join("fourbar.csv")).unwrap();
    assert_eq!(csv.lines().count() as u64, rows + 1, "header + the rows");
}

/// Two SIGINTs in a row, back to back and a few milliseconds apart (the
/// second landing while the run steps on or while its files are being
/// finished): whichever path ends the process (the run's own interrupted
/// end, or the second signal's immediate exit), the summary says
/// "interrupted", never "running"; it says the table is unfinished only
/// when the `.part` file is there, and complete only when the table is;
/// no lock and no temporary file stay behind.
#[test]
fn a_second_sigint_leaves_an_interrupted_summary() {
    for gap in ["", "sleep 0.003;", "sleep 0.02;"] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let mut child = spawn_long(out);
        wait_for_rows(&mut child, &out.join("fourbar.csv.part"));
        // both signals from one process
        let ok = Command::new("sh")
            .args([
                "-c",
                &format!("kill -INT {0}; {gap} kill -INT {0}", child.id()),
            ])
            .status()
            .unwrap();
        assert!(ok.success());
        let st = child.wait().unwrap();
        assert_eq!(st.code(), Some(130), "{gap}: {st:?}");
        let s = summary(out);
        assert_eq!(s["status"], "interrupted", "{gap}: {s}");
        let msg = s["message"].as_str().unwrap();
        let part = out.join("fourbar.csv.part");
        let table = out.join("fourbar.csv");
        if msg.contains("the table was not finished") {
            assert!(part.exists(), "{gap}: {msg}");
            assert!(msg.contains(&part.display().to_string()), "{msg}");
        } else if msg.contains("is complete up to where the first signal stopped") {
            assert!(!part.exists() && table.exists(), "{gap}: {msg}");
            assert!(complete_rows(&table).len() > 100);
        } else {
            // the run's own end: the full summary
            assert!(msg.contains("interrupted by a signal"), "{gap}: {msg}");
            let rows = complete_rows(&table);
            assert_eq!(s["output_rows"].as_u64().unwrap() as usize, rows.len());
        }
        let left: Vec<String> = std::fs::read_dir(out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp") || n.ends_with(".lock"))
            .collect();
        assert!(left.is_empty(), "{gap}: left behind {left:?}");
    }
}

/// A table that cannot be written (the file-size limit: `ulimit -f`) ends
/// the run as "failed" with the error in its summary, not "running", and
/// leaves no lock — whether the shell ignores SIGXFSZ or, as by default,
/// the signal would kill the process (the binary ignores it, so the write
/// fails with EFBIG).
#[test]
fn a_file_too_large_error_ends_with_a_failed_summary() {
    let dir = tempfile::tempdir().unwrap();
    // a limit between the table's size estimated before the run (a lower
    // bound: 17 bytes a CSV value) and its true size, which the run
    // reaches only while writing: measured by the same run unlimited
    let args = "--set time.end=0.2 --set output.dt=1e-5 --progress off";
    let full = dir.path().join("full");
    let o = Command::new("sh")
        .args([
            "-c",
            &format!(
                "exec {} run {} {args} --out {}",
                env!("CARGO_BIN_EXE_mbsolve"),
                fourbar(),
                full.display()
            ),
        ])
        .output()
        .unwrap();
    assert!(o.status.success());
    let csv = std::fs::read_to_string(full.join("fourbar.csv")).unwrap();
    let cols = csv.lines().next().unwrap().split(',').count();
    let estimate = 20001 * cols * 17;
    let blocks = (estimate + csv.len()) / 2 / 512;
    assert!(blocks * 512 > estimate + 512 && blocks * 512 + 512 < csv.len());
    for trap in ["trap '' XFSZ; ", ""] {
        let out = dir
            .path()
            .join(if trap.is_empty() { "default" } else { "trap" });
        let o = Command::new("sh")
            .args([
                "-c",
                &format!(
                    "{trap}ulimit -f {blocks}; exec {} run {} {args} --out {}",
                    env!("CARGO_BIN_EXE_mbsolve"),
                    fourbar(),
                    out.display()
                ),
            ])
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        // an output error: exit 2, as any file the run cannot write
        assert_eq!(o.status.code(), Some(2), "{trap}: {e}");
        let s = summary(&out);
        assert_eq!(s["status"], "failed", "{trap}: {s}");
        assert!(
            s["message"].as_str().unwrap().contains("File too large"),
            "{s}"
        );
        assert!(!out.join("fourbar.lock").exists(), "{trap}");
        assert!(
            out.join("fourbar.csv.part").exists(),
            "{trap}: the rows written"
        );
    }
}

/// Two runs into one `--out`: the second refuses up front, naming the
/// first one's process, and leaves the first one's files alone; a lock
/// left by a killed run is taken over.
#[test]
fn a_second_run_into_the_same_files_refuses_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    let mut child = spawn_long(out);
    wait_for_rows(&mut child, &out.join("fourbar.csv.part"));
    let o = run(&["run", &fourbar(), "--out", out.to_str().unwrap()]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains(&format!("another mbsolve run (process {})", child.id())),
        "{e}"
    );
    assert_eq!(summary(out)["status"], "running");
    assert!(out.join("fourbar.csv.part").exists());
    signal(&child, "-KILL");
    let _ = child.wait();
    assert!(out.join("fourbar.lock").exists());
    // the killed run's lock is stale: the next run takes it and ends clean
    let o = run(&["run", &fourbar(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(summary(out)["status"], "completed");
    assert!(!out.join("fourbar.lock").exists());
}

/// The table's size is estimated before the run (rows × columns × bytes
/// per value) against the file-size limit and the free space: 5e7 rows of
/// the four-bar cannot fit under `ulimit -f`; refused before any file.
#[test]
fn a_table_larger_than_the_space_is_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = Command::new("sh")
        .args([
            "-c",
            &format!(
                "ulimit -f 100000; exec {} run {} --set output.dt=4e-8 --progress off --out {}",
                env!("CARGO_BIN_EXE_mbsolve"),
                fourbar(),
                out.display()
            ),
        ])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    // 5e7 + 1 rows; the limit: 100000 blocks of 512 bytes
    assert!(e.contains("(50000001 rows × "), "{e}");
    assert!(e.contains("file-size limit of 51.200 MB"), "{e}");
    assert!(!out.join("fourbar.summary.json").exists());
    // without the limit, against the free space: the falling rod of 10⁴
    // segments (10⁴ rows of 3·10⁴ columns or more) at 1e-6 s: 0.5 TB at least
    let rod = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/falling_rod.toml");
    let o = run(&[
        "run",
        rod.to_str().unwrap(),
        "--set",
        "rod.segments=10000",
        "--set",
        "output.dt=1e-6",
        "--out",
        out.to_str().unwrap(),
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("free on its file system"), "{e}");
    assert!(!out.join("falling_rod.summary.json").exists());
}
