//! Components of a scenario: flexible rods (`[rod]` or `[[rod]]`) and link
//! chains (`[[chain]]`), each added by its builder
//! ([`crate::builders::add_named_rod`], [`crate::builders::add_link_chain`])
//! with its generated kernels attached to its own ranges, and each body
//! given a name usable wherever a body is named: `C.first`, `C.last`,
//! `C.segment[k]` (rods) or `C.link[k]` (chains), k = 1 … N from the first
//! end (docs/scenarios.md).

use super::{error, ScenarioError};
use crate::builders::{
    add_link_chain, add_named_rod, add_rod, ChainInfo, LinkChain, RodInfo, RodParams,
};
use crate::model::{ModelError, SystemBuilder};
use serde::Deserialize;
use std::collections::HashMap;

/// One rod: `[rod]` (the falling rod of problem B, docs/problems.md, named
/// `rod`) or an element of `[[rod]]`. Every material key defaults to
/// problem B.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRod {
    name: Option<String>,
    position: Option<[f64; 2]>,
    angle_deg: Option<f64>,
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

/// The document's `rod` key: the table `[rod]` or the array `[[rod]]`
/// (TOML allows only one of the two).
#[derive(Debug)]
pub(super) enum RawRods {
    One(Box<RawRod>),
    Many(Vec<RawRod>),
}

impl RawRods {
    /// Each rod with its key prefix (`rod` or `rod[k]`).
    pub(super) fn each(&self) -> Vec<(String, &RawRod)> {
        match self {
            RawRods::One(r) => vec![("rod".into(), &**r)],
            RawRods::Many(v) => v
                .iter()
                .enumerate()
                .map(|(k, r)| (format!("rod[{k}]"), r))
                .collect(),
        }
    }
}

/// `[[chain]]`: N uniform links ([`LinkChain`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawChain {
    name: Option<String>,
    pub(super) links: i64,
    length: f64,
    mass: Option<f64>,
    inertia: Option<f64>,
    density: Option<f64>,
    area: Option<f64>,
    position: Option<[f64; 2]>,
    angle_deg: Option<f64>,
    stiffness: Option<f64>,
    damping: Option<f64>,
    pivot: Option<bool>,
}

/// Parse the document's `rod` value; an error is `(key path, message)`.
pub(super) fn parse_rods(v: toml::Value) -> Result<RawRods, (String, String)> {
    fn at<T: for<'de> Deserialize<'de>>(
        v: toml::Value,
        prefix: &str,
    ) -> Result<T, (String, String)> {
        serde_path_to_error::deserialize(v).map_err(
            |e: serde_path_to_error::Error<toml::de::Error>| {
                let path = e.path().to_string();
                let key = match path.as_str() {
                    "." | "" => prefix.to_string(),
                    p if p.starts_with('[') => format!("{prefix}{p}"),
                    p => format!("{prefix}.{p}"),
                };
                (key, e.inner().message().to_string())
            },
        )
    }
    match v {
        toml::Value::Table(_) => at(v, "rod").map(|r| RawRods::One(Box::new(r))),
        toml::Value::Array(_) => at(v, "rod").map(RawRods::Many),
        other => Err((
            "rod".into(),
            format!("expected a table [rod] or tables [[rod]], got {other}"),
        )),
    }
}

/// What the components built: every rod and chain with its name.
#[derive(Debug, Default)]
pub(super) struct Components {
    /// The `[rod]` table's rod (the shipped falling rod).
    pub(super) rod: Option<RodInfo>,
    /// Every rod (`[rod]` included) by name.
    pub(super) rods: Vec<(String, RodInfo)>,
    /// Every chain by name.
    pub(super) chains: Vec<(String, ChainInfo)>,
    /// Half length of every rod segment and chain link, by body index
    /// (`"first_end"`, `"last_end"` points).
    pub(super) ends: HashMap<usize, f64>,
}

/// The component names in use (component name → its key), to find
/// duplicates; bodies are checked through `names`.
type Taken = HashMap<String, String>;

