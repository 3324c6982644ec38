//! `type = "torque"`: an applied torque on a body ([`AppliedTorque`]).

use super::{Context, ElementType};
use crate::forces::AppliedTorque;
use crate::scenario::ScenarioError;
use serde::Deserialize;

/// `[[force]]` of `type = "torque"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct Torque {
    /// A body (not the ground).
    body: String,
    /// Counter-clockwise torque [N m], a function of t (as a drive's
    /// `motion`).
    torque: toml::Value,
}

impl ElementType<Context<'_>> for Torque {
    const TYPE: &'static str = "torque";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let body = cx.body_index("body", &self.body)?;
        let torque = cx.function(Self::TYPE, "torque", self.torque)?;
        cx.builder.add_force(AppliedTorque {
            name: cx.name.clone(),
            body,
            torque,
        });
        Ok(())
    }
}
