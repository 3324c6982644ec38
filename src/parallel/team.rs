//! A two-thread team for the halves of [`join_if`](super::join_if) during
//! one integration run.
//!
//! An implicit step at N = 10 000 makes about eight joins per Newton
//! iteration, each of 20–200 µs of work a side: through `rayon::join` the
//! second worker would fall asleep between them and every join would pay a
//! wake-up. A team instead keeps its helper busy-waiting for the next half
//! for [`SPIN`] before it parks, and hands it the second half of every
//! join, so each half's data stays in the cache of one core
//! (docs/scaling.md).
//!
//! The hand-over ([`super::handover`]) never makes the caller wait for a
//! helper that is not running: a half the helper has not started when the
//! caller has finished its own is taken back and run by the caller, and a
//! caller waiting for a running half parks after a short spin. Under
//! [`Threads::Auto`] a team whose helper keeps missing its halves (a busy
//! machine: [`MISS_LIMIT`] take-backs in a row) stops posting for a while
//! ([`SOLO_MIN`] joins, doubled at each further miss up to [`SOLO_MAX`])
//! and lets the helper park, then tries again: the run falls back to one
//! thread while the second is not available.
//!
//! [`run`] opens a team around a run (the driver's loop). Under `Auto` the
//! helper is a job spawned in a `rayon::in_place_scope` of the run's pool
//! (so the team never uses more threads than the pool has; with no free
//! worker it never starts and the joins run here); under [`Threads::Two`]
//! it is a scoped thread of its own. Joins nested inside a half run both
//! halves on their thread. Which thread runs a half never changes what it
//! computes: the results do not depend on the team.

use super::handover::{Handover, Ran};
use super::{policy, Threads};
use serde::Serialize;
use std::cell::Cell;
use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

pub use super::handover::SPIN;

/// Take-backs in a row after which an `Auto` team stops posting halves.
pub const MISS_LIMIT: u32 = 4;
/// Joins an `Auto` team runs on one thread after [`MISS_LIMIT`] misses.
pub const SOLO_MIN: u32 = 64;
/// The longest such stretch (each miss of the next try doubles it).
pub const SOLO_MAX: u32 = 16_384;

/// What the concurrent passes of one run did ([`super::with_threads`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct TeamReport {
    /// Halves that ran on a second thread (a team's helper or a rayon
    /// worker).
    pub halves_split: usize,
    /// Halves posted to a team's helper that the caller took back and ran
    /// itself because the helper had not started them.
    pub halves_taken_back: usize,
    /// Joins a team ran on one thread without posting (the second thread
    /// was found busy).
    pub halves_solo: usize,
}

impl TeamReport {
    /// Threads the run used: 2 when any half ran on a second thread, else 1.
    pub fn threads(&self) -> usize {
        if self.halves_split > 0 {
            2
        } else {
            1
        }
    }

    fn add(&mut self, o: TeamReport) {
        self.halves_split += o.halves_split;
        self.halves_taken_back += o.halves_taken_back;
        self.halves_solo += o.halves_solo;
    }
}

thread_local! {
    /// The counts of the runs on this thread since [`super::with_threads`].
    pub(super) static REPORT: Cell<TeamReport> = const {
        Cell::new(TeamReport { halves_split: 0, halves_taken_back: 0, halves_solo: 0 })
    };
    /// The team of the run this thread drives, if any.
    static CURRENT: Cell<*const Team> = const { Cell::new(std::ptr::null()) };
    /// Set on a helper thread while it runs (joins there run sequentially).
    static IN_HELPER: Cell<bool> = const { Cell::new(false) };
}

/// A caller's hand-over and its bookkeeping (touched by the caller only;
/// atomics so that the helper may hold a shared reference).
struct Team {
    h: Handover,
    /// Back off on a busy machine (`Auto`).
    adaptive: bool,
    split: AtomicUsize,
    taken_back: AtomicUsize,
    solo: AtomicUsize,
    misses: AtomicU32,
    solo_left: AtomicU32,
    backoff: AtomicU32,
}

impl Team {
    fn new(adaptive: bool) -> Self {
        Self {
            h: Handover::new(),
            adaptive,
            split: AtomicUsize::new(0),
            taken_back: AtomicUsize::new(0),
            solo: AtomicUsize::new(0),
            misses: AtomicU32::new(0),
            solo_left: AtomicU32::new(0),
            backoff: AtomicU32::new(SOLO_MIN),
        }
    }

    /// Records how a posted half ran; after [`MISS_LIMIT`] take-backs in a
    /// row an adaptive team runs the next `backoff` joins alone.
    fn note(&self, ran: Ran) {
        let r = Ordering::Relaxed;
        match ran {
            Ran::Helper => {
                self.split.fetch_add(1, r);
                self.misses.store(0, r);
                self.backoff.store(SOLO_MIN, r);
            }
            Ran::TakenBack => {
                self.taken_back.fetch_add(1, r);
                let m = self.misses.load(r) + 1;
                if self.adaptive && m >= MISS_LIMIT {
                    let b = self.backoff.load(r);
                    self.solo_left.store(b, r);
                    self.backoff.store((2 * b).min(SOLO_MAX), r);
                    // one more miss at the next try backs off again
                    self.misses.store(MISS_LIMIT - 1, r);
                } else {
                    self.misses.store(m, r);
                }
            }
        }
    }

