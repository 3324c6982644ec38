//! Generated kernels (`mbsolve::generated`, emitted by `mbsolve-codegen` in
//! build.rs) against the generic per-joint evaluation: Φ, Φ_q values, Φ_t,
//! γ and (Φ_qᵀλ)_q on random states for rod chains (N = 1, 2, 10, 1000),
//! N-link pendulums and the four-bar; whole four-bar trajectories; force
//! kernels against the runtime's force elements; recognition.

use mbsolve::builders::{n_link_pendulum, RodParams};
use mbsolve::constraints::{Revolute, Translational};
use mbsolve::forces::{Drag, FdWorkspace, ForceElement, TorsionalSpringDamper, WallContact};
use mbsolve::generated::{self, attach_generated, kernels, ChainKernels, FourBarKernels};
use mbsolve::model::{
    Body, BodyRef, ConstraintKernels, ConstraintTerms, Evaluation, JointGeometry, System,
    SystemBuilder,
};
use mbsolve::scenario;
use mbsolve::scenario::FOURBAR_TOML;
use mbsolve::simulation::simulate;

struct Rng(u64);
impl Rng {
    fn uniform(&mut self, a: f64, b: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        a + (b - a) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
    fn vec(&mut self, n: usize, a: f64, b: f64) -> Vec<f64> {
        (0..n).map(|_| self.uniform(a, b)).collect()
    }
}

/// Rod-like chain: segment length `ls`, local y along the rod, ends at
/// (0, ∓ls/2); joint k: top of segment k = bottom of segment k+1.
fn rod_chain(n: usize, ls: f64) -> System {
    let mut b = SystemBuilder::new();
    for i in 0..n {
        let m = 7850.0 * 0.03 * 0.03 * ls;
        b.add_body(Body::new(
            format!("segment {}", i + 1),
            m,
            m * (ls * ls + 0.03 * 0.03) / 12.0,
            [0.0, (i as f64 + 0.5) * ls, 0.0],
        ));
    }
    for i in 0..n.saturating_sub(1) {
        b.add_constraint(Revolute::new(
            format!("joint {}", i + 1),
            BodyRef::Body(i),
            [0.0, 0.5 * ls],
            BodyRef::Body(i + 1),
            [0.0, -0.5 * ls],
        ));
    }
    b.build().unwrap()
}

fn rel_close(label: &str, a: &[f64], b: &[f64], tol: f64) {
    assert_eq!(a.len(), b.len(), "{label}: lengths");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        let scale = x.abs().max(y.abs()).max(1e-300);
        assert!(
            (x - y).abs() <= tol * scale || (x - y).abs() <= 1e-15,
            "{label}[{k}]: generic {x:e} vs generated {y:e}"
        );
    }
}

/// Generic (dyn Constraint loop) vs generated evaluation of everything the
/// kernels provide, on `samples` random states.
fn compare(sys: &mut System, r: &mut Rng, samples: usize) {
    assert!(attach_generated(sys), "topology not recognised");
    let (n, m, nnz) = (
        sys.n_coords(),
        sys.n_constraints(),
        sys.jacobian_pattern().len(),
    );
    for _ in 0..samples {
        let q = r.vec(n, -2.0, 2.0);
        let qd = r.vec(n, -3.0, 3.0);
        let t = r.uniform(0.0, 5.0);
        let mut res = Vec::new();
        for ev in [Evaluation::Generic, Evaluation::Generated] {
            sys.set_evaluation(ev).unwrap();
            let (mut phi, mut vals, mut phi_t, mut gamma) =
                (vec![0.0; m], vec![0.0; nnz], vec![7.0; m], vec![0.0; m]);
            sys.phi(&q, t, &mut phi);
            sys.jacobian_values(&q, t, &mut vals);
            sys.phi_t(&q, t, &mut phi_t);
            sys.gamma(&q, &qd, t, &mut gamma);
            // the index-3 residual's fused constraint part (Φ and Φ_qᵀλ
            // without the Φ_q values where the kernels have it) against Φ
            // and Φ_qᵀλ from the values and the pattern
            let lam = r.vec(m, -1.0, 1.0);
            let (mut phi2, mut tmul, mut scratch) = (vec![0.0; m], vec![5.0; n], vec![0.0; nnz]);
            sys.phi_and_jacobian_tmul(&q, t, &lam, &mut phi2, &mut tmul, &mut scratch);
            let mut want = vec![0.0; n];
            sys.jacobian_tmul(&vals, &lam, &mut want);
            rel_close("Φ (fused with Φ_qᵀλ)", &phi, &phi2, 1e-13);
            // sums of a few terms of either sign: to rounding of the largest
            let scale = want.iter().fold(1e-300_f64, |a, x| a.max(x.abs()));
            for (k, (x, y)) in want.iter().zip(&tmul).enumerate() {
                assert!(
                    (x - y).abs() <= 1e-13 * scale,
                    "{ev:?} Φ_qᵀλ[{k}]: {x:e} from Φ_q, {y:e} fused"
                );
            }
            res.push((phi, vals, phi_t, gamma));
        }
        let (g, k) = (&res[0], &res[1]);
        rel_close("Φ", &g.0, &k.0, 1e-13);
        rel_close("Φ_q", &g.1, &k.1, 1e-13);
        rel_close("Φ_t", &g.2, &k.2, 1e-13);
        rel_close("γ", &g.3, &k.3, 1e-13);
    }
    sys.set_evaluation(Evaluation::Auto).unwrap();
}

