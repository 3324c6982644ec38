//! The integration methods and the one table that says what each is:
//! [`METHODS`], one [`MethodInfo`] row per [`Method`] — its names, family,
//! the equations it integrates (index 1 or 3), fixed or adaptive steps,
//! what runs concurrently, and which `[integrator]` keys apply. The names,
//! predicates, the dispatch of `simulation`, the option validation, the
//! scenario loader's "applies to … only" messages and the method table of
//! docs/scenarios.md ([`markdown_table`]) all read it.

use super::IntegratorError;
use std::str::FromStr;

/// Integration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Bogacki–Shampine 3(2), adaptive, as MATLAB's `ode23`.
    Ode23,
    /// Dormand–Prince 5(4), adaptive, as MATLAB's `ode45`.
    Ode45,
    /// Classic Runge–Kutta 4, fixed step.
    Rk4,
    /// Variable-order Adams–Bashforth–Moulton PECE (Shampine & Gordon),
    /// adaptive, as MATLAB's `ode113`.
    Ode113,
    /// Variable-order (1–5), variable-step BDF on the index-3 equations
    /// ([`super::Bdf`], as DASSL / MATLAB's `ode15s`), adaptive. Not an
    /// [`super::OdeSystem`] integrator: run through `simulation::simulate`.
    Bdf,
    /// Generalized-α on the index-3 equations (Chung & Hulbert 1993;
    /// Arnold & Brüls 2007), parameters from ρ∞ — see [`super::GenAlpha`].
    /// Not an [`super::OdeSystem`] integrator: run through
    /// `simulation::simulate`.
    GenAlpha,
    /// HHT-α (Hilber, Hughes & Taylor 1977) as the generalized-α member
    /// with α_m = 0 (ρ∞ ∈ [½, 1]) — see [`super::AlphaParameters::hht`].
    Hht,
    /// Newmark (α_m = α_f = 0) with dissipation from ρ∞ — see
    /// [`super::AlphaParameters::newmark`]; `trapezoidal` is Newmark with
    /// ρ∞ = 1.
    Newmark,
    /// Radau IIA of order 5 (three stages, L-stable) on the index-3
    /// equations, fixed step or adaptive ([`super::Radau5`];
    /// docs/radau.md). Not an [`super::OdeSystem`] integrator.
    Radau5,
    /// Radau IIA of order 9 (five stages, L-stable) on the index-3
    /// equations, fixed step or adaptive ([`super::Radau9`];
    /// docs/radau.md). Not an [`super::OdeSystem`] integrator.
    Radau9,
    /// Radau IIA of variable order, 5 and 9 (RADAU's order selection),
    /// adaptive, on the index-3 equations ([`super::Radau59`];
    /// docs/radau.md). Not an [`super::OdeSystem`] integrator.
    Radau59,
    /// Radau IIA of order 13 (seven stages, L-stable) on the index-3
    /// equations, fixed step or adaptive ([`super::Radau13`];
    /// docs/radau.md). Not an [`super::OdeSystem`] integrator.
    Radau13,
}

/// The family a method belongs to: what runs it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// Explicit one-step Runge–Kutta methods (ode23, ode45, rk4) on the
    /// index-1 equations (eq. (5)/(9)).
    RungeKutta,
    /// Explicit variable-order Adams–Bashforth–Moulton (ode113) on the
    /// index-1 equations.
    Adams,
    /// Variable-order BDF / NDF on the index-3 equations.
    Bdf,
    /// The generalized-α family (generalized-α, HHT, Newmark) on the
    /// index-3 equations; also the scheme of the augmented Lagrangian.
    GeneralizedAlpha,
    /// Radau IIA (orders 5, 9 and 13) on the index-3 equations.
    Radau,
}

impl Family {
    /// Short lower-case name, as in messages and the docs table.
    pub fn name(self) -> &'static str {
        match self {
            Family::RungeKutta => "explicit Runge–Kutta",
            Family::Adams => "explicit Adams",
            Family::Bdf => "BDF",
            Family::GeneralizedAlpha => "generalized-α",
            Family::Radau => "Radau IIA",
        }
    }
}

