//! Integration tests of scenario files: components, force types, keys, overrides,
//! parameters, templates and includes.

#[path = "../common/mod.rs"]
mod common;

mod components;
mod forces;
mod functions;
mod joint_loads;
mod keys;
mod long_way;
mod names;
mod overrides;
mod parameters;
mod states;
mod templates;
