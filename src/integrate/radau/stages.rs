//! The Radau IIA tableau of any odd number of stages `S`, computed from
//! its definition (Hairer & Wanner II, §IV.5, §IV.8): the nodes are the
//! roots of the Radau polynomial `P_S(2x − 1) − P_{S−1}(2x − 1)` (shifted
//! Legendre polynomials; `c_S = 1`), `𝔄_ij = ∫₀^{c_i} ℓ_j` with the
//! Lagrange basis `ℓ_j` on the nodes, and the eigenvalues of 𝔄 the
//! reciprocals of the roots of the denominator of the `(S − 1, S)` Padé
//! approximant of `eᶻ` (Radau IIA's stability function): one real, `γ`,
//! and `(S − 1)/2` complex pairs `α ± iβ`, whose eigenvectors give the
//! real transformation `T⁻¹ 𝔄 T = diag(γ, [α₁ −β₁; β₁ α₁], …)` that
//! splits the simplified Newton system into one real and `(S − 1)/2`
//! complex systems.

use crate::numeric::{cabs, cadd, cdiv, csub};
pub(super) use crate::numeric::{cmul, C64};

/// The Radau IIA coefficients of `S` stages (S odd) and the real
/// eigen-transformation of 𝔄.
#[derive(Debug, Clone)]
pub struct RadauStages<const S: usize> {
    /// Nodes `c_i` (ascending, `c_S = 1`).
    pub c: [f64; S],
    /// `𝔄_ij = ∫₀^{c_i} ℓ_j`.
    pub a: [[f64; S]; S],
    /// `(𝔄²)_ij`.
    pub a2: [[f64; S]; S],
    /// Monomial coefficients of the Lagrange basis: `ℓ_j(τ) = Σ_k lag[j][k] τᵏ`.
    pub lag: [[f64; S]; S],
    /// The real eigenvalue γ of 𝔄.
    pub gamma: f64,
    /// The complex eigenvalues `α_p + iβ_p` (β_p > 0) of 𝔄, p = 1 … (S − 1)/2,
    /// in the order of the blocks of `T⁻¹ 𝔄 T`.
    pub mu: Vec<C64>,
    /// `T` with `T⁻¹ 𝔄 T = diag(γ, [α₁ −β₁; β₁ α₁], …)`.
    pub t: [[f64; S]; S],
    /// `T⁻¹`.
    pub t_inv: [[f64; S]; S],
    /// The weights `e_i = γ d_i` of the embedded error estimate
    /// `γ h f(y_n) + Σ_i e_i (Y_i − y_n)` (Hairer & Wanner II, §IV.8, eq.
    /// (8.19); RADAU's `DD`): `Σ_i d_i c_i = −1` and `Σ_i d_i c_iᵏ = 0`
    /// for k = 2 … S, so that the estimate vanishes on polynomials of
    /// degree ≤ S.
    pub e: [f64; S],
}

/// The Radau polynomial `P_s(2x − 1) − P_{s−1}(2x − 1)` at `x` (Legendre
/// recurrence).
pub(super) fn radau_polynomial(s: usize, x: f64) -> f64 {
    let y = 2.0 * x - 1.0;
    let (mut p0, mut p1) = (1.0, y);
    if s == 1 {
        return p1 - p0;
    }
    for k in 1..s {
        let p2 = ((2 * k + 1) as f64 * y * p1 - k as f64 * p0) / (k + 1) as f64;
        p0 = p1;
        p1 = p2;
    }
    p1 - p0
}

