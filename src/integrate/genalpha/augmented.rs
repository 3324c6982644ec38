//! The index-3 augmented Lagrangian with mass-orthogonal projections of
//! velocities and accelerations ("ALI3-P"; Bayo & Ledesma, "Augmented
//! Lagrangian and mass-orthogonal projection methods for constrained
//! multibody dynamics", Nonlinear Dyn. 9 (1996) 113–130; Cuadrado, Cardenal,
//! Morer & Bayo, "Intelligent simulation of multibody dynamics: space-state
//! and descriptor methods in sequential and parallel computing
//! environments", Multibody Syst. Dyn. 4 (2000); the reference formulation
//! of González, Dopico & Cuadrado's multibody benchmark), run by
//! [`GenAlpha`](super::GenAlpha) on a system with a
//! [`MultiplierUpdate`](super::super::implicit::MultiplierUpdate)
//! (`formulation::Augmented`).
//!
//! The equations of motion carry the constraint forces as a penalty plus
//! iterated multipliers, `M q̈ + Φ_qᵀ(αΦ + λ*) = g(q, q̇, t)`,
//! `λ*_{i+1} = λ*_i + αΦ_{i+1}`: no multiplier unknowns, no constraint
//! rows, a positive (semi-)definite penalty term — rank loss of Φ_q
//! (singular configurations) and redundant constraints need nothing
//! special. The scheme is the generalized-α member of the method
//! ([`AlphaParameters`](super::AlphaParameters); the trapezoidal rule is
//! Newmark β = ¼, γ = ½, i.e. `AlphaParameters::newmark(1)`), with the
//! positions as unknowns as in [`super`]: `∂q̇/∂q = γ' = γ/(βh)`,
//! `∂q̈/∂q = β' = (1 − α_m)/((1 − α_f)βh²)`. Newton on the residual scaled
//! by `s = βh²` (= h²/4 for the trapezoidal rule):
//!
//! ```text
//! f(q) = s [M q̈ + Φ_qᵀ(αΦ + λ*) − g]
//! W Δq = −f(q),  W = c_m M + c_c C + s (K + Φ_qᵀαΦ_q)          c_m = sβ', c_c = sγ'
//! λ*_{i+1} = λ*_i + αΦ(q_{i+1})
//! ```
//!
//! (`C = −∂g/∂q̇`, `K = −∂g/∂q + (Φ_qᵀλ)_q`; for the trapezoidal rule `W` is
//! `M + (h/2)C + (h²/4)(Φ_qᵀαΦ_q + K)`, the matrix of the ALI3-P
//! references), with `W` factorised at every predictor, until the weighted
//! Newton correction itself is below the tolerance (the multiplier update
//! contracts only linearly: no rate estimate). Then the velocities and
//! accelerations are projected with the same matrix (mass-orthogonal:
//! minimal `‖Δ‖_{W*}`, `W* = W − sΦ_qᵀαΦ_q`, with the violation penalised
//! by α):
//!
//! ```text
//! W Δq̇ = −s Φ_qᵀα (Φ_q q̇ + Φ_t),     W Δq̈ = −s Φ_qᵀα (Φ_q q̈ − γ)
//! ```
//!
//! and the auxiliary acceleration `a_{n+1}` of generalized-α is recomputed
//! from the projected `q̈_{n+1}`. Fixed step; a Newton failure halves the
//! step and the grid point is reached by sub-steps that double again.
//! An inconsistent initial state is projected onto the manifold before the
//! run (`formulation::Augmented::consistent_start`).
//!
//! **Penalty growth.** The multiplier update contracts by about
//! `1/(1 + x)` per iteration along a constraint direction, `x = c_k α σ²/m`
//! with `σ²/m` its eigenvalue of `Φ_q M⁻¹Φ_qᵀ`; near a singular position σ
//! goes to zero and the iteration crawls (two parallelogram loops crossing
//! together contract with θ close to 1, so the default Newton tolerance
//! is never reached and the step collapses). When the contraction θ stays above
//! [`SLOW_CONTRACTION`] after the matrix was renewed at the iterate, α is
//! multiplied for the rest of the attempt by `(1/0.1 − 1)/(1/θ − 1)`
//! (the factor that turns θ into 0.1), at most [`MAX_PENALTY_FACTOR`] in
//! all, and `W` is refactorised; the next step starts from the default α
//! again (a large α everywhere costs conditioning and branch changes at
//! the singular positions, docs/constraint_methods.md). A stagnating
//! iteration whose corrections are below `NOISE_REL` of the positions has
//! converged to the noise of the solve, as in generalized-α.

use super::super::driver::Failure;
use super::super::implicit::Convergence;
use super::super::{ImplicitOptions, IntegratorError, Method};
use super::Run;

