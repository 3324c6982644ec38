//! Sparse LDLᵀ (faer) of the saddle-point matrix with symbolic analysis once
//! per pattern and dynamic regularisation of the indefinite pivots.
//!
//! # What happens when
//!
//! * [`SaddlePointSolver::analyze`] (once per pattern): elimination order
//!   ([`Ordering`]), faer's symbolic Cholesky analysis of the permuted
//!   pattern (elimination tree, column counts, simplicial or supernodal
//!   structure), the permuted pattern in the triangle the numeric kernel
//!   reads plus a slot map `K slot → permuted slot`, the pivot signs, the
//!   storage of `L`/`D` and one workspace buffer sized for the numeric
//!   factorisation and the solve.
//! * [`SaddlePointSolver::factorize`] (per evaluation): a symmetric diagonal
//!   scaling (`O(nnz)`), a scatter of the scaled values through the slot map
//!   and faer's numeric LDLᵀ into the pre-allocated factor storage. No
//!   sorting, no symbolic work and no heap allocation at all: faer's
//!   numeric kernels take all their scratch from the pre-sized `MemStack`
//!   (`tests/linalg/sparse_saddle.rs` checks with a counting allocator that
//!   re-factorisation and solve perform zero allocations, on the
//!   simplicial and the supernodal path). The simplicial/supernodal numeric
//!   kernels are called directly rather than through
//!   `SymbolicCholesky::factorize_numeric_ldlt`, because that wrapper
//!   re-permutes the matrix on every call and drops faer's `LdltInfo` (the
//!   regularised-pivot count).
//! * [`SaddlePointSolver::solve_in_place`] (per right-hand side): scaled
//!   solve, residual check, at most one step of iterative refinement.
//!
//! # Regularisation
//!
//! `K` is indefinite: with `A` positive definite and `Φ_q` of full row rank
//! the LDLᵀ of a suitable order has `n` positive pivots (coordinates) and
//! `m` negative pivots (multipliers). faer's dynamic regularisation is given
//! these expected signs (in elimination order): a coordinate pivot
//! `d ≤ ε` is replaced by `+δ`, a multiplier pivot `d ≥ −ε` by `−δ`.
//! Replacing a pivot is the same as perturbing that diagonal entry of `K`,
//! so a redundant constraint row (rank-deficient `Φ_q`) gets the penalty
//! `−δ` on its multiplier: for a consistent right-hand side the coordinate
//! part of the solution is the unique one and the multiplier whose pivot
//! was regularised stays ≈ 0 (the pair's sum is the physical multiplier) — the least-squares / minimum-norm behaviour the
//! dynamics needs instead of NaNs.
//!
//! `ε` and `δ` are *relative*: each factorisation first scales
//! `K̃ = S K S` with `S = diag(s)`, `s_i = 1/√|A_ii|` for the coordinates
//! (unit diagonal of `Ã`) and `s_r = 1/max(maxᵢ |Φ_ri| s_i, √|D_rr|)` for
//! the multipliers (largest scaled Jacobian entry of each row is 1). In
//! these units the multiplier pivots of a well-conditioned full-rank `Φ_q`
//! are O(1) (≥ 1 for a diagonal `A` when a row's coordinates are eliminated
//! before it), while the pivot of a redundant row is rounding noise
//! (~1e-15); the coordinate pivots are ≥ the scaled smallest eigenvalue of
//! `A`. Defaults: [`DEFAULT_EPSILON`] = 1e-11,
//! [`DEFAULT_DELTA`] = 1e-8 (scaled units, i.e. relative to the size of the
//! mass/Newton diagonal and of the Jacobian rows).

use super::{FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::{LdltError, LdltRegularization};
use faer::perm::PermRef;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, simplicial, supernodal, CholeskySymbolicParams, LdltRef,
    SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side, Spec};

/// Pivot threshold `ε` of the dynamic regularisation, in the units of the
/// scaled matrix (unit coordinate diagonal, unit-max Jacobian rows).
pub const DEFAULT_EPSILON: f64 = 1e-11;
/// Replacement magnitude `δ` for a regularised pivot (scaled units).
pub const DEFAULT_DELTA: f64 = 1e-8;
/// Relative residual above which `solve_in_place` applies one step of
/// iterative refinement.
pub const REFINE_THRESHOLD: f64 = 1e-12;

