//! Uniform gravity.

use super::BodyLoads;

/// Uniform gravity `m g` on every listed body (g = (0, −9.81) m/s² in the
/// reference problems). Potential energy `−Σ m g·r`.
#[derive(Debug, Clone)]
pub struct Gravity {
    /// Acceleration of gravity \[m/s²\].
    pub g: [f64; 2],
    /// `(body index, mass)` pairs.
    pub bodies: Vec<(usize, f64)>,
}

impl BodyLoads for Gravity {
    fn label(&self) -> String {
        "gravity".into()
    }
    fn loaded_coordinates(&self) -> Vec<usize> {
        self.bodies
            .iter()
            .flat_map(|&(b, _)| [3 * b, 3 * b + 1])
            .collect()
    }
    fn add_loads(&self, g: &mut [f64], bodies: std::ops::Range<usize>) {
        for &(b, m) in self.bodies.iter().filter(|(b, _)| bodies.contains(b)) {
            g[3 * b] += m * self.g[0];
            g[3 * b + 1] += m * self.g[1];
        }
    }
    fn load_energy(&self, q: &[f64]) -> f64 {
        self.bodies
            .iter()
            .map(|&(b, m)| -m * (self.g[0] * q[3 * b] + self.g[1] * q[3 * b + 1]))
            .sum()
    }
}
