//! LDLᵀ of complex symmetric chain-like saddle-point matrices
//! `K = K_r + i K_i` in envelope storage: the complex stage system of
//! Radau IIA ([`crate::formulation::Index3Complex`]; Hairer & Wanner,
//! Solving ODEs II, §IV.8), `[c₀M + c₁C + c₂K, Φ_qᵀ; Φ_q, 0]` with
//! `c₁, c₂ ∈ ℂ`.
//!
//! The matrix is symmetric (not Hermitian): `Kᵀ = K`. Its LDLᵀ without
//! conjugation and without pivoting follows the real envelope
//! factorisation of [`super::ChainLdlt`] in its one-sided body-by-body
//! order (module docs of `chain.rs`: each body's coordinates before the
//! multiplier rows whose highest body it is; the same envelope), with the
//! Crout recurrence in complex arithmetic:
//!
//! ```text
//! t_ij = a_ij − Σ_{k<j} t_ik L_jk,   L_ij = t_ij / d_j,   d_i = a_ii − Σ_{j<i} t_ij L_ij
//! ```
//!
//! Rows and columns are scaled symmetrically (real scale factors keep the
//! matrix symmetric) as the real solver does, with the modulus of the
//! complex diagonal: `1/√|a_ii|` for a coordinate, `1/max(√|a_ii|,
//! maxⱼ |Φ_rj| s_j)` for a multiplier row. There is no sign rule for
//! complex pivots and no regularisation: a pivot of modulus below
//! `DEFAULT_EPSILON` (scaled units) is an error
//! ([`LinalgError::Singular`]), on which the caller falls back to a
//! pivoting LU.
//!
//! Cost: one complex multiply-add is four real ones, so a factorisation
//! or solve costs about four times the real one of the same pattern,
//! where the real embedding `[K_r −K_i; K_i K_r]` of size `2 dim` through
//! a sparse LU cost ≈ 50 × (measured in `docs/radau.md`).

use super::chain::{Envelope, Fill, RowTable, Scatter, PARALLEL_MIN_DIM};
use super::sparse::{coordinate_scale, multiplier_scale};
use super::{LinalgError, SaddleMatrix, Storage, DEFAULT_EPSILON};
use crate::parallel::join_if;

/// A complex number `re + i·im` (the few operations the recurrence needs).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct C {
    re: f64,
    im: f64,
}

impl C {
    const ZERO: C = C { re: 0.0, im: 0.0 };

    #[inline(always)]
    fn mul(self, o: C) -> C {
        C {
            re: self.re * o.re - self.im * o.im,
            im: self.re * o.im + self.im * o.re,
        }
    }

    #[inline(always)]
    fn sub(self, o: C) -> C {
        C {
            re: self.re - o.re,
            im: self.im - o.im,
        }
    }

    #[inline(always)]
    fn scale(self, s: f64) -> C {
        C {
            re: self.re * s,
            im: self.im * s,
        }
    }

    /// Modulus (without `hypot`'s overflow guard: matrix entries are far
    /// from 1e154).
    fn abs(self) -> f64 {
        (self.re * self.re + self.im * self.im).sqrt()
    }

    fn inv(self) -> C {
        let d = self.re * self.re + self.im * self.im;
        C {
            re: self.re / d,
            im: -self.im / d,
        }
    }
}

/// `Σ_o a[o] b[o]` in index order.
#[inline(always)]
fn cdot(a: &[C], b: &[C]) -> C {
    let mut s = C::ZERO;
    for (x, y) in a.iter().zip(b) {
        s = C {
            re: s.re + (x.re * y.re - x.im * y.im),
            im: s.im + (x.re * y.im + x.im * y.re),
        };
    }
    s
}

