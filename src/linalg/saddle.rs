//! The fixed sparse pattern of the saddle-point matrix and its values.

use super::{CscPattern, LinalgError};

/// How a [`SaddleMatrix`] stores its values: what its solver factorises
/// (see [`super::SaddlePointSolver::storage`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Storage {
    /// The lower triangle (row ≥ column) of a symmetric matrix: LDLᵀ,
    /// Cholesky-based Schur complement, dense LU of the mirrored matrix.
    #[default]
    SymmetricLower,
    /// Every entry of a possibly unsymmetric matrix: sparse LU.
    Full,
}

/// How an entry `(i, j)` of the `A` block enters the matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Symmetry {
    /// One triangle of a symmetric block (mass, (Φ_qᵀ λ)_q): the value
    /// stands for both `(i, j)` and `(j, i)`.
    Symmetric,
    /// One entry of an unsymmetric block (a force Jacobian ∂g/∂q). Full
    /// storage keeps it as is; symmetric storage keeps the symmetric part
    /// `½ (A + Aᵀ)`: weight ½ off the diagonal, so that `(i, j)` and
    /// `(j, i)`, sharing one slot, sum to their mean (a modified Newton
    /// matrix, see [`crate::formulation::Index3`]).
    Unsymmetric,
}

/// The entries of the `A` block of a saddle-point matrix, each with its
/// [`Symmetry`], registered once per system; entry ids are positions in
/// registration order and address the values at assembly
/// ([`SaddleMatrix::add_a`]).
#[derive(Debug, Clone, Default)]
pub struct APattern {
    entries: Vec<(usize, usize)>,
    symmetry: Vec<Symmetry>,
}

impl APattern {
    /// An empty pattern (diagonal `A` only: the diagonal is always stored).
    pub fn new() -> Self {
        Self::default()
    }
    /// Register `entries` of one block; returns the id of the first.
    pub fn push_block(&mut self, entries: &[(usize, usize)], symmetry: Symmetry) -> usize {
        let first = self.entries.len();
        self.entries.extend_from_slice(entries);
        self.symmetry
            .extend(std::iter::repeat_n(symmetry, entries.len()));
        first
    }
    /// Number of registered entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }
    /// No entries registered?
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
    /// The registered entries, in id order.
    pub fn entries(&self) -> &[(usize, usize)] {
        &self.entries
    }
}

/// Where an `A` entry's value goes: `values[slot] += weight · v` and, when
/// `slot_t != NONE`, `values[slot_t] += weight · v`.
#[derive(Debug, Clone, Copy)]
struct ASlot {
    slot: usize,
    slot_t: usize,
    weight: f64,
}

const NONE: usize = usize::MAX;

/// Saddle-point matrix `K = [A Φ_qᵀ; Φ_q D]` of dimension `n + m` in
/// compressed sparse columns with sorted row indices, in the [`Storage`]
/// its solver needs: the lower triangle of the symmetric matrix, or every
/// entry.
///
/// The pattern always contains the diagonal of `A` and, in symmetric
/// storage, of `D` (so that regularisation has a place; full storage has
/// no `D` block), the entries of `A`
/// registered at construction, and the structural non-zeros of `Φ_q` (at
/// `(n + row, col)`, and at `(col, n + row)` in full storage). Each entry
/// knows its *slot* in the value array, so assembly writes straight into
/// place with no searching per evaluation — through the same calls
/// ([`SaddleMatrix::add_a`], [`SaddleMatrix::set_jacobian`], …) whichever
/// the storage: formulations never branch on the solver.
#[derive(Debug, Clone)]
pub struct SaddleMatrix {
    n: usize,
    m: usize,
    storage: Storage,
    pattern: CscPattern,
    values: Vec<f64>,
    diag_slots: Vec<usize>,
    a_map: Vec<ASlot>,
    a_slots: Vec<usize>,
    jac_slots: Vec<usize>,
    /// Slots of Φ_qᵀ (full storage only).
    jac_slots_t: Vec<usize>,
    /// Per Φ_q entry: the first in `jac_pattern` order with its slot
    /// (its duplicates after it are summed into that slot).
    jac_first: Vec<bool>,
}