/// Newton iterations per attempt that scenarios give the augmented
/// Lagrangian when `integrator.max_newton` is not set (the implicit
/// default, 8, is for generalized-α): the multiplier update after every
/// correction converges linearly (docs/constraint_methods.md).
pub const ALM_MAX_NEWTON: usize = 30;

/// A Newton contraction `θ` above this with a fresh matrix raises the
/// penalty for the rest of the attempt (module docs, "Penalty growth").
pub const SLOW_CONTRACTION: f64 = 0.5;
/// The contraction the raised penalty aims at: the multiplier iteration
/// contracts by `1/(1 + x)` with `x = c_k α σ²/m`, so α is multiplied by
/// `(1/TARGET − 1)/(1/θ − 1)`.
const TARGET_CONTRACTION: f64 = 0.1;
/// Largest factor over the default penalty within one attempt (the
/// conditioning of `W` grows with it).
pub const MAX_PENALTY_FACTOR: f64 = 1e4;

/// The options that do not apply to the augmented Lagrangian (fixed step,
/// projections always on, a symmetric Newton matrix renewed at every
/// predictor): [`IntegratorError::NotApplicable`] for the first set one.
pub(super) fn check_options(method: Method, opts: &ImplicitOptions) -> Result<(), IntegratorError> {
    let d = ImplicitOptions::default();
    for (option, differs) in [
        ("adaptive", opts.adaptive != d.adaptive),
        ("project", opts.project != d.project),
        ("reuse", opts.reuse != d.reuse),
        ("filter_error", opts.filter_error != d.filter_error),
        (
            "check_constraints",
            opts.check_constraints != d.check_constraints,
        ),
        ("lu", opts.lu != d.lu),
        ("extrapolate", opts.extrapolate != d.extrapolate),
    ] {
        if differs {
            return Err(IntegratorError::NotApplicable {
                option,
                method: method.name(),
                reason: "not used by the augmented Lagrangian formulation (fixed step, \
                         projections always on, symmetric Newton matrix)"
                    .into(),
            });
        }
    }
    Ok(())
}

/// The answer to a slowly contracting multiplier iteration.
pub(super) enum SlowAnswer {
    /// Renew the matrix at the iterate (the predictor's may be stale).
    Renew,
    /// The penalty was raised: renew the matrix, measure the rate anew.
    RaisedPenalty,
    /// Nothing left to do (the penalty at its largest): iterate on.
    Nothing,
}

impl Run<'_, '_> {
    /// A contraction above [`SLOW_CONTRACTION`] (module docs, "Penalty
    /// growth"): first renew the matrix at the iterate; still slow with a
    /// fresh matrix, raise the penalty by the factor that turns θ into
    /// [`TARGET_CONTRACTION`] (at least 2, `boost` at most
    /// [`MAX_PENALTY_FACTOR`] in the attempt).
    pub(super) fn slow_multipliers(
        &mut self,
        conv: &mut Convergence,
        boost: &mut f64,
    ) -> SlowAnswer {
        if !conv.renewed() {
            conv.renewed_by_scheme();
            return SlowAnswer::Renew;
        }
        if *boost >= 0.5 * MAX_PENALTY_FACTOR {
            return SlowAnswer::Nothing;
        }
        let theta = conv.theta();
        let f = ((1.0 / TARGET_CONTRACTION - 1.0) / (1.0 / theta - 1.0))
            .max(2.0)
            .min(MAX_PENALTY_FACTOR / *boost);
        *boost *= f;
        if let Some(al) = self.sys.multiplier_update() {
            al.scale_penalty(f);
        }
        self.stats.penalty_increases += 1;
        self.stats.max_penalty_factor = self.stats.max_penalty_factor.max(*boost);
        SlowAnswer::RaisedPenalty
    }

    /// After an accepted attempt to `t_new` of step `h`: the projections
    /// of q̇ and q̈ with the factorised `W` (module docs) and `a_{n+1}`
    /// from the projected q̈ (the generalized-α recurrence).
    pub(super) fn project_motion(&mut self, t_new: f64, h: f64) -> Result<(), Failure> {
        self.stats.projections += 1;
        let s = self.p.beta * h * h;
        let t_from = self.t;
        if let Some(al) = self.sys.multiplier_update() {
            let new = &mut self.new;
            al.project_motion(t_new, &new.q, &mut new.v, &mut new.qdd, s)
                .map_err(Failure::system("projection", t_new, Some(t_from)))?;
        }
        let (am, af) = (self.p.alpha_m, self.p.alpha_f);
        let (cur, new) = (&self.cur, &mut self.new);
        for i in 0..self.n {
            new.a[i] = ((1.0 - af) * new.qdd[i] + af * cur.qdd[i] - am * cur.a[i]) / (1.0 - am);
        }
        Ok(())
    }
}
