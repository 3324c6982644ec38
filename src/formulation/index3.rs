//! The index-3 form of the equations of motion for implicit integrators:
//! residual and Newton (iteration) matrix, assembled into a fixed sparse
//! saddle-point pattern.
//!
//! Equations (our sign convention, see [`crate::linalg`]):
//!
//! ```text
//! M q̈ + Φ_qᵀ(q, t) λ = g(q, q̇, t),        Φ(q, t) = 0          (index 3)
//! ```
//!
//! An implicit method such as generalized-α (Arnold & Brüls, "Convergence
//! of the generalized-α scheme for constrained mechanical systems",
//! Multibody Syst. Dyn. 18 (2007)) treats `q̈ = q̈(q)`, `q̇ = q̇(q)` as
//! functions of the new positions through its update formulas, with
//! `∂q̈/∂q = β'` and `∂q̇/∂q = γ'` scalars. Newton's method on the residual
//! then needs the iteration matrix
//!
//! ```text
//! S_t = [ M β' + C_t γ' + K_t   Φ_qᵀ ]     C_t = −∂g/∂q̇
//!       [ Φ_q                   0    ]     K_t = −∂g/∂q + (Φ_qᵀ λ)_q
//! ```
//!
//! **Scaling** (Bottasso, Bauchau & Cardona, "Time-step-size-independent
//! conditioning and sensitivity to perturbations in the numerical solution
//! of index three differential algebraic equations", SIAM J. Sci. Comput.
//! 29 (2007); Arnold & Brüls 2007, §4): the dynamic rows are multiplied by
//! `s = β h²` and the multiplier increments are replaced by `μ = s Δλ`.
//! With `c_m = s β'`, `c_c = s γ'`, `c_k = s` the matrix solved is
//!
//! ```text
//! K = [ c_m M + c_c C_t + c_k K_t   Φ_qᵀ ]   [Δq]   [ −s (M q̈ + Φ_qᵀ λ − g) ]
//!     [ Φ_q                         0    ] · [ μ] = [ −Φ(q, t)               ]
//! ```
//!
//! whose blocks stay O(1) as `h → 0` (unscaled, `A ~ h⁻²` while the
//! multiplier Schur complement `Φ_q A⁻¹ Φ_qᵀ ~ h²`: condition number
//! O(h⁻⁴)); this is `β h² · D S_t D` with `D = diag(I, I/(β h²))`, so it
//! stays symmetric.
//!
//! **Symmetrisation.** The drag and contact Jacobians are not symmetric.
//! They are registered as unsymmetric blocks ([`Symmetry::Unsymmetric`]):
//! the sparse LU ([`NewtonSolverKind::SparseLu`]) factorises them as they
//! are (exact Newton); the symmetric solvers (the default LDLᵀ) receive a
//! symmetric approximation, a *modified* Newton method whose residual is
//! exact, so the converged solution is the same and only the contraction
//! rate can suffer (with `c_c ∝ h`, `c_k ∝ h²` the unsymmetric part
//! vanishes as `h → 0`). The approximation is the force Jacobians'
//! *reciprocal part* — of each pair `J_ij`, `J_ji` the smaller modulus
//! where the signs agree, else 0 — not the symmetric part `½ (J + Jᵀ)`,
//! which turns a one-way coupling (friction along a wall driven by the
//! penetration) into a negative stiffness (`DynamicBlocks::write` in
//! `dynamic_blocks.rs`). The assembly is the same for both
//! ([`SaddleMatrix::add_a`]); the storage follows the solver.
//!
//! **Pattern.** The `A` block's pattern is the union of the force elements'
//! Jacobian blocks ([`ForceElement::jacobian_coordinates`]² each) and the
//! joints' [`Constraint::hessian_pattern`] (evaluated by the generated
//! kernels where the system has them, [`System::add_constraint_hessians`]);
//! it is built **once**, the
//! symbolic analysis of the solver runs once, and each assembly writes the
//! values straight into precomputed slots (no search, no allocation beyond
//! what individual elements do).
//!
//! [`ForceElement::jacobian_coordinates`]: crate::model::ForceElement::jacobian_coordinates
//! [`Constraint::hessian_pattern`]: crate::model::Constraint::hessian_pattern

