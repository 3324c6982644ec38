//! One run, end to end: formulation + integrator + observation of the
//! constraint violation, with a [`Summary`] of the work done.

use crate::formulation::{
    Augmented, AugmentedParams, ExplicitForm, Formulation, FormulationError, Index1, Index1Options,
    Index3, Index3Complex, NewtonSolverKind, Partitioned, SingularityMonitor,
};
use crate::integrate::{
    integrator, Bdf, Family, GenAlpha, ImplicitOptions, Integrator, IntegratorError, Method,
    Observer, OdeOptions, Radau5, Report, Span, Stats, Termination, Tolerance,
};
use crate::model::System;
use crate::numeric::Time;
use crate::parallel::{with_threads, Threads};
use serde::Serialize;
use std::ops::ControlFlow;
use std::time::Instant;

pub mod choice;
mod methods;
mod stiffness;
mod watch;
pub use choice::MethodChoice;
use methods::{AugmentedRun, BdfRun, Explicit, GenAlphaRun, MethodRun, Partition, RadauRun};
use stiffness::stability_check;
pub use stiffness::LOAD_CROSSINGS;
use watch::Watch;
pub use watch::{IMPLICIT_ENERGY_GAIN, SIZE_FRACTION, STALL_FACTOR, STALL_SLACK};

/// What to integrate and how.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// Integration method (ignored when `choice` is [`MethodChoice::Auto`]).
    pub method: Method,
    /// Whether `method` is used as given or chosen at t0 ([`choice`]).
    pub choice: MethodChoice,
    /// Integrator options (tolerances, steps).
    pub ode: OdeOptions,
    /// Start time.
    pub t0: f64,
    /// End time.
    pub t_end: f64,
    /// Spacing of output times (t0, t0 + dt, …, t_end).
    pub output_dt: f64,
    /// How the constraints enter the equations of motion (scenario key
    /// `formulation`: saddle point, λ eliminated, penalty, partitioned,
    /// augmented Lagrangian), with the Baumgarte, projection, penalty and
    /// partitioning parameters and the linear solver of every method.
    pub formulation: Index1Options,
    /// Options of the index-3 methods (which fields apply to which method:
    /// [`crate::integrate::METHODS`]): ρ∞, adaptivity, Newton, projection. Their step,
    /// tolerances, `max_step`, `initial_step` and `max_steps` come from
    /// `ode`, their linear solver from `formulation.linear_solver`. Must stay
    /// at its default for the explicit methods ([`ImplicitOptions::validate`]).
    pub implicit: ImplicitOptions,
    /// Parameters of `formulation.formulation =`
    /// [`Formulation::AugmentedLagrangian`] (implicit methods only).
    pub augmented: AugmentedParams,
    /// Guards against silent nonsense: warnings and the "diverged" stop.
    pub guards: Guards,
    /// Quantities computed at each output time besides q, q̇ and ‖Φ‖.
    pub outputs: OutputQuantities,
    /// Threads of the run's concurrent passes (scenario key
    /// `integrator.threads`; `Auto`, the default, takes
    /// [`crate::parallel::THREADS_ENV`] when set).
    pub threads: Threads,
}

/// Optional quantities of each output row ([`Sample`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OutputQuantities {
    /// Velocities q̇ (always in a [`Sample`]; tells writers to include them).
    pub velocities: bool,
    /// Accelerations q̈ (from eq. (5) at the output state, with the run's
    /// Baumgarte terms; index-3 runs: without).
    pub accelerations: bool,
    /// Multipliers λ and the joint reactions `−Φ_qᵀλ`
    /// ([`System::joint_reactions`]).
    pub reactions: bool,
    /// The energy balance ([`EnergyTerms`]).
    pub energy: bool,
    /// The generalized force `−λ` of each drive ([`crate::model::drives`]);
    /// needs λ like the reactions.
    pub drives: bool,
}

/// The terms of the energy balance at an output time
/// (`crate::model::energy`): `T + V_g + V_e − E0 = W_f + W_d` up to
/// `balance_error`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyTerms {
    /// Kinetic energy T = ½ q̇ᵀMq̇ \[J\].
    pub kinetic: f64,
    /// Potential of gravity V_g \[J\].
    pub gravity: f64,
    /// Every other potential V_e (springs, contacts' elastic part,
    /// buoyancy) \[J\].
    pub elastic: f64,
    /// Work W_f of the non-conservative force elements since t0: dampers,
    /// friction (negative: dissipated), actuators and applied loads \[J\].
    pub work_forces: f64,
    /// Work W_d of the constraint forces since t0 (`∫λᵀΦ_t`: the drives;
    /// zero for scleronomic joints) \[J\].
    pub work_drives: f64,
    /// `T + V − E0 − W_f − W_d` \[J\].
    pub balance_error: f64,
}

