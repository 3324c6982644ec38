//! The index-3 augmented Lagrangian with mass-orthogonal projections of
//! velocities and accelerations ("ALI3-P"; Bayo & Ledesma, "Augmented
//! Lagrangian and mass-orthogonal projection methods for constrained
//! multibody dynamics", Nonlinear Dyn. 9 (1996) 113–130; Cuadrado, Cardenal,
//! Morer & Bayo, "Intelligent simulation of multibody dynamics: space-state
//! and descriptor methods in sequential and parallel computing
//! environments", Multibody Syst. Dyn. 4 (2000); the reference formulation
//! of González, Dopico & Cuadrado's multibody benchmark).
//!
//! The equations of motion carry the constraint forces as a penalty plus
//! iterated multipliers, `M q̈ + Φ_qᵀ(αΦ + λ*) = g(q, q̇, t)`,
//! `λ*_{i+1} = λ*_i + αΦ_{i+1}`: no multiplier unknowns, no constraint
//! rows, a positive (semi-)definite penalty term — rank loss of Φ_q
//! (singular configurations) and redundant constraints need nothing
//! special. The integrator is a member of the generalized-α family
//! ([`AlphaParameters`]; the trapezoidal rule is Newmark β = ¼, γ = ½, i.e.
//! [`AlphaParameters::newmark`]`(1)`), written with the positions as
//! unknowns (Arnold & Brüls 2007, as in [`super::GenAlpha`]):
//! `q̇ = q̇(q)`, `q̈ = q̈(q)` with `∂q̇/∂q = γ' = γ/(βh)`,
//! `∂q̈/∂q = β' = (1 − α_m)/((1 − α_f)βh²)`. Newton on the residual
//! scaled by `s = βh²` (= h²/4 for the trapezoidal rule):
//!
//! ```text
//! f(q) = s [M q̈ + Φ_qᵀ(αΦ + λ*) − g]
//! W Δq = −f(q),  W = c_m M + c_c C + s (K + Φ_qᵀαΦ_q)          c_m = sβ', c_c = sγ'
//! λ*_{i+1} = λ*_i + αΦ(q_{i+1})
//! ```
//!
//! (`C = −∂g/∂q̇`, `K = −∂g/∂q + (Φ_qᵀλ)_q`; for the trapezoidal rule `W` is
//! `M + (h/2)C + (h²/4)(Φ_qᵀαΦ_q + K)`, the matrix of the ALI3-P
//! references), until the weighted Newton correction is below the
//! tolerance. Then the velocities and accelerations are projected with the
//! same matrix (mass-orthogonal: minimal `‖Δ‖_{W*}`, `W* = W − sΦ_qᵀαΦ_q`,
//! with the violation penalised by α):
//!
//! ```text
//! W Δq̇ = −s Φ_qᵀα (Φ_q q̇ + Φ_t),     W Δq̈ = −s Φ_qᵀα (Φ_q q̈ − γ)
//! ```
//!
//! and the auxiliary acceleration `a_{n+1}` of generalized-α is recomputed
//! from the projected `q̈_{n+1}`. Fixed step; a Newton failure halves the
//! step and the grid point is reached by sub-steps that double again.
//! The system side is [`AugmentedDae`] (`formulation::Augmented`).
//! An inconsistent initial state is first projected onto the manifold
//! ([`AugmentedDae::consistent_state`], a warning of the run).
//!
//! **Penalty growth.** The multiplier update contracts by about
//! `1/(1 + x)` per iteration along a constraint direction, `x = c_k α σ²/m`
//! with `σ²/m` its eigenvalue of `Φ_q M⁻¹Φ_qᵀ`; near a singular position σ
//! goes to zero and the iteration crawls (two parallelogram loops crossing
//! together: θ ≈ 0.87 … 0.99, so the default Newton tolerance was never
//! reached and the step collapsed). When the contraction θ stays above
//! [`SLOW_CONTRACTION`] after the matrix was renewed at the iterate, α is
//! multiplied for the rest of the attempt by `(1/0.1 − 1)/(1/θ − 1)`
//! (the factor that turns θ into 0.1), at most [`MAX_PENALTY_FACTOR`] in
//! all, and `W` is refactorised; the next step starts from the default α
//! again (a large α everywhere costs conditioning and, measured, branch
//! changes at the singular positions). A stagnating iteration whose
//! corrections are below `NOISE_REL` of the positions has converged to the
//! noise of the solve, as in generalized-α.

