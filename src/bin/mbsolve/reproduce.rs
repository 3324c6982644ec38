//! The studies of the paper, reproduced: `mbsolve reproduce`.
//!
//! * Four-bar (§4.1, fig. 2 and 3): constraint fulfilment over time for the
//!   (α, β) sweep of problem A (docs/problems.md), with the correct and the "incorrect"
//!   initial state, ode23 at MATLAB's defaults.
//! * Falling rod (§4.2, fig. 5–7), N = 10: x of segments 1, N/2, N; relative
//!   angles φ_i − φ_1; one joint's constraint with and without Baumgarte
//!   stabilization; ode23 and ode45; contact events.
//! * The cantilevered chain (problem D) without gravity: its first three
//!   mode shapes beside the Euler–Bernoulli cantilever's
//!   ([`chain_modes_study`]).

use crate::figure::{Figure, Series};
use crate::output::{write_columns_csv, OutputError};
use mbsolve::scenario::{self, ScenarioError, FALLING_ROD_TOML, FOURBAR_TOML};
use mbsolve::simulation::{simulate, SimulationError, Summary};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

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
    /// The study's scenario lacks something the study needs.
    #[error("{0}")]
    Study(String),
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
    velocity_norm: Vec<f64>,
}

/// One run of the four-bar study.
#[derive(Debug, Clone)]
pub struct FourBarCase {
    /// Incorrect initial state?
    pub incorrect: bool,
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
    crate::output::create_dir(&dir).map_err(ReproduceError::Io)?;
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
            let row_b = joint_row(&sc.system, "B")?;
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
                velocity_norm: traj.velocity_constraint_norm.clone(),
            });
        }
        let fig = if incorrect { "fig3" } else { "fig2" };
        let what = if incorrect {
            "incorrect initial state"
        } else {
            "correct initial state"
        };
        let series = |k: usize| -> Vec<Series> {
            curves
                .iter()
                .map(|c| Series {
                    label: c.label.clone(),
                    x: c.t.clone(),
                    y: match k {
                        0 => c.phi_bx.iter().map(|v| 1e3 * v).collect(),
                        1 => c.norm.clone(),
                        _ => c.velocity_norm.clone(),
                    },
                })
                .collect()
        };
        Figure {
            title: format!("Four-bar, {what}: x-equation of pin B (ode23, RelTol 1e-3)"),
            x_label: "t [s]".into(),
            y_label: "Φ_Bx [mm]".into(),
            series: series(0),
            ..Default::default()
        }
        .save(&dir, &format!("{fig}_fourbar_{tag}_phiBx"))?;
        for (k, name, symbol, unit) in [
            (1, "norm", "‖Φ‖₂", "m"),
            (2, "velocity_norm", "‖dΦ/dt‖₂", "m/s"),
        ] {
            let series = series(k);
            let floor = floor_after_start(&series);
            Figure {
                title: format!("Four-bar, {what}: {symbol}"),
                x_label: "t [s]".into(),
                y_label: format!("{symbol} [{unit}]"),
                log_y: true,
                log_floor: floor,
                note: start_note(&series, floor, symbol, unit),
                series,
                ..Default::default()
            }
            .save(&dir, &format!("{fig}_fourbar_{tag}_{name}"))?;
        }
    }
    let table = fourbar_table(&cases);
    let path: PathBuf = dir.join("fourbar_table.md");
    std::fs::write(&path, &table)
        .map_err(|e| ReproduceError::Io(format!("{}: {e}", path.display())))?;
    Ok(cases)
}

/// The floor of a log figure of constraint residuals: the decade of the
/// smallest nonzero |y| after each curve's first sample, when some first
/// sample lies below it (`None` otherwise). The first sample is the
/// consistent initial state, zero up to rounding: its machine-zero
/// residual would stretch the axis over decades the run never visits.
fn floor_after_start(series: &[Series]) -> Option<f64> {
    let smallest = |v: &mut dyn Iterator<Item = &f64>| {
        v.filter(|y| y.is_finite() && **y != 0.0)
            .map(|y| y.abs())
            .fold(f64::INFINITY, f64::min)
    };
    let rest = smallest(&mut series.iter().flat_map(|s| s.y.iter().skip(1)));
    let first = smallest(&mut series.iter().filter_map(|s| s.y.first()));
    (rest.is_finite() && first < rest).then(|| 10f64.powf(rest.log10().floor()))
}

