//! LU with partial pivoting of a chain-like saddle-point matrix in full
//! (possibly unsymmetric) storage, banded after the body-by-body order.
//!
//! The matrices of the analyses — the static Newton matrix
//! `[K Φ_qᵀ; Φ_q 0]` and the shift-inverted `[K − σM, Φ_qᵀ; Φ_q, 0]` —
//! are unsymmetric where `K` is (follower loads, drag, springs at q̇ = 0),
//! indefinite where the equilibrium is unstable or σ lies inside the
//! spectrum, and have zero diagonal entries on the coordinates that only the
//! constraints hold (the translations of a chain of rigid segments carry no
//! stiffness of their own). An elimination without pivoting stops at such a
//! zero; a general sparse LU (COLAMD and a supernodal or simplicial
//! factorisation) handles all of it but its fill and memory access do not
//! follow the chain.
//!
//! Here the rows and columns are permuted symmetrically into the
//! body-by-body order of [`super`] ("Order and envelope": each body's
//! coordinates, then the constraint rows whose highest body it is), in
//! which a chain numbered along the chain is banded (lower and upper
//! bandwidth 8 for revolute joints and springs between neighbours). The
//! permuted matrix is factorised by Gaussian elimination with partial
//! (row) pivoting inside the band, `P Ã = L U` with `Ã` the permuted
//! matrix: `L` keeps the lower bandwidth `kl` and `U` has upper bandwidth
//! `kl + ku`, so fill stays inside a band of fixed width and the cost is
//! linear in the number of bodies, the factors streaming through memory in
//! body order (Golub & Van Loan, *Matrix Computations*, 4th ed., §4.3.5;
//! LAPACK's `xGBTF2` and its band storage). Partial pivoting takes the
//! zero diagonals and the indefinite cases in its stride: the pivot of
//! column `j` is the largest of its at most `kl + 1` candidates.
//!
//! **Fallback** to [`SparseLu`] (faer's sparse LU after COLAMD: today's
//! path of the analyses):
//! - for the pattern, at `analyze`, when the band in this order is wider
//!   than [`MAX_BANDWIDTH`] (trees, loops across the numbering, controller
//!   states coupled to many bodies) — then every factorisation is
//!   [`SparseLu`]'s;
//! - for one factorisation, when a pivot is at the rounding level of the
//!   matrix (`|u_jj| ≤ ε max|a|`: numerically singular) or the growth
//!   `max|u| / max|a|` exceeds [`ChainLu::with_growth_limit`] (default
//!   [`DEFAULT_GROWTH_LIMIT`]). The next factorisation tries the band
//!   again. [`SaddlePointSolver::fallbacks`] counts these.

use super::super::{
    FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats, SparseLu, Storage,
};
use super::{order::body_order, MAX_BANDWIDTH};

/// Default largest growth factor `max|u| / max|a|` of the band
/// factorisation before a factorisation is redone by [`SparseLu`]. Partial
/// pivoting keeps the growth near 1 in practice (its worst case grows like
/// a power of 2 in the bandwidth); 10⁸ leaves 8 of the 16 digits.
pub const DEFAULT_GROWTH_LIMIT: f64 = 1e8;

/// The band factorisation of one pattern (module docs).
#[derive(Debug)]
struct Band {
    dim: usize,
    nnz: usize,
    /// `perm[i]`: row/column of `K` in position `i` of the band.
    perm: Vec<usize>,
    /// Lower and upper bandwidth of the permuted matrix.
    kl: usize,
    ku: usize,
    /// Leading dimension of the band storage, `2 kl + ku + 1`.
    ldab: usize,
    /// Where each slot of `K` goes in `ab`.
    pos: Vec<u32>,
    /// Column-major band storage: `Ã_ij` (and after factorisation `U_ij`,
    /// `i ≤ j`, or `L_ij`, `i > j`) at `ab[j ldab + kl + ku + i − j]` for
    /// `j − kl − ku ≤ i ≤ j + kl` (the top `kl` rows hold `U`'s fill).
    ab: Vec<f64>,
    /// Row interchanged with row `j` at step `j`.
    ipiv: Vec<usize>,
    /// Permuted right-hand side.
    w: Vec<f64>,
}