/// Newton iterations per attempt that scenarios give the augmented
/// Lagrangian when `integrator.max_newton` is not set (the implicit
/// default, 8, is for generalized-α): the multiplier update after every
/// correction converges linearly, and with 8 the shipped four-bar at
/// h = 1e-3 s had 35 Newton failures (each halving the step) in 2035
/// steps; `mbsolve study constraints` runs it with 30.
pub const ALM_MAX_NEWTON: usize = 30;

/// A Newton contraction `θ` above this with a fresh matrix raises the
/// penalty for the rest of the attempt (module docs, "Penalty growth").
pub const SLOW_CONTRACTION: f64 = 0.5;
/// The contraction the raised penalty aims at: the multiplier iteration
/// contracts by `1/(1 + x)` with `x = c_k α σ²/m`, so α is multiplied by
/// `(1/TARGET − 1)/(1/θ − 1)`.
const TARGET_CONTRACTION: f64 = 0.1;
/// Largest factor over the default penalty within one attempt (the
/// conditioning of `W` grows with it).
pub const MAX_PENALTY_FACTOR: f64 = 1e4;
use std::sync::Arc;

use super::driver::{Failure, StepCut, Stepper};
use super::genalpha::{AlphaParameters, ROUNDING_ULPS};
use super::hermite::cubic;
use super::implicit::{
    run as run_implicit, validate_run, Assessment, Convergence, ConvergenceOptions, ImplicitStats,
    ImplicitStepper, Next, Remainder, Renewal, RenewalOptions,
};
use super::{common, ImplicitOptions, IntegratorError, Method, Observer, OdeOptions, Report};
use super::{Stats, SystemError};