/// The note that names the first samples a floor leaves out.
fn start_note(series: &[Series], floor: Option<f64>, symbol: &str, unit: &str) -> String {
    let Some(f) = floor else {
        return String::new();
    };
    let below: Vec<f64> = series
        .iter()
        .filter_map(|s| s.y.first())
        .filter(|y| y.abs() < f)
        .map(|y| y.abs())
        .collect();
    let hi = below.iter().cloned().fold(0.0, f64::max);
    if below.is_empty() {
        String::new()
    } else {
        format!("{symbol}(0) ≤ {hi:.1e} {unit} (rounding)")
    }
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
pub fn joint_row(sys: &mbsolve::model::System, name: &str) -> Result<usize, ReproduceError> {
    sys.constraints()
        .iter()
        .position(|c| c.name().ends_with(&format!("'{name}'")))
        .map(|k| sys.row_offset(k))
        .ok_or_else(|| ReproduceError::Study(format!("the scenario has no joint named '{name}'")))
}

/// One run of the rod study.
#[derive(Debug, Clone)]
pub struct RodCase {
    /// Integration method.
    pub method: String,
    /// Baumgarte α = β.
    pub alpha: f64,
    /// First contact time \[s\].
    pub first_contact: Option<f64>,
    /// Contact starts.
    pub contact_starts: usize,
    /// Peak normal force \[N\].
    pub peak_force: f64,
    /// (t, x of segment 1, x of segment N) at t = 0.25, 0.5, 1 s.
    pub x_at: Vec<(f64, f64, f64)>,
    /// The run summary.
    pub summary: Summary,
}

/// Run the falling-rod study (N = 10): figures 5–7, CSVs and a table under
/// `out/falling_rod/`.
pub fn rod_study(out: &Path) -> Result<Vec<RodCase>, ReproduceError> {
    use mbsolve::events::ContactMonitor;
    use mbsolve::simulation::Monitor;
    let dir = out.join("falling_rod");
    crate::output::create_dir(&dir).map_err(ReproduceError::Io)?;
    let mut cases = Vec::new();
    let mut stab_curves: Vec<(String, Vec<f64>, Vec<f64>)> = Vec::new();
    for (method, alpha) in [
        ("ode23", 0.0),
        ("ode23", 10.0),
        ("ode45", 0.0),
        ("ode45", 10.0),
    ] {
        let overrides = vec![
            format!("integrator.method=\"{method}\""),
            format!("stabilization.alpha={alpha}"),
            format!("stabilization.beta={alpha}"),
        ];
        let sc = scenario::parse(
            FALLING_ROD_TOML,
            "scenarios/falling_rod.toml",
            "falling_rod",
            &overrides,
        )?;
        let rod = sc.rod.clone().expect("the rod scenario has a [rod] table");
        let n = rod.n_segments();
        let mut mon = ContactMonitor::new(rod.clone());
        let mut mons: [&mut dyn Monitor; 1] = [&mut mon];
        let (traj, summary) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut mons)?;
        let x =
            |seg: usize| -> Vec<f64> { traj.q.iter().map(|q| q[3 * rod.bodies[seg]]).collect() };
        let phi = |seg: usize| -> Vec<f64> {
            traj.q.iter().map(|q| q[3 * rod.bodies[seg] + 2]).collect()
        };
        let (x1, xm, xn) = (x(0), x(n / 2 - 1), x(n - 1));
        let tag = format!("{method}_a{alpha}");
        // the middle joint's x-equation
        let row = sc.system.row_offset(rod.joints[(n - 1) / 2]);
        let phi_joint: Vec<f64> = traj.phi.iter().map(|p| p[row]).collect();
        write_columns_csv(
            &dir.join(format!("{tag}.csv")),
            &[
                ("t", &traj.t),
                ("x_seg1", &x1),
                ("x_segmid", &xm),
                ("x_segN", &xn),
                ("phi_joint_mid_x", &phi_joint),
                ("constraint_norm", &traj.constraint_norm),
            ],
        )?;
        if method == "ode23" {
            stab_curves.push((
                format!("ode23, α = β = {alpha}"),
                traj.t.clone(),
                phi_joint.clone(),
            ));
        }
        if method == "ode23" && alpha == 0.0 {
            let labels = [
                "segment 1".to_string(),
                format!("segment {}", n / 2),
                format!("segment {n}"),
            ];
            // the channel's walls, and where a segment's centre is when a
            // corner of the upright segment touches one (wall ∓ w/2)
            let mm = |v: &[f64]| -> Vec<f64> { v.iter().map(|x| 1e3 * x).collect() };
            let mut hlines = Vec::new();
            if let Some(c) = rod.contacts.first() {
                for wall in [c.left_wall, c.right_wall] {
                    hlines.push((
                        format!("walls, x = ±{:.0} mm", 1e3 * wall.abs()),
                        1e3 * wall,
                    ));
                }
                for wall in [c.left_wall, c.right_wall] {
                    let x = wall - wall.signum() * 0.5 * c.width;
                    hlines.push((
                        format!("centre at contact, φ = 0 (±{:.0} mm)", 1e3 * x.abs()),
                        1e3 * x,
                    ));
                }
            }
            Figure {
                title: format!("Falling rod, N = {n}: horizontal position of segments (ode23)"),
                x_label: "t [s]".into(),
                y_label: "x [mm]".into(),
                series: vec![
                    Series {
                        label: labels[0].clone(),
                        x: traj.t.clone(),
                        y: mm(&x1),
                    },
                    Series {
                        label: labels[1].clone(),
                        x: traj.t.clone(),
                        y: mm(&xm),
                    },
                    Series {
                        label: labels[2].clone(),
                        x: traj.t.clone(),
                        y: mm(&xn),
                    },
                ],
                hlines,
                ..Default::default()
            }
            .save(&dir, "fig5_rod_x")?;
            let p1 = phi(0);
            let rel: Vec<(String, Vec<f64>)> = [1, n / 2 - 1, n - 1]
                .iter()
                .filter(|&&i| i > 0)
                .map(|&i| {
                    let pi = phi(i);
                    (
                        format!("φ{} − φ1", i + 1),
                        pi.iter().zip(&p1).map(|(a, b)| 1e3 * (a - b)).collect(),
                    )
                })
                .collect();
            let series: Vec<Series> = rel
                .into_iter()
                .map(|(label, y)| Series {
                    label,
                    x: traj.t.clone(),
                    y,
                })
                .collect();
            Figure {
                title: format!("Falling rod, N = {n}: relative rotations (ode23)"),
                x_label: "t [s]".into(),
                y_label: "φ_i − φ_1 [mrad]".into(),
                series,
                ..Default::default()
            }
            .save(&dir, "fig6_rod_relative_angles")?;
        }
        let at = |t_q: f64| -> (f64, f64, f64) {
            let k = traj
                .t
                .iter()
                .position(|&t| (t - t_q).abs() < 1e-9)
                .unwrap_or(traj.t.len() - 1);
            (traj.t[k], x1[k], xn[k])
        };
        cases.push(RodCase {
            method: method.to_string(),
            alpha,
            first_contact: mon.first_contact(),
            contact_starts: mon.events.iter().filter(|e| e.kind == "start").count(),
            peak_force: mon.peak.map_or(0.0, |p| p.force),
            x_at: vec![at(0.25), at(0.5), at(1.0)],
            summary,
        });
    }
    let series: Vec<Series> = stab_curves
        .into_iter()
        .map(|(label, x, y)| Series { label, x, y })
        .collect();
    Figure {
        title: "Falling rod: x-equation of the middle joint, with and without stabilization".into(),
        x_label: "t [s]".into(),
        y_label: "|Φ| [m]".into(),
        log_y: true,
        log_floor: floor_after_start(&series),
        note: start_note(&series, floor_after_start(&series), "|Φ|", "m"),
        series,
        ..Default::default()
    }
    .save(&dir, "fig7_rod_joint_constraint")?;
    let table = rod_table(&cases);
    let path = dir.join("falling_rod_table.md");
    std::fs::write(&path, &table)
        .map_err(|e| ReproduceError::Io(format!("{}: {e}", path.display())))?;
    Ok(cases)
}

