//! The hand-over of one half between a caller thread and its helper: the
//! protocol of the two-thread team, on its own so that `loom` can explore
//! its interleavings (the `mbsolve-loom` crate includes this file with
//! `--cfg loom`, where the atomics, the cell and the park/unpark calls are
//! loom's). Imports nothing of the crate.
//!
//! States of the hand-over (`Handover::state`) and who owns the job slot in each:
//!
//! ```text
//!  IDLE ──caller posts──► POSTED ──helper takes──► RUNNING ──helper ends──► DONE
//!   ▲                       │                                                │
//!   └──caller takes back────┘◄────────────caller collects────────────────────┘
//! ```
//!
//! The caller writes the slot in `IDLE`, then publishes `POSTED`; exactly
//! one of the helper's `POSTED → RUNNING` and the caller's `POSTED → IDLE`
//! (take-back: the caller runs the half itself once its own half is done)
//! succeeds, so a half runs exactly once and the caller never waits for a
//! helper that has not started it (beyond [`GRACE`] for one that is
//! awake). A caller that waits for a running half spins for
//! [`WAIT_SPIN`], then parks until the helper's `DONE` unparks it; an idle
//! helper spins for [`SPIN`], then parks until a post unparks it: a
//! descheduled partner costs a wake-up, not a time slice.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::Duration;

#[cfg(not(loom))]
mod sync {
    pub(super) use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
    pub(super) use std::sync::Mutex;
    pub(crate) use std::thread::{current, park, Thread};
    use std::time::{Duration, Instant};

    /// A cell whose accesses the protocol serialises.
    pub(super) struct Slot<T>(std::cell::UnsafeCell<T>);
    impl<T> Slot<T> {
        pub(super) fn new(v: T) -> Self {
            Self(std::cell::UnsafeCell::new(v))
        }
        pub(super) fn with_mut<R>(&self, f: impl FnOnce(*mut T) -> R) -> R {
            f(self.0.get())
        }
    }

    /// A bounded busy-wait: `spin` is true until the thread has spun for
    /// `limit`, or `WALL_CAP` times `limit` of wall time has passed. The
    /// clock is read every 64 spins (a few microseconds); a longer
    /// interval between two readings ([`DESCHEDULED`]) is time the
    /// thread was not running (another task or the host held its core)
    /// and does not count, so a helper descheduled while it waits does
    /// not park as soon as it runs again, just before the next post.
    pub(super) struct Spin {
        start: Instant,
        last: Instant,
        spun: Duration,
        n: u32,
        limit: Duration,
    }
    /// A gap between two readings of a spinning thread's clock longer
    /// than this is time it was not running.
    pub(super) const DESCHEDULED: Duration = Duration::from_micros(50);
    /// The longest wait in wall time, in multiples of the spin's limit
    /// (on a machine that keeps descheduling the thread).
    const WALL_CAP: u32 = 10;
    impl Spin {
        pub(super) fn new(limit: Duration) -> Self {
            let now = Instant::now();
            Self {
                start: now,
                last: now,
                spun: Duration::ZERO,
                n: 0,
                limit,
            }
        }
        pub(super) fn spin(&mut self) -> bool {
            std::hint::spin_loop();
            self.n = self.n.wrapping_add(1);
            if self.n % 64 != 0 {
                return true;
            }
            let now = Instant::now();
            let dt = now.saturating_duration_since(self.last);
            self.last = now;
            if dt <= DESCHEDULED {
                self.spun += dt;
            }
            self.spun <= self.limit
                && now.saturating_duration_since(self.start) <= WALL_CAP * self.limit
        }
    }
}

#[cfg(loom)]
mod sync {
    pub use loom::sync::atomic::{AtomicBool, AtomicU8, Ordering};
    pub use loom::sync::Mutex;
    pub use loom::thread::{current, park, Thread};
    use std::time::Duration;

    /// loom's checked cell.
    pub struct Slot<T>(loom::cell::UnsafeCell<T>);
    impl<T> Slot<T> {
        pub fn new(v: T) -> Self {
            Self(loom::cell::UnsafeCell::new(v))
        }
        pub fn with_mut<R>(&self, f: impl FnOnce(*mut T) -> R) -> R {
            self.0.with_mut(f)
        }
    }

