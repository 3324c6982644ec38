//! # mbsolve
//!
//! Dynamics of constrained planar multibody systems in reference-point
//! coordinates (x, y, φ per body), after Hajžman & Polach, "Application of
//! stabilization techniques in the dynamic analysis of multibody systems",
//! Applied and Computational Mechanics 1 (2007).
//!
//! Data flows one way through the modules:
//! `model` (bodies, joints, force elements, [`model::System`]) →
//! `formulation` (index-1 saddle point with Baumgarte terms, eq. (5), (10)–(11);
//! λ eliminated, eq. (9); consistent initial conditions) → `integrate`
//! (ode23, ode45, rk4) → `output`. Linear algebra of the saddle point lives in
//! `linalg`, behind [`linalg::SaddlePointSolver`].
#![warn(missing_docs)]

pub mod builders;
pub mod constraints;
pub mod events;
pub mod forces;
pub mod formulation;
pub mod generated;
pub mod integrate;
pub mod linalg;
pub mod model;
pub mod scenario;
pub mod simulation;
