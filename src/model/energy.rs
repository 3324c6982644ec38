//! The terms of the energy balance (a drift monitor for every method):
//!
//! ```text
//! d/dt (T + V) = P_nc + P_c,     T = ½ q̇ᵀM q̇,   V = Σ_e V_e(q)
//! P_nc = Σ_e q̇ᵀ g_e + Σ_{e with V_e} ∇V_e · q̇     (non-conservative forces)
//! P_c  = −q̇ᵀ Φ_qᵀ λ = λᵀ Φ_t                      (constraint forces, drives)
//! ```
//!
//! It follows from `M q̈ + Φ_qᵀλ = g` multiplied by q̇ᵀ: `dT/dt = q̇ᵀg −
//! q̇ᵀΦ_qᵀλ`, and `dV/dt = Σ ∇V_e·q̇`. An element with a potential
//! ([`ForceElement::potential_energy`], e.g. gravity, a spring's elastic
//! part) contributes `q̇ᵀg_e + ∇V_e·q̇` — zero for a purely conservative
//! element, the damper's or actuator's power otherwise; an element without
//! one contributes all of `q̇ᵀg_e`. On the velocity manifold
//! `Φ_q q̇ = −Φ_t`, so the constraint power is `λᵀΦ_t`: ideal scleronomic
//! joints do no work, rheonomic drives do. [`System::constraint_power`]
//! returns `λᵀΦ_t` — off the manifold the work of the constraint forces on
//! the drift then shows up as an energy error, which is what a drift monitor
//! should see.
//!
//! So `E(t) − E(0) = ∫₀ᵗ (P_nc + P_c) dτ` with `E = T + V` along an exact
//! solution (tested in `tests/model/energy.rs`).

use super::{ForceElement, System};

/// Scratch for [`System::nonconservative_power`] and
/// [`System::constraint_power`]: buffers and, per force element, its
/// coordinates and whether it has a potential (both found at first use;
/// no allocation after).
#[derive(Debug, Clone, Default)]
pub struct EnergyWorkspace {
    g: Vec<f64>,
    q: Vec<f64>,
    phi_t: Vec<f64>,
    cols: Vec<Vec<usize>>,
    has_potential: Vec<bool>,
}

impl System {
    /// Mechanical energy `E = T + V`: kinetic ½ q̇ᵀMq̇ plus the potentials of
    /// every element that has one (gravity, springs).
    pub fn mechanical_energy(&self, q: &[f64], qd: &[f64]) -> f64 {
        self.kinetic_energy(qd) + self.potential_energy(q)
    }

    /// Power of the non-conservative forces `P_nc = Σ_e (q̇ᵀg_e + ∇V_e·q̇)`
    /// (module docs), element by element over its footprint. `∇V_e·q̇` is the
    /// central difference `(V_e(q + hq̇) − V_e(q − hq̇)) / 2h` along q̇ with
    /// `h‖q̇‖∞ = ε^(1/3) (1 + ‖q‖∞)` over the element's coordinates
    /// (truncation O(h²), exact for gravity's linear potential up to
    /// rounding).
    pub fn nonconservative_power(
        &self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        ws: &mut EnergyWorkspace,
    ) -> f64 {
        let (n, nb) = (self.n_coords(), self.n_body_coords());
        if ws.g.len() != n {
            ws.g = vec![0.0; n];
        }
        if ws.cols.len() != self.forces().len() {
            ws.cols = self.forces().iter().map(|f| f.coordinates()).collect();
            ws.has_potential = self
                .forces()
                .iter()
                .map(|f| f.potential_energy(q).is_some())
                .collect();
        }
        ws.q.clear();
        ws.q.extend_from_slice(q);
        let mut p = 0.0;
        for (e, f) in self.forces().iter().enumerate() {
            let cols = &ws.cols[e];
            f.add_forces(t, q, qd, &mut ws.g);
            for &c in cols {
                // the states' "forces" are their derivatives, not power
                if c < nb {
                    p += qd[c] * ws.g[c];
                }
                ws.g[c] = 0.0;
            }
            if ws.has_potential[e] {
                p += potential_rate(f.as_ref(), cols, q, qd, &mut ws.q);
            }
        }
        p
    }

    /// Power of the constraint forces `P_c = λᵀΦ_t(q, t)` (`= −q̇ᵀΦ_qᵀλ` on
    /// the velocity manifold; zero for scleronomic joints), with λ of
    /// `M q̈ + Φ_qᵀλ = g`.
    pub fn constraint_power(
        &self,
        q: &[f64],
        t: f64,
        lambda: &[f64],
        ws: &mut EnergyWorkspace,
    ) -> f64 {
        ws.phi_t.resize(self.n_constraints(), 0.0);
        self.phi_t(q, t, &mut ws.phi_t);
        ws.phi_t.iter().zip(lambda).map(|(a, b)| a * b).sum()
    }
}

/// `∇V_e · q̇` by a central difference along q̇ on the element's coordinates
/// `cols` (`work`: a copy of `q`, perturbed on `cols` and restored).
fn potential_rate(
    f: &dyn ForceElement,
    cols: &[usize],
    q: &[f64],
    qd: &[f64],
    work: &mut [f64],
) -> f64 {
    let vmax = cols.iter().fold(0.0_f64, |a, &c| a.max(qd[c].abs()));
    if vmax == 0.0 {
        return 0.0;
    }
    let qmax = cols.iter().fold(0.0_f64, |a, &c| a.max(q[c].abs()));
    let h = f64::EPSILON.cbrt() * (1.0 + qmax) / vmax;
    let mut v = [0.0; 2];
    for (k, s) in [1.0, -1.0].into_iter().enumerate() {
        for &c in cols {
            work[c] = q[c] + s * h * qd[c];
        }
        v[k] = f.potential_energy(work).unwrap_or(0.0);
        for &c in cols {
            work[c] = q[c];
        }
    }
    (v[0] - v[1]) / (2.0 * h)
}
