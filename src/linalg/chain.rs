//! LDLᵀ of chain-like saddle-point matrices in envelope (profile) storage
//! after a fixed body-by-body order, with faer's sparse LDLᵀ as the
//! fallback for every other pattern.
//!
//! # Order and envelope
//!
//! Coordinates `3b..3b+3` form group `b` (body `b`, the numbering of
//! [`crate::model::System`]); a multiplier row joins the group of the
//! highest body among its Jacobian columns. The order eliminates group
//! after group, each group's coordinates before its multipliers. Every
//! multiplier row is thus eliminated after all the coordinates it couples
//! to, so with `A` positive definite and `Φ_q` of full row rank every pivot
//! has its expected sign (`+` for coordinates, `−` for multipliers), as
//! with [`super::Ordering::Amd`]'s postponement. For a chain numbered along
//! the chain (rod, pendulum, cantilever: joint `k` between bodies `k` and
//! `k + 1`, springs between neighbours) the permuted matrix is banded with
//! half-bandwidth 8: the LDLᵀ without pivoting keeps its fill inside the
//! envelope (George & Liu, *Computer Solution of Large Sparse Positive
//! Definite Systems*, 1981, ch. 4), and the factorisation is the
//! row-by-row (Crout, "up-looking") recurrence
//!
//! ```text
//! t_ij = a_ij − Σ_{k<j} t_ik L_jk,   L_ij = t_ij / d_j,   d_i = a_ii − Σ_{j<i} t_ij L_ij
//! ```
//!
//! over the envelope only — the arithmetic of faer's simplicial LDLᵀ
//! without its elimination-tree traversal and indirect indexing.
//! Patterns whose envelope in this order is wider than [`MAX_BANDWIDTH`]
//! (trees, loops across the numbering, other numberings) go to
//! [`SparseLdlt`].
//!
//! Scaling and dynamic regularisation are [`SparseLdlt`]'s (same `ε`, `δ`,
//! same scaled units, same sign rule), so the two solvers agree to rounding
//! on every matrix both accept.

use super::sparse::{saddle_scaling, RefineBuffers};
use super::{
    FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats, SparseLdlt, Storage,
    DEFAULT_DELTA, DEFAULT_EPSILON,
};

/// Widest envelope row (entries left of the diagonal) the envelope path
/// takes; wider patterns use [`SparseLdlt`]. A chain of revolutes with
/// springs between neighbours has 8.
pub const MAX_BANDWIDTH: usize = 24;

/// The envelope factorisation of one pattern.
#[derive(Debug)]
struct Envelope {
    dim: usize,
    n: usize,
    nnz: usize,
    /// `perm[i]`: row/column of `K` eliminated `i`-th.
    perm: Vec<usize>,
    /// First column of row `i`'s envelope (permuted numbering).
    first: Vec<usize>,
    /// Row `i`'s entries left of the diagonal: `env[ptr[i] + (j − first[i])]`.
    ptr: Vec<usize>,
    /// `L` by rows (envelope), then the pivots `d` (`env[ptr[dim] + i]`).
    env: Vec<f64>,
    /// `1/d_i`.
    dinv: Vec<f64>,
    /// Slot of `K` → position in `env`.
    slot_to: Vec<usize>,
    /// Expected pivot signs (permuted numbering).
    positive: Vec<bool>,
    scale: Vec<f64>,
    /// `scale` in elimination order.
    pscale: Vec<f64>,
    /// Permuted right-hand side.
    w: Vec<f64>,
}

