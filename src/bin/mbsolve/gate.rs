//! The CI performance gate (`mbsolve bench-gate`): ratios measured in one
//! run, so they do not depend on the machine's speed.
//!
//! * RHS scaling: one right-hand-side evaluation of the falling rod at
//!   N = 8000 over N = 1000 (linear cost ≈ 8; fails above 10);
//! * sparse over dense: the RHS at N = 200 with the dense LU against the
//!   sparse LDLᵀ (fails below 50×);
//! * generated over generic: Φ, Φ_q and γ of the rod chain at N = 1000 from
//!   the build-time generated kernels against the generic per-joint
//!   evaluation (fails below 2×);
//! * generated over generic on the whole implicit run: 400 generalized-α
//!   steps of the stiff chain at N = 1000 (`../shared/peers/`) with the generated
//!   Newton assembly against the generic per-joint, per-element one
//!   (fails below [`IMPLICIT_GENERATED_MIN`]; [`implicit_generated_over_generic`]).
//! * the two-sided chain LDLᵀ over the one-sided one on one thread: factor
//!   and solve of the stiff chain's Newton matrix at N = 10 000, the
//!   median of paired rounds (fails above [`SPLIT_SOLVE_MAX`];
//!   [`split_chain_solve_over_one_sided`]).
//! * Newton iterations per step of generalized-α, BDF and adaptive radau5 on the stiff chain
//!   (N = 100, 0.02 s; fails above [`NEWTON_PER_STEP_MAX`]; a deterministic
//!   count, [`newton_iterations_per_step`]).
//!
//! * two threads over one on a busy machine: the stiff chain at N = 4000
//!   (generalized-α, ndf, radau5) beside one busy process per core that the
//!   gate starts itself, one thread's wall time over two threads' (fails
//!   below [`OVERSUBSCRIBED_MIN`]; [`oversubscribed_two_over_one`]).
//!
//! * work counts, deterministic: per accepted step of generalized-α and
//!   bdf on the stiff chain (N = 100) the Newton-matrix factorisations,
//!   solves and residual evaluations counted by the solver and the
//!   formulation equal those the integrator asked for, and the
//!   integrator's counts per step stay within ±15 % of [`WORK_PINS`](work::WORK_PINS); one
//!   factorisation and one solve per index-1 right-hand side
//!   ([`work_counts`](work::work_counts)).
//! * hot paths against a yardstick: the sparse and the chain LDLᵀ factor +
//!   solve, the index-3 residual and one Newton iteration of the stiff
//!   chain (N = 1000), each over a fixed block-tridiagonal Cholesky of
//!   known flop count ([`yardstick`](hot_paths::yardstick)) timed in the same round, in thread
//!   CPU time; the median of [`HOT_PATH_ROUNDS`](hot_paths::HOT_PATH_ROUNDS) rounds must stay below
//!   [`HOT_PATH_MARGIN`](hot_paths::HOT_PATH_MARGIN) × the clean ratio ([`HOT_PATH_CLEAN`](hot_paths::HOT_PATH_CLEAN);
//!   [`hot_paths_against_yardstick`](hot_paths::hot_paths_against_yardstick)). A hot path done twice fails it.
//!
//! Timings of the ratio checks are the minimum over interleaved
//! repetitions (the chain check: the median of paired rounds) of the
//! thread's CPU time (robust to a shared machine: the
//! time other processes hold the core is not counted) on a single thread
//! (so the ratio measures algorithmic scaling, not the concurrency that
//! only large N switch on), except the oversubscribed check (wall time).

use mbsolve::builders::{build_rod, stiff_chain, RodParams};
use mbsolve::formulation::{Index1, Index1Options};
use mbsolve::integrate::{Method, OdeOptions};
use mbsolve::linalg::SolverKind;
use mbsolve::model::{Evaluation, System};
use mbsolve::parallel::thread_cpu_seconds;
use mbsolve::simulation::{simulate, RunConfig};
use serde::Serialize;
use std::time::Instant;