    /// Two spins, then the park path: loom explores both.
    pub struct Spin(u32);
    impl Spin {
        pub fn new(_: Duration) -> Self {
            Self(0)
        }
        pub fn spin(&mut self) -> bool {
            loom::thread::yield_now();
            self.0 += 1;
            self.0 <= 2
        }
    }
}

pub(super) use sync::Thread;
use sync::{current, park, AtomicBool, AtomicU8, Mutex, Ordering, Slot, Spin};

/// How long an idle helper busy-waits for the next half before it parks
/// (time it is descheduled not counted, at most ten times this of wall
/// time): longer than the serial work between two joins of a Newton
/// iteration, than most serial stretches at a step's end (the observer's
/// ‖Φ‖, the step's acceptance: `Clock::gaps`) and than a pass of the
/// A/B rule's last window alone (the helper is woken at its start), so
/// that a quiet machine pays no wake-up inside a step nor at the start
/// of a window with the helper. Every busy-wait here counts its time
/// this way.
pub const SPIN: Duration = Duration::from_millis(1);

/// How long a caller busy-waits for a half the helper is running before
/// it parks: a few times the imbalance of two equal halves.
pub(super) const WAIT_SPIN: Duration = Duration::from_micros(50);

/// How long a caller whose own half is done waits for an awake helper to
/// start the posted half before taking it back: a few cache-line
/// transfers, far below the cost of a half (a helper that is awake but
/// not on a core costs at most this per join).
pub(super) const GRACE: Duration = Duration::from_micros(5);

const IDLE: u8 = 0;
const POSTED: u8 = 1;
const RUNNING: u8 = 2;
const DONE: u8 = 3;
const STOP: u8 = 4;

/// A posted half, its lifetime erased for the hand-over.
type Job = *mut (dyn FnMut() + Send + 'static);

/// Panic payload of a half.
type Panic = Box<dyn std::any::Any + Send>;

/// How a [`Handover::join`] ran its second half.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Ran {
    /// On the helper.
    Helper,
    /// Taken back and run by the caller (the helper had not started it);
    /// `awake`: the helper was not parked, so not on a core (a busy
    /// machine), else it was woken too late (a wake-up latency).
    TakenBack {
        /// Whether the helper was awake when the half was taken back.
        awake: bool,
    },
}

/// The shared state of a caller thread and its helper.
pub(super) struct Handover {
    state: AtomicU8,
    /// The posted half: written by the caller in `IDLE` before `POSTED`,
    /// taken by the helper after its `POSTED → RUNNING`, or cleared by the
    /// caller after its `POSTED → IDLE`.
    job: Slot<Option<Job>>,
    /// The panic of the helper's last half, written in `RUNNING`, read by
    /// the caller in `DONE`.
    panic: Slot<Option<Panic>>,
    /// Set by the helper when it starts (its thread is in `helper` then).
    started: AtomicBool,
    helper: Mutex<Option<Thread>>,
    caller: Thread,
    helper_parked: AtomicBool,
    caller_parked: AtomicBool,
    /// Set by a take-back of a half the helper had not started although
    /// it was not parked (awake, so not on a core: preempted); cleared by
    /// [`Handover::take_preempted`].
    preempted: AtomicBool,
    /// Waits of the caller that parked ([`Handover::parks`]); statistics,
    /// not part of the protocol (std's atomic under loom too).
    caller_parks: std::sync::atomic::AtomicUsize,
    /// Unparks of a parked helper by the caller ([`Handover::parks`]).
    helper_wakes: std::sync::atomic::AtomicUsize,
}

// SAFETY: `job` and `panic` are touched only by the side that owns the
// current state (caller: IDLE, DONE, and POSTED after a successful
// take-back; helper: RUNNING), each hand-over a SeqCst store or
// compare-exchange of `state` that the other side reads before touching
// them (model-checked: the `mbsolve-loom` crate). The `Job` pointer is
// sent to the helper but only called there while the caller waits for it.
unsafe impl Sync for Handover {}
// SAFETY: as for `Sync`; a `Handover` owns no job between joins.
unsafe impl Send for Handover {}

