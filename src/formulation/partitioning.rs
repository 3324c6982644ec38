//! Generalized coordinate partitioning (Wehage & Haug, "Generalized
//! coordinate partitioning for dimension reduction in analysis of
//! constrained dynamic systems", J. Mech. Des. 104 (1982) 247–255).
//!
//! The coordinates are split into dependent `u` (r of them, r = rank Φ_q)
//! and independent `v` (the d = n − r degrees of freedom) by Gaussian
//! elimination with complete pivoting on Φ_q ([`full_pivot_order`]): the
//! pivot columns are `u`, the pivot rows the r independent constraint
//! equations `Φ_R` (redundant rows are dropped, so redundant joints are
//! allowed). Only `y = [v; v̇]` (dimension 2d) is integrated, by ode23,
//! ode45 or rk4; at every evaluation
//!
//! ```text
//! Φ_R(u, v, t) = 0                       Newton on u (Φ_R,u Δu = −Φ_R)
//! Φ_R,u u̇ = −Φ_R,t − Φ_R,v v̇             dependent velocities
//! M q̈ + Φ_Rᵀλ = g,  Φ_R q̈ = γ_R         eq. (5) on the rows R, v̈ = q̈[v]
//! ```
//!
//! Eq. (5) is solved densely with partial pivoting and without
//! regularisation (the rows R are independent at t0): near a singular
//! configuration the regularised sparse LDLᵀ of the full system returns a
//! least-squares q̈ that took the parallelogram chain 8 mm off its branch
//! in 10 s, the exact dense solve 4.5 µm (tests/formulation/partitioning.rs).
//!
//! so positions and velocities satisfy the constraints to the Newton
//! tolerance by construction (no drift, no Baumgarte terms). The split is
//! re-chosen when the dependent block Φ_R,u becomes ill-conditioned
//! (κ₁ above [`PartitionOptions::max_condition`], checked at every
//! accepted step): the integration stops there and restarts cleanly from
//! the full state with the new split ([`Partitioned::integrate`]).
//!
//! Dense linear algebra (`O(n r²)` per evaluation): meant for mechanisms
//! of up to [`MAX_PARTITION_COORDS`] coordinates, the sizes of the
//! constraint-method study; larger systems are an error.

use super::FormulationError;
use super::{all_finite, Index1Options};
use crate::integrate::{
    integrator, Failure, Integrator, IntegratorError, Method, Observer, OdeOptions, OdeSystem,
    Report, Span, StateView, Stats, SystemError, Termination,
};
use crate::linalg::full_pivot_order;
use crate::model::System;
use crate::numeric::Time;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::lu::partial_pivoting::{factor, solve};
use faer::perm::PermRef;
use faer::{Mat, MatMut, Par};
use serde::Serialize;
use std::cell::RefCell;
use std::ops::ControlFlow;
use std::rc::Rc;

/// Largest system [`Partitioned`] accepts (dense matrices).
pub const MAX_PARTITION_COORDS: usize = 600;

/// Relative pivot threshold of the rank decision at the initial state.
const RANK_TOL: f64 = 1e-8;

/// Options of [`Partitioned`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PartitionOptions {
    /// Re-choose the split when the 1-norm condition number κ₁ of the
    /// dependent block Φ_R,u exceeds this at an accepted step.
    pub max_condition: f64,
    /// Newton tolerance on ‖Φ_R‖∞ for the dependent coordinates
    /// (constraint units, m for joints).
    pub tol: f64,
    /// Newton iterations allowed per evaluation.
    pub max_iter: usize,
}

impl Default for PartitionOptions {
    /// κ₁ ≤ 1e3, tolerance 1e-12, 20 iterations.
    fn default() -> Self {
        Self {
            max_condition: 1e3,
            tol: 1e-12,
            max_iter: 20,
        }
    }
}

/// Counters of [`Partitioned`].
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct PartitionStats {
    /// Re-choices of the independent set (restarts of the integrator).
    pub repartitions: usize,
    /// Newton iterations for the dependent coordinates, summed.
    pub newton_iterations: usize,
    /// Largest κ₁ of the dependent block seen at an accepted step.
    pub max_condition: f64,
    /// Time of the first re-choice.
    pub first_repartition_t: Option<f64>,
}

