//! One run of the stiff chain for the two-thread table of docs/scaling.md
//! (`scripts/threads_table.sh` runs it): the chain of `N` segments with
//! one of the issue's three settings, in a rayon pool of `THREADS`
//! threads, thread setting `auto`; prints one JSON line with the wall and
//! CPU seconds of the run, the tip's bits and what the two-thread team did.
//!
//! ```text
//! cargo run --release --example threads_table -- N radau5|ndf|genalpha T_END THREADS
//! ```
//!
//! radau5: h = 4e-4, `newton_tol` = 1; ndf: rtol 1e-5, atol 1e-8, order
//! ≤ 3; genalpha: h = 1e-5.

use mbsolve::builders::{stiff_chain, stiff_chain_tip_x};
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::simulation::{simulate, RunConfig};
use std::time::Instant;

mod common;
use common::{cpu_seconds, in_pool};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = || -> ! {
        eprintln!("usage: threads_table N radau5|ndf|genalpha T_END THREADS");
        std::process::exit(2)
    };
    if args.len() != 4 {
        usage();
    }
    let n: usize = args[0].parse().unwrap_or_else(|_| usage());
    let t_end: f64 = args[2].parse().unwrap_or_else(|_| usage());
    let threads: usize = args[3].parse().unwrap_or_else(|_| usage());
    let mut cfg = RunConfig {
        t_end,
        output_dt: t_end,
        ..Default::default()
    };
    cfg.ode.max_steps = 100_000_000;
    match args[1].as_str() {
        "radau5" => {
            cfg.method = Method::Radau5;
            cfg.ode.fixed_step = Some(4e-4);
            cfg.implicit.newton_tol = 1.0;
        }
        "ndf" => {
            cfg.method = Method::Bdf;
            cfg.ode.ndf = true;
            cfg.ode.max_order = 3;
            cfg.ode.rtol = 1e-5;
            cfg.ode.atol = Tolerance::Scalar(1e-8);
        }
        "genalpha" => {
            cfg.method = Method::GenAlpha;
            cfg.ode.fixed_step = Some(1e-5);
        }
        _ => usage(),
    }
    let (sys, q0, qd0, info) = stiff_chain(n, 5f64.to_radians()).expect("valid chain");
    let (cpu0, wall0) = (cpu_seconds(), Instant::now());
    let (traj, s) =
        in_pool(Some(threads), || simulate(&sys, &q0, &qd0, &cfg, &mut [])).expect("run starts");
    let (cpu, wall) = (cpu_seconds() - cpu0, wall0.elapsed().as_secs_f64());
    let tip = traj.q.last().map(|q| stiff_chain_tip_x(&info, q));
    let get = |k: &str| s.extra.get(k).cloned().unwrap_or(serde_json::Value::Null);
    let line = serde_json::json!({
        "n": n,
        "method": args[1],
        "threads": threads,
        "status": s.status,
        "t_reached": s.t_reached,
        "tip_bits": tip.map(|x| format!("{:016x}", x.to_bits())),
        "steps": s.steps,
        "wall_s": wall,
        "cpu_s": cpu,
        "threads_used": get("threads"),
        "halves_split": get("halves_split"),
        "halves_taken_back": get("halves_taken_back"),
        "halves_taken_back_awake": get("halves_taken_back_awake"),
        "threads_passes": get("threads_passes"),
        "caller_parks": get("threads_caller_parks"),
        "helper_wakes": get("threads_helper_wakes"),
        "newton_iterations": get("newton_iterations"),
        "halves_solo": get("halves_solo"),
        "threads_rule": get("threads_rule"),
        "threads_clock": get("threads_clock"),
    });
    println!("{line}");
}
