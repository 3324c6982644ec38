//! The fixed sparse pattern of the saddle-point matrix and its values.

use super::{CscPattern, LinalgError};

/// Symmetric saddle-point matrix `K = [A Φ_qᵀ; Φ_q D]` of dimension `n + m`,
/// stored as the lower triangle (row ≥ column) in compressed sparse columns
/// with sorted row indices.
///
/// The pattern always contains the full diagonal (coordinates and
/// multipliers, so that regularisation `D` has a place), the entries of `A`
/// named at construction, and the structural non-zeros of `Φ_q` (stored at
/// `(n + row, col)`). Each entry knows its *slot* in the value array, so
/// assembly writes straight into place with no searching per evaluation.
#[derive(Debug, Clone)]
pub struct SaddleMatrix {
    n: usize,
    m: usize,
    pattern: CscPattern,
    values: Vec<f64>,
    diag_slots: Vec<usize>,
    a_slots: Vec<usize>,
    jac_slots: Vec<usize>,
}

impl SaddleMatrix {
    /// Build the pattern.
    ///
    /// * `n`, `m`: coordinates and constraint equations;
    /// * `a_pattern`: off-diagonal entries `(i, j)` of the `n × n` block `A`
    ///   (either triangle; `(i, j)` and `(j, i)` share one slot; duplicates allowed);
    /// * `jac_pattern`: structural non-zeros `(row, col)` of `Φ_q`
    ///   (`row < m`, `col < n`; duplicates allowed and share one slot).
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
        let dim = n + m;
        for &(i, j) in a_pattern {
            assert!(i < n && j < n, "A entry ({i}, {j}) outside {n}×{n}");
        }
        for &(r, c) in jac_pattern {
            assert!(r < m && c < n, "Φ_q entry ({r}, {c}) outside {m}×{n}");
        }
        // Lower triangle (row ≥ col): the full diagonal, A, and Φ_q at (n + r, c).
        let pattern = CscPattern::from_entries(
            dim,
            (0..dim)
                .map(|i| (i, i))
                .chain(a_pattern.iter().map(|&(i, j)| (i.max(j), i.min(j))))
                .chain(jac_pattern.iter().map(|&(r, c)| (n + r, c))),
        );
        let mut k = Self {
            n,
            m,
            values: vec![0.0; pattern.nnz()],
            pattern,
            diag_slots: Vec::new(),
            a_slots: Vec::new(),
            jac_slots: Vec::new(),
        };
        k.diag_slots = (0..dim).map(|i| k.slot(i, i)).collect();
        k.a_slots = a_pattern
            .iter()
            .map(|&(i, j)| k.slot(i.max(j), i.min(j)))
            .collect();
        k.jac_slots = jac_pattern.iter().map(|&(r, c)| k.slot(n + r, c)).collect();
        k
    }

    fn slot(&self, row: usize, col: usize) -> usize {
        self.pattern.slot(row, col)
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
    /// Column pointers of the lower triangle (length `dim + 1`).
    pub fn col_ptr(&self) -> &[usize] {
        &self.pattern.col_ptr
    }
    /// Row indices of the lower triangle, sorted within each column.
    pub fn row_idx(&self) -> &[usize] {
        &self.pattern.row_idx
    }
    /// Values of the lower triangle, in pattern order.
    pub fn values(&self) -> &[f64] {
        &self.values
    }
    /// Mutable values, for assembly through the slot maps.
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }
    /// Slot of diagonal entry `i` (`i < n + m`).
    pub fn diag_slots(&self) -> &[usize] {
        &self.diag_slots
    }
    /// Slots of the `a_pattern` entries given at construction, in order.
    pub fn a_slots(&self) -> &[usize] {
        &self.a_slots
    }
    /// Slots of the `jac_pattern` entries given at construction, in order.
    pub fn jac_slots(&self) -> &[usize] {
        &self.jac_slots
    }
    /// Number of stored entries of the lower triangle.
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
        for &s in &self.a_slots {
            self.values[s] = 0.0;
        }
        for (i, &ai) in a.iter().enumerate() {
            self.values[self.diag_slots[i]] = ai;
        }
    }

    /// Write the multiplier block `D = diag(d)` (zero for the plain index-1 form).
    pub fn set_d_diagonal(&mut self, d: &[f64]) {
        debug_assert_eq!(d.len(), self.m);
        for (r, &dr) in d.iter().enumerate() {
            self.values[self.diag_slots[self.n + r]] = dr;
        }
    }

    /// Write the values of Φ_q, given in the order of `jac_pattern`
    /// (duplicate entries are summed).
    pub fn set_jacobian(&mut self, vals: &[f64]) {
        debug_assert_eq!(vals.len(), self.jac_slots.len());
        for &s in &self.jac_slots {
            self.values[s] = 0.0;
        }
        for (&s, &v) in self.jac_slots.iter().zip(vals) {
            self.values[s] += v;
        }
    }

    /// Check that every value is finite.
    pub fn check_finite(&self) -> Result<(), LinalgError> {
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

    /// `y = K x` using the symmetric lower-triangle storage.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
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

    /// The full symmetric matrix as a dense faer matrix (cross-checks, dense solver).
    pub fn to_dense(&self) -> faer::Mat<f64> {
        let dim = self.dim();
        let mut d = faer::Mat::<f64>::zeros(dim, dim);
        for col in 0..dim {
            for s in self.pattern.col_ptr[col]..self.pattern.col_ptr[col + 1] {
                let row = self.pattern.row_idx[s];
                d[(row, col)] = self.values[s];
                d[(col, row)] = self.values[s];
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
}
