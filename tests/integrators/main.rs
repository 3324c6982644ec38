//! Integration tests of the time integrators: the explicit methods (ode23, ode45,
//! ode113, rk4), generalized-α, BDF/NDF, Radau IIA, the augmented Lagrangian, the
//! automatic choice between them, their error control and stability limits, and the
//! stiff chain against the peers' reference.

#[path = "../common/mod.rs"]
mod common;

mod augmented_lagrangian;
mod auto;
mod bdf;
mod error_control;
mod every_method;
mod explicit;
mod genalpha;
mod radau;
mod radau13;
mod radau59;
mod radau9;
mod stability_limit;
mod stiff_chain;