/// (Φ_qᵀλ)_q joint by joint from the generic joints.
fn generic_hessian(sys: &System, q: &[f64], lambda: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    for (k, c) in sys.constraints().iter().enumerate() {
        let mut v = vec![0.0; c.hessian_pattern().len()];
        let r0 = sys.row_offset(k);
        c.add_hessian(
            q,
            0.0,
            &lambda[r0..r0 + c.n_eq()],
            &mut v,
            &mut mbsolve::model::FdWorkspace::default(),
        );
        out.extend(v);
    }
    out
}

#[test]
fn rod_chains_match_generic() {
    let mut r = Rng(0x5DEE_CE66_D1CE_4E5B);
    for (n, samples) in [(1usize, 5usize), (2, 20), (10, 20), (1000, 3)] {
        let mut sys = rod_chain(n, 1.0 / n as f64);
        compare(&mut sys, &mut r, samples);
        assert_eq!(sys.evaluation_name(), "generated:rod_chain");
        // (Φ_qᵀλ)_q
        let k = ChainKernels::recognise(&sys).unwrap();
        let q = r.vec(sys.n_coords(), -2.0, 2.0);
        let lam = r.vec(sys.n_constraints(), -1.0, 1.0);
        let want = generic_hessian(&sys, &q, &lam);
        let mut got = vec![0.0; want.len()];
        k.add_hessian(&q, 0.0, &lam, &mut got);
        rel_close("(Φ_qᵀλ)_q", &want, &got, 1e-13);
        // fused evaluation = the three separate ones
        let qd = r.vec(sys.n_coords(), -1.0, 1.0);
        let (m, nnz) = (sys.n_constraints(), sys.jacobian_pattern().len());
        let (mut a, mut b, mut c) = (vec![0.0; m], vec![0.0; nnz], vec![0.0; m]);
        let out = ConstraintTerms {
            phi: &mut a,
            vals: &mut b,
            gamma: &mut c,
        };
        k.evaluate(&q, &qd, 0.0, out);
        let (mut a2, mut b2, mut c2) = (vec![0.0; m], vec![0.0; nnz], vec![0.0; m]);
        sys.set_evaluation(Evaluation::Generic).unwrap();
        sys.phi(&q, 0.0, &mut a2);
        sys.jacobian_values(&q, 0.0, &mut b2);
        sys.gamma(&q, &qd, 0.0, &mut c2);
        rel_close("fused Φ", &a2, &a, 1e-13);
        rel_close("fused Φ_q", &b2, &b, 1e-13);
        rel_close("fused γ", &c2, &c, 1e-13);
    }
}

#[test]
fn any_segment_length_uses_the_same_kernels() {
    let mut r = Rng(17);
    for ls in [1e-3, 0.1, 2.5] {
        let mut sys = rod_chain(7, ls);
        compare(&mut sys, &mut r, 5);
    }
}

