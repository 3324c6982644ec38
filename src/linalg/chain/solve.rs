//! The substitutions with an [`Envelope`]'s factor: forward and backward
//! rows of the two halves (concurrently or interleaved), the separator
//! between them, the permutation and scaling fused in (module docs of
//! [`super`]).

use super::factor::dot2;
use super::{Envelope, PARALLEL_MIN_DIM};

impl Envelope {
    /// `x ← S (S K S)⁻¹ S x` with the last factorisation: `L y = P S x`,
    /// `Lᵀ z = D⁻¹ y` by rows of `L` from the last, `x = S Pᵀ z`; the
    /// halves concurrently as in `factorize`, the separator between them:
    /// two passes in halves (forward, backward). Returns whether every
    /// entry of the solution is finite.
    pub(super) fn solve(&mut self, x: &mut [f64]) -> bool {
        let (dim, s0, sb) = (self.dim, self.s0, self.sb);
        let par = dim >= PARALLEL_MIN_DIM;
        let (first, ptr, fa) = (&self.first, &self.ptr, &self.fa);
        let (w, wd) = (&mut self.w, &mut self.wd);
        let (perm, pscale, dinv) = (&self.perm, &self.pscale, &self.dinv);
        let env = &self.env[..ptr[dim]];
        let rows = Rows {
            len: &self.rows.len,
            ptr,
            env,
            perm: &self.rows.perm,
            pscale,
            dinv,
        };
        // the halves' forward rows read their right-hand side `(P S x)_i`
        // from x (the gather fused into the substitution) and write both
        // y (`w`: the separator's forward rows read it) and D⁻¹ y (`wd`:
        // what the backward substitution starts from), so that D⁻¹ needs
        // no pass of its own
        let xr: &[f64] = x;
        // two threads: a half each; one: both halves' rows in turn
        let two = par && crate::parallel::concurrent();
        {
            let (w_t, w_rest) = w.split_at_mut(s0);
            let w_b = &mut w_rest[..sb - s0];
            let (wd_t, wd_rest) = wd.split_at_mut(s0);
            let wd_b = &mut wd_rest[..sb - s0];
            if two {
                crate::parallel::team::join(
                    || rows.forward(xr, (0, 0..s0, w_t, wd_t)),
                    || rows.forward(xr, (s0, s0..sb, w_b, wd_b)),
                );
            } else {
                crate::parallel::team::one_thread_form(|| {
                    rows.forward_interleaved(xr, (0, 0..s0, w_t, wd_t), (s0, s0..sb, w_b, wd_b))
                });
            }
        }
        for i in sb..dim {
            w[i] = xr[perm[i]] * pscale[i];
        }
        for i in sb..dim {
            let (fai, fi, pi) = (fa[i - sb], first[i], ptr[i]);
            let la = s0 - fai;
            let d =
                dot2(&env[pi..pi + la], &w[fai..s0]) + dot2(&env[pi + la..ptr[i + 1]], &w[fi..i]);
            w[i] -= d;
            wd[i] = w[i] * dinv[i];
        }
        // x = S Pᵀ z: each z_i is written to x as soon as it is final (the
        // scatter fused into the backward substitution), and checked there
        let out = Scatter::new(x);
        let mut finite = true;
        for i in (sb..dim).rev() {
            let (fai, fi, pi, wi) = (fa[i - sb], first[i], ptr[i], wd[i]);
            let xi = wi * pscale[i];
            out.set(perm[i], xi);
            finite &= xi.is_finite();
            let la = s0 - fai;
            for (v, &l) in wd[fai..s0].iter_mut().zip(&env[pi..pi + la]) {
                *v -= l * wi;
            }
            for (v, &l) in wd[fi..i].iter_mut().zip(&env[pi + la..ptr[i + 1]]) {
                *v -= l * wi;
            }
        }
        let (wd_t, wd_rest) = wd.split_at_mut(s0);
        let wd_b = &mut wd_rest[..sb - s0];
        let (lo, hi) = if two {
            crate::parallel::team::join(
                || rows.backward(&out, (0, 0..s0, wd_t)),
                || rows.backward(&out, (s0, s0..sb, wd_b)),
            )
        } else {
            crate::parallel::team::one_thread_form(|| {
                rows.backward_interleaved(&out, (0, 0..s0, wd_t), (s0, s0..sb, wd_b))
            })
        };
        finite && lo && hi
    }
}

/// The solution vector `x` of [`Envelope::solve`] written through the
/// permutation by the backward substitution's rows, of both halves at
/// once: every position is written by exactly one row (`perm` is a
/// permutation), so concurrent writes never meet.
pub(in crate::linalg) struct Scatter<'a> {
    ptr: *mut f64,
    len: usize,
    _x: std::marker::PhantomData<&'a mut [f64]>,
}