/// The equations a method integrates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Equations {
    /// The index-1 ODE of eq. (5) (or (9)) with Baumgarte terms (10)–(11):
    /// `formulation` saddle, eliminated, penalty or partitioned.
    Index1,
    /// The index-3 DAE `M q̈ + Φ_qᵀλ = g, Φ = 0` (no Baumgarte terms;
    /// `formulation` saddle, for the generalized-α family also
    /// augmented_lagrangian).
    Index3,
}

/// How a method chooses its steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stepping {
    /// Fixed steps of `integrator.step` only.
    Fixed,
    /// Steps controlled by `rtol`/`atol` only.
    Adaptive,
    /// Fixed steps of `integrator.step`, or controlled by `rtol`/`atol`
    /// with `integrator.adaptive = true`.
    FixedOrAdaptive,
}

/// When an `[integrator]` key applies to a method of its row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum KeyUse {
    /// Whenever the method is chosen.
    Always,
    /// Only with fixed steps (without `integrator.adaptive = true`).
    FixedStep,
    /// Only with `integrator.adaptive = true`.
    Adaptive,
}

/// One row of [`METHODS`]: what a method is.
#[derive(Debug, Clone, Copy)]
pub struct MethodInfo {
    /// The method.
    pub method: Method,
    /// Its name (`integrator.method`, CLI, outputs).
    pub name: &'static str,
    /// Other names the scenario key `integrator.method` accepts for it,
    /// each with the parameter it fixes (`trapezoidal` = Newmark with
    /// ρ∞ = 1).
    pub aliases: &'static [Alias],
    /// Its family.
    pub family: Family,
    /// The equations it integrates (those of its family,
    /// [`Family::equations`]).
    pub equations: Equations,
    /// Fixed or adaptive steps.
    pub stepping: Stepping,
    /// What runs concurrently on a run's two threads (from
    /// `PARALLEL_MIN_COORDS` coordinates; results identical for any
    /// thread count).
    pub threads: &'static str,
    /// The `[integrator]` keys of the method itself that apply besides
    /// `method` and the step keys its [`Stepping`] implies
    /// ([`Stepping::key_use`]), in groups with when they apply.
    pub keys: Keys,
}

/// Groups of `[integrator]` keys, each with when its keys apply.
pub type Keys = &'static [(&'static [&'static str], KeyUse)];

/// Another name of a method that fixes its spectral radius: the
/// trapezoidal rule is Newmark (β = ¼, γ = ½), i.e. generalized-α with
/// ρ∞ = 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alias {
    /// The name `integrator.method` accepts.
    pub name: &'static str,
    /// The `integrator.rho_inf` it fixes (giving the key as well is an
    /// error).
    pub rho_inf: f64,
}

/// The method row and alias an alias name stands for (`None`: not an
/// alias).
pub fn alias(name: &str) -> Option<(&'static MethodInfo, Alias)> {
    METHODS
        .iter()
        .find_map(|m| m.aliases.iter().find(|a| a.name == name).map(|a| (m, *a)))
}

/// The step-control keys of the adaptive methods.
pub const STEP_CONTROL_KEYS: [&str; 4] = ["rtol", "atol", "max_step", "initial_step"];

/// The keys whose use follows from a method's [`Stepping`]
/// ([`Stepping::key_use`]), in the order of the docs table.
const STEPPING_KEYS: [&str; 6] = [
    "step",
    "rtol",
    "atol",
    "max_step",
    "initial_step",
    "adaptive",
];

impl Stepping {
    /// When a step key applies with this stepping: `step` to fixed steps,
    /// the [`STEP_CONTROL_KEYS`] to adaptive ones, `adaptive` where there
    /// is a choice; `None`: never (or not a step key).
    pub fn key_use(self, key: &str) -> Option<KeyUse> {
        let (fixed, adaptive) = match self {
            Stepping::Fixed => (Some(KeyUse::Always), None),
            Stepping::Adaptive => (None, Some(KeyUse::Always)),
            Stepping::FixedOrAdaptive => (Some(KeyUse::FixedStep), Some(KeyUse::Adaptive)),
        };
        match key {
            "step" => fixed,
            "adaptive" => (self == Stepping::FixedOrAdaptive).then_some(KeyUse::Always),
            k if STEP_CONTROL_KEYS.contains(&k) => adaptive,
            _ => None,
        }
    }
}

