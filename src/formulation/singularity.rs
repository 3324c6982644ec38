//! The rank of Φ_q along a run ([`SingularityMonitor`]): redundant rows at
//! the start and singular configurations crossed, from the dependent
//! block of a coordinate split ([`super::partitioning`]).

use super::partitioning::Split;
use crate::linalg::full_pivot_order;
use crate::model::System;

/// Largest system whose rank [`SingularityMonitor`] watches at every
/// accepted step (a dense `r × r` determinant per step, `O(r³)`; 64
/// coordinates covers the mechanisms of the constraint-method study;
/// above it only the regularised pivots of the factorisations tell).
pub const MONITOR_MAX_COORDS: usize = 64;

/// Rank measure (r-th over first complete pivot of Φ_R) below which a
/// sign change of the split's determinant is a singular configuration:
/// between the ratios at true crossings and those along a regular motion
/// (docs/scaling.md, "Measurements behind the defaults").
pub const SINGULAR_RATIO: f64 = 1e-3;

/// What [`SingularityMonitor::step`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingularCrossing {
    /// Estimated time of the singular configuration (secant root of the
    /// determinant between the two accepted steps).
    pub t: f64,
    /// `σ`-like rank measure there: the r-th pivot of complete pivoting on
    /// Φ_R over the first, at the interpolated position.
    pub ratio: f64,
}

/// Rank loss of Φ_q along a run, from accepted steps only:
/// the rank r₀ and independent rows R at t0 (m − r₀ > 0: redundant
/// constraints, [`SingularityMonitor::redundant_rows`]) and, at every step,
/// the sign of `det Φ_R,u` for a split chosen by complete pivoting. A sign
/// change between two steps is checked at both ends and at the secant root
/// of the determinant (positions interpolated linearly): if the r-th
/// complete pivot of Φ_R over the first falls below [`SINGULAR_RATIO`] at
/// one of them, every r × r block is (nearly) singular there — a singular
/// configuration was crossed; otherwise only the split went singular and it
/// is re-chosen.
pub struct SingularityMonitor {
    split: Split,
    m: usize,
    r: usize,
    /// Time and determinant sign of the last accepted step (`None` before
    /// the first), its positions in `last_q`.
    last: Option<(f64, f64)>,
    last_q: Vec<f64>,
    /// `ln|det|` of the last accepted step and `(t, ln|det|)` of the one
    /// before it with its positions in `before_q` (same sign): a local
    /// minimum of `|det|` between them is checked for an even crossing.
    last_ld: f64,
    before: Option<(f64, f64)>,
    before_q: Vec<f64>,
    /// Scratch of the r × r elimination and the interpolated positions:
    /// no allocation per step.
    lu: Vec<f64>,
    qm: Vec<f64>,
    crossings: usize,
    first: Option<SingularCrossing>,
}

impl SingularityMonitor {
    /// The rank and split at `(t0, q0)`; `None` for systems without
    /// constraints or above [`MONITOR_MAX_COORDS`].
    pub fn new(sys: &System, t0: f64, q0: &[f64]) -> Option<Self> {
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        if m == 0 || n > MONITOR_MAX_COORDS {
            return None;
        }
        let split = Split::choose(sys, t0, q0, None).ok()?;
        let r = split.dep.len();
        Some(Self {
            split,
            m,
            r,
            last: None,
            last_q: vec![0.0; n],
            last_ld: 0.0,
            before: None,
            before_q: vec![0.0; n],
            lu: vec![0.0; r * r],
            qm: vec![0.0; n],
            crossings: 0,
            first: None,
        })
    }

    /// Constraint rows that are redundant at t0 (`m − rank Φ_q`).
    pub fn redundant_rows(&self) -> usize {
        self.m - self.r
    }

    /// Singular configurations crossed so far.
    pub fn crossings(&self) -> usize {
        self.crossings
    }

    /// The first one.
    pub fn first(&self) -> Option<SingularCrossing> {
        self.first
    }

    /// `(sign, ln|det|)` of the current split's block at `(q, t)`, rows
    /// scaled to unit max (Gaussian elimination, partial pivoting).
    fn log_det(&mut self, sys: &System, t: f64, q: &[f64]) -> (f64, f64) {
        self.split.dense_jacobian(sys, t, q);
        let (r, n, sp) = (self.r, self.split.n, &self.split);
        let a = &mut self.lu;
        for (i, &row) in sp.rows.iter().enumerate() {
            for (j, &col) in sp.dep.iter().enumerate() {
                a[i * r + j] = sp.dense[row * n + col];
            }
        }
        let (mut sign, mut ld) = (1.0, 0.0);
        for row in a.chunks_mut(r) {
            let s = row.iter().fold(0.0_f64, |x, v| x.max(v.abs()));
            if s == 0.0 {
                return (0.0, f64::NEG_INFINITY);
            }
            row.iter_mut().for_each(|v| *v /= s);
        }
        for k in 0..r {
            let p = (k..r)
                .max_by(|&i, &j| a[i * r + k].abs().total_cmp(&a[j * r + k].abs()))
                .unwrap_or(k);
            if a[p * r + k] == 0.0 {
                return (0.0, f64::NEG_INFINITY);
            }
            if p != k {
                for c in 0..r {
                    a.swap(k * r + c, p * r + c);
                }
                sign = -sign;
            }
            let d = a[k * r + k];
            sign *= d.signum();
            ld += d.abs().ln();
            for i in k + 1..r {
                let f = a[i * r + k] / d;
                for c in k..r {
                    a[i * r + c] -= f * a[k * r + c];
                }
            }
        }
        (sign, ld)
    }

