//! Where the time of one right-hand-side evaluation of the falling rod goes,
//! forces, constraint terms, the whole RHS on 1 thread, and the whole RHS on
//! 2 threads (forces ∥ constraint terms when N is above the threshold).
//!
//! `cargo run --release --example rhs_breakdown`
use mbsolve::builders::{build_rod, RodParams};
use mbsolve::formulation::{Index1, Index1Options};
use std::time::Instant;

fn best<F: FnMut()>(reps: usize, mut f: F) -> f64 {
    let mut best = f64::MAX;
    for _ in 0..reps {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    best
}

fn main() {
    let pool1 = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let pool2 = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    for n in [100usize, 300, 500, 1000, 3000, 10_000] {
        let (sys, _) = build_rod(&RodParams::problem_b(n)).unwrap();
        let (q, mut qd) = sys.initial_state();
        qd.iter_mut()
            .enumerate()
            .for_each(|(i, v)| *v += 1e-3 * (i as f64).sin());
        let nc = sys.n_coords();
        let m = sys.n_constraints();
        let mut g = vec![0.0; nc];
        let mut jac = vec![0.0; sys.jacobian_pattern().len()];
        let mut gam = vec![0.0; m];
        let mut f = Index1::new(&sys, Index1Options::default()).unwrap();
        let mut qdd = vec![0.0; nc];
        let reps = 20;
        let tf = best(reps, || sys.forces_into(0.0, &q, &qd, &mut g));
        let tc = best(reps, || {
            sys.jacobian_values(&q, 0.0, &mut jac);
            sys.gamma(&q, &qd, 0.0, &mut gam);
        });
        let tr = pool1.install(|| best(reps, || f.accelerations(0.0, &q, &qd, &mut qdd).unwrap()));
        let tr2 = pool2.install(|| best(reps, || f.accelerations(0.0, &q, &qd, &mut qdd).unwrap()));
        println!(
            "N = {n:6}: forces {:8.1} µs, Φ_q + γ {:8.1} µs, whole RHS {:8.1} µs (linear solve ≈ {:8.1} µs); 2 threads {:8.1} µs",
            tf * 1e6,
            tc * 1e6,
            tr * 1e6,
            (tr - tf - tc) * 1e6,
            tr2 * 1e6
        );
    }
}
