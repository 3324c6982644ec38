//! The substitutions with an [`Envelope`]'s factor: forward and backward
//! rows of the two halves (concurrently or interleaved), the separator
//! between them, the permutation and scaling fused in (module docs of
//! [`super`]).

use super::factor::dot2;
use super::{Envelope, Scalar, PARALLEL_MIN_DIM};
use crate::parallel::join_if;

impl<T: Scalar> Envelope<T> {
    /// `x ← S (S K S)⁻¹ S x` with the last factorisation: `L y = P S x`,
    /// `Lᵀ z = D⁻¹ y` by rows of `L` from the last, `x = S Pᵀ z`; the
    /// halves concurrently as in `factorize`, the separator between them:
    /// two passes in halves (forward, backward). Returns whether every
    /// entry of the solution is finite.
    pub(in crate::linalg) fn solve(&mut self, x: &T::Vector<'_>) -> bool {
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
        // no pass of its own. Two threads: a half each; one: both halves'
        // rows in turn (`Scalar::INTERLEAVE`) or one half after the other.
        let two = par && crate::parallel::concurrent();
        let one_thread = T::INTERLEAVE && !two;
        {
            let (w_t, w_rest) = w.split_at_mut(s0);
            let w_b = &mut w_rest[..sb - s0];
            let (wd_t, wd_rest) = wd.split_at_mut(s0);
            let wd_b = &mut wd_rest[..sb - s0];
            if one_thread {
                crate::parallel::team::one_thread_form(|| {
                    rows.forward_interleaved(x, (0, 0..s0, w_t, wd_t), (s0, s0..sb, w_b, wd_b))
                });
            } else {
                join_if(
                    par,
                    || rows.forward(x, (0, 0..s0, w_t, wd_t)),
                    || rows.forward(x, (s0, s0..sb, w_b, wd_b)),
                );
            }
        }
        for i in sb..dim {
            let (fai, fi, pi) = (fa[i - sb], first[i], ptr[i]);
            let la = s0 - fai;
            w[i] = T::get(x, perm[i]).scale(pscale[i]).minus_segments(
                dot2(&env[pi..pi + la], &w[fai..s0]),
                dot2(&env[pi + la..ptr[i + 1]], &w[fi..i]),
            );
            wd[i] = w[i] * dinv[i];
        }
        // x = S Pᵀ z: each z_i is written to x as soon as it is final (the
        // scatter fused into the backward substitution), and checked there
        let mut bad = 0.0;
        for i in (sb..dim).rev() {
            let (fai, fi, pi, wi) = (fa[i - sb], first[i], ptr[i], wd[i]);
            bad += T::put(x, perm[i], wi.scale(pscale[i]));
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
        let (lo, hi) = if one_thread {
            crate::parallel::team::one_thread_form(|| {
                rows.backward_interleaved(x, (0, 0..s0, wd_t), (s0, s0..sb, wd_b))
            })
        } else {
            join_if(
                par,
                || rows.backward(x, (0, 0..s0, wd_t)),
                || rows.backward(x, (s0, s0..sb, wd_b)),
            )
        };
        bad == 0.0 && lo && hi
    }
}

/// The right-hand side `x` of [`Envelope::solve`], read through the
/// permutation by the forward substitution's rows and overwritten with
/// the solution by the backward substitution's rows, of both halves at
/// once: every position is read and written by exactly one row (`perm` is
/// a permutation), and all reads (forward) end before the first write
/// (backward), so concurrent accesses never meet.
pub(in crate::linalg) struct Scatter<'a> {
    ptr: *mut f64,
    len: usize,
    _x: std::marker::PhantomData<&'a mut [f64]>,
}

// SAFETY: the rows reading and writing through a `Scatter` touch disjoint
// positions (a permutation), and `x` is borrowed mutably for the
// `Scatter`'s life.
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
    pub(in crate::linalg) fn get(&self, k: usize) -> f64 {
        assert!(k < self.len);
        // SAFETY: in bounds (checked); no row writes while rows read
        unsafe { *self.ptr.add(k) }
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
struct Rows<'a, T> {
    len: &'a [u8],
    ptr: &'a [usize],
    env: &'a [T],
    perm: &'a [u32],
    pscale: &'a [f64],
    dinv: &'a [T],
}

/// One half's plain rows for a substitution: the first row's index
/// (`base`), the rows and their part of the work vector.
type Half<'a, T> = (usize, std::ops::Range<usize>, &'a mut [T]);

/// One half's plain rows for the forward substitution: as [`Half`], with
/// the half's part of `D⁻¹ y` (written beside `y`).
type HalfFwd<'a, T> = (usize, std::ops::Range<usize>, &'a mut [T], &'a mut [T]);

