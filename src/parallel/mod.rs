//! Concurrency of one run: the size thresholds from which passes split
//! into two concurrent halves, `join_if` and `split_pass` (`in_halves`) that run
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

pub use team::{Clock, Rule, TeamReport, CLOCK_ENV, GAP_BOUNDS_S, SPIN};

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

/// CPU time of the calling thread in seconds (`clock_gettime` with
/// `CLOCK_THREAD_CPUTIME_ID`, nanoseconds, current slice included): unlike
/// wall time it does not count the time other processes hold the core.
/// `None` where unavailable.
#[cfg(target_os = "linux")]
pub fn thread_cpu_seconds() -> Option<f64> {
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
pub fn thread_cpu_seconds() -> Option<f64> {
    None
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

/// `f()` (a run whose state, `q` and `q̇`, has `state` entries) with a
/// two-thread team ([`team::run`]) as the thread setting asks, for a state
/// of at least 2·[`PARALLEL_MIN_COORDS`] entries under `auto`. Opened once
/// around a run's stability check and integration; a nested call (the
/// integration's driver) runs in the team already open.
pub(crate) fn run_with_team<R>(state: usize, f: impl FnOnce() -> R) -> R {
    team::run(state >= 2 * PARALLEL_MIN_COORDS, state, f)
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

/// Data an element-wise pass splits into two halves at an element index
/// ([`split_pass`]): slices, arrays and tuples of them, all cut at the same
/// `k` (each component must have at least `k` elements).
pub(crate) trait Halve: Sized {
    /// The first `k` elements and the rest (no allocation).
    fn halve(self, k: usize) -> (Self, Self);
}

impl<T> Halve for &mut [T] {
    fn halve(self, k: usize) -> (Self, Self) {
        self.split_at_mut(k)
    }
}

impl<T> Halve for &[T] {
    fn halve(self, k: usize) -> (Self, Self) {
        self.split_at(k)
    }
}

impl<H: Halve, const N: usize> Halve for [H; N] {
    fn halve(self, k: usize) -> (Self, Self) {
        let mut parts = self.map(|h| {
            let (a, b) = h.halve(k);
            (Some(a), Some(b))
        });
        let lo = std::array::from_fn(|i| parts[i].0.take().expect("each half taken once"));
        let hi = std::array::from_fn(|i| parts[i].1.take().expect("each half taken once"));
        (lo, hi)
    }
}

macro_rules! halve_tuple {
    ($($t:ident $v:ident $a:ident $b:ident),+) => {
        impl<$($t: Halve),+> Halve for ($($t,)+) {
            fn halve(self, k: usize) -> (Self, Self) {
                let ($($v,)+) = self;
                $(let ($a, $b) = $v.halve(k);)+
                (($($a,)+), ($($b,)+))
            }
        }
    };
}
halve_tuple!(A a a0 a1);
halve_tuple!(A a a0 a1, B b b0 b1);
halve_tuple!(A a a0 a1, B b b0 b1, C c c0 c1);
halve_tuple!(A a a0 a1, B b b0 b1, C c c0 c1, D d d0 d1);
halve_tuple!(A a a0 a1, B b b0 b1, C c c0 c1, D d d0 d1, E e e0 e1);

/// The one helper for element-wise passes over two halves: `f(base, d)`
/// on the whole data `d` (elements `0 .. len`, `base` = 0), or with
/// `parallel` on its two halves (cut at `len / 2`, fixed by the length,
/// never by the thread count; `base` = the half's first element index)
/// through [`join_if`], the two results merged by `merge(low, high)`. Each
/// half is sequential inside and writes only its own elements, so with an
/// order-free merge (max, and, unit) the results do not depend on
/// `parallel` or on the thread count.
pub(crate) fn split_pass<D: Halve + Send, T: Send>(
    parallel: bool,
    len: usize,
    d: D,
    f: impl Fn(usize, D) -> T + Sync,
    merge: impl FnOnce(T, T) -> T,
) -> T {
    if !parallel {
        return f(0, d);
    }
    let k = len / 2;
    let (lo, hi) = d.halve(k);
    let (a, b) = join_if(true, || f(0, lo), || f(k, hi));
    merge(a, b)
}

/// Two element-wise passes in one hand-over: `f(base, d)` over `d` (`len`
/// elements) and `g(base, e)` over `e` (`len_e` elements; a Newton
/// update of the coordinates and of the multipliers), whole on this
/// thread, or with `parallel` each cut at its own middle (`len / 2`,
/// `len_e / 2`) and the two low halves run on one thread, the two high
/// halves on the other, through one [`join_if`]: the same halves as two
/// [`split_pass`] calls with one join instead of two. `f`'s results are
/// merged by `merge`; `g`'s are unit. Each half writes only its own
/// elements, so with an order-free merge the results do not depend on
/// `parallel` or on the thread count.
pub(crate) fn split_passes<D: Halve + Send, E: Halve + Send, T: Send>(
    parallel: bool,
    (len, d, f): (usize, D, impl Fn(usize, D) -> T + Sync),
    (len_e, e, g): (usize, E, impl Fn(usize, E) + Sync),
    merge: impl FnOnce(T, T) -> T,
) -> T {
    if !parallel {
        let t = f(0, d);
        g(0, e);
        return t;
    }
    let (k, ke) = (len / 2, len_e / 2);
    let ((d0, d1), (e0, e1)) = (d.halve(k), e.halve(ke));
    let (f, g) = (&f, &g);
    let (a, b) = join_if(
        true,
        || {
            let t = f(0, d0);
            g(0, e0);
            t
        },
        || {
            let t = f(k, d1);
            g(ke, e1);
            t
        },
    );
    merge(a, b)
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

impl<const W: usize, const R: usize> Halve for Slices<'_, W, R> {
    fn halve(self, k: usize) -> (Self, Self) {
        let (w0, w1) = self.w.halve(k);
        let (r0, r1) = self.r.halve(k);
        let lo = Slices {
            base: self.base,
            w: w0,
            r: r0,
        };
        let hi = Slices {
            base: self.base + k,
            w: w1,
            r: r1,
        };
        (lo, hi)
    }
}

/// An element-wise pass `f` over `s` (of `len` coordinates): whole, or
/// with `parallel` on its two halves ([`split_pass`]), the two results
/// merged by `merge`. With an order-free merge (max, and) the results do
/// not depend on `parallel` or the thread count.
pub(crate) fn in_halves<const W: usize, const R: usize, T: Send>(
    parallel: bool,
    len: usize,
    s: Slices<'_, W, R>,
    f: impl Fn(Slices<'_, W, R>) -> T + Sync,
    merge: impl FnOnce(T, T) -> T,
) -> T {
    split_pass(parallel, len, s, |_, s| f(s), merge)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `run(false)` (a pass in one piece) on this thread and `run(true)`
    /// (in halves) on a pool of two threads, for a comparison of their
    /// bits.
    fn in_one_piece_and_in_halves<R: Send>(run: impl Fn(bool) -> R + Sync) -> (R, R) {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        (run(false), pool.install(|| run(true)))
    }

    /// [`split_pass`] over a tuple of an array of written slices and a
    /// read slice, on two threads of a pool: each half sees its own
    /// elements with its global base index, writes only them, and the
    /// merged result and every written bit equal the pass in one piece.
    #[test]
    fn split_pass_halves_match_one_piece() {
        let len = 1001;
        let src: Vec<f64> = (0..len).map(|i| (i as f64 * 0.37).sin()).collect();
        let pass = |base: usize, (out, x): ([&mut [f64]; 2], &[f64])| {
            let [a, b] = out;
            let mut big = 0.0_f64;
            for k in 0..x.len() {
                a[k] = x[k] * (base + k) as f64;
                b[k] = x[k].exp();
                big = big.max(a[k].abs());
            }
            (big, x.len())
        };
        let run = |parallel: bool| {
            let (mut a, mut b) = (vec![0.0; len], vec![0.0; len]);
            let r = split_pass(
                parallel,
                len,
                ([&mut a[..], &mut b[..]], &src[..]),
                pass,
                |(m0, n0), (m1, n1)| (m0.max(m1), n0 + n1),
            );
            (r, a, b)
        };
        let (one, two) = in_one_piece_and_in_halves(run);
        assert_eq!(one.0 .1, len);
        assert_eq!(two.0 .1, len);
        assert_eq!(one.0 .0.to_bits(), two.0 .0.to_bits());
        for (x, y) in one.1.iter().zip(&two.1).chain(one.2.iter().zip(&two.2)) {
            assert_eq!(x.to_bits(), y.to_bits());
        }
        // the high half used its global indices
        assert_eq!(two.1[len - 1], src[len - 1] * (len - 1) as f64);
    }

    /// [`split_passes`] over a pass of 1001 elements and one of 600, on
    /// two threads of a pool: each pass sees its halves with their global
    /// base index (cut at its own middle), and every written bit and the
    /// merged result equal the two passes in one piece each.
    #[test]
    fn split_passes_match_two_passes_in_one_piece() {
        let (len, len_e) = (1001, 600);
        let src: Vec<f64> = (0..len).map(|i| (i as f64 * 0.37).sin()).collect();
        let run = |parallel: bool| {
            let (mut a, mut e) = (vec![0.0; len], vec![0.0; len_e]);
            let big = split_passes(
                parallel,
                (
                    len,
                    (&mut a[..], &src[..]),
                    |base: usize, (a, x): (&mut [f64], &[f64])| {
                        let mut big = 0.0_f64;
                        for k in 0..x.len() {
                            a[k] = x[k] * (base + k) as f64;
                            big = big.max(a[k].abs());
                        }
                        big
                    },
                ),
                (len_e, &mut e[..], |base: usize, e: &mut [f64]| {
                    for (k, v) in e.iter_mut().enumerate() {
                        *v = ((base + k) as f64).sqrt();
                    }
                }),
                f64::max,
            );
            (big, a, e)
        };
        let (one, two) = in_one_piece_and_in_halves(run);
        assert_eq!(one.0.to_bits(), two.0.to_bits());
        let expected = (0..len).fold(0.0_f64, |m, k| m.max((src[k] * k as f64).abs()));
        assert_eq!(two.0, expected);
        for (x, y) in one.1.iter().zip(&two.1).chain(one.2.iter().zip(&two.2)) {
            assert_eq!(x.to_bits(), y.to_bits());
        }
        // the high halves used their global indices
        assert_eq!(two.1[len - 1], src[len - 1] * (len - 1) as f64);
        assert_eq!(two.2[len_e - 1], ((len_e - 1) as f64).sqrt());
        assert_eq!(two.2[len_e / 2], ((len_e / 2) as f64).sqrt());
    }
}
