//! The complex Newton matrix of the index-3 equations, for the transformed
//! stages of Radau IIA ([`crate::integrate::Radau5`]; Hairer & Wanner,
//! Solving ODEs II, §IV.8):
//!
//! ```text
//! [ c₀ M + c₁ C_t + c₂ K_t   Φ_qᵀ ] [x]   [b]        c₁, c₂ ∈ ℂ,  x, y, b, d ∈ ℂ
//! [ Φ_q                      0    ] [y] = [d]        C_t = −∂g/∂q̇,  K_t = −∂g/∂q + (Φ_qᵀλ)_q
//! ```
//!
//! With `G = c₀ M + c₁ C_t + c₂ K_t = G_r + i G_i` (M, C_t, K_t real) it
//! is solved as the real system of twice the size
//!
//! ```text
//! [ G_r  −G_i  Φ_qᵀ  0   ] [x_r]   [b_r]
//! [ G_i   G_r  0     Φ_qᵀ] [x_i] = [b_i]
//! [ Φ_q   0    0     0   ] [y_r]   [d_r]
//! [ 0     Φ_q  0     0   ] [y_i]   [d_i]
//! ```
//!
//! a [`SaddleMatrix`] with `2n` coordinates and `2m` rows, unsymmetric
//! `A` block (full storage) factorised by faer's sparse LU
//! ([`SolverKind::SparseLu`]). The pattern is the real Newton matrix's
//! ([`Index3`](super::Index3): force Jacobians ∪ constraint Hessians) in
//! each of the four blocks, built once; the Jacobians are evaluated by
//! the same [`System`] calls as [`super::Index3`]'s.

use super::{all_finite, FormulationError};
use crate::integrate::{ComplexNewton, SystemError};
use crate::linalg::{
    solver_for, APattern, SaddleMatrix, SaddlePointSolver, SolverKind, SolverOptions, SolverStats,
    Symmetry,
};
use crate::model::{FdWorkspace, System};

/// Where one `A` entry of the embedded matrix takes its value from: the
/// force-Jacobian entry or the Hessian entry `e`, and which part of the
/// complex value (`Re`, `−Im` or `Im`).
#[derive(Debug, Clone, Copy)]
enum Source {
    Force(usize, Part),
    Hessian(usize, Part),
}

#[derive(Debug, Clone, Copy)]
enum Part {
    Re,
    NegIm,
    Im,
}

/// The complex Newton matrix of a [`System`] (module docs) and its sparse
/// LU.
pub struct Index3Complex<'a> {
    sys: &'a System,
    n: usize,
    m: usize,
    k: SaddleMatrix,
    solver: Box<dyn SaddlePointSolver>,
    sources: Vec<Source>,
    dq: Vec<f64>,
    dqd: Vec<f64>,
    hess: Vec<f64>,
    jac: Vec<f64>,
    jac2: Vec<f64>,
    x: Vec<f64>,
    ws: FdWorkspace,
    factorizations: usize,
}

impl std::fmt::Debug for Index3Complex<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Index3Complex")
            .field("n", &self.n)
            .field("m", &self.m)
            .field("nnz", &self.k.nnz())
            .finish()
    }
}

impl<'a> Index3Complex<'a> {
    /// Build the embedded pattern and run the LU's symbolic analysis (once).
    pub fn new(sys: &'a System) -> Result<Self, FormulationError> {
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let mut entries = Vec::new();
        let mut sources = Vec::new();
        // each real entry (i, j) in the four blocks: Re at (i, j) and
        // (n+i, n+j), −Im at (i, n+j), Im at (n+i, j)
        let mut push = |i: usize, j: usize, src: &dyn Fn(Part) -> Source| {
            for (e, p) in [
                ((i, j), Part::Re),
                ((n + i, n + j), Part::Re),
                ((i, n + j), Part::NegIm),
                ((n + i, j), Part::Im),
            ] {
                entries.push(e);
                sources.push(src(p));
            }
        };
        for (e, &(i, j)) in sys.force_jacobian_pattern().iter().enumerate() {
            push(i, j, &|p| Source::Force(e, p));
        }
        // a Hessian entry stands for (i, j) and (j, i)
        for (e, &(i, j)) in sys.hessian_pattern().iter().enumerate() {
            push(i, j, &|p| Source::Hessian(e, p));
            if i != j {
                push(j, i, &|p| Source::Hessian(e, p));
            }
        }
        let mut a = APattern::new();
        a.push_block(&entries, Symmetry::Unsymmetric);
        let jp = sys.jacobian_pattern();
        let jp2: Vec<(usize, usize)> = jp
            .iter()
            .copied()
            .chain(jp.iter().map(|&(r, c)| (m + r, n + c)))
            .collect();
        let mut solver = solver_for(
            SolverKind::SparseLu,
            2 * (n + m),
            SolverOptions {
                residual_check: false,
            },
        );
        let k = SaddleMatrix::with_storage(2 * n, 2 * m, &a, &jp2, solver.storage());
        solver
            .analyze(&k)
            .map_err(|source| FormulationError::Linear {
                t: f64::NAN,
                source,
            })?;
        Ok(Self {
            sys,
            n,
            m,
            k,
            solver,
            sources,
            dq: vec![0.0; sys.force_jacobian_pattern().len()],
            dqd: vec![0.0; sys.force_jacobian_pattern().len()],
            hess: vec![0.0; sys.hessian_pattern().len()],
            jac: vec![0.0; jp.len()],
            jac2: vec![0.0; 2 * jp.len()],
            x: vec![0.0; 2 * (n + m)],
            ws: FdWorkspace::default(),
            factorizations: 0,
        })
    }