use super::dynamic_blocks::DynamicBlocks;
use super::state_border::StateBorder;
use super::{all_finite, linear_at, mass_orthogonal_step, FormulationError};
use crate::integrate::{DaeResult, SecondOrderDae, StateView, SystemError};
use crate::linalg::{
    solver_for, APattern, SaddleMatrix, SaddlePointSolver, SolverKind, SolverOptions, SolverStats,
};
use crate::model::{BodyTrig, ResidualHalves, System};
use crate::numeric::Time;
use crate::parallel::{join_if, PARALLEL_MIN_COORDS};
use serde::Serialize;

/// Counters of [`Index3`].
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Index3Stats {
    /// Residual evaluations (forces, Φ, Φ_q each).
    pub residuals: usize,
    /// Assemblies of the Newton matrix (force Jacobians and (Φ_qᵀλ)_q each).
    pub jacobians: usize,
    /// Counters of the Newton-matrix solver.
    pub newton_solver: SolverStats,
    /// Counters of the mass-matrix solver (initial accelerations, projections).
    pub mass_solver: SolverStats,
    /// Counters of the output projection's mass-matrix solver
    /// ([`SecondOrderDae::project_output`]).
    pub output_solver: SolverStats,
    /// Projections onto the constraint manifold.
    pub projections: usize,
}

/// The index-3 residual and the scaled Newton matrix of a [`System`]
/// (module docs), plus the mass-weighted projections used for consistent
/// initial accelerations and drift control.
///
/// Two saddle-point matrices are built once:
/// * the Newton matrix `[c_m M + c_c C_t + c_k K_t, Φ_qᵀ; Φ_q, 0]` with the
///   full `A` pattern (force Jacobians ∪ constraint Hessians);
/// * the mass matrix `[M, Φ_qᵀ; Φ_q, 0]` (diagonal `A`), for
///   `M q̈ + Φ_qᵀ λ = g, Φ_q q̈ = γ` (eq. (5)) at the start and for the
///   projections `min ‖Δ‖_M` subject to `Φ_q Δ = −Φ` or `= −(Φ_q q̇ + Φ_t)`.
pub struct Index3<'a> {
    sys: &'a System,
    n: usize,
    m: usize,
    k: SaddleMatrix,
    solver: Box<dyn SaddlePointSolver>,
    kp: SaddleMatrix,
    psolver: Box<dyn SaddlePointSolver>,
    /// The output projection's factorisation of `kp`, without the residual
    /// check: its corrections are accepted by `‖Φ‖` alone
    /// ([`SecondOrderDae::project_output`]), so a refinement step would only
    /// double each solve. Made at the first output row that needs it (the
    /// solver `mass_kind`), so a run without such rows holds no second
    /// factorisation of `kp`.
    osolver: Option<Box<dyn SaddlePointSolver>>,
    /// The solver kind of `psolver` and `osolver`.
    mass_kind: SolverKind,
    /// The mass, force-Jacobian and (Φ_qᵀλ)_q blocks of `k`.
    blocks: DynamicBlocks,
    jac: Vec<f64>,
    g: Vec<f64>,
    tmp: Vec<f64>,
    /// The residual in two halves by bodies for large systems whose plan
    /// allows it ([`System::residual_halves`]), with its buffers; used
    /// when the halves run on two threads (`parallel::concurrent`).
    halves: Option<(ResidualHalves, HalfBuffers)>,
    phi: Vec<f64>,
    x: Vec<f64>,
    stats: Index3Stats,
    /// Whether `osolver` holds a factorisation (of the mass saddle matrix
    /// at some recent output row), which the next output row may reuse.
    output_factored: bool,
    /// The controller states' exact border over the symmetric solver.
    border: Option<StateBorder>,
    /// [`SecondOrderDae::correction_lengths`]: 1, except a body angle's
    /// radius of gyration.
    correction_lengths: Vec<f64>,
}

/// Buffers of [`Index3`]'s residual in halves: the high half's g and
/// Φ_qᵀλ (the low half uses `Index3::g`, `Index3::tmp`), the boundary's g
/// and Φ_qᵀλ ([`System::residual_boundary`]; full length, only the
/// boundary's entries meaningful) and its scratch Φ.
#[derive(Debug)]
struct HalfBuffers {
    g_hi: Vec<f64>,
    tmp_hi: Vec<f64>,
    g_edge: Vec<f64>,
    tmp_edge: Vec<f64>,
    phi_edge: Vec<f64>,
}

