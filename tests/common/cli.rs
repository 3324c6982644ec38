//! The `mbsolve` binary as the CLI tests call it: run from the package
//! root (so `scenarios/…` paths resolve), without Rust backtraces (so a
//! panic is the message, not a trace), output captured.

use std::path::Path;
use std::process::{Command, Output};

/// The binary, to be given arguments: run from the package root, with
/// `RUST_BACKTRACE=0`.
pub fn exe() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_mbsolve"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RUST_BACKTRACE", "0");
    c
}

/// Runs the binary with `args` to its end; its status and output.
pub fn mbsolve(args: &[&str]) -> Output {
    exe().args(args).output().expect("binary runs")
}

/// stderr of a finished command, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// stdout of a finished command, as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The absolute path of the shipped scenario `name` (`scenarios/NAME`).
pub fn scenario(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name)
        .to_string_lossy()
        .into_owned()
}
