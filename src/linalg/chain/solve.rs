//! The substitutions with an [`Envelope`]'s factor: forward and backward
//! rows of the two halves (concurrently or interleaved), the separator
//! between them, the permutation and scaling fused in (module docs of
//! [`super`]).

use super::factor::dot2;
use super::{Envelope, Scalar, PARALLEL_MIN_DIM};
use crate::numeric::with_avx;
use crate::parallel::join_if;

impl<T: Scalar> Envelope<T> {
    /// `x ← S (S K S)⁻¹ S x` with the last factorisation: `L y = P S x`,
    /// `Lᵀ z = D⁻¹ y` by rows of `L` from the last, `x = S Pᵀ z`; the
    /// halves concurrently as in `factorize`, the separator between them:
    /// two passes in halves (forward, backward). Returns whether every
    /// entry of the solution is finite. Panics when `x` is not of the
    /// dimension (the callers check it first).
    pub(in crate::linalg) fn solve(&mut self, x: &T::Vector<'_>) -> bool {
        assert_eq!(T::len(x), self.dim, "right-hand side of the envelope solve");
        let (dim, s0, sb) = (self.dim, self.s0, self.sb);
        let par = dim >= PARALLEL_MIN_DIM;
        let (first, ptr, fa) = (&self.first, &self.ptr, &self.fa);
        let (w, wd) = (&mut self.w, &mut self.wd);
        let (perm, pscale, dinv) = (&self.perm, &self.pscale, &self.dinv);
        let env = &self.env[..ptr[dim]];
        let table = &self.rows;
        // each half's rows as the sweeps read them (the table's checks:
        // module docs of `RowTable`)
        let half = |rows: std::ops::Range<usize>, h: usize| Rows {
            len: &table.len[rows.clone()],
            perm: &table.perm[rows.clone()],
            pscale: &pscale[rows.clone()],
            dinv: &dinv[rows],
            env: &env[table.start[h]..table.start[h + 1]],
        };
        let (top, bottom) = (half(0..s0, 0), half(s0..sb, 1));
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
                    with_avx(|| forward_interleaved(x, (&top, w_t, wd_t), (&bottom, w_b, wd_b)))
                });
            } else {
                join_if(
                    par,
                    || with_avx(|| top.forward(x, w_t, wd_t)),
                    || with_avx(|| bottom.forward(x, w_b, wd_b)),
                );
            }
        }
        for i in sb..dim {
            let (fai, fi, pi) = (fa[i - sb], first[i], ptr[i]);
            let la = s0 - fai;
            // SAFETY: perm[i] < dim = x's length (checked in `solve`)
            let xi = unsafe { T::get(x, perm[i]) };
            w[i] = xi.scale(pscale[i]).minus_segments(
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
            // SAFETY: as above
            bad += unsafe { T::put(x, perm[i], wi.scale(pscale[i])) };
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
                with_avx(|| backward_interleaved(x, (&top, wd_t), (&bottom, wd_b)))
            })
        } else {
            join_if(
                par,
                || with_avx(|| top.backward(x, wd_t)),
                || with_avx(|| bottom.backward(x, wd_b)),
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

    /// The length of `x`.
    pub(in crate::linalg) fn len(&self) -> usize {
        self.len
    }

    /// Entry `k`.
    ///
    /// # Safety
    /// `k` is below [`Self::len`].
    #[inline(always)]
    pub(in crate::linalg) unsafe fn get(&self, k: usize) -> f64 {
        debug_assert!(k < self.len);
        // SAFETY: in bounds (the caller's contract); no row writes while
        // rows read
        unsafe { *self.ptr.add(k) }
    }

    /// Write entry `k`.
    ///
    /// # Safety
    /// `k` is below [`Self::len`].
    #[inline(always)]
    pub(in crate::linalg) unsafe fn set(&self, k: usize, v: f64) {
        debug_assert!(k < self.len);
        // SAFETY: in bounds (the caller's contract), and no other row
        // writes position k
        unsafe { *self.ptr.add(k) = v }
    }
}

/// One half's plain rows as the substitutions read them, each slice from
/// the half's first row: the lengths of the envelope rows and the
/// permutation ([`RowTable`](super::RowTable)), the symmetric scaling
/// (`x`'s entry `perm[r]` is row `r`'s, times `pscale[r]`), `D⁻¹`, and
/// the half's entries of `L` (row after row). The table's checks make the
/// sweeps' unchecked reads safe: row `r`'s envelope `len[r] ≤ r` lies in
/// the half, its entries in `env` (the lengths sum to `env.len()`), and
/// `perm[r]` is below the dimension, `x`'s length.
#[derive(Clone, Copy)]
struct Rows<'a, T> {
    len: &'a [u8],
    perm: &'a [u32],
    pscale: &'a [f64],
    dinv: &'a [T],
    env: &'a [T],
}

