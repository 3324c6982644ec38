//! The run part of a scenario: `[integrator]`, `[stabilization]`,
//! `formulation`, `linear_solver`, `[time]`, `[output]` → a [`RunConfig`].
//! Keys that do not apply to the chosen method are errors naming the key.

use super::{error, positive, RawScenario, ScenarioError};
use crate::formulation::{
    AugmentedParams, Baumgarte, BaumgarteRule, Formulation, FormulationError, Index1Options,
    PartitionOptions, PenaltyParams, Projection,
};
use crate::integrate::{
    method_alias, methods_taking, Equations, Family, ImplicitOptions, IntegratorError, KeyUse,
    Method, OdeOptions, Tolerance, METHODS, STEP_CONTROL_KEYS,
};
use crate::linalg::SolverKind;
use crate::output::Format;
use crate::parallel::Threads;
use crate::simulation::{MethodChoice, OutputQuantities, RunConfig};
use serde::Deserialize;

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawStabilization {
    alpha: Option<f64>,
    beta: Option<f64>,
    rule: Option<String>,
    // index-1 methods: `Projection`; formulation = "penalty": `PenaltyParams`
    projection: Option<bool>,
    correction: Option<String>,
    // formulation = "partitioned": `PartitionOptions::max_condition`
    partition_condition: Option<f64>,
    penalty: Option<f64>,
    penalty_xi: Option<f64>,
    penalty_omega: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawIntegrator {
    method: Option<String>,
    rtol: Option<f64>,
    atol: Option<f64>,
    step: Option<f64>,
    max_step: Option<f64>,
    initial_step: Option<f64>,
    // implicit methods (genalpha, hht, newmark): see `ImplicitOptions`
    rho_inf: Option<f64>,
    adaptive: Option<bool>,
    newton_tol: Option<f64>,
    max_newton: Option<i64>,
    project: Option<bool>,
    reuse: Option<bool>,
    filter_error: Option<bool>,
    check_constraints: Option<bool>,
    min_step: Option<f64>,
    lu: Option<bool>,
    extrapolate: Option<bool>,
    // radau5, radau9, radau13 with a fixed step: `ImplicitOptions::flight_step`
    flight_step: Option<f64>,
    // bdf only: see `OdeOptions::max_order`, `OdeOptions::ndf`
    max_order: Option<i64>,
    ndf: Option<bool>,
    // every method: `crate::parallel::Threads`
    threads: Option<RawThreads>,
}

/// `integrator.threads`: `"auto"` or a number.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub(super) enum RawThreads {
    Number(i64),
    Name(String),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTime {
    #[serde(default)]
    start: f64,
    end: f64,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawOutput {
    dt: Option<f64>,
    /// Extra quantities per output row: "velocities", "accelerations",
    /// "reactions", "energy".
    #[serde(default)]
    quantities: Vec<String>,
    /// Table format: "csv" (default) or "arrow".
    format: Option<String>,
}

/// `output.format`: a [`Format`] this build can write.
pub(super) fn output_format(raw: &RawScenario, file: &str) -> Result<Format, ScenarioError> {
    let Some(name) = &raw.output.format else {
        return Ok(Format::default());
    };
    let f: Format = name.parse().map_err(|m| error(file, "output.format", m))?;
    if !f.available() {
        return Err(error(
            file,
            "output.format",
            format!("'{name}' needs mbsolve built with the '{name}' feature"),
        ));
    }
    Ok(f)
}

/// Build the run settings of `raw`; errors name keys of `file`.
pub(super) fn build(raw: &RawScenario, file: &str) -> Result<RunConfig, ScenarioError> {
    let err = |key: String, message: String| error(file, key, message);
    // an alias of the method table fixes ρ∞ ("trapezoidal": Newmark
    // with ρ∞ = 1)
    let alias = raw.integrator.method.as_deref().and_then(method_alias);
    if let (Some((row, a)), Some(r)) = (alias, raw.integrator.rho_inf) {
        return Err(err(
            "integrator.rho_inf".into(),
            format!(
                "{r} is given, but method = \"{}\" is {} with rho_inf = {}",
                a.name, row.name, a.rho_inf
            ),
        ));
    }
    // "auto": chosen at t0 (crate::simulation::choice); ode45 stands in
    // for the option checks, which take its step-control keys
    let auto = raw
        .integrator
        .method
        .as_deref()
        .is_some_and(|m| m.trim().eq_ignore_ascii_case(AUTO));
    let method: Method = match (&raw.integrator.method, alias) {
        _ if auto => Method::Ode45,
        (_, Some((row, _))) => row.method,
        (Some(m), None) => m.parse().map_err(|e: crate::integrate::IntegratorError| {
            err(
                "integrator.method".into(),
                format!("{e}, or \"{AUTO}\" (chosen at t0)"),
            )
        })?,
        (None, None) => Method::Ode23,
    };
    if auto {
        auto_keys(raw).map_err(|(key, why)| err(key, why))?;
    }
    let ri = &raw.integrator;
    let mut ode = OdeOptions::default();
    if let Some(r) = ri.rtol {
        ode.rtol = r;
    }
    if let Some(a) = ri.atol {
        ode.atol = Tolerance::Scalar(a);
    }
    ode.fixed_step = ri.step;
    ode.max_step = ri.max_step;
    ode.initial_step = ri.initial_step;
    // a count at `integrator.<key>`; a negative one is invalid because `must`
    let count = |key: &str, v: i64, must: &str| {
        usize::try_from(v).map_err(|_| {
            err(
                format!("integrator.{key}"),
                format!("{v} is invalid: {must}"),
            )
        })
    };
    if let Some(v) = ri.max_order {
        // a negative value is out of 1 … 5 (OdeOptions::validate names it)
        ode.max_order = count("max_order", v, "must be 1, 2, 3, 4 or 5")?;
    }
    ode.ndf = ri.ndf.unwrap_or(false);
    let threads: Threads = match &ri.threads {
        None => Ok(Threads::Auto),
        Some(RawThreads::Number(v)) => v.to_string().parse(),
        Some(RawThreads::Name(s)) => s.parse(),
    }
    .map_err(|m| err("integrator.threads".into(), m))?;
    let mut implicit = ImplicitOptions::default();
    if let Some((_, a)) = alias {
        implicit.rho_inf = a.rho_inf;
    }
    if let Some(r) = ri.rho_inf {
        implicit.rho_inf = r;
    }
    if let Some(v) = ri.newton_tol {
        implicit.newton_tol = v;
    }
    implicit.min_step = ri.min_step;
    implicit.flight_step = ri.flight_step;
    if let Some(v) = ri.max_newton {
        implicit.max_newton = count("max_newton", v, "must be ≥ 1")?;
    }
    for (flag, slot) in [
        (ri.adaptive, &mut implicit.adaptive),
        (ri.project, &mut implicit.project),
        (ri.reuse, &mut implicit.reuse),
        (ri.filter_error, &mut implicit.filter_error),
        (ri.check_constraints, &mut implicit.check_constraints),
        (ri.lu, &mut implicit.lu),
        (ri.extrapolate, &mut implicit.extrapolate),
    ] {
        if let Some(v) = flag {
            *slot = v;
        }
    }
    let (t0, t_end) = (raw.time.start, raw.time.end);
    super::limits::time_span(t0, t_end, file)?;
    let dt = raw.output.dt.unwrap_or((t_end - t0) / 500.0);
    positive(dt).map_err(|m| err("output.dt".into(), m))?;
    let st = &raw.stabilization;
    let rule = match &st.rule {
        Some(r) => r.parse().map_err(|m| err("stabilization.rule".into(), m))?,
        None => BaumgarteRule::Explicit,
    };
    if let (Some(b), Some(r)) = (st.beta, st.rule.as_deref()) {
        if rule != BaumgarteRule::Explicit {
            return Err(err(
                "stabilization.beta".into(),
                format!(
                    "{b} is given, but stabilization.rule = \"{r}\" derives β from α: \
                     remove beta, or use rule = \"explicit\""
                ),
            ));
        }
    }
    let baumgarte = if rule == BaumgarteRule::Step {
        step_rule(st, &ode).map_err(|m| err("stabilization.rule".into(), m))?
    } else {
        Baumgarte::from_rule(rule, st.alpha.unwrap_or(0.0), st.beta.unwrap_or(0.0))
    };
    baumgarte.validate().map_err(|e| match e {
        FormulationError::InvalidOption {
            option,
            value,
            reason,
        } => err(
            format!("stabilization.{option}"),
            format!("{value} is invalid: {reason}"),
        ),
        other => err("stabilization".into(), other.to_string()),
    })?;
    let formulation: Formulation = match &raw.formulation {
        Some(f) => f.parse().map_err(|m| err("formulation".into(), m))?,
        None => Formulation::Saddle,
    };
    if formulation == Formulation::AugmentedLagrangian && ri.max_newton.is_none() {
        // its multiplier update converges linearly (docs/constraint_methods.md)
        implicit.max_newton = crate::integrate::ALM_MAX_NEWTON;
    }
    let linear_solver: SolverKind = match &raw.linear_solver {
        Some(s) => s.parse().map_err(|m| err("linear_solver".into(), m))?,
        None => SolverKind::Auto,
    };
    inapplicable(raw, method, implicit.adaptive, &baumgarte, formulation)
        .map_err(|(key, why)| err(key, why))?;
    let (projection, penalty) =
        constraint_method(st, method, formulation).map_err(|(key, why)| err(key, why))?;
    let augmented = augmented_lagrangian(raw, formulation, linear_solver)
        .map_err(|(key, why)| err(key, why))?;
    let partition = partition_options(st, formulation, &baumgarte, &projection)
        .map_err(|(key, why)| err(key, why))?;
    // The options' own validators (values); their fields map to scenario keys.
    ode.validate(method, implicit.adaptive)
        .and_then(|()| implicit.validate(method, ode.fixed_step))
        .map_err(|e| integrator_error(&err, e))?;
    let run = RunConfig {
        method,
        choice: if auto {
            MethodChoice::Auto
        } else {
            MethodChoice::Given
        },
        ode,
        t0,
        t_end,
        output_dt: dt,
        formulation: Index1Options {
            formulation,
            baumgarte,
            linear_solver,
            projection,
            penalty,
            partition,
        },
        implicit,
        augmented,
        guards: Default::default(),
        outputs: output_quantities(&raw.output.quantities)
            .map_err(|m| err("output.quantities".into(), m))?,
        threads,
    };

    Ok(run)
}

/// The `integrator.method` value that lets the run choose
/// ([`crate::simulation::choice`]).
pub(super) const AUTO: &str = "auto";

/// The keys `integrator.method = "auto"` takes: the step control of
/// both methods it may choose (`rtol`, `atol`, `max_step`,
/// `initial_step`) and `threads`; no stabilization, projection or
/// formulation (it sets those for the method it chooses).
fn auto_keys(raw: &RawScenario) -> Result<(), (String, String)> {
    let why = |what: &str| {
        format!(
            "{what}: integrator.method = \"{AUTO}\" chooses ode45 (with projection) or radau5 \
             and takes only rtol, atol, max_step and initial_step; name the method to set this"
        )
    };
    for (key, present) in integrator_keys(&raw.integrator) {
        if present && key != "method" && !STEP_CONTROL_KEYS.contains(&key) {
            return Err((format!("integrator.{key}"), why("does not apply")));
        }
    }
    let st = &raw.stabilization;
    for (key, present) in [
        ("alpha", st.alpha.is_some()),
        ("beta", st.beta.is_some()),
        ("rule", st.rule.is_some()),
        ("projection", st.projection.is_some()),
        ("correction", st.correction.is_some()),
        ("partition_condition", st.partition_condition.is_some()),
        ("penalty", st.penalty.is_some()),
        ("penalty_xi", st.penalty_xi.is_some()),
        ("penalty_omega", st.penalty_omega.is_some()),
    ] {
        if present {
            return Err((format!("stabilization.{key}"), why("does not apply")));
        }
    }
    if raw
        .formulation
        .as_deref()
        .is_some_and(|f| f.trim() != "saddle")
    {
        return Err(("formulation".into(), why("does not apply")));
    }
    Ok(())
}

/// `output.quantities`: each of "velocities", "accelerations", "reactions",
/// "energy", at most once.
/// `rule = "step"`: α = β = 1/h ([`Baumgarte::from_step`]) with h the
/// fixed step (`integrator.step`) or else `integrator.max_step`; α and β
/// must not be given.
fn step_rule(st: &RawStabilization, ode: &OdeOptions) -> Result<Baumgarte, String> {
    if st.alpha.is_some() {
        return Err(
            "\"step\" derives α = β = 1/h from the step: remove stabilization.alpha".into(),
        );
    }
    match ode.fixed_step.or(ode.max_step) {
        Some(h) if h.is_finite() && h > 0.0 => Ok(Baumgarte::from_step(h)),
        Some(h) => Err(format!("\"step\" needs a step h > 0, got {h}")),
        None => Err(
            "\"step\" sets α = β = 1/h from the step: give integrator.step (rk4) or \
             integrator.max_step"
                .into(),
        ),
    }
}

/// `correction` and `partition_condition` (projection and partitioning).
fn partition_options(
    st: &RawStabilization,
    formulation: Formulation,
    baumgarte: &Baumgarte,
    projection: &Projection,
) -> Result<PartitionOptions, (String, String)> {
    let key = |k: &str| format!("stabilization.{k}");
    let mut p = PartitionOptions::default();
    if formulation != Formulation::Partitioned {
        if st.partition_condition.is_some() {
            return Err((
                key("partition_condition"),
                "applies to formulation = \"partitioned\" only".into(),
            ));
        }
        return Ok(p);
    }
    if !baumgarte.is_off() || projection.enabled {
        let k = if projection.enabled {
            "projection"
        } else {
            "alpha"
        };
        return Err((
            key(k),
            "does not apply to formulation = \"partitioned\" (the constraints hold by \
             construction)"
                .into(),
        ));
    }
    if let Some(c) = st.partition_condition {
        if !(c.is_finite() && c > 1.0) {
            return Err((
                key("partition_condition"),
                format!("{c} is invalid: must be finite and > 1"),
            ));
        }
        p.max_condition = c;
    }
    Ok(p)
}

fn output_quantities(names: &[String]) -> Result<OutputQuantities, String> {
    let mut o = OutputQuantities::default();
    for (k, name) in names.iter().enumerate() {
        let flag = match name.as_str() {
            "velocities" => &mut o.velocities,
            "accelerations" => &mut o.accelerations,
            "reactions" => &mut o.reactions,
            "energy" => &mut o.energy,
            "drives" => &mut o.drives,
            other => {
                return Err(format!(
                    "unknown quantity '{other}' (item {k}); expected velocities, accelerations, \
                     reactions, drives or energy"
                ))
            }
        };
        if *flag {
            return Err(format!("'{name}' is listed twice"));
        }
        *flag = true;
    }
    Ok(o)
}

/// `stabilization.projection` (index-1 methods, not with the penalty
/// formulation) and `stabilization.penalty`, `penalty_xi`, `penalty_omega`
/// (`formulation = "penalty"` only, which excludes Baumgarte α, β): the
/// offending key and why.
fn constraint_method(
    st: &RawStabilization,
    method: Method,
    formulation: Formulation,
) -> Result<(Projection, PenaltyParams), (String, String)> {
    let key = |k: &str| format!("stabilization.{k}");
    let mut projection = Projection::default();
    if let Some(on) = st.projection {
        if formulation == Formulation::Penalty {
            return Err((
                key("projection"),
                "does not apply to formulation = \"penalty\" (saddle and eliminated only)".into(),
            ));
        }
        if method.is_index3() {
            return Err((
                key("projection"),
                format!(
                    "applies to {}; {} integrates the index-3 equations{}",
                    index1_methods(),
                    method.name(),
                    if method.info().key_use("project").is_some() {
                        " and projects with integrator.project"
                    } else {
                        ""
                    }
                ),
            ));
        }
        projection.enabled = on;
    }
    if let Some(c) = &st.correction {
        projection.correction = c.parse().map_err(|m| (key("correction"), m))?;
        if st.projection == Some(false) || formulation == Formulation::Penalty {
            return Err((
                key("correction"),
                format!(
                    "\"{c}\" corrects after each step: it applies with projection (not \
                     projection = false, nor formulation = \"penalty\")"
                ),
            ));
        }
        if method.is_index3() {
            return Err((
                key("correction"),
                format!("applies to {}, not to {}", index1_methods(), method.name()),
            ));
        }
        projection.enabled = true;
    }
    let mut penalty = PenaltyParams::default();
    for (k, v, slot) in [
        ("penalty", st.penalty, &mut penalty.alpha),
        ("penalty_xi", st.penalty_xi, &mut penalty.xi),
        ("penalty_omega", st.penalty_omega, &mut penalty.omega),
    ] {
        if let Some(v) = v {
            let al = formulation == Formulation::AugmentedLagrangian && k == "penalty";
            if formulation != Formulation::Penalty && !al {
                return Err((
                    key(k),
                    "applies to formulation = \"penalty\" (penalty also to \
                     \"augmented_lagrangian\") only"
                        .into(),
                ));
            }
            if al {
                continue;
            }
            *slot = v;
        }
    }
    if formulation == Formulation::Penalty {
        if st.alpha.is_some() || st.beta.is_some() || st.rule.is_some() {
            let k = ["alpha", "beta", "rule"][[st.alpha.is_some(), st.beta.is_some(), true]
                .iter()
                .position(|&b| b)
                .unwrap_or(2)];
            return Err((
                key(k),
                "Baumgarte terms do not apply to formulation = \"penalty\": its \
                 stabilization.penalty_xi and penalty_omega play their role"
                    .into(),
            ));
        }
        penalty.validate().map_err(|e| match e {
            FormulationError::InvalidOption {
                option,
                value,
                reason,
            } => {
                let k = if option == "alpha" {
                    "penalty".to_string()
                } else {
                    format!("penalty_{option}")
                };
                (key(&k), format!("{value} is invalid: {reason}"))
            }
            other => (key("penalty"), other.to_string()),
        })?;
    }
    Ok((projection, penalty))
}

/// `formulation = "augmented_lagrangian"`: `stabilization.penalty` is its
/// α; the integrator keys of generalized-α that it does not use, and the
/// Schur solver, are errors.
fn augmented_lagrangian(
    raw: &RawScenario,
    formulation: Formulation,
    linear_solver: SolverKind,
) -> Result<AugmentedParams, (String, String)> {
    if formulation != Formulation::AugmentedLagrangian {
        return Ok(AugmentedParams::default());
    }
    // generalized-α's keys that the augmented Lagrangian does not use
    let unused = [
        "adaptive",
        "project",
        "reuse",
        "filter_error",
        "check_constraints",
        "lu",
        "extrapolate",
    ];
    for (key, present) in integrator_keys(&raw.integrator) {
        if present && unused.contains(&key) {
            return Err((
                format!("integrator.{key}"),
                "does not apply to formulation = \"augmented_lagrangian\" (fixed step, \
                 projections of velocities and accelerations always on, symmetric Newton \
                 matrix)"
                    .into(),
            ));
        }
    }
    if linear_solver == SolverKind::Schur {
        return Err((
            "linear_solver".into(),
            "\"schur\" does not apply to formulation = \"augmented_lagrangian\" (no \
             multipliers to eliminate)"
                .into(),
        ));
    }
    let p = AugmentedParams {
        alpha: raw.stabilization.penalty,
    };
    p.validate().map_err(|e| {
        (
            "stabilization.penalty".into(),
            match e {
                FormulationError::InvalidOption { value, reason, .. } => {
                    format!("{value} is invalid: {reason}")
                }
                other => other.to_string(),
            },
        )
    })?;
    Ok(p)
}

/// The `[integrator]` keys of `raw` (besides `method`) and whether each
/// is given, in declaration order.
fn integrator_keys(ri: &RawIntegrator) -> [(&'static str, bool); 20] {
    [
        ("rtol", ri.rtol.is_some()),
        ("atol", ri.atol.is_some()),
        ("step", ri.step.is_some()),
        ("max_step", ri.max_step.is_some()),
        ("initial_step", ri.initial_step.is_some()),
        ("rho_inf", ri.rho_inf.is_some()),
        ("adaptive", ri.adaptive.is_some()),
        ("newton_tol", ri.newton_tol.is_some()),
        ("max_newton", ri.max_newton.is_some()),
        ("project", ri.project.is_some()),
        ("reuse", ri.reuse.is_some()),
        ("filter_error", ri.filter_error.is_some()),
        ("check_constraints", ri.check_constraints.is_some()),
        ("min_step", ri.min_step.is_some()),
        ("lu", ri.lu.is_some()),
        ("extrapolate", ri.extrapolate.is_some()),
        ("flight_step", ri.flight_step.is_some()),
        ("max_order", ri.max_order.is_some()),
        ("ndf", ri.ndf.is_some()),
        ("method", ri.method.is_some()),
    ]
}

/// The index-1 methods' names, "a, b, c and d" (from the method table).
fn index1_methods() -> String {
    let names: Vec<&str> = METHODS
        .iter()
        .filter(|m| m.equations == Equations::Index1)
        .map(|m| m.name)
        .collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        _ => names.join(""),
    }
}

/// The first key of `raw` that does not apply to `method` (with
/// `adaptive` for the methods that step either way), and why; such a key
/// would be silently ignored. Which `[integrator]` keys apply is the
/// method's row of the method table ([`METHODS`]); the stabilization and
/// formulation follow from the equations it integrates.
fn inapplicable(
    raw: &RawScenario,
    method: Method,
    adaptive: bool,
    baumgarte: &Baumgarte,
    formulation: Formulation,
) -> Result<(), (String, String)> {
    let row = method.info();
    let name = method.name();
    for (key, present) in integrator_keys(&raw.integrator) {
        if !present || key == "method" || row.takes(key, adaptive) {
            continue;
        }
        let why = match row.key_use(key) {
            Some(KeyUse::FixedStep) => format!(
                "{name} with integrator.adaptive = true chooses its steps: use \
                 integrator.initial_step or integrator.max_step"
            ),
            Some(_) => format!(
                "applies to {name} with integrator.adaptive = true only \
                 (with a fixed integrator.step it would be ignored)"
            ),
            None if key == "step" => format!(
                "{name} chooses its own steps: use integrator.initial_step or \
                 integrator.max_step"
            ),
            None if STEP_CONTROL_KEYS.contains(&key) => format!(
                "applies to the adaptive methods; {name} takes fixed steps of \
                 integrator.step"
            ),
            None => format!("applies to {} only, not to {name}", methods_taking(key)),
        };
        return Err((format!("integrator.{key}"), why));
    }
    let alpha = method.family() == Family::GeneralizedAlpha;
    if method.is_index3() {
        if !baumgarte.is_off() {
            let key = if raw.stabilization.alpha.unwrap_or(0.0) != 0.0 {
                "stabilization.alpha"
            } else {
                "stabilization.beta"
            };
            return Err((
                key.into(),
                format!(
                    "Baumgarte stabilization applies to the index-1 methods ({}); {name} \
                     integrates the index-3 equations{}",
                    index1_methods(),
                    if row.key_use("project").is_some() {
                        " (use integrator.project)"
                    } else {
                        ""
                    }
                ),
            ));
        }
        let allowed = formulation == Formulation::Saddle
            || (alpha && formulation == Formulation::AugmentedLagrangian);
        if !allowed {
            return Err((
                "formulation".into(),
                format!(
                    "applies to the index-1 methods; {name} uses the index-3 form{}",
                    if alpha {
                        " (or formulation = \"augmented_lagrangian\")"
                    } else {
                        ""
                    }
                ),
            ));
        }
    } else if formulation == Formulation::AugmentedLagrangian {
        let alphas: Vec<&str> = METHODS
            .iter()
            .filter(|m| m.family == Family::GeneralizedAlpha)
            .flat_map(|m| std::iter::once(m.name).chain(m.aliases.iter().map(|a| a.name)))
            .collect();
        return Err((
            "formulation".into(),
            format!(
                "\"augmented_lagrangian\" is an index-3 formulation for the generalized-α \
                 methods ({}), not for {name}",
                alphas.join(", ")
            ),
        ));
    }
    Ok(())
}

/// An integrator option error as a scenario error at the option's key
/// (`fixed_step` is `integrator.step`).
fn integrator_error(
    err: &impl Fn(String, String) -> ScenarioError,
    e: IntegratorError,
) -> ScenarioError {
    let key = |option: &str| match option {
        "fixed_step" => "integrator.step".to_string(),
        o => format!("integrator.{o}"),
    };
    match e {
        IntegratorError::InvalidOption {
            option,
            value,
            reason,
        } => {
            let reason = reason.replace("fixed_step", "integrator.step");
            err(key(option), format!("{value} is invalid: {reason}"))
        }
        IntegratorError::NotApplicable {
            option,
            method,
            reason,
        } => err(key(option), format!("does not apply to {method}: {reason}")),
        other => err("integrator".into(), other.to_string()),
    }
}
