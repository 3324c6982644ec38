//! The studies of the paper, reproduced: `mbsolve reproduce`.
//!
//! * Four-bar (§4.1, fig. 2 and 3): constraint fulfilment over time for the
//!   (α, β) sweep of PROBLEMS.md A, with the correct and the "incorrect"
//!   initial state, ode23 at MATLAB's defaults.

use crate::output::{line_plot, write_columns_csv, OutputError, Series};
use crate::scenario::{self, ScenarioError};
use crate::simulation::{simulate, SimulationError, Summary};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The four-bar scenario shipped with the tool (embedded at build time).
pub const FOURBAR_TOML: &str = include_str!("../scenarios/fourbar.toml");

/// A failure of a study.
#[derive(Debug, thiserror::Error)]
pub enum ReproduceError {
    /// Scenario problem.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// Run could not start.
    #[error(transparent)]
    Simulation(#[from] SimulationError),
    /// Writing outputs failed.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// File-system problem.
    #[error("{0}")]
    Io(String),
}

/// The (α, β) pairs of the sweep, with labels: (0,0), (1,1), (5,5), (10,10),
/// (50,50), and for α = 5 the rules β = α√2 and β = √(2α).
pub fn fourbar_sweep() -> Vec<(String, f64, f64)> {
    let mut v: Vec<(String, f64, f64)> = [0.0, 1.0, 5.0, 10.0, 50.0]
        .iter()
        .map(|&a| (format!("α = β = {a}"), a, a))
        .collect();
    v.push(("α = 5, β = α√2".into(), 5.0, 5.0 * std::f64::consts::SQRT_2));
    v.push(("α = 5, β = √(2α)".into(), 5.0, 10f64.sqrt()));
    v
}

/// One curve of a four-bar figure.
struct Curve {
    label: String,
    t: Vec<f64>,
    phi_bx: Vec<f64>,
    norm: Vec<f64>,
}

/// One run of the four-bar study.
#[derive(Debug, Clone)]
pub struct FourBarCase {
    /// Incorrect initial state?
    pub incorrect: bool,
    /// Label of the (α, β) pair.
    pub label: String,
    /// α.
    pub alpha: f64,
    /// β.
    pub beta: f64,
    /// max over time of max_k |Φ_k| at the output times.
    pub max_abs_phi: f64,
    /// |Φ| at t = 2 s (∞-norm).
    pub final_abs_phi: f64,
    /// The run summary.
    pub summary: Summary,
}

/// Run the four-bar study, writing CSVs, SVG figures and a Markdown table
/// under `out/fourbar/`. Returns the cases.
pub fn fourbar_study(out: &Path) -> Result<Vec<FourBarCase>, ReproduceError> {
    let dir = out.join("fourbar");
    std::fs::create_dir_all(&dir)
        .map_err(|e| ReproduceError::Io(format!("{}: {e}", dir.display())))?;
    let mut cases = Vec::new();
    for incorrect in [false, true] {
        let tag = if incorrect { "incorrect" } else { "correct" };
        let mut curves: Vec<Curve> = Vec::new();
        for (label, alpha, beta) in fourbar_sweep() {
            let overrides = vec![
                format!("stabilization.alpha={alpha}"),
                format!("stabilization.beta={beta}"),
                format!("initial.incorrect={incorrect}"),
                "integrator.method=\"ode23\"".into(),
            ];
            let sc = scenario::parse(
                FOURBAR_TOML,
                "scenarios/fourbar.toml",
                "fourbar",
                &overrides,
            )?;
            let (traj, summary) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [])?;
            let row_b = joint_row(&sc.system, "B");
            let phi_bx: Vec<f64> = traj.phi.iter().map(|p| p[row_b]).collect();
            let inf: Vec<f64> = traj
                .phi
                .iter()
                .map(|p| p.iter().fold(0.0_f64, |a, b| a.max(b.abs())))
                .collect();
            let file = dir.join(format!("{tag}_a{alpha:.3}_b{beta:.3}.csv"));
            write_columns_csv(
                &file,
                &[
                    ("t", &traj.t),
                    ("phi_B_x", &phi_bx),
                    ("constraint_norm", &traj.constraint_norm),
                    ("velocity_constraint_norm", &traj.velocity_constraint_norm),
                ],
            )?;
            cases.push(FourBarCase {
                incorrect,
                label: label.clone(),
                alpha,
                beta,
                max_abs_phi: inf.iter().cloned().fold(0.0, f64::max),
                final_abs_phi: *inf.last().unwrap_or(&f64::NAN),
                summary,
            });
            curves.push(Curve {
                label,
                t: traj.t.clone(),
                phi_bx,
                norm: traj.constraint_norm.clone(),
            });
        }
        let fig = if incorrect { "fig3" } else { "fig2" };
        let what = if incorrect {
            "incorrect initial state"
        } else {
            "correct initial state"
        };
        let series = |k: usize| -> Vec<Series<'_>> {
            curves
                .iter()
                .map(|c| Series {
                    label: c.label.clone(),
                    x: &c.t,
                    y: if k == 0 { &c.phi_bx } else { &c.norm },
                })
                .collect()
        };
        line_plot(
            &dir.join(format!("{fig}_fourbar_{tag}_phiBx.svg")),
            &format!("Four-bar, {what}: x-equation of pin B (ode23, RelTol 1e-3)"),
            "t [s]",
            "Φ_Bx [m]",
            &series(0),
            false,
        )?;
        line_plot(
            &dir.join(format!("{fig}_fourbar_{tag}_norm.svg")),
            &format!("Four-bar, {what}: ‖Φ‖₂"),
            "t [s]",
            "‖Φ‖₂ [m]",
            &series(1),
            true,
        )?;
    }
    let table = fourbar_table(&cases);
    let path: PathBuf = dir.join("fourbar_table.md");
    std::fs::write(&path, &table)
        .map_err(|e| ReproduceError::Io(format!("{}: {e}", path.display())))?;
    Ok(cases)
}

/// Markdown table of max |Φ| per (α, β), correct and incorrect initial state.
pub fn fourbar_table(cases: &[FourBarCase]) -> String {
    let mut s = String::from(
        "| α | β | max \\|Φ\\| correct | max \\|Φ\\| incorrect | \\|Φ(2 s)\\| incorrect | ode23 steps (correct / incorrect) | failed | RHS evals | wall s |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for c in cases.iter().filter(|c| !c.incorrect) {
        if let Some(i) = cases
            .iter()
            .find(|i| i.incorrect && i.alpha == c.alpha && i.beta == c.beta)
        {
            let _ = writeln!(
                s,
                "| {:.3} | {:.3} | {:.3e} | {:.3e} | {:.3e} | {} / {} | {} / {} | {} / {} | {:.3} / {:.3} |",
                c.alpha,
                c.beta,
                c.max_abs_phi,
                i.max_abs_phi,
                i.final_abs_phi,
                c.summary.steps,
                i.summary.steps,
                c.summary.failed_steps,
                i.summary.failed_steps,
                c.summary.rhs_evals,
                i.summary.rhs_evals,
                c.summary.wall_s,
                i.summary.wall_s
            );
        }
    }
    s
}

/// First row of the joint named `name` (e.g. "B": its x-equation).
pub fn joint_row(sys: &crate::model::System, name: &str) -> usize {
    let k = sys
        .constraints()
        .iter()
        .position(|c| c.name().ends_with(&format!("'{name}'")))
        .unwrap_or(0);
    sys.row_offset(k)
}
