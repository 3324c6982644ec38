//! One run, end to end: formulation + integrator + observation of the
//! constraint violation, with a [`Summary`] of the work done.

use crate::formulation::{FormulationError, Index1, Index1Options};
use crate::integrate::{
    integrator, IntegratorError, Method, Observer, OdeOptions, Termination, Tolerance,
};
use crate::model::System;
use serde::Serialize;
use std::ops::ControlFlow;
use std::time::Instant;

/// What to integrate and how.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// Integration method.
    pub method: Method,
    /// Integrator options (tolerances, steps).
    pub ode: OdeOptions,
    /// Start time.
    pub t0: f64,
    /// End time.
    pub t_end: f64,
    /// Spacing of output times (t0, t0 + dt, …, t_end).
    pub output_dt: f64,
    /// Formulation, Baumgarte parameters, linear solver.
    pub index1: Index1Options,
}

impl RunConfig {
    /// Output times `t0, t0 + dt, …`, ending exactly at `t_end`.
    pub fn output_times(&self) -> Vec<f64> {
        let n = ((self.t_end - self.t0) / self.output_dt - 1e-9)
            .ceil()
            .max(1.0) as usize;
        let mut t: Vec<f64> = (0..n)
            .map(|k| self.t0 + k as f64 * self.output_dt)
            .collect();
        t.push(self.t_end);
        t
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

/// Work and accuracy figures of one run (written as `*.summary.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Integration method.
    pub method: String,
    /// `saddle` (eq. (5)) or `eliminated` (eq. (9)).
    pub formulation: String,
    /// Linear solver.
    pub linear_solver: String,
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
    /// `completed`, `failed` or `stopped`.
    pub status: String,
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
}

struct Watch<'s, 'm, 'd> {
    sys: &'s System,
    n: usize,
    traj: Trajectory,
    phi: Vec<f64>,
    phi_t: Vec<f64>,
    jac: Vec<f64>,
    phid: Vec<f64>,
    max_norm: f64,
    monitors: &'m mut [&'d mut dyn Monitor],
}

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

impl Observer for Watch<'_, '_, '_> {
    fn output(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        let (q, qd) = y.split_at(self.n);
        self.sys.phi(q, t, &mut self.phi);
        self.sys.phi_t(q, t, &mut self.phi_t);
        self.sys.jacobian_values(q, t, &mut self.jac);
        self.sys.jacobian_mul(&self.jac, qd, &mut self.phid);
        for (a, b) in self.phid.iter_mut().zip(&self.phi_t) {
            *a += b;
        }
        let cn = norm2(&self.phi);
        self.max_norm = self.max_norm.max(cn);
        self.traj.t.push(t);
        self.traj.q.push(q.to_vec());
        self.traj.qd.push(qd.to_vec());
        self.traj.phi.push(self.phi.clone());
        self.traj.constraint_norm.push(cn);
        self.traj.velocity_constraint_norm.push(norm2(&self.phid));
        ControlFlow::Continue(())
    }
    fn step(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        let (q, qd) = y.split_at(self.n);
        self.sys.phi(q, t, &mut self.phi);
        self.max_norm = self.max_norm.max(norm2(&self.phi));
        for m in self.monitors.iter_mut() {
            m.step(t, q, qd);
        }
        ControlFlow::Continue(())
    }
}

/// Integrate the equations of motion of `sys` from `(q0, q̇0)`.
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
    let n = sys.n_coords();
    if q0.len() != n || qd0.len() != n {
        return Err(SimulationError::Initial(format!(
            "expected {n} coordinates and velocities, got {} and {}",
            q0.len(),
            qd0.len()
        )));
    }
    if let Some(k) = q0.iter().chain(qd0).position(|v| !v.is_finite()) {
        return Err(SimulationError::Initial(format!(
            "component {k} of (q0, q̇0) is not finite"
        )));
    }
    let mut f = Index1::new(sys, cfg.index1)?;
    let mut integ = integrator(cfg.method, cfg.ode.clone())?;
    let mut y0 = q0.to_vec();
    y0.extend_from_slice(qd0);
    let m = sys.n_constraints();
    let mut watch = Watch {
        sys,
        n,
        traj: Trajectory::default(),
        phi: vec![0.0; m],
        phi_t: vec![0.0; m],
        jac: vec![0.0; sys.jacobian_pattern().len()],
        phid: vec![0.0; m],
        max_norm: 0.0,
        monitors,
    };
    let times = cfg.output_times();
    let start = Instant::now();
    let report = integ.integrate(&mut f, cfg.t0, cfg.t_end, &y0, &times, &mut watch)?;
    let wall_s = start.elapsed().as_secs_f64();
    let stats = f.stats();
    let (status, message) = match &report.termination {
        Termination::Completed => ("completed", None),
        Termination::Failed { reason, .. } => ("failed", Some(reason.clone())),
        Termination::Stopped { reason, .. } => ("stopped", Some(reason.clone())),
    };
    let mut extra = serde_json::Map::new();
    for mon in watch.monitors.iter() {
        mon.report(&mut extra);
    }
    let traj = watch.traj;
    let summary = Summary {
        method: cfg.method.name().to_string(),
        formulation: format!("{:?}", cfg.index1.formulation).to_lowercase(),
        linear_solver: f.solver_name().to_string(),
        alpha: cfg.index1.baumgarte.alpha,
        beta: cfg.index1.baumgarte.beta,
        rtol: cfg.ode.rtol,
        atol: match &cfg.ode.atol {
            Tolerance::Scalar(a) => *a,
            Tolerance::Vector(v) => v.iter().cloned().fold(0.0, f64::max),
        },
        bodies: sys.bodies().len(),
        coordinates: n,
        constraints: m,
        steps: report.stats.steps,
        failed_steps: report.stats.failed_steps,
        rhs_evals: report.stats.rhs_evals,
        factorizations: stats.solver.factorizations,
        regularized_pivots: stats.solver.regularized_pivots,
        wall_s,
        max_constraint_norm: watch.max_norm,
        final_constraint_norm: traj.constraint_norm.last().copied().unwrap_or(f64::NAN),
        max_velocity_constraint_norm: traj
            .velocity_constraint_norm
            .iter()
            .cloned()
            .fold(0.0, f64::max),
        t_end: cfg.t_end,
        t_reached: report.t_reached,
        status: status.to_string(),
        message,
        warnings: report.warnings.clone(),
        extra,
    };
    Ok((traj, summary))
}
