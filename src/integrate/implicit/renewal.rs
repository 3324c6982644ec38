//! The one policy for when an implicit scheme re-evaluates and
//! re-factorises its Newton matrix (simplified Newton: the matrix is kept
//! across corrections and steps while it serves; Hairer & Wanner II,
//! §IV.8). A factorisation is renewed at an attempt's predictor when the
//! scheme asked for it ([`Renewal::renew`]: slow contraction, a failed
//! attempt, a rejected step), when the step parameter it was made for
//! (the step h, BDF's leading coefficient a₀) has moved out of a band, or
//! always where the options say so; the per-scheme differences are
//! [`RenewalOptions`]. Renewals within an attempt (an exhausted or
//! diverging iteration) are the convergence test's
//! ([`super::Convergence`]).

/// Where the rules of [`Renewal`] differ between schemes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenewalOptions {
    /// A factorisation is kept while the step parameter stays within this
    /// relative distance of the one it was made for, `|p/p_f − 1| ≤ band`.
    pub band: f64,
    /// Keep factorisations from one attempt to the next (false: a fresh
    /// matrix at every predictor — `integrator.reuse = false`, the
    /// augmented Lagrangian).
    pub across_attempts: bool,
    /// Renew before every correction after an attempt's first (full
    /// Newton: `integrator.reuse = false` of generalized-α and Radau IIA).
    pub every_correction: bool,
}

/// The state of the policy over a run.
#[derive(Debug, Clone)]
pub struct Renewal {
    opts: RenewalOptions,
    /// The step parameter of the valid factorisation (None: none valid).
    at: Option<f64>,
    /// Renew at the next predictor.
    stale: bool,
    /// The current attempt has factorised (at its predictor or later).
    fresh: bool,
    /// The current attempt has made or tried to make a factorisation.
    made: bool,
}

impl Renewal {
    /// No valid factorisation yet: the first predictor factorises.
    pub fn new(opts: RenewalOptions) -> Self {
        Self {
            opts,
            at: None,
            stale: true,
            fresh: false,
            made: false,
        }
    }

    /// At the predictor of a new attempt with step parameter `p`: whether
    /// to factorise now.
    pub(crate) fn at_predictor(&mut self, p: f64) -> bool {
        self.fresh = false;
        self.made = false;
        let moved = self
            .at
            .is_none_or(|pf| (p / pf - 1.0).abs() > self.opts.band);
        self.stale || moved || !self.opts.across_attempts
    }

    /// Before correction `round` (from 0) on the current matrix: whether to
    /// factorise at the iterate first ([`RenewalOptions::every_correction`]).
    pub(crate) fn before_correction(&self, round: usize) -> bool {
        round > 0 && self.opts.every_correction
    }

    /// A factorisation is about to be made: none is valid until
    /// [`Renewal::factorised`] (a failed factorisation leaves none).
    pub fn factorising(&mut self) {
        self.at = None;
        self.made = true;
    }

    /// A factorisation was made for step parameter `p`.
    pub fn factorised(&mut self, p: f64) {
        self.at = Some(p);
        self.stale = false;
        self.fresh = true;
    }

    /// Renew at the next predictor.
    pub(crate) fn renew(&mut self) {
        self.stale = true;
    }

    /// Whether the current attempt has factorised its own matrix.
    pub fn fresh(&self) -> bool {
        self.fresh
    }

    /// Whether the current attempt has made, or tried to make, its own
    /// factorisation: a failure without one is worth a retry on a fresh
    /// matrix (`attempt_or_cut`).
    pub(crate) fn made_own(&self) -> bool {
        self.made
    }

    /// Whether a valid factorisation exists.
    pub fn valid(&self) -> bool {
        self.at.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_matrix_is_kept_within_the_band_and_renewed_outside_or_on_request() {
        let opts = RenewalOptions {
            band: 0.25,
            across_attempts: true,
            every_correction: false,
        };
        let mut r = Renewal::new(opts);
        assert!(r.at_predictor(1.0), "no factorisation yet");
        r.factorising();
        r.factorised(1.0);
        assert!(r.fresh() && r.valid() && r.made_own());
        assert!(!r.at_predictor(1.2), "within 25 %");
        assert!(!r.fresh() && !r.made_own());
        assert!(r.at_predictor(1.3), "outside 25 %");
        assert!(r.at_predictor(0.7));
        r.renew();
        assert!(r.at_predictor(1.0), "asked for");
        assert!(!r.before_correction(1));
        // a failed factorisation leaves none valid, and was the attempt's own
        r.factorising();
        assert!(!r.valid() && !r.fresh() && r.made_own());
        assert!(r.at_predictor(1.0));
    }

    #[test]
    fn without_reuse_every_predictor_and_correction_renews() {
        let mut r = Renewal::new(RenewalOptions {
            band: 0.25,
            across_attempts: false,
            every_correction: true,
        });
        r.factorising();
        r.factorised(1.0);
        assert!(r.at_predictor(1.0));
        assert!(!r.before_correction(0));
        assert!(r.before_correction(1));
    }
}
