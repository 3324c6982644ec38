//! The `A` block that the Newton matrices of the implicit formulations
//! share: `c_m M − c_c ∂g/∂q̇ − c_k ∂g/∂q + c_k (Φ_qᵀλ)_q` ([`super::Index3`],
//! [`super::Augmented`]), with the force Jacobians and the constraint
//! Hessians as blocks registered once in an [`APattern`] and evaluated by
//! the system (generated kernels where attached).

use super::{all_finite, FormulationError};
use crate::linalg::{APattern, SaddleMatrix, Storage, Symmetry};
use crate::model::{FdWorkspace, StateView, System};
use crate::parallel::{join_if, Halve, PARALLEL_MIN_COORDS};
use std::sync::OnceLock;

/// Ids of the registered blocks and the buffers of their values.
pub(crate) struct DynamicBlocks {
    /// Id of the first force-Jacobian entry among the `A` entries
    /// ([`System::force_jacobian_pattern`] order).
    force_first: usize,
    /// Id of the first (Φ_qᵀλ)_q entry ([`System::hessian_pattern`] order).
    hess_first: usize,
    /// The blocks' values at the last state evaluated.
    vals: BlockValues,
    /// The reciprocal part of the force Jacobians (symmetric storage,
    /// [`Self::write`]): per coordinate pair `{i, j}` (i ≠ j) of the force
    /// Jacobian pattern, `skew_ent[skew_ptr[p]..skew_ptr[p + 1]]` lists its
    /// entries, `true` for those at `(i, j)` with `i < j`; `skew_first[p]`
    /// is one of them, through which the correction is written.
    skew_first: Vec<usize>,
    skew_ptr: Vec<usize>,
    skew_ent: Vec<(usize, bool)>,
    /// Force-Jacobian entries not written in symmetric storage: those
    /// touching a controller state once [`Self::decouple_states`] was
    /// called (a `StateBorder` keeps them exactly), else none.
    skip: Vec<bool>,
    /// The assembly of [`Self::write_with_jacobian`] in two halves of the
    /// value array (symmetric storage from [`PARALLEL_MIN_COORDS`]
    /// coordinates on), made at its first call; `None` where it does not
    /// apply.
    plan: OnceLock<Option<HalfPlan>>,
}

/// The values of the dynamic blocks at one state: ∂g/∂q and ∂g/∂q̇ in the
/// order of [`System::force_jacobian_pattern`], (Φ_qᵀλ)_q in the order of
/// [`System::hessian_pattern`], with the finite-difference workspaces of
/// the elements that have no analytic ones. The Newton matrices that write
/// them ([`DynamicBlocks`], the complex matrix's real embedding) evaluate
/// them here.
pub(crate) struct BlockValues {
    pub(super) dq: Vec<f64>,
    pub(super) dqd: Vec<f64>,
    pub(super) hess: Vec<f64>,
    ws: FdWorkspace,
    /// The workspace of the Hessians (evaluated beside the force
    /// Jacobians, [`Self::evaluate`]).
    ws_hess: FdWorkspace,
}

impl BlockValues {
    /// Zeroed values for the patterns of `sys`.
    pub(crate) fn new(sys: &System) -> Self {
        let n_force = sys.force_jacobian_pattern().len();
        Self {
            dq: vec![0.0; n_force],
            dqd: vec![0.0; n_force],
            hess: vec![0.0; sys.hessian_pattern().len()],
            ws: FdWorkspace::default(),
            ws_hess: FdWorkspace::default(),
        }
    }

