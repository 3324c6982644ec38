//! The index-3 augmented Lagrangian formulation with mass-orthogonal
//! projections (ALI3-P; Bayo & Ledesma 1996) of a [`System`]: a
//! [`SecondOrderDae`] whose multipliers are iterated
//! ([`MultiplierUpdate`]), integrated by [`crate::integrate::GenAlpha`]
//! (the scheme: docs/constraint_methods.md and the generalized-α module's
//! part on the augmented Lagrangian).
//!
//! `M q̈ + Φ_qᵀ(αΦ + λ*) = g`, `λ*_{i+1} = λ*_i + αΦ_{i+1}`: the Newton
//! matrix `W = c_m M + c_c C + c_k (K + Φ_qᵀαΦ_q)` (`C = −∂g/∂q̇`,
//! `K = −∂g/∂q + (Φ_qᵀλ*)_q`) is the `A` block of a [`SaddleMatrix`] with
//! no constraint rows — mass diagonal, force Jacobian blocks, constraint
//! Hessian blocks and, per constraint row, every pair of its Φ_q columns
//! (as [`super::Penalty`]) — built once, factorised per assembly by the
//! solver of [`solver_for`] (sparse LDLᵀ by default; the reciprocal part of
//! an unsymmetric force Jacobian, as [`super::Index3`]'s: modified Newton
//! with the exact residual).
//! The penalty term is positive semi-definite whatever the rank of Φ_q, so
//! singular configurations and redundant constraints need no special
//! treatment: the redundant rows share their multiplier in the minimum-norm
//! way the multiplier iteration converges to.
//!
//! **Penalty.** The multiplier iteration converges for any α > 0, with
//! contraction `≈ 1/(1 + c_k α σ²/m)` per iteration along a constraint
//! direction of `Φ_q M⁻¹ Φ_qᵀ`-eigenvalue `σ²/m`; α only sets the speed
//! (and too large a value the conditioning, `cond W ~ c_k α ‖Φ_q‖²/m`).
//! Default ([`AugmentedParams::alpha`] = `None`): `α = κ m̄ / (β h²)`,
//! `κ` = [`PENALTY_SCALE`], `m̄` the mean translational mass — i.e.
//! `c_k α = κ m̄`, a step-size independent contraction; for `m̄` = 1 kg and
//! h = 1e-3 s with the trapezoidal rule that is α = 4e10 N/m (the
//! references' fixed α = 1e7 … 1e9 correspond to κ = 0.25 … 25 there).
//! The consistent accelerations at the start are the same iteration at
//! acceleration level, `(M + c_k αΦ_qᵀΦ_q) q̈ = g − Φ_qᵀλ + c_k αΦ_qᵀγ`,
//! `λ += c_k α(Φ_q q̈ − γ)`.
//!
//! **Inconsistent start.** Index-3 Newton with the penalty cannot move the
//! positions onto the manifold in the first step when they start far from
//! it (the four-bar with its coupler 0.05 rad off: the corrections grow,
//! θ ≈ 2, for every step size). So [`Augmented::consistent_start`] first
//! projects `(q₀, q̇₀)` at t0 (Bayo & Ledesma's mass-orthogonal projection
//! as an augmented Lagrangian, on the same matrix pattern): the closest
//! consistent positions in the mass norm,
//! `min ½(q − q₀)ᵀM(q − q₀)` s.t. `Φ(q, t0) = 0`, by
//! `(M + cΦ_qᵀΦ_q) Δq = −[M(q − q₀) + Φ_qᵀ(μ + cΦ)]`, `μ += cΦ(q + Δq)`
//! (Gauss–Newton on the KKT conditions, `c = αβh²` as at the start), then
//! the velocities the same way on `Φ_q q̇ + Φ_t = 0`. A semi-definite
//! `Φ_qᵀΦ_q` needs nothing special here either.

use super::dynamic_blocks::{DynamicBlocks, PenaltyBlock};
use super::{
    all_finite, check_state, linear_at, FormulationError, StartCorrection, START_MAX_ITER,
    START_TOL,
};
use crate::integrate::{DaeResult, MultiplierUpdate, SecondOrderDae, StateView, SystemError};
use crate::linalg::{
    solver_for, APattern, SaddleMatrix, SaddlePointSolver, SolverKind, SolverOptions, SolverStats,
};
use crate::model::System;
use serde::Serialize;