/// Dense LU with partial pivoting in buffers kept between factorisations
/// (faer's in-place kernels): no allocation per evaluation.
struct LuBuf {
    a: Mat<f64>,
    fwd: Vec<usize>,
    bwd: Vec<usize>,
    mem: MemBuffer,
}

impl LuBuf {
    fn new(dim: usize) -> Self {
        let req = StackReq::any_of(&[
            factor::lu_in_place_scratch::<usize, f64>(dim, dim, Par::Seq, Default::default()),
            solve::solve_in_place_scratch::<usize, f64>(dim, 1, Par::Seq),
        ]);
        Self {
            a: Mat::zeros(dim, dim),
            fwd: vec![0; dim],
            bwd: vec![0; dim],
            mem: MemBuffer::new(req),
        }
    }

    /// Factor the matrix `a(i, j) = f(i, j)` (partial pivoting).
    fn factor(&mut self, f: impl Fn(usize, usize) -> f64) {
        let dim = self.a.nrows();
        for j in 0..dim {
            for i in 0..dim {
                self.a[(i, j)] = f(i, j);
            }
        }
        factor::lu_in_place(
            self.a.as_mut(),
            &mut self.fwd,
            &mut self.bwd,
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
    }

    /// Solve with the last factorisation, in place.
    fn solve(&mut self, x: &mut [f64]) {
        let dim = self.a.nrows();
        // SAFETY: `fwd` and `bwd` are the mutually inverse permutations
        // written by `lu_in_place` on a matrix of this dimension
        let perm = unsafe { PermRef::new_unchecked(&self.fwd, &self.bwd, dim) };
        solve::solve_in_place(
            self.a.as_ref(),
            self.a.as_ref(),
            perm,
            MatMut::from_column_major_slice_mut(x, dim, 1),
            Par::Seq,
            MemStack::new(&mut self.mem),
        );
    }
}

impl Clone for LuBuf {
    fn clone(&self) -> Self {
        Self::new(self.a.nrows())
    }
}

/// The full states `(t, q, q̇)` of the last two accepted steps (`[0]` the
/// earlier), written by [`Partitioned`]'s `post_step` and read by the
/// observer of the run: the predictor of the dependent coordinates at an
/// output between them is the cubic Hermite interpolant of the two, so an
/// output next to a singular configuration lands on the branch of the
/// steps around it (a one-sided predictor put one output of the two-loop
/// chain on the other branch, 7.3 mm off).
#[derive(Default)]
struct Accepted {
    t: [f64; 2],
    q: [Vec<f64>; 2],
    qd: [Vec<f64>; 2],
}

impl Accepted {
    fn push(&mut self, t: f64, q: &[f64], qd: &[f64]) {
        self.t.swap(0, 1);
        self.q.swap(0, 1);
        self.qd.swap(0, 1);
        self.t[1] = t;
        self.q[1].clear();
        self.q[1].extend_from_slice(q);
        self.qd[1].clear();
        self.qd[1].extend_from_slice(qd);
    }

    fn reset(&mut self, t: f64, q: &[f64], qd: &[f64]) {
        self.push(t, q, qd);
        self.push(t, q, qd);
    }

