//! Consistent initial conditions (paper §2): positions on Φ(q, t₀) = 0 and
//! velocities on Φ_q q̇ = −Φ_t, given the independent coordinates.

use super::{all_finite, linear_at, FormulationError};
use crate::linalg::{solver_for, SaddleMatrix, SolverKind, SolverOptions};
use crate::model::{BodyRef, Slide, System};
use serde::Serialize;

/// What a lock row of the assembly holds at its given value: a body
/// coordinate, the relative angle of two bodies (a revolute joint's angle)
/// or the slide of a translational joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LockKind {
    /// The coordinate `q_k`.
    Coordinate(usize),
    /// `θ = φ_j − φ_i` (the ground's angle is 0) \[rad\].
    RelativeAngle {
        /// Reference body.
        body_i: BodyRef,
        /// Second body.
        body_j: BodyRef,
    },
    /// The slide of a translational joint \[m\] ([`Slide::eval`]).
    Slide(Slide),
}

/// A lock row `ℓ(q) = value` of the assembly, with the rate `ℓ̇ = ∇ℓ·q̇ =
/// rate` imposed on the velocities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lock {
    /// The locked quantity.
    pub kind: LockKind,
    /// Its value.
    pub value: f64,
    /// Its rate.
    pub rate: f64,
}

impl LockKind {
    /// The coordinates `ℓ` depends on (the order of [`LockKind::eval`]'s
    /// gradient).
    pub fn columns(&self) -> Vec<usize> {
        match *self {
            LockKind::Coordinate(k) => vec![k],
            LockKind::RelativeAngle { body_i, body_j } => [body_i, body_j]
                .iter()
                .filter_map(|b| b.offset().map(|o| o + 2))
                .collect(),
            LockKind::Slide(s) => s.columns(),
        }
    }

    /// `ℓ(q)`, and its gradient over [`LockKind::columns`] into `grad`.
    pub fn eval(&self, q: &[f64], grad: &mut [f64]) -> f64 {
        match *self {
            LockKind::Coordinate(k) => {
                grad[0] = 1.0;
                q[k]
            }
            LockKind::RelativeAngle { body_i, body_j } => {
                let ang = |b: BodyRef| b.offset().map_or(0.0, |o| q[o + 2]);
                let mut k = 0;
                for (b, v) in [(body_i, -1.0), (body_j, 1.0)] {
                    if b.offset().is_some() {
                        grad[k] = v;
                        k += 1;
                    }
                }
                ang(body_j) - ang(body_i)
            }
            LockKind::Slide(s) => s.eval(q, grad),
        }
    }
}

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
    /// How far the assembly moved each body: `[|Δr|, |Δφ|]` of its centre
    /// of mass \[m\] and angle \[rad\] from the given to the assembled
    /// positions.
    pub body_moves: Vec<[f64; 2]>,
    /// The largest lock error after the assembly, `max |ℓ(q) − value|,
    /// |∇ℓ·q̇ − rate|` over the lock rows (0 without locks): a lock the
    /// constraints contradict is given up by the least-squares velocity
    /// solve.
    pub lock_residual: f64,
}

/// Correct `(q, q̇)` onto the constraint manifold at `t0`, keeping the
/// coordinates listed in `independent` (and their velocities) at the given
/// values (`consistent_initial_state_locked` with coordinate locks).
pub fn consistent_initial_state(
    sys: &System,
    t0: f64,
    q: &[f64],
    qd: &[f64],
    independent: &[usize],
    opts: InitialOptions,
) -> Result<ConsistentState, FormulationError> {
    let n = sys.n_coords();
    if let Some(&k) = independent.iter().find(|&&k| k >= n) {
        return Err(FormulationError::Initial(format!(
            "independent coordinate index {k} out of range (the system has {n} coordinates)"
        )));
    }
    let locks: Vec<Lock> = independent
        .iter()
        .map(|&k| Lock {
            kind: LockKind::Coordinate(k),
            value: q[k],
            rate: qd[k],
        })
        .collect();
    consistent_initial_state_locked(sys, t0, q, qd, &locks, opts)
}

