//! The controller states' border of the index-3 Newton matrix: an exact
//! solve with the states' couplings kept, on top of the symmetric LDLᵀ of
//! the mechanism.
//!
//! A `[[state]]` z is the velocity of an extra coordinate
//! ([`crate::model::State`]); its couplings with the mechanism are one-way
//! in both directions: a load reads z (`∂g_b/∂q̇_s ≠ 0`), the state's rate
//! reads the bodies (`∂g_s/∂q_b`, `∂g_s/∂q̇_b ≠ 0`), seldom both with one
//! sign. The symmetric storage keeps only the reciprocal part of such a
//! pair (`DynamicBlocks::write`), which is 0 here: the states' Newton
//! corrections would not see the mechanism's, and with `c_c ∝ h`,
//! `c_k ∝ h²` the iteration stops contracting at large steps.
//!
//! With the coordinates split into P (the bodies' coordinates and the
//! multipliers) and S (the states, contiguous after the bodies'), the
//! Newton matrix is
//!
//! ```text
//! K = [ K_PP  K_PS ]      K_PS = [A_bs; 0],  K_SP = [A_sb  0],
//!     [ K_SP  K_SS ]      A = c_m M − c_c ∂g/∂q̇ − c_k ∂g/∂q
//! ```
//!
//! The sparse factorisation holds `K₀ = diag(K_PP, c_m I)` (the blocks
//! write no entry touching a state, `DynamicBlocks::decouple_states`), and
//! the states' Schur complement `S = K_SS − K_SP K_PP⁻¹ K_PS` (m × m,
//! dense, LU with partial pivoting) is formed exactly from the force
//! Jacobians with `m` extra solves per factorisation. A solve is then the
//! block elimination
//!
//! ```text
//! y = K_PP⁻¹ r_P,   x_S = S⁻¹ (r_S − K_SP y),   x_P = y − (K_PP⁻¹ K_PS) x_S
//! ```
//!
//! one sparse solve and O((n + m)·m) more. The body–body couplings stay as
//! the symmetric storage has them (their reciprocal part); the states'
//! couplings are exact.

use super::dynamic_blocks::DynamicBlocks;
use crate::linalg::{LinalgError, SaddleMatrix, SaddlePointSolver, Storage};
use crate::model::System;
use crate::numeric::{cabs, cdiv, cmul, C64};

/// The border of a system with controller states ([module docs](self)).
pub(crate) struct StateBorder {
    shape: Shape,
    /// The values of the shape's entries in `K` at the last factorisation.
    vals: Vec<f64>,
    /// `K_PP⁻¹ K_PS`, column by column (`size × ns`, the S rows zero).
    z: Vec<f64>,
    /// The LU factors of the Schur complement (row-major `ns × ns`) and
    /// its row permutation.
    lu: Vec<f64>,
    perm: Vec<usize>,
    /// Scratch: the right-hand side's S part, and its permuted copy.
    rs: Vec<f64>,
    tmp: Vec<f64>,
}

/// Where the states sit in the Newton matrix, shared by the real and the
/// complex border.
struct Shape {
    /// First state coordinate (3 · bodies) and the number of states.
    nb: usize,
    ns: usize,
    /// Size of the saddle-point system, n + m.
    size: usize,
    /// The force-Jacobian entries `(e, row, col)` with a state as row or
    /// column.
    entries: Vec<(usize, usize, usize)>,
}

impl Shape {
    /// `None` when the system has no states.
    fn of(sys: &System) -> Option<Self> {
        let (nb, ns) = (sys.n_body_coords(), sys.states().len());
        if ns == 0 {
            return None;
        }
        let entries = sys
            .force_jacobian_pattern()
            .iter()
            .enumerate()
            .filter(|(_, &(i, j))| i >= nb || j >= nb)
            .map(|(e, &(i, j))| (e, i, j))
            .collect();
        let size = sys.n_coords() + sys.n_constraints();
        Some(Self {
            nb,
            ns,
            size,
            entries,
        })
    }
}

impl StateBorder {
    /// `None` when the system has no states or the storage is not the
    /// symmetric one (the LU's full storage keeps the couplings exact).
    pub(crate) fn new(sys: &System, storage: Storage) -> Option<Self> {
        if storage != Storage::SymmetricLower {
            return None;
        }
        let shape = Shape::of(sys)?;
        let (ns, size) = (shape.ns, shape.size);
        Some(Self {
            vals: vec![0.0; shape.entries.len()],
            shape,
            z: vec![0.0; size * ns],
            lu: vec![0.0; ns * ns],
            perm: (0..ns).collect(),
            rs: vec![0.0; ns],
            tmp: vec![0.0; ns],
        })
    }