/// Check the name of the component at `key` (`rod[0]`) and give its bodies
/// their names in `names`: `C.first`, `C.last`, `C.<part>[k]` (k = 1 … N).
fn register(
    names: &mut HashMap<String, usize>,
    taken: &mut Taken,
    file: &str,
    key: &str,
    name: &str,
    part: &str,
    bodies: &[usize],
) -> Result<(), ScenarioError> {
    let mut all = vec![
        (format!("{name}.first"), bodies[0]),
        (format!("{name}.last"), bodies[bodies.len() - 1]),
    ];
    all.extend(
        bodies
            .iter()
            .enumerate()
            .map(|(k, &b)| (format!("{name}.{part}[{}]", k + 1), b)),
    );
    for (n, b) in all {
        if names.insert(n.clone(), b).is_some() {
            return Err(error(
                file,
                format!("{key}.name"),
                format!("'{name}': the body name '{n}' is already taken"),
            ));
        }
    }
    taken.insert(name.to_string(), key.to_string());
    Ok(())
}

/// The name of the component at `key`, checked: given (`None` allowed only
/// for the `[rod]` table, named `rod`), a plain word (letters, digits, `_`,
/// `-`), not `ground`, not a body's or another component's name.
fn component_name(
    given: &Option<String>,
    default: Option<&str>,
    names: &HashMap<String, usize>,
    taken: &Taken,
    file: &str,
    key: &str,
) -> Result<String, ScenarioError> {
    let err = |m: String| error(file, format!("{key}.name"), m);
    let name = match (given, default) {
        (Some(n), _) => n.clone(),
        (None, Some(d)) => d.to_string(),
        (None, None) => {
            return Err(err(
                "missing: every [[rod]] and [[chain]] needs a name (its bodies are then \
                 NAME.first, NAME.last, ...)"
                    .into(),
            ))
        }
    };
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_alphanumeric() || c == '_' || c == '-')
    {
        return Err(err(format!(
            "'{name}' is invalid: a component name is a word of letters, digits, _ and -"
        )));
    }
    if name == "ground" {
        return Err(err("'ground' is reserved for the fixed frame".into()));
    }
    if names.contains_key(&name) {
        return Err(err(format!("duplicate name '{name}': a body has it")));
    }
    if let Some(other) = taken.get(&name) {
        return Err(err(format!("duplicate name '{name}': {other} has it")));
    }
    Ok(name)
}

/// The scenario key of a builder's [`ModelError`]: the field's key under
/// `prefix`, renamed where the scenario spells it differently.
fn builder_error(
    file: &str,
    prefix: &str,
    e: ModelError,
    rename: &[(&str, &str)],
) -> ScenarioError {
    let key = match &e {
        ModelError::InvalidParameter { field, .. } => {
            let f = rename
                .iter()
                .find(|r| r.0 == field)
                .map_or(field.as_str(), |r| r.1);
            format!("{prefix}.{f}")
        }
        _ => prefix.to_string(),
    };
    error(file, key, e.to_string())
}

