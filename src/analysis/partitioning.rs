//! Sparse coordinate partitioning (Wehage & Haug 1982): a split of the
//! coordinates into `r = rank Φ_q` dependent ones (the pivot columns of an
//! elimination of Φ_q) and `n − r` independent ones, with the redundant
//! constraint rows, in time and memory proportional to the nonzeros of
//! Φ_q for chains and trees.
//!
//! The elimination is Markowitz's with threshold pivoting (Duff, Erisman &
//! Reid, *Direct Methods for Sparse Matrices*, §7): the next pivot column
//! is the one in the fewest remaining rows, its row the shortest among
//! those where the entry is at least [`THRESHOLD`] times the row's largest
//! (so the dependent block is well conditioned row by row); the pivot
//! row is then eliminated from the other rows of that column. On a chain
//! the free end's coordinates come first, each in one row, and no fill
//! arises: the translations become dependent and the angles independent,
//! as complete pivoting (the dense `full_pivot_order`) chooses too. A row
//! whose entries all fall to `tol` times the largest entry of Φ_q is
//! redundant. Columns whose rows all refuse the threshold are retried
//! once after the others and finally eliminated row by row on the row's
//! largest entry.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Threshold `u` of the pivot choice: a pivot is at least `u` times the
/// largest entry of its row (Duff, Erisman & Reid's usual 0.1).
pub const THRESHOLD: f64 = 0.1;

/// The split found by [`partition`].
#[derive(Debug, Clone, PartialEq)]
pub struct Partition {
    /// Numerical rank of Φ_q.
    pub rank: usize,
    /// Dependent coordinates (pivot columns), in pivot order.
    pub dependent: Vec<usize>,
    /// Independent coordinates (no pivot), ascending.
    pub independent: Vec<usize>,
    /// Redundant constraint rows (eliminated to below the tolerance),
    /// ascending.
    pub redundant: Vec<usize>,
}

/// A sparse row: `(column, value)` sorted by column, no zeros.
type Row = Vec<(usize, f64)>;

fn value_at(row: &Row, c: usize) -> Option<f64> {
    row.binary_search_by_key(&c, |e| e.0).ok().map(|k| row[k].1)
}

fn row_max(row: &Row) -> f64 {
    row.iter().fold(0.0f64, |a, e| a.max(e.1.abs()))
}

/// Working state of the elimination.
struct Elimination {
    n: usize,
    rows: Vec<Row>,
    col_rows: Vec<Vec<usize>>,
    active: Vec<bool>,
    pivot: Vec<bool>,
    deferred: Vec<bool>,
    heap: BinaryHeap<Reverse<(usize, usize)>>,
    /// Entries below this are dropped (rounding of a cancellation).
    drop: f64,
    /// A row whose largest entry is at most this is redundant.
    zero: f64,
    dependent: Vec<usize>,
    redundant: Vec<usize>,
    merged: Row,
}

impl Elimination {
    /// The active rows holding column `c` (stale entries removed).
    fn clean(&mut self, c: usize) -> usize {
        let (rows, active) = (&self.rows, &self.active);
        self.col_rows[c].retain(|&r| active[r] && value_at(&rows[r], c).is_some());
        self.col_rows[c].len()
    }

    fn key(&mut self, c: usize) -> usize {
        let cnt = self.clean(c);
        if self.deferred[c] {
            cnt + self.n + 1
        } else {
            cnt
        }
    }

    fn push(&mut self, c: usize) {
        if !self.pivot[c] {
            let k = self.key(c);
            if k > 0 && k != self.n + 1 {
                self.heap.push(Reverse((k, c)));
            }
        }
    }

    /// Row `r` pivots on column `c`: eliminated from every other active
    /// row of `c`.
    fn eliminate(&mut self, r: usize, c: usize) {
        self.pivot[c] = true;
        self.active[r] = false;
        self.dependent.push(c);
        let prow = std::mem::take(&mut self.rows[r]);
        let p = value_at(&prow, c).expect("the pivot entry");
        let others: Vec<usize> = self.col_rows[c]
            .iter()
            .copied()
            .filter(|&s| s != r)
            .collect();
        let mut touched: Vec<usize> = prow.iter().map(|e| e.0).collect();
        for s in others {
            let Some(v) = value_at(&self.rows[s], c) else {
                continue;
            };
            let f = v / p;
            let old = std::mem::take(&mut self.rows[s]);
            self.merged.clear();
            let (mut i, mut j) = (0, 0);
            while i < old.len() || j < prow.len() {
                let (col, val, fill) = if j >= prow.len() || (i < old.len() && old[i].0 < prow[j].0)
                {
                    i += 1;
                    (old[i - 1].0, old[i - 1].1, false)
                } else if i >= old.len() || prow[j].0 < old[i].0 {
                    j += 1;
                    (prow[j - 1].0, -f * prow[j - 1].1, true)
                } else {
                    i += 1;
                    j += 1;
                    (old[i - 1].0, old[i - 1].1 - f * prow[j - 1].1, false)
                };
                if col != c && val.abs() > self.drop {
                    self.merged.push((col, val));
                    if fill {
                        self.col_rows[col].push(s);
                    }
                }
            }
            touched.extend(old.iter().map(|e| e.0));
            self.rows[s] = std::mem::take(&mut self.merged);
            self.merged = old;
            if row_max(&self.rows[s]) <= self.zero {
                self.active[s] = false;
                self.redundant.push(s);
            }
        }
        self.rows[r] = prow;
        touched.sort_unstable();
        touched.dedup();
        for col in touched {
            self.push(col);
        }
    }

