//! Newton iteration on the positions and reuse of factorisations (module
//! docs of [`super`], "Newton iteration").

use super::*;

/// A factorisation is reused while the step size stays within this
/// relative distance of the one it was computed for.
pub const REUSE_BAND: f64 = 0.25;
/// Contraction factor θ above which the factorisation is renewed at the
/// next step. Measured on the stiff chain (N = 100, h = 1e-5): 0.2 gave
/// 2.7 Newton iterations per step with 186 factorisations, 0.05 gives 2.2
/// with 370, 0.02 2.1 with 503, at equal CPU time.
pub const THETA_REFACTOR: f64 = 0.05;
/// Iterations per step after which the factorisation is renewed at the
/// next step.
pub const SLOW_ITERATIONS: usize = 4;

/// Contraction factor above which the matrix is renewed at the current
/// iterate of the running attempt (at most [`MAX_REFRESH`] times).
pub const THETA_SLOW: f64 = 0.5;
/// Renewals of the matrix at an iterate within one attempt (after a
/// diverging or slow iteration, or `max_newton` corrections) before the
/// attempt fails.
pub const MAX_REFRESH: usize = 2;

/// Floor of the Newton tolerance on a position correction, in ulps of
/// `max(|q_i|, 1)`: below it corrections are rounding noise.
pub const ROUNDING_ULPS: f64 = 20.0;

/// A Newton iteration that stops contracting (θ ≥ 1) with corrections
/// below this many tolerances (`‖Δq‖_w ≤ STAGNATION`) has reached the
/// rounding noise of the linear solve and counts as converged (the noise
/// of the angle corrections of a chain grows like 1/segment length: at
/// N = 10 000, ~1e-14 rad, 50 ulps); above it, it diverges.
pub const STAGNATION: f64 = 100.0;

/// A stagnating iteration (θ ≥ 1) whose corrections are below this
/// fraction of `max(|q_i|, 1)` has also reached the noise of the solve,
/// even above [`STAGNATION`] tolerances: at a singular configuration (Φ_q
/// losing rank) the regularised factorisation amplifies the rounding noise
/// of the corrections to ~1e-11 m, above `STAGNATION` × the tolerance at
/// small steps (the position tolerance shrinks like β h²), and cutting the
/// step only shrank the tolerance further until the step collapsed
/// (measured: h = 1e-4 on the parallelogram chains of tests/augmented_lagrangian.rs).
pub const NOISE_REL: f64 = 1e-10;

/// The Newton predictor of a step (module docs of [`super`], "Newton
/// iteration"): the candidates, tried by [`Run::choose_predictor`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Predictor {
    /// `q̈_{n+1}` from the polynomial of degree k ≤ 2 through the last
    /// k + 1 accelerations (k = 0: `q̈_{n+1} = q̈_n`, exact for constant
    /// accelerations), `λ_{n+1}` likewise.
    Acceleration(usize),
    /// `q_{n+1} = q_n + h q̇_n + ½ h² ã` with `ã` the acceleration seen by
    /// the last two positions (0 on the first step), `λ_{n+1} = λ_n`: exact
    /// in the limit of infinitely stiff components, where the acceleration
    /// predictors are off by `(ωh)²` times their displacement.
    Position,
}

impl Predictor {
    /// Every candidate, in the order of [`Run::cand_q`].
    pub(super) const ALL: [Predictor; 4] = [
        Predictor::Acceleration(0),
        Predictor::Acceleration(1),
        Predictor::Acceleration(2),
        Predictor::Position,
    ];
    fn index(self) -> usize {
        match self {
            Predictor::Acceleration(k) => k,
            Predictor::Position => 3,
        }
    }
}

/// Extrapolation at `t_{n+1} = t_n + h` of the polynomial of degree `k`
/// through `(t_n, f0)`, `(t_n − h1, f1)`, `(t_n − h1 − h2, f2)` (Newton's
/// divided differences).
#[inline]
fn extrapolate(k: usize, h: f64, h1: f64, h2: f64, f0: f64, f1: f64, f2: f64) -> f64 {
    if k == 0 {
        return f0;
    }
    let d1 = (f0 - f1) / h1;
    if k == 1 {
        return f0 + h * d1;
    }
    let d2 = (d1 - (f1 - f2) / h2) / (h1 + h2);
    f0 + h * d1 + h * (h + h1) * d2
}

/// How a step attempt ended.
pub(super) enum Attempt {
    Converged,
    /// Newton did not converge (reason).
    Failed(SystemError),
}

