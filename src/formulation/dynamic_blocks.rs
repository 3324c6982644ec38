//! The `A` block that the Newton matrices of the implicit formulations
//! share: `c_m M − c_c ∂g/∂q̇ − c_k ∂g/∂q + c_k (Φ_qᵀλ)_q` ([`super::Index3`],
//! [`super::Augmented`]), with the force Jacobians and the constraint
//! Hessians as blocks registered once in an [`APattern`] and evaluated by
//! the system (generated kernels where attached).

use super::{all_finite, FormulationError};
use crate::linalg::{APattern, SaddleMatrix, Symmetry};
use crate::model::{FdWorkspace, System};

/// Ids of the registered blocks and the buffers of their values.
pub(crate) struct DynamicBlocks {
    /// Id of the first force-Jacobian entry among the `A` entries
    /// ([`System::force_jacobian_pattern`] order).
    force_first: usize,
    /// Id of the first (Φ_qᵀλ)_q entry ([`System::hessian_pattern`] order).
    hess_first: usize,
    hess_vals: Vec<f64>,
    dq: Vec<f64>,
    dqd: Vec<f64>,
    ws: FdWorkspace,
}

impl DynamicBlocks {
    /// Register ∂g/∂q, ∂g/∂q̇ (unsymmetric) and (Φ_qᵀλ)_q (symmetric) in `a`.
    pub(crate) fn register(sys: &System, a: &mut APattern) -> Self {
        let force_first = a.push_block(sys.force_jacobian_pattern(), Symmetry::Unsymmetric);
        let hess_first = a.push_block(sys.hessian_pattern(), Symmetry::Symmetric);
        let n_force = sys.force_jacobian_pattern().len();
        Self {
            force_first,
            hess_first,
            hess_vals: vec![0.0; sys.hessian_pattern().len()],
            dq: vec![0.0; n_force],
            dqd: vec![0.0; n_force],
            ws: FdWorkspace::default(),
        }
    }

    /// Zero `k` and write `c_m M − c_c ∂g/∂q̇ − c_k ∂g/∂q + c_k (Φ_qᵀλ)_q`
    /// at `(t, q, q̇, λ)` into its `A` block (the force Jacobians only when
    /// `c_c` or `c_k` ≠ 0, the Hessians only when `c_k` ≠ 0); `Φ_q(q, t)`
    /// into `jac`. Every evaluation is checked finite
    /// ([`FormulationError::NonFinite`]), so an overflow is not reported as
    /// a singular matrix.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn assemble(
        &mut self,
        sys: &System,
        k: &mut SaddleMatrix,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lam: &[f64],
        [c_m, c_c, c_k]: [f64; 3],
        jac: &mut [f64],
    ) -> Result<(), FormulationError> {
        self.evaluate(
            sys,
            t,
            q,
            qd,
            lam,
            c_c != 0.0 || c_k != 0.0,
            c_k != 0.0,
            jac,
        )?;
        self.write(sys, k, [c_m, c_c, c_k]);
        Ok(())
    }

    /// Evaluate the force Jacobians (when `forces`), the Hessians (when
    /// `hessians`) and `Φ_q(q, t)` into `jac`, each checked finite; the
    /// blocks not evaluated keep their old values.
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
        if forces {
            self.dq.fill(0.0);
            self.dqd.fill(0.0);
            sys.add_force_jacobians(t, q, qd, &mut self.dq, &mut self.dqd, &mut self.ws);
        }
        if hessians && !self.hess_vals.is_empty() {
            self.hess_vals.fill(0.0);
            sys.add_constraint_hessians(q, t, lam, &mut self.hess_vals, &mut self.ws);
        }
        sys.jacobian_values(q, t, jac);
        all_finite(
            t,
            &[
                ("the force Jacobian ∂g/∂q", &self.dq),
                ("the force Jacobian ∂g/∂q̇", &self.dqd),
                ("the constraint Hessian (Φ_qᵀλ)_q", &self.hess_vals),
                ("the constraint Jacobian Φ_q", jac),
            ],
        )
    }

    /// Zero `k` and write `c_m M − c_c ∂g/∂q̇ − c_k ∂g/∂q + c_k (Φ_qᵀλ)_q`
    /// into its `A` block from the last evaluated blocks ([`Self::evaluate`];
    /// the force Jacobians only when `c_c` or `c_k` ≠ 0, the Hessians only
    /// when `c_k` ≠ 0). The Jacobian block is left to the caller.
    pub(crate) fn write(&self, sys: &System, k: &mut SaddleMatrix, [c_m, c_c, c_k]: [f64; 3]) {
        k.set_zero();
        for (i, &mi) in sys.mass_diagonal().iter().enumerate() {
            k.add_diagonal(i, c_m * mi);
        }
        if c_c != 0.0 || c_k != 0.0 {
            for (e, (&dq, &dqd)) in self.dq.iter().zip(&self.dqd).enumerate() {
                k.add_a(self.force_first + e, -(c_c * dqd + c_k * dq));
            }
        }
        if c_k != 0.0 {
            for (e, &h) in self.hess_vals.iter().enumerate() {
                k.add_a(self.hess_first + e, c_k * h);
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