    /// The shortest active row of column `c` whose entry passes the
    /// threshold.
    fn choose_row(&self, c: usize) -> Option<usize> {
        let mut best: Option<(usize, f64, usize)> = None;
        for &s in &self.col_rows[c] {
            let row = &self.rows[s];
            let v = value_at(row, c).map_or(0.0, f64::abs);
            if v > 0.0 && v >= THRESHOLD * row_max(row) {
                let better = match best {
                    None => true,
                    Some((len, bv, _)) => row.len() < len || (row.len() == len && v > bv),
                };
                if better {
                    best = Some((row.len(), v, s));
                }
            }
        }
        best.map(|b| b.2)
    }
}

/// Sparse coordinate partitioning of the `m × n` matrix given by its
/// entries `(row, column, value)` (duplicates summed): module docs.
/// `tol` is relative to the largest entry (the dense path's
/// [`super::inverse::RANK_TOL`] gives the same rank decisions on
/// well-separated cases).
pub fn partition(m: usize, n: usize, entries: &[(usize, usize, f64)], tol: f64) -> Partition {
    let mut rows: Vec<Row> = vec![Vec::new(); m];
    for &(r, c, v) in entries {
        rows[r].push((c, v));
    }
    let mut scale = 0.0f64;
    for row in &mut rows {
        row.sort_unstable_by_key(|e| e.0);
        let mut out: Row = Vec::with_capacity(row.len());
        for &(c, v) in row.iter() {
            match out.last_mut() {
                Some(last) if last.0 == c => last.1 += v,
                _ => out.push((c, v)),
            }
        }
        out.retain(|e| e.1 != 0.0);
        scale = out.iter().fold(scale, |a, e| a.max(e.1.abs()));
        *row = out;
    }
    let mut col_rows: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (r, row) in rows.iter().enumerate() {
        for &(c, _) in row {
            col_rows[c].push(r);
        }
    }
    let mut e = Elimination {
        n,
        rows,
        col_rows,
        active: vec![true; m],
        pivot: vec![false; n],
        deferred: vec![false; n],
        heap: BinaryHeap::new(),
        drop: 16.0 * f64::EPSILON * scale,
        zero: tol * scale,
        dependent: Vec::new(),
        redundant: Vec::new(),
        merged: Vec::new(),
    };
    for r in 0..m {
        if row_max(&e.rows[r]) <= e.zero {
            e.active[r] = false;
            e.redundant.push(r);
        }
    }
    for c in 0..n {
        e.push(c);
    }
    while let Some(Reverse((k, c))) = e.heap.pop() {
        if e.pivot[c] || e.key(c) != k {
            continue; // stale: a fresher entry was pushed
        }
        match e.choose_row(c) {
            Some(r) => e.eliminate(r, c),
            None if !e.deferred[c] => {
                e.deferred[c] = true;
                e.push(c);
            }
            None => {} // left to the row-by-row pass
        }
    }
    // rows left: pivot on each one's largest entry
    for r in 0..m {
        if !e.active[r] {
            continue;
        }
        let row = &e.rows[r];
        let best = row.iter().fold((0.0f64, usize::MAX), |a, &(c, v)| {
            if v.abs() > a.0 {
                (v.abs(), c)
            } else {
                a
            }
        });
        if best.0 <= e.zero {
            e.active[r] = false;
            e.redundant.push(r);
        } else {
            e.clean(best.1);
            e.eliminate(r, best.1);
        }
    }
    let mut independent: Vec<usize> = (0..n).filter(|&c| !e.pivot[c]).collect();
    independent.sort_unstable();
    e.redundant.sort_unstable();
    Partition {
        rank: e.dependent.len(),
        dependent: e.dependent,
        independent,
        redundant: e.redundant,
    }
}
