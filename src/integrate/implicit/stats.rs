//! The work counters of an implicit run, one struct for every scheme.

use super::super::Stats;
use serde::Serialize;

/// Highest order of the variable-order schemes whose accepted steps are
/// counted per order ([`ImplicitStats::steps_at_order`]): BDF 1–5.
pub const COUNTED_ORDERS: usize = 5;

/// Work counters of an implicit (index-3) run: generalized-α, BDF/NDF,
/// Radau IIA and the augmented Lagrangian. Counters a scheme does not
/// have stay 0 (`complex_factorizations` outside Radau IIA,
/// `steps_at_order` outside BDF, `penalty_increases` outside the augmented
/// Lagrangian).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ImplicitStats {
    /// Accepted steps.
    pub steps: usize,
    /// Step attempts rejected by the error test (adaptive schemes).
    pub error_rejections: usize,
    /// Step attempts abandoned because Newton did not converge.
    pub newton_failures: usize,
    /// Newton corrections (linear solves of the Newton matrix; Radau IIA:
    /// one real and one complex solve each, the augmented Lagrangian: one
    /// multiplier update each).
    pub newton_iterations: usize,
    /// Factorisations of the (real) Newton matrix.
    pub factorizations: usize,
    /// Factorisations of the complex Newton matrix (Radau IIA).
    pub complex_factorizations: usize,
    /// Residual evaluations.
    pub residual_evaluations: usize,
    /// Projections onto the constraint manifold (the augmented
    /// Lagrangian: the velocity and acceleration projections of each
    /// accepted step).
    pub projections: usize,
    /// Accepted steps at each order 1 … [`COUNTED_ORDERS`] (index 0 unused;
    /// BDF/NDF).
    pub steps_at_order: [usize; COUNTED_ORDERS + 1],
    /// Times the penalty was raised within an attempt (augmented
    /// Lagrangian, slow contraction).
    pub penalty_increases: usize,
    /// Largest factor over the default penalty used in an attempt
    /// (augmented Lagrangian; 1 otherwise).
    pub max_penalty_factor: f64,
    /// Smallest accepted step \[s\] (0 without an accepted step).
    pub min_step_taken: f64,
    /// Largest accepted step \[s\].
    pub max_step_taken: f64,
}

impl Default for ImplicitStats {
    /// The counters at the start of a run (`min_step_taken` = ∞ until the
    /// first accepted step, `max_penalty_factor` = 1).
    fn default() -> Self {
        Self {
            steps: 0,
            error_rejections: 0,
            newton_failures: 0,
            newton_iterations: 0,
            factorizations: 0,
            complex_factorizations: 0,
            residual_evaluations: 0,
            projections: 0,
            steps_at_order: [0; COUNTED_ORDERS + 1],
            penalty_increases: 0,
            max_penalty_factor: 1.0,
            min_step_taken: f64::INFINITY,
            max_step_taken: 0.0,
        }
    }
}

impl ImplicitStats {
    /// As the explicit methods count: accepted steps, rejected attempts
    /// (error rejections + Newton failures), residual evaluations.
    pub fn counts(&self) -> Stats {
        Stats {
            steps: self.steps,
            failed_steps: self.error_rejections + self.newton_failures,
            rhs_evals: self.residual_evaluations,
        }
    }

    /// An accepted step of size `h` \[s\].
    pub(crate) fn accept(&mut self, h: f64) {
        self.steps += 1;
        self.min_step_taken = self.min_step_taken.min(h);
        self.max_step_taken = self.max_step_taken.max(h);
    }

    /// The counters at the end of a run: `min_step_taken` = 0 without an
    /// accepted step.
    pub fn finished(mut self) -> Self {
        if self.steps == 0 {
            self.min_step_taken = 0.0;
        }
        self
    }
}