    /// The cubic Hermite interpolant of the two states at `t` into `q[k]`,
    /// `k ∈ dep` (the nearer state when they coincide in time).
    fn predict(&self, t: f64, dep: &[usize], q: &mut [f64]) {
        let h = self.t[1] - self.t[0];
        if h <= 0.0 || self.q[0].len() != q.len() {
            for &k in dep {
                q[k] = self.q[1][k] + self.qd[1][k] * (t - self.t[1]);
            }
            return;
        }
        let s = (t - self.t[0]) / h;
        let (s2, s3) = (s * s, s * s * s);
        let (h00, h10, h01, h11) = (
            2.0 * s3 - 3.0 * s2 + 1.0,
            s3 - 2.0 * s2 + s,
            -2.0 * s3 + 3.0 * s2,
            s3 - s2,
        );
        let (qa, qb, va, vb) = (&self.q[0], &self.q[1], &self.qd[0], &self.qd[1]);
        for &k in dep {
            q[k] = h00 * qa[k] + h10 * h * va[k] + h01 * qb[k] + h11 * h * vb[k];
        }
    }
}

/// One split of the coordinates and the solves that complete a state from
/// its independent part (cloned into the observer of a run).
#[derive(Clone)]
pub(super) struct Split {
    pub(super) n: usize,
    /// Dependent coordinates (pivot columns), independent ones, and the
    /// independent constraint rows, each sorted.
    pub(super) dep: Vec<usize>,
    indep: Vec<usize>,
    pub(super) rows: Vec<usize>,
    jac: Vec<f64>,
    pub(super) dense: Vec<f64>,
    phi: Vec<f64>,
    phi_t: Vec<f64>,
    rhs: Vec<f64>,
    /// LU of the dependent block Φ_R,u (r × r).
    lu: LuBuf,
    /// Last accepted full state: the Newton predictor
    /// `q + q̇ Δt + ½ q̈ Δt²` (Δt = t − t_base).
    base_t: f64,
    base_q: Vec<f64>,
    base_qd: Vec<f64>,
    base_qdd: Vec<f64>,
}

impl Split {
    /// The split at `(t, q)`: the first `rank` pivots of complete pivoting
    /// on Φ_q (`rank = None`: the numerical rank at this state).
    pub(super) fn choose(
        sys: &System,
        t: f64,
        q: &[f64],
        rank: Option<usize>,
    ) -> Result<Self, FormulationError> {
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let mut s = Self {
            n,
            dep: Vec::new(),
            indep: Vec::new(),
            rows: Vec::new(),
            jac: vec![0.0; sys.jacobian_pattern().len()],
            dense: vec![0.0; m * n],
            phi: vec![0.0; m],
            phi_t: vec![0.0; m],
            rhs: Vec::new(),
            lu: LuBuf::new(0),
            base_t: t,
            base_q: q.to_vec(),
            base_qd: vec![0.0; n],
            base_qdd: vec![0.0; n],
        };
        s.dense_jacobian(sys, t, q);
        let mut a = s.dense.clone();
        let tol = if rank.is_some() { 0.0 } else { RANK_TOL };
        let order = full_pivot_order(&mut a, m, n, tol);
        let r = rank.unwrap_or(order.rank);
        if order.rank < r {
            return Err(FormulationError::Invalid(format!(
                "coordinate partitioning at t = {t}: Φ_q has rank {} < {r} (exactly singular)",
                order.rank
            )));
        }
        s.dep = order.cols[..r].to_vec();
        s.indep = order.cols[r..].to_vec();
        s.rows = order.rows[..r].to_vec();
        for v in [&mut s.dep, &mut s.indep, &mut s.rows] {
            v.sort_unstable();
        }
        s.rhs = vec![0.0; r];
        s.lu = LuBuf::new(r);
        Ok(s)
    }

    fn dof(&self) -> usize {
        self.indep.len()
    }

    fn set_base(&mut self, t: f64, q: &[f64], qd: &[f64], qdd: &[f64]) {
        self.base_t = t;
        self.base_q.copy_from_slice(q);
        self.base_qd.copy_from_slice(qd);
        self.base_qdd.copy_from_slice(qdd);
    }

    /// Φ_q at `(q, t)` as a dense row-major `m × n` matrix.
    pub(super) fn dense_jacobian(&mut self, sys: &System, t: f64, q: &[f64]) {
        sys.jacobian_values(q, t, &mut self.jac);
        self.dense.fill(0.0);
        for (&(i, j), &v) in sys.jacobian_pattern().iter().zip(&self.jac) {
            self.dense[i * self.n + j] += v;
        }
    }

