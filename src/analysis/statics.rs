//! Static equilibrium: Newton's method on
//!
//! ```text
//! F(q, λ) = g(q, 0, t₀) − Φ_qᵀ(q, t₀) λ = 0,      Φ(q, t₀) = 0
//! ```
//!
//! (velocity-dependent forces at q̇ = 0; our λ, see [`super::tangent`]),
//! with the exact Newton matrix `[K Φ_qᵀ; Φ_q 0]` of [`Tangent`]
//! (`K = −∂g/∂q + (Φ_qᵀλ)_q`) factorised by an LU with partial pivoting
//! ([`crate::linalg::ChainLu`]: in the band of the body-by-body order for
//! a chain, linear in N; faer's sparse LU otherwise — exact for
//! unsymmetric `K`, and `K` may be singular on coordinates held only by the
//! constraints).
//!
//! **Load stepping.** Large deflections are reached by continuation in a
//! load factor μ ∈ [0, 1] (Newton homotopy):
//! `F_μ(q, λ) = F(q, λ) − (1 − μ) F(q₀, λ₀)`, λ₀ the multipliers of the
//! start at rest (`M q̈ + Φ_qᵀλ₀ = g`, `Φ_q q̈ = γ`). At μ = 0 the start
//! `(q₀, λ₀)` solves it; at μ = 1 it is the equilibrium. When the start is
//! the unloaded configuration (springs at rest) `F(q₀, λ₀)` is the applied
//! load less what the constraints carry, so μ scales the loads (classical
//! load stepping). The first step tries
//! μ = 1; a step whose Newton iteration fails is cut by 4, a step that
//! converges lets the next one double; below [`StaticOptions::min_load_step`]
//! the search stops with [`StaticError::NoEquilibrium`] (the load factor
//! reached and the residual).
//!
//! **Redundant constraints.** Rows of `Φ_q` that the sparse coordinate
//! partitioning ([`super::partitioning::partition`]) eliminates to zero at
//! the start (a parallelogram's extra coupler pin) are left out of the
//! Newton matrix, which is then nonsingular; `Φ = 0` of those rows follows
//! from the others and is still checked by the convergence test. Their λ
//! are 0: with rigid bodies the split of the reactions among redundant
//! joints is statically indeterminate, and this is the particular solution
//! in which the rows the partitioning keeps carry all of it
//! ([`Equilibrium::redundant`] lists the rows left out). With the chain
//! LU the partitioning runs only when the band LU of `[s I, Φ_qᵀ; Φ_q, 0]`
//! at the start does not show full row rank (`NewtonMatrix::shows_full_rank`):
//! a chain without redundant joints skips it.
//!
//! **Controller states** ([`crate::model::State`], `ż = f(t, q, q̇, z)`,
//! held as the velocity of a coordinate w of unit mass after the bodies'):
//! the unknowns are the bodies' q, the states' values z and λ; the
//! equations add `f(t₀, q, 0, z) = 0` (the generalized force on w) to the
//! balance, which is evaluated at `q̇ = (0, z)`. The coordinate w itself
//! is not an unknown (nothing reads it; it keeps its start value). The
//! Newton matrix is `[K̃ Φ_qᵀ; Φ_q 0]`, `K̃` the columns of `K` of the
//! bodies' coordinates and the columns of `C = −∂g/∂q̇` of the states
//! (`−∂(g, f)/∂z`), exact from the same symbolic Jacobians. The rates
//! `f` share the force residual's relative tolerance. A state whose rate
//! is not zero and does not depend on q or z at the start (`ż = 1`) is an
//! error naming it; a failed search lists every state's rate where it
//! stopped. The stability of such an equilibrium is that of the
//! first-order system (the eigenvalues of its linearisation,
//! [`super::linearize`]), not [`super::stability::stability`]'s, which is about the
//! mechanism alone.
//!
//! The stability of an equilibrium (the inertia of the constrained
//! stiffness) is [`mod@super::stability`]'s.

use super::tangent::Tangent;
use crate::formulation::FormulationError;
use crate::linalg::{SolverKind, Storage};
use crate::model::System;
use serde::Serialize;

