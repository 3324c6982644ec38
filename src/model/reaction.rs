//! Joint reactions from the Lagrange multipliers.
//!
//! With `M q̈ + Φ_qᵀ λ = g` the constraint forces on the coordinates are
//! `−Φ_qᵀ λ` (paper eq. (2); its λ is our −λ). A joint's reaction on one of
//! its bodies is that product restricted to the joint's rows and the
//! body's columns: a force `(f_x, f_y)` at the centre of mass and a moment
//! `m_z` about it, in the global frame.

use super::{BodyRef, System};

/// Which joint each constraint row belongs to and which body each joint's
/// reaction is reported on: its second body (`body_j`), or the first when
/// the second is the ground (`None` for a joint on the ground only).
/// Computed once per system ([`System::reaction_map`]).
#[derive(Debug, Clone)]
pub struct ReactionMap {
    joint_of_row: Vec<usize>,
    bodies: Vec<Option<usize>>,
}

impl ReactionMap {
    /// The body joint `joint`'s reaction acts on.
    pub fn body(&self, joint: usize) -> Option<usize> {
        self.bodies[joint]
    }

    /// The constraint rows of joint `joint` (its multipliers λ): rows
    /// follow joint order, so they are one range, found by bisection.
    pub fn rows_of(&self, joint: usize) -> std::ops::Range<usize> {
        let start = self.joint_of_row.partition_point(|&j| j < joint);
        let end = self.joint_of_row.partition_point(|&j| j <= joint);
        start..end
    }
}

impl System {
    /// The [`ReactionMap`] of this system.
    pub fn reaction_map(&self) -> ReactionMap {
        let mut joint_of_row = Vec::with_capacity(self.n_constraints());
        let mut bodies = Vec::with_capacity(self.constraints().len());
        for (k, c) in self.constraints().iter().enumerate() {
            joint_of_row.extend(std::iter::repeat_n(k, c.n_eq()));
            bodies.push(c.bodies().iter().rev().find_map(|b| match b {
                BodyRef::Body(i) => Some(*i),
                BodyRef::Ground => None,
            }));
        }
        ReactionMap {
            joint_of_row,
            bodies,
        }
    }

    /// Reactions of every joint on its [`ReactionMap::body`]:
    /// `out[3k..3k+3] = (f_x, f_y, m_z)` of joint k = `−(Φ_qᵀ λ)` restricted
    /// to its rows and that body's coordinates, from the Jacobian values
    /// `jac` (in [`System::jacobian_pattern`] order) and `λ`. No allocation.
    pub fn joint_reactions(&self, map: &ReactionMap, jac: &[f64], lambda: &[f64], out: &mut [f64]) {
        out[..3 * map.bodies.len()].fill(0.0);
        for (&(r, c), &v) in self.jacobian_pattern().iter().zip(jac) {
            let k = map.joint_of_row[r];
            if map.bodies[k] == Some(c / 3) {
                out[3 * k + c % 3] -= v * lambda[r];
            }
        }
    }
}
