//! The methods [`super::simulate_into`] drives, each bound to its
//! formulation behind one interface, [`MethodRun`]: the explicit methods on
//! the index-1 or penalty form, coordinate partitioning, the index-3
//! schemes (generalized-α, bdf, radau5) on the index-3 form, the augmented
//! Lagrangian.

use super::*;
use crate::integrate::{AlphaParameters, ImplicitStats, Span};

/// A run's extra summary fields ([`Summary::extra`]).
type Extra = serde_json::Map<String, serde_json::Value>;

/// An index-3 form's consistent start ([`Index3::consistent_start`],
/// [`Augmented::consistent_start`]) and the name of its iterations in the
/// warning.
pub(super) trait StartForm {
    /// The iterations' name in the warning.
    fn how(&self) -> &'static str;
    /// Move `(q, v)` at `t` onto the constraint manifold.
    fn start(&mut self, t: f64, q: &mut [f64], v: &mut [f64]) -> StartResult;
}

/// What a consistent start returns.
type StartResult = Result<crate::formulation::StartCorrection, FormulationError>;

impl StartForm for Index3<'_> {
    fn how(&self) -> &'static str {
        "projection"
    }
    fn start(&mut self, t: f64, q: &mut [f64], v: &mut [f64]) -> StartResult {
        self.consistent_start(t, q, v)
    }
}

impl StartForm for Augmented<'_> {
    fn how(&self) -> &'static str {
        "augmented-Lagrangian"
    }
    fn start(&mut self, t: f64, q: &mut [f64], v: &mut [f64]) -> StartResult {
        self.consistent_start(t, q, v)
    }
}

/// A method bound to its formulation: the one interface [`simulate`]
/// drives, whichever the method.
pub(super) trait MethodRun {
    /// Integrate `span` with the settings `cfg`.
    fn integrate(&mut self, cfg: &RunConfig, span: Span<'_>) -> Result<Report, IntegratorError>;
    /// The form that moves an inconsistent initial state onto the
    /// constraint manifold before the run, where the method needs it (the
    /// index-3 forms); `None`: the index-1 forms keep the given state,
    /// their stabilization or projection treats the violation.
    fn start_form(&mut self) -> Option<&mut dyn StartForm> {
        None
    }
    /// Move an inconsistent initial state onto the constraint manifold
    /// before the run ([`MethodRun::start_form`]); `Some(warning)` if it
    /// moved.
    fn consistent_start(
        &mut self,
        cfg: &RunConfig,
        q: &mut [f64],
        qd: &mut [f64],
    ) -> Result<Option<String>, SimulationError> {
        let Some(f) = self.start_form() else {
            return Ok(None);
        };
        let c = f.start(cfg.t0, q, qd)?;
        Ok(c.changed().then(|| c.describe(cfg.t0, f.how())))
    }
    /// The formulation-specific figures of the run, and extra summary
    /// fields.
    fn work(&self, cfg: &RunConfig) -> (Work, Extra);
}

/// ode23, ode45, rk4 on the index-1 form (eq. (5)) or the penalty form
/// ([`ExplicitForm`]).
pub(super) struct Explicit<'s> {
    f: ExplicitForm<'s>,
    integ: Integrator,
}

impl<'s> Explicit<'s> {
    pub(super) fn new(sys: &'s System, cfg: &RunConfig) -> Result<Self, SimulationError> {
        Ok(Self {
            f: ExplicitForm::new(sys, cfg.formulation)?,
            integ: integrator(cfg.method, cfg.ode.clone())?,
        })
    }
}

impl MethodRun for Explicit<'_> {
    fn integrate(&mut self, _cfg: &RunConfig, s: Span<'_>) -> Result<Report, IntegratorError> {
        let y0 = [s.q0, s.qd0].concat();
        self.integ
            .integrate(&mut self.f, s.t0, s.t_end, &y0, s.output_times, s.obs)
    }
    fn work(&self, cfg: &RunConfig) -> (Work, Extra) {
        let stats = self.f.stats();
        let work = Work {
            formulation: format!("{:?}", cfg.formulation.formulation).to_lowercase(),
            linear_solver: self.f.solver_name().to_string(),
            baumgarte: (
                cfg.formulation.baumgarte.alpha,
                cfg.formulation.baumgarte.beta,
            ),
            factorizations: stats.solver.factorizations,
            regularized_pivots: stats.solver.regularized_pivots,
            indefinite_pivots: stats.solver.indefinite_pivots,
            first_regularized_t: stats.first_regularized_t,
        };
        let mut extra = serde_json::Map::new();
        if cfg.formulation.formulation == crate::formulation::Formulation::Penalty {
            let p = cfg.formulation.penalty;
            for (k, v) in [
                ("penalty", p.alpha),
                ("penalty_xi", p.xi),
                ("penalty_omega", p.omega),
            ] {
                extra.insert(k.into(), v.into());
            }
        }
        if cfg.formulation.projection.enabled {
            extra.insert("projections".into(), stats.projections.into());
            let it = stats.projection_iterations;
            extra.insert("projection_iterations".into(), it.into());
        }
        (work, extra)
    }
}

