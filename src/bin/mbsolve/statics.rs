//! `mbsolve static SCENARIO [--set K=V]… [--out DIR]`: the static
//! equilibrium of a scenario from its initial state
//! ([`mbsolve::analysis::statics`]): configuration, λ, joint reactions,
//! stability; writes `DIR/<stem>.static.json` and the equilibrium as a
//! state file `DIR/<stem>.equilibrium.json` that `run` starts from with
//! `--set initial.state=…`.

use crate::output::write_atomic;
use mbsolve::analysis::{stability, static_equilibrium, Equilibrium, Stability, StaticOptions};
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
    sc.refuse_states("static")?;
    let opts = StaticOptions {
        t0: sc.run.t0,
        ..Default::default()
    };
    let eq = static_equilibrium(&sc.system, &sc.q0, opts)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((sc, eq))
}

/// The state file of `q` at rest (what `initial.state` reads).
pub fn state_json(q: &[f64], t: f64) -> String {
    let v = json!({ "t": t, "q": q, "qd": vec![0.0; q.len()] });
    serde_json::to_string_pretty(&v).unwrap_or_default() + "\n"
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
    let st: Stability = stability(sys, t0, &eq.q, &eq.lambda, neutral_hz)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let stem = stem(path);
    let state_path = out.join(format!("{stem}.equilibrium.json"));
    write_atomic(&state_path, &state_json(&eq.q, t0)).map_err(|e| e.to_string())?;
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
        "stability": {
            "verdict": st.verdict(),
            "stable": st.stable,
            "unstable": st.unstable,
            "neutral": st.neutral,
            "neutral_below_hz": neutral_hz,
        },
        "bodies": bodies,
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
    say!(
        "stability: {} ({} stable, {} unstable, {} neutral directions; neutral below {neutral_hz} Hz)",
        st.verdict(),
        st.stable,
        st.unstable,
        st.neutral
    );
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
