//! The scaled, regularised LDLᵀ of an [`Envelope`]: the Crout rows of the
//! two halves, then the separator's two-segment rows (module docs of
//! [`super`]).

use super::scalar::Pivots;
use super::{Envelope, Fill, Scalar, PARALLEL_MIN_DIM};
use crate::linalg::sparse::{coordinate_scale, multiplier_scale};
use crate::linalg::LinalgError;
use crate::numeric::with_avx;
use crate::parallel::join_if;

impl<T: Scalar> Envelope<T> {
    /// Scaled LDLᵀ of the values `vals` (by slot of the analysed pattern;
    /// module docs), each pivot under [`Scalar::pivot`] with `ε`, `δ`: the
    /// halves `T` and `B` concurrently (`join_if`; each is sequential
    /// inside and touches only its own rows), then the separator.
    pub(in crate::linalg) fn factorize(
        &mut self,
        vals: T::Values<'_>,
        epsilon: f64,
        delta: f64,
    ) -> Result<Regularized, LinalgError> {
        let (dim, s0, sb) = (self.dim, self.s0, self.sb);
        let par = dim >= PARALLEL_MIN_DIM;
        let rule = Pivots {
            positive: &self.positive,
            perm: &self.perm,
            epsilon,
            delta,
        };
        let (first, ptr, fa) = (&self.first, &self.ptr, &self.fa);
        let profile = ptr[dim];
        let perm = &self.perm;
        let scaling = Scaling::<T> {
            n: self.n,
            perm: &self.perm,
            dslot: &self.dslot,
            phi_ptr: &self.phi_ptr,
            phi_ent: &self.phi_ent,
            vals,
        };
        // each part: its scaling, its values (checked finite) and the
        // LDLᵀ of its rows; T and B concurrently (`join_if`; each
        // sequential inside, touching only its own rows), then S
        let (lower, diag) = self.env.split_at_mut(profile);
        let (lower_t, lower_rest) = lower.split_at_mut(ptr[s0]);
        let (lower_b, _) = lower_rest.split_at_mut(ptr[sb] - ptr[s0]);
        let (diag_t, diag_rest) = diag.split_at_mut(s0);
        let (diag_b, _) = diag_rest.split_at_mut(sb - s0);
        let (dinv_t, dinv_rest) = self.dinv.split_at_mut(s0);
        let dinv_b = &mut dinv_rest[..sb - s0];
        let (ps_t, ps_rest) = self.pscale.split_at_mut(s0);
        let ps_b = &mut ps_rest[..sb - s0];
        let (fill_t, fill_b) = (&self.fill[0], &self.fill[1]);
        // (compiled for AVX where the processor has it: `with_avx`, the
        // same bits)
        let (rt, rb) = join_if(
            par,
            || {
                with_avx(|| {
                    scaling.rows(0..s0, 0, ps_t);
                    load(fill_t, perm, vals, ps_t, 0, lower_t, diag_t)?;
                    crout_rows(first, ptr, 0, 0..s0, lower_t, diag_t, dinv_t, &rule)
                })
            },
            || {
                with_avx(|| {
                    scaling.rows(s0..sb, s0, ps_b);
                    load(fill_b, perm, vals, ps_b, s0, lower_b, diag_b)?;
                    crout_rows(first, ptr, s0, s0..sb, lower_b, diag_b, dinv_b, &rule)
                })
            },
        );
        let mut regularized = rt? + rb?;
        scaling.rows(sb..dim, 0, &mut self.pscale);
        let (lower, diag) = self.env.split_at_mut(profile);
        {
            let (lower_s, diag_s) = (&mut lower[ptr[sb]..], &mut diag[sb..]);
            load(
                &self.fill[2],
                &self.perm,
                vals,
                &self.pscale,
                0,
                lower_s,
                diag_s,
            )?;
        }
        // the separator: two-segment rows against every row before them
        let dinv = &mut self.dinv;
        for i in sb..dim {
            let (fai, fi, pi) = (fa[i - sb], first[i], ptr[i]);
            let la = s0 - fai;
            // t_ij = a_ij − Σ_k t_ik L_jk over the overlap of rows i and j:
            // the T segment against plain rows j of T
            for j in fai..s0 {
                let k0 = fai.max(first[j]);
                let d = dot(lower, pi + (k0 - fai), ptr[j] + (k0 - first[j]), j - k0);
                lower[pi + (j - fai)] -= d;
            }
            // the second segment against rows of B (plain) and of S (two segments)
            for j in fi..i {
                let la_j = if j >= sb { s0 - fa[j - sb] } else { 0 };
                let k0 = fi.max(first[j]);
                let mut d = dot(
                    lower,
                    pi + la + (k0 - fi),
                    ptr[j] + la_j + (k0 - first[j]),
                    j - k0,
                );
                if j >= sb {
                    let k0 = fai.max(fa[j - sb]);
                    d += dot(lower, pi + (k0 - fai), ptr[j] + (k0 - fa[j - sb]), s0 - k0);
                }
                lower[pi + la + (j - fi)] -= d;
            }
            let mut d = diag[i];
            for (o, j) in (fai..s0).chain(fi..i).enumerate() {
                let t = lower[pi + o];
                let l = t * dinv[j];
                d -= t * l;
                lower[pi + o] = l;
            }
            let d = d.pivot(i, &rule, &mut regularized)?;
            diag[i] = d;
            dinv[i] = d.recip();
        }
        Ok(regularized)
    }
}

