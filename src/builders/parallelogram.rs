//! A chain of parallelogram four-bars through its singular configurations
//! (docs/constraint_methods.md), with an independent one-degree-of-freedom
//! reference.
//!
//! `k` loops in series share their cranks: `k + 1` equal cranks of length
//! `r` pivoted on the ground at `(i L, 0)`, `i = 0 … k`, and `k` couplers of
//! length `L` joining the tips of consecutive cranks. On the parallelogram
//! branch every crank turns by the same angle θ and every coupler
//! translates; at θ = 0 and θ = π all bars lie on the ground line, Φ_q
//! loses rank and the mechanism can leave its branch (towards an
//! antiparallelogram). Gravity acts along −y. With `redundant`, one rigid
//! coupler spans all the crank tips: for k ≥ 2 its extra pins are
//! redundant constraints (a parallelogram with a redundant link).
//!
//! **Reference (minimal coordinate θ).** With uniform bars (crank mass
//! `m_c`, inertia `m_c r²/12`; coupler mass `m_b`), the crank centres move
//! on circles of radius `r/2` and the couplers' centres on circles of
//! radius `r`:
//!
//! ```text
//! T = ½ I θ̇²,   I = (k + 1) m_c r²/3 + k m_b r²
//! V = C sin θ,  C = g ((k + 1) m_c r/2 + k m_b r)
//! I θ̈ = −C cos θ                       (Lagrange, free chain)
//! θ = θ₀ + ω t                          (driven chain)
//! ```
//!
//! [`ParallelogramChain::reference`] integrates the free equation with
//! classic RK4 at a fine fixed step (independent of the multibody code);
//! [`ParallelogramChain::marked_point`] is the tip of the last crank,
//! `(k L + r cos θ, r sin θ)`.

use crate::constraints::{DriveCoordinate, Revolute};
use crate::forces::Check;
use crate::model::{Body, BodyRef, ModelError, System, SystemBuilder, TimeFunction};

/// A chain of `loops` parallelogram four-bars (module docs), SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct ParallelogramChain {
    /// Number of loops k ≥ 1 (k + 1 cranks, k couplers).
    pub loops: usize,
    /// Crank length r \[m\].
    pub crank_length: f64,
    /// Pivot spacing = coupler length L \[m\].
    pub spacing: f64,
    /// Mass of each crank \[kg\].
    pub crank_mass: f64,
    /// Mass of each coupler \[kg\].
    pub coupler_mass: f64,
    /// Gravity g ≥ 0 along −y \[m/s²\].
    pub gravity: f64,
    /// Initial crank angle θ₀ \[rad\].
    pub theta0: f64,
    /// Initial crank rate θ̇₀ \[rad/s\] (the drive's rate when driven).
    pub rate0: f64,
    /// Drive crank 0 at the constant rate `rate0` (θ = θ₀ + θ̇₀ t, one
    /// rheonomic [`DriveCoordinate`]) instead of letting the chain move freely.
    pub driven: bool,
    /// One rigid coupler of length k L and mass k m_b pinned to every crank
    /// tip instead of k separate couplers: for k ≥ 2 the k − 1 extra pins
    /// are redundant (4k + 4 constraint rows of rank 3k + 5 away from the
    /// singular positions) and the reference motion is the same.
    pub redundant: bool,
}

impl Default for ParallelogramChain {
    /// One loop, r = 0.2 m, L = 0.4 m, bars of 1 kg/m (0.2 and 0.4 kg),
    /// g = 9.81, θ₀ = 0.3 rad, θ̇₀ = 15 rad/s (enough to turn over the top),
    /// free.
    fn default() -> Self {
        Self {
            loops: 1,
            crank_length: 0.2,
            spacing: 0.4,
            crank_mass: 0.2,
            coupler_mass: 0.4,
            gravity: 9.81,
            theta0: 0.3,
            rate0: 15.0,
            driven: false,
            redundant: false,
        }
    }
}

const NAME: Check = Check {
    element: "parallelogram chain",
};