/// Markdown table of the rod runs.
pub fn rod_table(cases: &[RodCase]) -> String {
    let mut s = String::from(
        "| method | α = β | first contact [s] | contact starts | peak F_n [N] | x1(0.25) | x10(0.25) | x1(0.5) | x10(0.5) | x1(1) | x10(1) | max ‖Φ‖ | steps | failed | RHS evals | wall s |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for c in cases {
        let _ = write!(s, "| {} | {} | ", c.method, c.alpha);
        let _ = write!(
            s,
            "{} | {} | {:.1} |",
            c.first_contact.map_or("-".into(), |t| format!("{t:.4}")),
            c.contact_starts,
            c.peak_force
        );
        for (_, a, b) in &c.x_at {
            let _ = write!(s, " {a:.5} | {b:.5} |");
        }
        let _ = writeln!(
            s,
            " {:.2e} | {} | {} | {} | {:.3} |",
            c.summary.max_constraint_norm,
            c.summary.steps,
            c.summary.failed_steps,
            c.summary.rhs_evals,
            c.summary.wall_s
        );
    }
    s
}

/// Segments of the chain whose mode shapes [`chain_modes_study`] draws.
pub const CHAIN_MODES_N: usize = 20;

/// Samples per segment of the figure's abscissa (the chain is linear
/// between its joints, the beam's shapes are smooth).
const CHAIN_MODES_SAMPLES: usize = 10;