mod hot_paths;
mod work;
use hot_paths::hot_paths_against_yardstick;
use work::work_counts;

/// One check of the gate.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// What is measured.
    pub name: String,
    /// Measured ratio.
    pub ratio: f64,
    /// Threshold.
    pub threshold: f64,
    /// `true` when the ratio must stay at or below the threshold, `false` when at or above.
    pub at_most: bool,
    /// Whether it passed.
    pub passed: bool,
    /// The underlying timings.
    pub detail: String,
}

struct RhsCase {
    sys: System,
    q: Vec<f64>,
    qd: Vec<f64>,
}

impl RhsCase {
    fn rod(n: usize) -> Self {
        let (sys, _) = build_rod(&RodParams::problem_b(n)).expect("problem B builds");
        let (q, mut qd) = sys.initial_state();
        // a generic state: small perturbations of every velocity
        for (i, v) in qd.iter_mut().enumerate() {
            *v += 1e-3 * ((i as f64) * 0.37).sin();
        }
        Self { sys, q, qd }
    }

    /// Seconds per RHS evaluation over a batch of `batch` evaluations
    /// (thread CPU time, [`per_call`]).
    fn time(&self, f: &mut Index1<'_>, batch: usize) -> f64 {
        let mut qdd = vec![0.0; self.sys.n_coords()];
        per_call(batch, &mut || {
            f.accelerations(0.0, &self.q, &self.qd, &mut qdd)
                .expect("RHS evaluates");
        })
    }
}

fn ratio_of(
    a: &RhsCase,
    fa: &mut Index1<'_>,
    batch_a: usize,
    b: &RhsCase,
    fb: &mut Index1<'_>,
    batch_b: usize,
    reps: usize,
) -> (f64, f64) {
    let (mut ta, mut tb) = (f64::MAX, f64::MAX);
    // warm-up, then interleave so that load changes hit both alike
    a.time(fa, 1);
    b.time(fb, 1);
    for _ in 0..reps {
        ta = ta.min(a.time(fa, batch_a));
        tb = tb.min(b.time(fb, batch_b));
    }
    (ta, tb)
}

/// Measurements of a timing check before it counts as failed.
pub const ATTEMPTS: usize = 3;

/// Bound of the falling rod's RHS cost at N = 8000 over N = 1000 (linear
/// work: 8): 12 = 8 × 1.5, room for the memory hierarchy (the N = 1000
/// factor fits a core's L2 cache, the N = 8000 one does not; measurements
/// in docs/scaling.md). A cost growing like N log N in the factorisation
/// gives 8 × ln 8000 / ln 1000 ≈ 10.4 before that memory factor, one
/// growing like N² gives 64; constant-factor slowdowns are the work
/// counts' and the yardstick checks' to catch.
pub const RHS_SCALING_MAX: f64 = 12.0;

/// `check` measured until it passes, at most [`ATTEMPTS`] times; the last
/// measurement is reported, with the failed ones before it in its detail.
/// The machine is shared, and one attempt can land on a burst of load
/// (docs/scaling.md); a real regression fails every attempt.
fn with_retries(mut check: impl FnMut() -> Check) -> Check {
    let mut failed = Vec::new();
    loop {
        let mut c = check();
        if c.passed || failed.len() + 1 == ATTEMPTS {
            if !failed.is_empty() {
                c.detail = format!(
                    "{} (after failed attempts at {})",
                    c.detail,
                    failed.join(", ")
                );
            }
            return c;
        }
        failed.push(format!("{:.2}", c.ratio));
    }
}

/// `check` measured [`ATTEMPTS`] times; the attempt with the median ratio
/// is reported (the others in its detail). Unlike [`with_retries`], one
/// lucky attempt does not pass a regression: two of three must.
fn median_of_attempts(mut check: impl FnMut() -> Check) -> Check {
    let mut all: Vec<Check> = (0..ATTEMPTS).map(|_| check()).collect();
    all.sort_by(|a, b| a.ratio.total_cmp(&b.ratio));
    let ratios: Vec<String> = all.iter().map(|c| format!("{:.2}", c.ratio)).collect();
    let mut c = all.swap_remove(ATTEMPTS / 2);
    c.detail = format!("{} (median of attempts at {})", c.detail, ratios.join(", "));
    c
}