impl ParallelogramChain {
    /// Check every parameter (errors name the field).
    pub fn validate(&self) -> Result<(), ModelError> {
        if self.loops == 0 {
            return Err(NAME.fail("loops", "0".into(), "the chain needs at least one loop"));
        }
        NAME.sign("crank_length", self.crank_length, true)?;
        NAME.sign("spacing", self.spacing, true)?;
        NAME.sign("crank_mass", self.crank_mass, true)?;
        NAME.sign("coupler_mass", self.coupler_mass, true)?;
        NAME.sign("gravity", self.gravity, false)?;
        NAME.finite("theta0", self.theta0)?;
        NAME.finite("rate0", self.rate0)
    }

    /// Reduced inertia `I = (k + 1) m_c r²/3 + k m_b r²` \[kg m²\].
    pub fn reduced_inertia(&self) -> f64 {
        let (k, r) = (self.loops as f64, self.crank_length);
        (k + 1.0) * self.crank_mass * r * r / 3.0 + k * self.coupler_mass * r * r
    }

    /// Gravity moment amplitude `C` of `V = C sin θ` \[N m\].
    pub fn gravity_moment(&self) -> f64 {
        let (k, r) = (self.loops as f64, self.crank_length);
        self.gravity * ((k + 1.0) * self.crank_mass * r / 2.0 + k * self.coupler_mass * r)
    }

    /// Energy `½ I θ̇² + C sin θ` of the minimal-coordinate model \[J\].
    pub fn reduced_energy(&self, theta: f64, rate: f64) -> f64 {
        0.5 * self.reduced_inertia() * rate * rate + self.gravity_moment() * theta.sin()
    }

    /// The coordinates and velocities of every body on the parallelogram
    /// branch at crank angle θ and rate θ̇ (bodies: cranks 0 … k, then
    /// couplers 0 … k − 1, or the one coupler when `redundant`).
    pub fn state(&self, theta: f64, rate: f64) -> (Vec<f64>, Vec<f64>) {
        let (k, r, l) = (self.loops, self.crank_length, self.spacing);
        let (s, c) = theta.sin_cos();
        let mut q = Vec::with_capacity(3 * (2 * k + 1));
        let mut v = Vec::with_capacity(3 * (2 * k + 1));
        for i in 0..=k {
            q.extend([i as f64 * l + 0.5 * r * c, 0.5 * r * s, theta]);
            v.extend([-0.5 * r * s * rate, 0.5 * r * c * rate, rate]);
        }
        let (n_couplers, centre0) = if self.redundant {
            (1, 0.5 * k as f64 * l)
        } else {
            (k, 0.5 * l)
        };
        for j in 0..n_couplers {
            q.extend([centre0 + j as f64 * l + r * c, r * s, 0.0]);
            v.extend([-r * s * rate, r * c * rate, 0.0]);
        }
        (q, v)
    }

    /// The marked point, the tip of the last crank, on the branch:
    /// `(k L + r cos θ, r sin θ)`.
    pub fn marked_point(&self, theta: f64) -> [f64; 2] {
        let (s, c) = theta.sin_cos();
        [
            self.loops as f64 * self.spacing + self.crank_length * c,
            self.crank_length * s,
        ]
    }

    /// The tip of the last crank from the coordinates `q` of the system
    /// [`parallelogram_chain`] builds (whatever the branch).
    pub fn marked_point_of(&self, q: &[f64]) -> [f64; 2] {
        let b = 3 * self.loops;
        let h = 0.5 * self.crank_length;
        let (s, c) = q[b + 2].sin_cos();
        [q[b] + h * c, q[b + 1] + h * s]
    }

