//! The initial-state part of a scenario: `[initial]` → positions and
//! velocities (assembled onto the constraints, then perturbed).

use super::model::body_index;
use super::{error, positive, ScenarioError};
use crate::formulation::{consistent_initial_state, ConsistentState, InitialOptions};
use crate::model::System;
use crate::simulation::RunConfig;
use serde::Deserialize;
use std::collections::HashMap;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInitial {
    #[serde(default = "yes")]
    consistent: bool,
    #[serde(default)]
    independent: Vec<String>,
    #[serde(default)]
    incorrect: bool,
    #[serde(default)]
    perturbation: Vec<RawPerturbation>,
    #[serde(default = "default_ic_tol")]
    tol: f64,
}

impl Default for RawInitial {
    fn default() -> Self {
        Self {
            consistent: true,
            independent: Vec::new(),
            incorrect: false,
            perturbation: Vec::new(),
            tol: default_ic_tol(),
        }
    }
}

fn yes() -> bool {
    true
}
fn default_ic_tol() -> f64 {
    1e-12
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPerturbation {
    coordinate: String,
    delta: f64,
}

/// Initial positions, velocities and the assembly report (when assembled).
pub(super) type Initial = (Vec<f64>, Vec<f64>, Option<ConsistentState>);

/// Initial positions and velocities of `system` from `raw` (and the
/// assembly report); errors name keys of `file`.
pub(super) fn build(
    raw: &RawInitial,
    system: &System,
    names: &HashMap<String, usize>,
    run: &RunConfig,
    file: &str,
) -> Result<Initial, ScenarioError> {
    let err = |key: String, message: String| error(file, key, message);
    let body_index = |key: String, name: &str| body_index(names, file, key, name);
    let (t0, linear_solver) = (run.t0, run.index1.linear_solver);
    let coord = |key: String, spec: &str| -> Result<usize, ScenarioError> {
        let (b, c) = spec.rsplit_once('.').ok_or_else(|| {
            err(
                key.clone(),
                format!("'{spec}' is not of the form BODY.x|y|phi"),
            )
        })?;
        let bi = body_index(key.clone(), b)?;
        let ci = match c {
            "x" => 0,
            "y" => 1,
            "phi" => 2,
            o => return Err(err(key, format!("'{o}' is not one of x, y, phi"))),
        };
        Ok(3 * bi + ci)
    };
    let independent = raw
        .independent
        .iter()
        .enumerate()
        .map(|(i, s)| coord(format!("initial.independent[{i}]"), s))
        .collect::<Result<Vec<_>, _>>()?;
    positive(raw.tol).map_err(|m| err("initial.tol".into(), m))?;
    let (mut q0, mut qd0) = system.initial_state();
    let mut assembly = None;
    if raw.consistent && system.n_constraints() > 0 {
        let st = consistent_initial_state(
            system,
            t0,
            &q0,
            &qd0,
            &independent,
            InitialOptions {
                tol: raw.tol,
                linear_solver,
                ..Default::default()
            },
        )
        .map_err(|e| err("initial".into(), e.to_string()))?;
        // The velocity solve is least squares: a residual left means the
        // given independent velocities are incompatible with the
        // constraints (a locked mechanism, dependent "independent" ones).
        let vscale = st.qd.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let vtol = 1e3 * raw.tol * vscale;
        // the kept values must have been kept (least squares gives up a
        // lock row when the constraints contradict it)
        let moved = independent.iter().find(|&&k| {
            (st.q[k] - q0[k]).abs() > 1e-9 * (1.0 + q0[k].abs())
                || (st.qd[k] - qd0[k]).abs() > 1e-9 * (1.0 + qd0[k].abs())
        });
        if let Some(&k) = moved {
            return Err(err(
                "initial.independent".into(),
                format!(
                    "{} cannot keep its given value: position {} → {}, rate {} → {} in the \
                     assembly; the constraints fix it (a locked mechanism, or the independent \
                     coordinates {:?} are not independent)",
                    System::coordinate_name(k),
                    q0[k],
                    st.q[k],
                    qd0[k],
                    st.qd[k],
                    raw.independent
                ),
            ));
        }
        if st.velocity_residual > vtol {
            return Err(err(
                "initial.independent".into(),
                format!(
                    "the initial velocities cannot satisfy the velocity constraints Φ_q q̇ = −Φ_t: \
                     residual ‖Φ_q q̇ + Φ_t‖ = {:.3e} > {vtol:.1e} (1e3 initial.tol max(1, |q̇|)); \
                     the mechanism is locked or the independent coordinates {:?} are not \
                     independent",
                    st.velocity_residual, raw.independent
                ),
            ));
        }
        q0.clone_from(&st.q);
        qd0.clone_from(&st.qd);
        assembly = Some(st);
    }
    if raw.incorrect {
        if raw.perturbation.is_empty() {
            return Err(err(
                "initial.incorrect".into(),
                "true, but the scenario gives no initial.perturbation".into(),
            ));
        }
        for (i, p) in raw.perturbation.iter().enumerate() {
            let c = coord(
                format!("initial.perturbation[{i}].coordinate"),
                &p.coordinate,
            )?;
            if !p.delta.is_finite() {
                return Err(err(
                    format!("initial.perturbation[{i}].delta"),
                    format!("{} is not finite", p.delta),
                ));
            }
            q0[c] += p.delta;
        }
    }
    Ok((q0, qd0, assembly))
}
