//! Kinematics and inverse dynamics of a mechanism without remaining
//! freedom once its drives are counted (rank Φ_q = n).
//!
//! At each output time t, with no integration:
//!
//! 1. positions: Newton on `Φ(q, t) = 0`, warm-started from the previous
//!    time's `q + h q̇ + ½ h² q̈` (each correction `Δq = −Φ_q⁻¹Φ`, taken as
//!    the mass-orthogonal step of [`Index1::project`], which is that one
//!    when Φ_q is square and regular);
//! 2. velocities: `Φ_q q̇ = −Φ_t`;
//! 3. accelerations: `Φ_q q̈ = γ` (paper eq. (4));
//! 4. multipliers from `M q̈ − g = −Φ_qᵀλ` (our sign: `M q̈ + Φ_qᵀλ = g`),
//!    so the drive forces/torques are `−λ` of the drive rows
//!    ([`crate::model::Drive::force`]) and the joint reactions `−Φ_qᵀλ`
//!    restricted to each joint ([`System::joint_reactions`]).
//!
//! Steps 3 and 4 are one solve of the saddle-point system of eq. (5)
//! `[M Φ_qᵀ; Φ_q 0] [q̈; λ] = [g; γ]` without Baumgarte terms: with Φ_q
//! square and regular its first block row decouples exactly into
//! `Φ_q q̈ = γ` and `Φ_qᵀλ = g − M q̈`.
//!
//! **Controller states** ([`crate::model::State`], `ż = f(t, q, q̇, z)`,
//! the velocity of a coordinate w nothing else reads) do not move the
//! mechanism; they follow the prescribed motion: between output times
//! `z` is integrated by the classical fourth-order Runge–Kutta method in
//! [`InverseOptions::state_substeps`] steps, `q(t)`, `q̇(t)` at each stage
//! time from steps 1–2 (so the error is `O(h⁴)` in the sub-step h). Their
//! forces then enter `g` in step 4, and a row's `q̇` holds z. They start
//! from their `initial` values ([`InverseDynamics::set_states`] takes
//! others). [`freedom`] counts the bodies' coordinates only.
//!
//! A mechanism with remaining freedom is refused by [`freedom`]: how many
//! degrees of freedom remain, a set of independent coordinates (the
//! non-pivot columns of Φ_q in a sparse elimination, Wehage & Haug 1982)
//! and the joints whose relative motion is still free (a drive on any of
//! them would remove a freedom).

use super::partitioning::{partition, Partition};
use crate::formulation::{FormulationError, Index1, Index1Options, LockKind, Projection};
use crate::linalg::full_pivot_order;
use crate::model::{JointGeometry, ReactionMap, System};
use crate::simulation::Sample;

/// Relative pivot tolerance of the rank decisions of [`freedom`]
/// (a row of Φ_q is redundant once eliminated to this times Φ_q's
/// largest entry).
pub const RANK_TOL: f64 = 1e-9;

/// Largest number of coordinates for which [`freedom`] also tests every
/// joint for a free relative motion (one dense elimination per joint).
pub const JOINT_TEST_MAX_COORDS: usize = 600;

/// Options of [`InverseDynamics`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseOptions {
    /// Newton tolerance on ‖Φ‖∞ of the positions \[m\]; default 1e-12.
    pub tol: f64,
    /// Newton iterations allowed per output time; default 25.
    pub max_iter: usize,
    /// Runge–Kutta (order 4) steps of the controller states per output
    /// interval (module docs); default 16.
    pub state_substeps: usize,
}

impl Default for InverseOptions {
    fn default() -> Self {
        Self {
            tol: 1e-12,
            max_iter: 25,
            state_substeps: 16,
        }
    }
}

