//! Analyses of a model other than a time integration, about a state:
//! the tangent matrices ([`tangent`]: `M`, `C`, `K`, `Φ_q` and their sign
//! convention), the static equilibrium ([`statics`]: load stepping,
//! Newton), its stability ([`mod@stability`]: by inertia) and the eigenmodes ([`modes`]:
//! shift-invert Lanczos, damped modes in the reduced basis), the sparse
//! choice of independent coordinates ([`partitioning`]).

pub mod inverse;
pub mod linearize;
pub mod modes;
pub mod partitioning;
pub mod stability;
pub mod statics;
pub mod tangent;

pub use modes::{eigenmodes, first_order_modes, FirstOrderMode, Mode, ModeOptions, Modes};
pub use stability::{constrained_inertia, stability, Stability};
pub use statics::{
    static_equilibrium, static_equilibrium_from, Equilibrium, StaticError, StaticOptions,
};
pub use tangent::{Tangent, Triplets};
