//! Consistent initial conditions (paper §2): positions on Φ(q, t₀) = 0 and
//! velocities on Φ_q q̇ = −Φ_t, given the independent coordinates.

use super::{all_finite, FormulationError};
use crate::linalg::{solver_for, SaddleMatrix, SolverKind, SolverOptions};
use crate::model::System;
use serde::Serialize;

/// Options of [`consistent_initial_state`].
#[derive(Debug, Clone, Copy, Serialize)]
pub struct InitialOptions {
    /// Newton tolerance on ‖Φ‖∞.
    pub tol: f64,
    /// Maximum Newton iterations.
    pub max_iter: usize,
    /// Linear solver for the augmented saddle-point systems.
    pub linear_solver: SolverKind,
}

impl Default for InitialOptions {
    fn default() -> Self {
        Self {
            tol: 1e-12,
            max_iter: 50,
            linear_solver: SolverKind::Auto,
        }
    }
}

/// A consistent state and how well it satisfies the constraints.
#[derive(Debug, Clone, Serialize)]
pub struct ConsistentState {
    /// Positions with Φ(q, t₀) ≈ 0.
    pub q: Vec<f64>,
    /// Velocities with Φ_q q̇ + Φ_t ≈ 0.
    pub qd: Vec<f64>,
    /// ‖Φ(q, t₀)‖₂ after the correction.
    pub position_residual: f64,
    /// ‖Φ_q q̇ + Φ_t‖₂ after the correction.
    pub velocity_residual: f64,
    /// Newton iterations used.
    pub iterations: usize,
}

/// Correct `(q, q̇)` onto the constraint manifold at `t0`, keeping the
/// coordinates listed in `independent` (and their velocities) at the given
/// values.
///
/// Each Newton step is the smallest correction `Δq` (Euclidean norm) with
/// `Φ_q Δq = −Φ` and `Δq_k = 0` for independent `k`, from the saddle-point
/// system `[I  Φ̃_qᵀ; Φ̃_q 0]` where Φ̃ appends the locks `q_k − q_k⁰` to Φ —
/// the same sparse machinery as the equations of motion. The velocities are
/// the closest to the given ones with `Φ_q q̇ = −Φ_t`, `q̇_k` fixed.
pub fn consistent_initial_state(
    sys: &System,
    t0: f64,
    q: &[f64],
    qd: &[f64],
    independent: &[usize],
    opts: InitialOptions,
) -> Result<ConsistentState, FormulationError> {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    if let Some(&k) = independent.iter().find(|&&k| k >= n) {
        return Err(FormulationError::Initial(format!(
            "independent coordinate index {k} out of range (the system has {n} coordinates)"
        )));
    }
    let nl = independent.len();
    let mut pattern = sys.jacobian_pattern().to_vec();
    pattern.extend(independent.iter().enumerate().map(|(i, &k)| (m + i, k)));
    let mut kmat = SaddleMatrix::new(n, m + nl, &[], &pattern);
    let mut solver = solver_for(opts.linear_solver, n + m + nl, SolverOptions::default());
    let lin = |source| FormulationError::Linear { t: t0, source };
    solver.analyze(&kmat).map_err(lin)?;
    kmat.set_a_diagonal(&vec![1.0; n]);

    let mut jac = vec![0.0; pattern.len()];
    let nsys = sys.jacobian_pattern().len();
    jac[nsys..].fill(1.0);
    let mut q = q.to_vec();
    let mut phi = vec![0.0; m];
    let mut x = vec![0.0; n + m + nl];
    let norm_inf = |v: &[f64]| v.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
    let mut iterations = 0;
    loop {
        sys.phi(&q, t0, &mut phi);
        let r = norm_inf(&phi);
        if !r.is_finite() {
            return Err(FormulationError::Initial(format!(
                "constraint residual is not finite after {iterations} Newton iterations"
            )));
        }
        if r <= opts.tol {
            break;
        }
        if iterations == opts.max_iter {
            return Err(FormulationError::Initial(format!(
                "Newton did not converge in {} iterations (‖Φ‖∞ = {r:.3e} > tol {:.1e}); \
                 the initial guess may be too far from an assembled position",
                opts.max_iter, opts.tol
            )));
        }
        sys.jacobian_values(&q, t0, &mut jac[..nsys]);
        all_finite(t0, &[("the constraint Jacobian Φ_q", &jac)])?;
        kmat.set_jacobian(&jac);
        solver.factorize(&kmat).map_err(lin)?;
        x.fill(0.0);
        for (xr, p) in x[n..n + m].iter_mut().zip(&phi) {
            *xr = -p;
        }
        solver.solve_in_place(&kmat, &mut x).map_err(lin)?;
        for (qi, dx) in q.iter_mut().zip(&x[..n]) {
            *qi += dx;
        }
        iterations += 1;
    }

    // Velocities: min ‖q̇ − q̇⁰‖ s.t. Φ_q q̇ = −Φ_t, q̇_k = q̇⁰_k.
    sys.jacobian_values(&q, t0, &mut jac[..nsys]);
    let mut phi_t = vec![0.0; m];
    sys.phi_t(&q, t0, &mut phi_t);
    all_finite(
        t0,
        &[
            ("the constraint Jacobian Φ_q", &jac),
            ("Φ_t (the constraints' time derivative)", &phi_t),
        ],
    )?;
    kmat.set_jacobian(&jac);
    solver.factorize(&kmat).map_err(lin)?;
    x[..n].copy_from_slice(qd);
    for r in 0..m {
        x[n + r] = -phi_t[r];
    }
    for (i, &k) in independent.iter().enumerate() {
        x[n + m + i] = qd[k];
    }
    solver.solve_in_place(&kmat, &mut x).map_err(lin)?;
    let qd: Vec<f64> = x[..n].to_vec();

    sys.phi(&q, t0, &mut phi);
    let position_residual = phi.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut phid = vec![0.0; m];
    sys.jacobian_mul(&jac[..nsys], &qd, &mut phid);
    let velocity_residual = phid
        .iter()
        .zip(&phi_t)
        .map(|(a, b)| (a + b) * (a + b))
        .sum::<f64>()
        .sqrt();
    Ok(ConsistentState {
        q,
        qd,
        position_residual,
        velocity_residual,
        iterations,
    })
}
