//! The two-sided ("split") envelope LDLᵀ of `ChainLdlt` and the concurrent
//! Newton assembly: solutions against the one-sided factorisation, and
//! results bit-identical for one and two threads.

use mbsolve::builders::stiff_chain;
use mbsolve::formulation::Index3;
use mbsolve::integrate::{Method, OdeOptions};
use mbsolve::linalg::{
    ChainLdlt, LinalgError, SaddleMatrix, SaddlePointSolver, SolverKind, PARALLEL_MIN_DIM,
    SPLIT_MIN_DIM,
};
use mbsolve::parallel::{Threads, PARALLEL_MIN_COORDS};
use mbsolve::simulation::{simulate, RunConfig};

/// Deterministic pseudo-random numbers in [−1, 1) (64-bit LCG).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// A random chain saddle-point matrix of `nb` bodies: a ground revolute on
/// body 0 and revolutes between neighbours (random Φ_q values in the
/// revolute pattern), `A` = a positive diagonal plus random within-body and
/// neighbour-angle couplings (diagonally dominant: positive definite).
fn random_chain(nb: usize, seed: u64) -> SaddleMatrix {
    let mut rng = Lcg(seed);
    let n = 3 * nb;
    let mut a_pat = Vec::new();
    for b in 0..nb {
        a_pat.push((3 * b + 2, 3 * b));
        a_pat.push((3 * b + 2, 3 * b + 1));
        if b + 1 < nb {
            a_pat.push((3 * b + 5, 3 * b + 2));
        }
    }
    let mut jac = vec![(0, 0), (0, 2), (1, 1), (1, 2)];
    for k in 0..nb - 1 {
        let (r, i, j) = (2 + 2 * k, 3 * k, 3 * k + 3);
        jac.extend([(r, i), (r, i + 2), (r, j), (r, j + 2)]);
        jac.extend([
            (r + 1, i + 1),
            (r + 1, i + 2),
            (r + 1, j + 1),
            (r + 1, j + 2),
        ]);
    }
    let m = 2 * nb;
    let mut k = SaddleMatrix::new(n, m, &a_pat, &jac);
    let diag: Vec<f64> = (0..n).map(|_| 4.0 + rng.next()).collect();
    k.set_a_diagonal(&diag);
    for id in 0..a_pat.len() {
        k.add_a(id, 0.5 * rng.next());
    }
    // x, y columns ±1 (the revolute's identity blocks), angles random
    let vals: Vec<f64> = jac
        .iter()
        .map(|&(_, c)| {
            if c % 3 == 2 {
                0.5 * rng.next()
            } else if c % 3 == 0 && c > 0 {
                1.0 + 0.1 * rng.next()
            } else {
                -1.0 + 0.1 * rng.next()
            }
        })
        .collect();
    k.set_jacobian(&vals);
    k
}

fn solve(k: &SaddleMatrix, split: bool, b: &[f64]) -> (Vec<f64>, bool) {
    let mut s = ChainLdlt::default()
        .with_residual_check(false)
        .with_split(split);
    s.analyze(k).unwrap();
    assert_eq!(s.is_envelope(), Some(true));
    let info = s.factorize(k).unwrap();
    assert_eq!(info.regularized_pivots, 0);
    let mut x = b.to_vec();
    s.solve_in_place(k, &mut x).unwrap();
    (x, s.is_split().unwrap())
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let num = a
        .iter()
        .zip(b)
        .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
    num / b.iter().fold(0.0_f64, |m, y| m.max(y.abs()))
}

/// Split and one-sided solutions of random chain matrices: both residuals
/// at rounding, the two solutions equal to rounding.
#[test]
fn split_envelope_solves_random_chains_like_the_one_sided_one() {
    for (nb, seed) in [(250, 1), (700, 2), (2001, 3)] {
        let k = random_chain(nb, seed);
        assert!(k.dim() >= SPLIT_MIN_DIM);
        let mut rng = Lcg(seed + 100);
        let b: Vec<f64> = (0..k.dim()).map(|_| rng.next()).collect();
        let (xs, split) = solve(&k, true, &b);
        let (xo, one) = solve(&k, false, &b);
        assert!(split && !one);
        let mut work = vec![0.0; k.dim()];
        let (rs, ro) = (
            k.relative_residual(&xs, &b, &mut work),
            k.relative_residual(&xo, &b, &mut work),
        );
        assert!(rs <= 1e-12 && ro <= 1e-12, "nb = {nb}: {rs:e}, {ro:e}");
        let d = rel_diff(&xs, &xo);
        assert!(d < 1e-11, "nb = {nb}: split vs one-sided {d:e}");
        assert!(xs != xo, "different orders round differently");
    }
}