    /// Evaluate the force Jacobians (when `forces`), the Hessians (when
    /// `hessians`) at `x` and λ `lam`, and `Φ_q(q, t)` into `jac`, each
    /// checked finite; the blocks not evaluated keep their old values.
    pub(crate) fn evaluate(
        &mut self,
        sys: &System,
        StateView { t, q, qd }: StateView<'_>,
        lam: &[f64],
        forces: bool,
        hessians: bool,
        jac: &mut [f64],
    ) -> Result<(), FormulationError> {
        // the force Jacobians, and the Hessians with Φ_q: concurrently for
        // large systems (`join_if`; each task sequential inside and
        // writing its own buffers, so the bits do not depend on threads)
        let (dq, dqd, ws) = (&mut self.dq, &mut self.dqd, &mut self.ws);
        let (hess, ws_h) = (&mut self.hess, &mut self.ws_hess);
        join_if(
            sys.n_coords() >= PARALLEL_MIN_COORDS,
            || {
                if forces {
                    dq.fill(0.0);
                    dqd.fill(0.0);
                    sys.add_force_jacobians(t, q, qd, dq, dqd, ws);
                }
            },
            || {
                if hessians && !hess.is_empty() {
                    hess.fill(0.0);
                    sys.add_constraint_hessians(q, t, lam, hess, ws_h);
                }
                sys.jacobian_values(q, t, jac);
            },
        );
        all_finite(
            t,
            &[
                ("the force Jacobian ∂g/∂q", &self.dq),
                ("the force Jacobian ∂g/∂q̇", &self.dqd),
                ("the constraint Hessian (Φ_qᵀλ)_q", &self.hess),
                ("the constraint Jacobian Φ_q", jac),
            ],
        )
    }
}

/// The additions of [`DynamicBlocks::write`] and
/// [`SaddleMatrix::set_jacobian`] into the values of a symmetric matrix,
/// sorted into the two halves of its value array (`values[..cut]`,
/// `values[cut..]`, `cut` where the counted work of the slots before it
/// reaches half the total: [`HalfPlan::balanced_cut`]). Each half lists the
/// additions to its slots in the order the one-piece assembly makes them
/// (diagonal, force Jacobians, their reciprocal parts, Hessians, Φ_q), so
/// every slot receives the same operations in the same order: the same
/// bits on one thread or two.
struct HalfPlan {
    /// Number of values of the matrix it was made for.
    nnz: usize,
    /// First value of the high half.
    cut: usize,
    /// Dimension of that matrix.
    dim: usize,
    halves: [HalfOps; 2],
}

/// One half's additions: `(source index, slot, weight)` per block
/// (the slot counted from the half's first value).
#[derive(Default)]
struct HalfOps {
    /// Coordinate `i`: `c_m M_ii`.
    diag: Vec<(usize, usize)>,
    /// Force-Jacobian entry `e` (not skipped).
    force: Vec<(usize, usize, f64)>,
    /// Coordinate pair `p` of the reciprocal part (through its first entry).
    skew: Vec<(usize, usize, f64)>,
    /// Hessian entry `e`.
    hess: Vec<(usize, usize, f64)>,
    /// Φ_q entry `e`.
    jac: Vec<(usize, usize)>,
}

impl HalfPlan {
    /// The cut of `k`'s values into two halves of equal counted work (so
    /// that neither thread waits for the other), counted in memory
    /// accesses: each value one (zeroing), each addition
    /// [`DynamicBlocks::write`] and [`SaddleMatrix::set_jacobian`] make to
    /// it three (its source read, the value read and written), a
    /// reciprocal part's two more per force entry it reads (`dq` and
    /// `dqd`); the cut is the first value at which the work before it
    /// passes half the total. It depends on the pattern only, never on
    /// the thread count.
    fn balanced_cut(b: &DynamicBlocks, k: &SaddleMatrix) -> usize {
        const ADD: usize = 3;
        let mut work = vec![1usize; k.nnz()];
        for &slot in &k.diag_slots()[..k.n()] {
            work[slot] += ADD;
        }
        let slot = |id: usize| k.a_entry(id).0;
        for e in (0..b.vals.dq.len()).filter(|&e| !b.skip[e]) {
            work[slot(b.force_first + e)] += ADD;
        }
        for (p, &first) in b.skew_first.iter().enumerate() {
            work[slot(b.force_first + first)] += ADD + 2 * (b.skew_ptr[p + 1] - b.skew_ptr[p]);
        }
        for e in 0..b.vals.hess.len() {
            work[slot(b.hess_first + e)] += ADD;
        }
        for &s in k.jac_slots() {
            work[s] += ADD;
        }
        let total: usize = work.iter().sum();
        let mut before = 0;
        work.iter()
            .position(|&w| {
                before += w;
                2 * before > total
            })
            .unwrap_or(k.nnz())
    }
}