/// What the augmented-Lagrangian integrator needs of a constrained
/// mechanical system `M q̈ + Φ_qᵀλ = g(q, q̇, t)`, `Φ(q, t) = 0` (module
/// docs), with the penalty α of the formulation.
pub trait AugmentedDae {
    /// Number of coordinates.
    fn n(&self) -> usize;
    /// Number of constraint rows.
    fn m(&self) -> usize;
    /// The Newton scale `s = β h²` of the step about to be attempted (the
    /// default penalty follows it; this also undoes
    /// [`AugmentedDae::scale_penalty`]).
    fn set_step_scale(&mut self, s: f64);
    /// Multiply the penalty α by `factor` for the rest of the attempt: the
    /// integrator's answer to a slowly contracting multiplier iteration.
    fn scale_penalty(&mut self, factor: f64);
    /// Move an inconsistent initial state `(q, q̇)` onto the constraint
    /// manifold (unchanged if consistent); `Some(what was done)` if it
    /// moved (a warning of the run).
    fn consistent_state(
        &mut self,
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<Option<String>, SystemError>;
    /// Accelerations and multipliers at `(t, q, q̇)` (the start of a run).
    fn accelerations(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &mut [f64],
        lam: &mut [f64],
    ) -> Result<(), SystemError>;
    /// The multiplier update `λ* += αΦ(q, t)`.
    fn update_multipliers(&mut self, t: f64, q: &[f64], lam: &mut [f64])
        -> Result<(), SystemError>;
    /// The scaled residual `r = s (M q̈ + Φ_qᵀ(αΦ + λ*) − g(q, q̇, t))`.
    #[allow(clippy::too_many_arguments)]
    fn residual(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        lam: &[f64],
        s: f64,
        r: &mut [f64],
    ) -> Result<(), SystemError>;
    /// Assemble and factorise `W = c[0] M + c[1] C + c[2] (K + Φ_qᵀαΦ_q)`.
    fn factorize(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lam: &[f64],
        c: [f64; 3],
    ) -> Result<(), SystemError>;
    /// Solve `W x = b` in place with the last factorisation.
    fn solve(&mut self, x: &mut [f64]) -> Result<(), SystemError>;
    /// Project `q̇` (`W Δ = −s Φ_qᵀα(Φ_q q̇ + Φ_t)`) and then `q̈`
    /// (`W Δ = −s Φ_qᵀα(Φ_q q̈ − γ)`, γ at the projected q̇) with the last
    /// factorisation.
    fn project(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &mut [f64],
        qdd: &mut [f64],
        s: f64,
    ) -> Result<(), SystemError>;
}

/// The augmented-Lagrangian integrator (module docs): fixed step
/// [`OdeOptions::fixed_step`], Newton tolerance and iterations and the
/// smallest step from [`ImplicitOptions`].
#[derive(Debug, Clone)]
pub struct AugmentedLagrangian {
    params: AlphaParameters,
    opts: ImplicitOptions,
    ode: OdeOptions,
    h: f64,
    stats: ImplicitStats,
}

impl AugmentedLagrangian {
    /// The scheme of `method` ([`Method::GenAlpha`], [`Method::Hht`],
    /// [`Method::Newmark`]; Newmark with ρ∞ = 1 is the trapezoidal rule)
    /// with ρ∞ = `opts.rho_inf`. Needs a fixed step; `adaptive`, `project`,
    /// `reuse`, `filter_error`, `check_constraints`, `lu`, `extrapolate`
    /// do not apply ([`IntegratorError::NotApplicable`]).
    pub fn new(
        method: Method,
        opts: ImplicitOptions,
        ode: OdeOptions,
    ) -> Result<Self, IntegratorError> {
        let d = ImplicitOptions::default();
        for (option, differs) in [
            ("adaptive", opts.adaptive != d.adaptive),
            ("project", opts.project != d.project),
            ("reuse", opts.reuse != d.reuse),
            ("filter_error", opts.filter_error != d.filter_error),
            (
                "check_constraints",
                opts.check_constraints != d.check_constraints,
            ),
            ("lu", opts.lu != d.lu),
            ("extrapolate", opts.extrapolate != d.extrapolate),
        ] {
            if differs {
                return Err(IntegratorError::NotApplicable {
                    option,
                    method: method.name(),
                    reason: "not used by the augmented Lagrangian formulation (fixed step, \
                             projections always on, symmetric Newton matrix)"
                        .into(),
                });
            }
        }
        ode.validate(method, false)?;
        opts.validate(method, ode.fixed_step)?;
        let params = AlphaParameters::for_method(method, opts.rho_inf)?;
        Ok(Self {
            params,
            opts,
            h: ode.fixed_step.unwrap_or(0.0),
            ode,
            stats: ImplicitStats::default(),
        })
    }

    /// The scheme's parameters.
    pub fn params(&self) -> AlphaParameters {
        self.params
    }

    /// Counters of the last run.
    pub fn stats(&self) -> ImplicitStats {
        self.stats
    }