/// The freedom a mechanism has at a configuration ([`freedom`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Freedom {
    /// Degrees of freedom `n_b − rank Φ_q` (`n_b` the bodies'
    /// coordinates: controller states are not freedoms of the mechanism).
    pub dof: usize,
    /// Redundant constraint equations `m − rank Φ_q`.
    pub redundant: usize,
    /// A set of independent coordinates of the bodies (`dof` of them,
    /// global indices).
    pub coordinates: Vec<usize>,
    /// Joints (indices into [`System::constraints`]) whose relative motion
    /// is free: prescribing it would lower `dof` (revolute and
    /// translational joints; empty above [`JOINT_TEST_MAX_COORDS`]).
    pub joints: Vec<usize>,
}

/// Why inverse dynamics could not be done.
#[derive(Debug, Clone, thiserror::Error)]
pub enum InverseError {
    /// The mechanism still moves with its drives held.
    #[error(
        "the mechanism has {dof} degree(s) of freedom left with its drives counted \
         (rank of Phi_q = {rank} for {n} coordinates): independent coordinates {}; \
         {}; inverse dynamics needs one drive per freedom",
        coordinates.join(", "),
        if joints.is_empty() { "no single joint's motion is free".to_string() }
        else { format!("joints whose motion is free (a drive on one removes a freedom): {}", joints.join(", ")) }
    )]
    Underdetermined {
        /// Degrees of freedom left.
        dof: usize,
        /// rank Φ_q.
        rank: usize,
        /// Coordinates n.
        n: usize,
        /// Names of independent coordinates (`BODY.x`, `BODY.y`, `BODY.phi`).
        coordinates: Vec<String>,
        /// Names of the joints whose motion is free.
        joints: Vec<String>,
    },
    /// No configuration satisfies the constraints at t (or Newton failed).
    #[error(
        "no configuration satisfies the constraints at t = {t} s: Newton on Phi(q, t) = 0 \
         stopped at |Phi|inf = {residual:.3e} after {iterations} iterations (tolerance {tol:.1e}); \
         the drives may prescribe an unreachable motion"
    )]
    Position {
        /// Time \[s\].
        t: f64,
        /// Largest |Φ| reached \[m\].
        residual: f64,
        /// Tolerance \[m\].
        tol: f64,
        /// Iterations made.
        iterations: usize,
    },
    /// A bad option.
    #[error("inverse dynamics: {0}")]
    Invalid(String),
    /// The saddle-point solve or an evaluation failed.
    #[error(transparent)]
    Formulation(#[from] FormulationError),
}

/// Name of coordinate `k` as `BODY.x`, `BODY.y` or `BODY.phi`.
/// A controller state's coordinate w (after the bodies') is
/// `state NAME`.
pub fn coordinate_label(sys: &System, k: usize) -> String {
    if k >= sys.n_body_coords() {
        let s = &sys.states()[k - sys.n_body_coords()];
        return format!("state {}", s.name);
    }
    let body = &sys.bodies()[k / 3].name;
    format!("{body}.{}", ["x", "y", "phi"][k % 3])
}

/// Dense Φ_q at `(q, t)`, row-major `m × n`.
fn dense_jacobian(sys: &System, q: &[f64], t: f64) -> Vec<f64> {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let mut vals = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, t, &mut vals);
    let mut a = vec![0.0; m * n];
    for (&(r, c), &v) in sys.jacobian_pattern().iter().zip(&vals) {
        a[r * n + c] += v;
    }
    a
}

/// The row of a joint's relative coordinate, if the joint has one: the
/// gradient of the relative angle `φ_j − φ_i` of a revolute joint, or of
/// the slide along a translational joint's axis ([`LockKind::eval`]).
fn relative_row(sys: &System, geometry: JointGeometry, q: &[f64]) -> Option<Vec<f64>> {
    let kind = match geometry {
        JointGeometry::Revolute { i, j } => LockKind::RelativeAngle {
            body_i: i.body,
            body_j: j.body,
        },
        JointGeometry::Translational(slide) => LockKind::Slide(slide),
        JointGeometry::Other => return None,
    };
    let mut grad = [0.0; 6];
    kind.eval(q, &mut grad);
    let mut row = vec![0.0; sys.n_coords()];
    for (c, g) in kind.columns().into_iter().zip(grad) {
        row[c] += g;
    }
    Some(row)
}

