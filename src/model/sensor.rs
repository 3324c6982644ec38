//! Named sensors: quantities an engineer reads off the mechanism at an
//! output state, evaluated from `(t, q, q̇)` alone (no file output here; the
//! CLI writes them as CSV columns `NAME.QUANTITY`).
//!
//! * [`SensorKind::Point`]: a body point `P = r + R(φ) s` and its velocity
//!   `Ṗ = ṙ + φ̇ J R(φ) s` (`J` the rotation by 90°).
//! * [`SensorKind::JointAngle`]: a joint's relative angle `θ = φ_j − φ_i`
//!   (the ground's angle is 0) and its rate `θ̇ = φ̇_j − φ̇_i`.
//! * [`SensorKind::Distance`]: `d = |P_j − P_i|` and `ḋ = e·(Ṗ_j − Ṗ_i)`,
//!   `e = (P_j − P_i)/d`.
//! * [`SensorKind::Element`]: what a force element reports of its own law
//!   ([`ForceElement::readings`]: a spring's tension and deflection, a
//!   contact's normal force and penetration).

use super::{BodyPoint, BodyRef, Constraint, System};

/// What a [`Sensor`] measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SensorKind {
    /// Position and velocity of a body point (body frame; the ground: a
    /// fixed global point).
    Point(BodyPoint),
    /// Relative angle and rate of the two bodies of joint `joint` (index
    /// into [`System::constraints`]).
    JointAngle {
        /// Reference body i.
        body_i: BodyRef,
        /// Body j.
        body_j: BodyRef,
    },
    /// Distance between two body points and its rate.
    Distance {
        /// The point on the first body.
        i: BodyPoint,
        /// The point on the second body.
        j: BodyPoint,
    },
    /// The readings of force element `element` (index into
    /// [`System::forces`]).
    Element {
        /// The element.
        element: usize,
    },
}

/// A named sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    /// Its name (the CSV column prefix).
    pub name: String,
    /// What it measures.
    pub kind: SensorKind,
}

/// Position and velocity of the body point `p`.
fn point_state(p: BodyPoint, q: &[f64], qd: &[f64]) -> ([f64; 2], [f64; 2]) {
    let s = p.point;
    match p.body.offset() {
        None => (s, [0.0; 2]),
        Some(o) => {
            let (sn, cs) = q[o + 2].sin_cos();
            let a = [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]];
            let w = qd[o + 2];
            (
                [q[o] + a[0], q[o + 1] + a[1]],
                [qd[o] - w * a[1], qd[o + 1] + w * a[0]],
            )
        }
    }
}

/// The short name of a joint: the quoted name in its description
/// ("revolute joint 'B'" → "B"), if any.
pub fn joint_short_name(c: &dyn Constraint) -> Option<String> {
    let name = c.name();
    match (name.find('\''), name.rfind('\'')) {
        (Some(a), Some(b)) if b > a + 1 => Some(name[a + 1..b].to_string()),
        _ => None,
    }
}

impl Sensor {
    /// The quantities it gives, `(name, unit)`, in the order of
    /// [`Sensor::evaluate`].
    pub fn quantities(&self, sys: &System) -> Vec<(&'static str, &'static str)> {
        match self.kind {
            SensorKind::Point(_) => {
                vec![("x", "m"), ("y", "m"), ("vx", "m/s"), ("vy", "m/s")]
            }
            SensorKind::JointAngle { .. } => vec![("angle", "rad"), ("rate", "rad/s")],
            SensorKind::Distance { .. } => vec![("distance", "m"), ("rate", "m/s")],
            SensorKind::Element { element } => sys
                .forces()
                .get(element)
                .map_or(Vec::new(), |f| f.readings().to_vec()),
        }
    }

    /// Append its values at `(t, q, q̇)` to `out` (as many as
    /// [`Sensor::quantities`]).
    pub fn evaluate(&self, sys: &System, t: f64, q: &[f64], qd: &[f64], out: &mut Vec<f64>) {
        match self.kind {
            SensorKind::Point(p) => {
                let (p, v) = point_state(p, q, qd);
                out.extend_from_slice(&[p[0], p[1], v[0], v[1]]);
            }
            SensorKind::JointAngle { body_i, body_j } => {
                let ang = |b: BodyRef, v: &[f64]| b.offset().map_or(0.0, |o| v[o + 2]);
                out.push(ang(body_j, q) - ang(body_i, q));
                out.push(ang(body_j, qd) - ang(body_i, qd));
            }
            SensorKind::Distance { i, j } => {
                let (pi, vi) = point_state(i, q, qd);
                let (pj, vj) = point_state(j, q, qd);
                let d = [pj[0] - pi[0], pj[1] - pi[1]];
                let len = d[0].hypot(d[1]);
                let rate = if len > 0.0 {
                    (d[0] * (vj[0] - vi[0]) + d[1] * (vj[1] - vi[1])) / len
                } else {
                    0.0
                };
                out.extend_from_slice(&[len, rate]);
            }
            SensorKind::Element { element } => {
                if let Some(f) = sys.forces().get(element) {
                    let start = out.len();
                    out.resize(start + f.readings().len(), 0.0);
                    f.read(t, q, qd, &mut out[start..]);
                }
            }
        }
    }
}

/// Every sensor's values at `(t, q, q̇)` into `out` (cleared first), sensor
/// after sensor.
pub(crate) fn evaluate_sensors(
    sensors: &[Sensor],
    sys: &System,
    t: f64,
    q: &[f64],
    qd: &[f64],
    out: &mut Vec<f64>,
) {
    out.clear();
    for s in sensors {
        s.evaluate(sys, t, q, qd, out);
    }
}

/// A drive of the system: its joint, its (single) constraint row and the
/// unit of its generalized force ([`Constraint::drive_unit`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Drive {
    /// Index into [`System::constraints`].
    pub joint: usize,
    /// Its row of Φ.
    pub row: usize,
    /// `"N"` or `"N m"`.
    pub unit: &'static str,
}

impl Drive {
    /// The drive's generalized force on its driven coordinate, `−λ_row`
    /// (from `M q̈ + Φ_qᵀλ = g` with `∂Φ_row/∂q_driven = 1`): the torque
    /// \[N m\] a relative-angle drive applies to its body j (body i gets
    /// its opposite), the force \[N\] or torque a coordinate drive applies.
    pub fn force(&self, lambda: &[f64]) -> f64 {
        -lambda[self.row]
    }
}

/// The drives of `sys`, in joint order.
pub fn drives(sys: &System) -> Vec<Drive> {
    let mut row = 0;
    let mut out = Vec::new();
    for (joint, c) in sys.constraints().iter().enumerate() {
        if let Some(unit) = c.drive_unit() {
            out.push(Drive { joint, row, unit });
        }
        row += c.n_eq();
    }
    out
}