/// Default `κ` of the penalty `α = κ m̄ / (β h²)` (module docs): the
/// multiplier iteration contracts by about `1/(1 + κ σ²)` per Newton
/// iteration for constraint directions of unit weight.
pub const PENALTY_SCALE: f64 = 1e4;

/// Parameters of the augmented Lagrangian formulation.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct AugmentedParams {
    /// Penalty α > 0 \[N/m for position constraints in m\]; `None`: from the
    /// mass scale and the step, `κ m̄ / (β h²)` ([`PENALTY_SCALE`]).
    pub alpha: Option<f64>,
}

impl AugmentedParams {
    /// α finite and > 0 when given ([`FormulationError::InvalidOption`]).
    pub fn validate(&self) -> Result<(), FormulationError> {
        match self.alpha {
            Some(a) if !(a.is_finite() && a > 0.0) => Err(FormulationError::InvalidOption {
                option: "alpha",
                value: a.to_string(),
                reason: "must be finite and > 0".into(),
            }),
            _ => Ok(()),
        }
    }

    /// The penalty in force for `sys` with the Newton scale `s = β h²`:
    /// the given α, or `PENALTY_SCALE · m̄ / s`.
    pub fn penalty(&self, sys: &System, s: f64) -> f64 {
        self.alpha.unwrap_or_else(|| {
            let m = sys.mass_diagonal();
            let (sum, count) = m[..sys.n_body_coords()]
                .chunks(3)
                .flat_map(|b| b[..2].iter())
                .fold((0.0, 0usize), |(a, c), v| (a + v, c + 1));
            let mbar = if count > 0 && sum > 0.0 {
                sum / count as f64
            } else {
                1.0
            };
            PENALTY_SCALE * mbar / s
        })
    }
}

/// Counters of [`Augmented`].
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct AugmentedFormStats {
    /// Multiplier iterations of the consistent accelerations at the start.
    pub initial_iterations: usize,
    /// Iterations of the projection of an inconsistent start.
    pub start_iterations: usize,
    /// Counters of the solver of `W`.
    pub solver: SolverStats,
}

/// The augmented Lagrangian form of a [`System`] (module docs).
pub struct Augmented<'a> {
    sys: &'a System,
    params: AugmentedParams,
    alpha: f64,
    /// Newton scale `s = β h²` of the nominal step (initial accelerations).
    s0: f64,
    k: SaddleMatrix,
    solver: Box<dyn SaddlePointSolver>,
    /// The mass, force-Jacobian and (Φ_qᵀλ)_q blocks of `k`.
    blocks: DynamicBlocks,
    /// The penalty block `Φ_qᵀαΦ_q` of `k`.
    penalty: PenaltyBlock,
    jac: Vec<f64>,
    g: Vec<f64>,
    x: Vec<f64>,
    phi: Vec<f64>,
    phi_t: Vec<f64>,
    e: Vec<f64>,
    lam_tot: Vec<f64>,
    stats: AugmentedFormStats,
}

