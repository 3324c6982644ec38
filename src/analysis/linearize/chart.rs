//! The chart `q(z)` of the linearisation and its sparse solves: positions
//! by Newton with the independent coordinates held, velocities and
//! accelerations by saddle-point solves (module docs of [`super`]).

use super::LinearizeError;
use crate::linalg::{
    solver_for, APattern, LinalgError, SaddleMatrix, SaddlePointSolver, SolverKind, SolverOptions,
};
use crate::model::System;
use faer::Mat;

/// Sparse solves of the chart (`[1 Φ̃ᵀ; Φ̃ 0]`) and of the dynamics
/// (`[M Φ_qᵀ; Φ_q 0]`) at a position.
pub(super) struct Chart<'a> {
    sys: &'a System,
    t: f64,
    independent: Vec<usize>,
    lock: SaddleMatrix,
    lock_solver: Box<dyn SaddlePointSolver>,
    dyn_k: SaddleMatrix,
    dyn_solver: Box<dyn SaddlePointSolver>,
    jac: Vec<f64>,
    lock_jac: Vec<f64>,
    x_lock: Vec<f64>,
    x_dyn: Vec<f64>,
    newton_tol: f64,
    /// Rows of Φ of the driven inputs, whose targets are shifted by σ.
    drive_rows: Vec<usize>,
}

impl<'a> Chart<'a> {
    pub(super) fn new(
        sys: &'a System,
        t: f64,
        independent: Vec<usize>,
        newton_tol: f64,
        drive_rows: Vec<usize>,
    ) -> Result<Self, LinearizeError> {
        let (n, m, f) = (sys.n_coords(), sys.n_constraints(), independent.len());
        let mut pattern = sys.jacobian_pattern().to_vec();
        pattern.extend(independent.iter().enumerate().map(|(i, &c)| (m + i, c)));
        let lin = |source| LinearizeError::Linear { t, source };
        let mut lock_solver = solver_for(SolverKind::Auto, n + m + f, SolverOptions::default());
        let lock =
            SaddleMatrix::with_storage(n, m + f, &APattern::new(), &pattern, lock_solver.storage());
        lock_solver.analyze(&lock).map_err(lin)?;
        let mut dyn_solver = solver_for(SolverKind::Auto, n + m, SolverOptions::default());
        let dyn_k = SaddleMatrix::with_storage(
            n,
            m,
            &APattern::new(),
            sys.jacobian_pattern(),
            dyn_solver.storage(),
        );
        dyn_solver.analyze(&dyn_k).map_err(lin)?;
        let nj = sys.jacobian_pattern().len();
        let mut lock_jac = vec![0.0; nj + f];
        lock_jac[nj..].fill(1.0);
        Ok(Self {
            sys,
            t,
            independent,
            lock,
            lock_solver,
            dyn_k,
            dyn_solver,
            jac: vec![0.0; nj],
            lock_jac,
            x_lock: vec![0.0; n + m + f],
            x_dyn: vec![0.0; n + m],
            newton_tol,
            drive_rows,
        })
    }

    pub(super) fn lin(&self, source: LinalgError) -> LinearizeError {
        LinearizeError::Linear { t: self.t, source }
    }

    /// Factorise the chart matrix at `q`.
    pub(super) fn factor_lock(&mut self, q: &[f64]) -> Result<(), LinearizeError> {
        let nj = self.jac.len();
        self.sys
            .jacobian_values(q, self.t, &mut self.lock_jac[..nj]);
        let ones = vec![1.0; self.sys.n_coords()];
        self.lock.set_a_diagonal(&ones);
        self.lock.set_jacobian(&self.lock_jac);
        self.lock_solver
            .factorize(&self.lock)
            .map_err(|e| self.lin(e))?;
        Ok(())
    }

    /// Solve `Φ̃ v = [r_phi; r_lock]` with the factorised chart matrix.
    pub(super) fn solve_lock(
        &mut self,
        r_phi: &[f64],
        r_lock: &[f64],
    ) -> Result<Vec<f64>, LinearizeError> {
        let (n, m) = (self.sys.n_coords(), self.sys.n_constraints());
        self.x_lock[..n].fill(0.0);
        self.x_lock[n..n + m].copy_from_slice(r_phi);
        self.x_lock[n + m..].copy_from_slice(r_lock);
        let mut x = std::mem::take(&mut self.x_lock);
        let r = self.lock_solver.solve_in_place(&self.lock, &mut x);
        self.x_lock = x;
        r.map_err(|e| self.lin(e))?;
        Ok(self.x_lock[..n].to_vec())
    }

    /// The null-space basis at `q` (columns).
    pub(super) fn basis(&mut self, q: &[f64]) -> Result<Vec<Vec<f64>>, LinearizeError> {
        self.factor_lock(q)?;
        let (m, f) = (self.sys.n_constraints(), self.independent.len());
        let zero = vec![0.0; m];
        let mut e = vec![0.0; f];
        let mut cols = Vec::with_capacity(f);
        for j in 0..f {
            e.fill(0.0);
            e[j] = 1.0;
            cols.push(self.solve_lock(&zero, &e)?);
        }
        Ok(cols)
    }