    /// Integrate from `(t0, q0, q̇0)` to `t_end`, delivering `y = [q; q̇]`
    /// at `output_times` (cubic Hermite between step ends) through
    /// [`super::drive`]; a failure midway is `Ok` with
    /// [`super::Termination::Failed`].
    #[allow(clippy::too_many_arguments)]
    pub fn integrate(
        &mut self,
        sys: &mut dyn AugmentedDae,
        t0: f64,
        t_end: f64,
        q0: &[f64],
        qd0: &[f64],
        output_times: &[f64],
        obs: &mut dyn Observer,
    ) -> Result<Report, IntegratorError> {
        let (n, m) = (sys.n(), sys.m());
        validate_run(n, t0, t_end, q0, qd0, output_times, &self.ode, false)?;
        let mut run = Run {
            p: self.params,
            opts: &self.opts,
            h_fixed: self.h,
            sys,
            n,
            t0,
            t_end,
            t: t0,
            cur: State::new(q0, qd0, m),
            new: State::new(q0, qd0, m),
            r: vec![0.0; n],
            y: [q0, qd0].concat(),
            h: self.h,
            k_grid: 1,
            t_old: t0,
            h_last: 0.0,
            stats: ImplicitStats::default(),
            warnings: Vec::new(),
            last_newton: None,
            renewal: Renewal::new(RenewalOptions {
                band: 0.0,
                across_attempts: false,
                every_correction: false,
            }),
        };
        let (report, stats) = run_implicit(&mut run, output_times, self.ode.max_steps, t_end, obs);
        self.stats = stats;
        Ok(report)
    }
}

/// Positions, velocities, true and auxiliary accelerations, multipliers λ*.
#[derive(Debug, Clone)]
struct State {
    q: Vec<f64>,
    v: Vec<f64>,
    qdd: Vec<f64>,
    a: Vec<f64>,
    lam: Vec<f64>,
}

impl State {
    fn new(q: &[f64], v: &[f64], m: usize) -> Self {
        Self {
            q: q.to_vec(),
            v: v.to_vec(),
            qdd: vec![0.0; q.len()],
            a: vec![0.0; q.len()],
            lam: vec![0.0; m],
        }
    }
}

struct Run<'g, 's> {
    p: AlphaParameters,
    opts: &'g ImplicitOptions,
    h_fixed: f64,
    sys: &'s mut dyn AugmentedDae,
    n: usize,
    t0: f64,
    t_end: f64,
    t: f64,
    cur: State,
    new: State,
    r: Vec<f64>,
    y: Vec<f64>,
    /// Step to try next; index of the next grid point.
    h: f64,
    k_grid: u64,
    t_old: f64,
    h_last: f64,
    stats: ImplicitStats,
    warnings: Vec<String>,
    last_newton: Option<StepCut>,
    /// The Newton matrix is renewed at every predictor.
    renewal: Renewal,
}

impl Run<'_, '_> {
    fn system_failure(&self, what: &'static str, t: f64, e: SystemError) -> Failure {
        Failure::System {
            what,
            t,
            step_from: Some(self.t),
            source: Arc::new(e),
        }
    }