impl Run<'_, '_> {
    /// Write the prediction of `pred` for the step `h` into `self.new`
    /// (positions, velocities, accelerations consistent with the scheme,
    /// multipliers) and every candidate's positions into `self.cand_q`
    /// (for [`Run::choose_predictor`]).
    pub(super) fn predict(&mut self, h: f64, pred: Predictor) {
        let p = self.p;
        let (am, af, g, b) = (p.alpha_m, p.alpha_f, p.gamma, p.beta);
        let (h1, h2) = (self.hist_h[0], self.hist_h[1]);
        // ã of the position predictor from q_{n−1} = q_n − h1 q̇_n + ½ h1² ã
        let ca = if self.hist >= 1 { 2.0 / (h1 * h1) } else { 0.0 };
        let (cur, new) = (&self.cur, &mut self.new);
        let [c0, c1, c2, c3] = &mut self.cand_q;
        let sel = pred.index();
        for i in 0..self.n {
            let base = cur.q[i] + h * cur.v[i] + h * h * (0.5 - b) * cur.a[i];
            let (f0, f1, f2) = (cur.qdd[i], self.prev_qdd[0][i], self.prev_qdd[1][i]);
            let q_acc = |qdd1: f64| {
                base + h * h * b * ((1.0 - af) * qdd1 + af * f0 - am * cur.a[i]) / (1.0 - am)
            };
            c0[i] = q_acc(f0);
            if self.hist >= 1 {
                c1[i] = q_acc(extrapolate(1, h, h1, h2, f0, f1, f2));
            }
            if self.hist >= 2 {
                c2[i] = q_acc(extrapolate(2, h, h1, h2, f0, f1, f2));
            }
            let at = ca * (self.prev_q[i] - cur.q[i] + h1 * cur.v[i]);
            c3[i] = cur.q[i] + h * cur.v[i] + 0.5 * h * h * at;
            let q1 = [c0[i], c1[i], c2[i], c3[i]][sel];
            let a1 = (q1 - base) / (b * h * h);
            new.a[i] = a1;
            new.q[i] = q1;
            new.v[i] = cur.v[i] + h * ((1.0 - g) * cur.a[i] + g * a1);
            new.qdd[i] = ((1.0 - am) * a1 + am * cur.a[i] - af * f0) / (1.0 - af);
        }
        let k = match pred {
            Predictor::Acceleration(k) => k,
            _ => 0,
        };
        for (j, l) in new.lam.iter_mut().enumerate() {
            *l = extrapolate(
                k,
                h,
                h1,
                h2,
                cur.lam[j],
                self.prev_lam[0][j],
                self.prev_lam[1][j],
            );
        }
    }

    /// After a converged attempt: the predictor for the next step is the
    /// candidate whose positions came closest to the converged ones (max
    /// norm relative to `max(|q_i|, 1)`).
    pub(super) fn choose_predictor(&mut self, used: Predictor) {
        let allowed = |c: Predictor| match c {
            Predictor::Acceleration(k) => k <= self.hist && (k == 0 || self.opts.extrapolate),
            Predictor::Position => true,
        };
        let mut best = (f64::INFINITY, used);
        for c in Predictor::ALL {
            if !allowed(c) {
                continue;
            }
            let d = self.cand_q[c.index()]
                .iter()
                .zip(&self.new.q)
                .fold(0.0_f64, |a, (p, q)| a.max((p - q).abs() / q.abs().max(1.0)));
            if d < best.0 {
                best = (d, c);
            }
        }
        self.predictor = best.1;
    }

    /// Factorise the iteration matrix at the current iterate.
    pub(super) fn factor(&mut self, t1: f64, h: f64, c: [f64; 3]) -> Result<(), SystemError> {
        self.stats.factorizations += 1;
        self.h_fact = None;
        self.sys
            .factorize(t1, &self.new.q, &self.new.v, &self.new.lam, c)?;
        self.h_fact = Some(h);
        self.refactor = false;
        self.last_attempt_fresh = true;
        Ok(())
    }

