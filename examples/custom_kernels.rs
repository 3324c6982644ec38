//! Generated kernels for your own topology, attached to a range of joints
//! of a larger system (docs/codegen.md).
//!
//! 1. What a downstream `build.rs` does: describe the topology as data
//!    ([`Topology`]) and emit Rust with [`emit_unrolled`]; here the emitted
//!    source is only measured, a `build.rs` writes it to `$OUT_DIR` and the
//!    crate `include!`s it.
//! 2. The same topology (a revolute between the ground and one body) is
//!    emitted by mbsolve's own `build.rs` as `mbsolve::generated::kernels::
//!    revolute_gb_*`; this example wraps those functions — standing in for
//!    your `include!`d module — in a [`ConstraintKernels`] for the pivot of
//!    a pendulum that is body 1 of a larger system (body 0 is a free body),
//!    attaches them to that joint's range, and checks Φ, Φ_q, Φ_t and γ
//!    against the generic per-joint evaluation.
//!
//! `cargo run --release --example custom_kernels`

use mbsolve::constraints::Revolute;
use mbsolve::generated::kernels as k;
use mbsolve::model::{Body, BodyRef, ConstraintKernels, Evaluation, System, SystemBuilder};
use mbsolve::simulation::{simulate, RunConfig};
use mbsolve_codegen::{
    emit_chain, emit_unrolled, ChainElement, ForceKind, JointKind, Side, Topology,
};

/// A ground–body revolute on body `body` of the system: the topology's
/// coordinates 0..3 are the system's `3 body .. 3 body + 3`; the joint
/// parameters `p = [s_i, s_j]` (ground point global, body point local).
#[derive(Debug)]
struct PivotKernels {
    body: usize,
    p: [f64; 4],
}

impl PivotKernels {
    /// The topology's coordinates within the system's `q`.
    fn local<'a>(&self, q: &'a [f64]) -> &'a [f64; 3] {
        q[3 * self.body..3 * self.body + 3].try_into().unwrap()
    }
}

impl ConstraintKernels for PivotKernels {
    fn name(&self) -> &str {
        "example:pivot"
    }
    /// The generated pattern (row, topology coordinate) moved to the
    /// system's columns.
    fn jacobian_pattern(&self) -> Vec<(usize, usize)> {
        k::REVOLUTE_GB_JAC_PATTERN
            .iter()
            .map(|&(r, c)| (r, 3 * self.body + c))
            .collect()
    }
    fn phi(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        k::revolute_gb_phi(self.local(q), &self.p, &[], out.try_into().unwrap());
    }
    fn jacobian_values(&self, q: &[f64], _t: f64, vals: &mut [f64]) {
        k::revolute_gb_jacobian(self.local(q), &self.p, &[], vals.try_into().unwrap());
    }
    fn phi_t(&self, q: &[f64], _t: f64, out: &mut [f64]) {
        k::revolute_gb_phi_t(self.local(q), &self.p, &[], out.try_into().unwrap());
    }
    fn gamma(&self, q: &[f64], qd: &[f64], _t: f64, out: &mut [f64]) {
        let qd: &[f64; 3] = qd[3 * self.body..3 * self.body + 3].try_into().unwrap();
        k::revolute_gb_gamma(self.local(q), qd, &self.p, &[], out.try_into().unwrap());
    }
}

/// Φ, Φ_q values, Φ_t and γ of `sys` at (q, q̇, t), concatenated.
fn everything(sys: &System, q: &[f64], qd: &[f64], t: f64) -> Vec<f64> {
    let m = sys.n_constraints();
    let (mut phi, mut phi_t, mut gamma) = (vec![0.0; m], vec![0.0; m], vec![0.0; m]);
    let mut vals = vec![0.0; sys.jacobian_pattern().len()];
    sys.phi(q, t, &mut phi);
    sys.jacobian_values(q, t, &mut vals);
    sys.phi_t(q, t, &mut phi_t);
    sys.gamma(q, qd, t, &mut gamma);
    [phi, vals, phi_t, gamma].concat()
}

