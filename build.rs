//! Runs the code generator (`mbsolve-codegen`) for the built-in topologies
//! and writes `$OUT_DIR/mbsolve_generated.rs`, included by `src/generated.rs`.
//! The generated file is not committed; it is rebuilt whenever this script
//! or the generator crate changes.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    let (code, _stats) = mbsolve_codegen::mbsolve_builtin();
    mbsolve_codegen::write_if_changed(&out.join("mbsolve_generated.rs"), &code)
        .expect("write generated kernels");
}
