//! λ eliminated, paper eq. (9): the Schur complement of a diagonal `A`.

use super::{FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats, Storage};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::{Mat, Par};

/// Solves `[A Φ_qᵀ; Φ_q D] [x; λ] = [b₁; b₂]` for a **diagonal** `A` by
/// eliminating `x` (paper, eq. (9)):
///
/// ```text
/// S = Φ_q A⁻¹ Φ_qᵀ − D,   S λ = Φ_q A⁻¹ b₁ − b₂,   x = A⁻¹ (b₁ − Φ_qᵀ λ)
/// ```
///
/// with a dense Cholesky factorisation of `S` (`m × m`): `O(m³)` per
/// factorisation, for small and moderate `m`. `S` must be positive definite:
/// redundant constraints (rank-deficient `Φ_q`) need the saddle-point
/// solvers. Scratch memory is sized in `analyze`; factorisation and solves
/// do not allocate.
pub struct SchurComplement {
    n: usize,
    m: usize,
    /// `Φ_q` entries by column: (row, slot) in the matrix's values.
    by_col: Vec<Vec<(usize, usize)>>,
    schur: Mat<f64>,
    rhs: Mat<f64>,
    mem: Option<MemBuffer>,
    ready: bool,
    stats: SolverStats,
}

impl Default for SchurComplement {
    fn default() -> Self {
        Self {
            n: 0,
            m: 0,
            by_col: Vec::new(),
            schur: Mat::zeros(0, 0),
            rhs: Mat::zeros(0, 1),
            mem: None,
            ready: false,
            stats: SolverStats::default(),
        }
    }
}

impl SaddlePointSolver for SchurComplement {
    fn name(&self) -> &'static str {
        "schur-dense-cholesky"
    }

    fn analyze(&mut self, k: &SaddleMatrix) -> Result<(), LinalgError> {
        k.require_storage(Storage::SymmetricLower, self.name())?;
        let (n, m) = (k.n(), k.m());
        let mut by_col = vec![Vec::new(); n];
        for (c, col) in by_col.iter_mut().enumerate() {
            for s in k.col_ptr()[c]..k.col_ptr()[c + 1] {
                let r = k.row_idx()[s];
                if r >= n {
                    col.push((r - n, s));
                } else if r != c {
                    return Err(LinalgError::Singular(format!(
                        "the Schur complement of eq. (9) needs a diagonal A block; \
                         A has an entry at ({r}, {c})"
                    )));
                }
            }
        }
        self.by_col = by_col;
        self.schur = Mat::zeros(m, m);
        self.rhs = Mat::zeros(m, 1);
        self.mem = Some(MemBuffer::new(
            llt::factor::cholesky_in_place_scratch::<f64>(m, Par::Seq, Default::default()),
        ));
        (self.n, self.m) = (n, m);
        self.ready = false;
        self.stats.analyses += 1;
        Ok(())
    }

    fn factorize(&mut self, k: &SaddleMatrix) -> Result<FactorInfo, LinalgError> {
        let Some(mem) = &mut self.mem else {
            return Err(LinalgError::NotReady("analyze"));
        };
        if k.n() != self.n || k.m() != self.m {
            return Err(LinalgError::Dimension {
                expected: self.n + self.m,
                got: k.dim(),
            });
        }
        self.ready = false;
        k.check_finite()?;
        let (vals, diag) = (k.values(), k.diag_slots());
        // S = Σ_c Φ_q[:, c] Φ_q[:, c]ᵀ / A_c over the entries of each column.
        self.schur.fill(0.0);
        for (c, col) in self.by_col.iter().enumerate() {
            let a = vals[diag[c]];
            for &(r1, s1) in col {
                for &(r2, s2) in col {
                    self.schur[(r1, r2)] += vals[s1] * vals[s2] / a;
                }
            }
        }
        for r in 0..self.m {
            self.schur[(r, r)] -= vals[diag[self.n + r]];
        }
        llt::factor::cholesky_in_place(
            self.schur.as_mut(),
            Default::default(),
            Par::Seq,
            MemStack::new(mem),
            Default::default(),
        )
        .map_err(|e| {
            LinalgError::Singular(format!(
                "Schur complement Φ_q M⁻¹ Φ_qᵀ is not positive definite ({e:?}); \
                 redundant constraints need the saddle formulation"
            ))
        })?;
        self.stats.factorizations += 1;
        self.ready = true;
        Ok(FactorInfo::default())
    }

    fn solve_in_place(&mut self, k: &SaddleMatrix, rhs: &mut [f64]) -> Result<(), LinalgError> {
        let (n, m) = (self.n, self.m);
        LinalgError::check_solve(self.ready, n + m, k, rhs)?;
        let (vals, diag) = (k.values(), k.diag_slots());
        // right-hand side Φ_q A⁻¹ b₁ − b₂
        for r in 0..m {
            self.rhs[(r, 0)] = -rhs[n + r];
        }
        for (c, col) in self.by_col.iter().enumerate() {
            for &(r, s) in col {
                self.rhs[(r, 0)] += vals[s] * rhs[c] / vals[diag[c]];
            }
        }
        llt::solve::solve_in_place_with_conj(
            self.schur.as_ref(),
            faer::Conj::No,
            self.rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut []),
        );
        // x = A⁻¹ (b₁ − Φ_qᵀ λ)
        for (c, col) in self.by_col.iter().enumerate() {
            let mut t = 0.0;
            for &(r, s) in col {
                t += vals[s] * self.rhs[(r, 0)];
            }
            rhs[c] = (rhs[c] - t) / vals[diag[c]];
        }
        for r in 0..m {
            rhs[n + r] = self.rhs[(r, 0)];
        }
        self.stats.solves += 1;
        LinalgError::check_solution(rhs, "the Schur-complement solve")
    }

    fn stats(&self) -> SolverStats {
        self.stats
    }
}
