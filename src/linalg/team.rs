//! A two-thread team for the halves of [`join_if`](super::join_if) during
//! one integration run.
//!
//! An implicit step at N = 10 000 makes about eight joins per Newton
//! iteration, each of 20–200 µs of work a side. Through `rayon::join` the
//! second worker falls asleep between them and every join pays a futex
//! wake-up and a context switch (stop 24: 11 % system time, ~10 000
//! switches per second, 1.13× from the second thread). A [`Team`] instead
//! keeps the second thread of the run's rayon pool busy-waiting for the
//! next half for [`SPIN`] before it parks, and always hands it the second
//! half, so each half's data stays in the cache of the same core.
//!
//! [`run`] opens a team around a run (the driver's loop) when the pool has
//! a second thread: the helper is a job spawned in an
//! `rayon::in_place_scope`, so the team never uses more threads than the
//! pool has. While the helper has not started (no free worker) or is busy,
//! and for joins nested inside a half, [`join`] runs both halves on the
//! calling thread. Which thread runs a half never changes what it
//! computes: the results do not depend on the team.

use std::cell::{Cell, UnsafeCell};
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::OnceLock;
use std::thread::Thread;
use std::time::{Duration, Instant};

/// How long the helper busy-waits for the next half before it parks:
/// longer than the serial work between two joins of a Newton iteration,
/// shorter than anything a user would notice as a spinning core.
pub const SPIN: Duration = Duration::from_micros(300);

const IDLE: u8 = 0;
const POSTED: u8 = 1;
const RUNNING: u8 = 2;
const DONE: u8 = 3;
const STOP: u8 = 4;

type Job = *mut (dyn FnMut() + Send + 'static);

/// The shared state of a caller thread and its helper.
struct Team {
    state: AtomicU8,
    /// The posted half; written by the caller before `POSTED`, read by the
    /// helper after it moved the state from `POSTED` to `RUNNING`.
    job: UnsafeCell<Option<Job>>,
    /// The panic of the helper's last half, handed back to the caller.
    panic: UnsafeCell<Option<Box<dyn std::any::Any + Send>>>,
    /// The helper's thread, once it runs.
    helper: OnceLock<Thread>,
    /// Set by the helper before it parks (so the caller unparks it).
    parked: AtomicBool,
    /// Halves the helper ran (for tests).
    #[cfg(test)]
    helped: std::sync::atomic::AtomicUsize,
}

// SAFETY: `job` and `panic` are accessed only by the side that owns the
// current state (caller: IDLE, DONE; helper: RUNNING), with the hand-over
// through `state` in Release/Acquire order.
unsafe impl Sync for Team {}

thread_local! {
    /// The team of the run this thread drives, if any.
    static CURRENT: Cell<*const Team> = const { Cell::new(std::ptr::null()) };
}

/// Runs `f` (a whole integration run) with a team of two threads when the
/// calling thread is a rayon worker of a pool with more than one thread
/// and `large` (the run has enough coordinates for its joins to pay);
/// else just `f()`. Nested calls run `f()` in the outer team.
pub fn run<R>(large: bool, f: impl FnOnce() -> R) -> R {
    let open = large
        && rayon::current_thread_index().is_some()
        && rayon::current_num_threads() > 1
        && CURRENT.with(|c| c.get().is_null());
    if !open {
        return f();
    }
    let team = Team {
        state: AtomicU8::new(IDLE),
        job: UnsafeCell::new(None),
        panic: UnsafeCell::new(None),
        helper: OnceLock::new(),
        parked: AtomicBool::new(false),
        #[cfg(test)]
        helped: Default::default(),
    };
    rayon::in_place_scope(|s| {
        let t = &team;
        s.spawn(move |_| helper_loop(t));
        CURRENT.with(|c| c.set(t));
        // reset and stop the helper even when `f` panics
        struct Close<'a>(&'a Team);
        impl Drop for Close<'_> {
            fn drop(&mut self) {
                CURRENT.with(|c| c.set(std::ptr::null()));
                self.0.state.store(STOP, Ordering::SeqCst);
                if let Some(h) = self.0.helper.get() {
                    h.unpark();
                }
            }
        }
        let _close = Close(t);
        let r = f();
        #[cfg(test)]
        LAST_HELPED.with(|c| c.set(t.helped.load(Ordering::SeqCst)));
        r
    })
}

