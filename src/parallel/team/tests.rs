//! Unit tests of the two-thread team (`super`).

use super::super::with_threads;
use super::*;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// Wait until the helper runs and is free.
fn helper_ready() -> bool {
    // an event, not a deadline: the helper starts when the scheduler
    // runs it (a helper that never starts hangs the test, and CI's step
    // limit names it)
    while !concurrent() {
        std::thread::yield_now();
    }
    true
}

fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
}

/// `b` runs on the helper whenever `a` waits until `b` has started: the
/// caller cannot take it back then (no dependence on timing).
#[test]
fn a_half_the_helper_started_runs_there_and_returns_its_result() {
    let (_, rep) = with_threads(Threads::Two, || {
        run(false, 0, || {
            assert!(helper_ready(), "the helper started");
            let me = std::thread::current().id();
            for k in 0..200u64 {
                let started = AtomicBool::new(false);
                let (a, (b, id)) = join(
                    || {
                        while !started.load(Ordering::SeqCst) {
                            std::hint::spin_loop();
                        }
                        k * 2
                    },
                    || {
                        started.store(true, Ordering::SeqCst);
                        (k * 3, std::thread::current().id())
                    },
                );
                assert_eq!((a, b), (2 * k, 3 * k));
                assert_ne!(id, me, "join {k}");
            }
        })
    });
    assert_eq!(rep.halves_split, 200);
    assert_eq!(rep.threads(), 2);
}

/// After MISS_LIMIT take-backs in a row from an awake helper an adaptive
/// team runs joins alone while no core is free, longer after each further
/// miss; a hit resets it. With a core free (an idle machine whose host
/// paused the helper's core) it keeps posting. Take-backs from a parked
/// helper (woken too late) are no misses and do not interrupt a row of
/// them.
#[test]
fn a_team_whose_helper_misses_backs_off() {
    // opened with a core free: its A/B rule starts with a window with the
    // helper, so the joins' backing off alone decides here
    TEST_FREE.with(|f| f.set(Some(true)));
    let team = Team::new(true);
    let parked = Ran::TakenBack { awake: false };
    let missed = Ran::TakenBack { awake: true };
    // a core free: any number of misses in a row, the team keeps posting
    for _ in 0..10 * MISS_LIMIT {
        team.note(missed);
    }
    assert_eq!(team.solo_left.load(Ordering::Relaxed), 0);
    assert!(!team.solo_join());
    // no core free: the next miss is the MISS_LIMIT-th in a row
    TEST_FREE.with(|f| f.set(Some(false)));
    team.note(missed);
    assert_eq!(team.solo_left.load(Ordering::Relaxed), SOLO_MIN);
    while team.solo_join() {}
    team.note(Ran::Helper);
    assert_eq!(team.misses.load(Ordering::Relaxed), 0);
    // any number of late wake-ups: the team keeps posting
    let before = team.taken_back.load(Ordering::Relaxed);
    for _ in 0..10 * MISS_LIMIT {
        team.note(parked);
    }
    assert_eq!(team.solo_left.load(Ordering::Relaxed), 0);
    assert!(!team.solo_join());
    assert_eq!(
        team.taken_back.load(Ordering::Relaxed) - before,
        10 * MISS_LIMIT as usize
    );
    for k in 0..MISS_LIMIT {
        team.note(missed);
        team.note(parked);
        let backed_off = team.solo_left.load(Ordering::Relaxed) > 0;
        assert_eq!(backed_off, k + 1 == MISS_LIMIT, "miss {k}");
    }
    assert_eq!(team.solo_left.load(Ordering::Relaxed), SOLO_MIN);
    let mut alone = 0;
    while team.solo_join() {
        alone += 1;
    }
    assert_eq!(alone, SOLO_MIN);
    // the next try misses again: twice as long alone
    team.note(missed);
    assert_eq!(team.solo_left.load(Ordering::Relaxed), 2 * SOLO_MIN);
    // a hit resets
    team.note(Ran::Helper);
    assert_eq!(team.backoff.load(Ordering::Relaxed), SOLO_MIN);
    assert_eq!(team.misses.load(Ordering::Relaxed), 0);
    // a forced team never backs off
    let forced = Team::new(false);
    for _ in 0..10 * MISS_LIMIT {
        forced.note(missed);
    }
    assert!(!forced.solo_join());
    TEST_FREE.with(|f| f.set(None));
}

