//! `type = "fluid"`: buoyancy and/or drag on a body ([`Buoyancy`],
//! [`Drag`]).

use super::{Context, ElementType};
use crate::forces::{Buoyancy, Drag};
use crate::scenario::{error, ScenarioError};
use serde::Deserialize;

/// `[[force]]` of `type = "fluid"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct Fluid {
    /// A body (not the ground).
    body: String,
    /// Fluid density ρ [kg/m³].
    fluid_density: f64,
    /// Displaced volume V [m³]: adds buoyancy.
    volume: Option<f64>,
    /// Width w [m]: with `length`, adds drag.
    width: Option<f64>,
    /// Length l [m].
    length: Option<f64>,
    /// Transverse drag coefficient C_t, default 1.2.
    c_transverse: Option<f64>,
    /// Skin friction coefficient C_f, default 0.02.
    c_skin: Option<f64>,
    /// End-face drag coefficient C_e, default 1.0.
    c_end: Option<f64>,
    /// Whether the end face drags, default false.
    end_face: Option<bool>,
}

impl ElementType<Context<'_>> for Fluid {
    const TYPE: &'static str = "fluid";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let body = cx.body_index("body", &self.body)?;
        let rho = self.fluid_density;
        if self.volume.is_none() && self.width.is_none() && self.length.is_none() {
            return Err(cx.err(
                "volume",
                "missing: a fluid load needs volume (buoyancy) and/or width and length (drag)",
            ));
        }
        if let Some(volume) = self.volume {
            let g = cx.known.gravity.unwrap_or([0.0, 0.0]);
            if g[0] != 0.0 || g[1] > 0.0 {
                return Err(error(
                    cx.file,
                    "gravity",
                    format!(
                        "{g:?}: buoyancy (force[{}].volume) needs gravity along -y, [0, -g]",
                        cx.k
                    ),
                ));
            }
            let b = Buoyancy {
                fluid_density: rho,
                gravity: -g[1],
                bodies: vec![(body, volume)],
            };
            cx.checked(&b, &[("bodies", "body")])?;
            cx.builder.add_force(b);
        }
        let drag_keys = [
            ("width", self.width.is_some()),
            ("length", self.length.is_some()),
            ("c_transverse", self.c_transverse.is_some()),
            ("c_skin", self.c_skin.is_some()),
            ("c_end", self.c_end.is_some()),
            ("end_face", self.end_face.is_some()),
        ];
        if drag_keys.iter().any(|d| d.1) {
            for fld in ["width", "length"] {
                if !drag_keys.iter().any(|d| d.0 == fld && d.1) {
                    return Err(cx.err(
                        fld,
                        "missing: drag needs width and length (and optionally c_transverse, \
                         c_skin, c_end, end_face)",
                    ));
                }
            }
            let d = Drag {
                body,
                width: self.width.unwrap_or_default(),
                length: self.length.unwrap_or_default(),
                fluid_density: rho,
                c_transverse: self.c_transverse.unwrap_or(1.2),
                c_skin: self.c_skin.unwrap_or(0.02),
                c_end: self.c_end.unwrap_or(1.0),
                end_face: self.end_face.unwrap_or(false),
            };
            cx.checked(&d, &[])?;
            cx.builder.add_force(d);
        }
        Ok(())
    }
}
