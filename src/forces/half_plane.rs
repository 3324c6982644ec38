//! Contact of a body-fixed point or circle with a straight wall (a
//! half-plane at any angle), with the rod's Hunt–Crossley normal law and
//! regularised Coulomb friction (docs/scenarios.md, `[[force]]`).

use super::contact::Engaged;
use super::ContactLaw;
use super::{check_coordinates, Check, ForceElement, ForceJacobians};
use crate::model::{BodyRef, ModelError, TimeFunction};

/// Penalty contact of a circle of radius `R ≥ 0` (a point for `R = 0`),
/// centred at the body-fixed point `s` of `body`, with the wall
/// `{x : n·(x − a) ≤ 0}` (the line through `a`; `n` the unit outward
/// normal, pointing into the free side).
///
/// With `u = A(φ) s`, centre `p = r + u`, the penetration is
/// `δ = R − n·(p − a)` and its rate `δ̇ = −n·ṗ`. The contact point is
/// `p_c = p − R n`, offset `c = u − R n` from the body's reference point,
/// its material velocity `v_c = ṙ + φ̇ J c` (`J` the rotation by +90°), and
/// the slip velocity along the wall `v_t = t·v_c` with `t = J n`. For
/// `δ > 0` the wall applies at `p_c`
///
/// `F = F_n n − μ F_n tanh(v_t / v_s) t`, `F_n = max(0, k_h δ^{3/2} (1 + χ δ̇))`
///
/// (the laws of [`super::WallContact`]); the generalized force is
/// `[F_x, F_y, c × F]`. Jacobians are analytic (chain rule through δ, δ̇,
/// v_t and c). Potential energy: the elastic part `(2/5) k_h δ^{5/2}`; the
/// damping and the friction only dissipate.
///
/// A moving wall ([`HalfPlaneContact::with_wall_motion`]) translates with
/// its point `a(t) = a₀ + (d_x(t), d_y(t))`, normal fixed: `δ = R − n·(p − a(t))`,
/// `δ̇ = −n·(ṗ − ȧ)`, slip `v_t = t·(v_c − ȧ)` — the contact in the wall's
/// own frame. Its force then works on the body, so it has no potential
/// energy (it counts as a non-conservative element).
#[derive(Debug, Clone)]
pub struct HalfPlaneContact {
    /// Body index.
    pub body: usize,
    /// Centre of the circle in the body frame \[m\].
    pub point: [f64; 2],
    /// Radius R ≥ 0 \[m\] (0: a point).
    pub radius: f64,
    /// A point of the wall line, global \[m\].
    pub wall_point: [f64; 2],
    /// Outward unit normal of the wall (into the free side); normalised by
    /// [`HalfPlaneContact::new`].
    pub normal: [f64; 2],
    /// The contact laws.
    pub law: ContactLaw,
    /// Displacement `(d_x(t), d_y(t))` \[m\] of the wall from `wall_point`,
    /// global; `None`: a fixed wall.
    pub wall_motion: Option<[TimeFunction; 2]>,
    /// Velocity of the (fixed-position) wall surface: the local tangent
    /// line of a moving road profile ([`super::RoadContact`]).
    pub(crate) surface_velocity: [f64; 2],
}

/// One evaluation in contact (δ > 0).
struct Eval {
    /// Rotated point `u = A s`.
    u: [f64; 2],
    /// Contact-point offset `c = u − R n`.
    c: [f64; 2],
    /// The laws at the contact point.
    engaged: Engaged,
}

impl HalfPlaneContact {
    /// A contact with the normal `normal` normalised (a zero or non-finite
    /// normal is kept as given and rejected by `validate`).
    pub fn new(
        body: usize,
        point: [f64; 2],
        radius: f64,
        wall_point: [f64; 2],
        normal: [f64; 2],
        law: ContactLaw,
    ) -> Self {
        let len = normal[0].hypot(normal[1]);
        let normal = if len.is_finite() && len > 0.0 {
            [normal[0] / len, normal[1] / len]
        } else {
            normal
        };
        Self {
            body,
            point,
            radius,
            wall_point,
            normal,
            law,
            wall_motion: None,
            surface_velocity: [0.0, 0.0],
        }
    }

    /// The same contact with a wall that translates by `(d_x(t), d_y(t))`
    /// \[m\] from `wall_point` (see the type's documentation).
    pub fn with_wall_motion(mut self, dx: TimeFunction, dy: TimeFunction) -> Self {
        self.wall_motion = Some([dx, dy]);
        self
    }

    /// The wall point `a(t)` and its velocity `ȧ(t)`.
    fn wall(&self, t: f64) -> ([f64; 2], [f64; 2]) {
        match &self.wall_motion {
            None => (self.wall_point, self.surface_velocity),
            Some([fx, fy]) => {
                let ([x, vx, _], [y, vy, _]) = (fx.eval(t), fy.eval(t));
                ([self.wall_point[0] + x, self.wall_point[1] + y], [vx, vy])
            }
        }
    }

