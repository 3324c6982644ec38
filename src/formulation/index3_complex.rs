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
//! the same code as [`super::Index3`]'s (`BlockValues::evaluate`).
//!
//! **Chain patterns** ([`ComplexSolverKind::Auto`], the default): when the
//! real Newton matrix's pattern is a chain's (the envelope of
//! [`crate::linalg::ChainLdlt`]), `G` is kept complex and factorised by
//! [`ComplexChainLdlt`] (LDLᵀ without conjugation): `K_r` = the real
//! Newton matrix at `(c₀, Re c₁, Re c₂)`, `K_i` = its `A` block at
//! `(0, Im c₁, Im c₂)` with `Φ_q` = 0, both assembled as
//! [`super::Index3`]'s (the reciprocal part of the force Jacobians, so
//! unsymmetric forces make it a modified Newton, as the real stage's) from
//! one evaluation of the Jacobians (the LU of the real embedding it
//! replaces dominated a radau5 run: docs/radau.md). A pivot that vanishes (no pivoting here) falls back to
//! the LU, built then, for the rest of the run.

use super::dynamic_blocks::{BlockValues, DynamicBlocks};
use super::state_border::ComplexStateBorder;
use super::{linear_at, FormulationError};
use crate::integrate::{ComplexNewton, StateView, SystemError};
use crate::linalg::{
    solver_for, APattern, ComplexChainLdlt, SaddleMatrix, SaddlePointSolver, SolverKind,
    SolverOptions, Storage, Symmetry,
};
use crate::model::System;

/// How [`Index3Complex`] factorises the complex Newton matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ComplexSolverKind {
    /// [`ComplexChainLdlt`] when the pattern is a chain's, else the sparse
    /// LU of the real embedding.
    #[default]
    Auto,
    /// Always the sparse LU of the real embedding (exact Newton matrix).
    SparseLu,
}

/// The chain path: the real and imaginary parts of `G` in the real Newton
/// matrix's symmetric pattern, and their complex LDLᵀ.
struct ChainPath {
    blocks: DynamicBlocks,
    kr: SaddleMatrix,
    ki: SaddleMatrix,
    jac: Vec<f64>,
    ldlt: ComplexChainLdlt,
    /// The controller states' exact border over `ldlt`.
    border: Option<ComplexStateBorder>,
}

impl ChainPath {
    /// `None` when the pattern is not a chain's.
    fn new(sys: &System) -> Option<Self> {
        let (n, m) = (sys.n_coords(), sys.n_constraints());
        let mut a = APattern::new();
        let mut blocks = DynamicBlocks::register(sys, &mut a);
        let jp = sys.jacobian_pattern();
        let kr = SaddleMatrix::with_storage(n, m, &a, jp, Storage::SymmetricLower);
        let ldlt = ComplexChainLdlt::analyze(&kr)?;
        let border = ComplexStateBorder::new(sys);
        if border.is_some() {
            blocks.decouple_states(sys);
        }
        Some(Self {
            border,
            blocks,
            ki: kr.clone(),
            kr,
            jac: vec![0.0; jp.len()],
            ldlt,
        })
    }

    /// Assemble `K_r`, `K_i` (module docs) at `x` and `λ` and factorise.
    fn factorize(
        &mut self,
        sys: &System,
        StateView { t, q, qd }: StateView<'_>,
        lambda: &[f64],
        [c0, c1, c2]: [[f64; 2]; 3],
    ) -> Result<(), FormulationError> {
        self.blocks
            .evaluate(sys, t, q, qd, lambda, true, true, &mut self.jac)?;
        // both parts in one pass, in two halves of their values for large n
        let parts = [&mut self.kr, &mut self.ki];
        self.blocks
            .write_complex_with_jacobian(sys, parts, [c0, c1, c2], &self.jac);
        self.ldlt
            .factorize(&self.kr, &self.ki)
            .map_err(linear_at(t))?;
        if let Some(b) = &mut self.border {
            let ldlt = &mut self.ldlt;
            b.factorize(sys, &self.blocks, [c0, c1, c2], |re, im| ldlt.solve(re, im))
                .map_err(linear_at(t))?;
        }
        Ok(())
    }
}

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

