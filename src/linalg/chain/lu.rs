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
//! LAPACK's `xGBTF2`). Partial pivoting takes the zero diagonals and the
//! indefinite cases in its stride: the pivot of column `j` is the largest
//! of its at most `kl + 1` candidates.
//!
//! **Window.** Step `j` of the elimination only reads and writes rows
//! `j..=j + kl` and columns `j..=j + kl + ku` of the partly eliminated
//! matrix (rows further down have no entry in column `j` yet). These rows
//! live in a small dense window (Irons' frontal order; rows and columns
//! indexed modulo powers of 2 at least `kl + 1` and `kl + ku + 1`) that
//! stays in the L1 cache: row `j + kl` is loaded from `K` when step `j`
//! begins, the pivot row leaves as row `j` of `U`, the multipliers as
//! column `j` of `L`, each stored up to its last non-zero, and column `j`
//! is cleared for column `j + 2^⌈log₂(kl + ku + 1)⌉`. The solve applies
//! the row interchanges and `L` column by column (as LAPACK's `xGBTRS`) and
//! `U` row by row (dot products).
//!
//! **Fallback** to [`SparseLu`] (faer's sparse LU after COLAMD, the
//! analyses' general path):
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
use std::cell::Cell;

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
    /// Permuted row `i`'s entries of `K`, `(slot, permuted column)`:
    /// `row_ent[row_ptr[i]..row_ptr[i + 1]]`.
    row_ptr: Vec<usize>,
    row_ent: Vec<(u32, u32)>,
    /// The window of the elimination (module docs, **Window**): rows
    /// `j..=j + kl` of the partly eliminated matrix, row `i` at
    /// `(i mod wr) wc`, column `c` at `c mod wc` (`wr`, `wc` powers of 2).
    win: Vec<f64>,
    wr: usize,
    wc: usize,
    /// `U` by rows without the diagonal: row `j` holds `u_{j, j+1..}` up
    /// to its last non-zero, `steps[j].u` values after rows `0..j`'s.
    u_val: Vec<f64>,
    /// `1 / u_jj`.
    dinv: Vec<f64>,
    /// `L` by columns without the unit diagonal: column `j` holds
    /// `l_{j+1.., j}` up to its last non-zero, `steps[j].l` values after
    /// columns `0..j`'s.
    l_val: Vec<f64>,
    /// Per elimination step, what the solve reads besides the values
    /// (three bytes: the solve streams them).
    steps: Vec<Step>,
    /// Permuted right-hand side.
    w: Vec<f64>,
}

/// One elimination step's row interchange and factor lengths ([`Band`]).
#[derive(Debug, Clone, Copy, Default)]
struct Step {
    /// Row `j + pivot` was interchanged with row `j`.
    pivot: u8,
    /// Stored values of column `j` of `L` (below the diagonal).
    l: u8,
    /// Stored values of row `j` of `U` (right of the diagonal).
    u: u8,
}

