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
//!
//! # Two halves
//!
//! From [`SPLIT_MIN_DIM`] on (and when the pattern allows it) the order is
//! two-sided, a one-level nested dissection of the chain (George 1973;
//! the "twisted" factorisation of tridiagonal matrices): with `gm` the
//! middle body, `T` = the bodies below `gm` in the order above (eliminated
//! towards the middle), `B` = the bodies above `gm` from the last one
//! down, each body's coordinates before the multiplier rows whose *lowest*
//! body it is (the mirror image: again every multiplier row after a body
//! it couples to), and last the separator `S` = body `gm` and every row
//! touching or spanning it. `T` and `B` do not couple, so their Crout
//! recurrences are independent (the envelope fill of each stays in its
//! half); the rows of `S` have two envelope segments (the tail of `T`,
//! then the tail of `B` and `S`) and are factorised after both. The solve
//! follows: forward substitution of `T` and `B`, of `S`; `D⁻¹`; backward
//! substitution of `S`, then of `T` and `B` (the forward rows read their
//! right-hand side `(P S x)_i` from `x` directly, the backward rows write
//! `x = S Pᵀ z` an entry at a time as it becomes final: no separate gather
//! and scatter passes). From [`PARALLEL_MIN_DIM`] on the two halves (with
//! their scaling and loading of values) run concurrently
//! ([`crate::parallel::join_if`]: the run's two-thread team) when
//! the pool has two threads; on one thread the substitutions take a
//! row of `T` and a row of `B` in turn. A substitution is a chain of dependent rows (row `i` needs
//! row `i − 1`'s result), bound by latency, not arithmetic: two independent
//! chains in flight overlap in the core, and each row takes the previous
//! row's result from a register instead of storing and reloading it
//! (forward: `y_{i−1}`; backward: the last update `L_{i+1,i} z_{i+1}`).
//! The split point is fixed by the pattern, never by the thread count, and
//! each row does the same operations in the same order on either path, so
//! the results are bit-identical for one thread and two
//! (tests/parallel_newton.rs). The
//! two-sided order rounds differently from the one-sided one (a different
//! elimination order), at rounding level.

use super::sparse::{coordinate_scale, multiplier_scale, RefineBuffers};
use super::{
    FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats, SparseLdlt, Storage,
    DEFAULT_DELTA, DEFAULT_EPSILON,
};
use crate::parallel::join_if;

/// Widest envelope row (entries left of the diagonal) the envelope path
/// takes; wider patterns use [`SparseLdlt`]. A chain of revolutes with
/// springs between neighbours has 8.
pub const MAX_BANDWIDTH: usize = 24;

/// Smallest dimension at which [`ChainLdlt`] splits the chain in two
/// halves (module docs, "Two halves"). Fixed, never the thread count: the
/// same matrix is always factorised by the same operations in the same
/// order.
pub const SPLIT_MIN_DIM: usize = 1000;

/// Smallest dimension at which the two halves are factorised and solved
/// concurrently (below it, one after the other: the same operations).
pub const PARALLEL_MIN_DIM: usize = 10_000;

/// Longest row of the separator (its two segments together).
const MAX_SEPARATOR_ROW: usize = 4 * MAX_BANDWIDTH;

