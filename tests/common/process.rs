//! Child processes judged by the work they do, not by the wall clock: a
//! process's CPU time does not grow when other processes load the machine,
//! its wall time does. Tests bound the CPU seconds a command may use, read
//! its peak resident memory from the kernel when it is reaped (`wait4`),
//! and wait for events (a file, a line) instead of sleeping for a guessed
//! time.

use std::io::Read;
use std::os::unix::process::ExitStatusExt;
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

/// What the kernel accounted to a reaped child.
#[derive(Clone, Copy, Debug)]
pub struct Usage {
    /// user + system CPU time \[s\]
    pub cpu_s: f64,
    /// peak resident set size \[kB\] (`ru_maxrss`, Linux): the child's,
    /// and also its spawner's up to the child's `exec` (the kernel keeps
    /// the larger), so it bounds the child's own peak from above
    pub max_rss_kb: u64,
}

/// CPU seconds (user + system) process `pid` has used so far, from
/// `/proc/PID/stat` (Linux; also readable while it is a zombie), or `None`
/// when it is gone.
pub fn cpu_so_far(pid: u32) -> Option<f64> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // fields after the command name "(…)": state is field 3, utime 14, stime 15
    let rest = &text[text.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    // SAFETY: sysconf has no preconditions
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    Some(ticks / hz)
}

fn usage_of(ru: &libc::rusage) -> Usage {
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    Usage {
        cpu_s: secs(ru.ru_utime) + secs(ru.ru_stime),
        max_rss_kb: ru.ru_maxrss.max(0) as u64,
    }
}

/// Reaps `child` if it has ended (`wait4`, `WNOHANG`): its status and usage.
/// After this the `Child` must not be waited for again.
fn try_reap(child: &Child, block: bool) -> Option<(ExitStatus, Usage)> {
    let mut status = 0;
    // SAFETY: an all-zero rusage is a valid value to be overwritten
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    let flags = if block { 0 } else { libc::WNOHANG };
    // SAFETY: `status` and `ru` are valid for writes; the pid is our child
    let r = unsafe { libc::wait4(child.id() as libc::pid_t, &mut status, flags, &mut ru) };
    assert!(r >= 0, "wait4: {}", std::io::Error::last_os_error());
    (r > 0).then(|| (ExitStatus::from_raw(status), usage_of(&ru)))
}

/// Waits for `child` to end and returns its exit status and the kernel's
/// account of its CPU time and peak memory.
pub fn wait_with_usage(child: &mut Child) -> (ExitStatus, Usage) {
    try_reap(child, true).expect("a blocking wait4 reaps the child")
}

/// Waits for `child` to end while it uses at most `cpu_limit_s` CPU
/// seconds; a child past the limit is killed and reported. A child that is
/// blocked (below 1 % of a CPU over at least a minute: a deadlock, not a
/// slow machine, whose runnable processes still get several percent) is
/// killed and reported too, so that a hang fails instead of stalling the
/// suite.
pub fn wait_cpu_bounded(
    child: &mut Child,
    cpu_limit_s: f64,
) -> Result<(ExitStatus, Usage), String> {
    let start = Instant::now();
    loop {
        if let Some(done) = try_reap(child, false) {
            return Ok(done);
        }
        let cpu = cpu_so_far(child.id()).unwrap_or(0.0);
        let wall = start.elapsed().as_secs_f64();
        let verdict = if cpu > cpu_limit_s {
            Some(format!("used more than {cpu_limit_s} CPU-s"))
        } else if wall > 60.0 && cpu < 0.01 * wall {
            Some(format!("blocked: {cpu:.2} CPU-s in {wall:.0} s"))
        } else {
            None
        };
        if let Some(v) = verdict {
            let _ = child.kill();
            let _ = try_reap(child, true);
            return Err(v);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Polls `ready` until it holds, while `child` runs and has used at most
/// `cpu_limit_s` CPU seconds: `Err` names what ended the wait (the child's
/// end, its CPU budget, or `what` never happening in a blocked child).
pub fn wait_for(
    child: &mut Child,
    what: &str,
    cpu_limit_s: f64,
    mut ready: impl FnMut() -> bool,
) -> Result<(), String> {
    let start = Instant::now();
    loop {
        if ready() {
            return Ok(());
        }
        if let Some(st) = child.try_wait().map_err(|e| e.to_string())? {
            return Err(format!("the process ended ({st}) before {what}"));
        }
        let cpu = cpu_so_far(child.id()).unwrap_or(0.0);
        let wall = start.elapsed().as_secs_f64();
        if cpu > cpu_limit_s {
            return Err(format!("{cpu:.1} CPU-s used and not yet {what}"));
        }
        if wall > 60.0 && cpu < 0.01 * wall {
            return Err(format!(
                "blocked ({cpu:.2} CPU-s in {wall:.0} s) before {what}"
            ));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs `cmd` to its end with stdout and stderr captured (read while it
/// runs, so a chatty child never blocks on a full pipe): its output and
/// the kernel's account of its CPU time and peak memory.
pub fn output_with_usage(cmd: &mut Command) -> (Output, Usage) {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary starts");
    let out = drain(child.stdout.take().unwrap());
    let err = drain(child.stderr.take().unwrap());
    let (status, usage) = wait_with_usage(&mut child);
    let o = Output {
        status,
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
    };
    (o, usage)
}

/// Reads `r` to its end on a thread of its own.
pub fn drain(mut r: impl Read + Send + 'static) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut v = Vec::new();
        r.read_to_end(&mut v).ok();
        v
    })
}
