//! Parameter sweeps: the Cartesian product of scenario overrides, run in
//! parallel (rayon). Each run is independent and sequential inside, so the
//! results do not depend on the number of threads; they are returned in the
//! order of the product.

use mbsolve::scenario::{self, ScenarioError};
use mbsolve::simulation::{simulate, Summary, Trajectory};
use rayon::prelude::*;
use std::path::Path;

/// One parameter of a sweep: a scenario key and its values.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepParam {
    /// Scenario key, e.g. `stabilization.alpha`.
    pub key: String,
    /// Values as they would be written after `--set KEY=`.
    pub values: Vec<String>,
}

impl std::str::FromStr for SweepParam {
    type Err = String;
    /// `KEY=v1,v2,…`.
    fn from_str(s: &str) -> Result<Self, String> {
        let (k, v) = s
            .split_once('=')
            .ok_or_else(|| format!("--param {s}: expected KEY=v1,v2,..."))?;
        let values: Vec<String> = v.split(',').map(|x| x.trim().to_string()).collect();
        if k.trim().is_empty() || values.iter().any(|x| x.is_empty()) {
            return Err(format!(
                "--param {s}: expected KEY=v1,v2,... with non-empty values"
            ));
        }
        Ok(Self {
            key: k.trim().to_string(),
            values,
        })
    }
}

/// The outcome of one run of a sweep.
#[derive(Debug)]
pub struct SweepRun {
    /// The `KEY=VALUE` overrides of this run (sweep parameters only).
    pub point: Vec<String>,
    /// Trajectory and summary, or why the run could not start.
    pub result: Result<(Trajectory, Summary), String>,
}

/// All combinations, first parameter slowest.
pub fn combinations(params: &[SweepParam]) -> Vec<Vec<String>> {
    let mut out = vec![Vec::new()];
    for p in params {
        out = out
            .into_iter()
            .flat_map(|prefix| {
                p.values.iter().map(move |v| {
                    let mut c = prefix.clone();
                    c.push(format!("{}={}", p.key, v));
                    c
                })
            })
            .collect();
    }
    out
}

/// Run the sweep over `path` (with `base` overrides applied first). The
/// first combination is validated before anything runs, so a bad key fails
/// fast with the scenario's error.
pub fn run(
    path: &Path,
    base: &[String],
    params: &[SweepParam],
) -> Result<Vec<SweepRun>, ScenarioError> {
    let points = combinations(params);
    let with = |p: &Vec<String>| -> Vec<String> { base.iter().chain(p).cloned().collect() };
    for p in &points {
        scenario::load(path, &with(p))?;
    }
    Ok(points
        .into_par_iter()
        .map(|point| {
            let result = scenario::load(path, &with(&point))
                .map_err(|e| e.to_string())
                .and_then(|sc| {
                    simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [])
                        .map_err(|e| e.to_string())
                });
            SweepRun { point, result }
        })
        .collect())
}
