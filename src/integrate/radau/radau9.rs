//! Radau IIA of order 9 (S = 5 stages) on the index-3 equations of a
//! [`SecondOrderDae`], fixed or adaptive steps (docs/radau.md, "radau9").
//!
//! The same scheme as [`super::Radau5`] with five stages (Hairer & Wanner
//! II, §IV.5, §IV.8, §VII.4): stage accelerations `A_i` and multipliers
//! `Λ_i` at `t_n + c_i h`,
//!
//! ```text
//! Q_i = q_n + c_i h v_n + h² Σ_j (𝔄²)_ij A_j,     V_i = v_n + h Σ_j 𝔄_ij A_j
//! M A_i + Φ_qᵀ(Q_i) Λ_i − g(Q_i, V_i, t_i) = 0,    Φ(Q_i, t_i) = 0
//! ```
//!
//! stiffly accurate (`q_{n+1} = Q_5`, `v_{n+1} = V_5`). On index-3
//! problems the positions converge with order `2S − 1 = 9`, the
//! velocities with order `S = 5`, the multipliers with order `S − 1 = 4`
//! (Hairer, Lubich & Roche, LNM 1409, 1989); L-stable (the (4, 5) Padé
//! approximant of eᶻ).
//!
//! The simplified Newton system is split by the tableau's
//! `T⁻¹ 𝔄 T = diag(γ, [α₁ −β₁; β₁ α₁], [α₂ −β₂; β₂ α₂])`
//! ([`RadauStages`]) into one real system (`SecondOrderDae::factorize`
//! with `c = [1, hγ, h²γ²]`) and two complex ones
//! ([`ComplexNewton`] with `μ_p = α_p + iβ_p`), each
//! `[M + hμ C_t + h²μ² K_t, Φ_qᵀ; Φ_q, 0]` with the constraint rows
//! divided by `h²μ²`; the Jacobians frozen at the step's start and kept
//! across steps while Newton contracts, the predictor, the convergence
//! test, the renewals within an attempt, the start ramp and the fixed-step
//! grid are radau5's (its module docs; the same stage loop, with five
//! stages). Dense output: the collocation
//! polynomials (`V` of degree 5, `Q` the quintic through `q_n` and the
//! `Q_i`), the rows projected onto `Φ = 0`
//! ([`SecondOrderDae::project_output`]).
//!
//! **Adaptive** ([`ImplicitOptions::adaptive`]): radau5's step control
//! (its module docs, "Step size") with the five-stage embedded estimate
//! `γ h f(y_n) + Σ_i e_i (Y_i − y_n)` (RADAU's `DD` for five stages,
//! [`RadauStages::e`]; O(h⁶)), RADAU's tolerance transformation
//! `rtol' = 0.1 rtol^{3/5}`, the controller exponent 1/6 and Newton's
//! fraction `fnewt = max(10 ε / rtol', min(0.03, rtol'^{2/3}))` (Hairer &
//! Wanner, J. Comput. Appl. Math. 111, 1999).

use super::*;

/// Stages of [`Radau9`].
const S: usize = 5;

/// Radau IIA, S = 5, fixed or adaptive steps, on the index-3 equations
/// (module docs).
#[derive(Debug, Clone)]
pub struct Radau9 {
    opts: ImplicitOptions,
    ode: OdeOptions,
    tab: RadauStages<S>,
    stats: ImplicitStats,
}

impl Radau9 {
    /// Validate the options: a fixed step ([`OdeOptions::fixed_step`]),
    /// or with [`ImplicitOptions::adaptive`] the tolerances `rtol`, `atol`
    /// (and `max_step`, `initial_step`); of [`ImplicitOptions`] it reads
    /// `newton_tol`, `max_newton`, `reuse`, `project`, `min_step` and
    /// `adaptive`, as [`Radau5::new`].
    pub fn new(opts: ImplicitOptions, ode: OdeOptions) -> Result<Self, IntegratorError> {
        ode.validate(Method::Radau9, opts.adaptive)?;
        opts.validate(Method::Radau9, ode.fixed_step)?;
        Ok(Self {
            opts,
            ode,
            tab: RadauStages::new(),
            stats: ImplicitStats::default(),
        })
    }

    /// Counters of the last run (`complex_factorizations` counts both
    /// complex pairs).
    pub fn stats(&self) -> ImplicitStats {
        self.stats
    }

    /// Integrate from `(t0, q0, q̇0)` to `t_end`; `cplx` are two complex
    /// Newton matrices of the same system (one per complex pair of 𝔄).
    /// Outputs as [`Radau5::integrate`].
    pub fn integrate(
        &mut self,
        sys: &mut dyn SecondOrderDae,
        [c1, c2]: [&mut dyn ComplexNewton; 2],
        span: Span<'_>,
    ) -> Result<Report, IntegratorError> {
        let (tab, opts, ode) = (&self.tab, &self.opts, &self.ode);
        let (report, stats) = integrate_stages(tab, opts, ode, sys, vec![c1, c2], span)?;
        self.stats = stats;
        Ok(report)
    }
}