/// The complex envelope LDLᵀ of one chain pattern (module docs).
#[derive(Debug)]
pub struct ComplexChainLdlt {
    dim: usize,
    n: usize,
    nnz: usize,
    perm: Vec<usize>,
    /// End of the top half `T` and of the bottom half `B` (unsplit:
    /// `s0 = sb = dim`).
    s0: usize,
    sb: usize,
    first: Vec<usize>,
    /// Separator row `sb + r`: first column of its segment in `T`.
    fa: Vec<usize>,
    ptr: Vec<usize>,
    /// Where each value of `K` goes, by part (`T`, `B`, `S`): its slot,
    /// its position in `env` (`L` rows, then the pivots from `ptr[dim]`),
    /// its permuted row and column.
    fill: [Vec<Fill>; 3],
    dslot: Vec<usize>,
    phi_ptr: Vec<usize>,
    phi_ent: Vec<(usize, usize)>,
    /// `L` by rows, then `d`.
    env: Vec<C>,
    dinv: Vec<C>,
    pscale: Vec<f64>,
    /// `y` of `L y = P S b`.
    w: Vec<C>,
    /// `D⁻¹ y`, then `z` of `Lᵀ z = D⁻¹ y` (the backward substitution).
    wd: Vec<C>,
    /// The substitutions' compact copy of `first` and `perm`.
    rows: RowTable,
    factorized: bool,
}

/// What the factorisation of one part reads: the pattern, the values and
/// their slots.
struct Part<'a> {
    n: usize,
    first: &'a [usize],
    ptr: &'a [usize],
    perm: &'a [usize],
    dslot: &'a [usize],
    phi_ptr: &'a [usize],
    phi_ent: &'a [(usize, usize)],
    vr: &'a [f64],
    vi: &'a [f64],
}

impl Part<'_> {
    fn value(&self, s: usize) -> C {
        C {
            re: self.vr[s],
            im: self.vi[s],
        }
    }

    /// `pscale[i − base]` for `rows` (in elimination order: a multiplier
    /// row's Φ_q columns come before it, from row `base` on).
    fn scale(&self, rows: std::ops::Range<usize>, base: usize, pscale: &mut [f64]) {
        for i in rows {
            let d = self.value(self.dslot[i]).abs();
            pscale[i - base] = if self.perm[i] < self.n {
                coordinate_scale(d)
            } else {
                let mut s = d.sqrt();
                for &(slot, c) in &self.phi_ent[self.phi_ptr[i]..self.phi_ptr[i + 1]] {
                    s = s.max(self.value(slot).abs() * pscale[c - base]);
                }
                multiplier_scale(s)
            };
        }
    }

    /// Writes the scaled values of one part (rows from `base`) into its
    /// zeroed storage: `lower` from `env[ptr[base]]`, `diag` from pivot
    /// `base`; `profile = ptr[dim]`, `pscale` from permuted row `ps_base`.
    #[allow(clippy::too_many_arguments)]
    fn load(
        &self,
        fill: &[Fill],
        profile: usize,
        base: usize,
        ps_base: usize,
        pscale: &[f64],
        lower: &mut [C],
        diag: &mut [C],
    ) -> Result<(), LinalgError> {
        lower.fill(C::ZERO);
        diag.fill(C::ZERO);
        let (p0, nl) = (self.ptr[base], lower.len());
        for &Fill {
            slot,
            pos,
            row,
            col,
        } in fill
        {
            let v = self.value(slot as usize);
            if !(v.re.is_finite() && v.im.is_finite()) {
                return Err(LinalgError::NonFinite {
                    row: self.perm[row as usize],
                    col: self.perm[col as usize],
                });
            }
            let x = v.scale(pscale[row as usize - ps_base] * pscale[col as usize - ps_base]);
            let p = pos as usize;
            let e = if p < profile {
                debug_assert!(p - p0 < nl);
                &mut lower[p - p0]
            } else {
                &mut diag[p - profile - base]
            };
            *e = C {
                re: e.re + x.re,
                im: e.im + x.im,
            };
        }
        Ok(())
    }

    /// The Crout recurrence (module docs) of the plain envelope rows
    /// `rows` of one half, whose envelopes stay inside it: `lower`,
    /// `diag`, `dinv` hold that half only (from row `base`).
    fn crout(
        &self,
        base: usize,
        rows: std::ops::Range<usize>,
        lower: &mut [C],
        diag: &mut [C],
        dinv: &mut [C],
    ) -> Result<(), LinalgError> {
        let (first, ptr) = (self.first, self.ptr);
        let p0 = ptr[base];
        for i in rows {
            let (fi, pi) = (first[i], ptr[i] - p0);
            for j in fi..i {
                let k0 = fi.max(first[j]);
                let (ti, lj) = (pi + (k0 - fi), ptr[j] - p0 + (k0 - first[j]));
                let (head, row_i) = lower.split_at_mut(pi);
                let d = cdot(
                    &row_i[ti - pi..ti - pi + (j - k0)],
                    &head[lj..lj + (j - k0)],
                );
                row_i[j - fi] = row_i[j - fi].sub(d);
            }
            let mut d = diag[i - base];
            for (t, &dj) in lower[pi..ptr[i + 1] - p0]
                .iter_mut()
                .zip(&dinv[fi - base..i - base])
            {
                let l = t.mul(dj);
                d = d.sub(t.mul(l));
                *t = l;
            }
            diag[i - base] = self.pivot(i, d)?;
            dinv[i - base] = d.inv();
        }
        Ok(())
    }

    /// `d` as the pivot of elimination step `i`, or the error for a
    /// modulus at or below `DEFAULT_EPSILON` (or NaN).
    fn pivot(&self, i: usize, d: C) -> Result<C, LinalgError> {
        if d.abs().is_nan() || d.abs() <= DEFAULT_EPSILON {
            return Err(LinalgError::Singular(format!(
                "complex envelope LDLᵀ: pivot {:.3e} at elimination step {i} (row {} of K)",
                d.abs(),
                self.perm[i]
            )));
        }
        Ok(d)
    }
}