/// The complex Newton matrix of a [`System`] (module docs): the complex
/// envelope LDLᵀ of chain patterns, else the sparse LU of its real
/// embedding.
pub struct Index3Complex<'a> {
    sys: &'a System,
    n: usize,
    m: usize,
    chain: Option<ChainPath>,
    /// Built in `new` without a chain path, or when the chain's
    /// factorisation fails.
    lu: Option<LuPath>,
    /// The last factorisation was the chain's.
    on_chain: bool,
    factorizations: usize,
}

/// The real embedding (module docs) and its sparse LU.
struct LuPath {
    k: SaddleMatrix,
    solver: Box<dyn SaddlePointSolver>,
    sources: Vec<Source>,
    /// ∂g/∂q, ∂g/∂q̇ and (Φ_qᵀλ)_q at the last state.
    vals: BlockValues,
    jac: Vec<f64>,
    jac2: Vec<f64>,
    x: Vec<f64>,
}

impl std::fmt::Debug for Index3Complex<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Index3Complex")
            .field("n", &self.n)
            .field("m", &self.m)
            .field("solver", &self.solver_name())
            .finish()
    }
}

impl<'a> Index3Complex<'a> {
    /// [`Index3Complex::with_solver`] with [`ComplexSolverKind::Auto`].
    pub fn new(sys: &'a System) -> Result<Self, FormulationError> {
        Self::with_solver(sys, ComplexSolverKind::Auto)
    }

    /// Build the pattern(s) and run the symbolic analysis (once).
    pub fn with_solver(sys: &'a System, kind: ComplexSolverKind) -> Result<Self, FormulationError> {
        let chain = match kind {
            ComplexSolverKind::Auto => ChainPath::new(sys),
            ComplexSolverKind::SparseLu => None,
        };
        let lu = match chain {
            Some(_) => None,
            None => Some(LuPath::new(sys)?),
        };
        Ok(Self {
            sys,
            n: sys.n_coords(),
            m: sys.n_constraints(),
            on_chain: chain.is_some(),
            chain,
            lu,
            factorizations: 0,
        })
    }

    /// `"complex-chain-ldlt"` or `"sparse-lu"`: the solver of the next
    /// (or last) factorisation.
    pub fn solver_name(&self) -> &'static str {
        if self.on_chain {
            "complex-chain-ldlt"
        } else {
            "sparse-lu"
        }
    }

    /// The real embedding (pattern and last values) once the LU path is
    /// built (`None` while the chain path runs).
    pub fn embedding(&self) -> Option<&SaddleMatrix> {
        self.lu.as_ref().map(|l| &l.k)
    }

    /// Factorisations so far.
    pub fn factorizations(&self) -> usize {
        self.factorizations
    }
}

impl LuPath {
    /// Build the embedded pattern and run the LU's symbolic analysis (once).
    fn new(sys: &System) -> Result<Self, FormulationError> {
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
        solver.analyze(&k).map_err(linear_at(f64::NAN))?;
        Ok(Self {
            k,
            solver,
            sources,
            vals: BlockValues::new(sys),
            jac: vec![0.0; jp.len()],
            jac2: vec![0.0; 2 * jp.len()],
            x: vec![0.0; 2 * (n + m)],
        })
    }

