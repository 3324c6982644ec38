//! Classic four-stage, fourth-order Runge–Kutta method with a fixed step.

use super::common::{self, call_rhs, eval_stages, lincomb, post_step, RunSpan, StepEnds};
use super::driver::{Failure, Stepper};
use super::hermite::cubic;
use super::{OdeSystem, Stats};

const RK4_C: [f64; 4] = [0.0, 0.5, 0.5, 1.0];
const RK4_A: [&[f64]; 4] = [&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]];
const RK4_B: [f64; 4] = [1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0];

/// Number of fixed steps of size `h` covering `span`.
fn step_count(span: f64, h: f64) -> usize {
    let r = span / h;
    let nearest = r.round();
    let n = if nearest >= 1.0 && (r - nearest).abs() <= 1e-9 * r {
        nearest
    } else {
        r.ceil()
    };
    (n.max(1.0)).min(usize::MAX as f64) as usize
}

/// Fixed-step classic RK4.
///
/// The step is `fixed_step`; the span is covered by `N = ceil((t_end - t0)/h)`
/// steps ending at `t0 + i·h` (no accumulated round-off), the last one
/// shortened to end exactly on `t_end` (a span within a relative `1e-9`
/// of an integer multiple of `h` uses exactly that many steps).
///
/// Dense output is the cubic Hermite interpolant of `y` and `f = y'` at both
/// ends of the step; `f(t_{i+1}, y_{i+1})` is evaluated after each step and
/// reused as the first stage of the next one, so a run costs
/// `rhs_evals = 4·steps + 1` evaluations.
///
/// One run: the system, the step grid and the work arrays.
pub(crate) struct Rk4Stepper<'a> {
    sys: &'a mut dyn OdeSystem,
    t0: f64,
    t_end: f64,
    h: f64,
    nsteps: usize,
    /// Start and end of the last accepted step (the current state).
    ends: StepEnds,
    ytmp: Vec<f64>,
    /// k_1..k_4 followed by f(t_new, y_new).
    k: Vec<f64>,
    stats: Stats,
}

impl<'a> Rk4Stepper<'a> {
    /// The stepper of one run (`n` = `sys.dim()`; `opts.fixed_step` set).
    pub(crate) fn new(sys: &'a mut dyn OdeSystem, run: &RunSpan<'_>) -> Self {
        let (opts, t0, t_end, y0, n) = (run.opts, run.t0, run.t_end, run.y0, run.n);
        let h = opts
            .fixed_step
            .expect("validated by integrator(): rk4 has a fixed_step");
        Self {
            sys,
            t0,
            t_end,
            h,
            nsteps: step_count(t_end - t0, h),
            ends: StepEnds::new(t0, y0),
            ytmp: vec![0.0; n],
            k: vec![0.0; 5 * n],
            stats: Stats::default(),
        }
    }
}

impl Stepper for Rk4Stepper<'_> {
    fn start(&mut self) -> Result<(), Failure> {
        let n = self.ends.y.len();
        call_rhs(
            self.sys,
            self.ends.t,
            &self.ends.y,
            &mut self.k[..n],
            &mut self.stats,
            None,
        )
    }

    fn step(&mut self) -> Result<bool, Failure> {
        let n = self.ends.y.len();
        if self.ends.advance() {
            self.k.copy_within(4 * n.., 0);
        }
        let (i, t) = (self.stats.steps, self.ends.t);
        let done = i + 1 >= self.nsteps;
        let tnew = if done {
            self.t_end
        } else {
            self.t0 + (i + 1) as f64 * self.h
        };
        let hs = tnew - t;
        let k = &mut self.k;
        eval_stages(
            self.sys,
            t,
            hs,
            &self.ends.y,
            &RK4_C,
            &RK4_A,
            1..=3,
            &mut k[..4 * n],
            &mut self.ytmp,
            &mut self.stats,
        )?;
        lincomb(&mut self.ends.ynew, &self.ends.y, hs, &RK4_B, &k[..4 * n]);
        common::step_end(
            self.sys,
            t,
            tnew,
            &self.ends.ynew,
            &mut k[4 * n..],
            &mut self.stats,
        )?;
        self.stats.steps += 1;
        // A projected end state gets its own f, so the Hermite cubic joins
        // consistent end data.
        let (_, f1) = self.k.split_at_mut(4 * n);
        post_step(self.sys, tnew, &mut self.ends.ynew, f1, &mut self.stats)?;
        self.ends.accept(tnew);
        Ok(done)
    }

    fn state(&self) -> (f64, &[f64]) {
        self.ends.current()
    }

    /// Cubic Hermite of `y` and `f` at both ends of the step.
    fn interpolate(&self, tk: f64, out: &mut [f64]) {
        let n = self.ends.y.len();
        let hs = self.ends.tnew - self.ends.t;
        let (f0, rest) = self.k.split_at(n);
        let f1 = &rest[3 * n..];
        cubic(
            out,
            (tk - self.ends.t) / hs,
            hs,
            &self.ends.y,
            f0,
            &self.ends.ynew,
            f1,
        );
    }

    fn stats(&self) -> Stats {
        self.stats.clone()
    }
}