impl ComplexChainLdlt {
    /// The envelope of `k`'s pattern (symmetric lower storage) in the
    /// body-by-body order of [`super::ChainLdlt`], two-sided where the real
    /// one is (from [`super::SPLIT_MIN_DIM`]), or `None` when the pattern
    /// is not a chain's (the real solver would fall back to faer too).
    pub fn analyze(k: &SaddleMatrix) -> Option<Self> {
        Self::analyze_order(k, true)
    }

    /// [`Self::analyze`] in the two-sided order when `split` (and the
    /// pattern allows it), else in the one-sided one.
    fn analyze_order(k: &SaddleMatrix, split: bool) -> Option<Self> {
        if k.storage() != Storage::SymmetricLower {
            return None;
        }
        let Envelope {
            dim,
            n,
            nnz,
            perm,
            s0,
            sb,
            first,
            fa,
            ptr,
            mut fill,
            dslot,
            phi_ptr,
            phi_ent,
            rows,
            ..
        } = Envelope::analyze(k, split)?;
        let profile = ptr[dim];
        // positions in each part's storage → positions in `env`, in place
        // (no second copy of the slot map)
        let parts = [0..s0, s0..sb, sb..dim];
        for (part, r) in fill.iter_mut().zip(&parts) {
            let (p0, nl) = (ptr[r.start], ptr[r.end] - ptr[r.start]);
            for f in part.iter_mut() {
                let pos = f.pos as usize;
                let g = if pos < nl {
                    p0 + pos
                } else {
                    profile + r.start + (pos - nl)
                };
                f.pos = g as u32;
            }
        }
        Some(Self {
            dim,
            n,
            nnz,
            perm,
            s0,
            sb,
            first,
            fa,
            ptr,
            fill,
            dslot,
            phi_ptr,
            phi_ent,
            env: vec![C::ZERO; profile + dim],
            dinv: vec![C::ZERO; dim],
            pscale: vec![1.0; dim],
            rows,
            w: vec![C::ZERO; dim],
            wd: vec![C::ZERO; dim],
            factorized: false,
        })
    }