#[test]
fn pendulums_match_generic() {
    let mut r = Rng(99);
    // The builder (pivot joint added last, ground on side i).
    for (n, len) in [(1usize, 0.7), (3, 0.25), (50, 0.02)] {
        let (mut sys, _) = n_link_pendulum(n, len, 0.3, 0.2, 9.81).unwrap();
        compare(&mut sys, &mut r, 5);
        assert_eq!(sys.evaluation_name(), "generated:pendulum_chain");
        let k = ChainKernels::recognise(&sys).unwrap();
        let q = r.vec(sys.n_coords(), -2.0, 2.0);
        let lam = r.vec(sys.n_constraints(), -1.0, 1.0);
        let want = generic_hessian(&sys, &q, &lam);
        let mut got = vec![0.0; want.len()];
        k.add_hessian(&q, 0.0, &lam, &mut got);
        rel_close("(Φ_qᵀλ)_q", &want, &got, 1e-13);
    }
    // Pivot first, ground on side j, attached to the last body.
    for n in [1usize, 4] {
        let ls = 0.3;
        let mut b = SystemBuilder::new();
        for i in 0..n {
            b.add_body(Body::new(format!("l{i}"), 1.0, 0.1, [0.0, 0.0, 0.0]));
        }
        b.add_constraint(Revolute::new(
            "pivot",
            BodyRef::Body(n - 1),
            [0.1, 0.5 * ls],
            BodyRef::Ground,
            [0.3, -0.2],
        ));
        for i in 0..n - 1 {
            b.add_constraint(Revolute::new(
                "link",
                BodyRef::Body(i),
                [0.02, 0.5 * ls],
                BodyRef::Body(i + 1),
                [-0.01, -0.5 * ls],
            ));
        }
        let mut sys = b.build().unwrap();
        compare(&mut sys, &mut r, 10);
        let k = ChainKernels::recognise(&sys).unwrap();
        let q = r.vec(sys.n_coords(), -2.0, 2.0);
        let lam = r.vec(sys.n_constraints(), -1.0, 1.0);
        let want = generic_hessian(&sys, &q, &lam);
        let mut got = vec![0.0; want.len()];
        k.add_hessian(&q, 0.0, &lam, &mut got);
        rel_close("(Φ_qᵀλ)_q", &want, &got, 1e-13);
    }
}

fn fourbar() -> scenario::Scenario {
    scenario::parse(FOURBAR_TOML, "fourbar.toml", "fourbar", &[]).unwrap()
}

#[test]
fn fourbar_matches_generic() {
    let mut sc = fourbar();
    assert!(FourBarKernels::recognise(&sc.system).is_some());
    let mut r = Rng(4);
    compare(&mut sc.system, &mut r, 50);
    assert_eq!(sc.system.evaluation_name(), "generated:fourbar");
    let k = FourBarKernels::recognise(&sc.system).unwrap();
    for _ in 0..10 {
        let q = r.vec(9, -2.0, 2.0);
        let lam = r.vec(8, -1.0, 1.0);
        let want = generic_hessian(&sc.system, &q, &lam);
        let mut got = vec![0.0; want.len()];
        k.add_hessian(&q, 0.0, &lam, &mut got);
        rel_close("(Φ_qᵀλ)_q", &want, &got, 1e-13);
    }
}

#[test]
fn fourbar_trajectories_agree() {
    let mut runs = Vec::new();
    for ev in [Evaluation::Generic, Evaluation::Generated] {
        for incorrect in [false, true] {
            let o = [
                format!("initial.incorrect={incorrect}"),
                "stabilization.alpha=5".to_string(),
                "stabilization.beta=5".to_string(),
            ];
            let mut sc = scenario::parse(FOURBAR_TOML, "fourbar.toml", "fourbar", &o).unwrap();
            attach_generated(&mut sc.system);
            sc.system.set_evaluation(ev).unwrap();
            let (traj, _) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
            runs.push(traj);
        }
    }
    for k in 0..2 {
        let (a, b) = (&runs[k], &runs[k + 2]);
        assert_eq!(a.t.len(), b.t.len(), "same output times");
        let (qa, qb) = (a.q.last().unwrap(), b.q.last().unwrap());
        let (va, vb) = (a.qd.last().unwrap(), b.qd.last().unwrap());
        let dmax = qa
            .iter()
            .zip(qb)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "four-bar run {k}: {} output times, max |Δq(t_end)| = {dmax:e}",
            a.t.len()
        );
        for i in 0..9 {
            assert!(
                (qa[i] - qb[i]).abs() <= 1e-12 * (1.0 + qa[i].abs()),
                "q{i}: {} vs {}",
                qa[i],
                qb[i]
            );
            assert!(
                (va[i] - vb[i]).abs() <= 1e-11 * (1.0 + va[i].abs()),
                "q̇{i}: {} vs {}",
                va[i],
                vb[i]
            );
        }
    }
}