    /// After `solver` factorised `k` (= `K₀`, the states decoupled): the
    /// entries of `K` touching a state from the last evaluated blocks with
    /// the coefficients `[c_m, c_c, c_k]`, `K_PP⁻¹ K_PS` (`ns` solves) and
    /// the LU of the Schur complement.
    pub(crate) fn factorize(
        &mut self,
        sys: &System,
        blocks: &DynamicBlocks,
        [c_m, c_c, c_k]: [f64; 3],
        solver: &mut dyn SaddlePointSolver,
        k: &SaddleMatrix,
    ) -> Result<(), LinalgError> {
        let (dq, dqd, _) = blocks.values();
        for (v, &(e, _, _)) in self.vals.iter_mut().zip(&self.shape.entries) {
            *v = -(c_c * dqd[e] + c_k * dq[e]);
        }
        let (nb, ns, size) = (self.shape.nb, self.shape.ns, self.shape.size);
        // Z = K_PP⁻¹ K_PS, column by column
        self.z.fill(0.0);
        for (&(_, i, j), &v) in self.shape.entries.iter().zip(&self.vals) {
            if i < nb && j >= nb {
                self.z[(j - nb) * size + i] += v;
            }
        }
        for s in 0..ns {
            let col = &mut self.z[s * size..(s + 1) * size];
            if col.iter().any(|&x| x != 0.0) {
                solver.solve_in_place(k, col)?;
                col[nb..nb + ns].fill(0.0);
            }
        }
        // S = K_SS − K_SP Z
        let lu = &mut self.lu;
        lu.fill(0.0);
        let mass = sys.mass_diagonal();
        for s in 0..ns {
            lu[s * ns + s] = c_m * mass[nb + s];
        }
        for (&(_, i, j), &v) in self.shape.entries.iter().zip(&self.vals) {
            if i < nb {
                continue;
            }
            let a = i - nb;
            if j >= nb {
                lu[a * ns + (j - nb)] += v;
            } else {
                for s in 0..ns {
                    lu[a * ns + s] -= v * self.z[s * size + j];
                }
            }
        }
        lu_factor(lu, &mut self.perm, ns)
    }

    /// Overwrite `rhs` with `K⁻¹ rhs` (module docs), `solver` holding the
    /// factorisation of `K₀` = `k`.
    pub(crate) fn solve(
        &mut self,
        solver: &mut dyn SaddlePointSolver,
        k: &SaddleMatrix,
        rhs: &mut [f64],
    ) -> Result<(), LinalgError> {
        let (nb, ns, size) = (self.shape.nb, self.shape.ns, self.shape.size);
        self.rs.copy_from_slice(&rhs[nb..nb + ns]);
        rhs[nb..nb + ns].fill(0.0);
        solver.solve_in_place(k, rhs)?;
        // r_S − K_SP y
        for (&(_, i, j), &v) in self.shape.entries.iter().zip(&self.vals) {
            if i >= nb && j < nb {
                self.rs[i - nb] -= v * rhs[j];
            }
        }
        lu_solve(&self.lu, &self.perm, &mut self.rs, &mut self.tmp);
        if let Some(bad) = self.rs.iter().find(|x| !x.is_finite()) {
            return Err(LinalgError::Singular(format!(
                "the controller states' Schur complement gave {bad}"
            )));
        }
        for (s, &x) in self.rs.iter().enumerate() {
            if x != 0.0 {
                let col = &self.z[s * size..(s + 1) * size];
                for (r, c) in rhs.iter_mut().zip(col) {
                    *r -= c * x;
                }
            }
        }
        rhs[nb..nb + ns].copy_from_slice(&self.rs);
        Ok(())
    }
}

/// The border of the complex Newton matrix of radau5's transformed stages
/// (`[c₀ M + c₁ C_t + c₂ K_t, Φ_qᵀ; Φ_q, 0]`, `c₁`, `c₂` complex) over a
/// complex symmetric factorisation of `K₀` (the complex chain LDLᵀ,
/// `index3_complex.rs`): [`StateBorder`]'s block elimination in complex
/// arithmetic, vectors as (re, im) halves.
pub(crate) struct ComplexStateBorder {
    shape: Shape,
    /// The shape's entries' values in `K` at the last factorisation.
    vals: Vec<C64>,
    /// `K_PP⁻¹ K_PS` column by column, real and imaginary parts.
    z_re: Vec<f64>,
    z_im: Vec<f64>,
    lu: Vec<C64>,
    perm: Vec<usize>,
    rs: Vec<C64>,
    tmp: Vec<C64>,
}

