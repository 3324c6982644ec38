//! Constraint kernels generated at build time by `mbsolve-codegen`
//! (ARCHITECTURE.md, "Code generation").
//!
//! `build.rs` runs the generator for the built-in topologies and writes
//! `$OUT_DIR/mbsolve_generated.rs`, included here as [`kernels`]: the
//! body–body revolute chain (per-joint kernels plus loops; the rod and the
//! links of the N-link pendulum), one revolute between the ground and a body
//! (the pendulum pivot, the cantilever base), the four-bar (fully unrolled),
//! and force kernels (torsional spring–dampers along a chain, drag on every
//! body). Joint parameters — the body-fixed points — are run-time inputs, so
//! one set of kernels serves every segment length and every N.
//!
//! The kernels implement [`ConstraintKernels`] for a range of joints,
//! including (Φ_qᵀλ)_q for the Newton matrix of the implicit methods, and
//! reproduce the generic per-joint evaluation (same rows, Φ_q values in the
//! order of [`System::jacobian_pattern`]). The builders attach the kernels
//! of what they build ([`ChainKernels::new`] for a rod's or a pendulum's
//! chain, any body numbering, anywhere in a larger system); for systems
//! read from scenario files, [`recognise`] inspects the joints as data
//! ([`crate::model::Constraint::geometry`]) and [`attach_generated`]
//! attaches matching whole-system kernels.
//!
//! Recognised topologies:
//! * **four-bar**: 3 bodies and exactly the revolutes ground–0, 0–1, 1–2,
//!   ground–2 in that order (docs/problems.md, problem A), any pin points;
//! * **revolute chain**: N bodies, joints `k = 0 … N−2` each a revolute with
//!   `body_i = k`, `body_j = k + 1` (any points), in row order — the rod of
//!   problem B (docs/problems.md); optionally one more revolute between the ground (either
//!   side) and any body, as the first or the last joint — the N-link
//!   pendulum and the cantilever of problem D (docs/problems.md).
//!
//! Anything else (another joint kind, other body numbering or order) gives
//! `None`, and the system keeps its generic evaluation.

mod chain;
mod forces;
mod fourbar;
mod memo;

pub use crate::trig::{sin_cos, sin_cos4};
pub use chain::{ChainKernels, GroundPivot};
pub use forces::{ContactJacobians, DragJacobians, TorsionalChainJacobians};
pub use fourbar::FourBarKernels;
pub use memo::SharedTrig;

use crate::model::{BodyRef, ConstraintKernels, JointGeometry, System};

/// The generated functions (`$OUT_DIR/mbsolve_generated.rs`).
pub mod kernels {
    include!(concat!(env!("OUT_DIR"), "/mbsolve_generated.rs"));
}

fn code(b: BodyRef) -> i64 {
    match b {
        BodyRef::Ground => -1,
        BodyRef::Body(i) => i as i64,
    }
}

/// A revolute joint as data: (body i, body j, kernel parameters s_i, s_j).
fn revolute(g: JointGeometry) -> Option<(BodyRef, BodyRef, [f64; 4])> {
    match g {
        JointGeometry::Revolute { i, j } => Some((
            i.body,
            j.body,
            [i.point[0], i.point[1], j.point[0], j.point[1]],
        )),
        _ => None,
    }
}

#[inline]
fn arr<const N: usize>(s: &[f64]) -> &[f64; N] {
    s[..N].try_into().expect("slice length")
}

#[inline]
fn arr_mut<const N: usize>(s: &mut [f64]) -> &mut [f64; N] {
    (&mut s[..N]).try_into().expect("slice length")
}

/// Generated kernels matching `sys`'s topology (four-bar or revolute
/// chain, see the module documentation), or `None`.
pub fn recognise(sys: &System) -> Option<Box<dyn ConstraintKernels>> {
    if let Some(k) = FourBarKernels::recognise(sys) {
        return Some(Box::new(k));
    }
    ChainKernels::recognise(sys).map(|k| Box::new(k) as Box<dyn ConstraintKernels>)
}

/// Recognise `sys`'s topology and attach the generated kernels to all its
/// joints, replacing kernels attached before (used from then on, see
/// [`System::attach_kernels`]). Returns whether kernels were attached; the
/// system is unchanged when none match.
pub fn attach_generated(sys: &mut System) -> bool {
    match recognise(sys) {
        Some(k) => {
            sys.detach_kernels();
            sys.attach_kernels(0..sys.constraints().len(), k).is_ok()
        }
        None => false,
    }
}