/// Guards watched at every accepted step (and ‖Φ̇‖ at every output:
/// a warning above `100 (rtol V + atol)`, V the largest body speed seen). A
/// guard that trips warns once
/// (console through [`Sink::warning`], and the summary), with the time;
/// past the divergence bounds the run stops with status `"diverged"`.
///
/// The length scale `L` is the largest position coordinate of `q0` (at
/// least 1 mm).
#[derive(Debug, Clone, PartialEq)]
pub struct Guards {
    /// Warn when ‖Φ‖₂ exceeds this \[m\]; `None`: `100 (rtol L + atol)`,
    /// the drift an accurate run at these tolerances stays far below.
    pub constraint_warn: Option<f64>,
    /// Stop ("diverged") when ‖Φ‖₂ exceeds this \[m\]; `None`:
    /// `max(L, 10 × constraint_warn)` — the mechanism has come apart.
    pub constraint_fail: Option<f64>,
    /// Stop ("diverged") when a position coordinate exceeds this multiple
    /// of `L` in magnitude.
    pub position_factor: f64,
    /// Stop on divergence (else only warn).
    pub stop_on_divergence: bool,
}

impl Default for Guards {
    fn default() -> Self {
        Self {
            constraint_warn: None,
            constraint_fail: None,
            position_factor: 1e6,
            stop_on_divergence: true,
        }
    }
}

impl Default for RunConfig {
    /// ode23 with MATLAB's default options from 0 to 1 s, outputs every
    /// 0.01 s, default index-1 and implicit options.
    fn default() -> Self {
        Self {
            method: Method::Ode23,
            choice: MethodChoice::Given,
            ode: OdeOptions::default(),
            t0: 0.0,
            t_end: 1.0,
            output_dt: 0.01,
            formulation: Index1Options::default(),
            implicit: ImplicitOptions::default(),
            augmented: AugmentedParams::default(),
            guards: Guards::default(),
            outputs: OutputQuantities::default(),
            threads: Threads::Auto,
        }
    }
}

impl RunConfig {
    /// Output times `t0, t0 + dt, …`, ending exactly at `t_end`.
    pub fn output_times(&self) -> Vec<f64> {
        let n = self.output_intervals() as usize;
        let mut t: Vec<f64> = (0..n)
            .map(|k| self.t0 + k as f64 * self.output_dt)
            .collect();
        t.push(self.t_end);
        t
    }

    /// Number of output times before `t_end` (at least 1), as an `f64` so
    /// that a huge count can be checked before anything is allocated;
    /// [`RunConfig::output_times`] has one more.
    pub fn output_intervals(&self) -> f64 {
        ((self.t_end - self.t0) / self.output_dt - 1e-9)
            .ceil()
            .max(1.0)
    }
}

/// Sampled solution at the output times.
#[derive(Debug, Clone, Default)]
pub struct Trajectory {
    /// Output times reached.
    pub t: Vec<f64>,
    /// Positions q at each output time.
    pub q: Vec<Vec<f64>>,
    /// Velocities q̇ at each output time.
    pub qd: Vec<Vec<f64>>,
    /// Constraint values Φ(q, t) at each output time.
    pub phi: Vec<Vec<f64>>,
    /// ‖Φ‖₂ at each output time.
    pub constraint_norm: Vec<f64>,
    /// ‖Φ̇‖₂ = ‖Φ_q q̇ + Φ_t‖₂ at each output time.
    pub velocity_constraint_norm: Vec<f64>,
}