/// Correct `(q, q̇)` onto the constraint manifold at `t0` with every lock
/// row `ℓ(q) = value`, `∇ℓ·q̇ = rate` ([`Lock`]) imposed.
///
/// Each Newton step is the smallest correction `Δq` (Euclidean norm) with
/// `Φ_q Δq = −Φ` and `∇ℓ Δq = value − ℓ(q)` for every lock, from the
/// saddle-point system `[I  Φ̃_qᵀ; Φ̃_q 0]` where Φ̃ appends the lock rows to
/// Φ — the same sparse machinery as the equations of motion. The velocities
/// are the closest to the given ones with `Φ_q q̇ = −Φ_t` and the locks'
/// rates.
pub(crate) fn consistent_initial_state_locked(
    sys: &System,
    t0: f64,
    q: &[f64],
    qd: &[f64],
    locks: &[Lock],
    opts: InitialOptions,
) -> Result<ConsistentState, FormulationError> {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let cols: Vec<Vec<usize>> = locks.iter().map(|l| l.kind.columns()).collect();
    if let Some(&k) = cols.iter().flatten().find(|&&k| k >= n) {
        return Err(FormulationError::Initial(format!(
            "a lock row reads coordinate {k}, out of range (the system has {n} coordinates)"
        )));
    }
    let nl = locks.len();
    let mut pattern = sys.jacobian_pattern().to_vec();
    for (i, c) in cols.iter().enumerate() {
        pattern.extend(c.iter().map(|&k| (m + i, k)));
    }
    let mut kmat = SaddleMatrix::new(n, m + nl, &[], &pattern);
    let mut solver = solver_for(opts.linear_solver, n + m + nl, SolverOptions::default());
    let lin = linear_at(t0);
    solver.analyze(&kmat).map_err(lin)?;
    kmat.set_a_diagonal(&vec![1.0; n]);

    let mut jac = vec![0.0; pattern.len()];
    let nsys = sys.jacobian_pattern().len();
    let q_given = q;
    let mut q = q.to_vec();
    // Φ and the lock residuals ℓ − value; their Jacobian rows into `jac`
    let mut phi = vec![0.0; m + nl];
    let eval_locks = |q: &[f64], res: &mut [f64], jac: &mut [f64]| {
        let mut at = nsys;
        for (i, l) in locks.iter().enumerate() {
            let k = cols[i].len();
            res[i] = l.kind.eval(q, &mut jac[at..at + k]) - l.value;
            at += k;
        }
    };
    let mut x = vec![0.0; n + m + nl];
    let norm_inf = |v: &[f64]| v.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
    let mut iterations = 0;
    loop {
        sys.phi(&q, t0, &mut phi[..m]);
        eval_locks(&q, &mut phi[m..], &mut jac);
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
        for (xr, p) in x[n..].iter_mut().zip(&phi) {
            *xr = -p;
        }
        solver.solve_in_place(&kmat, &mut x).map_err(lin)?;
        for (qi, dx) in q.iter_mut().zip(&x[..n]) {
            *qi += dx;
        }
        iterations += 1;
    }

    // Velocities: min ‖q̇ − q̇⁰‖ s.t. Φ_q q̇ = −Φ_t, ∇ℓ q̇ = rate.
    sys.jacobian_values(&q, t0, &mut jac[..nsys]);
    eval_locks(&q, &mut phi[m..], &mut jac);
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
    for (i, l) in locks.iter().enumerate() {
        x[n + m + i] = l.rate;
    }
    solver.solve_in_place(&kmat, &mut x).map_err(lin)?;
    let qd: Vec<f64> = x[..n].to_vec();

    sys.phi(&q, t0, &mut phi[..m]);
    let position_residual = phi[..m].iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut phid = vec![0.0; m];
    sys.jacobian_mul(&jac[..nsys], &qd, &mut phid);
    let velocity_residual = phid
        .iter()
        .zip(&phi_t)
        .map(|(a, b)| (a + b) * (a + b))
        .sum::<f64>()
        .sqrt();
    let mut lock_residual = 0.0_f64;
    let mut at = nsys;
    for (i, l) in locks.iter().enumerate() {
        let k = cols[i].len();
        let g = &mut jac[at..at + k];
        let v = l.kind.eval(&q, g);
        let rate: f64 = g.iter().zip(&cols[i]).map(|(a, &c)| a * qd[c]).sum();
        lock_residual = lock_residual
            .max((v - l.value).abs())
            .max((rate - l.rate).abs());
        at += k;
    }
    let nb = sys.n_body_coords();
    let body_moves = q_given[..nb]
        .chunks(3)
        .zip(q[..nb].chunks(3))
        .map(|(a, b)| [(b[0] - a[0]).hypot(b[1] - a[1]), (b[2] - a[2]).abs()])
        .collect();
    Ok(ConsistentState {
        q,
        qd,
        position_residual,
        velocity_residual,
        iterations,
        body_moves,
        lock_residual,
    })
}
/// Tolerance on ‖Φ‖∞ \[m\] (and on `‖Φ_q q̇ + Φ_t‖∞ / max(1, ‖q̇‖∞)`)
/// below which the initial state counts as consistent: the default of the
/// index-1 projection ([`super::Projection`]), and of every
/// start projection ([`super::Augmented::consistent_start`],
/// [`super::Index3::consistent_start`]).
pub const START_TOL: f64 = 1e-10;

/// Iterations allowed to each projection of the start.
pub const START_MAX_ITER: usize = 100;

