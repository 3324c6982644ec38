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
//! machine: [`MISS_LIMIT`] take-backs in a row from a helper that was
//! awake, not parked: it was not on a core, while no core is free by
//! `/proc/loadavg`) stops posting for a while
//! ([`SOLO_MIN`] joins, doubled at each further miss up to [`SOLO_MAX`])
//! and lets the helper park, then tries again: the run falls back to one
//! thread while the second is not available.
//!
//! Take-backs only see a helper that is not running at all. A helper that
//! runs but shares its core (a busy machine) can still make two threads
//! slower than one: it spins where the caller could run, and a half it is
//! preempted in holds the caller up. So an `Auto` team also compares the
//! two ways directly ([`Adapt`]): it runs probe windows of
//! [`PROBE_PASSES`] passes with the helper and without it (in the order
//! team, alone, alone, team, so that a steady drift of the machine's load
//! hits both alike), measures the wall time of each, and runs the next
//! [`EXPLOIT_MIN`] … [`EXPLOIT_MAX`] windows the faster way (the team
//! only when it took at most [`TEAM_MARGIN`] of the time alone;
//! [`EXPLOIT_MAX`] at once when at most [`CLEAR_MARGIN`]), then
//! probes again — at once when [`DOUBT_WINDOWS`] windows in a row gave
//! evidence against the way it runs (with the helper: a half taken back
//! from a helper that was awake, so preempted; alone, when it runs alone
//! because no core was free or its probe's choice of one thread is not yet
//! confirmed by a second one: a core free by `/proc/loadavg`). Long
//! stretches keep the probes' cost small on a machine whose load does not
//! change; the evidence brings the probe forward when it does.
//!
//! A probe costs where no core is free: its windows with the helper run
//! slower than alone (the helper takes its core time from the caller or
//! is preempted in a half), and on a machine whose cores are all busy the
//! answer is known. So a probe runs only when `/proc/loadavg` shows fewer
//! runnable tasks than cores (the caller counted, the helper parked): a
//! team opened without a free core starts alone, and a stretch alone that
//! ends without one is followed by another, twice as long (up to
//! [`EXPLOIT_MAX`]), instead of a probe. On a busy machine the run then
//! does what one thread does (the helper parked after its first
//! [`SPIN`]), and a core that becomes free brings a probe within
//! [`DOUBT_WINDOWS`] windows. A *pass* is one call of [`concurrent`] on the caller:
//! every pass that has a two-thread and a one-thread form asks it once
//! whatever the answer (a Newton iteration's residual and solve), so the
//! count of passes is the same whichever way the team runs and measures
//! progress. The decisions depend on timing; the results do not (each
//! pass computes the same bits in either form, and each half the same
//! bits on either thread).
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
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicUsize, Ordering};

pub use super::handover::SPIN;

mod clock;
pub(crate) use clock::one_thread_form;
use clock::{clock_wanted, clocked, cpu, start_gaps, Timed};
pub use clock::{Clock, CLOCK_ENV, GAP_BOUNDS_S};

/// Take-backs in a row after which an `Auto` team stops posting halves.
pub(crate) const MISS_LIMIT: u32 = 4;
/// Joins an `Auto` team runs on one thread after [`MISS_LIMIT`] misses.
pub(crate) const SOLO_MIN: u32 = 64;
/// The longest such stretch (each miss of the next try doubles it).
pub(crate) const SOLO_MAX: u32 = 16_384;

mod adapt;
pub(crate) use adapt::*;

#[cfg(test)]
thread_local! {
    /// A test's probe window (passes) for the teams opened on this thread.
    static TEST_WINDOW: Cell<Option<u32>> = const { Cell::new(None) };
    /// The passes of the last team closed on this thread.
    static TEST_PASSES: Cell<usize> = const { Cell::new(0) };
    /// A test's answer to whether a core is free (`None`: `/proc/loadavg`'s).
    static TEST_FREE: Cell<Option<bool>> = const { Cell::new(None) };
}

