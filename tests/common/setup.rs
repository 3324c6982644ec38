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
