//! Model check of the two-thread team's hand-over protocol
//! (`src/parallel/handover.rs` of mbsolve, included here) with `loom`:
//! every interleaving of the caller's and the helper's atomics, park and
//! unpark calls up to loom's preemption bound, with loom checking the
//! accesses to the job and panic slots for data races.
//!
//! ```text
//! RUSTFLAGS="--cfg loom" LOOM_MAX_PREEMPTIONS=3 CARGO_TARGET_DIR=target/loom \
//!     cargo test --release -p mbsolve-loom
//! ```
//!
//! Without `--cfg loom` the same tests run on std's primitives.

#[path = "../../src/parallel/handover.rs"]
#[allow(dead_code)]
// The file's docs link to its private constants, which only the main
// crate's private docs show.
#[allow(rustdoc::private_intra_doc_links)]
pub mod handover;

#[cfg(test)]
mod tests {
    use super::handover::{Handover, Ran};

    #[cfg(loom)]
    use loom::{model, sync::Arc, thread};
    #[cfg(not(loom))]
    use std::{sync::Arc, thread};
    #[cfg(not(loom))]
    fn model(f: impl Fn() + Sync + Send + 'static) {
        for _ in 0..200 {
            f()
        }
    }

    /// Two joins and a stop against a running helper: each half runs once,
    /// its result reaches the caller, the helper ends.
    #[test]
    fn two_joins_and_a_stop() {
        model(|| {
            let h = Arc::new(Handover::new());
            let helper = {
                let h = h.clone();
                thread::spawn(move || h.helper_loop())
            };
            let mut ran = Vec::new();
            for k in 0..2u32 {
                let ((a, b), r) = h.join(|| k, || k + 10);
                assert_eq!((a, b), (k, k + 10));
                ran.push(r);
            }
            h.stop();
            helper.join().unwrap();
            // whichever side ran a half, it ran exactly once (the
            // `expect`s inside `join` and the results above)
            assert_eq!(ran.len(), 2);
        });
    }

    /// A half that writes through its borrow: the caller reads the write
    /// after the join, whichever thread ran it (loom flags a race).
    #[test]
    fn a_half_writing_caller_data() {
        model(|| {
            let h = Arc::new(Handover::new());
            let helper = {
                let h = h.clone();
                thread::spawn(move || h.helper_loop())
            };
            let mut x = 0u64;
            let (_, ran) = h.join(|| (), || x = 7);
            assert_eq!(x, 7);
            assert!(matches!(ran, Ran::Helper | Ran::TakenBack { .. }));
            h.stop();
            helper.join().unwrap();
        });
    }

    /// A panic in the helper's half reaches the caller, and the hand-over
    /// serves the next join.
    #[test]
    fn a_panic_on_the_helper_reaches_the_caller() {
        model(|| {
            let h = Arc::new(Handover::new());
            let helper = {
                let h = h.clone();
                thread::spawn(move || h.helper_loop())
            };
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                h.join(|| 1, || -> u32 { panic!("b") })
            }));
            assert!(r.is_err());
            let ((a, b), _) = h.join(|| 2, || 3);
            assert_eq!((a, b), (2, 3));
            h.stop();
            helper.join().unwrap();
        });
    }
}