    /// Factor the dependent block of the last [`Split::dense_jacobian`]
    /// into `self.lu`.
    fn factor_block(&mut self) {
        let (n, rows, dep, dense) = (self.n, &self.rows, &self.dep, &self.dense);
        self.lu.factor(|i, j| dense[rows[i] * n + dep[j]]);
    }

    /// Solve `B x = self.rhs` in place with the LU of the block.
    fn solve(&mut self, t: f64) -> Result<(), FormulationError> {
        self.lu.solve(&mut self.rhs);
        if let Some((index, value)) = crate::numeric::first_non_finite(&self.rhs) {
            return Err(FormulationError::NonFinite {
                what: "the dependent-coordinate solve of coordinate partitioning",
                index,
                value,
                t,
            });
        }
        Ok(())
    }

    /// The base's predictor of the dependent coordinates at `t` into
    /// `q[dep]`, where [`Split::complete`] starts its Newton iteration.
    fn predict(&self, t: f64, q: &mut [f64]) {
        let dt = t - self.base_t;
        for &k in &self.dep {
            q[k] = self.base_q[k] + dt * (self.base_qd[k] + 0.5 * dt * self.base_qdd[k]);
        }
    }

    /// The full state from the independent part `v`, `v̇`: Newton on
    /// `Φ_R(u, v, t) = 0` from the predictor already in `q[dep]`
    /// ([`Split::predict`]), then the dependent velocities. Returns the
    /// Newton iterations.
    fn complete(
        &mut self,
        sys: &System,
        opts: &PartitionOptions,
        t: f64,
        y: &[f64],
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<usize, FormulationError> {
        let d = self.dof();
        let (v, vd) = y.split_at(d);
        for (i, &k) in self.indep.iter().enumerate() {
            q[k] = v[i];
            qd[k] = vd[i];
        }
        let mut iterations = 0;
        loop {
            sys.phi(q, t, &mut self.phi);
            let residual = self
                .rows
                .iter()
                .fold(0.0_f64, |a, &i| a.max(self.phi[i].abs()));
            if residual <= opts.tol {
                break;
            }
            FormulationError::check_projection(t, residual, opts.tol, iterations, opts.max_iter)?;
            self.dense_jacobian(sys, t, q);
            self.factor_block();
            for (x, &i) in self.rhs.iter_mut().zip(&self.rows) {
                *x = -self.phi[i];
            }
            self.solve(t)?;
            let mut step = 0.0_f64;
            for (&k, dx) in self.dep.iter().zip(&self.rhs) {
                q[k] += dx;
                step = step.max(dx.abs() / (1.0 + q[k].abs()));
            }
            iterations += 1;
            if step <= 4.0 * f64::EPSILON {
                break; // at the rounding floor of Φ
            }
        }
        // Φ_R,u u̇ = −Φ_R,t − Φ_R,v v̇ at the converged q
        self.dense_jacobian(sys, t, q);
        self.factor_block();
        sys.phi_t(q, t, &mut self.phi_t);
        let n = self.n;
        for (x, &i) in self.rhs.iter_mut().zip(&self.rows) {
            let row = &self.dense[i * n..(i + 1) * n];
            *x = -self.phi_t[i] - self.indep.iter().map(|&k| row[k] * qd[k]).sum::<f64>();
        }
        self.solve(t)?;
        for (&k, &x) in self.dep.iter().zip(&self.rhs) {
            qd[k] = x;
        }
        Ok(iterations)
    }

    /// κ₁(Φ_R,u) = ‖B‖₁ ‖B⁻¹‖₁ at `(q, t)` (∞ when B is singular).
    fn condition(&mut self, sys: &System, t: f64, q: &[f64]) -> f64 {
        self.dense_jacobian(sys, t, q);
        let (r, n) = (self.rows.len(), self.n);
        if r == 0 {
            return 1.0;
        }
        let norm_b = self
            .dep
            .iter()
            .map(|&c| self.rows.iter().map(|&i| self.dense[i * n + c].abs()).sum())
            .fold(0.0, f64::max);
        // ‖B⁻¹‖₁: the largest column sum of B⁻¹, column by column
        self.factor_block();
        let mut norm_inv = 0.0_f64;
        for j in 0..r {
            self.rhs.fill(0.0);
            self.rhs[j] = 1.0;
            self.lu.solve(&mut self.rhs);
            let c: f64 = self.rhs.iter().map(|v| v.abs()).sum();
            if !c.is_finite() {
                return f64::INFINITY;
            }
            norm_inv = norm_inv.max(c);
        }
        let k = norm_b * norm_inv;
        if k.is_finite() {
            k
        } else {
            f64::INFINITY
        }
    }
}

/// Coordinate partitioning (module docs) as an [`OdeSystem`] for
/// `y = [v; v̇]`, and the run that restarts it on a new split.
pub struct Partitioned<'a> {
    sys: &'a System,
    opts: PartitionOptions,
    split: Split,
    g: Vec<f64>,
    gamma: Vec<f64>,
    factorizations: usize,
    rank: usize,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    /// LU of eq. (5) on the rows R (dimension n + r) and its right-hand
    /// side: buffers kept between evaluations.
    kkt: LuBuf,
    x: Vec<f64>,
    /// `(t, y)` of the last evaluation whose `q`, `q̇`, `q̈` are in the
    /// buffers above (the accepted step's end is usually the last stage).
    last_t: Option<f64>,
    last_y: Vec<f64>,
    dydt: Vec<f64>,
    accepted: Rc<RefCell<Accepted>>,
    stats: PartitionStats,
}

impl<'a> Partitioned<'a> {
    /// The split at the initial state `(t0, q0)`; `index1` supplies the
    /// options of the run (Baumgarte terms and projection must be off: the
    /// constraints hold by construction; the linear solver is dense).
    pub fn new(
        sys: &'a System,
        opts: PartitionOptions,
        index1: Index1Options,
        t0: f64,
        q0: &[f64],
    ) -> Result<Self, FormulationError> {
        let n = sys.n_coords();
        if n > MAX_PARTITION_COORDS {
            return Err(FormulationError::Invalid(format!(
                "coordinate partitioning uses dense matrices (O(n r²) per evaluation): at most \
                 {MAX_PARTITION_COORDS} coordinates, this system has {n}; use the saddle-point \
                 formulation with projection or genalpha"
            )));
        }
        if !index1.baumgarte.is_off() || index1.projection.enabled {
            return Err(FormulationError::Invalid(
                "coordinate partitioning satisfies the constraints by construction: Baumgarte \
                 terms and projection do not apply"
                    .into(),
            ));
        }
        if !(opts.max_condition.is_finite() && opts.max_condition > 1.0) {
            return Err(FormulationError::InvalidOption {
                option: "max_condition",
                value: opts.max_condition.to_string(),
                reason: "must be finite and > 1".into(),
            });
        }
        if !(opts.tol.is_finite() && opts.tol > 0.0) || opts.max_iter == 0 {
            return Err(FormulationError::InvalidOption {
                option: "tol",
                value: format!("{} (max_iter {})", opts.tol, opts.max_iter),
                reason: "the tolerance must be finite and > 0, max_iter ≥ 1".into(),
            });
        }
        let split = Split::choose(sys, t0, q0, None)?;
        let rank = split.dep.len();
        Ok(Self {
            kkt: LuBuf::new(n + rank),
            x: vec![0.0; n + rank],
            last_t: None,
            last_y: Vec::new(),
            dydt: Vec::new(),
            accepted: Rc::default(),
            sys,
            opts,
            split,
            g: vec![0.0; n],
            gamma: vec![0.0; sys.n_constraints()],
            factorizations: 0,
            rank,
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
            stats: PartitionStats::default(),
        })
    }

