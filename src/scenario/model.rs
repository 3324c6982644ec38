//! The model part of a scenario: `[[body]]`, `[[joint]]`, `[[force]]`,
//! `gravity`, the components `[rod]`/`[[rod]]`/`[[chain]]` (built in
//! `components`) and `constraints.evaluation` → a [`System`].

use super::{error, list, RawScenario, ScenarioError};
use crate::builders::{ChainInfo, RodInfo};
use crate::forces::Law;
use crate::model::{Body, BodyRef, Evaluation, System, SystemBuilder, TimeFunction};
use serde::Deserialize;
use std::collections::HashMap;

/// What the model part builds.
pub(super) struct Model {
    pub(super) system: System,
    pub(super) rod: Option<RodInfo>,
    /// Every rod (`[rod]`, `[[rod]]`) by name.
    pub(super) rods: Vec<(String, RodInfo)>,
    /// Every `[[chain]]` by name.
    pub(super) chains: Vec<(String, ChainInfo)>,
    /// Body index by name (components' bodies as `C.first`, `C.last`,
    /// `C.segment[k]`, `C.link[k]`).
    pub(super) names: HashMap<String, usize>,
    /// Each `[[force]]`'s name and the force elements it built.
    pub(super) forces: Vec<(String, std::ops::Range<usize>)>,
    /// Half length of every rod segment and chain link by body index (the
    /// `"first_end"`/`"last_end"` points of sensors).
    pub(super) ends: HashMap<usize, f64>,
}

/// The body named `name` (or the ground), for errors at `key`.
pub(super) fn body_ref(
    names: &HashMap<String, usize>,
    file: &str,
    key: String,
    name: &str,
) -> Result<BodyRef, ScenarioError> {
    if name == "ground" {
        return Ok(BodyRef::Ground);
    }
    names
        .get(name)
        .map(|&i| BodyRef::Body(i))
        .ok_or_else(|| error(file, key, unknown_body(names, name)))
}

/// Why `name` names no body: a component part out of range
/// (`rod1.segment[0]`), a component that does not exist (`rodX.first`), or
/// no such body; lists what there is.
pub(super) fn unknown_body(names: &HashMap<String, usize>, name: &str) -> String {
    let bodies = list(names);
    if let Some((comp, part)) = name.split_once('.') {
        if !names.contains_key(&format!("{comp}.first")) {
            return format!(
                "no body named '{name}': there is no rod or chain named '{comp}' (bodies: {bodies})"
            );
        }
        if let Some(base) = part.strip_suffix(']').and_then(|p| p.split_once('[')) {
            let n = (1..)
                .take_while(|k| names.contains_key(&format!("{comp}.{}[{k}]", base.0)))
                .count();
            if n > 0 {
                return format!(
                    "no body named '{name}': {comp} has {n} {}s, {comp}.{}[k] with k = 1 .. {n} (1-based from its first end)",
                    base.0, base.0
                );
            }
        }
    }
    format!("no body named '{name}' (bodies: {bodies})")
}