impl DynamicBlocks {
    /// Register ∂g/∂q, ∂g/∂q̇ (unsymmetric) and (Φ_qᵀλ)_q (symmetric) in `a`.
    pub(crate) fn register(sys: &System, a: &mut APattern) -> Self {
        let force_first = a.push_block(sys.force_jacobian_pattern(), Symmetry::Unsymmetric);
        let hess_first = a.push_block(sys.hessian_pattern(), Symmetry::Symmetric);
        let n_force = sys.force_jacobian_pattern().len();
        let mut blocks = Self {
            force_first,
            hess_first,
            vals: BlockValues::new(sys),
            skew_first: Vec::new(),
            skew_ptr: Vec::new(),
            skew_ent: Vec::new(),
            skip: vec![false; n_force],
            plan: OnceLock::new(),
        };
        blocks.pairs(sys);
        blocks
    }

    /// In symmetric storage, write no force-Jacobian entry that touches a
    /// controller state (the states' block is then `c_m I` and their
    /// couplings 0): for a `StateBorder` (`state_border.rs`), which solves
    /// with those entries exactly.
    pub(crate) fn decouple_states(&mut self, sys: &System) {
        let nb = sys.n_body_coords();
        for (s, &(i, j)) in self.skip.iter_mut().zip(sys.force_jacobian_pattern()) {
            *s = i >= nb || j >= nb;
        }
        self.pairs(sys);
        self.plan = OnceLock::new();
    }

    /// The off-diagonal pairs of the force-Jacobian pattern, without the
    /// skipped entries, for the reciprocal part ([`Self::write`]).
    fn pairs(&mut self, sys: &System) {
        // the off-diagonal pairs in the order of their first entry
        let mut index = std::collections::HashMap::new();
        let mut members: Vec<Vec<(usize, bool)>> = Vec::new();
        let mut skew_first = Vec::new();
        for (e, &(i, j)) in sys.force_jacobian_pattern().iter().enumerate() {
            if i == j || self.skip[e] {
                continue;
            }
            let p = *index.entry((i.min(j), i.max(j))).or_insert_with(|| {
                skew_first.push(e);
                members.push(Vec::new());
                members.len() - 1
            });
            members[p].push((e, i < j));
        }
        let mut skew_ptr = vec![0];
        for m in &members {
            skew_ptr.push(skew_ptr.last().copied().unwrap_or(0) + m.len());
        }
        self.skew_first = skew_first;
        self.skew_ptr = skew_ptr;
        self.skew_ent = members.concat();
    }

