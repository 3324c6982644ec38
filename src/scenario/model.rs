//! The model part of a scenario: `[[body]]`, `[[joint]]`, `[[force]]`,
//! `gravity`, the components `[rod]`/`[[rod]]`/`[[chain]]` (built in
//! `components`) and `constraints.evaluation` → a [`System`].

use super::{error, list, RawScenario, ScenarioError};
use crate::builders::{ChainInfo, RodInfo};
use crate::constraints::{DriveCoordinate, DriveRelativeAngle, Revolute, Translational};
use crate::forces::{
    AppliedForce, AppliedTorque, Buoyancy, Drag, ExpressionError, ExpressionLoadBuilder,
    ForceElement, HalfPlaneContact, Law, LinePoint, PointSpringDamper, RotationalSpringDamper,
};
use crate::model::{Body, BodyRef, Evaluation, ModelError, System, SystemBuilder, TimeFunction};
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
fn unknown_body(names: &HashMap<String, usize>, name: &str) -> String {
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
}

/// `[[joint]]`: `type` = revolute | translational | drive_coordinate |
/// drive_angle; which other keys apply depends on the type.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawJoint {
    #[serde(rename = "type")]
    kind: String,
    name: Option<String>,
    body: Option<String>,
    body_i: Option<String>,
    point_i: Option<RawPoint>,
    axis_i: Option<[f64; 2]>,
    body_j: Option<String>,
    point_j: Option<RawPoint>,
    coordinate: Option<String>,
    motion: Option<RawFunction>,
}

/// `[[force]]`: `type` = torque | force | spring | rotational_spring |
/// contact | fluid | expression; which other keys apply depends on the type
/// (docs/scenarios.md).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawForce {
    #[serde(rename = "type")]
    kind: String,
    name: Option<String>,
    body: Option<String>,
    point: Option<RawPoint>,
    torque: Option<RawLoad>,
    fx: Option<RawLoad>,
    fy: Option<RawLoad>,
    force: Option<String>,
    body_i: Option<String>,
    point_i: Option<RawPoint>,
    body_j: Option<String>,
    point_j: Option<RawPoint>,
    free_length: Option<f64>,
    stiffness: Option<f64>,
    force_deflection: Option<RawTable>,
    damping: Option<f64>,
    force_velocity: Option<RawTable>,
    preload: Option<f64>,
    actuator: Option<RawFunction>,
    rest_angle: Option<f64>,
    rest_angle_deg: Option<f64>,
    torque_angle: Option<RawTable>,
    torque_rate: Option<RawTable>,
    radius: Option<f64>,
    wall_point: Option<[f64; 2]>,
    wall_normal: Option<[f64; 2]>,
    wall_normal_deg: Option<f64>,
    friction: Option<f64>,
    slip_velocity: Option<f64>,
    fluid_density: Option<f64>,
    volume: Option<f64>,
    width: Option<f64>,
    length: Option<f64>,
    c_transverse: Option<f64>,
    c_skin: Option<f64>,
    c_end: Option<f64>,
    end_face: Option<bool>,
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

/// A load value: a function of time ([`RawFunction`]) or an expression
/// string (only for `type = "expression"`).
#[derive(Debug)]
pub(super) enum RawLoad {
    Function(RawFunction),
    Text(String),
}

impl<'de> Deserialize<'de> for RawLoad {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = toml::Value::deserialize(d)?;
        match v {
            toml::Value::String(s) => Ok(RawLoad::Text(s)),
            v => RawFunction::try_from(v)
                .map(RawLoad::Function)
                .map_err(serde::de::Error::custom),
        }
    }
}

