//! Pieces shared by every integrator: input validation, right-hand-side
//! calls with failure/non-finite detection, the post-step hook,
//! Runge–Kutta stage evaluation, linear combinations of stages, and
//! delivery of requested outputs (used by [`super::driver::drive`]).

use std::ops::ControlFlow;

use super::driver::{Failure, StepCut, Stepper};
use super::{IntegratorError, Observer, OdeOptions, OdeSystem, Stats, Tolerance};
pub(crate) use crate::numeric::first_non_finite;

/// `out = y + h·Σ_j coeffs[j]·k_j`, where `k_j = k[j*n..(j+1)*n]`.
/// Zero coefficients are skipped. The sum over stages is formed first and
/// then added to `y`, as MATLAB's `y + f*hB(:,j)` does.
pub(crate) fn lincomb(out: &mut [f64], y: &[f64], h: f64, coeffs: &[f64], k: &[f64]) {
    weighted_sum(out, h, coeffs, k);
    for (o, yi) in out.iter_mut().zip(y) {
        *o += *yi;
    }
}

/// `out = h·Σ_j coeffs[j]·k_j` (stages stored contiguously in `k`).
pub(crate) fn weighted_sum(out: &mut [f64], h: f64, coeffs: &[f64], k: &[f64]) {
    let n = out.len();
    out.fill(0.0);
    for (j, &cj) in coeffs.iter().enumerate() {
        if cj == 0.0 {
            continue;
        }
        let w = h * cj;
        for (o, kj) in out.iter_mut().zip(&k[j * n..(j + 1) * n]) {
            *o += w * *kj;
        }
    }
}

/// What one explicit run starts from, as [`validate_run`] accepted it:
/// the options, the span `[t0, t_end]`, the initial state `y0` and its
/// dimension `n` (= `sys.dim()`).
pub(crate) struct RunSpan<'r> {
    pub opts: &'r OdeOptions,
    pub t0: f64,
    pub t_end: f64,
    pub y0: &'r [f64],
    pub n: usize,
}

/// Evaluates `f(t, y)` into `dydt`, counting the evaluation. Fails if the
/// system reports an error or returns a non-finite value; `step_from` is
/// the start of the step being taken, if any (named in the failure).
pub(crate) fn call_rhs(
    sys: &mut dyn OdeSystem,
    t: f64,
    y: &[f64],
    dydt: &mut [f64],
    stats: &mut Stats,
    step_from: Option<f64>,
) -> Result<(), Failure> {
    stats.rhs_evals += 1;
    sys.rhs(t, y, dydt)
        .map_err(Failure::system("right-hand side", t, step_from))?;
    if let Some((index, value)) = first_non_finite(dydt) {
        return Err(Failure::NonFinite {
            what: "right-hand side",
            t,
            step_from,
            index,
            value,
        });
    }
    Ok(())
}

/// The end `y_new` of a step from `t` to `t_new`: checked finite (else
/// [`Failure::NonFinite`] of the step) and `f(t_new, y_new)` evaluated
/// into `f_new` ([`call_rhs`]).
pub(crate) fn step_end(
    sys: &mut dyn OdeSystem,
    t: f64,
    t_new: f64,
    y_new: &[f64],
    f_new: &mut [f64],
    stats: &mut Stats,
) -> Result<(), Failure> {
    if let Some((index, value)) = first_non_finite(y_new) {
        return Err(Failure::NonFinite {
            what: "step",
            t: t_new,
            step_from: Some(t),
            index,
            value,
        });
    }
    call_rhs(sys, t_new, y_new, f_new, stats, Some(t))
}