#[cfg(test)]
thread_local! {
    /// How many halves the helper of this thread's last team ran.
    pub(crate) static LAST_HELPED: Cell<usize> = const { Cell::new(0) };
}

/// Whether a [`join`] on this thread would now run its halves on two
/// threads: inside a team whose helper runs and is free, or else inside a
/// rayon pool with more than one thread (`rayon::join`). Callers choose
/// between a two-thread and a one-thread form of the same computation
/// with it (results must not depend on the choice).
pub fn concurrent() -> bool {
    let t = CURRENT.with(|c| c.get());
    if t.is_null() {
        return !IN_HELPER.with(|h| h.get()) && rayon::current_num_threads() > 1;
    }
    // SAFETY: CURRENT points at the team of the enclosing `run`, alive
    // until `run` returns and resets it.
    let team = unsafe { &*t };
    team.helper.get().is_some() && team.state.load(Ordering::Acquire) == IDLE
}

/// `(a(), b())`, `b` on the team's helper while `a` runs here when a team
/// is open on this thread and its helper is free; else `rayon::join`
/// outside a team, or both here (in order a, b) inside a busy team.
pub fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    let t = CURRENT.with(|c| c.get());
    if t.is_null() {
        if IN_HELPER.with(|h| h.get()) {
            return (a(), b());
        }
        return rayon::join(a, b);
    }
    // SAFETY: as in `concurrent`.
    let team = unsafe { &*t };
    if team.helper.get().is_none() || team.state.load(Ordering::Acquire) != IDLE {
        return (a(), b());
    }
    let mut rb: Option<RB> = None;
    let mut b = Some(b);
    let mut job = || rb = Some((b.take().expect("the half runs once"))());
    let job: &mut (dyn FnMut() + Send) = &mut job;
    // SAFETY: the lifetime is erased only for the hand-over; this function
    // does not return (or unwind) before the helper finished the job
    // (`wait_done` below), so the borrow outlives every use of the pointer.
    let job: Job = unsafe { std::mem::transmute::<*mut (dyn FnMut() + Send + '_), Job>(job) };
    unsafe { *team.job.get() = Some(job) };
    team.state.store(POSTED, Ordering::SeqCst);
    if team.parked.load(Ordering::SeqCst) {
        if let Some(h) = team.helper.get() {
            h.unpark();
        }
    }
    let ra = catch_unwind(AssertUnwindSafe(a));
    // the half stays with the helper even when it has not started yet:
    // each half's data then stays in one core's cache (on this machine
    // bdf's Newton update ran ~9× slower with its halves on the other
    // cores than the passes before it: docs/scaling.md, stop 25)
    wait_done(team);
    // SAFETY: state DONE: the helper is finished with the job and the slot
    let panic_b = unsafe { (*team.panic.get()).take() };
    team.state.store(IDLE, Ordering::Release);
    let ra = match ra {
        Ok(ra) => ra,
        Err(p) => resume_unwind(p),
    };
    if let Some(p) = panic_b {
        resume_unwind(p);
    }
    (ra, rb.expect("the half ran"))
}

thread_local! {
    /// Set on a helper thread while it runs a half (nested joins there run
    /// sequentially).
    static IN_HELPER: Cell<bool> = const { Cell::new(false) };
}

/// The caller's wait for the helper's half: spin, then yield the core.
fn wait_done(team: &Team) {
    let mut spins = 0u32;
    while team.state.load(Ordering::Acquire) != DONE {
        if spins < 1 << 16 {
            std::hint::spin_loop();
            spins += 1;
        } else {
            std::thread::yield_now();
        }
    }
}

/// The helper: take posted halves until the run stops; busy-wait [`SPIN`]
/// after each, then park until the caller posts again.
fn helper_loop(team: &Team) {
    let _ = team.helper.set(std::thread::current());
    IN_HELPER.with(|h| h.set(true));
    let mut since = Instant::now();
    let mut spins = 0u32;
    loop {
        match team.state.load(Ordering::Acquire) {
            STOP => break,
            POSTED => {
                if team
                    .state
                    .compare_exchange(POSTED, RUNNING, Ordering::Acquire, Ordering::Acquire)
                    .is_ok()
                {
                    // SAFETY: state RUNNING: the job is ours until DONE
                    let job = unsafe { (*team.job.get()).take() }.expect("a posted job");
                    let r = catch_unwind(AssertUnwindSafe(|| unsafe { (*job)() }));
                    if let Err(p) = r {
                        unsafe { *team.panic.get() = Some(p) };
                    }
                    #[cfg(test)]
                    team.helped.fetch_add(1, Ordering::SeqCst);
                    team.state.store(DONE, Ordering::Release);
                    since = Instant::now();
                    spins = 0;
                }
            }
            _ => {
                std::hint::spin_loop();
                spins += 1;
                // read the clock only every few hundred spins
                if spins % 256 == 0 && since.elapsed() > SPIN {
                    team.parked.store(true, Ordering::SeqCst);
                    if team.state.load(Ordering::SeqCst) == IDLE {
                        std::thread::park();
                    }
                    team.parked.store(false, Ordering::SeqCst);
                    since = Instant::now();
                    spins = 0;
                }
            }
        }
    }
    IN_HELPER.with(|h| h.set(false));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Wait (at most a second) until the helper runs and is free.
    fn helper_ready() -> bool {
        let t0 = Instant::now();
        while !concurrent() {
            if t0.elapsed() > Duration::from_secs(1) {
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

    #[test]
    fn halves_run_on_two_threads_and_return_their_results() {
        pool(2).install(|| {
            run(true, || {
                assert!(helper_ready(), "the helper started");
                let me = std::thread::current().id();
                let mut other = 0;
                for k in 0..2000u64 {
                    if k % 500 == 0 {
                        // let the helper park between some of the joins
                        std::thread::sleep(2 * SPIN);
                    }
                    let (a, (b, id)) = join(|| k * 2, || (k * 3, std::thread::current().id()));
                    assert_eq!((a, b), (2 * k, 3 * k));
                    if id != me {
                        other += 1;
                    }
                }
                // once it runs, the helper takes every second half
                assert_eq!(other, 2000);
            })
        });
    }

    /// A bdf run of a stiff chain above the parallel thresholds in a pool
    /// of two: the driver opens a team and its helper takes halves (the
    /// results' independence of the thread count: tests/parallel_newton.rs).
    #[test]
    fn a_large_implicit_run_hands_halves_to_the_helper() {
        use crate::integrate::{Method, OdeOptions};
        use crate::simulation::{simulate, RunConfig};
        let (sys, q0, qd0, _) = crate::builders::stiff_chain(2000, 5f64.to_radians()).unwrap();
        let cfg = RunConfig {
            method: Method::Bdf,
            t_end: 2e-4,
            output_dt: 1e-4,
            ode: OdeOptions {
                rtol: 1e-5,
                ..Default::default()
            },
            ..Default::default()
        };
        let helped = pool(2).install(|| {
            let (_, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
            assert_eq!(s.status, "completed", "{:?}", s.message);
            LAST_HELPED.with(|c| c.get())
        });
        assert!(helped > 100, "the helper ran {helped} halves");
    }

    #[test]
    fn one_thread_pool_and_nested_joins_run_in_order() {
        pool(1).install(|| {
            run(true, || {
                assert!(!concurrent());
                let (a, b) = join(|| 1, || 2);
                assert_eq!((a, b), (1, 2));
            })
        });
        pool(2).install(|| {
            run(true, || {
                let ((a, b), (c, d)) = join(|| join(|| 1, || 2), || join(|| 3, || 4));
                assert_eq!((a, b, c, d), (1, 2, 3, 4));
            })
        });
    }

    #[test]
    fn a_panic_in_either_half_reaches_the_caller_after_both_ended() {
        pool(2).install(|| {
            run(true, || {
                assert!(helper_ready(), "the helper started");
                for side in 0..2 {
                    let done = std::sync::atomic::AtomicBool::new(false);
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
                    assert_eq!(join(|| 5, || 6), (5, 6));
                }
            })
        });
    }
}