/// The interior roots of the Radau polynomial of `s` stages in (0, 1),
/// ascending: sign changes on a fine grid, then bisection to the last bit.
fn radau_nodes(s: usize) -> Vec<f64> {
    let grid = 20_000;
    let mut roots = Vec::with_capacity(s);
    let mut x0 = 0.0;
    let mut f0 = radau_polynomial(s, x0);
    for k in 1..grid {
        let x1 = k as f64 / grid as f64;
        let f1 = radau_polynomial(s, x1);
        if f0 == 0.0 {
            roots.push(x0);
        } else if f0 * f1 < 0.0 {
            let (mut lo, mut hi, mut flo) = (x0, x1, f0);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                let fm = radau_polynomial(s, mid);
                if fm == 0.0 {
                    lo = mid;
                    hi = mid;
                    break;
                }
                if (fm < 0.0) == (flo < 0.0) {
                    lo = mid;
                    flo = fm;
                } else {
                    hi = mid;
                }
            }
            roots.push(0.5 * (lo + hi));
        }
        x0 = x1;
        f0 = f1;
    }
    roots
}

/// Solve the real system `m x = b` (Gaussian elimination, partial pivoting).
fn solve_real(mut m: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for col in 0..n {
        let p = (col..n)
            .max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))
            .unwrap_or(col);
        m.swap(col, p);
        b.swap(col, p);
        for row in col + 1..n {
            let f = m[row][col] / m[col][col];
            for k in col..n {
                m[row][k] -= f * m[col][k];
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| m[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / m[row][row];
    }
    x
}

/// Solve the complex system `m x = b` (Gaussian elimination, partial pivoting).
fn solve_complex(mut m: Vec<Vec<C64>>, mut b: Vec<C64>) -> Vec<C64> {
    let n = b.len();
    for col in 0..n {
        let p = (col..n)
            .max_by(|&i, &j| cabs(m[i][col]).total_cmp(&cabs(m[j][col])))
            .unwrap_or(col);
        m.swap(col, p);
        b.swap(col, p);
        for row in col + 1..n {
            let f = cdiv(m[row][col], m[col][col]);
            for k in col..n {
                m[row][k] = csub(m[row][k], cmul(f, m[col][k]));
            }
            b[row] = csub(b[row], cmul(f, b[col]));
        }
    }
    let mut x = vec![[0.0; 2]; n];
    for row in (0..n).rev() {
        let mut s = b[row];
        for k in row + 1..n {
            s = csub(s, cmul(m[row][k], x[k]));
        }
        x[row] = cdiv(s, m[row][row]);
    }
    x
}

/// The roots of the real polynomial `Σ_k p[k] zᵏ` (Durand–Kerner, then
/// Newton on each root).
fn polynomial_roots(p: &[f64]) -> Vec<C64> {
    let deg = p.len() - 1;
    let lead = p[deg];
    let monic: Vec<f64> = p.iter().map(|x| x / lead).collect();
    let eval = |z: C64| -> (C64, C64) {
        // Horner for the value and the derivative
        let (mut v, mut d) = ([0.0, 0.0], [0.0, 0.0]);
        for &c in monic.iter().rev() {
            d = cadd(cmul(d, z), v);
            v = cadd(cmul(v, z), [c, 0.0]);
        }
        (v, d)
    };
    let seed: C64 = [0.4, 0.9];
    let mut z: Vec<C64> = (0..deg)
        .scan([1.0, 0.0], |acc, _| {
            *acc = cmul(*acc, seed);
            Some(cmul(*acc, [2.0, 0.0]))
        })
        .collect();
    for _ in 0..2000 {
        let mut moved = 0.0_f64;
        for i in 0..deg {
            let mut den: C64 = [1.0, 0.0];
            for j in 0..deg {
                if j != i {
                    den = cmul(den, csub(z[i], z[j]));
                }
            }
            let step = cdiv(eval(z[i]).0, den);
            z[i] = csub(z[i], step);
            moved = moved.max(cabs(step) / cabs(z[i]).max(1.0));
        }
        if moved < 1e-15 {
            break;
        }
    }
    for zi in &mut z {
        for _ in 0..5 {
            let (v, d) = eval(*zi);
            if cabs(d) == 0.0 {
                break;
            }
            *zi = csub(*zi, cdiv(v, d));
        }
    }
    z
}

fn factorial(k: usize) -> f64 {
    (1..=k).map(|i| i as f64).product()
}

impl<const S: usize> RadauStages<S> {
    /// The tableau of Radau IIA with `S` stages; `S` odd.
    pub fn new() -> Self {
        assert!(S % 2 == 1, "Radau IIA tableau: S = {S} must be odd");
        let mut c = [1.0; S];
        for (ci, r) in c.iter_mut().zip(radau_nodes(S)) {
            *ci = r;
        }
        // Lagrange basis: the columns of the inverse Vandermonde matrix
        let mut lag = [[0.0; S]; S];
        for j in 0..S {
            let v: Vec<Vec<f64>> = (0..S)
                .map(|i| (0..S).map(|k| c[i].powi(k as i32)).collect())
                .collect();
            // ℓ_j(c_i) = δ_ij: V x = e_j with V_ik = c_iᵏ
            let mut e = vec![0.0; S];
            e[j] = 1.0;
            let x = solve_real(v, e);
            lag[j].copy_from_slice(&x);
        }
        // 𝔄 from the simplified condition C(S), Σ_j 𝔄_ij c_jᵏ = c_iᵏ⁺¹/(k + 1)
        // for k < S, one backward-stable solve per row (it holds to
        // rounding, where integrating the monomial basis loses digits)
        let mut a = [[0.0; S]; S];
        for i in 0..S {
            let m: Vec<Vec<f64>> = (0..S)
                .map(|k| (0..S).map(|j| c[j].powi(k as i32)).collect())
                .collect();
            let rhs: Vec<f64> = (0..S)
                .map(|k| c[i].powi(k as i32 + 1) / (k + 1) as f64)
                .collect();
            a[i].copy_from_slice(&solve_real(m, rhs));
        }
        let mut a2 = [[0.0; S]; S];
        for i in 0..S {
            for j in 0..S {
                a2[i][j] = (0..S).map(|k| a[i][k] * a[k][j]).sum();
            }
        }
        // det(I − z𝔄) is the denominator of the (S − 1, S) Padé
        // approximant: Σ_j (2S−1−j)! S! / ((2S−1)! j! (S−j)!) (−z)ʲ
        let q: Vec<f64> = (0..=S)
            .map(|j| {
                let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
                sign * factorial(2 * S - 1 - j) * factorial(S)
                    / (factorial(2 * S - 1) * factorial(j) * factorial(S - j))
            })
            .collect();
        let lambdas: Vec<C64> = polynomial_roots(&q)
            .into_iter()
            .map(|z| cdiv([1.0, 0.0], z))
            .collect();
        let gamma = lambdas
            .iter()
            .min_by(|x, y| x[1].abs().total_cmp(&y[1].abs()))
            .map(|l| l[0])
            .unwrap_or(0.0);
        let mut mu: Vec<C64> = lambdas.iter().filter(|l| l[1] > 1e-8).copied().collect();
        mu.sort_by(|x, y| x[0].total_cmp(&y[0]).reverse());
        // eigenvectors: (𝔄 − λI) x = 0 with x_S = 1 from the first S − 1 rows
        let eigvec = |lam: C64| -> Vec<C64> {
            let m: Vec<Vec<C64>> = (0..S - 1)
                .map(|i| {
                    (0..S - 1)
                        .map(|j| {
                            let d = if i == j { lam } else { [0.0, 0.0] };
                            csub([a[i][j], 0.0], d)
                        })
                        .collect()
                })
                .collect();
            let b: Vec<C64> = (0..S - 1).map(|i| [-a[i][S - 1], 0.0]).collect();
            let mut x = solve_complex(m, b);
            x.push([1.0, 0.0]);
            let big = x.iter().map(|z| cabs(*z)).fold(0.0, f64::max);
            x.iter().map(|z| [z[0] / big, z[1] / big]).collect()
        };
        let mut t = [[0.0; S]; S];
        let u = eigvec([gamma, 0.0]);
        for i in 0..S {
            t[i][0] = u[i][0];
        }
        for (p, m) in mu.iter().enumerate() {
            // 𝔄 w = μ w, w = x + iy: columns (x, −y) give [α −β; β α]
            let w = eigvec(*m);
            for i in 0..S {
                t[i][1 + 2 * p] = w[i][0];
                t[i][2 + 2 * p] = -w[i][1];
            }
        }
        let mut t_inv = [[0.0; S]; S];
        for j in 0..S {
            let m: Vec<Vec<f64>> = t.iter().map(|r| r.to_vec()).collect();
            let mut e = vec![0.0; S];
            e[j] = 1.0;
            let x = solve_real(m, e);
            for i in 0..S {
                t_inv[i][j] = x[i];
            }
        }
        // the embedded estimate's d: Σ_i d_i c_iᵏ = −δ_k1, k = 1 … S
        let m: Vec<Vec<f64>> = (1..=S)
            .map(|k| (0..S).map(|i| c[i].powi(k as i32)).collect())
            .collect();
        let mut rhs = vec![0.0; S];
        rhs[0] = -1.0;
        let d = solve_real(m, rhs);
        let e = std::array::from_fn(|i| gamma * d[i]);
        Self {
            c,
            a,
            a2,
            lag,
            gamma,
            mu,
            t,
            t_inv,
            e,
        }
    }
}

/// What Radau IIA's stage loop reads of a tableau of `S` stages: its
/// coefficients and the Lagrange basis `ℓ_j` on the nodes (predictor and
/// dense output; Hairer & Wanner II, §IV.8).
pub(super) trait Tableau<const S: usize> {
    /// The nodes, 𝔄, 𝔄², γ, the μ_p and the transformation `T`.
    fn stages(&self) -> &RadauStages<S>;
    /// `ℓ_j(τ)` for j = 0 … S − 1.
    fn basis(&self, tau: f64) -> [f64; S];
    /// `∫₀^τ ℓ_j` for j = 0 … S − 1.
    fn basis_integral(&self, tau: f64) -> [f64; S];
}

/// The tableau computed from its definition, the basis by Horner's rule.
impl<const S: usize> Tableau<S> for RadauStages<S> {
    fn stages(&self) -> &RadauStages<S> {
        self
    }

    fn basis(&self, tau: f64) -> [f64; S] {
        self.lag
            .map(|l| l.iter().rev().fold(0.0, |acc, &x| acc * tau + x))
    }

    fn basis_integral(&self, tau: f64) -> [f64; S] {
        self.lag.map(|l| {
            l.iter()
                .enumerate()
                .rev()
                .fold(0.0, |acc, (k, &x)| acc * tau + x / (k + 1) as f64)
                * tau
        })
    }
}

/// `Σ_j w_j x(j)`, summed from j = 0 on (the rounding of the sums
/// written out term by term).
#[inline(always)]
pub(super) fn dot<const S: usize>(w: &[f64; S], x: impl Fn(usize) -> f64) -> f64 {
    let mut s = w[0] * x(0);
    for j in 1..S {
        s += w[j] * x(j);
    }
    s
}

impl<const S: usize> Default for RadauStages<S> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::radau::RadauTableau;

    /// S = 5: the nodes are the roots of the Radau polynomial (and
    /// RADAU's constants), the order conditions B(9) and C(5) hold, and
    /// `T⁻¹ 𝔄 T` is block-diagonal with the blocks of the eigenvalues.
    #[test]
    fn five_stages_nodes_order_conditions_and_transformation() {
        let tab = RadauStages::<5>::new();
        // Hairer's RADAU (radau.f), NS = 5
        let known = [
            0.057_104_196_114_517_68,
            0.276_843_013_638_123_8,
            0.583_590_432_368_916_8,
            0.860_240_135_656_219_4,
            1.0,
        ];
        for (i, (&ci, &k)) in tab.c.iter().zip(&known).enumerate() {
            assert!((ci - k).abs() < 1e-15, "c[{i}] = {ci} against {k}");
            assert!(radau_polynomial(5, ci).abs() < 1e-13, "c[{i}] not a root");
        }
        assert_order_conditions(&tab, 1e-14);
        // T⁻¹ 𝔄 T block-diagonal
        assert_eq!(tab.mu.len(), 2);
        assert_block_diagonal(&tab, 1e-14);
        // the embedded error estimate's d = e/γ against RADAU's DD (NS = 5)
        let dd = [
            -27.780_933_944_064_637,
            3.641_478_498_049_213,
            -1.252_547_721_169_118_7,
            0.592_003_167_184_542_9,
            -0.2,
        ];
        for (i, (&e, &d)) in tab.e.iter().zip(&dd).enumerate() {
            assert!(
                (e / tab.gamma - d).abs() < 1e-12 * d.abs(),
                "d[{i}] = {}",
                e / tab.gamma
            );
        }
        // the eigenvalues of 𝔄⁻¹ (computed independently at 40 digits
        // with mpmath's eig of the same 𝔄)
        assert!((1.0 / tab.gamma - 6.2867047517292765).abs() < 1e-12);
        let inv = |m: C64| cdiv([1.0, 0.0], m);
        let (z1, z2) = (inv(tab.mu[0]), inv(tab.mu[1]));
        for (z, re, im) in [
            (z1, 5.70095329867179, -3.2102656003085497),
            (z2, 3.655694325463572, -6.543736899360077),
        ] {
            assert!(
                (z[0] - re).abs() < 1e-12 && (z[1] - im).abs() < 1e-12,
                "{z:?}"
            );
        }
    }

    /// B(2S − 1), `Σ b_i c_i^{k−1} = 1/k` with b the last row of 𝔄
    /// (stiffly accurate), and C(S), `Σ_j 𝔄_ij c_j^{k−1} = c_i^k / k`, to `tol`.
    fn assert_order_conditions<const S: usize>(tab: &RadauStages<S>, tol: f64) {
        for k in 1..2 * S as i32 {
            let s: f64 = (0..S).map(|i| tab.a[S - 1][i] * tab.c[i].powi(k - 1)).sum();
            assert!((s - 1.0 / k as f64).abs() < tol, "S = {S}, B({k}): {s}");
        }
        for i in 0..S {
            for k in 1..=S as i32 {
                let s: f64 = (0..S).map(|j| tab.a[i][j] * tab.c[j].powi(k - 1)).sum();
                let e = tab.c[i].powi(k) / k as f64;
                assert!(
                    (s - e).abs() < tol,
                    "S = {S}, C({k}) row {i}: {s} against {e}"
                );
            }
        }
    }

    /// `T⁻¹ 𝔄 T` against the blocks of γ and the μ_p, entry by entry.
    fn assert_block_diagonal<const S: usize>(tab: &RadauStages<S>, tol: f64) {
        let mut blocks = [[0.0; S]; S];
        blocks[0][0] = tab.gamma;
        for (p, m) in tab.mu.iter().enumerate() {
            let o = 1 + 2 * p;
            blocks[o][o] = m[0];
            blocks[o][o + 1] = -m[1];
            blocks[o + 1][o] = m[1];
            blocks[o + 1][o + 1] = m[0];
        }
        for i in 0..S {
            for j in 0..S {
                let x: f64 = (0..S)
                    .flat_map(|k| (0..S).map(move |l| (k, l)))
                    .map(|(k, l)| tab.t_inv[i][k] * tab.a[k][l] * tab.t[l][j])
                    .sum();
                assert!(
                    (x - blocks[i][j]).abs() < tol,
                    "S = {S}: T⁻¹𝔄T[{i}][{j}] = {x:e} against {:e}",
                    blocks[i][j]
                );
            }
        }
    }

    /// S = 7 (radau13): every constant against an independent 40-digit
    /// computation (mpmath: the roots of the Radau polynomial, 𝔄 from
    /// C(7), its inverse's eigenvalues, the `d_i` from their conditions),
    /// the order conditions B(13) and C(7), and `T⁻¹ 𝔄 T` block-diagonal.
    #[test]
    fn seven_stages_against_an_independent_computation() {
        let tab = RadauStages::<7>::new();
        let known = [
            0.029316427159784893,
            0.1480785996684843,
            0.3369846902811543,
            0.5586715187715501,
            0.7692338620300545,
            0.9269456713197411,
            1.0,
        ];
        for (i, (&ci, &k)) in tab.c.iter().zip(&known).enumerate() {
            assert!((ci - k).abs() < 1e-15, "c[{i}] = {ci} against {k}");
        }
        assert_order_conditions(&tab, 1e-13);
        assert_eq!(tab.mu.len(), 3);
        assert_block_diagonal(&tab, 1e-12);
        assert!((1.0 / tab.gamma - 8.936832788405216).abs() < 1e-11);
        let inv = |m: C64| cdiv([1.0, 0.0], m);
        for (p, (re, im)) in [
            (8.511834825102946, -3.281013624325059),
            (7.14105521918764, -6.623045922639276),
            (4.378693561506806, -10.169693283795011),
        ]
        .into_iter()
        .enumerate()
        {
            let z = inv(tab.mu[p]);
            assert!(
                (z[0] - re).abs() < 1e-11 && (z[1] - im).abs() < 1e-11,
                "1/μ_{p} = {z:?}"
            );
        }
        let dd = [
            -54.374436894128614,
            7.000024004259187,
            -2.355661091987557,
            1.1322890661061344,
            -0.6468913267673587,
            0.38753338537535237,
            -1.0 / 7.0,
        ];
        for (i, (&e, &d)) in tab.e.iter().zip(&dd).enumerate() {
            assert!(
                (e / tab.gamma - d).abs() < 1e-11 * d.abs(),
                "d[{i}] = {}",
                e / tab.gamma
            );
        }
    }

    /// S = 3 computed from the definition reproduces radau5's closed-form
    /// tableau and eigenvalues.
    #[test]
    fn three_stages_match_the_closed_form() {
        let gen = RadauStages::<3>::new();
        let tab = RadauTableau::new();
        for i in 0..3 {
            assert!((gen.c[i] - tab.c[i]).abs() < 1e-15);
            for j in 0..3 {
                assert!((gen.a[i][j] - tab.a[i][j]).abs() < 1e-14, "A[{i}][{j}]");
            }
        }
        assert!((gen.gamma - tab.gamma).abs() < 1e-14);
        // the error weights from their conditions against RADAU5's closed form
        let closed = super::super::tableau::ClosedForm::new();
        for i in 0..3 {
            let c = closed.stages().e[i];
            assert!(
                (gen.e[i] - c).abs() < 1e-13 * c.abs(),
                "e[{i}]: {} against {c}",
                gen.e[i]
            );
        }
        assert!((gen.mu[0][0] - tab.mu[0]).abs() < 1e-14);
        assert!((gen.mu[0][1] - tab.mu[1]).abs() < 1e-14);
    }

    #[test]
    fn basis_and_its_integral_interpolate_at_the_nodes() {
        let tab = RadauStages::<5>::new();
        for i in 0..5 {
            let l = tab.basis(tab.c[i]);
            let w = tab.basis_integral(tab.c[i]);
            for j in 0..5 {
                let d = if i == j { 1.0 } else { 0.0 };
                assert!((l[j] - d).abs() < 1e-12, "ℓ_{j}(c_{i})");
                // two computations of the same number (monomial basis and
                // C(S)); the monomial one loses a few digits
                assert!((w[j] - tab.a[i][j]).abs() < 1e-13, "∫ℓ_{j} to c_{i}");
            }
        }
    }
}
