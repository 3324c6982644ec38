//! The one convergence test of the implicit schemes' simplified Newton
//! iterations: the contraction rate θ = ‖Δ_k‖/‖Δ_{k−1}‖ and the estimate
//! η‖Δ_k‖ (η = θ/(1 − θ)) of the remaining error (Hairer & Wanner II,
//! §IV.8, eq. (8.10)–(8.11)), divergence at θ ≥ 1, stagnation at the
//! linear solve's noise, and when the Newton matrix is renewed within an
//! attempt. Norms are in units of the tolerance (converged at ≤ 1).

/// Contraction factor θ above which the factorisation is renewed at the
/// next step (the iteration converges, but slowly).
pub const THETA_REFACTOR: f64 = 0.2;

/// Floor of the Newton tolerance on a position correction, in ulps of
/// `max(|q_i|, 1)`: below it corrections are rounding noise.
pub const ROUNDING_ULPS: f64 = 20.0;

/// A Newton iteration that stops contracting (θ ≥ 1) with corrections
/// below this many tolerances (`‖Δq‖_w ≤ STAGNATION`) has reached the
/// rounding noise of the linear solve and counts as converged (the noise
/// of the angle corrections of a chain grows like 1/segment length); above
/// it, it diverges.
pub const STAGNATION: f64 = 100.0;

/// A stagnating iteration (θ ≥ 1) whose corrections are below this
/// fraction of `max(|q_i|, 1)` has also reached the noise of the solve,
/// even above [`STAGNATION`] tolerances: at a singular configuration (Φ_q
/// losing rank) the regularised factorisation amplifies the rounding noise
/// of the corrections above `STAGNATION` × the tolerance at small steps
/// (the position tolerance shrinks like β h²), and cutting the step only
/// shrinks the tolerance further.
pub const NOISE_REL: f64 = 1e-10;

/// Where the rules of [`Convergence`] differ between schemes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConvergenceOptions {
    /// Corrections per round (on one factorisation) before the iteration
    /// counts as exhausted (`max_newton`).
    pub max_iterations: usize,
    /// An exhausted iteration that still contracts renews the matrix at the
    /// iterate once and goes on (generalized-α with reuse, Radau IIA).
    pub renew_when_exhausted: bool,
    /// A diverging iteration (θ ≥ 1 above [`STAGNATION`], not at the
    /// noise) renews the matrix at the iterate once, the diverging
    /// correction undone (Radau IIA), instead of failing at once.
    pub renew_on_divergence: bool,
    /// After a renewal of an exhausted iteration the rate estimate starts
    /// again from η = 1 (generalized-α) instead of keeping the last one
    /// (Radau IIA).
    pub reset_rate_on_renewal: bool,
}

/// What the test says after one correction ([`Convergence::assess`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Assessment {
    /// The remaining error is within the tolerance, or the iteration
    /// stagnates at the solve's noise.
    Done,
    /// Contracting, not yet within the tolerance.
    NotYet,
    /// Diverging: undo the correction and renew the matrix at the iterate
    /// ([`ConvergenceOptions::renew_on_divergence`], once per attempt).
    RenewAfterUndo,
    /// Diverging (θ ≥ 1 above [`STAGNATION`] and above the noise).
    Diverged,
}

/// What to do after a correction that did not converge
/// ([`Convergence::next`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Next {
    /// Another correction on the same matrix.
    Iterate,
    /// Renew the matrix at the iterate, then iterate
    /// ([`ConvergenceOptions::renew_when_exhausted`]).
    Renew,
    /// [`ConvergenceOptions::max_iterations`] corrections without
    /// convergence.
    Exhausted,
}

/// The state of the test within one step attempt.
#[derive(Debug, Clone)]
pub struct Convergence {
    opts: ConvergenceOptions,
    /// η = θ/(1 − θ) of the last contracting correction (η ≥ 1 before the
    /// first rate of the attempt).
    eta: f64,
    /// The last correction's norm (NaN before the first of a round).
    prev: f64,
    /// θ of the last correction (NaN in the first of a round).
    theta: f64,
    /// Corrections since the last renewal.
    round: usize,
    /// The matrix was renewed within the attempt.
    renewed: bool,
}

impl Convergence {
    /// A new attempt, starting from the rate `eta` kept from the last
    /// converged attempt (at least 1).
    pub fn new(opts: ConvergenceOptions, eta: f64) -> Self {
        Self {
            opts,
            eta: eta.max(1.0),
            prev: f64::NAN,
            theta: f64::NAN,
            round: 0,
            renewed: false,
        }
    }

    /// Corrections since the last renewal of the matrix.
    pub fn round(&self) -> usize {
        self.round
    }

    /// The contraction factor θ of the last correction (NaN in the first
    /// correction of a round).
    pub fn theta(&self) -> f64 {
        self.theta
    }

    /// The last correction's norm in tolerances.
    pub fn last(&self) -> f64 {
        self.prev
    }

    /// The last correction contracted with θ > [`THETA_REFACTOR`]: the
    /// matrix is to be renewed at the next step.
    pub fn slow(&self) -> bool {
        self.theta > THETA_REFACTOR && self.theta < 1.0
    }

    /// η to keep for the next attempt after convergence: that of a
    /// contracting last correction, else none.
    pub fn rate_to_keep(&self) -> Option<f64> {
        (self.theta < 1.0).then_some(self.eta)
    }

