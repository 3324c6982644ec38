//! Newton iteration on the positions and reuse of factorisations (module
//! docs of [`super`], "Newton iteration").

use super::super::implicit::{
    Assessment, Convergence, ConvergenceOptions, Next, Remainder, ROUNDING_ULPS,
};
use super::augmented::{SlowAnswer, SLOW_CONTRACTION};
use super::*;
use crate::parallel::{in_halves, split_passes, Slices, PARALLEL_MIN_COORDS};

/// A factorisation is reused while the step size stays within this
/// relative distance of the one it was computed for.
pub const REUSE_BAND: f64 = 0.25;
/// Iterations per step after which the factorisation is renewed at the
/// next step.
pub const SLOW_ITERATIONS: usize = 4;

/// Corrections a matrix renewed at every predictor must save per step
/// (against the last step on an older matrix) to be renewed there: about
/// the cost of a factorisation, in corrections. The fresh matrix's count
/// is the smaller of its last two attempts (single corrections come and
/// go with the quadratic model). The counts behind it: docs/scaling.md,
/// "Measurements behind the defaults".
pub(super) const RENEW_SAVING: usize = 2;

/// A single Newton correction is accepted on a matrix factorised at the
/// predictor when the quadratic model `C ‖Δq₁‖²` of the remainder (module
/// docs of [`super`], "Convergence test") is at most this many tolerances.
pub(super) const SINGLE_CORRECTION: f64 = 1.0;
/// [`SINGLE_CORRECTION`] where the tolerance is the rounding floor of the
/// positions (`newton_tol/max(1, γ', β') < 20 ulps`, the default
/// `newton_tol` at small steps): a remainder of 4 floor units, 80 ulps.
/// On the stiff chain at N = 10 000 the second correction on a fresh
/// matrix is 1–3 floor units (the third, the solve's noise, 0.1–0.3), so
/// with 1 almost every such attempt made a second one; with 4 the tip at
/// t = 0.1 s moved by 3e-10 m (N = 1000) and 9e-11 m (N = 10 000) at
/// h = 1.25e-5, against tip errors of 9e-6 and 2e-6 m (docs/scaling.md).
pub(super) const SINGLE_CORRECTION_AT_FLOOR: f64 = 4.0;
/// Single-correction acceptances on one measured constant `C` before the
/// next attempt on a fresh matrix makes a second correction to measure it
/// again (the constant follows the curvature of the residual, which moves
/// with the state); likewise renewals of the matrix at consecutive
/// predictors before one step runs on the older matrix again.
pub(super) const QUAD_REUSE: usize = 10;

impl Run<'_, '_> {
    /// With [`ImplicitOptions::extrapolate`], after the step `h` to
    /// `self.new` was accepted: the next predictor extrapolates q̈ linearly
    /// (`q̈_n + h/h_{n−1}·(q̈_n − q̈_{n−1})`) if that would have predicted this
    /// step's converged q̈ better than the constant `q̈_n`, in the Newton
    /// norm's weights `1/max(|q_i|, 1)` (max over coordinates). Smooth
    /// motion takes the extrapolation, a free fall (constant q̈, its
    /// extrapolation only amplifying rounding) or a contact onset the
    /// constant. One serial pass; max is order-free.
    pub(super) fn choose_predictor(&mut self, h: f64) {
        let Some(hp) = self.h_prev else {
            return;
        };
        let r = h / hp;
        let (mut constant, mut extrapolated) = (0.0_f64, 0.0_f64);
        let (q, qdd0, qdd1, qddp) = (&self.cur.q, &self.cur.qdd, &self.new.qdd, &self.prev_qdd);
        for i in 0..self.n {
            let w = 1.0 / q[i].abs().max(1.0);
            let d = qdd1[i] - qdd0[i];
            constant = constant.max(d.abs() * w);
            extrapolated = extrapolated.max((d - r * (qdd0[i] - qddp[i])).abs() * w);
        }
        self.extrapolate_next = extrapolated < constant;
    }