    /// [`BlockValues::evaluate`] of these blocks at `(t, q, q̇)`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn evaluate(
        &mut self,
        sys: &System,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lam: &[f64],
        forces: bool,
        hessians: bool,
        jac: &mut [f64],
    ) -> Result<(), FormulationError> {
        let x = StateView { t, q, qd };
        self.vals.evaluate(sys, x, lam, forces, hessians, jac)
    }

    /// The last evaluated blocks ([`BlockValues::evaluate`]): ∂g/∂q and
    /// ∂g/∂q̇ in the order of [`System::force_jacobian_pattern`], (Φ_qᵀλ)_q
    /// in the order of [`System::hessian_pattern`].
    pub(crate) fn values(&self) -> (&[f64], &[f64], &[f64]) {
        (&self.vals.dq, &self.vals.dqd, &self.vals.hess)
    }

    /// Zero `k` and write `c_m M − c_c ∂g/∂q̇ − c_k ∂g/∂q + c_k (Φ_qᵀλ)_q`
    /// into its `A` block from the last evaluated blocks ([`BlockValues::evaluate`];
    /// the force Jacobians only when `c_c` or `c_k` ≠ 0, the Hessians only
    /// when `c_k` ≠ 0). The Jacobian block is left to the caller.
    ///
    /// In symmetric storage the force Jacobians enter by their
    /// **reciprocal part** (modified Newton, module docs of
    /// [`super::index3`]): for each coordinate pair `{i, j}` with
    /// `a = J_ij`, `b = J_ji` (of `∂g/∂q` and `∂g/∂q̇` each), both get
    /// `sign(a) min(|a|, |b|)` where `a` and `b` have the same sign, else 0
    /// ([`reciprocal_correction`]), instead of the symmetric part
    /// `(a + b)/2`. A symmetric pair keeps its value; a one-way coupling
    /// (`b = 0`: friction's force along a wall from the penetration normal
    /// to it) is left out, which
    /// makes the error of the Newton matrix nilpotent on it (two
    /// iterations for a linear problem), where its symmetric part
    /// `½ [0 a; a 0]` has the eigenvalue `−|a|/2`, a negative stiffness the
    /// true Jacobian does not have (on the falling rod's contacts: an
    /// indefinite `A` and diverging corrections; docs/scaling.md,
    /// "Measurements behind the defaults").
    pub(crate) fn write(&self, sys: &System, k: &mut SaddleMatrix, c: [f64; 3]) {
        self.write_parts(sys, [k], [c]);
    }

    /// [`Self::write`] into each matrix of `ks` with its coefficients of
    /// `cs`, in one pass over the blocks: each matrix receives the
    /// operations `write` makes, in the same order (the same bits), except
    /// that a zero `c_m` adds no mass (its zeroed slots stay +0, which is
    /// what adding `0 · M_ii` gives).
    fn write_parts<const P: usize>(
        &self,
        sys: &System,
        mut ks: [&mut SaddleMatrix; P],
        cs: [[f64; 3]; P],
    ) {
        for (k, &[c_m, _, _]) in ks.iter_mut().zip(&cs) {
            k.set_zero();
            if c_m != 0.0 {
                for (i, &mi) in sys.mass_diagonal().iter().enumerate() {
                    k.add_diagonal(i, c_m * mi);
                }
            }
        }
        let force = cs.map(|[_, c_c, c_k]| c_c != 0.0 || c_k != 0.0);
        let symmetric: [bool; P] =
            std::array::from_fn(|p| force[p] && ks[p].storage() == Storage::SymmetricLower);
        if force.contains(&true) {
            for (e, (&dq, &dqd)) in self.vals.dq.iter().zip(&self.vals.dqd).enumerate() {
                for p in 0..P {
                    if force[p] && !(symmetric[p] && self.skip[e]) {
                        let [_, c_c, c_k] = cs[p];
                        ks[p].add_a(self.force_first + e, -(c_c * dqd + c_k * dq));
                    }
                }
            }
        }
        if symmetric.contains(&true) {
            for (pair, &first) in self.skew_first.iter().enumerate() {
                let ents = &self.skew_ent[self.skew_ptr[pair]..self.skew_ptr[pair + 1]];
                let dq = reciprocal_correction(ents, &self.vals.dq);
                let dqd = reciprocal_correction(ents, &self.vals.dqd);
                if dq != 0.0 || dqd != 0.0 {
                    for p in (0..P).filter(|&p| symmetric[p]) {
                        let [_, c_c, c_k] = cs[p];
                        // through an entry of the pair (weight ½ in this storage)
                        ks[p].add_a(self.force_first + first, -2.0 * (c_c * dqd + c_k * dq));
                    }
                }
            }
        }
        for (k, &[_, _, c_k]) in ks.iter_mut().zip(&cs) {
            if c_k != 0.0 {
                for (e, &h) in self.vals.hess.iter().enumerate() {
                    k.add_a(self.hess_first + e, c_k * h);
                }
            }
        }
    }
}

impl DynamicBlocks {
    /// What the coefficients `[c_m, c_c, c_k]` of [`Self::write`] need
    /// [`BlockValues::evaluate`] to evaluate: `(forces, hessians)`, the force
    /// Jacobians when `c_c` or `c_k` ≠ 0, the Hessians when `c_k` ≠ 0.
    pub(crate) fn needs([_, c_c, c_k]: [f64; 3]) -> (bool, bool) {
        (c_c != 0.0 || c_k != 0.0, c_k != 0.0)
    }

    /// [`BlockValues::evaluate`] what `c` [`Self::needs`] (each evaluation checked
    /// finite, [`FormulationError::NonFinite`], so an overflow is not
    /// reported as a singular matrix), then [`Self::write_with_jacobian`]
    /// with `Φ_q` from `jac`: [`Self::write`] followed by
    /// [`SaddleMatrix::set_jacobian`], the same values.
    pub(crate) fn assemble_with_jacobian(
        &mut self,
        sys: &System,
        k: &mut SaddleMatrix,
        x: StateView<'_>,
        lam: &[f64],
        c: [f64; 3],
        jac: &mut [f64],
    ) -> Result<(), FormulationError> {
        let (forces, hessians) = Self::needs(c);
        self.vals.evaluate(sys, x, lam, forces, hessians, jac)?;
        self.write_with_jacobian(sys, k, c, jac);
        Ok(())
    }

