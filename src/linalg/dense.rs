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
