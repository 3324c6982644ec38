//! `mbsolve static SCENARIO [--set K=V]… [--out DIR]`: the static
//! equilibrium of a scenario from its initial state
//! ([`mbsolve::analysis::statics`]): configuration, λ, joint reactions,
//! stability; writes `DIR/<stem>.static.json` and the equilibrium as a
//! state file `DIR/<stem>.equilibrium.json` that `run` starts from with
//! `--set initial.state=…`. With `[[state]]` controller states the
//! equilibrium holds their values z (in the state file as the velocities
//! of their coordinates) and its stability is the first-order system's:
//! the eigenvalues of the linearisation about it.

use crate::output::write_atomic;
use mbsolve::analysis::linearize::{linearize, LinearizeOptions, Method};
use mbsolve::analysis::{
    first_order_modes, stability, static_equilibrium_from, Equilibrium, Stability, StaticOptions,
};
use mbsolve::model::System;
use mbsolve::scenario::{self, Scenario};
use serde_json::{json, Value};
use std::path::Path;
use std::process::ExitCode;

/// Below this frequency \[Hz\] a direction counts as neutral (default of
/// `--neutral-hz`).
pub const NEUTRAL_HZ: f64 = 1e-3;

/// Load `path` with `set`, find its equilibrium (load stepping from the
/// initial state, at the run's t₀); errors as text.
pub fn equilibrium_of(path: &Path, set: &[String]) -> Result<(Scenario, Equilibrium), String> {
    let sc = scenario::load(path, set).map_err(|e| e.to_string())?;
    let opts = StaticOptions {
        t0: sc.run.t0,
        ..Default::default()
    };
    // controller states start from the scenario's initial state
    let z0 = &sc.qd0[sc.system.n_body_coords()..];
    let eq = static_equilibrium_from(&sc.system, &sc.q0, z0, opts)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((sc, eq))
}

/// The state file of the equilibrium (what `initial.state` reads):
/// positions `q`, velocities `qd` (0, and the controller states' values).
pub fn state_json(q: &[f64], qd: &[f64], t: f64) -> String {
    let v = json!({ "t": t, "q": q, "qd": qd });
    serde_json::to_string_pretty(&v).unwrap_or_default() + "\n"
}

/// The stability of an equilibrium with controller states: the
/// eigenvalues s of the linearisation's A (exact tangent path); stable
/// when every Re s < −2π f_neutral, unstable when one Re s > 2π f_neutral,
/// else neutral. Returns the verdict and the JSON of the eigenvalues.
fn first_order_stability(
    sc: &Scenario,
    eq: &Equilibrium,
    neutral_hz: f64,
) -> Result<(&'static str, Value), String> {
    let opts = LinearizeOptions {
        method: Method::Tangent,
        // an equilibrium to the static solver's relative tolerance
        rest_tol: 1e-6,
        ..Default::default()
    };
    let t0 = sc.run.t0;
    let ss = linearize(
        &sc.system,
        &[],
        t0,
        &eq.q,
        &eq.velocities(),
        &[],
        &[],
        &opts,
    )
    .map_err(|e| e.to_string())?;
    let modes = first_order_modes(&ss.a).map_err(|e| e.to_string())?;
    let s = 2.0 * std::f64::consts::PI * neutral_hz;
    let verdict = if modes.iter().any(|m| m.re > s) {
        "unstable"
    } else if modes.iter().any(|m| m.re >= -s) {
        "neutral"
    } else {
        "stable"
    };
    let list: Vec<Value> = modes
        .iter()
        .map(|m| json!({ "re": m.re, "im": m.im }))
        .collect();
    Ok((verdict, json!(list)))
}

/// The joints' reactions on their bodies at `(q, λ)`.
pub fn reactions_json(sys: &System, t: f64, q: &[f64], lambda: &[f64]) -> Vec<Value> {
    let map = sys.reaction_map();
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, t, &mut jac);
    let nj = sys.constraints().len();
    let mut r = vec![0.0; 3 * nj];
    sys.joint_reactions(&map, &jac, lambda, &mut r);
    sys.constraints()
        .iter()
        .enumerate()
        .map(|(k, c)| {
            json!({
                "joint": c.name(),
                "body": map.body(k).map(|b| b + 1),
                "fx": r[3 * k],
                "fy": r[3 * k + 1],
                "mz": r[3 * k + 2],
                "lambda": lambda[map.rows_of(k)].to_vec(),
            })
        })
        .collect()
}