impl Family {
    /// The equations the family integrates.
    pub const fn equations(self) -> Equations {
        match self {
            Family::RungeKutta | Family::Adams => Equations::Index1,
            Family::Bdf | Family::GeneralizedAlpha | Family::Radau => Equations::Index3,
        }
    }
}

/// The keys of the Newton iteration of the generalized-α family and
/// Radau IIA.
const NEWTON_KEYS: &[&str] = &["newton_tol", "max_newton", "project", "reuse", "min_step"];

/// The generalized-α family's own keys.
const ALPHA_KEYS: Keys = &[
    (&["rho_inf"], KeyUse::Always),
    (NEWTON_KEYS, KeyUse::Always),
    (&["filter_error"], KeyUse::Adaptive),
    (&["check_constraints", "lu", "extrapolate"], KeyUse::Always),
];

/// Radau IIA's own keys: those of its Newton iteration.
const RADAU_KEYS: Keys = &[(NEWTON_KEYS, KeyUse::Always)];

/// Those of Radau IIA with fixed or adaptive steps: also the flight step
/// of the fixed-step mode.
const RADAU_FIXED_KEYS: Keys = &[
    (NEWTON_KEYS, KeyUse::Always),
    (&["flight_step"], KeyUse::FixedStep),
];

const EXPLICIT_THREADS: &str = "forces ∥ constraint terms of each RHS";
const ALPHA_THREADS: &str = "residual halves, Newton updates, split chain LDLᵀ";
const RADAU_THREADS: &str = "residual halves, split real chain LDLᵀ";

impl MethodInfo {
    /// A row without aliases; its equations are its family's.
    const fn row(
        method: Method,
        family: Family,
        stepping: Stepping,
        threads: &'static str,
        keys: Keys,
    ) -> Self {
        MethodInfo {
            method,
            name: Method::NAMES[method as usize],
            aliases: &[],
            family,
            equations: family.equations(),
            stepping,
            threads,
            keys,
        }
    }

    /// An explicit method's row: no keys of its own.
    const fn explicit(method: Method, family: Family, stepping: Stepping) -> Self {
        Self::row(method, family, stepping, EXPLICIT_THREADS, &[])
    }

    /// A generalized-α member's row.
    const fn alpha(method: Method, aliases: &'static [Alias]) -> Self {
        let f = Family::GeneralizedAlpha;
        let row = Self::row(
            method,
            f,
            Stepping::FixedOrAdaptive,
            ALPHA_THREADS,
            ALPHA_KEYS,
        );
        MethodInfo { aliases, ..row }
    }
}

/// Every method, one row each, in the order of [`Method::ALL`].
pub const METHODS: [MethodInfo; 12] = [
    MethodInfo::explicit(Method::Ode23, Family::RungeKutta, Stepping::Adaptive),
    MethodInfo::explicit(Method::Ode45, Family::RungeKutta, Stepping::Adaptive),
    MethodInfo::explicit(Method::Rk4, Family::RungeKutta, Stepping::Fixed),
    MethodInfo::explicit(Method::Ode113, Family::Adams, Stepping::Adaptive),
    MethodInfo::row(
        Method::Bdf,
        Family::Bdf,
        Stepping::Adaptive,
        "residual halves, predictor, error test, Newton updates, split chain LDLᵀ",
        &[(&["max_order", "ndf"], KeyUse::Always)],
    ),
    MethodInfo::alpha(Method::GenAlpha, &[]),
    MethodInfo::alpha(Method::Hht, &[]),
    MethodInfo::alpha(
        Method::Newmark,
        &[Alias {
            name: "trapezoidal",
            rho_inf: 1.0,
        }],
    ),
    MethodInfo::row(
        Method::Radau5,
        Family::Radau,
        Stepping::FixedOrAdaptive,
        RADAU_THREADS,
        RADAU_FIXED_KEYS,
    ),
    MethodInfo::row(
        Method::Radau9,
        Family::Radau,
        Stepping::FixedOrAdaptive,
        RADAU_THREADS,
        RADAU_FIXED_KEYS,
    ),
    MethodInfo::row(
        Method::Radau59,
        Family::Radau,
        Stepping::Adaptive,
        RADAU_THREADS,
        RADAU_KEYS,
    ),
    MethodInfo::row(
        Method::Radau13,
        Family::Radau,
        Stepping::FixedOrAdaptive,
        RADAU_THREADS,
        RADAU_FIXED_KEYS,
    ),
];