    /// Dimension `n + m`.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Factorise `re + i·im`: two matrices of the analysed pattern (same
    /// storage and slots), the real and the imaginary part. The halves
    /// `T` and `B` (scaling, values, Crout rows) run through
    /// `parallel::join_if` from [`super::PARALLEL_MIN_DIM`] on,
    /// each sequential inside, then the separator: the same bits on one
    /// thread or two.
    pub fn factorize(&mut self, re: &SaddleMatrix, im: &SaddleMatrix) -> Result<(), LinalgError> {
        for k in [re, im] {
            if k.dim() != self.dim || k.nnz() != self.nnz || k.n() != self.n {
                return Err(LinalgError::Dimension {
                    expected: self.dim,
                    got: k.dim(),
                });
            }
        }
        self.factorized = false;
        let (dim, s0, sb) = (self.dim, self.s0, self.sb);
        let par = dim >= PARALLEL_MIN_DIM;
        let part = Part {
            n: self.n,
            first: &self.first,
            ptr: &self.ptr,
            perm: &self.perm,
            dslot: &self.dslot,
            phi_ptr: &self.phi_ptr,
            phi_ent: &self.phi_ent,
            vr: re.values(),
            vi: im.values(),
        };
        let (ptr, first, fa) = (&self.ptr, &self.first, &self.fa);
        let profile = ptr[dim];
        let (lower, diag) = self.env.split_at_mut(profile);
        let (lower_t, lower_rest) = lower.split_at_mut(ptr[s0]);
        let lower_b = &mut lower_rest[..ptr[sb] - ptr[s0]];
        let (diag_t, diag_rest) = diag.split_at_mut(s0);
        let diag_b = &mut diag_rest[..sb - s0];
        let (dinv_t, dinv_rest) = self.dinv.split_at_mut(s0);
        let dinv_b = &mut dinv_rest[..sb - s0];
        let (ps_t, ps_rest) = self.pscale.split_at_mut(s0);
        let ps_b = &mut ps_rest[..sb - s0];
        let (fill_t, fill_b) = (&self.fill[0], &self.fill[1]);
        let part = &part;
        let (rt, rb) = join_if(
            par,
            || {
                part.scale(0..s0, 0, ps_t);
                part.load(fill_t, profile, 0, 0, ps_t, lower_t, diag_t)?;
                part.crout(0, 0..s0, lower_t, diag_t, dinv_t)
            },
            || {
                part.scale(s0..sb, s0, ps_b);
                part.load(fill_b, profile, s0, s0, ps_b, lower_b, diag_b)?;
                part.crout(s0, s0..sb, lower_b, diag_b, dinv_b)
            },
        );
        rt?;
        rb?;
        if sb < dim {
            part.scale(sb..dim, 0, &mut self.pscale);
            let (lower, diag) = self.env.split_at_mut(profile);
            part.load(
                &self.fill[2],
                profile,
                sb,
                0,
                &self.pscale,
                &mut lower[ptr[sb]..],
                &mut diag[sb..],
            )?;
            // the separator: two-segment rows against every row before them
            let dinv = &mut self.dinv;
            for i in sb..dim {
                let (fai, fi, pi) = (fa[i - sb], first[i], ptr[i]);
                let la = s0 - fai;
                // the T segment against plain rows j of T
                for j in fai..s0 {
                    let k0 = fai.max(first[j]);
                    let (a, b, len) = (pi + (k0 - fai), ptr[j] + (k0 - first[j]), j - k0);
                    let d = cdot(&lower[a..a + len], &lower[b..b + len]);
                    let e = pi + (j - fai);
                    lower[e] = lower[e].sub(d);
                }
                // the second segment against rows of B (plain) and of S
                // (two segments)
                for j in fi..i {
                    let la_j = if j >= sb { s0 - fa[j - sb] } else { 0 };
                    let k0 = fi.max(first[j]);
                    let (a, b, len) =
                        (pi + la + (k0 - fi), ptr[j] + la_j + (k0 - first[j]), j - k0);
                    let mut d = cdot(&lower[a..a + len], &lower[b..b + len]);
                    if j >= sb {
                        let k0 = fai.max(fa[j - sb]);
                        let (a, b, len) = (pi + (k0 - fai), ptr[j] + (k0 - fa[j - sb]), s0 - k0);
                        let d2 = cdot(&lower[a..a + len], &lower[b..b + len]);
                        d = C {
                            re: d.re + d2.re,
                            im: d.im + d2.im,
                        };
                    }
                    let e = pi + la + (j - fi);
                    lower[e] = lower[e].sub(d);
                }
                let mut d = diag[i];
                for (o, j) in (fai..s0).chain(fi..i).enumerate() {
                    let t = lower[pi + o];
                    let l = t.mul(dinv[j]);
                    d = d.sub(t.mul(l));
                    lower[pi + o] = l;
                }
                diag[i] = part.pivot(i, d)?;
                dinv[i] = d.inv();
            }
        }
        self.factorized = true;
        Ok(())
    }