/// One output row, as a [`Sink`] receives it at an output time.
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    /// Output time.
    pub t: f64,
    /// Positions q.
    pub q: &'a [f64],
    /// Velocities q̇.
    pub qd: &'a [f64],
    /// Constraint values Φ(q, t).
    pub phi: &'a [f64],
    /// ‖Φ‖₂.
    pub constraint_norm: f64,
    /// ‖Φ̇‖₂ = ‖Φ_q q̇ + Φ_t‖₂.
    pub velocity_constraint_norm: f64,
    /// Accelerations q̈, if [`OutputQuantities::accelerations`].
    pub qdd: Option<&'a [f64]>,
    /// Multipliers λ, if [`OutputQuantities::reactions`] or
    /// [`OutputQuantities::drives`] (`None` where eq. (5) failed).
    pub lambda: Option<&'a [f64]>,
    /// Joint reactions `(f_x, f_y, m_z)` per joint
    /// ([`System::joint_reactions`]), if [`OutputQuantities::reactions`].
    pub reactions: Option<&'a [f64]>,
    /// The energy balance, if [`OutputQuantities::energy`].
    pub energy: Option<EnergyTerms>,
}

/// Where a run's outputs go, as the integration delivers them: kept in
/// memory ([`Trajectory`]) or streamed to a file by the caller (the CLI
/// writes CSV rows as they come, in bounded memory).
pub trait Sink {
    /// One row at an output time. An `Err` ends the run: status
    /// `"failed"`, the message names the error; rows delivered before it
    /// stay valid.
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;
    /// After every accepted step, with the work so far: progress reports,
    /// interrupts. `Break(reason)` ends the run with status
    /// `"interrupted"`.
    fn progress(&mut self, _t: f64, _stats: &Stats) -> ControlFlow<String> {
        ControlFlow::Continue(())
    }
    /// A warning as it arises (it is also in [`Summary::warnings`]).
    fn warning(&mut self, _message: &str) {}
}

impl Sink for Trajectory {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.t.push(s.t);
        self.q.push(s.q.to_vec());
        self.qd.push(s.qd.to_vec());
        self.phi.push(s.phi.to_vec());
        self.constraint_norm.push(s.constraint_norm);
        self.velocity_constraint_norm
            .push(s.velocity_constraint_norm);
        Ok(())
    }
}

/// Work and accuracy figures of one run (written as `*.summary.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Integration method.
    pub method: String,
    /// `saddle` (eq. (5)), `eliminated` (eq. (9)), `penalty` or `index3`.
    pub formulation: String,
    /// Linear solver.
    pub linear_solver: String,
    /// Evaluation of Φ, Φ_q, γ: `generic` or the generated kernels' name.
    pub evaluation: String,
    /// Baumgarte α.
    pub alpha: f64,
    /// Baumgarte β.
    pub beta: f64,
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance (scalar, or the largest component).
    pub atol: f64,
    /// Bodies.
    pub bodies: usize,
    /// Coordinates n.
    pub coordinates: usize,
    /// Constraint equations m.
    pub constraints: usize,
    /// Accepted steps.
    pub steps: usize,
    /// Rejected steps.
    pub failed_steps: usize,
    /// Right-hand-side evaluations (as the integrator counts them).
    pub rhs_evals: usize,
    /// Numeric factorisations of the saddle-point (or Schur) matrix.
    pub factorizations: usize,
    /// Regularised pivots over all factorisations.
    pub regularized_pivots: usize,
    /// Those of them in Newton matrices whose `A` block was indefinite (a
    /// coordinate pivot ≤ 0: an iterate far from the solution, e.g. a
    /// contact onset in a large implicit step), not a loss of rank of Φ_q.
    pub indefinite_pivots: usize,
    /// Wall-clock time of the integration \[s\].
    pub wall_s: f64,
    /// max ‖Φ‖₂ over accepted steps and output times.
    pub max_constraint_norm: f64,
    /// ‖Φ‖₂ at the last output time.
    pub final_constraint_norm: f64,
    /// max ‖Φ̇‖₂ over output times.
    pub max_velocity_constraint_norm: f64,
    /// Requested end time.
    pub t_end: f64,
    /// Time reached.
    pub t_reached: f64,
    /// `completed`, `failed`, `diverged` (a [`Guards`] bound) or
    /// `interrupted` (the sink asked to stop, e.g. on SIGINT).
    pub status: String,
    /// Output rows delivered (all complete and valid, also when the run
    /// failed or was interrupted).
    pub output_rows: usize,
    /// Why the run failed or stopped.
    pub message: Option<String>,
    /// Integrator notices.
    pub warnings: Vec<String>,
    /// Extra figures from monitors (e.g. contact events).
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// Watches accepted steps (e.g. contact events) and adds to the summary.
pub trait Monitor {
    /// After each accepted step.
    fn step(&mut self, t: f64, q: &[f64], qd: &[f64]);
    /// Add figures to the summary.
    fn report(&self, extra: &mut serde_json::Map<String, serde_json::Value>);
}