/// Elimination order of the sparse LDLᵀ.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Ordering {
    /// faer's approximate minimum degree on the pattern of `K`, followed by
    /// a pass that postpones every multiplier until all coordinates of its
    /// Jacobian row have been eliminated. Plain AMD may eliminate a
    /// ground-joint multiplier (degree 2, zero diagonal) first, which turns
    /// a full-rank matrix into regularised pivots; with the postponement
    /// every leading block is a saddle matrix with full-rank constraint
    /// part, so all pivots have the expected sign, for a little more fill
    /// than plain AMD.
    ///
    /// The default: general purpose (trees, loops, coupled `A` blocks, any
    /// joint numbering) and no slower on chains than [`chain_order`] or
    /// [`Ordering::Natural`] (docs/linear_solvers.md; the figures in
    /// docs/scaling.md, "Measurements behind the defaults").
    #[default]
    Amd,
    /// The given order: all coordinates, then all multipliers. Always safe
    /// (Schur complement `−Φ_q A⁻¹ Φ_qᵀ`), and `O(N)` fill for a chain
    /// whose joints are numbered along the chain and whose `A` is block
    /// diagonal per body.
    Natural,
    /// A user elimination order: `order[k]` is the row/column of `K`
    /// eliminated `k`-th (e.g. [`chain_order`]). `analyze` returns
    /// [`LinalgError::Dimension`] if the length is not `n + m` and panics if
    /// it is not a permutation.
    Custom(Vec<usize>),
}

/// Baraff-style elimination order for serial chains and trees (bodies
/// numbered from the root, a parent before its children).
///
/// Body `i` owns coordinates `3i..3i+2`; `joint_rows[j] = (child, rows)`
/// says that the Jacobian rows `rows` (indices into `Φ_q`, i.e. `K`
/// rows `n + r`) belong to the joint attaching body `child` to its parent
/// (or to the ground). The order eliminates the bodies leaf-first: the
/// coordinates of body `i`, then the multipliers of the joints whose child
/// is `i`, then body `i − 1`, … Rows named by no joint (loop closures,
/// drivers) are eliminated last. For a chain this is the block-tridiagonal
/// elimination with no fill outside the tridiagonal blocks. A joint's multipliers are
/// pivoted on before the parent's coordinates, so its rows restricted to
/// the child body must have full rank (true for revolute and prismatic
/// joints); otherwise the pivots get regularised.
///
/// # Panics
/// If a body or row index is out of range or a row is named twice.
pub fn chain_order(
    n_bodies: usize,
    m: usize,
    joint_rows: &[(usize, std::ops::Range<usize>)],
) -> Vec<usize> {
    let n = 3 * n_bodies;
    let mut rows_of_body: Vec<Vec<usize>> = vec![Vec::new(); n_bodies];
    let mut named = vec![false; m];
    for (child, rows) in joint_rows {
        assert!(*child < n_bodies, "body {child} out of range");
        for r in rows.clone() {
            assert!(r < m, "constraint row {r} out of range");
            assert!(!named[r], "constraint row {r} named twice");
            named[r] = true;
            rows_of_body[*child].push(r);
        }
    }
    let mut order = Vec::with_capacity(n + m);
    for i in (0..n_bodies).rev() {
        order.extend(3 * i..3 * i + 3);
        order.extend(rows_of_body[i].iter().map(|&r| n + r));
    }
    order.extend((0..m).filter(|&r| !named[r]).map(|r| n + r));
    order
}

/// Everything `analyze` prepares for one pattern.
struct Analysis {
    dim: usize,
    n: usize,
    nnz: usize,
    symbolic: SymbolicCholesky<usize>,
    /// Permuted pattern (upper triangle for simplicial, lower for supernodal).
    p_col_ptr: Vec<usize>,
    p_row_idx: Vec<usize>,
    p_values: Vec<f64>,
    /// `slot_map[s]`: position in `p_values` of slot `s` of `K`.
    slot_map: Vec<usize>,
    /// Expected pivot signs in elimination order.
    signs: Vec<i8>,
    /// Numeric values of `L` and `D`.
    l_values: Vec<f64>,
    /// Diagonal scaling of the last factorisation.
    scale: Vec<f64>,
    /// Workspace for the numeric factorisation and for the solve.
    mem: MemBuffer,
}