/// What the concurrent passes of one run did ([`super::with_threads`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct TeamReport {
    /// Halves that ran on a second thread (a team's helper or a rayon
    /// worker).
    pub halves_split: usize,
    /// Halves posted to a team's helper that the caller took back and ran
    /// itself because the helper had not started them.
    pub halves_taken_back: usize,
    /// Those of [`Self::halves_taken_back`] whose helper was awake, not
    /// parked (it was not on a core, or not yet spinning): the rest were
    /// posted to a parked helper, woken too late.
    pub halves_taken_back_awake: usize,
    /// Joins a team ran on one thread without posting (the second thread
    /// was found busy, or the A/B rule ran that window alone).
    pub halves_solo: usize,
    /// Passes the caller of a team counted (`concurrent` calls): the
    /// A/B rule's measure of progress, the same whichever way it ran.
    pub passes: usize,
    /// Waits of the caller for a half running on the helper that
    /// outlasted its spin and parked (each then costs a wake-up).
    pub caller_parks: usize,
    /// Wake-ups of a parked helper (posts and wakes after an idle
    /// stretch longer than [`SPIN`]).
    pub helper_wakes: usize,
    /// Probes of the A/B rule that chose the team, and that chose one
    /// thread.
    pub decisions: [u32; 2],
    /// Why the run used the threads it did (the last integration of the
    /// run that reached the rule).
    pub rule: Rule,
    /// Where the run's wall time went ([`Clock`]).
    pub clock: Clock,
}

/// The thread rule's decision for one integration (`run`), with its
/// reason: reported in the run summary (`threads_rule`, and as text by
/// [`Rule::reason`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
#[serde(tag = "decision", rename_all = "snake_case")]
pub enum Rule {
    /// No integration reached the rule.
    #[default]
    None,
    /// The setting is one thread (`integrator.threads = 1`,
    /// `MBSOLVE_THREADS=1`, or a sweep that runs its runs side by side,
    /// each on one thread).
    One,
    /// `auto`, one thread: the state (`q` and `q̇`) has `state` entries,
    /// fewer than `min` (2·[`PARALLEL_MIN_COORDS`](super::PARALLEL_MIN_COORDS)),
    /// the size from which concurrent passes pay.
    Small {
        /// Entries of the run's state.
        state: usize,
        /// The size from which a team is opened.
        min: usize,
    },
    /// `auto`, one thread: no second thread to run on — the run is not on
    /// a worker of a rayon pool (`in_pool` false), or its pool has `pool`
    /// thread(s) (`RAYON_NUM_THREADS=1`).
    NoSecondThread {
        /// Threads of the pool the run is on (or of the global pool).
        pool: usize,
        /// Whether the run is on a pool's worker thread.
        in_pool: bool,
    },
    /// The setting is two threads (`integrator.threads = 2`): a team
    /// whose helper takes every half it can, without probing.
    Two,
    /// `auto` with a team: its A/B rule's probes (module docs) chose the
    /// team `team` times and one thread `alone` times; `last_ratio` is the
    /// last probe's wall time with the helper over its time alone (the
    /// team is chosen at ≤ `TEAM_MARGIN` (0.97); `None`: the run ended before
    /// its first probe did).
    Probed {
        /// Probes that chose the team.
        team: u32,
        /// Probes that chose one thread.
        alone: u32,
        /// The last probe's time with the helper over its time alone.
        last_ratio: Option<f64>,
        /// Probes not run because no core was free (`/proc/loadavg`):
        /// the team ran alone instead.
        skipped: u32,
        /// Stretches ended early, their probe brought forward by a few
        /// windows in a row (`DOUBT_WINDOWS`, 2) of evidence against them.
        cut: u32,
    },
}

