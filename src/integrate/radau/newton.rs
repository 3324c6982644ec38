//! The simplified Newton iteration of Radau IIA's stages (module docs of
//! [`super`], "Renewal"): the real and complex factorisations, the
//! predictor and the corrections under the one
//! [`Convergence`](super::super::implicit::Convergence) test.

use super::*;
use crate::parallel::{split_pass, split_passes, Halve, PARALLEL_MIN_COORDS};

/// The stage at whose predicted (or current) iterate the Newton matrices
/// of an attempt are factorised: `S/2`, the node nearest the step's
/// middle (`c = 0.645, 0.584, 0.559` for S = 3, 5, 7). The stages lie
/// within `max(c_m, 1 − c_m) h` of it instead of within `h` of the step's
/// start, so the frozen matrices' mismatch with the stages' own Jacobians
/// (the bodies turn within the step) is about halved (simplified Newton,
/// Hairer & Wanner II, §IV.8: its contraction grows with that mismatch).
pub(super) const fn middle<const S: usize>() -> usize {
    S / 2
}

/// The Newton test's tolerance factor per coordinate, `1/ℓ_k` with the
/// lengths `ℓ_k` of [`SecondOrderDae::correction_lengths`] (1 where the
/// system gives none): a correction `h² ΔA_k` passes at `h² newton_tol /
/// ℓ_k`, so a body angle's acceleration correction is measured at the
/// body's radius of gyration, in m/s² as the translations'. At 1 m per
/// rad an angle of the stiff chain (1 mm segments of a 3 cm square rod,
/// `ρ` = 8.7 mm) would be held to a test 115 times tighter than its
/// translations, and the corrections would go to its stiff modes at the
/// tip (docs/scaling.md, "radau5's Newton test with angles at the radius
/// of gyration").
pub(super) fn tolerance_factors(sys: &dyn SecondOrderDae) -> Vec<f64> {
    match sys.correction_lengths() {
        Some(l) => l.iter().map(|&l| 1.0 / l).collect(),
        None => vec![1.0; sys.n()],
    }
}

/// The rate estimate of an attempt's first correction from the last one
/// kept, `max(η, ε)^0.8` (RADAU5's `FACCON`).
pub(super) fn first_rate(eta: f64) -> f64 {
    eta.max(f64::EPSILON).powf(0.8)
}

/// The convergence rules of Radau IIA's simplified Newton (radau5 and
/// radau9): the rate test, a renewal at the iterate when the iteration is
/// exhausted or diverges.
pub(super) fn radau_convergence(max_newton: usize) -> ConvergenceOptions {
    ConvergenceOptions {
        remainder: Remainder::Rate,
        max_iterations: max_newton,
        renew_when_exhausted: true,
        renew_on_divergence: true,
        reset_rate_on_renewal: false,
    }
}

impl<const S: usize, T: Tableau<S>> Run<'_, '_, S, T> {
    /// Factorise the real and the complex matrices for the step `h` at the
    /// current iterate of stage `i`, `(t_n + c_i h, Q_i, V_i, Λ_i)` (`qs`,
    /// `vs` are overwritten): [`middle`]`::<S>()` at the predictor and
    /// before a correction, the last stage when an attempt renews them
    /// (module docs of [`super`], "Simplified Newton").
    pub(super) fn factor_at(&mut self, h: f64, i: usize) -> Result<(), SystemError> {
        let tab = self.tab.stages();
        let g = tab.gamma;
        self.renewal.factorising();
        self.stage_state(i, h);
        let (t, q, v, lam) = (self.t + tab.c[i] * h, &self.qs, &self.vs, &self.l[i]);
        self.stats.factorizations += 1;
        let x = StateView { t, q, qd: v };
        self.sys.factorize(x, lam, [1.0, h * g, h * h * g * g])?;
        for (c, mu) in self.cplx.iter_mut().zip(&tab.mu) {
            let hmu = [h * mu[0], h * mu[1]];
            self.stats.complex_factorizations += 1;
            c.factorize_complex(x, lam, [[1.0, 0.0], hmu, cmul(hmu, hmu)])?;
        }
        self.renewal.factorised(h);
        Ok(())
    }

