//! Static buoyancy (docs/problems.md, problem B).

use super::{check_coordinates, Check};
use crate::model::{BodyLoads, ModelError};

/// Static buoyancy of fully submerged bodies in still fluid (docs/problems.md, problem B,
/// "buoyancy"): a constant uplift `ρ_w g V` along +y on every listed body,
/// applied at its centre (no torque). For a rod segment `V = w² l_s`.
///
/// One element may cover many bodies. The force does not depend on the state,
/// so it is a [`BodyLoads`] (no Jacobian block). Potential energy
/// `−Σ ρ_w g V y`.
#[derive(Debug, Clone, PartialEq)]
pub struct Buoyancy {
    /// Fluid density ρ_w ≥ 0 \[kg/m³\].
    pub fluid_density: f64,
    /// Magnitude of the acceleration of gravity g ≥ 0 \[m/s²\] (gravity acts along −y).
    pub gravity: f64,
    /// `(body index, displaced volume V > 0 [m³])` pairs, distinct bodies.
    pub bodies: Vec<(usize, f64)>,
}

impl Buoyancy {
    /// Uplift on a body of displaced volume `volume` \[N\].
    pub fn uplift(&self, volume: f64) -> f64 {
        self.fluid_density * self.gravity * volume
    }
}

impl BodyLoads for Buoyancy {
    fn label(&self) -> String {
        format!("buoyancy ({} bodies)", self.bodies.len())
    }

    fn loaded_coordinates(&self) -> Vec<usize> {
        let mut c: Vec<usize> = self.bodies.iter().map(|&(b, _)| 3 * b + 1).collect();
        c.sort_unstable();
        c.dedup();
        c
    }

    fn add_loads(&self, g: &mut [f64], bodies: std::ops::Range<usize>) {
        for &(b, v) in self.bodies.iter().filter(|(b, _)| bodies.contains(b)) {
            g[3 * b + 1] += self.uplift(v);
        }
    }

    fn load_energy(&self, q: &[f64]) -> f64 {
        self.bodies
            .iter()
            .map(|&(b, v)| -self.uplift(v) * q[3 * b + 1])
            .sum()
    }

    fn check(&self, n_coords: usize) -> Result<(), ModelError> {
        let name = self.label();
        let check = Check { element: &name };
        check.sign("fluid_density", self.fluid_density, false)?;
        check.sign("gravity", self.gravity, false)?;
        for &(b, v) in &self.bodies {
            if !(v.is_finite() && v > 0.0) {
                return Err(check.fail(
                    "volume",
                    format!("{v} (body {b})"),
                    "must be finite and > 0",
                ));
            }
        }
        if self.loaded_coordinates().len() != self.bodies.len() {
            return Err(check.fail(
                "bodies",
                format!("{:?}", self.bodies),
                "each body may appear only once",
            ));
        }
        check_coordinates(&name, &self.loaded_coordinates(), n_coords)
    }
}