#[test]
fn other_topologies_are_not_recognised() {
    // a translational joint
    let mut b = SystemBuilder::new();
    b.add_body(Body::new("a", 1.0, 1.0, [0.0; 3]));
    b.add_body(Body::new("b", 1.0, 1.0, [0.0; 3]));
    b.add_constraint(Translational::new(
        "s",
        BodyRef::Body(0),
        [0.0; 2],
        [1.0, 0.0],
        BodyRef::Body(1),
        [0.0; 2],
        0.0,
    ));
    let mut sys = b.build().unwrap();
    assert!(generated::recognise(&sys).is_none());
    assert!(!attach_generated(&mut sys));
    assert_eq!(sys.evaluation_name(), "generic");
    assert!(sys.set_evaluation(Evaluation::Generated).is_err());
    // a chain with swapped sides, and one with a body gap
    for (i, j) in [(1, 0), (0, 2)] {
        let mut b = SystemBuilder::new();
        for _ in 0..3 {
            b.add_body(Body::new("x", 1.0, 1.0, [0.0; 3]));
        }
        b.add_constraint(Revolute::new(
            "r",
            BodyRef::Body(i),
            [0.0; 2],
            BodyRef::Body(j),
            [0.0; 2],
        ));
        b.add_constraint(Revolute::new(
            "r",
            BodyRef::Body(1),
            [0.0; 2],
            BodyRef::Body(2),
            [0.0; 2],
        ));
        assert!(generated::recognise(&b.build().unwrap()).is_none());
    }
    // two ground joints on a chain (not a four-bar: 2 bodies)
    let mut b = SystemBuilder::new();
    b.add_body(Body::new("x", 1.0, 1.0, [0.0; 3]));
    b.add_body(Body::new("y", 1.0, 1.0, [0.0; 3]));
    b.add_constraint(Revolute::new(
        "g1",
        BodyRef::Ground,
        [0.0; 2],
        BodyRef::Body(0),
        [0.0; 2],
    ));
    b.add_constraint(Revolute::new(
        "c",
        BodyRef::Body(0),
        [0.0; 2],
        BodyRef::Body(1),
        [0.0; 2],
    ));
    b.add_constraint(Revolute::new(
        "g2",
        BodyRef::Ground,
        [1.0, 0.0],
        BodyRef::Body(1),
        [0.0; 2],
    ));
    assert!(generated::recognise(&b.build().unwrap()).is_none());
    // the four-bar with its joints in another order
    let sc = fourbar();
    let mut b = SystemBuilder::new();
    for body in sc.system.bodies() {
        b.add_body(body.clone());
    }
    for k in [1, 0, 2, 3] {
        let JointGeometry::Revolute { i, j } = sc.system.constraints()[k].geometry() else {
            panic!("the four-bar has revolutes only")
        };
        b.add_constraint(Revolute::new(
            format!("j{k}"),
            i.body,
            i.point,
            j.body,
            j.point,
        ));
    }
    assert!(generated::recognise(&b.build().unwrap()).is_none());
}

