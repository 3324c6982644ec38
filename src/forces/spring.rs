//! Point-to-point spring–damper–actuator between two body-fixed points (or a
//! body point and a ground point).

use super::{check_coordinates, Check, ForceElement, ForceJacobians, Law};
use crate::model::{BodyPoint, ModelError, TimeFunction};

/// Lengths below this \[m\] have no direction: the element applies no force.
const MIN_LENGTH: f64 = 1e-12;

/// Spring–damper–actuator between the body points `i` and `j`
/// ([`BodyPoint`]: body-frame coordinates, global on the ground).
///
/// With `p = r + A(φ) s` the points, `d = p_j − p_i`, `L = |d|`, `e = d/L`,
/// deflection `δ = L − free_length` and rate `L̇ = e·ḋ`, the tension is
///
/// `F = preload + stiffness(δ) + damping(L̇) + actuator(t)`
///
/// (positive pulls the points together): body j receives `−F e` at `p_j`,
/// body i `+F e` at `p_i`, so the generalized force is `g = −F ∂L/∂q`.
/// Jacobians (analytic): `∂g/∂q = −∂L/∂q (k' ∂L/∂q + c' ∇²L q̇)ᵀ − F ∇²L`,
/// `∂g/∂q̇ = −c' ∂L/∂q ∂L/∂qᵀ`, with `k'`, `c'` the law slopes and
/// `∇²L = Dᵀ(I − e eᵀ)D / L + Σ_k e_k ∂²d_k/∂q²` (`D = ∂d/∂q`).
///
/// Potential energy (elastic part and preload; the actuator is a drive whose
/// work is accounted separately): `V = ∫₀^δ stiffness + preload · L`.
///
/// Zero length: for `L < 1e-12 m` the direction `e` is undefined; the element
/// then applies no force and no Jacobian (with `free_length = 0` and a
/// linear law the force `k L` tends to 0 there anyway; with `free_length > 0`
/// such a configuration is singular and should be avoided by the model).
#[derive(Debug, Clone)]
pub struct PointSpringDamper {
    /// The point on the first body (which receives `+F e`); may be on the
    /// ground.
    pub i: BodyPoint,
    /// The point on the second body (which receives `−F e`); may be on the
    /// ground.
    pub j: BodyPoint,
    /// Free length \[m\], ≥ 0.
    pub free_length: f64,
    /// Tension as a function of the deflection `δ` \[N\]; non-decreasing.
    pub stiffness: Law,
    /// Tension as a function of the rate `L̇` \[N\]; non-decreasing (dissipates).
    pub damping: Law,
    /// Constant tension \[N\].
    pub preload: f64,
    /// Actuator tension as a function of time \[N\].
    pub actuator: Option<TimeFunction>,
}

/// Geometry of one evaluation: length, direction, `∂L/∂q` and `∇²L`
/// over the local coordinates (3 per non-ground body, sorted by body).
struct Kin {
    len: f64,
    rate: f64,
    grad: [f64; 6],
    hess: [[f64; 6]; 6],
    n: usize,
}

impl PointSpringDamper {
    /// A linear spring (stiffness `k` \[N/m\]) and damper (`c` \[N s/m\]).
    pub fn linear(i: BodyPoint, j: BodyPoint, free_length: f64, k: f64, c: f64) -> Self {
        Self {
            i,
            j,
            free_length,
            stiffness: Law::Linear(k),
            damping: Law::Linear(c),
            preload: 0.0,
            actuator: None,
        }
    }

    /// Non-ground sides in coordinate order: `(offset, sign σ, point)` with
    /// `σ = −1` for body i and `+1` for body j (`d = Σ σ p`).
    fn sides(&self) -> ([(usize, f64, [f64; 2]); 2], usize) {
        let mut out = [(0, 0.0, [0.0; 2]); 2];
        let mut n = 0;
        for (b, s, p) in [
            (self.i.body, -1.0, self.i.point),
            (self.j.body, 1.0, self.j.point),
        ] {
            if let Some(o) = b.offset() {
                out[n] = (o, s, p);
                n += 1;
            }
        }
        if n == 2 && out[0].0 > out[1].0 {
            out.swap(0, 1);
        }
        (out, n)
    }

    /// Current length `L` of the element.
    pub fn length(&self, q: &[f64]) -> f64 {
        let (pi, pj) = (self.i.at(q), self.j.at(q));
        (pj[0] - pi[0]).hypot(pj[1] - pi[1])
    }