/// Why a band factorisation was handed to [`SparseLu`], or failed.
enum Reject {
    /// An entry of the matrix is not finite (an error, no fallback).
    NonFinite,
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
        let mut row_ptr = vec![0usize; dim + 1];
        for c in 0..dim {
            for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
                let (i, j) = (inv[r], inv[c]);
                kl = kl.max(i.saturating_sub(j));
                ku = ku.max(j.saturating_sub(i));
                row_ptr[i + 1] += 1;
            }
        }
        if kl > MAX_BANDWIDTH || ku > MAX_BANDWIDTH || k.nnz() > u32::MAX as usize {
            return None;
        }
        for i in 0..dim {
            row_ptr[i + 1] += row_ptr[i];
        }
        let mut next = row_ptr[..dim].to_vec();
        let mut row_ent = vec![(0u32, 0u32); k.nnz()];
        for c in 0..dim {
            for s in col_ptr[c]..col_ptr[c + 1] {
                let i = inv[row_idx[s]];
                row_ent[next[i]] = (s as u32, inv[c] as u32);
                next[i] += 1;
            }
        }
        let (wr, wc) = (
            (kl + 1).next_power_of_two(),
            (kl + ku + 1).next_power_of_two(),
        );
        // (none while the thread's locals are being destroyed)
        let (spare_u, spare_l) = SPARE.try_with(Cell::take).unwrap_or_default();
        Some(Self {
            dim,
            nnz: k.nnz(),
            perm,
            kl,
            ku,
            row_ptr,
            row_ent,
            win: vec![0.0; wr * wc],
            wr,
            wc,
            // the largest sizes, reserved (not touched): no reallocation
            // and copy as the factors grow
            u_val: reuse(spare_u, dim * (kl + ku)),
            dinv: vec![0.0; dim],
            l_val: reuse(spare_l, dim * kl),
            steps: vec![Step::default(); dim],
            w: vec![0.0; dim],
        })
    }

    /// `P Ã = L U` of the current values of `k`, partial pivoting inside
    /// the band; rejected (module docs) at a non-finite entry, a pivot at
    /// the rounding level or a growth above `growth_limit`. The rounding
    /// level `ε max|a|` is known once every row is loaded (each value of
    /// `k` is read once, by the load of its row), so the pivots are
    /// checked at the end: the smallest `|u_jj|` against it, the
    /// elimination being the same up to the first pivot that fails.
    fn factorize(&mut self, k: &SaddleMatrix, growth_limit: f64) -> Result<(), Reject> {
        let (dim, kl, kv) = (self.dim, self.kl, self.kl + self.ku);
        let (rm, cm, wc) = (self.wr - 1, self.wc - 1, self.wc);
        let vals = k.values();
        // max |a|, whether every a is finite, the smallest pivot and
        // whether one was NaN
        let (mut amax, mut finite) = (0.0f64, true);
        let (mut min_pivot, mut nan_pivot) = (f64::INFINITY, false);
        let mut umax = 0.0f64;
        let win = &mut self.win;
        win.fill(0.0);
        self.u_val.clear();
        self.l_val.clear();
        let mut load = |win: &mut [f64], i: usize| {
            let row = &mut win[(i & rm) * wc..(i & rm) * wc + wc];
            row.fill(0.0);
            for &(s, c) in &self.row_ent[self.row_ptr[i]..self.row_ptr[i + 1]] {
                let v = vals[s as usize];
                amax = amax.max(v.abs());
                finite &= v.is_finite();
                row[c as usize & cm] += v;
            }
        };
        for i in 0..kl.min(dim) {
            load(win, i);
        }
        let mut l = [0.0f64; MAX_BANDWIDTH];
        for j in 0..dim {
            if j + kl < dim {
                load(win, j + kl);
            }
            let km = kl.min(dim - 1 - j);
            let cj = j & cm;
            let at = |i: usize| (i & rm) * wc;
            let mut p = 0;
            let mut best = win[at(j) + cj].abs();
            for t in 1..=km {
                let a = win[at(j + t) + cj].abs();
                if a > best {
                    best = a;
                    p = t;
                }
            }
            // a NaN pivot is rejected too
            min_pivot = min_pivot.min(best);
            nan_pivot |= best.is_nan();
            // p ≤ kl and the lengths ≤ kl + ku ≤ 2 MAX_BANDWIDTH fit a byte
            self.steps[j].pivot = p as u8;
            if p != 0 {
                let (a, b) = (at(j), at(j + p));
                let (lo, hi) = (a.min(b), a.max(b));
                let (x, y) = win.split_at_mut(hi);
                x[lo..lo + wc].swap_with_slice(&mut y[..wc]);
            }
            // the pivot row: U's row j up to its last non-zero
            let pr = at(j);
            let last = (j + kv).min(dim - 1);
            let mut e = j;
            for c in (j + 1..=last).rev() {
                if win[pr + (c & cm)] != 0.0 {
                    e = c;
                    break;
                }
            }
            let pivot = win[pr + cj];
            let d = 1.0 / pivot;
            self.dinv[j] = d;
            umax = umax.max(best);
            for c in j + 1..=e {
                let u = win[pr + (c & cm)];
                umax = umax.max(u.abs());
                self.u_val.push(u);
            }
            let u_start = self.u_val.len() - (e - j);
            self.steps[j].u = (e - j) as u8;
            // multipliers, column j leaves the window
            let mut lk = 0;
            for t in 1..=km {
                let slot = at(j + t) + cj;
                let li = win[slot] * d;
                win[slot] = 0.0;
                l[t - 1] = li;
                if li != 0.0 {
                    lk = t;
                }
            }
            self.l_val.extend_from_slice(&l[..lk]);
            self.steps[j].l = lk as u8;
            // the rows below: row j + t −= l_t × (pivot row)
            let u = &self.u_val[u_start..];
            for (t, &li) in l[..lk].iter().enumerate() {
                if li == 0.0 {
                    continue;
                }
                let r = at(j + 1 + t);
                for (c, &uc) in (j + 1..=e).zip(u) {
                    win[r + (c & cm)] -= li * uc;
                }
            }
        }
        if !finite {
            return Err(Reject::NonFinite);
        }
        if nan_pivot || min_pivot <= f64::EPSILON * amax {
            return Err(Reject::TinyPivot);
        }
        if umax > growth_limit * amax || !umax.is_finite() {
            return Err(Reject::Growth);
        }
        Ok(())
    }

    /// `rhs ← K⁻¹ rhs` from the last factorisation; false if the solution
    /// is not finite.
    fn solve(&mut self, rhs: &mut [f64]) -> bool {
        let w = &mut self.w;
        for (wi, &p) in w.iter_mut().zip(&self.perm) {
            *wi = rhs[p];
        }
        // L y = P w, column by column
        let mut at = 0;
        for (j, st) in self.steps.iter().enumerate() {
            let p = st.pivot as usize;
            if p != 0 {
                w.swap(j, j + p);
            }
            let wj = w[j];
            let lj = &self.l_val[at..at + st.l as usize];
            at += lj.len();
            if wj != 0.0 {
                for (wi, &li) in w[j + 1..].iter_mut().zip(lj) {
                    *wi -= li * wj;
                }
            }
        }
        // U x = y, row by row from the last; each row's dot product from
        // its far end, so that the term of x_{j+1}, computed just before,
        // enters last (the other products do not wait for it)
        let mut end = self.u_val.len();
        for (j, st) in self.steps.iter().enumerate().rev() {
            let uj = &self.u_val[end - st.u as usize..end];
            end -= uj.len();
            let s: f64 = uj.iter().zip(&w[j + 1..]).rev().map(|(u, x)| u * x).sum();
            w[j] = (w[j] - s) * self.dinv[j];
        }
        let mut finite = true;
        for (&p, &wi) in self.perm.iter().zip(w.iter()) {
            rhs[p] = wi;
            finite &= wi.is_finite();
        }
        finite
    }

    /// Stored values of `L` and `U` (diagonal included) of the last
    /// factorisation.
    fn factor_len(&self) -> (usize, usize) {
        (self.l_val.len(), self.u_val.len() + self.dim)
    }
}