impl MethodInfo {
    /// When `key` (an `[integrator]` key) applies to this method; `None`:
    /// never.
    pub(crate) fn key_use(&self, key: &str) -> Option<KeyUse> {
        self.stepping
            .key_use(key)
            .or_else(|| self.keys.iter().find(|k| k.0.contains(&key)).map(|k| k.1))
    }

    /// Every key that applies to this method besides `method`, with when:
    /// the step keys of its stepping, then its own.
    pub fn all_keys(&self) -> impl Iterator<Item = (&'static str, KeyUse)> + '_ {
        let stepping = STEPPING_KEYS
            .into_iter()
            .filter_map(|k| self.stepping.key_use(k).map(|u| (k, u)));
        let own = (self.keys.iter()).flat_map(|&(keys, u)| keys.iter().map(move |&k| (k, u)));
        stepping.chain(own)
    }

    /// Whether `key` applies to this method with (`adaptive`) or without
    /// `integrator.adaptive = true` (ignored by methods that are only
    /// fixed-step or only adaptive).
    pub fn takes(&self, key: &str, adaptive: bool) -> bool {
        let adaptive = match self.stepping {
            Stepping::Fixed => false,
            Stepping::Adaptive => true,
            Stepping::FixedOrAdaptive => adaptive,
        };
        match self.key_use(key) {
            None => false,
            Some(KeyUse::Always) => true,
            Some(KeyUse::FixedStep) => !adaptive,
            Some(KeyUse::Adaptive) => adaptive,
        }
    }
}

impl Method {
    /// All methods, in the order of [`METHODS`].
    pub const ALL: [Method; 12] = [
        Method::Ode23,
        Method::Ode45,
        Method::Rk4,
        Method::Ode113,
        Method::Bdf,
        Method::GenAlpha,
        Method::Hht,
        Method::Newmark,
        Method::Radau5,
        Method::Radau9,
        Method::Radau59,
        Method::Radau13,
    ];
    /// The valid method names, in the order of [`METHODS`].
    pub const NAMES: [&'static str; 12] = [
        "ode23", "ode45", "rk4", "ode113", "bdf", "genalpha", "hht", "newmark", "radau5", "radau9",
        "radau59", "radau13",
    ];

    /// This method's row of [`METHODS`].
    pub fn info(&self) -> &'static MethodInfo {
        let row = &METHODS[*self as usize];
        debug_assert_eq!(row.method, *self);
        row
    }

    /// Lower-case name: one of [`Method::NAMES`].
    pub fn name(&self) -> &'static str {
        self.info().name
    }

    /// Its family ([`MethodInfo::family`]).
    pub fn family(&self) -> Family {
        self.info().family
    }

    /// Whether the method always adapts its step to `rtol`/`atol`
    /// ([`Stepping::Adaptive`]: ode23, ode45, ode113, bdf); the
    /// generalized-α family and radau5 only with
    /// [`super::ImplicitOptions::adaptive`].
    pub fn is_adaptive(&self) -> bool {
        self.info().stepping == Stepping::Adaptive
    }

    /// Whether the method is one of the generalized-α family (genalpha,
    /// hht, newmark; [`super::GenAlpha`]).
    pub fn is_generalized_alpha(&self) -> bool {
        self.family() == Family::GeneralizedAlpha
    }

    /// The methods that integrate the index-3 equations (the
    /// generalized-α family, bdf and radau5): no Baumgarte terms,
    /// numerical damping that only removes energy.
    pub fn is_index3(&self) -> bool {
        self.info().equations == Equations::Index3
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = IntegratorError;
    /// Parses one of [`Method::NAMES`] (case-insensitive, surrounding
    /// whitespace ignored).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let key = s.trim().to_ascii_lowercase();
        METHODS
            .iter()
            .find(|m| m.name == key)
            .map(|m| m.method)
            .ok_or_else(|| IntegratorError::UnknownMethod(s.to_string()))
    }
}

