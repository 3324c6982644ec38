//! `type = "force"`: an applied force at a body point ([`AppliedForce`]).

use super::{Context, ElementType};
use crate::forces::AppliedForce;
use crate::model::BodyRef;
use crate::scenario::model::RawPoint;
use crate::scenario::ScenarioError;
use serde::Deserialize;

/// `[[force]]` of `type = "force"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct Force {
    /// A body (not the ground).
    body: String,
    /// Point of application, body frame [m]; default the origin.
    point: Option<RawPoint>,
    /// Global x component [N], a function of t (as a drive's `motion`).
    fx: toml::Value,
    /// Global y component [N], a function of t.
    fy: toml::Value,
}

impl ElementType<Context<'_>> for Force {
    const TYPE: &'static str = "force";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let body = cx.body_index("body", &self.body)?;
        let point = cx.point("point", self.point, BodyRef::Body(body))?;
        let fx = cx.function(Self::TYPE, "fx", self.fx)?;
        let fy = cx.function(Self::TYPE, "fy", self.fy)?;
        cx.builder.add_force(AppliedForce {
            name: cx.name.clone(),
            body,
            point,
            fx,
            fy,
        });
        Ok(())
    }
}