    /// One step attempt from `(self.t, self.cur)` to `t1 = self.t + h`
    /// into `self.new`: predictor, then (modified) Newton.
    pub(super) fn attempt(&mut self, t1: f64, h: f64, pred: Predictor) -> Attempt {
        let p = self.p;
        let (n, tol) = (self.n, self.opts.newton_tol);
        let s = p.beta * h * h;
        let c_m = (1.0 - p.alpha_m) / (1.0 - p.alpha_f);
        let c = [c_m, p.gamma * h, s];
        let gp = p.gamma / (p.beta * h); // ∂q̇/∂q
        let bp = c_m / s; // ∂q̈/∂q
        let ap = 1.0 / s; // ∂a/∂q
        self.predict(h, pred);
        self.last_attempt_fresh = false;
        let stale = match self.h_fact {
            None => true,
            Some(hf) => (h / hf - 1.0).abs() > REUSE_BAND,
        };
        if self.refactor || stale || !self.opts.reuse {
            if let Err(e) = self.factor(t1, h, c) {
                return Attempt::Failed(e);
            }
        }
        // position-equivalent tolerance of the acceleration (and velocity)
        // corrections, floored at a few ulps of the positions
        let tol_q = tol / gp.max(bp).max(1.0);
        let mut prev = f64::NAN;
        let mut theta: f64;
        let mut eta = self.eta.max(1.0);
        // iterations since the last factorisation, refactorisations at an
        // iterate within this attempt
        let (mut round, mut refreshes) = (0usize, 0usize);
        let mut it = 0;
        loop {
            if round > 0 && !self.opts.reuse {
                if let Err(e) = self.factor(t1, h, c) {
                    return Attempt::Failed(e);
                }
            }
            self.stats.residual_evaluations += 1;
            let new = &self.new;
            if let Err(e) =
                self.sys
                    .residual(t1, &new.q, &new.v, &new.qdd, &new.lam, s, &mut self.r)
            {
                return Attempt::Failed(e);
            }
            for x in self.r.iter_mut() {
                *x = -*x;
            }
            if let Err(e) = self.sys.solve(t1, &mut self.r) {
                return Attempt::Failed(e);
            }
            self.stats.newton_iterations += 1;
            it += 1;
            let dnorm = self.r[..n]
                .iter()
                .zip(&self.new.q)
                .fold(0.0_f64, |a, (d, q)| {
                    a.max(d.abs() / (tol_q + ROUNDING_ULPS * f64::EPSILON * q.abs().max(1.0)))
                });
            if !dnorm.is_finite() {
                return Attempt::Failed(SystemError::msg("non-finite Newton correction"));
            }
            let drel = self.r[..n]
                .iter()
                .zip(&self.new.q)
                .fold(0.0_f64, |a, (d, q)| a.max(d.abs() / q.abs().max(1.0)));
            {
                let (new, dx) = (&mut self.new, &self.r);
                for (i, &d) in dx[..n].iter().enumerate() {
                    new.q[i] += d;
                    new.v[i] += gp * d;
                    new.qdd[i] += bp * d;
                    new.a[i] += ap * d;
                }
                for (l, d) in new.lam.iter_mut().zip(&dx[n..]) {
                    *l += d / s;
                }
            }
            // Renew the matrix at the current iterate (at most MAX_REFRESH
            // times per attempt) when the contraction is too slow to
            // converge soon. A diverging iteration (θ ≥ 1) is not rescued:
            // its predictor is outside the region where Newton finds the
            // step's solution (at the violent start of the stiff chain a
            // rescued iteration converged to another root, 0.4 m off).
            let slow = round > 0 && (THETA_SLOW..1.0).contains(&(dnorm / prev));
            if slow && self.opts.reuse && refreshes < MAX_REFRESH {
                refreshes += 1;
                self.stats.newton_refreshes += 1;
                if let Err(e) = self.factor(t1, h, c) {
                    return Attempt::Failed(e);
                }
                round = 0;
                eta = 1.0;
                prev = f64::NAN;
                continue;
            }
            let mut done = if round == 0 {
                theta = f64::NAN;
                dnorm * eta <= 1.0
            } else {
                theta = dnorm / prev;
                if theta >= 1.0 {
                    if dnorm > STAGNATION && drel > NOISE_REL {
                        return Attempt::Failed(SystemError::msg(format!(
                            "Newton diverges (contraction θ = {theta:.3}, correction {:.3e} × tol)",
                            dnorm
                        )));
                    }
                    // no contraction among corrections this small: the
                    // iteration has reached the noise floor of the solve
                    true
                } else {
                    eta = theta / (1.0 - theta);
                    if theta > THETA_REFACTOR {
                        self.refactor = true;
                    }
                    eta * dnorm <= 1.0
                }
            };
            prev = dnorm;
            round += 1;
            if done && self.opts.check_constraints {
                self.sys.constraints(t1, &self.new.q, &mut self.phi);
                let phi = self.phi.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
                let scale = self.new.q.iter().fold(1.0_f64, |a, x| a.max(x.abs()));
                done = phi <= tol_q + ROUNDING_ULPS * f64::EPSILON * scale;
            }
            if done {
                if theta.is_finite() && theta < 1.0 {
                    self.eta = eta;
                }
                if it > SLOW_ITERATIONS {
                    self.refactor = true;
                }
                self.choose_predictor(pred);
                return Attempt::Converged;
            }
            if round >= self.opts.max_newton {
                // Still contracting: renew the matrix at this (much better)
                // iterate once and carry on; otherwise give up.
                if self.opts.reuse && refreshes < MAX_REFRESH && theta < 1.0 {
                    refreshes += 1;
                    self.stats.newton_refreshes += 1;
                    if let Err(e) = self.factor(t1, h, c) {
                        return Attempt::Failed(e);
                    }
                    round = 0;
                    eta = 1.0;
                    continue;
                }
                return Attempt::Failed(SystemError::msg(format!(
                    "no convergence in {it} iterations (last correction {prev:.3e} × tol, θ = {theta:.3})"
                )));
            }
        }
    }
}
