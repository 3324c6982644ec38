//! Quadratic fluid drag on a rod segment (docs/problems.md, problem B).

use super::{check_coordinates, Check, ForceElement, ForceJacobians};
use crate::model::ModelError;

/// Quadratic drag of still fluid on one rod segment (docs/problems.md, problem B, "drag").
///
/// With `v` the velocity of the segment's centre, `e_a = (−sin φ, cos φ)` the
/// rod axis and `e_t = (cos φ, sin φ)` the transverse direction,
/// `v_a = v·e_a`, `v_t = v·e_t`:
///
/// * transverse: `F_t = −½ ρ_w C_t (w l_s) |v_t| v_t` along `e_t`;
/// * axial skin friction: `F_a = −½ ρ_w C_f (4 w l_s) |v_a| v_a` along `e_a`;
/// * end face (only with `end_face`, the bottom segment):
///   `−½ ρ_w C_e w² |v_a| v_a` along `e_a`;
/// * rotation: torque `−ρ_w C_t w l_s⁴ |φ̇| φ̇ / 64`.
///
/// The forces act at the centre. Jacobians are analytic
/// (`d(|u|u)/du = 2|u|`). The element only dissipates: `g·q̇ ≤ 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct Drag {
    /// Body index of the segment.
    pub body: usize,
    /// Width w of the square cross-section \[m\].
    pub width: f64,
    /// Segment length l_s \[m\].
    pub length: f64,
    /// Fluid density ρ_w \[kg/m³\].
    pub fluid_density: f64,
    /// Transverse (and rotational) drag coefficient C_t (1.2 in problem B).
    pub c_transverse: f64,
    /// Axial skin-friction coefficient C_f (0.02), on the wetted side area `4 w l_s`.
    pub c_skin: f64,
    /// End-face drag coefficient C_e (1.0), on the area `w²`; used only with `end_face`.
    pub c_end: f64,
    /// Whether the segment carries the end-face drag (the bottom segment in problem B).
    pub end_face: bool,
}

impl Drag {
    /// `(a_t, a_a, a_r)`: `F_t = a_t |v_t| v_t`, `F_a = a_a |v_a| v_a`, `T = a_r |φ̇| φ̇`.
    pub(crate) fn coefficients(&self) -> (f64, f64, f64) {
        let (rho, w, l) = (self.fluid_density, self.width, self.length);
        let at = -0.5 * rho * self.c_transverse * w * l;
        let end = if self.end_face {
            self.c_end * w * w
        } else {
            0.0
        };
        let aa = -0.5 * rho * (self.c_skin * 4.0 * w * l + end);
        let ar = -rho * self.c_transverse * w * l.powi(4) / 64.0;
        (at, aa, ar)
    }

    /// The generalized force `[F_x, F_y, T]` on the segment for its
    /// angle `phi` and velocity `v = [ẋ, ẏ, φ̇]`.
    pub fn force(&self, phi: f64, v: [f64; 3]) -> [f64; 3] {
        // the generated kernels' sine and cosine (one reduction for both,
        // the bits of `DragJacobians::add_forces`' four-lane ones)
        let (sn, cs) = crate::trig::sin_cos(phi);
        drag_force(self.coefficients(), sn, cs, v)
    }
}

/// The drag's generalized force `[F_x, F_y, T]` from the coefficients
/// `(a_t, a_a, a_r)` ([`Drag`]), the segment's `sin φ`, `cos φ` and velocity
/// `v = [ẋ, ẏ, φ̇]`: the one formula of `Drag::force` and of the generated
/// loop `DragJacobians::add_forces`.
#[inline(always)]
pub(crate) fn drag_force(a: (f64, f64, f64), sn: f64, cs: f64, v: [f64; 3]) -> [f64; 3] {
    let (at, aa, ar) = a;
    let vt = v[0] * cs + v[1] * sn;
    let va = -v[0] * sn + v[1] * cs;
    let ft = at * vt.abs() * vt;
    let fa = aa * va.abs() * va;
    [ft * cs - fa * sn, ft * sn + fa * cs, ar * v[2].abs() * v[2]]
}

impl ForceElement for Drag {
    fn name(&self) -> String {
        format!("drag on body {}", self.body)
    }

    fn coordinates(&self) -> Vec<usize> {
        let o = 3 * self.body;
        vec![o, o + 1, o + 2]
    }

    fn add_forces(&self, _t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let o = 3 * self.body;
        let f = self.force(q[o + 2], [qd[o], qd[o + 1], qd[o + 2]]);
        g[o] += f[0];
        g[o + 1] += f[1];
        g[o + 2] += f[2];
    }

    fn add_jacobians(&self, _t: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        let ForceJacobians { dq, dqd, .. } = out;
        let o = 3 * self.body;
        let (at, aa, ar) = self.coefficients();
        let (sn, cs) = crate::trig::sin_cos(q[o + 2]);
        let (vx, vy, w) = (qd[o], qd[o + 1], qd[o + 2]);
        let vt = vx * cs + vy * sn;
        let va = -vx * sn + vy * cs;
        let (et, ea) = ([cs, sn], [-sn, cs]);
        // F = a_t |v_t| v_t e_t + a_a |v_a| v_a e_a with ∂v_t/∂φ = v_a,
        // ∂v_a/∂φ = −v_t, ∂e_t/∂φ = e_a, ∂e_a/∂φ = −e_t.
        let ft = at * vt.abs() * vt;
        let fa = aa * va.abs() * va;
        let dft = 2.0 * at * vt.abs(); // ∂F_t/∂v_t
        let dfa = 2.0 * aa * va.abs(); // ∂F_a/∂v_a
        for r in 0..2 {
            // column φ of ∂g/∂q
            dq[r * 3 + 2] += dft * va * et[r] + ft * ea[r] - dfa * vt * ea[r] - fa * et[r];
            // columns ẋ, ẏ of ∂g/∂q̇: ∂v_t/∂v = e_t, ∂v_a/∂v = e_a
            for c in 0..2 {
                dqd[r * 3 + c] += dft * et[c] * et[r] + dfa * ea[c] * ea[r];
            }
        }
        dqd[2 * 3 + 2] += 2.0 * ar * w.abs();
    }

    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let name = self.name();
        let check = Check { element: &name };
        check.positive(&[("width", self.width), ("length", self.length)])?;
        check.non_negative(&[("fluid_density", self.fluid_density)])?;
        check.non_negative(&[("c_transverse", self.c_transverse), ("c_skin", self.c_skin)])?;
        check.non_negative(&[("c_end", self.c_end)])?;
        check_coordinates(&name, &self.coordinates(), n_coords)
    }
}