/// Add every rod and chain of the scenario to `builder` (after the
/// `[[body]]` bodies, before the joints), naming their bodies in `names`.
pub(super) fn add(
    builder: &mut SystemBuilder,
    rods: Option<&RawRods>,
    chains: &[RawChain],
    gravity: Option<[f64; 2]>,
    names: &mut HashMap<String, usize>,
    file: &str,
) -> Result<Components, ScenarioError> {
    let mut out = Components::default();
    let mut taken = Taken::new();
    let legacy = matches!(rods, Some(RawRods::One(_)));
    for (key, r) in rods.map(RawRods::each).unwrap_or_default() {
        let err = |f: &str, m: String| error(file, format!("{key}.{f}"), m);
        let name = component_name(&r.name, legacy.then_some("rod"), names, &taken, file, &key)?;
        let mut p = RodParams::problem_b(10);
        if let Some(n) = r.segments {
            if n < 1 {
                return Err(err(
                    "segments",
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
        let tilt_key = match (r.tilt_deg, r.angle_deg) {
            (Some(_), Some(_)) => {
                return Err(err(
                    "angle_deg",
                    "give either angle_deg or tilt_deg (the same angle), not both".into(),
                ))
            }
            (None, Some(_)) => "angle_deg",
            _ => "tilt_deg",
        };
        // a channel narrower than the default is blamed for a penetration
        let default_channel = p.channel_width;
        set(&mut p.length, r.length);
        set(&mut p.width, r.width);
        set(&mut p.density, r.density);
        set(&mut p.youngs_modulus, r.youngs_modulus);
        set(&mut p.damping_time, r.damping_time);
        set(&mut p.tilt, r.tilt_deg.or(r.angle_deg).map(f64::to_radians));
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
        // The falling rod's table has its water and walls by default; a
        // rod of [[rod]] only when asked.
        p.fluid = r.fluid.unwrap_or(legacy);
        p.contact = r.contact.unwrap_or(legacy);
        // Buoyancy uses the scenario's gravity (none without `gravity`).
        p.gravity = gravity.map_or(0.0, |g| g[0].hypot(g[1]));
        let rename = [
            ("n_segments", "segments"),
            // a penetration at the start is blamed on the channel width
            // where it was given alone or narrowed
            (
                "tilt",
                if r.tilt_deg.or(r.angle_deg).is_none() && r.channel_width.is_some()
                    || r.channel_width.is_some_and(|w| w < default_channel)
                {
                    "channel_width"
                } else {
                    tilt_key
                },
            ),
            ("initial_velocity", "velocity"),
            ("friction_coefficient", "friction"),
        ];
        let info = if legacy && r.position.is_none() && r.name.is_none() {
            // the library's falling rod, exactly (problem B)
            add_rod(builder, &p)
        } else {
            add_named_rod(builder, &p, &name, r.position)
        }
        .map_err(|e| builder_error(file, &key, e, &rename))?;
        // the bodies carry their scenario names (output columns
        // `rod.segment[k].x`), the library's rod included
        for (k, &b) in info.bodies.iter().enumerate() {
            builder.bodies_mut()[b].name = format!("{name}.segment[{}]", k + 1);
        }
        register(
            names,
            &mut taken,
            file,
            &key,
            &name,
            "segment",
            &info.bodies,
        )?;
        out.ends
            .extend(info.bodies.iter().map(|&b| (b, 0.5 * info.segment_length)));
        if legacy {
            out.rod = Some(info.clone());
        }
        out.rods.push((name, info));
    }
    for (k, c) in chains.iter().enumerate() {
        let key = format!("chain[{k}]");
        let err = |f: &str, m: String| error(file, format!("{key}.{f}"), m);
        let name = component_name(&c.name, None, names, &taken, file, &key)?;
        if c.links < 1 {
            return Err(err(
                "links",
                format!("{} is invalid: the chain needs at least one link", c.links),
            ));
        }
        let mass = match (c.mass, c.density, c.area) {
            (Some(m), None, None) => m,
            (None, Some(rho), Some(a)) => rho * a * c.length,
            (Some(_), _, _) => {
                return Err(err(
                    if c.density.is_some() {
                        "density"
                    } else {
                        "area"
                    },
                    "give either mass or density and area, not both".into(),
                ))
            }
            (None, None, None) => {
                return Err(err(
                    "mass",
                    "missing: a chain needs mass (per link) or density and area".into(),
                ))
            }
            (None, d, _) => {
                return Err(err(
                    if d.is_some() { "area" } else { "density" },
                    "missing: density and area go together (mass = density · area · length)".into(),
                ))
            }
        };
        let chain = LinkChain {
            links: c.links as usize,
            length: c.length,
            mass,
            // a slender bar: m l²/12
            inertia: c.inertia.unwrap_or(mass * c.length * c.length / 12.0),
            position: c.position.unwrap_or_default(),
            angle: c.angle_deg.unwrap_or(0.0).to_radians(),
            stiffness: c.stiffness.unwrap_or(0.0),
            damping: c.damping.unwrap_or(0.0),
            pivot: c.pivot.unwrap_or(false),
        };
        let mass_key = if c.mass.is_some() { "mass" } else { "density" };
        let info = add_link_chain(builder, &name, &chain).map_err(|e| {
            builder_error(file, &key, e, &[("angle", "angle_deg"), ("mass", mass_key)])
        })?;
        register(names, &mut taken, file, &key, &name, "link", &info.bodies)?;
        out.ends
            .extend(info.bodies.iter().map(|&b| (b, 0.5 * chain.length)));
        out.chains.push((name, info));
    }
    Ok(out)
}