    /// Whether the next join runs alone (and counts it); wakes the helper
    /// one join before the next try, so that it spins when the try posts.
    fn solo_join(&self) -> bool {
        let r = Ordering::Relaxed;
        let left = self.solo_left.load(r);
        if left == 0 {
            return false;
        }
        self.solo_left.store(left - 1, r);
        self.solo.fetch_add(1, r);
        if left == 1 {
            self.h.wake_helper();
        }
        true
    }

    fn report(&self) -> TeamReport {
        TeamReport {
            halves_split: self.split.load(Ordering::Relaxed),
            halves_taken_back: self.taken_back.load(Ordering::Relaxed),
            halves_solo: self.solo.load(Ordering::Relaxed),
        }
    }
}

/// Runs `f` (a whole integration run) with a two-thread team as the
/// thread setting of [`super::with_threads`] asks: under `Auto` when the
/// calling thread is a worker of a rayon pool with more than one thread
/// and `large` (the run has enough coordinates for its joins to pay);
/// under `Two` always; never under `One`. Else, and for nested calls, just
/// `f()`.
pub(crate) fn run<R>(large: bool, f: impl FnOnce() -> R) -> R {
    if !CURRENT.with(|c| c.get()).is_null() || IN_HELPER.with(|h| h.get()) {
        return f();
    }
    match policy() {
        Threads::One => f(),
        Threads::Auto => {
            if !(large
                && rayon::current_thread_index().is_some()
                && rayon::current_num_threads() > 1)
            {
                return f();
            }
            let team = Team::new(true);
            rayon::in_place_scope(|s| {
                let t = &team;
                s.spawn(move |_| helper(t));
                with_team(t, f)
            })
        }
        Threads::Two => {
            let team = Team::new(false);
            std::thread::scope(|s| {
                let t = &team;
                s.spawn(move || helper(t));
                with_team(t, f)
            })
        }
    }
}

/// The helper's side of a team.
fn helper(t: &Team) {
    IN_HELPER.with(|h| h.set(true));
    t.h.helper_loop();
    IN_HELPER.with(|h| h.set(false));
}

/// `f()` with `t` as this thread's team; stops the helper and adds the
/// team's counts to the report even when `f` panics.
fn with_team<R>(t: &Team, f: impl FnOnce() -> R) -> R {
    struct Close<'a>(&'a Team);
    impl Drop for Close<'_> {
        fn drop(&mut self) {
            CURRENT.with(|c| c.set(std::ptr::null()));
            self.0.h.stop();
            let rep = self.0.report();
            REPORT.with(|r| {
                let mut v = r.get();
                v.add(rep);
                r.set(v);
            });
        }
    }
    CURRENT.with(|c| c.set(t));
    let _close = Close(t);
    f()
}

/// The team open on this thread, if any.
fn current_team<'a>() -> Option<&'a Team> {
    let t = CURRENT.with(|c| c.get());
    // SAFETY: CURRENT points at the team of the enclosing `run` on this
    // thread, alive until `run`'s `Close` resets it before the team drops.
    (!t.is_null()).then(|| unsafe { &*t })
}

/// Whether a [`join`] on this thread would now run its halves on two
/// threads: inside a team whose helper runs, is free and is not backed off,
/// or else (not on a helper, not under `One`) inside a rayon pool with
/// more than one thread. Callers choose between a two-thread and a
/// one-thread form of the same computation with it (results must not
/// depend on the choice).
pub fn concurrent() -> bool {
    match current_team() {
        Some(t) => t.h.ready() && t.solo_left.load(Ordering::Relaxed) == 0,
        None => {
            !IN_HELPER.with(|h| h.get())
                && policy() != Threads::One
                && rayon::current_num_threads() > 1
        }
    }
}