/// The envelope factorisation of one pattern.
///
/// Elimination order `T, B, S` (module docs): rows `0..s0` (top half,
/// eliminated downward), `s0..sb` (bottom half, from the chain's end
/// towards the middle), `sb..dim` (the separator). Rows of `T` and `B` are
/// plain envelope rows `[first[i], i)` inside their own half; a separator
/// row has two segments, `[fa, s0)` in the tail of `T` and `[first[i], i)`
/// over the tail of `B` and the separator. Unsplit: `s0 = sb = dim`.
#[derive(Debug)]
pub(super) struct Envelope {
    pub(super) dim: usize,
    pub(super) n: usize,
    pub(super) nnz: usize,
    /// `perm[i]`: row/column of `K` eliminated `i`-th.
    pub(super) perm: Vec<usize>,
    pub(super) s0: usize,
    pub(super) sb: usize,
    /// First column of row `i`'s (last) envelope segment.
    pub(super) first: Vec<usize>,
    /// Separator row `sb + r`: first column of its segment in `T`.
    pub(super) fa: Vec<usize>,
    /// Row `i`'s entries left of the diagonal start at `env[ptr[i]]`
    /// (separator rows: the `T` segment, then the other).
    pub(super) ptr: Vec<usize>,
    /// `L` by rows (envelope), then the pivots `d` (`env[ptr[dim] + i]`).
    env: Vec<f64>,
    /// `1/d_i`.
    dinv: Vec<f64>,
    /// Where each value of `K` goes, by the part (`T`, `B`, `S`) of its
    /// envelope row: `K`'s slot, its position in that part's storage,
    /// the permuted row and column.
    pub(super) fill: [Vec<Fill>; 3],
    /// Slot of each permuted row's diagonal entry in `K`.
    pub(super) dslot: Vec<usize>,
    /// A multiplier row's Φ_q entries (slot, permuted column, always
    /// eliminated before the row and in the same part or an earlier one):
    /// `phi_ent[phi_ptr[i]..phi_ptr[i + 1]]` (permuted numbering).
    pub(super) phi_ptr: Vec<usize>,
    pub(super) phi_ent: Vec<(usize, usize)>,
    /// Expected pivot signs (permuted numbering).
    positive: Vec<bool>,
    /// The scaling of [`SparseLdlt`] (`saddle_scaling`) in elimination order.
    pscale: Vec<f64>,
    /// Permuted right-hand side.
    w: Vec<f64>,
}

/// Group (body) range of each multiplier row: lowest and highest body among
/// its coordinate columns, `None` when a row has no coordinate column.
fn row_groups(k: &SaddleMatrix) -> Option<Vec<(usize, usize)>> {
    let (dim, n) = (k.dim(), k.n());
    let (col_ptr, row_idx) = (k.col_ptr(), k.row_idx());
    let mut group = vec![(usize::MAX, 0usize); dim - n];
    for c in 0..n {
        for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
            if r >= n {
                let g = &mut group[r - n];
                *g = (g.0.min(c / 3), g.1.max(c / 3));
            }
        }
    }
    (!group.iter().any(|g| g.0 == usize::MAX)).then_some(group)
}

/// The one-sided body-by-body order: group after group, each group's
/// coordinates, then the multiplier rows whose highest body it is.
fn plain_order(n: usize, groups: &[(usize, usize)]) -> Vec<usize> {
    let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); n / 3];
    for (r, &(_, hi)) in groups.iter().enumerate() {
        rows_of[hi].push(n + r);
    }
    let mut perm = Vec::with_capacity(n + groups.len());
    for (g, rows) in rows_of.iter().enumerate() {
        perm.extend(3 * g..3 * g + 3);
        perm.extend_from_slice(rows);
    }
    perm
}

/// The two-sided order `T, B, S` about the middle body `gm`: `T` the
/// bodies below `gm` in the one-sided order, `B` the bodies above it from
/// the last down, each body's coordinates before the multiplier rows whose
/// lowest body it is, `S` body `gm` and every row touching it or spanning
/// it. Returns `(perm, s0, sb)`.
fn split_order(n: usize, groups: &[(usize, usize)]) -> (Vec<usize>, usize, usize) {
    let ng = n / 3;
    let gm = ng / 2;
    let (mut t_rows, mut b_rows) = (vec![Vec::new(); ng], vec![Vec::new(); ng]);
    let mut s_rows = Vec::new();
    for (r, &(lo, hi)) in groups.iter().enumerate() {
        if hi < gm {
            t_rows[hi].push(n + r);
        } else if lo > gm {
            b_rows[lo].push(n + r);
        } else {
            s_rows.push(n + r);
        }
    }
    let mut perm = Vec::with_capacity(n + groups.len());
    for (g, rows) in t_rows.iter().enumerate().take(gm) {
        perm.extend(3 * g..3 * g + 3);
        perm.extend_from_slice(rows);
    }
    let s0 = perm.len();
    for g in (gm + 1..ng).rev() {
        perm.extend(3 * g..3 * g + 3);
        perm.extend_from_slice(&b_rows[g]);
    }
    let sb = perm.len();
    perm.extend(3 * gm..3 * gm + 3);
    perm.extend_from_slice(&s_rows);
    (perm, s0, sb)
}

