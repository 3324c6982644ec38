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
/// rad a body with `ρ` ≪ 1 m would have its angle held to a test `1/ρ`
/// times tighter than its translations (docs/scaling.md, "radau5's Newton
/// test with angles at the radius of gyration").
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
                let scale = (inv_g, &inv_d[..]);
                let transform = |constraint: bool, (x, r): ([&mut [f64]; S], [&[f64]; S])| {
                    transform_rows(x, r, ti, constraint.then_some(scale));
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
                let norm = Norm {
                    h,
                    tt,
                    tol_q,
                    tol_factor,
                    adaptive: adaptive.then_some((a2w, fr, fa, &ode.atol)),
                };
                let update = |base: usize, ((mut av, x, q), (qst, vst, v)): Rows<'_, S>| {
                    let dnorm = update_rows(&norm, base, &mut av, x, q);
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
                let update_l = |_: usize, (lv, xl): ([&mut [f64]; S], [&[f64]; S])| {
                    update_multipliers(lv, xl, tt);
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

/// Rows of an element-wise pass computed together: one vector of AVX
/// (or two of SSE2) per stage and coordinate.
const LANES: usize = 4;

/// An element-wise pass over rows, done `L` rows at a time: each row's
/// operations as written, in the row's own lane, so the bits are those
/// of a plain loop over the rows.
trait Blocks {
    /// Rows `k .. k + L`.
    fn block<const L: usize>(&mut self, k: usize);
}

/// `pass` over rows `0..len` in blocks of [`LANES`], then the rest one
/// by one, compiled for AVX where the processor has it
/// ([`crate::numeric::with_avx`]).
#[inline(always)]
fn in_blocks(len: usize, pass: &mut impl Blocks) {
    crate::numeric::with_avx(|| {
        let full = len - len % LANES;
        for k in (0..full).step_by(LANES) {
            pass.block::<LANES>(k);
        }
        for k in full..len {
            pass.block::<1>(k);
        }
    })
}

/// Rows `k .. k + L` of each slice as arrays (one bounds check each).
#[inline(always)]
fn rows_at<const S: usize, const L: usize>(v: &[&[f64]; S], k: usize) -> [[f64; L]; S] {
    std::array::from_fn(|i| v[i][k..k + L].try_into().expect("L rows"))
}

/// Rows `k .. k + L` of `v` as an array to write (one bounds check).
#[inline(always)]
fn rows_mut<const L: usize>(v: &mut [f64], k: usize) -> &mut [f64; L] {
    (&mut v[k..k + L]).try_into().expect("L rows")
}

/// The transformed right-hand sides of one kind of rows (module docs of
/// [`super`], "Simplified Newton"): `x_j = −Σ_i (T⁻¹)_ji r_i` for each
/// row, and with `scale = Some((1/(h²γ²), [1/(h²μ_p²)]))` (the constraint
/// rows) `x_0` times the first and each complex pair `(x_{2p+1},
/// x_{2p+2})` times the second's entry `p`; in blocks of rows
/// ([`in_blocks`]).
fn transform_rows<const S: usize>(
    x: [&mut [f64]; S],
    r: [&[f64]; S],
    ti: &[[f64; S]; S],
    scale: Option<(f64, &[[f64; 2]])>,
) {
    let len = r[0].len();
    in_blocks(len, &mut Transform { x, r, ti, scale });
}

/// The pass of [`transform_rows`].
struct Transform<'a, const S: usize> {
    x: [&'a mut [f64]; S],
    r: [&'a [f64]; S],
    ti: &'a [[f64; S]; S],
    scale: Option<(f64, &'a [[f64; 2]])>,
}

impl<const S: usize> Blocks for Transform<'_, S> {
    #[inline(always)]
    fn block<const L: usize>(&mut self, k: usize) {
        let rk: [[f64; L]; S] = rows_at(&self.r, k);
        let ti = self.ti;
        let mut out: [[f64; L]; S] =
            std::array::from_fn(|j| std::array::from_fn(|l| -dot(&ti[j], |i| rk[i][l])));
        if let Some((inv_g, inv_d)) = self.scale {
            for o in &mut out[0] {
                *o *= inv_g;
            }
            for (p, d) in inv_d.iter().enumerate() {
                for l in 0..L {
                    let z = cmul([out[1 + 2 * p][l], out[2 + 2 * p][l]], *d);
                    out[1 + 2 * p][l] = z[0];
                    out[2 + 2 * p][l] = z[1];
                }
            }
        }
        for (xj, o) in self.x.iter_mut().zip(&out) {
            *rows_mut(xj, k) = *o;
        }
    }
}

/// What the correction norm of [`update_rows`] needs: the step `h`, the
/// back-transformation `T`, the position tolerance `h² newton_tol`, its
/// factor per coordinate ([`tolerance_factors`], indexed from 0 over all
/// coordinates), and for adaptive steps RADAU5's test ((𝔄²), the
/// fractions `fr`, `fa` of `rtol` and `atol`, `atol`).
pub(super) struct Norm<'a, const S: usize> {
    pub(super) h: f64,
    pub(super) tt: &'a [[f64; S]; S],
    pub(super) tol_q: f64,
    pub(super) tol_factor: &'a [f64],
    pub(super) adaptive: Option<(&'a [[f64; S]; S], f64, f64, &'a Tolerance)>,
}

/// The back-transformed corrections `ΔA_i = Σ_j T_ij x_j` added to the
/// stages `av` of coordinates `base ..` (rows of `x`, `q`), and the
/// largest of each coordinate's `max_i |h² ΔA_i| / (h² newton_tol f_k +
/// floor)` (`f_k` of [`tolerance_factors`]) (floor: [`ROUNDING_ULPS`] of `q`), for adaptive steps the
/// smaller of that and RADAU5's `max_i |ΔQ_i| / (fa atol + fr |q| +
/// floor)` with `ΔQ_i = h² Σ_j (𝔄²)_ij ΔA_j`. In blocks of rows
/// ([`in_blocks`]); a maximum per lane, then over the lanes (the same
/// maximum in any order).
fn update_rows<const S: usize>(
    norm: &Norm<'_, S>,
    base: usize,
    av: &mut [&mut [f64]; S],
    x: [&[f64]; S],
    q: &[f64],
) -> f64 {
    let mut pass = Update {
        norm,
        base,
        av,
        x,
        q,
        dnorm: [0.0; LANES],
    };
    in_blocks(q.len(), &mut pass);
    pass.dnorm.into_iter().fold(0.0, f64::max)
}

/// The pass of [`update_rows`], with its maximum per lane.
struct Update<'a, 'b, const S: usize> {
    norm: &'a Norm<'a, S>,
    base: usize,
    av: &'a mut [&'b mut [f64]; S],
    x: [&'a [f64]; S],
    q: &'a [f64],
    dnorm: [f64; LANES],
}

impl<const S: usize> Blocks for Update<'_, '_, S> {
    #[inline(always)]
    fn block<const L: usize>(&mut self, k: usize) {
        let Norm {
            h,
            tt,
            tol_q,
            tol_factor,
            ..
        } = *self.norm;
        let y: [[f64; L]; S] = rows_at(&self.x, k);
        let q: [f64; L] = rows_at(&[self.q], k)[0];
        let d: [[f64; L]; S] =
            std::array::from_fn(|i| std::array::from_fn(|l| dot(&tt[i], |j| y[j][l])));
        let mut big: [f64; L] = std::array::from_fn(|l| (h * h * d[0][l]).abs());
        for (i, a) in self.av.iter_mut().enumerate() {
            let a = rows_mut::<L>(a, k);
            for l in 0..L {
                a[l] += d[i][l];
                if i > 0 {
                    big[l] = big[l].max((h * h * d[i][l]).abs());
                }
            }
        }
        for l in 0..L {
            let floor = ROUNDING_ULPS * f64::EPSILON * q[l].abs().max(1.0);
            let mut ratio = big[l] / (tol_q * tol_factor[self.base + k + l] + floor);
            if let Some((a2w, fr, fa, atol)) = self.norm.adaptive {
                // RADAU5's test on the stage position corrections
                // ΔQ_i = h² Σ_j (𝔄²)_ij ΔA_j, where looser
                let dq = |i: usize| (h * h * dot(&a2w[i], |j| d[j][l])).abs();
                let big_q = (1..S).fold(dq(0), |b, i| b.max(dq(i)));
                let atol = match atol {
                    Tolerance::Scalar(a) => *a,
                    Tolerance::Vector(v) => v[self.base + k + l],
                };
                ratio = ratio.min(big_q / (fa * atol + fr * q[l].abs() + floor));
            }
            self.dnorm[l] = self.dnorm[l].max(ratio);
        }
    }
}

/// The multipliers' corrections `ΔΛ_i = Σ_j T_ij x_j` added to the stages
/// `lv`, in blocks of rows ([`in_blocks`]).
fn update_multipliers<const S: usize>(lv: [&mut [f64]; S], xl: [&[f64]; S], tt: &[[f64; S]; S]) {
    let len = xl[0].len();
    in_blocks(len, &mut Multipliers { lv, xl, tt });
}

/// The pass of [`update_multipliers`].
struct Multipliers<'a, const S: usize> {
    lv: [&'a mut [f64]; S],
    xl: [&'a [f64]; S],
    tt: &'a [[f64; S]; S],
}

impl<const S: usize> Blocks for Multipliers<'_, S> {
    #[inline(always)]
    fn block<const L: usize>(&mut self, k: usize) {
        let y: [[f64; L]; S] = rows_at(&self.xl, k);
        for (li, ti) in self.lv.iter_mut().zip(self.tt) {
            let li = rows_mut::<L>(li, k);
            for l in 0..L {
                li[l] += dot(ti, |j| y[j][l]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::BASELINE;

    /// The Newton passes in blocks of rows (with AVX where the processor
    /// has it, and held to the baseline build) give the bits of their
    /// formulas evaluated one row at a time, left to right: the
    /// transformed right-hand sides with and without the constraint
    /// rows' scaling, the stage and multiplier updates, and the norm with
    /// and without RADAU5's adaptive test (a tolerance per coordinate),
    /// for three and five stages and 37 rows (blocks and a rest).
    #[test]
    fn the_newton_passes_give_the_bits_of_the_formulas() {
        fn check<const S: usize>(baseline: bool) {
            BASELINE.set(baseline);
            let tab = RadauStages::<S>::new();
            let n = 37;
            let x = |i: usize| (i as f64 * 0.754_877_666_246_692_7).fract() - 0.5;
            let vecs = |s: usize, f: f64| -> [Vec<f64>; S] {
                std::array::from_fn(|j| (0..n).map(|k| f * x(k + s * (j + 1))).collect())
            };
            let (r, xs, a0) = (vecs(211, 1e2), vecs(307, 1e-3), vecs(401, 10.0));
            let q: Vec<f64> = (0..n).map(|k| 3.0 * x(k + 13)).collect();
            let (h, inv_g) = (3.7e-4, 0.37);
            let inv_d: Vec<[f64; 2]> = (0..(S - 1) / 2).map(|p| [1.5 + p as f64, -0.25]).collect();
            let bits = |v: f64| v.to_bits();
            // the transformation, plain and scaled
            for scale in [None, Some((inv_g, &inv_d[..]))] {
                let mut out: [Vec<f64>; S] = std::array::from_fn(|_| vec![0.0; n]);
                transform_rows(
                    out.each_mut().map(|o| &mut o[..]),
                    r.each_ref().map(|r| &r[..]),
                    &tab.t_inv,
                    scale,
                );
                for k in 0..n {
                    let mut want: [f64; S] = std::array::from_fn(|j| {
                        let mut s = tab.t_inv[j][0] * r[0][k];
                        for i in 1..S {
                            s += tab.t_inv[j][i] * r[i][k];
                        }
                        -s
                    });
                    if scale.is_some() {
                        want[0] *= inv_g;
                        for (p, d) in inv_d.iter().enumerate() {
                            let (a, b) = (want[1 + 2 * p], want[2 + 2 * p]);
                            want[1 + 2 * p] = a * d[0] - b * d[1];
                            want[2 + 2 * p] = a * d[1] + b * d[0];
                        }
                    }
                    for j in 0..S {
                        assert_eq!(bits(out[j][k]), bits(want[j]), "x_{j}[{k}] ({scale:?})");
                    }
                }
            }
            // the updates and the norm, fixed and adaptive steps
            let atol = Tolerance::Vector((0..n).map(|k| 1e-6 * (1.0 + x(k + 5))).collect());
            let f: Vec<f64> = (0..n).map(|k| 1.0 + 100.0 * x(k + 29).abs()).collect();
            for adaptive in [None, Some((&tab.a2, 2e-3, 0.7, &atol))] {
                let norm = Norm {
                    h,
                    tt: &tab.t,
                    tol_q: h * h,
                    tol_factor: &f,
                    adaptive,
                };
                let mut av = a0.clone();
                let dnorm = update_rows(
                    &norm,
                    0,
                    &mut av.each_mut().map(|a| &mut a[..]),
                    xs.each_ref().map(|x| &x[..]),
                    &q,
                );
                let mut lv = a0.clone();
                update_multipliers(
                    lv.each_mut().map(|l| &mut l[..]),
                    xs.each_ref().map(|x| &x[..]),
                    &tab.t,
                );
                let mut want_norm = 0.0_f64;
                for k in 0..n {
                    let d: [f64; S] = std::array::from_fn(|i| {
                        let mut s = tab.t[i][0] * xs[0][k];
                        for j in 1..S {
                            s += tab.t[i][j] * xs[j][k];
                        }
                        s
                    });
                    let mut big = 0.0_f64;
                    for i in 0..S {
                        assert_eq!(bits(av[i][k]), bits(a0[i][k] + d[i]), "A_{i}[{k}]");
                        assert_eq!(bits(lv[i][k]), bits(a0[i][k] + d[i]), "Λ_{i}[{k}]");
                        big = big.max((h * h * d[i]).abs());
                    }
                    let floor = ROUNDING_ULPS * f64::EPSILON * q[k].abs().max(1.0);
                    let mut ratio = big / (h * h * f[k] + floor);
                    if adaptive.is_some() {
                        let mut big_q = 0.0_f64;
                        for i in 0..S {
                            let mut s = tab.a2[i][0] * d[0];
                            for j in 1..S {
                                s += tab.a2[i][j] * d[j];
                            }
                            big_q = big_q.max((h * h * s).abs());
                        }
                        let Tolerance::Vector(a) = &atol else {
                            unreachable!()
                        };
                        ratio = ratio.min(big_q / (0.7 * a[k] + 2e-3 * q[k].abs() + floor));
                    }
                    want_norm = want_norm.max(ratio);
                }
                assert_eq!(
                    bits(dnorm),
                    bits(want_norm),
                    "norm ({})",
                    adaptive.is_some()
                );
            }
            BASELINE.set(false);
        }
        for baseline in [false, true] {
            check::<3>(baseline);
            check::<5>(baseline);
        }
    }
}
