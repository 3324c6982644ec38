//! Scenario files (TOML): a model, its initial state and the run settings.
//!
//! A scenario lists bodies (`[[body]]`), joints (`[[joint]]`), force elements
//! (`[[force]]`), `gravity`, and the tables `[initial]`, `[stabilization]`,
//! `[integrator]`, `[time]`, `[output]`; see `scenarios/fourbar.toml`.
//! Angles are radians unless the key ends in `_deg`.
//!
//! Every error names the file, the key and the problem. `--set KEY=VALUE`
//! overrides are applied to the parsed document before validation, so they
//! obey the same rules (an unknown key is an error).

use crate::builders::{add_rod, RodInfo, RodParams};
use crate::constraints::{DriveCoordinate, DriveRelativeAngle, Revolute, Translational};
use crate::forces::{AppliedForce, AppliedTorque};
use crate::formulation::{
    consistent_initial_state, Baumgarte, BaumgarteRule, ConsistentState, Formulation,
    Index1Options, InitialOptions,
};
use crate::integrate::{ImplicitOptions, Method, OdeOptions, Tolerance};
use crate::linalg::SolverKind;
use crate::model::Evaluation;
use crate::model::{Body, BodyRef, System, SystemBuilder, TimeFunction};
use crate::simulation::RunConfig;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

/// The four-bar scenario shipped with the tool (docs/problems.md, problem A), embedded at
/// build time so that the binary needs no files.
pub const FOURBAR_TOML: &str = include_str!("../scenarios/fourbar.toml");

/// The falling-rod scenario shipped with the tool (docs/problems.md, problem B), embedded
/// at build time.
pub const FALLING_ROD_TOML: &str = include_str!("../scenarios/falling_rod.toml");

/// A scenario error: where (file and key) and what.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{file}: {key}: {message}")]
pub struct ScenarioError {
    /// The scenario file (or `--set`).
    pub file: String,
    /// Dotted key path, e.g. `body[1].mass`.
    pub key: String,
    /// What is wrong.
    pub message: String,
}

/// A loaded, validated scenario, ready to run.
#[derive(Debug)]
pub struct Scenario {
    /// Scenario name (file stem unless `name` is given).
    pub name: String,
    /// Free text.
    pub description: String,
    /// The model.
    pub system: System,
    /// Initial positions (after assembly and perturbation).
    pub q0: Vec<f64>,
    /// Initial velocities.
    pub qd0: Vec<f64>,
    /// The assembly report, when `initial.consistent` is true.
    pub assembly: Option<ConsistentState>,
    /// Integrator, formulation, time span and output times.
    pub run: RunConfig,
    /// The rod's bookkeeping when the scenario has a `[rod]` table.
    pub rod: Option<RodInfo>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    description: Option<String>,
    gravity: Option<[f64; 2]>,
    #[serde(default)]
    body: Vec<RawBody>,
    #[serde(default)]
    joint: Vec<RawJoint>,
    #[serde(default)]
    force: Vec<RawForce>,
    #[serde(default)]
    initial: RawInitial,
    #[serde(default)]
    stabilization: RawStabilization,
    #[serde(default)]
    integrator: RawIntegrator,
    time: RawTime,
    #[serde(default)]
    output: RawOutput,
    formulation: Option<String>,
    linear_solver: Option<String>,
    rod: Option<RawRod>,
    #[serde(default)]
    constraints: RawConstraints,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawConstraints {
    evaluation: Option<String>,
}

/// `[rod]`: the finite-segment rod of problem B (docs/problems.md); every key defaults to
/// problem B. Segments are added after the `[[body]]` bodies.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRod {
    segments: Option<i64>,
    length: Option<f64>,
    width: Option<f64>,
    density: Option<f64>,
    youngs_modulus: Option<f64>,
    damping_time: Option<f64>,
    tilt_deg: Option<f64>,
    velocity: Option<[f64; 2]>,
    channel_width: Option<f64>,
    water_density: Option<f64>,
    drag_transverse: Option<f64>,
    drag_skin: Option<f64>,
    drag_end: Option<f64>,
    contact_stiffness: Option<f64>,
    contact_damping: Option<f64>,
    friction: Option<f64>,
    friction_velocity: Option<f64>,
    fluid: Option<bool>,
    contact: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBody {
    name: String,
    mass: f64,
    inertia: f64,
    #[serde(default)]
    x: f64,
    #[serde(default)]
    y: f64,
    phi: Option<f64>,
    phi_deg: Option<f64>,
    #[serde(default)]
    vx: f64,
    #[serde(default)]
    vy: f64,
    #[serde(default)]
    omega: f64,
}

/// `[[joint]]`: `type` = revolute | translational | drive_coordinate |
/// drive_angle; which other keys apply depends on the type.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJoint {
    #[serde(rename = "type")]
    kind: String,
    name: Option<String>,
    body: Option<String>,
    body_i: Option<String>,
    point_i: Option<[f64; 2]>,
    axis_i: Option<[f64; 2]>,
    body_j: Option<String>,
    point_j: Option<[f64; 2]>,
    coordinate: Option<String>,
    motion: Option<RawFunction>,
}

