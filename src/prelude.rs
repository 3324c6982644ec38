//! What an embedding program needs, in one import:
//! `use mbsolve::prelude::*;`.
//!
//! Loading a scenario file and running it:
//!
//! ```no_run
//! use mbsolve::prelude::*;
//!
//! let sc = load_scenario(std::path::Path::new("scenarios/fourbar.toml"), &[])?;
//! let (trajectory, summary) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [])?;
//! println!("{} rows, status {}", trajectory.t.len(), summary.status);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Building a model in code goes through [`SystemBuilder`] with [`Body`],
//! the joints of [`crate::constraints`] and the force elements of
//! [`crate::forces`]; the ready-made models are in [`crate::builders`]; the
//! analyses about a state (statics, modes, linearisation, inverse
//! dynamics) in [`crate::analysis`]. Everything here is a re-export: each
//! item's documentation is at its home module.

pub use crate::analysis::{
    eigenmodes, static_equilibrium, Equilibrium, ModeOptions, Modes, StaticError, StaticOptions,
    Tangent,
};
pub use crate::builders::{build_rod, stiff_chain, RodInfo, RodParams};
pub use crate::constraints::{Revolute, Translational};
pub use crate::forces::{
    AppliedForce, AppliedTorque, PointSpringDamper, RotationalSpringDamper, TorsionalSpringDamper,
};
pub use crate::formulation::{Formulation, FormulationError};
pub use crate::integrate::{ImplicitOptions, Method, OdeOptions, Tolerance};
pub use crate::linalg::SolverKind;
pub use crate::model::{
    Body, BodyRef, Constraint, ForceElement, ModelError, System, SystemBuilder, TimeFunction,
};
pub use crate::scenario::{
    load as load_scenario, parse as parse_scenario, Scenario, ScenarioError,
};
pub use crate::simulation::{
    simulate, simulate_into, Monitor, RunConfig, Sample, SimulationError, Sink, Summary, Trajectory,
};
