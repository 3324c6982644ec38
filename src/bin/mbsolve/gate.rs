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
//!   and solve of the stiff chain's Newton matrix at N = 10 000 (fails
//!   above [`SPLIT_SOLVE_MAX`]; [`split_chain_solve_over_one_sided`]).
//! * Newton iterations per step of generalized-α and BDF on the stiff chain
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
//!   integrator's counts per step stay within ±15 % of [`WORK_PINS`]; one
//!   factorisation and one solve per index-1 right-hand side
//!   ([`work_counts`]).
//! * hot paths against a yardstick: the sparse and the chain LDLᵀ factor +
//!   solve, the index-3 residual and one Newton iteration of the stiff
//!   chain (N = 1000), each over a fixed block-tridiagonal Cholesky of
//!   known flop count ([`yardstick`]) timed in the same round, in thread
//!   CPU time; the median of [`HOT_PATH_ROUNDS`] rounds must stay below
//!   [`HOT_PATH_MARGIN`] × the clean ratio ([`HOT_PATH_CLEAN`];
//!   [`hot_paths_against_yardstick`]). A hot path done twice fails it.
//!
//! Timings of the ratio checks are the minimum over interleaved
//! repetitions of the thread's CPU time (robust to a shared machine: the
//! time other processes hold the core is not counted) on a single thread
//! (so the ratio measures algorithmic scaling, not the concurrency that
//! only large N switch on), except the oversubscribed check (wall time).

use mbsolve::builders::{build_rod, stiff_chain, RodParams};
use mbsolve::formulation::{Index1, Index1Options};
use mbsolve::integrate::{Method, OdeOptions};
use mbsolve::linalg::SolverKind;
use mbsolve::model::{Evaluation, System};
use mbsolve::simulation::{simulate, RunConfig};
use serde::Serialize;
use std::time::Instant;

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

/// Whole generalized-α run of the stiff chain (N = 1000, h = 1e-5, 400
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

/// Bound of [`split_chain_solve_over_one_sided`].
pub const SPLIT_SOLVE_MAX: f64 = 1.2;

/// Factor + solve of the stiff chain's Newton matrix (N = 10 000) by the
/// two-sided envelope LDLᵀ `Index3` uses (`ChainLdlt`, its halves
/// concurrent with more threads) over the one-sided one, on the gate's one
/// thread: the split must cost (almost) nothing where it cannot run in
/// parallel. Thread CPU time ([`per_call`]), minimum over interleaved
/// batches.
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
    for _ in 0..15 {
        for (s, t) in solvers.iter_mut().zip(&mut best) {
            let per = per_call(4, &mut || {
                s.factorize(k).expect("factorises");
                x.copy_from_slice(&b);
                s.solve_in_place(k, &mut x).expect("solves");
            });
            *t = t.min(per);
        }
    }
    let r = best[0] / best[1];
    Check {
        name: "chain Newton factor + solve N = 10 000, two-sided over one-sided, 1 thread".into(),
        ratio: r,
        threshold: SPLIT_SOLVE_MAX,
        at_most: true,
        passed: r <= SPLIT_SOLVE_MAX,
        detail: format!(
            "split {:.0} µs vs one-sided {:.0} µs",
            best[0] * 1e6,
            best[1] * 1e6
        ),
    }
}

/// Most Newton iterations per accepted step on the stiff chain (`../shared/peers/`).
pub const NEWTON_PER_STEP_MAX: f64 = 2.5;

