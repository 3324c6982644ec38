//! Where the time of one right-hand-side evaluation of the falling rod goes:
//! forces, constraint terms (generic and generated), the whole RHS with
//! generic and with generated constraint evaluation on one thread, and the
//! whole RHS on two threads (forces ∥ constraint terms above
//! `PARALLEL_MIN_COORDS`).
//!
//! `cargo run --release --example rhs_breakdown`
use mbsolve::builders::{build_rod, RodParams};
use mbsolve::formulation::{Index1, Index1Options};
use mbsolve::model::Evaluation;
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
    println!("times in µs, best of 30");
    println!("       N |   forces | Φ,Φ_q,γ generic | Φ,Φ_q,γ generated | RHS generic | RHS generated | ratio | RHS generated, 2 threads");
    for n in [10usize, 100, 1000, 3000, 10_000] {
        let (mut sys, _) = build_rod(&RodParams::problem_b(n)).unwrap();
        let (q, mut qd) = sys.initial_state();
        qd.iter_mut()
            .enumerate()
            .for_each(|(i, v)| *v += 1e-3 * (i as f64).sin());
        let nc = sys.n_coords();
        let m = sys.n_constraints();
        let mut g = vec![0.0; nc];
        let mut jac = vec![0.0; sys.jacobian_pattern().len()];
        let (mut gam, mut phi) = (vec![0.0; m], vec![0.0; m]);
        let mut qdd = vec![0.0; nc];
        let reps = 30;
        let tf = best(reps, || sys.forces_into(0.0, &q, &qd, &mut g));
        let mut rhs = |sys: &mut mbsolve::model::System, e: Evaluation| {
            sys.set_evaluation(e).unwrap();
            let tc = best(reps, || {
                sys.constraint_terms(&q, &qd, 0.0, Some(&mut phi), &mut jac, &mut gam)
            });
            let mut f = Index1::new(sys, Index1Options::default()).unwrap();
            let t1 =
                pool1.install(|| best(reps, || f.accelerations(0.0, &q, &qd, &mut qdd).unwrap()));
            let t2 =
                pool2.install(|| best(reps, || f.accelerations(0.0, &q, &qd, &mut qdd).unwrap()));
            (tc, t1, t2)
        };
        let (tc_gen, r_gen, _) = rhs(&mut sys, Evaluation::Generic);
        let (tc_k, r_k, r_k2) = rhs(&mut sys, Evaluation::Generated);
        println!(
            "{n:8} | {:8.1} | {:15.1} | {:17.1} | {:11.1} | {:13.1} | {:5.2} | {:23.1}",
            tf * 1e6,
            tc_gen * 1e6,
            tc_k * 1e6,
            r_gen * 1e6,
            r_k * 1e6,
            r_gen / r_k,
            r_k2 * 1e6
        );
    }
}