/// How the Newton matrix is factorised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NewtonSolverKind {
    /// A symmetric approximation of the `A` block (the force Jacobians'
    /// reciprocal part, module docs) with the symmetric saddle-point solver
    /// (sparse LDLᵀ by default): modified Newton.
    #[default]
    SymmetricLdlt,
    /// The full unsymmetric matrix with faer's sparse LU (COLAMD column
    /// order, partial pivoting; `faer::sparse::linalg::lu`): exact Newton.
    SparseLu,
}

impl std::fmt::Debug for Index3<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Index3")
            .field("n", &self.n)
            .field("m", &self.m)
            .field("nnz", &self.k.nnz())
            .field("stats", &self.stats)
            .finish()
    }
}

impl<'a> Index3<'a> {
    /// Build both patterns and run the symbolic analyses (once).
    ///
    /// `linear_solver` chooses the saddle-point solver of both matrices
    /// ([`solver_for`]); the sparse LDLᵀ is the default, for the Newton
    /// matrix without its residual check (a modified Newton iteration
    /// tolerates an inexact solve: its residual is exact).
    pub fn new(sys: &'a System, linear_solver: SolverKind) -> Result<Self, FormulationError> {
        Self::with_newton_solver(sys, linear_solver, NewtonSolverKind::default())
    }

    /// As [`Index3::new`], choosing how the Newton matrix is factorised
    /// ([`NewtonSolverKind`]); `linear_solver` then only applies to the
    /// mass matrix with [`NewtonSolverKind::SparseLu`].
    pub fn with_newton_solver(
        sys: &'a System,
        linear_solver: SolverKind,
        newton: NewtonSolverKind,
    ) -> Result<Self, FormulationError> {
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let mut a = APattern::new();
        // ∂g/∂q, ∂g/∂q̇ and (Φ_qᵀλ)_q: every force element's and joint's
        // block, evaluated by the system (generated kernels where attached).
        let mut blocks = DynamicBlocks::register(sys, &mut a);
        // Newton corrections need no residual check: an inaccurate solve
        // only slows the (exact-residual) iteration down.
        // `Auto`: the envelope LDLᵀ when the pattern is a chain, faer's
        // sparse LDLᵀ otherwise (`ChainLdlt`).
        let kind = match newton {
            NewtonSolverKind::SymmetricLdlt if linear_solver == SolverKind::Auto => {
                SolverKind::Chain
            }
            NewtonSolverKind::SymmetricLdlt => linear_solver,
            NewtonSolverKind::SparseLu => SolverKind::SparseLu,
        };
        let newton_opts = SolverOptions {
            residual_check: false,
        };
        let mut solver = solver_for(kind, n + m, newton_opts);
        let k = SaddleMatrix::with_storage(n, m, &a, sys.jacobian_pattern(), solver.storage());
        let border = StateBorder::new(sys, solver.storage());
        if border.is_some() {
            blocks.decouple_states(sys);
        }
        let lin = linear_at(f64::NAN);
        solver.analyze(&k).map_err(lin)?;
        let mut psolver = solver_for(linear_solver, n + m, SolverOptions::default());
        let kp = SaddleMatrix::with_storage(
            n,
            m,
            &APattern::new(),
            sys.jacobian_pattern(),
            psolver.storage(),
        );
        psolver.analyze(&kp).map_err(lin)?;
        Ok(Self {
            sys,
            n,
            m,
            k,
            solver,
            kp,
            psolver,
            osolver: None,
            mass_kind: linear_solver,
            blocks,
            jac: vec![0.0; sys.jacobian_pattern().len()],
            g: vec![0.0; n],
            tmp: vec![0.0; n],
            halves: (n >= PARALLEL_MIN_COORDS)
                .then(|| sys.residual_halves(sys.bodies().len() / 2))
                .flatten()
                .map(|h| {
                    let b = HalfBuffers {
                        g_hi: vec![0.0; n],
                        tmp_hi: vec![0.0; n],
                        g_edge: vec![0.0; n],
                        tmp_edge: vec![0.0; n],
                        phi_edge: vec![0.0; m],
                    };
                    (h, b)
                }),
            phi: vec![0.0; m],
            x: vec![0.0; n + m],
            stats: Index3Stats::default(),
            output_factored: false,
            border,
            correction_lengths: correction_lengths(sys),
        })
    }

    /// The system.
    pub fn system(&self) -> &System {
        self.sys
    }