/// Newton iterations per accepted step of generalized-α (h = 1e-5) and
/// BDF (rtol 1e-6, atol 1e-9) on the stiff chain of the peer comparisons,
/// N = 100 released from rest, over 0.02 s (the start transient included);
/// iteration counts are deterministic, so no repetitions.
fn newton_iterations_per_step() -> Vec<Check> {
    [
        (Method::GenAlpha, "genalpha, h = 1e-5"),
        (Method::Bdf, "bdf, rtol 1e-6"),
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

/// Bound of [`oversubscribed_two_over_one`]: two threads may take at most
/// twice the wall time of one on a machine whose cores are all busy. The
/// target is 0.95, but the ratio of a correct build spreads over about
/// 0.8–1.07 from run to run on a 2-core machine, so a gate there would fail
/// at random; the regression this check guards against (a team that spins
/// on a descheduled partner) gives 0.03–0.2 (docs/scaling.md).
pub const OVERSUBSCRIBED_MIN: f64 = 0.5;

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
        let mut split = 0;
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
            "{}{}: {:.2} s / {:.2} s ({split} halves on the second thread)",
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

// ---------------------------------------------------------------------------
// Hot paths against an in-process yardstick, and deterministic work counts

/// Blocks of the yardstick ([`yardstick`]).
const YARD_BLOCKS: usize = 20_000;

/// Flops of one yardstick run: per 3 × 3 block about 36 for the Schur
/// update, 20 for the Cholesky factor, 45 for the next off-diagonal block
/// and 60 for the forward and back substitution: ≈ 160 per block.
pub const YARD_FLOPS: f64 = 160.0 * YARD_BLOCKS as f64;

/// The yardstick of the hot-path timings: the block Cholesky factorisation
/// and solve of a fixed symmetric positive definite block-tridiagonal
/// matrix (3 × 3 blocks, [`YARD_BLOCKS`] of them; diagonal blocks
/// `4I + S`, off-diagonal blocks `−I/2 + T`, `S`, `T` small and fixed),
/// about [`YARD_FLOPS`] flops streamed through memory like a chain
/// factorisation. Plain Rust without the crate's or faer's code, so that
/// a regression there cannot move the yardstick. Returns a checksum (kept
/// live against the optimiser).
fn yardstick(l_diag: &mut [[f64; 9]], l_off: &mut [[f64; 9]], x: &mut [[f64; 3]]) -> f64 {
    let nb = l_diag.len();
    let d = |i: usize| -> [f64; 9] {
        let s = 0.1 * ((i % 7) as f64) / 7.0;
        [4.0 + s, s, 0.0, s, 4.0, s, 0.0, s, 4.0 - s]
    };
    let b = |i: usize| -> [f64; 9] {
        let t = 0.05 * ((i % 5) as f64) / 5.0;
        [-0.5, t, 0.0, 0.0, -0.5, t, t, 0.0, -0.5]
    };
    for i in 0..nb {
        // A = D_i − L_{i,i−1} L_{i,i−1}ᵀ (lower triangle)
        let mut a = d(i);
        if i > 0 {
            let lo = &l_off[i - 1];
            for r in 0..3 {
                for c in 0..=r {
                    let mut s = 0.0;
                    for k in 0..3 {
                        s += lo[3 * r + k] * lo[3 * c + k];
                    }
                    a[3 * r + c] -= s;
                }
            }
        }
        // Cholesky of A
        let l = &mut l_diag[i];
        *l = [0.0; 9];
        for c in 0..3 {
            let mut s = a[3 * c + c];
            for k in 0..c {
                s -= l[3 * c + k] * l[3 * c + k];
            }
            let p = s.sqrt();
            l[3 * c + c] = p;
            for r in c + 1..3 {
                let mut s = a[3 * r + c];
                for k in 0..c {
                    s -= l[3 * r + k] * l[3 * c + k];
                }
                l[3 * r + c] = s / p;
            }
        }
        // L_{i+1,i} = B_iᵀ L_iiᵀ⁻¹: rows x of X with X L_iiᵀ = B_iᵀ
        if i + 1 < nb {
            let bi = b(i);
            let lo = &mut l_off[i];
            for r in 0..3 {
                for c in 0..3 {
                    let mut s = bi[3 * c + r];
                    for k in 0..c {
                        s -= lo[3 * r + k] * l[3 * c + k];
                    }
                    lo[3 * r + c] = s / l[3 * c + c];
                }
            }
        }
    }
    // forward: L y = 1, back: Lᵀ x = y
    for i in 0..nb {
        let mut r = [1.0; 3];
        if i > 0 {
            let (lo, y) = (&l_off[i - 1], x[i - 1]);
            for (k, rk) in r.iter_mut().enumerate() {
                *rk -= lo[3 * k] * y[0] + lo[3 * k + 1] * y[1] + lo[3 * k + 2] * y[2];
            }
        }
        let l = &l_diag[i];
        for k in 0..3 {
            let mut s = r[k];
            for j in 0..k {
                s -= l[3 * k + j] * x[i][j];
            }
            x[i][k] = s / l[3 * k + k];
        }
    }
    for i in (0..nb).rev() {
        let mut r = x[i];
        if i + 1 < nb {
            let (lo, y) = (&l_off[i], x[i + 1]);
            for (k, rk) in r.iter_mut().enumerate() {
                *rk -= lo[k] * y[0] + lo[3 + k] * y[1] + lo[6 + k] * y[2];
            }
        }
        let l = &l_diag[i];
        for k in (0..3).rev() {
            let mut s = r[k];
            for j in k + 1..3 {
                s -= l[3 * j + k] * x[i][j];
            }
            x[i][k] = s / l[3 * k + k];
        }
    }
    x.iter().map(|v| v[0] + v[1] + v[2]).sum()
}

/// Bounds of [`hot_paths_against_yardstick`]: each hot path's time over
/// the yardstick's may be at most this many times its clean ratio
/// ([`HOT_PATH_CLEAN`]). A path done twice costs at least 1.5× (2× its
/// repeated part; the sparse factor + solve done twice, its scaling and
/// scatter once: 1.6×), while a clean run's median stays within about
/// 1.1× of the clean ratio (thread CPU time; docs/scaling.md): 1.3 sits at
/// the geometric middle of the two.
pub const HOT_PATH_MARGIN: f64 = 1.3;

/// Repetitions of each hot-path measurement; the median of the per-round
/// ratios counts.
pub const HOT_PATH_ROUNDS: usize = 15;

/// One hot path: its name, the ratio to the yardstick measured on a clean
/// build (the reference of the bound, a pin) and the closure timed.
struct HotPath<'a> {
    name: &'static str,
    clean: f64,
    run: Box<dyn FnMut() + 'a>,
}

/// CPU time of the calling thread in seconds (`clock_gettime` with
/// `CLOCK_THREAD_CPUTIME_ID`, nanoseconds, current slice included): unlike
/// wall time it does not count the time other processes hold the core.
/// `None` where unavailable.
#[cfg(target_os = "linux")]
fn thread_cpu_seconds() -> Option<f64> {
    #[repr(C)]
    struct Timespec {
        tv_sec: std::ffi::c_long,
        tv_nsec: std::ffi::c_long,
    }
    extern "C" {
        fn clock_gettime(clock: std::ffi::c_int, tp: *mut Timespec) -> std::ffi::c_int;
    }
    const CLOCK_THREAD_CPUTIME_ID: std::ffi::c_int = 3;
    let mut ts = Timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec of the C layout
    // (`time_t` and `long` are `long` on Linux); the call only writes it.
    let rc = unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    (rc == 0).then_some(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
}

#[cfg(not(target_os = "linux"))]
fn thread_cpu_seconds() -> Option<f64> {
    None
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

/// The hot paths of an implicit run on the stiff chain (N = 1000, its
/// Newton matrix at a bent, moving state), each timed against the
/// [`yardstick`] in the same round, on the gate's one thread: the sparse
/// LDLᵀ factor + solve (faer, chain ordering), the chain LDLᵀ factor +
/// solve (`ChainLdlt`, the Newton default), the index-3 residual and one
/// Newton iteration (residual, assembly and factorisation, solve). For
/// each path the median over [`HOT_PATH_ROUNDS`] rounds of
/// (path time / yardstick time) must stay below [`HOT_PATH_MARGIN`] ×
/// its clean ratio.
pub fn hot_paths_against_yardstick() -> Vec<Check> {
    use mbsolve::formulation::Index3;
    use mbsolve::linalg::{ChainLdlt, SaddlePointSolver, SparseLdlt};
    let (sys, q0, _, _) = stiff_chain(1000, 5f64.to_radians()).expect("stiff chain builds");
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let q: Vec<f64> = q0
        .iter()
        .enumerate()
        .map(|(i, x)| x + 1e-4 * (i as f64 * 0.7).sin())
        .collect();
    let qd: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 * 1.3).cos()).collect();
    let qdd: Vec<f64> = (0..n).map(|i| (i as f64 * 0.4).sin()).collect();
    let lam: Vec<f64> = (0..m).map(|i| 1.0 + 0.1 * (i as f64 * 0.3).sin()).collect();
    let (h, beta, gamma) = (1e-5, 0.3, 0.6);
    let (c_m, c_c, c_k) = (1.0, gamma * h, beta * h * h);
    let mut f = Index3::new(&sys, SolverKind::Auto).expect("formulation");
    f.assemble_and_factorize(0.0, &q, &qd, &lam, c_m, c_c, c_k)
        .expect("factorises");
    let k = f.newton_matrix().clone();
    let b: Vec<f64> = (0..n + m).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut sparse = SparseLdlt::default().with_residual_check(false);
    let mut chain = ChainLdlt::default().with_residual_check(false);
    let mut x = b.clone();
    let setup = sparse
        .analyze(&k)
        .and_then(|_| chain.analyze(&k))
        .map_err(|e| e.to_string());
    if let Err(e) = setup {
        return vec![Check {
            name: "hot paths against the yardstick".into(),
            ratio: f64::INFINITY,
            threshold: HOT_PATH_MARGIN,
            at_most: true,
            passed: false,
            detail: e,
        }];
    }
    let mut x2 = b.clone();
    let mut x3 = b.clone();
    let mut r = vec![0.0; n + m];
    let mut r2 = vec![0.0; n + m];
    let mut f2 = Index3::new(&sys, SolverKind::Auto).expect("formulation");
    let mut paths = [
        HotPath {
            name: "sparse LDLᵀ factor + solve (faer), stiff chain N = 1000 Newton matrix",
            clean: 0.0,
            run: Box::new(|| {
                sparse.factorize(&k).expect("factorises");
                x.copy_from_slice(&b);
                sparse.solve_in_place(&k, &mut x).expect("solves");
            }),
        },
        HotPath {
            name: "chain LDLᵀ factor + solve, stiff chain N = 1000 Newton matrix",
            clean: 0.0,
            run: Box::new(|| {
                chain.factorize(&k).expect("factorises");
                x2.copy_from_slice(&b);
                chain.solve_in_place(&k, &mut x2).expect("solves");
            }),
        },
        HotPath {
            name: "index-3 residual, stiff chain N = 1000",
            clean: 0.0,
            run: Box::new(|| {
                f.residual_into(0.0, &q, &qd, &qdd, &lam, 1.0, &mut r)
                    .expect("residual");
            }),
        },
        HotPath {
            name: "one Newton iteration (residual, assembly + factorisation, solve), stiff chain N = 1000",
            clean: 0.0,
            run: Box::new(|| {
                f2.residual_into(0.0, &q, &qd, &qdd, &lam, 1.0, &mut r2)
                    .expect("residual");
                f2.assemble_and_factorize(0.0, &q, &qd, &lam, c_m, c_c, c_k)
                    .expect("factorises");
                x3.copy_from_slice(&r2);
                f2.solve_newton(0.0, &mut x3).expect("solves");
            }),
        },
    ];
    for (p, clean) in paths.iter_mut().zip(HOT_PATH_CLEAN) {
        p.clean = clean;
    }
    let mut l_diag = vec![[0.0; 9]; YARD_BLOCKS];
    let mut l_off = vec![[0.0; 9]; YARD_BLOCKS];
    let mut xy = vec![[0.0; 3]; YARD_BLOCKS];
    let mut yard = || {
        std::hint::black_box(yardstick(&mut l_diag, &mut l_off, &mut xy));
    };
    // warm-up and batch sizes of ≈ 4 ms each
    let t_yard = per_call(3, &mut yard);
    let batch = |t: f64| ((4e-3 / t.max(1e-9)).ceil() as usize).clamp(1, 1000);
    let yard_batch = batch(t_yard);
    let batches: Vec<usize> = paths
        .iter_mut()
        .map(|p| batch(per_call(3, &mut p.run)))
        .collect();
    let mut ratios = vec![Vec::with_capacity(HOT_PATH_ROUNDS); paths.len()];
    let mut yard_times = Vec::with_capacity(HOT_PATH_ROUNDS);
    for _ in 0..HOT_PATH_ROUNDS {
        for (i, p) in paths.iter_mut().enumerate() {
            // the yardstick right before each path: a load change hits both
            let ty = per_call(yard_batch, &mut yard);
            let tp = per_call(batches[i], &mut p.run);
            yard_times.push(ty);
            ratios[i].push(tp / ty);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let ty = median(&mut yard_times);
    paths
        .iter()
        .zip(&mut ratios)
        .map(|(p, rs)| {
            let r = median(rs);
            let bound = HOT_PATH_MARGIN * p.clean;
            Check {
                name: format!("{} over the yardstick", p.name),
                ratio: r,
                threshold: bound,
                at_most: true,
                passed: r <= bound,
                detail: format!(
                    "{r:.4}, median of {HOT_PATH_ROUNDS} rounds (spread {:.4}–{:.4}); {:.1} µs vs yardstick {:.2} ms ({:.2} Gflop/s) of thread CPU time; clean ratio {}",
                    rs[0],
                    rs[rs.len() - 1],
                    r * ty * 1e6,
                    ty * 1e3,
                    YARD_FLOPS / ty * 1e-9,
                    p.clean
                ),
            }
        })
        .collect()
}

/// Ratios (path time / yardstick time) of [`hot_paths_against_yardstick`]
/// on a clean build, in the order of the paths there: sparse, chain,
/// residual, Newton iteration (pins from clean gate runs: docs/scaling.md,
/// "The gate's hot paths and work counts").
pub const HOT_PATH_CLEAN: [f64; 4] = [0.217, 0.142, 0.0086, 0.198];

/// Work counts of fixed runs, deterministic (no timing): per accepted
/// step, the factorisations, residual evaluations and linear solves the
/// solver and the formulation count themselves must equal those the
/// integrator asked for (a factorisation or solve done twice below the
/// integrator doubles them), and the integrator's own counts per step stay
/// within ±15 % of the pinned values ([`WORK_PINS`]; a change of the
/// Newton strategy moves them on purpose and updates the pins with its
/// reason).
pub fn work_counts() -> Vec<Check> {
    use mbsolve::formulation::Index3;
    use mbsolve::integrate::{Bdf, GenAlpha, ImplicitOptions, Tolerance};
    let mut checks = Vec::new();
    let (sys, q0, qd0, _) = match stiff_chain(100, 5f64.to_radians()) {
        Ok(c) => c,
        Err(e) => {
            return vec![Check {
                name: "work counts".into(),
                ratio: f64::INFINITY,
                threshold: 0.0,
                at_most: true,
                passed: false,
                detail: e.to_string(),
            }]
        }
    };
    let t_end = 2e-3;
    for (what, pins) in WORK_PINS {
        let mut f = Index3::new(&sys, SolverKind::Auto).expect("formulation");
        let ode = if what.starts_with("genalpha") {
            OdeOptions {
                fixed_step: Some(1e-5),
                ..Default::default()
            }
        } else {
            OdeOptions {
                rtol: 1e-6,
                atol: Tolerance::Scalar(1e-9),
                ..Default::default()
            }
        };
        let run = if what.starts_with("genalpha") {
            let mut g =
                GenAlpha::new(Method::GenAlpha, ImplicitOptions::default(), ode).expect("options");
            g.integrate(&mut f, 0.0, t_end, &q0, &qd0, &[t_end], &mut ())
                .map(|r| (r, g.stats()))
        } else {
            let mut b = Bdf::new(ode).expect("options");
            b.integrate(&mut f, 0.0, t_end, &q0, &qd0, &[t_end], &mut ())
                .map(|r| (r, b.stats()))
        };
        let (rep, st) = match run {
            Ok((rep, st)) if rep.termination == mbsolve::integrate::Termination::Completed => {
                (rep, st)
            }
            Ok((rep, _)) => {
                checks.push(failed_count(what, format!("{:?}", rep.termination)));
                continue;
            }
            Err(e) => {
                checks.push(failed_count(what, e.to_string()));
                continue;
            }
        };
        let fs = f.stats();
        let steps = st.steps.max(1) as f64;
        // below the integrator: the solver's and the formulation's own counts
        // (the initial accelerations use the mass matrix's solver)
        let same = [
            (
                "Newton-matrix factorisations (solver / integrator)",
                fs.newton_solver.factorizations,
                st.factorizations,
            ),
            (
                "Newton solves (solver / integrator's corrections)",
                fs.newton_solver.solves,
                st.newton_iterations,
            ),
            (
                "residual evaluations (formulation / integrator)",
                fs.residuals,
                st.residual_evaluations,
            ),
        ];
        for (name, below, asked) in same {
            // the integrator counts its initial accelerations as one
            // residual evaluation; the formulation counts them apart
            let below = if name.starts_with("residual") {
                below + 1
            } else {
                below
            };
            let r = below as f64 / asked.max(1) as f64;
            checks.push(Check {
                name: format!("work count, {what}: {name}"),
                ratio: r,
                threshold: 1.0,
                at_most: true,
                passed: below == asked,
                detail: format!("{below} counted by the solver/formulation, {asked} asked for"),
            });
        }
        let per_step = [
            ("factorisations", st.factorizations as f64 / steps),
            (
                "residual evaluations",
                st.residual_evaluations as f64 / steps,
            ),
            ("Newton solves", st.newton_iterations as f64 / steps),
        ];
        for ((name, got), pin) in per_step.into_iter().zip(pins) {
            let r = got / pin;
            checks.push(Check {
                name: format!("work count, {what}: {name} per step over the pin {pin}"),
                ratio: r,
                threshold: 1.15,
                at_most: true,
                passed: (1.0 / 1.15..=1.15).contains(&r),
                detail: format!(
                    "{got:.3} per step ({} steps, {} rejected); at least 1/1.15 of the pin too",
                    st.steps, rep.stats.failed_steps
                ),
            });
        }
    }
    // the index-1 right-hand side: one factorisation and one solve each
    let (rod, _) = build_rod(&RodParams::problem_b(200)).expect("problem B builds");
    let (q, qd) = rod.initial_state();
    let opts = Index1Options {
        linear_solver: SolverKind::Sparse,
        ..Default::default()
    };
    let mut f = Index1::new(&rod, opts).expect("formulation");
    let mut qdd = vec![0.0; rod.n_coords()];
    let before = f.stats();
    for _ in 0..10 {
        f.accelerations(0.0, &q, &qd, &mut qdd)
            .expect("RHS evaluates");
    }
    let after = f.stats();
    let fac = after.solver.factorizations - before.solver.factorizations;
    let sol = after.solver.solves - before.solver.solves;
    let evals = after.evaluations - before.evaluations;
    checks.push(Check {
        name: "work count, index-1 RHS (falling rod N = 200, sparse): factorisations and solves per evaluation".into(),
        ratio: (fac + sol) as f64 / (2 * evals).max(1) as f64,
        threshold: 1.0,
        at_most: true,
        passed: fac == evals && sol == evals,
        detail: format!("{evals} evaluations: {fac} factorisations, {sol} solves"),
    });
    checks
}

fn failed_count(what: &str, detail: String) -> Check {
    Check {
        name: format!("work counts, {what}"),
        ratio: f64::INFINITY,
        threshold: 1.0,
        at_most: true,
        passed: false,
        detail,
    }
}

/// Pinned work per accepted step on the stiff chain (N = 100, from rest,
/// 0 … 2 ms): factorisations, residual evaluations, Newton solves, for
/// generalized-α at h = 1e-5 and bdf at rtol 1e-6, atol 1e-9 (pins of
/// the clean build's counts, docs/scaling.md "Gate").
pub const WORK_PINS: [(&str, [f64; 3]); 2] = [
    (
        "genalpha h = 1e-5, stiff chain N = 100",
        [0.941, 3.158, 3.153],
    ),
    ("bdf rtol 1e-6, stiff chain N = 100", [0.142, 2.152, 2.149]),
];