/// Run every check (about 15–30 s on the 2-core CI machine).
pub fn run() -> Vec<Check> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    let mut checks = one_thread_checks(&pool);
    checks.extend(pool.install(work_counts));
    checks.extend(pool.install(hot_paths_against_yardstick));
    checks.push(with_retries(oversubscribed_two_over_one));
    checks
}

/// The checks measured on one thread.
fn one_thread_checks(pool: &rayon::ThreadPool) -> Vec<Check> {
    pool.install(|| {
        let mut checks = newton_iterations_per_step();
        let sparse = Index1Options {
            linear_solver: SolverKind::Sparse,
            ..Default::default()
        };

        let small = RhsCase::rod(1000);
        let large = RhsCase::rod(8000);
        let mut fs = Index1::new(&small.sys, sparse).expect("formulation");
        let mut fl = Index1::new(&large.sys, sparse).expect("formulation");
        checks.push(median_of_attempts(|| {
            let (ts, tl) = ratio_of(&small, &mut fs, 40, &large, &mut fl, 5, 60);
            let r = tl / ts;
            Check {
                name: "RHS cost, falling rod N = 8000 over N = 1000 (linear ≈ 8)".into(),
                ratio: r,
                threshold: RHS_SCALING_MAX,
                at_most: true,
                passed: r <= RHS_SCALING_MAX,
                detail: format!("{:.1} µs vs {:.1} µs per evaluation", tl * 1e6, ts * 1e6),
            }
        }));

        let mid = RhsCase::rod(200);
        let dense = Index1Options {
            linear_solver: SolverKind::Dense,
            ..Default::default()
        };
        let mut fd = Index1::new(&mid.sys, dense).expect("formulation");
        let mut fsp = Index1::new(&mid.sys, sparse).expect("formulation");
        let (td, tsp) = ratio_of(&mid, &mut fd, 3, &mid, &mut fsp, 300, 15);
        let r = td / tsp;
        checks.push(Check {
            name: "RHS speed, sparse LDLᵀ over dense LU, falling rod N = 200 (dim 998)".into(),
            ratio: r,
            threshold: 50.0,
            at_most: false,
            passed: r >= 50.0,
            detail: format!(
                "dense {:.2} ms vs sparse {:.1} µs per evaluation",
                td * 1e3,
                tsp * 1e6
            ),
        });
        // Generated over generic constraint evaluation (Φ, Φ_q, γ), N = 1000.
        let mut chain = RhsCase::rod(1000);
        if !chain.sys.uses_kernels() {
            checks.push(Check {
                name: "generated over generic Φ, Φ_q, γ".into(),
                ratio: 0.0,
                threshold: 2.0,
                at_most: false,
                passed: false,
                detail: "the rod chain was not recognised by the generated kernels".into(),
            });
            return checks;
        }
        let (tg, tgen) = {
            let m = chain.sys.n_constraints();
            let mut phi = vec![0.0; m];
            let mut gam = vec![0.0; m];
            let mut jac = vec![0.0; chain.sys.jacobian_pattern().len()];
            let mut q = chain.q.clone();
            let mut time = |sys: &System, q: &mut Vec<f64>| {
                let mut k = 0;
                per_call(200, &mut || {
                    // a new state each time (no caching across evaluations)
                    q[2] = 1e-3 * k as f64;
                    k += 1;
                    sys.constraint_terms(q, &chain.qd, 0.0, Some(&mut phi), &mut jac, &mut gam);
                })
            };
            let (mut tg, mut tgen) = (f64::MAX, f64::MAX);
            for _ in 0..20 {
                chain
                    .sys
                    .set_evaluation(Evaluation::Generic)
                    .expect("generic");
                tg = tg.min(time(&chain.sys, &mut q));
                chain
                    .sys
                    .set_evaluation(Evaluation::Generated)
                    .expect("kernels attached");
                tgen = tgen.min(time(&chain.sys, &mut q));
            }
            (tg, tgen)
        };
        let r = tg / tgen;
        checks.push(median_of_attempts(implicit_generated_over_generic));
        checks.push(split_chain_solve_over_one_sided());
        checks.push(Check {
            name: "Φ, Φ_q, γ of the rod chain N = 1000, generated over generic".into(),
            ratio: r,
            threshold: 2.0,
            at_most: false,
            passed: r >= 2.0,
            detail: format!(
                "generic {:.1} µs vs generated {:.1} µs",
                tg * 1e6,
                tgen * 1e6
            ),
        });
        checks
    })
}

