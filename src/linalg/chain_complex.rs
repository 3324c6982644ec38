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

use super::chain::Envelope;
use super::sparse::{coordinate_scale, multiplier_scale};
use super::{LinalgError, SaddleMatrix, Storage, DEFAULT_EPSILON};

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
    first: Vec<usize>,
    ptr: Vec<usize>,
    /// Where each value of `K` goes: its slot, its position in `env` (`L`
    /// rows, then the pivots from `ptr[dim]`), its permuted row and column.
    fill: Vec<(u32, u32, u32, u32)>,
    dslot: Vec<usize>,
    phi_ptr: Vec<usize>,
    phi_ent: Vec<(usize, usize)>,
    /// `L` by rows, then `d`.
    env: Vec<C>,
    dinv: Vec<C>,
    pscale: Vec<f64>,
    w: Vec<C>,
    factorized: bool,
}

impl ComplexChainLdlt {
    /// The envelope of `k`'s pattern (symmetric lower storage) in the
    /// one-sided body-by-body order, or `None` when the pattern is not a
    /// chain's (the real [`super::ChainLdlt`] would fall back to faer too).
    pub fn analyze(k: &SaddleMatrix) -> Option<Self> {
        if k.storage() != Storage::SymmetricLower {
            return None;
        }
        let Envelope {
            dim,
            n,
            nnz,
            perm,
            first,
            ptr,
            fill,
            dslot,
            phi_ptr,
            phi_ent,
            ..
        } = Envelope::analyze(k, false)?;
        let [fill, _, _] = fill;
        let fill = fill.iter().map(|f| (f.slot, f.pos, f.row, f.col)).collect();
        let profile = ptr[dim];
        Some(Self {
            dim,
            n,
            nnz,
            perm,
            first,
            ptr,
            fill,
            dslot,
            phi_ptr,
            phi_ent,
            env: vec![C::ZERO; profile + dim],
            dinv: vec![C::ZERO; dim],
            pscale: vec![1.0; dim],
            w: vec![C::ZERO; dim],
            factorized: false,
        })
    }

