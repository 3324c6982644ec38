//! Contact of a rod segment's corners with the two channel walls (docs/problems.md, problem B).

use super::{check_coordinates, Check, ForceElement, ForceJacobians};
use crate::model::ModelError;

/// One of the two vertical channel walls.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Wall {
    /// The wall at `x = left_wall` (pushes bodies towards +x).
    Left,
    /// The wall at `x = right_wall` (pushes bodies towards −x).
    Right,
}

/// A segment corner in contact with a wall (penetration δ > 0), as reported
/// by [`WallContact::corner_states`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornerState {
    /// Body index of the segment.
    pub body: usize,
    /// Segment label of the element ([`WallContact::segment`]; the rod
    /// builder numbers segments 0, 1, … from the bottom).
    pub segment: usize,
    /// Corner index 0..4, see [`WallContact::corner_offset`].
    pub corner: usize,
    /// The wall touched.
    pub wall: Wall,
    /// Global position of the corner \[m\].
    pub position: [f64; 2],
    /// Penetration δ > 0 \[m\].
    pub penetration: f64,
    /// Penetration rate δ̇ \[m/s\] (positive while approaching the wall).
    pub penetration_rate: f64,
    /// Normal force `max(0, k_h δ^{3/2} (1 + χ δ̇))` \[N\] (0 while the
    /// corner separates faster than `1/χ`).
    pub normal_force: f64,
    /// Friction force along the wall (y component) \[N\].
    pub friction_force: f64,
}

/// Penalty contact of the four corners of one rectangular rod segment with
/// two vertical walls `x = left_wall` and `x = right_wall` (docs/problems.md, problem B,
/// "contact").
///
/// Corner `c` sits at the body-fixed point [`WallContact::corner_offset`]
/// `(±w/2, ±l_s/2)`. A corner at global `p` with velocity `ṗ` penetrates the
/// left wall by `δ = left_wall − p_x` and the right wall by
/// `δ = p_x − right_wall`. For `δ > 0` the wall pushes it back with the
/// Hunt–Crossley normal force `F_n = k_h δ^{3/2} (1 + χ δ̇)`, clamped at
/// `F_n ≥ 0`, and friction `−μ F_n tanh(ṗ_y / v_s)` along the wall; both act
/// at the corner, so they also produce a torque on the segment.
///
/// Jacobians are analytic. Potential energy: the elastic part
/// `Σ (2/5) k_h δ^{5/2}` (damping and friction only dissipate).
#[derive(Debug, Clone, PartialEq)]
pub struct WallContact {
    /// Body index of the segment.
    pub body: usize,
    /// Label reported in [`CornerState::segment`].
    pub segment: usize,
    /// Segment width w \[m\].
    pub width: f64,
    /// Segment length l_s \[m\].
    pub length: f64,
    /// x of the left wall \[m\] (−d/2 in problem B).
    pub left_wall: f64,
    /// x of the right wall \[m\] (+d/2 in problem B).
    pub right_wall: f64,
    /// The contact laws (problem B: k_h = 1e9 N/m^{3/2}, χ = 0.75 s/m,
    /// μ = 0.3, v_s = 1e-3 m/s).
    pub law: ContactLaw,
}

/// The laws of a penalty contact (docs/problems.md, problem B, "contact"),
/// one piece of code for [`WallContact`] and [`super::HalfPlaneContact`]:
/// the Hunt–Crossley normal force `F_n = max(0, k_h δ^{3/2} (1 + χ δ̇))` for
/// penetration `δ > 0` and its rate `δ̇` (positive while approaching), with
/// the elastic potential `(2/5) k_h δ^{5/2}`, and regularised Coulomb
/// friction `−μ F_n tanh(v / v_s)` for slip velocity `v`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactLaw {
    /// Hertz stiffness k_h > 0 \[N/m^{3/2}\].
    pub stiffness: f64,
    /// Hunt–Crossley damping factor χ ≥ 0 \[s/m\].
    pub damping: f64,
    /// Friction coefficient μ ≥ 0.
    pub friction: f64,
    /// Regularisation velocity v_s > 0 of the friction law \[m/s\].
    pub slip_velocity: f64,
}

impl ContactLaw {
    /// `F_n(δ, δ̇)` (clamped at 0), for `δ > 0`.
    #[inline]
    pub(crate) fn force(&self, delta: f64, delta_dot: f64) -> f64 {
        (self.stiffness * delta * delta.sqrt() * (1.0 + self.damping * delta_dot)).max(0.0)
    }