/// The chain's lowest modes beside the Euler–Bernoulli cantilever's.
#[derive(Debug, Clone)]
pub struct ChainModes {
    /// Segments.
    pub n: usize,
    /// The chain's undamped natural frequencies \[Hz\], lowest first.
    pub chain_hz: Vec<f64>,
    /// The Euler–Bernoulli cantilever's \[Hz\].
    pub beam_hz: Vec<f64>,
    /// Largest |chain − beam| of each normalised shape over the joints.
    pub shape_difference: Vec<f64>,
}

/// Root `β L` of the cantilever's frequency equation `1 + cos β cosh β = 0`
/// near `guess` (Newton).
pub fn cantilever_root(guess: f64) -> f64 {
    let mut b = guess;
    for _ in 0..50 {
        let f = 1.0 + b.cos() * b.cosh();
        let df = -b.sin() * b.cosh() + b.cos() * b.sinh();
        let step = f / df;
        b -= step;
        if step.abs() < 1e-15 * b {
            break;
        }
    }
    b
}

/// The Euler–Bernoulli cantilever's mode shape of root `bl = β L` at
/// `x / L = xi`, `cosh βx − cos βx − σ (sinh βx − sin βx)` with
/// `σ = (cosh βL + cos βL) / (sinh βL + sin βL)`, scaled to 1 at the tip.
pub fn cantilever_shape(bl: f64, xi: f64) -> f64 {
    let sigma = (bl.cosh() + bl.cos()) / (bl.sinh() + bl.sin());
    let w = |x: f64| (x.cosh() - x.cos()) - sigma * (x.sinh() - x.sin());
    w(bl * xi) / w(bl)
}

