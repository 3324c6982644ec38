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
        let mut by_col: Vec<(usize, usize)> = entries
            .into_iter()
            .map(|(r, c)| {
                assert!(r < dim && c < dim, "entry ({r}, {c}) outside {dim}×{dim}");
                (c, r)
            })
            .collect();
        by_col.sort_unstable();
        by_col.dedup();
        let mut col_ptr = vec![0usize; dim + 1];
        let mut row_idx = Vec::with_capacity(by_col.len());
        for &(c, r) in &by_col {
            col_ptr[c + 1] += 1;
            row_idx.push(r);
        }
        for c in 0..dim {
            col_ptr[c + 1] += col_ptr[c];
        }
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
}