/// The symmetric scaling of [`SparseLdlt`](crate::linalg::SparseLdlt) (`saddle_scaling`,
/// `coordinate_scale`, `multiplier_scale`) row by row in elimination
/// order, so each part computes its own (the maximum is exact: any order
/// gives the same bits), with the modulus of complex entries (real scale
/// factors keep the matrix symmetric).
struct Scaling<'a, 'v, T: Scalar> {
    n: usize,
    perm: &'a [usize],
    dslot: &'a [usize],
    phi_ptr: &'a [usize],
    phi_ent: &'a [(usize, usize)],
    vals: T::Values<'v>,
}

impl<T: Scalar> Scaling<'_, '_, T> {
    /// `pscale[i − base]` for the rows `rows` (`pscale` from permuted row
    /// `base`, covering the columns of their Φ_q entries).
    #[inline(always)]
    fn rows(&self, rows: std::ops::Range<usize>, base: usize, pscale: &mut [f64]) {
        for i in rows {
            let d = T::value(self.vals, self.dslot[i]).modulus();
            pscale[i - base] = if self.perm[i] < self.n {
                coordinate_scale(d)
            } else {
                let mut s = d.sqrt();
                for &(slot, c) in &self.phi_ent[self.phi_ptr[i]..self.phi_ptr[i + 1]] {
                    s = s.max(T::value(self.vals, slot).modulus() * pscale[c - base]);
                }
                multiplier_scale(s)
            };
        }
    }
}

/// Write the scaled values `K_rc s_r s_c` of one part into its zeroed
/// storage (`lower`, then `diag` at positions from `lower.len()`), `pscale`
/// from permuted row `base`; a non-finite value of `K` is an error naming
/// its row and column.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn load<T: Scalar>(
    fill: &[Fill],
    perm: &[usize],
    vals: T::Values<'_>,
    pscale: &[f64],
    base: usize,
    lower: &mut [T],
    diag: &mut [T],
) -> Result<(), LinalgError> {
    lower.fill(T::ZERO);
    diag.fill(T::ZERO);
    let nl = lower.len();
    for f in fill {
        let v = T::value(vals, f.slot as usize);
        let x = v.scale_sym(pscale[f.row as usize - base], pscale[f.col as usize - base]);
        if !v.is_finite() {
            return Err(LinalgError::NonFinite {
                row: perm[f.row as usize],
                col: perm[f.col as usize],
            });
        }
        let p = f.pos as usize;
        if p < nl {
            lower[p] += x;
        } else {
            diag[p - nl] += x;
        }
    }
    Ok(())
}

/// Regularised pivots of one factorisation: all of them, and those of
/// coordinate rows (a pivot of the `A` part ≤ ε: `A` not positive definite
/// there, [`SolverStats::indefinite_pivots`](crate::linalg::SolverStats)).
#[derive(Debug, Clone, Copy, Default)]
pub(in crate::linalg) struct Regularized {
    pub(in crate::linalg) all: usize,
    pub(in crate::linalg) coordinate: usize,
}

impl std::ops::Add for Regularized {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            all: self.all + o.all,
            coordinate: self.coordinate + o.coordinate,
        }
    }
}

/// `Σ_o v[a + o] v[b + o]`, `o < len`.
fn dot<T: Scalar>(v: &[T], a: usize, b: usize, len: usize) -> T {
    dot2(&v[a..a + len], &v[b..b + len])
}

/// `Σ_i a_i b_i` in index order.
pub(super) fn dot2<T: Scalar>(a: &[T], b: &[T]) -> T {
    a.iter().zip(b).fold(T::ZERO, |s, (&x, &y)| s + x * y)
}

/// Crout (up-looking) LDLᵀ of the plain envelope rows `rows` of one half,
/// whose envelopes stay inside the half: `lower`, `diag`, `dinv` hold that
/// half only (from row `base`, at `env[ptr[base]..]`).
///
/// ```text
/// t_ij = a_ij − Σ_{k<j} t_ik L_jk,   L_ij = t_ij / d_j,   d_i = a_ii − Σ_{j<i} t_ij L_ij
/// ```
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn crout_rows<T: Scalar>(
    first: &[usize],
    ptr: &[usize],
    base: usize,
    rows: std::ops::Range<usize>,
    lower: &mut [T],
    diag: &mut [T],
    dinv: &mut [T],
    rule: &Pivots<'_>,
) -> Result<Regularized, LinalgError> {
    let p0 = ptr[base];
    let mut regularized = Regularized::default();
    for i in rows {
        let (fi, pi) = (first[i], ptr[i] - p0);
        assert!(ptr[i + 1] - p0 <= lower.len() && i - base < dinv.len() && fi >= base);
        for j in fi..i {
            let fj = first[j];
            let k0 = fi.max(fj);
            let (ti, lj) = (pi + (k0 - fi), ptr[j] - p0 + (k0 - fj));
            let mut dot = T::ZERO;
            for o in 0..j - k0 {
                // SAFETY: rows base ≤ j < i lie before row i in `lower`
                // (ptr is increasing, ptr[i + 1] − p0 ≤ len checked above),
                // and k0 + o < j stays inside both rows' envelopes.
                unsafe {
                    dot += *lower.get_unchecked(ti + o) * *lower.get_unchecked(lj + o);
                }
            }
            lower[pi + (j - fi)] -= dot;
        }
        let mut d = diag[i - base];
        for (t, &dj) in lower[pi..ptr[i + 1] - p0]
            .iter_mut()
            .zip(&dinv[fi - base..i - base])
        {
            let l = *t * dj;
            d -= *t * l;
            *t = l;
        }
        let d = d.pivot(i, rule, &mut regularized)?;
        diag[i - base] = d;
        dinv[i - base] = d.recip();
    }
    Ok(regularized)
}