    /// Assemble `G` (coefficients `[re, im]`, `c₀` real) at `x` and `λ` in
    /// its real embedding and factorise it.
    fn assemble_and_factorize(
        &mut self,
        sys: &System,
        x: StateView<'_>,
        lambda: &[f64],
        c: [[f64; 2]; 3],
    ) -> Result<(), FormulationError> {
        let (n, t) = (sys.n_coords(), x.t);
        let [c0, c1, c2] = c;
        self.vals
            .evaluate(sys, x, lambda, true, true, &mut self.jac)?;
        let BlockValues { dq, dqd, hess, .. } = &self.vals;
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
                    let (a, b) = (dqd[e], dq[e]);
                    pick([-(c1[0] * a + c2[0] * b), -(c1[1] * a + c2[1] * b)], p)
                }
                // c₂ (Φ_qᵀλ)_q
                Source::Hessian(e, p) => pick([c2[0] * hess[e], c2[1] * hess[e]], p),
            };
            k.add_a(id, v);
        }
        let l = self.jac.len();
        self.jac2[..l].copy_from_slice(&self.jac);
        self.jac2[l..].copy_from_slice(&self.jac);
        k.set_jacobian(&self.jac2);
        self.solver.factorize(k).map_err(linear_at(t))?;
        Ok(())
    }

    /// Solve with the last factorisation (`re + i·im`, each `[x; y]`).
    fn solve_in_place(
        &mut self,
        t: f64,
        n: usize,
        m: usize,
        re: &mut [f64],
        im: &mut [f64],
    ) -> Result<(), FormulationError> {
        let x = &mut self.x;
        x[..n].copy_from_slice(&re[..n]);
        x[n..2 * n].copy_from_slice(&im[..n]);
        x[2 * n..2 * n + m].copy_from_slice(&re[n..]);
        x[2 * n + m..].copy_from_slice(&im[n..]);
        self.solver
            .solve_in_place(&self.k, x)
            .map_err(linear_at(t))?;
        re[..n].copy_from_slice(&x[..n]);
        im[..n].copy_from_slice(&x[n..2 * n]);
        re[n..].copy_from_slice(&x[2 * n..2 * n + m]);
        im[n..].copy_from_slice(&x[2 * n + m..]);
        Ok(())
    }
}

impl ComplexNewton for Index3Complex<'_> {
    /// Assemble `[c₀ M + c₁ C_t + c₂ K_t, Φ_qᵀ; Φ_q, 0]` at `x` and `λ`
    /// (coefficients `[re, im]`, `c₀` real) and factorise it (module docs).
    fn factorize_complex(
        &mut self,
        x: StateView<'_>,
        lambda: &[f64],
        c: [[f64; 2]; 3],
    ) -> Result<(), SystemError> {
        if c[0][1] != 0.0 {
            return Err(SystemError::new(FormulationError::Invalid(
                "complex Newton matrix: the mass coefficient c₀ must be real".into(),
            )));
        }
        self.factorizations += 1;
        if let Some(ch) = self.chain.as_mut().filter(|_| self.on_chain) {
            match ch.factorize(self.sys, x, lambda, c) {
                Ok(()) => return Ok(()),
                // a vanishing pivot: the pivoting LU from here on
                Err(FormulationError::Linear { .. }) => self.on_chain = false,
                Err(e) => return Err(SystemError::new(e)),
            }
        }
        if self.lu.is_none() {
            self.lu = Some(LuPath::new(self.sys).map_err(SystemError::new)?);
        }
        let lu = self.lu.as_mut().expect("built above");
        lu.assemble_and_factorize(self.sys, x, lambda, c)
            .map_err(SystemError::new)
    }
    /// Solve with the last factorisation: `re + i·im` (each `[x; y]`,
    /// length `n + m`) is overwritten with the solution.
    fn solve_complex(&mut self, t: f64, re: &mut [f64], im: &mut [f64]) -> Result<(), SystemError> {
        let lin = linear_at(t);
        match (&mut self.chain, &mut self.lu) {
            (Some(ch), _) if self.on_chain => match &mut ch.border {
                Some(b) => b.solve(re, im, |re, im| ch.ldlt.solve(re, im)),
                None => ch.ldlt.solve(re, im),
            }
            .map_err(lin),
            (_, Some(lu)) => lu.solve_in_place(t, self.n, self.m, re, im),
            _ => Err(lin(crate::linalg::LinalgError::NotReady("factorize"))),
        }
        .map_err(SystemError::new)
    }
}