/// Drives an A/B rule of windows of `w` passes for `passes` passes
/// on a synthetic clock where a pass costs `cost(alone)` µs; returns
/// (alone, wake) per pass.
fn drive(a: &mut Adapt, passes: usize, cost: impl Fn(bool) -> u64) -> Vec<(bool, bool)> {
    let t0 = Instant::now();
    let mut t = Duration::ZERO;
    (0..passes)
        .map(|_| {
            let r = a.pass(t0 + t, || true);
            t += Duration::from_micros(cost(r.0));
            r
        })
        .collect()
}

/// The A/B rule probes team, alone, alone, team, runs the faster way
/// for EXPLOIT_MIN windows (twice as long after a confirming probe),
/// and changes its mind when the costs change; a tie goes to one
/// thread; the helper is woken on the last pass before a team window.
#[test]
fn the_ab_rule_runs_the_faster_way_and_probes_again() {
    let w = 2usize;
    let probe = [false, false, true, true, true, true, false, false];
    let mut a = Adapt::new(w as u32, true);
    // the team faster, not clearly (0.87: above CLEAR_MARGIN)
    let r = drive(&mut a, 8 + 8 * w + 8 + 16 * w, |alone| {
        if alone {
            115
        } else {
            100
        }
    });
    let modes: Vec<bool> = r.iter().map(|x| x.0).collect();
    assert_eq!(modes[..8], probe);
    assert!(modes[8..8 + 8 * w].iter().all(|&s| !s));
    assert_eq!(modes[8 + 8 * w..16 + 8 * w], probe);
    assert!(modes[16 + 8 * w..].iter().all(|&s| !s));
    assert_eq!(a.exploit, 2 * EXPLOIT_MIN);
    assert_eq!(a.decided, [2, 0]);
    // woken exactly on the last pass of the second alone window
    let wakes: Vec<usize> = (0..8).filter(|&i| r[i].1).collect();
    assert_eq!(wakes, [5]);
    // the machine gets busy: the team now 1.5× slower
    let r = drive(&mut a, 8 + 8 * w + 8, |alone| if alone { 200 } else { 300 });
    let modes: Vec<bool> = r.iter().map(|x| x.0).collect();
    assert_eq!(modes[..8], probe);
    assert!(modes[8..8 + 8 * w].iter().all(|&s| s));
    assert_eq!(a.decided, [2, 1]);
    assert_eq!(a.exploit, EXPLOIT_MIN);
    // the helper is woken before the next probe's team window
    assert!(r[8 + 8 * w - 1].1);
    // a tie (within TEAM_MARGIN) goes to one thread
    let mut b = Adapt::new(1, true);
    drive(&mut b, 5, |alone| if alone { 100 } else { 99 });
    assert_eq!(b.decided, [0, 1]);
}

/// A probe whose team windows took at most CLEAR_MARGIN of the time
/// alone runs the longest stretch (EXPLOIT_MAX windows) at once: over a
/// run of radau5's 2014 passes at N = 10 000 in windows of PROBE_PASSES,
/// one probe runs, against four after closer probes (the team within
/// TEAM_MARGIN, above CLEAR_MARGIN: stretches of 8, 16, 32 windows).
#[test]
fn a_clear_gain_probes_less_often() {
    let w = PROBE_PASSES as usize;
    let alone_passes = |alone_cost: u64| {
        let mut a = Adapt::new(w as u32, true);
        let r = drive(&mut a, 2014, |alone| if alone { alone_cost } else { 100 });
        (r.iter().filter(|x| x.0).count(), a.decided)
    };
    assert_eq!(alone_passes(170), (2 * w, [1, 0]));
    assert_eq!(alone_passes(115), (8 * w, [4, 0]));
    let mut a = Adapt::new(2, true);
    let k = EXPLOIT_MAX;
    for _ in 0..3 {
        let r = drive(
            &mut a,
            8 + 2 * k as usize,
            |alone| {
                if alone {
                    170
                } else {
                    100
                }
            },
        );
        assert!(r[8..].iter().all(|x| !x.0), "stretch of {k} windows");
        assert_eq!(a.exploit, k);
    }
}