impl<T: Scalar> Rows<'_, T> {
    /// Forward substitution `L y = P S x` over the plain rows of one half
    /// (`y` into `w`, `D⁻¹ y` into `wd`, from row `base`).
    fn forward(&self, x: &T::Vector<'_>, (base, rows, w, wd): HalfFwd<'_, T>) {
        let (mut prev, mut p) = (T::ZERO, self.ptr[rows.start]);
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
        x: &T::Vector<'_>,
        base: usize,
        i: usize,
        (w, wd): (&mut [T], &mut [T]),
        prev: T,
        p: &mut usize,
    ) -> T {
        let (env, len, pi) = (self.env, usize::from(self.len[i]), *p);
        *p = pi + len;
        assert!(pi + len <= env.len() && i - base < w.len() && len <= i - base);
        assert!(i - base < wd.len() && i < self.dinv.len());
        let fi = i - len;
        let mut y = T::get(x, self.perm[i] as usize).scale(self.pscale[i]);
        if len > 0 {
            let mut dot = T::ZERO;
            for o in 0..len - 1 {
                // SAFETY: row i's entries are env[pi..pi + len] (checked
                // above) and its columns base ≤ fi + o < i lie in `w`.
                unsafe {
                    dot += *env.get_unchecked(pi + o) * *w.get_unchecked(fi - base + o);
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
    fn backward(&self, out: &T::Vector<'_>, (base, rows, w): Half<'_, T>) -> bool {
        let (mut carry, mut bad, mut p) = ((T::ZERO, T::ZERO), 0.0, self.ptr[rows.end]);
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
    /// scattered one by one (the same bits). Adds [`Scalar::put`]'s check
    /// of the entry written to `bad`, which stays zero while every entry is
    /// finite: no branch.
    #[inline(always)]
    fn backward_row(
        &self,
        out: &T::Vector<'_>,
        base: usize,
        i: usize,
        w: &mut [T],
        carry: (T, T),
        (bad, p): (&mut f64, &mut usize),
    ) -> (T, T) {
        let (env, len) = (self.env, usize::from(self.len[i]));
        assert!(len <= *p && *p <= env.len() && len <= i - base);
        let pi = *p - len;
        *p = pi;
        let zi = w[i - base] - carry.0 * carry.1;
        *bad += T::put(out, self.perm[i] as usize, zi.scale(self.pscale[i]));
        if len == 0 {
            return (T::ZERO, T::ZERO);
        }
        let fi = i - len;
        for o in 0..len - 1 {
            // SAFETY: as in `forward_row`
            unsafe {
                *w.get_unchecked_mut(fi - base + o) -= *env.get_unchecked(pi + o) * zi;
            }
        }
        (env[pi + len - 1], zi)
    }

    /// [`Self::forward`] of both halves on one thread, a row of each in
    /// turn. Each substitution is a chain of dependent rows (row `i` waits
    /// for row `i − 1`), latency-bound; the two independent chains overlap
    /// in the core. Every row does the same operations as in
    /// [`Self::forward`], so the results are the same bits.
    fn forward_interleaved(&self, x: &T::Vector<'_>, t: HalfFwd<'_, T>, b: HalfFwd<'_, T>) {
        let ((bt, rt, wt, dt), (bb, rb, wb, db)) = (t, b);
        let common = rt.len().min(rb.len());
        let (mut pt, mut pb) = (T::ZERO, T::ZERO);
        let (mut qt, mut qb) = (self.ptr[rt.start], self.ptr[rb.start]);
        for r in 0..common {
            pt = self.forward_row(x, bt, rt.start + r, (wt, dt), pt, &mut qt);
            pb = self.forward_row(x, bb, rb.start + r, (wb, db), pb, &mut qb);
        }
        // the longer half's rest, its chain continued
        let rest = |(b, r, w, d): HalfFwd<'_, T>, mut prev: T, mut p: usize| {
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
    fn backward_interleaved(
        &self,
        out: &T::Vector<'_>,
        t: Half<'_, T>,
        b: Half<'_, T>,
    ) -> (bool, bool) {
        let ((bt, rt, wt), (bb, rb, wb)) = (t, b);
        let common = rt.len().min(rb.len());
        let (mut ct, mut cb) = ((T::ZERO, T::ZERO), (T::ZERO, T::ZERO));
        let (mut ft, mut fb) = (0.0, 0.0);
        let (mut qt, mut qb) = (self.ptr[rt.end], self.ptr[rb.end]);
        for r in 1..=common {
            ct = self.backward_row(out, bt, rt.end - r, wt, ct, (&mut ft, &mut qt));
            cb = self.backward_row(out, bb, rb.end - r, wb, cb, (&mut fb, &mut qb));
        }
        let rest = |(b, r, w): Half<'_, T>, mut carry: (T, T), bad: &mut f64, mut p: usize| {
            for i in (r.start..r.end - common).rev() {
                carry = self.backward_row(out, b, i, w, carry, (bad, &mut p));
            }
        };
        rest((bt, rt, wt), ct, &mut ft, qt);
        rest((bb, rb, wb), cb, &mut fb, qb);
        (ft == 0.0, fb == 0.0)
    }
}
