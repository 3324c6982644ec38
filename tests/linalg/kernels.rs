//! Generated kernels at run time: attached by the builders to ranges of
//! joints, used for Φ, Φ_q, γ and for (Φ_qᵀλ)_q in the Newton matrix of
//! the implicit methods; the Newton-matrix assembly allocates nothing.

use mbsolve::builders::{add_rod, build_rod, n_link_pendulum, RodParams};
use mbsolve::constraints::{Revolute, Translational};
use mbsolve::forces::{ForceElement, Gravity};
use mbsolve::formulation::{Index3, NewtonSolverKind};
use mbsolve::linalg::SolverKind;
use mbsolve::model::{Body, BodyRef, Evaluation, FdWorkspace, System, SystemBuilder};
use mbsolve::scenario::{self, FALLING_ROD_TOML};
use mbsolve::simulation::simulate;

use crate::counting::allocations;

/// Deterministic pseudo-random numbers (xorshift).
struct Rng(u64);
impl Rng {
    fn unif(&mut self, a: f64, b: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        a + (b - a) * (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn vec(&mut self, n: usize, a: f64, b: f64) -> Vec<f64> {
        (0..n).map(|_| self.unif(a, b)).collect()
    }
}

fn close(label: &str, a: &[f64], b: &[f64], tol: f64) {
    assert_eq!(a.len(), b.len(), "{label}: lengths");
    let scale = a.iter().chain(b).fold(0.0_f64, |m, v| m.max(v.abs()));
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= tol * scale.max(1e-300),
            "{label}[{k}]: {x:e} vs {y:e} (scale {scale:e})"
        );
    }
}

/// A state near the system's initial one.
fn perturbed(sys: &System, r: &mut Rng) -> (Vec<f64>, Vec<f64>) {
    let (q0, _) = sys.initial_state();
    let q = q0.iter().map(|v| v + r.unif(-2e-3, 2e-3)).collect();
    (q, r.vec(q0.len(), -0.2, 0.2))
}

/// The Newton matrix of `sys` assembled with its kernels and generically.
fn newton_values(sys: &mut System, q: &[f64], qd: &[f64], lam: &[f64]) -> [Vec<f64>; 2] {
    let mut out = [Vec::new(), Vec::new()];
    for (k, ev) in [Evaluation::Auto, Evaluation::Generic].iter().enumerate() {
        sys.set_evaluation(*ev).unwrap();
        // dense LU: pivoting copes with the indefinite in-wall states
        let mut ix = Index3::new(sys, SolverKind::Dense).unwrap();
        ix.assemble_and_factorize(0.0, q, qd, lam, 1.0, 5e-4, 2.5e-7)
            .unwrap();
        out[k] = ix.newton_matrix().values().to_vec();
    }
    out
}

#[test]
fn newton_matrix_with_kernels_equals_generic() {
    let mut r = Rng(0x9E37_79B9_7F4A_7C15);
    let (rod, _) = build_rod(&RodParams::problem_b(20)).unwrap();
    let (pend, _) = n_link_pendulum(8, 0.25, 0.5, 0.3, 9.81).unwrap();
    assert_eq!(
        rod.force_kernel_names(),
        [
            "generated:torsional_chain",
            "generated:drag_bodies",
            "generated:contact_bodies"
        ]
    );
    for (mut sys, name) in [
        (rod, "generated:rod_chain"),
        (pend, "generated:pendulum_chain"),
    ] {
        assert_eq!(sys.evaluation_name(), name);
        for sample in 0..4 {
            let (mut q, qd) = perturbed(&sys, &mut r);
            if sample == 3 {
                // into the right wall: the contact Jacobians are non-zero
                for b in 0..sys.bodies().len() {
                    q[3 * b] += 0.012;
                }
            }
            let lam = r.vec(sys.n_constraints(), -1.0, 1.0);
            let [with, without] = newton_values(&mut sys, &q, &qd, &lam);
            close(name, &with, &without, 1e-13);
            // (Φ_qᵀλ)_q is in there: with λ scaled, the matrix changes
            let lam2: Vec<f64> = lam.iter().map(|v| 3.0 * v).collect();
            let [with2, _] = newton_values(&mut sys, &q, &qd, &lam2);
            assert!(with2 != with, "{name}: the Hessian term is missing");
        }
    }
}