impl SaddleMatrix {
    /// Symmetric lower-triangle storage with every `a_pattern` entry
    /// [`Symmetry::Symmetric`] (`(i, j)` and `(j, i)` share one slot;
    /// duplicates allowed) and the structural non-zeros `(row, col)` of
    /// `Φ_q` (`row < m`, `col < n`; duplicates allowed, summed).
    ///
    /// # Panics
    /// If an index is out of range (a programming error: patterns come from
    /// validated systems).
    pub fn new(
        n: usize,
        m: usize,
        a_pattern: &[(usize, usize)],
        jac_pattern: &[(usize, usize)],
    ) -> Self {
        let mut a = APattern::new();
        a.push_block(a_pattern, Symmetry::Symmetric);
        Self::with_storage(n, m, &a, jac_pattern, Storage::SymmetricLower)
    }

    /// The matrix of `n` coordinates and `m` constraint equations with the
    /// `A` entries of `a`, the `Φ_q` pattern `jac_pattern`, in `storage`.
    ///
    /// # Panics
    /// As [`SaddleMatrix::new`].
    pub fn with_storage(
        n: usize,
        m: usize,
        a: &APattern,
        jac_pattern: &[(usize, usize)],
        storage: Storage,
    ) -> Self {
        let dim = n + m;
        for &(i, j) in &a.entries {
            assert!(i < n && j < n, "A entry ({i}, {j}) outside {n}×{n}");
        }
        for &(r, c) in jac_pattern {
            assert!(r < m && c < n, "Φ_q entry ({r}, {c}) outside {m}×{n}");
        }
        let full = storage == Storage::Full;
        let lower = |i: usize, j: usize| (i.max(j), i.min(j));
        // Full storage (sparse LU) has no D block: D = 0 and the multiplier
        // diagonal stays out of the pattern (its structural zeros would
        // change LU's column ordering).
        let n_diag = if full { n } else { dim };
        let mut entries: Vec<(usize, usize)> = Vec::with_capacity(
            n_diag + 2 * a.entries.len() + (1 + usize::from(full)) * jac_pattern.len(),
        );
        entries.extend((0..n_diag).map(|i| (i, i)));
        for (&(i, j), &sym) in a.entries.iter().zip(&a.symmetry) {
            match (full, sym) {
                (false, _) => entries.push(lower(i, j)),
                (true, Symmetry::Unsymmetric) => entries.push((i, j)),
                (true, Symmetry::Symmetric) => entries.extend([(i, j), (j, i)]),
            }
        }
        for &(r, c) in jac_pattern {
            entries.push((n + r, c));
            if full {
                entries.push((c, n + r));
            }
        }
        let pattern = CscPattern::from_entries(dim, entries);
        let slot = |r: usize, c: usize| pattern.slot(r, c);
        let a_map: Vec<ASlot> = a
            .entries
            .iter()
            .zip(&a.symmetry)
            .map(|(&(i, j), &sym)| match (full, sym) {
                (false, Symmetry::Symmetric) => ASlot {
                    slot: slot(i.max(j), i.min(j)),
                    slot_t: NONE,
                    weight: 1.0,
                },
                (false, Symmetry::Unsymmetric) => ASlot {
                    slot: slot(i.max(j), i.min(j)),
                    slot_t: NONE,
                    weight: if i == j { 1.0 } else { 0.5 },
                },
                (true, Symmetry::Unsymmetric) => ASlot {
                    slot: slot(i, j),
                    slot_t: NONE,
                    weight: 1.0,
                },
                (true, Symmetry::Symmetric) => ASlot {
                    slot: slot(i, j),
                    slot_t: if i == j { NONE } else { slot(j, i) },
                    weight: 1.0,
                },
            })
            .collect();
        let diag_slots = (0..dim)
            .map(|i| if i < n_diag { slot(i, i) } else { NONE })
            .collect();
        let jac_slots: Vec<usize> = jac_pattern.iter().map(|&(r, c)| slot(n + r, c)).collect();
        let mut seen = vec![false; pattern.nnz()];
        let jac_first = jac_slots
            .iter()
            .map(|&s| !std::mem::replace(&mut seen[s], true))
            .collect();
        let jac_slots_t = if full {
            jac_pattern.iter().map(|&(r, c)| slot(c, n + r)).collect()
        } else {
            Vec::new()
        };
        Self {
            n,
            m,
            storage,
            values: vec![0.0; pattern.nnz()],
            diag_slots,
            a_slots: a_map.iter().map(|s| s.slot).collect(),
            a_map,
            jac_slots,
            jac_slots_t,
            jac_first,
            pattern,
        }
    }