/// `[[force]]`: `type` = torque | force.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawForce {
    #[serde(rename = "type")]
    kind: String,
    name: Option<String>,
    body: String,
    torque: Option<RawFunction>,
    point: Option<[f64; 2]>,
    fx: Option<RawFunction>,
    fy: Option<RawFunction>,
}

/// A number (constant) or a table `{ polynomial = [c0, c1, …] }` or
/// `{ amplitude, omega, phase = 0, offset = 0 }` (harmonic).
#[derive(Debug, Deserialize)]
#[serde(try_from = "toml::Value")]
enum RawFunction {
    Constant(f64),
    Polynomial(Vec<f64>),
    Harmonic {
        amplitude: f64,
        omega: f64,
        phase: f64,
        offset: f64,
    },
}

impl TryFrom<toml::Value> for RawFunction {
    type Error = String;
    fn try_from(v: toml::Value) -> Result<Self, String> {
        const EXPECTED: &str = "expected a number, { polynomial = [c0, c1, ...] } or \
                                { amplitude, omega, phase, offset }";
        let num = |v: &toml::Value| match v {
            toml::Value::Float(f) => Some(*f),
            toml::Value::Integer(i) => Some(*i as f64),
            _ => None,
        };
        if let Some(c) = num(&v) {
            return Ok(RawFunction::Constant(c));
        }
        let t = v
            .as_table()
            .ok_or_else(|| format!("invalid value {v}: {EXPECTED}"))?;
        if let Some(p) = t.get("polynomial") {
            if t.len() != 1 {
                return Err(format!("a polynomial takes no other keys: {EXPECTED}"));
            }
            let arr = p
                .as_array()
                .ok_or_else(|| format!("polynomial must be an array of numbers, got {p}"))?;
            return arr
                .iter()
                .map(|c| {
                    num(c).ok_or_else(|| format!("polynomial coefficient {c} is not a number"))
                })
                .collect::<Result<Vec<_>, _>>()
                .map(RawFunction::Polynomial);
        }
        for k in t.keys() {
            if !["amplitude", "omega", "phase", "offset"].contains(&k.as_str()) {
                return Err(format!("unknown key '{k}': {EXPECTED}"));
            }
        }
        let get = |k: &str, required: bool| -> Result<f64, String> {
            match t.get(k) {
                Some(x) => num(x).ok_or_else(|| format!("{k} = {x} is not a number")),
                None if required => Err(format!("missing key '{k}': {EXPECTED}")),
                None => Ok(0.0),
            }
        };
        Ok(RawFunction::Harmonic {
            amplitude: get("amplitude", true)?,
            omega: get("omega", true)?,
            phase: get("phase", false)?,
            offset: get("offset", false)?,
        })
    }
}