/// A team whose A/B rule changes its way at every pass (windows of
/// one pass) gives the bits of one thread, and counts the same passes
/// as a team that always posts: the passes measure progress whichever
/// way they run.
#[test]
fn an_alternating_team_gives_the_bits_of_one_thread() {
    use crate::integrate::{Method, OdeOptions};
    use crate::simulation::{simulate, RunConfig};
    let (sys, q0, qd0, _) = crate::builders::stiff_chain(2000, 5f64.to_radians()).unwrap();
    for (method, step) in [
        (Method::Bdf, None),
        (Method::GenAlpha, Some(1e-5)),
        (Method::Radau5, Some(1e-5)),
    ] {
        let cfg = RunConfig {
            method,
            t_end: 3e-5,
            output_dt: 1e-5,
            ode: OdeOptions {
                rtol: 1e-5,
                fixed_step: step,
                ..Default::default()
            },
            ..Default::default()
        };
        let run = |threads| {
            let cfg = RunConfig {
                threads,
                ..cfg.clone()
            };
            pool(2).install(|| {
                TEST_WINDOW.with(|w| w.set(Some(1)));
                TEST_FREE.with(|f| f.set(Some(true)));
                TEST_PASSES.with(|p| p.set(0));
                let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
                TEST_WINDOW.with(|w| w.set(None));
                TEST_FREE.with(|f| f.set(None));
                (traj, s, TEST_PASSES.with(|p| p.get()))
            })
        };
        let (one, _, _) = run(Threads::One);
        let (two, s2, p2) = run(Threads::Two);
        let (auto, sa, pa) = run(Threads::Auto);
        assert!(p2 > 10, "{method:?}: {p2} passes");
        assert_eq!(p2, pa, "{method:?}");
        let count = |s: &crate::simulation::Summary, k: &str| s.extra[k].as_u64().unwrap();
        assert!(count(&sa, "halves_solo") > 0, "{method:?}");
        // the summary names the rule's decision: the probes of windows
        // of one pass decided at least once
        let rule = &sa.extra["threads_rule"];
        assert_eq!(rule["decision"], "probed", "{method:?}");
        let probes = rule["team"].as_u64().unwrap() + rule["alone"].as_u64().unwrap();
        assert!(probes > 0 && rule["last_ratio"].as_f64().unwrap() > 0.0);
        let reason = sa.extra["threads_reason"].as_str().unwrap();
        assert!(reason.contains("probes chose"), "{reason}");
        assert_eq!(s2.extra["threads_rule"]["decision"], "two");
        for traj in [&two, &auto] {
            assert_eq!(one.t, traj.t);
            for (a, b) in one.q.iter().zip(&traj.q).chain(one.qd.iter().zip(&traj.qd)) {
                assert!(
                    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{method:?}"
                );
            }
        }
        assert_eq!(
            count(&s2, "newton_iterations"),
            count(&sa, "newton_iterations")
        );
    }
}

