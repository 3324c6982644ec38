//! Run settings and scenario texts as the tests write them.

use mbsolve::integrate::{Method, OdeOptions, Tolerance};
use mbsolve::model::System;
use mbsolve::scenario::{self, Scenario, ScenarioError};
use mbsolve::simulation::{simulate, RunConfig, Summary, Trajectory};

/// `text` (a scenario, named `test.toml` in messages) with `overrides`
/// (`"key=value"`, as `--set`).
pub fn parse(text: &str, overrides: &[&str]) -> Result<Scenario, ScenarioError> {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    scenario::parse(text, "test.toml", "test", &o)
}

/// An adaptive run of `method` to `t_end` with outputs every `dt`, scalar
/// tolerances `rtol`, `atol`; everything else default.
pub fn adaptive(method: Method, rtol: f64, atol: f64, t_end: f64, dt: f64) -> RunConfig {
    RunConfig {
        method,
        ode: OdeOptions {
            rtol,
            atol: Tolerance::Scalar(atol),
            ..Default::default()
        },
        t_end,
        output_dt: dt,
        ..Default::default()
    }
}

/// `simulate` from `(q0, q̇0)` with `cfg`, asserting that the run completed.
pub fn completed(sys: &System, q0: &[f64], qd0: &[f64], cfg: &RunConfig) -> (Trajectory, Summary) {
    let (traj, s) = simulate(sys, q0, qd0, cfg, &mut []).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    (traj, s)
}

/// `text` parsed as [`parse`] does, without overrides; a parse error
/// panics with its message.
pub fn scenario(text: &str) -> Scenario {
    parse(text, &[]).unwrap_or_else(|e| panic!("{e}"))
}

/// The message of the error `text` gives ([`parse`], `test.toml`);
/// panics when it parses.
pub fn parse_error(text: &str) -> String {
    parse(text, &[])
        .map(|_| ())
        .expect_err("an error")
        .to_string()
}

/// The ```` ```toml ```` block of docs/scenarios.md that starts with the
/// comment line `# {title}`.
pub fn docs_example(title: &str) -> String {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/scenarios.md"))
        .expect("docs/scenarios.md");
    let head = format!("# {title}");
    doc.split("```toml\n")
        .skip(1)
        .map(|b| b.split("```").next().unwrap())
        .find(|b| b.starts_with(&head))
        .unwrap_or_else(|| panic!("no example '{head}' in docs/scenarios.md"))
        .to_string()
}