/// Sparse LDLᵀ of the saddle-point matrix (faer), symbolic analysis once per
/// pattern, dynamic regularisation of the pivots (see the module docs).
pub struct SparseLdlt {
    ordering: Ordering,
    epsilon: f64,
    delta: f64,
    analysis: Option<Analysis>,
    factorized: bool,
    check_residual: bool,
    bufs: RefineBuffers,
    stats: SolverStats,
}

impl Default for SparseLdlt {
    fn default() -> Self {
        Self::new(Ordering::default())
    }
}

impl std::fmt::Debug for SparseLdlt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseLdlt")
            .field("ordering", &self.ordering)
            .field("epsilon", &self.epsilon)
            .field("delta", &self.delta)
            .field("analyzed", &self.analysis.is_some())
            .field("stats", &self.stats)
            .finish()
    }
}

impl SparseLdlt {
    /// Solver with the given elimination order and default regularisation.
    pub fn new(ordering: Ordering) -> Self {
        Self {
            ordering,
            epsilon: DEFAULT_EPSILON,
            delta: DEFAULT_DELTA,
            analysis: None,
            factorized: false,
            check_residual: true,
            bufs: RefineBuffers::default(),
            stats: SolverStats::default(),
        }
    }

    /// Switch the residual check (and the iterative refinement it may
    /// trigger) after each solve on or off (default on). Off saves one
    /// sparse matrix–vector product per solve — for a chain about a quarter
    /// of factorisation + solve — at the price of not detecting an
    /// inaccurate solution; non-finite solutions are still rejected.
    pub fn with_residual_check(mut self, on: bool) -> Self {
        self.check_residual = on;
        self
    }

    /// The elimination order requested at construction.
    pub fn ordering(&self) -> &Ordering {
        &self.ordering
    }

    /// Whether the analysed pattern uses faer's supernodal (rather than
    /// simplicial) factorisation; `None` before `analyze`.
    pub fn is_supernodal(&self) -> Option<bool> {
        self.analysis
            .as_ref()
            .map(|a| matches!(a.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)))
    }

    /// Number of stored values of the factor (`L` and `D`); `None` before
    /// `analyze`.
    pub fn factor_nnz(&self) -> Option<usize> {
        self.analysis.as_ref().map(|a| a.l_values.len())
    }

    /// Elimination order (`order[k]` = index eliminated `k`-th) for `k`.
    fn elimination_order(&self, k: &SaddleMatrix) -> Result<Vec<usize>, LinalgError> {
        let dim = k.dim();
        match &self.ordering {
            Ordering::Natural => Ok((0..dim).collect()),
            Ordering::Custom(order) => {
                if order.len() != dim {
                    return Err(LinalgError::Dimension {
                        expected: dim,
                        got: order.len(),
                    });
                }
                let mut seen = vec![false; dim];
                for &i in order {
                    assert!(
                        i < dim && !std::mem::replace(&mut seen[i], true),
                        "custom ordering is not a permutation of 0..{dim}"
                    );
                }
                Ok(order.clone())
            }
            Ordering::Amd => amd_order(k),
        }
    }
}

/// faer's AMD order (forward permutation) of the symmetric `dim × dim`
/// pattern `(col_ptr, row_idx)` (both triangles, sorted rows); the error
/// names the failure.
pub(crate) fn amd_permutation(
    dim: usize,
    col_ptr: &[usize],
    row_idx: &[usize],
) -> Result<Vec<usize>, String> {
    let mut fwd = vec![0usize; dim];
    let mut inv = vec![0usize; dim];
    if dim > 0 {
        let pattern = SymbolicSparseColMatRef::new_checked(dim, dim, col_ptr, None, row_idx);
        let mut mem = MemBuffer::new(amd::order_scratch::<usize>(dim, row_idx.len()));
        amd::order(
            &mut fwd,
            &mut inv,
            pattern,
            amd::Control::default(),
            MemStack::new(&mut mem),
        )
        .map_err(|e| format!("AMD ordering failed: {e:?}"))?;
    }
    Ok(fwd)
}