// SAFETY: the rows writing through a `Scatter` write disjoint positions
// (a permutation), and `x` is borrowed mutably for the `Scatter`'s life.
unsafe impl Send for Scatter<'_> {}
unsafe impl Sync for Scatter<'_> {}

impl<'a> Scatter<'a> {
    pub(in crate::linalg) fn new(x: &'a mut [f64]) -> Self {
        Self {
            ptr: x.as_mut_ptr(),
            len: x.len(),
            _x: std::marker::PhantomData,
        }
    }

    #[inline(always)]
    pub(in crate::linalg) fn set(&self, k: usize, v: f64) {
        assert!(k < self.len);
        // SAFETY: in bounds (checked), and no other row writes position k
        unsafe { *self.ptr.add(k) = v }
    }
}

/// What the substitutions read of a factorisation: the envelope rows
/// (their lengths [`RowTable`](super::RowTable), where each half's rows
/// start in `ptr`, `env`), the permutation and the symmetric scaling
/// (`x`'s entry `perm[i]` is row `i`'s, times `pscale[i]`), `D⁻¹`.
#[derive(Clone, Copy)]
struct Rows<'a> {
    len: &'a [u8],
    ptr: &'a [usize],
    env: &'a [f64],
    perm: &'a [u32],
    pscale: &'a [f64],
    dinv: &'a [f64],
}

/// One half's plain rows for a substitution: the first row's index
/// (`base`), the rows and their part of the work vector.
type Half<'a> = (usize, std::ops::Range<usize>, &'a mut [f64]);

/// One half's plain rows for the forward substitution: as [`Half`], with
/// the half's part of `D⁻¹ y` (written beside `y`).
type HalfFwd<'a> = (usize, std::ops::Range<usize>, &'a mut [f64], &'a mut [f64]);