    /// Degrees of freedom d = n − rank Φ_q (at t0).
    pub fn dof(&self) -> usize {
        self.split.dof()
    }

    /// The independent coordinates of the current split (sorted).
    pub fn independent(&self) -> &[usize] {
        &self.split.indep
    }

    /// Counters so far.
    pub fn stats(&self) -> PartitionStats {
        self.stats
    }

    /// Dense factorisations of eq. (5) so far.
    pub fn factorizations(&self) -> usize {
        self.factorizations
    }

    /// `q̈` from eq. (5) on the independent rows R,
    /// `[M Φ_Rᵀ; Φ_R 0][q̈; λ_R] = [g; γ_R]`, at a state completed by
    /// [`Partitioned::expand`] (Φ_q of that state in the split's buffer).
    fn accelerations(&mut self, x: StateView<'_>, qdd: &mut [f64]) -> Result<(), FormulationError> {
        let StateView { t, q, qd } = x;
        let sys = self.sys;
        let n = sys.n_coords();
        sys.forces_into(t, q, qd, &mut self.g);
        sys.gamma(q, qd, t, &mut self.gamma);
        all_finite(
            t,
            &[
                ("the forces g", &self.g),
                ("γ (the right-hand side of Φ_q q̈ = γ)", &self.gamma),
            ],
        )?;
        let (mass, sp) = (sys.mass_diagonal(), &self.split);
        self.kkt.factor(|i, j| match (i < n, j < n) {
            (true, true) => {
                if i == j {
                    mass[i]
                } else {
                    0.0
                }
            }
            (true, false) => sp.dense[sp.rows[j - n] * n + i],
            (false, true) => sp.dense[sp.rows[i - n] * n + j],
            (false, false) => 0.0,
        });
        let x = &mut self.x;
        x[..n].copy_from_slice(&self.g);
        for (xi, &i) in x[n..].iter_mut().zip(&sp.rows) {
            *xi = self.gamma[i];
        }
        self.kkt.solve(x);
        self.factorizations += 1;
        if let Some((index, value)) = crate::numeric::first_non_finite(x) {
            return Err(FormulationError::NonFinite {
                what: "the accelerations of eq. (5) (singular configuration?)",
                index,
                value,
                t,
            });
        }
        qdd.copy_from_slice(&x[..n]);
        Ok(())
    }

