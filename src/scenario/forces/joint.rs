//! `type = "joint_torque"` and `type = "joint_force"`: a torque between the
//! two bodies of a named revolute joint, or a force along the axis of a
//! named translational joint, given as an expression that may read the
//! joint's coordinate (`angle`, `rate`; or `slide`, `speed`) besides t and
//! the bodies' coordinates; built as one term of an
//! [`crate::forces::ExpressionLoad`] (exact symbolic Jacobians).

use super::expression::{bodies_named, expression_error};
use super::{Context, ElementType};
use crate::forces::{ExpressionLoadBuilder, LinePoint};
use crate::model::{BodyRef, JointGeometry};
use crate::scenario::ScenarioError;
use serde::Deserialize;

/// A `[[joint]]` a joint load can act at: its name, key, type and geometry.
#[derive(Debug)]
pub(in crate::scenario) struct NamedJoint {
    /// The joint's `name` (default `joint{k+1}`).
    pub(in crate::scenario) name: String,
    /// Its `type`.
    pub(in crate::scenario) kind: String,
    /// Its bodies and points as built.
    pub(in crate::scenario) geometry: JointGeometry,
}

/// `[[force]]` of `type = "joint_torque"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct JointTorque {
    /// The name of a revolute `[[joint]]`.
    joint: String,
    /// Torque [N m] on its `body_j` (the opposite on `body_i`): an
    /// expression of t, `angle`, `rate` and bodies' coordinates.
    torque: String,
}

/// `[[force]]` of `type = "joint_force"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct JointForce {
    /// The name of a translational `[[joint]]`.
    joint: String,
    /// Force [N] along the axis on its `body_j` (the opposite on
    /// `body_i`): an expression of t, `slide`, `speed` and bodies'
    /// coordinates.
    force: String,
}

/// The joint named at `joint` if it has type `want`.
fn find<'a>(
    cx: &'a Context,
    what: &str,
    name: &str,
    want: &str,
) -> Result<&'a NamedJoint, ScenarioError> {
    let Some(j) = cx.known.joints.iter().find(|j| j.name == name) else {
        let known: Vec<&str> = cx.known.joints.iter().map(|j| j.name.as_str()).collect();
        return Err(cx.err(
            "joint",
            format!(
                "no joint named '{name}' (joints: {})",
                if known.is_empty() {
                    "none".to_string()
                } else {
                    known.join(", ")
                }
            ),
        ));
    };
    if j.kind != want {
        return Err(cx.err(
            "joint",
            format!(
                "joint '{name}' is a {} joint; a {what} acts at a {want} joint",
                j.kind
            ),
        ));
    }
    Ok(j)
}

/// The name a body index is read by in the load (its first name in sort
/// order, for determinism), `None` for the ground.
fn body_name(cx: &Context, b: BodyRef) -> Option<String> {
    match b {
        BodyRef::Ground => None,
        BodyRef::Body(i) => cx
            .names
            .iter()
            .filter(|n| *n.1 == i)
            .map(|n| n.0.clone())
            .min(),
    }
}

/// The builder reading the bodies named in `text` and `sides`.
fn builder(cx: &Context, text: &str, sides: &[&Option<String>]) -> ExpressionLoadBuilder {
    let mut read = bodies_named(cx.names, &[text.to_string()]);
    for s in sides.iter().copied().flatten() {
        if let Some((n, &i)) = cx.names.get_key_value(s) {
            if !read.iter().any(|r| r.0 == n) {
                read.push((n.as_str(), i));
            }
        }
    }
    let states =
        super::expression::expression_names(cx.names, cx.known.states, &[text.to_string()]).1;
    ExpressionLoadBuilder::new(&cx.name, &read).with_states(&states)
}

impl ElementType<Context<'_>> for JointTorque {
    const TYPE: &'static str = "joint_torque";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let j = find(cx, "joint_torque", &self.joint, "revolute")?;
        let JointGeometry::Revolute { i, j, .. } = j.geometry else {
            return Err(cx.err("joint", format!("joint '{}' is not revolute", self.joint)));
        };
        let (i, jj) = (body_name(cx, i.body), body_name(cx, j.body));
        let load = builder(cx, &self.torque, &[&i, &jj])
            .joint_torque(i.as_deref(), jj.as_deref(), &self.torque)
            .map_err(|e| expression_error(cx, e))?
            .build();
        cx.builder.add_force(load);
        Ok(())
    }
}

impl ElementType<Context<'_>> for JointForce {
    const TYPE: &'static str = "joint_force";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let j = find(cx, "joint_force", &self.joint, "translational")?;
        let JointGeometry::Translational(slide) = j.geometry else {
            return Err(cx.err(
                "joint",
                format!("joint '{}' is not translational", self.joint),
            ));
        };
        let (i, jj) = (body_name(cx, slide.i.body), body_name(cx, slide.j.body));
        let (a, b) = (
            LinePoint {
                body: i.clone(),
                point: slide.i.point,
            },
            LinePoint {
                body: jj.clone(),
                point: slide.j.point,
            },
        );
        let load = builder(cx, &self.force, &[&i, &jj])
            .joint_force(&a, slide.u_i, &b, &self.force)
            .map_err(|e| expression_error(cx, e))?
            .build();
        cx.builder.add_force(load);
        Ok(())
    }
}