/// AMD of the pattern of `K`, then multipliers postponed until all the
/// coordinates of their Jacobian row are eliminated.
fn amd_order(k: &SaddleMatrix) -> Result<Vec<usize>, LinalgError> {
    let (dim, n) = (k.dim(), k.n());
    let (col_ptr, row_idx) = (k.col_ptr(), k.row_idx());
    let fwd = amd_permutation(dim, col_ptr, row_idx).map_err(LinalgError::Singular)?;
    let order = postpone_multipliers(&fwd, n, |c| &row_idx[col_ptr[c]..col_ptr[c + 1]]);
    debug_assert_eq!(order.len(), dim);
    Ok(order)
}

/// The fill-reducing order `fwd` (a permutation of `0..n + m`, coordinates
/// `< n`, multipliers `≥ n`) with every multiplier moved to just after the
/// last of the coordinates of its Jacobian row, so that an unpivoted
/// factorisation meets a multiplier pivot only once its row is eliminated.
/// `neighbours(c)` lists, for a coordinate `c`, the indices adjacent to it
/// in the saddle matrix's pattern (those `≥ n` are its multiplier rows;
/// others are ignored).
pub(crate) fn postpone_multipliers<'a>(
    fwd: &[usize],
    n: usize,
    neighbours: impl Fn(usize) -> &'a [usize],
) -> Vec<usize> {
    let dim = fwd.len();
    // remaining (not yet eliminated) coordinates of each multiplier row
    let mut remaining = vec![0usize; dim];
    for c in 0..n {
        for &r in neighbours(c) {
            if r >= n {
                remaining[r] += 1;
            }
        }
    }
    let mut pending = vec![false; dim];
    let mut order = Vec::with_capacity(dim);
    for &i in fwd {
        if i < n {
            order.push(i);
            for &r in neighbours(i) {
                if r >= n {
                    remaining[r] -= 1;
                    if remaining[r] == 0 && pending[r] {
                        pending[r] = false;
                        order.push(r);
                    }
                }
            }
        } else if remaining[i] == 0 {
            order.push(i);
        } else {
            pending[i] = true;
        }
    }
    order
}