impl Envelope {
    /// The envelope of `k` in the body-by-body order (two-sided when
    /// `split` and the pattern allows it), or `None` when a multiplier row
    /// has no coordinate column or a row is wider than [`MAX_BANDWIDTH`].
    pub(super) fn analyze(k: &SaddleMatrix, split: bool) -> Option<Self> {
        let n = k.n();
        if n % 3 != 0 {
            return None;
        }
        let groups = row_groups(k)?;
        if split && k.dim() >= SPLIT_MIN_DIM && n / 3 >= 3 {
            let (perm, s0, sb) = split_order(n, &groups);
            if let Some(e) = Self::layout(k, perm, s0, sb) {
                return Some(e);
            }
        }
        let dim = k.dim();
        Self::layout(k, plain_order(n, &groups), dim, dim)
    }

    /// Envelope rows, storage and slot map of `k` in the order `perm` with
    /// the halves ending at `s0`, `sb`; `None` when an entry couples the
    /// two halves or a row is too wide.
    fn layout(k: &SaddleMatrix, perm: Vec<usize>, s0: usize, sb: usize) -> Option<Self> {
        let (dim, n) = (k.dim(), k.n());
        let (col_ptr, row_idx) = (k.col_ptr(), k.row_idx());
        let mut inv = vec![0usize; dim];
        for (new, &old) in perm.iter().enumerate() {
            inv[old] = new;
        }
        let mut first: Vec<usize> = (0..dim).collect();
        let mut fa = vec![s0; dim - sb];
        for c in 0..dim {
            for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
                let (a, b) = (inv[r], inv[c]);
                let (hi, lo) = (a.max(b), a.min(b));
                if hi >= sb && lo < s0 {
                    fa[hi - sb] = fa[hi - sb].min(lo);
                } else if hi >= s0 && hi < sb && lo < s0 {
                    return None; // B coupled to T: no separator here
                } else {
                    first[hi] = first[hi].min(lo);
                }
            }
        }
        let len = |i: usize| {
            (i - first[i])
                + if i >= sb {
                    s0 - fa[i - sb] // fa = s0: no T segment
                } else {
                    0
                }
        };
        if (0..sb).any(|i| i - first[i] > MAX_BANDWIDTH)
            || (sb..dim).any(|i| len(i) > MAX_SEPARATOR_ROW)
        {
            return None;
        }
        let mut ptr = vec![0usize; dim + 1];
        for i in 0..dim {
            ptr[i + 1] = ptr[i] + len(i);
        }
        let profile = ptr[dim];
        if profile + dim > u32::MAX as usize {
            return None;
        }
        // each value's part and its position in that part: L rows from
        // ptr[part start], then the part's pivots
        let parts = [0..s0, s0..sb, sb..dim];
        let part_of = |i: usize| usize::from(i >= s0) + usize::from(i >= sb);
        let mut fill: [Vec<Fill>; 3] = Default::default();
        for c in 0..dim {
            for s in col_ptr[c]..col_ptr[c + 1] {
                let (a, b) = (inv[row_idx[s]], inv[c]);
                let (hi, lo) = (a.max(b), a.min(b));
                let part = part_of(hi);
                let r = &parts[part];
                let p0 = ptr[r.start];
                let pos = if hi == lo {
                    (ptr[r.end] - p0) + (hi - r.start)
                } else if hi >= sb && lo < s0 {
                    ptr[hi] - p0 + (lo - fa[hi - sb])
                } else if hi >= sb {
                    ptr[hi] - p0 + (s0 - fa[hi - sb]) + (lo - first[hi])
                } else {
                    ptr[hi] - p0 + (lo - first[hi])
                };
                fill[part].push(Fill {
                    slot: s as u32,
                    pos: pos as u32,
                    row: a as u32,
                    col: b as u32,
                });
            }
        }
        let diag_slots = k.diag_slots();
        let dslot: Vec<usize> = perm.iter().map(|&j| diag_slots[j]).collect();
        let mut phi_rows: Vec<Vec<(usize, usize)>> = vec![Vec::new(); dim];
        for c in 0..n {
            for s in col_ptr[c]..col_ptr[c + 1] {
                if row_idx[s] >= n {
                    phi_rows[inv[row_idx[s]]].push((s, inv[c]));
                }
            }
        }
        let mut phi_ptr = vec![0usize; dim + 1];
        for (i, r) in phi_rows.iter().enumerate() {
            phi_ptr[i + 1] = phi_ptr[i] + r.len();
        }
        let phi_ent = phi_rows.concat();
        let positive = perm.iter().map(|&i| i < n).collect();
        Some(Self {
            dim,
            n,
            nnz: k.nnz(),
            perm,
            s0,
            sb,
            first,
            fa,
            ptr,
            env: vec![0.0; profile + dim],
            dinv: vec![0.0; dim],
            fill,
            dslot,
            phi_ptr,
            phi_ent,
            positive,
            pscale: vec![1.0; dim],
            w: vec![0.0; dim],
        })
    }

    /// Is the order two-sided?
    fn is_split(&self) -> bool {
        self.s0 < self.dim
    }

    /// Scaled, regularised LDLᵀ of the values of `k` (module docs): the
    /// halves `T` and `B` concurrently (`join_if`; each is sequential
    /// inside and touches only its own rows), then the separator.
    fn factorize(
        &mut self,
        k: &SaddleMatrix,
        epsilon: f64,
        delta: f64,
    ) -> Result<Regularized, LinalgError> {
        let (dim, s0, sb) = (self.dim, self.s0, self.sb);
        let par = dim >= PARALLEL_MIN_DIM;
        let rule = Pivots {
            positive: &self.positive,
            epsilon,
            delta,
        };
        let vals = k.values();
        let (first, ptr, fa) = (&self.first, &self.ptr, &self.fa);
        let profile = ptr[dim];
        let perm = &self.perm;
        let scaling = Scaling {
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
        let (rt, rb) = join_if(
            par,
            || {
                scaling.rows(0..s0, 0, ps_t);
                load(fill_t, perm, vals, ps_t, 0, lower_t, diag_t)?;
                crout_rows(first, ptr, 0, 0..s0, lower_t, diag_t, dinv_t, &rule)
            },
            || {
                scaling.rows(s0..sb, s0, ps_b);
                load(fill_b, perm, vals, ps_b, s0, lower_b, diag_b)?;
                crout_rows(first, ptr, s0, s0..sb, lower_b, diag_b, dinv_b, &rule)
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
            let d = rule.pivot(i, d, &mut regularized)?;
            diag[i] = d;
            dinv[i] = 1.0 / d;
        }
        Ok(regularized)
    }

    /// `x ← S (S K S)⁻¹ S x` with the last factorisation: `L y = P S x`,
    /// `Lᵀ z = D⁻¹ y` by rows of `L` from the last, `x = S Pᵀ z`; the
    /// halves concurrently as in `factorize`, the separator between them.
    /// Returns whether every entry of the solution is finite.
    fn solve(&mut self, x: &mut [f64]) -> bool {
        let (dim, s0, sb) = (self.dim, self.s0, self.sb);
        let par = dim >= PARALLEL_MIN_DIM;
        let (w, first, ptr, fa) = (&mut self.w, &self.first, &self.ptr, &self.fa);
        let (perm, pscale, dinv) = (&self.perm, &self.pscale, &self.dinv);
        let env = &self.env[..ptr[dim]];
        let rows = Rows {
            first,
            ptr,
            env,
            perm,
            pscale,
        };
        // the halves' forward rows read their right-hand side `(P S x)_i`
        // from x (the gather fused into the substitution); the separator's
        // forward rows need the halves' y before D⁻¹, so D⁻¹ comes after
        let xr: &[f64] = x;
        // two threads: a half each; one: both halves' rows in turn
        let two = par && crate::parallel::concurrent();
        {
            let (w_t, w_rest) = w.split_at_mut(s0);
            let w_b = &mut w_rest[..sb - s0];
            if two {
                crate::parallel::team::join(
                    || rows.forward(xr, (0, 0..s0, w_t)),
                    || rows.forward(xr, (s0, s0..sb, w_b)),
                );
            } else {
                rows.forward_interleaved(xr, (0, 0..s0, w_t), (s0, s0..sb, w_b));
            }
        }
        for i in sb..dim {
            w[i] = xr[perm[i]] * pscale[i];
        }
        for i in sb..dim {
            let (fai, fi, pi) = (fa[i - sb], first[i], ptr[i]);
            let la = s0 - fai;
            let d =
                dot2(&env[pi..pi + la], &w[fai..s0]) + dot2(&env[pi + la..ptr[i + 1]], &w[fi..i]);
            w[i] -= d;
        }
        {
            let (w_t, w_rest) = w.split_at_mut(s0);
            let scale = |w: &mut [f64], d: &[f64]| {
                for (wi, &di) in w.iter_mut().zip(d) {
                    *wi *= di;
                }
            };
            let (w_b, w_s) = w_rest.split_at_mut(sb - s0);
            join_if(
                par,
                || scale(w_t, &dinv[..s0]),
                || scale(w_b, &dinv[s0..sb]),
            );
            scale(w_s, &dinv[sb..]);
        }
        // x = S Pᵀ z: each z_i is written to x as soon as it is final (the
        // scatter fused into the backward substitution)
        let out = Scatter::new(x);
        for i in (sb..dim).rev() {
            let (fai, fi, pi, wi) = (fa[i - sb], first[i], ptr[i], w[i]);
            out.set(perm[i], wi * pscale[i]);
            let la = s0 - fai;
            for (v, &l) in w[fai..s0].iter_mut().zip(&env[pi..pi + la]) {
                *v -= l * wi;
            }
            for (v, &l) in w[fi..i].iter_mut().zip(&env[pi + la..ptr[i + 1]]) {
                *v -= l * wi;
            }
        }
        {
            let (w_t, w_rest) = w.split_at_mut(s0);
            let w_b = &mut w_rest[..sb - s0];
            if two {
                crate::parallel::team::join(
                    || rows.backward(&out, (0, 0..s0, w_t)),
                    || rows.backward(&out, (s0, s0..sb, w_b)),
                );
            } else {
                rows.backward_interleaved(&out, (0, 0..s0, w_t), (s0, s0..sb, w_b));
            }
        }
        let (x_lo, x_hi) = x.split_at(dim / 2);
        let finite = |x: &[f64]| crate::numeric::first_non_finite(x).is_none();
        let (lo, hi) = join_if(par, || finite(x_lo), || finite(x_hi));
        lo && hi
    }
}

/// The solution vector `x` of [`Envelope::solve`] written through the
/// permutation by the backward substitution's rows, of both halves at
/// once: every position is written by exactly one row (`perm` is a
/// permutation), so concurrent writes never meet.
pub(super) struct Scatter<'a> {
    ptr: *mut f64,
    len: usize,
    _x: std::marker::PhantomData<&'a mut [f64]>,
}

