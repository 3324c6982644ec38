//! `[[sensor]]` → named [`Sensor`]s (docs/scenarios.md): `point`,
//! `joint_angle`, `distance`, `force_element`, `contact`.

use super::element::{Decl, Kind, RawTagged};
use super::model::RawPoint;
use super::ScenarioError;
use crate::model::{joint_short_name, BodyPoint, Sensor, SensorKind, System};
use serde::Deserialize;
use std::collections::HashMap;
use std::ops::Range;

/// `type = "point"`: a body point's position and velocity.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointSensor {
    /// A body or `"ground"`.
    body: String,
    /// The point, body frame [m] (or `"first_end"` / `"last_end"` on a rod
    /// segment or chain link); default the origin.
    point: Option<RawPoint>,
}

/// `type = "joint_angle"`: a joint's relative angle and rate.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointAngleSensor {
    /// The name of a joint of two bodies.
    joint: String,
}

/// `type = "distance"`: the distance of two body points and its rate.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DistanceSensor {
    /// A body or `"ground"`.
    body_i: String,
    /// Its point [m] (or an end); default the origin.
    point_i: Option<RawPoint>,
    /// Another body or `"ground"`.
    body_j: String,
    /// Its point [m] (or an end); default the origin.
    point_j: Option<RawPoint>,
}

/// `type = "force_element"` (a spring's or rotational spring's readings)
/// or `type = "contact"` (a contact's).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ElementSensor {
    /// The `name` of a `[[force]]`.
    force: String,
}

/// One sensor table read as its type.
enum Spec {
    Point(PointSensor),
    JointAngle(JointAngleSensor),
    Distance(DistanceSensor),
    Element { force: String, contact: bool },
}

/// The `[[sensor]]` tables.
pub(super) static SENSOR: Kind = Kind::new("sensor", "sensor");

/// Every `[[sensor]]` type, in the order of docs/scenarios.md (read by
/// [`spec`]).
pub(super) const TYPES: &[Decl<()>] = &[
    Decl::new::<PointSensor>("point", ()),
    Decl::new::<JointAngleSensor>("joint_angle", ()),
    Decl::new::<DistanceSensor>("distance", ()),
    Decl::new::<ElementSensor>("force_element", ()),
    Decl::new::<ElementSensor>("contact", ()),
];

/// Sensor table `k` read as the struct of its type `name` (a row of
/// [`TYPES`]).
fn spec(raw: &RawTagged, name: &str, k: usize, file: &str) -> Result<Spec, ScenarioError> {
    Ok(match name {
        "point" => Spec::Point(SENSOR.read(raw, name, k, file)?),
        "joint_angle" => Spec::JointAngle(SENSOR.read(raw, name, k, file)?),
        "distance" => Spec::Distance(SENSOR.read(raw, name, k, file)?),
        _ => {
            let e: ElementSensor = SENSOR.read(raw, name, k, file)?;
            Spec::Element {
                force: e.force,
                contact: name == "contact",
            }
        }
    })
}