impl Rule {
    /// The decision and its reason as one sentence for the run's console
    /// line and summary.
    pub fn reason(&self) -> String {
        match *self {
            Rule::None => "no integration reached the thread rule".into(),
            Rule::One => {
                "one thread: the setting is 1 (integrator.threads = 1, MBSOLVE_THREADS=1, \
                 or a sweep running its runs side by side)"
                    .into()
            }
            Rule::Small { state, min } => format!(
                "auto: one thread, the state has {state} entries, fewer than the {min} \
                 from which concurrent passes pay"
            ),
            Rule::NoSecondThread { pool, in_pool } => {
                if in_pool {
                    format!(
                        "auto: one thread, the thread pool has {pool} thread{} (RAYON_NUM_THREADS)",
                        if pool == 1 { "" } else { "s" }
                    )
                } else {
                    "auto: one thread, the run is not on a worker of a thread pool".into()
                }
            }
            Rule::Two => "two threads forced: integrator.threads = 2 (or MBSOLVE_THREADS=2)".into(),
            Rule::Probed {
                team,
                alone,
                last_ratio,
                skipped,
                ..
            } => {
                let busy = match skipped {
                    0 => String::new(),
                    k => format!(
                        "; {k} probe{} skipped, no core being free",
                        if k == 1 { "" } else { "s" }
                    ),
                };
                match last_ratio {
                    None if skipped > 0 => format!(
                        "auto: a two-thread team that ran alone: no core was free at its \
                         {skipped} probe time{}",
                        if skipped == 1 { "" } else { "s" }
                    ),
                    None => "auto: a two-thread team; the run ended before its first probe".into(),
                    Some(r) => format!(
                        "auto: a two-thread team whose probes chose two threads {team} time{} \
                         and one thread {alone} time{}; the last probe took {r:.2}× the time \
                         alone with the helper (two threads at ≤ {TEAM_MARGIN}){busy}",
                        if team == 1 { "" } else { "s" },
                        if alone == 1 { "" } else { "s" },
                    ),
                }
            }
        }
    }
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
        self.halves_taken_back_awake += o.halves_taken_back_awake;
        self.halves_solo += o.halves_solo;
        self.passes += o.passes;
        self.caller_parks += o.caller_parks;
        self.helper_wakes += o.helper_wakes;
        self.decisions[0] += o.decisions[0];
        self.decisions[1] += o.decisions[1];
        self.clock.run_s += o.clock.run_s;
        self.clock.halves_s += o.clock.halves_s;
        self.clock.work_s += o.clock.work_s;
        self.clock.longer_s += o.clock.longer_s;
        for (a, b) in self.clock.gaps.iter_mut().zip(o.clock.gaps) {
            *a += b;
        }
        if o.rule != Rule::None {
            self.rule = o.rule;
        }
    }
}

thread_local! {
    /// The counts of the runs on this thread since [`super::with_threads`].
    pub(super) static REPORT: Cell<TeamReport> = const {
        Cell::new(TeamReport {
            halves_split: 0,
            halves_taken_back: 0,
            halves_taken_back_awake: 0,
            halves_solo: 0,
            passes: 0,
            caller_parks: 0,
            helper_wakes: 0,
            decisions: [0; 2],
            rule: Rule::None,
            clock: Clock {
                run_s: 0.0,
                halves_s: 0.0,
                work_s: 0.0,
                longer_s: 0.0,
                gaps: [0; 5],
            },
        })
    };
    /// Nesting of passes in halves on this thread (only the outermost is
    /// timed).
    static DEPTH: Cell<u32> = const { Cell::new(0) };
    /// Set while a [`run`] is timed on this thread.
    static IN_RUN: Cell<bool> = const { Cell::new(false) };
    /// Whether the run on this thread keeps a [`Clock`] ([`CLOCK_ENV`]).
    static CLOCK_ON: Cell<bool> = const { Cell::new(false) };
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
    taken_back_awake: AtomicUsize,
    solo: AtomicUsize,
    misses: AtomicU32,
    solo_left: AtomicU32,
    backoff: AtomicU32,
    /// The A/B rule (`Auto` teams only).
    adapt: Option<std::sync::Mutex<Adapt>>,
    /// Whether the A/B rule runs the current window alone.
    ab_solo: AtomicBool,
    passes: AtomicUsize,
    /// Cores of the machine (for the free-core evidence of the A/B rule).
    cores: usize,
}

impl Team {
    fn new(adaptive: bool) -> Self {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        // asked before the helper starts: it would count as a runnable task
        let free = adaptive && core_free(cores);
        Self {
            h: Handover::new(),
            adaptive,
            split: AtomicUsize::new(0),
            taken_back: AtomicUsize::new(0),
            taken_back_awake: AtomicUsize::new(0),
            solo: AtomicUsize::new(0),
            misses: AtomicU32::new(0),
            solo_left: AtomicU32::new(0),
            backoff: AtomicU32::new(SOLO_MIN),
            adapt: adaptive.then(|| {
                #[cfg(test)]
                let window = TEST_WINDOW.with(|w| w.get()).unwrap_or(PROBE_PASSES);
                #[cfg(not(test))]
                let window = PROBE_PASSES;
                std::sync::Mutex::new(Adapt::new(window, free))
            }),
            ab_solo: AtomicBool::new(adaptive && !free),
            passes: AtomicUsize::new(0),
            cores,
        }
    }