impl ComplexStateBorder {
    /// `None` when the system has no states.
    pub(crate) fn new(sys: &System) -> Option<Self> {
        let shape = Shape::of(sys)?;
        let (ns, size) = (shape.ns, shape.size);
        Some(Self {
            vals: vec![[0.0; 2]; shape.entries.len()],
            shape,
            z_re: vec![0.0; size * ns],
            z_im: vec![0.0; size * ns],
            lu: vec![[0.0; 2]; ns * ns],
            perm: (0..ns).collect(),
            rs: vec![[0.0; 2]; ns],
            tmp: vec![[0.0; 2]; ns],
        })
    }

    /// As [`StateBorder::factorize`] with the complex coefficients
    /// `[c₀, c₁, c₂]` (`c₀` real) and `solve` the complex solve with `K₀`.
    pub(crate) fn factorize(
        &mut self,
        sys: &System,
        blocks: &DynamicBlocks,
        [c0, c1, c2]: [C64; 3],
        mut solve: impl FnMut(&mut [f64], &mut [f64]) -> Result<(), LinalgError>,
    ) -> Result<(), LinalgError> {
        let (dq, dqd, _) = blocks.values();
        for (v, &(e, _, _)) in self.vals.iter_mut().zip(&self.shape.entries) {
            *v = [
                -(c1[0] * dqd[e] + c2[0] * dq[e]),
                -(c1[1] * dqd[e] + c2[1] * dq[e]),
            ];
        }
        let (nb, ns, size) = (self.shape.nb, self.shape.ns, self.shape.size);
        self.z_re.fill(0.0);
        self.z_im.fill(0.0);
        for (&(_, i, j), &v) in self.shape.entries.iter().zip(&self.vals) {
            if i < nb && j >= nb {
                self.z_re[(j - nb) * size + i] += v[0];
                self.z_im[(j - nb) * size + i] += v[1];
            }
        }
        for s in 0..ns {
            let re = &mut self.z_re[s * size..(s + 1) * size];
            let im = &mut self.z_im[s * size..(s + 1) * size];
            if re.iter().chain(im.iter()).any(|&x| x != 0.0) {
                solve(re, im)?;
                re[nb..nb + ns].fill(0.0);
                im[nb..nb + ns].fill(0.0);
            }
        }
        let lu = &mut self.lu;
        lu.fill([0.0; 2]);
        let mass = sys.mass_diagonal();
        for s in 0..ns {
            lu[s * ns + s] = [c0[0] * mass[nb + s], c0[1] * mass[nb + s]];
        }
        for (&(_, i, j), &v) in self.shape.entries.iter().zip(&self.vals) {
            if i < nb {
                continue;
            }
            let a = i - nb;
            if j >= nb {
                let x = &mut lu[a * ns + (j - nb)];
                x[0] += v[0];
                x[1] += v[1];
            } else {
                for s in 0..ns {
                    let z = [self.z_re[s * size + j], self.z_im[s * size + j]];
                    let p = cmul(v, z);
                    lu[a * ns + s][0] -= p[0];
                    lu[a * ns + s][1] -= p[1];
                }
            }
        }
        clu_factor(lu, &mut self.perm, ns)
    }

    /// Overwrite `re + i·im` with `K⁻¹ (re + i·im)`, `solve` the complex
    /// solve with `K₀`.
    pub(crate) fn solve(
        &mut self,
        re: &mut [f64],
        im: &mut [f64],
        solve: impl FnOnce(&mut [f64], &mut [f64]) -> Result<(), LinalgError>,
    ) -> Result<(), LinalgError> {
        let (nb, ns, size) = (self.shape.nb, self.shape.ns, self.shape.size);
        for s in 0..ns {
            self.rs[s] = [re[nb + s], im[nb + s]];
        }
        re[nb..nb + ns].fill(0.0);
        im[nb..nb + ns].fill(0.0);
        solve(re, im)?;
        for (&(_, i, j), &v) in self.shape.entries.iter().zip(&self.vals) {
            if i >= nb && j < nb {
                let p = cmul(v, [re[j], im[j]]);
                self.rs[i - nb][0] -= p[0];
                self.rs[i - nb][1] -= p[1];
            }
        }
        for (t, &p) in self.tmp.iter_mut().zip(&self.perm) {
            *t = self.rs[p];
        }
        let b = &mut self.tmp;
        for r in 0..ns {
            for c in 0..r {
                let p = cmul(self.lu[r * ns + c], b[c]);
                b[r] = [b[r][0] - p[0], b[r][1] - p[1]];
            }
        }
        for r in (0..ns).rev() {
            for c in r + 1..ns {
                let p = cmul(self.lu[r * ns + c], b[c]);
                b[r] = [b[r][0] - p[0], b[r][1] - p[1]];
            }
            b[r] = cdiv(b[r], self.lu[r * ns + r]);
        }
        if let Some(bad) = b.iter().flatten().find(|x| !x.is_finite()) {
            return Err(LinalgError::Singular(format!(
                "the controller states' complex Schur complement gave {bad}"
            )));
        }
        for (s, &x) in b.iter().enumerate() {
            if x == [0.0; 2] {
                continue;
            }
            let (zr, zi) = (
                &self.z_re[s * size..(s + 1) * size],
                &self.z_im[s * size..(s + 1) * size],
            );
            for r in 0..size {
                let p = cmul([zr[r], zi[r]], x);
                re[r] -= p[0];
                im[r] -= p[1];
            }
        }
        for (s, &x) in b.iter().enumerate() {
            re[nb + s] = x[0];
            im[nb + s] = x[1];
        }
        Ok(())
    }
}