    /// One attempt from `(self.t, self.cur)` to `t1 = self.t + h` into
    /// `self.new`: predictor (constant q̈, λ*), then Newton with a
    /// multiplier update after every correction; the matrix is renewed at
    /// the iterate when the contraction is slow (θ > ½).
    fn attempt(&mut self, t1: f64, h: f64) -> Result<(), SystemError> {
        let p = self.p;
        let n = self.n;
        let s = p.beta * h * h;
        let c_m = (1.0 - p.alpha_m) / (1.0 - p.alpha_f);
        let c = [c_m, p.gamma * h, s];
        let gp = p.gamma / (p.beta * h);
        let bp = c_m / s;
        let ap = 1.0 / s;
        self.sys.set_step_scale(s);
        {
            let (cur, new) = (&self.cur, &mut self.new);
            let (am, af, g, b) = (p.alpha_m, p.alpha_f, p.gamma, p.beta);
            for i in 0..n {
                let qdd0 = cur.qdd[i];
                new.qdd[i] = qdd0;
                new.a[i] = ((1.0 - af) * qdd0 + af * cur.qdd[i] - am * cur.a[i]) / (1.0 - am);
                new.v[i] = cur.v[i] + h * ((1.0 - g) * cur.a[i] + g * new.a[i]);
                new.q[i] = cur.q[i] + h * cur.v[i] + h * h * ((0.5 - b) * cur.a[i] + b * new.a[i]);
            }
            new.lam.copy_from_slice(&cur.lam);
        }
        let tol_q = self.opts.newton_tol / gp.max(bp).max(1.0);
        // the correction itself against the tolerance: the multiplier
        // update after each correction contracts only linearly
        let mut conv = Convergence::new(
            ConvergenceOptions {
                remainder: Remainder::Correction {
                    slow: SLOW_CONTRACTION,
                },
                max_iterations: self.opts.max_newton,
                renew_when_exhausted: false,
                renew_on_divergence: false,
                reset_rate_on_renewal: false,
            },
            1.0,
        );
        // a fresh matrix at the predictor (`across_attempts` false), again
        // at the iterate when the iteration is slow
        let mut renew_now = self.renewal.at_predictor(h);
        let mut boost = 1.0;
        for it in 0.. {
            if it > 0 {
                let new = &mut self.new;
                self.sys.update_multipliers(t1, &new.q, &mut new.lam)?;
            }
            if renew_now {
                self.stats.factorizations += 1;
                self.renewal.factorising();
                let new = &self.new;
                self.sys.factorize(t1, &new.q, &new.v, &new.lam, c)?;
                self.renewal.factorised(h);
                renew_now = false;
            }
            self.stats.residual_evaluations += 1;
            let new = &self.new;
            self.sys
                .residual(t1, &new.q, &new.v, &new.qdd, &new.lam, s, &mut self.r)?;
            for x in self.r.iter_mut() {
                *x = -*x;
            }
            self.sys.solve(&mut self.r)?;
            self.stats.newton_iterations += 1;
            let dnorm = self.r.iter().zip(&self.new.q).fold(0.0_f64, |a, (d, q)| {
                a.max(d.abs() / (tol_q + ROUNDING_ULPS * f64::EPSILON * q.abs().max(1.0)))
            });
            if !dnorm.is_finite() {
                return Err(SystemError::msg("non-finite Newton correction"));
            }
            let drel = self
                .r
                .iter()
                .zip(&self.new.q)
                .fold(0.0_f64, |a, (d, q)| a.max(d.abs() / q.abs().max(1.0)));
            let new = &mut self.new;
            for (i, &d) in self.r.iter().enumerate() {
                new.q[i] += d;
                new.v[i] += gp * d;
                new.qdd[i] += bp * d;
                new.a[i] += ap * d;
            }
            let mut restart = false;
            match conv.assess(dnorm, || drel, false) {
                Assessment::Done => {
                    // converged (or at the noise floor of the solve): the
                    // last multiplier update at the converged positions
                    let new = &mut self.new;
                    return self.sys.update_multipliers(t1, &new.q, &mut new.lam);
                }
                Assessment::Slow if !conv.renewed() => {
                    // first: the matrix of the predictor may be stale
                    conv.renewed_by_scheme();
                    renew_now = true;
                }
                Assessment::Slow if boost < 0.5 * MAX_PENALTY_FACTOR => {
                    // still slow with a fresh matrix: a nearly lost
                    // constraint direction (module docs, "Penalty growth")
                    let theta = conv.theta();
                    let f = ((1.0 / TARGET_CONTRACTION - 1.0) / (1.0 / theta - 1.0))
                        .max(2.0)
                        .min(MAX_PENALTY_FACTOR / boost);
                    boost *= f;
                    self.sys.scale_penalty(f);
                    self.stats.penalty_increases += 1;
                    self.stats.max_penalty_factor = self.stats.max_penalty_factor.max(boost);
                    renew_now = true;
                    restart = true;
                }
                Assessment::NotYet | Assessment::Slow => {}
                Assessment::Diverged | Assessment::Hopeless | Assessment::RenewAfterUndo => {
                    return Err(SystemError::msg(format!(
                        "Newton diverges (contraction θ = {:.3}, correction {dnorm:.3e} × tol)",
                        conv.theta()
                    )));
                }
            }
            if conv.next(dnorm, false) == Some(Next::Exhausted) {
                return Err(SystemError::msg(format!(
                    "no convergence in {} iterations (last correction {dnorm:.3e} × tol, θ = \
                     {:.3})",
                    it + 1,
                    conv.theta()
                )));
            }
            if restart {
                conv.restart();
            }
        }
        unreachable!()
    }
}

impl ImplicitStepper for Run<'_, '_> {
    fn books(&mut self) -> (ImplicitStats, &mut Vec<String>) {
        (self.stats, &mut self.warnings)
    }
}

impl Stepper for Run<'_, '_> {
    fn start(&mut self) -> Result<(), Failure> {
        let t0 = self.t0;
        self.stats.residual_evaluations += 1;
        let cur = &mut self.cur;
        let moved = self
            .sys
            .consistent_state(t0, &mut cur.q, &mut cur.v)
            .map_err(|e| Failure::System {
                what: "consistent initial state",
                t: t0,
                step_from: None,
                source: Arc::new(e),
            })?;
        if let Some(msg) = moved {
            let n = self.n;
            self.y[..n].copy_from_slice(&cur.q);
            self.y[n..].copy_from_slice(&cur.v);
            self.warnings.push(msg);
        }
        self.sys
            .accelerations(t0, &cur.q, &cur.v, &mut cur.qdd, &mut cur.lam)
            .map_err(|e| Failure::System {
                what: "initial accelerations",
                t: t0,
                step_from: None,
                source: Arc::new(e),
            })?;
        cur.a.copy_from_slice(&cur.qdd);
        Ok(())
    }

