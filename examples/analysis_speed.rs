//! CPU time of the analyses at N = 1000 and 10 000 (and the slope of the
//! cost in N): the 10 lowest modes of the peers' stiff chain about its
//! static equilibrium and the chain's static equilibrium from its released
//! state (every segment at 5°).
//!
//! `cargo run --release --example analysis_speed [static|modes] [N …]`;
//! one JSON line per measurement; CPU seconds of the process
//! (`examples/common`), each the mean over enough repetitions to span at
//! least 0.5 s of CPU (the clock ticks in 10 ms). Under `valgrind
//! --tool=callgrind` the instruction counts of one call per N give a
//! slope that the machine's load cannot disturb.

mod common;

use common::cpu_seconds;
use mbsolve::analysis::{eigenmodes, static_equilibrium, ModeOptions, StaticOptions, Tangent};
use mbsolve::builders::stiff_chain;

/// Mean CPU seconds of `f` over repetitions spanning at least `min_cpu`
/// seconds (at most `max_reps`), and the last result.
fn timed<R>(min_cpu: f64, max_reps: usize, mut f: impl FnMut() -> R) -> (f64, usize, R) {
    let c0 = cpu_seconds();
    let mut reps = 0;
    loop {
        let r = f();
        reps += 1;
        let spent = cpu_seconds() - c0;
        if spent >= min_cpu || reps >= max_reps {
            return (spent / reps as f64, reps, r);
        }
    }
}

fn main() {
    let mut what = "all".to_string();
    let mut ns: Vec<usize> = Vec::new();
    for a in std::env::args().skip(1) {
        match a.parse() {
            Ok(n) => ns.push(n),
            Err(_) => what = a,
        }
    }
    if ns.is_empty() {
        ns = vec![1000, 10_000];
    }
    // one call per N under callgrind (MBSOLVE_ONCE set): the instruction
    // count is the measure there
    let once = std::env::var_os("MBSOLVE_ONCE").is_some();
    let (min_cpu, max_reps) = if once { (0.0, 1) } else { (0.5, 1000) };
    let mut rows = Vec::new();
    for &n in &ns {
        let (sys, q0, _, _) = stiff_chain(n, 5f64.to_radians()).expect("the stiff chain");
        let mut t_static = f64::NAN;
        let mut t_modes = f64::NAN;
        let (teq, reps, eq) = timed(min_cpu, max_reps, || {
            static_equilibrium(&sys, &q0, StaticOptions::default()).expect("an equilibrium")
        });
        if what != "modes" {
            t_static = teq;
            println!(
                "{{\"case\":\"stiff_chain_static\",\"n\":{n},\"reps\":{reps},\"cpu_s\":{teq:.5},\
                 \"load_steps\":{},\"newton\":{},\"residual\":{:.3e}}}",
                eq.load_steps, eq.iterations, eq.residual
            );
        }
        if what != "static" {
            let mut tan = Tangent::new(&sys);
            tan.evaluate(0.0, &eq.q, &vec![0.0; eq.q.len()], &eq.lambda)
                .expect("tangent");
            let opts = ModeOptions {
                count: 10,
                ..Default::default()
            };
            let (tm, reps, modes) =
                timed(min_cpu, max_reps, || eigenmodes(&tan, opts).expect("modes"));
            t_modes = tm;
            let f: Vec<f64> = modes.modes.iter().map(|m| m.frequency_hz).collect();
            println!(
                "{{\"case\":\"stiff_chain_modes\",\"n\":{n},\"reps\":{reps},\"cpu_s\":{tm:.5},\
                 \"lanczos_steps\":{},\"converged\":{},\"f1_hz\":{:.6},\"f10_hz\":{:.4}}}",
                modes.lanczos_steps,
                modes.converged,
                f[0],
                f[f.len() - 1]
            );
        }
        rows.push((n as f64, t_static, t_modes));
    }
    if rows.len() >= 2 {
        let (a, b) = (rows[0], rows[rows.len() - 1]);
        let slope = |x: f64, y: f64| (y / x).ln() / (b.0 / a.0).ln();
        println!(
            "{{\"slope_static\":{:.3},\"slope_modes\":{:.3}}}",
            slope(a.1, b.1),
            slope(a.2, b.2)
        );
    }
}