    /// The reference crank angle and rate `(θ, θ̇)` at each of `times`
    /// (increasing, from 0): `θ₀ + θ̇₀ t` when driven, else the free equation
    /// `I θ̈ = −C cos θ` by classic RK4 with steps of at most `h`.
    pub fn reference(&self, times: &[f64], h: f64) -> Vec<(f64, f64)> {
        if self.driven {
            return times
                .iter()
                .map(|&t| (self.theta0 + self.rate0 * t, self.rate0))
                .collect();
        }
        let a = self.gravity_moment() / self.reduced_inertia();
        let f = |y: [f64; 2]| [y[1], -a * y[0].cos()];
        let mut y = [self.theta0, self.rate0];
        let mut t = 0.0;
        let mut out = Vec::with_capacity(times.len());
        for &te in times {
            while t < te {
                let dt = h.min(te - t);
                let k1 = f(y);
                let k2 = f([y[0] + 0.5 * dt * k1[0], y[1] + 0.5 * dt * k1[1]]);
                let k3 = f([y[0] + 0.5 * dt * k2[0], y[1] + 0.5 * dt * k2[1]]);
                let k4 = f([y[0] + dt * k3[0], y[1] + dt * k3[1]]);
                for i in 0..2 {
                    y[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
                }
                t = if te - t <= dt { te } else { t + dt };
            }
            out.push((y[0], y[1]));
        }
        out
    }
}

/// Build the chain (module docs): bodies cranks 0 … k (body x axis from
/// pivot to tip, pins at local `(∓r/2, 0)`), then couplers 0 … k − 1 (x
/// axis from crank j's tip to crank j + 1's, pins at `(∓L/2, 0)`) or, when
/// `redundant`, one coupler over all tips (pins at `i L − k L/2`); joints:
/// the k + 1 ground pivots, then per coupler its two pins (or the k + 1
/// pins of the one coupler), then (when driven) the drive of crank 0's
/// angle. Every body starts exactly on the
/// parallelogram branch at `(θ₀, θ̇₀)` ([`ParallelogramChain::state`]).
pub fn parallelogram_chain(p: &ParallelogramChain) -> Result<System, ModelError> {
    p.validate()?;
    let (k, r, l) = (p.loops, p.crank_length, p.spacing);
    let (q0, v0) = p.state(p.theta0, p.rate0);
    let mut b = SystemBuilder::new();
    let body = |name: String, mass: f64, len: f64, i: usize| {
        Body::new(
            name,
            mass,
            mass * len * len / 12.0,
            [q0[3 * i], q0[3 * i + 1], q0[3 * i + 2]],
        )
        .with_velocity([v0[3 * i], v0[3 * i + 1], v0[3 * i + 2]])
    };
    for i in 0..=k {
        b.add_body(body(format!("crank{i}"), p.crank_mass, r, i));
    }
    let len = k as f64 * l;
    if p.redundant {
        b.add_body(body(
            "coupler".into(),
            k as f64 * p.coupler_mass,
            len,
            k + 1,
        ));
    } else {
        for j in 0..k {
            b.add_body(body(format!("coupler{j}"), p.coupler_mass, l, k + 1 + j));
        }
    }
    for i in 0..=k {
        b.add_constraint(Revolute::new(
            format!("pivot{i}"),
            BodyRef::Ground,
            [i as f64 * l, 0.0],
            BodyRef::Body(i),
            [-0.5 * r, 0.0],
        ));
    }
    let tip = |crank: usize, coupler: usize, at: f64| {
        Revolute::new(
            format!("pin{crank}-body{coupler}"),
            BodyRef::Body(crank),
            [0.5 * r, 0.0],
            BodyRef::Body(coupler),
            [at, 0.0],
        )
    };
    if p.redundant {
        for i in 0..=k {
            b.add_constraint(tip(i, k + 1, i as f64 * l - 0.5 * len));
        }
    } else {
        for j in 0..k {
            b.add_constraint(tip(j, k + 1 + j, -0.5 * l));
            b.add_constraint(tip(j + 1, k + 1 + j, 0.5 * l));
        }
    }
    if p.driven {
        b.add_constraint(DriveCoordinate::new(
            "crank drive",
            0,
            2,
            TimeFunction::Polynomial(vec![p.theta0, p.rate0]),
        ));
    }
    if p.gravity != 0.0 {
        b.gravity([0.0, -p.gravity]);
    }
    b.build()
}