/// The sparse coordinate partitioning of Φ_q at `(q, t)`
/// ([`super::partitioning::partition`], relative tolerance [`RANK_TOL`]).
pub fn partition_at(sys: &System, q: &[f64], t: f64) -> Partition {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let mut vals = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, t, &mut vals);
    let entries: Vec<(usize, usize, f64)> = sys
        .jacobian_pattern()
        .iter()
        .zip(&vals)
        .map(|(&(r, c), &v)| (r, c, v))
        .collect();
    partition(m, n, &entries, RANK_TOL)
}

/// The freedom of `sys` at `(q, t)`: rank of Φ_q and the independent
/// coordinates from the sparse coordinate partitioning ([`partition_at`],
/// `O(nnz Φ_q)` for chains), and the joints whose relative motion is free
/// (appending its row raises the rank: one dense complete pivoting
/// ([`full_pivot_order`]) per joint, only up to
/// [`JOINT_TEST_MAX_COORDS`] coordinates).
pub fn freedom(sys: &System, q: &[f64], t: f64) -> Freedom {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let nb = sys.n_body_coords();
    let part = partition_at(sys, q, t);
    let rank = part.rank;
    let mut joints = Vec::new();
    if rank < nb && n <= JOINT_TEST_MAX_COORDS {
        let a = dense_jacobian(sys, q, t);
        let rank_of = |mut a: Vec<f64>, rows: usize| full_pivot_order(&mut a, rows, n, RANK_TOL);
        let dense_rank = rank_of(a.clone(), m).rank;
        for (k, c) in sys.constraints().iter().enumerate() {
            let Some(row) = relative_row(sys, c.geometry(), q) else {
                continue;
            };
            let mut b = a.clone();
            b.extend_from_slice(&row);
            if rank_of(b, m + 1).rank > dense_rank {
                joints.push(k);
            }
        }
    }
    Freedom {
        dof: nb - rank,
        redundant: m - rank,
        coordinates: part.independent.into_iter().filter(|&k| k < nb).collect(),
        joints,
    }
}

/// Positions, velocities, accelerations, multipliers and joint reactions
/// of a mechanism without freedom, time after time (module docs). Holds the
/// saddle-point solver (analysed once) and the last state as the next
/// Newton start.
pub struct InverseDynamics<'a> {
    sys: &'a System,
    index1: Index1<'a>,
    map: ReactionMap,
    jac: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    phi: Vec<f64>,
    phid: Vec<f64>,
    reactions: Vec<f64>,
    last_t: Option<f64>,
    iterations: usize,
    state_substeps: usize,
}