    /// [`Self::write`] and then `k.set_jacobian(jac)`: the same bits, in
    /// two concurrent halves of `k`'s values of equal counted work
    /// ([`HalfPlan`], [`join_if`]) for a symmetric matrix of at least
    /// [`PARALLEL_MIN_COORDS`] coordinates, else in one piece. Every `k`
    /// given to one `DynamicBlocks` must have the pattern its blocks were
    /// registered into (a plan made for another number of values is not
    /// used).
    pub(crate) fn write_with_jacobian(
        &self,
        sys: &System,
        k: &mut SaddleMatrix,
        c: [f64; 3],
        jac: &[f64],
    ) {
        self.write_parts_with_jacobian(sys, [k], [c], [Some(jac)]);
    }

    /// The real and imaginary parts `[re, im]` of the complex Newton matrix
    /// `c₀ M − c₁ ∂g/∂q̇ − c₂ ∂g/∂q + c₂ (Φ_qᵀλ)_q` with `Φ_q` from `jac` in
    /// `re` (`c = [c₀, c₁, c₂]`, each `[re, im]`; `c₀` real): the bits of
    /// [`Self::write_with_jacobian`] of each part (`im` with `Φ_q` = 0), in
    /// one pass over the blocks.
    pub(crate) fn write_complex_with_jacobian(
        &self,
        sys: &System,
        [re, im]: [&mut SaddleMatrix; 2],
        c: [[f64; 2]; 3],
        jac: &[f64],
    ) {
        let part = |p: usize| c.map(|ci| ci[p]);
        self.write_parts_with_jacobian(sys, [re, im], [part(0), part(1)], [Some(jac), None]);
    }

    /// [`Self::write_parts`] and the Jacobian block of each matrix: `Φ_q`
    /// from `jacs[p]`, or 0 for `None`; in two halves of the values
    /// ([`Self::write_with_jacobian`]) when the plan applies to every
    /// matrix (all of one pattern).
    fn write_parts_with_jacobian<const P: usize>(
        &self,
        sys: &System,
        mut ks: [&mut SaddleMatrix; P],
        cs: [[f64; 3]; P],
        jacs: [Option<&[f64]>; P],
    ) {
        let Some(k0) = ks.first() else {
            return;
        };
        let plan = self.plan.get_or_init(|| self.half_plan(sys, k0)).as_ref();
        match plan {
            Some(p) if ks.iter().all(|k| p.nnz == k.nnz() && p.dim == k.dim()) => {
                let (lo, hi) = ks.map(|k| k.values_mut()).halve(p.cut);
                join_if(
                    true,
                    || self.apply(&p.halves[0], lo, sys, cs, jacs),
                    || self.apply(&p.halves[1], hi, sys, cs, jacs),
                );
            }
            _ => {
                // the Φ_q slots of a `None` stay at the zeros of `set_zero`
                self.write_parts(sys, ks.each_mut().map(|k| &mut **k), cs);
                for (k, jac) in ks.iter_mut().zip(jacs) {
                    if let Some(jac) = jac {
                        k.set_jacobian(jac);
                    }
                }
            }
        }
    }

    /// The additions of [`Self::write_with_jacobian`] sorted into the
    /// halves of `k`'s values, or `None` (full storage, or fewer than
    /// [`PARALLEL_MIN_COORDS`] coordinates).
    fn half_plan(&self, sys: &System, k: &SaddleMatrix) -> Option<HalfPlan> {
        if k.storage() != Storage::SymmetricLower || k.n() < PARALLEL_MIN_COORDS {
            return None;
        }
        let cut = HalfPlan::balanced_cut(self, k);
        let side = |slot: usize| {
            (
                usize::from(slot >= cut),
                slot - if slot >= cut { cut } else { 0 },
            )
        };
        let mut halves: [HalfOps; 2] = Default::default();
        for i in 0..sys.mass_diagonal().len() {
            let (h, s) = side(k.diag_slots()[i]);
            halves[h].diag.push((i, s));
        }
        let a = |id: usize| {
            let (slot, slot_t, w) = k.a_entry(id);
            debug_assert_eq!(slot_t, usize::MAX, "symmetric storage has one slot");
            let (h, s) = side(slot);
            (h, s, w)
        };
        for e in 0..self.vals.dq.len() {
            if !self.skip[e] {
                let (h, s, w) = a(self.force_first + e);
                halves[h].force.push((e, s, w));
            }
        }
        for (p, &first) in self.skew_first.iter().enumerate() {
            let (h, s, w) = a(self.force_first + first);
            halves[h].skew.push((p, s, w));
        }
        for e in 0..self.vals.hess.len() {
            let (h, s, w) = a(self.hess_first + e);
            halves[h].hess.push((e, s, w));
        }
        for (e, &slot) in k.jac_slots().iter().enumerate() {
            let (h, s) = side(slot);
            halves[h].jac.push((e, s));
        }
        Some(HalfPlan {
            nnz: k.nnz(),
            cut,
            dim: k.dim(),
            halves,
        })
    }