/// ode23, ode45, rk4 on the independent coordinates of coordinate
/// partitioning ([`Partitioned`]). Extra summary fields: `dof`,
/// `repartitions` (re-choices of the independent set, each a restart),
/// `first_repartition_t`, `partition_newton_iterations`, `max_condition`
/// (largest κ₁ of the dependent block at an accepted step).
pub(super) struct Partition<'s> {
    pub(super) f: Partitioned<'s>,
}

impl MethodRun for Partition<'_> {
    fn integrate(&mut self, cfg: &RunConfig, span: Span<'_>) -> Result<Report, IntegratorError> {
        self.f.integrate(cfg.method, &cfg.ode, span)
    }
    fn work(&self, _cfg: &RunConfig) -> (Work, Extra) {
        let ps = self.f.stats();
        let work = Work {
            formulation: "partitioned".into(),
            linear_solver: "dense-lu".into(),
            baumgarte: (0.0, 0.0),
            factorizations: self.f.factorizations(),
            regularized_pivots: 0,
            indefinite_pivots: 0,
            first_regularized_t: None,
        };
        let mut extra = serde_json::Map::new();
        extra.insert("dof".into(), self.f.dof().into());
        extra.insert("repartitions".into(), ps.repartitions.into());
        if let Some(t) = ps.first_repartition_t {
            extra.insert("first_repartition_t".into(), t.into());
        }
        let it = ps.newton_iterations;
        extra.insert("partition_newton_iterations".into(), it.into());
        extra.insert("max_condition".into(), ps.max_condition.into());
        (work, extra)
    }
}

/// The index-3 augmented Lagrangian with projections ([`Augmented`], a
/// system with a multiplier update) on the generalized-α scheme
/// ([`GenAlpha`]) of an implicit method (newmark
/// with ρ∞ = 1: the trapezoidal rule). Summary: `formulation =
/// "augmented_lagrangian"`, `factorizations` of `W`; `extra` adds
/// `penalty` (that of the step; growth within attempts is in
/// `max_penalty_factor`), `newton_iterations`, `newton_failures`,
/// `projections`, `initial_iterations`, the scheme's parameters and
/// `fixed_step`.
pub(super) struct AugmentedRun<'s> {
    f: Augmented<'s>,
    integ: GenAlpha,
    /// The penalty of the run's step (before any growth within an attempt).
    penalty: f64,
}

impl<'s> AugmentedRun<'s> {
    pub(super) fn new(sys: &'s System, cfg: &RunConfig) -> Result<Self, SimulationError> {
        if !cfg.method.is_generalized_alpha() {
            return Err(FormulationError::InvalidOption {
                option: "formulation",
                value: "augmented_lagrangian".into(),
                reason: format!(
                    "is an index-3 formulation for the implicit methods (genalpha, hht, \
                     newmark/trapezoidal), not for {}",
                    cfg.method.name()
                ),
            }
            .into());
        }
        let integ =
            GenAlpha::for_augmented_lagrangian(cfg.method, cfg.implicit.clone(), cfg.ode.clone())?;
        let h = cfg.ode.fixed_step.unwrap_or(f64::NAN);
        let s0 = integ.params().beta * h * h;
        let f = Augmented::new(sys, cfg.augmented, cfg.formulation.linear_solver, s0)?;
        let penalty = f.alpha();
        Ok(Self { f, integ, penalty })
    }
}

impl MethodRun for AugmentedRun<'_> {
    fn integrate(&mut self, _cfg: &RunConfig, span: Span<'_>) -> Result<Report, IntegratorError> {
        self.integ.integrate(&mut self.f, span)
    }
    fn start_form(&mut self) -> Option<&mut dyn StartForm> {
        Some(&mut self.f)
    }
    fn work(&self, cfg: &RunConfig) -> (Work, Extra) {
        let gs = self.integ.stats();
        let fs = self.f.stats();
        let mut extra = counters(
            &gs,
            &[
                "newton_iterations",
                "newton_failures",
                "projections",
                "penalty_increases",
                "max_penalty_factor",
                "min_step_taken",
            ],
        );
        extra.extend(fields([
            ("penalty", self.penalty.into()),
            ("initial_iterations", fs.initial_iterations.into()),
            ("fixed_step", cfg.ode.fixed_step.into()),
            ("newton_tol", cfg.implicit.newton_tol.into()),
        ]));
        scheme_fields(&mut extra, &self.integ.params(), cfg.implicit.rho_inf);
        let work = index3_work(
            "augmented_lagrangian",
            self.f.solver_name(),
            gs.factorizations,
            &fs.solver,
        );
        (work, extra)
    }
}