impl<'a> InverseDynamics<'a> {
    /// Set up for `sys` from the position guess `q0` at `t0`; refuses a
    /// mechanism with freedom left ([`InverseError::Underdetermined`]).
    pub fn new(
        sys: &'a System,
        q0: &[f64],
        t0: f64,
        opts: InverseOptions,
    ) -> Result<Self, InverseError> {
        if !(opts.tol.is_finite() && opts.tol > 0.0)
            || opts.max_iter == 0
            || opts.state_substeps == 0
        {
            return Err(InverseError::Invalid(format!(
                "tolerance must be finite and > 0, max_iter and state_substeps ≥ 1, got tol = {}, \
                 max_iter = {}, state_substeps = {}",
                opts.tol, opts.max_iter, opts.state_substeps
            )));
        }
        let n = sys.n_coords();
        if q0.len() != n {
            return Err(InverseError::Invalid(format!(
                "q0 has {} entries for {n} coordinates",
                q0.len()
            )));
        }
        let f = freedom(sys, q0, t0);
        if f.dof > 0 {
            return Err(InverseError::Underdetermined {
                dof: f.dof,
                rank: sys.n_body_coords() - f.dof,
                n,
                coordinates: f
                    .coordinates
                    .iter()
                    .map(|&k| coordinate_label(sys, k))
                    .collect(),
                joints: f
                    .joints
                    .iter()
                    .map(|&k| crate::output::joint_label(sys, k))
                    .collect(),
            });
        }
        let index1 = Index1::new(
            sys,
            Index1Options {
                projection: Projection {
                    enabled: true,
                    tol: opts.tol,
                    max_iter: opts.max_iter,
                    ..Projection::default()
                },
                ..Index1Options::default()
            },
        )?;
        let m = sys.n_constraints();
        // the controller states start from their initial values
        let mut qd = vec![0.0; n];
        for (v, st) in qd[sys.n_body_coords()..].iter_mut().zip(sys.states()) {
            *v = st.initial;
        }
        Ok(Self {
            sys,
            index1,
            map: sys.reaction_map(),
            jac: vec![0.0; sys.jacobian_pattern().len()],
            q: q0.to_vec(),
            qd,
            qdd: vec![0.0; n],
            phi: vec![0.0; m],
            phid: vec![0.0; m],
            reactions: vec![0.0; 3 * sys.constraints().len()],
            last_t: None,
            iterations: 0,
            state_substeps: opts.state_substeps,
        })
    }

    /// Start the controller states from `z` (one value per
    /// [`System::states`]) instead of their initial values; before the
    /// first [`InverseDynamics::at`].
    pub fn set_states(&mut self, z: &[f64]) -> Result<(), InverseError> {
        let nb = self.sys.n_body_coords();
        if z.len() != self.qd.len() - nb || z.iter().any(|v| !v.is_finite()) {
            return Err(InverseError::Invalid(format!(
                "{} finite controller-state values expected, got {z:?}",
                self.qd.len() - nb
            )));
        }
        self.qd[nb..].copy_from_slice(z);
        Ok(())
    }