/// Options of [`static_equilibrium`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticOptions {
    /// Time t₀ at which forces and constraints are evaluated \[s\]
    /// (default 0).
    pub t0: f64,
    /// Relative tolerance: converged when `‖F‖∞ ≤ tol · F_ref` (F_ref the
    /// largest of `‖g‖∞`, `‖Φ_qᵀλ‖∞` seen, and of the start's load) and
    /// `‖Φ‖∞ ≤ tol · (1 + ‖q‖∞)` (default 1e-10) — or when the last
    /// Newton correction was below 1e-13 (1 + ‖q‖∞) with `‖F‖∞ ≤ 1e-6 F_ref`
    /// and `‖Φ‖∞ ≤ 1e-10 (1 + ‖q‖∞)` (the rounding floor of stiff springs).
    pub tol: f64,
    /// Newton iterations per load step (default 30).
    pub max_iter: usize,
    /// Largest number of load steps, failed ones included (default 200).
    pub max_load_steps: usize,
    /// Smallest load-factor increment before giving up (default 1e-6).
    pub min_load_step: f64,
    /// Solver of the Newton matrix: [`SolverKind::ChainLu`] (default: the
    /// band LU in the body-by-body order, faer's sparse LU for other
    /// patterns) or [`SolverKind::SparseLu`]; the symmetric solvers are
    /// rejected (`K` can be unsymmetric).
    pub linear_solver: SolverKind,
}

impl Default for StaticOptions {
    fn default() -> Self {
        Self {
            t0: 0.0,
            tol: 1e-10,
            max_iter: 30,
            max_load_steps: 200,
            min_load_step: 1e-6,
            linear_solver: SolverKind::ChainLu,
        }
    }
}

/// A static equilibrium found by [`static_equilibrium`].
#[derive(Debug, Clone, Serialize)]
pub struct Equilibrium {
    /// Positions \[m, rad\].
    pub q: Vec<f64>,
    /// Multipliers (our sign: `Φ_qᵀλ = g` at equilibrium).
    pub lambda: Vec<f64>,
    /// The controller states' values z at equilibrium, in
    /// [`System::states`] order (units of each state; empty without
    /// states). The velocities of the equilibrium are `q̇ = (0, z)`
    /// ([`Equilibrium::velocities`]).
    pub states: Vec<f64>,
    /// Load steps taken (accepted and cut).
    pub load_steps: usize,
    /// Newton iterations over all load steps.
    pub iterations: usize,
    /// `‖g − Φ_qᵀλ‖∞` at the solution \[N, N m\].
    pub residual: f64,
    /// `‖Φ‖∞` at the solution.
    pub constraint_residual: f64,
    /// Constraint rows left out as redundant (module docs), ascending;
    /// their λ are 0. Empty when Φ_q has full row rank at the start.
    pub redundant: Vec<usize>,
    /// The Newton matrix's factorisations (solver, count, fallbacks).
    pub factorizations: super::Factorizations,
}

impl Equilibrium {
    /// The velocities of the equilibrium: 0 for the bodies' coordinates,
    /// z for the states' (what a state file's `qd` holds).
    pub fn velocities(&self) -> Vec<f64> {
        let nb = self.q.len() - self.states.len();
        let mut qd = vec![0.0; self.q.len()];
        qd[nb..].copy_from_slice(&self.states);
        qd
    }
}

/// Why no equilibrium was found.
#[derive(Debug, thiserror::Error)]
pub enum StaticError {
    /// The load stepping could not reach μ = 1.
    #[error(
        "no static equilibrium found: load factor reached {load_factor:.6} of 1 ({reason}); \
         at the last attempt ‖g − Φ_qᵀλ‖∞ = {residual:.3e}, ‖Φ‖∞ = {constraint_residual:.3e} \
         after {iterations} Newton iterations in {load_steps} load steps"
    )]
    NoEquilibrium {
        /// The largest load factor at which an equilibrium was found.
        load_factor: f64,
        /// Force residual of the last failed attempt.
        residual: f64,
        /// Constraint residual of the last failed attempt.
        constraint_residual: f64,
        /// Newton iterations in total.
        iterations: usize,
        /// Load steps in total.
        load_steps: usize,
        /// What stopped the search.
        reason: String,
    },
    /// An evaluation or a linear solve failed.
    #[error(transparent)]
    Formulation(#[from] FormulationError),
}

