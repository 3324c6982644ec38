//! Dense LU with partial pivoting (faer): for tiny systems and cross-checks;
//! complete pivoting (faer) for the rank and the pivot order of small dense
//! Jacobians.

use super::{FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::full_pivoting;
use faer::linalg::solvers::{PartialPivLu, Solve};
use faer::{Mat, MatMut, Par};

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
        LinalgError::check_solve(true, k.dim(), k, rhs)?;
        if self.work.len() != k.dim() {
            self.work = vec![0.0; k.dim()];
            self.rhs0 = vec![0.0; k.dim()];
        }
        self.rhs0.copy_from_slice(rhs);
        let dim = rhs.len();
        lu.solve_in_place(MatMut::from_column_major_slice_mut(rhs, dim, 1));
        self.stats.solves += 1;
        LinalgError::check_solution(rhs, "dense LU")?;
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
/// (overwritten with the factors of `P a Q`), by faer's full-pivoting LU
/// (`faer::linalg::lu::full_pivoting`, sequential, so the order does not
/// depend on the thread count): at each stage the entry of largest
/// magnitude of the remaining submatrix is the pivot; the rank is the
/// number of leading pivots whose magnitude exceeds `tol` times the first
/// (rank revealed; `tol = 0`: the nonzero ones). Used to choose the
/// dependent coordinates of coordinate partitioning (Wehage & Haug 1982):
/// the pivot columns of Φ_q are the best-conditioned dependent set this
/// greedy order finds. Among entries of equal magnitude (the ±1 entries of
/// Φ_q) faer's search picks by its own scan order (SIMD lanes, fixed by
/// faer's aligned storage, so the same matrix always gives the same
/// order), which may differ from a row-by-row scan's: of the shipped
/// scenarios only the 40-loop parallelogram chain's independent coordinate
/// changes (98 for 119, an equally regular block); the rank does not
/// (tests/linalg/dense_pivoting.rs). Dense, `O(m n min(m, n))`, allocates a copy,
/// its permutations and faer's scratch.
pub fn full_pivot_order(a: &mut [f64], m: usize, n: usize, tol: f64) -> PivotOrder {
    assert_eq!(a.len(), m * n, "full_pivot_order: matrix size");
    let (mut rows, mut rows_inv) = (vec![0usize; m], vec![0usize; m]);
    let (mut cols, mut cols_inv) = (vec![0usize; n], vec![0usize; n]);
    let size = m.min(n);
    if size == 0 {
        return PivotOrder {
            rank: 0,
            rows: (0..m).collect(),
            cols: (0..n).collect(),
            pivots: Vec::new(),
        };
    }
    let mut mem = MemBuffer::new(full_pivoting::factor::lu_in_place_scratch::<usize, f64>(
        m,
        n,
        Par::Seq,
        Default::default(),
    ));
    // faer's own storage (aligned columns): its SIMD search visits the
    // entries in an order that depends on their alignment, so on a slice
    // of any address a tie could be broken differently from run to run
    let mut lu = Mat::<f64>::from_fn(m, n, |i, j| a[i * n + j]);
    full_pivoting::factor::lu_in_place(
        lu.as_mut(),
        &mut rows,
        &mut rows_inv,
        &mut cols,
        &mut cols_inv,
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    for i in 0..m {
        for j in 0..n {
            a[i * n + j] = lu[(i, j)];
        }
    }
    // U's diagonal holds the pivots in the order taken; faer stops (and
    // leaves the rest of the diagonal as it is) when the largest remaining
    // entry is below the smallest normal number
    let mut pivots = Vec::new();
    let mut first = 0.0;
    for k in 0..size {
        let v = a[k * n + k].abs();
        if k == 0 {
            first = v;
        }
        if v <= tol * first || v < f64::MIN_POSITIVE || v.is_nan() {
            break;
        }
        pivots.push(v);
    }
    PivotOrder {
        rank: pivots.len(),
        rows,
        cols,
        pivots,
    }
}