/// The generalized-α scheme of a run in the summary's `extra`: `rho_inf`,
/// `alpha_m`, `alpha_f`, `gamma_newmark`, `beta_newmark`.
fn scheme_fields(extra: &mut Extra, p: &AlphaParameters, rho_inf: f64) {
    extra.extend(fields([
        ("rho_inf", rho_inf.into()),
        ("alpha_m", p.alpha_m.into()),
        ("alpha_f", p.alpha_f.into()),
        ("gamma_newmark", p.gamma.into()),
        ("beta_newmark", p.beta.into()),
    ]));
}

/// The counters every index-3 scheme reports in the summary's `extra`.
const IMPLICIT_COUNTERS: [&str; 6] = [
    "newton_iterations",
    "newton_failures",
    "error_rejections",
    "projections",
    "min_step_taken",
    "max_step_taken",
];

/// The [`ImplicitStats`] counters named in `keys` as summary `extra`
/// fields of the same names.
fn counters(st: &ImplicitStats, keys: &[&str]) -> Extra {
    keys.iter()
        .map(|&k| {
            let v: serde_json::Value = match k {
                "newton_iterations" => st.newton_iterations.into(),
                "newton_failures" => st.newton_failures.into(),
                "error_rejections" => st.error_rejections.into(),
                "projections" => st.projections.into(),
                "penalty_increases" => st.penalty_increases.into(),
                "max_penalty_factor" => st.max_penalty_factor.into(),
                "min_step_taken" => st.min_step_taken.into(),
                "max_step_taken" => st.max_step_taken.into(),
                _ => unreachable!("not a counter: {k}"),
            };
            (k.to_string(), v)
        })
        .collect()
}

/// The [`Work`] of an index-3 run: no Baumgarte terms, the Newton
/// matrix's factorisations and the pivots of its solver.
fn index3_work(
    formulation: &str,
    linear_solver: &str,
    factorizations: usize,
    solver: &crate::linalg::SolverStats,
) -> Work {
    Work {
        formulation: formulation.to_string(),
        linear_solver: linear_solver.to_string(),
        baumgarte: (0.0, 0.0),
        factorizations,
        regularized_pivots: solver.regularized_pivots,
        indefinite_pivots: solver.indefinite_pivots,
        first_regularized_t: None,
    }
}

/// Summary `extra` fields from `(name, value)` pairs.
fn fields<const N: usize>(pairs: [(&str, serde_json::Value); N]) -> Extra {
    pairs.into_iter().map(|(k, v)| (k.to_string(), v)).collect()
}

/// An index-3 scheme on [`Index3`] ([`Index3Run`]): how it integrates and
/// what it adds to the summary.
pub(super) trait Index3Scheme {
    /// Integrate `span` on `f` (as [`MethodRun::integrate`]).
    fn integrate(&mut self, f: &mut Index3<'_>, span: Span<'_>) -> Result<Report, IntegratorError>;
    /// The factorisations of the run (all Newton matrices) and the
    /// scheme's summary `extra` fields.
    fn work(&self, f: &Index3<'_>, cfg: &RunConfig) -> (usize, Extra);
}

/// An index-3 scheme bound to [`Index3`]; the same [`Trajectory`] and
/// [`Summary`] as the explicit methods. Summary fields: `formulation =
/// "index3"`, Baumgarte α = β = 0, `rhs_evals` = residual evaluations,
/// `factorizations` = factorisations of the Newton matrices,
/// `failed_steps` = error rejections + Newton failures; `extra` adds the
/// scheme's fields ([`Index3Scheme::work`]).
pub(super) struct Index3Run<'s, S> {
    f: Index3<'s>,
    scheme: S,
}

impl<'s, S> Index3Run<'s, S> {
    /// `scheme` on the index-3 form of `sys` with the Newton matrix in
    /// `newton`.
    fn with_scheme(
        sys: &'s System,
        cfg: &RunConfig,
        newton: NewtonSolverKind,
        scheme: S,
    ) -> Result<Self, SimulationError> {
        let f = Index3::with_newton_solver(sys, cfg.formulation.linear_solver, newton)?;
        Ok(Self { f, scheme })
    }
}

