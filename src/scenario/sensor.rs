//! `[[sensor]]` → named [`Sensor`]s (docs/scenarios.md): `point`,
//! `joint_angle`, `distance`, `force_element`, `contact`.

use super::model::{body_point, body_ref, RawPoint};
use super::{error, ScenarioError};
use crate::model::{joint_short_name, Sensor, SensorKind, System};
use serde::Deserialize;
use std::collections::HashMap;
use std::ops::Range;

/// `[[sensor]]`: `name`, `type` and the keys of that type.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSensor {
    name: String,
    #[serde(rename = "type")]
    kind: String,
    body: Option<String>,
    point: Option<RawPoint>,
    joint: Option<String>,
    body_i: Option<String>,
    point_i: Option<RawPoint>,
    body_j: Option<String>,
    point_j: Option<RawPoint>,
    force: Option<String>,
}

/// The sensor types and the keys each needs (points default to the origin
/// of the body frame and may be omitted).
const SENSOR_TYPES: &[(&str, &[&str], &[&str])] = &[
    ("point", &["body"], &["point"]),
    ("joint_angle", &["joint"], &[]),
    ("distance", &["body_i", "body_j"], &["point_i", "point_j"]),
    ("force_element", &["force"], &[]),
    ("contact", &["force"], &[]),
];

/// The sensors of `raw`; errors name `sensor[k].key` of `file`.
pub(super) fn build(
    raw: &[RawSensor],
    system: &System,
    names: &HashMap<String, usize>,
    forces: &[(String, Range<usize>)],
    ends: &HashMap<usize, f64>,
    file: &str,
) -> Result<Vec<Sensor>, ScenarioError> {
    let mut out: Vec<Sensor> = Vec::with_capacity(raw.len());
    for (k, s) in raw.iter().enumerate() {
        let key = |f: &str| format!("sensor[{k}].{f}");
        let err = |f: &str, m: String| error(file, key(f), m);
        let valid_name = !s.name.is_empty()
            && s.name
                .chars()
                .all(|c| c.is_alphanumeric() || c == '_' || c == '-');
        if !valid_name {
            return Err(err(
                "name",
                format!(
                    "'{}' is not a sensor name (letters, digits, _ and -: it prefixes CSV columns)",
                    s.name
                ),
            ));
        }
        if out.iter().any(|o| o.name == s.name) {
            return Err(err("name", format!("duplicate sensor name '{}'", s.name)));
        }
        let Some(&(_, needs, allowed)) = SENSOR_TYPES.iter().find(|t| t.0 == s.kind) else {
            let types: Vec<&str> = SENSOR_TYPES.iter().map(|t| t.0).collect();
            return Err(err(
                "type",
                format!(
                    "unknown sensor type '{}' (expected one of {})",
                    s.kind,
                    types.join(", ")
                ),
            ));
        };
        for (f, present) in [
            ("body", s.body.is_some()),
            ("point", s.point.is_some()),
            ("joint", s.joint.is_some()),
            ("body_i", s.body_i.is_some()),
            ("point_i", s.point_i.is_some()),
            ("body_j", s.body_j.is_some()),
            ("point_j", s.point_j.is_some()),
            ("force", s.force.is_some()),
        ] {
            if present && !needs.contains(&f) && !allowed.contains(&f) {
                return Err(err(f, format!("not a key of a {} sensor", s.kind)));
            }
            if !present && needs.contains(&f) {
                return Err(err(
                    f,
                    format!("missing: a {} sensor needs {}", s.kind, needs.join(", ")),
                ));
            }
        }
        let text = |o: &Option<String>| o.clone().unwrap_or_default();
        let body = |f: &str, o: &Option<String>| body_ref(names, file, key(f), &text(o));
        // `[x, y]`, or the ends of rod segments and chain links, as joints
        // and forces take them
        let point = |f: &str, p: Option<RawPoint>, b| body_point(p, b, ends, file, key(f));
        let kind = match s.kind.as_str() {
            "point" => {
                let b = body("body", &s.body)?;
                SensorKind::Point {
                    body: b,
                    point: point("point", s.point, b)?,
                }
            }
            "distance" => {
                let (bi, bj) = (body("body_i", &s.body_i)?, body("body_j", &s.body_j)?);
                SensorKind::Distance {
                    body_i: bi,
                    point_i: point("point_i", s.point_i, bi)?,
                    body_j: bj,
                    point_j: point("point_j", s.point_j, bj)?,
                }
            }
            "joint_angle" => {
                let name = text(&s.joint);
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
            _ => {
                let name = text(&s.force);
                let (_, range) = forces.iter().find(|f| f.0 == name).ok_or_else(|| {
                    let all: Vec<&str> = forces.iter().map(|f| f.0.as_str()).collect();
                    err(
                        "force",
                        format!("no [[force]] named '{name}' (forces: {})", all.join(", ")),
                    )
                })?;
                let contact = s.kind == "contact";
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
                            s.kind,
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
        out.push(Sensor {
            name: s.name.clone(),
            kind,
        });
    }
    Ok(out)
}
