//! Sparse LU with partial pivoting (faer, COLAMD column order) of the full,
//! possibly unsymmetric saddle-point matrix: the exact Newton matrix of
//! implicit methods with unsymmetric force Jacobians (drag, friction).

use super::{FactorInfo, LinalgError, SaddleMatrix, SaddlePointSolver, SolverStats, Storage};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuRef, NumericLu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par};

/// faer's sparse LU over [`Storage::Full`]: symbolic analysis (COLAMD and
/// the elimination structure) once per pattern in `analyze`, numeric
/// factorisation per evaluation and solves without allocation (scratch
/// memory sized once).
#[derive(Default)]
pub struct SparseLu {
    symbolic: Option<SymbolicLu<usize>>,
    numeric: NumericLu<usize, f64>,
    mem: Option<MemBuffer>,
    dim: usize,
    nnz: usize,
    ready: bool,
    stats: SolverStats,
}

impl SaddlePointSolver for SparseLu {
    fn name(&self) -> &'static str {
        "sparse-lu"
    }

    fn storage(&self) -> Storage {
        Storage::Full
    }

    fn analyze(&mut self, k: &SaddleMatrix) -> Result<(), LinalgError> {
        k.require_storage(Storage::Full, self.name())?;
        let dim = k.dim();
        let pattern =
            SymbolicSparseColMatRef::new_checked(dim, dim, k.col_ptr(), None, k.row_idx());
        let symbolic = factorize_symbolic_lu(pattern, Default::default())
            .map_err(|e| LinalgError::Singular(format!("sparse LU symbolic analysis: {e:?}")))?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        self.mem = Some(MemBuffer::new(req));
        self.symbolic = Some(symbolic);
        self.dim = dim;
        self.nnz = k.nnz();
        self.ready = false;
        self.stats.analyses += 1;
        Ok(())
    }

    fn factorize(&mut self, k: &SaddleMatrix) -> Result<FactorInfo, LinalgError> {
        let (Some(symbolic), Some(mem)) = (&self.symbolic, &mut self.mem) else {
            return Err(LinalgError::NotReady("analyze"));
        };
        if k.dim() != self.dim || k.nnz() != self.nnz {
            return Err(LinalgError::Dimension {
                expected: self.dim,
                got: k.dim(),
            });
        }
        self.ready = false;
        k.check_finite()?;
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(
                self.dim,
                self.dim,
                k.col_ptr(),
                None,
                k.row_idx(),
            ),
            k.values(),
        );
        symbolic
            .factorize_numeric_lu(
                &mut self.numeric,
                a,
                Par::Seq,
                MemStack::new(mem),
                Default::default(),
            )
            .map_err(|e| LinalgError::Singular(format!("sparse LU: {e:?}")))?;
        self.stats.factorizations += 1;
        self.ready = true;
        Ok(FactorInfo::default())
    }

    fn solve_in_place(&mut self, k: &SaddleMatrix, rhs: &mut [f64]) -> Result<(), LinalgError> {
        let (Some(symbolic), Some(mem)) = (&self.symbolic, &mut self.mem) else {
            return Err(LinalgError::NotReady("analyze"));
        };
        LinalgError::check_solve(self.ready, self.dim, k, rhs)?;
        if self.dim > 0 {
            LuRef::new_unchecked(symbolic, &self.numeric).solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(rhs, self.dim, 1),
                Par::Seq,
                MemStack::new(mem),
            );
        }
        self.stats.solves += 1;
        LinalgError::check_solution(rhs, "sparse LU")
    }

    fn stats(&self) -> SolverStats {
        self.stats
    }
}
