//! The one convergence test of the implicit schemes' simplified Newton
//! iterations: the contraction rate θ = ‖Δ_k‖/‖Δ_{k−1}‖ and the estimate
//! η‖Δ_k‖ (η = θ/(1 − θ)) of the remaining error (Hairer & Wanner II,
//! §IV.8, eq. (8.10)–(8.11)), divergence, stagnation at the linear solve's
//! noise, and when the Newton matrix is renewed within an attempt. Where
//! the schemes' rules differ they are options ([`Remainder`],
//! [`ConvergenceOptions`]): generalized-α and Radau IIA estimate the
//! remainder with η kept from the last converged attempt; BDF/NDF with
//! ode15s's rate on the current matrix (Shampine & Reichelt 1997); the
//! augmented Lagrangian, whose multiplier update after each correction
//! contracts only linearly, takes the correction itself.

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

/// How the remaining error after a correction is estimated and what
/// counts as divergence: the per-scheme part of [`Convergence`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Remainder {
    /// `η‖Δ‖ ≤ 1` (norms in tolerances) with `η = θ/(1 − θ)`, η of the
    /// first correction kept from the last converged attempt (at least 1);
    /// divergence at θ ≥ 1 above the noise (Hairer & Wanner II, §IV.8;
    /// generalized-α, Radau IIA).
    Rate,
    /// ode15s's test (Shampine & Reichelt 1997) on raw norms: the rate
    /// `ρ = max(θ, 0.9 ρ_prev)` measured on the current matrix (none after
    /// a factorisation); the first correction converges only with a rate
    /// measured before, `ρ' = max(ρ, first_rate)`, at
    /// `‖Δ‖ρ'/(1 − ρ') ≤ tol_first`; later ones at `‖Δ‖ρ/(1 − ρ) ≤ tol`;
    /// θ above `diverge_above`, or a rate that cannot reach `tol` within
    /// [`ConvergenceOptions::max_iterations`], fails (no stagnation rule).
    /// BDF/NDF.
    Ode15s {
        /// Bound of the estimated remainder (ode15s: κ·rtol).
        tol: f64,
        /// Bound for the first correction (ode15s: κ₁·rtol).
        tol_first: f64,
        /// Smallest rate assumed for the first correction.
        first_rate: f64,
        /// Contraction above which the iteration fails (ode15s: 0.9).
        diverge_above: f64,
    },
    /// The correction itself, `‖Δ‖ ≤ 1` (norms in tolerances), for an
    /// iteration that contracts linearly (the augmented Lagrangian's
    /// multiplier update); a contraction above `slow` asks the scheme to
    /// act ([`Assessment::Slow`]: renew the matrix, raise the penalty);
    /// divergence counts only from the third correction on and after the
    /// scheme renewed something (`Convergence::renewed_by_scheme`).
    Correction {
        /// Contraction above which the scheme is asked to act.
        slow: f64,
    },
}

/// Where the rules of [`Convergence`] differ between schemes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConvergenceOptions {
    /// The remainder estimate and divergence rule.
    pub remainder: Remainder,
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

/// What the test says after one correction (`Convergence::assess`).
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
    /// Diverging (θ ≥ 1 above [`STAGNATION`] and above the noise; with
    /// [`Remainder::Ode15s`] θ above its bound).
    Diverged,
    /// [`Remainder::Ode15s`]: the rate cannot reach the tolerance within
    /// [`ConvergenceOptions::max_iterations`] corrections.
    Hopeless,
    /// [`Remainder::Correction`]: contracting slower than its `slow`.
    Slow,
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
    /// [`Remainder::Ode15s`]: the rate measured on the current matrix.
    rate: Option<f64>,
    /// The last assessment asks for a renewal at the next step.
    slow: bool,
}

impl Convergence {
    /// A new attempt, starting from the rate `eta` kept from the last
    /// converged attempt (at least 1; [`Remainder::Rate`]).
    pub fn new(opts: ConvergenceOptions, eta: f64) -> Self {
        Self {
            opts,
            eta: eta.max(1.0),
            prev: f64::NAN,
            theta: f64::NAN,
            round: 0,
            renewed: false,
            rate: None,
            slow: false,
        }
    }

    /// A new attempt whose first correction is judged with the rate
    /// estimate `eta` as given ([`Remainder::Rate`]), where [`Convergence::new`]
    /// raises it to at least 1: Radau IIA's `η₀ = max(η_prev, ε)^0.8`
    /// (RADAU5, Hairer & Wanner II, §IV.8), which lets a good predictor on a
    /// contracting matrix converge in one correction and creeps back
    /// towards 1 over attempts that measure no rate.
    pub fn with_first_rate(opts: ConvergenceOptions, eta: f64) -> Self {
        Self {
            eta,
            ..Self::new(opts, 1.0)
        }
    }

    /// A new attempt of [`Remainder::Ode15s`] on a matrix whose rate was
    /// measured before (`None` for a fresh matrix).
    pub(crate) fn with_rate(opts: ConvergenceOptions, rate: Option<f64>) -> Self {
        Self {
            rate,
            ..Self::new(opts, 1.0)
        }
    }

