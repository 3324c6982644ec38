//! # mbsolve
//!
//! Dynamics of constrained planar multibody systems in reference-point
//! coordinates (x, y, φ per body), after Hajžman & Polach, "Application of
//! stabilization techniques in the dynamic analysis of multibody systems",
//! Applied and Computational Mechanics 1 (2007).
//!
//! The library is a ladder; each module uses only those above it:
//!
//! 1. [`model`]: bodies, the [`model::Constraint`] and [`model::ForceElement`]
//!    traits, gravity, and [`model::System`], which fixes the numbering and
//!    evaluates Φ, Φ_q, Φ_t, γ, (Φ_qᵀλ)_q, g and ∂g/∂q, ∂g/∂q̇ — generically
//!    or through attached kernels;
//! 2. [`constraints`] (revolute, translational, drives) and [`forces`]
//!    (applied loads, springs, the rod's fluid and contact loads);
//! 3. [`generated`]: build-time generated kernels (crate `mbsolve-codegen`)
//!    for chains and the four-bar, attached to ranges of joints and force
//!    elements; [`builders`]: the falling rod, cantilever, N-link pendulum;
//! 4. [`linalg`]: the saddle-point matrix and every linear solver behind
//!    [`linalg::SaddlePointSolver`] (sparse LDLᵀ, sparse LU, dense LU, the
//!    Schur complement of eq. (9)); [`integrate`]: ode23, ode45, rk4 for
//!    first-order ODEs and generalized-α/HHT/Newmark for second-order DAEs,
//!    knowing nothing of multibody systems;
//! 5. [`formulation`]: [`formulation::Index1`] (eq. (5) with Baumgarte terms
//!    (10)–(11), or λ eliminated, eq. (9)) as an ODE, [`formulation::Index3`]
//!    (index-3 residual and Newton matrix) as a second-order DAE, consistent
//!    initial conditions;
//! 6. [`simulation`]: one run — formulation + integrator + observation — and
//!    [`scenario`]: TOML files to validated models and run settings;
//! 7. [`analysis`]: linearisation and inverse dynamics on the same
//!    system and saddle-point solves;
//! 8. [`output`]: a run's rows as tables (CSV, Arrow IPC) streamed to any
//!    writer in bounded memory.
//!
//! [`prelude`] re-exports what an embedding program needs (scenario
//! loading, model building, the simulate entry points, results, errors,
//! the analyses); `numeric`, `trig` and `words` are crate-internal leaves.
//!
//! The `mbsolve` binary (src/bin/mbsolve/) adds the CLI, the paper's
//! studies, sweeps, the performance gate, figures and animations.
#![warn(missing_docs)]

pub mod analysis;
pub mod builders;
pub mod constraints;
pub mod drawing;
pub mod events;
pub mod forces;
pub mod formulation;
pub mod generated;
pub mod integrate;
pub mod linalg;
pub mod model;
pub(crate) mod numeric;
pub mod output;
pub mod parallel;
pub mod prelude;
pub mod scenario;
pub mod simulation;
pub(crate) mod trig;
pub(crate) mod words;