/// Residual buffers of the Newton iteration.
struct Work {
    g: Vec<f64>,
    jac: Vec<f64>,
    ct: Vec<f64>,
    phi: Vec<f64>,
    /// Velocities of the evaluation: 0 for bodies, z for states.
    qd: Vec<f64>,
}

impl Work {
    /// `F = g(q, (0, z)) − Φ_qᵀλ − (1 − μ) F₀` into `f` (z: `self.qd`'s
    /// state entries), Φ into `self.phi`;
    /// returns (‖F‖∞, ‖Φ‖∞, max(‖g‖∞, ‖Φ_qᵀλ‖∞)).
    #[allow(clippy::too_many_arguments)]
    fn residual(
        &mut self,
        sys: &System,
        t: f64,
        q: &[f64],
        lam: &[f64],
        mu: f64,
        f0: &[f64],
        f: &mut [f64],
    ) -> (f64, f64, f64) {
        sys.forces_into(t, q, &self.qd, &mut self.g);
        sys.jacobian_values(q, t, &mut self.jac);
        sys.jacobian_tmul(&self.jac, lam, &mut self.ct);
        sys.phi(q, t, &mut self.phi);
        let (mut nf, mut scale) = (0.0f64, 0.0f64);
        for i in 0..f.len() {
            f[i] = self.g[i] - self.ct[i] - (1.0 - mu) * f0[i];
            nf = nf.max(f[i].abs());
            scale = scale.max(self.g[i].abs()).max(self.ct[i].abs());
        }
        let np = self.phi.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        // NaN compares false: make a non-finite residual infinite
        let fix = |v: f64| if v.is_finite() { v } else { f64::INFINITY };
        (fix(nf), fix(np), scale)
    }
}

/// The static equilibrium of `sys` from `q0` (module docs): load stepping
/// and Newton. `q0` need not satisfy the constraints exactly. Controller
/// states start from their `initial` values
/// ([`static_equilibrium_from`] takes others).
pub fn static_equilibrium(
    sys: &System,
    q0: &[f64],
    opts: StaticOptions,
) -> Result<Equilibrium, StaticError> {
    let z0: Vec<f64> = sys.states().iter().map(|s| s.initial).collect();
    static_equilibrium_from(sys, q0, &z0, opts)
}

