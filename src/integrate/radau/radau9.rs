//! Radau IIA of order 9 (S = 5 stages) on the index-3 equations of a
//! [`SecondOrderDae`], fixed step (docs/radau.md, "radau9").
//!
//! The same scheme as [`super::Radau5`] with five stages (Hairer & Wanner
//! II, §IV.5, §IV.8, §VII.4): stage accelerations `A_i` and multipliers
//! `Λ_i` at `t_n + c_i h`,
//!
//! ```text
//! Q_i = q_n + c_i h v_n + h² Σ_j (𝔄²)_ij A_j,     V_i = v_n + h Σ_j 𝔄_ij A_j
//! M A_i + Φ_qᵀ(Q_i) Λ_i − g(Q_i, V_i, t_i) = 0,    Φ(Q_i, t_i) = 0
//! ```
//!
//! stiffly accurate (`q_{n+1} = Q_5`, `v_{n+1} = V_5`). On index-3
//! problems the positions converge with order `2S − 1 = 9`, the
//! velocities with order `S = 5`, the multipliers with order `S − 1 = 4`
//! (Hairer, Lubich & Roche, LNM 1409, 1989); L-stable (the (4, 5) Padé
//! approximant of eᶻ).
//!
//! The simplified Newton system is split by the tableau's
//! `T⁻¹ 𝔄 T = diag(γ, [α₁ −β₁; β₁ α₁], [α₂ −β₂; β₂ α₂])`
//! ([`RadauStages`]) into one real system (`SecondOrderDae::factorize`
//! with `c = [1, hγ, h²γ²]`) and two complex ones
//! ([`ComplexNewton`] with `μ_p = α_p + iβ_p`), each
//! `[M + hμ C_t + h²μ² K_t, Φ_qᵀ; Φ_q, 0]` with the constraint rows
//! divided by `h²μ²`; the Jacobians frozen at the step's start and kept
//! across steps while Newton contracts, the predictor, the convergence
//! test, the renewals within an attempt, the start ramp and the fixed-step
//! grid are radau5's (its module docs). Dense output: the collocation
//! polynomials (`V` of degree 5, `Q` the quintic through `q_n` and the
//! `Q_i`), the rows projected onto `Φ = 0`
//! ([`SecondOrderDae::project_output`]).

use super::*;

/// Stages of [`Radau9`].
const S: usize = 5;

/// Radau IIA, S = 5, fixed step, on the index-3 equations (module docs).
#[derive(Debug, Clone)]
pub struct Radau9 {
    opts: ImplicitOptions,
    ode: OdeOptions,
    tab: RadauStages<S>,
    stats: ImplicitStats,
}

impl Radau9 {
    /// Validate the options: a fixed step ([`OdeOptions::fixed_step`]); of
    /// [`ImplicitOptions`] it reads `newton_tol`, `max_newton`, `reuse`,
    /// `project` and `min_step` (`adaptive` is an error: radau9 has fixed
    /// steps only).
    pub fn new(opts: ImplicitOptions, ode: OdeOptions) -> Result<Self, IntegratorError> {
        if opts.adaptive {
            return Err(IntegratorError::InvalidOption {
                option: "adaptive",
                value: "true".into(),
                reason: "radau9 takes fixed steps only (integrator.step)".into(),
            });
        }
        ode.validate(Method::Radau9, false)?;
        check_newton_options(&opts)?;
        Ok(Self {
            opts,
            ode,
            tab: RadauStages::new(),
            stats: ImplicitStats::default(),
        })
    }

    /// Counters of the last run (`complex_factorizations` counts both
    /// complex pairs).
    pub fn stats(&self) -> ImplicitStats {
        self.stats
    }

