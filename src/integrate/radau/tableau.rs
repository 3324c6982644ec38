//! The Radau IIA (s = 3) tableau: nodes, coefficients, the Lagrange basis
//! of the collocation polynomials and the eigen-transformation of 𝔄
//! (Hairer & Wanner II, §IV.8).

use super::stages::{cmul, RadauStages, Tableau};

/// The Radau IIA (s = 3) coefficients and the transformation of its
/// matrix, computed from the nodes.
#[derive(Debug, Clone)]
pub struct RadauTableau {
    /// Nodes `c_i`.
    pub c: [f64; 3],
    /// `𝔄_ij = ∫₀^{c_i} ℓ_j`.
    pub a: [[f64; 3]; 3],
    /// `(𝔄²)_ij`.
    pub a2: [[f64; 3]; 3],
    /// Monomial coefficients of the Lagrange basis `ℓ_j` on `c`.
    pub lag: [[f64; 3]; 3],
    /// Real eigenvalue γ of 𝔄.
    pub gamma: f64,
    /// Complex eigenvalue `α + iβ` of 𝔄.
    pub mu: [f64; 2],
    /// `T` with `T⁻¹ 𝔄 T = diag(γ, [α −β; β α])`.
    pub t: [[f64; 3]; 3],
    /// `T⁻¹`.
    pub t_inv: [[f64; 3]; 3],
}

fn inv3(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let (i1, i2) = ((j + 1) % 3, (j + 2) % 3);
            let (j1, j2) = ((i + 1) % 3, (i + 2) % 3);
            r[i][j] = (m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]) / det;
        }
    }
    r
}

impl RadauTableau {
    /// The coefficients of Radau IIA with three stages.
    pub fn new() -> Self {
        let s6 = 6f64.sqrt();
        let c = [(4.0 - s6) / 10.0, (4.0 + s6) / 10.0, 1.0];
        // Lagrange basis: solve the Vandermonde system V x = e_j
        let v = [
            [1.0, c[0], c[0] * c[0]],
            [1.0, c[1], c[1] * c[1]],
            [1.0, c[2], c[2] * c[2]],
        ];
        let vi = inv3(&v);
        let mut lag = [[0.0; 3]; 3];
        for (j, l) in lag.iter_mut().enumerate() {
            for (k, lk) in l.iter_mut().enumerate() {
                *lk = vi[k][j];
            }
        }
        let int1 = |l: &[f64; 3], x: f64| l[0] * x + l[1] * x * x / 2.0 + l[2] * x.powi(3) / 3.0;
        let mut a = [[0.0; 3]; 3];
        let mut a2 = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] = int1(&lag[j], c[i]);
            }
        }
        for i in 0..3 {
            for j in 0..3 {
                a2[i][j] = (0..3).map(|k| a[i][k] * a[k][j]).sum();
            }
        }
        // eigenvalues of 𝔄 (RADAU5's constants, Hairer & Wanner II, §IV.8)
        let (c81, c9) = (81f64.cbrt(), 9f64.cbrt());
        let gamma = (6.0 + c81 - c9) / 30.0;
        let alpha = (12.0 - c81 + c9) / 60.0;
        let beta = (c81 + c9) * 3f64.sqrt() / 60.0;
        // real eigenvector: cross product of two rows of 𝔄 − γI
        let r = |m: [f64; 2], i: usize| -> [[f64; 2]; 3] {
            let mut row = [[0.0; 2]; 3];
            for (j, x) in row.iter_mut().enumerate() {
                *x = [a[i][j], 0.0];
            }
            row[i][0] -= m[0];
            row[i][1] -= m[1];
            row
        };
        let cross = |x: [[f64; 2]; 3], y: [[f64; 2]; 3]| -> [[f64; 2]; 3] {
            let mut z = [[0.0; 2]; 3];
            for (k, zk) in z.iter_mut().enumerate() {
                let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                let p = cmul(x[i], y[j]);
                let q = cmul(x[j], y[i]);
                *zk = [p[0] - q[0], p[1] - q[1]];
            }
            z
        };
        let u = cross(r([gamma, 0.0], 0), r([gamma, 0.0], 1));
        let w = cross(r([alpha, beta], 0), r([alpha, beta], 1));
        // 𝔄 w = μ w, w = x + iy: T = [u, x, −y] gives the block [α −β; β α]
        let mut t = [[0.0; 3]; 3];
        for i in 0..3 {
            t[i] = [u[i][0], w[i][0], -w[i][1]];
        }
        let t_inv = inv3(&t);
        Self {
            c,
            a,
            a2,
            lag,
            gamma,
            mu: [alpha, beta],
            t,
            t_inv,
        }
    }
}