/// The index of the body named `name` (not the ground), for errors at `key`.
pub(super) fn body_index(
    names: &HashMap<String, usize>,
    file: &str,
    key: String,
    name: &str,
) -> Result<usize, ScenarioError> {
    match body_ref(names, file, key.clone(), name)? {
        BodyRef::Body(i) => Ok(i),
        BodyRef::Ground => Err(error(file, key, "the ground cannot be used here")),
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawConstraints {
    evaluation: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawBody {
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
    /// Outline drawn by `animate` and `view` (not used by the dynamics).
    pub(super) shape: Option<crate::drawing::BodyShape>,
}

/// A body point: `[x, y]` in the body frame, or on a rod segment or chain
/// link `"first_end"` = (0, −l/2) and `"last_end"` = (0, +l/2), its ends
/// towards the component's first and last end (whatever the segment count).
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(try_from = "toml::Value")]
pub(super) enum RawPoint {
    At([f64; 2]),
    FirstEnd,
    LastEnd,
}

impl TryFrom<toml::Value> for RawPoint {
    type Error = String;
    fn try_from(v: toml::Value) -> Result<Self, String> {
        const EXPECTED: &str = "expected [x, y] (body frame) or, on a rod segment or chain \
                                link, \"first_end\" or \"last_end\"";
        match &v {
            toml::Value::String(s) if s == "first_end" => Ok(RawPoint::FirstEnd),
            toml::Value::String(s) if s == "last_end" => Ok(RawPoint::LastEnd),
            toml::Value::Array(a) => {
                let num = |x: &toml::Value| match x {
                    toml::Value::Float(f) => Some(*f),
                    toml::Value::Integer(i) => Some(*i as f64),
                    _ => None,
                };
                match a.as_slice() {
                    [x, y] => match (num(x), num(y)) {
                        (Some(x), Some(y)) => Ok(RawPoint::At([x, y])),
                        _ => Err(format!("invalid point {v}: {EXPECTED}")),
                    },
                    _ => Err(format!("invalid point {v}: {EXPECTED}")),
                }
            }
            _ => Err(format!("invalid point {v}: {EXPECTED}")),
        }
    }
}

/// The body-frame coordinates of `p` on `body` (`None`: the origin); `ends`
/// holds the half length of every rod segment and chain link by body index.
pub(super) fn body_point(
    p: Option<RawPoint>,
    body: BodyRef,
    ends: &HashMap<usize, f64>,
    file: &str,
    key: String,
) -> Result<[f64; 2], ScenarioError> {
    let half = |sign: f64, what: &str| match body {
        BodyRef::Body(b) if ends.contains_key(&b) => Ok([0.0, sign * ends[&b]]),
        _ => Err(error(
            file,
            key.clone(),
            format!(
                "\"{what}\" is an end of a rod segment or chain link, and this body is neither"
            ),
        )),
    };
    match p {
        None => Ok([0.0, 0.0]),
        Some(RawPoint::At(a)) if a.iter().all(|v| v.is_finite()) => Ok(a),
        Some(RawPoint::At(a)) => Err(error(file, key, format!("{a:?} is not finite"))),
        Some(RawPoint::FirstEnd) => half(-1.0, "first_end"),
        Some(RawPoint::LastEnd) => half(1.0, "last_end"),
    }
}

/// A tabulated law `{ x = [...], f = [...] }` (piecewise linear, see [`Law`]).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTable {
    x: Vec<f64>,
    f: Vec<f64>,
}

impl RawTable {
    /// The tabulated [`Law`].
    pub(super) fn to_law(&self) -> Law {
        Law::Table {
            x: self.x.clone(),
            f: self.f.clone(),
        }
    }
}

/// A load of `type = "expression"`: an expression string (a function of
/// time, [`time_function`], is read to say so in the error).
#[derive(Debug)]
pub(super) enum RawLoad {
    Function,
    Text(String),
}

impl<'de> Deserialize<'de> for RawLoad {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = toml::Value::deserialize(d)?;
        match v {
            toml::Value::String(s) => Ok(RawLoad::Text(s)),
            v => time_function(v)
                .map(|_| RawLoad::Function)
                .map_err(serde::de::Error::custom),
        }
    }
}

