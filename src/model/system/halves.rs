//! The forces and constraint terms of the index-3 residual (eq. (5):
//! `g(q, q̇, t)`, `Φ(q, t)` and `Φ_qᵀλ`) in two halves by bodies, for two
//! threads: each half evaluates what acts on the bodies below (or from) a
//! split body, so each thread reads and writes only its own half of q, q̇,
//! g and Φ_qᵀλ — the halves that its Newton update, substitutions and
//! error estimates touch (`crate::parallel::team`: a line moved between
//! the cores costs far more than a local one).
//!
//! Each half writes its own full-length buffers of g and Φ_qᵀλ (global
//! indices; only its coordinates are zeroed and meaningful). A piece that
//! acts on both sides (the spring and the joint across the split) goes to
//! the low half, which also zeroes and writes those of its coordinates that
//! lie in the high half (the *boundary*). Into every entry but the
//! boundary's each half adds the pieces in the order of the system's
//! evaluation plan, so those entries have the bits of
//! [`System::forces_into`] and [`System::phi_and_jacobian_tmul`]; the
//! boundary's entries, loaded from both sides, are summed afterwards by
//! the few pieces that load them, evaluated once more on their own in plan
//! order ([`System::residual_boundary`]): the same bits there too.

use super::{BodyTrig, HalfTask, Segment, StateView, System};
use std::collections::BTreeSet;
use std::ops::Range;

/// More boundary coordinates than this and the halves are not used (a
/// piece that couples far across the split).
const MAX_BOUNDARY: usize = 64;

/// One piece of a half's forces, in the order of the force plan.
#[derive(Debug, Clone)]
enum Part {
    /// Force element `e`, whole.
    Element(usize),
    /// The loads of body-separable element `e` on these bodies.
    Bodies(usize, Range<usize>),
    /// Elements (within the block) of force-kernel block `i`.
    Kernels(usize, Range<usize>),
}

/// Consecutive joints of the kernel block on one side: (high side?,
/// joints within the block, their rows).
type Run = (bool, Range<usize>, Range<usize>);

/// The residual's two halves of a [`System`] ([`System::residual_halves`]).
#[derive(Debug, Clone)]
pub struct ResidualHalves {
    split: usize,
    forces: [Vec<Part>; 2],
    runs: Vec<Run>,
    boundary: Vec<usize>,
    /// The pieces that load a boundary coordinate, in plan order (forces;
    /// joints within the block, their rows), and the coordinates they
    /// write: evaluated once more on their own for the boundary's sums.
    edge_forces: Vec<Part>,
    edge_joints: (Range<usize>, Range<usize>),
    edge_coords: Vec<usize>,
}

impl ResidualHalves {
    /// More runs of joints than this (sides alternating along the block)
    /// and the halves are not used.
    pub const MAX_RUNS: usize = 4;
    /// First coordinate of the high half (3 × the split body).
    pub fn split(&self) -> usize {
        self.split
    }
    /// The constraint rows in consecutive runs, in order, each with its
    /// side (true: the high half): `System::residual_half` takes its
    /// side's runs of Φ in this order.
    pub fn row_runs(&self) -> impl Iterator<Item = (bool, Range<usize>)> + '_ {
        self.runs.iter().map(|(h, _, r)| (*h, r.clone()))
    }
    /// Coordinates of the high half that the low half also loads: their
    /// entries come from `System::residual_boundary`.
    pub fn boundary(&self) -> &[usize] {
        &self.boundary
    }
}