    /// After an attempt converged in `it` corrections on a matrix
    /// factorised at its predictor (`fresh`) or an older one: whether a
    /// matrix renewed at the next predictor saves at least
    /// [`RENEW_SAVING`] corrections, judged by the last converged attempts
    /// of the other kind. Every [`QUAD_REUSE`]-th renewal in a row is
    /// skipped, so that the corrections an older matrix needs are measured
    /// again.
    fn renew_pays(&mut self, fresh: bool, it: usize) -> bool {
        let (fresh_its, stale_its) = if fresh {
            let f = self.newton_its.0.map_or(it, |(last, _)| last.min(it));
            self.newton_its.0 = Some((it, f));
            (Some(f), self.newton_its.1)
        } else {
            self.newton_its.1 = Some(it);
            (self.newton_its.0.map(|(_, f)| f), Some(it))
        };
        let pays = matches!((fresh_its, stale_its), (Some(f), Some(s)) if s >= f + RENEW_SAVING);
        if !pays || !fresh {
            self.renewals = 0;
            return pays;
        }
        self.renewals += 1;
        if self.renewals > QUAD_REUSE {
            self.renewals = 0;
            return false;
        }
        true
    }

    /// Factorise the iteration matrix at the current iterate.
    pub(super) fn factor(&mut self, t1: f64, h: f64, c: [f64; 3]) -> Result<(), SystemError> {
        self.stats.factorizations += 1;
        self.renewal.factorising();
        let new = &self.new;
        self.sys.factorize(new.at(t1), &new.lam, c)?;
        self.renewal.factorised(h);
        Ok(())
    }