impl<T: Scalar> Rows<'_, T> {
    /// Forward substitution `L y = P S x` over the rows of one half (`y`
    /// into `w`, `D⁻¹ y` into `wd`, both of the half's length).
    #[inline(always)]
    fn forward(&self, x: &T::Vector<'_>, w: &mut [T], wd: &mut [T]) {
        assert!(w.len() == self.len.len() && wd.len() == w.len());
        let (mut prev, mut p) = (T::ZERO, 0);
        for r in 0..w.len() {
            // SAFETY: r < the half's length (the loop and the check above)
            prev = unsafe { self.forward_row(x, r, (w, wd), prev, &mut p) };
        }
    }

    /// Row `r` of [`Self::forward`]: `y_r = x_{perm[r]} s_r − Σ_j L_rj y_j`
    /// over its envelope `[r − len[r], r)`, which ends at column `r − 1`
    /// when not empty: `prev = y_{r−1}`, the previous row's result, is
    /// taken from the register instead of `w`, so the chain of dependent
    /// rows does not wait on a store and a reload. Its entries start at
    /// `env[*p]`, and `*p` moves on to the next row's. Writes `y_r` to `w` and
    /// `y_r / d_r` to `wd` (the same bits as a separate `D⁻¹` pass);
    /// returns `y_r`. The terms are added in column order (the same bits
    /// as a plain dot product after a separate gather).
    ///
    /// # Safety
    /// `r` is below the half's length, `w` and `wd` are of that length, and
    /// `*p` is where row `r`'s entries start (the sum of the lengths
    /// before it).
    #[inline(always)]
    unsafe fn forward_row(
        &self,
        x: &T::Vector<'_>,
        r: usize,
        (w, wd): (&mut [T], &mut [T]),
        prev: T,
        p: &mut usize,
    ) -> T {
        // SAFETY: the contract and the table's checks (type docs): rows
        // r − len .. r and entries *p .. *p + len are in bounds
        unsafe {
            let len = usize::from(*self.len.get_unchecked(r));
            let xr = T::get(x, *self.perm.get_unchecked(r) as usize);
            let mut y = xr.scale(*self.pscale.get_unchecked(r));
            if len > 0 {
                let e = self.env.as_ptr().add(*p);
                let v = w.as_ptr().add(r - len);
                let mut dot = T::ZERO;
                for o in 0..len - 1 {
                    dot += *e.add(o) * *v.add(o);
                }
                y -= dot + *e.add(len - 1) * prev;
            }
            *p += len;
            *w.get_unchecked_mut(r) = y;
            *wd.get_unchecked_mut(r) = y * *self.dinv.get_unchecked(r);
            y
        }
    }

    /// Backward substitution `Lᵀ z = w` over the rows of one half, from
    /// the last (`w` of the half's length); each `z_r`, final once its row
    /// is reached, goes to `x_{perm[r]} = z_r s_r` at once. Returns whether
    /// every entry it wrote is finite.
    #[inline(always)]
    fn backward(&self, out: &T::Vector<'_>, w: &mut [T]) -> bool {
        assert!(w.len() == self.len.len());
        let (mut carry, mut bad, mut p) = ((T::ZERO, T::ZERO), 0.0, self.env.len());
        for r in (0..w.len()).rev() {
            // SAFETY: r < the half's length (the loop and the check above)
            carry = unsafe { self.backward_row(out, r, w, carry, (&mut bad, &mut p)) };
        }
        bad == 0.0
    }

    /// Row `r` of [`Self::backward`]: `z_r = w_r − L_{r+1,r} z_{r+1}` with
    /// the last update, `carry = (L_{r+1,r}, z_{r+1})` from the row after,
    /// taken from the register (the others are already in `w`), then
    /// `w_j −= L_rj z_r` over the envelope but its last column `r − 1`,
    /// which is returned as the next row's carry. Its entries end at
    /// `env[*p]`, and `*p` moves back to where they start (the previous
    /// row's end). The updates of each `w_j` come in the same order as
    /// scattered one by one (the same bits). Adds [`Scalar::put`]'s check
    /// of the entry written to `bad`, which stays zero while every entry is
    /// finite: no branch.
    ///
    /// # Safety
    /// `r` is below the half's length, `w` is of that length, and `*p` is
    /// where row `r`'s entries end (the sum of the lengths up to it).
    #[inline(always)]
    unsafe fn backward_row(
        &self,
        out: &T::Vector<'_>,
        r: usize,
        w: &mut [T],
        carry: (T, T),
        (bad, p): (&mut f64, &mut usize),
    ) -> (T, T) {
        // SAFETY: as in `forward_row`
        unsafe {
            let len = usize::from(*self.len.get_unchecked(r));
            *p -= len;
            let zr = *w.get_unchecked(r) - carry.0 * carry.1;
            let xr = zr.scale(*self.pscale.get_unchecked(r));
            *bad += T::put(out, *self.perm.get_unchecked(r) as usize, xr);
            if len == 0 {
                return (T::ZERO, T::ZERO);
            }
            let e = self.env.as_ptr().add(*p);
            let v = w.as_mut_ptr().add(r - len);
            for o in 0..len - 1 {
                *v.add(o) -= *e.add(o) * zr;
            }
            (*e.add(len - 1), zr)
        }
    }
}