    fn step(&mut self) -> Result<bool, Failure> {
        let n = self.n;
        loop {
            let target = (self.t0 + self.k_grid as f64 * self.h_fixed).min(self.t_end);
            let mut h_try = self.h.min(target - self.t);
            if target - (self.t + h_try) <= 1e-9 * self.h_fixed {
                h_try = target - self.t;
            }
            let last = self.t_end - (self.t + h_try) <= 1e-9 * self.h_fixed;
            if last {
                h_try = self.t_end - self.t;
            }
            let t_new = if last { self.t_end } else { self.t + h_try };
            let hmin = {
                let floor = 16.0 * common::eps(self.t);
                self.opts.min_step.map_or(floor, |h| h.max(floor))
            };
            if let Err(e) = self.attempt(t_new, h_try) {
                self.stats.newton_failures += 1;
                let msg = format!("Newton failed at t = {t_new} with h = {h_try:.3e}: {e}");
                if self.warnings.len() < 20 {
                    self.warnings.push(msg);
                }
                let cut = StepCut::Newton {
                    t: t_new,
                    h: h_try,
                    source: Arc::new(e),
                };
                if 0.5 * h_try < hmin {
                    return Err(Failure::StepTooSmall {
                        t: self.t,
                        h: 0.5 * h_try,
                        h_min: hmin,
                        cause: self.last_newton.take().unwrap_or(cut),
                    });
                }
                self.last_newton.get_or_insert(cut);
                self.h = 0.5 * h_try;
                continue;
            }
            // Projections of q̇ and q̈ with the factorised W; a_{n+1} from
            // the projected q̈ (the generalized-α recurrence).
            self.stats.projections += 1;
            let s = self.p.beta * h_try * h_try;
            let new = &mut self.new;
            self.sys
                .project(t_new, &new.q, &mut new.v, &mut new.qdd, s)
                .map_err(|e| self.system_failure("projection", t_new, e))?;
            let (am, af) = (self.p.alpha_m, self.p.alpha_f);
            let new = &mut self.new;
            for i in 0..n {
                new.a[i] = ((1.0 - af) * new.qdd[i] + af * self.cur.qdd[i] - am * self.cur.a[i])
                    / (1.0 - am);
            }
            self.t_old = self.t;
            self.h_last = h_try;
            std::mem::swap(&mut self.cur, &mut self.new);
            self.t = t_new;
            self.stats.accept(h_try);
            self.y[..n].copy_from_slice(&self.cur.q);
            self.y[n..].copy_from_slice(&self.cur.v);
            if (self.t - target).abs() <= 1e-9 * self.h_fixed || self.t >= target {
                self.k_grid += 1;
            }
            self.h = (2.0 * self.h).min(self.h_fixed);
            self.last_newton = None;
            return Ok(self.t >= self.t_end);
        }
    }

    fn state(&self) -> (f64, &[f64]) {
        (self.t, &self.y)
    }

    /// Cubic Hermite between the two ends of the last step: q from
    /// (q, q̇), q̇ from (q̇, q̈).
    fn interpolate(&self, tk: f64, out: &mut [f64]) {
        let h = self.h_last;
        let sigma = (tk - self.t_old) / h;
        let (a, b) = (&self.new, &self.cur);
        let (q, v) = out.split_at_mut(self.n);
        cubic(q, sigma, h, &a.q, &a.v, &b.q, &b.v);
        cubic(v, sigma, h, &a.v, &a.qdd, &b.v, &b.qdd);
    }

    fn output_snap(&self) -> f64 {
        1e-9 * self.h_last
    }

    fn stats(&self) -> Stats {
        self.stats.counts()
    }

    fn warnings(&self) -> &[String] {
        &self.warnings
    }
}
