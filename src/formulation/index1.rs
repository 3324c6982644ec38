//! The index-1 form, eq. (5), with Baumgarte terms, eq. (11).

use super::{
    all_finite, check_state, feedback, linear_at, mass_orthogonal_step, Baumgarte, Correction,
    Formulation, FormulationError, PartitionOptions, PenaltyParams, Projection,
};
use crate::integrate::{OdeSystem, SystemError};
use crate::linalg::{
    solver_for, APattern, SaddleMatrix, SaddlePointSolver, SolverKind, SolverOptions, SolverStats,
};
use crate::model::System;
use serde::Serialize;

use crate::parallel::PARALLEL_MIN_COORDS;

/// Options of [`Index1`].
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Index1Options {
    /// Saddle point (eq. (5)) or λ eliminated (eq. (9)).
    pub formulation: Formulation,
    /// Baumgarte parameters (α = β = 0: none).
    pub baumgarte: Baumgarte,
    /// Linear solver for the saddle-point form.
    pub linear_solver: SolverKind,
    /// Projection onto the manifold after each accepted step (off by default).
    pub projection: Projection,
    /// Parameters of [`Formulation::Penalty`] (used by [`super::Penalty`] only).
    pub penalty: PenaltyParams,
    /// Parameters of [`Formulation::Partitioned`] (used by
    /// [`super::Partitioned`] only).
    pub partition: PartitionOptions,
}

/// Counters of [`Index1`].
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct RhsStats {
    /// Right-hand-side (acceleration) evaluations.
    pub evaluations: usize,
    /// Linear-solver counters (the Schur complement's for eq. (9)).
    pub solver: SolverStats,
    /// Projections onto the constraint manifold ([`Index1::project`]).
    pub projections: usize,
    /// Newton iterations of the position projections, summed.
    pub projection_iterations: usize,
    /// Time of the first evaluation whose factorisation regularised a
    /// pivot (Φ_q lost rank: a singular configuration or redundant joints).
    pub first_regularized_t: Option<f64>,
}

/// The equations of motion as a first-order ODE for `y = [q; q̇]`.
///
/// Each evaluation computes Φ_q, g, γ (and Φ, Φ_t for the Baumgarte terms),
/// writes them into the fixed pattern of the saddle-point matrix and solves
/// `M q̈ + Φ_qᵀ λ = g`, `Φ_q q̈ = γ̄` (eq. (5), multipliers with the sign of
/// [`crate::linalg`]) — with the chosen saddle-point solver, or, for
/// [`Formulation::Eliminated`], with λ eliminated through the Schur
/// complement of eq. (9) ([`crate::linalg::SchurComplement`]). No
/// allocation per evaluation.
pub struct Index1<'a> {
    sys: &'a System,
    opts: Index1Options,
    pub(super) b: RhsBuffers,
}

/// What an explicit formulation ([`Index1`], [`super::Penalty`]) keeps
/// between evaluations: its solver and matrix, the model's terms at the
/// last state (`Φ_q` values, `g`, `γ` or `γ̄`, `Φ`, `Φ_t`, `Φ_q q̇`), the
/// solve's work vector, the multipliers and the counters.
pub(super) struct RhsBuffers {
    pub(super) solver: Box<dyn SaddlePointSolver>,
    pub(super) k: SaddleMatrix,
    pub(super) jac: Vec<f64>,
    pub(super) g: Vec<f64>,
    pub(super) gamma: Vec<f64>,
    pub(super) phi: Vec<f64>,
    pub(super) phi_t: Vec<f64>,
    pub(super) phid: Vec<f64>,
    pub(super) x: Vec<f64>,
    pub(super) lambda: Vec<f64>,
    pub(super) stats: RhsStats,
}

impl RhsBuffers {
    /// Zeroed buffers for `sys` with `solver` (analysed) on `k` and a work
    /// vector of length `x_len`.
    pub(super) fn new(
        sys: &System,
        solver: Box<dyn SaddlePointSolver>,
        k: SaddleMatrix,
        x_len: usize,
    ) -> Self {
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        Self {
            solver,
            k,
            jac: vec![0.0; sys.jacobian_pattern().len()],
            g: vec![0.0; n],
            gamma: vec![0.0; m],
            phi: vec![0.0; m],
            phi_t: vec![0.0; m],
            phid: vec![0.0; m],
            x: vec![0.0; x_len],
            lambda: vec![0.0; m],
            stats: RhsStats::default(),
        }
    }

    /// Counters so far, with the solver's.
    pub(super) fn stats(&self) -> RhsStats {
        let mut s = self.stats;
        s.solver = self.solver.stats();
        s
    }
}