impl<S: Index3Scheme> MethodRun for Index3Run<'_, S> {
    fn integrate(&mut self, _cfg: &RunConfig, span: Span<'_>) -> Result<Report, IntegratorError> {
        self.scheme.integrate(&mut self.f, span)
    }
    fn start_form(&mut self) -> Option<&mut dyn StartForm> {
        Some(&mut self.f)
    }
    fn work(&self, cfg: &RunConfig) -> (Work, Extra) {
        let (factorizations, extra) = self.scheme.work(&self.f, cfg);
        let fs = self.f.stats();
        let work = index3_work(
            "index3",
            self.f.solver_name(),
            factorizations,
            &fs.newton_solver,
        );
        (work, extra)
    }
}

/// genalpha, hht, newmark ([`GenAlpha`] over [`Index3`]); `extra`:
/// `newton_iterations`, `newton_failures`, `error_rejections`,
/// `jacobian_evaluations`, `projections`, `projection_factorizations`,
/// `rho_inf`, `alpha_m`, `alpha_f`, `gamma_newmark`, `beta_newmark`,
/// `fixed_step` (or null), `adaptive`, `newton_tol`, `min_step_taken`,
/// `max_step_taken`.
pub(super) type GenAlphaRun<'s> = Index3Run<'s, GenAlpha>;

impl<'s> GenAlphaRun<'s> {
    pub(super) fn new(sys: &'s System, cfg: &RunConfig) -> Result<Self, SimulationError> {
        let scheme = GenAlpha::new(cfg.method, cfg.implicit.clone(), cfg.ode.clone())?;
        let newton = if cfg.implicit.lu {
            NewtonSolverKind::SparseLu
        } else {
            NewtonSolverKind::SymmetricLdlt
        };
        Self::with_scheme(sys, cfg, newton, scheme)
    }
}

impl Index3Scheme for GenAlpha {
    fn integrate(&mut self, f: &mut Index3<'_>, span: Span<'_>) -> Result<Report, IntegratorError> {
        GenAlpha::integrate(self, f, span)
    }
    fn work(&self, f: &Index3<'_>, cfg: &RunConfig) -> (usize, Extra) {
        let gs = self.stats();
        let fs = f.stats();
        let opts = self.options();
        let fixed_step = if opts.adaptive {
            serde_json::Value::Null
        } else {
            cfg.ode.fixed_step.into()
        };
        let mut extra = counters(&gs, &IMPLICIT_COUNTERS);
        extra.extend(fields([
            ("jacobian_evaluations", fs.jacobians.into()),
            (
                "projection_factorizations",
                (fs.mass_solver.factorizations + fs.output_solver.factorizations).into(),
            ),
            ("fixed_step", fixed_step),
            ("adaptive", opts.adaptive.into()),
            ("newton_tol", opts.newton_tol.into()),
        ]));
        scheme_fields(&mut extra, &self.params(), opts.rho_inf);
        (gs.factorizations, extra)
    }
}

/// bdf ([`Bdf`] over [`Index3`], the symmetric LDLᵀ Newton matrix);
/// `extra`: `newton_iterations`, `newton_failures`, `error_rejections`,
/// `jacobian_evaluations`, `steps_at_order` (orders 1–5),
/// `min_step_taken`, `max_step_taken`.
pub(super) type BdfRun<'s> = Index3Run<'s, Bdf>;

impl<'s> BdfRun<'s> {
    pub(super) fn new(sys: &'s System, cfg: &RunConfig) -> Result<Self, SimulationError> {
        let scheme = Bdf::new(cfg.ode.clone())?;
        Self::with_scheme(sys, cfg, NewtonSolverKind::SymmetricLdlt, scheme)
    }
}

impl Index3Scheme for Bdf {
    fn integrate(&mut self, f: &mut Index3<'_>, span: Span<'_>) -> Result<Report, IntegratorError> {
        Bdf::integrate(self, f, span)
    }
    fn work(&self, f: &Index3<'_>, _cfg: &RunConfig) -> (usize, Extra) {
        let bs = self.stats();
        let mut extra = counters(&bs, &IMPLICIT_COUNTERS);
        extra.remove("projections");
        extra.insert("jacobian_evaluations".into(), f.stats().jacobians.into());
        let orders = bs.steps_at_order[1..].to_vec();
        extra.insert("steps_at_order".into(), orders.into());
        (bs.factorizations, extra)
    }
}