impl Handover {
    /// The hand-over of halves from the calling thread.
    pub(super) fn new() -> Self {
        Self {
            state: AtomicU8::new(IDLE),
            job: Slot::new(None),
            panic: Slot::new(None),
            started: AtomicBool::new(false),
            helper: Mutex::new(None),
            caller: current(),
            helper_parked: AtomicBool::new(false),
            caller_parked: AtomicBool::new(false),
            preempted: AtomicBool::new(false),
            caller_parks: std::sync::atomic::AtomicUsize::new(0),
            helper_wakes: std::sync::atomic::AtomicUsize::new(0),
        }
    }

    /// Whether the helper runs and no half is out (a [`Self::join`] would
    /// post).
    pub(super) fn ready(&self) -> bool {
        self.started.load(Ordering::Acquire) && self.state.load(Ordering::Acquire) == IDLE
    }

    /// Whether the helper is not parked (spinning or running a half: a
    /// runnable task of the machine).
    pub(super) fn helper_awake(&self) -> bool {
        !self.helper_parked.load(Ordering::SeqCst)
    }

    /// Wakes a parked helper (it spins for [`SPIN`] again).
    pub(super) fn wake_helper(&self) {
        if self.helper_parked.load(Ordering::SeqCst) {
            if let Some(h) = self.helper.lock().unwrap().as_ref() {
                h.unpark();
                self.helper_wakes
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
        }
    }

    /// The caller's waits for a running half that parked (after
    /// [`WAIT_SPIN`]) and its wake-ups of a parked helper (a post or a
    /// wake after the helper's [`SPIN`] ran out): each costs a wake-up
    /// latency, the first on the caller's path.
    pub(super) fn parks(&self) -> (usize, usize) {
        let r = std::sync::atomic::Ordering::Relaxed;
        (self.caller_parks.load(r), self.helper_wakes.load(r))
    }

    /// `(a(), b())`: posts `b` to the helper, runs `a`, then takes `b`
    /// back and runs it here if the helper has not started it, else waits
    /// for it. A panic of either half is resumed here after both ended
    /// (first `a`'s). Call only from the thread that created the hand-over,
    /// in state `IDLE` ([`Self::ready`]).
    pub(super) fn join<A, B, RA, RB>(&self, a: A, b: B) -> ((RA, RB), Ran)
    where
        A: FnOnce() -> RA,
        B: FnOnce() -> RB + Send,
        RB: Send,
    {
        let mut rb: Option<RB> = None;
        let mut b = Some(b);
        let mut run_b = || rb = Some((b.take().expect("the half runs once"))());
        {
            let job: &mut (dyn FnMut() + Send) = &mut run_b;
            // SAFETY: the lifetime is erased only for the hand-over: this
            // function does not return or unwind before the helper has
            // finished with the pointer (DONE) or the caller took the job
            // back (then the helper never read it), so the borrow outlives
            // every use of the pointer.
            let job: Job =
                unsafe { std::mem::transmute::<*mut (dyn FnMut() + Send + '_), Job>(job) };
            // SAFETY: state IDLE: the slot is the caller's.
            self.job.with_mut(|s| unsafe { *s = Some(job) });
        }
        self.state.store(POSTED, Ordering::SeqCst);
        self.wake_helper();
        let ra = catch_unwind(AssertUnwindSafe(a));
        let (panic_b, ran) = if let Some(awake) = self.take_back() {
            // SAFETY: the take-back made the slot the caller's again (the
            // helper takes the job only after its own POSTED → RUNNING).
            self.job.with_mut(|s| unsafe { *s = None });
            (
                catch_unwind(AssertUnwindSafe(&mut run_b)).err(),
                Ran::TakenBack { awake },
            )
        } else {
            self.wait_done();
            // SAFETY: state DONE: the helper is finished with both slots.
            let p = self.panic.with_mut(|s| unsafe { (*s).take() });
            self.state.store(IDLE, Ordering::SeqCst);
            (p, Ran::Helper)
        };
        let ra = match ra {
            Ok(ra) => ra,
            Err(p) => std::panic::resume_unwind(p),
        };
        if let Some(p) = panic_b {
            std::panic::resume_unwind(p);
        }
        ((ra, rb.expect("the half ran")), ran)
    }

    /// Takes the posted half back unless the helper has started it; a
    /// helper that is awake (not parked) gets [`GRACE`] to start it first.
    /// Returns, for a half taken back, whether the helper was awake.
    fn take_back(&self) -> Option<bool> {
        let awake = !self.helper_parked.load(Ordering::SeqCst);
        if awake {
            let mut spin = Spin::new(GRACE);
            while self.state.load(Ordering::Acquire) == POSTED && spin.spin() {}
        }
        let taken = self
            .state
            .compare_exchange(POSTED, IDLE, Ordering::SeqCst, Ordering::SeqCst)
            .is_ok();
        if taken && awake {
            self.preempted.store(true, Ordering::Relaxed);
        }
        taken.then_some(awake)
    }

    /// Whether a half was taken back from an awake helper (one that was
    /// not on a core: the machine is busy) since the last call; clears it.
    /// A take-back from a parked helper (woken too late after a long
    /// serial stretch) does not count.
    pub(super) fn take_preempted(&self) -> bool {
        self.preempted.swap(false, Ordering::Relaxed)
    }

    /// The caller's wait for a running half: spin, then park until DONE.
    fn wait_done(&self) {
        let mut spin = Spin::new(WAIT_SPIN);
        while self.state.load(Ordering::Acquire) != DONE {
            if !spin.spin() {
                self.caller_parks
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                self.caller_parked.store(true, Ordering::SeqCst);
                while self.state.load(Ordering::SeqCst) != DONE {
                    park();
                }
                self.caller_parked.store(false, Ordering::SeqCst);
                return;
            }
        }
    }

    /// Ends the helper's loop (after the last join).
    pub(super) fn stop(&self) {
        self.state.store(STOP, Ordering::SeqCst);
        if let Some(h) = self.helper.lock().unwrap().as_ref() {
            h.unpark();
        }
    }

    /// The helper: take posted halves until [`Self::stop`]; busy-wait
    /// [`SPIN`] after each, then park until the caller posts again.
    pub(super) fn helper_loop(&self) {
        *self.helper.lock().unwrap() = Some(current());
        self.started.store(true, Ordering::Release);
        let mut spin = Spin::new(SPIN);
        loop {
            match self.state.load(Ordering::Acquire) {
                STOP => break,
                POSTED => {
                    if self
                        .state
                        .compare_exchange(POSTED, RUNNING, Ordering::SeqCst, Ordering::SeqCst)
                        .is_ok()
                    {
                        // SAFETY: state RUNNING: the slots are the helper's until DONE
                        let job = self.job.with_mut(|s| unsafe { (*s).take() });
                        let job = job.expect("a posted job");
                        // SAFETY: the caller keeps the closure alive and
                        // untouched until it sees DONE (`join`).
                        let r = catch_unwind(AssertUnwindSafe(|| unsafe { (*job)() }));
                        if let Err(p) = r {
                            // SAFETY: still RUNNING
                            self.panic.with_mut(|s| unsafe { *s = Some(p) });
                        }
                        self.state.store(DONE, Ordering::SeqCst);
                        if self.caller_parked.load(Ordering::SeqCst) {
                            self.caller.unpark();
                        }
                        spin = Spin::new(SPIN);
                    }
                }
                _ => {
                    if !spin.spin() {
                        self.helper_parked.store(true, Ordering::SeqCst);
                        let s = self.state.load(Ordering::SeqCst);
                        if s != POSTED && s != STOP {
                            park();
                        }
                        self.helper_parked.store(false, Ordering::SeqCst);
                        spin = Spin::new(SPIN);
                    }
                }
            }
        }
    }
}

impl Default for Handover {
    fn default() -> Self {
        Self::new()
    }
}