impl<'a> Augmented<'a> {
    /// Pattern, solver and symbolic analysis (once). `s0 = β h²` of the
    /// nominal step sets the default penalty ([`AugmentedParams::penalty`]);
    /// `linear_solver` must not be [`SolverKind::Schur`] (there are no
    /// multipliers to eliminate).
    pub fn new(
        sys: &'a System,
        params: AugmentedParams,
        linear_solver: SolverKind,
        s0: f64,
    ) -> Result<Self, FormulationError> {
        params.validate()?;
        if linear_solver == SolverKind::Schur {
            return Err(FormulationError::InvalidOption {
                option: "linear_solver",
                value: "schur".into(),
                reason: "does not apply to the augmented Lagrangian formulation (no \
                         multipliers to eliminate)"
                    .into(),
            });
        }
        if !(s0.is_finite() && s0 > 0.0) {
            return Err(FormulationError::InvalidOption {
                option: "step",
                value: s0.to_string(),
                reason: "β h² must be finite and > 0".into(),
            });
        }
        let n = sys.n_coords();
        let mut a = APattern::new();
        let blocks = DynamicBlocks::register(sys, &mut a);
        let jp = sys.jacobian_pattern();
        let penalty = PenaltyBlock::register(sys, &mut a);
        let mut solver = solver_for(
            linear_solver,
            n,
            SolverOptions {
                residual_check: false,
            },
        );
        let k = SaddleMatrix::with_storage(n, 0, &a, &[], solver.storage());
        solver.analyze(&k).map_err(linear_at(f64::NAN))?;
        let m = sys.n_constraints();
        Ok(Self {
            sys,
            params,
            alpha: params.penalty(sys, s0),
            s0,
            k,
            solver,
            blocks,
            penalty,
            jac: vec![0.0; jp.len()],
            g: vec![0.0; n],
            x: vec![0.0; n],
            phi: vec![0.0; m],
            phi_t: vec![0.0; m],
            e: vec![0.0; m],
            lam_tot: vec![0.0; m],
            stats: AugmentedFormStats::default(),
        })
    }

