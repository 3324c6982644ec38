//! The model part of a scenario: `[[body]]`, `[[joint]]`, `[[force]]`,
//! `gravity`, `[rod]` and `constraints.evaluation` → a [`System`].

use super::{error, list, RawScenario, ScenarioError};
use crate::builders::{add_rod, RodInfo, RodParams};
use crate::constraints::{DriveCoordinate, DriveRelativeAngle, Revolute, Translational};
use crate::forces::{AppliedForce, AppliedTorque};
use crate::model::{Body, BodyRef, Evaluation, System, SystemBuilder, TimeFunction};
use serde::Deserialize;
use std::collections::HashMap;

/// What the model part builds.
pub(super) struct Model {
    pub(super) system: System,
    pub(super) rod: Option<RodInfo>,
    /// Body index by name.
    pub(super) names: HashMap<String, usize>,
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
    names.get(name).map(|&i| BodyRef::Body(i)).ok_or_else(|| {
        error(
            file,
            key,
            format!("no body named '{name}' (bodies: {})", list(names)),
        )
    })
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

/// `[rod]`: the finite-segment rod of problem B (docs/problems.md); every key defaults to
/// problem B. Segments are added after the `[[body]]` bodies.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRod {
    pub(super) segments: Option<i64>,
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
pub(super) struct RawForce {
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

    Ok(Model { system, rod, names })
}
