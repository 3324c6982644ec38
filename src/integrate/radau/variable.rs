//! Radau IIA of variable order, 5 and 9 (S = 3 and 5 stages), with
//! adaptive steps on the index-3 equations of a [`SecondOrderDae`]
//! (docs/radau.md, "radau59").
//!
//! Each order is the stage loop of [`super::Radau5`] with its tableau, its
//! embedded error estimate (RADAU's `DD`, [`RadauStages::e`]), its
//! tolerance transformation `rtol' = 0.1 rtol^{(S+1)/(2S)}` and its
//! controller exponent `1/(S + 1)`, on the same index-3 Newton matrices
//! (one real, and one complex per complex pair of 𝔄).
//!
//! **Order selection** (RADAU's rule: Hairer & Wanner, "Stiff differential
//! equations solved by Radau methods", J. Comput. Appl. Math. 111 (1999);
//! the code RADAU's `VITU`, `VITD`, `HHOU`, `HHOD`, at their defaults).
//! After each accepted step the contraction θ of its simplified Newton
//! iteration ([`THETA_ONE`] for a step of one correction, RADAU's `THET`)
//! is smoothed, `θ̄ = min(10, max(θ, θ̄/2))`. The order goes up to 9 when
//! the step took more than one correction, `θ̄ ≤` [`THETA_UP`], the next
//! step is within ([`STEP_RATIO_DOWN`], [`STEP_RATIO_UP`]) times this one
//! and at least [`STEPS_BEFORE_UP`] steps were taken since the start or
//! the last change; it goes down to 5 when `θ̄ ≥` [`THETA_DOWN`] or the
//! step had a Newton failure. A fast contraction says the iteration would
//! stay cheap with five stages; a steady step says the solution is smooth
//! at this scale. The run starts at order 5. A change takes effect at the
//! next step, with the step the controller chose: the last step's stage
//! polynomials are evaluated at the new nodes for the predictor, the
//! matrices are factorised for the new eigenvalues, and the predictive
//! controller starts over.

use super::*;

/// θ of a step that converged in one correction (RADAU's `THET`).
pub(super) const THETA_ONE: f64 = 0.001;
/// Largest smoothed contraction θ̄ for order 9 (RADAU's `VITU`).
pub(super) const THETA_UP: f64 = 0.002;
/// Smoothed contraction θ̄ from which order 9 goes back to 5 (RADAU's
/// `VITD`).
pub(super) const THETA_DOWN: f64 = 0.8;
/// The next step over this one must stay below this ratio for order 9
/// (RADAU's `HHOU`).
pub(super) const STEP_RATIO_UP: f64 = 1.2;
/// … and above this one (RADAU's `HHOD`).
pub(super) const STEP_RATIO_DOWN: f64 = 0.8;
/// Steps at an order before it may go up (RADAU: 10).
pub(super) const STEPS_BEFORE_UP: usize = 10;

/// What the order rule reads of a run after an accepted step.
pub(super) struct Signals {
    /// Newton corrections of the step's converged attempt.
    pub(super) corrections: usize,
    /// Their last contraction θ (None: one correction).
    pub(super) theta: Option<f64>,
    /// The step \[s\].
    pub(super) h: f64,
    /// The step the controller chose next \[s\].
    pub(super) h_next: f64,
    /// Newton failures of the run so far.
    pub(super) newton_failures: usize,
}

/// Steps and changes of order of a [`Radau59`] run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OrderCounts {
    /// Accepted steps at order 5 (three stages).
    pub steps_order5: usize,
    /// Accepted steps at order 9 (five stages).
    pub steps_order9: usize,
    /// Changes of order.
    pub changes: usize,
}

/// RADAU's order rule over a run (module docs).
#[derive(Debug, Clone, Copy, Default)]
struct OrderRule {
    theta_bar: f64,
    since_change: usize,
    newton_failures: usize,
}

impl OrderRule {
    /// After an accepted step at order 9 (`nine`) or 5: whether the next
    /// step takes order 9.
    fn next(&mut self, nine: bool, s: &Signals) -> bool {
        let theta = s.theta.unwrap_or(THETA_ONE);
        self.theta_bar = theta.max(0.5 * self.theta_bar).min(10.0);
        self.since_change += 1;
        let failed = s.newton_failures > self.newton_failures;
        self.newton_failures = s.newton_failures;
        let ratio = s.h_next / s.h;
        let next = if nine {
            self.theta_bar < THETA_DOWN && !failed
        } else {
            s.corrections > 1
                && self.theta_bar <= THETA_UP
                && ratio > STEP_RATIO_DOWN
                && ratio < STEP_RATIO_UP
                && self.since_change >= STEPS_BEFORE_UP
        };
        if next != nine {
            self.since_change = 0;
        }
        next
    }
}

/// The stage loop of the current order.
enum Stages<'g, 's> {
    Five(Box<Run<'g, 's, 3, ClosedForm>>),
    Nine(Box<Run<'g, 's, 5, RadauStages<5>>>),
}

/// `$body` with `$r` the current order's run.
macro_rules! on_run {
    ($stages:expr, $r:ident => $body:expr) => {
        match $stages {
            Stages::Five($r) => $body,
            Stages::Nine($r) => $body,
        }
    };
}

/// A radau59 run: the current order's stage loop and the order rule.
struct VariableRun<'g, 's> {
    /// None only while the order changes within [`Stepper::step`].
    run: Option<Stages<'g, 's>>,
    five: &'g ClosedForm,
    nine: &'g RadauStages<5>,
    rule: OrderRule,
    /// The order of the next step (true: 9).
    next_nine: bool,
    counts: OrderCounts,
}

