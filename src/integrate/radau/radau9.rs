//! Radau IIA of order 9 and 13 (S = 5 and 7 stages) on the index-3
//! equations of a [`SecondOrderDae`], fixed or adaptive steps
//! (docs/radau.md, "radau9", "radau13").
//!
//! The same scheme as [`super::Radau5`] with S stages (Hairer & Wanner
//! II, §IV.5, §IV.8, §VII.4): stage accelerations `A_i` and multipliers
//! `Λ_i` at `t_n + c_i h`,
//!
//! ```text
//! Q_i = q_n + c_i h v_n + h² Σ_j (𝔄²)_ij A_j,     V_i = v_n + h Σ_j 𝔄_ij A_j
//! M A_i + Φ_qᵀ(Q_i) Λ_i − g(Q_i, V_i, t_i) = 0,    Φ(Q_i, t_i) = 0
//! ```
//!
//! stiffly accurate (`q_{n+1} = Q_S`, `v_{n+1} = V_S`). On index-3
//! problems the positions converge with order `2S − 1` (9, 13), the
//! velocities with order `S`, the multipliers with order `S − 1`
//! (Hairer, Lubich & Roche, LNM 1409, 1989); L-stable (the (S − 1, S)
//! Padé approximant of eᶻ).
//!
//! The simplified Newton system is split by the tableau's
//! `T⁻¹ 𝔄 T = diag(γ, [α₁ −β₁; β₁ α₁], …, [α_P −β_P; β_P α_P])`
//! ([`RadauStages`], `P = (S − 1)/2`) into one real system
//! (`SecondOrderDae::factorize` with `c = [1, hγ, h²γ²]`) and P complex
//! ones ([`ComplexNewton`] with `μ_p = α_p + iβ_p`), each
//! `[M + hμ C_t + h²μ² K_t, Φ_qᵀ; Φ_q, 0]` with the constraint rows
//! divided by `h²μ²`; the Jacobians frozen at the predictor's middle stage and kept
//! across steps while Newton contracts, the predictor, the convergence
//! test, the renewals within an attempt, the start ramp and the fixed-step
//! grid are radau5's (its module docs; the same stage loop, with S
//! stages). Dense output: the collocation polynomials (`V` of degree S,
//! `Q` the polynomial of degree S through `q_n` and the `Q_i`), the rows
//! projected onto `Φ = 0` ([`SecondOrderDae::project_output`]).
//!
//! **Adaptive** ([`ImplicitOptions::adaptive`]): radau5's step control
//! (its module docs, "Step size") with the S-stage embedded estimate
//! `γ h f(y_n) + Σ_i e_i (Y_i − y_n)` (RADAU's `DD` for S stages,
//! [`RadauStages::e`]; O(h^{S+1})), RADAU's tolerance transformation
//! `rtol' = 0.1 rtol^{(S+1)/(2S)}`, the controller exponent `1/(S + 1)`,
//! Newton's fraction of the error test's weights
//! `fnewt = max(10 ε / rtol', min(0.03, rtol'^{(S−1)/(S+1)}))` and RADAU's
//! limit of Newton corrections, `max_newton + 5 (S − 3)/2` (Hairer &
//! Wanner, J. Comput. Appl. Math. 111, 1999; the code RADAU's `NIT`).

use super::*;

/// Radau IIA of `S` stages (S odd, `P = (S − 1)/2` complex pairs), fixed
/// or adaptive steps, on the index-3 equations (module docs).
#[derive(Debug, Clone)]
pub struct RadauHigh<const S: usize, const P: usize> {
    method: Method,
    opts: ImplicitOptions,
    ode: OdeOptions,
    tab: RadauStages<S>,
    stats: ImplicitStats,
}

/// Radau IIA of order 9 (five stages, two complex pairs).
pub type Radau9 = RadauHigh<5, 2>;
/// Radau IIA of order 13 (seven stages, three complex pairs).
pub type Radau13 = RadauHigh<7, 3>;

impl<const S: usize, const P: usize> RadauHigh<S, P> {
    /// Validate the options: a fixed step ([`OdeOptions::fixed_step`]),
    /// or with [`ImplicitOptions::adaptive`] the tolerances `rtol`, `atol`
    /// (and `max_step`, `initial_step`); of [`ImplicitOptions`] it reads
    /// `newton_tol`, `max_newton`, `reuse`, `project`, `min_step` and
    /// `adaptive`, as [`Radau5::new`].
    pub fn new(opts: ImplicitOptions, ode: OdeOptions) -> Result<Self, IntegratorError> {
        const {
            assert!(
                (S == 5 || S == 7) && S == 2 * P + 1,
                "radau9 (S = 5, P = 2) or radau13 (S = 7, P = 3)"
            )
        };
        let method = if S == 5 {
            Method::Radau9
        } else {
            Method::Radau13
        };
        ode.validate(method, opts.adaptive)?;
        opts.validate(method, ode.fixed_step)?;
        Ok(Self {
            method,
            opts,
            ode,
            tab: RadauStages::new(),
            stats: ImplicitStats::default(),
        })
    }

    /// The method of this stage count.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Counters of the last run (`complex_factorizations` counts every
    /// complex pair's).
    pub fn stats(&self) -> ImplicitStats {
        self.stats
    }

    /// Integrate from `(t0, q0, q̇0)` to `t_end`; `cplx` are P complex
    /// Newton matrices of the same system (one per complex pair of 𝔄).
    /// Outputs as [`Radau5::integrate`].
    pub fn integrate(
        &mut self,
        sys: &mut dyn SecondOrderDae,
        cplx: [&mut dyn ComplexNewton; P],
        span: Span<'_>,
    ) -> Result<Report, IntegratorError> {
        let (tab, opts, ode) = (&self.tab, &self.opts, &self.ode);
        // each matrix reborrowed for the run (the trait objects' lifetimes
        // shortened to that of `sys`)
        let cplx = cplx
            .into_iter()
            .map(|c| -> &mut dyn ComplexNewton { c })
            .collect();
        let (report, stats) = integrate_stages(tab, opts, ode, sys, cplx, span)?;
        self.stats = stats;
        Ok(report)
    }
}