/// [`static_equilibrium`] from positions `q0` and controller-state values
/// `z0` (one per [`System::states`], in that order; e.g. the velocities of
/// the states' coordinates in a state file).
pub fn static_equilibrium_from(
    sys: &System,
    q0: &[f64],
    z0: &[f64],
    opts: StaticOptions,
) -> Result<Equilibrium, StaticError> {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let nb = sys.n_body_coords();
    let t = opts.t0;
    if q0.len() != n {
        return Err(FormulationError::Invalid(format!(
            "static equilibrium: q0 has {} entries, the system {n} coordinates",
            q0.len()
        ))
        .into());
    }
    if z0.len() != n - nb {
        return Err(FormulationError::Invalid(format!(
            "static equilibrium: {} controller-state values for {} states",
            z0.len(),
            n - nb
        ))
        .into());
    }
    // q̇ of every evaluation: 0 for the bodies, z for the states
    let mut qd0 = vec![0.0; n];
    qd0[nb..].copy_from_slice(z0);
    let mut w = Work {
        g: vec![0.0; n],
        jac: vec![0.0; sys.jacobian_pattern().len()],
        ct: vec![0.0; n],
        phi: vec![0.0; m],
        qd: qd0.clone(),
    };
    let mut tan = Tangent::new(sys);
    let zero = qd0.clone();
    // the rows kept in the Newton matrix: all but the redundant ones at q₀
    // (the partitioning decides, unless the band LU shows full rank first:
    // NewtonMatrix::shows_full_rank)
    let evaluated = m > 0 && tan.evaluate(t, q0, &zero, &vec![0.0; m]).is_ok();
    let mut nm = NewtonMatrix::new(sys, &tan, (0..m).collect(), opts)?;
    let mut redundant = Vec::new();
    if evaluated && !nm.shows_full_rank(&tan) {
        let phi = tan.constraint_jacobian();
        redundant = super::partitioning::partition(
            phi.rows,
            phi.cols,
            &phi.entries,
            super::inverse::RANK_TOL,
        )
        .redundant;
        if !redundant.is_empty() {
            let kept = (0..m)
                .filter(|r| redundant.binary_search(r).is_err())
                .collect();
            nm = NewtonMatrix::new(sys, &tan, kept, opts)?;
        }
    }
    let lam0 = match evaluated {
        true => nm.lambda0(sys, &tan, t, q0, &zero),
        false => None,
    };
    // 0 when the λ₀ solve fails (the iteration finds λ)
    let lam0 = lam0.unwrap_or_else(|| vec![0.0; m]);
    let mk = nm.kept.len();
    // F₀ = F(q₀, λ₀): the start's unbalanced load
    let mut f0 = vec![0.0; n];
    let zero_n = vec![0.0; n];
    let (_, _, scale0) = w.residual(sys, t, q0, &lam0, 1.0, &zero_n, &mut f0);
    let f_ref0 = f0.iter().fold(scale0, |a, v| a.max(v.abs()));
    if !f_ref0.is_finite() {
        return Err(FormulationError::Invalid(
            "static equilibrium: the forces at the start are not finite".into(),
        )
        .into());
    }
    // a state whose rate is not zero and depends on nothing the iteration
    // moves (ż = 1) has no equilibrium
    if let Some(s) = &nm.states {
        tan.evaluate(t, q0, &qd0, &lam0)?;
        for (k, st) in sys.states().iter().enumerate() {
            let rate = f0[nb + k];
            if rate != 0.0 && !s.row_depends(&tan, nb + k) {
                return Err(StaticError::NoEquilibrium {
                    load_factor: 0.0,
                    residual: rate.abs(),
                    constraint_residual: w.phi.iter().fold(0.0f64, |a, v| a.max(v.abs())),
                    iterations: 0,
                    load_steps: 0,
                    reason: format!(
                        "controller state '{}' has ż = {rate:e} at the start and ż depends on \
                         no coordinate and no state there, so no q, z make it 0",
                        st.name
                    ),
                });
            }
        }
    }
    let (mut q, mut lam) = (q0.to_vec(), lam0);
    let mut z = z0.to_vec();
    let (mut mu, mut dmu) = (0.0f64, 1.0f64);
    let (mut steps, mut iterations) = (0usize, 0usize);
    let mut f = vec![0.0; n];
    let mut x = vec![0.0; n + mk];
    let mut last = (f64::INFINITY, f64::INFINITY);
    let mut reason = String::new();
    while mu < 1.0 {
        if steps >= opts.max_load_steps {
            reason = format!("{} load steps", opts.max_load_steps);
            break;
        }
        steps += 1;
        let target = (mu + dmu).min(1.0);
        let (mut qt, mut lt, mut zt) = (q.clone(), lam.clone(), z.clone());
        w.qd[nb..].copy_from_slice(&zt);
        let mut f_ref = f_ref0;
        let mut converged = false;
        let mut first = f64::INFINITY;
        let mut last_dq = f64::INFINITY;
        let mut sizes: Vec<f64> = Vec::new();
        for it in 0..=opts.max_iter {
            let (nf, np, scale) = w.residual(sys, t, &qt, &lt, target, &f0, &mut f);
            f_ref = f_ref.max(scale);
            last = (nf, np);
            let qscale = 1.0 + qt.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            // converged: the residuals below the tolerance, or the last
            // correction at the rounding level of q (the residual's floor
            // is ε × the largest internal force, e.g. k Δφ of stiff
            // springs, which can exceed tol × the load)
            if (nf <= opts.tol * f_ref && np <= opts.tol * qscale)
                || (last_dq <= 1e-13 * qscale && nf <= 1e-6 * f_ref && np <= 1e-10 * qscale)
            {
                converged = true;
                break;
            }
            let size = nf / f_ref.max(f64::MIN_POSITIVE) + np / qscale;
            if it == 0 {
                first = size;
                sizes.clear();
            }
            // give up on this load step: iterations exhausted, divergence,
            // or stagnation (less than a halving over 4 iterations: Newton
            // converges faster where it converges at all; a smaller load
            // step is cheaper than more iterations)
            if it == opts.max_iter
                || !size.is_finite()
                || size > 1e8 * first.max(1e-300)
                || (it >= 4 && size > 0.5 * sizes[it - 4])
            {
                break;
            }
            sizes.push(size);
            iterations += 1;
            tan.evaluate(t, &qt, &w.qd, &lt)?;
            // [K Φ_qᵀ; Φ_q 0] [Δq; Δλ] = [F; −Φ]; where that is singular
            // (a direction without stiffness: a free rotation), K + εM
            // with ε from 1e-12 of the largest K_ii/M_ii up (a modified
            // Newton step, the residual stays exact)
            let mut eps = 0.0;
            let solved = loop {
                nm.write(&tan, eps, 1.0);
                if nm.solver.factorize(&nm.k).is_ok() {
                    x[..n].copy_from_slice(&f);
                    for (xi, &r) in x[n..].iter_mut().zip(&nm.kept) {
                        *xi = -w.phi[r];
                    }
                    let big = 1e8 * qscale;
                    if nm.solver.solve_in_place(&nm.k, &mut x).is_ok()
                        && x[..n].iter().all(|v| v.is_finite() && v.abs() < big)
                        && x[n..].iter().all(|v| v.is_finite())
                    {
                        break true;
                    }
                }
                let kscale = tan.stiffness_scale();
                if eps == 0.0 {
                    eps = 1e-12 * kscale;
                } else {
                    eps *= 1e3;
                }
                if !(eps > 0.0 && eps <= 1e-3 * kscale) {
                    break false;
                }
            };
            if !solved {
                break;
            }
            last_dq = x[..n].iter().fold(0.0f64, |a, v| a.max(v.abs()));
            // the states' columns are Δz (their coordinates w stay)
            for (qi, d) in qt[..nb].iter_mut().zip(&x[..nb]) {
                *qi += d;
            }
            for (zi, d) in zt.iter_mut().zip(&x[nb..n]) {
                *zi += d;
            }
            w.qd[nb..].copy_from_slice(&zt);
            for (&r, d) in nm.kept.iter().zip(&x[n..]) {
                lt[r] += d;
            }
        }
        if converged {
            mu = target;
            q = qt;
            lam = lt;
            z = zt;
            dmu = (2.0 * dmu).min(1.0);
        } else {
            dmu *= 0.25;
            if dmu < opts.min_load_step {
                reason = format!(
                    "the load step fell below {:e} without Newton converging",
                    opts.min_load_step
                );
                break;
            }
        }
    }
    w.qd[nb..].copy_from_slice(&z);
    if mu < 1.0 {
        if !z.is_empty() {
            // the states' rates where the search stopped
            let (mut g, zero_f) = (vec![0.0; n], vec![0.0; n]);
            w.residual(sys, t, &q, &lam, 1.0, &zero_f, &mut g);
            let rates: Vec<String> = sys
                .states()
                .iter()
                .enumerate()
                .map(|(k, s)| format!("{} = {:.3e}", s.name, g[nb + k]))
                .collect();
            reason = format!(
                "{reason}; controller-state rates ż at load factor 1 from the last \
                 equilibrium found: {}",
                rates.join(", ")
            );
        }
        return Err(StaticError::NoEquilibrium {
            load_factor: mu,
            residual: last.0,
            constraint_residual: last.1,
            iterations,
            load_steps: steps,
            reason,
        });
    }
    let (residual, constraint_residual, _) = w.residual(sys, t, &q, &lam, 1.0, &f0, &mut f);
    Ok(Equilibrium {
        q,
        lambda: lam,
        states: z,
        load_steps: steps,
        iterations,
        residual,
        constraint_residual,
        redundant,
        factorizations: super::Factorizations::of(&*nm.solver),
    })
}