impl System {
    /// The residual's halves split at body `body`, when the evaluation
    /// plan can be cut there: every joint in one kernel block (the
    /// generated chain kernels) whose joints acting below the split come
    /// first, every force element one-sided, separable by bodies, or
    /// within a kernel block whose low elements come first, and at most
    /// a few boundary coordinates. `None` otherwise.
    pub fn residual_halves(&self, body: usize) -> Option<ResidualHalves> {
        let nb = self.bodies.len();
        if !self.use_kernels || self.kernels.len() != 1 || self.plan.len() != 1 || body >= nb {
            return None;
        }
        let split = 3 * body;
        let mut boundary = BTreeSet::new();
        let b = &self.kernels[0];
        if b.rows != (0..self.n_constraints()) {
            return None;
        }
        let cols = |k: usize| -> Vec<usize> {
            self.jac_pattern[self.jac_offset[k]..self.jac_offset[k + 1]]
                .iter()
                .map(|&(_, c)| c)
                .collect()
        };
        let low = |c: &[usize]| c.iter().min().is_none_or(|&m| m < split);
        // the joints in runs of one side (a joint acting on both: low)
        let mut runs: Vec<Run> = Vec::new();
        for (j, k) in b.joints.clone().enumerate() {
            let c = cols(k);
            let high = !low(&c);
            if !high {
                boundary.extend(c.into_iter().filter(|&x| x >= split));
            }
            let rows = self.rows(k);
            match runs.last_mut() {
                Some((h, js, rs)) if *h == high => {
                    js.end = j + 1;
                    rs.end = rows.end;
                }
                _ => runs.push((high, j..j + 1, rows)),
            }
        }
        if runs.len() > ResidualHalves::MAX_RUNS {
            return None;
        }
        // the low pieces of a sequence (a block's elements, or one element) are
        // a prefix: its length, with their coordinates beyond the split
        let mut prefix = |coords: &mut dyn Iterator<Item = Vec<usize>>| -> Option<usize> {
            let mut p = 0;
            let mut high_seen = false;
            for c in coords {
                if low(&c) {
                    if high_seen {
                        return None;
                    }
                    p += 1;
                    boundary.extend(c.into_iter().filter(|&x| x >= split));
                } else {
                    high_seen = true;
                }
            }
            Some(p)
        };
        let (mut lo, mut hi) = (Vec::new(), Vec::new());
        for s in &self.force_plan {
            match *s {
                Segment::Joint(e) => {
                    let f = &self.forces[e];
                    if f.separable_by_body() {
                        lo.push(Part::Bodies(e, 0..body));
                        hi.push(Part::Bodies(e, body..nb));
                    } else {
                        let p = prefix(&mut std::iter::once(f.coordinates()))?;
                        if p == 1 {
                            lo.push(Part::Element(e));
                        } else {
                            hi.push(Part::Element(e));
                        }
                    }
                }
                Segment::Kernels(i) => {
                    let el = self.force_kernels[i].elements.clone();
                    let len = el.len();
                    let p = prefix(&mut el.map(|e| self.forces[e].coordinates()))?;
                    if p > 0 {
                        lo.push(Part::Kernels(i, 0..p));
                    }
                    if p < len {
                        hi.push(Part::Kernels(i, p..len));
                    }
                }
            }
        }
        if boundary.len() > MAX_BOUNDARY {
            return None;
        }
        // the pieces that load the boundary, and every coordinate they write
        let on_edge = |c: &[usize]| c.iter().any(|x| boundary.contains(x));
        let mut edge_coords = BTreeSet::new();
        let mut edge_forces = Vec::new();
        for s in &self.force_plan {
            match *s {
                Segment::Joint(e) => {
                    let f = &self.forces[e];
                    let c = f.coordinates();
                    if f.separable_by_body() {
                        let mut bodies: Vec<usize> = c
                            .iter()
                            .filter(|x| boundary.contains(x))
                            .map(|x| x / 3)
                            .collect();
                        bodies.dedup();
                        for b in bodies {
                            edge_coords.extend(3 * b..3 * b + 3);
                            edge_forces.push(Part::Bodies(e, b..b + 1));
                        }
                    } else if on_edge(&c) {
                        edge_coords.extend(c);
                        edge_forces.push(Part::Element(e));
                    }
                }
                Segment::Kernels(i) => {
                    let el = self.force_kernels[i].elements.clone();
                    for (j, e) in el.enumerate() {
                        let c = self.forces[e].coordinates();
                        if on_edge(&c) {
                            edge_coords.extend(c);
                            edge_forces.push(Part::Kernels(i, j..j + 1));
                        }
                    }
                }
            }
        }
        // the joints that load the boundary: one range of the block
        let edge: Vec<usize> = (0..b.joints.len())
            .filter(|&j| on_edge(&cols(b.joints.start + j)))
            .collect();
        let edge_joints = match (edge.first(), edge.last()) {
            (Some(&a), Some(&z)) if z - a + 1 == edge.len() => {
                for j in a..=z {
                    edge_coords.extend(cols(b.joints.start + j));
                }
                let rows =
                    self.row_offset[b.joints.start + a]..self.row_offset[b.joints.start + z + 1];
                (a..z + 1, rows)
            }
            (None, None) => (0..0, 0..0),
            _ => return None,
        };
        Some(ResidualHalves {
            split,
            forces: [lo, hi],
            runs,
            boundary: boundary.into_iter().collect(),
            edge_forces,
            edge_joints,
            edge_coords: edge_coords.into_iter().collect(),
        })
    }