impl SaddlePointSolver for SparseLdlt {
    fn name(&self) -> &'static str {
        "sparse-ldlt"
    }

    fn analyze(&mut self, k: &SaddleMatrix) -> Result<(), LinalgError> {
        k.require_storage(super::Storage::SymmetricLower, self.name())?;
        let dim = k.dim();
        let n = k.n();
        let nnz = k.nnz();
        let fwd = self.elimination_order(k)?;
        let mut inv = vec![0usize; dim];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }

        let pattern =
            SymbolicSparseColMatRef::new_checked(dim, dim, k.col_ptr(), None, k.row_idx());
        // Always a custom permutation (even the identity): faer 0.24's
        // `SymmetricOrdering::Identity` skips the conversion of a
        // lower-triangle input to the upper triangle its symbolic analysis
        // reads, which yields a wrong elimination tree.
        let ord = SymmetricOrdering::Custom(PermRef::new_checked(&fwd, &inv, dim));
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            ord,
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| LinalgError::Singular(format!("symbolic analysis failed: {e:?}")))?;
        let supernodal = matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_));

        // Permuted pattern P K Pᵀ in the triangle the numeric kernel reads:
        // upper for simplicial, lower for supernodal.
        let (col_ptr, row_idx) = (k.col_ptr(), k.row_idx());
        let mut entries: Vec<(usize, usize, usize)> = Vec::with_capacity(nnz); // (col, row, slot)
        for c in 0..dim {
            for s in col_ptr[c]..col_ptr[c + 1] {
                let (a, b) = (inv[row_idx[s]], inv[c]);
                let (lo, hi) = (a.min(b), a.max(b));
                entries.push(if supernodal { (lo, hi, s) } else { (hi, lo, s) });
            }
        }
        entries.sort_unstable();
        let mut p_col_ptr = vec![0usize; dim + 1];
        let mut p_row_idx = Vec::with_capacity(nnz);
        let mut slot_map = vec![0usize; nnz];
        for (pos, &(col, row, slot)) in entries.iter().enumerate() {
            p_col_ptr[col + 1] += 1;
            p_row_idx.push(row);
            slot_map[slot] = pos;
        }
        for c in 0..dim {
            p_col_ptr[c + 1] += p_col_ptr[c];
        }
        // Validate once; `factorize` then builds the view unchecked.
        let _ = SymbolicSparseColMatRef::new_checked(dim, dim, &p_col_ptr, None, &p_row_idx);

        let signs = fwd
            .iter()
            .map(|&i| if i < n { 1i8 } else { -1i8 })
            .collect();
        let factor_req = match symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(_) => {
                simplicial::factorize_simplicial_numeric_ldlt_scratch::<usize, f64>(dim)
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                supernodal::factorize_supernodal_numeric_ldlt_scratch::<usize, f64>(
                    s,
                    Par::Seq,
                    Spec::default(),
                )
            }
        };
        let solve_req = symbolic.solve_in_place_scratch::<f64>(1, Par::Seq);
        let mem = MemBuffer::new(StackReq::any_of(&[factor_req, solve_req]));
        let l_values = vec![0.0; symbolic.len_val()];

        self.analysis = Some(Analysis {
            dim,
            n,
            nnz,
            symbolic,
            p_col_ptr,
            p_row_idx,
            p_values: vec![0.0; nnz],
            slot_map,
            signs,
            l_values,
            scale: vec![1.0; dim],
            mem,
        });
        self.bufs.resize(dim);
        self.factorized = false;
        self.stats.analyses += 1;
        Ok(())
    }

    fn factorize(&mut self, k: &SaddleMatrix) -> Result<FactorInfo, LinalgError> {
        let an = self
            .analysis
            .as_mut()
            .ok_or(LinalgError::NotReady("analyze"))?;
        if k.dim() != an.dim || k.nnz() != an.nnz || k.n() != an.n {
            return Err(LinalgError::Dimension {
                expected: an.dim,
                got: k.dim(),
            });
        }
        k.check_finite()?;
        self.factorized = false;
        let dim = an.dim;
        let (col_ptr, row_idx, vals) = (k.col_ptr(), k.row_idx(), k.values());

        saddle_scaling(k, &mut an.scale);

        // Scatter the scaled values into the permuted pattern.
        let scale = &an.scale;
        for c in 0..dim {
            let sc = scale[c];
            for s in col_ptr[c]..col_ptr[c + 1] {
                an.p_values[an.slot_map[s]] = vals[s] * scale[row_idx[s]] * sc;
            }
        }

        // SAFETY: the permuted pattern was validated with `new_checked` in
        // `analyze` and is immutable since.
        let a = SparseColMatRef::new(
            unsafe {
                SymbolicSparseColMatRef::new_unchecked(dim, dim, &an.p_col_ptr, None, &an.p_row_idx)
            },
            &an.p_values,
        );
        let regularization = LdltRegularization {
            dynamic_regularization_signs: Some(&an.signs),
            dynamic_regularization_delta: self.delta,
            dynamic_regularization_epsilon: self.epsilon,
        };
        let stack = MemStack::new(&mut an.mem);
        let result = match an.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(sym) => simplicial::factorize_simplicial_numeric_ldlt(
                &mut an.l_values,
                a,
                regularization,
                sym,
                stack,
            ),
            SymbolicCholeskyRaw::Supernodal(sym) => supernodal::factorize_supernodal_numeric_ldlt(
                &mut an.l_values,
                a,
                regularization,
                sym,
                Par::Seq,
                stack,
                Spec::default(),
            ),
        };
        let info = match result {
            Ok(info) => FactorInfo {
                regularized_pivots: info.dynamic_regularization_count,
                indefinite: false,
            },
            Err(LdltError::ZeroPivot { index }) => {
                return Err(LinalgError::Singular(format!(
                    "sparse LDLᵀ: zero or non-finite pivot at elimination step {index}"
                )))
            }
        };
        self.factorized = true;
        self.stats.factorizations += 1;
        self.stats.regularized_pivots += info.regularized_pivots;
        Ok(info)
    }

    fn solve_in_place(&mut self, k: &SaddleMatrix, rhs: &mut [f64]) -> Result<(), LinalgError> {
        let an = self
            .analysis
            .as_mut()
            .ok_or(LinalgError::NotReady("analyze"))?;
        LinalgError::check_solve(self.factorized, an.dim, k, rhs)?;
        self.stats.solves += 1;
        if self.check_residual {
            let refined = self.bufs.solve_checked(k, rhs, |x| scaled_solve(an, x));
            self.stats.refinements += usize::from(refined);
        } else {
            scaled_solve(an, rhs);
        }
        LinalgError::check_solution(rhs, "sparse LDLᵀ")
    }

    fn stats(&self) -> SolverStats {
        self.stats
    }
}

