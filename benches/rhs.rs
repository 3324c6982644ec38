//! One full right-hand-side evaluation of the falling rod (forces,
//! constraint terms, sparse factorisation, solve) for N = 10 … 10 000.
//!
//! `cargo bench --bench rhs`; the log–log slope between N = 1000 and
//! 10 000 is the scaling figure reported in docs/scaling.md.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use mbsolve::builders::{build_rod, RodParams};
use mbsolve::formulation::{Index1, Index1Options};
use mbsolve::linalg::SolverKind;
use std::time::Duration;

fn rhs(c: &mut Criterion) {
    let mut group = c.benchmark_group("rhs_falling_rod");
    group.warm_up_time(Duration::from_millis(300));
    group.measurement_time(Duration::from_secs(2));
    group.sample_size(20);
    for n in [10usize, 100, 1000, 10_000] {
        let (sys, _) = build_rod(&RodParams::problem_b(n)).unwrap();
        let (q, mut qd) = sys.initial_state();
        for (i, v) in qd.iter_mut().enumerate() {
            *v += 1e-3 * ((i as f64) * 0.37).sin();
        }
        let mut qdd = vec![0.0; sys.n_coords()];
        for (label, kind) in [("sparse", SolverKind::Sparse), ("dense", SolverKind::Dense)] {
            if kind == SolverKind::Dense && n > 100 {
                continue; // dense LU at N = 1000 takes seconds per evaluation
            }
            let opts = Index1Options {
                linear_solver: kind,
                ..Default::default()
            };
            let mut f = Index1::new(&sys, opts).unwrap();
            group.bench_with_input(BenchmarkId::new(label, n), &n, |b, _| {
                b.iter(|| f.accelerations(0.0, &q, &qd, &mut qdd).unwrap())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, rhs);
criterion_main!(benches);