/// `ẏ = (q̇, q̈)` of `y = (q, q̇)` (`n` coordinates) with `q̈` from
/// `accelerations(q, q̇, q̈)`: the first-order form of an explicit
/// formulation.
pub(super) fn first_order_rhs(
    n: usize,
    y: &[f64],
    dydt: &mut [f64],
    accelerations: impl FnOnce(&[f64], &[f64], &mut [f64]) -> Result<(), FormulationError>,
) -> Result<(), SystemError> {
    let (q, qd) = y.split_at(n);
    let (dq, dqd) = dydt.split_at_mut(n);
    dq.copy_from_slice(qd);
    accelerations(q, qd, dqd).map_err(SystemError::new)
}

impl<'a> Index1<'a> {
    /// Set up the pattern, the solver and its symbolic analysis (once).
    pub fn new(sys: &'a System, opts: Index1Options) -> Result<Self, FormulationError> {
        let b = opts.baumgarte;
        if !(b.alpha.is_finite() && b.alpha >= 0.0 && b.beta.is_finite() && b.beta >= 0.0) {
            return Err(FormulationError::Invalid(format!(
                "Baumgarte parameters must be finite and ≥ 0, got alpha = {}, beta = {}",
                b.alpha, b.beta
            )));
        }
        opts.projection.validate()?;
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let kind = match opts.formulation {
            Formulation::Saddle => opts.linear_solver,
            Formulation::Eliminated => SolverKind::Schur,
            Formulation::Penalty | Formulation::AugmentedLagrangian | Formulation::Partitioned => {
                return Err(FormulationError::Invalid(
                    "Index1 solves the saddle-point or eliminated form; the penalty \
                     formulation is Penalty (or ExplicitForm), the augmented Lagrangian \
                     Augmented, coordinate partitioning Partitioned"
                        .into(),
                ))
            }
        };
        let mut solver = solver_for(kind, n + m, SolverOptions::default());
        let k = SaddleMatrix::with_storage(
            n,
            m,
            &APattern::new(),
            sys.jacobian_pattern(),
            solver.storage(),
        );
        solver.analyze(&k).map_err(linear_at(f64::NAN))?;
        Ok(Self {
            sys,
            opts,
            b: RhsBuffers::new(sys, solver, k, n + m),
        })
    }

    /// The system.
    pub fn system(&self) -> &System {
        self.sys
    }

    /// Options in force.
    pub fn options(&self) -> &Index1Options {
        &self.opts
    }

    /// Multipliers λ of the last evaluation (`M q̈ + Φ_qᵀ λ = g`).
    pub fn lambda(&self) -> &[f64] {
        &self.b.lambda
    }

    /// Counters so far.
    pub fn stats(&self) -> RhsStats {
        self.b.stats()
    }

    /// Name of the linear solver in use.
    pub fn solver_name(&self) -> &'static str {
        self.b.solver.name()
    }

    /// Accelerations `q̈(q, q̇, t)`; λ is kept (see [`Index1::lambda`]).
    pub fn accelerations(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), FormulationError> {
        let sys = self.sys;
        let n = sys.n_coords();
        self.b.stats.evaluations += 1;
        check_state(t, q, qd)?;
        // Forces and constraint terms are independent: evaluate them
        // concurrently for large systems. Each task is sequential inside, so
        // the result is bit-identical whatever the number of threads.
        let b = self.opts.baumgarte;
        let (g, jac, gamma, phi, phi_t, phid) = (
            &mut self.b.g,
            &mut self.b.jac,
            &mut self.b.gamma,
            &mut self.b.phi,
            &mut self.b.phi_t,
            &mut self.b.phid,
        );
        let constraint_terms = || {
            // Φ comes for free with generated kernels (one fused pass).
            let want_phi = !b.is_off() || sys.uses_kernels();
            sys.constraint_terms(q, qd, t, want_phi.then_some(&mut phi[..]), jac, gamma);
            if !b.is_off() {
                // eq. (11): γ̄ = γ − 2αΦ̇ − β²Φ with Φ̇ = Φ_q q̇ + Φ_t
                sys.phi_t(q, t, phi_t);
                sys.jacobian_mul(jac, qd, phid);
                feedback(gamma, phid, phi_t, phi, 2.0 * b.alpha, b.beta * b.beta);
            }
        };
        crate::parallel::join_if(
            n >= PARALLEL_MIN_COORDS,
            || sys.forces_into(t, q, qd, g),
            constraint_terms,
        );
        all_finite(
            t,
            &[
                ("the forces g", &self.b.g),
                ("the constraint Jacobian Φ_q", &self.b.jac),
                ("γ (the right-hand side of Φ_q q̈ = γ)", &self.b.gamma),
            ],
        )?;
        self.b.k.set_a_diagonal(sys.mass_diagonal());
        self.b.k.set_jacobian(&self.b.jac);
        let lin = linear_at(t);
        let info = self.b.solver.factorize(&self.b.k).map_err(lin)?;
        if info.regularized_pivots > 0 && self.b.stats.first_regularized_t.is_none() {
            self.b.stats.first_regularized_t = Some(t);
        }
        self.b.x[..n].copy_from_slice(&self.b.g);
        self.b.x[n..].copy_from_slice(&self.b.gamma);
        self.b
            .solver
            .solve_in_place(&self.b.k, &mut self.b.x)
            .map_err(lin)?;
        qdd.copy_from_slice(&self.b.x[..n]);
        self.b.lambda.copy_from_slice(&self.b.x[n..]);
        Ok(())
    }
}