/// Why a band factorisation was handed to [`SparseLu`].
enum Reject {
    /// A pivot at the rounding level of the matrix (or not finite).
    TinyPivot,
    /// The growth factor above the limit.
    Growth,
}

impl Band {
    /// The band of `k` in the body-by-body order (the identity order when
    /// `k` has no body structure), `None` when it is wider than
    /// [`MAX_BANDWIDTH`] on either side.
    fn analyze(k: &SaddleMatrix) -> Option<Self> {
        let dim = k.dim();
        let perm = body_order(k).unwrap_or_else(|| (0..dim).collect());
        let mut inv = vec![0usize; dim];
        for (new, &old) in perm.iter().enumerate() {
            inv[old] = new;
        }
        let (col_ptr, row_idx) = (k.col_ptr(), k.row_idx());
        let (mut kl, mut ku) = (0usize, 0usize);
        for c in 0..dim {
            for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
                let (i, j) = (inv[r], inv[c]);
                kl = kl.max(i.saturating_sub(j));
                ku = ku.max(j.saturating_sub(i));
            }
        }
        if kl > MAX_BANDWIDTH || ku > MAX_BANDWIDTH {
            return None;
        }
        let ldab = 2 * kl + ku + 1;
        if dim.checked_mul(ldab)? > u32::MAX as usize {
            return None;
        }
        let kv = kl + ku;
        let mut pos = vec![0u32; k.nnz()];
        for c in 0..dim {
            for s in col_ptr[c]..col_ptr[c + 1] {
                let (i, j) = (inv[row_idx[s]], inv[c]);
                pos[s] = (j * ldab + kv + i - j) as u32;
            }
        }
        Some(Self {
            dim,
            nnz: k.nnz(),
            perm,
            kl,
            ku,
            ldab,
            pos,
            ab: vec![0.0; dim * ldab],
            ipiv: vec![0; dim],
            w: vec![0.0; dim],
        })
    }

    /// `P Ã = L U` of the current values of `k`, partial pivoting inside
    /// the band; rejected (module docs) at a pivot at the rounding level or
    /// a growth above `growth_limit`.
    fn factorize(&mut self, k: &SaddleMatrix, growth_limit: f64) -> Result<(), Reject> {
        let (dim, kl, ku, ldab) = (self.dim, self.kl, self.ku, self.ldab);
        let kv = kl + ku;
        let ab = &mut self.ab;
        ab.fill(0.0);
        let mut amax = 0.0f64;
        for (&p, &v) in self.pos.iter().zip(k.values()) {
            ab[p as usize] += v;
            amax = amax.max(v.abs());
        }
        let tiny = f64::EPSILON * amax;
        let mut umax = 0.0f64;
        // last column touched by a pivot row so far (U's fill)
        let mut ju = 0usize;
        for j in 0..dim {
            let km = kl.min(dim - 1 - j);
            let col = j * ldab + kv; // Ã_jj
            let mut p = 0;
            let mut best = ab[col].abs();
            for t in 1..=km {
                let a = ab[col + t].abs();
                if a > best {
                    best = a;
                    p = t;
                }
            }
            // also false for NaN
            if !(best > tiny) {
                return Err(Reject::TinyPivot);
            }
            self.ipiv[j] = j + p;
            ju = ju.max((j + ku + p).min(dim - 1));
            if p != 0 {
                // rows j and j + p, columns j..=ju (row i of column c at
                // c ldab + kv + i − c)
                for c in j..=ju {
                    let base = c * ldab + kv - c;
                    ab.swap(base + j, base + j + p);
                }
            }
            let r = 1.0 / ab[col];
            for t in 1..=km {
                ab[col + t] *= r;
            }
            let (left, right) = ab.split_at_mut((j + 1) * ldab);
            let l = &left[col + 1..col + 1 + km];
            for c in j + 1..=ju {
                // column c's rows j..=j + km start at this offset in `right`
                let base = (c - j - 1) * ldab + kv + j - c;
                let u = right[base];
                umax = umax.max(u.abs());
                if u != 0.0 {
                    for (a, &li) in right[base + 1..base + 1 + km].iter_mut().zip(l) {
                        *a -= li * u;
                    }
                }
            }
            umax = umax.max(best);
        }
        if umax > growth_limit * amax || !umax.is_finite() {
            return Err(Reject::Growth);
        }
        Ok(())
    }

    /// `rhs ← K⁻¹ rhs` from the last factorisation; false if the solution
    /// is not finite.
    fn solve(&mut self, rhs: &mut [f64]) -> bool {
        let (dim, kl, ldab) = (self.dim, self.kl, self.ldab);
        let kv = kl + self.ku;
        let (ab, w) = (&self.ab, &mut self.w);
        for (wi, &p) in w.iter_mut().zip(&self.perm) {
            *wi = rhs[p];
        }
        // L y = P w
        for j in 0..dim {
            let l = self.ipiv[j];
            if l != j {
                w.swap(j, l);
            }
            let km = kl.min(dim - 1 - j);
            let wj = w[j];
            if wj != 0.0 {
                let col = j * ldab + kv;
                for (wi, &li) in w[j + 1..=j + km].iter_mut().zip(&ab[col + 1..=col + km]) {
                    *wi -= li * wj;
                }
            }
        }
        // U x = y, column by column from the last
        for j in (0..dim).rev() {
            let col = j * ldab + kv;
            let xj = w[j] / ab[col];
            w[j] = xj;
            let i0 = j.saturating_sub(kv);
            if xj != 0.0 {
                let u = &ab[col - (j - i0)..col];
                for (wi, &ui) in w[i0..j].iter_mut().zip(u) {
                    *wi -= ui * xj;
                }
            }
        }
        let mut finite = true;
        for (&p, &wi) in self.perm.iter().zip(w.iter()) {
            rhs[p] = wi;
            finite &= wi.is_finite();
        }
        finite
    }
}

