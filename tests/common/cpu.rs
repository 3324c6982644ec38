//! CPU time of a child process, for tests that bound how much work a
//! command does: unlike its wall time, its CPU time does not grow when the
//! machine is loaded by other processes. Include with
//! `#[path = "common/cpu.rs"] mod cpu;`.

use std::process::{Command, Output};

/// Run `program args…` under `sh`, whose `times` reports the user and
/// system CPU time of its children (POSIX): the output of the program and
/// its CPU seconds (user + system). The program's exit status is kept.
pub fn output_with_cpu(program: &str, args: &[&str]) -> (Output, f64) {
    let mut o = Command::new("sh")
        .arg("-c")
        .arg("\"$@\"; s=$?; times >&2; exit $s")
        .arg("sh")
        .arg(program)
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("sh starts");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let mut lines: Vec<&str> = err.lines().collect();
    // the last line of `times`: the children's user and system time
    let children = lines.pop().unwrap_or_default().to_string();
    lines.pop(); // the shell's own times
    let secs = |v: &str| -> f64 {
        // "1m2.345s" (dash, bash)
        let v = v.trim_end_matches('s');
        match v.split_once('m') {
            Some((m, s)) => {
                m.parse::<f64>().unwrap_or(f64::NAN) * 60.0 + s.parse::<f64>().unwrap_or(f64::NAN)
            }
            None => f64::NAN,
        }
    };
    let cpu: f64 = children.split_whitespace().map(secs).sum();
    assert!(cpu.is_finite(), "no `times` line: {err}");
    o.stderr = lines.join("\n").into_bytes();
    (o, cpu)
}
