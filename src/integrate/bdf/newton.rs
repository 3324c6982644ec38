//! The predictor and the Newton iteration of a BDF step (module docs of
//! [`super`]): ode15s's convergence test on the error test's norm of q,
//! the predictor and history sums in one pass (`predict`), each
//! correction's update in one pass (`newton_update`).

use super::super::implicit::{Assessment, Convergence, ConvergenceOptions, Next, Remainder};
use super::*;
use crate::parallel::{in_halves, split_passes, Slices};

impl BdfRun<'_> {
    pub(super) fn factor(&mut self, t1: f64, a0: f64) -> Result<(), SystemError> {
        self.stats.factorizations += 1;
        self.renewal.factorising();
        self.sys.factorize(
            StateView {
                t: t1,
                q: &self.q,
                qd: &self.v,
            },
            &self.lam_new,
            [1.0, 1.0 / a0, 1.0 / (a0 * a0)],
        )?;
        self.renewal.factorised(a0);
        self.rate = None;
        Ok(())
    }

    /// Predictor and Newton for the step to `t1` at order `k` (module docs).
    pub(super) fn attempt(&mut self, t1: f64, h: f64) -> Result<(), SystemError> {
        let (n, k) = (self.n, self.k);
        let mut nodes = [0.0; MAX_ORDER + 2];
        let mut a = [0.0; MAX_ORDER + 2];
        nodes[0] = t1;
        for j in 0..k {
            nodes[j + 1] = self.ts[j];
        }
        bdf_coefficients(&nodes[..k + 1], &mut a[..k + 1]);
        // NDF: ẏ ≈ Σ_j a_j y_{n+1−j} − (κγ/h)(y_{n+1} − ŷ), with ŷ the
        // predictor, a polynomial in the history: a_0 → a_0 − κγ/h and the
        // history sums gain (κγ/h)·ŷ
        let g = if self.ndf { ndf_shift(k) / h } else { 0.0 };
        let a0 = a[0] - g;
        // predictor ŷ = Σ_j cp_j y_j over the last `np` accepted points (at
        // the first step y_0 + h ẏ_0); history sums r = Σ_j cr_j y_j (+ g h ẏ_0)
        let first = self.ts.len() == 1;
        let mut cp = [0.0; MAX_ORDER + 2];
        let np = if first {
            cp[0] = 1.0;
            1
        } else {
            let np = (k + 1).min(self.ts.len());
            let mut past = [0.0; MAX_ORDER + 2];
            for (pj, tj) in past.iter_mut().zip(&self.ts).take(np) {
                *pj = *tj;
            }
            lagrange(&past[..np], t1, &mut cp[..np]);
            np
        };
        let mut cr = [0.0; MAX_ORDER + 2];
        let nh = np.max(k);
        for j in 0..nh {
            cr[j] = if j < k { a[j + 1] } else { 0.0 } + g * cp[j];
        }
        let mut hist: [&[f64]; MAX_ORDER + 2] = [&[]; MAX_ORDER + 2];
        for (hj, y) in hist.iter_mut().zip(&self.ys).take(nh) {
            *hj = y;
        }
        let src = PredictIn {
            n,
            hist: &hist[..nh],
            cr: &cr[..nh],
            cp: &cp[..nh],
            first: first.then_some((&self.f0[..], h, g * h)),
            threshold: &self.threshold,
            a0,
        };
        in_halves(
            n >= PARALLEL_MIN_COORDS,
            n,
            Slices {
                base: 0,
                w: [
                    &mut self.q,
                    &mut self.v,
                    &mut self.qdd,
                    &mut self.rq,
                    &mut self.rv,
                    &mut self.inv_w,
                ],
                r: [],
            },
            |o| predict(o, &src),
            |(), ()| (),
        );
        self.lam_new.copy_from_slice(&self.lam);
        if self.renewal.at_predictor(a0) {
            self.factor(t1, a0)?;
        }
        let s = 1.0 / (a0 * a0);
        // a position error δ makes a velocity error a_0 δ, which the error
        // test weighs as h·a_0·δ (`BdfRun::step_end`): one factor on the q-norm
        let vfac = (a0 * h).max(1.0);
        let floor = ROUNDING_ULPS * f64::EPSILON;
        // ode15s's test (Shampine & Reichelt 1997) with the rate kept on
        // this matrix
        let mut conv = Convergence::with_rate(
            ConvergenceOptions {
                remainder: Remainder::Ode15s {
                    tol: NEWTON_KAPPA * self.rtol,
                    tol_first: NEWTON_KAPPA_FIRST * self.rtol,
                    first_rate: THETA_FIRST,
                    diverge_above: DIVERGE_ABOVE,
                },
                max_iterations: MAX_NEWTON,
                renew_when_exhausted: false,
                renew_on_divergence: false,
                reset_rate_on_renewal: false,
            },
            self.rate,
        );
        loop {
            self.stats.residual_evaluations += 1;
            self.sys.residual(
                StateView {
                    t: t1,
                    q: &self.q,
                    qd: &self.v,
                },
                &self.qdd,
                &self.lam_new,
                s,
                &mut self.r,
            )?;
            // solving for r (not −r) gives −Δ, the correction negated
            // exactly (the solve is linear and rounds symmetrically):
            // subtracted below, the same bits as adding Δ
            self.sys.solve(t1, &mut self.r)?;
            self.stats.newton_iterations += 1;
            // q += Δq, with q̇ and q̈ from it, the error test's norm of Δq
            // (velocities through `vfac`) and the rounding floor of q: one
            // pass, in two fixed halves concurrently for large n
            // λ −= Δλ/s in the same hand-over (each in its own two halves)
            let (dq, dl) = self.r.split_at(n);
            let (mut dnorm, at_floor) = split_passes(
                n >= PARALLEL_MIN_COORDS,
                (
                    n,
                    Slices {
                        base: 0,
                        w: [&mut self.q, &mut self.v, &mut self.qdd],
                        r: [dq, &self.inv_w, &self.rq, &self.rv],
                    },
                    |_, u| newton_update(u, a0, floor),
                ),
                (
                    dl.len(),
                    Slices {
                        base: 0,
                        w: [&mut self.lam_new],
                        r: [dl],
                    },
                    |_, u| {
                        let ([l], [d]) = (u.w, u.r);
                        for (l, d) in l.iter_mut().zip(d) {
                            *l -= d / s;
                        }
                    },
                ),
                |(n0, f0), (n1, f1)| (n0.max(n1), f0 && f1),
            );
            dnorm *= vfac;
            if !dnorm.is_finite() {
                return Err(SystemError::msg("non-finite Newton correction"));
            }
            // a correction at the rounding floor of q, or below
            // NEWTON_FLOOR·rtol, ends the iteration
            let accept = at_floor || dnorm <= NEWTON_FLOOR * self.rtol;
            let verdict = conv.assess(dnorm, || 0.0, accept);
            self.rate = conv.rate();
            let theta = conv.theta();
            let why = match verdict {
                Assessment::Done => {
                    if conv.slow() {
                        self.renewal.renew();
                    }
                    return Ok(());
                }
                Assessment::NotYet if conv.next(dnorm, false) != Some(Next::Exhausted) => continue,
                Assessment::Diverged => format!(
                    "Newton contracts too slowly (θ = {theta:.3}, correction {dnorm:.3e} of the weights)"
                ),
                _ => format!(
                    "no convergence in {MAX_NEWTON} iterations expected (correction {dnorm:.3e} of the weights, θ = {theta:.3})"
                ),
            };
            return Err(SystemError::msg(why));
        }
    }
}

