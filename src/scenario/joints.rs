//! `[[joint]]`: one serde struct per `type` (`revolute`, `translational`,
//! `drive_coordinate`, `drive_angle`), read from the joint's table after
//! its `type` ([`super::element`]), and the constraint each builds.

use super::element::{self, AddFn, Decl, ElementType, Kind, RawTagged};
use super::model::{time_function, RawPoint};
use super::ScenarioError;
use crate::constraints::{
    expression_motion, spline_motion, DriveCoordinate, DriveRelativeAngle, Revolute, Spline,
    Translational,
};
use crate::model::{BodyPoint, BodyRef, SystemBuilder, TimeFunction};
use serde::Deserialize;
use std::collections::HashMap;

/// What a joint type builds with.
type Context<'a> = element::Context<'a, ()>;

impl Context<'_> {
    /// The two points a joint joins, `point_i` on `body_i` and `point_j`
    /// on `body_j` ([`Site::two_points`](element::Site::two_points)).
    fn ends(
        &self,
        body_i: &str,
        point_i: RawPoint,
        body_j: &str,
        point_j: RawPoint,
    ) -> Result<(BodyPoint, BodyPoint), ScenarioError> {
        self.two_points("a joint", (body_i, Some(point_i)), (body_j, Some(point_j)))
    }

    /// The `motion` of a drive ([`function_of_time`]).
    fn motion(&self, v: toml::Value) -> Result<TimeFunction, ScenarioError> {
        function_of_time(v, "motion").map_err(|(k, m)| self.err(&k, m))
    }
}

/// A function of time at key `fld` (a drive's `motion`, a wall's
/// `wall_motion` entry): a number, a polynomial or harmonic table
/// ([`time_function`]), an expression of t, or a table of points
/// `{ t = [...], value = [...], spline = "cubic" | "linear" }`. Errors:
/// (key, message).
pub(in crate::scenario) fn function_of_time(
    v: toml::Value,
    fld: &str,
) -> Result<TimeFunction, (String, String)> {
    let err = |k: &str, m: &dyn std::fmt::Display| (k.to_string(), m.to_string());
    if let toml::Value::String(text) = &v {
        return expression_motion(text)
            .map_err(|e| err(fld, &format!("\"{text}\" (an expression of t): {e}")));
    }
    let is_table = v
        .as_table()
        .is_some_and(|t| ["t", "value", "spline"].iter().any(|k| t.contains_key(*k)));
    if !is_table {
        return time_function(v).map_err(|m| {
            err(
                fld,
                &format!(
                    "{m}; or an expression of t (\"0.1*sin(6*t)\") or points \
                         {{ t = [...], value = [...], spline = \"cubic\" }}"
                ),
            )
        });
    }
    let t = v.as_table().expect("a table");
    for k in t.keys() {
        if !["t", "value", "spline"].contains(&k.as_str()) {
            return Err(err(
                &format!("{fld}.{k}"),
                &"not a key of a tabulated motion (it takes t, value, spline)",
            ));
        }
    }
    let numbers = |k: &str| -> Result<Vec<f64>, (String, String)> {
        let a = t
            .get(k)
            .ok_or_else(|| {
                err(
                    &format!("{fld}.{k}"),
                    &"missing: a tabulated motion needs t and value",
                )
            })?
            .as_array()
            .ok_or_else(|| err(&format!("{fld}.{k}"), &"expected an array of numbers"))?;
        a.iter()
            .enumerate()
            .map(|(i, x)| match x {
                toml::Value::Float(f) => Ok(*f),
                toml::Value::Integer(n) => Ok(*n as f64),
                x => Err(err(
                    &format!("{fld}.{k}[{i}]"),
                    &format!("{x} is not a number"),
                )),
            })
            .collect()
    };
    let (ts, ys) = (numbers("t")?, numbers("value")?);
    let kind = match t.get("spline").map(|s| s.as_str()) {
        None | Some(Some("cubic")) => Spline::Cubic,
        Some(Some("linear")) => Spline::Linear,
        Some(s) => {
            return Err(err(
                &format!("{fld}.spline"),
                &format!(
                    "{} is not one of \"cubic\", \"linear\"",
                    s.map_or_else(|| t["spline"].to_string(), |s| format!("\"{s}\""))
                ),
            ))
        }
    };
    spline_motion(&ts, &ys, kind).map_err(|m| err(fld, &m))
}

/// The `[[joint]]` tables.
pub(super) static JOINT: Kind = Kind::new("joint", "joint");

/// A joint type's row of [`TYPES`].
pub(super) type JointDecl = Decl<AddFn<()>>;

/// Every `[[joint]]` type, in the order of docs/scenarios.md.
pub(super) const TYPES: &[JointDecl] = &[
    JointDecl::of::<RevoluteJoint>(),
    JointDecl::of::<TranslationalJoint>(),
    JointDecl::of::<DriveCoordinateJoint>(),
    JointDecl::of::<DriveAngleJoint>(),
];