/// radau5's coefficients: [`RadauTableau`]'s closed form, with its
/// Lagrange basis, the basis' integral and RADAU5's error weights written
/// out for three stages.
#[derive(Debug, Clone)]
pub(super) struct ClosedForm(RadauStages<3>);

impl ClosedForm {
    /// The closed-form tableau of three stages.
    pub(super) fn new() -> Self {
        let t = RadauTableau::new();
        // RADAU5's error weights `DD1`–`DD3` times γ, in closed form
        let s6 = 6f64.sqrt();
        let e = [
            -(13.0 + 7.0 * s6) / 3.0,
            (-13.0 + 7.0 * s6) / 3.0,
            -1.0 / 3.0,
        ]
        .map(|d| t.gamma * d);
        Self(RadauStages {
            c: t.c,
            a: t.a,
            a2: t.a2,
            lag: t.lag,
            gamma: t.gamma,
            mu: vec![t.mu],
            t: t.t,
            t_inv: t.t_inv,
            e,
        })
    }
}

impl Tableau<3> for ClosedForm {
    fn stages(&self) -> &RadauStages<3> {
        &self.0
    }

    fn basis(&self, tau: f64) -> [f64; 3] {
        self.0.lag.map(|l| l[0] + l[1] * tau + l[2] * tau * tau)
    }

    fn basis_integral(&self, tau: f64) -> [f64; 3] {
        self.0
            .lag
            .map(|l| l[0] * tau + l[1] * tau * tau / 2.0 + l[2] * tau.powi(3) / 3.0)
    }
}

impl Default for RadauTableau {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::RadauTableau;

    /// The tableau against the closed form of Radau IIA (s = 3) and the
    /// transformation against 𝔄.
    #[test]
    fn tableau_and_transformation() {
        let tab = RadauTableau::new();
        let s6 = 6f64.sqrt();
        let exact = [
            [
                (88.0 - 7.0 * s6) / 360.0,
                (296.0 - 169.0 * s6) / 1800.0,
                (-2.0 + 3.0 * s6) / 225.0,
            ],
            [
                (296.0 + 169.0 * s6) / 1800.0,
                (88.0 + 7.0 * s6) / 360.0,
                (-2.0 - 3.0 * s6) / 225.0,
            ],
            [(16.0 - s6) / 36.0, (16.0 + s6) / 36.0, 1.0 / 9.0],
        ];
        for i in 0..3 {
            for j in 0..3 {
                assert!((tab.a[i][j] - exact[i][j]).abs() < 1e-14, "A[{i}][{j}]");
                let sq: f64 = (0..3).map(|k| exact[i][k] * exact[k][j]).sum();
                assert!((tab.a2[i][j] - sq).abs() < 1e-14, "A²[{i}][{j}]");
            }
        }
        let (g, [al, be]) = (tab.gamma, tab.mu);
        let b = [[g, 0.0, 0.0], [0.0, al, -be], [0.0, be, al]];
        for i in 0..3 {
            for j in 0..3 {
                let tbt: f64 = (0..3)
                    .flat_map(|k| (0..3).map(move |l| (k, l)))
                    .map(|(k, l)| tab.t[i][k] * b[k][l] * tab.t_inv[l][j])
                    .sum();
                assert!((tbt - exact[i][j]).abs() < 1e-13, "T B T⁻¹ [{i}][{j}]");
            }
        }
        // eigenvalues of 𝔄⁻¹ as in RADAU5
        assert!((1.0 / g - 3.637834252744496).abs() < 1e-12);
        let d = al * al + be * be;
        assert!((al / d - 2.681082873627752).abs() < 1e-12);
        assert!((be / d - 3.05043019924741).abs() < 1e-12);
    }
}
