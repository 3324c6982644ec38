//! Force elements: contributions to the generalized forces g(q, q̇, t) of
//! eq. (5), each with its sparse footprint and (for implicit methods) its
//! Jacobians ∂g/∂q and ∂g/∂q̇.
//!
//! Users add their own forces by implementing [`ForceElement`].

mod applied;
mod buoyancy;
mod contact;
mod drag;
mod gravity;
mod torsional;

pub use applied::{AppliedForce, AppliedTorque};
pub use buoyancy::Buoyancy;
pub use contact::{CornerState, Wall, WallContact};
pub use drag::Drag;
pub use gravity::Gravity;
pub use torsional::TorsionalSpringDamper;

use crate::model::ModelError;
use std::fmt::Debug;

/// A force element. It reads the coordinates it names and adds generalized
/// forces to the same coordinates (its *footprint*), so the sparse structure
/// of its Jacobians is known before any evaluation.
pub trait ForceElement: Send + Sync + Debug {
    /// Description used in messages.
    fn name(&self) -> String;
    /// Global coordinates the element reads and writes (sorted, distinct).
    fn coordinates(&self) -> Vec<usize>;
    /// Add the element's generalized forces to `g` (length = all coordinates).
    fn add_forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]);
    /// Coordinates on which the forces depend (the Jacobian block);
    /// `[]` for constant loads. Default: [`ForceElement::coordinates`].
    fn jacobian_coordinates(&self) -> Vec<usize> {
        self.coordinates()
    }
    /// Add `∂g/∂q` to `dq` and `∂g/∂q̇` to `dqd`, both `k × k` row-major over
    /// [`ForceElement::jacobian_coordinates`] (`[r * k + c] = ∂g_r/∂q_c`).
    /// Default: central finite differences through [`FdWorkspace`].
    fn add_jacobians(
        &self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        dq: &mut [f64],
        dqd: &mut [f64],
        ws: &mut FdWorkspace,
    ) {
        ws.jacobians(self, t, q, qd, dq, dqd);
    }
    /// Potential energy, for conservative elements (energy checks).
    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        let _ = q;
        None
    }
    /// Check parameters and that every coordinate is `< n_coords`.
    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        check_coordinates(&self.name(), &self.coordinates(), n_coords)
    }
}

/// Every coordinate of a footprint exists.
pub fn check_coordinates(
    element: &str,
    coords: &[usize],
    n_coords: usize,
) -> Result<(), ModelError> {
    match coords.iter().find(|&&c| c >= n_coords) {
        Some(&c) => Err(ModelError::MissingBody {
            element: element.to_string(),
            index: c / 3,
            n_bodies: n_coords / 3,
        }),
        None => Ok(()),
    }
}

/// Scratch space for finite-difference Jacobians of force elements: copies
/// of q, q̇ and a zeroed force vector of full length, perturbed and restored
/// only on an element's footprint (cost O(footprint²), not O(n)).
#[derive(Debug, Clone, Default)]
pub struct FdWorkspace {
    q: Vec<f64>,
    qd: Vec<f64>,
    g: Vec<f64>,
}

impl FdWorkspace {
    /// Central-difference `∂g/∂q`, `∂g/∂q̇` of `elem` (see [`ForceElement::add_jacobians`]).
    pub fn jacobians<E: ForceElement + ?Sized>(
        &mut self,
        elem: &E,
        t: f64,
        q: &[f64],
        qd: &[f64],
        dq: &mut [f64],
        dqd: &mut [f64],
    ) {
        let n = q.len();
        if self.q.len() != n {
            self.q = q.to_vec();
            self.qd = qd.to_vec();
            self.g = vec![0.0; n];
        }
        let cols = elem.jacobian_coordinates();
        let k = cols.len();
        // Bring the copies up to date on the footprint only.
        for &c in &cols {
            self.q[c] = q[c];
            self.qd[c] = qd[c];
        }
        for (which, out) in [(0, &mut *dq), (1, &mut *dqd)] {
            for (ci, &c) in cols.iter().enumerate() {
                let x0 = if which == 0 { q[c] } else { qd[c] };
                let h = 1e-7 * (1.0 + x0.abs());
                let mut col_val = |x: f64, gs: &mut Vec<f64>| {
                    if which == 0 {
                        self.q[c] = x;
                    } else {
                        self.qd[c] = x;
                    }
                    for &r in &cols {
                        gs[r] = 0.0;
                    }
                    elem.add_forces(t, &self.q, &self.qd, gs);
                };
                let mut g = std::mem::take(&mut self.g);
                col_val(x0 + h, &mut g);
                let plus: Vec<f64> = cols.iter().map(|&r| g[r]).collect();
                col_val(x0 - h, &mut g);
                for (ri, &r) in cols.iter().enumerate() {
                    out[ri * k + ci] += (plus[ri] - g[r]) / (2.0 * h);
                    g[r] = 0.0;
                }
                self.g = g;
                if which == 0 {
                    self.q[c] = x0;
                } else {
                    self.qd[c] = x0;
                }
            }
        }
    }
}