    /// The embedded real matrix (pattern and last values).
    pub fn matrix(&self) -> &SaddleMatrix {
        &self.k
    }

    /// Factorisations so far.
    pub fn factorizations(&self) -> usize {
        self.factorizations
    }

    /// Counters of the sparse LU.
    pub fn solver_stats(&self) -> SolverStats {
        self.solver.stats()
    }

    /// Assemble `[c₀ M + c₁ C_t + c₂ K_t, Φ_qᵀ; Φ_q, 0]` at `(t, q, q̇, λ)`
    /// (coefficients `[re, im]`) in its real embedding and factorise it.
    #[allow(clippy::too_many_arguments)]
    pub fn assemble_and_factorize(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lambda: &[f64],
        c: [[f64; 2]; 3],
    ) -> Result<(), FormulationError> {
        let (sys, n) = (self.sys, self.n);
        let [c0, c1, c2] = c;
        if c0[1] != 0.0 {
            return Err(FormulationError::Invalid(
                "complex Newton matrix: the mass coefficient c₀ must be real".into(),
            ));
        }
        self.dq.fill(0.0);
        self.dqd.fill(0.0);
        sys.add_force_jacobians(t, q, qd, &mut self.dq, &mut self.dqd, &mut self.ws);
        self.hess.fill(0.0);
        sys.add_constraint_hessians(q, t, lambda, &mut self.hess, &mut self.ws);
        sys.jacobian_values(q, t, &mut self.jac);
        all_finite(
            t,
            &[
                ("the force Jacobian ∂g/∂q", &self.dq),
                ("the force Jacobian ∂g/∂q̇", &self.dqd),
                ("the constraint Hessian (Φ_qᵀλ)_q", &self.hess),
                ("the constraint Jacobian Φ_q", &self.jac),
            ],
        )?;
        let k = &mut self.k;
        k.set_zero();
        for (i, &mi) in sys.mass_diagonal().iter().enumerate() {
            // c₀ M: Re on both diagonal blocks, Im off the diagonal blocks
            k.add_diagonal(i, c0[0] * mi);
            k.add_diagonal(n + i, c0[0] * mi);
        }
        let pick = |v: [f64; 2], p: Part| match p {
            Part::Re => v[0],
            Part::NegIm => -v[1],
            Part::Im => v[1],
        };
        for (id, s) in self.sources.iter().enumerate() {
            let v = match *s {
                // −(c₁ ∂g/∂q̇ + c₂ ∂g/∂q)
                Source::Force(e, p) => {
                    let (a, b) = (self.dqd[e], self.dq[e]);
                    pick([-(c1[0] * a + c2[0] * b), -(c1[1] * a + c2[1] * b)], p)
                }
                // c₂ (Φ_qᵀλ)_q
                Source::Hessian(e, p) => pick([c2[0] * self.hess[e], c2[1] * self.hess[e]], p),
            };
            k.add_a(id, v);
        }
        let l = self.jac.len();
        self.jac2[..l].copy_from_slice(&self.jac);
        self.jac2[l..].copy_from_slice(&self.jac);
        k.set_jacobian(&self.jac2);
        self.factorizations += 1;
        self.solver
            .factorize(k)
            .map_err(|source| FormulationError::Linear { t, source })?;
        Ok(())
    }

    /// Solve with the last factorisation: `re + i·im` (each `[x; y]`, length
    /// `n + m`) is overwritten with the solution.
    pub fn solve_in_place(
        &mut self,
        t: f64,
        re: &mut [f64],
        im: &mut [f64],
    ) -> Result<(), FormulationError> {
        let (n, m) = (self.n, self.m);
        let x = &mut self.x;
        x[..n].copy_from_slice(&re[..n]);
        x[n..2 * n].copy_from_slice(&im[..n]);
        x[2 * n..2 * n + m].copy_from_slice(&re[n..]);
        x[2 * n + m..].copy_from_slice(&im[n..]);
        self.solver
            .solve_in_place(&self.k, x)
            .map_err(|source| FormulationError::Linear { t, source })?;
        re[..n].copy_from_slice(&x[..n]);
        im[..n].copy_from_slice(&x[n..2 * n]);
        re[n..].copy_from_slice(&x[2 * n..2 * n + m]);
        im[n..].copy_from_slice(&x[2 * n + m..]);
        Ok(())
    }
}

impl ComplexNewton for Index3Complex<'_> {
    fn factorize_complex(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lambda: &[f64],
        c: [[f64; 2]; 3],
    ) -> Result<(), SystemError> {
        self.assemble_and_factorize(t, q, qd, lambda, c)
            .map_err(SystemError::new)
    }
    fn solve_complex(&mut self, t: f64, re: &mut [f64], im: &mut [f64]) -> Result<(), SystemError> {
        self.solve_in_place(t, re, im).map_err(SystemError::new)
    }
}
