//! Generated, fully unrolled kernels of the four-bar.

use super::{arr, arr_mut, code, kernels, revolute};
use crate::model::{ConstraintKernels, ConstraintTerms, System};

/// Generated, fully unrolled kernels for the four-bar (docs/problems.md, problem A).
#[derive(Debug, Clone)]
pub struct FourBarKernels {
    params: [f64; kernels::FOURBAR_N_PARAMS],
}

impl FourBarKernels {
    /// Kernels for `sys` if it is a four-bar: 3 bodies and the revolutes
    /// ground–0, 0–1, 1–2, ground–2 in that order (any pin points).
    pub fn recognise(sys: &System) -> Option<Self> {
        if sys.bodies().len() != 3 || sys.constraints().len() != kernels::FOURBAR_JOINTS.len() {
            return None;
        }
        let mut params = [0.0; kernels::FOURBAR_N_PARAMS];
        for (k, (c, &(kind, i, j))) in sys
            .constraints()
            .iter()
            .zip(&kernels::FOURBAR_JOINTS)
            .enumerate()
        {
            let (bi, bj, points) = revolute(c.geometry())?;
            if kind != "revolute" || code(bi) != i || code(bj) != j {
                return None;
            }
            params[4 * k..4 * k + 4].copy_from_slice(&points);
        }
        (sys.jacobian_pattern() == kernels::FOURBAR_JAC_PATTERN).then_some(Self { params })
    }
}

impl ConstraintKernels for FourBarKernels {
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        kernels::FOURBAR_JAC_PATTERN.to_vec()
    }
    fn has_hessian(&self) -> bool {
        true
    }
    fn add_hessian(&self, q: &[f64], _t: f64, lambda: &[f64], vals: &mut [f64]) {
        kernels::fourbar_hessian(arr(q), &self.params, &[], arr(lambda), arr_mut(vals));
    }
    fn evaluate(&self, q: &[f64], qd: &[f64], _t: f64, out: ConstraintTerms<'_>) {
        let (phi, vals, gamma) = (arr_mut(out.phi), arr_mut(out.vals), arr_mut(out.gamma));
        kernels::fourbar_eval(arr(q), arr(qd), &self.params, &[], phi, vals, gamma);
    }
    fn name(&self) -> &str {
        "generated:fourbar"
    }
    fn phi(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        kernels::fourbar_phi(arr(q), &self.params, &[], arr_mut(out));
    }
    fn jacobian_values(&self, q: &[f64], _t: f64, vals: &mut [f64]) {
        kernels::fourbar_jacobian(arr(q), &self.params, &[], arr_mut(vals));
    }
    fn phi_t(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        kernels::fourbar_phi_t(arr(q), &self.params, &[], arr_mut(out));
    }
    fn gamma(&self, q: &[f64], qd: &[f64], _t: f64, out: &mut [f64]) {
        kernels::fourbar_gamma(arr(q), arr(qd), &self.params, &[], arr_mut(out));
    }
}