    /// κ₁ of the current dependent block at `(t, q)`.
    pub fn condition(&mut self, t: f64, q: &[f64]) -> f64 {
        self.split.condition(self.sys, t, q)
    }

    /// Complete `y = [v; v̇]` to `(q, q̇)` (Newton on the dependent
    /// coordinates from the last accepted state, then their velocities).
    pub fn expand(
        &mut self,
        t: f64,
        y: &[f64],
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<usize, FormulationError> {
        self.split.predict(t, q);
        let it = self.split.complete(self.sys, &self.opts, t, y, q, qd)?;
        self.stats.newton_iterations += it;
        Ok(it)
    }

    /// A segment starts at the full state `(t, q, q̇)`: the predictor's
    /// base (with `q̈` there; zero if eq. (5) fails, which the first
    /// evaluation then reports) and both accepted states.
    fn start_segment(&mut self, t: f64, q: &[f64], qd: &[f64]) {
        self.split.dense_jacobian(self.sys, t, q);
        let mut qdd = std::mem::take(&mut self.qdd);
        if self
            .accelerations(StateView { t, q, qd }, &mut qdd)
            .is_err()
        {
            qdd.fill(0.0);
        }
        self.split.set_base(t, q, qd, &qdd);
        self.qdd = qdd;
        self.last_t = None;
        self.accepted.borrow_mut().reset(t, q, qd);
    }

    /// `[q[v]; q̇[v]]` of a full state.
    pub fn reduce(&self, q: &[f64], qd: &[f64]) -> Vec<f64> {
        let ix = &self.split.indep;
        ix.iter()
            .map(|&k| q[k])
            .chain(ix.iter().map(|&k| qd[k]))
            .collect()
    }

    /// Integrate with `method` from `(q0, q̇0)` at `t0`, delivering full
    /// states `[q; q̇]` to `obs`: each segment runs with the split of its
    /// start until κ₁ of the dependent block exceeds
    /// [`PartitionOptions::max_condition`] at an accepted step and complete
    /// pivoting there picks a different dependent set; then the integrator
    /// is rebuilt and restarted from that full state (fresh first step,
    /// outputs after it). Work and notices of all segments are summed.
    pub fn integrate(
        &mut self,
        method: Method,
        ode: &OdeOptions,
        span: Span<'_>,
    ) -> Result<Report, IntegratorError> {
        let Span {
            t0,
            t_end,
            q0,
            qd0,
            output_times: times,
            obs,
        } = span;
        let sys = self.sys;
        let n = sys.n_coords();
        let (mut t, mut q, mut qd) = (t0, q0.to_vec(), qd0.to_vec());
        let mut total = Stats::default();
        let mut warnings: Vec<String> = Vec::new();
        let mut first = true;
        loop {
            if !first {
                match Split::choose(sys, t, &q, Some(self.rank)) {
                    Ok(s) => self.split = s,
                    Err(e) => {
                        let reason = Failure::System {
                            what: "coordinate partitioning",
                            t,
                            step_from: None,
                            source: std::sync::Arc::new(SystemError::new(e)),
                        };
                        return Ok(Report {
                            stats: total,
                            termination: Termination::Failed { t, reason },
                            t_reached: t,
                            warnings,
                        });
                    }
                }
            }
            self.start_segment(t, &q, &qd);
            let y0 = self.reduce(&q, &qd);
            let seg_times: Vec<f64> = times
                .iter()
                .copied()
                .filter(|&tk| if first { tk >= t } else { tk > t })
                .collect();
            let mut seg_ode = ode.clone();
            seg_ode.max_steps = ode.max_steps.saturating_sub(total.steps).max(1);
            let mut integ: Integrator = integrator(method, seg_ode)?;
            let mut watch = FullState {
                sys,
                opts: self.opts,
                split: self.split.clone(),
                accepted: Rc::clone(&self.accepted),
                inner: &mut *obs,
                full: vec![0.0; 2 * n],
                seen: &mut warnings,
                repartition: false,
                max_condition: 0.0,
                rank: self.rank,
            };
            let report = integ.integrate(self, t, t_end, &y0, &seg_times, &mut watch)?;
            let again = watch.repartition;
            let (qs, qds) = watch.full.split_at(n);
            let (qs, qds) = (qs.to_vec(), qds.to_vec());
            self.stats.max_condition = self.stats.max_condition.max(watch.max_condition);
            drop(watch);
            total.steps += report.stats.steps;
            total.failed_steps += report.stats.failed_steps;
            total.rhs_evals += report.stats.rhs_evals;
            for w in report.warnings {
                if !warnings.contains(&w) {
                    warnings.push(w);
                }
            }
            first = false;
            match report.termination {
                Termination::Stopped { t: ts, .. } if again && ts < t_end => {
                    self.stats.repartitions += 1;
                    self.stats.first_repartition_t.get_or_insert(ts);
                    (t, q, qd) = (ts, qs, qds);
                }
                termination => {
                    let termination = if again {
                        Termination::Completed // re-chosen on the last step
                    } else {
                        termination
                    };
                    return Ok(Report {
                        stats: total,
                        termination,
                        t_reached: report.t_reached,
                        warnings,
                    });
                }
            }
        }
    }
}

impl OdeSystem for Partitioned<'_> {
    fn dim(&self) -> usize {
        2 * self.split.dof()
    }
    /// `[v̇; v̈]` with `v̈ = q̈[v]` from eq. (5) at the completed state.
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<(), SystemError> {
        let (mut q, mut qd) = (std::mem::take(&mut self.q), std::mem::take(&mut self.qd));
        let r = self.expand(t, y, &mut q, &mut qd).and_then(|_| {
            let mut qdd = std::mem::take(&mut self.qdd);
            let r = self.accelerations(StateView { t, q: &q, qd: &qd }, &mut qdd);
            self.qdd = qdd;
            r.map(|()| {
                let d = self.split.dof();
                for (i, &k) in self.split.indep.iter().enumerate() {
                    dydt[i] = qd[k];
                    dydt[d + i] = self.qdd[k];
                }
            })
        });
        (self.q, self.qd) = (q, qd);
        if r.is_ok() {
            self.last_t = Some(t);
            self.last_y.clear();
            self.last_y.extend_from_slice(y);
        } else {
            self.last_t = None;
        }
        r.map_err(SystemError::new)
    }
    /// The accepted state (`q`, `q̇`, `q̈`: those of the last evaluation
    /// when it was at this `(t, y)`) becomes the Newton predictor's base
    /// and the newest accepted state (`y` is not moved).
    fn post_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        if self.last_t != Some(t) || self.last_y != y {
            let mut dydt = std::mem::take(&mut self.dydt);
            dydt.resize(y.len(), 0.0);
            let r = self.rhs(t, y, &mut dydt);
            self.dydt = dydt;
            r?;
        }
        self.split.set_base(t, &self.q, &self.qd, &self.qdd);
        self.accepted.borrow_mut().push(t, &self.q, &self.qd);
        Ok(false)
    }
}