/// The symmetric scaling `S` of [`SparseLdlt`] (module docs): `s_i =
/// 1/√|A_ii|` for the coordinates, `s_r = 1/max(maxᵢ |Φ_ri| s_i, √|D_rr|)`
/// for the multipliers (1 where that is 0); [`super::ChainLdlt`] computes
/// the same row by row in its elimination order (`coordinate_scale`,
/// `multiplier_scale`).
pub(super) fn saddle_scaling(k: &SaddleMatrix, scale: &mut [f64]) {
    let (n, dim) = (k.n(), k.dim());
    let (col_ptr, row_idx, vals) = (k.col_ptr(), k.row_idx(), k.values());
    let diag = k.diag_slots();
    for c in 0..n {
        scale[c] = coordinate_scale(vals[diag[c]]);
    }
    for r in n..dim {
        scale[r] = vals[diag[r]].abs().sqrt();
    }
    for c in 0..n {
        for s in col_ptr[c]..col_ptr[c + 1] {
            let r = row_idx[s];
            if r >= n {
                scale[r] = scale[r].max(vals[s].abs() * scale[c]);
            }
        }
    }
    for s in &mut scale[n..dim] {
        *s = multiplier_scale(*s);
    }
}

/// `1/√|A_ii|` (1 for a zero diagonal), the scaling of a coordinate.
pub(super) fn coordinate_scale(a_ii: f64) -> f64 {
    let a = a_ii.abs();
    if a > 0.0 {
        1.0 / a.sqrt()
    } else {
        1.0
    }
}

/// `1/max` (1 where it is 0) of `max = max(maxᵢ |Φ_ri| s_i, √|D_rr|)`,
/// the scaling of a multiplier row.
pub(super) fn multiplier_scale(max: f64) -> f64 {
    if max > 0.0 {
        1.0 / max
    } else {
        1.0
    }
}

/// Buffers of the residual check and the one step of iterative refinement
/// the LDLᵀ solvers apply after a solve when it is on.
#[derive(Debug, Default)]
pub(super) struct RefineBuffers {
    rhs0: Vec<f64>,
    work: Vec<f64>,
    corr: Vec<f64>,
}

impl RefineBuffers {
    pub(super) fn resize(&mut self, dim: usize) {
        for v in [&mut self.rhs0, &mut self.work, &mut self.corr] {
            v.clear();
            v.resize(dim, 0.0);
        }
    }