/// The first three mode shapes of the cantilevered stiff chain
/// (docs/problems.md, problem D; the peers' chain without gravity) at
/// [`CHAIN_MODES_N`] segments, hanging straight down, drawn as lateral
/// deflection against the position along the rod beside the
/// Euler–Bernoulli cantilever's shapes, each scaled to 1 at the free end,
/// frequencies in the legend. Writes under `out/chain_modes/`:
/// `chain_modes.svg` with its CSV (sampled along the rod; the chain's
/// rigid segments are linear between their joints), `chain_modes_joints.csv`
/// (the chain's deflection at its joints beside the beam's) and
/// `chain_modes_table.md`.
pub fn chain_modes_study(out: &Path) -> Result<ChainModes, ReproduceError> {
    use mbsolve::analysis::{eigenmodes, ModeOptions, Tangent};
    use mbsolve::builders::{cantilever, RodParams};
    let dir = out.join("chain_modes");
    crate::output::create_dir(&dir).map_err(ReproduceError::Io)?;
    let n = CHAIN_MODES_N;
    let mut p = RodParams::problem_b(n);
    p.tilt = std::f64::consts::PI;
    let study = |e: String| ReproduceError::Study(format!("chain modes: {e}"));
    let (sys, info) = cantilever(&p, [0.0, 0.0]).map_err(|e| study(e.to_string()))?;
    let (q0, _) = sys.initial_state();
    let mut tan = Tangent::new(&sys);
    tan.evaluate(
        0.0,
        &q0,
        &vec![0.0; sys.n_coords()],
        &vec![0.0; sys.n_constraints()],
    )
    .map_err(|e| study(e.to_string()))?;
    let modes = eigenmodes(
        &tan,
        ModeOptions {
            count: 3,
            ..Default::default()
        },
    )
    .map_err(|e| study(e.to_string()))?;
    if modes.modes.len() < 3 || !modes.converged {
        return Err(study("the three lowest modes did not converge".into()));
    }
    let ls = info.segment_length;
    // lateral (x) deflection of the joints: the pivot end of segment 1,
    // then the free end of every segment (local (0, ∓l_s/2), linearised)
    let joints = |shape: &[f64]| -> Vec<f64> {
        let mut v = Vec::with_capacity(n + 1);
        let b0 = info.bodies[0];
        v.push(shape[3 * b0] + 0.5 * ls * q0[3 * b0 + 2].cos() * shape[3 * b0 + 2]);
        for &b in &info.bodies {
            v.push(shape[3 * b] - 0.5 * ls * q0[3 * b + 2].cos() * shape[3 * b + 2]);
        }
        let tip = v[n];
        v.iter().map(|d| d / tip).collect()
    };
    let ei = p.youngs_modulus * p.width.powi(4) / 12.0;
    let rho_a = p.density * p.width * p.width;
    let roots: Vec<f64> = [1.875, 4.694, 7.855]
        .iter()
        .map(|&g| cantilever_root(g))
        .collect();
    let beam_hz: Vec<f64> = roots
        .iter()
        .map(|b| b * b * (ei / (rho_a * p.length.powi(4))).sqrt() / (2.0 * std::f64::consts::PI))
        .collect();
    let s_joint: Vec<f64> = (0..=n).map(|k| k as f64 * ls).collect();
    let xi: Vec<f64> = s_joint.iter().map(|s| s / p.length).collect();
    let chain_joint: Vec<Vec<f64>> = modes.modes.iter().map(|m| joints(&m.shape)).collect();
    let beam_joint: Vec<Vec<f64>> = roots
        .iter()
        .map(|&b| xi.iter().map(|&x| cantilever_shape(b, x)).collect())
        .collect();
    let shape_difference: Vec<f64> = chain_joint
        .iter()
        .zip(&beam_joint)
        .map(|(c, b)| {
            c.iter()
                .zip(b)
                .fold(0.0f64, |a, (u, v)| a.max((u - v).abs()))
        })
        .collect();
    let chain_hz: Vec<f64> = modes.modes.iter().map(|m| m.frequency_hz).collect();
    // the joints' table
    let mut cols: Vec<(String, &[f64])> = vec![("s [m]".into(), &s_joint)];
    for k in 0..3 {
        cols.push((format!("chain mode {}", k + 1), &chain_joint[k]));
        cols.push((format!("Euler–Bernoulli mode {}", k + 1), &beam_joint[k]));
    }
    let refs: Vec<(&str, &[f64])> = cols.iter().map(|(a, b)| (a.as_str(), *b)).collect();
    write_columns_csv(&dir.join("chain_modes_joints.csv"), &refs)?;
    // the figure, sampled along the rod
    let samples = n * CHAIN_MODES_SAMPLES;
    let s: Vec<f64> = (0..=samples)
        .map(|j| p.length * j as f64 / samples as f64)
        .collect();
    let on_chain = |v: &[f64], x: f64| -> f64 {
        let u = (x / ls).clamp(0.0, n as f64);
        let k = (u.floor() as usize).min(n - 1);
        let f = u - k as f64;
        (1.0 - f) * v[k] + f * v[k + 1]
    };
    let mut series = Vec::new();
    for k in 0..3 {
        series.push(Series {
            label: format!("chain, mode {} ({:.2} Hz)", k + 1, chain_hz[k]),
            x: s.clone(),
            y: s.iter().map(|&x| on_chain(&chain_joint[k], x)).collect(),
        });
    }
    for k in 0..3 {
        series.push(Series {
            label: format!("Euler–Bernoulli, mode {} ({:.2} Hz)", k + 1, beam_hz[k]),
            x: s.clone(),
            y: s.iter()
                .map(|&x| cantilever_shape(roots[k], x / p.length))
                .collect(),
        });
    }
    Figure {
        title: format!(
            "Cantilevered chain, N = {n}, no gravity: first three mode shapes beside the Euler–Bernoulli beam"
        ),
        x_label: "position along the rod from the pivot [m]".into(),
        y_label: "lateral deflection / tip deflection [-]".into(),
        series,
        ..Default::default()
    }
    .save(&dir, "chain_modes")?;
    let mut table = String::from(
        "| mode | chain [Hz] | Euler–Bernoulli [Hz] | relative difference | max shape difference |\n|---|---|---|---|---|\n",
    );
    for k in 0..3 {
        let _ = writeln!(
            table,
            "| {} | {:.4} | {:.4} | {:.3e} | {:.3e} |",
            k + 1,
            chain_hz[k],
            beam_hz[k],
            chain_hz[k] / beam_hz[k] - 1.0,
            shape_difference[k]
        );
    }
    let path = dir.join("chain_modes_table.md");
    std::fs::write(&path, &table)
        .map_err(|e| ReproduceError::Io(format!("{}: {e}", path.display())))?;
    Ok(ChainModes {
        n,
        chain_hz,
        beam_hz,
        shape_difference,
    })
}
