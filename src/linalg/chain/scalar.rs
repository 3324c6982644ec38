//! The scalars of the envelope LDLᵀ: `f64` ([`super::ChainLdlt`]) and
//! [`Complex`] ([`crate::linalg::ComplexChainLdlt`], the complex symmetric
//! stage matrices of Radau IIA). The factorisation and the substitutions
//! ([`super::factor`], [`super::solve`]) are written once over
//! [`Scalar`]: the ring operations, the few real-valued ones the scaling
//! and the checks need, the pivot rule, and how values, right-hand side
//! and solution are stored.

use std::ops::{Add, AddAssign, Mul, Sub, SubAssign};

use super::factor::Regularized;
use super::solve::Scatter;
use crate::linalg::LinalgError;

/// A number `re + i·im` (without conjugation: the matrices are complex
/// symmetric, `Kᵀ = K`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(in crate::linalg) struct Complex {
    pub(in crate::linalg) re: f64,
    pub(in crate::linalg) im: f64,
}

impl Add for Complex {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self {
            re: self.re + o.re,
            im: self.im + o.im,
        }
    }
}

impl Sub for Complex {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self {
            re: self.re - o.re,
            im: self.im - o.im,
        }
    }
}

impl AddAssign for Complex {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl SubAssign for Complex {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

impl Mul for Complex {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self {
            re: self.re * o.re - self.im * o.im,
            im: self.re * o.im + self.im * o.re,
        }
    }
}

/// What the envelope LDLᵀ needs of its entries. Sums and products are
/// evaluated in the order the loops write them (no fused operations), so
/// a solver's bits depend only on its scalar and its pattern.
pub(in crate::linalg) trait Scalar:
    Copy
    + Send
    + Sync
    + std::fmt::Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + AddAssign
    + SubAssign
{
    const ZERO: Self;

    /// Whether the one-thread form of a substitution takes a row of each
    /// half in turn: a real row is bound by the latency of the row chain,
    /// so two chains in flight overlap; a complex row by its arithmetic,
    /// so its halves run one after the other.
    const INTERLEAVE: bool;

    /// The values of `K` by slot: `&[f64]`, or the real and the imaginary
    /// part's.
    type Values<'a>: Copy + Send + Sync;

    /// The right-hand side, overwritten by the solution through the
    /// permutation: one [`Scatter`], or one per part.
    type Vector<'a>: Sync;

    /// Entry `s` of the values.
    fn value(v: Self::Values<'_>, s: usize) -> Self;

    /// The length of the right-hand side (of its shortest part).
    fn len(x: &Self::Vector<'_>) -> usize;

    /// Entry `p` of the right-hand side.
    ///
    /// # Safety
    /// `p` is below [`Self::len`].
    unsafe fn get(x: &Self::Vector<'_>, p: usize) -> Self;

    /// Write entry `p` of the solution; returns `x · 0` summed over its
    /// parts: zero when it is finite, NaN when not.
    ///
    /// # Safety
    /// `p` is below [`Self::len`].
    unsafe fn put(x: &Self::Vector<'_>, p: usize, v: Self) -> f64;

    /// `self · s` for a real `s`.
    fn scale(self, s: f64) -> Self;

    /// The scaled entry `K_rc s_r s_c`; `f64` multiplies by `s_r`, then by
    /// `s_c` (the rounding of [`crate::linalg::SparseLdlt`]'s scaling),
    /// [`Complex`] by the product `s_r s_c`.
    fn scale_sym(self, s_r: f64, s_c: f64) -> Self;

    /// `|self|`, for the scaling (`saddle_scaling`).
    fn modulus(self) -> f64;

    /// `1 / self`.
    fn recip(self) -> Self;

    /// Are all parts finite?
    fn is_finite(self) -> bool;

    /// `self − (a + b)` for `f64`, `(self − a) − b` for [`Complex`]: a
    /// separator row's forward step over its two envelope segments.
    fn minus_segments(self, a: Self, b: Self) -> Self;

    /// Pivot `d` of elimination step `i` under `rule`: `f64` replaces a
    /// pivot of the wrong sign or within `ε` of 0 by `δ` with the expected
    /// sign (counted, [`crate::linalg::SparseLdlt`]'s regularisation) and
    /// errs on a non-finite one; [`Complex`] has no sign rule and errs on a
    /// modulus at or below `ε` (or NaN), on which the caller falls back to a
    /// pivoting LU.
    fn pivot(
        self,
        i: usize,
        rule: &Pivots<'_>,
        regularized: &mut Regularized,
    ) -> Result<Self, LinalgError>;
}

/// The pivot rule's data: expected signs and rows of `K` (permuted
/// numbering), `ε`, `δ`.
pub(in crate::linalg) struct Pivots<'a> {
    pub(in crate::linalg) positive: &'a [bool],
    pub(in crate::linalg) perm: &'a [usize],
    pub(in crate::linalg) epsilon: f64,
    pub(in crate::linalg) delta: f64,
}

impl Scalar for f64 {
    const ZERO: Self = 0.0;
    const INTERLEAVE: bool = true;
    type Values<'a> = &'a [f64];
    type Vector<'a> = Scatter<'a>;

    #[inline(always)]
    fn value(v: &[f64], s: usize) -> f64 {
        v[s]
    }

    fn len(x: &Scatter<'_>) -> usize {
        x.len()
    }

    #[inline(always)]
    unsafe fn get(x: &Scatter<'_>, p: usize) -> f64 {
        // SAFETY: p < x's length (the contract)
        unsafe { x.get(p) }
    }

    #[inline(always)]
    unsafe fn put(x: &Scatter<'_>, p: usize, v: f64) -> f64 {
        // SAFETY: p < x's length (the contract)
        unsafe { x.set(p, v) };
        v * 0.0
    }

    #[inline(always)]
    fn scale(self, s: f64) -> f64 {
        self * s
    }

    #[inline(always)]
    fn scale_sym(self, s_r: f64, s_c: f64) -> f64 {
        self * s_r * s_c
    }

    #[inline(always)]
    fn modulus(self) -> f64 {
        self.abs()
    }

    #[inline(always)]
    fn recip(self) -> f64 {
        1.0 / self
    }

    #[inline(always)]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }

    #[inline(always)]
    fn minus_segments(self, a: f64, b: f64) -> f64 {
        self - (a + b)
    }

    fn pivot(self, i: usize, rule: &Pivots<'_>, reg: &mut Regularized) -> Result<f64, LinalgError> {
        let d = if rule.positive[i] {
            if self <= rule.epsilon {
                reg.all += 1;
                reg.coordinate += 1;
                rule.delta
            } else {
                self
            }
        } else if self >= -rule.epsilon {
            reg.all += 1;
            -rule.delta
        } else {
            self
        };
        if !d.is_finite() {
            return Err(LinalgError::Singular(format!(
                "envelope LDLᵀ: non-finite pivot at elimination step {i}"
            )));
        }
        Ok(d)
    }
}

impl Scalar for Complex {
    const ZERO: Self = Complex { re: 0.0, im: 0.0 };
    const INTERLEAVE: bool = false;
    type Values<'a> = (&'a [f64], &'a [f64]);
    type Vector<'a> = (Scatter<'a>, Scatter<'a>);

    #[inline(always)]
    fn value((re, im): (&[f64], &[f64]), s: usize) -> Self {
        Complex {
            re: re[s],
            im: im[s],
        }
    }

    fn len((re, im): &(Scatter<'_>, Scatter<'_>)) -> usize {
        re.len().min(im.len())
    }

    #[inline(always)]
    unsafe fn get((re, im): &(Scatter<'_>, Scatter<'_>), p: usize) -> Self {
        // SAFETY: p < both parts' lengths (the contract)
        unsafe {
            Complex {
                re: re.get(p),
                im: im.get(p),
            }
        }
    }

    #[inline(always)]
    unsafe fn put((re, im): &(Scatter<'_>, Scatter<'_>), p: usize, v: Self) -> f64 {
        // SAFETY: p < both parts' lengths (the contract)
        unsafe {
            re.set(p, v.re);
            im.set(p, v.im);
        }
        v.re * 0.0 + v.im * 0.0
    }

    #[inline(always)]
    fn scale(self, s: f64) -> Self {
        Complex {
            re: self.re * s,
            im: self.im * s,
        }
    }

    #[inline(always)]
    fn scale_sym(self, s_r: f64, s_c: f64) -> Self {
        self.scale(s_r * s_c)
    }

    /// Without `hypot`'s overflow guard: matrix entries are far from 1e154.
    #[inline(always)]
    fn modulus(self) -> f64 {
        (self.re * self.re + self.im * self.im).sqrt()
    }

    #[inline(always)]
    fn recip(self) -> Self {
        let d = self.re * self.re + self.im * self.im;
        Complex {
            re: self.re / d,
            im: -self.im / d,
        }
    }

    #[inline(always)]
    fn is_finite(self) -> bool {
        self.re.is_finite() && self.im.is_finite()
    }

    #[inline(always)]
    fn minus_segments(self, a: Self, b: Self) -> Self {
        self - a - b
    }

    fn pivot(self, i: usize, rule: &Pivots<'_>, _: &mut Regularized) -> Result<Self, LinalgError> {
        let m = self.modulus();
        if m.is_nan() || m <= rule.epsilon {
            return Err(LinalgError::Singular(format!(
                "complex envelope LDLᵀ: pivot {m:.3e} at elimination step {i} (row {} of K)",
                rule.perm[i]
            )));
        }
        Ok(self)
    }
}
