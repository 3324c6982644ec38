//! `type = "rotational_spring"`: a rotational spring–damper on the
//! relative angle of two bodies ([`RotationalSpringDamper`]).

use super::{Context, ElementType};
use crate::forces::RotationalSpringDamper;
use crate::scenario::model::RawTable;
use crate::scenario::ScenarioError;
use serde::Deserialize;

/// `[[force]]` of `type = "rotational_spring"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct RotationalSpring {
    /// A body or `"ground"` (angle 0).
    body_i: String,
    /// Another body or `"ground"`.
    body_j: String,
    /// Rest angle φ0 [rad], default 0.
    rest_angle: Option<f64>,
    /// Rest angle φ0 [°] (instead of `rest_angle`).
    rest_angle_deg: Option<f64>,
    /// Linear stiffness [N m/rad], default 0.
    stiffness: Option<f64>,
    /// Tabulated torque over angle (instead of `stiffness`).
    torque_angle: Option<RawTable>,
    /// Linear damping [N m s/rad], default 0.
    damping: Option<f64>,
    /// Tabulated torque over rate (instead of `damping`).
    torque_rate: Option<RawTable>,
}

impl ElementType<Context<'_>> for RotationalSpring {
    const TYPE: &'static str = "rotational_spring";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let (body_i, body_j) = cx.two_bodies("a rotational spring", &self.body_i, &self.body_j)?;
        let rest_angle = match (self.rest_angle, self.rest_angle_deg) {
            (Some(_), Some(_)) => {
                return Err(cx.err(
                    "rest_angle_deg",
                    "give either rest_angle or rest_angle_deg, not both",
                ))
            }
            (Some(a), None) => cx.finite("rest_angle", a)?,
            (None, Some(d)) => cx.finite("rest_angle_deg", d)?.to_radians(),
            (None, None) => 0.0,
        };
        let s = RotationalSpringDamper {
            body_i,
            body_j,
            rest_angle,
            stiffness: cx.law(
                ("stiffness", self.stiffness),
                ("torque_angle", &self.torque_angle),
            )?,
            damping: cx.law(
                ("damping", self.damping),
                ("torque_rate", &self.torque_rate),
            )?,
        };
        cx.checked(&s, &[])?;
        cx.builder.add_force(s);
        Ok(())
    }
}