/// The split solve checks the entries of its solution as its backward
/// rows write them: a right-hand side with one non-finite entry (in turn
/// at the start, the quarters, the middle and the end of `b`, so in rows
/// of both halves and of the separator) gives `NonFiniteSolution`, in
/// pools of one and of two threads; a finite one solves.
#[test]
fn split_solve_reports_a_non_finite_solution_on_one_thread_and_two() {
    let k = random_chain(2001, 5);
    let dim = k.dim();
    assert!(dim >= PARALLEL_MIN_DIM);
    let mut s = ChainLdlt::default()
        .with_residual_check(false)
        .with_split(true);
    s.analyze(&k).unwrap();
    s.factorize(&k).unwrap();
    assert_eq!(s.is_split(), Some(true));
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            for at in [0, dim / 4, dim / 2, 3 * dim / 4, dim - 1] {
                for bad in [f64::NAN, f64::INFINITY] {
                    let mut x: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.37).sin()).collect();
                    x[at] = bad;
                    let r = s.solve_in_place(&k, &mut x);
                    assert!(
                        matches!(r, Err(LinalgError::NonFiniteSolution(_))),
                        "{threads} thread(s), b[{at}] = {bad}: {r:?}"
                    );
                }
            }
            let mut x: Vec<f64> = (0..dim).map(|i| (i as f64 * 0.37).sin()).collect();
            s.solve_in_place(&k, &mut x).unwrap();
        });
    }
}

/// The stiff chain's Newton matrix (N = 2000, its halves concurrent, gen-α's coefficients at
/// h = 1e-5, a state away from rest): split against one-sided, and the
/// split one bit-identical in one- and two-thread pools.
#[test]
fn split_envelope_solves_the_stiff_chain_newton_matrix() {
    let (sys, q0, _, _) = stiff_chain(2000, 5f64.to_radians()).unwrap();
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    assert!(n + m >= PARALLEL_MIN_DIM);
    let q: Vec<f64> = q0
        .iter()
        .enumerate()
        .map(|(i, x)| x + 1e-4 * (i as f64 * 0.7).sin())
        .collect();
    let qd: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 * 0.3).cos()).collect();
    let lam: Vec<f64> = (0..m).map(|r| 50.0 + (r as f64 * 0.2).sin()).collect();
    let mut f = Index3::new(&sys, SolverKind::Auto).unwrap();
    let h = 1e-5;
    let beta = 0.3025;
    f.assemble_and_factorize(0.0, &q, &qd, &lam, 1.2, 0.6 * h, beta * h * h)
        .unwrap();
    let k = f.newton_matrix();
    let b: Vec<f64> = (0..n + m).map(|i| (i as f64 * 0.37).sin()).collect();
    let (xs, split) = solve(k, true, &b);
    let (xo, _) = solve(k, false, &b);
    assert!(split);
    let mut work = vec![0.0; n + m];
    let rs = k.relative_residual(&xs, &b, &mut work);
    let ro = k.relative_residual(&xo, &b, &mut work);
    eprintln!("stiff chain N = 2000: relative residual split {rs:e}, one-sided {ro:e}");
    // at rounding: the one-sided factorisation's own residual is 2.2e-12
    // here (the chain's conditioning grows with N; 1e-12 holds at N = 400)
    assert!(
        rs <= 1e-11 && rs <= 2.0 * ro,
        "split {rs:e}, one-sided {ro:e}"
    );
    let d = rel_diff(&xs, &xo);
    assert!(d < 1e-10, "split vs one-sided {d:e}");
    let in_pool = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| solve(k, true, &b).0)
    };
    let (x1, x2) = (in_pool(1), in_pool(2));
    assert!(x1.iter().zip(&x2).all(|(a, b)| a.to_bits() == b.to_bits()));
}

/// Whole gen-α runs of a 2000-segment stiff chain (its Newton matrix split,
/// the halves and the residual's forces and constraint terms concurrent) in one- and two-thread pools: every output
/// bit-identical, and the run moved.
#[test]
fn genalpha_stiff_chain_is_bit_identical_with_one_and_two_threads() {
    bit_identical_with_one_and_two_threads(
        Method::GenAlpha,
        OdeOptions {
            fixed_step: Some(1e-5),
            ..Default::default()
        },
    );
}

/// The same for bdf (adaptive, its Newton update in two concurrent
/// halves as well): every output bit-identical, and the run moved.
#[test]
fn bdf_stiff_chain_is_bit_identical_with_one_and_two_threads() {
    bit_identical_with_one_and_two_threads(
        Method::Bdf,
        OdeOptions {
            rtol: 1e-5,
            atol: mbsolve::integrate::Tolerance::Scalar(1e-8),
            ..Default::default()
        },
    );
}

