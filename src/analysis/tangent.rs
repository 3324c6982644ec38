//! The tangent matrices of the constrained system at a state
//! `(q, q̇, λ, t)`: mass `M`, damping `C`, stiffness `K` and the
//! constraint Jacobian `Φ_q` — the blocks of the index-3 Newton matrix
//! ([`crate::formulation::Index3`]), evaluated by the same code (the
//! system's force Jacobians and constraint Hessians, generated kernels
//! where attached), exposed unscaled and exact.
//!
//! # Sign convention
//!
//! The equations of motion are `M q̈ + Φ_qᵀ(q, t) λ = g(q, q̇, t)`,
//! `Φ(q, t) = 0` (our λ; the paper's eq. (5) has −λ, see
//! [`crate::linalg`]). Perturbing a state `(q, q̇, q̈, λ)` that satisfies
//! them by `(δq, δq̇, δq̈, δλ)` at fixed `t` gives, to first order,
//!
//! ```text
//! M δq̈ + C δq̇ + K δq + Φ_qᵀ δλ = 0,      Φ_q δq = 0
//!
//! C = −∂g/∂q̇                (damping: positive for a damper)
//! K = −∂g/∂q + (Φ_qᵀλ)_q    (stiffness: positive for a spring; the
//!                            second term is the constraint forces'
//!                            geometric stiffness, with our λ)
//! ```
//!
//! (`M` is constant and diagonal in reference-point coordinates, so
//! `(M q̈)_q = 0`.) These are the `C_t`, `K_t` of the Newton matrix in
//! [`crate::formulation::Index3`]'s module docs. A static equilibrium is
//! stable when `K` is positive definite on the tangent space
//! `{δq : Φ_q δq = 0}`; the undamped modes solve `K x = ω² M x`,
//! `Φ_q x = 0`.
//!
//! The matrices are returned exactly as evaluated ([`Tangent::stiffness`]
//! and [`Tangent::damping`] may be unsymmetric: drag, friction, follower
//! loads). [`Tangent::write_saddle`] writes `c_m M + c_c C + c_k K` into a
//! [`SaddleMatrix`] through the Newton matrix's own assembly, so symmetric
//! storage receives the force Jacobians' reciprocal part, as the index-3
//! Newton matrix does.

use crate::formulation::dynamic_blocks::DynamicBlocks;
use crate::formulation::FormulationError;
use crate::linalg::{APattern, SaddleMatrix, Storage};
use crate::model::System;

/// A sparse matrix as `(row, column, value)` triplets; duplicate positions
/// are summed (as every consumer here does).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Triplets {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// The entries, in no particular order, duplicates to be summed.
    pub entries: Vec<(usize, usize, f64)>,
}

impl Triplets {
    /// An empty `rows × cols` matrix.
    pub fn new(rows: usize, cols: usize) -> Self {
        Self {
            rows,
            cols,
            entries: Vec::new(),
        }
    }

    /// `y = A x` (`x` of length `cols`, `y` of length `rows`).
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        for &(i, j, v) in &self.entries {
            y[i] += v * x[j];
        }
    }

    /// `y = Aᵀ x` (`x` of length `rows`, `y` of length `cols`).
    pub fn tmul_vec(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        for &(i, j, v) in &self.entries {
            y[j] += v * x[i];
        }
    }

    /// The same matrix with entries sorted by (column, row), duplicates
    /// summed and exact zeros dropped.
    pub fn compressed(&self) -> Self {
        let mut e = self.entries.clone();
        e.sort_by_key(|&(i, j, _)| (j, i));
        let mut out: Vec<(usize, usize, f64)> = Vec::with_capacity(e.len());
        for (i, j, v) in e {
            match out.last_mut() {
                Some(last) if last.0 == i && last.1 == j => last.2 += v,
                _ => out.push((i, j, v)),
            }
        }
        out.retain(|&(_, _, v)| v != 0.0);
        Self {
            rows: self.rows,
            cols: self.cols,
            entries: out,
        }
    }

    /// The matrix as a dense faer matrix (small systems, cross-checks).
    pub fn to_dense(&self) -> faer::Mat<f64> {
        let mut d = faer::Mat::<f64>::zeros(self.rows, self.cols);
        for &(i, j, v) in &self.entries {
            d[(i, j)] += v;
        }
        d
    }
}

/// The tangent matrices `M`, `C`, `K`, `Φ_q` of a [`System`] at a state
/// (module docs for the sign convention). Build once per system
/// ([`Tangent::new`]: the patterns), then [`Tangent::evaluate`] at each
/// state of interest and read the matrices.
pub struct Tangent<'a> {
    sys: &'a System,
    a: APattern,
    blocks: DynamicBlocks,
    jac: Vec<f64>,
    evaluated: bool,
}