/// Builds `joint[k]` (`raw`) into `builder`; every error names `joint[k].key`.
pub(super) fn add_joint(
    raw: &RawTagged,
    builder: &mut SystemBuilder,
    k: usize,
    names: &HashMap<String, usize>,
    ends: &HashMap<usize, f64>,
    file: &str,
) -> Result<(), ScenarioError> {
    let decl = JOINT.decl(raw, TYPES, k, file)?;
    let mut cx = Context {
        site: JOINT.site(raw, k, names, ends, file),
        builder,
        known: (),
    };
    (decl.add)(raw, &mut cx)
}

/// `type = "revolute"`: the two points coincide ([`Revolute`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RevoluteJoint {
    /// A body or `"ground"`.
    body_i: String,
    /// The joint's point on `body_i` (body frame; global on the ground) [m].
    point_i: RawPoint,
    /// Another body or `"ground"`.
    body_j: String,
    /// The joint's point on `body_j` [m].
    point_j: RawPoint,
}

impl ElementType<Context<'_>> for RevoluteJoint {
    const TYPE: &'static str = "revolute";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let (i, j) = cx.ends(&self.body_i, self.point_i, &self.body_j, self.point_j)?;
        let name = std::mem::take(&mut cx.site.name);
        cx.builder
            .add_constraint(Revolute::new(name, i.body, i.point, j.body, j.point));
        Ok(())
    }
}

/// `type = "translational"`: `point_j` stays on the line through
/// `point_i` along `axis_i`, the relative angle at its initial value
/// ([`Translational`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TranslationalJoint {
    /// A body or `"ground"`.
    body_i: String,
    /// A point of the line on `body_i` [m].
    point_i: RawPoint,
    /// The line's direction, body-i frame (non-zero).
    axis_i: [f64; 2],
    /// Another body or `"ground"`.
    body_j: String,
    /// The point on `body_j` that stays on the line [m].
    point_j: RawPoint,
}

impl ElementType<Context<'_>> for TranslationalJoint {
    const TYPE: &'static str = "translational";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let (i, j) = cx.ends(&self.body_i, self.point_i, &self.body_j, self.point_j)?;
        let axis = self.axis_i;
        let len = axis[0].hypot(axis[1]);
        if !len.is_finite() || len <= 0.0 {
            return Err(cx.err(
                "axis_i",
                format!("{axis:?}: the axis must be a non-zero vector"),
            ));
        }
        let angle = |b: BodyRef| match b {
            BodyRef::Ground => 0.0,
            BodyRef::Body(i) => cx.builder.bodies()[i].q0[2],
        };
        let theta0 = angle(j.body) - angle(i.body);
        let name = std::mem::take(&mut cx.site.name);
        cx.builder.add_constraint(Translational::new(
            name, i.body, i.point, axis, j.body, j.point, theta0,
        ));
        Ok(())
    }
}

/// `type = "drive_coordinate"`: a coordinate of a body follows
/// `motion(t)` ([`DriveCoordinate`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DriveCoordinateJoint {
    /// A body (not the ground).
    body: String,
    /// `"x"`, `"y"` or `"phi"`.
    coordinate: String,
    /// The coordinate's motion [m or rad], a function of t.
    motion: toml::Value,
}

impl ElementType<Context<'_>> for DriveCoordinateJoint {
    const TYPE: &'static str = "drive_coordinate";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let b = cx.body_index("body", &self.body)?;
        let c = match self.coordinate.as_str() {
            "x" => 0,
            "y" => 1,
            "phi" => 2,
            o => return Err(cx.err("coordinate", format!("'{o}' is not one of x, y, phi"))),
        };
        let f = cx.motion(self.motion)?;
        let name = std::mem::take(&mut cx.site.name);
        cx.builder
            .add_constraint(DriveCoordinate::new(name, b, c, f));
        Ok(())
    }
}

/// `type = "drive_angle"`: `φ_j − φ_i = motion(t)` ([`DriveRelativeAngle`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DriveAngleJoint {
    /// A body or `"ground"` (angle 0).
    body_i: String,
    /// Another body or `"ground"`.
    body_j: String,
    /// The relative angle [rad], a function of t.
    motion: toml::Value,
}

impl ElementType<Context<'_>> for DriveAngleJoint {
    const TYPE: &'static str = "drive_angle";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let bi = cx.body_ref("body_i", &self.body_i)?;
        let bj = cx.body_ref("body_j", &self.body_j)?;
        let f = cx.motion(self.motion)?;
        let name = std::mem::take(&mut cx.site.name);
        cx.builder
            .add_constraint(DriveRelativeAngle::new(name, bi, bj, f));
        Ok(())
    }
}
