//! Speed of the analyses on the peers' stiff chain (`builders::stiff_chain`,
//! every segment released at 5°): the static equilibrium from the released
//! state and the 10 lowest modes about it, at N = 1000 and 10 000.
//!
//! ```text
//! cargo bench --bench analysis            # criterion, both analyses, both N
//! cargo bench --bench analysis -- slope   # only the printed times and slopes
//! ```
//!
//! `slope`: each analysis at N = 1000 and 10 000, interleaved, the minimum
//! over batches of the wall time per call (one thread of work: the
//! analyses do not open a team), and the slope
//! `log(t₁₀₀₀₀ / t₁₀₀₀) / log 10` of the cost in N. The budgets are 1 s
//! for the static equilibrium and 2 s for the modes at N = 10 000, a slope
//! of at most 1.1.
//!
//! The falling rod of problem B is not a case here: a free rod under
//! gravity has no static equilibrium (docs/analyses.md).

use criterion::{criterion_group, BenchmarkId, Criterion};
use mbsolve::analysis::{
    eigenmodes, static_equilibrium, Equilibrium, ModeOptions, StaticOptions, Tangent,
};
use mbsolve::builders::stiff_chain;
use mbsolve::model::System;
use std::hint::black_box;
use std::time::{Duration, Instant};

/// The chain, its released state and its static equilibrium.
fn chain(n: usize) -> (System, Vec<f64>, Equilibrium) {
    let (sys, q0, _, _) = stiff_chain(n, 5f64.to_radians()).expect("the stiff chain builds");
    let eq = static_equilibrium(&sys, &q0, StaticOptions::default()).expect("an equilibrium");
    (sys, q0, eq)
}

/// The tangent matrices about the equilibrium.
fn tangent<'a>(sys: &'a System, eq: &Equilibrium) -> Tangent<'a> {
    let mut tan = Tangent::new(sys);
    tan.evaluate(0.0, &eq.q, &vec![0.0; eq.q.len()], &eq.lambda)
        .expect("the tangent matrices");
    tan
}

/// The 10 lowest modes, the other options at their defaults.
fn modes10() -> ModeOptions {
    ModeOptions {
        count: 10,
        ..Default::default()
    }
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("analysis");
    g.sample_size(10).measurement_time(Duration::from_secs(3));
    for n in [1000usize, 10_000] {
        let (sys, q0, eq) = chain(n);
        g.bench_with_input(BenchmarkId::new("static", n), &n, |b, _| {
            b.iter(|| static_equilibrium(&sys, black_box(&q0), StaticOptions::default()))
        });
        let tan = tangent(&sys, &eq);
        g.bench_with_input(BenchmarkId::new("modes10", n), &n, |b, _| {
            b.iter(|| eigenmodes(black_box(&tan), modes10()))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);

/// Minimum over `batches` of the mean wall time of `reps` calls.
fn min_time(batches: usize, reps: usize, mut f: impl FnMut()) -> f64 {
    (0..batches)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..reps {
                f();
            }
            t.elapsed().as_secs_f64() / reps as f64
        })
        .fold(f64::INFINITY, f64::min)
}

fn slope() {
    let cases: Vec<_> = [1000usize, 10_000].iter().map(|&n| (n, chain(n))).collect();
    let mut t_static = [f64::INFINITY; 2];
    let mut t_modes = [f64::INFINITY; 2];
    // interleaved rounds, so that a busy spell of the machine hits both N
    for _ in 0..5 {
        for (k, (n, (sys, q0, eq))) in cases.iter().enumerate() {
            let reps = (10_000 / n).max(1);
            t_static[k] = t_static[k].min(min_time(1, reps, || {
                black_box(static_equilibrium(sys, q0, StaticOptions::default()).expect("eq"));
            }));
            let tan = tangent(sys, eq);
            t_modes[k] = t_modes[k].min(min_time(1, reps, || {
                black_box(eigenmodes(&tan, modes10()).expect("modes"));
            }));
        }
    }
    let slope = |t: [f64; 2]| (t[1] / t[0]).ln() / 10f64.ln();
    for (name, t, budget) in [("static", t_static, 1.0), ("modes10", t_modes, 2.0)] {
        println!(
            "{name:8} N=1000 {:.4} s  N=10000 {:.4} s (budget {budget} s)  slope {:.3} (budget 1.1)",
            t[0],
            t[1],
            slope(t)
        );
    }
}

fn main() {
    if std::env::args().any(|a| a == "slope") {
        slope();
        return;
    }
    benches();
    criterion::Criterion::default()
        .configure_from_args()
        .final_summary();
}