    /// The penalty α in force.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// Name of the linear solver of `W`.
    pub fn solver_name(&self) -> &'static str {
        self.solver.name()
    }

    /// Counters so far.
    pub fn stats(&self) -> AugmentedFormStats {
        let mut s = self.stats;
        s.solver = self.solver.stats();
        s
    }

    /// Assemble `c_m M + c_c C + c_k K + c_p Φ_qᵀΦ_q` at `(t, q, q̇, λ)`
    /// (the Hessian term only for `c_k ≠ 0`) and factorise it.
    #[allow(clippy::too_many_arguments)]
    fn assemble(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lam: &[f64],
        c_m: f64,
        c_c: f64,
        c_k: f64,
        c_p: f64,
    ) -> Result<(), FormulationError> {
        let sys = self.sys;
        check_state(t, q, qd)?;
        let c = [c_m, c_c, c_k];
        let (forces, hessians) = DynamicBlocks::needs(c);
        let jac = &mut self.jac;
        self.blocks
            .evaluate(sys, t, q, qd, lam, forces, hessians, jac)?;
        self.blocks.write(sys, &mut self.k, c);
        self.penalty.add(&mut self.k, c_p, &self.jac);
        self.solver
            .factorize(&self.k)
            .map(|_| ())
            .map_err(linear_at(t))
    }

    /// `x += −c Φ_qᵀ e` solved with `W`: `Δ = −W⁻¹ c Φ_qᵀ e` into `v`.
    fn correct(&mut self, t: f64, c: f64, v: &mut [f64]) -> Result<(), FormulationError> {
        self.sys.jacobian_tmul(&self.jac, &self.e, &mut self.x);
        for x in self.x.iter_mut() {
            *x *= -c;
        }
        self.solver
            .solve_in_place(&self.k, &mut self.x)
            .map_err(linear_at(t))?;
        for (vi, d) in v.iter_mut().zip(&self.x) {
            *vi += d;
        }
        Ok(())
    }

    /// `x ← −[M(v − v₀) + Φ_qᵀ(μ + c e)]` solved with the factorised
    /// `M + cΦ_qᵀΦ_q`; `v += x`; returns `max |x_i|`.
    fn start_correction(
        &mut self,
        t: f64,
        c: f64,
        v: &mut [f64],
        v0: &[f64],
        mu: &[f64],
    ) -> Result<f64, FormulationError> {
        for ((e, m), p) in self.e.iter_mut().zip(mu).zip(&self.phi) {
            *e = m + c * p;
        }
        self.sys.jacobian_tmul(&self.jac, &self.e, &mut self.x);
        for (((x, m), a), b) in self
            .x
            .iter_mut()
            .zip(self.sys.mass_diagonal())
            .zip(v.iter())
            .zip(v0)
        {
            *x = -(*x + m * (a - b));
        }
        self.solver
            .solve_in_place(&self.k, &mut self.x)
            .map_err(linear_at(t))?;
        let mut dmax: f64 = 0.0;
        for (vi, d) in v.iter_mut().zip(&self.x) {
            *vi += d;
            dmax = dmax.max(d.abs());
        }
        Ok(dmax)
    }

    /// Put an inconsistent initial state onto the constraint manifold
    /// (module docs, "Inconsistent start"): positions to the closest
    /// consistent ones in the mass norm, then velocities to the closest
    /// ones on `Φ_q q̇ + Φ_t = 0`, each until its residual is below
    /// [`START_TOL`] and the last correction below it too. A consistent
    /// state is left untouched (bit for bit). If the iteration does not
    /// get there in [`START_MAX_ITER`] iterations, or ‖Φ‖ grows tenfold,
    /// [`FormulationError::Initial`] says why: no consistent configuration
    /// near the given one (or a locked-up one at a singular position).
    pub fn consistent_start(
        &mut self,
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<StartCorrection, FormulationError> {
        let sys = self.sys;
        check_state(t, q, qd)?;
        let norm = crate::numeric::max_abs;
        let c = self.alpha * self.s0;
        let mut out = StartCorrection::default();
        let m = sys.n_constraints();
        let mut mu = vec![0.0; m];
        sys.phi(q, t, &mut self.phi);
        all_finite(t, &[("the constraints Φ", &self.phi)])?;
        out.phi = norm(&self.phi);
        if out.phi > START_TOL {
            let q0 = q.to_vec();
            let mut res = out.phi;
            let mut it = 0;
            loop {
                if it == START_MAX_ITER || res > 10.0 * out.phi {
                    return Err(FormulationError::Initial(format!(
                        "the initial positions violate the constraints (‖Φ‖∞ = {:.3e} at t = \
                         {t}) and the augmented Lagrangian's mass-orthogonal projection did not \
                         reach the manifold ({}: ‖Φ‖∞ = {res:.3e} after {it} iterations): there is \
                         no consistent configuration near the given one (check the initial \
                         positions and the joint geometry) or the mechanism locks up there",
                        out.phi,
                        if it == START_MAX_ITER {
                            "no convergence"
                        } else {
                            "diverged"
                        }
                    )));
                }
                it += 1;
                self.assemble(t, q, qd, &mu, 1.0, 0.0, 0.0, c)?;
                let dmax = self.start_correction(t, c, q, &q0, &mu)?;
                sys.phi(q, t, &mut self.phi);
                all_finite(t, &[("the constraints Φ", &self.phi)])?;
                for (u, p) in mu.iter_mut().zip(&self.phi) {
                    *u += c * p;
                }
                res = norm(&self.phi);
                if res <= START_TOL && dmax <= START_TOL {
                    break;
                }
            }
            out.moved_q = crate::numeric::max_abs_diff(q, &q0);
            out.iterations += it;
        }
        // velocities at the (projected) positions: Φ̇ = Φ_q q̇ + Φ_t
        sys.jacobian_values(q, t, &mut self.jac);
        sys.phi_t(q, t, &mut self.phi_t);
        let vel_residual = |this: &mut Self, qd: &[f64]| {
            sys.jacobian_mul(&this.jac, qd, &mut this.phi);
            for (p, pt) in this.phi.iter_mut().zip(&this.phi_t) {
                *p += pt;
            }
            norm(&this.phi)
        };
        let vscale = norm(qd).max(1.0);
        out.phi_dot = vel_residual(self, qd);
        all_finite(t, &[("the velocity constraints Φ̇", &self.phi)])?;
        if out.phi_dot > START_TOL * vscale {
            let qd0 = qd.to_vec();
            mu.fill(0.0);
            self.assemble(t, q, qd, &mu, 1.0, 0.0, 0.0, c)?;
            let mut res = out.phi_dot;
            let mut it = 0;
            loop {
                if it == START_MAX_ITER || res > 10.0 * out.phi_dot {
                    return Err(FormulationError::Initial(format!(
                        "the initial velocities violate the velocity constraints (‖Φ_q q̇ + \
                         Φ_t‖∞ = {:.3e} at t = {t}) and the mass-orthogonal projection did not \
                         converge (‖Φ̇‖∞ = {res:.3e} after {it} iterations): the positions are \
                         at or near a singular configuration",
                        out.phi_dot
                    )));
                }
                it += 1;
                let dmax = self.start_correction(t, c, qd, &qd0, &mu)?;
                res = vel_residual(self, qd);
                all_finite(t, &[("the velocity constraints Φ̇", &self.phi)])?;
                for (u, p) in mu.iter_mut().zip(&self.phi) {
                    *u += c * p;
                }
                if res <= START_TOL * vscale && dmax <= START_TOL * vscale {
                    break;
                }
            }
            out.moved_qd = crate::numeric::max_abs_diff(qd, &qd0);
            out.iterations += it;
        }
        self.stats.start_iterations += out.iterations;
        Ok(out)
    }

    /// Consistent accelerations and multipliers at `(t, q, q̇)` by the
    /// multiplier iteration at acceleration level (module docs), until
    /// `‖Φ_q q̈ − γ‖∞ ≤ 1e-12 (1 + ‖γ‖∞)` or the correction stalls (at a
    /// singular or redundant Φ_q: the least-squares answer).
    pub(crate) fn initial_accelerations(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &mut [f64],
        lam: &mut [f64],
    ) -> Result<(), FormulationError> {
        let sys = self.sys;
        let cp = self.alpha * self.s0;
        self.assemble(t, q, qd, lam, 1.0, 0.0, 0.0, cp)?;
        sys.forces_into(t, q, qd, &mut self.g);
        sys.gamma(q, qd, t, &mut self.phi_t);
        all_finite(t, &[("the forces g", &self.g), ("γ", &self.phi_t)])?;
        lam.fill(0.0);
        qdd.fill(0.0);
        let gmax = crate::numeric::max_abs(&self.phi_t);
        let mut prev = f64::INFINITY;
        for _ in 0..100 {
            self.stats.initial_iterations += 1;
            // (M + cpΦ_qᵀΦ_q) q̈ = g − Φ_qᵀλ + cpΦ_qᵀγ
            for (e, (l, gm)) in self.e.iter_mut().zip(lam.iter().zip(&self.phi_t)) {
                *e = l - cp * gm;
            }
            sys.jacobian_tmul(&self.jac, &self.e, &mut self.x);
            for (x, g) in self.x.iter_mut().zip(&self.g) {
                *x = g - *x;
            }
            self.solver
                .solve_in_place(&self.k, &mut self.x)
                .map_err(linear_at(t))?;
            qdd.copy_from_slice(&self.x);
            sys.jacobian_mul(&self.jac, qdd, &mut self.e);
            let mut res: f64 = 0.0;
            for ((l, e), gm) in lam.iter_mut().zip(&mut self.e).zip(&self.phi_t) {
                *e -= gm;
                *l += cp * *e;
                res = res.max(e.abs());
            }
            if res <= 1e-12 * (1.0 + gmax) || res >= 0.999 * prev {
                break;
            }
            prev = res;
        }
        Ok(())
    }
}

