//! The flight step of Radau IIA's fixed steps ([`ImplicitOptions::flight_step`]
//! `H = k h`, the module docs of [`super`], "Flight step"): when an attempt
//! spans `k` grid steps, and where its Newton iteration starts.

use super::*;

impl<const S: usize, T: Tableau<S>> Run<'_, '_, S, T> {
    /// Grid steps of `h_fixed` the next fixed-step attempt spans: the
    /// flight stride from a grid point at the full step when no force
    /// element foresees an onset within [`FLIGHT_LOOKAHEAD`] flight steps
    /// ([`SecondOrderDae::onset_within`]), else 1.
    pub(super) fn grid_steps(&mut self) -> u64 {
        let k = self.flight_stride;
        let at_grid = (self.t - (self.t0 + (self.k_grid - 1) as f64 * self.h_fixed)).abs()
            <= 1e-9 * self.h_fixed;
        if k == 1 || self.flight_failed || !at_grid || self.h < self.h_fixed * (1.0 - 1e-9) {
            return 1;
        }
        let here = StateView {
            t: self.t,
            q: &self.q,
            qd: &self.v,
        };
        let horizon = FLIGHT_LOOKAHEAD * k as f64 * self.h_fixed;
        match self.sys.onset_within(here, horizon) {
            None => k,
            Some(_) => 1,
        }
    }

    /// The last step `h_prev`, whose stage polynomials the predictor of an
    /// attempt of `h` extrapolates to the new stage times `t_n + c_i h`,
    /// or `None` for the constant predictor (`A_i = q̈_n`, `Λ_i = λ_n`):
    /// that of a flight step (`h` above `h_fixed`) after a shorter step.
    /// The polynomials of a step of `h_fixed` extrapolated over `k` times
    /// their interval put corners deep into the walls that none is near
    /// (the falling rod; docs/scaling.md, "The falling rod's contact phases").
    pub(super) fn extrapolated_step(&self, h: f64) -> Option<f64> {
        let flight = !self.opts.adaptive && h > self.h_fixed * (1.0 + 1e-9);
        self.h_prev.filter(|&hp| !(flight && hp < h * (1.0 - 1e-9)))
    }
}