/// Evaluates the explicit stages `first..=last` of a Runge–Kutta step:
/// `k_i = f(t + c_i·h, y + h·Σ_{j<i} a[i][j]·k_j)`, using `ytmp` as the stage
/// input buffer. `k` holds all stages contiguously (`k_0` must be filled in).
#[allow(clippy::too_many_arguments)]
pub(crate) fn eval_stages(
    sys: &mut dyn OdeSystem,
    t: f64,
    h: f64,
    y: &[f64],
    c: &[f64],
    a: &[&[f64]],
    stages: std::ops::RangeInclusive<usize>,
    k: &mut [f64],
    ytmp: &mut [f64],
    stats: &mut Stats,
) -> Result<(), Failure> {
    let n = y.len();
    for i in stages {
        let (done, rest) = k.split_at_mut(i * n);
        lincomb(ytmp, y, h, a[i], done);
        call_rhs(sys, t + c[i] * h, ytmp, &mut rest[..n], stats, Some(t))?;
    }
    Ok(())
}

/// The system's [`OdeSystem::post_step`] on an accepted step's end state
/// `(t, y)`; if it moved `y`, `f(t, y)` is evaluated anew into `f`.
/// Returns whether it moved `y`.
pub(crate) fn post_step(
    sys: &mut dyn OdeSystem,
    t: f64,
    y: &mut [f64],
    f: &mut [f64],
    stats: &mut Stats,
) -> Result<bool, Failure> {
    let changed = sys
        .post_step(t, y)
        .map_err(Failure::system("post-step projection", t, None))?;
    if changed {
        if let Some((index, value)) = first_non_finite(y) {
            return Err(Failure::NonFinite {
                what: "post-step projection",
                t,
                step_from: None,
                index,
                value,
            });
        }
        call_rhs(sys, t, y, f, stats, None)?;
    }
    Ok(changed)
}

/// The two ends of an explicit step: the state `(t, y)` at its start and,
/// once it is accepted, its end `(tnew, ynew)` — the current state until
/// the next step begins ([`StepEnds::advance`]), so that the dense output
/// of the accepted step can still use both ends.
pub(crate) struct StepEnds {
    pub t: f64,
    pub tnew: f64,
    pub y: Vec<f64>,
    pub ynew: Vec<f64>,
    pending: bool,
}

impl StepEnds {
    /// The state `(t0, y0)`, no step taken.
    pub(crate) fn new(t0: f64, y0: &[f64]) -> Self {
        Self {
            t: t0,
            tnew: t0,
            y: y0.to_vec(),
            ynew: vec![0.0; y0.len()],
            pending: false,
        }
    }

    /// Start of a step: an accepted end becomes the start (`true` if there
    /// was one).
    pub(crate) fn advance(&mut self) -> bool {
        if !self.pending {
            return false;
        }
        self.pending = false;
        self.t = self.tnew;
        std::mem::swap(&mut self.y, &mut self.ynew);
        true
    }

    /// The step to `tnew` (in `ynew`) is accepted.
    pub(crate) fn accept(&mut self, tnew: f64) {
        self.tnew = tnew;
        self.pending = true;
    }

    /// The current state: the accepted end, or the start before any step.
    pub(crate) fn current(&self) -> (f64, &[f64]) {
        if self.pending {
            (self.tnew, &self.ynew)
        } else {
            (self.t, &self.y)
        }
    }
}

/// Spacing of doubles at `x`, as MATLAB's `eps(x)`: the distance from `|x|`
/// to the next larger double (`eps(1) = 2^-52`, `eps(0) = 2^-1074`).
/// NaN for non-finite `x`.
pub fn eps(x: f64) -> f64 {
    let a = x.abs();
    if !a.is_finite() {
        return f64::NAN;
    }
    let exp = ((a.to_bits() >> 52) & 0x7ff) as i64;
    if exp <= 52 {
        // The spacing is subnormal: 2^(max(exp,1) - 1075).
        f64::from_bits(1u64 << (exp.max(1) - 1))
    } else {
        f64::from_bits(((exp - 52) as u64) << 52)
    }
}

/// MATLAB's step-size state of ode23/ode45/ode113 over one run: the
/// tolerances ([`MatlabTolerances`]), the span's end, the user's first step
/// and the proposed `|h|` of the next step.
pub(crate) struct MatlabSteps {
    /// `rtol`, at least `100 eps`.
    pub(crate) rtol: f64,
    /// `atol / rtol` per component.
    pub(crate) threshold: Vec<f64>,
    /// The largest step.
    pub(crate) hmax: f64,
    /// The user's first step, if given.
    pub(crate) initial_step: Option<f64>,
    /// The end of the span.
    pub(crate) t_end: f64,
    /// The proposed `|h|` of the next step.
    pub(crate) absh: f64,
    /// The tolerances' warnings.
    pub(crate) warnings: Vec<String>,
}

