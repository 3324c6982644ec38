//! The penalty formulation (Bayo, García de Jalón & Serna, "A modified
//! Lagrangian formulation for the dynamic analysis of constrained mechanical
//! systems", Comput. Methods Appl. Mech. Engrg. 71 (1988) 183–195; the
//! paper's §3.1), and [`ExplicitForm`], the formulation an explicit
//! integrator drives.
//!
//! The constraints are replaced by forces `−Φ_qᵀλ` with
//! `λ = α (Φ̈ + 2ξωΦ̇ + ω²Φ)` — a penalty α on a critically damped (ξ = 1)
//! constraint "spring" of frequency ω. With `Φ̈ = Φ_q q̈ − γ`,
//! `γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt` (rheonomic terms included,
//! [`crate::model::Constraint::gamma`]) and `Φ̇ = Φ_q q̇ + Φ_t`:
//!
//! ```text
//! (M + α Φ_qᵀΦ_q) q̈ = g + α Φ_qᵀ (γ − 2ξω Φ̇ − ω² Φ)
//! ```
//!
//! an ODE in `y = [q; q̇]` with no multipliers and a symmetric positive
//! definite matrix (positive semi-definite penalty term, rank-deficient Φ_q
//! allowed). The constraint violation obeys `Φ̈ + 2ξωΦ̇ + ω²Φ = λ/α`, so it
//! shrinks like `1/α` (tested). The bracket is the Baumgarte γ̄ of eq. (11)
//! with `α_B = ξω`, `β_B = ω`.

use super::dynamic_blocks::PenaltyBlock;
use super::index1::{first_order_rhs, RhsBuffers};
use super::{
    check_state, feedback, linear_at, Formulation, FormulationError, Index1, Index1Options,
    RhsStats,
};
use crate::integrate::{OdeSystem, StateView, SystemError};
use crate::linalg::{solver_for, APattern, SaddleMatrix, SolverKind, SolverOptions};
use crate::model::System;
use serde::Serialize;

/// Parameters of the penalty formulation: `λ = α (Φ̈ + 2ξωΦ̇ + ω²Φ)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PenaltyParams {
    /// Penalty α > 0 (kg for position constraints in m).
    pub alpha: f64,
    /// Damping ratio ξ ≥ 0 of the constraint dynamics.
    pub xi: f64,
    /// Natural frequency ω ≥ 0 of the constraint dynamics \[rad/s\].
    pub omega: f64,
}

impl Default for PenaltyParams {
    /// α = 1e7, ξ = 1, ω = 10 (Bayo et al. 1988 recommend α = 1e7 … 1e9 and
    /// report insensitivity to ξ = 1, ω = 10 for their examples).
    fn default() -> Self {
        Self {
            alpha: 1e7,
            xi: 1.0,
            omega: 10.0,
        }
    }
}

impl PenaltyParams {
    /// α finite and > 0, ξ and ω finite and ≥ 0
    /// ([`FormulationError::InvalidOption`] names the field).
    pub fn validate(&self) -> Result<(), FormulationError> {
        let bad = |option, v: f64, reason: &str| {
            Err(FormulationError::InvalidOption {
                option,
                value: v.to_string(),
                reason: reason.into(),
            })
        };
        if !(self.alpha.is_finite() && self.alpha > 0.0) {
            return bad("alpha", self.alpha, "must be finite and > 0");
        }
        for (option, v) in [("xi", self.xi), ("omega", self.omega)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(option, v, "must be finite and ≥ 0");
            }
        }
        Ok(())
    }
}

/// The penalty formulation of a [`System`] as a first-order ODE for
/// `y = [q; q̇]` (module docs). The matrix `M + αΦ_qᵀΦ_q` is the `A` block
/// of a [`SaddleMatrix`] with no constraint rows: its pattern (the mass
/// diagonal and, per constraint row, every pair of its Φ_q columns) is
/// built once and factorised per evaluation by the solver of
/// [`Index1Options::linear_solver`] ([`solver_for`]; sparse LDLᵀ by
/// default). No allocation per evaluation.
pub struct Penalty<'a> {
    sys: &'a System,
    p: PenaltyParams,
    /// The `α Φ_qᵀΦ_q` block (the mass is the diagonal).
    block: PenaltyBlock,
    b: RhsBuffers,
}