/// The static Newton matrix `[A Φ_qᵀ; Φ_q 0]` of the kept constraint rows
/// (module docs: `A = c_m M + K`, or `K̃` with controller states) and its
/// solver, analysed once for the pattern.
struct NewtonMatrix {
    /// The constraint rows kept (ascending).
    kept: Vec<usize>,
    /// The states' columns, `None` without states.
    states: Option<StateColumns>,
    k: crate::linalg::SaddleMatrix,
    solver: Box<dyn crate::linalg::SaddlePointSolver>,
}

impl NewtonMatrix {
    fn new(
        sys: &System,
        tan: &Tangent,
        kept: Vec<usize>,
        opts: StaticOptions,
    ) -> Result<Self, StaticError> {
        let (n, mk) = (sys.n_coords(), kept.len());
        let states = StateColumns::new(sys, &kept);
        let k = match &states {
            Some(s) => s.saddle_matrix(n, mk),
            None if mk == sys.n_constraints() => tan.saddle_matrix(Storage::Full),
            None => tan.saddle_matrix_of_rows(Storage::Full, &kept),
        };
        let mut solver =
            super::full_storage_solver(opts.linear_solver, n + mk, "static equilibrium")?;
        solver
            .analyze(&k)
            .map_err(|source| FormulationError::Linear { t: opts.t0, source })?;
        Ok(Self {
            kept,
            states,
            k,
            solver,
        })
    }