/// A rod inside a larger mechanism: a pendulum block on a ground pivot,
/// the rod, a pin from the block to the rod's top, and a slider. The
/// builder's kernels cover the rod's joints only; everything agrees with
/// the generic evaluation, and the Newton-matrix assembly allocates nothing
/// (finite-difference Hessian of the slider and finite-difference
/// Jacobians of a user force included).
#[test]
fn a_rod_inside_a_mechanism_keeps_its_kernels_and_assembles_without_allocating() {
    let mut b = SystemBuilder::new();
    let block = b.add_body(Body::new("block", 2.0, 0.1, [0.0, 0.6, 0.0]));
    b.add_constraint(Revolute::new(
        "pivot",
        BodyRef::Ground,
        [0.0, 0.8],
        BodyRef::Body(block),
        [0.0, 0.2],
    ));
    let mut params = RodParams::problem_b(12);
    params.tilt = 0.0;
    let info = add_rod(&mut b, &params).unwrap();
    let top = *info.bodies.last().unwrap();
    let ls = params.segment_length();
    b.add_constraint(Revolute::new(
        "block–rod",
        BodyRef::Body(block),
        [0.0, -0.2],
        BodyRef::Body(top),
        [0.0, 0.5 * ls],
    ));
    let slider = b.add_body(Body::new("slider", 0.3, 0.01, [0.3, 0.6, 0.0]));
    b.add_constraint(Translational::new(
        "slide",
        BodyRef::Body(block),
        [0.0, 0.0],
        [1.0, 0.0],
        BodyRef::Body(slider),
        [0.0, 0.0],
        0.0,
    ));
    b.add_force(Tether {
        a: block,
        b: slider,
        k: 40.0,
    });
    b.add_force(Gravity {
        g: [0.0, -9.81],
        bodies: vec![(block, 2.0), (slider, 0.3)],
    });
    let mut sys = b.build().unwrap();
    assert_eq!(sys.evaluation_name(), "generated:rod_chain+generic");

    let mut r = Rng(77);
    let (q, qd) = perturbed(&sys, &mut r);
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let lam = r.vec(m, -1.0, 1.0);
    // constraint terms and Hessians against the generic evaluation
    let mut got = [
        vec![0.0; m],
        vec![0.0; sys.jacobian_pattern().len()],
        vec![0.0; m],
    ];
    let mut want = got.clone();
    let nh = sys.hessian_pattern().len();
    let (mut h_got, mut h_want) = (vec![0.0; nh], vec![0.0; nh]);
    let mut ws = FdWorkspace::default();
    for (ev, out, h) in [
        (Evaluation::Auto, &mut got, &mut h_got),
        (Evaluation::Generic, &mut want, &mut h_want),
    ] {
        sys.set_evaluation(ev).unwrap();
        let [phi, vals, gamma] = out;
        sys.constraint_terms(&q, &qd, 0.0, Some(phi), vals, gamma);
        sys.add_constraint_hessians(&q, 0.0, &lam, h, &mut ws);
    }
    for (k, label) in ["Φ", "Φ_q", "γ"].iter().enumerate() {
        close(label, &got[k], &want[k], 1e-13);
    }
    close("(Φ_qᵀλ)_q", &h_got, &h_want, 1e-7); // the slider's is by finite differences

    sys.set_evaluation(Evaluation::Auto).unwrap();
    // symmetric LDLᵀ (modified Newton) and sparse LU (exact Newton)
    for newton in [NewtonSolverKind::SymmetricLdlt, NewtonSolverKind::SparseLu] {
        let mut ix = Index3::with_newton_solver(&sys, SolverKind::Sparse, newton).unwrap();
        ix.assemble_and_factorize(0.0, &q, &qd, &lam, 1.0, 5e-4, 2.5e-7)
            .unwrap(); // first call: per-element caches
        let states: Vec<Vec<f64>> = (1..4)
            .map(|s| q.iter().map(|v| v + 1e-4 * s as f64).collect())
            .collect();
        let mut rhs = vec![1.0; n + m];
        let before = allocations();
        for q2 in &states {
            ix.assemble_and_factorize(0.0, q2, &qd, &lam, 1.0, 5e-4, 2.5e-7)
                .unwrap();
            rhs.fill(1.0);
            ix.solve_newton(0.0, &mut rhs).unwrap();
        }
        assert_eq!(
            allocations() - before,
            0,
            "{newton:?}: Newton assembly, factorisation and solve allocate"
        );
    }
}

/// A nonlinear spring between two body centres with only `add_forces`:
/// its Jacobians come from the finite-difference default.
#[derive(Debug)]
struct Tether {
    a: usize,
    b: usize,
    k: f64,
}

impl ForceElement for Tether {
    fn name(&self) -> String {
        "tether".into()
    }
    fn coordinates(&self) -> Vec<usize> {
        vec![3 * self.a, 3 * self.a + 1, 3 * self.b, 3 * self.b + 1]
    }
    fn add_forces(&self, _t: f64, q: &[f64], _qd: &[f64], g: &mut [f64]) {
        let d = [
            q[3 * self.b] - q[3 * self.a],
            q[3 * self.b + 1] - q[3 * self.a + 1],
        ];
        let l = d[0].hypot(d[1]);
        let f = self.k * (l - 0.2) * l; // stiffening
        for i in 0..2 {
            g[3 * self.a + i] += f * d[i] / l;
            g[3 * self.b + i] -= f * d[i] / l;
        }
    }
}

/// Generalized-α on the rod (N = 20, contacts and fluid) with the kernels
/// and with the generic evaluation: the same trajectory to roundoff.
#[test]
fn genalpha_with_kernels_agrees_with_generic() {
    let mut finals = Vec::new();
    for ev in ["auto", "generic"] {
        let o = [
            "rod.segments=20".to_string(),
            "integrator.method=\"genalpha\"".to_string(),
            "integrator.step=1e-4".to_string(),
            "time.end=0.06".to_string(),
            format!("constraints.evaluation=\"{ev}\""),
        ];
        let sc = scenario::parse(FALLING_ROD_TOML, "falling_rod.toml", "falling_rod", &o).unwrap();
        assert_eq!(sc.system.uses_kernels(), ev == "auto");
        let (traj, summary) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
        assert_eq!(summary.status, "completed");
        finals.push(traj.q.last().unwrap().clone());
    }
    close("final q", &finals[0], &finals[1], 1e-10);
}
