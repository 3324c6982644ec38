//! `mbsolve study constraints`: the paper's review of constraint
//! enforcement (§3) run side by side.
//!
//! Every method of [`methods`] runs on every problem of [`problems`]: the
//! four-bar of problem A with the correct and the incorrect initial state,
//! the falling rod at N = 10, a chain of two parallelogram loops through
//! its singular configurations (Φ_q loses rank twice per revolution) and
//! the same chain with one rigid coupler over all crank tips (redundant
//! pins). Each run is judged against a reference ([`Reference`]) and
//! reported in one table: max ‖Φ‖, max ‖Φ̇‖, the energy-balance error
//! relative to the energy scale, steps, Newton iterations, wall time and
//! pass/fail. Figures: ‖Φ‖ and the energy-balance error over time per
//! problem (the paper's figs. 2–3 and 7), and the point error of the
//! parallelogram chains.

use crate::figure::{Figure, Series};
use crate::output::OutputError;
use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::formulation::{Baumgarte, Correction, Formulation};
use mbsolve::integrate::{Method, Tolerance, ALM_MAX_NEWTON};
use mbsolve::model::System;
use mbsolve::scenario::{self, FALLING_ROD_TOML, FOURBAR_TOML};
use mbsolve::simulation::{simulate_into, RunConfig, Sample, Sink, Summary};
use std::fmt::Write as _;
use std::path::Path;

/// Tolerances of the adaptive index-1 runs of the study.
const RTOL: f64 = 1e-6;
/// Absolute tolerance of the adaptive runs.
const ATOL: f64 = 1e-9;
/// Step cap of every run: an index-1 run stuck at a redundant constraint
/// set fails here instead of taking minutes.
const MAX_STEPS: usize = 200_000;
/// A position within this of the reference passes \[m\] (or rad).
const POSITION_TOL: f64 = 1e-3;
/// Relative energy drift allowed on the conservative parallelogram chains.
const ENERGY_TOL: f64 = 1e-4;
/// ‖Φ(t_end)‖ below this passes the incorrect start \[m\].
const RECOVERY_TOL: f64 = 1e-5;

/// One constraint-enforcement method: a label and how it sets a run up.
pub struct StudyMethod {
    /// Short name (file names, CSV).
    pub key: &'static str,
    /// Table label.
    pub label: &'static str,
    /// The integrator it runs on.
    pub base: Base,
    /// The method's own settings, on top of `base`'s.
    pub tweak: fn(&mut RunConfig),
}

/// The integrator a study method runs on.
#[derive(Clone, Copy)]
pub enum Base {
    /// ode45 at [`RTOL`], [`ATOL`].
    Ode45,
    /// Generalized-α at the problem's fixed step.
    GenAlpha,
    /// Variable-order BDF at [`RTOL`], [`ATOL`].
    Bdf,
}

impl StudyMethod {
    /// Set a run up: `base` (`h` is the problem's step for the fixed-step
    /// implicit methods, at most [`MAX_STEPS`] steps), then `tweak`.
    pub fn apply(&self, c: &mut RunConfig, h: f64) {
        c.method = match self.base {
            Base::Ode45 => Method::Ode45,
            Base::GenAlpha => Method::GenAlpha,
            Base::Bdf => Method::Bdf,
        };
        match self.base {
            Base::Ode45 | Base::Bdf => {
                c.ode.rtol = RTOL;
                c.ode.atol = Tolerance::Scalar(ATOL);
            }
            Base::GenAlpha => c.ode.fixed_step = Some(h),
        }
        c.ode.max_steps = MAX_STEPS;
        (self.tweak)(c);
    }
}

/// Baumgarte α = β = 10 \[1/s\].
const BAUMGARTE_10: Baumgarte = Baumgarte {
    alpha: 10.0,
    beta: 10.0,
};

/// The index-3 augmented Lagrangian with its own Newton iteration cap.
fn augmented_lagrangian(c: &mut RunConfig) {
    c.implicit.max_newton = ALM_MAX_NEWTON;
    c.formulation.formulation = Formulation::AugmentedLagrangian;
}