fn sys_err(e: FormulationError) -> SystemError {
    SystemError::new(e)
}

impl SecondOrderDae for Augmented<'_> {
    fn n(&self) -> usize {
        self.sys.n_coords()
    }
    fn m(&self) -> usize {
        self.sys.n_constraints()
    }
    fn mass_diagonal(&self) -> &[f64] {
        self.sys.mass_diagonal()
    }
    fn accelerations(&mut self, x: StateView<'_>, qdd: &mut [f64], lam: &mut [f64]) -> DaeResult {
        self.initial_accelerations(x.t, x.q, x.qd, qdd, lam)
            .map_err(sys_err)
    }
    /// The scaled residual `r = s (M q̈ + Φ_qᵀ(αΦ + λ*) − g(q, q̇, t))` (n
    /// rows; λ is λ*).
    fn residual(
        &mut self,
        StateView { t, q, qd }: StateView<'_>,
        qdd: &[f64],
        lam: &[f64],
        s: f64,
        r: &mut [f64],
    ) -> Result<(), SystemError> {
        let sys = self.sys;
        check_state(t, q, qd).map_err(sys_err)?;
        sys.jacobian_values(q, t, &mut self.jac);
        sys.phi(q, t, &mut self.phi);
        sys.forces_into(t, q, qd, &mut self.g);
        for ((lt, l), p) in self.lam_tot.iter_mut().zip(lam).zip(&self.phi) {
            *lt = l + self.alpha * p;
        }
        sys.jacobian_tmul(&self.jac, &self.lam_tot, r);
        for ((ri, (m, a)), g) in r
            .iter_mut()
            .zip(sys.mass_diagonal().iter().zip(qdd))
            .zip(&self.g)
        {
            *ri = s * (m * a + *ri - g);
        }
        all_finite(
            t,
            &[
                ("the forces g", &self.g),
                ("the constraint Jacobian Φ_q", &self.jac),
                ("the augmented Lagrangian residual", r),
            ],
        )
        .map_err(sys_err)
    }
    fn constraints(&mut self, t: f64, q: &[f64], phi: &mut [f64]) {
        self.sys.phi(q, t, phi);
    }
    /// Assemble and factorise `W = c[0] M + c[1] C + c[2] (K + Φ_qᵀαΦ_q)`.
    fn factorize(&mut self, x: StateView<'_>, lam: &[f64], c: [f64; 3]) -> DaeResult {
        let (StateView { t, q, qd }, cp) = (x, c[2] * self.alpha);
        self.assemble(t, q, qd, lam, c[0], c[1], c[2], cp)
            .map_err(sys_err)
    }
    /// Solve `W x = b` (n rows) in place with the last factorisation.
    fn solve(&mut self, t: f64, x: &mut [f64]) -> Result<(), SystemError> {
        self.solver
            .solve_in_place(&self.k, x)
            .map_err(|source| sys_err(linear_at(t)(source)))
    }
    /// The mass-orthogonal projection of [`Augmented::consistent_start`].
    fn project(&mut self, t: f64, q: &mut [f64], qd: &mut [f64]) -> Result<(), SystemError> {
        self.consistent_start(t, q, qd).map(|_| ()).map_err(sys_err)
    }
    fn multiplier_update(&mut self) -> Option<&mut dyn MultiplierUpdate> {
        Some(self)
    }
}