impl std::fmt::Debug for Tangent<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tangent")
            .field("n", &self.sys.n_coords())
            .field("m", &self.sys.n_constraints())
            .field("a_entries", &self.a.len())
            .field("evaluated", &self.evaluated)
            .finish()
    }
}

impl<'a> Tangent<'a> {
    /// Register the patterns of the force Jacobians and constraint
    /// Hessians of `sys` (once; nothing is evaluated yet).
    pub fn new(sys: &'a System) -> Self {
        let mut a = APattern::new();
        let blocks = DynamicBlocks::register(sys, &mut a);
        Self {
            sys,
            a,
            blocks,
            jac: vec![0.0; sys.jacobian_pattern().len()],
            evaluated: false,
        }
    }

    /// The system.
    pub fn system(&self) -> &'a System {
        self.sys
    }

    /// Evaluate ∂g/∂q, ∂g/∂q̇, (Φ_qᵀλ)_q and Φ_q at `(t, q, q̇, λ)`
    /// (λ in our sign convention, of length `n_constraints`).
    /// [`FormulationError::NonFinite`] names a non-finite evaluation;
    /// [`FormulationError::Invalid`] a wrong length.
    pub fn evaluate(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lambda: &[f64],
    ) -> Result<(), FormulationError> {
        let (n, m) = (self.sys.n_coords(), self.sys.n_constraints());
        if q.len() != n || qd.len() != n || lambda.len() != m {
            return Err(FormulationError::Invalid(format!(
                "tangent matrices: expected q, q̇ of length {n} and λ of length {m}, got {}, {}, {}",
                q.len(),
                qd.len(),
                lambda.len()
            )));
        }
        self.blocks
            .evaluate(self.sys, t, q, qd, lambda, true, true, &mut self.jac)?;
        self.evaluated = true;
        Ok(())
    }

    /// Number of coordinates `n`.
    pub fn n(&self) -> usize {
        self.sys.n_coords()
    }

    /// Number of constraint rows `m`.
    pub fn m(&self) -> usize {
        self.sys.n_constraints()
    }

    /// The diagonal of the (constant) mass matrix `M` \[kg, kg m²\].
    pub fn mass_diagonal(&self) -> &[f64] {
        self.sys.mass_diagonal()
    }

    /// `M` as triplets (`n × n`, diagonal).
    pub fn mass(&self) -> Triplets {
        self.square(
            self.sys
                .mass_diagonal()
                .iter()
                .enumerate()
                .map(|(i, &v)| (i, i, v)),
        )
    }

    /// An `n × n` matrix of `entries`.
    fn square(&self, entries: impl Iterator<Item = (usize, usize, f64)>) -> Triplets {
        let n = self.n();
        Triplets {
            rows: n,
            cols: n,
            entries: entries.collect(),
        }
    }

    /// `C = −∂g/∂q̇` at the last evaluated state (`n × n`, exact, possibly
    /// unsymmetric).
    pub fn damping(&self) -> Triplets {
        self.square(self.damping_entries())
    }

    /// The entries of [`Tangent::damping`], in its order, without
    /// collecting them.
    pub fn damping_entries(&self) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        self.assert_evaluated();
        let (_, dqd, _) = self.blocks.values();
        self.sys
            .force_jacobian_pattern()
            .iter()
            .zip(dqd)
            .map(|(&(i, j), &v)| (i, j, -v))
    }

    /// `K = −∂g/∂q + (Φ_qᵀλ)_q` at the last evaluated state (`n × n`,
    /// exact, possibly unsymmetric).
    pub fn stiffness(&self) -> Triplets {
        self.square(self.stiffness_entries())
    }

    /// The entries of [`Tangent::stiffness`], in its order (the force
    /// Jacobian's, then each Hessian entry and its mirror), without
    /// collecting them.
    pub fn stiffness_entries(&self) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        self.assert_evaluated();
        let (dq, _, hess) = self.blocks.values();
        let force = self
            .sys
            .force_jacobian_pattern()
            .iter()
            .zip(dq)
            .map(|(&(i, j), &v)| (i, j, -v));
        // the Hessian pattern is one triangle of a symmetric matrix
        let hessian = self
            .sys
            .hessian_pattern()
            .iter()
            .zip(hess)
            .flat_map(|(&(i, j), &v)| {
                let mirror = (i != j).then_some((j, i, v));
                std::iter::once((i, j, v)).chain(mirror)
            });
        force.chain(hessian)
    }

    /// The scale of ω² \[1/s²\] at the last evaluated state: the largest
    /// `|K_ii| / M_ii`, or 1 when that is not positive and finite (`K`
    /// without a diagonal). The static Newton iteration's regularisation
    /// and the modes' fallback shift are fractions of it.
    pub fn stiffness_scale(&self) -> f64 {
        let mass = self.mass_diagonal();
        let mut d = vec![0.0f64; mass.len()];
        for (i, j, v) in self.stiffness_entries() {
            if i == j {
                d[i] += v;
            }
        }
        let r = d
            .iter()
            .zip(mass)
            .fold(0.0f64, |a, (k, mi)| a.max((k / mi).abs()));
        if r > 0.0 && r.is_finite() {
            r
        } else {
            1.0
        }
    }

    /// `Φ_q` at the last evaluated state (`m × n`).
    pub fn constraint_jacobian(&self) -> Triplets {
        self.assert_evaluated();
        Triplets {
            rows: self.m(),
            cols: self.n(),
            entries: self
                .sys
                .jacobian_pattern()
                .iter()
                .zip(&self.jac)
                .map(|(&(r, c), &v)| (r, c, v))
                .collect(),
        }
    }

    /// The values of `Φ_q` in the order of [`System::jacobian_pattern`]
    /// (what [`SaddleMatrix::set_jacobian`] takes).
    pub fn jacobian_values(&self) -> &[f64] {
        &self.jac
    }

    /// An empty saddle-point matrix `[A Φ_qᵀ; Φ_q D]` in `storage` whose
    /// `A` pattern holds `M`, `C` and `K` (fill with
    /// [`Tangent::write_saddle`]).
    pub fn saddle_matrix(&self, storage: Storage) -> SaddleMatrix {
        SaddleMatrix::with_storage(
            self.n(),
            self.m(),
            &self.a,
            self.sys.jacobian_pattern(),
            storage,
        )
    }

    /// Zero `k` (built by [`Tangent::saddle_matrix`]) and write
    /// `A = c_m M + c_c C + c_k K` and `Φ_q` from the last evaluation; `D`
    /// stays 0. Symmetric storage receives the force Jacobians' reciprocal
    /// part, as the index-3 Newton matrix (exact for symmetric `K`, `C`).
    pub fn write_saddle(&self, k: &mut SaddleMatrix, [c_m, c_c, c_k]: [f64; 3]) {
        self.assert_evaluated();
        self.blocks.write(self.sys, k, [c_m, c_c, c_k]);
        k.set_jacobian(&self.jac);
    }

    /// [`Tangent::saddle_matrix`] with only the constraint rows `rows`
    /// (ascending, distinct), renumbered `0 … rows.len() − 1` in that
    /// order: the saddle matrix of the constraints without their redundant
    /// rows (fill with [`Tangent::write_saddle_of_rows`]).
    pub fn saddle_matrix_of_rows(&self, storage: Storage, rows: &[usize]) -> SaddleMatrix {
        let (pattern, _) = self.row_subset(rows);
        SaddleMatrix::with_storage(self.n(), rows.len(), &self.a, &pattern, storage)
    }

    /// [`Tangent::write_saddle`] into a matrix of
    /// [`Tangent::saddle_matrix_of_rows`] with the same `rows`: `A` in full,
    /// `Φ_q` of those rows only.
    pub fn write_saddle_of_rows(&self, k: &mut SaddleMatrix, coeffs: [f64; 3], rows: &[usize]) {
        self.assert_evaluated();
        self.blocks.write(self.sys, k, coeffs);
        let (_, which) = self.row_subset(rows);
        let vals: Vec<f64> = which.iter().map(|&e| self.jac[e]).collect();
        k.set_jacobian(&vals);
    }

    /// The Jacobian pattern of the constraint rows `rows`, renumbered, and
    /// the positions of its entries in [`System::jacobian_pattern`].
    fn row_subset(&self, rows: &[usize]) -> (Vec<(usize, usize)>, Vec<usize>) {
        let mut new_row = vec![usize::MAX; self.m()];
        for (k, &r) in rows.iter().enumerate() {
            new_row[r] = k;
        }
        let mut pattern = Vec::new();
        let mut which = Vec::new();
        for (e, &(r, c)) in self.sys.jacobian_pattern().iter().enumerate() {
            if new_row[r] != usize::MAX {
                pattern.push((new_row[r], c));
                which.push(e);
            }
        }
        (pattern, which)
    }

    fn assert_evaluated(&self) {
        assert!(
            self.evaluated,
            "Tangent: evaluate() must be called before reading the matrices"
        );
    }
}