/// The methods compared, in table order.
pub fn methods() -> Vec<StudyMethod> {
    use Base::{Bdf, GenAlpha, Ode45};
    let row = |key, label, base, tweak: fn(&mut RunConfig)| StudyMethod {
        key,
        label,
        base,
        tweak,
    };
    vec![
        row(
            "none",
            "index 1, eq. (5), no stabilization (ode45)",
            Ode45,
            |_| {},
        ),
        row(
            "baumgarte",
            "Baumgarte α = β = 10, eq. (5) (ode45)",
            Ode45,
            |c| {
                c.formulation.baumgarte = BAUMGARTE_10;
            },
        ),
        row(
            "eliminated",
            "Baumgarte α = β = 10, λ eliminated, eq. (9) (ode45)",
            Ode45,
            |c| {
                c.formulation.formulation = Formulation::Eliminated;
                c.formulation.baumgarte = BAUMGARTE_10;
            },
        ),
        row(
            "projection",
            "mass-orthogonal projection of q, q̇ (ode45)",
            Ode45,
            |c| {
                c.formulation.projection.enabled = true;
            },
        ),
        row(
            "direct",
            "direct violation correction, one M-weighted step (ode45)",
            Ode45,
            |c| {
                c.formulation.projection.enabled = true;
                c.formulation.projection.correction = Correction::Direct;
            },
        ),
        row(
            "step_rule",
            "Baumgarte α = β = 1/h, h = max step 1e-3 s (ode45)",
            Ode45,
            |c| {
                c.ode.max_step = Some(1e-3);
                c.formulation.baumgarte = Baumgarte::from_step(1e-3);
            },
        ),
        row(
            "partitioned",
            "coordinate partitioning, Wehage & Haug (ode45)",
            Ode45,
            |c| {
                c.formulation.formulation = Formulation::Partitioned;
            },
        ),
        row(
            "penalty",
            "penalty, α = 1e7, ξ = 1, ω = 10 (ode45)",
            Ode45,
            |c| {
                c.formulation.formulation = Formulation::Penalty;
            },
        ),
        row(
            "alm_trapezoidal",
            "index-3 augmented Lagrangian + projections, trapezoidal",
            GenAlpha,
            |c| {
                c.method = Method::Newmark;
                c.implicit.rho_inf = 1.0;
                augmented_lagrangian(c);
            },
        ),
        row(
            "alm_genalpha",
            "index-3 augmented Lagrangian + projections, generalized-α",
            GenAlpha,
            augmented_lagrangian,
        ),
        row(
            "genalpha",
            "index 3, generalized-α ρ∞ = 0.8",
            GenAlpha,
            |_| {},
        ),
        row(
            "bdf",
            "index 3, variable-order BDF (rtol 1e-6)",
            Bdf,
            |_| {},
        ),
        row(
            "genalpha_projected",
            "index 3, generalized-α + projection",
            GenAlpha,
            |c| {
                c.implicit.project = true;
            },
        ),
    ]
}

/// How a run is judged.
pub enum Reference {
    /// Every position coordinate within [`POSITION_TOL`] of this trajectory
    /// at the output times (an ode45 run at rtol 1e-12 with projection).
    Trajectory(Vec<Vec<f64>>),
    /// ‖Φ‖ at the end below [`RECOVERY_TOL`] (an inconsistent start).
    Recovery,
    /// The chain's marked point within [`POSITION_TOL`] of the 1-DOF
    /// solution, and |E − E0| ≤ [`ENERGY_TOL`] E0.
    Chain(ParallelogramChain, Vec<[f64; 2]>),
}

/// One problem of the study.
pub struct Problem {
    /// Short name (file names).
    pub key: &'static str,
    /// Title of its figures.
    pub title: &'static str,
    /// The model.
    pub system: System,
    /// Initial state.
    pub q0: Vec<f64>,
    /// Initial velocities.
    pub qd0: Vec<f64>,
    /// Time span and outputs; methods set the rest.
    pub base: RunConfig,
    /// Step of the fixed-step implicit methods \[s\].
    pub h: f64,
    /// The judge.
    pub reference: Reference,
}

/// What the study keeps of one run.
#[derive(Default)]
struct Record {
    t: Vec<f64>,
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    norm: Vec<f64>,
    energy_error: Vec<f64>,
}

impl Sink for Record {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.t.push(s.t);
        self.q.push(s.q.to_vec());
        self.qd.push(s.qd.to_vec());
        self.norm.push(s.constraint_norm);
        self.energy_error
            .push(s.energy.map_or(f64::NAN, |e| e.balance_error.abs()));
        Ok(())
    }
}

