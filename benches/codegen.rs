//! Generated (build-time `mbsolve-codegen`) vs generic (per-joint
//! `dyn Constraint`) evaluation of Φ + Φ_q + γ for the rod chain
//! (N bodies, N − 1 body–body revolutes, rod geometry of problem B (docs/problems.md)).
//!
//! * `phi_jac_gamma/generic/N`: `System::jacobian_values`, `gamma`, `phi`
//!   (the order of the index-1 formulation) with `Evaluation::Generic`;
//! * `phi_jac_gamma/generated/N`: the same three `System` calls with the
//!   generated kernels attached (what the formulation uses);
//! * `phi_jac_gamma/generated_fused/N`: `ChainKernels::evaluate`, one pass
//!   for all three (each body's sine and cosine computed once).
//!
//! Run: `cargo bench --bench codegen` (≈ 1 min).
//!
//! A new q every iteration. Measured figures: docs/codegen.md.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use mbsolve::constraints::Revolute;
use mbsolve::generated::{attach_generated, ChainKernels};
use mbsolve::model::{
    Body, BodyRef, ConstraintKernels, ConstraintTerms, Evaluation, System, SystemBuilder,
};
use std::hint::black_box;

fn rod_chain(n: usize) -> System {
    let ls = 1.0 / n as f64;
    let mut b = SystemBuilder::new();
    for i in 0..n {
        b.add_body(Body::new(
            format!("segment {}", i + 1),
            1.0,
            0.1,
            [0.0, (i as f64 + 0.5) * ls, 0.01],
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

fn state(n: usize) -> (Vec<f64>, Vec<f64>) {
    let q = (0..3 * n).map(|k| (k as f64 * 0.37).sin()).collect();
    let qd = (0..3 * n).map(|k| (k as f64 * 0.11).cos()).collect();
    (q, qd)
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("phi_jac_gamma");
    for &n in &[1000usize, 10_000] {
        let mut sys = rod_chain(n);
        assert!(attach_generated(&mut sys));
        let fused = ChainKernels::recognise(&sys).unwrap();
        // Two states, alternated: every iteration sees a new q (as every
        // right-hand-side evaluation of an integrator does), so the
        // per-body sine/cosine memo of the kernels must recompute.
        let (q, qd) = state(n);
        let q2: Vec<f64> = q.iter().map(|x| x + 1e-3).collect();
        let states = [&q, &q2];
        let m = sys.n_constraints();
        let nnz = sys.jacobian_pattern().len();
        let (mut phi, mut vals, mut gamma) = (vec![0.0; m], vec![0.0; nnz], vec![0.0; m]);
        for (label, ev) in [
            ("generic", Evaluation::Generic),
            ("generated", Evaluation::Generated),
        ] {
            sys.set_evaluation(ev).unwrap();
            let mut it = 0usize;
            g.bench_with_input(BenchmarkId::new(label, n), &n, |b, _| {
                b.iter(|| {
                    it += 1;
                    let q = black_box(states[it % 2]);
                    sys.jacobian_values(q, 0.0, &mut vals);
                    sys.gamma(q, black_box(&qd), 0.0, &mut gamma);
                    sys.phi(q, 0.0, &mut phi);
                    black_box((&phi, &vals, &gamma));
                })
            });
        }
        g.bench_with_input(BenchmarkId::new("generated_fused", n), &n, |b, _| {
            b.iter(|| {
                let out = ConstraintTerms {
                    phi: &mut phi,
                    vals: &mut vals,
                    gamma: &mut gamma,
                };
                fused.evaluate(black_box(&q), black_box(&qd), 0.0, out);
                black_box((&phi, &vals, &gamma));
            })
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = bench
}
criterion_main!(benches);
