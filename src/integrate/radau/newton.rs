//! The simplified Newton iteration of Radau IIA's stages (module docs of
//! [`super`], "Renewal"): the real and complex factorisations, the
//! predictor and the corrections under the one
//! [`Convergence`](super::super::implicit::Convergence) test.

use super::*;

/// `newton_tol` positive and finite, `max_newton` at least 1.
pub(super) fn check_newton_options(opts: &ImplicitOptions) -> Result<(), IntegratorError> {
    if !(opts.newton_tol > 0.0 && opts.newton_tol.is_finite()) {
        return Err(IntegratorError::InvalidOption {
            option: "newton_tol",
            value: opts.newton_tol.to_string(),
            reason: "must be positive and finite".into(),
        });
    }
    if opts.max_newton == 0 {
        return Err(IntegratorError::InvalidOption {
            option: "max_newton",
            value: "0".into(),
            reason: "must be at least 1".into(),
        });
    }
    Ok(())
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

impl Run<'_, '_> {
    /// Factorise the real and the complex matrix at the step's start.
    pub(super) fn factor(&mut self, h: f64) -> Result<(), SystemError> {
        self.factor_at(h, false)
    }

    /// Factorise the real and the complex matrix for the step `h` at its
    /// start (`at_end` false) or at the current iterate of its last stage
    /// `(Q₃, V₃, Λ₃)` (`at_end`; `qs`, `vs` are overwritten).
    pub(super) fn factor_at(&mut self, h: f64, at_end: bool) -> Result<(), SystemError> {
        let tab = self.tab;
        let (g, mu) = (tab.gamma, tab.mu);
        let hmu = [h * mu[0], h * mu[1]];
        let h2mu2 = cmul(hmu, hmu);
        self.renewal.factorising();
        if at_end {
            self.stage_state(2, h);
        }
        let (t, q, v, lam) = if at_end {
            (self.t + h, &self.qs, &self.vs, &self.l[2])
        } else {
            (self.t, &self.q, &self.v, &self.lam)
        };
        self.stats.factorizations += 1;
        self.sys
            .factorize(t, q, v, lam, [1.0, h * g, h * h * g * g])?;
        self.stats.complex_factorizations += 1;
        self.cplx
            .factorize_complex(t, q, v, lam, [[1.0, 0.0], hmu, h2mu2])?;
        self.renewal.factorised(h);
        Ok(())
    }

    /// One attempt of the step `h` from `(t, q, v)` into `a`, `l`.
    pub(super) fn attempt(&mut self, h: f64) -> Result<(), SystemError> {
        let (n, m) = (self.n, self.m);
        let tab = self.tab;
        // predictor: the previous step's stage polynomials extrapolated
        match self.h_prev {
            Some(hp) => {
                for i in 0..3 {
                    let w = tab.basis(1.0 + tab.c[i] * h / hp);
                    for (out, prev) in [
                        (&mut self.a[i], &self.a_prev),
                        (&mut self.l[i], &self.l_prev),
                    ] {
                        let len = out.len();
                        let (p0, p1, p2) = (&prev[0][..len], &prev[1][..len], &prev[2][..len]);
                        for k in 0..len {
                            out[k] = w[0] * p0[k] + w[1] * p1[k] + w[2] * p2[k];
                        }
                    }
                }
            }
            None => {
                for i in 0..3 {
                    self.a[i].copy_from_slice(&self.qdd);
                    self.l[i].copy_from_slice(&self.lam);
                }
            }
        }
        // the matrix of another step size is renewed (a step that differs
        // from the factorised one by the rounding of the grid's
        // arithmetic, `target − t`, is the same step: `SAME_STEP`)
        if self.renewal.at_predictor(h) {
            self.factor(h)?;
        }
        let (g, mu) = (tab.gamma, tab.mu);
        let hmu = [h * mu[0], h * mu[1]];
        let d = cmul(hmu, hmu); // h²μ²
        let dd = d[0] * d[0] + d[1] * d[1];
        let inv_d = [d[0] / dd, -d[1] / dd];
        let inv_g = 1.0 / (h * h * g * g);
        let tol_q = self.opts.newton_tol * h * h;
        // adaptive: RADAU5's Newton tolerance where it is looser, the
        // fraction `fnewt = max(10 ε / rtol', min(0.03, √rtol'))` of the
        // error test's weights `(rtol'/rtol)(atol + rtol |q|)` (module
        // docs, "Step size")
        let ode = self.ode;
        let adaptive = self.opts.adaptive;
        let a2w = tab.a2;
        let (fr, fa) = if adaptive {
            let rt = 0.1 * ode.rtol.powf(2.0 / 3.0);
            let fnewt = (10.0 * f64::EPSILON / rt).max(0.03f64.min(rt.sqrt()));
            (fnewt * rt, fnewt * rt / ode.rtol)
        } else {
            (0.0, 0.0)
        };
        // the first correction is judged with RADAU5's η₀ = max(η, ε)^0.8
        let eta0 = first_rate(self.eta);
        let mut conv = Convergence::with_first_rate(radau_convergence(self.opts.max_newton), eta0);
        let mut its = 0usize;
        loop {
            if self.renewal.before_correction(conv.round()) {
                self.factor(h)?;
            }
            // residuals of the three stages
            for i in 0..3 {
                self.stage_state(i, h);
                self.stats.residual_evaluations += 1;
                let ti = self.t + tab.c[i] * h;
                self.sys.residual(
                    ti,
                    &self.qs,
                    &self.vs,
                    &self.a[i],
                    &self.l[i],
                    1.0,
                    &mut self.r[i],
                )?;
            }
            // transformed right-hand sides: x_k = −Σ_i T⁻¹_ki r_i, the
            // constraint rows divided by h²μ_k²
            let ti = tab.t_inv;
            {
                let len = n + m;
                let (r0, r1, r2) = (&self.r[0][..len], &self.r[1][..len], &self.r[2][..len]);
                let [x0, x1, x2] = &mut self.x;
                let (x0, x1, x2) = (&mut x0[..len], &mut x1[..len], &mut x2[..len]);
                for k in 0..len {
                    let (a, b, c) = (r0[k], r1[k], r2[k]);
                    x0[k] = -(ti[0][0] * a + ti[0][1] * b + ti[0][2] * c);
                    x1[k] = -(ti[1][0] * a + ti[1][1] * b + ti[1][2] * c);
                    x2[k] = -(ti[2][0] * a + ti[2][1] * b + ti[2][2] * c);
                }
                for k in n..n + m {
                    x0[k] *= inv_g;
                    let z = cmul([x1[k], x2[k]], inv_d);
                    x1[k] = z[0];
                    x2[k] = z[1];
                }
            }
            self.sys.solve(self.t, &mut self.x[0])?;
            {
                let [_, x1, x2] = &mut self.x;
                self.cplx.solve_complex(self.t, x1, x2)?;
            }
            self.stats.newton_iterations += 1;
            its += 1;
            // back-transform, update, norm of the position-equivalent corrections
            let tt = tab.t;
            let mut dnorm = 0.0_f64;
            {
                let [x0, x1, x2] = &self.x;
                let [a0, a1, a2] = &mut self.a;
                let (a0, a1, a2) = (&mut a0[..n], &mut a1[..n], &mut a2[..n]);
                let q = &self.q[..n];
                let (z0, z1, z2) = (&x0[..n], &x1[..n], &x2[..n]);
                // the largest stage correction of each coordinate, then one
                // division (both monotone: the same max as dividing each)
                for k in 0..n {
                    let (y0, y1, y2) = (z0[k], z1[k], z2[k]);
                    let d0 = tt[0][0] * y0 + tt[0][1] * y1 + tt[0][2] * y2;
                    let d1 = tt[1][0] * y0 + tt[1][1] * y1 + tt[1][2] * y2;
                    let d2 = tt[2][0] * y0 + tt[2][1] * y1 + tt[2][2] * y2;
                    a0[k] += d0;
                    a1[k] += d1;
                    a2[k] += d2;
                    let big = (h * h * d0)
                        .abs()
                        .max((h * h * d1).abs())
                        .max((h * h * d2).abs());
                    let floor = ROUNDING_ULPS * f64::EPSILON * q[k].abs().max(1.0);
                    let mut ratio = big / (tol_q + floor);
                    if adaptive {
                        // RADAU5's test on the stage position corrections
                        // ΔQ_i = h² Σ_j (𝔄²)_ij ΔA_j, where looser
                        let dq = |r: [f64; 3]| (h * h * (r[0] * d0 + r[1] * d1 + r[2] * d2)).abs();
                        let big_q = dq(a2w[0]).max(dq(a2w[1])).max(dq(a2w[2]));
                        let atol = match &ode.atol {
                            Tolerance::Scalar(a) => *a,
                            Tolerance::Vector(v) => v[k],
                        };
                        ratio = ratio.min(big_q / (fa * atol + fr * q[k].abs() + floor));
                    }
                    dnorm = dnorm.max(ratio);
                }
                let [l0, l1, l2] = &mut self.l;
                for k in n..n + m {
                    let (y0, y1, y2) = (x0[k], x1[k], x2[k]);
                    l0[k - n] += tt[0][0] * y0 + tt[0][1] * y1 + tt[0][2] * y2;
                    l1[k - n] += tt[1][0] * y0 + tt[1][1] * y1 + tt[1][2] * y2;
                    l2[k - n] += tt[2][0] * y0 + tt[2][1] * y1 + tt[2][2] * y2;
                }
            }
            if !dnorm.is_finite() {
                return Err(SystemError::msg("non-finite Newton correction"));
            }
            // stagnation with corrections at the noise of the solve
            // relative to q (module docs)
            let drel = || {
                let [x0, x1, x2] = &self.x;
                let mut drel = 0.0_f64;
                for k in 0..n {
                    let (y0, y1, y2) = (x0[k], x1[k], x2[k]);
                    for row in &tab.t {
                        let d = row[0] * y0 + row[1] * y1 + row[2] * y2;
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
                    let tt = tab.t;
                    let [x0, x1, x2] = &self.x;
                    for (i, a) in self.a.iter_mut().enumerate() {
                        for k in 0..n {
                            a[k] -= tt[i][0] * x0[k] + tt[i][1] * x1[k] + tt[i][2] * x2[k];
                        }
                    }
                    for (i, l) in self.l.iter_mut().enumerate() {
                        for k in n..n + m {
                            l[k - n] -= tt[i][0] * x0[k] + tt[i][1] * x1[k] + tt[i][2] * x2[k];
                        }
                    }
                    self.factor_at(h, true)?;
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
                Some(Next::Renew) => self.factor_at(h, true)?,
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