/// One row of the study's table.
pub struct StudyRow {
    /// Problem key.
    pub problem: &'static str,
    /// Method key.
    pub method: &'static str,
    /// Method label.
    pub label: &'static str,
    /// The run's summary.
    pub summary: Summary,
    /// max ‖Φ‖₂ over the output times \[m\].
    pub max_phi: f64,
    /// ‖Φ‖₂ at the last output \[m\].
    pub final_phi: f64,
    /// Largest deviation from the reference (positions, or the chain's
    /// point) \[m\]; NaN for the recovery problem.
    pub deviation: f64,
    /// max |T + V − E0 − W| / energy scale.
    pub energy_drift: f64,
    /// Judged against the reference.
    pub pass: bool,
    /// Why it failed, if it did.
    pub why: String,
}

fn fourbar(incorrect: bool) -> Result<(System, Vec<f64>, Vec<f64>, RunConfig), String> {
    let sc = scenario::parse(
        FOURBAR_TOML,
        "scenarios/fourbar.toml",
        "fourbar",
        &[format!("initial.incorrect={incorrect}")],
    )
    .map_err(|e| e.to_string())?;
    Ok((sc.system, sc.q0, sc.qd0, sc.run))
}

fn chain_problem(
    key: &'static str,
    title: &'static str,
    redundant: bool,
) -> Result<Problem, String> {
    let p = ParallelogramChain {
        loops: 2,
        redundant,
        ..Default::default()
    };
    let system = parallelogram_chain(&p).map_err(|e| e.to_string())?;
    let (q0, qd0) = p.state(p.theta0, p.rate0);
    let base = RunConfig {
        t_end: 10.0,
        output_dt: 0.005,
        ..Default::default()
    };
    let points = p
        .reference(&base.output_times(), 1e-4)
        .into_iter()
        .map(|(th, _)| p.marked_point(th))
        .collect();
    Ok(Problem {
        key,
        title,
        system,
        q0,
        qd0,
        base,
        // generalized-α's numerical damping at 1e-3 s loses 1.3e-4 of the
        // energy over 10 s; 5e-4 s is the step of tests/integrators/augmented_lagrangian.rs
        h: 5e-4,
        reference: Reference::Chain(p, points),
    })
}

/// The reference of a problem given by a trajectory: ode45 at rtol 1e-12
/// with projection.
fn reference_run(system: &System, q0: &[f64], qd0: &[f64], base: &RunConfig) -> Reference {
    let mut c = base.clone();
    c.method = Method::Ode45;
    c.ode.rtol = 1e-12;
    c.ode.atol = Tolerance::Scalar(1e-14);
    c.formulation.projection.enabled = true;
    let mut r = Record::default();
    match simulate_into(system, q0, qd0, &c, &mut [], &mut r) {
        Ok(_) => Reference::Trajectory(r.q),
        Err(_) => Reference::Trajectory(Vec::new()),
    }
}

/// The problems, with their references.
pub fn problems() -> Result<Vec<Problem>, String> {
    let mut v = Vec::new();
    for incorrect in [false, true] {
        let (system, q0, qd0, mut base) = fourbar(incorrect)?;
        base.t_end = 2.0;
        let reference = if incorrect {
            Reference::Recovery
        } else {
            reference_run(&system, &q0, &qd0, &base)
        };
        v.push(Problem {
            key: if incorrect {
                "fourbar_incorrect"
            } else {
                "fourbar_correct"
            },
            title: if incorrect {
                "Four-bar, incorrect initial state"
            } else {
                "Four-bar, correct initial state"
            },
            system,
            q0,
            qd0,
            base,
            // the crank reaches 75 rad/s: steps of 1e-3 s give a phase
            // error of 0.26 rad at 2 s, 1e-4 s of 2.2e-3 rad
            h: 5e-5,
            reference,
        });
    }
    let sc = scenario::parse(
        FALLING_ROD_TOML,
        "scenarios/falling_rod.toml",
        "falling_rod",
        &[],
    )
    .map_err(|e| e.to_string())?;
    let mut base = sc.run.clone();
    base.t_end = 0.5;
    let reference = reference_run(&sc.system, &sc.q0, &sc.qd0, &base);
    v.push(Problem {
        key: "falling_rod",
        title: "Falling rod, N = 10",
        system: sc.system,
        q0: sc.q0,
        qd0: sc.qd0,
        base,
        h: 5e-5,
        reference,
    });
    v.push(chain_problem(
        "parallelogram",
        "Two parallelogram loops through singular positions",
        false,
    )?);
    v.push(chain_problem(
        "parallelogram_redundant",
        "Two parallelogram loops, one redundant coupler",
        true,
    )?);
    Ok(v)
}