    /// `A = c_m M + c_k K` (or `K̃`) and `Φ_q` of the kept rows from the
    /// last evaluation of `tan`.
    fn write(&mut self, tan: &Tangent, c_m: f64, c_k: f64) {
        match &self.states {
            Some(s) => s.write(tan, &mut self.k, c_m, c_k),
            None if self.kept.len() == tan.m() => tan.write_saddle(&mut self.k, [c_m, 0.0, c_k]),
            None => tan.write_saddle_of_rows(&mut self.k, [c_m, 0.0, c_k], &self.kept),
        }
    }

    /// Does the band LU show that `Φ_q` (of `tan`'s last evaluation) has
    /// full row rank? It factorises `[s I, Φ_qᵀ; Φ_q, 0]`, `s = max |Φ_q|`,
    /// regular exactly when `Φ_q` has full row rank: eliminating the
    /// coordinates leaves the Schur complement `−Φ_q Φ_qᵀ / s`, whose
    /// pivots are about `r_ii² / s` for `r_ii` the distance of a row from
    /// the rows before it (the `R` of `Φ_qᵀ = QR`). The band LU rejects a
    /// pivot at or below `ε s`, i.e. a row within about `√ε s` of the
    /// others, more than the partitioning's [`super::inverse::RANK_TOL`]
    /// `s`; so when it accepts, no row is redundant and the
    /// partitioning is skipped. Only [`crate::linalg::ChainLu`] on its
    /// band path answers (an accepted factorisation with no fallback);
    /// other solvers return false and the partitioning decides.
    fn shows_full_rank(&mut self, tan: &Tangent) -> bool {
        if self.solver.name() != "chain-lu" {
            return false;
        }
        let s = tan
            .jacobian_values()
            .iter()
            .fold(0.0f64, |a, v| a.max(v.abs()));
        if !(s > 0.0 && s.is_finite()) {
            return false;
        }
        self.write(tan, 0.0, 0.0);
        for i in 0..tan.n() {
            self.k.add_diagonal(i, s);
        }
        let fallbacks = self.solver.fallbacks();
        self.solver.factorize(&self.k).is_ok() && self.solver.fallbacks() == fallbacks
    }

    /// λ₀: the multipliers of the start at rest (`M q̈ + Φ_qᵀλ = g`,
    /// `Φ_q q̈ = γ`, the kept rows; the others 0), so that `K` holds the
    /// constraint forces' geometric stiffness from the first iteration on
    /// (a mechanism held only by it — a pendulum under gravity — has a
    /// singular Newton matrix at λ = 0). `tan` evaluated at `(q0, zero)`;
    /// `None` when the solve fails or is not finite.
    fn lambda0(
        &mut self,
        sys: &System,
        tan: &Tangent,
        t: f64,
        q0: &[f64],
        zero: &[f64],
    ) -> Option<Vec<f64>> {
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        // [M Φ_qᵀ; Φ_q 0] [q̈; λ₀] = [g; γ] with the Newton matrix's LU
        self.write(tan, 1.0, 0.0);
        let mut rhs = vec![0.0; n + self.kept.len()];
        let mut gamma = vec![0.0; m];
        sys.forces_into(t, q0, zero, &mut rhs[..n]);
        sys.gamma(q0, zero, t, &mut gamma);
        for (x, &r) in rhs[n..].iter_mut().zip(&self.kept) {
            *x = gamma[r];
        }
        self.solver.factorize(&self.k).ok()?;
        self.solver.solve_in_place(&self.k, &mut rhs).ok()?;
        let mut lam0 = vec![0.0; m];
        for (x, &r) in rhs[n..].iter().zip(&self.kept) {
            lam0[r] = *x;
        }
        lam0.iter().all(|v| v.is_finite()).then_some(lam0)
    }
}