/// `(a(), b())`: `b` posted to the team's helper while `a` runs here when
/// a team is open on this thread and its helper is free (taken back if
/// the helper has not started it by then); else `rayon::join` outside a
/// team, or both here (in order a, b) inside a busy or backed-off team, on
/// a helper, or under `One`.
pub fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    match current_team() {
        Some(t) => {
            if !t.h.ready() || t.solo_join() {
                return (a(), b());
            }
            let (r, ran) = t.h.join(a, b);
            t.note(ran);
            r
        }
        None => {
            if IN_HELPER.with(|h| h.get()) || policy() == Threads::One {
                return (a(), b());
            }
            let me = std::thread::current().id();
            let (ra, (rb, other)) = rayon::join(a, || (b(), std::thread::current().id() != me));
            if other {
                REPORT.with(|r| {
                    let mut v = r.get();
                    v.halves_split += 1;
                    r.set(v);
                });
            }
            (ra, rb)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::with_threads;
    use super::*;
    use std::panic::{catch_unwind, AssertUnwindSafe};
    use std::sync::atomic::AtomicBool;
    use std::time::{Duration, Instant};

    /// Wait (at most ten seconds) until the helper runs and is free.
    fn helper_ready() -> bool {
        let t0 = Instant::now();
        while !concurrent() {
            if t0.elapsed() > Duration::from_secs(10) {
                return false;
            }
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
            run(false, || {
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

    /// After MISS_LIMIT take-backs in a row an adaptive team runs joins
    /// alone, longer after each further miss; a hit resets it.
    #[test]
    fn a_team_whose_helper_misses_backs_off() {
        let team = Team::new(true);
        for _ in 0..MISS_LIMIT {
            team.note(Ran::TakenBack);
        }
        assert_eq!(team.solo_left.load(Ordering::Relaxed), SOLO_MIN);
        let mut alone = 0;
        while team.solo_join() {
            alone += 1;
        }
        assert_eq!(alone, SOLO_MIN);
        // the next try misses again: twice as long alone
        team.note(Ran::TakenBack);
        assert_eq!(team.solo_left.load(Ordering::Relaxed), 2 * SOLO_MIN);
        // a hit resets
        team.note(Ran::Helper);
        assert_eq!(team.backoff.load(Ordering::Relaxed), SOLO_MIN);
        assert_eq!(team.misses.load(Ordering::Relaxed), 0);
        // a forced team never backs off
        let forced = Team::new(false);
        for _ in 0..10 * MISS_LIMIT {
            forced.note(Ran::TakenBack);
        }
        assert!(!forced.solo_join());
    }

    /// With no helper running, a posted half comes back to the caller.
    #[test]
    fn a_posted_half_nobody_takes_runs_on_the_caller() {
        let h = Handover::new();
        // no helper: `join` is called directly on the hand-over
        for k in 0..10u64 {
            let me = std::thread::current().id();
            let ((a, (b, id)), ran) = h.join(|| k, || (k + 1, std::thread::current().id()));
            assert_eq!((a, b, id, ran), (k, k + 1, me, Ran::TakenBack));
        }
    }

    /// A bdf run of a stiff chain above the parallel thresholds with two
    /// threads forced: the driver opens a team and posts halves (the
    /// results' independence of the thread count: tests/parallel_newton.rs).
    #[test]
    fn a_large_implicit_run_posts_halves_to_the_helper() {
        use crate::integrate::{Method, OdeOptions};
        use crate::simulation::{simulate, RunConfig};
        let (sys, q0, qd0, _) = crate::builders::stiff_chain(2000, 5f64.to_radians()).unwrap();
        let mut cfg = RunConfig {
            method: Method::Bdf,
            t_end: 2e-4,
            output_dt: 1e-4,
            ode: OdeOptions {
                rtol: 1e-5,
                ..Default::default()
            },
            ..Default::default()
        };
        cfg.threads = Threads::Two;
        let (_, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
        assert_eq!(s.status, "completed", "{:?}", s.message);
        let posted = s.extra["halves_split"].as_u64().unwrap()
            + s.extra["halves_taken_back"].as_u64().unwrap();
        assert!(posted > 100, "{posted} halves posted");
        assert_eq!(s.extra["halves_solo"].as_u64(), Some(0));
        // one thread: no team, nothing split
        cfg.threads = Threads::One;
        let (_, s) = pool(2).install(|| simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap());
        assert_eq!(s.extra["threads"].as_u64(), Some(1));
        assert_eq!(s.extra["halves_split"].as_u64(), Some(0));
        assert_eq!(s.extra["halves_taken_back"].as_u64(), Some(0));
    }

    #[test]
    fn one_thread_pool_and_nested_joins_run_in_order() {
        pool(1).install(|| {
            with_threads(Threads::Auto, || {
                run(true, || {
                    assert!(!concurrent());
                    let (a, b) = join(|| 1, || 2);
                    assert_eq!((a, b), (1, 2));
                })
            })
        });
        with_threads(Threads::Two, || {
            run(true, || {
                let ((a, b), (c, d)) = join(|| join(|| 1, || 2), || join(|| 3, || 4));
                assert_eq!((a, b, c, d), (1, 2, 3, 4));
            })
        });
        // under One nothing leaves the thread, not even through rayon
        pool(2).install(|| {
            let me = std::thread::current().id();
            let ((a, b), rep) = with_threads(Threads::One, || {
                run(true, || {
                    assert!(!concurrent());
                    join(
                        || std::thread::current().id(),
                        || std::thread::current().id(),
                    )
                })
            });
            assert_eq!((a, b), (me, me));
            assert_eq!(rep, TeamReport::default());
        });
    }

    #[test]
    fn a_panic_in_either_half_reaches_the_caller_after_both_ended() {
        with_threads(Threads::Two, || {
            run(true, || {
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
}
