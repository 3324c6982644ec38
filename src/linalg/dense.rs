//! Dense LU with partial pivoting (faer): for tiny systems and cross-checks.

use super::{FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats};
use faer::linalg::solvers::{PartialPivLu, Solve};
use faer::MatMut;

/// Dense LU of the full saddle-point matrix (either storage). `O((n+m)³)`
/// per factorisation: only for small systems and as an independent
/// reference for the sparse path. Unlike the other solvers it allocates per
/// factorisation (a dense copy and faer's `PartialPivLu`): it is a
/// cross-check, never chosen by `Auto`, and simplicity beats speed here.
#[derive(Default)]
pub struct DenseLu {
    lu: Option<PartialPivLu<f64>>,
    work: Vec<f64>,
    rhs0: Vec<f64>,
    stats: SolverStats,
}

/// Relative residual above which the solution is rejected as singular.
const SINGULAR_RESIDUAL: f64 = 1e-6;

impl SaddlePointSolver for DenseLu {
    fn name(&self) -> &'static str {
        "dense-lu"
    }

    fn analyze(&mut self, k: &SaddleMatrix) -> Result<(), LinalgError> {
        self.work = vec![0.0; k.dim()];
        self.rhs0 = vec![0.0; k.dim()];
        self.stats.analyses += 1;
        Ok(())
    }

    fn factorize(&mut self, k: &SaddleMatrix) -> Result<FactorInfo, LinalgError> {
        k.check_finite()?;
        self.lu = Some(k.to_dense().partial_piv_lu());
        self.stats.factorizations += 1;
        Ok(FactorInfo::default())
    }

    fn solve_in_place(&mut self, k: &SaddleMatrix, rhs: &mut [f64]) -> Result<(), LinalgError> {
        let lu = self.lu.as_ref().ok_or(LinalgError::NotReady("factorize"))?;
        if rhs.len() != k.dim() {
            return Err(LinalgError::Dimension {
                expected: k.dim(),
                got: rhs.len(),
            });
        }
        if self.work.len() != k.dim() {
            self.work = vec![0.0; k.dim()];
            self.rhs0 = vec![0.0; k.dim()];
        }
        self.rhs0.copy_from_slice(rhs);
        let dim = rhs.len();
        lu.solve_in_place(MatMut::from_column_major_slice_mut(rhs, dim, 1));
        self.stats.solves += 1;
        if rhs.iter().any(|v| !v.is_finite()) {
            return Err(LinalgError::NonFiniteSolution("dense LU"));
        }
        let res = k.relative_residual(rhs, &self.rhs0, &mut self.work);
        if res > SINGULAR_RESIDUAL {
            return Err(LinalgError::Singular(format!(
                "dense LU residual {res:.2e} (rank-deficient constraint Jacobian?)"
            )));
        }
        Ok(())
    }

    fn stats(&self) -> SolverStats {
        self.stats
    }
}

/// The pivot order of Gaussian elimination with complete pivoting on a
/// dense `m × n` matrix ([`full_pivot_order`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PivotOrder {
    /// Numerical rank: pivots whose magnitude exceeds `tol × |first pivot|`.
    pub rank: usize,
    /// Row order: the first `rank` are the pivot rows (independent equations).
    pub rows: Vec<usize>,
    /// Column order: the first `rank` are the pivot columns, the rest the
    /// columns no pivot was taken from.
    pub cols: Vec<usize>,
    /// Magnitudes of the pivots taken (`rank` of them).
    pub pivots: Vec<f64>,
}

/// Gaussian elimination with complete pivoting (Golub & Van Loan, Matrix
/// Computations, Alg. 3.4.2) of the row-major `m × n` matrix `a`
/// (overwritten): at each stage the entry of largest magnitude of the
/// remaining submatrix is the pivot; elimination stops when it falls to
/// `tol` times the first pivot (rank revealed). Used to choose the
/// dependent coordinates of coordinate partitioning (Wehage & Haug 1982):
/// the pivot columns of Φ_q are the best-conditioned dependent set this
/// greedy order finds. Dense, `O(m² n)`.
pub fn full_pivot_order(a: &mut [f64], m: usize, n: usize, tol: f64) -> PivotOrder {
    assert_eq!(a.len(), m * n, "full_pivot_order: matrix size");
    let mut rows: Vec<usize> = (0..m).collect();
    let mut cols: Vec<usize> = (0..n).collect();
    let mut pivots = Vec::new();
    let mut first = 0.0;
    for k in 0..m.min(n) {
        // largest remaining entry (in the permuted indexing)
        let (mut bi, mut bj, mut best) = (k, k, -1.0_f64);
        for i in k..m {
            for j in k..n {
                let v = a[rows[i] * n + cols[j]].abs();
                if v > best {
                    (bi, bj, best) = (i, j, v);
                }
            }
        }
        if k == 0 {
            first = best;
        }
        if best <= tol * first || best == 0.0 || best.is_nan() {
            break;
        }
        rows.swap(k, bi);
        cols.swap(k, bj);
        pivots.push(best);
        let (pr, pc) = (rows[k], cols[k]);
        let p = a[pr * n + pc];
        for &r in &rows[k + 1..] {
            let f = a[r * n + pc] / p;
            if f != 0.0 {
                for &c in &cols[k..] {
                    a[r * n + c] -= f * a[pr * n + c];
                }
            }
        }
    }
    PivotOrder {
        rank: pivots.len(),
        rows,
        cols,
        pivots,
    }
}