impl MatlabSteps {
    /// The state at the start of `run`.
    pub(crate) fn new(run: &RunSpan<'_>) -> Self {
        let tol = MatlabTolerances::new(run.opts, run.n, run.t0, run.t_end);
        MatlabSteps {
            rtol: tol.rtol,
            threshold: tol.threshold,
            hmax: tol.hmax,
            initial_step: run.opts.initial_step,
            t_end: run.t_end,
            absh: 0.0,
            warnings: tol.warnings,
        }
    }

    /// MATLAB's first step from `f0 = f(t, y)`: the given `initial_step`
    /// clamped to `[16 eps(t), hmax]`; else `min(hmax, |t_end − t|)`, cut
    /// to `1/rh` with `rh = ‖f0‖ / scale` in the norm of [`error_norm`],
    /// and no smaller than `16 eps(t)`.
    pub(crate) fn first(&mut self, t: f64, f0: &[f64], y: &[f64], scale: f64) {
        let hmin = 16.0 * eps(t);
        self.absh = match self.initial_step {
            Some(htry) => self.hmax.min(hmin.max(htry)),
            None => {
                let mut absh = self.hmax.min((self.t_end - t).abs());
                let rh = error_norm(f0, y, y, &self.threshold) / scale;
                if absh * rh > 1.0 {
                    absh = 1.0 / rh;
                }
                absh.max(hmin)
            }
        };
    }

    /// The first attempt of the step from `t` ([`Attempt`]).
    pub(crate) fn attempt(&self, t: f64) -> Attempt {
        let hmin = 16.0 * eps(t);
        let absh = self.hmax.min(hmin.max(self.absh));
        if 1.1 * absh >= (self.t_end - t).abs() {
            let h = self.t_end - t;
            Attempt {
                h,
                absh: h.abs(),
                hmin,
                done: true,
            }
        } else {
            Attempt {
                h: absh,
                absh,
                hmin,
                done: false,
            }
        }
    }
}

/// MATLAB's step attempt from `t` (ode23/ode45/ode113): `|h|` the proposed
/// `absh` clamped to `[hmin, hmax]` with `hmin = 16 eps(t)`, stretched to
/// end at `t_end` when within 10 % of it (`done`); after a failed error
/// test, a smaller `|h|` ([`Attempt::retry`]).
pub(crate) struct Attempt {
    /// The step.
    pub(crate) h: f64,
    /// Its modulus.
    pub(crate) absh: f64,
    /// The smallest step, `16 eps(t)`.
    pub(crate) hmin: f64,
    /// The step ends at `t_end`.
    pub(crate) done: bool,
}

impl Attempt {
    /// After a failed error test (`err > rtol`): the step cannot be cut
    /// below `hmin` ([`Failure::StepTooSmall`] at `t`).
    pub(crate) fn check_cut(&self, t: f64, err: f64, rtol: f64) -> Result<(), Failure> {
        if self.absh <= self.hmin {
            return Err(Failure::StepTooSmall {
                t,
                h: self.absh,
                h_min: self.hmin,
                cause: StepCut::ErrorTest { err: err / rtol },
            });
        }
        Ok(())
    }

    /// Retry with the smaller `absh` (no longer ending at `t_end`).
    pub(crate) fn retry(&mut self, absh: f64) {
        self.absh = absh;
        self.h = absh;
        self.done = false;
    }
}