/// One half's rows and its parts of `y` and `D⁻¹ y` for the forward
/// substitution.
type HalfFwd<'a, 'r, T> = (&'r Rows<'a, T>, &'r mut [T], &'r mut [T]);

/// [`Rows::forward`] of both halves on one thread, a row of each in
/// turn. Each substitution is a chain of dependent rows (row `r` waits
/// for row `r − 1`), latency-bound; the two independent chains overlap
/// in the core. Every row does the same operations as in
/// [`Rows::forward`], so the results are the same bits.
#[inline(always)]
fn forward_interleaved<T: Scalar>(x: &T::Vector<'_>, t: HalfFwd<'_, '_, T>, b: HalfFwd<'_, '_, T>) {
    let ((ht, wt, dt), (hb, wb, db)) = (t, b);
    assert!(wt.len() == ht.len.len() && dt.len() == wt.len());
    assert!(wb.len() == hb.len.len() && db.len() == wb.len());
    let common = wt.len().min(wb.len());
    let (mut pt, mut pb) = (T::ZERO, T::ZERO);
    let (mut qt, mut qb) = (0, 0);
    for r in 0..common {
        // SAFETY: r < both halves' lengths (checked above)
        unsafe {
            pt = ht.forward_row(x, r, (wt, dt), pt, &mut qt);
            pb = hb.forward_row(x, r, (wb, db), pb, &mut qb);
        }
    }
    // the longer half's rest, its chain continued
    for (h, w, d, mut prev, mut p) in [(ht, wt, dt, pt, qt), (hb, wb, db, pb, qb)] {
        for r in common..w.len() {
            // SAFETY: r < the half's length (checked above)
            prev = unsafe { h.forward_row(x, r, (w, d), prev, &mut p) };
        }
    }
}

/// [`Rows::backward`] of both halves on one thread, a row of each in
/// turn from their last rows (as [`forward_interleaved`]); returns
/// whether every entry of each half it wrote is finite.
#[inline(always)]
fn backward_interleaved<T: Scalar>(
    out: &T::Vector<'_>,
    (ht, wt): (&Rows<'_, T>, &mut [T]),
    (hb, wb): (&Rows<'_, T>, &mut [T]),
) -> (bool, bool) {
    assert!(wt.len() == ht.len.len() && wb.len() == hb.len.len());
    let (nt, nb) = (wt.len(), wb.len());
    let common = nt.min(nb);
    let (mut ct, mut cb) = ((T::ZERO, T::ZERO), (T::ZERO, T::ZERO));
    let (mut ft, mut fb) = (0.0, 0.0);
    let (mut qt, mut qb) = (ht.env.len(), hb.env.len());
    for k in 1..=common {
        // SAFETY: the rows are below both halves' lengths (checked above)
        unsafe {
            ct = ht.backward_row(out, nt - k, wt, ct, (&mut ft, &mut qt));
            cb = hb.backward_row(out, nb - k, wb, cb, (&mut fb, &mut qb));
        }
    }
    for (h, w, mut carry, bad, mut p) in [(ht, wt, ct, &mut ft, qt), (hb, wb, cb, &mut fb, qb)] {
        for r in (0..w.len() - common).rev() {
            // SAFETY: r < the half's length
            carry = unsafe { h.backward_row(out, r, w, carry, (&mut *bad, &mut p)) };
        }
    }
    (ft == 0.0, fb == 0.0)
}