/// The static Newton matrix of a system with controller states (module
/// docs): `A = c_m M + c_k K̃`, `K̃` the bodies' columns of `K` and the
/// states' columns of `C`, in full storage (entries as evaluated), and
/// `Φ_q` of the kept rows.
struct StateColumns {
    /// Positions in `Tangent::stiffness()`'s entries kept (bodies' columns).
    from_k: Vec<usize>,
    /// Positions in `Tangent::damping()`'s entries kept (states' columns).
    from_c: Vec<usize>,
    /// Each entry's `(row, column)`, `from_k` then `from_c`.
    entries: Vec<(usize, usize)>,
    /// The kept rows' pattern and its positions in the system's.
    rows: (Vec<(usize, usize)>, Vec<usize>),
}

impl StateColumns {
    /// `None` without states.
    fn new(sys: &System, kept: &[usize]) -> Option<Self> {
        let nb = sys.n_body_coords();
        if sys.states().is_empty() {
            return None;
        }
        // the order of Tangent::stiffness(): the force-Jacobian pattern,
        // then each Hessian entry and its mirror
        let mut k_pos = Vec::new();
        for &(i, j) in sys.force_jacobian_pattern() {
            k_pos.push((i, j));
        }
        for &(i, j) in sys.hessian_pattern() {
            k_pos.push((i, j));
            if i != j {
                k_pos.push((j, i));
            }
        }
        let mut out = Self {
            from_k: Vec::new(),
            from_c: Vec::new(),
            entries: Vec::new(),
            rows: (Vec::new(), Vec::new()),
        };
        for (e, &(i, j)) in k_pos.iter().enumerate() {
            if j < nb {
                out.from_k.push(e);
                out.entries.push((i, j));
            }
        }
        for (e, &(i, j)) in sys.force_jacobian_pattern().iter().enumerate() {
            if j >= nb {
                out.from_c.push(e);
                out.entries.push((i, j));
            }
        }
        let mut new_row = vec![usize::MAX; sys.n_constraints()];
        for (k, &r) in kept.iter().enumerate() {
            new_row[r] = k;
        }
        for (e, &(r, c)) in sys.jacobian_pattern().iter().enumerate() {
            if new_row[r] != usize::MAX {
                out.rows.0.push((new_row[r], c));
                out.rows.1.push(e);
            }
        }
        Some(out)
    }

    fn saddle_matrix(&self, n: usize, mk: usize) -> crate::linalg::SaddleMatrix {
        let mut a = crate::linalg::APattern::new();
        a.push_block(&self.entries, crate::linalg::Symmetry::Unsymmetric);
        crate::linalg::SaddleMatrix::with_storage(n, mk, &a, &self.rows.0, Storage::Full)
    }

    fn write(&self, tan: &Tangent, k: &mut crate::linalg::SaddleMatrix, c_m: f64, c_k: f64) {
        k.set_zero();
        for (i, &mi) in tan.mass_diagonal().iter().enumerate() {
            k.add_diagonal(i, c_m * mi);
        }
        if c_k != 0.0 {
            let (kt, ct) = (tan.stiffness(), tan.damping());
            let vals = self
                .from_k
                .iter()
                .map(|&e| kt.entries[e].2)
                .chain(self.from_c.iter().map(|&e| ct.entries[e].2));
            for (id, v) in vals.enumerate() {
                k.add_a(id, c_k * v);
            }
        }
        let jac = tan.jacobian_values();
        let vals: Vec<f64> = self.rows.1.iter().map(|&e| jac[e]).collect();
        k.set_jacobian(&vals);
    }

    /// Does row `r` of `K̃` (the last evaluation) hold a non-zero?
    fn row_depends(&self, tan: &Tangent, r: usize) -> bool {
        let (kt, ct) = (tan.stiffness(), tan.damping());
        self.from_k
            .iter()
            .map(|&e| kt.entries[e])
            .chain(self.from_c.iter().map(|&e| ct.entries[e]))
            .any(|(i, _, v)| i == r && v != 0.0)
    }
}