    /// Positions and velocities at `ts` (z not touched), by Newton from
    /// the Taylor step of `(q, q̇, q̈)` at `t`.
    #[allow(clippy::too_many_arguments)]
    fn kinematics(
        &mut self,
        t: f64,
        base: (&[f64], &[f64], &[f64]),
        ts: f64,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<(), InverseError> {
        let h = ts - t;
        for i in 0..q.len() {
            q[i] = base.0[i] + h * base.1[i] + 0.5 * h * h * base.2[i];
            qd[i] = base.1[i] + h * base.2[i];
        }
        match self.index1.project(ts, q, qd) {
            Ok(k) => {
                self.iterations += k;
                Ok(())
            }
            Err(FormulationError::Projection {
                residual,
                tol,
                iterations,
                ..
            }) => Err(InverseError::Position {
                t: ts,
                residual,
                tol,
                iterations,
            }),
            Err(e) => Err(e.into()),
        }
    }

    /// The controller states at `t` from those at the last output time
    /// (module docs: RK4 along the prescribed motion).
    fn integrate_states(&mut self, t_prev: f64, t: f64) -> Result<Vec<f64>, InverseError> {
        let sys = self.sys;
        let (n, nb) = (sys.n_coords(), sys.n_body_coords());
        let base = (self.q.clone(), self.qd.clone(), self.qdd.clone());
        let mut z = self.qd[nb..].to_vec();
        let steps = self.state_substeps;
        let h = (t - t_prev) / steps as f64;
        let (mut q, mut qd, mut g) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        // the kinematics at a time (z-independent), then ż at (that, z)
        let mut kin = |me: &mut Self, ts: f64| -> Result<(Vec<f64>, Vec<f64>), InverseError> {
            me.kinematics(t_prev, (&base.0, &base.1, &base.2), ts, &mut q, &mut qd)?;
            Ok((q.clone(), qd.clone()))
        };
        let rate = |at: &(Vec<f64>, Vec<f64>), ts: f64, z: &[f64], g: &mut [f64]| -> Vec<f64> {
            let mut v = at.1.clone();
            v[nb..].copy_from_slice(z);
            sys.forces_into(ts, &at.0, &v, g);
            g[nb..].to_vec()
        };
        let mut start = (base.0.clone(), base.1.clone());
        for i in 0..steps {
            let ta = t_prev + i as f64 * h;
            let tb = if i + 1 == steps { t } else { ta + h };
            let mid = kin(self, ta + 0.5 * h)?;
            let end = kin(self, tb)?;
            let k1 = rate(&start, ta, &z, &mut g);
            let zs: Vec<f64> = z.iter().zip(&k1).map(|(z, k)| z + 0.5 * h * k).collect();
            let k2 = rate(&mid, ta + 0.5 * h, &zs, &mut g);
            let zs: Vec<f64> = z.iter().zip(&k2).map(|(z, k)| z + 0.5 * h * k).collect();
            let k3 = rate(&mid, ta + 0.5 * h, &zs, &mut g);
            let zs: Vec<f64> = z.iter().zip(&k3).map(|(z, k)| z + h * k).collect();
            let k4 = rate(&end, tb, &zs, &mut g);
            for j in 0..z.len() {
                z[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
            start = end;
        }
        if let Some(k) = z.iter().position(|v| !v.is_finite()) {
            return Err(InverseError::Invalid(format!(
                "controller state '{}' is not finite at t = {t} s",
                sys.states()[k].name
            )));
        }
        Ok(z)
    }

    /// Newton iterations of the position solves so far.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// The state at time `t` (module docs), as an output row: `q`, `q̇`,
    /// `q̈`, λ and the joint reactions; energy not computed.
    pub fn at(&mut self, t: f64) -> Result<Sample<'_>, InverseError> {
        if !t.is_finite() {
            return Err(InverseError::Invalid(format!("time {t} is not finite")));
        }
        // the controller states along the motion since the last time
        let nb = self.sys.n_body_coords();
        let z = match self.last_t {
            Some(t_prev) if nb < self.qd.len() => Some(self.integrate_states(t_prev, t)?),
            _ => None,
        };
        // warm start: Taylor step from the last solution
        if let Some(t_prev) = self.last_t {
            let h = t - t_prev;
            for ((q, qd), qdd) in self.q.iter_mut().zip(&mut self.qd).zip(&self.qdd) {
                *q += h * *qd + 0.5 * h * h * qdd;
                *qd += h * qdd;
            }
        }
        if let Some(z) = z {
            self.qd[nb..].copy_from_slice(&z);
        }
        let sys = self.sys;
        match self.index1.project(t, &mut self.q, &mut self.qd) {
            Ok(k) => self.iterations += k,
            Err(FormulationError::Projection {
                residual,
                tol,
                iterations,
                ..
            }) => {
                return Err(InverseError::Position {
                    t,
                    residual,
                    tol,
                    iterations,
                })
            }
            Err(e) => return Err(e.into()),
        }
        self.index1
            .accelerations(t, &self.q, &self.qd, &mut self.qdd)?;
        self.last_t = Some(t);
        sys.phi(&self.q, t, &mut self.phi);
        sys.jacobian_values(&self.q, t, &mut self.jac);
        sys.jacobian_mul(&self.jac, &self.qd, &mut self.phid);
        let mut phi_t = vec![0.0; self.phi.len()];
        sys.phi_t(&self.q, t, &mut phi_t);
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        for (a, b) in self.phid.iter_mut().zip(&phi_t) {
            *a += b;
        }
        let lambda = self.index1.lambda();
        sys.joint_reactions(&self.map, &self.jac, lambda, &mut self.reactions);
        Ok(Sample {
            t,
            q: &self.q,
            qd: &self.qd,
            phi: &self.phi,
            constraint_norm: norm(&self.phi),
            velocity_constraint_norm: norm(&self.phid),
            qdd: Some(&self.qdd),
            lambda: Some(lambda),
            reactions: Some(&self.reactions),
            energy: None,
        })
    }
}