/// CPU seconds of this process, user + system (`/proc/self/stat`, clock
/// ticks of 10 ms; `NaN` where unavailable).
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // the fields after the parenthesised command: utime and stime are the 12th and 13th
    let rest = stat.rsplit_once(')').map_or("", |r| r.1);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok());
    match (tick(11), tick(12)) {
        (Some(u), Some(s)) => (u + s) / 100.0,
        _ => f64::NAN,
    }
}

/// Bound of [`implicit_generated_over_generic`]: the speed target's 1.5
/// (measurements in docs/scaling.md).
pub const IMPLICIT_GENERATED_MIN: f64 = 1.5;

/// Whole generalized-α run of the stiff chain (N = 1000, h = 1e-5, 800
/// steps) with the generated evaluation (kernels, fused trigonometry)
/// over the generic one (every joint and force element on its own): CPU
/// time of the process (the gate's one-thread pool), the minimum over
/// interleaved repetitions of each, in this process.
pub fn implicit_generated_over_generic() -> Check {
    let name =
        "whole implicit run (gen-α, stiff chain N = 1000, 800 steps), generated over generic";
    let (mut sys, q0, qd0, _) = stiff_chain(1000, 5f64.to_radians()).expect("stiff chain builds");
    let cfg = RunConfig {
        method: Method::GenAlpha,
        t_end: 8e-3,
        output_dt: 8e-3,
        ode: OdeOptions {
            fixed_step: Some(1e-5),
            ..Default::default()
        },
        ..Default::default()
    };
    let time = |sys: &mut System, e: Evaluation| -> Result<f64, String> {
        sys.set_evaluation(e).map_err(|e| e.to_string())?;
        let t = cpu_seconds();
        let (_, s) = simulate(sys, &q0, &qd0, &cfg, &mut []).map_err(|e| e.to_string())?;
        if s.status != "completed" {
            return Err(format!("{e:?} run {}: {:?}", s.status, s.message));
        }
        Ok(cpu_seconds() - t)
    };
    let mut best = (f64::MAX, f64::MAX);
    let mut ratios = Vec::new();
    // the median of the ratios of 5 pairs, each pair measured back to
    // back: on the shared 2-core machine the best-of-3 times gave 1.25 and
    // 1.32 in two CI runs right after the test suite, where runs around
    // them gave 1.52–2.04
    for _ in 0..5 {
        let tg = time(&mut sys, Evaluation::Generic);
        let tk = time(&mut sys, Evaluation::Generated);
        match (tg, tk) {
            (Ok(tg), Ok(tk)) => {
                best = (best.0.min(tg), best.1.min(tk));
                ratios.push(tg / tk);
            }
            (Err(e), _) | (_, Err(e)) => {
                return Check {
                    name: name.into(),
                    ratio: 0.0,
                    threshold: IMPLICIT_GENERATED_MIN,
                    at_most: false,
                    passed: false,
                    detail: e,
                }
            }
        }
    }
    ratios.sort_by(f64::total_cmp);
    let r = ratios[ratios.len() / 2];
    Check {
        name: name.into(),
        ratio: r,
        threshold: IMPLICIT_GENERATED_MIN,
        at_most: false,
        passed: r >= IMPLICIT_GENERATED_MIN,
        detail: format!(
            "median of 5 pairs; best generic {:.2} s vs best generated {:.2} s of CPU",
            best.0, best.1
        ),
    }
}