/// [`lu_factor`] in complex arithmetic.
fn clu_factor(a: &mut [C64], perm: &mut [usize], n: usize) -> Result<(), LinalgError> {
    for (k, p) in perm.iter_mut().enumerate() {
        *p = k;
    }
    let scale = a.iter().fold(0.0f64, |m, &x| m.max(cabs(x)));
    for k in 0..n {
        let p = (k..n)
            .max_by(|&x, &y| cabs(a[x * n + k]).total_cmp(&cabs(a[y * n + k])))
            .unwrap_or(k);
        let pivot = a[p * n + k];
        if cabs(pivot).is_nan() || cabs(pivot) <= 1e-14 * scale {
            return Err(LinalgError::Singular(format!(
                "the controller states' complex Schur complement has the pivot of modulus \
                 {:e} (largest entry {scale:e})",
                cabs(pivot)
            )));
        }
        if p != k {
            for c in 0..n {
                a.swap(p * n + c, k * n + c);
            }
            perm.swap(p, k);
        }
        for r in k + 1..n {
            let f = cdiv(a[r * n + k], pivot);
            a[r * n + k] = f;
            for c in k + 1..n {
                let m = cmul(f, a[k * n + c]);
                a[r * n + c] = [a[r * n + c][0] - m[0], a[r * n + c][1] - m[1]];
            }
        }
    }
    Ok(())
}

/// LU with partial pivoting of the row-major `n × n` matrix `a` in place
/// (`perm[k]`: the original row now at row k).
fn lu_factor(a: &mut [f64], perm: &mut [usize], n: usize) -> Result<(), LinalgError> {
    for (k, p) in perm.iter_mut().enumerate() {
        *p = k;
    }
    let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for k in 0..n {
        let p = (k..n)
            .max_by(|&x, &y| a[x * n + k].abs().total_cmp(&a[y * n + k].abs()))
            .unwrap_or(k);
        let pivot = a[p * n + k];
        if pivot.is_nan() || pivot.abs() <= 1e-14 * scale {
            return Err(LinalgError::Singular(format!(
                "the controller states' Schur complement has the pivot {pivot:e} (largest \
                 entry {scale:e})"
            )));
        }
        if p != k {
            for c in 0..n {
                a.swap(p * n + c, k * n + c);
            }
            perm.swap(p, k);
        }
        for r in k + 1..n {
            let f = a[r * n + k] / pivot;
            a[r * n + k] = f;
            for c in k + 1..n {
                a[r * n + c] -= f * a[k * n + c];
            }
        }
    }
    Ok(())
}

/// Solve with the factors of [`lu_factor`] in place (`tmp`: scratch of
/// `b`'s length).
fn lu_solve(lu: &[f64], perm: &[usize], b: &mut [f64], tmp: &mut [f64]) {
    let n = b.len();
    for (t, &p) in tmp.iter_mut().zip(perm) {
        *t = b[p];
    }
    b.copy_from_slice(tmp);
    for r in 0..n {
        for c in 0..r {
            b[r] -= lu[r * n + c] * b[c];
        }
    }
    for r in (0..n).rev() {
        for c in r + 1..n {
            b[r] -= lu[r * n + c] * b[c];
        }
        b[r] /= lu[r * n + r];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lu_solves_a_pivoting_system() {
        // [[0, 2, 1], [1, 1, 0], [3, 0, 1]] x = b with x = (1, -2, 3)
        let a0 = [0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0];
        let x = [1.0, -2.0, 3.0];
        let mut b: Vec<f64> = (0..3)
            .map(|r| (0..3).map(|c| a0[r * 3 + c] * x[c]).sum())
            .collect();
        let (mut a, mut p) = (a0.to_vec(), vec![0; 3]);
        lu_factor(&mut a, &mut p, 3).unwrap();
        lu_solve(&a, &p, &mut b, &mut [0.0; 3]);
        for (u, v) in b.iter().zip(x) {
            assert!((u - v).abs() < 1e-14, "{b:?}");
        }
        let mut s = vec![1.0, 2.0, 2.0, 4.0];
        assert!(lu_factor(&mut s, &mut p[..2], 2).is_err());
    }
}