/// The observer of one segment: completes each reduced state to `[q; q̇]`
/// for the run's observer and, after each accepted step, asks for a new
/// split when the dependent block is ill-conditioned.
struct FullState<'o, 's> {
    sys: &'s System,
    opts: PartitionOptions,
    split: Split,
    accepted: Rc<RefCell<Accepted>>,
    inner: &'o mut dyn Observer,
    full: Vec<f64>,
    seen: &'o mut Vec<String>,
    repartition: bool,
    max_condition: f64,
    rank: usize,
}

impl FullState<'_, '_> {
    /// `[q; q̇]` at `(t, y)` into `self.full`: the accepted state itself at
    /// its time, else Newton from the Hermite predictor of the two accepted
    /// states around `t` ([`Accepted`]).
    fn complete(&mut self, t: f64, y: &[f64]) -> Result<(), String> {
        let n = self.split.n;
        let (q, qd) = self.full.split_at_mut(n);
        let acc = self.accepted.borrow();
        let d = self.split.dof();
        let at_step = acc.t[1] == t
            && acc.q[1].len() == n
            && self
                .split
                .indep
                .iter()
                .enumerate()
                .all(|(i, &k)| acc.q[1][k] == y[i] && acc.qd[1][k] == y[d + i]);
        if at_step {
            q.copy_from_slice(&acc.q[1]);
            qd.copy_from_slice(&acc.qd[1]);
            return Ok(());
        }
        acc.predict(t, &self.split.dep, q);
        drop(acc);
        self.split
            .complete(self.sys, &self.opts, t, y, q, qd)
            .map(|_| ())
            .map_err(|e| format!("coordinate partitioning: {e}"))
    }
}

