//! `type = "expression"`: one term of an [`crate::forces::ExpressionLoad`]
//! (a torque, a force at a body point, or a line force) given as
//! expressions in t and named bodies' coordinates; the bodies it may read
//! are those named in its expressions (`B.x`, …) and its own.

use super::{Context, ElementType};
use crate::forces::{ExpressionError, ExpressionLoadBuilder, LinePoint};
use crate::model::BodyRef;
use crate::scenario::model::{unknown_body, RawLoad, RawPoint};
use crate::scenario::{list, ScenarioError};
use serde::Deserialize;
use std::collections::HashMap;

/// `[[force]]` of `type = "expression"`: the keys of one of its terms.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct Expression {
    /// The body of a torque or point force.
    body: Option<String>,
    /// The point of a point force, body frame [m]; default the origin.
    point: Option<RawPoint>,
    /// Torque [N m] on `body`: an expression.
    torque: Option<RawLoad>,
    /// Global x component [N] of a point force: an expression.
    fx: Option<RawLoad>,
    /// Global y component [N] of a point force: an expression.
    fy: Option<RawLoad>,
    /// First end of a line force: a body or `"ground"`.
    body_i: Option<String>,
    /// Its point [m].
    point_i: Option<RawPoint>,
    /// Second end of a line force: a body or `"ground"`.
    body_j: Option<String>,
    /// Its point [m].
    point_j: Option<RawPoint>,
    /// Line force [N] along the line, positive in tension: an expression.
    force: Option<String>,
}

impl ElementType<Context<'_>> for Expression {
    const TYPE: &'static str = "expression";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let f = &self;
        let names = cx.names;
        let err = |fld: &str, message: String| cx.err(fld, message);
        let text = |fld: &str, l: &Option<RawLoad>| match l {
            Some(RawLoad::Text(s)) => Ok(s.clone()),
            Some(RawLoad::Function) => Err(err(
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
        let given = [
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
        ];
        for (fld, present) in given {
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
        let mut read = bodies_named(names, &texts);
        let mut note = |n: &str| {
            if let Some((s, &i)) = names.get_key_value(n) {
                if !read.iter().any(|r| r.0 == s) {
                    read.push((s.as_str(), i));
                }
            }
        };
        for (fld, b) in [
            ("body", &f.body),
            ("body_i", &f.body_i),
            ("body_j", &f.body_j),
        ] {
            if let Some(b) = b {
                // checks the name (ground allowed only for line-force ends)
                if fld == "body" {
                    cx.body_index(fld, b)?;
                } else {
                    cx.body_ref(fld, b)?;
                }
                note(b);
            }
        }
        let map = |e| expression_error(cx, e);
        let states = expression_names(names, cx.known.states, &texts).1;
        let b = ExpressionLoadBuilder::new(&cx.name, &read).with_states(&states);
        let b = if f.torque.is_some() {
            b.torque(
                f.body.as_deref().unwrap_or_default(),
                &text("torque", &f.torque)?,
            )
        } else if let Some(force) = &f.force {
            let end = |fld: &str, body: &Option<String>, p: Option<RawPoint>| {
                let b = cx.body_ref(fld, body.as_deref().unwrap_or_default())?;
                let fld = fld.replace("body", "point");
                Ok::<_, ScenarioError>(LinePoint {
                    body: body.clone().filter(|b| b != "ground"),
                    point: cx.point(&fld, p, b)?,
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
            let body = cx.body_index("body", f.body.as_deref().unwrap_or_default())?;
            b.force(
                f.body.as_deref().unwrap_or_default(),
                cx.point("point", f.point, BodyRef::Body(body))?,
                &text("fx", &f.fx)?,
                &text("fy", &f.fy)?,
            )
        }
        .map_err(map)?;
        let load = b.build();
        cx.builder.add_force(load);
        Ok(())
    }
}

/// The bodies an expression reads: those named in `texts` as
/// `B.<coordinate>` (a body under two names, aliases, is read by both).
pub(super) fn bodies_named<'a>(
    names: &'a HashMap<String, usize>,
    texts: &[String],
) -> Vec<(&'a str, usize)> {
    let mut read: Vec<(&str, usize)> = Vec::new();
    for t in texts {
        for tok in t.split(|c: char| !(c.is_alphanumeric() || "_.[]".contains(c))) {
            if let Some((b, _)) = tok.rsplit_once('.') {
                if let Some((s, &i)) = names.get_key_value(b) {
                    if !read.iter().any(|r| r.0 == s) {
                        read.push((s.as_str(), i));
                    }
                }
            }
        }
    }
    read
}

/// Names with their body index or state coordinate.
pub(in crate::scenario) type Named<'a> = Vec<(&'a str, usize)>;

/// The bodies and the controller states (name, coordinate) that `texts`
/// read.
pub(in crate::scenario) fn expression_names<'a>(
    names: &'a HashMap<String, usize>,
    states: &'a [(String, usize)],
    texts: &[String],
) -> (Named<'a>, Named<'a>) {
    let mut read = Vec::new();
    for t in texts {
        for tok in t.split(|c: char| !(c.is_alphanumeric() || "_.[]".contains(c))) {
            if let Some(s) = states.iter().find(|s| s.0 == tok) {
                if !read.iter().any(|r: &(&str, usize)| r.1 == s.1) {
                    read.push((s.0.as_str(), s.1));
                }
            }
        }
    }
    (bodies_named(names, texts), read)
}

/// An [`ExpressionError`] as an error at the force's key.
pub(super) fn expression_error(cx: &Context, e: ExpressionError) -> ScenarioError {
    let names = cx.names;
    let err = |fld: &str, message: String| cx.err(fld, message);
    match e {
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
            // an unknown `B.c`: say whether the body or the coordinate
            let why = match &source.kind {
                mbsolve_codegen::ParseErrorKind::UnknownName(n) => match n.rsplit_once('.') {
                    Some((b, _)) if names.contains_key(b) => format!(
                        " (a body's variables are {b}.x, {b}.y, {b}.phi, {b}.vx, {b}.vy, \
                             {b}.omega)"
                    ),
                    Some((b, _)) => format!(" ({})", unknown_body(names, b)),
                    None => String::new(),
                },
                _ => String::new(),
            };
            err(&field, format!("{shown}: {source}{why}"))
        }
        ExpressionError::UnknownBody { body, .. } => {
            err("body", format!("no body named '{body}' ({})", list(names)))
        }
        ExpressionError::BadPoint { point, .. } => err("point", format!("{point:?} is not finite")),
    }
}
