//! Problem A, the four-bar of the paper (docs/problems.md, §A): the shipped
//! `scenarios/fourbar.toml` parsed with `--set`-style overrides.

use mbsolve::scenario::{self, Scenario, FOURBAR_TOML};

/// The shipped four-bar with `overrides` (`"key=value"`, as `--set`).
pub fn fourbar(overrides: &[&str]) -> Scenario {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    scenario::parse(FOURBAR_TOML, "scenarios/fourbar.toml", "fourbar", &o).unwrap()
}
