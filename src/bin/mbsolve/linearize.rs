//! `mbsolve linearize` (in progress).
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `mbsolve linearize`.
#[derive(clap::Args)]
pub struct LinearizeArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
}

/// The command.
pub fn command(_a: &LinearizeArgs) -> Result<ExitCode, String> {
    Err("not yet".into())
}