    /// One step attempt from `(self.t, self.cur)` to `t1 = self.t + h`
    /// into `self.new`: predictor, then (modified) Newton; with the
    /// augmented Lagrangian's hook ([`SecondOrderDae::multiplier_update`])
    /// λ* kept from the last step and updated after every correction
    /// (module docs of [`super::augmented`]).
    pub(super) fn attempt(&mut self, t1: f64, h: f64) -> Result<(), SystemError> {
        let p = self.p;
        let (n, tol) = (self.n, self.opts.newton_tol);
        let s = p.beta * h * h;
        let c_m = (1.0 - p.alpha_m) / (1.0 - p.alpha_f);
        let c = [c_m, p.gamma * h, s];
        let gp = p.gamma / (p.beta * h); // ∂q̇/∂q
        let bp = c_m / s; // ∂q̈/∂q
        let ap = 1.0 / s; // ∂a/∂q
        let augmented = self.augmented;
        if let Some(al) = self.sys.multiplier_update() {
            al.set_step_scale(s);
        }
        {
            let (cur, new) = (&self.cur, &mut self.new);
            let (am, af, g, b) = (p.alpha_m, p.alpha_f, p.gamma, p.beta);
            // q̈_{n+1} predicted constant or extrapolated linearly from the
            // last two steps; λ_n for a factorisation at the predictor
            let r = match self.h_prev {
                Some(hp) if self.extrapolate_next => h / hp,
                _ => 0.0,
            };
            // element by element, in two fixed halves concurrently for
            // large n (the same bits)
            in_halves(
                n >= PARALLEL_MIN_COORDS,
                n,
                Slices {
                    base: 0,
                    w: [&mut new.qdd, &mut new.a, &mut new.v, &mut new.q],
                    r: [&cur.qdd, &self.prev_qdd, &cur.a, &cur.v, &cur.q],
                },
                |u| {
                    let ([nqdd, na, nv, nq], [qdd, pqdd, ca, cv, cq]) = (u.w, u.r);
                    for i in 0..nq.len() {
                        let qdd0 = qdd[i] + r * (qdd[i] - pqdd[i]);
                        nqdd[i] = qdd0;
                        na[i] = ((1.0 - af) * qdd0 + af * qdd[i] - am * ca[i]) / (1.0 - am);
                        nv[i] = cv[i] + h * ((1.0 - g) * ca[i] + g * na[i]);
                        nq[i] = cq[i] + h * cv[i] + h * h * ((0.5 - b) * ca[i] + b * na[i]);
                    }
                },
                |(), ()| (),
            );
            new.lam.copy_from_slice(&cur.lam);
        }
        if self.renewal.at_predictor(h) {
            self.factor(t1, h, c)?;
        }
        // The multipliers start from 0 (module docs of [`super`], "Newton
        // iteration"): the first correction computes λ_{n+1} whole, in the
        // representative the regularised solve picks, instead of adding an
        // increment to λ_n that carries the previous steps' components in
        // the (near-)null space of Φ_qᵀ. The augmented Lagrangian's λ* is
        // no unknown: it starts from λ*_n and is iterated.
        if !augmented {
            self.new.lam.fill(0.0);
        }
        // the matrix was factorised at this step's predictor: Newton
        // converges quadratically from the first correction on
        let fresh = self.renewal.fresh();
        // position-equivalent tolerance of the acceleration (and velocity)
        // corrections, floored at a few ulps of the positions
        let tol_q = tol / gp.max(bp).max(1.0);
        let single_max = if tol_q < ROUNDING_ULPS * f64::EPSILON {
            SINGLE_CORRECTION_AT_FLOOR
        } else {
            SINGLE_CORRECTION
        };
        let mut conv = Convergence::new(
            ConvergenceOptions {
                // the augmented Lagrangian: the correction itself against
                // the tolerance (the multiplier update after each
                // correction contracts only linearly)
                remainder: if augmented {
                    Remainder::Correction {
                        slow: SLOW_CONTRACTION,
                    }
                } else {
                    Remainder::Rate
                },
                max_iterations: self.opts.max_newton,
                renew_when_exhausted: self.opts.reuse && !augmented,
                renew_on_divergence: false,
                reset_rate_on_renewal: true,
            },
            self.eta,
        );
        // the first correction's norm (for the quadratic model)
        let mut first = f64::NAN;
        let mut it = 0;
        // renew the matrix at the iterate before the next correction
        let mut renew_now = false;
        // the augmented Lagrangian's penalty factor within this attempt
        let mut boost = 1.0;
        loop {
            if it > 0 {
                if let Some(al) = self.sys.multiplier_update() {
                    let new = &mut self.new;
                    al.update_multipliers(t1, &new.q, &mut new.lam)?;
                }
            }
            if renew_now || self.renewal.before_correction(conv.round()) {
                renew_now = false;
                self.factor(t1, h, c)?;
            }
            self.stats.residual_evaluations += 1;
            let new = &self.new;
            self.sys
                .residual(new.at(t1), &new.qdd, &new.lam, s, &mut self.r)?;
            // solving for r (not −r) gives −Δ, the correction negated
            // exactly (the solve is linear and rounds symmetrically):
            // `correct` and the multipliers subtract it, the same bits as
            // adding Δ
            self.sys.solve(t1, &mut self.r)?;
            self.stats.newton_iterations += 1;
            it += 1;
            // the correction's norm in tolerances (floored at a few ulps of
            // the positions), its size relative to the positions, and the
            // update of q, q̇, q̈, a — one pass (two fixed halves
            // concurrently for large n; max is order-free, so the bits do
            // not depend on the thread count)
            // λ −= (−Δλ)/s in the same hand-over, each in its own two halves
            // (the augmented Lagrangian's solve has no multiplier rows: an
            // empty pass)
            let (dx, new) = (&self.r, &mut self.new);
            let ml = dx.len() - n;
            let (dnorm, drel) = split_passes(
                n >= PARALLEL_MIN_COORDS,
                (
                    n,
                    Slices {
                        base: 0,
                        w: [&mut new.q, &mut new.v, &mut new.qdd, &mut new.a],
                        r: [&dx[..n]],
                    },
                    |_, u| correct(u, [gp, bp, ap, tol_q]),
                ),
                (
                    ml,
                    Slices {
                        base: 0,
                        w: [&mut new.lam[..ml]],
                        r: [&dx[n..]],
                    },
                    |_, u| {
                        let ([l], [d]) = (u.w, u.r);
                        for (l, d) in l.iter_mut().zip(d) {
                            *l -= d / s;
                        }
                    },
                ),
                |(n0, r0), (n1, r1)| (n0.max(n1), r0.max(r1)),
            );
            if !dnorm.is_finite() {
                return Err(SystemError::msg("non-finite Newton correction"));
            }
            if fresh && it == 2 && !augmented {
                // ‖Δq₂‖ = C ‖Δq₁‖² (quadratic convergence on a fresh matrix)
                self.quad = Some((dnorm / (first * first), h, 0));
            }
            if it == 1 {
                first = dnorm;
            }
            // a single correction on a fresh matrix whose remainder the
            // quadratic model puts at the tolerance: the second correction
            // would only iterate into the rounding floor
            let single = match &mut self.quad {
                // measured at this step size (the tolerance units move with h)
                Some((quad, hq, uses))
                    if fresh && it == 1 && *uses < QUAD_REUSE && *hq == h && !augmented =>
                {
                    let single = *quad * dnorm * dnorm <= single_max;
                    *uses += single as usize;
                    single
                }
                _ => false,
            };
            let mut restart = false;
            let mut done = match conv.assess(dnorm, || drel, single) {
                Assessment::Done => true,
                Assessment::NotYet => false,
                // the augmented Lagrangian's slow multiplier iteration
                // (module docs of [`super::augmented`], "Penalty growth")
                Assessment::Slow => {
                    match self.slow_multipliers(&mut conv, &mut boost) {
                        SlowAnswer::Renew => renew_now = true,
                        SlowAnswer::RaisedPenalty => {
                            renew_now = true;
                            restart = true;
                        }
                        SlowAnswer::Nothing => {}
                    }
                    false
                }
                Assessment::Diverged | Assessment::RenewAfterUndo | Assessment::Hopeless => {
                    // an iterate at the constraints' rounding floor has converged
                    // (the augmented Lagrangian has its own noise rule)
                    if !augmented && self.at_constraint_noise(t1, s, [gp, bp, ap, tol_q])? {
                        return Ok(());
                    }
                    return Err(SystemError::msg(format!(
                        "Newton diverges (contraction θ = {:.3}, correction {:.3e} × tol)",
                        conv.theta(),
                        dnorm
                    )));
                }
            };
            if conv.slow() {
                self.renewal.renew();
            }
            if done && self.opts.check_constraints {
                self.sys.constraints(t1, &self.new.q, &mut self.phi);
                let phi = crate::numeric::max_abs(&self.phi);
                let scale = crate::numeric::max_abs(&self.new.q).max(1.0);
                done = phi <= tol_q + ROUNDING_ULPS * f64::EPSILON * scale;
            }
            match conv.next(dnorm, done) {
                None if augmented => {
                    // the last multiplier update at the converged positions
                    if let Some(al) = self.sys.multiplier_update() {
                        let new = &mut self.new;
                        al.update_multipliers(t1, &new.q, &mut new.lam)?;
                    }
                    return Ok(());
                }
                None => {
                    if let Some(eta) = conv.rate_to_keep() {
                        self.eta = eta;
                    }
                    if it > SLOW_ITERATIONS || self.renew_pays(fresh, it) {
                        self.renewal.renew();
                    }
                    return Ok(());
                }
                Some(Next::Iterate) => {
                    if restart {
                        // the penalty changed: a new rate measurement
                        conv.restart();
                    }
                }
                // still contracting: renew the matrix at this (much better)
                // iterate once and carry on
                Some(Next::Renew) => renew_now = true,
                Some(Next::Exhausted) => {
                    return Err(SystemError::msg(format!(
                        "no convergence in {it} iterations (last correction {:.3e} × tol, θ = {:.3})",
                        conv.last(),
                        conv.theta()
                    )));
                }
            }
        }
    }
}