    /// `re + i·im ← K⁻¹ (re + i·im)` with the last factorisation:
    /// `L y = P S b` (the halves, then the separator; each row writes `y_i`
    /// and `y_i / d_i`), `Lᵀ z = D⁻¹ y` by columns from the last row (the
    /// separator, then the halves), `x = S Pᵀ z`, each entry checked as
    /// it is written; the halves through `parallel::join_if` as in
    /// [`Self::factorize`]. Errors when no factorisation is ready, on a
    /// length mismatch, or when the solution is not finite.
    pub fn solve(&mut self, re: &mut [f64], im: &mut [f64]) -> Result<(), LinalgError> {
        if !self.factorized {
            return Err(LinalgError::NotReady("factorize"));
        }
        if re.len() != self.dim || im.len() != self.dim {
            return Err(LinalgError::Dimension {
                expected: self.dim,
                got: re.len().min(im.len()),
            });
        }
        let (dim, s0, sb) = (self.dim, self.s0, self.sb);
        let par = dim >= PARALLEL_MIN_DIM;
        let (first, ptr, ps, fa) = (&self.first, &self.ptr, &self.pscale, &self.fa);
        let env = &self.env[..ptr[dim]];
        let (w, wd) = (&mut self.w, &mut self.wd);
        let rows = CRows {
            len: &self.rows.len,
            ptr,
            env,
            perm: &self.rows.perm,
            pscale: ps,
            dinv: &self.dinv,
        };
        // two threads: a half each; one: the halves one after the other (the
        // rows of a complex substitution are bound by their arithmetic, not
        // by the latency of the row chain, so they are not interleaved as
        // the real solver's are), as the team decides in `join_if`; the
        // pass counted once for an `Auto` team's A/B rule (`concurrent`).
        // The forward rows write y (`w`: the separator's forward rows read
        // it) and D⁻¹ y (`wd`: where the backward substitution starts), so
        // D⁻¹ needs no pass of its own; the backward rows check the
        // entries they write: two passes in halves
        let _pass = par && crate::parallel::concurrent();
        {
            let (br, bi): (&[f64], &[f64]) = (re, im);
            let (w_t, w_rest) = w.split_at_mut(s0);
            let w_b = &mut w_rest[..sb - s0];
            let (wd_t, wd_rest) = wd.split_at_mut(s0);
            let wd_b = &mut wd_rest[..sb - s0];
            join_if(
                par,
                || rows.forward((br, bi), (0, 0..s0, w_t, wd_t)),
                || rows.forward((br, bi), (s0, s0..sb, w_b, wd_b)),
            );
            for i in sb..dim {
                let (fai, fi, pi) = (fa[i - sb], first[i], ptr[i]);
                let la = s0 - fai;
                w[i] = rows
                    .rhs((br, bi), i)
                    .sub(cdot(&env[pi..pi + la], &w[fai..s0]))
                    .sub(cdot(&env[pi + la..ptr[i + 1]], &w[fi..i]));
                wd[i] = w[i].mul(self.dinv[i]);
            }
        }
        let out = (Scatter::new(re), Scatter::new(im));
        let mut bad = 0.0;
        for i in (sb..dim).rev() {
            let (fai, fi, pi, z) = (fa[i - sb], first[i], ptr[i], wd[i]);
            bad += rows.put(&out, i, z);
            let la = s0 - fai;
            for (v, &l) in wd[fai..s0].iter_mut().zip(&env[pi..pi + la]) {
                *v = v.sub(l.mul(z));
            }
            for (v, &l) in wd[fi..i].iter_mut().zip(&env[pi + la..ptr[i + 1]]) {
                *v = v.sub(l.mul(z));
            }
        }
        let (wd_t, wd_rest) = wd.split_at_mut(s0);
        let wd_b = &mut wd_rest[..sb - s0];
        let (lo, hi) = join_if(
            par,
            || rows.backward(&out, (0, 0..s0, wd_t)),
            || rows.backward(&out, (s0, s0..sb, wd_b)),
        );
        if bad == 0.0 && lo && hi {
            Ok(())
        } else {
            Err(LinalgError::NonFiniteSolution("complex envelope LDLᵀ"))
        }
    }
}