    /// One attempt of the step `h` from `(t, q, v)` into `a`, `l`.
    pub(super) fn attempt(&mut self, h: f64) -> Result<(), SystemError> {
        let (n, m) = (self.n, self.m);
        let tab = self.tab.stages();
        // predictor: the previous step's stage polynomials extrapolated
        // (element-wise: in two halves concurrently for large n)
        let par = n >= PARALLEL_MIN_COORDS;
        match self.extrapolated_step(h) {
            Some(hp) => {
                let w: [[f64; S]; S] =
                    std::array::from_fn(|i| self.tab.basis(1.0 + tab.c[i] * h / hp));
                let extrapolate = |_: usize, (out, p): ([&mut [f64]; S], [&[f64]; S])| {
                    for (out, w) in out.into_iter().zip(&w) {
                        for (k, o) in out.iter_mut().enumerate() {
                            *o = dot(w, |j| p[j][k]);
                        }
                    }
                };
                let a_prev: [&[f64]; S] = std::array::from_fn(|j| &self.a_prev[j][..n]);
                let a = self.a.each_mut().map(|a| &mut a[..n]);
                split_pass(par, n, (a, a_prev), extrapolate, |(), ()| ());
                let l_prev: [&[f64]; S] = std::array::from_fn(|j| &self.l_prev[j][..m]);
                let l = self.l.each_mut().map(|l| &mut l[..m]);
                split_pass(par, m, (l, l_prev), extrapolate, |(), ()| ());
            }
            None => {
                for i in 0..S {
                    self.a[i].copy_from_slice(&self.qdd);
                    self.l[i].copy_from_slice(&self.lam);
                }
            }
        }
        // the matrix of another step size is renewed (a step that differs
        // from the factorised one by the rounding of the grid's
        // arithmetic, `target − t`, is the same step: `SAME_STEP`)
        if self.renewal.at_predictor(h) {
            self.factor_at(h, middle::<S>())?;
        }
        // the constraint rows of each transformed system divided by h²μ²
        let g = tab.gamma;
        let inv_g = 1.0 / (h * h * g * g);
        let inv_d: Vec<[f64; 2]> = tab
            .mu
            .iter()
            .map(|mu| {
                let hmu = [h * mu[0], h * mu[1]];
                let d = cmul(hmu, hmu); // h²μ²
                let dd = d[0] * d[0] + d[1] * d[1];
                [d[0] / dd, -d[1] / dd]
            })
            .collect();
        let tol_q = self.opts.newton_tol * h * h;
        // adaptive: RADAU5's Newton tolerance where it is looser, the
        // fraction `fnewt = max(10 ε / rtol', min(0.03, √rtol'))` of the
        // error test's weights `(rtol'/rtol)(atol + rtol |q|)` (module
        // docs, "Step size")
        let ode = self.ode;
        let adaptive = self.opts.adaptive;
        let a2w = &tab.a2;
        let (fr, fa) = if adaptive {
            let rt = transformed_rtol::<S>(ode.rtol);
            let fnewt = newton_fraction::<S>(rt);
            (fnewt * rt, fnewt * rt / ode.rtol)
        } else {
            (0.0, 0.0)
        };
        // the first correction is judged with RADAU5's η₀ = max(η, ε)^0.8
        let eta0 = first_rate(self.eta);
        let limit = newton_limit::<S>(self.opts.max_newton);
        let mut conv = Convergence::with_first_rate(radau_convergence(limit), eta0);
        let mut its = 0usize;
        // whether `qst`, `vst` hold the stage states of the current `a`
        // (the update computes them for the next correction)
        let mut stages_current = false;
        loop {
            if self.renewal.before_correction(conv.round()) {
                self.factor_at(h, middle::<S>())?;
            }
            // residuals of the stages (their states in one pass, unless
            // the last update computed them)
            if !stages_current {
                self.stage_states(h);
            }
            for i in 0..S {
                self.stats.residual_evaluations += 1;
                let ti = self.t + tab.c[i] * h;
                self.sys.residual(
                    StateView {
                        t: ti,
                        q: &self.qst[i],
                        qd: &self.vst[i],
                    },
                    &self.a[i],
                    &self.l[i],
                    1.0,
                    &mut self.r[i],
                )?;
            }
            // transformed right-hand sides: x_k = −Σ_i T⁻¹_ki r_i, the
            // constraint rows divided by h²μ_k²; the coordinates and the
            // constraint rows each in their own two halves, in one
            // hand-over (each thread takes half of both, the same rows as
            // in the update below)
            let ti = &tab.t_inv;
            {
                let (x_q, x_l) = self.x.each_mut().map(|x| &mut x[..n + m]).halve(n);
                let (r_q, r_l) = self.r.each_ref().map(|r| &r[..n + m]).halve(n);
                let inv_d = &inv_d;
                let transform = |constraint: bool, (mut x, r): ([&mut [f64]; S], [&[f64]; S])| {
                    for k in 0..r[0].len() {
                        let rk: [f64; S] = std::array::from_fn(|i| r[i][k]);
                        for (xj, tj) in x.iter_mut().zip(ti) {
                            xj[k] = -dot(tj, |i| rk[i]);
                        }
                        if constraint {
                            x[0][k] *= inv_g;
                            for (p, d) in inv_d.iter().enumerate() {
                                let z = cmul([x[1 + 2 * p][k], x[2 + 2 * p][k]], *d);
                                x[1 + 2 * p][k] = z[0];
                                x[2 + 2 * p][k] = z[1];
                            }
                        }
                    }
                };
                split_passes(
                    par,
                    (n, (x_q, r_q), |_, d| transform(false, d)),
                    (m, (x_l, r_l), |_, d| transform(true, d)),
                    |(), ()| (),
                );
            }
            {
                let (x0, rest) = self.x.split_at_mut(1);
                self.sys.solve(self.t, &mut x0[0])?;
                for (c, pair) in self.cplx.iter_mut().zip(rest.chunks_exact_mut(2)) {
                    let (re, im) = pair.split_at_mut(1);
                    c.solve_complex(self.t, &mut re[0], &mut im[0])?;
                }
            }
            self.stats.newton_iterations += 1;
            its += 1;
            // back-transform, update, norm of the position-equivalent corrections
            let tt = &tab.t;
            let dnorm = {
                let x: [&[f64]; S] = std::array::from_fn(|j| &self.x[j][..n]);
                let av: [&mut [f64]; S] = self.a.each_mut().map(|a| &mut a[..n]);
                let (q, v) = (&self.q[..n], &self.v[..n]);
                let tol_factor = &self.tol_factor[..n];
                let qst: [&mut [f64]; S] = self.qst.each_mut().map(|x| &mut x[..n]);
                let vst: [&mut [f64]; S] = self.vst.each_mut().map(|x| &mut x[..n]);
                // the largest stage correction of each coordinate, then one
                // division (both monotone: the same max as dividing each);
                // then the next correction's stage states from the updated
                // stages (as `stage_states`, over the same half); in two halves
                // concurrently for large n (max: order-free), with the
                // multipliers' update
                type Rows<'a, const S: usize> = (
                    ([&'a mut [f64]; S], [&'a [f64]; S], &'a [f64]),
                    ([&'a mut [f64]; S], [&'a mut [f64]; S], &'a [f64]),
                );
                let update = |base: usize, ((av, x, q), (qst, vst, v)): Rows<'_, S>| {
                    let mut dnorm = 0.0_f64;
                    for k in 0..q.len() {
                        let y: [f64; S] = std::array::from_fn(|j| x[j][k]);
                        let d: [f64; S] = std::array::from_fn(|i| dot(&tt[i], |j| y[j]));
                        let mut big = (h * h * d[0]).abs();
                        av[0][k] += d[0];
                        for i in 1..S {
                            av[i][k] += d[i];
                            big = big.max((h * h * d[i]).abs());
                        }
                        let floor = ROUNDING_ULPS * f64::EPSILON * q[k].abs().max(1.0);
                        let mut ratio = big / (tol_q * tol_factor[base + k] + floor);
                        if adaptive {
                            // RADAU5's test on the stage position corrections
                            // ΔQ_i = h² Σ_j (𝔄²)_ij ΔA_j, where looser
                            let dq = |i: usize| (h * h * dot(&a2w[i], |j| d[j])).abs();
                            let big_q = (1..S).fold(dq(0), |b, i| b.max(dq(i)));
                            let atol = match &ode.atol {
                                Tolerance::Scalar(a) => *a,
                                Tolerance::Vector(v) => v[base + k],
                            };
                            ratio = ratio.min(big_q / (fa * atol + fr * q[k].abs() + floor));
                        }
                        dnorm = dnorm.max(ratio);
                    }
                    let av: [&[f64]; S] = av.map(|a| -> &[f64] { a });
                    let stages = 0..S;
                    stage_rows(
                        StageBase {
                            tab,
                            stages,
                            h,
                            q,
                            v,
                            st: av,
                        },
                        qst,
                        vst,
                    );
                    dnorm
                };
                let xl: [&[f64]; S] = std::array::from_fn(|j| &self.x[j][n..n + m]);
                let lv: [&mut [f64]; S] = self.l.each_mut().map(|l| &mut l[..m]);
                let update_l = |_: usize, (mut lv, xl): ([&mut [f64]; S], [&[f64]; S])| {
                    for k in 0..xl[0].len() {
                        let y: [f64; S] = std::array::from_fn(|j| xl[j][k]);
                        for (li, ti) in lv.iter_mut().zip(tt) {
                            li[k] += dot(ti, |j| y[j]);
                        }
                    }
                };
                // the coordinates' and the multipliers' updates in one
                // hand-over (each in its own two halves)
                split_passes(
                    par,
                    (n, ((av, x, q), (qst, vst, v)), update),
                    (m, (lv, xl), update_l),
                    f64::max,
                )
            };
            stages_current = true;
            if !dnorm.is_finite() {
                return Err(SystemError::msg("non-finite Newton correction"));
            }
            // stagnation with corrections at the noise of the solve
            // relative to q (module docs)
            let drel = || {
                let mut drel = 0.0_f64;
                for k in 0..n {
                    for row in tt {
                        let d = dot(row, |j| self.x[j][k]);
                        drel = drel.max((h * h * d).abs() / self.q[k].abs().max(1.0));
                    }
                }
                drel
            };
            let done = match conv.assess(dnorm, drel, false) {
                Assessment::Done => true,
                Assessment::NotYet => false,
                Assessment::RenewAfterUndo => {
                    // undo the diverging correction and renew the
                    // matrices at the last stage's iterate
                    for i in 0..S {
                        for k in 0..n + m {
                            let d = dot(&tt[i], |j| self.x[j][k]);
                            if k < n {
                                self.a[i][k] -= d;
                            } else {
                                self.l[i][k - n] -= d;
                            }
                        }
                    }
                    stages_current = false;
                    self.factor_at(h, S - 1)?;
                    continue;
                }
                Assessment::Diverged | Assessment::Hopeless | Assessment::Slow => {
                    return Err(SystemError::msg(format!(
                        "Newton diverges (contraction θ = {:.3}, correction {dnorm:.3e} × tol)",
                        conv.theta()
                    )));
                }
            };
            if conv.slow() {
                self.renewal.renew();
            }
            match conv.next(dnorm, done) {
                None => {
                    self.last_theta = Some(conv.theta()).filter(|th| its > 1 && th.is_finite());
                    match conv.rate_to_keep() {
                        Some(eta) => self.eta = eta,
                        // no rate measured: η₀ creeps back towards 1
                        None if its == 1 => self.eta = eta0,
                        None => {}
                    }
                    self.last_its = its;
                    return Ok(());
                }
                Some(Next::Iterate) => {}
                // still contracting: renew the matrices at the last stage's
                // (much better) iterate once and go on, as generalized-α
                Some(Next::Renew) => self.factor_at(h, S - 1)?,
                Some(Next::Exhausted) => {
                    return Err(SystemError::msg(format!(
                        "no convergence in {} iterations (last correction {:.3e} × tol)",
                        conv.round(),
                        conv.last()
                    )));
                }
            }
        }
    }
}