impl Run<'_, '_> {
    /// Before an attempt whose corrections stopped contracting (θ ≥ 1)
    /// fails:
    /// whether its iterate already solves the equations to working
    /// precision (module docs of [`super`], "Noise near a singular
    /// position"): `‖Φ‖∞` at the corrected iterate is at its rounding
    /// floor ([`ROUNDING_ULPS`] ulps of `max(|q|, 1)`), and the correction
    /// asked for by the dynamic rows of the residual alone (its constraint
    /// rows zeroed) is within the tolerance; that correction is then
    /// applied and λ computed whole from zero at the accepted positions. Near a singular position the corrections of the full
    /// residual are the rounding of Φ amplified by the inverse of Φ_q's
    /// smallest singular value, in its near-null direction, and do not
    /// contract whatever the step. `c = [γ', β', 1/(βh²), tol_q]` as for
    /// [`correct`]. Costs one evaluation of Φ and, if it is at the floor,
    /// two residuals and two solves, on this failure path only.
    fn at_constraint_noise(&mut self, t1: f64, s: f64, c: [f64; 4]) -> Result<bool, SystemError> {
        let n = self.n;
        if self.phi.is_empty() {
            return Ok(false);
        }
        self.sys.constraints(t1, &self.new.q, &mut self.phi);
        let phi = crate::numeric::max_abs(&self.phi);
        let scale = crate::numeric::max_abs(&self.new.q).max(1.0);
        if phi.is_nan() || phi > ROUNDING_ULPS * f64::EPSILON * scale {
            return Ok(false);
        }
        self.solve_dynamic_rows(t1, s)?;
        self.stats.newton_iterations += 1;
        let [gp, bp, ap, tol_q] = c;
        let floor = ROUNDING_ULPS * f64::EPSILON;
        let (q, d) = (&self.new.q, &self.r[..n]);
        let dnorm = d.iter().zip(q).fold(0.0_f64, |a, (di, qi)| {
            a.max(di.abs() / (tol_q + floor * qi.abs().max(1.0)))
        });
        if dnorm.is_nan() || dnorm > 1.0 {
            return Ok(false);
        }
        // `r` holds the correction negated, as in the Newton loop
        let new = &mut self.new;
        for (i, &di) in self.r[..n].iter().enumerate() {
            new.q[i] -= di;
            new.v[i] -= gp * di;
            new.qdd[i] -= bp * di;
            new.a[i] -= ap * di;
        }
        // λ whole from zero at the accepted positions (as the first
        // correction of every attempt computes it): the sum over the
        // non-contracting corrections carries their noise in the
        // (near-)null space of Φ_qᵀ, which the next predictor's geometric
        // stiffness (Φ_qᵀλ)_q would take
        new.lam.fill(0.0);
        self.solve_dynamic_rows(t1, s)?;
        for (l, d) in self.new.lam.iter_mut().zip(&self.r[n..]) {
            *l = -d / s;
        }
        Ok(true)
    }