/// What a start projection did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StartCorrection {
    /// ‖Φ(q₀)‖∞ before.
    pub phi: f64,
    /// `‖Φ_q q̇₀ + Φ_t‖∞` before (at the projected positions).
    pub phi_dot: f64,
    /// Largest change of a position coordinate.
    pub moved_q: f64,
    /// Largest change of a velocity coordinate.
    pub moved_qd: f64,
    /// Iterations (positions + velocities).
    pub iterations: usize,
}

impl StartCorrection {
    /// Whether anything was changed.
    pub fn changed(&self) -> bool {
        self.moved_q > 0.0 || self.moved_qd > 0.0
    }

    /// The run's warning for a start that was moved onto the manifold at
    /// `t` by `how` iterations.
    pub fn describe(&self, t: f64, how: &str) -> String {
        format!(
            "initial state off the constraint manifold (‖Φ‖∞ = {:.3e}, ‖Φ̇‖∞ = {:.3e}): \
             projected at t = {t} (mass-orthogonal, {} {how} iterations; positions moved by \
             up to {:.3e}, velocities by up to {:.3e})",
            self.phi, self.phi_dot, self.iterations, self.moved_q, self.moved_qd
        )
    }
}

/// Put an inconsistent initial state of an index-3 run (generalized-α,
/// HHT, Newmark, bdf) onto the constraint manifold: [`Index3::project`](super::Index3::project)
/// (one mass-orthogonal Newton step on Φ(q, t) = 0, then the velocities
/// onto `Φ_q q̇ + Φ_t = 0`, paper §3.3) repeated until ‖Φ‖∞ ≤ [`START_TOL`]
/// and `‖Φ_q q̇ + Φ_t‖∞ ≤ START_TOL · max(1, ‖q̇‖∞)`. A consistent state is
/// left untouched (bit for bit). Without it the index-3 methods either
/// fail at t₀ (bdf) or start with a constraint force that snaps the state
/// onto the manifold in one step and injects energy (generalized-α from
/// the four-bar's incorrect start gained 1.0e4 J on a scale of 14 J).
/// [`FormulationError::Initial`] if [`START_MAX_ITER`] iterations do not
/// get there or ‖Φ‖ grows tenfold.
pub(super) fn index3_consistent_start(
    sys: &System,
    f: &mut super::Index3<'_>,
    t: f64,
    q: &mut [f64],
    qd: &mut [f64],
) -> Result<StartCorrection, FormulationError> {
    let norm = crate::numeric::max_abs;
    let m = sys.n_constraints();
    let mut phi = vec![0.0; m];
    let mut phi_t = vec![0.0; m];
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    // (‖Φ‖∞, ‖Φ_q q̇ + Φ_t‖∞ / max(1, ‖q̇‖∞)) at (q, q̇)
    let mut residuals = |q: &[f64], qd: &[f64]| {
        sys.phi(q, t, &mut phi);
        all_finite(t, &[("the constraints Φ", &phi)])?;
        let p = norm(&phi);
        sys.jacobian_values(q, t, &mut jac);
        sys.phi_t(q, t, &mut phi_t);
        all_finite(
            t,
            &[
                ("Φ_q", &jac),
                ("Φ_t (the constraints' time derivative)", &phi_t),
            ],
        )?;
        sys.jacobian_mul(&jac, qd, &mut phi);
        let v = phi
            .iter()
            .zip(&phi_t)
            .fold(0.0_f64, |a, (x, y)| a.max((x + y).abs()));
        Ok::<_, FormulationError>((p, v, v / norm(qd).max(1.0)))
    };
    let (p0, v0, mut vrel) = residuals(q, qd)?;
    let mut out = StartCorrection {
        phi: p0,
        phi_dot: v0,
        ..Default::default()
    };
    if p0 <= START_TOL && vrel <= START_TOL {
        return Ok(out);
    }
    let (q_in, qd_in) = (q.to_vec(), qd.to_vec());
    let mut p = p0;
    while p > START_TOL || vrel > START_TOL {
        if out.iterations == START_MAX_ITER || p.is_nan() || p > 10.0 * p0.max(START_TOL) {
            return Err(FormulationError::Initial(format!(
                "the initial state violates the constraints (‖Φ‖∞ = {p0:.3e}, ‖Φ_q q̇ + Φ_t‖∞ \
                 = {v0:.3e} at t = {t}) and the mass-orthogonal projection did not reach the \
                 manifold ({}: ‖Φ‖∞ = {p:.3e} after {} iterations): there is no consistent \
                 configuration near the given one (check the initial positions and the joint \
                 geometry) or the mechanism locks up there",
                if out.iterations == START_MAX_ITER {
                    "no convergence"
                } else {
                    "diverged"
                },
                out.iterations
            )));
        }
        f.project(t, q, qd)?;
        out.iterations += 1;
        (p, _, vrel) = residuals(q, qd)?;
    }
    out.moved_q = crate::numeric::max_abs_diff(q, &q_in);
    out.moved_qd = crate::numeric::max_abs_diff(qd, &qd_in);
    Ok(out)
}