/// The methods whose row has `key`, as "a, b and c" (for messages).
pub(crate) fn methods_taking(key: &str) -> String {
    let names: Vec<&str> = METHODS
        .iter()
        .filter(|m| m.key_use(key).is_some())
        .map(|m| m.name)
        .collect();
    let label = if names.len() < 2 {
        String::new()
    } else if METHODS
        .iter()
        .filter(|m| names.contains(&m.name))
        .all(|m| m.equations == Equations::Index3)
    {
        "the implicit methods ".to_string()
    } else {
        String::new()
    };
    match names.split_last() {
        None => "no method".into(),
        Some((last, [])) => format!("{label}{last}"),
        Some((last, rest)) => format!("{label}{} and {last}", rest.join(", ")),
    }
}

/// The method table of docs/scenarios.md, generated from [`METHODS`]
/// (a test holds the docs to it).
pub fn markdown_table() -> String {
    let mut out = String::from(
        "| method | family | equations | steps | concurrent on two threads | `[integrator]` keys |\n\
         |---|---|---|---|---|---|\n",
    );
    for m in &METHODS {
        let names = std::iter::once(format!("`{}`", m.name))
            .chain(
                m.aliases
                    .iter()
                    .map(|a| format!("`{}` (rho_inf = {})", a.name, a.rho_inf)),
            )
            .collect::<Vec<_>>()
            .join(", ");
        let equations = match m.equations {
            Equations::Index1 => "index 1",
            Equations::Index3 => "index 3",
        };
        let steps = match m.stepping {
            Stepping::Fixed => "fixed",
            Stepping::Adaptive => "adaptive",
            Stepping::FixedOrAdaptive => "fixed or `adaptive`",
        };
        let keys = m
            .all_keys()
            .map(|(k, u)| match u {
                KeyUse::Always => format!("`{k}`"),
                KeyUse::FixedStep => format!("`{k}` (fixed)"),
                KeyUse::Adaptive => format!("`{k}` (adaptive)"),
            })
            .collect::<Vec<_>>()
            .join(", ");
        out.push_str(&format!(
            "| {names} | {} | {equations} | {steps} | {} | {keys} |\n",
            m.family.name(),
            m.threads
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_alias_names_its_row_and_the_parameter_it_fixes() {
        let (row, a) = alias("trapezoidal").unwrap();
        assert_eq!(row.method, Method::Newmark);
        assert_eq!(a.rho_inf, 1.0);
        assert!(alias("newmark").is_none() && alias("trapezoid").is_none());
    }

    #[test]
    fn rows_are_in_method_order_and_names_parse_back() {
        for (i, m) in Method::ALL.iter().enumerate() {
            assert_eq!(METHODS[i].method, *m);
            assert_eq!(m.name().parse::<Method>().unwrap(), *m);
            assert_eq!(Method::NAMES[i], m.name());
        }
        assert!("trapezoid".parse::<Method>().is_err());
    }

    #[test]
    fn predicates_follow_the_table() {
        use Method::*;
        let alpha: Vec<Method> = Method::ALL
            .into_iter()
            .filter(Method::is_generalized_alpha)
            .collect();
        assert_eq!(alpha, [GenAlpha, Hht, Newmark]);
        let index3: Vec<Method> = Method::ALL.into_iter().filter(Method::is_index3).collect();
        assert_eq!(
            index3,
            [Bdf, GenAlpha, Hht, Newmark, Radau5, Radau9, Radau59, Radau13]
        );
        let adaptive: Vec<Method> = Method::ALL
            .into_iter()
            .filter(Method::is_adaptive)
            .collect();
        assert_eq!(adaptive, [Ode23, Ode45, Ode113, Bdf, Radau59]);
    }

    /// docs/scenarios.md carries the generated method table verbatim.
    #[test]
    fn docs_method_table_is_the_generated_one() {
        let docs = include_str!("../../docs/scenarios.md");
        let table = markdown_table();
        assert!(
            docs.contains(&table),
            "docs/scenarios.md's method table differs from integrate::method::markdown_table(); \
             replace it with:\n{table}"
        );
    }
}
