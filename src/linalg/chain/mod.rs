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
//! follows: forward substitution of `T` and `B`, of `S` (each row writes
//! `y_i` and `y_i / d_i`: no `D⁻¹` pass); backward
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
//! (tests/linalg/parallel_newton.rs). The
//! two-sided order rounds differently from the one-sided one (a different
//! elimination order), at rounding level.
//!
//! # Files
//!
//! [`order`] the body-by-body orders and the envelope layout, [`factor`]
//! the scaled, regularised Crout LDLᵀ, [`solve`] the substitutions, each
//! written once for real and complex entries ([`scalar`]: `f64`, and
//! [`Complex`] for [`super::ComplexChainLdlt`]);
//! [`lu`] the band LU with partial pivoting of full (unsymmetric,
//! indefinite) matrices in the same order ([`ChainLu`]).

mod factor;
mod lu;
mod order;
mod scalar;
mod solve;

pub use lu::{ChainLu, DEFAULT_GROWTH_LIMIT};

pub(super) use scalar::{Complex, Scalar};
pub(super) use solve::Scatter;

use super::sparse::RefineBuffers;
use super::{
    FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats, SparseLdlt, Storage,
    DEFAULT_DELTA, DEFAULT_EPSILON,
};

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
/// Entries of type `T`: `f64` ([`ChainLdlt`]) or [`Complex`].
#[derive(Debug)]
pub(super) struct Envelope<T: Scalar = f64> {
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
    env: Vec<T>,
    /// `1/d_i`.
    dinv: Vec<T>,
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
    /// `y` of `L y = P S x`.
    w: Vec<T>,
    /// The substitutions' compact copy of `first` and `perm`.
    pub(super) rows: RowTable,
    /// `D⁻¹ y`, then `z` of `Lᵀ z = D⁻¹ y` (the backward substitution).
    wd: Vec<T>,
}

/// What the substitutions read per plain row besides the values, in 5
/// bytes instead of the 24 of `first`, `ptr` and `perm`: the length
/// `i − first[i]` of row `i`'s (last) envelope segment, at most
/// `MAX_SEPARATOR_ROW` < 256 (a plain row's entries start where the
/// previous row's end, `ptr[i + 1] = ptr[i] + len[i]`, so a sweep counts
/// `ptr` on from its first row), and `perm[i]`. Where the factors do not
/// fit the last-level cache (the stiff chain at N = 10⁵), every sweep
/// streams these arrays from memory with the values.
///
/// Checked once when made, so that the sweeps need no bounds checks: a
/// plain row's envelope lies inside its half (`len[i] ≤ i − base`, `base`
/// the half's first row), every `perm[i]` is below the dimension, and each
/// half's entries are `L[start[h]..start[h + 1]]` (the lengths summed).
#[derive(Debug)]
pub(in crate::linalg) struct RowTable {
    /// `i − first[i]`.
    pub(in crate::linalg) len: Vec<u8>,
    /// `perm[i]`.
    pub(in crate::linalg) perm: Vec<u32>,
    /// Where the plain rows of `T` (`0..s0`) and of `B` (`s0..sb`) start
    /// and end in the envelope storage: `T`'s are `start[0]..start[1]`,
    /// `B`'s `start[1]..start[2]`.
    pub(in crate::linalg) start: [usize; 3],
}

impl RowTable {
    /// The table of `first` and `perm` with the halves `0..s0`, `s0..sb`,
    /// or `None` when a row is longer than 255, an index does not fit 32
    /// bits, `perm` has an entry not below its length, or a plain row's
    /// envelope leaves its half.
    pub(super) fn new(first: &[usize], perm: &[usize], s0: usize, sb: usize) -> Option<Self> {
        let dim = perm.len();
        let inside = |i: usize| first[i] <= i && (i < s0 || i >= sb || first[i] >= s0);
        if first.len() != dim || s0 > sb || sb > dim || !(0..dim).all(inside) {
            return None;
        }
        let len: Vec<u8> = first
            .iter()
            .enumerate()
            .map(|(i, &f)| u8::try_from(i - f).ok())
            .collect::<Option<_>>()?;
        let perm = perm
            .iter()
            .map(|&p| u32::try_from(p).ok().filter(|_| p < dim))
            .collect::<Option<_>>()?;
        let sum = |r: std::ops::Range<usize>| len[r].iter().map(|&l| usize::from(l)).sum::<usize>();
        let start = [0, sum(0..s0), sum(0..sb)];
        Some(Self { len, perm, start })
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
        k.require_storage(Storage::SymmetricLower, "chain-ldlt")?;
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
        let r = e.factorize(k.values(), self.epsilon, self.delta)?;
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
                e.solve(&Scatter::new(x));
            });
            self.stats.refinements += usize::from(refined);
            rhs.iter().all(|v| v.is_finite())
        } else {
            e.solve(&Scatter::new(rhs))
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