/// A number (constant) or a table `{ polynomial = [c0, c1, …] }` or
/// `{ amplitude, omega, phase = 0, offset = 0 }` (harmonic).
#[derive(Debug, Deserialize)]
#[serde(try_from = "toml::Value")]
pub(super) enum RawFunction {
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
    let body_ref = |key: String, name: &str| body_ref(&names, file, key, name);
    let body_index = |key: String, name: &str| body_index(&names, file, key, name);
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
                let pi = body_point(j.point_i, bi, &components.ends, file, key("point_i"))?;
                let pj = body_point(j.point_j, bj, &components.ends, file, key("point_j"))?;
                if j.kind == "revolute" {
                    builder.add_constraint(Revolute::new(name, bi, pi, bj, pj));
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
                    builder.add_constraint(Translational::new(name, bi, pi, axis, bj, pj, theta0));
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
    let gravity = raw.gravity;
    let mut forces = Vec::with_capacity(raw.force.len());
    for (k, f) in raw.force.iter().enumerate() {
        let start = builder.n_forces();
        add_force(&mut builder, f, k, gravity, &names, &components.ends, file)?;
        let name = f.name.clone().unwrap_or_else(|| format!("force{}", k + 1));
        forces.push((name, start..builder.n_forces()));
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

/// The `[[force]]` types and the keys each takes: `(type, needed, allowed)`.
/// An `expression` needs `body` with `torque`, or `body` with `fx` and `fy`
/// (`point` allowed), or `body_i`, `body_j` and `force` (`point_i`,
/// `point_j` allowed); checked in [`add_force`].
const FORCE_TYPES: &[(&str, &[&str], &[&str])] = &[
    ("torque", &["body", "torque"], &[]),
    ("force", &["body", "fx", "fy"], &["point"]),
    (
        "spring",
        &["body_i", "body_j"],
        &[
            "point_i",
            "point_j",
            "free_length",
            "stiffness",
            "force_deflection",
            "damping",
            "force_velocity",
            "preload",
            "actuator",
        ],
    ),
    (
        "rotational_spring",
        &["body_i", "body_j"],
        &[
            "rest_angle",
            "rest_angle_deg",
            "stiffness",
            "torque_angle",
            "damping",
            "torque_rate",
        ],
    ),
    (
        "contact",
        &["body", "stiffness"],
        &[
            "point",
            "radius",
            "wall_point",
            "wall_normal",
            "wall_normal_deg",
            "damping",
            "friction",
            "slip_velocity",
        ],
    ),
    (
        "fluid",
        &["body", "fluid_density"],
        &[
            "volume",
            "width",
            "length",
            "c_transverse",
            "c_skin",
            "c_end",
            "end_face",
        ],
    ),
    (
        "expression",
        &[],
        &[
            "body", "point", "torque", "fx", "fy", "body_i", "point_i", "body_j", "point_j",
            "force",
        ],
    ),
];

/// The keys of `f` other than `type` and `name`, and whether each is given.
fn given_keys(f: &RawForce) -> [(&'static str, bool); 36] {
    [
        ("body", f.body.is_some()),
        ("point", f.point.is_some()),
        ("torque", f.torque.is_some()),
        ("fx", f.fx.is_some()),
        ("fy", f.fy.is_some()),
        ("force", f.force.is_some()),
        ("body_i", f.body_i.is_some()),
        ("point_i", f.point_i.is_some()),
        ("body_j", f.body_j.is_some()),
        ("point_j", f.point_j.is_some()),
        ("free_length", f.free_length.is_some()),
        ("stiffness", f.stiffness.is_some()),
        ("force_deflection", f.force_deflection.is_some()),
        ("damping", f.damping.is_some()),
        ("force_velocity", f.force_velocity.is_some()),
        ("preload", f.preload.is_some()),
        ("actuator", f.actuator.is_some()),
        ("rest_angle", f.rest_angle.is_some()),
        ("rest_angle_deg", f.rest_angle_deg.is_some()),
        ("torque_angle", f.torque_angle.is_some()),
        ("torque_rate", f.torque_rate.is_some()),
        ("radius", f.radius.is_some()),
        ("wall_point", f.wall_point.is_some()),
        ("wall_normal", f.wall_normal.is_some()),
        ("wall_normal_deg", f.wall_normal_deg.is_some()),
        ("friction", f.friction.is_some()),
        ("slip_velocity", f.slip_velocity.is_some()),
        ("fluid_density", f.fluid_density.is_some()),
        ("volume", f.volume.is_some()),
        ("width", f.width.is_some()),
        ("length", f.length.is_some()),
        ("c_transverse", f.c_transverse.is_some()),
        ("c_skin", f.c_skin.is_some()),
        ("c_end", f.c_end.is_some()),
        ("end_face", f.end_face.is_some()),
        ("name", f.name.is_some()),
    ]
}

/// Build `force[k]` into `builder`; every error names `force[k].key`.
fn add_force(
    builder: &mut SystemBuilder,
    f: &RawForce,
    k: usize,
    gravity: Option<[f64; 2]>,
    names: &HashMap<String, usize>,
    ends: &HashMap<usize, f64>,
    file: &str,
) -> Result<(), ScenarioError> {
    let key = |fld: &str| format!("force[{k}].{fld}");
    let err = |fld: &str, message: String| error(file, key(fld), message);
    let name = f.name.clone().unwrap_or_else(|| format!("force{}", k + 1));
    let kind = f.kind.as_str();
    let Some(&(_, needs, allowed)) = FORCE_TYPES.iter().find(|t| t.0 == kind) else {
        let types: Vec<&str> = FORCE_TYPES.iter().map(|t| t.0).collect();
        return Err(err(
            "type",
            format!(
                "unknown force type '{kind}' (expected one of {})",
                types.join(", ")
            ),
        ));
    };
    for (fld, present) in given_keys(f) {
        if fld == "name" {
            continue;
        }
        if present && !(needs.contains(&fld) || allowed.contains(&fld)) {
            return Err(err(fld, format!("not a key of a {kind} force element")));
        }
        if !present && needs.contains(&fld) {
            return Err(err(
                fld,
                format!("missing: a {kind} force element needs {}", needs.join(", ")),
            ));
        }
    }
    let body_ref = |fld: &str, n: &Option<String>| {
        body_ref(names, file, key(fld), n.as_deref().unwrap_or_default())
    };
    let body_index = |fld: &str, n: &Option<String>| {
        body_index(names, file, key(fld), n.as_deref().unwrap_or_default())
    };
    // `body_i` and `body_j` of a two-body element, which must differ
    let two_bodies = |what: &str| {
        let body_i = body_ref("body_i", &f.body_i)?;
        let body_j = body_ref("body_j", &f.body_j)?;
        if body_i == body_j {
            return Err(err(
                "body_j",
                format!(
                    "{what} must connect two different bodies, got '{}' twice",
                    f.body_j.as_deref().unwrap_or_default()
                ),
            ));
        }
        Ok((body_i, body_j))
    };
    let finite = |fld: &str, v: f64| {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(err(fld, format!("{v} is not finite")))
        }
    };
    let point = |fld: &str, p: Option<RawPoint>, b: BodyRef| body_point(p, b, ends, file, key(fld));
    let global = |fld: &str, p: Option<[f64; 2]>| {
        let p = p.unwrap_or_default();
        if p.iter().all(|v| v.is_finite()) {
            Ok(p)
        } else {
            Err(err(fld, format!("{p:?} is not finite")))
        }
    };
    // A linear coefficient or a table, at most one of the two; `monotone`:
    // the law must be non-decreasing.
    let law = |lin: (&str, Option<f64>), tab: (&str, &Option<RawTable>)| {
        let law = match (lin.1, tab.1) {
            (Some(_), Some(_)) => {
                return Err(err(
                    tab.0,
                    format!("give either {} or {}, not both", lin.0, tab.0),
                ))
            }
            (Some(c), None) => (lin.0, Law::Linear(c)),
            (None, Some(t)) => (
                tab.0,
                Law::Table {
                    x: t.x.clone(),
                    f: t.f.clone(),
                },
            ),
            (None, None) => (lin.0, Law::Linear(0.0)),
        };
        law.1
            .validate(&name, law.0, true)
            .map_err(|e| model_error(file, k, e, &[]))?;
        Ok(law.1)
    };
    let function = |fld: &str, l: &Option<RawLoad>| match l {
        Some(RawLoad::Function(f)) => Ok(f.to_function()),
        Some(RawLoad::Text(s)) => Err(err(
            fld,
            format!(
                "\"{s}\": expressions need type = \"expression\"; a {kind} takes a number, \
                 {{ polynomial = [...] }} or {{ amplitude, omega, phase, offset }}"
            ),
        )),
        None => Err(err(fld, "missing".into())),
    };
    // Validate a library element, naming the scenario key of a field.
    let checked = |e: &dyn ForceElement, rename: &[(&str, &str)]| {
        e.validate(usize::MAX)
            .map_err(|e| model_error(file, k, e, rename))
    };
    match kind {
        "torque" => {
            let body = body_index("body", &f.body)?;
            builder.add_force(AppliedTorque {
                name,
                body,
                torque: function("torque", &f.torque)?,
            });
        }
        "force" => {
            let body = body_index("body", &f.body)?;
            builder.add_force(AppliedForce {
                name,
                body,
                point: point("point", f.point, BodyRef::Body(body))?,
                fx: function("fx", &f.fx)?,
                fy: function("fy", &f.fy)?,
            });
        }
        "spring" => {
            let (body_i, body_j) = two_bodies("a spring")?;
            let s = PointSpringDamper {
                body_i,
                point_i: point("point_i", f.point_i, body_i)?,
                body_j,
                point_j: point("point_j", f.point_j, body_j)?,
                free_length: finite("free_length", f.free_length.unwrap_or(0.0))?,
                stiffness: law(
                    ("stiffness", f.stiffness),
                    ("force_deflection", &f.force_deflection),
                )?,
                damping: law(
                    ("damping", f.damping),
                    ("force_velocity", &f.force_velocity),
                )?,
                preload: finite("preload", f.preload.unwrap_or(0.0))?,
                actuator: f.actuator.as_ref().map(RawFunction::to_function),
            };
            checked(&s, &[])?;
            builder.add_force(s);
        }
        "rotational_spring" => {
            let (body_i, body_j) = two_bodies("a rotational spring")?;
            let rest_angle = match (f.rest_angle, f.rest_angle_deg) {
                (Some(_), Some(_)) => {
                    return Err(err(
                        "rest_angle_deg",
                        "give either rest_angle or rest_angle_deg, not both".into(),
                    ))
                }
                (Some(a), None) => finite("rest_angle", a)?,
                (None, Some(d)) => finite("rest_angle_deg", d)?.to_radians(),
                (None, None) => 0.0,
            };
            let s = RotationalSpringDamper {
                body_i,
                body_j,
                rest_angle,
                stiffness: law(
                    ("stiffness", f.stiffness),
                    ("torque_angle", &f.torque_angle),
                )?,
                damping: law(("damping", f.damping), ("torque_rate", &f.torque_rate))?,
            };
            checked(&s, &[])?;
            builder.add_force(s);
        }
        "contact" => {
            let body = body_index("body", &f.body)?;
            let normal = match (f.wall_normal, f.wall_normal_deg) {
                (Some(_), Some(_)) => {
                    return Err(err(
                        "wall_normal_deg",
                        "give either wall_normal or wall_normal_deg, not both".into(),
                    ))
                }
                (Some(n), None) => {
                    let len = n[0].hypot(n[1]);
                    if !(len.is_finite() && len > 0.0) {
                        return Err(err(
                            "wall_normal",
                            format!("{n:?}: the normal must be a finite, non-zero vector"),
                        ));
                    }
                    n
                }
                (None, Some(d)) => {
                    let (s, c) = finite("wall_normal_deg", d)?.to_radians().sin_cos();
                    [c, s]
                }
                (None, None) => {
                    return Err(err(
                        "wall_normal",
                        "missing: a contact needs wall_normal or wall_normal_deg \
                         (the outward normal of the wall)"
                            .into(),
                    ))
                }
            };
            let c = HalfPlaneContact::new(
                body,
                point("point", f.point, BodyRef::Body(body))?,
                f.radius.unwrap_or(0.0),
                global("wall_point", f.wall_point)?,
                normal,
                f.stiffness.unwrap_or_default(),
                f.damping.unwrap_or(0.0),
                f.friction.unwrap_or(0.0),
                f.slip_velocity.unwrap_or(1e-3),
            );
            checked(&c, &[("normal", "wall_normal")])?;
            builder.add_force(c);
        }
        "fluid" => {
            let body = body_index("body", &f.body)?;
            let rho = f.fluid_density.unwrap_or_default();
            if f.volume.is_none() && f.width.is_none() && f.length.is_none() {
                return Err(err(
                    "volume",
                    "missing: a fluid load needs volume (buoyancy) and/or width and length (drag)"
                        .into(),
                ));
            }
            if let Some(volume) = f.volume {
                let g = gravity.unwrap_or([0.0, 0.0]);
                if g[0] != 0.0 || g[1] > 0.0 {
                    return Err(error(
                        file,
                        "gravity",
                        format!(
                            "{g:?}: buoyancy (force[{k}].volume) needs gravity along -y, [0, -g]"
                        ),
                    ));
                }
                let b = Buoyancy {
                    fluid_density: rho,
                    gravity: -g[1],
                    bodies: vec![(body, volume)],
                };
                checked(&b, &[("bodies", "body")])?;
                builder.add_force(b);
            }
            let drag_keys = [
                ("width", f.width.is_some()),
                ("length", f.length.is_some()),
                ("c_transverse", f.c_transverse.is_some()),
                ("c_skin", f.c_skin.is_some()),
                ("c_end", f.c_end.is_some()),
                ("end_face", f.end_face.is_some()),
            ];
            if drag_keys.iter().any(|d| d.1) {
                for fld in ["width", "length"] {
                    if !drag_keys.iter().any(|d| d.0 == fld && d.1) {
                        return Err(err(
                            fld,
                            "missing: drag needs width and length (and optionally c_transverse, \
                             c_skin, c_end, end_face)"
                                .into(),
                        ));
                    }
                }
                let d = Drag {
                    body,
                    width: f.width.unwrap_or_default(),
                    length: f.length.unwrap_or_default(),
                    fluid_density: rho,
                    c_transverse: f.c_transverse.unwrap_or(1.2),
                    c_skin: f.c_skin.unwrap_or(0.02),
                    c_end: f.c_end.unwrap_or(1.0),
                    end_face: f.end_face.unwrap_or(false),
                };
                checked(&d, &[])?;
                builder.add_force(d);
            }
        }
        _ => add_expression(builder, f, k, &name, names, ends, file)?,
    }
    Ok(())
}

/// `force[k]` of `type = "expression"`: one term of an [`crate::forces::ExpressionLoad`]
/// (a torque, a force at a body point, or a line force); the bodies it may
/// read are those named in its expressions (`B.x`, …) and its own.
fn add_expression(
    builder: &mut SystemBuilder,
    f: &RawForce,
    k: usize,
    name: &str,
    names: &HashMap<String, usize>,
    ends: &HashMap<usize, f64>,
    file: &str,
) -> Result<(), ScenarioError> {
    let key = |fld: &str| format!("force[{k}].{fld}");
    let err = |fld: &str, message: String| error(file, key(fld), message);
    let text = |fld: &str, l: &Option<RawLoad>| match l {
        Some(RawLoad::Text(s)) => Ok(s.clone()),
        Some(RawLoad::Function(_)) => Err(err(
            fld,
            "an expression element takes an expression string, e.g. \"-2*A.omega\"".into(),
        )),
        None => Err(err(fld, "missing".into())),
    };
    // Which term: torque, point force or line force.
    let term: (&[&str], &[&str]) = if f.torque.is_some() {
        (&["body", "torque"], &[])
    } else if f.force.is_some() {
        (&["body_i", "body_j", "force"], &["point_i", "point_j"])
    } else if f.fx.is_some() || f.fy.is_some() {
        (&["body", "fx", "fy"], &["point"])
    } else {
        return Err(err(
            "torque",
            "missing: an expression element needs torque, fx and fy, or force (a line force)"
                .into(),
        ));
    };
    for (fld, present) in given_keys(f) {
        if fld == "name" {
            continue;
        }
        if present && !(term.0.contains(&fld) || term.1.contains(&fld)) {
            return Err(err(
                fld,
                format!(
                    "not a key of this expression term (it takes {})",
                    [term.0, term.1].concat().join(", ")
                ),
            ));
        }
        if !present && term.0.contains(&fld) {
            return Err(err(
                fld,
                format!("missing: this expression term needs {}", term.0.join(", ")),
            ));
        }
    }
    let texts: Vec<String> = [&f.torque, &f.fx, &f.fy]
        .iter()
        .filter_map(|l| match l {
            Some(RawLoad::Text(s)) => Some(s.clone()),
            _ => None,
        })
        .chain(f.force.clone())
        .collect();
    // the bodies read: named in the texts as `B.<coordinate>`, and the term's own
    let mut read: Vec<(&str, usize)> = Vec::new();
    let mut note = |n: &str| {
        if let Some((s, &i)) = names.get_key_value(n) {
            if !read.iter().any(|r| r.1 == i) {
                read.push((s.as_str(), i));
            }
        }
    };
    for t in &texts {
        for tok in t.split(|c: char| !(c.is_alphanumeric() || c == '_' || c == '.')) {
            if let Some((b, _)) = tok.rsplit_once('.') {
                note(b);
            }
        }
    }
    for (fld, b) in [
        ("body", &f.body),
        ("body_i", &f.body_i),
        ("body_j", &f.body_j),
    ] {
        if let Some(b) = b {
            // checks the name (ground allowed only for line-force ends)
            if fld == "body" {
                body_index(names, file, key(fld), b)?;
            } else {
                body_ref(names, file, key(fld), b)?;
            }
            note(b);
        }
    }
    let map = |e: ExpressionError| match e {
        ExpressionError::Parse {
            field,
            text,
            source,
            ..
        } => {
            // A long text is shown by its start and length.
            let shown = match text.char_indices().nth(60) {
                Some((cut, _)) => format!("\"{}…\" ({} bytes)", &text[..cut], text.len()),
                None => format!("\"{text}\""),
            };
            err(&field, format!("{shown}: {source}"))
        }
        ExpressionError::UnknownBody { body, .. } => {
            err("body", format!("no body named '{body}' ({})", list(names)))
        }
        ExpressionError::BadPoint { point, .. } => err("point", format!("{point:?} is not finite")),
    };
    let b = ExpressionLoadBuilder::new(name, &read);
    let b = if f.torque.is_some() {
        b.torque(
            f.body.as_deref().unwrap_or_default(),
            &text("torque", &f.torque)?,
        )
    } else if let Some(force) = &f.force {
        let end = |fld: &str, body: &Option<String>, p: Option<RawPoint>| {
            let b = body_ref(names, file, key(fld), body.as_deref().unwrap_or_default())?;
            let fld = fld.replace("body", "point");
            Ok::<_, ScenarioError>(LinePoint {
                body: body.clone().filter(|b| b != "ground"),
                point: body_point(p, b, ends, file, key(&fld))?,
            })
        };
        let (a, c) = (
            end("body_i", &f.body_i, f.point_i)?,
            end("body_j", &f.body_j, f.point_j)?,
        );
        if a.body.is_none() && c.body.is_none() {
            return Err(err("body_j", "a line force needs at least one body".into()));
        }
        b.line_force(&a, &c, force)
    } else {
        let body = body_index(
            names,
            file,
            key("body"),
            f.body.as_deref().unwrap_or_default(),
        )?;
        b.force(
            f.body.as_deref().unwrap_or_default(),
            body_point(f.point, BodyRef::Body(body), ends, file, key("point"))?,
            &text("fx", &f.fx)?,
            &text("fy", &f.fy)?,
        )
    }
    .map_err(map)?;
    builder.add_force(b.build());
    Ok(())
}

/// A library element's [`ModelError`] as an error at `force[k].<key>`;
/// `rename` maps element field names to scenario keys where they differ.
fn model_error(file: &str, k: usize, e: ModelError, rename: &[(&str, &str)]) -> ScenarioError {
    match e {
        ModelError::InvalidParameter {
            field, value, why, ..
        } => {
            let head_len = field.find(['.', '[']).unwrap_or(field.len());
            let (head, tail) = field.split_at(head_len);
            let head = rename.iter().find(|r| r.0 == head).map_or(head, |r| r.1);
            error(
                file,
                format!("force[{k}].{head}{tail}"),
                format!("{value} is invalid: {why}"),
            )
        }
        other => error(file, format!("force[{k}]"), other.to_string()),
    }
}