/// A run that could not start.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SimulationError {
    /// Invalid formulation settings or a failing symbolic analysis.
    #[error(transparent)]
    Formulation(#[from] FormulationError),
    /// Invalid integrator settings.
    #[error(transparent)]
    Integrator(#[from] IntegratorError),
    /// Initial state of the wrong length or not finite.
    #[error("initial state: {0}")]
    Initial(String),
    /// A bad setting from the environment (e.g. `MBSOLVE_THREADS`).
    #[error("{0}")]
    Environment(String),
    /// The steps the system's fastest rates at t0 demand exceed the run's
    /// step cap ([`crate::integrate::OdeOptions::max_steps`]): the run
    /// could only end failing, after minutes.
    #[error("{0}")]
    TooStiff(String),
    /// The fixed step of an explicit method exceeds its stability limit.
    #[error(
        "{method} with step {h:e} s (integrator.step) is unstable for this system: the stability limit is \
         {limit:.3e} s ({reach} / max(ω, σ), fastest mode ω = {omega:.4e} rad/s, damping rate \
         σ = {sigma:.4e} 1/s at t0); use a step below the limit or an implicit method \
         (genalpha)"
    )]
    Unstable {
        /// The method.
        method: &'static str,
        /// Its step.
        h: f64,
        /// The largest stable step.
        limit: f64,
        /// Reach of the method's stability region.
        reach: f64,
        /// Fastest natural frequency.
        omega: f64,
        /// Fastest damping rate.
        sigma: f64,
    },
}

/// Integrate the equations of motion of `sys` from `(q0, q̇0)`, keeping
/// every output in memory ([`Trajectory`]); see [`simulate_into`].
///
/// A failure midway (step-size collapse, singular matrix) is not an `Err`:
/// the trajectory up to the failure is returned and the summary says where
/// and why (`status = "failed"`).
pub fn simulate(
    sys: &System,
    q0: &[f64],
    qd0: &[f64],
    cfg: &RunConfig,
    monitors: &mut [&mut dyn Monitor],
) -> Result<(Trajectory, Summary), SimulationError> {
    let mut traj = Trajectory::default();
    let summary = simulate_into(sys, q0, qd0, cfg, monitors, &mut traj)?;
    Ok((traj, summary))
}

/// `Err` with the reason unless `q` and `q̇` are a state of `sys`:
/// [`System::n_coords`] entries each, all finite.
pub(crate) fn check_state(sys: &System, q: &[f64], qd: &[f64]) -> Result<(), String> {
    let n = sys.n_coords();
    if q.len() != n || qd.len() != n {
        return Err(format!(
            "expected {n} coordinates and velocities, got {} and {}",
            q.len(),
            qd.len()
        ));
    }
    match q.iter().chain(qd).position(|v| !v.is_finite()) {
        Some(k) => Err(format!("component {k} of (q, q̇) is not finite")),
        None => Ok(()),
    }
}