/// Bound of [`split_chain_solve_over_one_sided`]: the two-sided order does
/// the same rows' arithmetic as the one-sided one plus a separator of a few
/// rows (a ratio of ≈ 1.0), so 1.2 is a 20 % slowdown of the split path.
pub const SPLIT_SOLVE_MAX: f64 = 1.2;

/// Rounds of [`split_chain_solve_over_one_sided`]: each times a batch of
/// each solver back to back; the median of the rounds' ratios counts.
pub const SPLIT_SOLVE_ROUNDS: usize = 21;

/// Factor + solve of the stiff chain's Newton matrix (N = 10 000) by the
/// two-sided envelope LDLᵀ `Index3` uses (`ChainLdlt`, its halves
/// concurrent with more threads) over the one-sided one, on the gate's one
/// thread: the split must cost (almost) nothing where it cannot run in
/// parallel. Thread CPU time ([`per_call`]) of a batch of each, back to
/// back (which goes first alternates); the median over
/// [`SPLIT_SOLVE_ROUNDS`] rounds of the per-round ratio. The ratio of the
/// two solvers' separate minima would compare the quietest moment of one
/// with the quietest of the other: on a shared machine the two matrices
/// (3 MB each, beyond a core's L2) meet different cache contention from
/// other processes at different moments, and the ratio of such minima
/// spread 0.91–1.24 within one binary (docs/scaling.md).
pub fn split_chain_solve_over_one_sided() -> Check {
    use mbsolve::formulation::Index3;
    use mbsolve::linalg::{ChainLdlt, SaddlePointSolver};
    let (sys, q, _, _) = stiff_chain(10_000, 5f64.to_radians()).expect("stiff chain builds");
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let mut f = Index3::new(&sys, SolverKind::Auto).expect("formulation");
    let (qd, lam) = (vec![0.0; n], vec![1.0; m]);
    f.assemble_and_factorize(0.0, &q, &qd, &lam, 1.2, 6e-6, 3e-11)
        .expect("factorises");
    let k = f.newton_matrix();
    let b: Vec<f64> = (0..n + m).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut x = b.clone();
    let mut solvers = [true, false].map(|split| {
        let mut s = ChainLdlt::default()
            .with_residual_check(false)
            .with_split(split);
        s.analyze(k).expect("analyses");
        s
    });
    let mut best = [f64::MAX; 2];
    let mut ratios = Vec::with_capacity(SPLIT_SOLVE_ROUNDS);
    for round in 0..SPLIT_SOLVE_ROUNDS {
        let mut this = [0.0; 2];
        let order = if round % 2 == 0 { [0, 1] } else { [1, 0] };
        for i in order {
            let s = &mut solvers[i];
            this[i] = per_call(4, &mut || {
                s.factorize(k).expect("factorises");
                x.copy_from_slice(&b);
                s.solve_in_place(k, &mut x).expect("solves");
            });
            best[i] = best[i].min(this[i]);
        }
        ratios.push(this[0] / this[1]);
    }
    ratios.sort_by(f64::total_cmp);
    let r = ratios[ratios.len() / 2];
    Check {
        name: "chain Newton factor + solve N = 10 000, two-sided over one-sided, 1 thread".into(),
        ratio: r,
        threshold: SPLIT_SOLVE_MAX,
        at_most: true,
        passed: r <= SPLIT_SOLVE_MAX,
        detail: format!(
            "median of {SPLIT_SOLVE_ROUNDS} paired rounds (range {:.2}–{:.2}); \
             best split {:.0} µs vs best one-sided {:.0} µs",
            ratios[0],
            ratios[ratios.len() - 1],
            best[0] * 1e6,
            best[1] * 1e6
        ),
    }
}