    /// `(∂F_n/∂δ, ∂F_n/∂δ̇)` of the unclamped law, for `δ > 0`.
    #[inline]
    pub(crate) fn slopes(&self, delta: f64, delta_dot: f64) -> (f64, f64) {
        let sq = delta.sqrt();
        (
            1.5 * self.stiffness * sq * (1.0 + self.damping * delta_dot),
            self.stiffness * delta * sq * self.damping,
        )
    }

    /// Elastic potential `(2/5) k_h δ^{5/2}`, for `δ > 0`.
    #[inline]
    pub(crate) fn energy(&self, delta: f64) -> f64 {
        0.4 * self.stiffness * delta * delta * delta.sqrt()
    }

    /// `(tanh(v/v_s), d tanh(v/v_s)/dv)` of the friction law at slip
    /// velocity `v`.
    #[inline]
    pub(crate) fn friction_tanh(&self, v: f64) -> (f64, f64) {
        let th = (v / self.slip_velocity).tanh();
        (th, (1.0 - th * th) / self.slip_velocity)
    }

    /// The laws at a point in contact: penetration `delta` > 0 \[m\], its
    /// rate `delta_dot` \[m/s\], slip velocity `v` \[m/s\].
    #[inline]
    pub(crate) fn engage(&self, delta: f64, delta_dot: f64, v: f64) -> Engaged {
        let (tanh, dtanh) = self.friction_tanh(v);
        Engaged {
            delta,
            delta_dot,
            fn_: self.force(delta, delta_dot),
            tanh,
            dtanh,
        }
    }

    /// The friction force `−μ F_n tanh` for the normal force `fn_`.
    #[inline]
    pub(crate) fn friction_force(&self, fn_: f64, tanh: f64) -> f64 {
        -self.friction * fn_ * tanh
    }

    /// The checks of an element's `validate`: `stiffness` and
    /// `slip_velocity` positive, `damping` and `friction` non-negative.
    pub(crate) fn check(&self, check: &Check) -> Result<(), ModelError> {
        check.positive(&[("stiffness", self.stiffness)])?;
        check.positive(&[("slip_velocity", self.slip_velocity)])?;
        check.non_negative(&[("damping", self.damping), ("friction", self.friction)])
    }
}

/// The contact laws at one point in contact ([`ContactLaw::engage`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Engaged {
    /// Penetration δ > 0 \[m\].
    pub(crate) delta: f64,
    /// Its rate δ̇ \[m/s\].
    pub(crate) delta_dot: f64,
    /// Normal force F_n ≥ 0 \[N\].
    pub(crate) fn_: f64,
    /// `tanh(v/v_s)` of the slip velocity v.
    pub(crate) tanh: f64,
    /// Its derivative `d tanh(v/v_s)/dv` \[s/m\].
    pub(crate) dtanh: f64,
}

/// Per-corner contact evaluation against one wall.
struct CornerEval {
    wall: Wall,
    /// +1 for the left wall (force along +x), −1 for the right.
    sigma: f64,
    /// Rotated corner offset R(φ) s.
    rs: [f64; 2],
    pos: [f64; 2],
    /// The laws at the corner.
    engaged: Engaged,
}

impl WallContact {
    /// Body-fixed position of corner `c` (0..4): 0 = (−w/2, −l_s/2),
    /// 1 = (+w/2, −l_s/2), 2 = (+w/2, +l_s/2), 3 = (−w/2, +l_s/2)
    /// (counter-clockwise from bottom left at φ = 0). Panics for `c >= 4`.
    pub fn corner_offset(&self, c: usize) -> [f64; 2] {
        const SIGNS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
        [
            SIGNS[c][0] * 0.5 * self.width,
            SIGNS[c][1] * 0.5 * self.length,
        ]
    }

    /// Whether no corner of a segment centred at `x` can reach either wall,
    /// whatever its angle: every corner lies within `|R(φ) s|_x ≤ w/2 + l_s/2`
    /// of the centre (the bound widened by 1e-12 relative against rounding,
    /// so a corner this test clears has δ ≤ 0 exactly as computed below).
    /// Skips the sine, cosine and corner loop for the segments away from the
    /// walls, which are most of a long rod's.
    #[inline]
    pub(crate) fn clear_of_walls(&self, x: f64) -> bool {
        self.clearance().clear(x)
    }

