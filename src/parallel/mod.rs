//! Concurrency of one run: the size thresholds from which passes split
//! into two concurrent halves, `join_if` and `in_halves` that run
//! them, the run's two-thread team (`team`) and the user's switch
//! ([`Threads`], scenario key `integrator.threads`, environment variable
//! [`THREADS_ENV`]).
//!
//! Every concurrent pass is a pair of closures, each sequential inside,
//! that write disjoint data: running them on one thread (in order) or on
//! two gives the same bits, so no result depends on the thread count, on
//! the switch, or on which thread ran a half.
//!
//! This module imports nothing else of the crate: the floors below and
//! above it (`linalg`, `integrate`, `formulation`, the generated kernels)
//! take their concurrency from here.
#![warn(unreachable_pub)]

mod handover;
pub(crate) mod team;

pub use team::{Rule, TeamReport, SPIN};

use serde::Serialize;
use std::cell::Cell;

/// Number of coordinates from which forces and constraint terms, the
/// index-3 residual and the implicit integrators' element-wise passes are
/// evaluated in two concurrent halves; a run with a state (q and q̇) of at
/// least twice this opens a two-thread team (`team::run`). Below it a
/// join costs more than it saves (measurements: docs/scaling.md).
pub const PARALLEL_MIN_COORDS: usize = 6000;

/// Environment variable that sets [`Threads`] for runs whose own setting
/// is `auto` (`"auto"`, `"1"` or `"2"`; unset: `auto`).
pub const THREADS_ENV: &str = "MBSOLVE_THREADS";

/// How many threads one run uses for its concurrent passes (scenario key
/// `integrator.threads`; default `auto`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Threads {
    /// Two threads for a large run (state ≥ 2·[`PARALLEL_MIN_COORDS`])
    /// inside a rayon pool with a free second thread, while the second
    /// thread keeps up: when it repeatedly has not taken a posted half
    /// by the time the caller finished its own (a busy machine), the run
    /// continues on one thread for a while and then tries again; and
    /// while short probe windows with and without the second thread find
    /// it faster (`team`'s A/B rule: wall time of a few dozen passes each
    /// way, re-probed every 8–128 windows, sooner when the machine's load
    /// changes). Probes run only while the machine has a core free
    /// (`/proc/loadavg`); with all cores busy the run uses one thread.
    #[default]
    #[serde(rename = "auto")]
    Auto,
    /// One thread: every pass runs whole on the calling thread.
    #[serde(rename = "1")]
    One,
    /// Two threads for every pass above its size threshold, also for
    /// smaller runs and outside a rayon pool (the helper is then a thread
    /// of its own), without backing off on a busy machine.
    #[serde(rename = "2")]
    Two,
}

impl std::str::FromStr for Threads {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "auto" => Ok(Self::Auto),
            "1" => Ok(Self::One),
            "2" => Ok(Self::Two),
            other => Err(format!(
                "unknown thread setting '{other}' (expected \"auto\", 1 or 2)"
            )),
        }
    }
}

impl Threads {
    /// The setting of [`THREADS_ENV`]: `Ok(None)` when unset, an error
    /// naming the variable and the value when it is not `auto`, `1` or `2`.
    pub fn from_env() -> Result<Option<Self>, String> {
        match std::env::var(THREADS_ENV) {
            Err(std::env::VarError::NotPresent) => Ok(None),
            Err(std::env::VarError::NotUnicode(v)) => Err(format!(
                "environment variable {THREADS_ENV}: {v:?} is not text"
            )),
            Ok(v) => v
                .parse()
                .map(Some)
                .map_err(|e| format!("environment variable {THREADS_ENV}: {e}")),
        }
    }

    /// `self`, or for `Auto` the environment's setting ([`Self::from_env`]).
    pub fn resolve(self) -> Result<Self, String> {
        match self {
            Self::Auto => Ok(Self::from_env()?.unwrap_or(Self::Auto)),
            other => Ok(other),
        }
    }
}

