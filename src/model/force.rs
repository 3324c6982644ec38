//! The [`ForceElement`] trait: contributions to the generalized forces
//! g(q, q̇, t) of eq. (5), each with its sparse footprint and (for implicit
//! methods) its Jacobians ∂g/∂q and ∂g/∂q̇ (the elements themselves live in
//! [`crate::forces`]); and [`FdWorkspace`], the allocation-free finite
//! differences behind the default Jacobians of forces and constraints.

use super::{touched_columns, BodyPoint, Constraint, ModelError};
use std::collections::HashMap;
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
    /// Add `∂g/∂q` to `out.dq` and `∂g/∂q̇` to `out.dqd` (see
    /// [`ForceJacobians`]). Default: central finite differences through
    /// `out.ws`.
    fn add_jacobians(&self, t: f64, q: &[f64], qd: &[f64], out: ForceJacobians<'_>) {
        out.ws.jacobians(self, t, q, qd, out.dq, out.dqd);
    }
    /// Potential energy, for conservative elements (energy checks).
    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        let _ = q;
        None
    }
    /// What the element reports of its own law for sensors, `(name,
    /// unit)` ([`ForceElement::read`]): a spring's tension and deflection,
    /// a contact's normal force and penetration. Default: nothing.
    fn readings(&self) -> &'static [(&'static str, &'static str)] {
        &[]
    }
    /// The values of [`ForceElement::readings`] at `(t, q, q̇)` into `out`.
    fn read(&self, t: f64, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let _ = (t, q, qd, out);
    }
    /// The time from `(t, q, q̇)` within which an onset of this element's
    /// force (a contact's start) cannot be ruled out, if it lies within
    /// `horizon` \[s\]: for a contact, its gap over its current speed across
    /// the wall; `Some(0.0)` while the force is on (a contact running) or
    /// when the element cannot foresee its onsets; `None` when no onset lies
    /// within `horizon` (the default: an element whose force has none). Radau IIA's flight step
    /// ([`crate::integrate::ImplicitOptions::flight_step`]) is taken only
    /// when no element foresees an onset within it.
    fn onset_within(&self, t: f64, q: &[f64], qd: &[f64], horizon: f64) -> Option<f64> {
        let _ = (t, q, qd, horizon);
        None
    }
    /// Is the element a sum of loads on single bodies (gravity, buoyancy),
    /// so that [`ForceElement::add_forces_on_bodies`] can split it between
    /// the index-3 residual's two halves? Default: false.
    fn separable_by_body(&self) -> bool {
        false
    }
    /// Add the forces on bodies `bodies` only: into each of their entries
    /// of `g` the same operations as [`ForceElement::add_forces`], in the
    /// same order. Called only when [`ForceElement::separable_by_body`];
    /// the default adds every force.
    fn add_forces_on_bodies(
        &self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        g: &mut [f64],
        bodies: std::ops::Range<usize>,
    ) {
        let _ = bodies;
        self.add_forces(t, q, qd, g)
    }
    /// Check parameters and that every coordinate is `< n_coords`.
    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        check_coordinates(&self.name(), &self.coordinates(), n_coords)
    }
    /// The element as data, for drawing it. Default: [`ForceGeometry::Other`].
    fn geometry(&self) -> ForceGeometry {
        ForceGeometry::Other
    }
}

/// State-independent loads, each on a single body (gravity, buoyancy): a
/// [`ForceElement`] with no Jacobian block (`∂g/∂q = ∂g/∂q̇ = 0`) that splits
/// by body ([`ForceElement::separable_by_body`]). Implementing this trait
/// implements [`ForceElement`].
pub trait BodyLoads: Send + Sync + Debug {
    /// Description used in messages ([`ForceElement::name`]).
    fn label(&self) -> String;
    /// The loaded coordinates ([`ForceElement::coordinates`]).
    fn loaded_coordinates(&self) -> Vec<usize>;
    /// Add the loads on the bodies in `bodies` to `g`.
    fn add_loads(&self, g: &mut [f64], bodies: std::ops::Range<usize>);
    /// Potential energy of the loads at `q` \[J\].
    fn load_energy(&self, q: &[f64]) -> f64;
    /// Check parameters ([`ForceElement::validate`]). Default: the
    /// coordinates only.
    fn check(&self, n_coords: usize) -> Result<(), ModelError> {
        check_coordinates(&self.label(), &self.loaded_coordinates(), n_coords)
    }
}