thread_local! {
    /// The factor storage (`u_val`, `l_val`) of the last [`Band`] dropped
    /// on this thread, taken by the next [`Band::analyze`]: the analyses
    /// build a solver per call, and the factors of a long chain are
    /// megabytes that the allocator would return to the system at the end
    /// of one call and map afresh (page faults, zeroed pages) in the next.
    /// Kept only up to [`SPARE_MAX_VALUES`] values.
    static SPARE: Cell<(Vec<f64>, Vec<f64>)> = const { Cell::new((Vec::new(), Vec::new())) };
}

/// Largest factor storage (values of `U` and `L` reserved) that a dropped
/// [`Band`] leaves to the next one on its thread: 4 Mi values, 32 MiB.
const SPARE_MAX_VALUES: usize = 1 << 22;

/// `spare`, emptied, when it has room for `cap` values, else a new vector
/// with that capacity.
fn reuse(mut spare: Vec<f64>, cap: usize) -> Vec<f64> {
    if spare.capacity() >= cap {
        spare.clear();
        spare
    } else {
        Vec::with_capacity(cap)
    }
}

impl Drop for Band {
    fn drop(&mut self) {
        let (u, l) = (
            std::mem::take(&mut self.u_val),
            std::mem::take(&mut self.l_val),
        );
        if u.capacity() + l.capacity() <= SPARE_MAX_VALUES {
            // dropped with the storage while the thread's locals are being
            // destroyed
            let _ = SPARE.try_with(|s| s.set((u, l)));
        }
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

    /// Stored values of the last band factorisation's `L` (below the
    /// diagonal) and `U` (diagonal included), each row or column up to its
    /// last non-zero (`None` on the pattern's fallback path).
    pub fn factor_len(&self) -> Option<(usize, usize)> {
        self.band.as_ref().map(Band::factor_len)
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
        k.require_storage(Storage::Full, "chain-lu")?;
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
        let result = band.factorize(k, self.growth_limit);
        if let Err(Reject::NonFinite) = result {
            // the error naming the first non-finite entry
            k.check_finite()?;
        }
        self.stats.factorizations += 1;
        let info = match result {
            Ok(()) => {
                self.on_fallback = false;
                FactorInfo::default()
            }
            Err(Reject::NonFinite | Reject::TinyPivot | Reject::Growth) => {
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
