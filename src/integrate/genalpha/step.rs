//! Local error estimate and step-size choice of the adaptive mode (module
//! docs of [`super`]).

use super::*;

/// Safety factor of the step-size controller.
pub const SAFETY: f64 = 0.9;

/// The rtol at which the local error per step is taken as it is
/// (MATLAB's default rtol); see [`proportionality`].
pub(super) const PROPORTIONAL_FROM: f64 = 1e-3;

/// Tolerance proportionality of a second-order method: with the local
/// error per step held at `tol`, the global error grows like the number of
/// steps times `tol`, i.e. like `tol^{2/3}` (steps `∝ tol^{−1/3}`), so at
/// rtol 1e-7 the global error of the stiff chain was 28× rtol. The test
/// runs at `tol = rtol·√(rtol/PROPORTIONAL_FROM)` below
/// [`PROPORTIONAL_FROM`], which makes the global error `∝ rtol` (as
/// Hairer's RADAU5 transforms its tolerance, Hairer & Wanner II §IV.8):
/// the error norm is multiplied by the returned factor.
pub(super) fn proportionality(rtol: f64) -> f64 {
    (PROPORTIONAL_FROM / rtol).sqrt().max(1.0)
}

impl Run<'_, '_> {
    /// Norm of the local error estimate of the attempt in `self.new`
    /// (module docs); ≤ 1 passes.
    pub(super) fn error_norm(&mut self, t1: f64, h: f64) -> Result<f64, Failure> {
        let p = self.p;
        let n = self.n;
        // Position LTE constant; for the first-order Newmark members the
        // velocity LTE (γ − ½) h² q⃛ is added (a heuristic for their
        // dominant error).
        let newmark = p.alpha_m == 0.0 && p.alpha_f == 0.0;
        let extra = if newmark {
            (p.gamma - 0.5).max(0.0)
        } else {
            0.0
        };
        let cst = (p.error_constant() + extra).abs() * h * h;
        for i in 0..n {
            self.err[i] = cst * (self.new.a[i] - self.cur.a[i]);
        }
        if self.opts.filter_error && self.renewal.valid() {
            let c_m = (1.0 - p.alpha_m) / (1.0 - p.alpha_f);
            let mass = self.sys.mass_diagonal();
            for (e, m) in self.err[..n].iter_mut().zip(mass) {
                *e *= c_m * m;
            }
            self.err[n..].fill(0.0);
            self.sys.solve(t1, &mut self.err).map_err(Failure::system(
                "error filter",
                t1,
                Some(self.t),
            ))?;
        }
        let norm = common::max_weighted(
            n,
            |i| self.err[i],
            |i| self.atol(i) + self.ode.rtol * self.cur.q[i].abs().max(self.new.q[i].abs()),
        );
        Ok(norm * proportionality(self.ode.rtol))
    }

    pub(super) fn initial_step_guess(&mut self, span: f64) -> f64 {
        common::initial_step_from_accelerations(
            &self.cur.qdd[..self.n],
            |i| self.atol(i) + self.ode.rtol * self.cur.q[i].abs(),
            span,
        )
    }
}
