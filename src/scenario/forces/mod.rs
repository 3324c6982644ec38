//! `[[force]]`: one serde struct per `type` (its own file here), read from
//! the force's table after its `type` ([`super::element`]), and the
//! context every type builds its elements with. A new force type is a file
//! with its struct and [`ElementType`] implementation and one row of
//! [`TYPES`].

pub(super) use super::element::ElementType;
use super::element::{self, AddFn, Decl, Kind, Knows, RawTagged};
use super::model::RawTable;
use super::{error, ScenarioError};
use crate::forces::{ForceElement, Law};
use crate::model::{ModelError, SystemBuilder, TimeFunction};
use std::collections::HashMap;

mod applied;
mod contact;
mod expression;
mod fluid;
mod joint;
mod rotational;
mod spring;
mod torque;

pub(super) use expression::expression_names;
pub(super) use joint::NamedJoint;

/// The `[[force]]` tables.
pub(super) static FORCE: Kind = Kind::new("force", "force element");

/// A force type's row of [`TYPES`].
pub(super) type ForceDecl = Decl<AddFn<Forces>>;

/// Every `[[force]]` type, in the order of docs/scenarios.md.
pub(super) const TYPES: &[ForceDecl] = &[
    ForceDecl::of::<torque::Torque>(),
    ForceDecl::of::<applied::Force>(),
    ForceDecl::of::<spring::Spring>(),
    ForceDecl::of::<rotational::RotationalSpring>(),
    ForceDecl::of::<contact::Contact>(),
    ForceDecl::of::<fluid::Fluid>(),
    ForceDecl::of::<expression::Expression>(),
    ForceDecl::of::<joint::JointTorque>(),
    ForceDecl::of::<joint::JointForce>(),
];

/// The `[[force]]` kind: what its types build with besides the builder
/// and the site is [`Known`].
pub(super) struct Forces;

impl Knows for Forces {
    type Data<'a> = Known<'a>;
}

/// What a force type builds with.
pub(super) type Context<'a> = element::Context<'a, Forces>;

/// What the model knows when its forces are added: the names of bodies
/// and joints, the rods' and chains' half lengths, the states and gravity.
#[derive(Clone, Copy)]
pub(super) struct Known<'a> {
    /// Body index by name.
    pub(super) names: &'a HashMap<String, usize>,
    /// The half length of every rod segment and chain link by body index.
    pub(super) ends: &'a HashMap<usize, f64>,
    /// The `[[joint]]`s.
    pub(super) joints: &'a [NamedJoint],
    /// The `[[state]]`s: (name, coordinate).
    pub(super) states: &'a [(String, usize)],
    /// The scenario's `gravity`.
    pub(super) gravity: Option<[f64; 2]>,
}

/// Builds `force[k]` (`raw`) into `builder`; every error names `force[k].key`.
pub(super) fn add_force(
    raw: &RawTagged,
    builder: &mut SystemBuilder,
    k: usize,
    known: Known<'_>,
    file: &str,
) -> Result<(), ScenarioError> {
    let decl = FORCE.decl(raw, TYPES, k, file)?;
    let mut cx = Context {
        site: FORCE.site(raw, k, known.names, known.ends, file),
        builder,
        known,
    };
    (decl.add)(raw, &mut cx)
}

impl Context<'_> {
    /// `v` at `fld` if finite.
    pub(super) fn finite(&self, fld: &str, v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err(fld, format!("{v} is not finite")))
        }
    }

    /// A global point at `fld` (`None`: the origin), finite.
    pub(super) fn global(&self, fld: &str, p: Option<[f64; 2]>) -> Result<[f64; 2], ScenarioError> {
        let p = p.unwrap_or_default();
        if p.iter().all(|v| v.is_finite()) {
            Ok(p)
        } else {
            Err(self.err(fld, format!("{p:?} is not finite")))
        }
    }

    /// A law given as a linear coefficient `lin` or a table `tab`, at most
    /// one of the two (neither: linear 0), validated non-decreasing.
    pub(super) fn law(
        &self,
        lin: (&str, Option<f64>),
        tab: (&str, &Option<RawTable>),
    ) -> Result<Law, ScenarioError> {
        let law = match (lin.1, tab.1) {
            (Some(_), Some(_)) => {
                return Err(self.err(
                    tab.0,
                    format!("give either {} or {}, not both", lin.0, tab.0),
                ))
            }
            (Some(c), None) => (lin.0, Law::Linear(c)),
            (None, Some(t)) => (tab.0, t.to_law()),
            (None, None) => (lin.0, Law::Linear(0.0)),
        };
        law.1
            .validate(&self.name, law.0, true)
            .map_err(|e| self.model_error(e, &[]))?;
        Ok(law.1)
    }

    /// The function of time at `fld` of a `kind` force element: every
    /// form a drive's `motion` takes ([`super::joints::function_of_time`]:
    /// a number, a polynomial or harmonic table, an expression of t, a
    /// table of points); an expression that reads coordinates is an error
    /// pointing to `type = "expression"`.
    pub(super) fn function(
        &self,
        kind: &str,
        fld: &str,
        v: toml::Value,
    ) -> Result<TimeFunction, ScenarioError> {
        let text = v.as_str().map(str::to_string);
        super::joints::function_of_time(v, fld).map_err(|(k, m)| {
            let hint = match text {
                Some(_) => format!(
                    "; a {kind} takes a function of t only: loads that read coordinates \
                     need type = \"expression\""
                ),
                None => String::new(),
            };
            error(self.file, self.key(&k), format!("{m}{hint}"))
        })
    }

    /// Validates a library element, naming the scenario key of a field
    /// (`rename`: element field → scenario key where they differ).
    pub(super) fn checked(
        &self,
        e: &dyn ForceElement,
        rename: &[(&str, &str)],
    ) -> Result<(), ScenarioError> {
        e.validate(usize::MAX)
            .map_err(|e| self.model_error(e, rename))
    }

    /// A library element's [`ModelError`] as an error at `force[k].<key>`.
    fn model_error(&self, e: ModelError, rename: &[(&str, &str)]) -> ScenarioError {
        match e {
            ModelError::InvalidParameter {
                field, value, why, ..
            } => {
                let head_len = field.find(['.', '[']).unwrap_or(field.len());
                let (head, tail) = field.split_at(head_len);
                let head = rename.iter().find(|r| r.0 == head).map_or(head, |r| r.1);
                let key = self.key(&format!("{head}{tail}"));
                error(self.file, key, format!("{value} is invalid: {why}"))
            }
            other => error(self.file, self.kind.path(self.k), other.to_string()),
        }
    }
}
