//! `mbsolve inverse SCENARIO [--set K=V]… [--out DIR]`: kinematics and
//! inverse dynamics of a mechanism without freedom once its drives are
//! counted, at the scenario's output times, no integration
//! ([`mbsolve::analysis::inverse`]). Writes `DIR/<stem>.inverse.csv` (the
//! columns of `run`'s table with velocities, accelerations, reactions and
//! drives: same names), `<stem>.inverse.columns.json` and
//! `<stem>.inverse.summary.json`. Controller states are integrated along
//! the prescribed motion (their columns hold z).

use crate::output::{columns_json, create_fresh, sibling, write_atomic, OutputError};
use mbsolve::analysis::inverse::{InverseDynamics, InverseOptions};
use mbsolve::model::drives;
use mbsolve::output::{columns, joint_label, Format, RowBuilder};
use mbsolve::scenario;
use mbsolve::simulation::OutputQuantities;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// The command; `Err` is printed by `main` with exit status 2.
pub fn command(path: &Path, set: &[String], out: &Path) -> Result<ExitCode, String> {
    inverse(path, set, out).map_err(|e| e.to_string())
}

fn inverse(
    path: &Path,
    set: &[String],
    out: &Path,
) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let sc = scenario::load(path, set).map_err(|e| e.to_string())?;
    let sys = &sc.system;
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| sc.name.clone());
    let times = sc.run.output_times();
    let start = Instant::now();
    let mut inv = InverseDynamics::new(sys, &sc.q0, sc.run.t0, InverseOptions::default())
        .map_err(|e| format!("{}: {e}", path.display()))?;
    // controller states from the scenario's initial state (integrated
    // along the prescribed motion)
    inv.set_states(&sc.qd0[sys.n_body_coords()..])
        .map_err(|e| format!("{}: {e}", path.display()))?;
    crate::output::create_dir(out)?;
    let quantities = OutputQuantities {
        velocities: true,
        accelerations: true,
        reactions: true,
        drives: true,
        energy: false,
    };
    let cols = columns(sys, &quantities, &sc.sensors);
    let csv = out.join(format!("{stem}.inverse.csv"));
    let part = sibling(&csv, ".part");
    let file = create_fresh(&part)?;
    let mut table = Format::Csv
        .writer(file, &cols)
        .map_err(|e| OutputError::new(&part, e))?;
    write_atomic(
        &out.join(format!("{stem}.inverse.columns.json")),
        &columns_json(&cols),
    )?;
    let mut rows = RowBuilder::new(sys, quantities, &sc.sensors);
    let list = drives(sys);
    let mut peak = vec![0.0_f64; list.len()];
    let (mut max_phi, mut max_phid) = (0.0_f64, 0.0_f64);
    for &t in &times {
        let s = inv.at(t).map_err(|e| format!("{}: {e}", path.display()))?;
        max_phi = max_phi.max(s.constraint_norm);
        max_phid = max_phid.max(s.velocity_constraint_norm);
        if let Some(l) = s.lambda {
            for (p, d) in peak.iter_mut().zip(&list) {
                if d.force(l).abs() > p.abs() {
                    *p = d.force(l);
                }
            }
        }
        table
            .write_row(rows.row(&s))
            .map_err(|e| OutputError::new(&part, e))?;
    }
    table.finish().map_err(|e| OutputError::new(&part, e))?;
    std::fs::rename(&part, &csv).map_err(|e| OutputError::new(&csv, e))?;
    let wall = start.elapsed().as_secs_f64();
    let peaks: serde_json::Map<String, serde_json::Value> = list
        .iter()
        .zip(&peak)
        .map(|(d, p)| {
            (
                joint_label(sys, d.joint),
                serde_json::json!({"peak": p, "unit": d.unit}),
            )
        })
        .collect();
    let summary = serde_json::json!({
        "analysis": "inverse_dynamics",
        "scenario": path.display().to_string(),
        "overrides": set,
        "mbsolve_version": env!("CARGO_PKG_VERSION"),
        "status": "completed",
        "bodies": sys.bodies().len(),
        "coordinates": sys.n_coords(),
        "constraints": sys.n_constraints(),
        "t0": sc.run.t0,
        "t_end": sc.run.t_end,
        "output_rows": times.len(),
        "newton_iterations": inv.iterations(),
        "max_constraint_norm": max_phi,
        "max_velocity_constraint_norm": max_phid,
        "drives": peaks,
        "wall_s": wall,
    });
    let json = out.join(format!("{stem}.inverse.summary.json"));
    write_atomic(
        &json,
        &(serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n"),
    )?;
    say!(
        "{}: inverse dynamics at {} output times, {} Newton iterations, max ‖Φ‖ = {:.3e}, {:.3} s",
        sc.name,
        times.len(),
        inv.iterations(),
        max_phi,
        wall
    );
    for (d, p) in list.iter().zip(&peak) {
        say!(
            "  drive {}: peak {p:.6e} {}",
            joint_label(sys, d.joint),
            d.unit
        );
    }
    say!("wrote {} and {}", csv.display(), json.display());
    Ok(ExitCode::SUCCESS)
}