impl Envelope {
    /// The envelope of `k` in the body-by-body order, or `None` when a
    /// multiplier row has no coordinate column or a row is wider than
    /// [`MAX_BANDWIDTH`].
    fn analyze(k: &SaddleMatrix) -> Option<Self> {
        let (dim, n) = (k.dim(), k.n());
        let (col_ptr, row_idx) = (k.col_ptr(), k.row_idx());
        if n % 3 != 0 {
            return None;
        }
        let n_groups = n / 3;
        // group of each multiplier row: the highest body of its columns
        let mut group = vec![usize::MAX; dim - n];
        for c in 0..n {
            for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
                if r >= n {
                    let g = &mut group[r - n];
                    *g = if *g == usize::MAX {
                        c / 3
                    } else {
                        (*g).max(c / 3)
                    };
                }
            }
        }
        if group.contains(&usize::MAX) {
            return None;
        }
        let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); n_groups];
        for (r, &g) in group.iter().enumerate() {
            rows_of[g].push(n + r);
        }
        let mut perm = Vec::with_capacity(dim);
        for (g, rows) in rows_of.iter().enumerate() {
            perm.extend(3 * g..3 * g + 3);
            perm.extend_from_slice(rows);
        }
        let mut inv = vec![0usize; dim];
        for (new, &old) in perm.iter().enumerate() {
            inv[old] = new;
        }
        let mut first: Vec<usize> = (0..dim).collect();
        for c in 0..dim {
            for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
                let (a, b) = (inv[r], inv[c]);
                let (hi, lo) = (a.max(b), a.min(b));
                first[hi] = first[hi].min(lo);
            }
        }
        if (0..dim).any(|i| i - first[i] > MAX_BANDWIDTH) {
            return None;
        }
        let mut ptr = vec![0usize; dim + 1];
        for i in 0..dim {
            ptr[i + 1] = ptr[i] + (i - first[i]);
        }
        let profile = ptr[dim];
        let mut slot_to = vec![0usize; k.nnz()];
        for c in 0..dim {
            for s in col_ptr[c]..col_ptr[c + 1] {
                let (a, b) = (inv[row_idx[s]], inv[c]);
                let (hi, lo) = (a.max(b), a.min(b));
                slot_to[s] = if hi == lo {
                    profile + hi
                } else {
                    ptr[hi] + (lo - first[hi])
                };
            }
        }
        let positive = perm.iter().map(|&i| i < n).collect();
        Some(Self {
            dim,
            n,
            nnz: k.nnz(),
            perm,
            first,
            ptr,
            env: vec![0.0; profile + dim],
            dinv: vec![0.0; dim],
            slot_to,
            positive,
            scale: vec![1.0; dim],
            pscale: vec![1.0; dim],
            w: vec![0.0; dim],
        })
    }

    /// Scaled, regularised LDLᵀ of the values of `k` (module docs).
    fn factorize(
        &mut self,
        k: &SaddleMatrix,
        epsilon: f64,
        delta: f64,
    ) -> Result<usize, LinalgError> {
        saddle_scaling(k, &mut self.scale);
        for (ps, &p) in self.pscale.iter_mut().zip(&self.perm) {
            *ps = self.scale[p];
        }
        let (col_ptr, row_idx, vals) = (k.col_ptr(), k.row_idx(), k.values());
        self.env.fill(0.0);
        for c in 0..self.dim {
            let sc = self.scale[c];
            for s in col_ptr[c]..col_ptr[c + 1] {
                self.env[self.slot_to[s]] += vals[s] * self.scale[row_idx[s]] * sc;
            }
        }
        let profile = self.ptr[self.dim];
        let (lower, diag) = self.env.split_at_mut(profile);
        let (first, ptr, dinv) = (&self.first, &self.ptr, &mut self.dinv);
        let mut regularized = 0;
        for i in 0..self.dim {
            let (fi, pi) = (first[i], ptr[i]);
            assert!(ptr[i + 1] <= lower.len() && i < dinv.len());
            // t_ij = a_ij − Σ_k t_ik L_jk over the overlap of rows i and j
            for j in fi..i {
                let fj = first[j];
                let k0 = fi.max(fj);
                let (ti, lj) = (pi + (k0 - fi), ptr[j] + (k0 - fj));
                let mut dot = 0.0;
                for o in 0..j - k0 {
                    // SAFETY: rows j < i lie before row i in `lower`
                    // (ptr is increasing, ptr[i + 1] ≤ len checked above),
                    // and k0 + o < j stays inside both rows' envelopes.
                    unsafe {
                        dot += lower.get_unchecked(ti + o) * lower.get_unchecked(lj + o);
                    }
                }
                lower[pi + (j - fi)] -= dot;
            }
            let mut d = diag[i];
            for (t, &dj) in lower[pi..ptr[i + 1]].iter_mut().zip(&dinv[fi..i]) {
                let l = *t * dj;
                d -= *t * l;
                *t = l;
            }
            if self.positive[i] {
                if d <= epsilon {
                    d = delta;
                    regularized += 1;
                }
            } else if d >= -epsilon {
                d = -delta;
                regularized += 1;
            }
            if !d.is_finite() {
                return Err(LinalgError::Singular(format!(
                    "envelope LDLᵀ: non-finite pivot at elimination step {i}"
                )));
            }
            diag[i] = d;
            dinv[i] = 1.0 / d;
        }
        Ok(regularized)
    }

    /// `x ← S (S K S)⁻¹ S x` with the last factorisation: `L y = P S x`,
    /// `Lᵀ z = D⁻¹ y` by rows of `L` from the last, `x = S Pᵀ z`.
    fn solve(&mut self, x: &mut [f64]) {
        let (w, first, ptr, env) = (&mut self.w, &self.first, &self.ptr, &self.env);
        for ((wi, &p), &s) in w.iter_mut().zip(&self.perm).zip(&self.pscale) {
            *wi = x[p] * s;
        }
        assert!(ptr[self.dim] <= env.len() && w.len() == self.dim);
        for i in 0..self.dim {
            let (fi, pi) = (first[i], ptr[i]);
            let mut dot = 0.0;
            for o in 0..i - fi {
                // SAFETY: row i's entries are env[pi..ptr[i + 1]] (within
                // env, checked above) and columns fi + o < i < dim.
                unsafe {
                    dot += env.get_unchecked(pi + o) * w.get_unchecked(fi + o);
                }
            }
            w[i] -= dot;
        }
        for (wi, &di) in w.iter_mut().zip(&self.dinv) {
            *wi *= di;
        }
        for i in (0..self.dim).rev() {
            let (fi, pi, wi) = (first[i], ptr[i], w[i]);
            for o in 0..i - fi {
                // SAFETY: as in the forward loop
                unsafe {
                    *w.get_unchecked_mut(fi + o) -= env.get_unchecked(pi + o) * wi;
                }
            }
        }
        for ((&wi, &p), &s) in w.iter().zip(&self.perm).zip(&self.pscale) {
            x[p] = wi * s;
        }
    }
}