impl Index1<'_> {
    /// Factorise `[M Φ_qᵀ; Φ_q 0]` at `q` (Φ_q left in `self.b.jac`).
    fn factor_at(&mut self, t: f64, q: &[f64]) -> Result<(), FormulationError> {
        self.sys.jacobian_values(q, t, &mut self.b.jac);
        self.b.k.set_a_diagonal(self.sys.mass_diagonal());
        self.b.k.set_jacobian(&self.b.jac);
        self.b.solver.factorize(&self.b.k).map_err(linear_at(t))?;
        Ok(())
    }

    /// Mass-orthogonal projection onto the constraint manifold
    /// ([`Projection`]; docs/constraint_methods.md): Newton on `Φ(q, t) = 0`,
    /// each correction the smallest in the M-norm,
    /// `Δq = −M⁻¹Φ_qᵀ(Φ_q M⁻¹Φ_qᵀ)⁻¹Φ` from the saddle-point matrix at the
    /// current iterate, until `‖Φ‖∞ ≤ tol`; then
    /// `Δq̇ = −M⁻¹Φ_qᵀ(Φ_q M⁻¹Φ_qᵀ)⁻¹(Φ_q q̇ + Φ_t)` with Φ_q at the
    /// projected q, so `Φ_q q̇ = −Φ_t` to rounding. Returns the Newton
    /// iterations; [`FormulationError::Projection`] when `max_iter` are not
    /// enough (or Φ is not finite). With [`Correction::Direct`] (Yu & Chen
    /// 2000) exactly one position correction is made whatever the
    /// residual (none when Φ = 0), so no tolerance can fail.
    pub fn project(
        &mut self,
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<usize, FormulationError> {
        let p = self.opts.projection;
        let lin = linear_at(t);
        let mut iterations = 0;
        loop {
            self.sys.phi(q, t, &mut self.b.phi);
            let residual = crate::numeric::max_abs(&self.b.phi);
            let direct = p.correction == Correction::Direct;
            if (residual <= p.tol && !direct) || residual == 0.0 || (direct && iterations == 1) {
                break;
            }
            FormulationError::check_projection(t, residual, p.tol, iterations, p.max_iter)?;
            self.factor_at(t, q)?;
            mass_orthogonal_step(
                &mut *self.b.solver,
                &self.b.k,
                &self.b.phi,
                &mut self.b.x,
                q,
            )
            .map_err(lin)?;
            iterations += 1;
        }
        self.factor_at(t, q)?;
        self.sys.jacobian_mul(&self.b.jac, qd, &mut self.b.phid);
        self.sys.phi_t(q, t, &mut self.b.phi_t);
        for (a, b) in self.b.phid.iter_mut().zip(&self.b.phi_t) {
            *a += b;
        }
        mass_orthogonal_step(
            &mut *self.b.solver,
            &self.b.k,
            &self.b.phid,
            &mut self.b.x,
            qd,
        )
        .map_err(lin)?;
        self.b.stats.projections += 1;
        self.b.stats.projection_iterations += iterations;
        Ok(iterations)
    }
}

impl OdeSystem for Index1<'_> {
    fn dim(&self) -> usize {
        2 * self.sys.n_coords()
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<(), SystemError> {
        first_order_rhs(self.sys.n_coords(), y, dydt, |q, qd, qdd| {
            self.accelerations(t, q, qd, qdd)
        })
    }
    /// With [`Projection::enabled`]: [`Index1::project`] the step's end state.
    fn post_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        if !self.opts.projection.enabled {
            return Ok(false);
        }
        let (q, qd) = y.split_at_mut(self.sys.n_coords());
        self.project(t, q, qd).map_err(SystemError::new)?;
        Ok(true)
    }
}