    /// Integrate from `(t0, q0, q̇0)` to `t_end`; `cplx` are two complex
    /// Newton matrices of the same system (one per complex pair of 𝔄).
    /// Outputs as [`Radau5::integrate`].
    #[allow(clippy::too_many_arguments)]
    pub fn integrate(
        &mut self,
        sys: &mut dyn SecondOrderDae,
        cplx: [&mut dyn ComplexNewton; 2],
        t0: f64,
        t_end: f64,
        q0: &[f64],
        qd0: &[f64],
        output_times: &[f64],
        obs: &mut dyn Observer,
    ) -> Result<Report, IntegratorError> {
        let (n, m) = (sys.n(), sys.m());
        validate_run(n, t0, t_end, q0, qd0, output_times, &self.ode, false)?;
        let h = self.ode.fixed_step.unwrap_or(0.0);
        let vn = || std::array::from_fn(|_| vec![0.0; n]);
        let vm = || std::array::from_fn(|_| vec![0.0; m]);
        let vnm = || std::array::from_fn(|_| vec![0.0; n + m]);
        let [c1, c2] = cplx;
        let mut run = StageRun {
            tab: &self.tab,
            opts: &self.opts,
            ode: &self.ode,
            sys,
            cplx: [c1, c2],
            n,
            m,
            t0,
            t_end,
            h_fixed: h,
            h,
            k_grid: 1,
            t: t0,
            q: q0.to_vec(),
            v: qd0.to_vec(),
            qdd: vec![0.0; n],
            lam: vec![0.0; m],
            q_old: q0.to_vec(),
            v_old: qd0.to_vec(),
            a: vn(),
            l: vm(),
            a_prev: vn(),
            l_prev: vm(),
            qs: vec![0.0; n],
            vs: vec![0.0; n],
            r: vnm(),
            x: vnm(),
            y: [q0, qd0].concat(),
            renewal: Renewal::new(RenewalOptions {
                band: SAME_STEP,
                across_attempts: self.opts.reuse,
                every_correction: !self.opts.reuse,
            }),
            eta: 1.0,
            h_last: 0.0,
            h_prev: None,
            stats: ImplicitStats::default(),
            warnings: Vec::new(),
            cuts: Cuts::new(CutRules {
                shrink: Shrink::Halve,
                warn: Warn::First,
                first_cause: false,
            }),
        };
        let (report, stats) = run_implicit(&mut run, output_times, self.ode.max_steps, t_end, obs);
        self.stats = stats;
        Ok(report)
    }
}

struct StageRun<'g, 's> {
    tab: &'g RadauStages<S>,
    opts: &'g ImplicitOptions,
    ode: &'g OdeOptions,
    sys: &'s mut dyn SecondOrderDae,
    cplx: [&'s mut dyn ComplexNewton; 2],
    n: usize,
    m: usize,
    t0: f64,
    t_end: f64,
    h_fixed: f64,
    h: f64,
    k_grid: u64,
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
    qdd: Vec<f64>,
    lam: Vec<f64>,
    /// State at the start of the last accepted step (dense output).
    q_old: Vec<f64>,
    v_old: Vec<f64>,
    /// Stage accelerations and multipliers of the current attempt.
    a: [Vec<f64>; S],
    l: [Vec<f64>; S],
    /// Those of the last accepted step (predictor, dense output).
    a_prev: [Vec<f64>; S],
    l_prev: [Vec<f64>; S],
    qs: Vec<f64>,
    vs: Vec<f64>,
    r: [Vec<f64>; S],
    x: [Vec<f64>; S],
    y: Vec<f64>,
    renewal: Renewal,
    eta: f64,
    h_last: f64,
    h_prev: Option<f64>,
    stats: ImplicitStats,
    warnings: Vec<String>,
    cuts: Cuts,
}

impl StageRun<'_, '_> {
    /// Stage i's position and velocity into `qs`, `vs`.
    fn stage_state(&mut self, i: usize, h: f64) {
        let tab = self.tab;
        let n = self.n;
        let (ch, a, a2) = (tab.c[i] * h, tab.a[i], tab.a2[i]);
        let (q, v) = (&self.q[..n], &self.v[..n]);
        let (qs, vs) = (&mut self.qs[..n], &mut self.vs[..n]);
        let st: [&[f64]; S] = std::array::from_fn(|j| &self.a[j][..n]);
        for k in 0..n {
            let (mut p, mut w) = (0.0, 0.0);
            for j in 0..S {
                p += a2[j] * st[j][k];
                w += a[j] * st[j][k];
            }
            qs[k] = q[k] + ch * v[k] + h * h * p;
            vs[k] = v[k] + h * w;
        }
    }

