//! Analyses of a model other than a time integration, about a state:
//! the tangent matrices ([`tangent`]: `M`, `C`, `K`, `Φ_q` and their sign
//! convention), the static equilibrium and the eigenmodes.

pub mod inverse;
pub mod linearize;
pub mod tangent;

pub use tangent::{Tangent, Triplets};
