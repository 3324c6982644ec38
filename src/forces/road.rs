//! Contact of a body-fixed point or circle with a road profile `y = h(x, t)`
//! (an expression of x and t, docs/expressions.md), with the laws of
//! [`HalfPlaneContact`] against the profile's local tangent line.

use super::{Check, ContactLaw, ForceElement, HalfPlaneContact};
use crate::model::ModelError;
use mbsolve_codegen::{parse, Ctx, ParseError, Tape};
use std::sync::Mutex;

/// Penalty contact of a circle of radius `R ≥ 0` (a point for `R = 0`)
/// centred at the body point `s` with the ground below the profile
/// `y = h(x, t)`.
///
/// At the centre `p`, with `h` and its slopes `h_x`, `h_t` at `(p_x, t)`,
/// the road is taken as its tangent line there: normal
/// `n = (−h_x, 1)/√(1 + h_x²)`, penetration `δ = R − (p_y − h)/√(1 + h_x²)`,
/// surface velocity `(0, h_t)`; the force is that of a [`HalfPlaneContact`]
/// against this line (Hunt–Crossley normal law, regularised friction,
/// applied at `p − R n`). Exact for straight profiles; on a curved profile
/// the circle is assumed small against the radius of curvature (the
/// contact point is taken below the centre's tangent line, not at the
/// true closest point). The Jacobians are finite differences
/// ([`crate::model::FdWorkspace`]), so they include the dependence of the
/// line on `p_x`. No potential energy (the profile may move).
#[derive(Debug)]
pub struct RoadContact {
    /// The contact's laws and body point (`wall_point`, `normal` unused).
    base: HalfPlaneContact,
    /// The profile text (messages).
    profile: String,
    /// `h`, `∂h/∂x`, `∂h/∂t` at `(x, t)`.
    tape: Mutex<Tape>,
}

impl RoadContact {
    /// A road contact of `body`'s circle (`point` in the body frame \[m\],
    /// `radius` \[m\]) with the profile `y = profile(x, t)` \[m\], and the
    /// contact laws `law`.
    pub fn new(
        body: usize,
        point: [f64; 2],
        radius: f64,
        profile: &str,
        law: ContactLaw,
    ) -> Result<Self, ParseError> {
        let mut ctx = Ctx::new();
        let x = ctx.var("x");
        let t = ctx.var("t");
        ctx.set_time(t);
        let h = parse(&mut ctx, profile, |n, _| match n {
            "x" => Some(x),
            "t" => Some(t),
            _ => None,
        })?;
        let hx = ctx.diff(h, x);
        let ht = ctx.diff(h, t);
        let base = HalfPlaneContact::new(body, point, radius, [0.0, 0.0], [0.0, 1.0], law);
        Ok(Self {
            base,
            profile: profile.to_string(),
            tape: Mutex::new(Tape::new(&ctx, &[h, hx, ht])),
        })
    }

    /// The contact against the tangent line at the circle's centre at `t`.
    fn local(&self, t: f64, q: &[f64]) -> HalfPlaneContact {
        let b = &self.base;
        let o = 3 * b.body;
        let (sn, cs) = q[o + 2].sin_cos();
        let px = q[o] + cs * b.point[0] - sn * b.point[1];
        let mut v = [0.0; 3];
        self.tape
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .eval(&[px, t], &mut v);
        let len = v[1].hypot(1.0);
        let mut c = b.clone();
        c.wall_point = [px, v[0]];
        c.normal = [-v[1] / len, 1.0 / len];
        c.surface_velocity = [0.0, v[2]];
        c
    }
}

impl ForceElement for RoadContact {
    fn name(&self) -> String {
        format!(
            "road contact of body {} at {:?} (radius {}) with y = {}",
            self.base.body, self.base.point, self.base.radius, self.profile
        )
    }
    fn coordinates(&self) -> Vec<usize> {
        self.base.coordinates()
    }
    fn add_forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        self.local(t, q).add_forces(t, q, qd, g);
    }
    /// `Some(0.0)`: the profile's next rise is not foreseen.
    fn onset_within(&self, _t: f64, _q: &[f64], _qd: &[f64], _horizon: f64) -> Option<f64> {
        Some(0.0)
    }
    fn readings(&self) -> &'static [(&'static str, &'static str)] {
        self.base.readings()
    }
    fn read(&self, t: f64, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let c = self.local(t, q);
        c.read(t, q, qd, out);
    }
    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let name = self.name();
        Check { element: &name }.finite_point("point", self.base.point)?;
        self.base.validate(n_coords)
    }
}