    /// [`Remainder::Ode15s`]: the rate measured on the current matrix, to
    /// keep while the matrix is kept.
    pub fn rate(&self) -> Option<f64> {
        self.rate
    }

    /// The scheme renewed the matrix (or the problem) within the attempt
    /// ([`Remainder::Correction`]).
    pub(crate) fn renewed_by_scheme(&mut self) {
        self.renewed = true;
    }

    /// Whether the matrix was renewed within the attempt.
    pub(crate) fn renewed(&self) -> bool {
        self.renewed
    }

    /// The next correction starts a new rate measurement (no θ), after the
    /// scheme changed the problem (the augmented Lagrangian's penalty).
    pub(crate) fn restart(&mut self) {
        self.prev = f64::NAN;
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

    /// The last assessed correction contracted with θ (ode15s: the
    /// converged rate) above [`THETA_REFACTOR`]: the matrix is to be
    /// renewed at the next step.
    pub fn slow(&self) -> bool {
        self.slow
    }

    /// η to keep for the next attempt after convergence: that of a
    /// contracting last correction, else none.
    pub(crate) fn rate_to_keep(&self) -> Option<f64> {
        (self.theta < 1.0).then_some(self.eta)
    }

    /// Test a correction of norm `dnorm` (in tolerances, or raw with
    /// [`Remainder::Ode15s`]; finite); `drel` gives its size relative to
    /// `max(|q|, 1)` where stagnation asks for it; `accept`: the scheme
    /// accepts this correction by its own rule (generalized-α's quadratic
    /// model on a fresh matrix, BDF's rounding floor).
    pub(crate) fn assess(
        &mut self,
        dnorm: f64,
        drel: impl FnOnce() -> f64,
        accept: bool,
    ) -> Assessment {
        self.slow = false;
        if accept {
            self.theta = f64::NAN;
            return Assessment::Done;
        }
        match self.opts.remainder {
            Remainder::Rate => self.assess_rate(dnorm, drel),
            Remainder::Ode15s {
                tol,
                tol_first,
                first_rate,
                diverge_above,
            } => self.assess_ode15s(dnorm, tol, tol_first, first_rate, diverge_above),
            Remainder::Correction { slow } => self.assess_correction(dnorm, drel, slow),
        }
    }

    /// Whether the iteration stagnates at the solve's noise (θ ≥ 1 with
    /// corrections this small).
    fn at_noise(dnorm: f64, drel: impl FnOnce() -> f64) -> bool {
        dnorm <= STAGNATION || drel() <= NOISE_REL
    }

    fn assess_rate(&mut self, dnorm: f64, drel: impl FnOnce() -> f64) -> Assessment {
        if self.round == 0 {
            self.theta = f64::NAN;
            return if dnorm * self.eta <= 1.0 {
                Assessment::Done
            } else {
                Assessment::NotYet
            };
        }
        let theta = dnorm / self.prev;
        self.theta = theta;
        if theta >= 1.0 {
            if Self::at_noise(dnorm, drel) {
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
        self.slow = theta > THETA_REFACTOR;
        self.eta = theta / (1.0 - theta);
        if self.eta * dnorm <= 1.0 {
            Assessment::Done
        } else {
            Assessment::NotYet
        }
    }

    fn assess_ode15s(
        &mut self,
        dnorm: f64,
        tol: f64,
        tol_first: f64,
        first_rate: f64,
        diverge_above: f64,
    ) -> Assessment {
        if self.round == 0 {
            self.theta = f64::NAN;
            // one correction suffices only with a contraction rate
            // measured on this matrix
            if let Some(rate) = self.rate {
                let rate = rate.max(first_rate);
                if dnorm * rate / (1.0 - rate) <= tol_first {
                    return Assessment::Done;
                }
            }
            return Assessment::NotYet;
        }
        let theta = dnorm / self.prev;
        self.theta = theta;
        if theta > diverge_above {
            return Assessment::Diverged;
        }
        let rate = self.rate.map_or(theta, |r| theta.max(0.9 * r));
        self.rate = Some(rate);
        let errit = dnorm * rate / (1.0 - rate);
        if errit <= tol {
            self.slow = rate > THETA_REFACTOR;
            return Assessment::Done;
        }
        let it = self.round + 1;
        let max = self.opts.max_iterations;
        if it >= max || errit * rate.powi((max - it) as i32) > tol {
            return Assessment::Hopeless;
        }
        Assessment::NotYet
    }

    fn assess_correction(
        &mut self,
        dnorm: f64,
        drel: impl FnOnce() -> f64,
        slow: f64,
    ) -> Assessment {
        let theta = dnorm / self.prev;
        self.theta = theta;
        if dnorm <= 1.0 || (theta >= 1.0 && Self::at_noise(dnorm, drel)) {
            return Assessment::Done;
        }
        if theta >= 1.0 && self.round >= 2 && self.renewed {
            return Assessment::Diverged;
        }
        if theta > slow {
            return Assessment::Slow;
        }
        Assessment::NotYet
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
            remainder: Remainder::Rate,
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

    fn ode15s() -> ConvergenceOptions {
        ConvergenceOptions {
            remainder: Remainder::Ode15s {
                tol: 0.1,
                tol_first: 0.02,
                first_rate: 0.3,
                diverge_above: 0.9,
            },
            max_iterations: 4,
            renew_when_exhausted: false,
            renew_on_divergence: false,
            reset_rate_on_renewal: false,
        }
    }

    #[test]
    fn ode15s_accepts_one_correction_only_with_a_rate_measured_on_the_matrix() {
        // a fresh matrix: no rate, the first correction never suffices
        let mut c = Convergence::with_rate(ode15s(), None);
        assert_eq!(c.assess(1e-6, || 1.0, false), Assessment::NotYet);
        // a kept rate 0.1 is floored at 0.3: η = 3/7, 0.04·3/7 ≈ 0.017 ≤ 0.02
        let mut c = Convergence::with_rate(ode15s(), Some(0.1));
        assert_eq!(c.assess(0.04, || 1.0, false), Assessment::Done);
        let mut c = Convergence::with_rate(ode15s(), Some(0.1));
        assert_eq!(c.assess(0.05, || 1.0, false), Assessment::NotYet);
        // the scheme's own acceptance (BDF's rounding floor) at any round
        c.next(0.05, false);
        assert_eq!(c.assess(0.05, || 1.0, true), Assessment::Done);
        assert!(!c.slow());
    }

    #[test]
    fn ode15s_rate_has_memory_and_slow_or_hopeless_iterations_end() {
        // 1, 0.3: θ = ρ = 0.3, remainder 0.129 > 0.1 (reachable: 0.129 ρ²
        // ≤ 0.1); 0.05: θ = 1/6, ρ = max(1/6, 0.9·0.3) = 0.27, remainder
        // 0.018 ≤ 0.1, slow (ρ > 0.2)
        let mut c = Convergence::with_rate(ode15s(), None);
        assert_eq!(c.assess(1.0, || 1.0, false), Assessment::NotYet);
        c.next(1.0, false);
        assert_eq!(c.assess(0.3, || 1.0, false), Assessment::NotYet);
        assert_eq!(c.rate(), Some(0.3));
        assert!(!c.slow(), "not converged");
        c.next(0.3, false);
        assert_eq!(c.assess(0.05, || 1.0, false), Assessment::Done);
        assert_eq!(c.rate(), Some(0.9 * 0.3));
        assert!(c.slow());
        // θ above 0.9 diverges, even at the noise (no stagnation rule)
        let mut c = Convergence::with_rate(ode15s(), None);
        c.assess(1.0, || 1.0, false);
        c.next(1.0, false);
        assert_eq!(c.assess(0.95, || 0.0, false), Assessment::Diverged);
        // 100 → 50: the remainder 50 would need ρ² ≤ 0.002 in the two
        // corrections left
        let mut c = Convergence::with_rate(ode15s(), None);
        c.assess(100.0, || 1.0, false);
        c.next(100.0, false);
        assert_eq!(c.assess(50.0, || 1.0, false), Assessment::Hopeless);
    }

    #[test]
    fn the_correction_test_asks_for_action_when_slow_and_diverges_only_after_a_renewal() {
        let opts = ConvergenceOptions {
            remainder: Remainder::Correction { slow: 0.5 },
            max_iterations: 30,
            renew_when_exhausted: false,
            renew_on_divergence: false,
            reset_rate_on_renewal: false,
        };
        let mut c = Convergence::new(opts, 1.0);
        assert_eq!(c.assess(1e3, || 1.0, false), Assessment::NotYet);
        c.next(1e3, false);
        // growing before any renewal: slow, the scheme renews
        assert_eq!(c.assess(2e3, || 1.0, false), Assessment::Slow);
        c.renewed_by_scheme();
        c.next(2e3, false);
        assert_eq!(c.assess(4e3, || 1.0, false), Assessment::Diverged);
        // growth at the noise of the solve converges; ‖Δ‖ ≤ 1 converges
        // whatever θ (no rate estimate)
        let mut c = Convergence::new(opts, 1.0);
        c.assess(1e3, || 1.0, false);
        c.next(1e3, false);
        assert_eq!(c.assess(2e3, || 1e-12, false), Assessment::Done);
        let mut c = Convergence::new(opts, 1.0);
        c.assess(2.0, || 1.0, false);
        c.next(2.0, false);
        assert_eq!(c.assess(1.0, || 1.0, false), Assessment::Done);
        // a restart forgets the last correction: no θ, no verdict on it
        let mut c = Convergence::new(opts, 1.0);
        c.assess(1e3, || 1.0, false);
        c.next(1e3, false);
        c.restart();
        assert_eq!(c.assess(2e3, || 1.0, false), Assessment::NotYet);
        assert!(c.theta().is_nan());
    }
}