thread_local! {
    /// The setting of the run this thread drives ([`with_threads`]).
    static POLICY: Cell<Threads> = const { Cell::new(Threads::Auto) };
}

/// The setting in force on this thread.
pub(crate) fn policy() -> Threads {
    POLICY.with(|p| p.get())
}

/// Runs `f` (one simulation) with the thread setting `threads` (resolved,
/// not `Auto` from the environment: see [`Threads::resolve`]) and returns
/// what the teams opened inside it did.
pub fn with_threads<R>(threads: Threads, f: impl FnOnce() -> R) -> (R, TeamReport) {
    struct Restore(Threads, TeamReport);
    impl Drop for Restore {
        fn drop(&mut self) {
            POLICY.with(|p| p.set(self.0));
            team::REPORT.with(|r| r.set(self.1));
        }
    }
    let saved = Restore(
        POLICY.with(|p| p.replace(threads)),
        team::REPORT.with(|r| r.replace(TeamReport::default())),
    );
    let out = f();
    let report = team::REPORT.with(|r| r.get());
    drop(saved);
    (out, report)
}

/// [`team::join(a, b)`](team::join) when `parallel` (the run's two-thread
/// team, else `rayon::join`; both halves here under [`Threads::One`]),
/// else `a()` then `b()` on this thread: the same operations either way,
/// so the results do not depend on the choice or on the thread count (the
/// callers' determinism rests on each task being sequential inside).
/// Small problems run sequentially: a join from outside a rayon pool costs
/// tens of microseconds.
pub(crate) fn join_if<A, B, RA, RB>(parallel: bool, a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    if parallel {
        team::join(a, b)
    } else {
        (a(), b())
    }
}

/// Whether a [`join_if`] on this thread would now run its halves on two
/// threads ([`team::concurrent`]); callers choose between a two-thread
/// and a one-thread form of the same computation with it.
pub(crate) fn concurrent() -> bool {
    team::concurrent()
}

/// The coordinate slices an element-wise pass over coordinates
/// `base .. base + len` writes (`w`) and reads (`r`), all of length `len`:
/// what [`in_halves`] splits.
pub(crate) struct Slices<'a, const W: usize, const R: usize> {
    /// Global index of the first coordinate.
    pub base: usize,
    pub w: [&'a mut [f64]; W],
    pub r: [&'a [f64]; R],
}

impl<'a, const W: usize, const R: usize> Slices<'a, W, R> {
    /// The first `k` coordinates and the rest (no allocation).
    fn split(self, k: usize) -> (Self, Self) {
        let mut w = self.w.map(|s| {
            let (a, b) = s.split_at_mut(k);
            (Some(a), Some(b))
        });
        let r = self.r.map(|s| s.split_at(k));
        let lo = Slices {
            base: self.base,
            w: std::array::from_fn(|i| w[i].0.take().expect("each half taken once")),
            r: std::array::from_fn(|i| r[i].0),
        };
        let hi = Slices {
            base: self.base + k,
            w: std::array::from_fn(|i| w[i].1.take().expect("each half taken once")),
            r: std::array::from_fn(|i| r[i].1),
        };
        (lo, hi)
    }
}

/// An element-wise pass `f` over `s` (of `len` coordinates): whole, or
/// with `parallel` on its two halves (split at `len / 2`, fixed by the
/// length) through [`join_if`], the two results merged by `merge`. With an
/// order-free merge (max, and) the results do not depend on `parallel` or
/// the thread count.
pub(crate) fn in_halves<const W: usize, const R: usize, T: Send>(
    parallel: bool,
    len: usize,
    s: Slices<'_, W, R>,
    f: impl Fn(Slices<'_, W, R>) -> T + Sync,
    merge: impl FnOnce(T, T) -> T,
) -> T {
    if !parallel {
        return f(s);
    }
    let (lo, hi) = s.split(len / 2);
    let (a, b) = join_if(true, || f(lo), || f(hi));
    merge(a, b)
}