/// A bdf run (rtol 1e-5) to `t_end` with outputs every `output_dt`.
fn bdf_run(t_end: f64, output_dt: f64) -> crate::simulation::RunConfig {
    crate::simulation::RunConfig {
        method: crate::integrate::Method::Bdf,
        t_end,
        output_dt,
        ode: crate::integrate::OdeOptions {
            rtol: 1e-5,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// The rule's decision and reason for a run that opens no team: a
/// small state, a pool of one thread, the setting one.
#[test]
fn the_summary_says_why_a_run_used_one_thread() {
    use crate::simulation::{simulate, RunConfig};
    let chain = |n| crate::builders::stiff_chain(n, 5f64.to_radians()).unwrap();
    let cfg = bdf_run(1e-5, 1e-5);
    let rule = |n, pool_threads, threads| {
        let (sys, q0, qd0, _) = chain(n);
        let cfg = RunConfig {
            threads,
            ..cfg.clone()
        };
        let (_, s) =
            pool(pool_threads).install(|| simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap());
        assert_eq!(s.extra["threads"], 1);
        assert_eq!(s.extra["split"], false);
        (
            s.extra["threads_rule"].clone(),
            s.extra["threads_reason"].as_str().unwrap().to_string(),
        )
    };
    // 10 segments: a state of 60 entries
    let (r, why) = rule(10, 2, Threads::Auto);
    assert_eq!(r["decision"], "small");
    assert_eq!(r["state"], 60);
    assert_eq!(r["min"], 2 * super::super::PARALLEL_MIN_COORDS);
    assert!(why.contains("60 entries"), "{why}");
    // 2000 segments (12 000 entries) in a pool of one thread
    let (r, why) = rule(2000, 1, Threads::Auto);
    assert_eq!(r["decision"], "no_second_thread");
    assert_eq!(
        (r["pool"].clone(), r["in_pool"].clone()),
        (1.into(), true.into())
    );
    assert!(why.contains("pool has 1 thread "), "{why}");
    let (r, why) = rule(2000, 2, Threads::One);
    assert_eq!(r["decision"], "one");
    assert!(why.starts_with("one thread"), "{why}");
}

/// With no helper running, a posted half comes back to the caller.
#[test]
fn a_posted_half_nobody_takes_runs_on_the_caller() {
    let h = Handover::new();
    // no helper: `join` is called directly on the hand-over
    for k in 0..10u64 {
        let me = std::thread::current().id();
        let ((a, (b, id)), ran) = h.join(|| k, || (k + 1, std::thread::current().id()));
        assert_eq!((a, b, id), (k, k + 1, me));
        assert!(matches!(ran, Ran::TakenBack { .. }));
    }
}

/// A bdf run of a stiff chain above the parallel thresholds with two
/// threads forced: the driver opens a team and posts halves (the
/// results' independence of the thread count: tests/linalg/parallel_newton.rs).
#[test]
fn a_large_implicit_run_posts_halves_to_the_helper() {
    use crate::simulation::simulate;
    let (sys, q0, qd0, _) = crate::builders::stiff_chain(2000, 5f64.to_radians()).unwrap();
    let mut cfg = bdf_run(2e-4, 1e-4);
    cfg.threads = Threads::Two;
    let (_, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    let posted =
        s.extra["halves_split"].as_u64().unwrap() + s.extra["halves_taken_back"].as_u64().unwrap();
    assert!(posted > 100, "{posted} halves posted");
    assert_eq!(s.extra["halves_solo"].as_u64(), Some(0));
    // one thread: no team, nothing split
    cfg.threads = Threads::One;
    let (_, s) = pool(2).install(|| simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap());
    assert_eq!(s.extra["threads"].as_u64(), Some(1));
    assert_eq!(s.extra["halves_split"].as_u64(), Some(0));
    assert_eq!(s.extra["halves_taken_back"].as_u64(), Some(0));
}

/// The stability check before a run (`fastest_modes`: 3 power
/// iterations of 61 chain solves, besides the solve for the loads'
/// accelerations) runs in the run's team: a short generalized-α run of a
/// chain whose Newton matrix is large enough for two-sided solves counts
/// at least those 183 solves as passes of its team beside its own.
#[test]
fn the_stability_check_runs_in_the_team() {
    use crate::integrate::{Method, OdeOptions};
    use crate::simulation::{simulate, RunConfig};
    // 3·2000 coordinates and 2·2000 constraints: dimension 10 000, the
    // chain solves' two-sided size (`linalg::chain::PARALLEL_MIN_DIM`)
    let (sys, q0, qd0, _) = crate::builders::stiff_chain(2000, 5f64.to_radians()).unwrap();
    let cfg = RunConfig {
        method: Method::GenAlpha,
        t_end: 1e-5,
        output_dt: 1e-5,
        ode: OdeOptions {
            fixed_step: Some(1e-5),
            ..Default::default()
        },
        threads: Threads::Two,
        ..Default::default()
    };
    let (_, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    // the integration's passes: a residual per evaluation and a solve
    // per Newton iteration (a pass count does not depend on timing)
    let run = s.rhs_evals + s.extra["newton_iterations"].as_u64().unwrap() as usize;
    let passes = TEST_PASSES.with(|p| p.get());
    assert!(
        passes >= 183 + run,
        "{passes} passes, {run} of them the run's"
    );
}

#[test]
fn one_thread_pool_and_nested_joins_run_in_order() {
    pool(1).install(|| {
        with_threads(Threads::Auto, || {
            run(true, 0, || {
                assert!(!concurrent());
                let (a, b) = join(|| 1, || 2);
                assert_eq!((a, b), (1, 2));
            })
        })
    });
    with_threads(Threads::Two, || {
        run(true, 0, || {
            let ((a, b), (c, d)) = join(|| join(|| 1, || 2), || join(|| 3, || 4));
            assert_eq!((a, b, c, d), (1, 2, 3, 4));
        })
    });
    // under One nothing leaves the thread, not even through rayon
    pool(2).install(|| {
        let me = std::thread::current().id();
        let ((a, b), rep) = with_threads(Threads::One, || {
            run(true, 0, || {
                assert!(!concurrent());
                join(
                    || std::thread::current().id(),
                    || std::thread::current().id(),
                )
            })
        });
        assert_eq!((a, b), (me, me));
        let one = TeamReport {
            rule: Rule::One,
            clock: rep.clock,
            ..TeamReport::default()
        };
        assert_eq!(rep, one);
    });
}

/// Busy-waits `ms` milliseconds of this thread's CPU time (work of a
/// known length however loaded the machine).
fn work(ms: u64) {
    let t = cpu();
    while cpu() - t < 1e-3 * ms as f64 {
        std::hint::spin_loop();
    }
}

/// The run's clock counts each outermost pass in halves once, its
/// nested joins not again, and each half's own time on its thread:
/// with passes nested three deep, each level's halves 2 ms and 1 ms of
/// their own, counting the nested joins would put more time in halves
/// than in the run.
#[test]
fn the_clock_counts_outermost_passes_once() {
    fn nest(level: u32) {
        if level > 0 {
            join(
                || {
                    work(2);
                    nest(level - 1)
                },
                || work(1),
            );
        }
    }
    for threads in [Threads::One, Threads::Two] {
        let ((), rep) = with_threads(threads, || {
            run(true, 0, || {
                work(3);
                nest(3);
                let r = one_thread_form(|| {
                    work(2);
                    7
                });
                assert_eq!(r, 7);
            })
        });
        let c = rep.clock;
        // at least: 3 levels of 2 ms + 1 ms in halves (in turn) or 2 ms
        // (two threads), plus the 2 ms of the one-thread form
        let min_halves = if threads == Threads::One { 11e-3 } else { 8e-3 };
        assert!(c.halves_s >= min_halves, "{threads:?}: {c:?}");
        assert!(c.run_s >= c.halves_s + 3e-3, "{threads:?}: {c:?}");
        // the halves: the first 3 × 2 ms + 2 + 1 ms nested in it, the
        // second 1 ms; the one-thread form's 2 ms counts as two halves
        assert!(c.work_s >= 11e-3, "{threads:?}: {c:?}");
        assert!(c.longer_s >= 9e-3, "{threads:?}: {c:?}");
        assert!(c.longer_s <= c.work_s, "{threads:?}: {c:?}");
        if threads == Threads::One {
            assert!(c.work_s <= c.halves_s, "{threads:?}: {c:?}");
        }
    }
}

/// The clock counts the caller's serial stretches between two outermost
/// passes by their CPU time, on one thread and on two: 2 ms of serial
/// work before the second pass (beyond 0, 0.1, 0.3 and 1 ms, not 3 ms)
/// and none before the third; the work before the first pass and after
/// the last is no stretch between passes, nor are nested joins.
#[test]
fn the_clock_counts_serial_stretches_between_passes() {
    for threads in [Threads::One, Threads::Two] {
        let ((), rep) = with_threads(threads, || {
            run(true, 0, || {
                work(4);
                join(|| join(|| work(1), || work(1)), || work(1));
                work(2);
                join(|| work(1), || work(1));
                one_thread_form(|| work(1));
                work(4);
            })
        });
        assert_eq!(rep.clock.gaps, [2, 1, 1, 1, 0], "{threads:?}");
    }
}

#[test]
fn a_panic_in_either_half_reaches_the_caller_after_both_ended() {
    with_threads(Threads::Two, || {
        run(true, 0, || {
            assert!(helper_ready(), "the helper started");
            for side in 0..2 {
                let done = AtomicBool::new(false);
                let r = catch_unwind(AssertUnwindSafe(|| {
                    join(
                        || {
                            if side == 0 {
                                panic!("a")
                            }
                        },
                        || {
                            std::thread::sleep(Duration::from_millis(2));
                            done.store(true, Ordering::SeqCst);
                            if side == 1 {
                                panic!("b")
                            }
                        },
                    )
                }));
                assert!(r.is_err());
                assert!(done.load(Ordering::SeqCst), "b ended before the unwind");
                // the team is usable afterwards
                assert!(helper_ready());
                assert_eq!(join(|| 5, || 6), (5, 6));
            }
        })
    });
}

/// Drives `a` one pass at a time as `Team::pass` does, with the
/// evidence `against(alone)` at the end of every exploit window (alone:
/// whether a core is free, counted only for a stretch chosen while none
/// was) and a core free when `free` says so; returns (alone, wake) per
/// pass.
fn drive_with_evidence(
    a: &mut Adapt,
    passes: usize,
    cost: impl Fn(bool) -> u64,
    free: &std::cell::Cell<bool>,
    mut against: impl FnMut(bool) -> bool,
) -> Vec<(bool, bool)> {
    let t0 = Instant::now();
    let mut t = Duration::ZERO;
    (0..passes)
        .map(|_| {
            let (solo, mut wake) = a.pass(t0 + t, || free.get());
            if a.exploit_window_ended() {
                let e = against(solo);
                wake |= a.evidence(if solo { a.busy && e } else { e });
            }
            t += Duration::from_micros(cost(solo));
            (solo, wake)
        })
        .collect()
}

/// A stretch runs EXPLOIT_MIN, then twice as many windows per confirming
/// probe up to EXPLOIT_MAX; evidence against the way it runs in
/// DOUBT_WINDOWS windows in a row (not one, nor two apart) ends it and
/// the probe follows at once (the helper woken for it when the stretch
/// ran alone); the probe still decides.
#[test]
fn evidence_against_a_stretch_brings_the_probe_forward() {
    let w = 2usize;
    let probe = [false, false, true, true, true, true, false, false];
    let fast_team = |alone: bool| if alone { 115 } else { 100 };
    let yes = std::cell::Cell::new(true);
    // no evidence: stretches of 8, 16, 32, 64, 128, 128 windows
    let mut a = Adapt::new(w as u32, true);
    let mut passes = 0;
    for k in [8u32, 16, 32, 64, 128, 128] {
        let r = drive_with_evidence(&mut a, 8 + k as usize * w, fast_team, &yes, |_| false);
        passes += r.len();
        assert_eq!(r[..8].iter().map(|x| x.0).collect::<Vec<_>>(), probe);
        assert!(r[8..].iter().all(|x| !x.0), "stretch of {k} windows");
        assert_eq!(a.exploit, k);
    }
    assert_eq!(a.exploit, EXPLOIT_MAX);
    assert_eq!((a.decided, a.cut, passes), ([6, 0], 0, 6 * 8 + 376 * w));
    // a preempted helper in one window, then in two windows apart: no cut
    let mut n = 0;
    let r = drive_with_evidence(&mut a, 8 + 10 * w, fast_team, &yes, |_| {
        n += 1;
        n == 2 || n == 5 || n == 7
    });
    assert!(r[8..].iter().all(|x| !x.0));
    assert_eq!(a.cut, 0);
    // in two windows in a row: the stretch ends after the second, and
    // the next pass starts a probe (team, alone, alone, team)
    let mut a = Adapt::new(w as u32, true);
    drive_with_evidence(&mut a, 8, fast_team, &yes, |_| false);
    let seen = std::cell::Cell::new(0);
    let r = drive_with_evidence(&mut a, 3 * w + 9, fast_team, &yes, |alone| {
        assert!(!alone, "evidence is asked in the team's stretch only here");
        seen.set(seen.get() + 1);
        seen.get() >= 2
    });
    assert_eq!(a.cut, 1);
    let modes: Vec<bool> = r.iter().map(|x| x.0).collect();
    assert!(modes[..3 * w].iter().all(|&s| !s));
    assert_eq!(modes[3 * w..3 * w + 8], probe);
    // the probe still decides: the team is faster, so it stays
    assert_eq!(a.decided, [2, 0]);
    // alone, chosen while no core was free (a busy machine), with a core
    // found free twice in a row: the stretch ends and the helper is woken
    // on its last pass
    let mut b = Adapt::new(w as u32, true);
    let slow_team = |alone: bool| if alone { 100 } else { 300 };
    let no = std::cell::Cell::new(false);
    // the probe's windows, then its decision on the stretch's first pass
    drive_with_evidence(&mut b, 8 + 1, slow_team, &no, |_| false);
    assert_eq!(b.decided, [0, 1]);
    assert!(b.busy);
    let r = drive_with_evidence(&mut b, 2 * w, slow_team, &yes, |alone| alone);
    assert_eq!(b.cut, 1);
    assert!(r[..2 * w - 1].iter().all(|x| x.0));
    assert!(r[2 * w - 2].1, "helper woken on the stretch's last pass");
    assert!(
        !r[2 * w - 1].0,
        "the probe's first window runs with the helper"
    );
}

/// A team opened with no core free runs alone without probing while
/// none is (its stretches doubling up to EXPLOIT_MAX, the probes counted
/// as skipped); a core found free in DOUBT_WINDOWS windows in a row
/// brings the probe; a choice of one thread made while a core was free
/// (the team slower on an idle machine) is cut short by free cores only
/// until a second probe confirms it, and its stretch then ends in a
/// probe.
#[test]
fn no_core_free_skips_the_probes() {
    let w = 3usize;
    let team_fast = |alone: bool| if alone { 200 } else { 100 };
    let (no, yes) = (std::cell::Cell::new(false), std::cell::Cell::new(true));
    let mut a = Adapt::new(w as u32, false);
    assert!(a.busy && a.skipped == 1);
    // 8 + 16 + 32 + 64 + 128 + 128 windows, all alone
    let r = drive_with_evidence(&mut a, 376 * w, team_fast, &no, |_| false);
    assert!(r.iter().all(|&(alone, wake)| alone && !wake));
    assert_eq!((a.decided, a.skipped, a.exploit), ([0, 0], 7, EXPLOIT_MAX));
    assert_eq!(a.last_ratio, None);
    // a core free from now on: two windows later the probe starts
    // (team, alone, alone, team) and chooses the faster team
    let r = drive_with_evidence(&mut a, 2 * w + 4 * w + 1, team_fast, &yes, |alone| alone);
    assert_eq!(a.cut, 1);
    assert!(r[..2 * w].iter().all(|x| x.0));
    assert!(r[2 * w - 1].1, "helper woken for the probe");
    let modes: Vec<bool> = r[2 * w..6 * w].iter().map(|x| x.0).collect();
    let probe: Vec<bool> = [false, true, true, false]
        .iter()
        .flat_map(|&m| std::iter::repeat_n(m, w))
        .collect();
    assert_eq!(modes, probe);
    assert_eq!(a.decided, [1, 0]);
    assert!(!r[6 * w].0 && !a.busy);
    // an idle machine where one thread is faster: a first choice of one
    // thread is doubted by free cores (the stretch cut after two
    // windows); once a second probe confirms it, free cores are no
    // evidence, and the stretch (twice EXPLOIT_MIN windows) ends in a
    // probe
    let mut b = Adapt::new(w as u32, true);
    let team_slow = |alone: bool| if alone { 100 } else { 300 };
    drive_with_evidence(&mut b, 4 * w + 1, team_slow, &yes, |alone| alone);
    assert!(b.busy && b.decided == [0, 1]);
    // the rest of the two windows, the probe, the decision
    drive_with_evidence(&mut b, 2 * w - 1 + 4 * w + 1, team_slow, &yes, |alone| {
        alone
    });
    assert_eq!(b.cut, 1);
    assert!(!b.busy && b.decided == [0, 2]);
    let r = drive_with_evidence(&mut b, 16 * w, team_slow, &yes, |alone| alone);
    assert_eq!((b.cut, b.skipped), (1, 0));
    assert!(r[..16 * w - 1].iter().all(|x| x.0));
    assert!(!r[16 * w - 1].0, "the next probe's first window");
}

/// The runnable-task count of `/proc/loadavg` lines.
#[test]
fn runnable_tasks_of_loadavg() {
    assert_eq!(runnable_tasks("0.52 0.58 0.59 3/412 12345\n"), Some(3));
    assert_eq!(runnable_tasks("15.50 14.02 8.58 17/206 5672"), Some(17));
    assert_eq!(runnable_tasks("0.1 0.2 0.3"), None);
    assert_eq!(runnable_tasks("0.1 0.2 0.3 x/4 5"), None);
}

/// The evidence of an exploit window against the way it ran: with the
/// helper, a half taken back from an awake helper counts only while no
/// core is free beside the team (a busy machine), not on an idle one;
/// alone, a free core counts only against a stretch chosen for want of
/// one.
#[test]
fn a_take_back_is_evidence_only_on_a_busy_machine() {
    let t = Team::new(false);
    for (free, preempted, busy, with_helper, alone) in [
        (false, true, false, true, false),
        (false, false, false, false, false),
        (true, true, false, false, false),
        (true, false, true, false, true),
        (false, false, true, false, false),
    ] {
        TEST_FREE.with(|f| f.set(Some(free)));
        assert_eq!(
            t.against(false, busy, preempted),
            with_helper,
            "{free} {preempted}"
        );
        assert_eq!(t.against(true, busy, preempted), alone, "{free} {busy}");
    }
    TEST_FREE.with(|f| f.set(None));
}

/// A slow host under an idle guest (the hypervisor takes time from the
/// cores: an awake helper misses a half in every window, and every pass
/// is slower, the team still faster than one thread): the team's
/// stretches are never cut and every probe keeps the team; on a busy
/// guest (no core free beside the team) the same misses cut the stretch.
#[test]
fn a_slow_idle_host_keeps_the_second_thread() {
    let w = 2usize;
    let slow_team = |alone: bool| if alone { 230 } else { 200 };
    let yes = std::cell::Cell::new(true);
    let t = Team::new(false);
    let misses_every_window = |solo: bool| t.against(solo, false, true);
    TEST_FREE.with(|f| f.set(Some(true)));
    let mut a = Adapt::new(w as u32, true);
    // three probes and the stretches of 8 and 16 windows between them
    let r = drive_with_evidence(
        &mut a,
        24 + 24 * w + 1,
        slow_team,
        &yes,
        misses_every_window,
    );
    assert_eq!((a.decided, a.cut), ([3, 0], 0));
    let probes = [0..8, 8 + 8 * w..16 + 8 * w, 16 + 24 * w..24 + 24 * w];
    for (k, x) in r.iter().enumerate() {
        assert!(
            probes.iter().any(|p| p.contains(&k)) || !x.0,
            "pass {k} alone"
        );
    }
    // a busy guest: the misses are evidence, the stretch ends after
    // DOUBT_WINDOWS windows
    TEST_FREE.with(|f| f.set(Some(false)));
    let mut b = Adapt::new(w as u32, true);
    drive_with_evidence(&mut b, 8 + 1 + 2 * w, slow_team, &yes, misses_every_window);
    assert_eq!((b.decided, b.cut), ([1, 0], 1));
    TEST_FREE.with(|f| f.set(None));
}