    /// The solve of the residual's dynamic rows alone (its constraint rows
    /// zeroed) at the current iterate into `r` ([`Self::at_constraint_noise`]).
    fn solve_dynamic_rows(&mut self, t1: f64, s: f64) -> Result<(), SystemError> {
        self.stats.residual_evaluations += 1;
        let new = &self.new;
        self.sys
            .residual(new.at(t1), &new.qdd, &new.lam, s, &mut self.r)?;
        self.r[self.n..].fill(0.0);
        self.sys.solve(t1, &mut self.r)
    }
}

/// One Newton correction `Δq = −u.r[0]` of generalized-α (module docs of
/// [`super`]) on `u.w = [q, q̇, q̈, a]`: `q += Δq`, `q̇ += γ/(βh) Δq`,
/// `q̈ += c_m/(βh²) Δq`, `a += Δq/(βh²)` (`c = [γ/(βh), c_m/(βh²), 1/(βh²),
/// tol_q]`), and the max-norms `‖Δq ./ (tol_q + 20 ulp·max(|q|, 1))‖∞` and
/// `‖Δq ./ max(|q|, 1)‖∞` at the iterate before the correction. Split into
/// halves ([`in_halves`]), the max does not depend on the order: same bits.
fn correct(u: Slices<'_, 4, 1>, c: [f64; 4]) -> (f64, f64) {
    let [q, v, qdd, a] = u.w;
    let [d] = u.r;
    let [gp, bp, ap, tol_q] = c;
    let len = q.len();
    let (q, v, qdd, a, d) = (
        &mut q[..len],
        &mut v[..len],
        &mut qdd[..len],
        &mut a[..len],
        &d[..len],
    );
    let floor = ROUNDING_ULPS * f64::EPSILON;
    let (mut dnorm, mut drel) = (MaxRatio::default(), MaxRatio::default());
    for i in 0..len {
        // `d` holds −Δq: subtracting it (and `c·d`) rounds as adding Δq
        let (di, qi) = (d[i], q[i]);
        let scale = qi.abs().max(1.0);
        dnorm.add(di.abs(), tol_q + floor * scale);
        drel.add(di.abs(), scale);
        q[i] = qi - di;
        v[i] -= gp * di;
        qdd[i] -= bp * di;
        a[i] -= ap * di;
    }
    (dnorm.max, drel.max)
}