impl MultiplierUpdate for Augmented<'_> {
    fn set_step_scale(&mut self, s: f64) {
        self.alpha = self.params.penalty(self.sys, s);
    }
    fn scale_penalty(&mut self, factor: f64) {
        self.alpha *= factor;
    }
    fn update_multipliers(
        &mut self,
        t: f64,
        q: &[f64],
        lam: &mut [f64],
    ) -> Result<(), SystemError> {
        self.sys.phi(q, t, &mut self.phi);
        all_finite(t, &[("the constraints Φ", &self.phi)]).map_err(sys_err)?;
        for (l, p) in lam.iter_mut().zip(&self.phi) {
            *l += self.alpha * p;
        }
        Ok(())
    }
    fn project_motion(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &mut [f64],
        qdd: &mut [f64],
        s: f64,
    ) -> Result<(), SystemError> {
        let sys = self.sys;
        let c = s * self.alpha;
        // the factorised W stays; Φ_q at the converged q
        sys.jacobian_values(q, t, &mut self.jac);
        sys.phi_t(q, t, &mut self.phi_t);
        sys.jacobian_mul(&self.jac, qd, &mut self.e);
        for (e, pt) in self.e.iter_mut().zip(&self.phi_t) {
            *e += pt;
        }
        self.correct(t, c, qd).map_err(sys_err)?;
        sys.gamma(q, qd, t, &mut self.phi_t);
        sys.jacobian_mul(&self.jac, qdd, &mut self.e);
        for (e, gm) in self.e.iter_mut().zip(&self.phi_t) {
            *e -= gm;
        }
        self.correct(t, c, qdd).map_err(sys_err)?;
        all_finite(
            t,
            &[
                ("the projected velocities", qd),
                ("the projected accelerations", qdd),
            ],
        )
        .map_err(sys_err)
    }
}