    /// The Newton matrix (pattern and the values of the last assembly).
    pub fn newton_matrix(&self) -> &SaddleMatrix {
        &self.k
    }

    /// Name of the linear solver of the Newton matrix.
    pub fn solver_name(&self) -> &'static str {
        self.solver.name()
    }

    /// Counters so far.
    pub fn stats(&self) -> Index3Stats {
        let mut s = self.stats;
        s.newton_solver = self.solver.stats();
        s.mass_solver = self.psolver.stats();
        s.output_solver = self.osolver.as_ref().map(|s| s.stats()).unwrap_or_default();
        s
    }

    /// Index-3 residual, scaled (module docs):
    /// `r[..n] = s (M q̈ + Φ_qᵀ λ − g(q, q̇, t))`, `r[n..] = Φ(q, t)`.
    #[allow(clippy::too_many_arguments)]
    pub fn residual_into(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        lambda: &[f64],
        scale: f64,
        r: &mut [f64],
    ) -> Result<(), FormulationError> {
        let sys = self.sys;
        let n = self.n;
        self.stats.residuals += 1;
        // in halves only where they run on two threads: on one, the
        // one-piece evaluation does the same work without the boundary
        // pass and the per-half scans (the same bits either way)
        if self.halves.is_some()
            && crate::parallel::concurrent()
            && self.residual_in_halves(StateView { t, q, qd }, qdd, lambda, scale, r)
        {
            return Ok(());
        }
        // in one piece (systems without halves, small ones, and the
        // naming of a non-finite culprit): forces and constraint terms
        // concurrently (`join_if`; each task sequential inside, so the
        // bits do not depend on the thread count); errors in the order:
        // state, g, Φ_q, residual
        let (g, tmp, jac) = (&mut self.g, &mut self.tmp, &mut self.jac);
        let (r_dyn, r_phi) = r.split_at_mut(n);
        let par = n >= PARALLEL_MIN_COORDS;
        // a non-finite g or Φ_qᵀλ makes r non-finite: each part of r is
        // scanned where it is computed, and the parts only on failure, to
        // name the first culprit
        let (ra, phi_finite) = join_if(
            par,
            || {
                finite_state(t, q, qd)?;
                sys.forces_into(t, q, qd, g);
                Ok(())
            },
            || {
                sys.phi_and_jacobian_tmul(q, t, lambda, r_phi, tmp, jac);
                crate::numeric::first_non_finite(r_phi).is_none()
            },
        );
        ra?;
        let mass = sys.mass_diagonal();
        let (g, tmp) = (&self.g, &self.tmp);
        let half = n / 2;
        let fill = |r: &mut [f64], base: usize| fill_dynamic(r, base, scale, mass, qdd, tmp, g);
        let (r_lo, r_hi) = r_dyn.split_at_mut(half);
        let (lo_finite, hi_finite) = join_if(par, || fill(r_lo, 0), || fill(r_hi, half));
        if phi_finite && lo_finite && hi_finite {
            return Ok(());
        }
        all_finite(
            t,
            &[
                ("the forces g", &self.g),
                ("the constraint forces Φ_qᵀλ", &self.tmp),
                ("the index-3 residual (M q̈ + Φ_qᵀ λ − g, Φ)", r),
            ],
        )
    }

    /// [`Index3::residual_into`] in two halves by bodies, concurrently
    /// ([`System::residual_halves`]): the boundary's sums first
    /// ([`System::residual_boundary`]), then each half checks its part of
    /// the state, evaluates its forces and constraint terms into its own
    /// buffers (the high half takes the boundary's entries) and fills its
    /// part of the residual; the two parts of `Φ` are the halves' rows. Returns false,
    /// leaving the work to the caller's one-piece evaluation (which names
    /// the culprit), when anything is not finite — or, for good, when the
    /// constraint kernels cannot evaluate a range of joints.
    fn residual_in_halves(
        &mut self,
        StateView { t, q, qd }: StateView<'_>,
        qdd: &[f64],
        lambda: &[f64],
        scale: f64,
        r: &mut [f64],
    ) -> bool {
        let (sys, n) = (self.sys, self.n);
        let Some((h, b)) = &mut self.halves else {
            return false;
        };
        let HalfBuffers {
            g_hi,
            tmp_hi,
            g_edge,
            tmp_edge,
            phi_edge,
        } = b;
        let (g_lo, tmp_lo) = (&mut self.g, &mut self.tmp);
        let split = h.split();
        // the boundary's sums first (a few pieces, here): the high half
        // takes them before it fills its rows
        if !sys.residual_boundary(h, t, q, qd, lambda, g_edge, phi_edge, tmp_edge) {
            self.halves = None;
            return false;
        }
        let (g_edge, tmp_edge) = (&*g_edge, &*tmp_edge);
        // Φ's rows in the halves' runs (at most `ResidualHalves::MAX_RUNS`)
        let (r_dyn, mut r_phi) = r.split_at_mut(n);
        let mut phis: [[&mut [f64]; ResidualHalves::MAX_RUNS]; 2] = Default::default();
        let mut count = [0; 2];
        for (high, rows) in h.row_runs() {
            let (run, rest) = std::mem::take(&mut r_phi).split_at_mut(rows.len());
            r_phi = rest;
            let side = usize::from(high);
            phis[side][count[side]] = run;
            count[side] += 1;
        }
        let [phi_lo, phi_hi] = &mut phis;
        let (phi_lo, phi_hi) = (&mut phi_lo[..count[0]], &mut phi_hi[..count[1]]);
        let (r_lo, r_hi) = r_dyn.split_at_mut(split);
        let finite = |x: &[f64]| crate::numeric::first_non_finite(x).is_none();
        let mass = sys.mass_diagonal();
        let h = &*h;
        // one half: its state checked, its forces and constraint terms, the
        // boundary's sums (high half), its rows filled; None: the kernels
        // cannot evaluate a range of joints
        let x = StateView { t, q, qd };
        let half = |high: bool,
                    g: &mut [f64],
                    phi: &mut [&mut [f64]],
                    tmp: &mut [f64],
                    r: &mut [f64],
                    trig: Option<BodyTrig<'_>>| {
            let c = if high { split..n } else { 0..split };
            if !(finite(&q[c.clone()]) && finite(&qd[c.clone()])) {
                return Some(false);
            }
            if !sys.residual_half(h, high, x, lambda, g, phi, tmp, trig) {
                return None;
            }
            if high {
                for &k in h.boundary() {
                    g[k] = g_edge[k];
                    tmp[k] = tmp_edge[k];
                }
            }
            let rows = fill_dynamic(r, c.start, scale, mass, qdd, tmp, g);
            Some(rows && phi.iter().all(|p| finite(p)))
        };
        // each half's result (Some(false): not finite; None: the kernels
        // cannot evaluate a range of joints), and the halves' shared work
        // (the sines and cosines of their bodies) in the same hand-over
        let (mut lo, mut hi) = (None, None);
        sys.in_residual_halves(
            h,
            q,
            t,
            &mut |trig| lo = half(false, g_lo, phi_lo, tmp_lo, r_lo, trig),
            &mut |trig| hi = half(true, g_hi, phi_hi, tmp_hi, r_hi, trig),
        );
        match (lo, hi) {
            (Some(true), Some(true)) => true,
            (None, _) | (_, None) => {
                self.halves = None;
                false
            }
            _ => false,
        }
    }

    /// Assemble the scaled Newton matrix at `(t, q, q̇, λ)`:
    /// `A = c_m M − c_c ∂g/∂q̇ − c_k ∂g/∂q + c_k (Φ_qᵀ λ)_q` (with the force
    /// Jacobians' reciprocal part for the symmetric solvers, module docs),
    /// Jacobian block `Φ_q(q, t)`,
    /// multiplier block 0 — and factorise it.
    #[allow(clippy::too_many_arguments)]
    pub fn assemble_and_factorize(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lambda: &[f64],
        c_m: f64,
        c_c: f64,
        c_k: f64,
    ) -> Result<(), FormulationError> {
        let sys = self.sys;
        self.stats.jacobians += 1;
        finite_state(t, q, qd)?;
        // the A block and Φ_q, in two halves of the values for large n
        self.blocks.assemble_with_jacobian(
            sys,
            &mut self.k,
            StateView { t, q, qd },
            lambda,
            [c_m, c_c, c_k],
            &mut self.jac,
        )?;
        self.solver.factorize(&self.k).map_err(linear_at(t))?;
        if let Some(b) = &mut self.border {
            let c = [c_m, c_c, c_k];
            b.factorize(sys, &self.blocks, c, &mut *self.solver, &self.k)
                .map_err(linear_at(t))?;
        }
        Ok(())
    }

    /// Overwrite `rhs` (length `n + m`) with `K⁻¹ rhs` using the last
    /// factorisation of the Newton matrix.
    pub fn solve_newton(&mut self, t: f64, rhs: &mut [f64]) -> Result<(), FormulationError> {
        match &mut self.border {
            Some(b) => b.solve(&mut *self.solver, &self.k, rhs),
            None => self.solver.solve_in_place(&self.k, rhs),
        }
        .map_err(linear_at(t))
    }

    /// The mass saddle matrix `[M, Φ_qᵀ; Φ_q, 0]` at `q` into `kp`.
    fn load_mass(&mut self, t: f64, q: &[f64]) -> Result<(), FormulationError> {
        self.sys.jacobian_values(q, t, &mut self.jac);
        all_finite(t, &[("the constraint Jacobian Φ_q", &self.jac)])?;
        self.kp.set_a_diagonal(self.sys.mass_diagonal());
        self.kp.set_jacobian(&self.jac);
        Ok(())
    }

    /// Factorise the mass saddle matrix at `q` with `psolver`.
    fn factor_mass(&mut self, t: f64, q: &[f64]) -> Result<(), FormulationError> {
        self.load_mass(t, q)?;
        self.psolver.factorize(&self.kp).map_err(linear_at(t))?;
        Ok(())
    }

    /// Factorise the mass saddle matrix at the output row `q` with `osolver`.
    fn factor_output(&mut self, t: f64, q: &[f64]) -> Result<(), FormulationError> {
        self.load_mass(t, q)?;
        self.output_factored = false;
        let solver = match &mut self.osolver {
            Some(s) => s,
            None => {
                let opts = SolverOptions {
                    residual_check: false,
                };
                let mut s = solver_for(self.mass_kind, self.n + self.m, opts);
                s.analyze(&self.kp).map_err(linear_at(t))?;
                self.osolver.insert(s)
            }
        };
        solver.factorize(&self.kp).map_err(linear_at(t))?;
        self.output_factored = true;
        Ok(())
    }

    /// Consistent accelerations and multipliers at `(t, q, q̇)`:
    /// `M q̈ + Φ_qᵀ λ = g`, `Φ_q q̈ = γ` (eq. (5), no Baumgarte terms).
    pub fn accelerations(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        qdd: &mut [f64],
        lambda: &mut [f64],
    ) -> Result<(), FormulationError> {
        finite_state(t, q, qd)?;
        let n = self.n;
        self.factor_mass(t, q)?;
        self.sys.forces_into(t, q, qd, &mut self.g);
        self.x[..n].copy_from_slice(&self.g);
        self.sys.gamma(q, qd, t, &mut self.x[n..]);
        all_finite(
            t,
            &[
                ("the forces g", &self.x[..n]),
                ("γ (the right-hand side of Φ_q q̈ = γ)", &self.x[n..]),
            ],
        )?;
        self.psolver
            .solve_in_place(&self.kp, &mut self.x)
            .map_err(linear_at(t))?;
        qdd.copy_from_slice(&self.x[..n]);
        lambda.copy_from_slice(&self.x[n..]);
        Ok(())
    }

    /// Move an inconsistent initial state onto the constraint manifold
    /// (`initial.rs`: [`Index3::project`]
    /// repeated to [`super::START_TOL`]); a consistent state is left
    /// untouched, bit for bit. [`FormulationError::Initial`] when there is
    /// no consistent configuration nearby.
    pub fn consistent_start(
        &mut self,
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<super::StartCorrection, FormulationError> {
        let sys = self.sys;
        super::initial::index3_consistent_start(sys, self, t, q, qd)
    }

    /// Mass-weighted projection onto the constraint manifold: one Newton
    /// step `min ‖Δq‖_M` s.t. `Φ_q Δq = −Φ(q, t)` on the positions, then
    /// `min ‖Δq̇‖_M` s.t. `Φ_q Δq̇ = −(Φ_q q̇ + Φ_t)` on the velocities (with
    /// the same factorisation, Φ_q at the corrected q on the right-hand side).
    pub fn project(
        &mut self,
        t: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<(), FormulationError> {
        let n = self.n;
        let lin = linear_at(t);
        self.stats.projections += 1;
        self.factor_mass(t, q)?;
        // positions
        self.sys.phi(q, t, &mut self.phi);
        all_finite(t, &[("the constraints Φ", &self.phi)])?;
        mass_orthogonal_step(&mut *self.psolver, &self.kp, &self.phi, &mut self.x, q)
            .map_err(lin)?;
        // velocities
        self.sys.jacobian_values(q, t, &mut self.jac);
        self.sys.jacobian_mul(&self.jac, qd, &mut self.phi);
        self.sys.phi_t(q, t, &mut self.x[n..]);
        for (p, pt) in self.phi.iter_mut().zip(&self.x[n..]) {
            *p += pt;
        }
        mass_orthogonal_step(&mut *self.psolver, &self.kp, &self.phi, &mut self.x, qd)
            .map_err(lin)?;
        Ok(())
    }
}

/// The state must be finite: else [`FormulationError::Invalid`] naming
/// the component ([`super::non_finite_state`]).
fn finite_state(t: f64, q: &[f64], qd: &[f64]) -> Result<(), FormulationError> {
    match super::non_finite_state(q, qd) {
        None => Ok(()),
        Some(c) => Err(FormulationError::Invalid(format!(
            "at t = {t}: state component {c} is not finite"
        ))),
    }
}

/// The lengths of [`SecondOrderDae::correction_lengths`]: 1 for every
/// coordinate but a body's angle (coordinate `3i + 2` of body `i`), which
/// gets the body's radius of gyration `√(I/m)` (1 where that is not a
/// positive finite number).
fn correction_lengths(sys: &System) -> Vec<f64> {
    let mut l = vec![1.0; sys.n_coords()];
    for (i, b) in sys.bodies().iter().enumerate() {
        let rho = (b.inertia / b.mass).sqrt();
        if rho.is_finite() && rho > 0.0 {
            l[3 * i + 2] = rho;
        }
    }
    l
}

/// [`Index3`] is the multibody instance of the integrator's abstract
/// second-order DAE ([`SecondOrderDae`]), so `integrate` stays free of
/// multibody types.
impl SecondOrderDae for Index3<'_> {
    fn n(&self) -> usize {
        self.n
    }
    fn m(&self) -> usize {
        self.m
    }
    fn mass_diagonal(&self) -> &[f64] {
        self.sys.mass_diagonal()
    }
    fn correction_lengths(&self) -> Option<&[f64]> {
        Some(&self.correction_lengths)
    }
    fn accelerations(&mut self, x: StateView<'_>, qdd: &mut [f64], lam: &mut [f64]) -> DaeResult {
        Index3::accelerations(self, x.t, x.q, x.qd, qdd, lam).map_err(SystemError::new)
    }
    fn residual(
        &mut self,
        StateView { t, q, qd }: StateView<'_>,
        qdd: &[f64],
        lambda: &[f64],
        scale: f64,
        r: &mut [f64],
    ) -> Result<(), SystemError> {
        self.residual_into(t, q, qd, qdd, lambda, scale, r)
            .map_err(SystemError::new)
    }
    fn constraints(&mut self, t: f64, q: &[f64], phi: &mut [f64]) {
        self.sys.phi(q, t, phi);
    }
    fn factorize(&mut self, x: StateView<'_>, lambda: &[f64], c: [f64; 3]) -> DaeResult {
        let StateView { t, q, qd } = x;
        self.assemble_and_factorize(t, q, qd, lambda, c[0], c[1], c[2])
            .map_err(SystemError::new)
    }
    fn solve(&mut self, t: f64, rhs: &mut [f64]) -> Result<(), SystemError> {
        self.solve_newton(t, rhs).map_err(SystemError::new)
    }
    fn project(&mut self, t: f64, q: &mut [f64], qd: &mut [f64]) -> Result<(), SystemError> {
        Index3::project(self, t, q, qd).map_err(SystemError::new)
    }
    /// The earliest [`crate::model::ForceElement::onset_within`] of the
    /// system's force elements.
    fn onset_within(&mut self, x: StateView<'_>, horizon: f64) -> Option<f64> {
        let StateView { t, q, qd } = x;
        self.sys
            .forces()
            .iter()
            .filter_map(|f| f.onset_within(t, q, qd, horizon))
            .reduce(f64::min)
    }
    /// The position step of [`Index3::project`] until
    /// `‖Φ‖∞ ≤ 64 ε max(1, ‖q‖∞)`: a simplified Newton with the mass
    /// saddle matrix `[M, Φ_qᵀ; Φ_q, 0]` last factorised at a nearby
    /// output row (at the first row: at it), refactorised at the
    /// interpolated `q` when the violation does not fall fourfold per
    /// correction or after `OUTPUT_PROJECTION_ITERATIONS` corrections. The
    /// velocities are left as given (their constraint violation is the
    /// method's, as at its steps). The projection has its own factorisation,
    /// neither the Newton matrix's nor that of [`Index3::project`], and its
    /// solves have no residual check: `‖Φ‖` accepts its corrections.
    fn project_output(&mut self, t: f64, q: &mut [f64]) -> Result<bool, SystemError> {
        let norm = crate::numeric::max_abs;
        let err = SystemError::new;
        let tol = 64.0 * f64::EPSILON * norm(q).max(1.0);
        self.sys.phi(q, t, &mut self.phi);
        all_finite(t, &[("the constraints Φ", &self.phi)]).map_err(err)?;
        let first = norm(&self.phi);
        if first <= tol {
            return Ok(true);
        }
        let interpolated = q.to_vec();
        let out = self.correct_output(t, q, &interpolated, first, tol);
        if out.is_err() {
            q.copy_from_slice(&interpolated);
        }
        out.map_err(err)
    }
}