/// Force kernels (torsional spring–dampers along a chain, drag on every
/// body) against the runtime's force elements.
#[test]
fn force_kernels_match_runtime_elements() {
    let mut r = Rng(31337);
    let n = 6;
    let (k, c, rest) = (123.0, 0.45, 0.01);
    let springs: Vec<TorsionalSpringDamper> = (0..n - 1)
        .map(|i| TorsionalSpringDamper {
            rest_angle: rest,
            ..TorsionalSpringDamper::new(BodyRef::Body(i), BodyRef::Body(i + 1), k, c)
        })
        .collect();
    let drags: Vec<Drag> = (0..n)
        .map(|i| Drag {
            body: i,
            width: 0.03,
            length: 0.1,
            fluid_density: 1000.0,
            c_transverse: 1.2,
            c_skin: 0.02,
            c_end: 1.0,
            end_face: i == 0,
        })
        .collect();
    let fp_springs: Vec<f64> = springs
        .iter()
        .flat_map(|s| [s.k, s.c, s.rest_angle])
        .collect();
    let fp_drag: Vec<f64> = drags
        .iter()
        .flat_map(|d| {
            let (rho, w, l) = (d.fluid_density, d.width, d.length);
            let end = if d.end_face { d.c_end * w * w } else { 0.0 };
            [
                -0.5 * rho * d.c_transverse * w * l,
                -0.5 * rho * (d.c_skin * 4.0 * w * l + end),
                -rho * d.c_transverse * w * l.powi(4) / 64.0,
            ]
        })
        .collect();
    let mut ws = FdWorkspace::default();
    for _ in 0..10 {
        let q = r.vec(3 * n, -2.0, 2.0);
        let qd = r.vec(3 * n, -3.0, 3.0);
        // forces
        let mut want = vec![0.0; 3 * n];
        for s in &springs {
            s.add_forces(0.0, &q, &qd, &mut want);
        }
        for d in &drags {
            d.add_forces(0.0, &q, &qd, &mut want);
        }
        let mut got = vec![0.0; 3 * n];
        kernels::torsional_chain_forces(&q, &qd, &fp_springs, &mut got);
        kernels::drag_bodies_forces(&q, &qd, &fp_drag, &mut got);
        rel_close("g", &want, &got, 1e-13);
        // Jacobians, element by element (same k×k layout as the runtime)
        let (mut dq, mut dqd) = (vec![0.0; 4 * (n - 1)], vec![0.0; 4 * (n - 1)]);
        kernels::torsional_chain_force_jacobians(&q, &qd, &fp_springs, &mut dq, &mut dqd);
        for (i, s) in springs.iter().enumerate() {
            let (mut a, mut b) = (vec![0.0; 4], vec![0.0; 4]);
            s.add_jacobians(
                0.0,
                &q,
                &qd,
                mbsolve::forces::ForceJacobians {
                    dq: &mut a,
                    dqd: &mut b,
                    ws: &mut ws,
                },
            );
            rel_close("spring ∂g/∂q", &a, &dq[4 * i..4 * i + 4], 1e-13);
            rel_close("spring ∂g/∂q̇", &b, &dqd[4 * i..4 * i + 4], 1e-13);
        }
        let (mut dq, mut dqd) = (vec![0.0; 9 * n], vec![0.0; 9 * n]);
        kernels::drag_bodies_force_jacobians(&q, &qd, &fp_drag, &mut dq, &mut dqd);
        for (i, d) in drags.iter().enumerate() {
            let (mut a, mut b) = (vec![0.0; 9], vec![0.0; 9]);
            d.add_jacobians(
                0.0,
                &q,
                &qd,
                mbsolve::forces::ForceJacobians {
                    dq: &mut a,
                    dqd: &mut b,
                    ws: &mut ws,
                },
            );
            rel_close("drag ∂g/∂q", &a, &dq[9 * i..9 * i + 9], 1e-12);
            rel_close("drag ∂g/∂q̇", &b, &dqd[9 * i..9 * i + 9], 1e-12);
        }
    }
}

/// The kernels' per-body sine/cosine memo: changing one angle, or
/// evaluating from several threads at once, gives the generic values.
#[test]
fn trig_memo_is_exact_under_partial_updates_and_threads() {
    let n = 40;
    let mut sys = rod_chain(n, 0.05);
    assert!(attach_generated(&mut sys));
    let mut r = Rng(8);
    let m = sys.n_constraints();
    let nnz = sys.jacobian_pattern().len();
    let eval = |sys: &System, q: &[f64], qd: &[f64]| {
        let (mut a, mut b, mut c) = (vec![0.0; m], vec![0.0; nnz], vec![0.0; m]);
        sys.jacobian_values(q, 0.0, &mut b);
        sys.gamma(q, qd, 0.0, &mut c);
        sys.phi(q, 0.0, &mut a);
        [a, b, c].concat()
    };
    let mut generic = rod_chain(n, 0.05);
    generic.set_evaluation(Evaluation::Generic).unwrap();
    let mut q = r.vec(3 * n, -2.0, 2.0);
    let qd = r.vec(3 * n, -2.0, 2.0);
    for step in 0..20 {
        q[3 * (step % n) + 2] += 0.1; // one angle changes
        q[3 * ((7 * step) % n)] -= 0.05; // and one position
        rel_close(
            "memo",
            &eval(&generic, &q, &qd),
            &eval(&sys, &q, &qd),
            1e-13,
        );
    }
    let states: Vec<(Vec<f64>, Vec<f64>)> = (0..8)
        .map(|_| (r.vec(3 * n, -2.0, 2.0), r.vec(3 * n, -2.0, 2.0)))
        .collect();
    let want: Vec<Vec<f64>> = states.iter().map(|(q, qd)| eval(&generic, q, qd)).collect();
    std::thread::scope(|s| {
        for t in 0..4 {
            let (sys, states, want) = (&sys, &states, &want);
            s.spawn(move || {
                for rep in 0..200 {
                    let k = (t + rep) % states.len();
                    let got = eval(sys, &states[k].0, &states[k].1);
                    rel_close("threads", &want[k], &got, 1e-13);
                }
            });
        }
    });
}