impl<'g, 's> VariableRun<'g, 's> {
    fn stages(&self) -> &Stages<'g, 's> {
        self.run.as_ref().expect("a radau59 run between steps")
    }

    fn stages_mut(&mut self) -> &mut Stages<'g, 's> {
        self.run.as_mut().expect("a radau59 run between steps")
    }
}

impl Stepper for VariableRun<'_, '_> {
    fn start(&mut self) -> Result<(), Failure> {
        on_run!(self.stages_mut(), r => r.start())
    }

    fn step(&mut self) -> Result<bool, Failure> {
        let run = self.run.take().expect("a radau59 run between steps");
        self.run = Some(match (run, self.next_nine) {
            (Stages::Five(r), true) => {
                self.counts.changes += 1;
                Stages::Nine(Box::new(r.into_stages(self.nine)))
            }
            (Stages::Nine(r), false) => {
                self.counts.changes += 1;
                Stages::Five(Box::new(r.into_stages(self.five)))
            }
            (run, _) => run,
        });
        let (done, nine, signals) = match self.stages_mut() {
            Stages::Five(r) => (r.step()?, false, r.signals()),
            Stages::Nine(r) => (r.step()?, true, r.signals()),
        };
        if nine {
            self.counts.steps_order9 += 1;
        } else {
            self.counts.steps_order5 += 1;
        }
        self.next_nine = self.rule.next(nine, &signals);
        Ok(done)
    }

    fn state(&self) -> (f64, &[f64]) {
        on_run!(self.stages(), r => r.state())
    }

    fn interpolate(&self, t: f64, out: &mut [f64]) {
        on_run!(self.stages(), r => r.interpolate(t, out))
    }

    fn output_snap(&self) -> f64 {
        on_run!(self.stages(), r => r.output_snap())
    }

    fn settle(&mut self, t: f64, out: &mut [f64]) {
        on_run!(self.stages_mut(), r => r.settle(t, out))
    }

    fn warnings(&self) -> &[String] {
        on_run!(self.stages(), r => r.warnings())
    }

    fn stats(&self) -> crate::integrate::Stats {
        on_run!(self.stages(), r => Stepper::stats(&**r))
    }
}

impl ImplicitStepper for VariableRun<'_, '_> {
    fn books(&mut self) -> (&mut ImplicitStats, &mut Vec<String>) {
        on_run!(self.stages_mut(), r => r.books())
    }
    fn newton_attempt(&mut self, t_new: f64, h: f64) -> Result<(), SystemError> {
        on_run!(self.stages_mut(), r => r.newton_attempt(t_new, h))
    }
    fn renewal(&mut self) -> &mut Renewal {
        on_run!(self.stages_mut(), r => r.renewal())
    }
    fn cuts(&mut self) -> &mut Cuts {
        on_run!(self.stages_mut(), r => r.cuts())
    }
}

/// Radau IIA of variable order (5 and 9), adaptive, on the index-3
/// equations (module docs).
#[derive(Debug, Clone)]
pub struct Radau59 {
    opts: ImplicitOptions,
    ode: OdeOptions,
    five: ClosedForm,
    nine: RadauStages<5>,
    stats: ImplicitStats,
    counts: OrderCounts,
}

impl Radau59 {
    /// Validate the options: the tolerances `rtol`, `atol` (and
    /// `max_step`, `initial_step`) of [`OdeOptions`]; of
    /// [`ImplicitOptions`] it reads `newton_tol`, `max_newton`, `reuse`,
    /// `project` and `min_step` (the steps are always adaptive).
    pub fn new(opts: ImplicitOptions, ode: OdeOptions) -> Result<Self, IntegratorError> {
        ode.validate(Method::Radau59, true)?;
        opts.validate(Method::Radau59, ode.fixed_step)?;
        Ok(Self {
            opts: ImplicitOptions {
                adaptive: true,
                ..opts
            },
            ode,
            five: ClosedForm::new(),
            nine: RadauStages::new(),
            stats: ImplicitStats::default(),
            counts: OrderCounts::default(),
        })
    }

    /// Counters of the last run (`complex_factorizations` counts every
    /// complex pair's).
    pub fn stats(&self) -> ImplicitStats {
        self.stats
    }

    /// Steps at each order and changes of order of the last run.
    pub fn order_counts(&self) -> OrderCounts {
        self.counts
    }

    /// Integrate from `(t0, q0, q̇0)` to `t_end`; `cplx` are two complex
    /// Newton matrices of the same system (order 5 uses the first).
    /// Outputs as [`Radau5::integrate`].
    pub fn integrate(
        &mut self,
        sys: &mut dyn SecondOrderDae,
        [c1, c2]: [&mut dyn ComplexNewton; 2],
        span: Span<'_>,
    ) -> Result<Report, IntegratorError> {
        let (opts, ode) = (&self.opts, &self.ode);
        let run = Run::new(&self.five, opts, ode, sys, vec![c1, c2], &span)?;
        let mut v = VariableRun {
            run: Some(Stages::Five(Box::new(run))),
            five: &self.five,
            nine: &self.nine,
            rule: OrderRule::default(),
            next_nine: false,
            counts: OrderCounts::default(),
        };
        let (report, stats) = run_implicit(&mut v, span, ode.max_steps);
        self.counts = v.counts;
        self.stats = stats;
        Ok(report)
    }
}
