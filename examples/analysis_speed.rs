//! CPU time of the analyses at N = 1000 and 10 000 (and the slope of the
//! cost in N): the 10 lowest modes of the peers' stiff chain about its
//! static equilibrium and the chain's static equilibrium from its released
//! state (every segment at 5°).
//!
//! ```text
//! RAYON_NUM_THREADS=1 target/release/examples/analysis_speed [static|modes|all|solver] [rounds=R] [N …]
//! ```
//!
//! `solver` times the linear algebra alone, for the chain LU and faer's
//! sparse LU on the same matrix (`[K, Φ_qᵀ; Φ_q, 0]` about the
//! equilibrium, the modes' matrix at σ = 0): `analyze`, one
//! `factorize` and one solve, minimum over the rounds.
//!
//! Every call is timed alone by the calling thread's CPU clock
//! (`clock_gettime(CLOCK_THREAD_CPUTIME_ID)`, nanoseconds: neither the
//! 10 ms tick of the process's CPU time nor other processes' time enters),
//! with the thread setting `Threads::One`, so that every concurrent pass
//! of the library runs on that thread and enters its clock.
//! The sizes are interleaved: each of `R` rounds (default 15) calls each
//! analysis at every N in turn, `max(1, 10 000 / N)` times, so a busy
//! spell of the machine hits all sizes alike. One JSON line per analysis
//! and N gives the minimum and the median over all calls, the minor page
//! faults per call (`getrusage(RUSAGE_THREAD)`: fresh memory touched), and
//! a last line the slopes `log(t_last / t_first) / log(N_last / N_first)`
//! of the minima and of the medians. Under `valgrind --tool=callgrind`
//! set `MBSOLVE_ONCE=1`: one call per N, whose instruction count is the
//! measure there.

mod common;

use common::thread_cpu;
use mbsolve::analysis::{eigenmodes, static_equilibrium, ModeOptions, StaticOptions, Tangent};
use mbsolve::builders::stiff_chain;
use mbsolve::linalg::{solver_for, ChainLu, SaddlePointSolver, SolverKind, Storage};
use mbsolve::parallel::{with_threads, Threads};

/// `f()` with every concurrent pass of the library on the calling thread
/// (`Threads::One`): from `PARALLEL_MIN_COORDS` coordinates on, the
/// evaluations would otherwise run on a rayon worker while the calling
/// thread waits, and its CPU clock would miss them.
fn one_thread<R>(f: impl FnOnce() -> R) -> R {
    with_threads(Threads::One, f).0
}

/// Minor page faults of the calling thread so far (`RUSAGE_THREAD`).
fn minor_faults() -> i64 {
    // SAFETY: an all-zero rusage is valid; getrusage fills it
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `ru` is a valid, writable rusage
    unsafe { libc::getrusage(libc::RUSAGE_THREAD, &mut ru) };
    ru.ru_minflt
}

/// Per-call samples of one analysis at one N: CPU seconds, page faults.
#[derive(Default)]
struct Samples {
    cpu: Vec<f64>,
    faults: Vec<i64>,
}

impl Samples {
    /// Times one call of `f`.
    fn time<R>(&mut self, f: impl FnOnce() -> R) -> R {
        let (f0, c0) = (minor_faults(), thread_cpu());
        let r = f();
        let (c1, f1) = (thread_cpu(), minor_faults());
        self.cpu.push(c1 - c0);
        self.faults.push(f1 - f0);
        r
    }

    fn min(&self) -> f64 {
        self.cpu.iter().copied().fold(f64::INFINITY, f64::min)
    }

    fn median(&self) -> f64 {
        let mut v = self.cpu.clone();
        v.sort_by(f64::total_cmp);
        let k = v.len();
        if k == 0 {
            f64::NAN
        } else if k % 2 == 1 {
            v[k / 2]
        } else {
            0.5 * (v[k / 2 - 1] + v[k / 2])
        }
    }

    fn faults_per_call(&self) -> f64 {
        self.faults.iter().sum::<i64>() as f64 / self.faults.len().max(1) as f64
    }
}