    /// Tangent `t = J n`.
    fn tangent(&self) -> [f64; 2] {
        [-self.normal[1], self.normal[0]]
    }

    /// Penetration `δ` \[m\] (negative: the gap) with the wall where it is
    /// at t = 0 ([`HalfPlaneContact::penetration_at`] for a moving wall at
    /// another time).
    pub fn penetration(&self, q: &[f64]) -> f64 {
        self.penetration_at(0.0, q)
    }

    /// Penetration `δ` \[m\] at time `t` \[s\] (negative: the gap).
    pub fn penetration_at(&self, t: f64, q: &[f64]) -> f64 {
        let a = self.wall(t).0;
        let p = BodyRef::Body(self.body).point_at(q, self.point);
        let n = self.normal;
        self.radius - (n[0] * (p[0] - a[0]) + n[1] * (p[1] - a[1]))
    }

    /// The state in contact, `None` without penetration.
    fn eval(&self, time: f64, q: &[f64], qd: &[f64]) -> Option<Eval> {
        let delta = self.penetration_at(time, q);
        let ad = self.wall(time).1;
        if delta.is_nan() || delta <= 0.0 {
            return None;
        }
        let o = 3 * self.body;
        let (sn, cs) = q[o + 2].sin_cos();
        let s = self.point;
        let u = [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]];
        let (n, t) = (self.normal, self.tangent());
        let c = [u[0] - self.radius * n[0], u[1] - self.radius * n[1]];
        let w = qd[o + 2];
        // ṗ = ṙ + ω J u; v_c = ṙ + ω J c; both relative to the wall
        let pd = [qd[o] - w * u[1] - ad[0], qd[o + 1] + w * u[0] - ad[1]];
        let vc = [qd[o] - w * c[1] - ad[0], qd[o + 1] + w * c[0] - ad[1]];
        let delta_dot = -(n[0] * pd[0] + n[1] * pd[1]);
        let vt = t[0] * vc[0] + t[1] * vc[1];
        Some(Eval {
            u,
            c,
            engaged: self.law.engage(delta, delta_dot, vt),
        })
    }

    /// `(F_n, F_t, δ)` at time `t` \[s\]: normal force, friction force
    /// along `t = J n` \[N\] and penetration \[m\]; zeros without contact.
    pub fn contact_forces_at(&self, t: f64, q: &[f64], qd: &[f64]) -> (f64, f64, f64) {
        self.eval(t, q, qd).map_or((0.0, 0.0, 0.0), |ev| {
            let e = ev.engaged;
            (e.fn_, self.law.friction_force(e.fn_, e.tanh), e.delta)
        })
    }
}

impl ForceElement for HalfPlaneContact {
    fn geometry(&self) -> crate::model::ForceGeometry {
        if self.wall_motion.is_some() {
            return crate::model::ForceGeometry::Other;
        }
        crate::model::ForceGeometry::Wall {
            body: self.body,
            point: self.point,
            radius: self.radius,
            wall_point: self.wall_point,
            normal: self.normal,
        }
    }

    fn name(&self) -> String {
        format!(
            "half-plane contact of body {} at {:?} (radius {})",
            self.body, self.point, self.radius
        )
    }

    fn coordinates(&self) -> Vec<usize> {
        let o = 3 * self.body;
        vec![o, o + 1, o + 2]
    }

    fn add_forces(&self, time: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let Some(ev) = self.eval(time, q, qd) else {
            return;
        };
        let e = ev.engaged;
        if e.fn_ <= 0.0 {
            return;
        }
        let (n, t) = (self.normal, self.tangent());
        let ff = self.law.friction_force(e.fn_, e.tanh);
        let f = [e.fn_ * n[0] + ff * t[0], e.fn_ * n[1] + ff * t[1]];
        let o = 3 * self.body;
        g[o] += f[0];
        g[o + 1] += f[1];
        g[o + 2] += ev.c[0] * f[1] - ev.c[1] * f[0];
    }