impl RawFunction {
    fn to_function(&self) -> TimeFunction {
        match self {
            RawFunction::Constant(c) => TimeFunction::Constant(*c),
            RawFunction::Polynomial(c) => TimeFunction::Polynomial(c.clone()),
            RawFunction::Harmonic {
                amplitude,
                omega,
                phase,
                offset,
            } => TimeFunction::Harmonic {
                amplitude: *amplitude,
                omega: *omega,
                phase: *phase,
                offset: *offset,
            },
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInitial {
    #[serde(default = "yes")]
    consistent: bool,
    #[serde(default)]
    independent: Vec<String>,
    #[serde(default)]
    incorrect: bool,
    #[serde(default)]
    perturbation: Vec<RawPerturbation>,
    #[serde(default = "default_ic_tol")]
    tol: f64,
}

impl Default for RawInitial {
    fn default() -> Self {
        Self {
            consistent: true,
            independent: Vec::new(),
            incorrect: false,
            perturbation: Vec::new(),
            tol: default_ic_tol(),
        }
    }
}

fn yes() -> bool {
    true
}
fn default_ic_tol() -> f64 {
    1e-12
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPerturbation {
    coordinate: String,
    delta: f64,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStabilization {
    #[serde(default)]
    alpha: f64,
    #[serde(default)]
    beta: f64,
    rule: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawIntegrator {
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
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTime {
    #[serde(default)]
    start: f64,
    end: f64,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOutput {
    dt: Option<f64>,
}

/// Load a scenario file and apply `KEY=VALUE` overrides.
pub fn load(path: &Path, overrides: &[String]) -> Result<Scenario, ScenarioError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ScenarioError {
        file: file.clone(),
        key: "-".into(),
        message: format!("cannot read the file: {e}"),
    })?;
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scenario".into());
    parse(&text, &file, &stem, overrides)
}

/// Parse scenario text. `file` names it in errors; `stem` is the default name.
pub fn parse(
    text: &str,
    file: &str,
    stem: &str,
    overrides: &[String],
) -> Result<Scenario, ScenarioError> {
    let err = |key: &str, message: String| ScenarioError {
        file: file.to_string(),
        key: key.to_string(),
        message,
    };
    let mut doc: toml::Table = text.parse().map_err(|e: toml::de::Error| {
        let key = e
            .span()
            .map(|s| {
                let line = text[..s.start].matches('\n').count() + 1;
                format!("line {line}")
            })
            .unwrap_or_else(|| "-".into());
        err(&key, e.message().to_string())
    })?;
    let mut set_keys = Vec::new();
    for o in overrides {
        let key = apply_override(&mut doc, o).map_err(|m| ScenarioError {
            file: "--set".into(),
            key: o.clone(),
            message: m,
        })?;
        set_keys.push(key);
    }
    let raw: RawScenario = serde_path_to_error::deserialize(toml::Value::Table(doc)).map_err(
        |e: serde_path_to_error::Error<toml::de::Error>| {
            let key = e.path().to_string();
            let origin = attribute(file, &key, &set_keys);
            let message = e.inner().message().to_string();
            ScenarioError {
                file: origin,
                key,
                message,
            }
        },
    )?;
    build(raw, file, stem).map_err(|mut e| {
        e.file = attribute(file, &e.key, &set_keys);
        e
    })
}

/// The origin of an error at `key`: the file, or the file and the `--set`
/// override that wrote the key (or a table or key below it).
fn attribute(file: &str, key: &str, set_keys: &[String]) -> String {
    let related = |k: &String| {
        key == k || key.starts_with(&format!("{k}.")) || k.starts_with(&format!("{key}."))
    };
    match set_keys.iter().find(|k| related(k)) {
        Some(k) => format!("{file} (--set {k})"),
        None => file.to_string(),
    }
}

/// Apply `a.b.c=VALUE` to the document; returns the key. VALUE is read as a
/// TOML value (number, boolean, quoted string, array) or else as a bare string.
fn apply_override(doc: &mut toml::Table, spec: &str) -> Result<String, String> {
    let (key, value) = spec
        .split_once('=')
        .ok_or_else(|| "expected KEY=VALUE".to_string())?;
    let key = key.trim();
    let value = value.trim();
    if key.is_empty() {
        return Err("empty key".into());
    }
    let parsed: toml::Value = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    let parts: Vec<&str> = key.split('.').collect();
    let mut table = doc;
    for p in &parts[..parts.len() - 1] {
        let entry = table
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        table = entry
            .as_table_mut()
            .ok_or_else(|| format!("'{p}' is not a table"))?;
    }
    table.insert(parts[parts.len() - 1].to_string(), parsed);
    Ok(key.to_string())
}

fn build(raw: RawScenario, file: &str, stem: &str) -> Result<Scenario, ScenarioError> {
    let err = |key: String, message: String| ScenarioError {
        file: file.to_string(),
        key,
        message,
    };
    let mut builder = SystemBuilder::new();
    let mut names: HashMap<String, usize> = HashMap::new();
    for (i, b) in raw.body.iter().enumerate() {
        let key = |f: &str| format!("body[{i}].{f}");
        if b.name == "ground" {
            return Err(err(
                key("name"),
                "'ground' is reserved for the fixed frame".into(),
            ));
        }
        if names.insert(b.name.clone(), i).is_some() {
            return Err(err(
                key("name"),
                format!("duplicate body name '{}'", b.name),
            ));
        }
        for (f, v) in [("mass", b.mass), ("inertia", b.inertia)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(err(
                    key(f),
                    format!("{v} is invalid: must be finite and > 0"),
                ));
            }
        }
        let phi = match (b.phi, b.phi_deg) {
            (Some(_), Some(_)) => {
                return Err(err(
                    key("phi_deg"),
                    "give either phi or phi_deg, not both".into(),
                ))
            }
            (Some(p), None) => p,
            (None, Some(d)) => d.to_radians(),
            (None, None) => 0.0,
        };
        for (f, v) in [
            ("x", b.x),
            ("y", b.y),
            ("phi", phi),
            ("vx", b.vx),
            ("vy", b.vy),
            ("omega", b.omega),
        ] {
            if !v.is_finite() {
                return Err(err(key(f), format!("{v} is not finite")));
            }
        }
        builder.add_body(
            Body::new(b.name.clone(), b.mass, b.inertia, [b.x, b.y, phi])
                .with_velocity([b.vx, b.vy, b.omega]),
        );
    }
    let body_ref = |key: String, name: &str| -> Result<BodyRef, ScenarioError> {
        if name == "ground" {
            return Ok(BodyRef::Ground);
        }
        names.get(name).map(|&i| BodyRef::Body(i)).ok_or_else(|| {
            err(
                key,
                format!("no body named '{name}' (bodies: {})", list(&names)),
            )
        })
    };
    let body_index = |key: String, name: &str| -> Result<usize, ScenarioError> {
        match body_ref(key.clone(), name)? {
            BodyRef::Body(i) => Ok(i),
            BodyRef::Ground => Err(err(key, "the ground cannot be used here".into())),
        }
    };
    for (k, j) in raw.joint.iter().enumerate() {
        let key = |f: &str| format!("joint[{k}].{f}");
        let name = j.name.clone().unwrap_or_else(|| format!("joint{}", k + 1));
        // Keys each type takes; anything else given is an error.
        let (needs, allowed): (&[&str], &[&str]) = match j.kind.as_str() {
            "revolute" => (&["body_i", "point_i", "body_j", "point_j"], &[]),
            "translational" => (&["body_i", "point_i", "axis_i", "body_j", "point_j"], &[]),
            "drive_coordinate" => (&["body", "coordinate", "motion"], &[]),
            "drive_angle" => (&["body_i", "body_j", "motion"], &[]),
            o => {
                return Err(err(
                    key("type"),
                    format!("unknown joint type '{o}' (expected revolute, translational, drive_coordinate or drive_angle)"),
                ))
            }
        };
        let given = [
            ("body", j.body.is_some()),
            ("body_i", j.body_i.is_some()),
            ("point_i", j.point_i.is_some()),
            ("axis_i", j.axis_i.is_some()),
            ("body_j", j.body_j.is_some()),
            ("point_j", j.point_j.is_some()),
            ("coordinate", j.coordinate.is_some()),
            ("motion", j.motion.is_some()),
        ];
        for (f, present) in given {
            let wanted = needs.contains(&f) || allowed.contains(&f);
            if present && !wanted {
                return Err(err(key(f), format!("not a key of a {} joint", j.kind)));
            }
            if !present && needs.contains(&f) {
                return Err(err(
                    key(f),
                    format!("missing: a {} joint needs {}", j.kind, needs.join(", ")),
                ));
            }
        }
        let s = |o: &Option<String>| o.clone().unwrap_or_default();
        let p = |o: &Option<[f64; 2]>| o.unwrap_or_default();
        match j.kind.as_str() {
            "revolute" | "translational" => {
                let bi = body_ref(key("body_i"), &s(&j.body_i))?;
                let bj = body_ref(key("body_j"), &s(&j.body_j))?;
                if bi == bj {
                    return Err(err(
                        key("body_j"),
                        format!(
                            "a joint must connect two different bodies, got '{}' twice",
                            s(&j.body_j)
                        ),
                    ));
                }
                if j.kind == "revolute" {
                    builder.add_constraint(Revolute::new(
                        name,
                        bi,
                        p(&j.point_i),
                        bj,
                        p(&j.point_j),
                    ));
                } else {
                    let axis = p(&j.axis_i);
                    let len = axis[0].hypot(axis[1]);
                    if !len.is_finite() || len <= 0.0 {
                        return Err(err(
                            key("axis_i"),
                            format!("{axis:?}: the axis must be a non-zero vector"),
                        ));
                    }
                    let angle = |b: BodyRef| match b {
                        BodyRef::Ground => 0.0,
                        BodyRef::Body(i) => builder.bodies()[i].q0[2],
                    };
                    let theta0 = angle(bj) - angle(bi);
                    builder.add_constraint(Translational::new(
                        name,
                        bi,
                        p(&j.point_i),
                        axis,
                        bj,
                        p(&j.point_j),
                        theta0,
                    ));
                }
            }
            "drive_coordinate" => {
                let b = body_index(key("body"), &s(&j.body))?;
                let c = match s(&j.coordinate).as_str() {
                    "x" => 0,
                    "y" => 1,
                    "phi" => 2,
                    o => {
                        return Err(err(
                            key("coordinate"),
                            format!("'{o}' is not one of x, y, phi"),
                        ))
                    }
                };
                let f = j.motion.as_ref().expect("checked").to_function();
                builder.add_constraint(DriveCoordinate::new(name, b, c, f));
            }
            _ => {
                let bi = body_ref(key("body_i"), &s(&j.body_i))?;
                let bj = body_ref(key("body_j"), &s(&j.body_j))?;
                let f = j.motion.as_ref().expect("checked").to_function();
                builder.add_constraint(DriveRelativeAngle::new(name, bi, bj, f));
            }
        }
    }
    for (k, f) in raw.force.iter().enumerate() {
        let key = |fld: &str| format!("force[{k}].{fld}");
        let name = f.name.clone().unwrap_or_else(|| format!("force{}", k + 1));
        let b = body_index(key("body"), &f.body)?;
        match f.kind.as_str() {
            "torque" => {
                for (fld, present) in [
                    ("point", f.point.is_some()),
                    ("fx", f.fx.is_some()),
                    ("fy", f.fy.is_some()),
                ] {
                    if present {
                        return Err(err(key(fld), "not a key of a torque".into()));
                    }
                }
                let torque = f
                    .torque
                    .as_ref()
                    .ok_or_else(|| err(key("torque"), "missing: a torque needs torque".into()))?;
                builder.add_force(AppliedTorque {
                    name,
                    body: b,
                    torque: torque.to_function(),
                });
            }
            "force" => {
                if f.torque.is_some() {
                    return Err(err(
                        key("torque"),
                        "not a key of a force (use type = \"torque\")".into(),
                    ));
                }
                let (fx, fy) = match (&f.fx, &f.fy) {
                    (Some(x), Some(y)) => (x.to_function(), y.to_function()),
                    _ => return Err(err(key("fx"), "missing: a force needs fx and fy".into())),
                };
                builder.add_force(AppliedForce {
                    name,
                    body: b,
                    point: f.point.unwrap_or_default(),
                    fx,
                    fy,
                });
            }
            o => {
                return Err(err(
                    key("type"),
                    format!("unknown force type '{o}' (expected torque or force)"),
                ));
            }
        }
    }
    let mut rod = None;
    if let Some(r) = &raw.rod {
        let mut p = RodParams::problem_b(10);
        if let Some(n) = r.segments {
            if n < 1 {
                return Err(err(
                    "rod.segments".into(),
                    format!("{n} is invalid: the rod needs at least one segment"),
                ));
            }
            p.n_segments = n as usize;
        }
        let set = |slot: &mut f64, v: Option<f64>| {
            if let Some(v) = v {
                *slot = v;
            }
        };
        set(&mut p.length, r.length);
        set(&mut p.width, r.width);
        set(&mut p.density, r.density);
        set(&mut p.youngs_modulus, r.youngs_modulus);
        set(&mut p.damping_time, r.damping_time);
        set(&mut p.tilt, r.tilt_deg.map(f64::to_radians));
        set(&mut p.channel_width, r.channel_width);
        set(&mut p.water_density, r.water_density);
        set(&mut p.drag_transverse, r.drag_transverse);
        set(&mut p.drag_skin, r.drag_skin);
        set(&mut p.drag_end, r.drag_end);
        set(&mut p.contact_stiffness, r.contact_stiffness);
        set(&mut p.contact_damping, r.contact_damping);
        set(&mut p.friction_coefficient, r.friction);
        set(&mut p.friction_velocity, r.friction_velocity);
        if let Some(v) = r.velocity {
            p.initial_velocity = v;
        }
        p.fluid = r.fluid.unwrap_or(true);
        p.contact = r.contact.unwrap_or(true);
        // Buoyancy uses the scenario's gravity (none without `gravity`).
        p.gravity = raw.gravity.map_or(0.0, |g| g[0].hypot(g[1]));
        let info = add_rod(&mut builder, &p).map_err(|e| {
            // Name the scenario key of the offending builder field.
            let key = match &e {
                crate::model::ModelError::InvalidParameter { field, .. } => match field.as_str() {
                    "n_segments" => "rod.segments".to_string(),
                    "tilt" => "rod.tilt_deg".to_string(),
                    "initial_velocity" => "rod.velocity".to_string(),
                    "friction_coefficient" => "rod.friction".to_string(),
                    f => format!("rod.{f}"),
                },
                _ => "rod".to_string(),
            };
            err(key, e.to_string())
        })?;
        rod = Some(info);
    }
    if let Some(g) = raw.gravity {
        builder.gravity(g);
    }
    let mut system = builder
        .build()
        .map_err(|e| err("model".into(), e.to_string()))?;
    let evaluation = match raw.constraints.evaluation.as_deref() {
        None | Some("auto") => Evaluation::Auto,
        Some("generic") => Evaluation::Generic,
        Some("generated") => Evaluation::Generated,
        Some(o) => {
            return Err(err(
                "constraints.evaluation".into(),
                format!("unknown evaluation '{o}' (expected auto, generic or generated)"),
            ))
        }
    };
    // Generated kernels for recognised topologies (chains, four-bar);
    // `constraints.evaluation` decides whether they are used.
    crate::generated::attach_generated(&mut system);
    system
        .set_evaluation(evaluation)
        .map_err(|e| err("constraints.evaluation".into(), e.to_string()))?;

    // Run settings.
    let method: Method = match &raw.integrator.method {
        Some(m) => m.parse().map_err(|e: crate::integrate::IntegratorError| {
            err("integrator.method".into(), e.to_string())
        })?,
        None => Method::Ode23,
    };
    let mut ode = OdeOptions::default();
    if let Some(r) = raw.integrator.rtol {
        positive(r).map_err(|m| err("integrator.rtol".into(), m))?;
        ode.rtol = r;
    }
    if let Some(a) = raw.integrator.atol {
        if !(a.is_finite() && a >= 0.0) {
            return Err(err(
                "integrator.atol".into(),
                format!("{a} is invalid: must be finite and ≥ 0"),
            ));
        }
        ode.atol = Tolerance::Scalar(a);
    }
    for (k, v, slot) in [
        ("integrator.step", raw.integrator.step, &mut ode.fixed_step),
        (
            "integrator.max_step",
            raw.integrator.max_step,
            &mut ode.max_step,
        ),
        (
            "integrator.initial_step",
            raw.integrator.initial_step,
            &mut ode.initial_step,
        ),
    ] {
        if let Some(v) = v {
            positive(v).map_err(|m| err(k.into(), m))?;
            *slot = Some(v);
        }
    }
    let ri = &raw.integrator;
    let mut implicit = ImplicitOptions::default();
    if let Some(r) = ri.rho_inf {
        let lo = if method == Method::Hht { 0.5 } else { 0.0 };
        if !(r.is_finite() && (lo..=1.0).contains(&r)) {
            return Err(err(
                "integrator.rho_inf".into(),
                format!("{r} is invalid: must be in [{lo}, 1] for {}", method.name()),
            ));
        }
        implicit.rho_inf = r;
    }
    if let Some(v) = ri.newton_tol {
        positive(v).map_err(|m| err("integrator.newton_tol".into(), m))?;
        implicit.newton_tol = v;
    }
    if let Some(v) = ri.min_step {
        positive(v).map_err(|m| err("integrator.min_step".into(), m))?;
        implicit.min_step = Some(v);
    }
    if let Some(v) = ri.max_newton {
        if v < 1 {
            return Err(err(
                "integrator.max_newton".into(),
                format!("{v} is invalid: must be ≥ 1"),
            ));
        }
        implicit.max_newton = v as usize;
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
    implicit.step = ode.fixed_step;
    if method.is_implicit() && ode.fixed_step.is_none() && !implicit.adaptive {
        return Err(err(
            "integrator.step".into(),
            format!(
                "{} needs a fixed integrator.step, or integrator.adaptive = true",
                method.name()
            ),
        ));
    }
    if method == Method::Rk4 && ode.fixed_step.is_none() {
        return Err(err(
            "integrator.step".into(),
            "the fixed-step method rk4 needs integrator.step".into(),
        ));
    }
    let (t0, t_end) = (raw.time.start, raw.time.end);
    if !(t0.is_finite() && t_end.is_finite() && t_end > t0) {
        return Err(err(
            "time.end".into(),
            format!("{t_end} is invalid: must be finite and > time.start = {t0}"),
        ));
    }
    let dt = raw.output.dt.unwrap_or((t_end - t0) / 500.0);
    positive(dt).map_err(|m| err("output.dt".into(), m))?;
    let rule = match &raw.stabilization.rule {
        Some(r) => r.parse().map_err(|m| err("stabilization.rule".into(), m))?,
        None => BaumgarteRule::Explicit,
    };
    for (k, v) in [
        ("stabilization.alpha", raw.stabilization.alpha),
        ("stabilization.beta", raw.stabilization.beta),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(err(
                k.into(),
                format!("{v} is invalid: must be finite and ≥ 0"),
            ));
        }
    }
    let baumgarte = Baumgarte::from_rule(rule, raw.stabilization.alpha, raw.stabilization.beta);
    let formulation: Formulation = match &raw.formulation {
        Some(f) => f.parse().map_err(|m| err("formulation".into(), m))?,
        None => Formulation::Saddle,
    };
    let linear_solver: SolverKind = match &raw.linear_solver {
        Some(s) => s.parse().map_err(|m| err("linear_solver".into(), m))?,
        None => SolverKind::Auto,
    };
    let run = RunConfig {
        method,
        ode,
        t0,
        t_end,
        output_dt: dt,
        index1: Index1Options {
            formulation,
            baumgarte,
            linear_solver,
        },
        implicit,
    };

    // Initial state.
    let coord = |key: String, spec: &str| -> Result<usize, ScenarioError> {
        let (b, c) = spec.rsplit_once('.').ok_or_else(|| {
            err(
                key.clone(),
                format!("'{spec}' is not of the form BODY.x|y|phi"),
            )
        })?;
        let bi = body_index(key.clone(), b)?;
        let ci = match c {
            "x" => 0,
            "y" => 1,
            "phi" => 2,
            o => return Err(err(key, format!("'{o}' is not one of x, y, phi"))),
        };
        Ok(3 * bi + ci)
    };
    let independent = raw
        .initial
        .independent
        .iter()
        .enumerate()
        .map(|(i, s)| coord(format!("initial.independent[{i}]"), s))
        .collect::<Result<Vec<_>, _>>()?;
    positive(raw.initial.tol).map_err(|m| err("initial.tol".into(), m))?;
    let (mut q0, mut qd0) = system.initial_state();
    let mut assembly = None;
    if raw.initial.consistent && system.n_constraints() > 0 {
        let st = consistent_initial_state(
            &system,
            t0,
            &q0,
            &qd0,
            &independent,
            InitialOptions {
                tol: raw.initial.tol,
                linear_solver,
                ..Default::default()
            },
        )
        .map_err(|e| err("initial".into(), e.to_string()))?;
        q0.clone_from(&st.q);
        qd0.clone_from(&st.qd);
        assembly = Some(st);
    }
    if raw.initial.incorrect {
        if raw.initial.perturbation.is_empty() {
            return Err(err(
                "initial.incorrect".into(),
                "true, but the scenario gives no initial.perturbation".into(),
            ));
        }
        for (i, p) in raw.initial.perturbation.iter().enumerate() {
            let c = coord(
                format!("initial.perturbation[{i}].coordinate"),
                &p.coordinate,
            )?;
            if !p.delta.is_finite() {
                return Err(err(
                    format!("initial.perturbation[{i}].delta"),
                    format!("{} is not finite", p.delta),
                ));
            }
            q0[c] += p.delta;
        }
    }
    Ok(Scenario {
        name: raw.name.unwrap_or_else(|| stem.to_string()),
        description: raw.description.unwrap_or_default(),
        system,
        q0,
        qd0,
        assembly,
        run,
        rod,
    })
}

fn positive(v: f64) -> Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!("{v} is invalid: must be finite and > 0"))
    }
}

fn list(names: &HashMap<String, usize>) -> String {
    let mut v: Vec<(&usize, &String)> = names.iter().map(|(k, v)| (v, k)).collect();
    v.sort();
    v.into_iter()
        .map(|(_, k)| k.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}
