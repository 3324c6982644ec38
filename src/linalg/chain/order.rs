//! The one- and two-sided body-by-body orders of a chain pattern and the
//! envelope layout of the permuted matrix (module docs of [`super`],
//! "Order and envelope" and "Two halves").

use super::{Envelope, Fill, Scalar, MAX_BANDWIDTH, MAX_SEPARATOR_ROW, SPLIT_MIN_DIM};
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

/// Items `0..keys.len()` bucketed by key (`None`: left out) in
/// compressed storage: bucket `b` is `idx[start[b]..start[b + 1]]`, each
/// in increasing item order (a stable counting sort: one allocation
/// instead of a `Vec` per bucket).
fn buckets(n_buckets: usize, keys: impl Iterator<Item = Option<usize>> + Clone) -> Buckets {
    let mut start = vec![0usize; n_buckets + 1];
    for b in keys.clone().flatten() {
        start[b + 1] += 1;
    }
    for b in 0..n_buckets {
        start[b + 1] += start[b];
    }
    let mut next = start[..n_buckets].to_vec();
    let mut idx = vec![0usize; start[n_buckets]];
    for (item, key) in keys.enumerate() {
        if let Some(b) = key {
            idx[next[b]] = item;
            next[b] += 1;
        }
    }
    Buckets { start, idx }
}

/// The result of [`buckets`].
struct Buckets {
    start: Vec<usize>,
    idx: Vec<usize>,
}

impl Buckets {
    /// Items of bucket `b`, in increasing order.
    fn of(&self, b: usize) -> &[usize] {
        &self.idx[self.start[b]..self.start[b + 1]]
    }
}

/// The one-sided body-by-body order: group after group, each group's
/// coordinates, then the multiplier rows whose highest body it is.
fn plain_order(n: usize, groups: &[(usize, usize)]) -> Vec<usize> {
    let ng = n / 3;
    let rows_of = buckets(ng, groups.iter().map(|&(_, hi)| Some(hi)));
    let mut perm = Vec::with_capacity(n + groups.len());
    for g in 0..ng {
        perm.extend(3 * g..3 * g + 3);
        perm.extend(rows_of.of(g).iter().map(|&r| n + r));
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
    // a row's bucket: its highest body in T, its lowest in B, `ng` for S
    let rows = buckets(
        ng + 1,
        groups.iter().map(|&(lo, hi)| {
            Some(if hi < gm {
                hi
            } else if lo > gm {
                lo
            } else {
                ng
            })
        }),
    );
    let mut perm = Vec::with_capacity(n + groups.len());
    for g in 0..gm {
        perm.extend(3 * g..3 * g + 3);
        perm.extend(rows.of(g).iter().map(|&r| n + r));
    }
    let s0 = perm.len();
    for g in (gm + 1..ng).rev() {
        perm.extend(3 * g..3 * g + 3);
        perm.extend(rows.of(g).iter().map(|&r| n + r));
    }
    let sb = perm.len();
    perm.extend(3 * gm..3 * gm + 3);
    perm.extend(rows.of(ng).iter().map(|&r| n + r));
    (perm, s0, sb)
}

/// The one-sided body-by-body order of `k` (`perm[i]`: the row and
/// column eliminated `i`-th), or `None` when `n` is not a multiple of 3 or
/// a multiplier row has no coordinate column. The order of [`Envelope`]'s
/// unsplit layout, shared with [`super::lu`].
pub(super) fn body_order(k: &SaddleMatrix) -> Option<Vec<usize>> {
    let n = k.n();
    if n % 3 != 0 {
        return None;
    }
    Some(plain_order(n, &row_groups(k)?))
}

impl<T: Scalar> Envelope<T> {
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
        // each part's storage sized exactly (counted first: no growth slack)
        let mut count = [0usize; 3];
        for c in 0..dim {
            for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
                count[part_of(inv[r].max(inv[c]))] += 1;
            }
        }
        let mut fill: [Vec<Fill>; 3] = count.map(Vec::with_capacity);
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
        // the Φ_q entries (slots `col_ptr[0]..col_ptr[n]`, multiplier rows)
        // by permuted row, in slot order within a row
        let rows_of_slot = |s: usize| (row_idx[s] >= n).then(|| inv[row_idx[s]]);
        let by_row = buckets(dim, (0..col_ptr[n]).map(rows_of_slot));
        let mut col_of_slot = vec![0usize; col_ptr[n]];
        for c in 0..n {
            col_of_slot[col_ptr[c]..col_ptr[c + 1]].fill(inv[c]);
        }
        let phi_ptr = by_row.start;
        let phi_ent: Vec<(usize, usize)> =
            by_row.idx.iter().map(|&s| (s, col_of_slot[s])).collect();
        let positive = perm.iter().map(|&i| i < n).collect();
        let rows = super::RowTable::new(&first, &perm, s0, sb)?;
        debug_assert!(rows.start[1] == ptr[s0] && rows.start[2] == ptr[sb]);
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
            env: vec![T::ZERO; profile + dim],
            dinv: vec![T::ZERO; dim],
            fill,
            dslot,
            phi_ptr,
            phi_ent,
            positive,
            pscale: vec![1.0; dim],
            w: vec![T::ZERO; dim],
            wd: vec![T::ZERO; dim],
            rows,
        })
    }

    /// Is the order two-sided?
    pub(super) fn is_split(&self) -> bool {
        self.s0 < self.dim
    }
}