/// A number (constant) or a table `{ polynomial = [c0, c1, …] }` or
/// `{ amplitude, omega, phase = 0, offset = 0 }` (harmonic).
pub(super) fn time_function(v: toml::Value) -> Result<TimeFunction, String> {
    const EXPECTED: &str = "expected a number, { polynomial = [c0, c1, ...] } or \
                            { amplitude, omega, phase, offset }";
    let num = |v: &toml::Value| match v {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    };
    if let Some(c) = num(&v) {
        return Ok(TimeFunction::Constant(c));
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
            .map(|c| num(c).ok_or_else(|| format!("polynomial coefficient {c} is not a number")))
            .collect::<Result<Vec<_>, _>>()
            .map(TimeFunction::Polynomial);
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
    Ok(TimeFunction::Harmonic {
        amplitude: get("amplitude", true)?,
        omega: get("omega", true)?,
        phase: get("phase", false)?,
        offset: get("offset", false)?,
    })
}

/// Build the model of `raw`; errors name keys of `file`.
pub(super) fn build(raw: &RawScenario, file: &str) -> Result<Model, ScenarioError> {
    let err = |key: String, message: String| error(file, key, message);
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
        if let Some(shape) = &b.shape {
            shape.check().map_err(|m| err(key("shape"), m))?;
        }
        builder.add_body(
            Body::new(b.name.clone(), b.mass, b.inertia, [b.x, b.y, phi])
                .with_velocity([b.vx, b.vy, b.omega]),
        );
    }
    // Rods and chains: their bodies after the [[body]] bodies, named before
    // the joints and forces that attach to them.
    let components = super::components::add(
        &mut builder,
        raw.rod.as_ref(),
        &raw.chain,
        raw.gravity,
        &mut names,
        file,
    )?;
    let states = super::state::add(&raw.state, &mut builder, &names, file)?;
    let mut joints: Vec<super::forces::NamedJoint> = Vec::with_capacity(raw.joint.len());
    for (k, j) in raw.joint.iter().enumerate() {
        super::joints::add_joint(j, &mut builder, k, &names, &components.ends, file)?;
        let name = j
            .name()
            .map_or_else(|| format!("joint{}", k + 1), str::to_string);
        if let Some(first) = joints.iter().position(|o| o.name == name) {
            return Err(err(
                format!("joint[{k}].name"),
                format!(
                    "duplicate joint name '{name}': joint[{first}] has it (names address \
                     joints in --set, expressions and output columns)"
                ),
            ));
        }
        let last = builder.constraints().last().expect("a joint was added");
        joints.push(super::forces::NamedJoint {
            name,
            kind: j
                .0
                .get("type")
                .and_then(toml::Value::as_str)
                .unwrap_or_default()
                .into(),
            geometry: last.geometry(),
        });
    }
    let mut forces = Vec::with_capacity(raw.force.len());
    for (k, f) in raw.force.iter().enumerate() {
        let start = builder.n_forces();
        super::forces::add_force(
            f,
            &mut builder,
            k,
            super::forces::Known {
                names: &names,
                ends: &components.ends,
                joints: &joints,
                states: &states,
                gravity: raw.gravity,
            },
            file,
        )?;
        let name = f
            .name()
            .map_or_else(|| format!("force{}", k + 1), str::to_string);
        if let Some(first) = forces.iter().position(|(o, _)| *o == name) {
            return Err(err(
                format!("force[{k}].name"),
                format!(
                    "duplicate force name '{name}': force[{first}] has it (names address \
                     forces in --set and output columns)"
                ),
            ));
        }
        forces.push((name, start..builder.n_forces()));
    }
    super::state::add_rates(&raw.state, &states, &mut builder, &names, file)?;
    if let Some(g) = raw.gravity {
        builder.gravity(g);
    }
    let mut system = builder
        .build()
        .map_err(|e| err("model".into(), e.to_string()))?;
    for (k, (name, range)) in forces.iter().enumerate() {
        for i in range.clone() {
            system.set_force_name(i, format!("force[{k}] '{name}'"));
        }
    }
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
    // `constraints.evaluation` decides whether they are used. Rods and
    // chains attach their own (joints and force elements) when built.
    if components.rods.is_empty() && components.chains.is_empty() {
        crate::generated::attach_generated(&mut system);
    }
    system
        .set_evaluation(evaluation)
        .map_err(|e| err("constraints.evaluation".into(), e.to_string()))?;

    Ok(Model {
        system,
        rod: components.rod,
        rods: components.rods,
        chains: components.chains,
        names,
        forces,
        ends: components.ends,
    })
}
