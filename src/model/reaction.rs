//! Joint reactions from the Lagrange multipliers.
//!
//! With `M q̈ + Φ_qᵀ λ = g` the constraint forces on the coordinates are
//! `−Φ_qᵀ λ` (paper eq. (2); its λ is our −λ). A joint's reaction on one of
//! its bodies is that product restricted to the joint's rows and the
//! body's columns: a force `(f_x, f_y)` at the centre of mass and a moment
//! `m_z` about it, in the global frame.

use super::{BodyRef, System};

impl System {
    /// The body a joint's reaction is reported on: its second body
    /// (`body_j`), or the first when the second is the ground. `None` for a
    /// joint on the ground only.
    pub fn reaction_body(&self, joint: usize) -> Option<usize> {
        let bodies = self.constraints()[joint].bodies();
        bodies.iter().rev().find_map(|b| match b {
            BodyRef::Body(i) => Some(*i),
            BodyRef::Ground => None,
        })
    }

    /// Reactions of every joint on its [`System::reaction_body`]:
    /// `out[3k..3k+3] = (f_x, f_y, m_z)` of joint k = `−(Φ_qᵀ λ)` restricted
    /// to its rows and that body's coordinates, from the Jacobian values
    /// `jac` (in [`System::jacobian_pattern`] order) and `λ`.
    pub fn joint_reactions(&self, jac: &[f64], lambda: &[f64], out: &mut [f64]) {
        let nj = self.constraints().len();
        out[..3 * nj].fill(0.0);
        // joint of each constraint row
        let mut joint_of_row = Vec::with_capacity(self.n_constraints());
        for k in 0..nj {
            let rows = self.constraints()[k].n_eq();
            joint_of_row.extend(std::iter::repeat_n(k, rows));
        }
        let targets: Vec<Option<usize>> = (0..nj).map(|k| self.reaction_body(k)).collect();
        for (&(r, c), &v) in self.jacobian_pattern().iter().zip(jac) {
            let k = joint_of_row[r];
            if targets[k] == Some(c / 3) {
                out[3 * k + c % 3] -= v * lambda[r];
            }
        }
    }
}
