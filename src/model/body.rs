//! Planar rigid bodies.

use super::ModelError;

/// A planar rigid body in reference-point coordinates `[x, y, φ]` of its
/// centre of mass; mass matrix `diag(m, m, I)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Name used in messages and outputs.
    pub name: String,
    /// Mass m > 0 \[kg\].
    pub mass: f64,
    /// Moment of inertia about the centre of mass I > 0 \[kg m²\].
    pub inertia: f64,
    /// Initial (or guessed) position `[x, y, φ]` \[m, m, rad\].
    pub q0: [f64; 3],
    /// Initial (or guessed) velocity `[ẋ, ẏ, φ̇]`.
    pub v0: [f64; 3],
}

impl Body {
    /// A body at rest at `q0`.
    pub fn new(name: impl Into<String>, mass: f64, inertia: f64, q0: [f64; 3]) -> Self {
        Self {
            name: name.into(),
            mass,
            inertia,
            q0,
            v0: [0.0; 3],
        }
    }

    /// Set the initial velocity.
    pub fn with_velocity(mut self, v0: [f64; 3]) -> Self {
        self.v0 = v0;
        self
    }

    /// Check the parameters: finite positive mass and inertia, finite state.
    pub fn validate(&self) -> Result<(), ModelError> {
        let bad = |field, value, why| ModelError::InvalidBody {
            body: self.name.clone(),
            field,
            value,
            why,
        };
        if !(self.mass.is_finite() && self.mass > 0.0) {
            return Err(bad("mass", self.mass, "must be finite and > 0"));
        }
        if !(self.inertia.is_finite() && self.inertia > 0.0) {
            return Err(bad("inertia", self.inertia, "must be finite and > 0"));
        }
        for (k, (fq, fv)) in [("x", "vx"), ("y", "vy"), ("phi", "omega")]
            .into_iter()
            .enumerate()
        {
            if !self.q0[k].is_finite() {
                return Err(bad(fq, self.q0[k], "must be finite"));
            }
            if !self.v0[k].is_finite() {
                return Err(bad(fv, self.v0[k], "must be finite"));
            }
        }
        Ok(())
    }
}

/// One side of a joint: the ground (fixed frame) or a body by index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BodyRef {
    /// The fixed frame: points are given in global coordinates.
    Ground,
    /// Body with this index (its coordinates are `3i, 3i+1, 3i+2`).
    Body(usize),
}

impl BodyRef {
    /// Index of the first coordinate, or `None` for ground.
    pub fn offset(self) -> Option<usize> {
        match self {
            BodyRef::Ground => None,
            BodyRef::Body(i) => Some(3 * i),
        }
    }

    /// Global position `r + R(φ) s` \[m\] of the body-fixed point `s` at
    /// the pose `q` (3 coordinates per body); `s` itself on the ground.
    pub fn point_at(self, q: &[f64], s: [f64; 2]) -> [f64; 2] {
        match self.offset() {
            None => s,
            Some(o) => {
                let (sn, cs) = q[o + 2].sin_cos();
                [
                    q[o] + cs * s[0] - sn * s[1],
                    q[o + 1] + sn * s[0] + cs * s[1],
                ]
            }
        }
    }
}

/// A point fixed on a body, or a fixed point of the ground: where joints,
/// springs and sensors attach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyPoint {
    /// The body, or the ground.
    pub body: BodyRef,
    /// The point in the body frame \[m\] (global on the ground).
    pub point: [f64; 2],
}

impl BodyPoint {
    /// The point `point` of `body`.
    pub fn new(body: BodyRef, point: [f64; 2]) -> Self {
        Self { body, point }
    }

    /// Its global position `r + R(φ) s` \[m\] at the pose `q`
    /// ([`BodyRef::point_at`]).
    pub fn at(self, q: &[f64]) -> [f64; 2] {
        self.body.point_at(q, self.point)
    }
}
