//! The run's thread clock ([`Clock`]): where a run's CPU time goes, in
//! passes split into halves and outside them, kept when [`CLOCK_ENV`] is
//! `1`.

use super::{CLOCK_ON, DEPTH, IN_HELPER, REPORT};
use serde::Serialize;
use std::cell::Cell;

/// Environment variable that makes a run keep its [`Clock`] (`1`).
pub const CLOCK_ENV: &str = "MBSOLVE_THREADS_CLOCK";

/// CPU seconds of a run on the thread that drives it (so that other
/// processes holding the core do not count), kept when [`CLOCK_ENV`] is
/// `1` (else zero; it reads the thread CPU clock, a system call, twice per
/// pass and twice per half): inside the run (its stability check and
/// integration), inside the outermost passes in halves there (joins, and
/// the one-thread forms of two-half passes), and each half's on the
/// thread that ran it. `halves_s / run_s` is the share of the run in
/// passes that split; `run_s / (run_s − halves_s + longer_s)` bounds the
/// gain of a second thread that costs nothing (Amdahl's law, each pass as
/// long as its longer half); with two threads `run_s − halves_s` is the
/// caller's serial work and `halves_s − longer_s` what the hand-over cost
/// it beyond the longer halves (spinning; parked waits do not count).
/// `gaps` counts the caller's serial stretches between two outermost
/// passes by their CPU seconds: an idle helper parks after
/// [`SPIN`](super::SPIN) of wall time, so a stretch longer than that
/// costs the next pass a wake-up.
/// Zero where the thread CPU clock is unavailable (not Linux).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Clock {
    /// CPU seconds of the run (stability check and integration).
    pub run_s: f64,
    /// CPU seconds inside the outermost passes in halves.
    pub halves_s: f64,
    /// Both halves of those passes, each timed on the thread that ran it
    /// (a one-thread form that interleaves them: the whole pass).
    pub work_s: f64,
    /// The longer half of each of those passes (a one-thread form that
    /// interleaves them: half the pass).
    pub longer_s: f64,
    /// Serial stretches between two outermost passes of the run (the
    /// caller's CPU seconds from the end of one to the start of the next)
    /// of at least each of [`GAP_BOUNDS_S`]: all, 0.1 ms, 0.3 ms, 1 ms
    /// ([`SPIN`](super::SPIN)), 3 ms.
    pub gaps: [usize; 5],
}

/// The bounds of [`Clock::gaps`], CPU seconds.
pub const GAP_BOUNDS_S: [f64; 5] = [0.0, 1e-4, 3e-4, 1e-3, 3e-3];

thread_local! {
    /// The CPU seconds at the end of the last outermost pass of the run
    /// on this thread (NaN: none yet).
    static PASS_END: Cell<f64> = const { Cell::new(f64::NAN) };
}

/// Forgets the last pass's end (a run starts).
pub(super) fn start_gaps() {
    PASS_END.with(|e| e.set(f64::NAN));
}

/// Whether a run keeps a [`Clock`]: [`CLOCK_ENV`] is `1` (in tests,
/// always).
pub(super) fn clock_wanted() -> bool {
    cfg!(test) || std::env::var_os(CLOCK_ENV).is_some_and(|v| v == "1")
}

/// The calling thread's CPU seconds ([`crate::parallel::thread_cpu_seconds`]; 0
/// where unavailable).
pub(super) fn cpu() -> f64 {
    crate::parallel::thread_cpu_seconds().unwrap_or(0.0)
}

/// `f` returning its result and, when `on`, its own CPU seconds on
/// whichever thread runs it.
pub(super) fn clocked<R>(on: bool, f: impl FnOnce() -> R) -> impl FnOnce() -> (R, f64) {
    move || {
        if !on {
            return (f(), 0.0);
        }
        let start = cpu();
        let r = f();
        (r, cpu() - start)
    }
}

/// The timing of one pass in halves on this thread ([`Clock`]): started
/// for an outermost pass off a helper when the run keeps a clock, added
/// to the report when dropped.
pub(super) struct Timed {
    /// The thread's CPU seconds at the start, for a timed pass.
    pub(super) start: Option<f64>,
    /// The CPU seconds of the two halves, where known.
    pub(super) halves: Option<(f64, f64)>,
}

impl Timed {
    pub(super) fn new() -> Self {
        let depth = DEPTH.with(|d| d.replace(d.get() + 1));
        let outermost = depth == 0 && !IN_HELPER.with(|h| h.get());
        let timed = outermost && CLOCK_ON.with(|c| c.get());
        let start = timed.then(cpu);
        if let Some(s) = start {
            let gap = s - PASS_END.with(|e| e.get());
            if gap >= 0.0 {
                REPORT.with(|r| {
                    let mut v = r.get();
                    for (n, b) in v.clock.gaps.iter_mut().zip(GAP_BOUNDS_S) {
                        *n += usize::from(gap >= b);
                    }
                    r.set(v);
                });
            }
        }
        Self {
            start,
            halves: None,
        }
    }
}

impl Drop for Timed {
    fn drop(&mut self) {
        DEPTH.with(|d| d.set(d.get() - 1));
        if let Some(s) = self.start {
            let end = cpu();
            PASS_END.with(|e| e.set(end));
            let whole = end - s;
            // a one-thread form that runs both halves at once: two equal
            // halves
            let (a, b) = self.halves.unwrap_or((whole / 2.0, whole / 2.0));
            REPORT.with(|r| {
                let mut v = r.get();
                v.clock.halves_s += whole;
                v.clock.work_s += a + b;
                v.clock.longer_s += a.max(b);
                r.set(v);
            });
        }
    }
}

/// `f()`: a two-half pass in a one-thread form that runs both halves at
/// once (interleaved rows), timed as a pass in halves ([`Clock`]) of two
/// equal halves.
pub(crate) fn one_thread_form<R>(f: impl FnOnce() -> R) -> R {
    let _clock = Timed::new();
    f()
}