    /// The r-th complete pivot of Φ_R over the first at `(q, t)`.
    fn rank_ratio(&mut self, sys: &System, t: f64, q: &[f64]) -> f64 {
        self.split.dense_jacobian(sys, t, q);
        let n = self.split.n;
        let mut a: Vec<f64> = self
            .split
            .rows
            .iter()
            .flat_map(|&i| self.split.dense[i * n..(i + 1) * n].iter().copied())
            .collect();
        let order = full_pivot_order(&mut a, self.r, n, 0.0);
        if order.rank < self.r || order.pivots.is_empty() {
            return 0.0;
        }
        order.pivots[self.r - 1] / order.pivots[0]
    }

    /// After an accepted step: `Some` the first time a singular
    /// configuration is found crossed (see the type's docs).
    pub fn step(&mut self, sys: &System, t: f64, q: &[f64]) -> Option<SingularCrossing> {
        if self.r == 0 {
            return None;
        }
        let (sign, ld) = self.log_det(sys, t, q);
        let mut found = None;
        if let Some((t_a, sign_a)) = self.last.take() {
            if sign != sign_a {
                let q_a = std::mem::take(&mut self.last_q);
                let (_, ld_a) = self.log_det(sys, t_a, &q_a);
                // secant root of det between the steps
                let s = 1.0 / (1.0 + (ld - ld_a).exp());
                let s = if s.is_finite() { s } else { 0.5 };
                let mut qm = std::mem::take(&mut self.qm);
                for ((m, a), b) in qm.iter_mut().zip(&q_a).zip(q) {
                    *m = a + s * (b - a);
                }
                let tm = t_a + s * (t - t_a);
                let (ra, rb, rm) = (
                    self.rank_ratio(sys, t_a, &q_a),
                    self.rank_ratio(sys, t, q),
                    self.rank_ratio(sys, tm, &qm),
                );
                (self.last_q, self.qm) = (q_a, qm);
                if ra.min(rb).min(rm) < SINGULAR_RATIO {
                    self.crossings += 1;
                    let c = SingularCrossing { t: tm, ratio: rm };
                    if self.first.is_none() {
                        self.first = Some(c);
                        found = Some(c);
                    }
                } else if let Ok(s) = Split::choose(sys, t, q, Some(self.r)) {
                    self.split = s; // only this split went singular
                    let (sign, ld) = self.log_det(sys, t, q);
                    self.last = Some((t, sign));
                    self.last_q.copy_from_slice(q);
                    self.last_ld = ld;
                    self.before = None;
                    return None;
                }
                self.before = None;
            } else if let Some(c) = self.even_crossing(sys, t_a, t, ld, q) {
                found = Some(c);
            }
            if sign == sign_a {
                self.before = Some((t_a, self.last_ld));
                std::mem::swap(&mut self.before_q, &mut self.last_q);
            }
        }
        self.last = Some((t, sign));
        self.last_q.copy_from_slice(q);
        self.last_ld = ld;
        found
    }

    /// An even number of singular directions crossed together (k identical
    /// loops, k even) leaves the determinant's sign unchanged: `det` then
    /// behaves like `c (t − t_s)²` near `t_s`. When `|det|` of the middle
    /// of the last three accepted steps is a local minimum, the vertex of
    /// the parabola through the three determinants (scaled by the middle
    /// one) estimates `t_s`; the rank measure there (positions interpolated
    /// linearly), or at the middle step, below [`SINGULAR_RATIO`] is a
    /// crossing.
    fn even_crossing(
        &mut self,
        sys: &System,
        t1: f64,
        t2: f64,
        ld2: f64,
        q2: &[f64],
    ) -> Option<SingularCrossing> {
        let (t0, ld0) = self.before?;
        let ld1 = self.last_ld;
        if !(ld1 < ld0 && ld1 < ld2) {
            return None;
        }
        let (d0, d2) = ((ld0 - ld1).exp(), (ld2 - ld1).exp());
        // vertex of the parabola through (t0, d0), (t1, 1), (t2, d2)
        let (a0, a2) = ((d0 - 1.0) / (t0 - t1), (d2 - 1.0) / (t2 - t1));
        let curv = (a2 - a0) / (t2 - t0);
        let tv = if curv > 0.0 && curv.is_finite() {
            0.5 * (t1 + t0 - a0 / curv)
        } else {
            t1
        };
        let tv = tv.clamp(t0, t2);
        let mut qm = std::mem::take(&mut self.qm);
        let (ta, qa, tb, qb) = if tv <= t1 {
            (t0, &self.before_q[..], t1, &self.last_q[..])
        } else {
            (t1, &self.last_q[..], t2, q2)
        };
        let s = if tb > ta { (tv - ta) / (tb - ta) } else { 0.0 };
        for ((m, a), b) in qm.iter_mut().zip(qa.iter()).zip(qb.iter()) {
            *m = a + s * (b - a);
        }
        let rm = self.rank_ratio(sys, tv, &qm);
        self.qm = qm;
        let q1 = std::mem::take(&mut self.last_q);
        let r1 = self.rank_ratio(sys, t1, &q1);
        self.last_q = q1;
        if rm.min(r1) >= SINGULAR_RATIO {
            return None;
        }
        self.crossings += 1;
        let c = SingularCrossing {
            t: tv,
            ratio: rm.min(r1),
        };
        if self.first.is_none() {
            self.first = Some(c);
            return Some(c);
        }
        None
    }
}