/// What the predictor pass reads: the history points `hist` (newest
/// first, each `[q; q̇]` of length `2n`), the predictor's and the history
/// sums' coefficients per point, at the first step `(ẏ_0, h, κγ)` for the
/// Euler predictor and the NDF term, the weights' thresholds and `a_0`.
struct PredictIn<'a> {
    n: usize,
    hist: &'a [&'a [f64]],
    cr: &'a [f64],
    cp: &'a [f64],
    first: Option<(&'a [f64], f64, f64)>,
    threshold: &'a [f64],
    a0: f64,
}

/// The predictor of a BDF step and everything Newton needs from the
/// history, in one pass over the coordinates (module docs): `q = ŷ =
/// Σ_j cp_j q_j` (+ `h q̇_0` at the first step), the history sums
/// `r_q = Σ_j cr_j q_j`, `r_v = Σ_j cr_j q̇_j` (+ `κγ h ẏ_0` at the first
/// step), `q̇ = a₀ q + r_q`, `q̈ = a₀ q̇ + r_v` and the Newton norm's
/// inverse weights `1/max(|q_n|, |ŷ|, thr)`, into `o.w = [q, q̇, q̈, r_q,
/// r_v, w]`. Element by element, so the split into halves
/// ([`in_halves`]) changes no bit.
fn predict(o: Slices<'_, 6, 0>, x: &PredictIn<'_>) {
    let [q, v, qdd, rq, rv, inv_w] = o.w;
    let (n, a0, len) = (x.n, x.a0, q.len());
    // in chunks that stay in L1, each sum over contiguous slices
    // (vectorised), its terms in the same order as one coordinate at a time
    let mut s = 0;
    while s < len {
        let e = (s + CHUNK).min(len);
        let (gs, ge) = (o.base + s, o.base + e);
        let (q, rq, rv) = (&mut q[s..e], &mut rq[s..e], &mut rv[s..e]);
        for (j, ((y, &c), &p)) in x.hist.iter().zip(x.cr).zip(x.cp).enumerate() {
            let (yq, yv) = (&y[gs..ge], &y[n + gs..n + ge]);
            if j == 0 {
                // `0.0 + …`: the sums start from +0, as one at a time
                for l in 0..q.len() {
                    rq[l] = 0.0 + c * yq[l];
                    rv[l] = 0.0 + c * yv[l];
                    q[l] = 0.0 + p * yq[l];
                }
            } else {
                for l in 0..q.len() {
                    rq[l] += c * yq[l];
                    rv[l] += c * yv[l];
                    q[l] += p * yq[l];
                }
            }
        }
        if let Some((f0, h, gh)) = x.first {
            let (fq, fv) = (&f0[gs..ge], &f0[n + gs..n + ge]);
            for l in 0..q.len() {
                q[l] += h * fq[l];
                rq[l] += gh * fq[l];
                rv[l] += gh * fv[l];
            }
        }
        let (v, qdd, inv_w) = (&mut v[s..e], &mut qdd[s..e], &mut inv_w[s..e]);
        let (y0, thr) = (&x.hist[0][gs..ge], &x.threshold[gs..ge]);
        for l in 0..q.len() {
            let vi = a0 * q[l] + rq[l];
            v[l] = vi;
            qdd[l] = a0 * vi + rv[l];
            inv_w[l] = 1.0 / y0[l].abs().max(q[l].abs()).max(thr[l]);
        }
        s = e;
    }
}