/// Checks the per-run inputs (time span, initial state, output times, the
/// length of a vector `atol`).
pub(crate) fn validate_run(
    sys: &dyn OdeSystem,
    options: &OdeOptions,
    t0: f64,
    t_end: f64,
    y0: &[f64],
    output_times: &[f64],
) -> Result<usize, IntegratorError> {
    check_span(t0, t_end)?;
    let n = sys.dim();
    if y0.len() != n {
        return Err(IntegratorError::DimensionMismatch {
            what: "y0",
            expected: n,
            got: y0.len(),
        });
    }
    if let Some((index, value)) = first_non_finite(y0) {
        return Err(IntegratorError::NonFiniteInitialState { index, value });
    }
    if let Tolerance::Vector(v) = &options.atol {
        if v.len() != n {
            return Err(IntegratorError::DimensionMismatch {
                what: "atol",
                expected: n,
                got: v.len(),
            });
        }
    }
    check_output_times(t0, t_end, output_times)?;
    Ok(n)
}

/// The time span of a run: finite, forward (`t_end > t0`). Shared by every
/// integrator.
pub(crate) fn check_span(t0: f64, t_end: f64) -> Result<(), IntegratorError> {
    let reason = if !t0.is_finite() {
        "t0 must be finite"
    } else if !t_end.is_finite() {
        "t_end must be finite"
    } else if t_end <= t0 {
        "t_end must be greater than t0 (only forward integration is supported)"
    } else {
        return Ok(());
    };
    Err(IntegratorError::InvalidTimeSpan {
        t0,
        t_end,
        reason: reason.into(),
    })
}

/// Requested output times: finite, inside `[t0, t_end]`, strictly
/// increasing. Shared by every integrator.
pub(crate) fn check_output_times(
    t0: f64,
    t_end: f64,
    output_times: &[f64],
) -> Result<(), IntegratorError> {
    for (i, &tk) in output_times.iter().enumerate() {
        let bad = |reason: String| IntegratorError::InvalidOutputTimes {
            index: i,
            value: tk,
            reason,
        };
        if !tk.is_finite() {
            return Err(bad("not finite".into()));
        }
        if tk < t0 || tk > t_end {
            return Err(bad(format!("outside the time span [{t0}, {t_end}]")));
        }
        if i > 0 && tk <= output_times[i - 1] {
            return Err(bad(format!(
                "output times must be strictly increasing (previous is {})",
                output_times[i - 1]
            )));
        }
    }
    Ok(())
}

/// Walks through the requested output times as the integration advances.
pub(crate) struct OutputCursor<'a> {
    times: &'a [f64],
    next: usize,
}

impl<'a> OutputCursor<'a> {
    /// A cursor at the first of `times` (validated by [`check_output_times`]).
    pub(crate) fn new(times: &'a [f64]) -> Self {
        Self { times, next: 0 }
    }

    /// Delivers `output(t0, y0)` if `t0` is a requested time.
    pub(crate) fn deliver_initial(
        &mut self,
        t0: f64,
        y0: &[f64],
        obs: &mut dyn Observer,
    ) -> ControlFlow<(f64, String)> {
        if self.times.first() == Some(&t0) {
            self.next = 1;
            if let ControlFlow::Break(r) = obs.output(t0, y0) {
                return ControlFlow::Break((t0, r));
            }
        }
        ControlFlow::Continue(())
    }

    /// Delivers every requested time in `(t, t_new]` after `st`'s accepted
    /// step ending at `t_new`: a time within [`Stepper::output_snap`] of
    /// `t_new` — or, when `at_end`, any remaining one — gets the step end's
    /// state (generalized-α's grid steps land on the output times only up
    /// to rounding), earlier ones the continuous extension
    /// ([`Stepper::interpolate`], then [`Stepper::settle`]) through `buf`.
    pub(crate) fn deliver_step_snapped(
        &mut self,
        t_new: f64,
        at_end: bool,
        st: &mut dyn Stepper,
        buf: &mut [f64],
        obs: &mut dyn Observer,
    ) -> ControlFlow<(f64, String)> {
        let snap = st.output_snap();
        while let Some(&tk) = self.times.get(self.next) {
            let exact = (tk - t_new).abs() <= snap || at_end && tk >= t_new;
            if tk > t_new && !exact {
                break;
            }
            self.next += 1;
            let flow = if exact {
                obs.output(tk, st.state().1)
            } else {
                st.interpolate(tk, buf);
                st.settle(tk, buf);
                obs.output(tk, buf)
            };
            if let ControlFlow::Break(r) = flow {
                return ControlFlow::Break((tk, r));
            }
        }
        ControlFlow::Continue(())
    }
}