/// The sensors of `raw`; errors name `sensor[k].key` of `file`.
pub(super) fn build(
    raw: &[RawTagged],
    system: &System,
    names: &HashMap<String, usize>,
    forces: &[(String, Range<usize>)],
    ends: &HashMap<usize, f64>,
    file: &str,
) -> Result<Vec<Sensor>, ScenarioError> {
    let mut out: Vec<Sensor> = Vec::with_capacity(raw.len());
    for (k, s) in raw.iter().enumerate() {
        let site = SENSOR.site(s, k, names, ends, file);
        let err = |f: &str, m: String| site.err(f, m);
        let name = match s.0.get("name") {
            Some(toml::Value::String(n)) => n.clone(),
            Some(v) => {
                return Err(err(
                    "name",
                    format!("invalid type: {} `{v}`, expected a string", v.type_str()),
                ))
            }
            None => return Err(err("name", "missing: a sensor needs a name".into())),
        };
        let valid_name = !name.is_empty()
            && name
                .chars()
                .all(|c| c.is_alphanumeric() || c == '_' || c == '-');
        if !valid_name {
            return Err(err(
                "name",
                format!(
                    "'{name}' is not a sensor name (letters, digits, _ and -: it prefixes CSV columns)"
                ),
            ));
        }
        if out.iter().any(|o| o.name == name) {
            return Err(err("name", format!("duplicate sensor name '{name}'")));
        }
        let decl = SENSOR.decl(s, TYPES, k, file)?;
        let body = |f: &str, n: &str| site.body_ref(f, n);
        // `[x, y]`, or the ends of rod segments and chain links, as joints
        // and forces take them
        let point = |f: &str, p: Option<RawPoint>, b| site.point(f, p, b);
        let kind = match spec(s, decl.name, k, file)? {
            Spec::Point(p) => {
                let b = body("body", &p.body)?;
                SensorKind::Point(BodyPoint::new(b, point("point", p.point, b)?))
            }
            Spec::Distance(d) => {
                let (bi, bj) = (body("body_i", &d.body_i)?, body("body_j", &d.body_j)?);
                SensorKind::Distance {
                    i: BodyPoint::new(bi, point("point_i", d.point_i, bi)?),
                    j: BodyPoint::new(bj, point("point_j", d.point_j, bj)?),
                }
            }
            Spec::JointAngle(j) => {
                let name = j.joint;
                let c = system
                    .constraints()
                    .iter()
                    .find(|c| joint_short_name(c.as_ref()).as_deref() == Some(name.as_str()))
                    .ok_or_else(|| {
                        let all: Vec<String> = system
                            .constraints()
                            .iter()
                            .filter_map(|c| joint_short_name(c.as_ref()))
                            .collect();
                        err(
                            "joint",
                            format!("no joint named '{name}' (joints: {})", all.join(", ")),
                        )
                    })?;
                match c.bodies()[..] {
                    [body_i, body_j] => SensorKind::JointAngle { body_i, body_j },
                    _ => {
                        return Err(err(
                            "joint",
                            format!(
                                "'{name}' is a {} on one body: it has no relative angle",
                                c.name()
                            ),
                        ))
                    }
                }
            }
            Spec::Element {
                force: name,
                contact,
            } => {
                let (_, range) = forces.iter().find(|f| f.0 == name).ok_or_else(|| {
                    let all: Vec<&str> = forces.iter().map(|f| f.0.as_str()).collect();
                    err(
                        "force",
                        format!("no [[force]] named '{name}' (forces: {})", all.join(", ")),
                    )
                })?;
                let reads = |i: usize| system.forces()[i].readings();
                let fits = |i: &usize| {
                    let r = reads(*i);
                    !r.is_empty() && r.iter().any(|q| q.0 == "penetration") == contact
                };
                let element = range.clone().find(fits).ok_or_else(|| {
                    err(
                        "force",
                        format!(
                            "[[force]] '{name}' is not {} (a {} sensor reads {})",
                            if contact {
                                "a contact"
                            } else {
                                "a spring or rotational_spring"
                            },
                            decl.name,
                            if contact {
                                "type = \"contact\""
                            } else {
                                "type = \"spring\" or \"rotational_spring\""
                            }
                        ),
                    )
                })?;
                SensorKind::Element { element }
            }
        };
        let sensor = Sensor { name, kind };
        // its columns `S.QUANTITY` must not be a body's columns `B.x`, …
        let labels = crate::output::body_labels(system);
        if let Some(q) = sensor.quantities(system).iter().find(|(q, _)| {
            labels.contains(&sensor.name)
                && crate::output::POSITION
                    .iter()
                    .chain(&crate::output::VELOCITY)
                    .chain(&crate::output::ACCELERATION)
                    .any(|c| c == q)
        }) {
            return Err(err(
                "name",
                format!(
                    "'{}' is also a body's name: the sensor's column {}.{} would be the body's \
                     (give the sensor another name)",
                    sensor.name, sensor.name, q.0
                ),
            ));
        }
        out.push(sensor);
    }
    Ok(out)
}
