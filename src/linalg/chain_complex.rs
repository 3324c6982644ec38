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
//! The order, layout, scaling, recurrence and substitutions are the real
//! solver's, written once over the scalar (`chain/scalar.rs`); this type
//! holds the complex factor and checks its input.
//!
//! Cost: one complex multiply-add is four real ones, so a factorisation
//! or solve costs about four times the real one of the same pattern,
//! where the real embedding `[K_r −K_i; K_i K_r]` of size `2 dim` through
//! a sparse LU cost ≈ 50 × (measured in `docs/radau.md`).

use super::chain::{Complex, Envelope, Scatter};
use super::{LinalgError, SaddleMatrix, Storage, DEFAULT_DELTA, DEFAULT_EPSILON};

/// The complex envelope LDLᵀ of one chain pattern (module docs).
#[derive(Debug)]
pub struct ComplexChainLdlt {
    envelope: Envelope<Complex>,
    factorized: bool,
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
        Some(Self {
            envelope: Envelope::analyze(k, split)?,
            factorized: false,
        })
    }

    /// Dimension `n + m`.
    pub fn dim(&self) -> usize {
        self.envelope.dim
    }

    /// Factorise `re + i·im`: two matrices of the analysed pattern (same
    /// storage and slots), the real and the imaginary part. The halves
    /// `T` and `B` (scaling, values, Crout rows) run through
    /// `parallel::join_if` from [`super::PARALLEL_MIN_DIM`] on,
    /// each sequential inside, then the separator: the same bits on one
    /// thread or two. A pivot of modulus at or below `DEFAULT_EPSILON`
    /// (scaled units) is [`LinalgError::Singular`].
    pub fn factorize(&mut self, re: &SaddleMatrix, im: &SaddleMatrix) -> Result<(), LinalgError> {
        let e = &mut self.envelope;
        for k in [re, im] {
            if k.dim() != e.dim || k.nnz() != e.nnz || k.n() != e.n {
                return Err(LinalgError::Dimension {
                    expected: e.dim,
                    got: k.dim(),
                });
            }
        }
        self.factorized = false;
        e.factorize((re.values(), im.values()), DEFAULT_EPSILON, DEFAULT_DELTA)?;
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
        let dim = self.envelope.dim;
        if re.len() != dim || im.len() != dim {
            return Err(LinalgError::Dimension {
                expected: dim,
                got: re.len().min(im.len()),
            });
        }
        if self.envelope.solve(&(Scatter::new(re), Scatter::new(im))) {
            Ok(())
        } else {
            Err(LinalgError::NonFiniteSolution("complex envelope LDLᵀ"))
        }
    }
}

#[cfg(test)]
mod tests;