impl<L: BodyLoads> ForceElement for L {
    fn name(&self) -> String {
        self.label()
    }
    fn coordinates(&self) -> Vec<usize> {
        self.loaded_coordinates()
    }
    fn add_forces(&self, _t: f64, _q: &[f64], _qd: &[f64], g: &mut [f64]) {
        self.add_loads(g, 0..usize::MAX)
    }
    fn jacobian_coordinates(&self) -> Vec<usize> {
        Vec::new()
    }
    fn separable_by_body(&self) -> bool {
        true
    }
    fn add_forces_on_bodies(
        &self,
        _t: f64,
        _q: &[f64],
        _qd: &[f64],
        g: &mut [f64],
        bodies: std::ops::Range<usize>,
    ) {
        self.add_loads(g, bodies)
    }
    fn potential_energy(&self, q: &[f64]) -> Option<f64> {
        Some(self.load_energy(q))
    }
    fn validate(&self, n_coords: usize) -> Result<(), ModelError> {
        self.check(n_coords)
    }
}

/// A force element described as data ([`ForceElement::geometry`]), what a
/// drawing of the model needs. Points are in the body frame (global for the
/// ground) \[m\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ForceGeometry {
    /// A spring and/or damper between two body points.
    PointToPoint {
        /// The point on the first body.
        i: BodyPoint,
        /// The point on the second body.
        j: BodyPoint,
        /// Free length \[m\].
        free_length: f64,
        /// Has a stiffness (drawn as a zig-zag).
        spring: bool,
        /// Has a damping law (drawn as a dashpot).
        damper: bool,
    },
    /// A circle (or point) on a body against a fixed straight wall.
    Wall {
        /// Body index.
        body: usize,
        /// Centre of the circle in the body frame.
        point: [f64; 2],
        /// Radius (0: a point).
        radius: f64,
        /// A point of the wall line, global.
        wall_point: [f64; 2],
        /// Unit normal of the wall, into the free side.
        normal: [f64; 2],
    },
    /// Anything else (gravity, loads, fluid forces).
    Other,
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

/// Where [`ForceElement::add_jacobians`] adds an element's Jacobian blocks:
/// both `k × k` row-major over [`ForceElement::jacobian_coordinates`]
/// (`[r * k + c] = ∂g_r/∂q_c`), with the finite-difference scratch space for
/// elements without analytic Jacobians.
#[derive(Debug)]
pub struct ForceJacobians<'a> {
    /// The `∂g/∂q` block.
    pub dq: &'a mut [f64],
    /// The `∂g/∂q̇` block.
    pub dqd: &'a mut [f64],
    /// Scratch space of the default finite differences.
    pub ws: &'a mut FdWorkspace,
}

/// Scratch space for finite-difference derivatives: the default
/// [`ForceElement::add_jacobians`] and [`Constraint::add_hessian`].
///
/// Holds full copies of q, q̇ and a zeroed force vector, perturbed and
/// restored only on an element's footprint, so one element costs
/// O(footprint²), not O(n); and, per element, its coordinate lists and
/// pattern maps, computed at its first call (keyed by the element's
/// address): later calls do not allocate. A workspace serves the elements of
/// one system (they must outlive it, as in a formulation borrowing the
/// system).
///
/// Invariant between calls: `g` is all zero; `q`, `qd` may be stale anywhere,
/// and are refreshed on the element's footprint (which covers everything it
/// reads) at the start of each call.
#[derive(Debug, Clone, Default)]
pub struct FdWorkspace {
    q: Vec<f64>,
    qd: Vec<f64>,
    g: Vec<f64>,
    plus: Vec<f64>,
    jp: Vec<f64>,
    jm: Vec<f64>,
    forces: HashMap<usize, ForceLists>,
    hessians: HashMap<usize, HessianMaps>,
}

/// A force element's footprint and Jacobian coordinates.
#[derive(Debug, Clone)]
struct ForceLists {
    footprint: Vec<usize>,
    cols: Vec<usize>,
}

/// A constraint's Φ_q pattern, touched columns, and for each (touched
/// column, pattern entry) the position in its Hessian pattern
/// (`usize::MAX`: outside the stored triangle).
#[derive(Debug, Clone)]
struct HessianMaps {
    pattern: Vec<(usize, usize)>,
    cols: Vec<usize>,
    target: Vec<usize>,
}

/// Identity of an element for the caches: its data address.
fn key<T: ?Sized>(e: &T) -> usize {
    e as *const T as *const () as usize
}