/// MATLAB's tolerance and step-limit setup shared by the step-controlled
/// explicit methods (`odearguments.m`): `rtol` raised to `100·eps` (with a
/// warning), `threshold = atol / rtol` per component, and
/// `hmax = min(|tf − t0|, MaxStep)` with `MaxStep` defaulting to
/// `0.1·|tf − t0|`.
pub(crate) struct MatlabTolerances {
    pub rtol: f64,
    pub threshold: Vec<f64>,
    pub hmax: f64,
    pub warnings: Vec<String>,
}

impl MatlabTolerances {
    /// The setup for a run of dimension `n` over `[t0, t_end]`.
    pub(crate) fn new(opts: &OdeOptions, n: usize, t0: f64, t_end: f64) -> Self {
        let mut warnings = Vec::new();
        let mut rtol = opts.rtol;
        if rtol < 100.0 * f64::EPSILON {
            rtol = 100.0 * f64::EPSILON;
            warnings.push(format!(
                "rtol = {:e} is smaller than 100*eps; raised to {rtol:e} (as MATLAB does)",
                opts.rtol
            ));
        }
        let threshold: Vec<f64> = match &opts.atol {
            Tolerance::Scalar(a) => vec![a / rtol; n],
            Tolerance::Vector(v) => v.iter().map(|a| a / rtol).collect(),
        };
        let htspan = (t_end - t0).abs();
        Self {
            rtol,
            threshold,
            hmax: htspan.min(opts.max_step.map_or(0.1 * htspan, f64::abs)),
            warnings,
        }
    }
}

/// Weighted infinity norm of MATLAB's error estimates:
/// `max_i |est_i| / max(|y_i|, |ynew_i|, thr_i)`. A component with `0/0`
/// (possible only with `atol = 0`) contributes 0, as MATLAB's `max`
/// ignores the NaN it produces.
pub(crate) fn error_norm(est: &[f64], y: &[f64], ynew: &[f64], thr: &[f64]) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..est.len() {
        let r = est[i].abs() / y[i].abs().max(ynew[i].abs()).max(thr[i]);
        if r > m {
            m = r;
        }
    }
    m
}

/// `max_i |e_i| / w_i` over `i < n` (∞ where `w_i = 0 < |e_i|`, nothing
/// where both are 0): the error norm of the index-3 methods' adaptive
/// modes (generalized-α, radau5), `w_i = atol_i + rtol max(|q_n,i|,
/// |q_{n+1},i|)`.
pub(crate) fn max_weighted(n: usize, e: impl Fn(usize) -> f64, w: impl Fn(usize) -> f64) -> f64 {
    let mut norm: f64 = 0.0;
    for i in 0..n {
        let (w, e) = (w(i), e(i).abs());
        norm = norm.max(if w > 0.0 {
            e / w
        } else if e > 0.0 {
            f64::INFINITY
        } else {
            0.0
        });
    }
    norm
}

/// First step of an adaptive index-3 run (generalized-α, radau5) without
/// `initial_step`: the position change `½ h² q̈` of the start at 1 % of
/// the tolerance `w_i = atol_i + rtol |q_i|`, within `[1e-6, 1e-2]` of the
/// span.
pub(crate) fn initial_step_from_accelerations(
    qdd: &[f64],
    w: impl Fn(usize) -> f64,
    span: f64,
) -> f64 {
    let mut acc: f64 = 0.0;
    for (i, a) in qdd.iter().enumerate() {
        let w = w(i);
        if w > 0.0 {
            acc = acc.max(a.abs() / w);
        }
    }
    let h = if acc > 0.0 {
        (0.02 / acc).sqrt()
    } else {
        0.01 * span
    };
    h.min(0.01 * span).max(1e-6 * span)
}