/// What the substitutions read of a complex factorisation: the envelope
/// rows (their lengths [`RowTable`], where each half's rows start in
/// `ptr`, `env`), the permutation and the symmetric scaling (the
/// right-hand side's entry `perm[i]` is row `i`'s, times `pscale[i]`);
/// the complex counterpart of the real solver's rows (`chain/solve.rs`),
/// with the same register carries.
#[derive(Clone, Copy)]
struct CRows<'a> {
    len: &'a [u8],
    ptr: &'a [usize],
    env: &'a [C],
    perm: &'a [u32],
    pscale: &'a [f64],
    /// `1/d_i`.
    dinv: &'a [C],
}

/// One half's plain rows for a substitution: the first row's index
/// (`base`), the rows and their part of the work vector.
type CHalf<'a> = (usize, std::ops::Range<usize>, &'a mut [C]);

/// One half's plain rows for the forward substitution: as [`CHalf`], with
/// the half's part of `D⁻¹ y` (written beside `y`).
type CHalfFwd<'a> = (usize, std::ops::Range<usize>, &'a mut [C], &'a mut [C]);

/// The right-hand side's real and imaginary parts.
type Rhs<'a> = (&'a [f64], &'a [f64]);

/// The solution's real and imaginary parts, written through the
/// permutation.
type Out<'a> = (Scatter<'a>, Scatter<'a>);