/// The deviation from the reference at each output (empty for
/// [`Reference::Recovery`]).
fn deviations(p: &Problem, r: &Record) -> Vec<f64> {
    match &p.reference {
        Reference::Trajectory(qr) => {
            r.q.iter()
                .zip(qr)
                .map(|(q, qref)| {
                    q.iter()
                        .zip(qref)
                        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
                })
                .collect()
        }
        Reference::Recovery => Vec::new(),
        Reference::Chain(chain, points) => {
            r.q.iter()
                .zip(points)
                .map(|(q, pr)| {
                    let pq = chain.marked_point_of(q);
                    (pq[0] - pr[0]).hypot(pq[1] - pr[1])
                })
                .collect()
        }
    }
}

fn judge(p: &Problem, r: &Record, s: &Summary, dev: &[f64]) -> (f64, bool, String) {
    let completed = s.status == "completed";
    let mut why = if completed {
        String::new()
    } else {
        format!("{} at t = {:.4}", s.status, s.t_reached)
    };
    let fail = |why: &mut String, msg: String| {
        if why.is_empty() {
            *why = msg;
        }
    };
    let deviation = match &p.reference {
        Reference::Trajectory(qr) => {
            let worst = dev.iter().cloned().fold(0.0, f64::max);
            if qr.len() < r.q.len() || qr.is_empty() {
                fail(&mut why, "no reference".into());
            }
            if !within(worst, POSITION_TOL) {
                fail(&mut why, format!("deviation {worst:.1e}"));
            }
            worst
        }
        Reference::Recovery => {
            let last = r.norm.last().copied().unwrap_or(f64::NAN);
            if !within(last, RECOVERY_TOL) {
                fail(&mut why, format!("final ‖Φ‖ {last:.1e}"));
            }
            f64::NAN
        }
        Reference::Chain(chain, _) => {
            let worst = dev.iter().cloned().fold(0.0, f64::max);
            if !within(worst, POSITION_TOL) {
                fail(
                    &mut why,
                    format!("left the branch: point off by {worst:.1e} m"),
                );
            }
            let e0 = chain.reduced_energy(chain.theta0, chain.rate0);
            // conservative: T + V is the whole balance
            let de =
                r.q.iter()
                    .zip(&r.qd)
                    .map(|(q, qd)| (p.system.mechanical_energy(q, qd) - e0).abs())
                    .fold(0.0, f64::max);
            if !within(de, ENERGY_TOL * e0) {
                fail(&mut why, format!("energy drift {:.1e}", de / e0));
            }
            worst
        }
    };
    // an implicit run that gained energy left its manifold or branch,
    // whatever its final ‖Φ‖ (the four-bar's incorrect start before the
    // index-3 start projection: +1.0e4 J on 14 J with ‖Φ(t_end)‖ tiny)
    if s.warnings.iter().any(|w| w.contains("gained energy")) {
        fail(&mut why, "gained energy".into());
    }
    (deviation, completed && why.is_empty(), why)
}

/// `v ≤ tol`, false for NaN.
fn within(v: f64, tol: f64) -> bool {
    v <= tol
}

fn fmt_e(v: f64) -> String {
    if v.is_nan() {
        "–".into()
    } else {
        format!("{v:.2e}")
    }
}

