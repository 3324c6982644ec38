//! Compressed-sparse-column patterns built once from a list of entries,
//! with slot lookup for assembly straight into the value array.

/// The structure of a `dim × dim` sparse matrix in CSC form: column
/// pointers and row indices sorted within each column, no duplicates.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CscPattern {
    /// Column pointers (length `dim + 1`).
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted within each column.
    pub row_idx: Vec<usize>,
}

impl CscPattern {
    /// The pattern holding every `(row, col)` entry given (duplicates merged).
    ///
    /// # Panics
    /// If an index is `≥ dim` (a programming error: patterns come from
    /// validated systems).
    pub(crate) fn from_entries(
        dim: usize,
        entries: impl IntoIterator<Item = (usize, usize)>,
    ) -> Self {
        // a counting sort by column (linear in the entries, where a sort of
        // the (column, row) pairs was n log n), then each column's few rows
        // sorted and merged in place
        let entries: Vec<(usize, usize)> = entries
            .into_iter()
            .inspect(|&(r, c)| assert!(r < dim && c < dim, "entry ({r}, {c}) outside {dim}×{dim}"))
            .collect();
        let mut col_ptr = vec![0usize; dim + 1];
        for &(_, c) in &entries {
            col_ptr[c + 1] += 1;
        }
        for c in 0..dim {
            col_ptr[c + 1] += col_ptr[c];
        }
        let mut next = col_ptr.clone();
        let mut rows = vec![0usize; entries.len()];
        for &(r, c) in &entries {
            rows[next[c]] = r;
            next[c] += 1;
        }
        let mut row_idx = Vec::with_capacity(rows.len());
        for c in 0..dim {
            let col = &mut rows[col_ptr[c]..col_ptr[c + 1]];
            col.sort_unstable();
            col_ptr[c] = row_idx.len();
            for (k, &r) in col.iter().enumerate() {
                if k == 0 || r != col[k - 1] {
                    row_idx.push(r);
                }
            }
        }
        col_ptr[dim] = row_idx.len();
        Self { col_ptr, row_idx }
    }

    /// Index into the value array of entry `(row, col)`.
    ///
    /// # Panics
    /// If the entry is not in the pattern.
    pub fn slot(&self, row: usize, col: usize) -> usize {
        let range = self.col_ptr[col]..self.col_ptr[col + 1];
        let pos = self.row_idx[range.clone()]
            .binary_search(&row)
            .expect("entry is in the pattern");
        range.start + pos
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_are_sorted_merged_and_found() {
        let p = CscPattern::from_entries(3, [(2, 0), (0, 0), (2, 0), (1, 2), (0, 2)]);
        assert_eq!(p.col_ptr, vec![0, 2, 2, 4]);
        assert_eq!(p.row_idx, vec![0, 2, 0, 1]);
        assert_eq!(p.nnz(), 4);
        assert_eq!(
            (p.slot(0, 0), p.slot(2, 0), p.slot(0, 2), p.slot(1, 2)),
            (0, 1, 2, 3)
        );
    }

    #[test]
    fn matches_a_sorted_set_of_the_entries() {
        // a deterministic scatter with many duplicates, against the
        // (column, row) order of a BTreeSet
        let dim = 97;
        let entries: Vec<(usize, usize)> = (0..3000usize)
            .map(|k| ((k * 37 + k / 7) % dim, (k * 53 + k * k) % dim))
            .collect();
        let p = CscPattern::from_entries(dim, entries.iter().copied());
        let set: std::collections::BTreeSet<(usize, usize)> =
            entries.iter().map(|&(r, c)| (c, r)).collect();
        let rows: Vec<usize> = set.iter().map(|&(_, r)| r).collect();
        assert_eq!(p.row_idx, rows);
        for c in 0..dim {
            let n_c = set.iter().filter(|e| e.0 == c).count();
            assert_eq!(p.col_ptr[c + 1] - p.col_ptr[c], n_c, "column {c}");
        }
    }
}
