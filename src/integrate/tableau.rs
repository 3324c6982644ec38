//! Butcher tableaus, error estimators and continuous extensions of the
//! embedded FSAL pairs used by `ode23` and `ode45`, written exactly as the
//! `A`, `B`, `E` arrays of MATLAB's `ode23.m` / `ode45.m` and the `BI`
//! matrices of `ntrp23.m` / `ntrp45.m` (Shampine & Reichelt, "The MATLAB ODE
//! Suite", SIAM J. Sci. Comput. 18 (1997)).

/// An explicit embedded Runge–Kutta pair with the FSAL property
/// ("first same as last"): the last stage is evaluated at `(t + h, y_new)`
/// and becomes the first stage of the next step.
///
/// Stage `i` (0-based) is evaluated at `t + c[i]·h`, with input
/// `y + h·Σ_{j<i} a[i][j]·k_j`. Row `a[s-1]` holds the weights of the
/// propagated solution `y_new` (local extrapolation: the higher-order
/// formula is propagated).
#[derive(Debug)]
pub(crate) struct EmbeddedTableau {
    /// Abscissae `c_i`, `c_0 = 0`, `c_{s-1} = 1`.
    pub c: &'static [f64],
    /// Strictly lower triangular coefficients; `a[0]` is empty, `a[s-1]` = solution weights.
    pub a: &'static [&'static [f64]],
    /// Error-estimate weights (difference of the two embedded formulas), MATLAB's `E`.
    pub e: &'static [f64],
    /// Continuous extension: `y(t + σh) = y + h·Σ_j k_j·Σ_p bi[j][p]·σ^{p+1}` (MATLAB's `BI`).
    pub bi: &'static [&'static [f64]],
    /// Exponent of the step-size formula, 1/(lower order + 1): MATLAB's `pow`.
    pub pow: f64,
    /// Lower bound of the step-reduction factor after the first failure of a
    /// step: `absh *= max(first_failure_floor, 0.8·(rtol/err)^pow)`.
    /// MATLAB's `ode23.m` uses 0.5, `ode45.m` uses 0.1.
    pub first_failure_floor: f64,
}

impl EmbeddedTableau {
    /// Number of stages including the FSAL stage.
    pub(crate) fn stages(&self) -> usize {
        self.c.len()
    }
    /// Solution weights `b` (last row of `a`).
    pub(crate) fn b(&self) -> &'static [f64] {
        self.a[self.stages() - 1]
    }
    /// Degree of the continuous extension (number of columns of `BI`).
    pub(crate) fn interp_degree(&self) -> usize {
        self.bi[0].len()
    }
}

/// Largest stage count of any tableau here (for stack buffers).
pub(crate) const MAX_STAGES: usize = 7;

/// Bogacki–Shampine 3(2) pair (Bogacki & Shampine, "A 3(2) pair of
/// Runge–Kutta formulas", Appl. Math. Lett. 2 (1989)), as in MATLAB's `ode23.m`,
/// with the cubic Hermite continuous extension of `ntrp23.m`.
pub(crate) static BS23: EmbeddedTableau = EmbeddedTableau {
    c: &[0.0, 1.0 / 2.0, 3.0 / 4.0, 1.0],
    a: &[
        &[],
        &[1.0 / 2.0],
        &[0.0, 3.0 / 4.0],
        &[2.0 / 9.0, 1.0 / 3.0, 4.0 / 9.0],
    ],
    e: &[-5.0 / 72.0, 1.0 / 12.0, 1.0 / 9.0, -1.0 / 8.0],
    bi: &[
        &[1.0, -4.0 / 3.0, 5.0 / 9.0],
        &[0.0, 1.0, -2.0 / 3.0],
        &[0.0, 4.0 / 3.0, -8.0 / 9.0],
        &[0.0, -1.0, 1.0],
    ],
    pow: 1.0 / 3.0,
    first_failure_floor: 0.5,
};

/// Dormand–Prince 5(4) pair (Dormand & Prince, "A family of embedded
/// Runge–Kutta formulae", J. Comput. Appl. Math. 6 (1980)), as in MATLAB's
/// `ode45.m`, with the quartic continuous extension of `ntrp45.m`.
pub(crate) static DP54: EmbeddedTableau = EmbeddedTableau {
    c: &[0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0],
    a: &[
        &[],
        &[1.0 / 5.0],
        &[3.0 / 40.0, 9.0 / 40.0],
        &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
        &[
            19372.0 / 6561.0,
            -25360.0 / 2187.0,
            64448.0 / 6561.0,
            -212.0 / 729.0,
        ],
        &[
            9017.0 / 3168.0,
            -355.0 / 33.0,
            46732.0 / 5247.0,
            49.0 / 176.0,
            -5103.0 / 18656.0,
        ],
        &[
            35.0 / 384.0,
            0.0,
            500.0 / 1113.0,
            125.0 / 192.0,
            -2187.0 / 6784.0,
            11.0 / 84.0,
        ],
    ],
    e: &[
        71.0 / 57600.0,
        0.0,
        -71.0 / 16695.0,
        71.0 / 1920.0,
        -17253.0 / 339200.0,
        22.0 / 525.0,
        -1.0 / 40.0,
    ],
    bi: &[
        &[1.0, -183.0 / 64.0, 37.0 / 12.0, -145.0 / 128.0],
        &[0.0, 0.0, 0.0, 0.0],
        &[0.0, 1500.0 / 371.0, -1000.0 / 159.0, 1000.0 / 371.0],
        &[0.0, -125.0 / 32.0, 125.0 / 12.0, -375.0 / 64.0],
        &[0.0, 9477.0 / 3392.0, -729.0 / 106.0, 25515.0 / 6784.0],
        &[0.0, -11.0 / 7.0, 11.0 / 3.0, -55.0 / 28.0],
        &[0.0, 3.0 / 2.0, -4.0, 5.0 / 2.0],
    ],
    pow: 1.0 / 5.0,
    first_failure_floor: 0.1,
};

#[cfg(test)]
mod tests {
    use super::*;

    fn check(tab: &EmbeddedTableau) {
        let s = tab.stages();
        assert!(s <= MAX_STAGES);
        assert_eq!(tab.a.len(), s);
        assert_eq!(tab.e.len(), s);
        assert_eq!(tab.bi.len(), s);
        assert_eq!(tab.c[0], 0.0);
        assert_eq!(tab.c[s - 1], 1.0);
        for i in 0..s {
            assert_eq!(tab.a[i].len(), i);
            let sum: f64 = tab.a[i].iter().sum();
            assert!(
                (sum - tab.c[i]).abs() < 1e-14,
                "row {i}: {sum} vs {}",
                tab.c[i]
            );
            assert_eq!(tab.bi[i].len(), tab.interp_degree());
        }
        let esum: f64 = tab.e.iter().sum();
        assert!(esum.abs() < 1e-15);
        // The interpolant at sigma = 1 reproduces y_new.
        for j in 0..s {
            let bj = if j < s - 1 { tab.b()[j] } else { 0.0 };
            let sum: f64 = tab.bi[j].iter().sum();
            assert!((sum - bj).abs() < 1e-14, "BI row {j}");
        }
    }

    #[test]
    fn tableaus_are_consistent() {
        check(&BS23);
        check(&DP54);
    }
}