/// LU of the full saddle-point matrix that takes the band path of the
/// module docs when the pattern is a chain in body order and [`SparseLu`]
/// otherwise (decided by `analyze`, once per pattern), with a per
/// factorisation fallback to [`SparseLu`] at a pivot at the rounding level
/// or a large growth.
pub struct ChainLu {
    band: Option<Band>,
    fallback: SparseLu,
    /// `fallback` has analysed the pattern.
    fallback_analyzed: bool,
    /// The last factorisation is `fallback`'s.
    on_fallback: bool,
    growth_limit: f64,
    analyzed: bool,
    factorized: bool,
    fallbacks: usize,
    stats: SolverStats,
}

impl Default for ChainLu {
    fn default() -> Self {
        Self {
            band: None,
            fallback: SparseLu::default(),
            fallback_analyzed: false,
            on_fallback: false,
            growth_limit: DEFAULT_GROWTH_LIMIT,
            analyzed: false,
            factorized: false,
            fallbacks: 0,
            stats: SolverStats::default(),
        }
    }
}

impl std::fmt::Debug for ChainLu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ChainLu")
            .field("bandwidths", &self.bandwidths())
            .field("growth_limit", &self.growth_limit)
            .field("fallbacks", &self.fallbacks)
            .field("stats", &self.stats)
            .finish()
    }
}

impl ChainLu {
    /// Largest growth factor `max|u| / max|a|` of the band factorisation
    /// before a factorisation is redone by [`SparseLu`] (default
    /// [`DEFAULT_GROWTH_LIMIT`]).
    pub fn with_growth_limit(mut self, limit: f64) -> Self {
        self.growth_limit = limit;
        self
    }

    /// Did `analyze` choose the band path (`None` before `analyze`)?
    pub fn is_band(&self) -> Option<bool> {
        self.analyzed.then_some(self.band.is_some())
    }