/// Most Newton iterations per accepted step on the stiff chain (`../shared/peers/`).
pub const NEWTON_PER_STEP_MAX: f64 = 2.5;

/// Newton iterations per accepted step of generalized-α (h = 1e-5),
/// BDF (rtol 1e-6, atol 1e-9) and adaptive radau5 (rtol 1e-4, atol 1e-7;
/// docs/radau.md) on the stiff chain of the peer comparisons, N = 100
/// released from rest, over 0.02 s (the start transient included);
/// iteration counts are deterministic, so no repetitions.
fn newton_iterations_per_step() -> Vec<Check> {
    [
        (Method::GenAlpha, "genalpha, h = 1e-5"),
        (Method::Bdf, "bdf, rtol 1e-6"),
        (Method::Radau5, "adaptive radau5, rtol 1e-4"),
    ]
    .into_iter()
    .map(|(method, what)| {
        let mut cfg = RunConfig {
            method,
            t_end: 0.02,
            output_dt: 0.02,
            ..Default::default()
        };
        if method == Method::GenAlpha {
            cfg.ode.fixed_step = Some(1e-5);
        } else if method == Method::Radau5 {
            cfg.implicit.adaptive = true;
            cfg.ode.rtol = 1e-4;
            cfg.ode.atol = mbsolve::integrate::Tolerance::Scalar(1e-7);
        } else {
            cfg.ode.rtol = 1e-6;
            cfg.ode.atol = mbsolve::integrate::Tolerance::Scalar(1e-9);
        }
        let run = stiff_chain(100, 5f64.to_radians())
            .map_err(|e| e.to_string())
            .and_then(|(sys, q0, qd0, _)| {
                simulate(&sys, &q0, &qd0, &cfg, &mut []).map_err(|e| e.to_string())
            });
        let (ratio, detail) = match run {
            Ok((_, s)) if s.status == "completed" => {
                let get = |k: &str| s.extra.get(k).and_then(|v| v.as_u64()).unwrap_or(0);
                let its = get("newton_iterations");
                (
                    its as f64 / s.steps.max(1) as f64,
                    format!(
                        "{its} iterations, {} steps, {} factorisations, {} Newton failures",
                        s.steps,
                        s.factorizations,
                        get("newton_failures")
                    ),
                )
            }
            Ok((_, s)) => (f64::INFINITY, format!("run {}: {:?}", s.status, s.message)),
            Err(e) => (f64::INFINITY, e),
        };
        Check {
            name: format!("Newton iterations per step, {what}, stiff chain N = 100"),
            ratio,
            threshold: NEWTON_PER_STEP_MAX,
            at_most: true,
            passed: ratio <= NEWTON_PER_STEP_MAX,
            detail,
        }
    })
    .collect()
}

/// Bound of [`oversubscribed_two_over_one`]: one thread's wall time over
/// two threads' on a machine whose cores are all busy. With every core
/// busy an `auto` team does not probe and runs the one-thread path, so
/// the ratio is that of the same work measured twice: about 1, the
/// medians of five interleaved runs keeping the machine's spread inside
/// this margin (docs/scaling.md). A team that tries its helper there, or
/// spins on a descheduled partner, falls below it.
pub const OVERSUBSCRIBED_MIN: f64 = 0.85;

/// Busy processes, one per core, ended (killed and reaped) on drop.
struct BusyProcesses(Vec<std::process::Child>);

impl BusyProcesses {
    /// `yes > /dev/null` on every core (as many as the machine reports).
    fn start() -> std::io::Result<Self> {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        let mut v = Vec::new();
        for _ in 0..cores {
            let child = std::process::Command::new("yes")
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::null())
                .spawn()?;
            v.push(child);
        }
        Ok(Self(v))
    }
}