/// Hunt–Crossley wall contact (docs/problems.md, problem B): generated forces and
/// Jacobians against the runtime's `WallContact`, on states where corners
/// penetrate the walls.
#[test]
fn contact_kernels_match_runtime_elements() {
    let n = 5;
    let ls = 0.1;
    let elems: Vec<WallContact> = (0..n)
        .map(|i| RodParams::problem_b(10).contact_element(i, i))
        .collect();
    let fp: Vec<f64> = elems
        .iter()
        .flat_map(|e| {
            [
                0.5 * e.width,
                0.5 * e.length,
                e.left_wall,
                e.right_wall,
                e.law.stiffness,
                e.law.damping,
                e.law.friction,
                e.law.slip_velocity,
            ]
        })
        .collect();
    let mut r = Rng(2718);
    let mut ws = FdWorkspace::default();
    let mut touching = 0;
    for _ in 0..50 {
        let mut q = vec![0.0; 3 * n];
        let mut qd = vec![0.0; 3 * n];
        for b in 0..n {
            q[3 * b] = r.uniform(-0.02, 0.02);
            q[3 * b + 1] = b as f64 * ls;
            q[3 * b + 2] = r.uniform(-0.3, 0.3);
            qd[3 * b] = r.uniform(-0.2, 0.2);
            qd[3 * b + 1] = r.uniform(-0.01, 0.01);
            qd[3 * b + 2] = r.uniform(-1.0, 1.0);
        }
        let base = r.vec(3 * n, -1.0, 1.0); // forces already in g
        let mut want = base.clone();
        for e in &elems {
            e.add_forces(0.0, &q, &qd, &mut want);
        }
        let mut got = base.clone();
        kernels::contact_bodies_forces(&q, &qd, &fp, &mut got);
        rel_close("contact g", &want, &got, 1e-13);
        let (mut dq, mut dqd) = (vec![0.0; 9 * n], vec![0.0; 9 * n]);
        kernels::contact_bodies_force_jacobians(&q, &qd, &fp, &mut dq, &mut dqd);
        for (i, e) in elems.iter().enumerate() {
            let (mut a, mut b) = (vec![0.0; 9], vec![0.0; 9]);
            e.add_jacobians(
                0.0,
                &q,
                &qd,
                mbsolve::forces::ForceJacobians {
                    dq: &mut a,
                    dqd: &mut b,
                    ws: &mut ws,
                },
            );
            if a.iter().any(|&x| x != 0.0) {
                touching += 1;
            }
            rel_close("contact ∂g/∂q", &a, &dq[9 * i..9 * i + 9], 1e-12);
            rel_close("contact ∂g/∂q̇", &b, &dqd[9 * i..9 * i + 9], 1e-12);
        }
    }
    assert!(touching > 50, "only {touching} segments in contact");
}

/// With the torsional-chain kernels attached, the forces g come from the
/// generated loop (`ForceKernels::add_forces`) and must be bit-identical to
/// the elements' (so the explicit methods' trajectories do not depend on
/// the evaluation): the stiff chain (springs from the ground and between
/// neighbours) and the rod (springs, drag, contacts) at random states.
#[test]
fn generated_forces_are_bit_identical_to_the_elements() {
    let mut r = Rng(4242);
    let (stiff, _, _, _) = mbsolve::builders::stiff_chain(50, 0.1).unwrap();
    let (rod, _) =
        mbsolve::builders::build_rod(&mbsolve::builders::RodParams::problem_b(40)).unwrap();
    for (name, mut sys) in [("stiff chain", stiff), ("rod", rod)] {
        assert!(
            sys.force_kernel_names()
                .contains(&"generated:torsional_chain"),
            "{name}: {:?}",
            sys.force_kernel_names()
        );
        if name == "rod" {
            assert!(
                sys.force_kernel_names().contains(&"generated:drag_bodies"),
                "{:?}",
                sys.force_kernel_names()
            );
        }
        let n = sys.n_coords();
        for _ in 0..5 {
            let q = r.vec(n, -2.0, 2.0);
            let qd = r.vec(n, -3.0, 3.0);
            let mut g = Vec::new();
            for ev in [Evaluation::Generic, Evaluation::Generated] {
                sys.set_evaluation(ev).unwrap();
                let mut gi = vec![f64::NAN; n];
                sys.forces_into(0.3, &q, &qd, &mut gi);
                g.push(gi);
            }
            for (k, (a, b)) in g[0].iter().zip(&g[1]).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "{name} g[{k}]: {a:e} vs {b:e}");
            }
        }
    }
}