    /// Length, rate and derivatives; `None` below [`MIN_LENGTH`].
    fn kin(&self, q: &[f64], qd: &[f64]) -> Option<Kin> {
        let (pi, pj) = (self.i.at(q), self.j.at(q));
        let d = [pj[0] - pi[0], pj[1] - pi[1]];
        let len = d[0].hypot(d[1]);
        if len.is_nan() || len < MIN_LENGTH {
            return None;
        }
        let e = [d[0] / len, d[1] / len];
        let (sides, nb) = self.sides();
        let n = 3 * nb;
        // D = ∂d/∂q (2 × n), and e·∂²d/∂φ² per side
        let mut dmat = [[0.0; 6]; 2];
        let mut curv = [0.0; 2];
        for (k, &(o, sg, s)) in sides.iter().take(nb).enumerate() {
            let (sn, cs) = q[o + 2].sin_cos();
            let a_s = [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]];
            let b_s = [-a_s[1], a_s[0]]; // ∂(A s)/∂φ
            dmat[0][3 * k] = sg;
            dmat[1][3 * k + 1] = sg;
            dmat[0][3 * k + 2] = sg * b_s[0];
            dmat[1][3 * k + 2] = sg * b_s[1];
            // ∂²(A s)/∂φ² = −A s
            curv[k] = -sg * (e[0] * a_s[0] + e[1] * a_s[1]);
        }
        let mut grad = [0.0; 6];
        for c in 0..n {
            grad[c] = e[0] * dmat[0][c] + e[1] * dmat[1][c];
        }
        let mut rate = 0.0;
        for (k, &(o, _, _)) in sides.iter().take(nb).enumerate() {
            for m in 0..3 {
                rate += grad[3 * k + m] * qd[o + m];
            }
        }
        // (I − e eᵀ)/L = n nᵀ / L with n = perp(e)
        let nv = [-e[1], e[0]];
        let mut hess = [[0.0; 6]; 6];
        let mut nd = [0.0; 6];
        for c in 0..n {
            nd[c] = nv[0] * dmat[0][c] + nv[1] * dmat[1][c];
        }
        for r in 0..n {
            for c in 0..n {
                hess[r][c] = nd[r] * nd[c] / len;
            }
        }
        for (k, cv) in curv.iter().take(nb).enumerate() {
            hess[3 * k + 2][3 * k + 2] += cv;
        }
        Some(Kin {
            len,
            rate,
            grad,
            hess,
            n,
        })
    }

    /// Tension `F` at length `len`, rate `rate`, time `t`.
    fn tension(&self, t: f64, len: f64, rate: f64) -> f64 {
        let act = self.actuator.as_ref().map_or(0.0, |a| a.eval(t)[0]);
        self.preload + self.stiffness.value(len - self.free_length) + self.damping.value(rate) + act
    }

    /// Tension `F` \[N\] (positive pulls the points together); 0 below the
    /// minimum length.
    pub fn force(&self, t: f64, q: &[f64], qd: &[f64]) -> f64 {
        self.kin(q, qd)
            .map_or(0.0, |k| self.tension(t, k.len, k.rate))
    }
}

impl ForceElement for PointSpringDamper {
    fn geometry(&self) -> crate::model::ForceGeometry {
        let nonzero = |l: &Law| match l {
            Law::Linear(k) => *k != 0.0,
            Law::Table { f, .. } => f.iter().any(|v| *v != 0.0),
        };
        crate::model::ForceGeometry::PointToPoint {
            i: self.i,
            j: self.j,
            free_length: self.free_length,
            spring: nonzero(&self.stiffness),
            damper: nonzero(&self.damping),
        }
    }

    fn name(&self) -> String {
        format!(
            "point spring-damper {:?} {:?} - {:?} {:?}",
            self.i.body, self.i.point, self.j.body, self.j.point
        )
    }

    fn coordinates(&self) -> Vec<usize> {
        let (sides, nb) = self.sides();
        sides[..nb]
            .iter()
            .flat_map(|&(o, _, _)| [o, o + 1, o + 2])
            .collect()
    }

    fn add_forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) {
        let Some(k) = self.kin(q, qd) else { return };
        let f = self.tension(t, k.len, k.rate);
        let (sides, nb) = self.sides();
        for (s, &(o, _, _)) in sides.iter().take(nb).enumerate() {
            for m in 0..3 {
                g[o + m] -= f * k.grad[3 * s + m];
            }
        }
    }

    fn add_jacobians(&self, t: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        let ForceJacobians { dq, dqd, .. } = out;
        let Some(k) = self.kin(q, qd) else { return };
        let f = self.tension(t, k.len, k.rate);
        let ks = self.stiffness.slope(k.len - self.free_length);
        let cs = self.damping.slope(k.rate);
        let (sides, nb) = self.sides();
        let n = k.n;
        // local q̇
        let mut v = [0.0; 6];
        for (s, &(o, _, _)) in sides.iter().take(nb).enumerate() {
            for m in 0..3 {
                v[3 * s + m] = qd[o + m];
            }
        }
        // ∂F/∂q = k' ∇L + c' ∇²L q̇
        let mut df = [0.0; 6];
        for (c, dfc) in df.iter_mut().enumerate().take(n) {
            let hv: f64 = (0..n).map(|m| k.hess[c][m] * v[m]).sum();
            *dfc = ks * k.grad[c] + cs * hv;
        }
        for r in 0..n {
            for c in 0..n {
                dq[r * n + c] -= k.grad[r] * df[c] + f * k.hess[r][c];
                dqd[r * n + c] -= cs * k.grad[r] * k.grad[c];
            }
        }
    }

    fn readings(&self) -> &'static [(&'static str, &'static str)] {
        &[
            ("force", "N"),
            ("length", "m"),
            ("deflection", "m"),
            ("rate", "m/s"),
        ]
    }

    /// Tension `F` (0 below the minimum length), length `L`, deflection
    /// `L − L₀`, rate `L̇`.
    fn read(&self, t: f64, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let (len, rate) = self
            .kin(q, qd)
            .map_or((self.length(q), 0.0), |k| (k.len, k.rate));
        out[0] = self.force(t, q, qd);
        out[1] = len;
        out[2] = len - self.free_length;
        out[3] = rate;
    }

    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        let len = self.length(q);
        Some(self.stiffness.integral(len - self.free_length) + self.preload * len)
    }

    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        let name = self.name();
        let check = Check { element: &name };
        check.two_bodies(self.i.body, self.j.body)?;
        check.finite_point("point_i", self.i.point)?;
        check.finite_point("point_j", self.j.point)?;
        check.sign("free_length", self.free_length, false)?;
        check.finite("preload", self.preload)?;
        self.stiffness.validate(&name, "stiffness", true)?;
        self.damping.validate(&name, "damping", true)?;
        check_coordinates(&name, &self.coordinates(), n_coords)
    }
}