    /// Positions with `q_I = z` on `Φ(q, t) = σ e_r` (the drive rows
    /// shifted by `sigma`), Newton from `guess`.
    pub(super) fn positions(
        &mut self,
        guess: &[f64],
        z: &[f64],
        sigma: &[f64],
    ) -> Result<Vec<f64>, LinearizeError> {
        let m = self.sys.n_constraints();
        let f = self.independent.len();
        let mut q = guess.to_vec();
        for (&c, &v) in self.independent.iter().zip(z) {
            q[c] = v;
        }
        let mut phi = vec![0.0; m];
        let zero = vec![0.0; f];
        for it in 0..=30 {
            self.sys.phi(&q, self.t, &mut phi);
            for (&r, &s) in self.drive_rows.iter().zip(sigma) {
                phi[r] -= s;
            }
            let res = phi.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
            if res <= self.newton_tol {
                return Ok(q);
            }
            if it == 30 || !res.is_finite() {
                return Err(LinearizeError::Chart {
                    t: self.t,
                    residual: res,
                    iterations: it,
                });
            }
            self.factor_lock(&q)?;
            for v in &mut phi {
                *v = -*v;
            }
            let dq = self.solve_lock(&phi, &zero)?;
            for (a, d) in q.iter_mut().zip(&dq) {
                *a += d;
            }
        }
        unreachable!()
    }

    /// Velocities at `q` with `q̇_I = zd`: `Φ̃ q̇ = [−Φ_t + σ̇ e_r; ż]`.
    pub(super) fn velocities(
        &mut self,
        q: &[f64],
        zd: &[f64],
        sigma_rate: &[f64],
    ) -> Result<Vec<f64>, LinearizeError> {
        let mut phi_t = vec![0.0; self.sys.n_constraints()];
        self.sys.phi_t(q, self.t, &mut phi_t);
        for v in &mut phi_t {
            *v = -*v;
        }
        for (&r, &s) in self.drive_rows.iter().zip(sigma_rate) {
            phi_t[r] += s;
        }
        self.factor_lock(q)?;
        self.solve_lock(&phi_t, zd)
    }

    /// Factorise `[M Φ_qᵀ; Φ_q 0]` at `q`.
    pub(super) fn factor_dyn(&mut self, q: &[f64]) -> Result<(), LinearizeError> {
        self.sys.jacobian_values(q, self.t, &mut self.jac);
        self.dyn_k.set_a_diagonal(self.sys.mass_diagonal());
        self.dyn_k.set_jacobian(&self.jac);
        self.dyn_solver
            .factorize(&self.dyn_k)
            .map_err(|e| LinearizeError::Linear {
                t: self.t,
                source: e,
            })?;
        Ok(())
    }

    /// Solve the factorised dynamics matrix for `[rhs_q; rhs_c]`.
    pub(super) fn solve_dyn(
        &mut self,
        rhs_q: &[f64],
        rhs_c: &[f64],
    ) -> Result<Vec<f64>, LinearizeError> {
        let n = self.sys.n_coords();
        self.x_dyn[..n].copy_from_slice(rhs_q);
        self.x_dyn[n..].copy_from_slice(rhs_c);
        let mut x = std::mem::take(&mut self.x_dyn);
        let r = self.dyn_solver.solve_in_place(&self.dyn_k, &mut x);
        self.x_dyn = x;
        r.map_err(|e| self.lin(e))?;
        Ok(self.x_dyn.clone())
    }

    /// `(q̈, λ)` at `(q, q̇)` from eq. (5) without Baumgarte terms.
    pub(super) fn accelerations(
        &mut self,
        q: &[f64],
        qd: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>), LinearizeError> {
        let (n, m) = (self.sys.n_coords(), self.sys.n_constraints());
        let mut g = vec![0.0; n];
        let mut gamma = vec![0.0; m];
        self.sys.forces_into(self.t, q, qd, &mut g);
        self.sys
            .constraint_terms(q, qd, self.t, None, &mut self.jac, &mut gamma);
        if let Some(i) = g.iter().chain(&gamma).position(|v| !v.is_finite()) {
            return Err(LinearizeError::Invalid(format!(
                "non-finite force or γ entry {i} at t = {}",
                self.t
            )));
        }
        self.factor_dyn(q)?;
        let x = self.solve_dyn(&g, &gamma)?;
        Ok((x[..n].to_vec(), x[n..].to_vec()))
    }
}

/// Dense `VᵀXW` of an `n × n` sparse `X` and columns `v`, `w`.
pub(super) fn project(x: &crate::analysis::Triplets, v: &[Vec<f64>], w: &[Vec<f64>]) -> Mat<f64> {
    let mut xw = vec![0.0; x.rows];
    let mut out = Mat::<f64>::zeros(v.len(), w.len());
    for (j, wj) in w.iter().enumerate() {
        x.mul_vec(wj, &mut xw);
        for (i, vi) in v.iter().enumerate() {
            out[(i, j)] = vi.iter().zip(&xw).map(|(a, b)| a * b).sum();
        }
    }
    out
}