impl Drop for BusyProcesses {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Wall time of the same runs of the stiff chain (N = 4000: a state large
/// enough for the two-thread team) with one thread over two threads (the
/// default setting, `auto`, in a pool of two), with one busy process per
/// core started by the gate: a second thread that is not available must
/// not slow the run down. Each method's runs are interleaved (one
/// thread, two, five times) and the median of each setting's five taken
/// (robust to a burst of other load in either direction); the ratio is of
/// the sums over the methods.
pub fn oversubscribed_two_over_one() -> Check {
    use mbsolve::parallel::Threads;
    let (sys, q0, qd0, _) = stiff_chain(4000, 5f64.to_radians()).expect("stiff chain builds");
    let busy = match BusyProcesses::start() {
        Ok(b) => b,
        Err(e) => {
            return Check {
                name: "two threads over one, stiff chain N = 4000, all cores busy".into(),
                ratio: 0.0,
                threshold: OVERSUBSCRIBED_MIN,
                at_most: false,
                passed: false,
                detail: format!("could not start the busy processes (`yes`): {e}"),
            }
        }
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a two-thread pool");
    let cases: [(Method, f64, bool); 3] = [
        (Method::GenAlpha, 1e-5, false),
        (Method::Bdf, 1e-5, true),
        (Method::Radau5, 4e-4, false),
    ];
    let (mut one, mut two) = (0.0, 0.0);
    let mut detail = Vec::new();
    for (method, h, ndf) in cases {
        let mut cfg = RunConfig {
            method,
            t_end: if method == Method::GenAlpha {
                2e-4
            } else {
                2e-3
            },
            ode: OdeOptions {
                ndf,
                ..Default::default()
            },
            ..Default::default()
        };
        cfg.output_dt = cfg.t_end;
        if ndf {
            cfg.ode.rtol = h;
            cfg.ode.atol = mbsolve::integrate::Tolerance::Scalar(h * 1e-3);
        } else {
            cfg.ode.fixed_step = Some(h);
        }
        if method == Method::Radau5 {
            cfg.implicit.newton_tol = 1.0;
        }
        let mut times: [Vec<f64>; 2] = Default::default();
        let (mut split, mut skipped) = (0, 0);
        for _ in 0..5 {
            for (k, threads) in [Threads::One, Threads::Auto].into_iter().enumerate() {
                cfg.threads = threads;
                let t = Instant::now();
                let (_, s) = pool
                    .install(|| simulate(&sys, &q0, &qd0, &cfg, &mut []))
                    .expect("the stiff chain runs");
                times[k].push(t.elapsed().as_secs_f64());
                if k == 1 {
                    split += s.extra["halves_split"].as_u64().unwrap_or(0);
                    skipped += s.extra["threads_rule"]["skipped"].as_u64().unwrap_or(0);
                }
            }
        }
        let median = times.map(|mut v| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        });
        one += median[0];
        two += median[1];
        detail.push(format!(
            "{}{}: {:.2} s / {:.2} s ({split} halves on the second thread, \
             {skipped} probes skipped for no free core)",
            method.name(),
            if ndf { " (ndf)" } else { "" },
            median[0],
            median[1]
        ));
    }
    drop(busy);
    let r = one / two;
    Check {
        name: "two threads over one, stiff chain N = 4000, all cores busy".into(),
        ratio: r,
        threshold: OVERSUBSCRIBED_MIN,
        at_most: false,
        passed: r >= OVERSUBSCRIBED_MIN,
        detail: format!("one thread / two threads: {}", detail.join("; ")),
    }
}

/// Time `f` over `batch` calls, seconds per call: the thread's CPU time
/// ([`thread_cpu_seconds`]), wall time where that is unavailable.
fn per_call(batch: usize, f: &mut dyn FnMut()) -> f64 {
    let (c0, t) = (thread_cpu_seconds(), Instant::now());
    for _ in 0..batch {
        f();
    }
    match (c0, thread_cpu_seconds()) {
        (Some(a), Some(b)) => (b - a) / batch as f64,
        _ => t.elapsed().as_secs_f64() / batch as f64,
    }
}