    fn add_jacobians(&self, time: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        let ForceJacobians { dq, dqd, .. } = out;
        let Some(ev) = self.eval(time, q, qd) else {
            return;
        };
        let e = ev.engaged;
        if e.fn_ <= 0.0 {
            return; // clamped: force and derivatives vanish
        }
        let (n, t) = (self.normal, self.tangent());
        let w = qd[3 * self.body + 2];
        let mu = self.law.friction;
        let (a, b) = self.law.slopes(e.delta, e.delta_dot);
        let ff = -mu * e.fn_ * e.tanh;
        let f = [e.fn_ * n[0] + ff * t[0], e.fn_ * n[1] + ff * t[1]];
        let ju = [-ev.u[1], ev.u[0]]; // ∂u/∂φ = ∂c/∂φ = J u
        let jc = [-ev.c[1], ev.c[0]];
        let n_ju = n[0] * ju[0] + n[1] * ju[1];
        let n_u = n[0] * ev.u[0] + n[1] * ev.u[1];
        let t_u = t[0] * ev.u[0] + t[1] * ev.u[1];
        let t_jc = t[0] * jc[0] + t[1] * jc[1];
        // derivatives of δ, δ̇, v_t w.r.t. (x, y, φ) and (ẋ, ẏ, φ̇):
        // δ = R − n·(r + u − a); δ̇ = −n·(ṙ + ω J u) with ∂(J u)/∂φ = −u;
        // v_t = t·(ṙ + ω J c) with ∂(J c)/∂φ = −u.
        let d_delta_q = [-n[0], -n[1], -n_ju];
        let d_ddot_q = [0.0, 0.0, w * n_u];
        let d_vt_q = [0.0, 0.0, -w * t_u];
        let d_ddot_qd = [-n[0], -n[1], -n_ju];
        let d_vt_qd = [t[0], t[1], t_jc];
        for (out, dd, ddd, dvt, is_q) in [
            (&mut *dq, d_delta_q, d_ddot_q, d_vt_q, true),
            (&mut *dqd, [0.0; 3], d_ddot_qd, d_vt_qd, false),
        ] {
            for col in 0..3 {
                let dfn = a * dd[col] + b * ddd[col];
                let dff = -mu * (e.tanh * dfn + e.fn_ * e.dtanh * dvt[col]);
                let df = [dfn * n[0] + dff * t[0], dfn * n[1] + dff * t[1]];
                let mut dm = ev.c[0] * df[1] - ev.c[1] * df[0];
                if is_q && col == 2 {
                    dm += ju[0] * f[1] - ju[1] * f[0];
                }
                out[col] += df[0];
                out[3 + col] += df[1];
                out[6 + col] += dm;
            }
        }
    }

    /// `τ = −δ / |δ̇|` for a gap `δ < 0`, towards the wall or away from it
    /// (relative to a moving wall, with its velocity at `t`; as
    /// [`super::WallContact`]'s corners); `Some(0.0)` in contact (`δ ≥ 0`).
    fn onset_within(&self, t: f64, q: &[f64], qd: &[f64], horizon: f64) -> Option<f64> {
        let delta = self.penetration_at(t, q);
        if delta >= 0.0 {
            return Some(0.0);
        }
        let (o, n) = (3 * self.body, self.normal);
        let ad = self.wall(t).1;
        let (sn, cs) = q[o + 2].sin_cos();
        let s = self.point;
        let u = [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]];
        let w = qd[o + 2];
        let pd = [qd[o] - w * u[1] - ad[0], qd[o + 1] + w * u[0] - ad[1]];
        let delta_dot = -(n[0] * pd[0] + n[1] * pd[1]);
        let tau = -delta / delta_dot.abs();
        (delta_dot != 0.0 && tau <= horizon).then_some(tau)
    }

    fn readings(&self) -> &'static [(&'static str, &'static str)] {
        &[
            ("normal_force", "N"),
            ("friction_force", "N"),
            ("penetration", "m"),
        ]
    }

    /// [`HalfPlaneContact::contact_forces_at`]: `F_n`, `F_t`, and the
    /// penetration `δ` (negative: the gap, also out of contact).
    fn read(&self, t: f64, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let (fn_, ft, _) = self.contact_forces_at(t, q, qd);
        out[0] = fn_;
        out[1] = ft;
        out[2] = self.penetration_at(t, q);
    }

    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        if self.wall_motion.is_some() {
            return None;
        }
        let delta = self.penetration(q);
        Some(if delta > 0.0 {
            self.law.energy(delta)
        } else {
            0.0
        })
    }

    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let name = self.name();
        let check = Check { element: &name };
        check.finite_point("point", self.point)?;
        check.finite_point("wall_point", self.wall_point)?;
        if let Some(m) = &self.wall_motion {
            if !m.iter().all(TimeFunction::is_finite) {
                return Err(check.fail(
                    "wall_motion",
                    format!("{m:?}"),
                    "must have finite parameters",
                ));
            }
        }
        let len = self.normal[0].hypot(self.normal[1]);
        if !(len.is_finite() && (len - 1.0).abs() < 1e-12) {
            return Err(check.fail(
                "normal",
                format!("{:?}", self.normal),
                "must be a unit vector (a finite, non-zero normal given to `new`)",
            ));
        }
        self.law.check(&check)?;
        check.non_negative(&[("radius", self.radius)])?;
        check_coordinates(&name, &self.coordinates(), n_coords)
    }
}