    /// Number of coordinates `n`.
    pub fn n(&self) -> usize {
        self.n
    }
    /// Number of constraint equations `m`.
    pub fn m(&self) -> usize {
        self.m
    }
    /// Dimension `n + m`.
    pub fn dim(&self) -> usize {
        self.n + self.m
    }
    /// How the values are stored.
    pub fn storage(&self) -> Storage {
        self.storage
    }
    /// `Ok` when the values are stored as `needs`, else the error naming
    /// `solver` (a solver's check at `analyze`).
    pub(crate) fn require_storage(
        &self,
        needs: Storage,
        solver: &'static str,
    ) -> Result<(), LinalgError> {
        if self.storage == needs {
            Ok(())
        } else {
            Err(LinalgError::Storage { solver, needs })
        }
    }
    /// Column pointers (length `dim + 1`).
    pub fn col_ptr(&self) -> &[usize] {
        &self.pattern.col_ptr
    }
    /// Row indices, sorted within each column.
    pub fn row_idx(&self) -> &[usize] {
        &self.pattern.row_idx
    }
    /// Values, in pattern order.
    pub fn values(&self) -> &[f64] {
        &self.values
    }
    /// Mutable values in pattern order (low level: formulations assemble
    /// through [`SaddleMatrix::add_a`] and the `set_*` calls).
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }
    /// Slot of diagonal entry `i` (`i < n + m`; `usize::MAX` for the
    /// multiplier rows in full storage, which has no `D` block).
    pub fn diag_slots(&self) -> &[usize] {
        &self.diag_slots
    }
    /// Primary slot of each registered `A` entry, in id order.
    pub fn a_slots(&self) -> &[usize] {
        &self.a_slots
    }
    /// Where the registered `A` entry `id` is added ([`Self::add_a`]):
    /// `(slot, slot_t, weight)`, `slot_t` = `usize::MAX` when there is no
    /// second slot (always in symmetric storage).
    pub(crate) fn a_entry(&self, id: usize) -> (usize, usize, f64) {
        let s = self.a_map[id];
        (s.slot, s.slot_t, s.weight)
    }
    /// Slots of the Φ_q entries, in the order of `jac_pattern`
    /// ([`Self::set_jacobian`]; in full storage also `jac_slots_t`).
    pub(crate) fn jac_slots(&self) -> &[usize] {
        &self.jac_slots
    }
    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.pattern.row_idx.len()
    }

    /// Zero every value.
    pub fn set_zero(&mut self) {
        self.values.fill(0.0);
    }

    /// Write a diagonal `A = diag(a)` (e.g. the mass matrix) and zero the
    /// off-diagonal `A` entries.
    pub fn set_a_diagonal(&mut self, a: &[f64]) {
        debug_assert_eq!(a.len(), self.n);
        for s in &self.a_map {
            self.values[s.slot] = 0.0;
            if s.slot_t != NONE {
                self.values[s.slot_t] = 0.0;
            }
        }
        for (i, &ai) in a.iter().enumerate() {
            self.values[self.diag_slots[i]] = ai;
        }
    }

    /// Add `v` to diagonal entry `i` (`i < n`, or `< n + m` in symmetric
    /// storage).
    #[inline]
    pub fn add_diagonal(&mut self, i: usize, v: f64) {
        self.values[self.diag_slots[i]] += v;
    }

    /// Add `v` to the registered `A` entry `id` as its [`Symmetry`] and
    /// the storage prescribe (weight ½ for an unsymmetric off-diagonal
    /// entry in symmetric storage; both triangles of a symmetric entry in
    /// full storage).
    #[inline]
    pub fn add_a(&mut self, id: usize, v: f64) {
        let s = self.a_map[id];
        self.values[s.slot] += s.weight * v;
        if s.slot_t != NONE {
            self.values[s.slot_t] += s.weight * v;
        }
    }

    /// Write the multiplier block `D = diag(d)` (zero for the plain index-1
    /// form). Symmetric storage only: full storage has no `D` block.
    ///
    /// # Panics
    /// In full storage.
    pub fn set_d_diagonal(&mut self, d: &[f64]) {
        debug_assert_eq!(d.len(), self.m);
        assert_eq!(
            self.storage,
            Storage::SymmetricLower,
            "full storage has no D block"
        );
        for (r, &dr) in d.iter().enumerate() {
            self.values[self.diag_slots[self.n + r]] = dr;
        }
    }

    /// Write the values of Φ_q, given in the order of `jac_pattern`
    /// (duplicate entries are summed), in one pass: the first entry of a
    /// slot sets it (`0 + v`, as adding to a zeroed slot), the duplicates
    /// after it add.
    pub fn set_jacobian(&mut self, vals: &[f64]) {
        debug_assert_eq!(vals.len(), self.jac_slots.len());
        let put = |values: &mut [f64], s: usize, first: bool, v: f64| {
            values[s] = (if first { 0.0 } else { values[s] }) + v;
        };
        if self.jac_slots_t.is_empty() {
            for ((&s, &first), &v) in self.jac_slots.iter().zip(&self.jac_first).zip(vals) {
                put(&mut self.values, s, first, v);
            }
            return;
        }
        let slots = self.jac_slots.iter().zip(&self.jac_slots_t);
        for (((&s, &t), &first), &v) in slots.zip(&self.jac_first).zip(vals) {
            put(&mut self.values, s, first, v);
            put(&mut self.values, t, first, v);
        }
    }

    /// Check that every value is finite (one pass over the values; the
    /// columns are searched for the entry to name only when one is not).
    pub(crate) fn check_finite(&self) -> Result<(), LinalgError> {
        if self.values.iter().all(|v| v.is_finite()) {
            return Ok(());
        }
        for col in 0..self.dim() {
            for s in self.pattern.col_ptr[col]..self.pattern.col_ptr[col + 1] {
                if !self.values[s].is_finite() {
                    return Err(LinalgError::NonFinite {
                        row: self.pattern.row_idx[s],
                        col,
                    });
                }
            }
        }
        Ok(())
    }

    /// `y = K x`.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        if self.storage == Storage::Full {
            for (col, &xc) in x.iter().enumerate().take(self.dim()) {
                for s in self.pattern.col_ptr[col]..self.pattern.col_ptr[col + 1] {
                    y[self.pattern.row_idx[s]] += self.values[s] * xc;
                }
            }
            return;
        }
        for col in 0..self.dim() {
            let range = self.pattern.col_ptr[col]..self.pattern.col_ptr[col + 1];
            let (rows, vals) = (&self.pattern.row_idx[range.clone()], &self.values[range]);
            let xc = x[col];
            // Column `col` of the lower triangle gives y[row] += v x[col] and,
            // by symmetry, y[col] += v x[row] for the rows below the diagonal.
            let mut acc = 0.0;
            for (&row, &v) in rows.iter().zip(vals) {
                y[row] += v * xc;
                acc += v * x[row];
            }
            // The diagonal (always stored, first in its column) was counted twice.
            let diag = vals.first().copied().unwrap_or(0.0);
            y[col] += acc - diag * xc;
        }
    }

    /// Relative residual `‖K x − b‖∞ / max(‖b‖∞, tiny)`.
    pub fn relative_residual(&self, x: &[f64], b: &[f64], work: &mut [f64]) -> f64 {
        self.mul_vec(x, work);
        let mut r: f64 = 0.0;
        let mut nb: f64 = 0.0;
        for i in 0..b.len() {
            r = r.max((work[i] - b[i]).abs());
            nb = nb.max(b[i].abs());
        }
        r / nb.max(f64::MIN_POSITIVE)
    }

    /// The matrix as a dense faer matrix (cross-checks, dense solver).
    pub fn to_dense(&self) -> faer::Mat<f64> {
        let dim = self.dim();
        let mut d = faer::Mat::<f64>::zeros(dim, dim);
        for col in 0..dim {
            for s in self.pattern.col_ptr[col]..self.pattern.col_ptr[col + 1] {
                let row = self.pattern.row_idx[s];
                d[(row, col)] = self.values[s];
                if self.storage == Storage::SymmetricLower {
                    d[(col, row)] = self.values[s];
                }
            }
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pattern_slots_and_product() {
        // n = 3, m = 1, A has (2,0); Φ_q = [1 0 2]
        let mut k = SaddleMatrix::new(3, 1, &[(0, 2)], &[(0, 0), (0, 2)]);
        assert_eq!(k.dim(), 4);
        k.set_a_diagonal(&[1.0, 2.0, 3.0]);
        let a = k.a_slots()[0];
        k.values_mut()[a] = 0.5;
        k.set_jacobian(&[1.0, 2.0]);
        let dense = k.to_dense();
        let x = [1.0, -1.0, 2.0, 0.5];
        let mut y = [0.0; 4];
        k.mul_vec(&x, &mut y);
        for i in 0..4 {
            let yi: f64 = (0..4).map(|j| dense[(i, j)] * x[j]).sum();
            assert!((yi - y[i]).abs() < 1e-15);
        }
        assert_eq!(dense[(3, 2)], 2.0);
        assert_eq!(dense[(0, 2)], 0.5);
    }

    /// One assembly, two storages: the full matrix holds the unsymmetric
    /// block as given, the symmetric one its symmetric part; both hold the
    /// symmetric block, Φ_q and Φ_qᵀ alike.
    #[test]
    fn one_assembly_into_both_storages() {
        let mut a = APattern::new();
        let u = a.push_block(&[(0, 0), (0, 1), (1, 0), (1, 1)], Symmetry::Unsymmetric);
        let h = a.push_block(&[(2, 1)], Symmetry::Symmetric);
        let jac = [(0, 0), (0, 2)];
        let assemble = |k: &mut SaddleMatrix| {
            k.set_zero();
            for i in 0..3 {
                k.add_diagonal(i, 10.0 + i as f64);
            }
            for (e, v) in [1.0, 2.0, 4.0, 8.0].iter().enumerate() {
                k.add_a(u + e, *v);
            }
            k.add_a(h, 0.25);
            k.set_jacobian(&[1.0, -3.0]);
        };
        let mut full = SaddleMatrix::with_storage(3, 1, &a, &jac, Storage::Full);
        let mut sym = SaddleMatrix::with_storage(3, 1, &a, &jac, Storage::SymmetricLower);
        assemble(&mut full);
        assemble(&mut sym);
        let (f, s) = (full.to_dense(), sym.to_dense());
        let expect_full = [
            [11.0, 2.0, 0.0, 1.0],
            [4.0, 19.0, 0.25, 0.0],
            [0.0, 0.25, 12.0, -3.0],
            [1.0, 0.0, -3.0, 0.0],
        ];
        for i in 0..4 {
            for j in 0..4 {
                assert_eq!(f[(i, j)], expect_full[i][j], "full ({i}, {j})");
                let sym_part = 0.5 * (expect_full[i][j] + expect_full[j][i]);
                assert_eq!(s[(i, j)], sym_part, "symmetric ({i}, {j})");
            }
        }
        let x = [1.0, -2.0, 0.5, 3.0];
        let mut y = [0.0; 4];
        full.mul_vec(&x, &mut y);
        for i in 0..4 {
            let yi: f64 = (0..4).map(|j| expect_full[i][j] * x[j]).sum();
            assert_eq!(y[i], yi);
        }
    }
}