    /// Dimension `n + m`.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Factorise `re + i·im`: two matrices of the analysed pattern (same
    /// storage and slots), the real and the imaginary part.
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
        let (vr, vi) = (re.values(), im.values());
        let value = |s: usize| C {
            re: vr[s],
            im: vi[s],
        };
        // scaling in elimination order (a multiplier row's Φ_q columns are
        // eliminated before it)
        for i in 0..self.dim {
            let d = value(self.dslot[i]).abs();
            self.pscale[i] = if self.perm[i] < self.n {
                coordinate_scale(d)
            } else {
                let mut s = d.sqrt();
                for &(slot, c) in &self.phi_ent[self.phi_ptr[i]..self.phi_ptr[i + 1]] {
                    s = s.max(value(slot).abs() * self.pscale[c]);
                }
                multiplier_scale(s)
            };
        }
        self.env.fill(C::ZERO);
        let profile = self.ptr[self.dim];
        for &(slot, pos, row, col) in &self.fill {
            let v = value(slot as usize);
            if !(v.re.is_finite() && v.im.is_finite()) {
                return Err(LinalgError::NonFinite {
                    row: self.perm[row as usize],
                    col: self.perm[col as usize],
                });
            }
            let x = v.scale(self.pscale[row as usize] * self.pscale[col as usize]);
            let p = pos as usize;
            self.env[p] = C {
                re: self.env[p].re + x.re,
                im: self.env[p].im + x.im,
            };
        }
        let (lower, diag) = self.env.split_at_mut(profile);
        let (first, ptr) = (&self.first, &self.ptr);
        for i in 0..self.dim {
            let (fi, pi) = (first[i], ptr[i]);
            for j in fi..i {
                let k0 = fi.max(first[j]);
                let (ti, lj) = (pi + (k0 - fi), ptr[j] + (k0 - first[j]));
                let (head, row_i) = lower.split_at_mut(pi);
                let d = cdot(
                    &row_i[ti - pi..ti - pi + (j - k0)],
                    &head[lj..lj + (j - k0)],
                );
                row_i[j - fi] = row_i[j - fi].sub(d);
            }
            let mut d = diag[i];
            for (t, &dj) in lower[pi..ptr[i + 1]].iter_mut().zip(&self.dinv[fi..i]) {
                let l = t.mul(dj);
                d = d.sub(t.mul(l));
                *t = l;
            }
            if d.abs().is_nan() || d.abs() <= DEFAULT_EPSILON {
                return Err(LinalgError::Singular(format!(
                    "complex envelope LDLᵀ: pivot {:.3e} at elimination step {i} (row {} of K)",
                    d.abs(),
                    self.perm[i]
                )));
            }
            diag[i] = d;
            self.dinv[i] = d.inv();
        }
        self.factorized = true;
        Ok(())
    }

    /// `re + i·im ← K⁻¹ (re + i·im)` with the last factorisation:
    /// `L y = P S b`, `D`, `Lᵀ z = y` by columns from the last row,
    /// `x = S Pᵀ z`. Errors when no factorisation is ready, on a length
    /// mismatch, or when the solution is not finite.
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
        let (first, ptr, perm, ps) = (&self.first, &self.ptr, &self.perm, &self.pscale);
        let env = &self.env[..ptr[self.dim]];
        let w = &mut self.w;
        for i in 0..self.dim {
            let b = C {
                re: re[perm[i]],
                im: im[perm[i]],
            }
            .scale(ps[i]);
            let (fi, pi) = (first[i], ptr[i]);
            w[i] = b.sub(cdot(&env[pi..ptr[i + 1]], &w[fi..i]));
        }
        for (wi, &d) in w.iter_mut().zip(&self.dinv) {
            *wi = wi.mul(d);
        }
        for i in (0..self.dim).rev() {
            let z = w[i];
            let x = z.scale(ps[i]);
            re[perm[i]] = x.re;
            im[perm[i]] = x.im;
            let (fi, pi) = (first[i], ptr[i]);
            for (v, &l) in w[fi..i].iter_mut().zip(&env[pi..ptr[i + 1]]) {
                *v = v.sub(l.mul(z));
            }
        }
        if re.iter().chain(im.iter()).all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(LinalgError::NonFiniteSolution("complex envelope LDLᵀ"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{APattern, Symmetry};

    /// A chain-like saddle matrix: `bodies` bodies of 3 coordinates, a
    /// 2-row joint between neighbours, springs coupling neighbouring
    /// angles; values from `seed`.
    fn chain_pair(bodies: usize, seed: u64) -> (SaddleMatrix, SaddleMatrix) {
        let n = 3 * bodies;
        let mut a_entries = Vec::new();
        for b in 0..bodies {
            for i in 0..3 {
                for j in 0..=i {
                    a_entries.push((3 * b + i, 3 * b + j));
                }
            }
            if b + 1 < bodies {
                a_entries.push((3 * b + 5, 3 * b + 2));
            }
        }
        let mut jac = Vec::new();
        for jn in 0..bodies - 1 {
            for r in 0..2 {
                for c in [3 * jn + r, 3 * jn + 2, 3 * jn + 3 + r, 3 * jn + 5] {
                    jac.push((2 * jn + r, c));
                }
            }
        }
        let m = 2 * (bodies - 1);
        let mut a = APattern::new();
        a.push_block(&a_entries, Symmetry::Symmetric);
        let mut state = seed;
        let mut rnd = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut mats =
            [(); 2].map(|()| SaddleMatrix::with_storage(n, m, &a, &jac, Storage::SymmetricLower));
        for (part, k) in mats.iter_mut().enumerate() {
            k.set_zero();
            for (id, &(i, j)) in a_entries.iter().enumerate() {
                // a diagonally dominant real part, a smaller imaginary one
                let v = if i == j { 4.0 + rnd() } else { 0.5 * rnd() };
                k.add_a(id, if part == 0 { v } else { 0.3 * rnd() + 0.1 * v });
            }
            let jv: Vec<f64> = jac
                .iter()
                .map(|_| if part == 0 { 1.0 + rnd() } else { 0.0 })
                .collect();
            k.set_jacobian(&jv);
        }
        let [re, im] = mats;
        (re, im)
    }

    /// The residual `(K_r + i K_i)(x_r + i x_i) − b` of the solution,
    /// computed with the two real matrices' products (independent of the
    /// factorisation), is at rounding level.
    #[test]
    fn solves_complex_symmetric_chain_systems() {
        for bodies in [2, 5, 40] {
            let (kr, ki) = chain_pair(bodies, bodies as u64);
            let mut f = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
            f.factorize(&kr, &ki).expect("nonsingular");
            let dim = kr.dim();
            let br: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.37).sin()).collect();
            let bi: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.11).cos()).collect();
            let (mut xr, mut xi) = (br.clone(), bi.clone());
            f.solve(&mut xr, &mut xi).expect("finite");
            let mul = |k: &SaddleMatrix, x: &[f64]| {
                let mut y = vec![0.0; dim];
                k.mul_vec(x, &mut y);
                y
            };
            let (rr, ii, ri, ir) = (mul(&kr, &xr), mul(&ki, &xi), mul(&kr, &xi), mul(&ki, &xr));
            let mut worst: f64 = 0.0;
            for i in 0..dim {
                worst = worst
                    .max((rr[i] - ii[i] - br[i]).abs())
                    .max((ri[i] + ir[i] - bi[i]).abs());
            }
            assert!(worst < 1e-12, "N = {bodies}: residual {worst:e}");
            // the imaginary part matters: solving with K_r alone is far off
            let mut g = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
            let zero = {
                let mut z = ki.clone();
                z.set_zero();
                z
            };
            g.factorize(&kr, &zero).expect("nonsingular");
            let (mut yr, mut yi) = (br.clone(), bi.clone());
            g.solve(&mut yr, &mut yi).expect("finite");
            let diff = yr
                .iter()
                .zip(&xr)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(diff > 1e-3, "N = {bodies}: K_i had no effect ({diff:e})");
        }
    }

    #[test]
    fn errors_before_factorisation_and_on_singular_pivots() {
        let (kr, ki) = chain_pair(3, 7);
        let mut f = ComplexChainLdlt::analyze(&kr).expect("a chain pattern");
        let dim = kr.dim();
        let (mut a, mut b) = (vec![1.0; dim], vec![0.0; dim]);
        assert!(matches!(
            f.solve(&mut a, &mut b),
            Err(LinalgError::NotReady(_))
        ));
        let mut zero = ki.clone();
        zero.set_zero();
        let err = f.factorize(&zero, &zero).unwrap_err();
        assert!(matches!(err, LinalgError::Singular(_)), "{err}");
        assert!(f.solve(&mut a, &mut b).is_err());
        let mut nan = kr.clone();
        nan.values_mut()[0] = f64::NAN;
        assert!(matches!(
            f.factorize(&nan, &ki),
            Err(LinalgError::NonFinite { .. })
        ));
    }
}