fn main() {
    let mut what = "all".to_string();
    let mut ns: Vec<usize> = Vec::new();
    let mut rounds = 15usize;
    for a in std::env::args().skip(1) {
        if let Some(r) = a.strip_prefix("rounds=") {
            rounds = r.parse().expect("rounds=R with R a count");
        } else if let Ok(n) = a.parse() {
            ns.push(n);
        } else {
            what = a;
        }
    }
    if ns.is_empty() {
        ns = vec![1000, 10_000];
    }
    let once = std::env::var_os("MBSOLVE_ONCE").is_some();
    if once {
        rounds = 1;
    }
    if what == "solver" {
        solver_times(&ns, rounds);
        return;
    }
    let (do_static, do_modes) = (what != "modes", what != "static");
    let opts = ModeOptions {
        count: 10,
        ..Default::default()
    };
    // the chains, their released states and equilibria (outside the clock)
    let cases: Vec<_> = ns
        .iter()
        .map(|&n| {
            let (sys, q0, _, _) = stiff_chain(n, 5f64.to_radians()).expect("the stiff chain");
            let eq = static_equilibrium(&sys, &q0, StaticOptions::default()).expect("equilibrium");
            (sys, q0, eq)
        })
        .collect();
    let mut st: Vec<Samples> = ns.iter().map(|_| Samples::default()).collect();
    let mut md: Vec<Samples> = ns.iter().map(|_| Samples::default()).collect();
    let mut info_static = vec![String::new(); ns.len()];
    let mut info_modes = vec![String::new(); ns.len()];
    for _ in 0..rounds {
        for (k, (sys, q0, eq)) in cases.iter().enumerate() {
            let reps = if once { 1 } else { (10_000 / ns[k]).max(1) };
            if do_static {
                for _ in 0..reps {
                    let e = st[k].time(|| {
                        one_thread(|| static_equilibrium(sys, q0, StaticOptions::default()))
                            .expect("equilibrium")
                    });
                    info_static[k] = format!(
                        "\"load_steps\":{},\"newton\":{},\"residual\":{:.3e}",
                        e.load_steps, e.iterations, e.residual
                    );
                }
            }
            if do_modes {
                let mut tan = Tangent::new(sys);
                tan.evaluate(0.0, &eq.q, &vec![0.0; eq.q.len()], &eq.lambda)
                    .expect("tangent");
                for _ in 0..reps {
                    let m = md[k].time(|| one_thread(|| eigenmodes(&tan, opts)).expect("modes"));
                    info_modes[k] = format!(
                        "\"lanczos_steps\":{},\"converged\":{},\"f1_hz\":{:.6},\"f10_hz\":{:.4}",
                        m.lanczos_steps,
                        m.converged,
                        m.modes[0].frequency_hz,
                        m.modes[m.modes.len() - 1].frequency_hz
                    );
                }
            }
        }
    }
    let (a, b) = (0, ns.len() - 1);
    let slope = |ta: f64, tb: f64| (tb / ta).ln() / (ns[b] as f64 / ns[a] as f64).ln();
    let mut slopes = Vec::new();
    for (name, on, s, info) in [
        ("static", do_static, &st, &info_static),
        ("modes", do_modes, &md, &info_modes),
    ] {
        if !on {
            continue;
        }
        for (k, &n) in ns.iter().enumerate() {
            println!(
                "{{\"case\":\"stiff_chain_{name}\",\"n\":{n},\"calls\":{},\"cpu_min_s\":{:.6},\
                 \"cpu_median_s\":{:.6},\"minor_faults_per_call\":{:.1},{}}}",
                s[k].cpu.len(),
                s[k].min(),
                s[k].median(),
                s[k].faults_per_call(),
                info[k]
            );
        }
        if b > a {
            slopes.push(format!(
                "\"slope_{name}_min\":{:.3},\"slope_{name}_median\":{:.3}",
                slope(s[a].min(), s[b].min()),
                slope(s[a].median(), s[b].median())
            ));
        }
    }
    if !slopes.is_empty() {
        println!("{{{}}}", slopes.join(","));
    }
}

/// The `solver` case (module docs): per N and solver, the minimum thread
/// CPU time of `analyze`, `factorize` and one solve over `rounds` rounds.
fn solver_times(ns: &[usize], rounds: usize) {
    for &n in ns {
        let (sys, q0, _, _) = stiff_chain(n, 5f64.to_radians()).expect("the stiff chain");
        let eq = static_equilibrium(&sys, &q0, StaticOptions::default()).expect("equilibrium");
        let mut tan = Tangent::new(&sys);
        tan.evaluate(0.0, &eq.q, &vec![0.0; eq.q.len()], &eq.lambda)
            .expect("tangent");
        let mut k = tan.saddle_matrix(Storage::Full);
        tan.write_saddle(&mut k, [0.0, 0.0, 1.0]);
        let dim = k.dim();
        let rhs: Vec<f64> = (0..dim).map(|i| 1.0 + (i as f64 * 0.37).sin()).collect();
        let mut c = ChainLu::default();
        c.analyze(&k).expect("analyze");
        c.factorize(&k).expect("factorize");
        println!(
            "{{\"n\":{n},\"bandwidths\":{:?},\"factor_len\":{:?},\"band\":{}}}",
            c.bandwidths(),
            c.factor_len(),
            c.bandwidths().map_or(0, |(l, u)| dim * (2 * l + u + 1))
        );
        for kind in [SolverKind::ChainLu, SolverKind::SparseLu] {
            let mut best = [f64::INFINITY; 3];
            let mut x = rhs.clone();
            let mut name = "";
            for _ in 0..rounds.max(1) {
                let mut s = solver_for(kind, dim, Default::default());
                let mut t = thread_cpu();
                s.analyze(&k).expect("analyze");
                let mut lap = |i: usize, t: &mut f64| {
                    let now = thread_cpu();
                    best[i] = best[i].min(now - *t);
                    *t = now;
                };
                lap(0, &mut t);
                s.factorize(&k).expect("factorize");
                lap(1, &mut t);
                for _ in 0..3 {
                    x.copy_from_slice(&rhs);
                    t = thread_cpu();
                    s.solve_in_place(&k, &mut x).expect("solve");
                    lap(2, &mut t);
                }
                name = s.name();
            }
            let mut r = vec![0.0; dim];
            let res = k.relative_residual(&x, &rhs, &mut r);
            println!(
                "{{\"case\":\"solver\",\"n\":{n},\"dim\":{dim},\"solver\":\"{name}\",\
                 \"analyze_s\":{:.6},\"factorize_s\":{:.6},\"solve_s\":{:.6},\
                 \"relative_residual\":{res:.2e}}}",
                best[0], best[1], best[2]
            );
        }
    }
}