    /// Lower and upper bandwidth of the permuted matrix (`None` on the
    /// pattern's fallback path or before `analyze`).
    pub fn bandwidths(&self) -> Option<(usize, usize)> {
        self.band.as_ref().map(|b| (b.kl, b.ku))
    }

    /// Non-zero values of the last band factorisation's `L` (below the
    /// diagonal) and `U` (`None` on the pattern's fallback path).
    pub fn factor_nonzeros(&self) -> Option<(usize, usize)> {
        let b = self.band.as_ref()?;
        let kv = b.kl + b.ku;
        let (mut l, mut u) = (0, 0);
        for (j, col) in b.ab.chunks(b.ldab).enumerate() {
            for (r, v) in col.iter().enumerate() {
                if *v != 0.0 && r + j >= kv {
                    if r > kv {
                        l += 1;
                    } else {
                        u += 1;
                    }
                }
            }
        }
        Some((l, u))
    }

    /// Factorise with the fallback, analysing it first if needed.
    fn factorize_fallback(&mut self, k: &SaddleMatrix) -> Result<FactorInfo, LinalgError> {
        if !self.fallback_analyzed {
            self.fallback.analyze(k)?;
            self.fallback_analyzed = true;
        }
        self.on_fallback = true;
        self.fallback.factorize(k)
    }
}

impl SaddlePointSolver for ChainLu {
    fn name(&self) -> &'static str {
        if self.band.is_some() {
            "chain-lu"
        } else {
            "sparse-lu"
        }
    }

    fn storage(&self) -> Storage {
        Storage::Full
    }

    fn analyze(&mut self, k: &SaddleMatrix) -> Result<(), LinalgError> {
        if k.storage() != Storage::Full {
            return Err(LinalgError::Storage {
                solver: "chain-lu",
                needs: Storage::Full,
            });
        }
        self.factorized = false;
        self.analyzed = true;
        self.fallback_analyzed = false;
        self.band = Band::analyze(k);
        self.stats.analyses += 1;
        Ok(())
    }

    fn factorize(&mut self, k: &SaddleMatrix) -> Result<FactorInfo, LinalgError> {
        if !self.analyzed {
            return Err(LinalgError::NotReady("analyze"));
        }
        self.factorized = false;
        let Some(band) = self.band.as_mut() else {
            let info = self.factorize_fallback(k)?;
            self.factorized = true;
            self.stats.factorizations += 1;
            return Ok(info);
        };
        if k.dim() != band.dim || k.nnz() != band.nnz {
            return Err(LinalgError::Dimension {
                expected: band.dim,
                got: k.dim(),
            });
        }
        k.check_finite()?;
        self.stats.factorizations += 1;
        let info = match band.factorize(k, self.growth_limit) {
            Ok(()) => {
                self.on_fallback = false;
                FactorInfo::default()
            }
            Err(Reject::TinyPivot | Reject::Growth) => {
                self.fallbacks += 1;
                self.factorize_fallback(k)?
            }
        };
        self.factorized = true;
        Ok(info)
    }

    fn solve_in_place(&mut self, k: &SaddleMatrix, rhs: &mut [f64]) -> Result<(), LinalgError> {
        if !self.factorized {
            return Err(LinalgError::NotReady("factorize"));
        }
        let band = match self.band.as_mut() {
            Some(b) if !self.on_fallback => b,
            _ => {
                self.stats.solves += 1;
                return self.fallback.solve_in_place(k, rhs);
            }
        };
        if rhs.len() != band.dim || k.dim() != band.dim {
            return Err(LinalgError::Dimension {
                expected: band.dim,
                got: rhs.len(),
            });
        }
        self.stats.solves += 1;
        if band.solve(rhs) {
            Ok(())
        } else {
            Err(LinalgError::NonFiniteSolution("band LU"))
        }
    }

    fn stats(&self) -> SolverStats {
        self.stats
    }

    /// Factorisations on the band path that were handed to [`SparseLu`]
    /// (a pivot at the rounding level or a large growth; module docs).
    fn fallbacks(&self) -> usize {
        self.fallbacks
    }
}