impl<'a> Penalty<'a> {
    /// Pattern, solver and symbolic analysis (once). Uses
    /// `opts.penalty` and `opts.linear_solver`; Baumgarte terms, projection
    /// and the Schur solver do not apply (errors naming the option).
    pub fn new(sys: &'a System, opts: Index1Options) -> Result<Self, FormulationError> {
        let p = opts.penalty;
        p.validate()?;
        let not_applicable = |option: &'static str, value: String| {
            Err(FormulationError::InvalidOption {
                option,
                value,
                reason: "does not apply to the penalty formulation (its ξ, ω play the role \
                         of the Baumgarte terms)"
                    .into(),
            })
        };
        if !opts.baumgarte.is_off() {
            return not_applicable(
                "baumgarte",
                format!("({}, {})", opts.baumgarte.alpha, opts.baumgarte.beta),
            );
        }
        if opts.projection.enabled {
            return not_applicable("projection", "true".into());
        }
        if opts.linear_solver == SolverKind::Schur {
            return not_applicable("linear_solver", "schur".into());
        }
        let n = sys.n_coords();
        let mut a = APattern::new();
        let block = PenaltyBlock::register(sys, &mut a);
        let mut solver = solver_for(opts.linear_solver, n, SolverOptions::default());
        let k = SaddleMatrix::with_storage(n, 0, &a, &[], solver.storage());
        solver.analyze(&k).map_err(linear_at(f64::NAN))?;
        Ok(Self {
            sys,
            p,
            block,
            b: RhsBuffers::new(sys, solver, k, n),
        })
    }

    /// The system.
    pub fn system(&self) -> &System {
        self.sys
    }

    /// The penalty forces' multipliers of the last evaluation,
    /// `λ = α (Φ̈ + 2ξωΦ̇ + ω²Φ)` (sign of `M q̈ + Φ_qᵀλ = g`).
    pub fn lambda(&self) -> &[f64] {
        &self.b.lambda
    }

    /// Accelerations from `(M + αΦ_qᵀΦ_q) q̈ = g + αΦ_qᵀ(γ − 2ξωΦ̇ − ω²Φ)`.
    pub fn accelerations(
        &mut self,
        x: StateView<'_>,
        qdd: &mut [f64],
    ) -> Result<(), FormulationError> {
        let StateView { t, q, qd } = x;
        let sys = self.sys;
        self.b.stats.evaluations += 1;
        check_state(t, q, qd)?;
        let PenaltyParams { alpha, xi, omega } = self.p;
        sys.forces_into(t, q, qd, &mut self.b.g);
        sys.constraint_terms(
            q,
            qd,
            t,
            Some(&mut self.b.phi),
            &mut self.b.jac,
            &mut self.b.gamma,
        );
        sys.phi_t(q, t, &mut self.b.phi_t);
        sys.jacobian_mul(&self.b.jac, qd, &mut self.b.phid);
        // γ̄ = γ − 2ξωΦ̇ − ω²Φ (kept in `gamma`)
        feedback(
            &mut self.b.gamma,
            &self.b.phid,
            &self.b.phi_t,
            &self.b.phi,
            2.0 * xi * omega,
            omega * omega,
        );
        self.b.k.set_zero();
        for (i, &m) in sys.mass_diagonal().iter().enumerate() {
            self.b.k.add_diagonal(i, m);
        }
        self.block.add(&mut self.b.k, alpha, &self.b.jac);
        let lin = linear_at(t);
        self.b.solver.factorize(&self.b.k).map_err(lin)?;
        sys.jacobian_tmul(&self.b.jac, &self.b.gamma, &mut self.b.x);
        for (x, g) in self.b.x.iter_mut().zip(&self.b.g) {
            *x = g + alpha * *x;
        }
        self.b
            .solver
            .solve_in_place(&self.b.k, &mut self.b.x)
            .map_err(lin)?;
        qdd.copy_from_slice(&self.b.x);
        // λ = α (Φ_q q̈ − γ̄)
        sys.jacobian_mul(&self.b.jac, qdd, &mut self.b.lambda);
        for (l, gb) in self.b.lambda.iter_mut().zip(&self.b.gamma) {
            *l = alpha * (*l - gb);
        }
        Ok(())
    }
}

impl OdeSystem for Penalty<'_> {
    fn dim(&self) -> usize {
        2 * self.sys.n_coords()
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<(), SystemError> {
        first_order_rhs(self.sys.n_coords(), y, dydt, |q, qd, qdd| {
            self.accelerations(StateView { t, q, qd }, qdd)
        })
    }
}

/// The formulation an explicit integrator (ode23, ode45, rk4) drives, as
/// [`Index1Options::formulation`] chooses: [`Index1`] (saddle point or
/// eliminated) or [`Penalty`].
pub enum ExplicitForm<'a> {
    /// Eq. (5) or eq. (9), with Baumgarte terms and optional projection.
    Index1(Index1<'a>),
    /// The penalty formulation.
    Penalty(Penalty<'a>),
}

impl<'a> ExplicitForm<'a> {
    /// Build the formulation `opts.formulation` names.
    pub fn new(sys: &'a System, opts: Index1Options) -> Result<Self, FormulationError> {
        Ok(match opts.formulation {
            Formulation::Penalty => Self::Penalty(Penalty::new(sys, opts)?),
            _ => Self::Index1(Index1::new(sys, opts)?),
        })
    }

    /// The buffers of the formulation in use.
    fn buffers(&self) -> &RhsBuffers {
        match self {
            Self::Index1(f) => &f.b,
            Self::Penalty(f) => &f.b,
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> RhsStats {
        self.buffers().stats()
    }

    /// Name of the linear solver in use.
    pub fn solver_name(&self) -> &'static str {
        self.buffers().solver.name()
    }

    /// Multipliers of the last evaluation (`M q̈ + Φ_qᵀλ = g`).
    pub fn lambda(&self) -> &[f64] {
        match self {
            Self::Index1(f) => f.lambda(),
            Self::Penalty(f) => f.lambda(),
        }
    }
}

impl OdeSystem for ExplicitForm<'_> {
    fn dim(&self) -> usize {
        match self {
            Self::Index1(f) => f.dim(),
            Self::Penalty(f) => f.dim(),
        }
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<(), SystemError> {
        match self {
            Self::Index1(f) => f.rhs(t, y, dydt),
            Self::Penalty(f) => f.rhs(t, y, dydt),
        }
    }
    fn post_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        match self {
            Self::Index1(f) => f.post_step(t, y),
            Self::Penalty(f) => f.post_step(t, y),
        }
    }
}