// SAFETY: the rows writing through a `Scatter` write disjoint positions
// (a permutation), and `x` is borrowed mutably for the `Scatter`'s life.
unsafe impl Send for Scatter<'_> {}
unsafe impl Sync for Scatter<'_> {}

impl<'a> Scatter<'a> {
    pub(super) fn new(x: &'a mut [f64]) -> Self {
        Self {
            ptr: x.as_mut_ptr(),
            len: x.len(),
            _x: std::marker::PhantomData,
        }
    }

    #[inline(always)]
    pub(super) fn set(&self, k: usize, v: f64) {
        assert!(k < self.len);
        // SAFETY: in bounds (checked), and no other row writes position k
        unsafe { *self.ptr.add(k) = v }
    }
}

/// One value of `K` in the envelope: slot, position in its part's
/// storage, permuted row and column (of `K`'s lower-triangle entry).
#[derive(Debug, Clone, Copy)]
pub(super) struct Fill {
    pub(super) slot: u32,
    pub(super) pos: u32,
    pub(super) row: u32,
    pub(super) col: u32,
}

/// The symmetric scaling of [`SparseLdlt`] (`saddle_scaling`,
/// `coordinate_scale`, `multiplier_scale`) row by row in elimination
/// order, so each part computes its own (the maximum is exact: any order
/// gives the same bits).
struct Scaling<'a> {
    n: usize,
    perm: &'a [usize],
    dslot: &'a [usize],
    phi_ptr: &'a [usize],
    phi_ent: &'a [(usize, usize)],
    vals: &'a [f64],
}