impl FdWorkspace {
    /// Size the full-length copies for `n` coordinates.
    fn ensure(&mut self, q: &[f64], qd: &[f64]) {
        let n = q.len();
        if self.q.len() != n {
            self.q = q.to_vec();
            self.qd = qd.to_vec();
            self.g = vec![0.0; n];
        }
    }

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
        self.ensure(q, qd);
        let lists = self.forces.entry(key(elem)).or_insert_with(|| ForceLists {
            footprint: elem.coordinates(),
            cols: elem.jacobian_coordinates(),
        });
        let (footprint, cols) = (&lists.footprint, &lists.cols);
        for &c in footprint {
            self.q[c] = q[c];
            self.qd[c] = qd[c];
        }
        let k = cols.len();
        self.plus.resize(k, 0.0);
        for velocity in [false, true] {
            let out = if velocity { &mut *dqd } else { &mut *dq };
            for (ci, &c) in cols.iter().enumerate() {
                let x0 = if velocity { qd[c] } else { q[c] };
                let h = 1e-7 * (1.0 + x0.abs());
                for (sign, store_plus) in [(1.0, true), (-1.0, false)] {
                    let x = x0 + sign * h;
                    if velocity {
                        self.qd[c] = x;
                    } else {
                        self.q[c] = x;
                    }
                    elem.add_forces(t, &self.q, &self.qd, &mut self.g);
                    for (ri, &r) in cols.iter().enumerate() {
                        if store_plus {
                            self.plus[ri] = self.g[r];
                        } else {
                            out[ri * k + ci] += (self.plus[ri] - self.g[r]) / (2.0 * h);
                        }
                    }
                    for &r in footprint {
                        self.g[r] = 0.0;
                    }
                }
                if velocity {
                    self.qd[c] = x0;
                } else {
                    self.q[c] = x0;
                }
            }
        }
    }

    /// Central differences of Φ_qᵀ λ: adds (Φ_qᵀ λ)_q of `c` (λ local to
    /// it) in the order of its [`Constraint::hessian_pattern`].
    pub fn constraint_hessian<C: Constraint + ?Sized>(
        &mut self,
        c: &C,
        q: &[f64],
        t: f64,
        lambda: &[f64],
        vals: &mut [f64],
    ) {
        self.ensure(q, q);
        let maps = self.hessians.entry(key(c)).or_insert_with(|| {
            let pattern = c.jacobian_pattern();
            let cols = touched_columns(&pattern);
            let hp = c.hessian_pattern();
            let target = cols
                .iter()
                .flat_map(|&col| {
                    pattern
                        .iter()
                        .map(move |&(_, cp)| (cp, col))
                        .collect::<Vec<_>>()
                })
                .map(|(cp, col)| {
                    if cp >= col {
                        hp.iter()
                            .position(|&e| e == (cp, col))
                            .unwrap_or(usize::MAX)
                    } else {
                        usize::MAX
                    }
                })
                .collect();
            HessianMaps {
                pattern,
                cols,
                target,
            }
        });
        let np = maps.pattern.len();
        self.jp.resize(np, 0.0);
        self.jm.resize(np, 0.0);
        for &col in &maps.cols {
            self.q[col] = q[col];
        }
        for (ci, &col) in maps.cols.iter().enumerate() {
            let h = 1e-6 * (1.0 + q[col].abs());
            self.q[col] = q[col] + h;
            c.jacobian(&self.q, t, &mut self.jp);
            self.q[col] = q[col] - h;
            c.jacobian(&self.q, t, &mut self.jm);
            self.q[col] = q[col];
            // d/dq_col of (Φ_qᵀλ)_{c'} = Σ_r λ_r dΦ_q[r, c'] / dq_col
            for (k, &(r, _)) in maps.pattern.iter().enumerate() {
                let pos = maps.target[ci * np + k];
                if pos != usize::MAX {
                    vals[pos] += lambda[r] * (self.jp[k] - self.jm[k]) / (2.0 * h);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forces::TorsionalSpringDamper;
    use crate::model::BodyRef;

    #[test]
    fn fd_workspace_matches_analytic_jacobians_and_stays_clean() {
        let spring = TorsionalSpringDamper::new(BodyRef::Body(0), BodyRef::Body(2), 3.0, 0.7);
        let q = [0.1, 0.2, 0.3, 0.0, 0.0, -0.4, 0.5, 0.6, 0.9];
        let qd = [0.0, 0.0, 1.5, 0.0, 0.0, 0.0, 0.0, 0.0, -2.0];
        let k = spring.jacobian_coordinates().len();
        let (mut a_q, mut a_qd) = (vec![0.0; k * k], vec![0.0; k * k]);
        let mut ws = FdWorkspace::default();
        let out = ForceJacobians {
            dq: &mut a_q,
            dqd: &mut a_qd,
            ws: &mut ws,
        };
        spring.add_jacobians(0.0, &q, &qd, out);
        // twice through the workspace: the second call must see fresh q and a clean g
        for q_shift in [0.0, 0.25] {
            let q2: Vec<f64> = q.iter().map(|v| v + q_shift).collect();
            let (mut f_q, mut f_qd) = (vec![0.0; k * k], vec![0.0; k * k]);
            ws.jacobians(&spring, 0.0, &q2, &qd, &mut f_q, &mut f_qd);
            for i in 0..k * k {
                assert!((a_q[i] - f_q[i]).abs() < 1e-6, "{a_q:?} vs {f_q:?}");
                assert!((a_qd[i] - f_qd[i]).abs() < 1e-6, "{a_qd:?} vs {f_qd:?}");
            }
        }
        assert!(ws.g.iter().all(|&v| v == 0.0));
    }
}