    /// One half of [`Self::write_parts_with_jacobian`]: `vs` = each
    /// matrix's values of the half whose additions `ops` lists, zeroed,
    /// then its additions in the one-piece order ([`Self::write_parts`],
    /// [`SaddleMatrix::set_jacobian`]).
    fn apply<const P: usize>(
        &self,
        ops: &HalfOps,
        mut vs: [&mut [f64]; P],
        sys: &System,
        cs: [[f64; 3]; P],
        jacs: [Option<&[f64]>; P],
    ) {
        let mass = sys.mass_diagonal();
        for (v, &[c_m, _, _]) in vs.iter_mut().zip(&cs) {
            v.fill(0.0);
            if c_m != 0.0 {
                for &(i, s) in &ops.diag {
                    v[s] += c_m * mass[i];
                }
            }
        }
        let force = cs.map(|[_, c_c, c_k]| c_c != 0.0 || c_k != 0.0);
        if force.contains(&true) {
            for &(e, s, w) in &ops.force {
                let (dq, dqd) = (self.vals.dq[e], self.vals.dqd[e]);
                for (v, &[_, c_c, c_k]) in vs
                    .iter_mut()
                    .zip(&cs)
                    .filter(|(_, c)| c[1] != 0.0 || c[2] != 0.0)
                {
                    v[s] += w * -(c_c * dqd + c_k * dq);
                }
            }
            for &(pair, s, w) in &ops.skew {
                let ents = &self.skew_ent[self.skew_ptr[pair]..self.skew_ptr[pair + 1]];
                let dq = reciprocal_correction(ents, &self.vals.dq);
                let dqd = reciprocal_correction(ents, &self.vals.dqd);
                if dq != 0.0 || dqd != 0.0 {
                    for (v, &[_, c_c, c_k]) in vs
                        .iter_mut()
                        .zip(&cs)
                        .filter(|(_, c)| c[1] != 0.0 || c[2] != 0.0)
                    {
                        v[s] += w * (-2.0 * (c_c * dqd + c_k * dq));
                    }
                }
            }
        }
        if cs.iter().any(|c| c[2] != 0.0) {
            for &(e, s, w) in &ops.hess {
                let h = self.vals.hess[e];
                for (v, &[_, _, c_k]) in vs.iter_mut().zip(&cs).filter(|(_, c)| c[2] != 0.0) {
                    v[s] += w * (c_k * h);
                }
            }
        }
        for (v, jac) in vs.iter_mut().zip(jacs) {
            if let Some(jac) = jac {
                for &(e, s) in &ops.jac {
                    v[s] += jac[e];
                }
            }
        }
    }
}

/// The penalty block `c Φ_qᵀΦ_q` of an `A`-only matrix ([`super::Penalty`],
/// [`super::Augmented`]): per constraint row, every pair of its Φ_q
/// entries, registered once in an [`APattern`].
pub(crate) struct PenaltyBlock {
    /// Id of its first entry among the `A` entries.
    first: usize,
    /// Per entry: the two Φ_q value positions and a weight (2 for two
    /// entries of one row in the same column).
    pairs: Vec<(usize, usize, f64)>,
}