/// Integrate the equations of motion of `sys` from `(q0, q̇0)`, handing
/// each output row to `sink` as the integration delivers it (memory
/// bounded independently of the number of outputs).
///
/// A failure midway, a failing sink or an interrupt from the sink is not
/// an `Err`: the summary says where and why (`status`, `message`) and how
/// many rows were delivered (`output_rows`).
pub fn simulate_into(
    sys: &System,
    q0: &[f64],
    qd0: &[f64],
    cfg: &RunConfig,
    monitors: &mut [&mut dyn Monitor],
    sink: &mut dyn Sink,
) -> Result<Summary, SimulationError> {
    check_state(sys, q0, qd0).map_err(SimulationError::Initial)?;
    // `integrator.method = "auto"`: the method from the rates at t0
    let chosen = match cfg.choice {
        MethodChoice::Given => None,
        MethodChoice::Auto => Some(choice::choose(sys, cfg, q0, qd0)?),
    };
    let cfg = chosen.as_ref().map_or(cfg, |(run, _)| run);
    cfg.implicit.validate(cfg.method, cfg.ode.fixed_step)?;
    let threads = cfg
        .threads
        .resolve()
        .map_err(SimulationError::Environment)?;
    // the method's family (its row of the method table) picks the run;
    // the augmented Lagrangian and coordinate partitioning are formulations
    let mut method: Box<dyn MethodRun + '_> =
        match (cfg.method.family(), cfg.formulation.formulation) {
            (_, Formulation::AugmentedLagrangian) => Box::new(AugmentedRun::new(sys, cfg)?),
            (Family::GeneralizedAlpha, _) => Box::new(GenAlphaRun::new(sys, cfg)?),
            (Family::Bdf, _) => Box::new(BdfRun::new(sys, cfg)?),
            (Family::Radau, _) => Box::new(RadauRun::new(sys, cfg)?),
            (Family::RungeKutta | Family::Adams, Formulation::Partitioned) => {
                let f =
                    Partitioned::new(sys, cfg.formulation.partition, cfg.formulation, cfg.t0, q0)?;
                Box::new(Partition { f })
            }
            (Family::RungeKutta | Family::Adams, _) => Box::new(Explicit::new(sys, cfg)?),
        };
    let (mut q0, mut qd0) = (q0.to_vec(), qd0.to_vec());
    let moved = method.consistent_start(cfg, &mut q0, &mut qd0)?;
    let mut watch = Watch::new(sys, cfg, &q0, monitors, sink);
    if let Some(message) = moved {
        watch.warn(message);
    }
    let times = cfg.output_times();
    let mut start = Instant::now();
    // one team for the stability check's solves and the integration, both
    // under the run's thread setting
    let (report, team) = with_threads(threads, || {
        crate::parallel::run_with_team(q0.len() + qd0.len(), || {
            stability_check(sys, cfg, &q0, &qd0, &mut watch)?;
            watch.start_balance(cfg.t0, &q0, &qd0);
            start = Instant::now();
            let span = Span {
                t0: cfg.t0,
                t_end: cfg.t_end,
                q0: &q0,
                qd0: &qd0,
                output_times: &times,
                obs: &mut watch,
            };
            Ok::<_, SimulationError>(method.integrate(cfg, span)?)
        })
    });
    let report = report?;
    let wall_s = start.elapsed().as_secs_f64();
    let (work, mut extra) = method.work(cfg);
    // what the concurrent passes did (crate::parallel)
    let setting = serde_json::to_value(threads).unwrap_or_default();
    extra.insert("threads_setting".into(), setting);
    extra.insert("threads".into(), team.threads().into());
    extra.insert("split".into(), (team.halves_split > 0).into());
    extra.insert("halves_split".into(), team.halves_split.into());
    extra.insert("halves_taken_back".into(), team.halves_taken_back.into());
    extra.insert(
        "halves_taken_back_awake".into(),
        team.halves_taken_back_awake.into(),
    );
    extra.insert("threads_passes".into(), team.passes.into());
    extra.insert("threads_caller_parks".into(), team.caller_parks.into());
    extra.insert("threads_helper_wakes".into(), team.helper_wakes.into());
    extra.insert("halves_solo".into(), team.halves_solo.into());
    extra.insert(
        "threads_rule".into(),
        serde_json::to_value(team.rule).unwrap_or_default(),
    );
    extra.insert("threads_reason".into(), team.rule.reason().into());
    if team.clock.run_s > 0.0 {
        extra.insert(
            "threads_clock".into(),
            serde_json::to_value(team.clock).unwrap_or_default(),
        );
    }
    if let Some((run, reason)) = &chosen {
        extra.insert("method_choice".into(), run.method.name().into());
        extra.insert("method_choice_reason".into(), reason.clone().into());
    }
    Ok(finish(sys, cfg, watch, &report, wall_s, work, extra))
}

/// Formulation-specific figures of a run, for [`finish`].
struct Work {
    formulation: String,
    linear_solver: String,
    baumgarte: (f64, f64),
    factorizations: usize,
    regularized_pivots: usize,
    /// Those in factorisations with an indefinite `A` block
    /// ([`crate::linalg::FactorInfo::indefinite`]).
    indefinite_pivots: usize,
    /// Time of the first regularised pivot (index-1 runs).
    first_regularized_t: Option<f64>,
}