    /// Counts a pass for the A/B rule (caller only); returns whether it
    /// runs alone.
    fn pass(&self) -> bool {
        self.passes.fetch_add(1, Ordering::Relaxed);
        let Some(a) = &self.adapt else {
            return false;
        };
        let mut a = a.lock().unwrap_or_else(|e| e.into_inner());
        let (solo, mut wake) = a.pass(std::time::Instant::now(), || core_free(self.cores));
        if a.left % a.window == 0 {
            // a window ended with this pass: the evidence it gave
            let preempted = self.h.take_preempted();
            if a.exploit_window_ended() {
                let against = self.against(solo, a.busy, preempted);
                wake |= a.evidence(against);
            }
        }
        drop(a);
        self.ab_solo.store(solo, Ordering::Relaxed);
        if wake {
            self.h.wake_helper();
        }
        solo
    }

    /// Whether an exploit window just ended gives evidence against the
    /// way it ran ([`DOUBT_WINDOWS`]). Alone: a core found free, only
    /// against a stretch chosen because none was (`busy`). With the
    /// helper: a half taken back from it awake (`preempted`: it was not on
    /// a core) while no core is free beside the team's two threads (the
    /// helper counted among the runnable tasks while awake); on an idle
    /// machine such a take-back is a passing pause of the helper's core,
    /// whose cost the probes weigh by wall time.
    fn against(&self, solo: bool, busy: bool, preempted: bool) -> bool {
        if solo {
            busy && core_free(self.cores)
        } else {
            preempted && !core_free(self.cores + usize::from(self.h.helper_awake()))
        }
    }

    /// Records how a posted half ran; after [`MISS_LIMIT`] take-backs in a
    /// row from an awake helper (one that was not on a core) an adaptive
    /// team runs the next `backoff` joins alone, unless a core is free
    /// beside the team's two threads (`/proc/loadavg`, the awake helper
    /// counted: on an idle machine such a row is a pause of the helper's
    /// core by the host, and the A/B rule's probes weigh its cost by wall
    /// time; each further miss asks again). A take-back from a parked
    /// helper, woken too late after a serial stretch longer than [`SPIN`],
    /// is a wake-up latency, not a busy machine: it neither counts as a
    /// miss nor resets the count (posting to a parked helper costs the
    /// post; the helper is awake at the next join).
    fn note(&self, ran: Ran) {
        let r = Ordering::Relaxed;
        match ran {
            Ran::Helper => {
                self.split.fetch_add(1, r);
                self.misses.store(0, r);
                self.backoff.store(SOLO_MIN, r);
            }
            Ran::TakenBack { awake: false } => {
                self.taken_back.fetch_add(1, r);
            }
            Ran::TakenBack { awake: true } => {
                self.taken_back.fetch_add(1, r);
                self.taken_back_awake.fetch_add(1, r);
                let m = self.misses.load(r) + 1;
                if self.adaptive
                    && m >= MISS_LIMIT
                    && !core_free(self.cores + usize::from(self.h.helper_awake()))
                {
                    let b = self.backoff.load(r);
                    self.solo_left.store(b, r);
                    self.backoff.store((2 * b).min(SOLO_MAX), r);
                    // one more miss at the next try backs off again
                    self.misses.store(MISS_LIMIT - 1, r);
                } else {
                    self.misses.store(m.min(MISS_LIMIT - 1), r);
                }
            }
        }
    }

    /// Whether the next join runs alone (and counts it); wakes the helper
    /// one join before the next try, so that it spins when the try posts.
    fn solo_join(&self) -> bool {
        let r = Ordering::Relaxed;
        if self.ab_solo.load(r) {
            self.solo.fetch_add(1, r);
            return true;
        }
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
        let (decisions, rule) = match &self.adapt {
            None => ([0; 2], Rule::Two),
            Some(a) => {
                let a = a.lock().unwrap_or_else(|e| e.into_inner());
                let [team, alone] = a.decided;
                let rule = Rule::Probed {
                    team,
                    alone,
                    last_ratio: a.last_ratio,
                    skipped: a.skipped,
                    cut: a.cut,
                };
                (a.decided, rule)
            }
        };
        let (caller_parks, helper_wakes) = self.h.parks();
        TeamReport {
            caller_parks,
            helper_wakes,
            halves_split: self.split.load(Ordering::Relaxed),
            halves_taken_back: self.taken_back.load(Ordering::Relaxed),
            halves_taken_back_awake: self.taken_back_awake.load(Ordering::Relaxed),
            halves_solo: self.solo.load(Ordering::Relaxed),
            passes: self.passes.load(Ordering::Relaxed),
            decisions,
            rule,
            clock: Clock::default(),
        }
    }
}