/// Run the study, writing the table (Markdown and CSV), the figures and
/// their CSVs under `out/constraints/`. Returns the rows.
pub fn constraints(out: &Path) -> Result<Vec<StudyRow>, String> {
    let dir = out.join("constraints");
    crate::output::create_dir(&dir)?;
    let mut rows = Vec::new();
    for p in problems()? {
        let mut norm_series = Vec::new();
        let mut energy_series = Vec::new();
        let mut dev_series = Vec::new();
        for m in methods() {
            let mut c = p.base.clone();
            m.apply(&mut c, p.h);
            c.outputs.energy = true;
            let mut r = Record::default();
            let summary = match simulate_into(&p.system, &p.q0, &p.qd0, &c, &mut [], &mut r) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("  {} / {}: could not start: {e}", p.key, m.key);
                    continue;
                }
            };
            let dev = deviations(&p, &r);
            let (deviation, pass, why) = judge(&p, &r, &summary, &dev);
            if !dev.is_empty() {
                dev_series.push(Series {
                    label: m.key.into(),
                    x: r.t.clone(),
                    y: dev,
                });
            }
            let extra = |k: &str| {
                summary
                    .extra
                    .get(k)
                    .and_then(|v| v.as_f64())
                    .unwrap_or(f64::NAN)
            };
            let energy_drift = extra("max_energy_balance_error") / extra("energy_scale");
            let max_phi = r.norm.iter().cloned().fold(0.0, f64::max);
            eprintln!(
                "  {:<24} {:<20} {} {:>6} steps, max‖Φ‖ {}, dev {}, {:.2} s {}",
                p.key,
                m.key,
                if pass { "pass" } else { "FAIL" },
                summary.steps,
                fmt_e(max_phi),
                fmt_e(deviation),
                summary.wall_s,
                why
            );
            norm_series.push(Series {
                label: m.key.into(),
                x: r.t.clone(),
                y: r.norm.clone(),
            });
            energy_series.push(Series {
                label: m.key.into(),
                x: r.t.clone(),
                y: r.energy_error.clone(),
            });
            rows.push(StudyRow {
                problem: p.key,
                method: m.key,
                label: m.label,
                max_phi,
                final_phi: r.norm.last().copied().unwrap_or(f64::NAN),
                deviation,
                energy_drift,
                pass,
                why,
                summary,
            });
        }
        // one figure over time, log y: `what` in its title, saved as `<problem>_<file>`
        let save = |what: &str, y_label: &str, series: Vec<Series>, file: &str| {
            let f = Figure {
                title: format!("{}: {what}", p.title),
                x_label: "t [s]".into(),
                y_label: y_label.into(),
                series,
                log_y: true,
                ..Default::default()
            };
            let name = format!("{}_{file}", p.key);
            f.save(&dir, &name).map_err(|e: OutputError| e.to_string())
        };
        save("‖Φ‖₂", "‖Φ‖₂ [m]", norm_series, "norm")?;
        let energy = "|T + V − E0 − W| [J]";
        save("energy balance error", energy, energy_series, "energy")?;
        if !dev_series.is_empty() {
            let (what, y_label) = if matches!(p.reference, Reference::Chain(..)) {
                ("point error against the 1-DOF solution", "error [m]")
            } else {
                (
                    "max |q − q_ref| (ode45, rtol 1e-12, projected)",
                    "max |Δq| [m, rad]",
                )
            };
            save(what, y_label, dev_series, "deviation")?;
        }
    }
    let md = table(&rows);
    std::fs::write(dir.join("table.md"), &md).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("table.csv"), table_csv(&rows)).map_err(|e| e.to_string())?;
    Ok(rows)
}

fn newton(s: &Summary) -> String {
    s.extra
        .get("newton_iterations")
        .and_then(|v| v.as_u64())
        .map_or("–".into(), |n| n.to_string())
}

/// The Markdown table of the study.
pub fn table(rows: &[StudyRow]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| problem | method | max ‖Φ‖ [m] | max ‖Φ̇‖ [m/s] | final ‖Φ‖ | deviation | energy drift | steps | Newton its | wall [s] | result |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {} |",
            r.problem,
            r.label,
            fmt_e(r.max_phi),
            fmt_e(r.summary.max_velocity_constraint_norm),
            fmt_e(r.final_phi),
            fmt_e(r.deviation),
            fmt_e(r.energy_drift),
            r.summary.steps,
            newton(&r.summary),
            r.summary.wall_s,
            if r.pass {
                "pass".to_string()
            } else {
                format!("FAIL: {}", r.why)
            }
        );
    }
    s
}

fn table_csv(rows: &[StudyRow]) -> String {
    let mut s = String::from(
        "problem,method,max_phi,max_phid,final_phi,deviation,energy_drift,steps,newton_iterations,wall_s,status,pass\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{:e},{:e},{:e},{:e},{:e},{},{},{:e},{},{}",
            r.problem,
            r.method,
            r.max_phi,
            r.summary.max_velocity_constraint_norm,
            r.final_phi,
            r.deviation,
            r.energy_drift,
            r.summary.steps,
            newton(&r.summary),
            r.summary.wall_s,
            r.summary.status,
            r.pass
        );
    }
    s
}
