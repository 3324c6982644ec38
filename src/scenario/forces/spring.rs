//! `type = "spring"`: a point-to-point spring–damper–actuator
//! ([`PointSpringDamper`]).

use super::{Context, ElementType};
use crate::forces::PointSpringDamper;
use crate::scenario::model::{RawPoint, RawTable};
use crate::scenario::ScenarioError;
use serde::Deserialize;

/// `[[force]]` of `type = "spring"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct Spring {
    /// A body or `"ground"`.
    body_i: String,
    /// Attachment on `body_i` (body frame; global on the ground) [m].
    point_i: Option<RawPoint>,
    /// Another body or `"ground"`.
    body_j: String,
    /// Attachment on `body_j` [m].
    point_j: Option<RawPoint>,
    /// Free length [m], default 0.
    free_length: Option<f64>,
    /// Linear stiffness [N/m], default 0.
    stiffness: Option<f64>,
    /// Tabulated force over deflection (instead of `stiffness`).
    force_deflection: Option<RawTable>,
    /// Linear damping [N s/m], default 0.
    damping: Option<f64>,
    /// Tabulated force over velocity (instead of `damping`).
    force_velocity: Option<RawTable>,
    /// Constant tension [N], default 0.
    preload: Option<f64>,
    /// Actuator tension [N], a function of t (as a drive's `motion`).
    actuator: Option<toml::Value>,
}

impl ElementType<Context<'_>> for Spring {
    const TYPE: &'static str = "spring";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let (i, j) = cx.two_points(
            "a spring",
            (&self.body_i, self.point_i),
            (&self.body_j, self.point_j),
        )?;
        let actuator = match self.actuator {
            Some(v) => Some(cx.function(Self::TYPE, "actuator", v)?),
            None => None,
        };
        let s = PointSpringDamper {
            i,
            j,
            free_length: cx.finite("free_length", self.free_length.unwrap_or(0.0))?,
            stiffness: cx.law(
                ("stiffness", self.stiffness),
                ("force_deflection", &self.force_deflection),
            )?,
            damping: cx.law(
                ("damping", self.damping),
                ("force_velocity", &self.force_velocity),
            )?,
            preload: cx.finite("preload", self.preload.unwrap_or(0.0))?,
            actuator,
        };
        cx.checked(&s, &[])?;
        cx.builder.add_force(s);
        Ok(())
    }
}
