//! Speed of the analyses on the peers' stiff chain (`builders::stiff_chain`,
//! every segment released at 5°): the static equilibrium from the released
//! state and the 10 lowest modes about it, at N = 1000 and 10 000.
//!
//! ```text
//! cargo bench --bench analysis            # criterion, both analyses, both N
//! cargo bench --bench analysis -- slope   # only the printed times and slopes
//! ```
//!
//! `slope`: each analysis at N = 1000 and 10 000, interleaved over 15
//! rounds, every call timed alone by the calling thread's CPU clock, with
//! the thread setting `Threads::One` (every concurrent pass on that
//! thread); the minimum and the median per N and the
//! slopes `log(t₁₀₀₀₀ / t₁₀₀₀) / log 10` of both. The budgets are 1 s
//! for the static equilibrium and 2 s for the modes at N = 10 000, a slope
//! of at most 1.1.
//!
//! The falling rod of problem B is not a case here: a free rod under
//! gravity has no static equilibrium (docs/analyses.md).

#[path = "../examples/common/mod.rs"]
mod common;

use common::thread_cpu;
use criterion::{criterion_group, BenchmarkId, Criterion};
use mbsolve::analysis::{
    eigenmodes, static_equilibrium, Equilibrium, ModeOptions, StaticOptions, Tangent,
};
use mbsolve::builders::stiff_chain;
use mbsolve::model::System;
use mbsolve::parallel::{with_threads, Threads};
use std::hint::black_box;
use std::time::Duration;

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

/// Appends the thread CPU time of each of `reps` calls of `f` to `out`,
/// each with the thread setting `Threads::One`: every concurrent pass of
/// the library then runs on this thread and enters its clock (from
/// `PARALLEL_MIN_COORDS` coordinates on it would run on a rayon worker
/// while this thread waits).
fn sample(out: &mut Vec<f64>, reps: usize, mut f: impl FnMut()) {
    for _ in 0..reps {
        let t = thread_cpu();
        with_threads(Threads::One, &mut f);
        out.push(thread_cpu() - t);
    }
}

/// Minimum and median of `v`.
fn min_median(v: &[f64]) -> (f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let k = s.len();
    let med = if k % 2 == 1 {
        s[k / 2]
    } else {
        0.5 * (s[k / 2 - 1] + s[k / 2])
    };
    (s[0], med)
}

fn slope() {
    let cases: Vec<_> = [1000usize, 10_000].iter().map(|&n| (n, chain(n))).collect();
    let mut t_static = [Vec::new(), Vec::new()];
    let mut t_modes = [Vec::new(), Vec::new()];
    // interleaved rounds, so that a busy spell of the machine hits both N;
    // every call timed alone by the thread's CPU clock
    for _ in 0..15 {
        for (k, (n, (sys, q0, eq))) in cases.iter().enumerate() {
            let reps = (10_000 / n).max(1);
            sample(&mut t_static[k], reps, || {
                black_box(static_equilibrium(sys, q0, StaticOptions::default()).expect("eq"));
            });
            let tan = tangent(sys, eq);
            sample(&mut t_modes[k], reps, || {
                black_box(eigenmodes(&tan, modes10()).expect("modes"));
            });
        }
    }
    let slope = |a: f64, b: f64| (b / a).ln() / 10f64.ln();
    for (name, t, budget) in [("static", t_static, 1.0), ("modes10", t_modes, 2.0)] {
        let (min0, med0) = min_median(&t[0]);
        let (min1, med1) = min_median(&t[1]);
        println!(
            "{name:8} thread CPU min / median: N=1000 {min0:.4} / {med0:.4} s  N=10000 {min1:.4} / \
             {med1:.4} s (budget {budget} s)  slope {:.3} / {:.3} (budget 1.1)",
            slope(min0, min1),
            slope(med0, med1)
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
