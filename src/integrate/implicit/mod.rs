//! The one core of the implicit (index-3) schemes — generalized-α (with
//! HHT, Newmark and the trapezoidal rule), BDF/NDF, Radau IIA and the
//! augmented Lagrangian: their statistics.

mod stats;

pub use stats::{ImplicitStats, COUNTED_ORDERS};