impl Rows<'_> {
    /// Forward substitution `L y = P S x` over the plain rows of one half
    /// (`y` into `w`, `D⁻¹ y` into `wd`, from row `base`).
    fn forward(&self, x: &[f64], (base, rows, w, wd): HalfFwd<'_>) {
        let (mut prev, mut p) = (0.0, self.ptr[rows.start]);
        for i in rows {
            prev = self.forward_row(x, base, i, (w, wd), prev, &mut p);
        }
    }

    /// Row `i` of [`Self::forward`]: `y_i = x_{perm[i]} s_i − Σ_j L_ij y_j`
    /// over its envelope `[first[i], i)`, which ends at column `i − 1`
    /// when not empty: `prev = y_{i−1}`, the previous row's result, is
    /// taken from the register instead of `w`, so the chain of dependent
    /// rows does not wait on a store and a reload. Its entries start at
    /// `env[*p]`, and `*p` moves on to the next row's. Writes `y_i` to `w` and
    /// `y_i / d_i` to `wd` (the same bits as a separate `D⁻¹` pass);
    /// returns `y_i`. The terms are added in column order (the same bits
    /// as a plain dot product after a separate gather).
    #[inline(always)]
    fn forward_row(
        &self,
        x: &[f64],
        base: usize,
        i: usize,
        (w, wd): (&mut [f64], &mut [f64]),
        prev: f64,
        p: &mut usize,
    ) -> f64 {
        let (env, len, pi) = (self.env, usize::from(self.len[i]), *p);
        *p = pi + len;
        assert!(pi + len <= env.len() && i - base < w.len() && len <= i - base);
        assert!(i - base < wd.len() && i < self.dinv.len());
        let fi = i - len;
        let mut y = x[self.perm[i] as usize] * self.pscale[i];
        if len > 0 {
            let mut dot = 0.0;
            for o in 0..len - 1 {
                // SAFETY: row i's entries are env[pi..pi + len] (checked
                // above) and its columns base ≤ fi + o < i lie in `w`.
                unsafe {
                    dot += env.get_unchecked(pi + o) * w.get_unchecked(fi - base + o);
                }
            }
            y -= dot + env[pi + len - 1] * prev;
        }
        w[i - base] = y;
        wd[i - base] = y * self.dinv[i];
        y
    }

    /// Backward substitution `Lᵀ z = w` over the plain rows of one half,
    /// from the last (`w` from row `base`); each `z_i`, final once its row
    /// is reached, goes to `x_{perm[i]} = z_i s_i` at once. Returns whether
    /// every entry it wrote is finite.
    fn backward(&self, out: &Scatter<'_>, (base, rows, w): Half<'_>) -> bool {
        let (mut carry, mut bad, mut p) = ((0.0, 0.0), 0.0, self.ptr[rows.end]);
        for i in rows.rev() {
            carry = self.backward_row(out, base, i, w, carry, (&mut bad, &mut p));
        }
        bad == 0.0
    }

    /// Row `i` of [`Self::backward`]: `z_i = w_i − L_{i+1,i} z_{i+1}` with
    /// the last update, `carry = (L_{i+1,i}, z_{i+1})` from the row after,
    /// taken from the register (the others are already in `w`), then
    /// `w_j −= L_ij z_i` over the envelope but its last column `i − 1`,
    /// which is returned as the next row's carry. Its entries end at
    /// `env[*p]`, and `*p` moves back to where they start (the previous
    /// row's end). The updates of each `w_j` come in the same order as
    /// scattered one by one (the same bits). Adds `x · 0` of the entry `x` written to `bad`, which stays
    /// zero while every entry is finite (an infinite or NaN one makes it
    /// NaN): two operations per row, no branch.
    #[inline(always)]
    fn backward_row(
        &self,
        out: &Scatter<'_>,
        base: usize,
        i: usize,
        w: &mut [f64],
        carry: (f64, f64),
        (bad, p): (&mut f64, &mut usize),
    ) -> (f64, f64) {
        let (env, len) = (self.env, usize::from(self.len[i]));
        assert!(len <= *p && *p <= env.len() && len <= i - base);
        let pi = *p - len;
        *p = pi;
        let zi = w[i - base] - carry.0 * carry.1;
        let xi = zi * self.pscale[i];
        out.set(self.perm[i] as usize, xi);
        *bad += xi * 0.0;
        if len == 0 {
            return (0.0, 0.0);
        }
        let fi = i - len;
        for o in 0..len - 1 {
            // SAFETY: as in `forward_row`
            unsafe {
                *w.get_unchecked_mut(fi - base + o) -= env.get_unchecked(pi + o) * zi;
            }
        }
        (env[pi + len - 1], zi)
    }

    /// [`Self::forward`] of both halves on one thread, a row of each in
    /// turn. Each substitution is a chain of dependent rows (row `i` waits
    /// for row `i − 1`), latency-bound; the two independent chains overlap
    /// in the core. Every row does the same operations as in
    /// [`Self::forward`], so the results are the same bits.
    fn forward_interleaved(&self, x: &[f64], t: HalfFwd<'_>, b: HalfFwd<'_>) {
        let ((bt, rt, wt, dt), (bb, rb, wb, db)) = (t, b);
        let common = rt.len().min(rb.len());
        let (mut pt, mut pb) = (0.0, 0.0);
        let (mut qt, mut qb) = (self.ptr[rt.start], self.ptr[rb.start]);
        for r in 0..common {
            pt = self.forward_row(x, bt, rt.start + r, (wt, dt), pt, &mut qt);
            pb = self.forward_row(x, bb, rb.start + r, (wb, db), pb, &mut qb);
        }
        // the longer half's rest, its chain continued
        let rest = |(b, r, w, d): HalfFwd<'_>, mut prev: f64, mut p: usize| {
            for i in r.start + common..r.end {
                prev = self.forward_row(x, b, i, (w, d), prev, &mut p);
            }
        };
        rest((bt, rt, wt, dt), pt, qt);
        rest((bb, rb, wb, db), pb, qb);
    }

    /// [`Self::backward`] of both halves on one thread, a row of each in
    /// turn from their last rows (as [`Self::forward_interleaved`]);
    /// returns whether every entry of each half it wrote is finite.
    fn backward_interleaved(&self, out: &Scatter<'_>, t: Half<'_>, b: Half<'_>) -> (bool, bool) {
        let ((bt, rt, wt), (bb, rb, wb)) = (t, b);
        let common = rt.len().min(rb.len());
        let (mut ct, mut cb) = ((0.0, 0.0), (0.0, 0.0));
        let (mut ft, mut fb) = (0.0, 0.0);
        let (mut qt, mut qb) = (self.ptr[rt.end], self.ptr[rb.end]);
        for r in 1..=common {
            ct = self.backward_row(out, bt, rt.end - r, wt, ct, (&mut ft, &mut qt));
            cb = self.backward_row(out, bb, rb.end - r, wb, cb, (&mut fb, &mut qb));
        }
        let rest = |(b, r, w): Half<'_>, mut carry: (f64, f64), bad: &mut f64, mut p: usize| {
            for i in (r.start..r.end - common).rev() {
                carry = self.backward_row(out, b, i, w, carry, (bad, &mut p));
            }
        };
        rest((bt, rt, wt), ct, &mut ft, qt);
        rest((bb, rb, wb), cb, &mut fb, qb);
        (ft == 0.0, fb == 0.0)
    }
}