    /// Test a correction of norm `dnorm` (in tolerances; finite); `drel`
    /// gives its size relative to `max(|q|, 1)` where stagnation asks for
    /// it; `single`: the scheme accepts this first correction by its own
    /// model (generalized-α's quadratic model on a fresh matrix).
    pub fn assess(&mut self, dnorm: f64, drel: impl FnOnce() -> f64, single: bool) -> Assessment {
        if self.round == 0 {
            self.theta = f64::NAN;
            return if single || dnorm * self.eta <= 1.0 {
                Assessment::Done
            } else {
                Assessment::NotYet
            };
        }
        let theta = dnorm / self.prev;
        self.theta = theta;
        if theta >= 1.0 {
            if dnorm <= STAGNATION || drel() <= NOISE_REL {
                // no contraction among corrections this small: the
                // iteration has reached the noise floor of the solve
                return Assessment::Done;
            }
            if self.opts.renew_on_divergence && !self.renewed {
                self.renewed = true;
                self.round = 0;
                self.prev = f64::NAN;
                return Assessment::RenewAfterUndo;
            }
            return Assessment::Diverged;
        }
        self.eta = theta / (1.0 - theta);
        if self.eta * dnorm <= 1.0 {
            Assessment::Done
        } else {
            Assessment::NotYet
        }
    }

    /// After an assessed correction of norm `dnorm`: whether it converged
    /// (`done`, possibly vetoed by the scheme), else what comes next.
    /// `None` when converged.
    pub fn next(&mut self, dnorm: f64, done: bool) -> Option<Next> {
        self.prev = dnorm;
        self.round += 1;
        if done {
            return None;
        }
        if self.round < self.opts.max_iterations {
            return Some(Next::Iterate);
        }
        if self.opts.renew_when_exhausted && !self.renewed && self.theta < 1.0 {
            self.renewed = true;
            self.round = 0;
            self.prev = f64::NAN;
            self.theta = f64::NAN;
            if self.opts.reset_rate_on_renewal {
                self.eta = 1.0;
            }
            return Some(Next::Renew);
        }
        Some(Next::Exhausted)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(renew_on_divergence: bool) -> ConvergenceOptions {
        ConvergenceOptions {
            max_iterations: 4,
            renew_when_exhausted: true,
            renew_on_divergence,
            reset_rate_on_renewal: true,
        }
    }

    #[test]
    fn linear_contraction_stops_when_the_estimated_remainder_is_within_tolerance() {
        // corrections 8, 4, 2, 1: θ = ½, η = 1; converged at η‖Δ‖ ≤ 1
        let mut c = Convergence::new(opts(false), 1.0);
        let mut verdicts = Vec::new();
        for d in [8.0, 4.0, 2.0, 1.0] {
            let a = c.assess(d, || 1.0, false);
            verdicts.push(a);
            if c.next(d, a == Assessment::Done).is_none() {
                break;
            }
        }
        use Assessment::*;
        assert_eq!(verdicts, [NotYet, NotYet, NotYet, Done]);
        assert_eq!(c.rate_to_keep(), Some(1.0));
        assert!(c.slow(), "θ = 0.5 > THETA_REFACTOR");
    }

    #[test]
    fn divergence_fails_or_renews_once_and_noise_counts_as_converged() {
        let mut c = Convergence::new(opts(false), 1.0);
        assert_eq!(c.assess(1e3, || 1.0, false), Assessment::NotYet);
        c.next(1e3, false);
        assert_eq!(c.assess(2e3, || 1.0, false), Assessment::Diverged);
        // the same growth at the noise of the solve, or below STAGNATION
        let mut c = Convergence::new(opts(false), 1.0);
        c.assess(1e3, || 1.0, false);
        c.next(1e3, false);
        assert_eq!(c.assess(2e3, || 1e-12, false), Assessment::Done);
        let mut c = Convergence::new(opts(false), 1.0);
        c.assess(10.0, || 1.0, false);
        c.next(10.0, false);
        assert_eq!(c.assess(50.0, || 1.0, false), Assessment::Done);
        // renewed once on divergence, then it fails
        let mut c = Convergence::new(opts(true), 1.0);
        c.assess(1e3, || 1.0, false);
        c.next(1e3, false);
        assert_eq!(c.assess(2e3, || 1.0, false), Assessment::RenewAfterUndo);
        assert_eq!(c.round(), 0);
        c.assess(1e3, || 1.0, false);
        c.next(1e3, false);
        assert_eq!(c.assess(2e3, || 1.0, false), Assessment::Diverged);
    }

    #[test]
    fn an_exhausted_contracting_iteration_is_renewed_once() {
        // θ = 0.9: still contracting after 4 corrections
        let mut c = Convergence::new(opts(false), 1.0);
        let mut d = 1e3;
        let mut nexts = Vec::new();
        for _ in 0..8 {
            let a = c.assess(d, || 1.0, false);
            let n = c.next(d, a == Assessment::Done);
            nexts.push(n);
            if n == Some(Next::Exhausted) {
                break;
            }
            d *= 0.9;
        }
        use Next::*;
        let expect = [
            Iterate, Iterate, Iterate, Renew, Iterate, Iterate, Iterate, Exhausted,
        ];
        assert_eq!(nexts, expect.map(Some));
    }
}