    /// The boundary's sums, for the high half's entries there: the pieces that load
    /// a boundary coordinate, once more on their own and in plan order,
    /// into `g` and `tmp` (full length; only the boundary's entries are
    /// meaningful afterwards) — the operations [`System::forces_into`] and
    /// [`System::phi_and_jacobian_tmul`] do on those entries. `phi`: scratch
    /// for the joints' Φ (at least their rows). Returns false as
    /// [`System::residual_half`] does.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn residual_boundary(
        &self,
        h: &ResidualHalves,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lambda: &[f64],
        g: &mut [f64],
        phi: &mut [f64],
        tmp: &mut [f64],
    ) -> bool {
        for &k in &h.edge_coords {
            g[k] = 0.0;
            tmp[k] = 0.0;
        }
        let (joints, rows) = &h.edge_joints;
        if !joints.is_empty() {
            let k = &self.kernels[0].kernels;
            let l = &lambda[rows.clone()];
            let phi = &mut phi[..rows.len()];
            if !k.phi_tmul_joints(q, t, l, phi, tmp, joints.clone(), None) {
                return false;
            }
        }
        for part in &h.edge_forces {
            self.add_part(part, StateView { t, q, qd }, g, None);
        }
        true
    }

    /// Add one piece's forces at `x` to `g` (`trig`: the sines and
    /// cosines handed to the half, if any).
    fn add_part(&self, part: &Part, x: StateView<'_>, g: &mut [f64], trig: Option<BodyTrig<'_>>) {
        let StateView { t, q, qd } = x;
        match part {
            &Part::Element(e) => self.forces[e].add_forces(t, q, qd, g),
            Part::Bodies(e, bodies) => {
                self.forces[*e].add_forces_on_bodies(t, q, qd, g, bodies.clone())
            }
            Part::Kernels(i, r) => {
                let b = &self.force_kernels[*i];
                if !b.kernels.add_forces_range(x, g, r.clone(), trig) {
                    let e0 = b.elements.start;
                    for f in &self.forces[e0 + r.start..e0 + r.end] {
                        f.add_forces(t, q, qd, g);
                    }
                }
            }
        }
    }

    /// The residual's two halves `lo` and `hi` concurrently, each with
    /// the shared work of its bodies done in the same hand-over
    /// ([`crate::model::ConstraintKernels::in_halves`]; `q`: the state
    /// the halves evaluate at).
    pub(crate) fn in_residual_halves(
        &self,
        h: &ResidualHalves,
        q: &[f64],
        t: f64,
        lo: HalfTask<'_>,
        hi: HalfTask<'_>,
    ) {
        self.kernels[0].kernels.in_halves(q, t, h.split / 3, lo, hi)
    }

    /// One half of the residual's forces and constraint terms (`high`:
    /// the bodies from the split): zero the half's coordinates of `g` and
    /// `tmp` (the low half: and the boundary), put its runs' Φ into `phi`
    /// (its runs of rows, in the order of [`ResidualHalves::row_runs`])
    /// and add their Φ_qᵀλ to `tmp` (λ: every multiplier), then its
    /// forces to `g`; `trig`: the sines and cosines of its bodies handed
    /// to it by [`System::in_residual_halves`], if any. Returns false when
    /// the constraint kernels cannot evaluate a range of joints (`g`,
    /// `tmp`, `phi` then unusable).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn residual_half(
        &self,
        h: &ResidualHalves,
        high: bool,
        x: StateView<'_>,
        lambda: &[f64],
        g: &mut [f64],
        phi: &mut [&mut [f64]],
        tmp: &mut [f64],
        trig: Option<BodyTrig<'_>>,
    ) -> bool {
        let StateView { t, q, .. } = x;
        let side = usize::from(high);
        let coords = if high { h.split..g.len() } else { 0..h.split };
        g[coords.clone()].fill(0.0);
        tmp[coords].fill(0.0);
        if !high {
            for &k in &h.boundary {
                g[k] = 0.0;
                tmp[k] = 0.0;
            }
        }
        // the constraint terms before the forces (separate buffers: the
        // same bits either way). Measured on the stiff chain, N = 10 000,
        // two threads: after the forces, the low half's Φ_qᵀλ took 3.5–4×
        // the high half's; before them both take the same (cause not
        // isolated)
        let k = &self.kernels[0].kernels;
        let mine = h.runs.iter().filter(|r| r.0 == high);
        for ((_, joints, rows), phi) in mine.zip(phi.iter_mut()) {
            let l = &lambda[rows.clone()];
            if !k.phi_tmul_joints(q, t, l, phi, tmp, joints.clone(), trig) {
                return false;
            }
        }
        for part in &h.forces[side] {
            self.add_part(part, x, g, trig);
        }
        true
    }
}