/// The same for radau5 (fixed step; its real stage's Newton matrix on
/// the split chain solver, its passes in halves): bit-identical.
#[test]
fn radau5_stiff_chain_is_bit_identical_with_one_and_two_threads() {
    bit_identical_with_one_and_two_threads(
        Method::Radau5,
        OdeOptions {
            fixed_step: Some(1e-5),
            ..Default::default()
        },
    );
}

/// The same for adaptive radau5 with a tolerance per coordinate (its
/// Newton test reads `atol` of each coordinate in the halves of the
/// update pass): bit-identical.
#[test]
fn radau5_adaptive_stiff_chain_is_bit_identical_with_one_and_two_threads() {
    let (sys, _, _, _) = stiff_chain(2000, 5f64.to_radians()).unwrap();
    let atol = (0..sys.n_coords())
        .map(|i| if i % 3 == 2 { 1e-7 } else { 1e-8 })
        .collect();
    bit_identical_runs(
        Method::Radau5,
        OdeOptions {
            rtol: 1e-4,
            atol: mbsolve::integrate::Tolerance::Vector(atol),
            ..Default::default()
        },
        true,
    );
}

/// The same for adaptive radau9, radau13 and radau59 (five and seven
/// stages, two and three complex matrices; radau59 changes order between
/// steps): bit-identical.
#[test]
fn radau9_radau13_and_radau59_adaptive_stiff_chain_are_bit_identical_with_one_and_two_threads() {
    for (method, adaptive) in [
        (Method::Radau9, true),
        (Method::Radau13, true),
        (Method::Radau59, false),
    ] {
        bit_identical_runs(
            method,
            OdeOptions {
                rtol: 1e-4,
                atol: mbsolve::integrate::Tolerance::Scalar(1e-7),
                ..Default::default()
            },
            adaptive,
        );
    }
}

fn bit_identical_with_one_and_two_threads(method: Method, ode: OdeOptions) {
    bit_identical_runs(method, ode, false);
}

/// Runs the stiff chain of 2000 segments (above both parallel
/// thresholds) for 4e-5 s with `method` in one- and two-thread pools and
/// with each thread setting (`auto`, one, two forced — also in a pool of
/// one) and asserts bit-identical outputs and Newton counts, and that the
/// summary reports what the setting asks (`adaptive`: the implicit
/// method's adaptive step).
fn bit_identical_runs(method: Method, ode: OdeOptions, adaptive: bool) {
    let (sys, q0, qd0, _) = stiff_chain(2000, 5f64.to_radians()).unwrap();
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    assert!(n >= PARALLEL_MIN_COORDS && n + m >= PARALLEL_MIN_DIM);
    let mut cfg = RunConfig {
        method,
        t_end: 4e-5,
        output_dt: 1e-5,
        ode,
        ..Default::default()
    };
    cfg.implicit.adaptive = adaptive;
    let run = |threads: usize, setting: Threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let cfg = RunConfig {
            threads: setting,
            ..cfg.clone()
        };
        let (traj, s) = pool.install(|| simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap());
        assert_eq!(s.status, "completed", "{:?}", s.message);
        assert_eq!(s.linear_solver, "chain-ldlt");
        let count = |k: &str| s.extra[k].as_u64().unwrap();
        match setting {
            // nothing leaves the thread
            Threads::One => {
                assert_eq!(s.extra["threads"], 1);
                assert_eq!(count("halves_split") + count("halves_taken_back"), 0);
            }
            // every concurrent pass posts its second half (run by the
            // helper or taken back: which, depends on the scheduler)
            Threads::Two => {
                assert!(count("halves_split") + count("halves_taken_back") > 50);
                assert_eq!(count("halves_solo"), 0);
            }
            Threads::Auto => {}
        }
        (traj, s.extra.get("newton_iterations").cloned())
    };
    let (a, ia) = run(1, Threads::Auto);
    for (threads, setting) in [
        (2, Threads::Auto),
        (2, Threads::One),
        (2, Threads::Two),
        (1, Threads::Two),
    ] {
        let (b, ib) = run(threads, setting);
        assert_eq!(ia, ib);
        assert_eq!(a.t, b.t);
        assert_eq!(a.q.len(), 5);
        for (qa, qb) in a.q.iter().zip(&b.q).chain(a.qd.iter().zip(&b.qd)) {
            assert!(
                qa.iter().zip(qb).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{threads} threads, {setting:?}"
            );
        }
    }
    let moved = a.q.last().unwrap().iter().zip(&q0).any(|(x, y)| x != y);
    assert!(moved);
}