/// [`free_core`], or in tests the answer a test fixed for this thread.
fn core_free(cores: usize) -> bool {
    #[cfg(test)]
    if let Some(free) = TEST_FREE.with(|f| f.get()) {
        return free;
    }
    free_core(cores)
}

/// Whether the machine has a core free now: fewer runnable tasks than
/// `cores` (the fourth field of `/proc/loadavg`, `running/total`, counts
/// the caller itself). `true` where unreadable (not Linux): the probes
/// then decide alone, as they would with a core free.
fn free_core(cores: usize) -> bool {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| runnable_tasks(&s))
        .is_none_or(|r| r < cores)
}

/// The runnable tasks of a `/proc/loadavg` line (`0.52 0.58 0.59 3/412
/// 12345`: the fourth field's numerator), `None` when malformed.
fn runnable_tasks(loadavg: &str) -> Option<usize> {
    let (r, _) = loadavg.split_whitespace().nth(3)?.split_once('/')?;
    r.parse().ok()
}

/// Runs `f` (a whole integration run) with a two-thread team as the
/// thread setting of [`super::with_threads`] asks: under `Auto` when the
/// calling thread is a worker of a rayon pool with more than one thread
/// and `large` (the run has enough coordinates for its joins to pay);
/// under `Two` always; never under `One`. Else, and for nested calls, just
/// `f()`.
/// `state` is the number of entries of the run's state (reported in the
/// [`Rule`]).
pub(crate) fn run<R>(large: bool, state: usize, f: impl FnOnce() -> R) -> R {
    if !CURRENT.with(|c| c.get()).is_null() || IN_HELPER.with(|h| h.get()) {
        return f();
    }
    // a call nested in a run without a team (one thread) is timed by the
    // outer one
    let outer = !IN_RUN.with(|r| r.replace(true));
    let clock = outer && clock_wanted();
    if outer {
        CLOCK_ON.with(|c| c.set(clock));
        start_gaps();
    }
    /// Adds the run's CPU seconds to the report ([`Clock::run_s`]).
    struct RunClock(bool, Option<f64>);
    impl Drop for RunClock {
        fn drop(&mut self) {
            if self.0 {
                IN_RUN.with(|r| r.set(false));
                CLOCK_ON.with(|c| c.set(false));
            }
            if let Some(start) = self.1 {
                REPORT.with(|r| {
                    let mut v = r.get();
                    v.clock.run_s += cpu() - start;
                    r.set(v);
                });
            }
        }
    }
    let _clock = RunClock(outer, clock.then(cpu));
    let decided = |rule: Rule| {
        REPORT.with(|r| {
            let mut v = r.get();
            v.rule = rule;
            r.set(v);
        })
    };
    match policy() {
        Threads::One => {
            decided(Rule::One);
            f()
        }
        Threads::Auto => {
            let in_pool = rayon::current_thread_index().is_some();
            let pool = rayon::current_num_threads();
            if !large {
                decided(Rule::Small {
                    state,
                    min: 2 * super::PARALLEL_MIN_COORDS,
                });
                return f();
            }
            if !(in_pool && pool > 1) {
                decided(Rule::NoSecondThread { pool, in_pool });
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
            #[cfg(test)]
            TEST_PASSES.with(|p| p.set(rep.passes));
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
/// threads: inside a team whose helper runs, is free and is not backed off
/// (nor in a window the A/B rule runs alone), or else (not on a helper,
/// not under `One`) inside a rayon pool with more than one thread.
/// Callers choose between a two-thread and a one-thread form of the same
/// computation with it (results must not depend on the choice), once per
/// pass whatever the answer: in an `Auto` team each call counts one pass
/// of the A/B rule's windows (module docs).
pub(crate) fn concurrent() -> bool {
    match current_team() {
        Some(t) => {
            let solo = t.pass();
            !solo && t.h.ready() && t.solo_left.load(Ordering::Relaxed) == 0
        }
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
pub(crate) fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    let mut clock = Timed::new();
    let on = clock.start.is_some();
    let (a, b) = (clocked(on, a), clocked(on, b));
    let ((ra, da), (rb, db)) = match current_team() {
        Some(t) if t.h.ready() && !t.solo_join() => {
            let (r, ran) = t.h.join(a, b);
            t.note(ran);
            r
        }
        Some(_) => (a(), b()),
        None if IN_HELPER.with(|h| h.get()) || policy() == Threads::One => (a(), b()),
        None => {
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
    };
    clock.halves = Some((da, db));
    (ra, rb)
}

#[cfg(test)]
mod tests;