impl PenaltyBlock {
    /// Register the pattern of `Φ_qᵀΦ_q` in `a` (symmetric).
    pub(crate) fn register(sys: &System, a: &mut APattern) -> Self {
        let jp = sys.jacobian_pattern();
        // entries of Φ_q grouped by row, then every pair within a row
        let mut by_row: Vec<Vec<usize>> = vec![Vec::new(); sys.n_constraints()];
        for (e, &(r, _)) in jp.iter().enumerate() {
            by_row[r].push(e);
        }
        let (mut entries, mut pairs) = (Vec::new(), Vec::new());
        for row in &by_row {
            for (i, &e1) in row.iter().enumerate() {
                for &e2 in &row[i..] {
                    let (c1, c2) = (jp[e1].1, jp[e2].1);
                    entries.push((c1, c2));
                    pairs.push((e1, e2, if e1 != e2 && c1 == c2 { 2.0 } else { 1.0 }));
                }
            }
        }
        let first = a.push_block(&entries, Symmetry::Symmetric);
        Self { first, pairs }
    }

    /// Add `c Φ_qᵀΦ_q` to the `A` block of `k`, Φ_q's values in `jac`.
    pub(crate) fn add(&self, k: &mut SaddleMatrix, c: f64, jac: &[f64]) {
        for (id, &(e1, e2, w)) in self.pairs.iter().enumerate() {
            k.add_a(self.first + id, c * w * jac[e1] * jac[e2]);
        }
    }
}