    /// `rhs ← K⁻¹ rhs` by `solve`, then the relative residual
    /// `‖K x − b‖∞/‖b‖∞` and, above [`REFINE_THRESHOLD`] (or NaN) with a
    /// finite solution, one step `x += K⁻¹ (b − K x)`. Returns whether it
    /// refined.
    pub(super) fn solve_checked(
        &mut self,
        k: &SaddleMatrix,
        rhs: &mut [f64],
        mut solve: impl FnMut(&mut [f64]),
    ) -> bool {
        self.rhs0.copy_from_slice(rhs);
        solve(rhs);
        let res = k.relative_residual(rhs, &self.rhs0, &mut self.work);
        let mut refined = false;
        if (res.is_nan() || res > REFINE_THRESHOLD) && rhs.iter().all(|v| v.is_finite()) {
            // `work` holds K x after `relative_residual`.
            for ((c, &b), &kx) in self.corr.iter_mut().zip(&self.rhs0).zip(&self.work) {
                *c = b - kx;
            }
            solve(&mut self.corr);
            for (x, c) in rhs.iter_mut().zip(&self.corr) {
                *x += c;
            }
            refined = true;
        }
        refined
    }
}

/// `x ← S (S K S)⁻¹ S x` with the factorisation held in `an`.
fn scaled_solve(an: &mut Analysis, x: &mut [f64]) {
    for (v, s) in x.iter_mut().zip(&an.scale) {
        *v *= s;
    }
    if an.dim > 0 {
        let dim = an.dim;
        LdltRef::new(&an.symbolic, &an.l_values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, dim, 1),
            Par::Seq,
            MemStack::new(&mut an.mem),
        );
    }
    for (v, s) in x.iter_mut().zip(&an.scale) {
        *v *= s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A duplicated Jacobian row with a consistent right-hand side.
    #[test]
    fn tiny_saddle_and_redundant_row() {
        // n = 3, m = 2 identical rows [1 0 1].
        let mut k = SaddleMatrix::new(3, 2, &[], &[(0, 0), (0, 2), (1, 0), (1, 2)]);
        k.set_a_diagonal(&[2.0, 1.0, 3.0]);
        k.set_jacobian(&[1.0, 1.0, 1.0, 1.0]);
        let mut s = SparseLdlt::new(Ordering::Amd);
        s.analyze(&k).unwrap();
        let info = s.factorize(&k).unwrap();
        assert!(info.regularized_pivots > 0);
        let mut x = vec![1.0, 2.0, 3.0, 0.5, 0.5];
        s.solve_in_place(&k, &mut x).unwrap();
        assert!(x.iter().all(|v| v.is_finite()));
        // Non-redundant: 2a + λ = 1, b = 2, 3c + λ = 3, a + c = 0.5.
        // a = (1 − λ)/2, c = (3 − λ)/3 → (1−λ)/2 + (3−λ)/3 = 0.5 → λ = 1.2
        assert!((x[0] - (-0.1)).abs() < 1e-10, "{x:?}");
        assert!((x[1] - 2.0).abs() < 1e-10);
        assert!((x[2] - 0.6).abs() < 1e-10);
        assert!((x[3] + x[4] - 1.2).abs() < 1e-8);
    }

    #[test]
    fn empty_and_unconstrained() {
        let k = SaddleMatrix::new(0, 0, &[], &[]);
        let mut s = SparseLdlt::default();
        s.analyze(&k).unwrap();
        s.factorize(&k).unwrap();
        s.solve_in_place(&k, &mut []).unwrap();

        // m = 0: plain SPD A with one coupling.
        let mut k = SaddleMatrix::new(3, 0, &[(2, 0)], &[]);
        k.set_a_diagonal(&[4.0, 1.0, 2.0]);
        let slot = k.a_slots()[0];
        k.values_mut()[slot] = 1.0;
        for ord in [
            Ordering::Amd,
            Ordering::Natural,
            Ordering::Custom(vec![2, 0, 1]),
        ] {
            let mut s = SparseLdlt::new(ord);
            s.analyze(&k).unwrap();
            assert_eq!(s.factorize(&k).unwrap().regularized_pivots, 0);
            let mut x = vec![5.0, 1.0, 3.0];
            s.solve_in_place(&k, &mut x).unwrap();
            assert!((x[0] - 1.0).abs() < 1e-14 && (x[1] - 1.0).abs() < 1e-14);
            assert!((x[2] - 1.0).abs() < 1e-14, "{x:?}");
        }
        let mut s = SparseLdlt::new(Ordering::Custom(vec![0, 1]));
        assert!(matches!(s.analyze(&k), Err(LinalgError::Dimension { .. })));
    }
}