impl Index3<'_> {
    /// [`SecondOrderDae::project_output`]'s corrections of `q` (at first
    /// the `interpolated` row, whose violation is `first > tol`).
    fn correct_output(
        &mut self,
        t: f64,
        q: &mut [f64],
        interpolated: &[f64],
        first: f64,
        tol: f64,
    ) -> Result<bool, FormulationError> {
        let norm = crate::numeric::max_abs;
        let mut fresh = !self.output_factored;
        if fresh {
            self.factor_output(t, q)?;
        }
        let (mut res, mut it) = (first, 0);
        loop {
            let Some(solver) = self.osolver.as_deref_mut() else {
                return Err(FormulationError::Invalid(
                    "the output projection has no factorisation".into(),
                ));
            };
            mass_orthogonal_step(solver, &self.kp, &self.phi, &mut self.x, q)
                .map_err(linear_at(t))?;
            self.sys.phi(q, t, &mut self.phi);
            let now = norm(&self.phi);
            it += 1;
            if now <= tol {
                return Ok(true);
            }
            if now.is_finite() && now <= 0.25 * res && it < OUTPUT_PROJECTION_ITERATIONS {
                res = now;
                continue;
            }
            if fresh {
                if now <= first {
                    // the fresh matrix's corrections stall at rounding:
                    // the row stays where they got it
                    return Ok(true);
                }
                return Err(FormulationError::Invalid(format!(
                    "the projection of an output row at t = {t} diverged (‖Φ‖∞ {first:.3e} → \
                     {now:.3e})",
                    t = Time(t)
                )));
            }
            q.copy_from_slice(interpolated);
            self.factor_output(t, q)?;
            self.sys.phi(q, t, &mut self.phi);
            (fresh, res, it) = (true, first, 0);
        }
    }
}

/// Most position corrections of one interpolated output row with one
/// factorisation ([`SecondOrderDae::project_output`]): with the matrix at
/// the row each multiplies the violation by `O(ε)` for an interpolation
/// error ε, so rounding is reached in two or three.
const OUTPUT_PROJECTION_ITERATIONS: usize = 6;

/// The dynamic rows `base ..` of the index-3 residual into `r`:
/// `r_i = s (M_k q̈_k + (Φ_qᵀλ)_k − g_k)`, `k = base + i`; whether every
/// entry is finite.
fn fill_dynamic(
    r: &mut [f64],
    base: usize,
    scale: f64,
    mass: &[f64],
    qdd: &[f64],
    tmp: &[f64],
    g: &[f64],
) -> bool {
    // the inputs cut to r's rows: no bounds checks, vectorised
    let rows = base..base + r.len();
    let (mass, qdd, tmp, g) = (
        &mass[rows.clone()],
        &qdd[rows.clone()],
        &tmp[rows.clone()],
        &g[rows],
    );
    for k in 0..r.len() {
        r[k] = scale * (mass[k] * qdd[k] + tmp[k] - g[k]);
    }
    crate::numeric::first_non_finite(r).is_none()
}