    /// What [`Self::clear_of_walls`] reads, in 24 bytes (for loops over
    /// many segments that should not stream the whole elements).
    pub(crate) fn clearance(&self) -> Clearance {
        Clearance {
            reach: 0.5 * (self.width + self.length) * (1.0 + 1e-12),
            left: self.left_wall,
            right: self.right_wall,
        }
    }

    /// The body's three entries of a full coordinate or velocity vector.
    fn body_q(&self, v: &[f64]) -> [f64; 3] {
        let o = 3 * self.body;
        [v[o], v[o + 1], v[o + 2]]
    }

    /// Calls `f` for every (corner, wall) pair with δ > 0.
    /// `qb`, `vb`: the body's `[x, y, φ]` and `[ẋ, ẏ, φ̇]`.
    fn for_each_contact(&self, qb: [f64; 3], vb: [f64; 3], mut f: impl FnMut(usize, &CornerEval)) {
        if self.clear_of_walls(qb[0]) {
            return;
        }
        let (sn, cs) = qb[2].sin_cos();
        let w = vb[2];
        for c in 0..4 {
            let s = self.corner_offset(c);
            let rs = [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]];
            let pos = [qb[0] + rs[0], qb[1] + rs[1]];
            let vel = [vb[0] - w * rs[1], vb[1] + w * rs[0]];
            for (wall, sigma, xw) in [
                (Wall::Left, 1.0, self.left_wall),
                (Wall::Right, -1.0, self.right_wall),
            ] {
                let delta = sigma * (xw - pos[0]);
                if delta <= 0.0 {
                    continue;
                }
                let engaged = self.law.engage(delta, -sigma * vel[0], vel[1]);
                f(
                    c,
                    &CornerEval {
                        wall,
                        sigma,
                        rs,
                        pos,
                        engaged,
                    },
                );
            }
        }
    }

    /// Append to `out` the state of every corner that penetrates a wall
    /// (δ > 0), in corner order. `out` is not cleared. `q`, `qd` are the
    /// full coordinate and velocity vectors.
    pub fn corner_states(&self, q: &[f64], qd: &[f64], out: &mut Vec<CornerState>) {
        self.for_each_contact(self.body_q(q), self.body_q(qd), |c, ce| {
            let e = ce.engaged;
            out.push(CornerState {
                body: self.body,
                segment: self.segment,
                corner: c,
                wall: ce.wall,
                position: ce.pos,
                penetration: e.delta,
                penetration_rate: e.delta_dot,
                normal_force: e.fn_,
                friction_force: self.law.friction_force(e.fn_, e.tanh),
            })
        });
    }
}

/// A segment's reach (half its width plus half its length, widened by
/// 1e-12 relative) and the two walls: [`WallContact::clear_of_walls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Clearance {
    reach: f64,
    left: f64,
    right: f64,
}

impl Clearance {
    /// Whether no corner of a segment centred at `x` can reach either wall.
    #[inline]
    pub(crate) fn clear(&self, x: f64) -> bool {
        x - self.reach > self.left && x + self.reach < self.right
    }
}

impl ForceElement for WallContact {
    fn name(&self) -> String {
        format!("wall contact of body {}", self.body)
    }

    fn coordinates(&self) -> Vec<usize> {
        let o = 3 * self.body;
        vec![o, o + 1, o + 2]
    }

    fn add_forces(&self, _t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let o = 3 * self.body;
        self.for_each_contact(self.body_q(q), self.body_q(qd), |_, ce| {
            let e = ce.engaged;
            if e.fn_ > 0.0 {
                let fx = ce.sigma * e.fn_;
                let fy = self.law.friction_force(e.fn_, e.tanh);
                g[o] += fx;
                g[o + 1] += fy;
                g[o + 2] += ce.rs[0] * fy - ce.rs[1] * fx;
            }
        });
    }