fn main() {
    // 1. The build step (docs/codegen.md): topology as data → Rust source.
    let topo = Topology::new("crane", 2)
        .revolute("base", Side::Ground, Side::Body(0))
        .joint(
            "boom",
            JointKind::Translational,
            Side::Body(0),
            Side::Body(1),
        )
        .force(
            "luff",
            ForceKind::TorsionalSpringDamper,
            Side::Ground,
            Side::Body(0),
        );
    topo.validate().expect("topology");
    let (mut code, stats) = emit_unrolled(&topo, "crane");
    let (chain, _) = emit_chain("my_chain", ChainElement::Joint(JointKind::Revolute));
    code.push_str(&chain);
    for f in [
        "crane_phi(",
        "crane_eval(",
        "crane_force_jacobians(",
        "my_chain_eval(",
    ] {
        assert!(code.contains(&format!("pub fn {f}")), "{f}");
    }
    println!(
        "emitted {} functions, {} operations, {} bytes of Rust",
        stats.functions,
        stats.ops,
        code.len()
    );

    // 2. A free body 0 and a pendulum (body 1, length 0.6 m, top end at
    // local (0, l/2)) pinned at (0.1, 0.2), released at φ = 0.5 rad; the
    // pivot is joint 0.
    let (l, pivot, phi0) = (0.6f64, [0.1, 0.2], 0.5f64);
    let mut b = SystemBuilder::new();
    b.add_body(Body::new("free", 1.0, 0.1, [1.0, 0.0, 0.0]).with_velocity([0.0, 1.0, 0.0]));
    let centre = [
        pivot[0] + 0.5 * l * phi0.sin(),
        pivot[1] - 0.5 * l * phi0.cos(),
    ];
    let pendulum = b.add_body(Body::new(
        "pendulum",
        2.0,
        2.0 * l * l / 12.0,
        [centre[0], centre[1], phi0],
    ));
    let s_j = [0.0, 0.5 * l];
    let joint = b.add_constraint(Revolute::new(
        "pivot",
        BodyRef::Ground,
        pivot,
        BodyRef::Body(pendulum),
        s_j,
    ));
    b.attach_kernels(
        joint..joint + 1,
        Box::new(PivotKernels {
            body: pendulum,
            p: [pivot[0], pivot[1], s_j[0], s_j[1]],
        }),
    );
    b.gravity([0.0, -9.81]);
    let mut sys = b.build().expect("the kernels' pattern matches the joint's");
    assert_eq!(sys.evaluation_name(), "example:pivot");

    // Kernels vs the generic evaluation at an arbitrary state.
    let q = [1.0, 0.5, 0.3, 0.4, -0.1, 0.7];
    let qd = [0.2, -0.1, 0.5, 1.5, -0.3, 2.0];
    let generated = everything(&sys, &q, &qd, 0.0);
    sys.set_evaluation(Evaluation::Generic).unwrap();
    let generic = everything(&sys, &q, &qd, 0.0);
    let diff = generated
        .iter()
        .zip(&generic)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    println!("generated vs generic: largest difference {diff:.1e}");
    assert!(diff <= 1e-14);

    // And a run with them.
    sys.set_evaluation(Evaluation::Auto).unwrap();
    let (q0, qd0) = sys.initial_state();
    let cfg = RunConfig {
        t_end: 1.0,
        ..RunConfig::default()
    };
    let (traj, summary) = simulate(&sys, &q0, &qd0, &cfg, &mut []).expect("runs");
    let last = traj.q.last().unwrap();
    println!(
        "{}: pendulum at t = {}: phi = {:.4} rad, ‖Φ‖ = {:.1e}",
        summary.status,
        traj.t.last().unwrap(),
        last[5],
        traj.constraint_norm.last().unwrap()
    );
}