impl CRows<'_> {
    /// `(P S b)_i`: row `i`'s entry of the permuted, scaled right-hand side.
    #[inline(always)]
    fn rhs(&self, (br, bi): Rhs<'_>, i: usize) -> C {
        let p = self.perm[i] as usize;
        C {
            re: br[p],
            im: bi[p],
        }
        .scale(self.pscale[i])
    }

    /// `x_{perm[i]} = z_i s_i`; returns `re · 0 + im · 0` of the entry,
    /// zero when both parts are finite, else NaN (the backward rows sum
    /// it: no branch).
    #[inline(always)]
    fn put(&self, (re, im): &Out<'_>, i: usize, z: C) -> f64 {
        let (p, s) = (self.perm[i] as usize, self.pscale[i]);
        let (xr, xi) = (z.re * s, z.im * s);
        re.set(p, xr);
        im.set(p, xi);
        xr * 0.0 + xi * 0.0
    }

    /// Forward substitution `L y = P S b` over the plain rows of one half
    /// (`y` into `w`, `D⁻¹ y` into `wd`, from row `base`).
    fn forward(&self, b: Rhs<'_>, (base, rows, w, wd): CHalfFwd<'_>) {
        let (mut prev, mut p) = (C::ZERO, self.ptr[rows.start]);
        let (dinv, wd) = (&self.dinv[rows.clone()], &mut wd[rows.start - base..]);
        for (k, i) in rows.enumerate() {
            prev = self.forward_row(b, base, i, w, prev, &mut p);
            wd[k] = prev.mul(dinv[k]);
        }
    }

    /// Row `i` of [`Self::forward`]: `y_i = (P S b)_i − Σ_j L_ij y_j` over
    /// its envelope `[first[i], i)`, whose last column is `i − 1` when not
    /// empty: `prev = y_{i−1}` comes from the register, not from `w`, so
    /// the chain of dependent rows does not wait on a store and a reload.
    /// Its entries start at `env[*p]`, and `*p` moves on to the next
    /// row's. The terms are added in column order (the same bits as one
    /// `cdot`).
    #[inline(always)]
    fn forward_row(
        &self,
        b: Rhs<'_>,
        base: usize,
        i: usize,
        w: &mut [C],
        prev: C,
        p: &mut usize,
    ) -> C {
        let (env, len, pi) = (self.env, usize::from(self.len[i]), *p);
        *p = pi + len;
        assert!(pi + len <= env.len() && i - base < w.len() && len <= i - base);
        let fi = i - len;
        let mut y = self.rhs(b, i);
        if len > 0 {
            let mut s = cdot(&env[pi..pi + len - 1], &w[fi - base..i - base - 1]);
            let l = env[pi + len - 1];
            s = C {
                re: s.re + (l.re * prev.re - l.im * prev.im),
                im: s.im + (l.re * prev.im + l.im * prev.re),
            };
            y = y.sub(s);
        }
        w[i - base] = y;
        y
    }

    /// Backward substitution `Lᵀ z = w` over the plain rows of one half,
    /// from the last (`w` from row `base`); each `z_i`, final once its row
    /// is reached, goes to the solution at once. Returns whether every
    /// entry it wrote is finite.
    fn backward(&self, out: &Out<'_>, (base, rows, w): CHalf<'_>) -> bool {
        let (mut carry, mut bad, mut p) = ((C::ZERO, C::ZERO), 0.0, self.ptr[rows.end]);
        for i in rows.rev() {
            carry = self.backward_row(out, base, i, w, carry, (&mut bad, &mut p));
        }
        bad == 0.0
    }

    /// Row `i` of [`Self::backward`]: `z_i = w_i − L_{i+1,i} z_{i+1}` with
    /// the row after's last update `carry = (L_{i+1,i}, z_{i+1})` from the
    /// register, then `w_j −= L_ij z_i` over the envelope but its last
    /// column `i − 1`, returned as the next row's carry. Each `w_j` gets
    /// its updates in the same order as without the carry (the same bits).
    /// Adds [`Self::put`]'s check of the entry written to `bad`. Its
    /// entries end at `env[*p]`, and `*p` moves back to where they start.
    #[inline(always)]
    fn backward_row(
        &self,
        out: &Out<'_>,
        base: usize,
        i: usize,
        w: &mut [C],
        carry: (C, C),
        (bad, p): (&mut f64, &mut usize),
    ) -> (C, C) {
        let (env, len) = (self.env, usize::from(self.len[i]));
        assert!(len <= *p && *p <= env.len() && len <= i - base);
        let pi = *p - len;
        *p = pi;
        let zi = w[i - base].sub(carry.0.mul(carry.1));
        *bad += self.put(out, i, zi);
        if len == 0 {
            return (C::ZERO, C::ZERO);
        }
        let fi = i - len;
        for (v, &l) in w[fi - base..i - base - 1]
            .iter_mut()
            .zip(&env[pi..pi + len - 1])
        {
            *v = v.sub(l.mul(zi));
        }
        (env[pi + len - 1], zi)
    }
}

#[cfg(test)]
mod tests;