    fn add_jacobians(&self, _t: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        let ForceJacobians { dq, dqd, .. } = out;
        let w = qd[3 * self.body + 2];
        let (mu, law) = (self.law.friction, self.law);
        self.for_each_contact(self.body_q(q), self.body_q(qd), |_, ce| {
            let e = ce.engaged;
            if e.fn_ <= 0.0 {
                return; // clamped: force and derivatives vanish
            }
            let (sg, rs) = (ce.sigma, ce.rs);
            // Derivatives w.r.t. (x, y, φ) and (ẋ, ẏ, φ̇).
            // p = r + R s: ∂p_x/∂q = (1, 0, −rs_y); ṗ = ṙ + φ̇ J R s:
            // ∂ṗ_x/∂φ = −φ̇ rs_x, ∂ṗ_y/∂φ = −φ̇ rs_y, ∂ṗ/∂q̇ = (I, J R s).
            let d_delta_q = [-sg, 0.0, sg * rs[1]];
            let d_ddelta_q = [0.0, 0.0, sg * w * rs[0]];
            let d_ddelta_qd = [-sg, 0.0, sg * rs[1]];
            let d_vy_q = [0.0, 0.0, -w * rs[1]];
            let d_vy_qd = [0.0, 1.0, rs[0]];
            let (a, b) = law.slopes(e.delta, e.delta_dot); // ∂F_n/∂δ, ∂F_n/∂δ̇
            let fx = sg * e.fn_;
            let fy = -mu * e.fn_ * e.tanh;
            for (out, dd, ddd, dvy, is_q) in [
                (&mut *dq, d_delta_q, d_ddelta_q, d_vy_q, true),
                (&mut *dqd, [0.0; 3], d_ddelta_qd, d_vy_qd, false),
            ] {
                for c in 0..3 {
                    let dfn = a * dd[c] + b * ddd[c];
                    let dfx = sg * dfn;
                    let dfy = -mu * (e.tanh * dfn + e.fn_ * e.dtanh * dvy[c]);
                    let mut dt = rs[0] * dfy - rs[1] * dfx;
                    if is_q && c == 2 {
                        // ∂(R s)/∂φ = J R s = (−rs_y, rs_x)
                        dt += -rs[1] * fy - rs[0] * fx;
                    }
                    out[c] += dfx;
                    out[3 + c] += dfy;
                    out[6 + c] += dt;
                }
            }
        });
    }

    /// The first corner that could reach a wall within `horizon` at its
    /// current speed across the wall, `τ = −δ / |δ̇|` for a gap `δ < 0`,
    /// towards the wall or away from it (a corner leaving a wall may come
    /// back within a flight step as the rod bends; the two rules compared
    /// in docs/scaling.md, "The falling rod with a flight step");
    /// `Some(0.0)` while a corner penetrates (`δ ≥ 0`). A segment whose
    /// corners cannot travel to a wall, at most `(|ẋ| + |φ̇| r) horizon` with
    /// `r` the reach of the segment (half its width plus half its length),
    /// is cleared first.
    fn onset_within(&self, _t: f64, q: &[f64], qd: &[f64], horizon: f64) -> Option<f64> {
        let (qb, vb) = (self.body_q(q), self.body_q(qd));
        let c = self.clearance();
        let travel = (vb[0].abs() + vb[2].abs() * c.reach) * horizon;
        if qb[0] - c.reach - travel > c.left && qb[0] + c.reach + travel < c.right {
            return None;
        }
        let (sn, cs) = qb[2].sin_cos();
        let mut first: Option<f64> = None;
        for k in 0..4 {
            let s = self.corner_offset(k);
            let rs = [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]];
            let (x, vx) = (qb[0] + rs[0], vb[0] - vb[2] * rs[1]);
            for (sigma, xw) in [(1.0, self.left_wall), (-1.0, self.right_wall)] {
                let (delta, delta_dot) = (sigma * (xw - x), -sigma * vx);
                let tau = if delta >= 0.0 {
                    0.0
                } else if delta_dot != 0.0 {
                    -delta / delta_dot.abs()
                } else {
                    continue;
                };
                if tau <= horizon && first.is_none_or(|f| tau < f) {
                    first = Some(tau);
                }
            }
        }
        first
    }

    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        let mut e = 0.0;
        self.for_each_contact(self.body_q(q), [0.0; 3], |_, c| {
            e += self.law.energy(c.engaged.delta);
        });
        Some(e)
    }

    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let name = self.name();
        let check = Check { element: &name };
        check.positive(&[("width", self.width), ("length", self.length)])?;
        self.law.check(&check)?;
        check.finite("left_wall", self.left_wall)?;
        check.finite("right_wall", self.right_wall)?;
        if self.right_wall - self.left_wall <= self.width {
            return Err(check.fail(
                "right_wall",
                self.right_wall.to_string(),
                "the gap between the walls must exceed the segment width",
            ));
        }
        check_coordinates(&name, &self.coordinates(), n_coords)
    }
}