/// One Newton correction of the BDF step: `q += Δq`, then
/// `q̇ = a₀ q + r_q`, `q̈ = a₀ q̇ + r_v` (the BDF derivative formula, module
/// docs), and the max-norm `max |Δq_i| w_i` with whether every correction
/// is below `floor·max(|q_i|, 1)`; `u.w = [q, q̇, q̈]`, `u.r = [−Δq, w,
/// r_q, r_v]` (the solve's result, the correction negated). Four
/// coordinates per turn with a max and a conjunction per lane, so the
/// loop runs in SIMD registers; split into halves ([`in_halves`]) or
/// lanes, the max and the conjunction do not depend on the order, so
/// neither do the results.
fn newton_update(u: Slices<'_, 3, 4>, a0: f64, floor: f64) -> (f64, bool) {
    const L: usize = 4;
    let [q, v, qdd] = u.w;
    let [d, inv_w, rq, rv] = u.r;
    let len = q.len();
    let (q, v, qdd) = (&mut q[..len], &mut v[..len], &mut qdd[..len]);
    let (d, inv_w, rq, rv) = (&d[..len], &inv_w[..len], &rq[..len], &rv[..len]);
    let (mut dn, mut fl) = ([0.0f64; L], [true; L]);
    let one =
        |i: usize, dn: &mut f64, fl: &mut bool, q: &mut [f64], v: &mut [f64], qdd: &mut [f64]| {
            let di = d[i];
            *dn = dn.max(di.abs() * inv_w[i]);
            *fl &= di.abs() <= floor * q[i].abs().max(1.0);
            let qi = q[i] - di;
            q[i] = qi;
            let vi = a0 * qi + rq[i];
            v[i] = vi;
            qdd[i] = a0 * vi + rv[i];
        };
    let body = len / L * L;
    for c in (0..body).step_by(L) {
        for l in 0..L {
            one(c + l, &mut dn[l], &mut fl[l], q, v, qdd);
        }
    }
    for i in body..len {
        one(i, &mut dn[0], &mut fl[0], q, v, qdd);
    }
    (
        dn.iter().fold(0.0, |a: f64, &b| a.max(b)),
        fl.iter().all(|&f| f),
    )
}
