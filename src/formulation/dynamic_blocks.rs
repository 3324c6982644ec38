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
        k.set_zero();
        for (i, &mi) in sys.mass_diagonal().iter().enumerate() {
            k.add_diagonal(i, c_m * mi);
        }
        if c_c != 0.0 || c_k != 0.0 {
            self.dq.fill(0.0);
            self.dqd.fill(0.0);
            sys.add_force_jacobians(t, q, qd, &mut self.dq, &mut self.dqd, &mut self.ws);
            for (e, (&dq, &dqd)) in self.dq.iter().zip(&self.dqd).enumerate() {
                k.add_a(self.force_first + e, -(c_c * dqd + c_k * dq));
            }
        }
        if c_k != 0.0 && !self.hess_vals.is_empty() {
            self.hess_vals.fill(0.0);
            sys.add_constraint_hessians(q, t, lam, &mut self.hess_vals, &mut self.ws);
            for (e, &h) in self.hess_vals.iter().enumerate() {
                k.add_a(self.hess_first + e, c_k * h);
            }
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
}
