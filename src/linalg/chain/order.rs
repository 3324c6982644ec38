//! The one- and two-sided body-by-body orders of a chain pattern and the
//! envelope layout of the permuted matrix (module docs of [`super`],
//! "Order and envelope" and "Two halves").

use super::{Envelope, Fill, MAX_BANDWIDTH, MAX_SEPARATOR_ROW, SPLIT_MIN_DIM};
use crate::linalg::SaddleMatrix;

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
    pub(in crate::linalg) fn analyze(k: &SaddleMatrix, split: bool) -> Option<Self> {
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
    pub(super) fn is_split(&self) -> bool {
        self.s0 < self.dim
    }
}