/// The command.
pub fn command(
    path: &Path,
    set: &[String],
    out: &Path,
    neutral_hz: f64,
) -> Result<ExitCode, String> {
    if !(neutral_hz.is_finite() && neutral_hz >= 0.0) {
        return Err(format!("--neutral-hz {neutral_hz}: must be finite and ≥ 0"));
    }
    let (sc, eq) = equilibrium_of(path, set)?;
    let sys = &sc.system;
    let t0 = sc.run.t0;
    let with_states = !sys.states().is_empty();
    // the mechanism's stability, or with controller states the first-order
    // system's (module docs)
    let (stability_json, verdict_line) = if with_states {
        // the equilibrium stands even when its linearisation fails
        let (verdict, eig) = first_order_stability(&sc, &eq, neutral_hz).unwrap_or_else(|e| {
            eprintln!("warning: {}: stability not determined: {e}", path.display());
            ("unknown", json!({ "error": e }))
        });
        (
            json!({
                "verdict": verdict,
                "of": "the first-order system with its controller states: eigenvalues of the \
                       linearisation's A",
                "eigenvalues": eig,
                "neutral_below_hz": neutral_hz,
            }),
            format!(
                "stability: {verdict} (eigenvalues of the linearisation with the controller \
                 states; neutral where |Re s| ≤ 2π·{neutral_hz} 1/s)"
            ),
        )
    } else {
        let st: Stability = stability(sys, t0, &eq.q, &eq.lambda, neutral_hz)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        (
            json!({
                "verdict": st.verdict(),
                "stable": st.stable,
                "unstable": st.unstable,
                "neutral": st.neutral,
                "neutral_below_hz": neutral_hz,
            }),
            format!(
                "stability: {} ({} stable, {} unstable, {} neutral directions; neutral below \
                 {neutral_hz} Hz)",
                st.verdict(),
                st.stable,
                st.unstable,
                st.neutral
            ),
        )
    };
    crate::output::create_dir(out)?;
    let stem = stem(path);
    let state_path = out.join(format!("{stem}.equilibrium.json"));
    write_atomic(&state_path, &state_json(&eq.q, &eq.velocities(), t0))
        .map_err(|e| e.to_string())?;
    let states: serde_json::Map<String, Value> = sys
        .states()
        .iter()
        .zip(&eq.states)
        .map(|(s, &z)| (s.name.clone(), json!(z)))
        .collect();
    let bodies: Vec<Value> = (0..sys.bodies().len())
        .map(|b| json!({ "body": b + 1, "x": eq.q[3 * b], "y": eq.q[3 * b + 1], "phi": eq.q[3 * b + 2] }))
        .collect();
    let report = json!({
        "scenario": path.display().to_string(),
        "t0": t0,
        "coordinates": sys.n_coords(),
        "constraints": sys.n_constraints(),
        "load_steps": eq.load_steps,
        "newton_iterations": eq.iterations,
        "residual": eq.residual,
        "constraint_residual": eq.constraint_residual,
        "redundant_rows": eq.redundant,
        "stability": stability_json,
        "bodies": bodies,
        "states": states,
        "reactions": reactions_json(sys, t0, &eq.q, &eq.lambda),
        "lambda": eq.lambda,
        "state_file": state_path.display().to_string(),
    });
    let json_path = out.join(format!("{stem}.static.json"));
    write_atomic(
        &json_path,
        &(serde_json::to_string_pretty(&report).unwrap_or_default() + "\n"),
    )
    .map_err(|e| e.to_string())?;
    say!(
        "{}: equilibrium after {} load steps, {} Newton iterations; ‖g − Φ_qᵀλ‖∞ = {:.2e}, ‖Φ‖∞ = {:.2e}",
        path.display(),
        eq.load_steps,
        eq.iterations,
        eq.residual,
        eq.constraint_residual
    );
    if !eq.redundant.is_empty() {
        say!(
            "{} redundant constraint rows left out (their λ are 0: the split of the reactions \
             among redundant joints is statically indeterminate): {:?}",
            eq.redundant.len(),
            eq.redundant
        );
    }
    for (s, z) in sys.states().iter().zip(&eq.states) {
        say!("controller state {} = {z:.9e}", s.name);
    }
    say!("{verdict_line}");
    say!("wrote {}", json_path.display());
    // absolute: a relative `initial.state` is read from the scenario's directory
    let abs = std::fs::canonicalize(&state_path).unwrap_or_else(|_| state_path.clone());
    say!(
        "wrote {} (start a run from it: --set initial.state={})",
        state_path.display(),
        abs.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The scenario's file stem.
pub fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scenario".into())
}