    /// Factorise the real and both complex matrices for the step `h` at its
    /// start (`at_end` false) or at the last stage's current iterate.
    fn factor_at(&mut self, h: f64, at_end: bool) -> Result<(), SystemError> {
        let tab = self.tab;
        let g = tab.gamma;
        self.renewal.factorising();
        if at_end {
            self.stage_state(S - 1, h);
        }
        let (t, q, v, lam) = if at_end {
            (self.t + h, &self.qs, &self.vs, &self.l[S - 1])
        } else {
            (self.t, &self.q, &self.v, &self.lam)
        };
        self.stats.factorizations += 1;
        self.sys
            .factorize(t, q, v, lam, [1.0, h * g, h * h * g * g])?;
        for (c, mu) in self.cplx.iter_mut().zip(&tab.mu) {
            let hmu = [h * mu[0], h * mu[1]];
            self.stats.complex_factorizations += 1;
            c.factorize_complex(t, q, v, lam, [[1.0, 0.0], hmu, cmul(hmu, hmu)])?;
        }
        self.renewal.factorised(h);
        Ok(())
    }

    /// One attempt of the step `h` from `(t, q, v)` into `a`, `l`.
    fn attempt(&mut self, h: f64) -> Result<(), SystemError> {
        let (n, m) = (self.n, self.m);
        let tab = self.tab;
        // predictor: the previous step's stage polynomials extrapolated
        match self.h_prev {
            Some(hp) => {
                for i in 0..S {
                    let w = tab.basis(1.0 + tab.c[i] * h / hp);
                    for (out, prev) in [
                        (&mut self.a[i], &self.a_prev),
                        (&mut self.l[i], &self.l_prev),
                    ] {
                        let len = out.len();
                        let p: [&[f64]; S] = std::array::from_fn(|j| &prev[j][..len]);
                        for k in 0..len {
                            out[k] = (0..S).map(|j| w[j] * p[j][k]).sum();
                        }
                    }
                }
            }
            None => {
                for i in 0..S {
                    self.a[i].copy_from_slice(&self.qdd);
                    self.l[i].copy_from_slice(&self.lam);
                }
            }
        }
        if self.renewal.at_predictor(h) {
            self.factor_at(h, false)?;
        }
        // the constraint rows of each transformed system divided by h²μ²
        let g = tab.gamma;
        let inv_g = 1.0 / (h * h * g * g);
        let inv_d: [C2; 2] = std::array::from_fn(|p| {
            let mu = tab.mu[p];
            let hmu = [h * mu[0], h * mu[1]];
            let d = cmul(hmu, hmu);
            let dd = d[0] * d[0] + d[1] * d[1];
            [d[0] / dd, -d[1] / dd]
        });
        let tol_q = self.opts.newton_tol * h * h;
        let eta0 = first_rate(self.eta);
        let mut conv = Convergence::with_first_rate(radau_convergence(self.opts.max_newton), eta0);
        let mut its = 0usize;
        loop {
            if self.renewal.before_correction(conv.round()) {
                self.factor_at(h, false)?;
            }
            for i in 0..S {
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
            // transformed right-hand sides x_k = −Σ_i T⁻¹_ki r_i
            let ti = tab.t_inv;
            {
                let len = n + m;
                let r: [&[f64]; S] = std::array::from_fn(|i| &self.r[i][..len]);
                let [x0, x1, x2, x3, x4] = &mut self.x;
                let (x0, x1, x2, x3, x4) = (
                    &mut x0[..len],
                    &mut x1[..len],
                    &mut x2[..len],
                    &mut x3[..len],
                    &mut x4[..len],
                );
                for k in 0..len {
                    let rk: [f64; S] = std::array::from_fn(|i| r[i][k]);
                    let y: [f64; S] =
                        std::array::from_fn(|j| -(0..S).map(|i| ti[j][i] * rk[i]).sum::<f64>());
                    x0[k] = y[0];
                    x1[k] = y[1];
                    x2[k] = y[2];
                    x3[k] = y[3];
                    x4[k] = y[4];
                }
                for k in n..len {
                    x0[k] *= inv_g;
                    let z = cmul([x1[k], x2[k]], inv_d[0]);
                    x1[k] = z[0];
                    x2[k] = z[1];
                    let z = cmul([x3[k], x4[k]], inv_d[1]);
                    x3[k] = z[0];
                    x4[k] = z[1];
                }
            }
            {
                let [x0, x1, x2, x3, x4] = &mut self.x;
                self.sys.solve(self.t, x0)?;
                let [c1, c2] = &mut self.cplx;
                c1.solve_complex(self.t, x1, x2)?;
                c2.solve_complex(self.t, x3, x4)?;
            }
            self.stats.newton_iterations += 1;
            its += 1;
            // back-transform, update, norm of the position corrections
            let tt = tab.t;
            let mut dnorm = 0.0_f64;
            {
                let x: [&[f64]; S] = std::array::from_fn(|j| &self.x[j][..n + m]);
                let q = &self.q[..n];
                for i in 0..S {
                    let row = tt[i];
                    let ai = &mut self.a[i][..n];
                    for k in 0..n {
                        let d: f64 = (0..S).map(|j| row[j] * x[j][k]).sum();
                        ai[k] += d;
                        let w = tol_q + ROUNDING_ULPS * f64::EPSILON * q[k].abs().max(1.0);
                        dnorm = dnorm.max((h * h * d).abs() / w);
                    }
                    let li = &mut self.l[i][..m];
                    for k in 0..m {
                        li[k] += (0..S).map(|j| row[j] * x[j][n + k]).sum::<f64>();
                    }
                }
            }
            if !dnorm.is_finite() {
                return Err(SystemError::msg("non-finite Newton correction"));
            }
            let drel = || {
                let mut drel = 0.0_f64;
                for k in 0..n {
                    for row in &tt {
                        let d: f64 = (0..S).map(|j| row[j] * self.x[j][k]).sum();
                        drel = drel.max((h * h * d).abs() / self.q[k].abs().max(1.0));
                    }
                }
                drel
            };
            let done = match conv.assess(dnorm, drel, false) {
                Assessment::Done => true,
                Assessment::NotYet => false,
                Assessment::RenewAfterUndo => {
                    for i in 0..S {
                        let row = tt[i];
                        for k in 0..n + m {
                            let d: f64 = (0..S).map(|j| row[j] * self.x[j][k]).sum();
                            if k < n {
                                self.a[i][k] -= d;
                            } else {
                                self.l[i][k - n] -= d;
                            }
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
                        None if its == 1 => self.eta = eta0,
                        None => {}
                    }
                    return Ok(());
                }
                Some(Next::Iterate) => {}
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

/// A complex number `[re, im]`.
type C2 = [f64; 2];

impl ImplicitStepper for StageRun<'_, '_> {
    fn books(&mut self) -> (&mut ImplicitStats, &mut Vec<String>) {
        (&mut self.stats, &mut self.warnings)
    }
    fn newton_attempt(&mut self, _t_new: f64, h: f64) -> Result<(), SystemError> {
        self.attempt(h)
    }
    fn renewal(&mut self) -> &mut Renewal {
        &mut self.renewal
    }
    fn cuts(&mut self) -> &mut Cuts {
        &mut self.cuts
    }
}

impl Stepper for StageRun<'_, '_> {
    fn start(&mut self) -> Result<(), Failure> {
        self.stats.residual_evaluations += 1;
        self.sys
            .accelerations(self.t0, &self.q, &self.v, &mut self.qdd, &mut self.lam)
            .map_err(|e| Failure::System {
                what: "initial accelerations",
                t: self.t0,
                step_from: None,
                source: Arc::new(e),
            })?;
        // ramp up from the first-step guess, as radau5
        let guess = common::initial_step_from_accelerations(
            &self.qdd[..self.n],
            |i| {
                let atol = match &self.ode.atol {
                    Tolerance::Scalar(a) => *a,
                    Tolerance::Vector(v) => v[i],
                };
                atol + self.ode.rtol * self.q[i].abs()
            },
            self.t_end - self.t0,
        );
        self.h = guess.min(self.h_fixed);
        Ok(())
    }

    fn step(&mut self) -> Result<bool, Failure> {
        let n = self.n;
        loop {
            let target = (self.t0 + self.k_grid as f64 * self.h_fixed).min(self.t_end);
            let x = step_try(
                self.t,
                self.h,
                target,
                self.h_fixed,
                self.t_end,
                self.opts,
                &self.cuts,
            )?;
            let (h, t_new) = (x.h, x.t_new);
            if let Attempted::Cut(h) = attempt_or_cut(self, x)? {
                self.h = h;
                continue;
            }
            let h_next = (2.0 * h).min(self.h_fixed);
            // accept: stiffly accurate, the last stage is the step's end
            self.q_old.copy_from_slice(&self.q);
            self.v_old.copy_from_slice(&self.v);
            self.stage_state(S - 1, h);
            self.q.copy_from_slice(&self.qs);
            self.v.copy_from_slice(&self.vs);
            self.qdd.copy_from_slice(&self.a[S - 1]);
            self.lam.copy_from_slice(&self.l[S - 1]);
            if self.opts.project {
                self.stats.projections += 1;
                let (q, v) = (&mut self.q, &mut self.v);
                self.sys.project(t_new, q, v).map_err(|e| Failure::System {
                    what: "projection",
                    t: t_new,
                    step_from: Some(self.t),
                    source: Arc::new(e),
                })?;
            }
            std::mem::swap(&mut self.a_prev, &mut self.a);
            std::mem::swap(&mut self.l_prev, &mut self.l);
            self.h_prev = Some(h);
            self.h_last = h;
            self.t = t_new;
            self.stats.accept(h);
            self.y[..n].copy_from_slice(&self.q);
            self.y[n..].copy_from_slice(&self.v);
            if (self.t - target).abs() <= 1e-9 * self.h_fixed || self.t >= target {
                self.k_grid += 1;
            }
            self.h = h_next;
            return Ok(self.t >= self.t_end);
        }
    }

    fn state(&self) -> (f64, &[f64]) {
        (self.t, &self.y)
    }

    /// The collocation polynomials of the last step.
    fn interpolate(&self, t: f64, out: &mut [f64]) {
        let (n, h) = (self.n, self.h_last);
        let th = (t - (self.t - h)) / h;
        let w1 = self.tab.basis_integral(th);
        // Q: the polynomial of degree S through q_old (τ = 0) and the
        // stage positions Q_i at c_i
        let c = self.tab.c;
        let node = |k: usize| if k == 0 { 0.0 } else { c[k - 1] };
        let li: [f64; S] = std::array::from_fn(|i| {
            (0..=S)
                .filter(|&k| k != i + 1)
                .map(|k| (th - node(k)) / (c[i] - node(k)))
                .product::<f64>()
        });
        let a2 = self.tab.a2;
        let w2: [f64; S] = std::array::from_fn(|j| (0..S).map(|i| li[i] * a2[i][j]).sum());
        let a = &self.a_prev;
        for k in 0..n {
            let (mut p, mut w) = (0.0, 0.0);
            for j in 0..S {
                p += w2[j] * a[j][k];
                w += w1[j] * a[j][k];
            }
            out[k] = self.q_old[k] + th * h * self.v_old[k] + h * h * p;
            out[n + k] = self.v_old[k] + h * w;
        }
    }

    fn output_snap(&self) -> f64 {
        1e-9 * self.h_last
    }

    fn settle(&mut self, t: f64, out: &mut [f64]) {
        settle_output(self.sys, t, out, &mut self.warnings);
    }

    fn warnings(&self) -> &[String] {
        &self.warnings
    }

    fn stats(&self) -> Stats {
        self.stats.counts()
    }
}