/// `max_i a_i / b_i` (`a_i ≥ 0`, `b_i > 0`) with the division made only
/// where the quotient can exceed the running maximum `M`: a float
/// `a < fl(M·b)` is at most the float below `fl(M·b)`, which lies below
/// `M·b` (`fl` rounds to the nearest), so `a/b < M`, `fl(a/b) ≤ M`
/// (rounding is monotone) and `M.max(fl(a/b))` would return `M` — the same
/// bits as dividing every time, at a multiplication and a comparison for
/// most coordinates (a division costs several times their latency). NaN
/// compares false and takes the division, as before.
#[derive(Default)]
struct MaxRatio {
    max: f64,
}

impl MaxRatio {
    #[inline(always)]
    fn add(&mut self, a: f64, b: f64) {
        if a < self.max * b {
            return;
        }
        self.max = self.max.max(a / b);
    }
}

#[cfg(test)]
mod tests {
    use super::MaxRatio;

    /// The skipped divisions change no bit: against `max_i fl(a_i / b_i)`
    /// divided every time, on ratios that cluster just below and above
    /// the running maximum (where `fl(M (1 − 4ε) b)` is closest to `a`),
    /// spread over many decades, and with zeros, NaN and ∞.
    #[test]
    fn max_ratio_has_the_bits_of_dividing_every_time() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..20_000 {
            let len = 1 + (next() * 300.0) as usize;
            let (mut a, mut b) = (Vec::with_capacity(len), Vec::with_capacity(len));
            for _ in 0..len {
                let bi = 10f64.powf(next() * 20.0 - 10.0);
                let r = match case % 4 {
                    // quotients within a few ulps of each other
                    0 => {
                        // mantissas near 1 and near 2, a few ulps apart
                        let m = [1.0, 1.5, 2.0 - 64.0 * f64::EPSILON][case / 4 % 3];
                        m * (1.0 + (next() * 8.0).floor() * f64::EPSILON)
                    }
                    1 => 10f64.powf(next() * 30.0 - 15.0),
                    2 => next(),
                    _ => [0.0, 1.0, 1.0 - f64::EPSILON, 1.0 + 2.0 * f64::EPSILON]
                        [(next() * 4.0) as usize],
                };
                a.push(r * bi);
                b.push(bi);
            }
            if case % 50 == 7 {
                a[len / 2] = f64::NAN;
            }
            if case % 50 == 9 {
                a[len / 3] = f64::INFINITY;
            }
            let plain = a.iter().zip(&b).fold(0.0_f64, |m, (x, y)| m.max(x / y));
            let mut m = MaxRatio::default();
            for (x, y) in a.iter().zip(&b) {
                m.add(*x, *y);
            }
            assert_eq!(m.max.to_bits(), plain.to_bits(), "case {case}");
        }
        // the closest case: the maximum M first, then a = the float just
        // below fl(M·b), the largest a that skips its division
        for _ in 0..100_000 {
            let big = (1.0 + next()) * 10f64.powf(next() * 20.0 - 10.0);
            let bi = (1.0 + next()) * 10f64.powf(next() * 20.0 - 10.0);
            let a = f64::from_bits((big * bi).to_bits() - 1);
            let plain = big.max(a / bi);
            let mut m = MaxRatio::default();
            m.add(big, 1.0);
            m.add(a, bi);
            assert_eq!(m.max.to_bits(), plain.to_bits(), "M = {big:e}, b = {bi:e}");
        }
    }
}