impl Observer for FullState<'_, '_> {
    fn output(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        if let Err(e) = self.complete(t, y) {
            return ControlFlow::Break(e);
        }
        self.inner.output(t, &self.full)
    }
    fn step(&mut self, t: f64, y: &[f64]) -> ControlFlow<String> {
        if let Err(e) = self.complete(t, y) {
            return ControlFlow::Break(e);
        }
        let n = self.split.n;
        self.inner.step(t, &self.full)?;
        let q = &self.full[..n];
        let kappa = self.split.condition(self.sys, t, q);
        self.max_condition = self.max_condition.max(kappa);
        if kappa > self.opts.max_condition {
            if let Ok(s) = Split::choose(self.sys, t, q, Some(self.rank)) {
                if s.dep != self.split.dep {
                    self.repartition = true;
                    return ControlFlow::Break(format!(
                        "coordinate partitioning: new independent set at t = {t} \
                         (κ₁ = {kappa:.2e})",
                        t = Time(t)
                    ));
                }
            }
        }
        ControlFlow::Continue(())
    }
    fn progress(&mut self, t: f64, stats: &Stats) -> ControlFlow<String> {
        self.inner.progress(t, stats)
    }
    fn warning(&mut self, message: &str) {
        if !self.seen.iter().any(|w| w == message) {
            self.seen.push(message.to_string());
            self.inner.warning(message);
        }
    }
}
