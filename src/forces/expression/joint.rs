//! Joint loads: a torque or a force between the two bodies of a joint, given
//! as an expression that may read the joint's own coordinate (relative angle
//! and rate, or slide and speed) besides t and the named bodies' coordinates.
//! The terms go into the same symbolic g as the other expression terms, so
//! their Jacobians are exact symbolic derivatives.

use super::{ExpressionError, ExpressionLoadBuilder, LinePoint};
use mbsolve_codegen::Id;

impl ExpressionLoadBuilder {
    /// φ of a side (`None`: the ground, angle 0) and its rate.
    fn side_angle(&mut self, body: Option<&str>) -> Result<(Id, Id), ExpressionError> {
        match body {
            None => {
                let z = self.ctx.zero();
                Ok((z, z))
            }
            Some(b) => {
                let k = self.local(b)?;
                Ok((self.q[3 * k + 2], self.qd[3 * k + 2]))
            }
        }
    }

    /// A torque \[N m\] between the two bodies of a revolute joint:
    /// `+τ` on `body_j`, `−τ` on `body_i` (`None`: the ground, which takes
    /// nothing). The expression may use `angle` = φ_j − φ_i \[rad\] and
    /// `rate` = ω_j − ω_i \[rad/s\]; a positive τ drives `angle` up.
    pub fn joint_torque(
        mut self,
        body_i: Option<&str>,
        body_j: Option<&str>,
        torque: &str,
    ) -> Result<Self, ExpressionError> {
        let (pi, wi) = self.side_angle(body_i)?;
        let (pj, wj) = self.side_angle(body_j)?;
        let angle = self.ctx.sub(pj, pi);
        let rate = self.ctx.sub(wj, wi);
        let m = self.parse("torque", torque, &[("angle", angle), ("rate", rate)])?;
        if let Some(b) = body_j {
            let k = self.local(b)?;
            self.g[3 * k + 2] = self.ctx.add(self.g[3 * k + 2], m);
        }
        if let Some(b) = body_i {
            let k = self.local(b)?;
            self.g[3 * k + 2] = self.ctx.sub(self.g[3 * k + 2], m);
        }
        Ok(self)
    }

    /// A force \[N\] along the axis of a translational joint: `+f u` on
    /// `j` at its sliding point `p_j`, `−f u` on `i` at the same global
    /// point (so the pair has no net moment), where `u = R(φ_i) axis_i`
    /// (unit) is the axis in the global frame. The expression may use
    /// `slide` = u · (p_j − p_i) \[m\] (the distance of `p_j` from the
    /// axis point `p_i` along the axis) and `speed` = its time derivative
    /// \[m/s\]; a positive f drives `slide` up. `axis_i` is in body i's
    /// frame (global on the ground); a zero or non-finite axis is an error.
    pub fn joint_force(
        mut self,
        i: &LinePoint,
        axis_i: [f64; 2],
        j: &LinePoint,
        force: &str,
    ) -> Result<Self, ExpressionError> {
        let len = axis_i[0].hypot(axis_i[1]);
        if !len.is_finite() || len <= 0.0 {
            return Err(ExpressionError::BadPoint {
                load: self.name.clone(),
                point: axis_i,
            });
        }
        let (pa, _, ka) = self.point(i)?;
        let (pb, _, kb) = self.point(j)?;
        let (phi, _) = self.side_angle(i.body.as_deref())?;
        let c = &mut self.ctx;
        let (ax, ay) = (c.constant(axis_i[0] / len), c.constant(axis_i[1] / len));
        let (co, si) = (c.cos(phi), c.sin(phi));
        let (a, b) = (c.mul(co, ax), c.mul(si, ay));
        let ux = c.sub(a, b);
        let (a, b) = (c.mul(si, ax), c.mul(co, ay));
        let uy = c.add(a, b);
        let dx = c.sub(pb[0], pa[0]);
        let dy = c.sub(pb[1], pa[1]);
        let (a, b) = (c.mul(ux, dx), c.mul(uy, dy));
        let slide = c.add(a, b);
        // speed = Σ ∂slide/∂q_k q̇_k (the chain rule over every coordinate read)
        let mut terms = Vec::with_capacity(self.q.len());
        for (&v, &vd) in self.q.iter().zip(&self.qd) {
            let d = self.ctx.diff(slide, v);
            terms.push(self.ctx.mul(d, vd));
        }
        let speed = self.ctx.sum(&terms);
        let f = self.parse("force", force, &[("slide", slide), ("speed", speed)])?;
        self.add_force_pair(f, [ux, uy], (kb, pb), (ka, pb));
        Ok(self)
    }
}