/// Assemble the [`Summary`] of a run (both paths).
fn finish(
    sys: &System,
    cfg: &RunConfig,
    watch: Watch<'_, '_, '_, '_>,
    report: &Report,
    wall_s: f64,
    work: Work,
    mut extra: serde_json::Map<String, serde_json::Value>,
) -> Summary {
    let (status, message) = match (&report.termination, &watch.sink_error, &watch.diverged) {
        (Termination::Completed, _, _) => ("completed", None),
        (Termination::Failed { reason, .. }, _, _) => {
            let mut m = reason.to_string();
            // a Newton collapse of the index-3 form where Φ_q lost rank
            if let (
                "index3",
                crate::integrate::Failure::StepTooSmall {
                    cause: crate::integrate::StepCut::Newton { .. },
                    ..
                },
            ) = (work.formulation.as_str(), reason)
            {
                let rank = work.regularized_pivots - work.indefinite_pivots;
                if rank > 0 {
                    m.push_str(&format!(
                        " — {rank} regularised pivots: if the position is singular or constraints are \
                         redundant, formulation = \"augmented_lagrangian\" passes through them \
                         (docs/constraint_methods.md)"
                    ));
                } else if work.indefinite_pivots > 0 {
                    m.push_str(&format!(
                        " — {} regularised pivots, all in Newton matrices whose A block was \
                         indefinite (iterates far from the solution), none from Φ_q losing rank: \
                         a smaller step",
                        work.indefinite_pivots
                    ));
                } else {
                    // What was checked: the pivots of every Newton matrix's
                    // factorisation, at the system's full size; a nearly
                    // singular Φ_q above the regularisation threshold is not
                    // excluded by them.
                    m.push_str(&format!(
                        " — no regularised pivot in the {} factorisations of the Newton matrix \
                         ({} coordinates): none found Φ_q rank-deficient; a nearly singular \
                         position is not excluded by that check",
                        work.factorizations,
                        sys.n_coords()
                    ));
                }
            }
            ("failed", Some(m))
        }
        (Termination::Stopped { .. }, Some(e), _) => ("failed", Some(e.clone())),
        (Termination::Stopped { .. }, None, _) if watch.stalled.is_some() => {
            ("failed", watch.stalled.clone())
        }
        (Termination::Stopped { .. }, None, Some(d)) => ("diverged", Some(d.clone())),
        (Termination::Stopped { reason, .. }, None, None) => ("interrupted", Some(reason.clone())),
    };
    if let Some(b) = &watch.balance {
        extra.insert("max_energy_balance_error".into(), b.max_error.into());
        extra.insert("energy_scale".into(), b.scale.into());
        extra.insert("energy_quadrature_error".into(), b.quadrature_error.into());
    }
    // shown as they occurred first (guards, then the integrator's notices
    // forwarded through the sink), then the end-of-run ones
    let mut warnings = watch.warnings;
    warnings.extend(report.warnings.iter().cloned());
    if let Some(b) = &watch.balance {
        // what the tolerance and the quadrature of W explain
        let bound = (100.0 * cfg.ode.rtol * b.scale).max(b.floor) + 10.0 * b.quadrature_error;
        if !cfg.method.is_index3() && b.max_error > bound {
            warnings.push(format!(
                "energy balance broken: |T + V − E0 − W| reached {:.3e} J, more than \
                 100 rtol × {:.3e} J (the energy in play: the largest of |T0| + |V0| + |W|, T \
                 and the changes of V) or {:.3e} J (½ Σ (2m + I) atol², the energy of a \
                 velocity error of atol), whichever is larger, + 10 × {:.3e} J (the quadrature \
                 error of W) = {bound:.3e} J: the integration error or the constraint drift \
                 is larger than the tolerance explains",
                b.max_error, b.scale, b.floor, b.quadrature_error
            ));
        }
        // The implicit methods damp numerically (ρ∞ < 1) or conserve
        // (trapezoidal): they lose energy, they never create it. A gain
        // beyond IMPLICIT_ENERGY_GAIN of the scale (plus the quadrature
        // error of W) means the run left its manifold or its branch.
        let gain_bound = (IMPLICIT_ENERGY_GAIN * b.scale).max(b.floor) + 10.0 * b.quadrature_error;
        if cfg.method.is_index3() && b.max_gain > gain_bound {
            warnings.push(format!(
                "energy balance broken: the run gained energy, T + V − E0 − W reached \
                 +{:.3e} J, more than {} of the energy in play {:.3e} J or the energy of a \
                 velocity error of atol {:.3e} J, whichever is larger (+ 10 × {:.3e} J, the \
                 quadrature error of W); the numerical damping of {} only removes energy, \
                 so the run left its constraint manifold or its branch of motion",
                b.max_gain,
                IMPLICIT_ENERGY_GAIN,
                b.scale,
                b.floor,
                b.quadrature_error,
                cfg.method.name()
            ));
        }
    }
    // rank of Φ_q: redundant rows at t0, singular configurations crossed
    // (small systems, `SingularityMonitor`), else the regularised pivots
    let (redundant, crossings) = match &watch.singular {
        Some(s) => {
            extra.insert("redundant_rows".into(), s.redundant_rows().into());
            extra.insert("singular_crossings".into(), s.crossings().into());
            if let Some(c) = s.first() {
                extra.insert("first_singular_t".into(), c.t.into());
            }
            (Some(s.redundant_rows()), s.crossings())
        }
        None => (None, 0),
    };
    if let Some(r) = redundant.filter(|&r| r > 0) {
        warnings.push(format!(
            "{r} of the {} constraint rows are redundant (rank of Φ_q at t0: {}): they are \
             solved in the least-squares sense — the motion is determined, the reactions of \
             the redundant joints are the minimum-norm split",
            sys.n_constraints(),
            sys.n_constraints() - r
        ));
    }
    if work.indefinite_pivots > 0 {
        warnings.push(format!(
            "{} regularised pivots in Newton matrices whose A block was indefinite (a \
             coordinate pivot ≤ 0): at iterates far from the solution — e.g. a contact onset \
             taken in a large step — or a negative stiffness, not Φ_q losing rank; Newton \
             converged more slowly or failed there (failures are counted and cut the step), and \
             every accepted step met the Newton tolerance",
            work.indefinite_pivots
        ));
    }
    let rank_pivots = work.regularized_pivots - work.indefinite_pivots;
    if rank_pivots > 0 {
        let first = work.first_regularized_t.map_or(String::new(), |t| {
            format!(", the first at t = {t}", t = Time(t))
        });
        if let Some(t) = work.first_regularized_t {
            extra.insert("first_regularized_t".into(), t.into());
        }
        let why = match (redundant, crossings) {
            (Some(r), 0) if r > 0 => Some("the redundant rows above".to_string()),
            (Some(_), 0) => None,
            (Some(_), c) => Some(format!(
                "{c} singular configuration(s) crossed (the first reported above)"
            )),
            (None, _) => None,
        };
        match why {
            Some(why) => warnings.push(format!(
                "{rank_pivots} regularised pivots in the factorisations{first}: Φ_q lost rank — {why}"
            )),
            None => warnings.push(format!(
                "{rank_pivots} regularised pivots in the factorisations{first}: Φ_q lost rank (a singular \
                 configuration or redundant constraints); the multipliers there are a \
                 regularised least-squares answer and the motion may have left its branch — \
                 check with stabilization.projection = true, formulation = \"partitioned\" or \
                 genalpha with integrator.project = true (docs/constraint_methods.md)"
            )),
        }
    }
    if let Some(nf) = extra.get("newton_failures").and_then(|v| v.as_u64()) {
        if nf > 0 {
            warnings.push(format!(
                "{nf} Newton failures, each cutting the step (the first ones are listed above)"
            ));
        }
    }
    for mon in watch.monitors.iter() {
        mon.report(&mut extra);
    }
    Summary {
        method: cfg.method.name().to_string(),
        formulation: work.formulation,
        linear_solver: work.linear_solver,
        evaluation: sys.evaluation_name().to_string(),
        alpha: work.baumgarte.0,
        beta: work.baumgarte.1,
        rtol: cfg.ode.rtol,
        atol: match &cfg.ode.atol {
            Tolerance::Scalar(a) => *a,
            Tolerance::Vector(v) => v.iter().cloned().fold(0.0, f64::max),
        },
        bodies: sys.bodies().len(),
        coordinates: sys.n_coords(),
        constraints: sys.n_constraints(),
        steps: report.stats.steps,
        failed_steps: report.stats.failed_steps,
        rhs_evals: report.stats.rhs_evals,
        factorizations: work.factorizations,
        regularized_pivots: work.regularized_pivots,
        indefinite_pivots: work.indefinite_pivots,
        wall_s,
        max_constraint_norm: watch.max_norm,
        final_constraint_norm: watch.final_norm,
        max_velocity_constraint_norm: watch.max_velocity_norm,
        t_end: cfg.t_end,
        t_reached: report.t_reached,
        status: status.to_string(),
        output_rows: watch.rows,
        message,
        warnings,
        extra,
    }
}