/// The change `r − (a + b)/2` from the symmetric part to the reciprocal
/// part `r = sign(a) min(|a|, |b|)` (0 where `a`, `b` differ in sign) of a
/// coordinate pair whose entries are `ents` (`true`: at `(i, j)`, summed
/// into `a`; `false`: into `b`) in `vals` ([`DynamicBlocks::write`]).
fn reciprocal_correction(ents: &[(usize, bool)], vals: &[f64]) -> f64 {
    let (mut a, mut b) = (0.0, 0.0);
    for &(e, upper) in ents {
        if upper {
            a += vals[e];
        } else {
            b += vals[e];
        }
    }
    if a == b {
        return 0.0;
    }
    let r = if a * b > 0.0 {
        a.signum() * a.abs().min(b.abs())
    } else {
        0.0
    };
    r - 0.5 * (a + b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::stiff_chain;

    /// Do two matrices hold the same values, bit for bit?
    fn same_bits(a: &SaddleMatrix, b: &SaddleMatrix) -> bool {
        let (a, b) = (a.values(), b.values());
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    /// The blocks of a stiff chain of `bodies` bodies evaluated at a random
    /// state near its start, with random unsymmetric parts added to the
    /// force Jacobians (every coordinate pair gets a reciprocal
    /// correction): the system, the blocks, a matrix of their pattern in
    /// symmetric storage and Φ_q.
    fn random_blocks(
        bodies: usize,
        rnd: &mut impl FnMut() -> f64,
    ) -> (System, DynamicBlocks, SaddleMatrix, Vec<f64>) {
        let (sys, q0, qd0, _) = stiff_chain(bodies, 0.1).unwrap();
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let mut a = APattern::new();
        let mut blocks = DynamicBlocks::register(&sys, &mut a);
        let jp = sys.jacobian_pattern();
        let k0 = SaddleMatrix::with_storage(n, m, &a, jp, Storage::SymmetricLower);
        let q: Vec<f64> = q0.iter().map(|x| x + 1e-3 * rnd()).collect();
        let qd: Vec<f64> = qd0.iter().map(|x| x + rnd()).collect();
        let lam: Vec<f64> = (0..m).map(|_| 1e3 * rnd()).collect();
        let mut jac = vec![0.0; jp.len()];
        blocks
            .evaluate(&sys, 0.0, &q, &qd, &lam, true, true, &mut jac)
            .unwrap();
        for v in blocks.vals.dq.iter_mut().chain(blocks.vals.dqd.iter_mut()) {
            *v += 1e4 * rnd();
        }
        (sys, blocks, k0, jac)
    }

    /// [`DynamicBlocks::write_with_jacobian`] in its two halves (on two
    /// threads of a pool) writes the bits of [`DynamicBlocks::write`] and
    /// [`SaddleMatrix::set_jacobian`] in one piece, for each combination of
    /// blocks, with unsymmetric force Jacobians (every coordinate pair gets
    /// a reciprocal correction) and over stale values.
    #[test]
    fn halves_write_the_one_piece_bits() {
        let mut u = crate::numeric::test_uniform(12345);
        let mut rnd = move || u() * 2.0 - 1.0;
        let (sys, blocks, k0, jac) = random_blocks(2100, &mut rnd);
        assert!(sys.n_coords() >= PARALLEL_MIN_COORDS);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        for c in [[1.3, 2e-3, 4e-6], [1.0, 0.0, 0.0], [0.7, 5e-3, 0.0]] {
            let (mut one, mut two) = (k0.clone(), k0.clone());
            one.values_mut().fill(f64::NAN);
            two.values_mut().fill(-7.0);
            blocks.write(&sys, &mut one, c);
            one.set_jacobian(&jac);
            pool.install(|| blocks.write_with_jacobian(&sys, &mut two, c, &jac));
            assert!(same_bits(&one, &two), "coefficients {c:?}");
            assert!(one.values().iter().all(|v| v.is_finite()));
        }
        // the halves were used, each with a share of every block
        let p = blocks.plan.get().unwrap().as_ref().unwrap();
        for h in &p.halves {
            assert!(!h.diag.is_empty() && !h.force.is_empty() && !h.skew.is_empty());
            assert!(!h.hess.is_empty() && !h.jac.is_empty());
        }
        // and they hold equal work, counted from their lists of additions
        // (as `balanced_cut` weighs them): within 1 % of the total
        let work = |h: &HalfOps, values: usize| {
            let skew: usize = h
                .skew
                .iter()
                .map(|&(q, _, _)| 3 + 2 * (blocks.skew_ptr[q + 1] - blocks.skew_ptr[q]))
                .sum();
            values + 3 * (h.diag.len() + h.force.len() + h.hess.len() + h.jac.len()) + skew
        };
        let (w0, w1) = (work(&p.halves[0], p.cut), work(&p.halves[1], p.nnz - p.cut));
        assert!(
            w0.abs_diff(w1) * 100 <= w0 + w1,
            "work {w0} and {w1}, cut {} of {}",
            p.cut,
            p.nnz
        );
        // the reciprocal corrections are not all zero (the test sees them)
        let corrected = (0..blocks.skew_first.len()).any(|p| {
            let ents = &blocks.skew_ent[blocks.skew_ptr[p]..blocks.skew_ptr[p + 1]];
            reciprocal_correction(ents, &blocks.vals.dq) != 0.0
        });
        assert!(corrected);
    }

    /// [`DynamicBlocks::write_complex_with_jacobian`] writes the bits of
    /// two [`DynamicBlocks::write_with_jacobian`] calls (the imaginary part
    /// with Φ_q = 0), in one piece (n below [`PARALLEL_MIN_COORDS`]) and in
    /// the two halves (above, on one thread and on two), over stale values,
    /// with unsymmetric force Jacobians and random complex coefficients.
    #[test]
    fn complex_parts_in_one_pass_have_the_bits_of_two_writes() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let mut u = crate::numeric::test_uniform(777);
        let mut rnd = move || u() * 2.0 - 1.0;
        for (bodies, threads) in [(40, 1), (2100, 1), (2100, 2)] {
            let (sys, blocks, k0, jac) = random_blocks(bodies, &mut rnd);
            let n = sys.n_coords();
            let zeros = vec![0.0; jac.len()];
            let c = [[1.0, 0.0], [rnd(), rnd()], [1e-3 * rnd(), 1e-3 * rnd()]];
            let part = |p: usize| c.map(|ci| ci[p]);
            let (mut re1, mut im1) = (k0.clone(), k0.clone());
            blocks.write_with_jacobian(&sys, &mut re1, part(0), &jac);
            blocks.write_with_jacobian(&sys, &mut im1, part(1), &zeros);
            let (mut re2, mut im2) = (k0.clone(), k0.clone());
            re2.values_mut().fill(f64::NAN);
            im2.values_mut().fill(-3.0);
            let pool = (threads == 2).then_some(&pool);
            let mut write = || {
                blocks.write_complex_with_jacobian(&sys, [&mut re2, &mut im2], c, &jac);
            };
            match pool {
                Some(p) => p.install(write),
                None => write(),
            }
            for (one, two) in [(&re1, &re2), (&im1, &im2)] {
                assert!(same_bits(one, two), "{bodies} bodies, {threads} thread(s)");
            }
            assert_eq!(
                blocks.plan.get().unwrap().is_some(),
                n >= PARALLEL_MIN_COORDS
            );
            assert!(im1.values().iter().any(|v| *v != 0.0));
        }
    }
}
