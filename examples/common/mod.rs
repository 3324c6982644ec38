//! Helpers shared by the stiff-chain examples.

/// CPU seconds of this process (user + system, from /proc; 0 elsewhere):
/// fields 14 and 15 of `/proc/self/stat`, in clock ticks of 10 ms.
#[allow(dead_code)] // not every example that includes this module reads it
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // the fields after the command name in parentheses
    let rest = stat.rsplit_once(')').map_or("", |r| r.1);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11).and_then(|u| u.parse().ok()).unwrap_or(0.0)
        + f.get(12).and_then(|s| s.parse().ok()).unwrap_or(0.0);
    ticks / 100.0
}

/// Runs `f` inside a rayon pool of `threads` threads (`None`: rayon's
/// default, `RAYON_NUM_THREADS` or one per core), so that the joins of the
/// parallel paths (above `PARALLEL_MIN_COORDS`) run inside the pool instead
/// of being handed from the main thread to the global pool and waited for
/// (ARCHITECTURE.md, "Concurrency"; stiff chain N = 10 000: 1 thread
/// 9.7 → 5.9 s, 2 threads 6.9 → 3.8 s wall).
#[allow(dead_code)] // not every example that includes this module runs a pool
pub fn in_pool<R: Send>(threads: Option<usize>, f: impl FnOnce() -> R + Send) -> R {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        b = b.num_threads(t);
    }
    b.build().expect("a thread pool").install(f)
}

/// CPU time of the calling thread \[s\] (`CLOCK_THREAD_CPUTIME_ID`,
/// nanoseconds: other processes' time and the 10 ms tick of the process
/// clock do not enter).
#[allow(dead_code)] // not every example that includes this module reads it
pub fn thread_cpu() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID)");
    ts.tv_sec as f64 + 1e-9 * ts.tv_nsec as f64
}