impl Scaling<'_> {
    /// `pscale[i − base]` for the rows `rows` (`pscale` from permuted row
    /// `base`, covering the columns of their Φ_q entries).
    fn rows(&self, rows: std::ops::Range<usize>, base: usize, pscale: &mut [f64]) {
        for i in rows {
            let d = self.vals[self.dslot[i]];
            pscale[i - base] = if self.perm[i] < self.n {
                coordinate_scale(d)
            } else {
                let mut s = d.abs().sqrt();
                for &(slot, c) in &self.phi_ent[self.phi_ptr[i]..self.phi_ptr[i + 1]] {
                    s = s.max(self.vals[slot].abs() * pscale[c - base]);
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
fn load(
    fill: &[Fill],
    perm: &[usize],
    vals: &[f64],
    pscale: &[f64],
    base: usize,
    lower: &mut [f64],
    diag: &mut [f64],
) -> Result<(), LinalgError> {
    lower.fill(0.0);
    diag.fill(0.0);
    let nl = lower.len();
    for f in fill {
        let v = vals[f.slot as usize];
        let x = v * pscale[f.row as usize - base] * pscale[f.col as usize - base];
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
/// there, [`SolverStats::indefinite_pivots`](super::SolverStats)).
#[derive(Debug, Clone, Copy, Default)]
struct Regularized {
    all: usize,
    coordinate: usize,
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

/// The expected pivot signs and the regularisation of [`SparseLdlt`].
struct Pivots<'a> {
    positive: &'a [bool],
    epsilon: f64,
    delta: f64,
}

impl Pivots<'_> {
    /// Pivot `d` of row `i` (global numbering): `δ` with the expected sign
    /// when `d` has the wrong sign or is within `ε` of 0 (counted).
    fn pivot(&self, i: usize, d: f64, regularized: &mut Regularized) -> Result<f64, LinalgError> {
        let d = if self.positive[i] {
            if d <= self.epsilon {
                regularized.all += 1;
                regularized.coordinate += 1;
                self.delta
            } else {
                d
            }
        } else if d >= -self.epsilon {
            regularized.all += 1;
            -self.delta
        } else {
            d
        };
        if !d.is_finite() {
            return Err(LinalgError::Singular(format!(
                "envelope LDLᵀ: non-finite pivot at elimination step {i}"
            )));
        }
        Ok(d)
    }
}

/// `Σ_o v[a + o] v[b + o]`, `o < len`.
fn dot(v: &[f64], a: usize, b: usize, len: usize) -> f64 {
    dot2(&v[a..a + len], &v[b..b + len])
}

/// `Σ_i a_i b_i` in index order.
fn dot2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |s, (x, y)| s + x * y)
}

/// Crout (up-looking) LDLᵀ of the plain envelope rows `rows` of one half,
/// whose envelopes stay inside the half: `lower`, `diag`, `dinv` hold that
/// half only (from row `base`, at `env[ptr[base]..]`).
///
/// ```text
/// t_ij = a_ij − Σ_{k<j} t_ik L_jk,   L_ij = t_ij / d_j,   d_i = a_ii − Σ_{j<i} t_ij L_ij
/// ```
#[allow(clippy::too_many_arguments)]
fn crout_rows(
    first: &[usize],
    ptr: &[usize],
    base: usize,
    rows: std::ops::Range<usize>,
    lower: &mut [f64],
    diag: &mut [f64],
    dinv: &mut [f64],
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
            let mut dot = 0.0;
            for o in 0..j - k0 {
                // SAFETY: rows base ≤ j < i lie before row i in `lower`
                // (ptr is increasing, ptr[i + 1] − p0 ≤ len checked above),
                // and k0 + o < j stays inside both rows' envelopes.
                unsafe {
                    dot += lower.get_unchecked(ti + o) * lower.get_unchecked(lj + o);
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
        let d = rule.pivot(i, d, &mut regularized)?;
        diag[i - base] = d;
        dinv[i - base] = 1.0 / d;
    }
    Ok(regularized)
}

/// What the substitutions read of a factorisation: the envelope rows
/// (`first`, `ptr`, `env`), the permutation and the symmetric scaling
/// (`x`'s entry `perm[i]` is row `i`'s, times `pscale[i]`).
#[derive(Clone, Copy)]
struct Rows<'a> {
    first: &'a [usize],
    ptr: &'a [usize],
    env: &'a [f64],
    perm: &'a [usize],
    pscale: &'a [f64],
}

/// One half's plain rows for a substitution: the first row's index
/// (`base`), the rows and their part of the work vector.
type Half<'a> = (usize, std::ops::Range<usize>, &'a mut [f64]);

impl Rows<'_> {
    /// Forward substitution `L y = P S x` over the plain rows of one half
    /// (`y` into `w`, from row `base`).
    fn forward(&self, x: &[f64], (base, rows, w): Half<'_>) {
        let mut prev = 0.0;
        for i in rows {
            prev = self.forward_row(x, base, i, w, prev);
        }
    }

    /// Row `i` of [`Self::forward`]: `y_i = x_{perm[i]} s_i − Σ_j L_ij y_j`
    /// over its envelope `[first[i], i)`, which ends at column `i − 1`
    /// when not empty: `prev = y_{i−1}`, the previous row's result, is
    /// taken from the register instead of `w`, so the chain of dependent
    /// rows does not wait on a store and a reload. Returns `y_i`. The
    /// terms are added in column order (the same bits as a plain dot
    /// product after a separate gather).
    #[inline(always)]
    fn forward_row(&self, x: &[f64], base: usize, i: usize, w: &mut [f64], prev: f64) -> f64 {
        let (env, fi, pi) = (self.env, self.first[i], self.ptr[i]);
        assert!(self.ptr[i + 1] <= env.len() && i - base < w.len() && fi >= base);
        let len = i - fi;
        let mut y = x[self.perm[i]] * self.pscale[i];
        if len > 0 {
            let mut dot = 0.0;
            for o in 0..len - 1 {
                // SAFETY: row i's entries are env[pi..ptr[i + 1]] (checked
                // above) and its columns base ≤ fi + o < i lie in `w`.
                unsafe {
                    dot += env.get_unchecked(pi + o) * w.get_unchecked(fi - base + o);
                }
            }
            y -= dot + env[pi + len - 1] * prev;
        }
        w[i - base] = y;
        y
    }

    /// Backward substitution `Lᵀ z = w` over the plain rows of one half,
    /// from the last (`w` from row `base`); each `z_i`, final once its row
    /// is reached, goes to `x_{perm[i]} = z_i s_i` at once.
    fn backward(&self, out: &Scatter<'_>, (base, rows, w): Half<'_>) {
        let mut carry = (0.0, 0.0);
        for i in rows.rev() {
            carry = self.backward_row(out, base, i, w, carry);
        }
    }

    /// Row `i` of [`Self::backward`]: `z_i = w_i − L_{i+1,i} z_{i+1}` with
    /// the last update, `carry = (L_{i+1,i}, z_{i+1})` from the row after,
    /// taken from the register (the others are already in `w`), then
    /// `w_j −= L_ij z_i` over the envelope but its last column `i − 1`,
    /// which is returned as the next row's carry. The updates of each
    /// `w_j` come in the same order as scattered one by one (the same
    /// bits).
    #[inline(always)]
    fn backward_row(
        &self,
        out: &Scatter<'_>,
        base: usize,
        i: usize,
        w: &mut [f64],
        carry: (f64, f64),
    ) -> (f64, f64) {
        let (env, fi, pi) = (self.env, self.first[i], self.ptr[i]);
        assert!(self.ptr[i + 1] <= env.len() && fi >= base);
        let zi = w[i - base] - carry.0 * carry.1;
        out.set(self.perm[i], zi * self.pscale[i]);
        let len = i - fi;
        if len == 0 {
            return (0.0, 0.0);
        }
        for o in 0..len - 1 {
            // SAFETY: as in `forward_row`
            unsafe {
                *w.get_unchecked_mut(fi - base + o) -= env.get_unchecked(pi + o) * zi;
            }
        }
        (env[pi + len - 1], zi)
    }

    /// [`Self::forward`] of both halves on one thread, a row of each in
    /// turn. Each substitution is a chain of dependent rows (row `i` waits
    /// for row `i − 1`), latency-bound; the two independent chains overlap
    /// in the core. Every row does the same operations as in
    /// [`Self::forward`], so the results are the same bits.
    fn forward_interleaved(&self, x: &[f64], t: Half<'_>, b: Half<'_>) {
        let ((bt, rt, wt), (bb, rb, wb)) = (t, b);
        let common = rt.len().min(rb.len());
        let (mut pt, mut pb) = (0.0, 0.0);
        for r in 0..common {
            pt = self.forward_row(x, bt, rt.start + r, wt, pt);
            pb = self.forward_row(x, bb, rb.start + r, wb, pb);
        }
        // the longer half's rest, its chain continued
        let rest = |(b, r, w): Half<'_>, mut prev: f64| {
            for i in r.start + common..r.end {
                prev = self.forward_row(x, b, i, w, prev);
            }
        };
        rest((bt, rt, wt), pt);
        rest((bb, rb, wb), pb);
    }

    /// [`Self::backward`] of both halves on one thread, a row of each in
    /// turn from their last rows (as [`Self::forward_interleaved`]).
    fn backward_interleaved(&self, out: &Scatter<'_>, t: Half<'_>, b: Half<'_>) {
        let ((bt, rt, wt), (bb, rb, wb)) = (t, b);
        let common = rt.len().min(rb.len());
        let (mut ct, mut cb) = ((0.0, 0.0), (0.0, 0.0));
        for r in 1..=common {
            ct = self.backward_row(out, bt, rt.end - r, wt, ct);
            cb = self.backward_row(out, bb, rb.end - r, wb, cb);
        }
        let rest = |(b, r, w): Half<'_>, mut carry: (f64, f64)| {
            for i in (r.start..r.end - common).rev() {
                carry = self.backward_row(out, b, i, w, carry);
            }
        };
        rest((bt, rt, wt), ct);
        rest((bb, rb, wb), cb);
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
    split: bool,
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
            split: true,
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

    /// Allow the two-sided order of the module docs ("Two halves") from
    /// [`SPLIT_MIN_DIM`] on (default on); off: always the one-sided order.
    pub fn with_split(mut self, on: bool) -> Self {
        self.split = on;
        self
    }

    /// Did `analyze` choose the two-sided order (`None` before `analyze`
    /// or on the fallback path)?
    pub fn is_split(&self) -> Option<bool> {
        self.envelope.as_ref().map(Envelope::is_split)
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
        self.envelope = Envelope::analyze(k, self.split);
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
        self.factorized = false;
        let r = e.factorize(k, self.epsilon, self.delta)?;
        self.factorized = true;
        self.stats.factorizations += 1;
        self.stats.regularized_pivots += r.all;
        let indefinite = r.coordinate > 0;
        if indefinite {
            self.stats.indefinite_pivots += r.all;
        }
        Ok(FactorInfo {
            regularized_pivots: r.all,
            indefinite,
        })
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
        let finite = if self.check_residual {
            let refined = self.bufs.solve_checked(k, rhs, |x| {
                e.solve(x);
            });
            self.stats.refinements += usize::from(refined);
            rhs.iter().all(|v| v.is_finite())
        } else {
            e.solve(rhs)
        };
        if finite {
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
