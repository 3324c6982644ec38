//! Problem A, the four-bar of the paper (docs/problems.md, §A): the shipped
//! `scenarios/fourbar.toml` parsed with `--set`-style overrides.

use mbsolve::scenario::{self, Scenario, FOURBAR_TOML};

/// The shipped four-bar with `overrides` (`"key=value"`, as `--set`).
pub fn fourbar(overrides: &[&str]) -> Scenario {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    scenario::parse(FOURBAR_TOML, "scenarios/fourbar.toml", "fourbar", &o).unwrap()
}

/// A second revolute joint `B2` at the crank–coupler pin B, appended to the
/// four-bar's text: Φ_q becomes rank-deficient (10 rows, rank 8).
pub const DOUBLED_B: &str = r#"
[[joint]]
type = "revolute"
name = "B2"
body_i = "crank"
point_i = [0.1, 0.0]
body_j = "coupler"
point_j = [-0.2, 0.0]
"#;