/// LDLᵀ of the saddle-point matrix that takes the envelope path of the
/// module docs when the pattern is a chain and [`SparseLdlt`] otherwise
/// (decided by `analyze`, once per pattern); the same scaling,
/// regularisation and optional residual check.
#[derive(Debug)]
pub struct ChainLdlt {
    epsilon: f64,
    delta: f64,
    envelope: Option<Envelope>,
    fallback: SparseLdlt,
    analyzed: bool,
    factorized: bool,
    check_residual: bool,
    bufs: RefineBuffers,
    stats: SolverStats,
}

impl Default for ChainLdlt {
    fn default() -> Self {
        Self {
            epsilon: DEFAULT_EPSILON,
            delta: DEFAULT_DELTA,
            envelope: None,
            fallback: SparseLdlt::default(),
            analyzed: false,
            factorized: false,
            check_residual: true,
            bufs: RefineBuffers::default(),
            stats: SolverStats::default(),
        }
    }
}

impl ChainLdlt {
    /// Switch the residual check (and one step of iterative refinement)
    /// after each solve on or off (default on), as
    /// [`SparseLdlt::with_residual_check`].
    pub fn with_residual_check(mut self, on: bool) -> Self {
        self.check_residual = on;
        self.fallback = self.fallback.with_residual_check(on);
        self
    }

    /// Did `analyze` choose the envelope path (`None` before `analyze`)?
    pub fn is_envelope(&self) -> Option<bool> {
        self.analyzed.then_some(self.envelope.is_some())
    }

    /// Stored values of the envelope factor (`L` and `d`), `None` on the
    /// fallback path or before `analyze`.
    pub fn factor_nnz(&self) -> Option<usize> {
        self.envelope.as_ref().map(|e| e.env.len())
    }
}

impl SaddlePointSolver for ChainLdlt {
    fn name(&self) -> &'static str {
        if self.envelope.is_some() {
            "chain-ldlt"
        } else {
            "sparse-ldlt"
        }
    }

    fn analyze(&mut self, k: &SaddleMatrix) -> Result<(), LinalgError> {
        if k.storage() != Storage::SymmetricLower {
            return Err(LinalgError::Storage {
                solver: "chain-ldlt",
                needs: Storage::SymmetricLower,
            });
        }
        self.factorized = false;
        self.analyzed = true;
        self.envelope = Envelope::analyze(k);
        match &self.envelope {
            Some(e) => {
                self.bufs.resize(e.dim);
                self.stats.analyses += 1;
                Ok(())
            }
            None => self.fallback.analyze(k),
        }
    }

    fn factorize(&mut self, k: &SaddleMatrix) -> Result<FactorInfo, LinalgError> {
        let Some(e) = self.envelope.as_mut() else {
            return self.fallback.factorize(k);
        };
        if k.dim() != e.dim || k.nnz() != e.nnz || k.n() != e.n {
            return Err(LinalgError::Dimension {
                expected: e.dim,
                got: k.dim(),
            });
        }
        k.check_finite()?;
        self.factorized = false;
        let regularized_pivots = e.factorize(k, self.epsilon, self.delta)?;
        self.factorized = true;
        self.stats.factorizations += 1;
        self.stats.regularized_pivots += regularized_pivots;
        Ok(FactorInfo { regularized_pivots })
    }

    fn solve_in_place(&mut self, k: &SaddleMatrix, rhs: &mut [f64]) -> Result<(), LinalgError> {
        let Some(e) = self.envelope.as_mut() else {
            return self.fallback.solve_in_place(k, rhs);
        };
        if !self.factorized {
            return Err(LinalgError::NotReady("factorize"));
        }
        if rhs.len() != e.dim || k.dim() != e.dim {
            return Err(LinalgError::Dimension {
                expected: e.dim,
                got: rhs.len(),
            });
        }
        self.stats.solves += 1;
        if self.check_residual {
            let refined = self.bufs.solve_checked(k, rhs, |x| e.solve(x));
            self.stats.refinements += usize::from(refined);
        } else {
            e.solve(rhs);
        }
        if rhs.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(LinalgError::NonFiniteSolution("envelope LDLᵀ"))
        }
    }

    fn stats(&self) -> SolverStats {
        if self.envelope.is_some() {
            self.stats
        } else {
            self.fallback.stats()
        }
    }
}