/// radau5 ([`Radau5`] over [`Index3`] for the real stage and
/// [`Index3Complex`] for the complex pair); `factorizations` = real +
/// complex factorisations; `extra`: `newton_iterations`,
/// `newton_failures`, `real_factorizations`, `complex_factorizations`,
/// `projections`, `fixed_step` (or null), `adaptive`, `error_rejections`,
/// `newton_tol`, `min_step_taken`, `max_step_taken`.
pub(super) type RadauRun<'s> = Index3Run<'s, RadauScheme<'s>>;

/// [`Radau5`] (or radau9) with the complex Newton matrix of its system.
pub(super) struct RadauScheme<'s> {
    integ: RadauOrder<'s>,
    c: Index3Complex<'s>,
}

/// The Radau IIA of the run: radau5, or radau9, radau13 or radau59 with
/// the complex matrices of the further complex pairs.
enum RadauOrder<'s> {
    Three(Box<Radau5>),
    Five(Box<(crate::integrate::Radau9, Index3Complex<'s>)>),
    Seven(Box<(crate::integrate::Radau13, [Index3Complex<'s>; 2])>),
    Variable(Box<(crate::integrate::Radau59, Index3Complex<'s>)>),
}

impl<'s> RadauRun<'s> {
    pub(super) fn new(sys: &'s System, cfg: &RunConfig) -> Result<Self, SimulationError> {
        let (imp, ode) = (cfg.implicit.clone(), cfg.ode.clone());
        let integ = match cfg.method {
            Method::Radau9 => {
                let r9 = crate::integrate::Radau9::new(imp, ode)?;
                RadauOrder::Five(Box::new((r9, Index3Complex::new(sys)?)))
            }
            Method::Radau13 => {
                let r = crate::integrate::Radau13::new(imp, ode)?;
                let c = [Index3Complex::new(sys)?, Index3Complex::new(sys)?];
                RadauOrder::Seven(Box::new((r, c)))
            }
            Method::Radau59 => {
                let r = crate::integrate::Radau59::new(imp, ode)?;
                RadauOrder::Variable(Box::new((r, Index3Complex::new(sys)?)))
            }
            _ => RadauOrder::Three(Box::new(Radau5::new(imp, ode)?)),
        };
        let scheme = RadauScheme {
            integ,
            c: Index3Complex::new(sys)?,
        };
        Self::with_scheme(sys, cfg, NewtonSolverKind::SymmetricLdlt, scheme)
    }
}

impl Index3Scheme for RadauScheme<'_> {
    fn integrate(&mut self, f: &mut Index3<'_>, span: Span<'_>) -> Result<Report, IntegratorError> {
        match &mut self.integ {
            RadauOrder::Three(r5) => r5.integrate(f, &mut self.c, span),
            RadauOrder::Five(b) => {
                let (r9, c2) = &mut **b;
                let cplx: [&mut dyn crate::integrate::ComplexNewton; 2] = [&mut self.c, c2];
                r9.integrate(f, cplx, span)
            }
            RadauOrder::Seven(b) => {
                let (r, [c2, c3]) = &mut **b;
                r.integrate(f, [&mut self.c, c2, c3], span)
            }
            RadauOrder::Variable(b) => {
                let (r, c2) = &mut **b;
                let cplx: [&mut dyn crate::integrate::ComplexNewton; 2] = [&mut self.c, c2];
                r.integrate(f, cplx, span)
            }
        }
    }
    fn work(&self, _f: &Index3<'_>, cfg: &RunConfig) -> (usize, Extra) {
        let rs = match &self.integ {
            RadauOrder::Three(r5) => r5.stats(),
            RadauOrder::Five(b) => b.0.stats(),
            RadauOrder::Seven(b) => b.0.stats(),
            RadauOrder::Variable(b) => b.0.stats(),
        };
        let mut extra = counters(&rs, &IMPLICIT_COUNTERS);
        if let RadauOrder::Variable(b) = &self.integ {
            let o = b.0.order_counts();
            extra.extend(fields([
                ("steps_order5", o.steps_order5.into()),
                ("steps_order9", o.steps_order9.into()),
                ("order_changes", o.changes.into()),
            ]));
        }
        extra.extend(fields([
            ("real_factorizations", rs.factorizations.into()),
            ("complex_factorizations", rs.complex_factorizations.into()),
            ("fixed_step", cfg.ode.fixed_step.into()),
            (
                "adaptive",
                (cfg.implicit.adaptive || cfg.method.is_adaptive()).into(),
            ),
            ("newton_tol", cfg.implicit.newton_tol.into()),
        ]));
        (rs.factorizations + rs.complex_factorizations, extra)
    }
}
