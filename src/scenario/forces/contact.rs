//! `type = "contact"`: a body point or circle against a straight wall,
//! fixed or moving ([`HalfPlaneContact`]).

use super::{Context, ElementType};
use crate::forces::{ContactLaw, HalfPlaneContact, RoadContact};
use crate::model::BodyRef;
use crate::scenario::joints::function_of_time;
use crate::scenario::model::RawPoint;
use crate::scenario::ScenarioError;
use serde::Deserialize;

/// `[[force]]` of `type = "contact"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(in crate::scenario) struct Contact {
    /// A body (not the ground).
    body: String,
    /// Centre of the circle, body frame [m]; default the origin.
    point: Option<RawPoint>,
    /// Radius R [m], default 0 (a point).
    radius: Option<f64>,
    /// A point of the wall line, global [m]; default the origin.
    wall_point: Option<[f64; 2]>,
    /// Outward normal of the wall (any non-zero length).
    wall_normal: Option<[f64; 2]>,
    /// Or its direction from +x [°].
    wall_normal_deg: Option<f64>,
    /// Hunt–Crossley stiffness k_h [N/m^{3/2}].
    stiffness: f64,
    /// Hunt–Crossley damping χ [s/m], default 0.
    damping: Option<f64>,
    /// Friction coefficient μ, default 0.
    friction: Option<f64>,
    /// Slip velocity v_s [m/s], default 1e-3.
    slip_velocity: Option<f64>,
    /// Displacement `[d_x(t), d_y(t)]` [m] of the wall from `wall_point`,
    /// two functions of time; default none (a fixed wall).
    wall_motion: Option<Vec<toml::Value>>,
    /// Or a road profile `y = h(x, t)` [m]: an expression of x and t
    /// instead of the wall keys.
    road: Option<String>,
}

impl ElementType<Context<'_>> for Contact {
    const TYPE: &'static str = "contact";
    fn add(self, cx: &mut Context) -> Result<(), ScenarioError> {
        let body = cx.body_index("body", &self.body)?;
        let law = ContactLaw {
            stiffness: self.stiffness,
            damping: self.damping.unwrap_or(0.0),
            friction: self.friction.unwrap_or(0.0),
            slip_velocity: self.slip_velocity.unwrap_or(1e-3),
        };
        if let Some(road) = &self.road {
            for (k, given) in [
                ("wall_point", self.wall_point.is_some()),
                ("wall_normal", self.wall_normal.is_some()),
                ("wall_normal_deg", self.wall_normal_deg.is_some()),
                ("wall_motion", self.wall_motion.is_some()),
            ] {
                if given {
                    return Err(cx.err(k, "a contact takes either a road or a wall, not both"));
                }
            }
            let c = RoadContact::new(
                body,
                cx.point("point", self.point, BodyRef::Body(body))?,
                self.radius.unwrap_or(0.0),
                road,
                law,
            )
            .map_err(|e| {
                cx.err(
                    "road",
                    format!("\"{road}\" (an expression of x and t): {e}"),
                )
            })?;
            cx.checked(&c, &[])?;
            cx.builder.add_force(c);
            return Ok(());
        }
        let normal = match (self.wall_normal, self.wall_normal_deg) {
            (Some(_), Some(_)) => {
                return Err(cx.err(
                    "wall_normal_deg",
                    "give either wall_normal or wall_normal_deg, not both",
                ))
            }
            (Some(n), None) => {
                let len = n[0].hypot(n[1]);
                if !(len.is_finite() && len > 0.0) {
                    return Err(cx.err(
                        "wall_normal",
                        format!("{n:?}: the normal must be a finite, non-zero vector"),
                    ));
                }
                n
            }
            (None, Some(d)) => {
                let (s, c) = cx.finite("wall_normal_deg", d)?.to_radians().sin_cos();
                [c, s]
            }
            (None, None) => {
                return Err(cx.err(
                    "wall_normal",
                    "missing: a contact needs wall_normal or wall_normal_deg \
                     (the outward normal of the wall), or a road",
                ))
            }
        };
        let c = HalfPlaneContact::new(
            body,
            cx.point("point", self.point, BodyRef::Body(body))?,
            self.radius.unwrap_or(0.0),
            cx.global("wall_point", self.wall_point)?,
            normal,
            law,
        );
        let c = match self.wall_motion {
            None => c,
            Some(m) => {
                let [dx, dy]: [toml::Value; 2] = m.try_into().map_err(|m: Vec<_>| {
                    cx.err(
                        "wall_motion",
                        format!(
                            "expected two functions of t [d_x, d_y], got {} entries",
                            m.len()
                        ),
                    )
                })?;
                let f = |v, i: usize| {
                    function_of_time(v, &format!("wall_motion[{i}]"))
                        .map_err(|(k, m)| cx.err(&k, m))
                };
                c.with_wall_motion(f(dx, 0)?, f(dy, 1)?)
            }
        };
        cx.checked(&c, &[("normal", "wall_normal")])?;
        cx.builder.add_force(c);
        Ok(())
    }
}
