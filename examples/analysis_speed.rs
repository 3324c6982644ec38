//! CPU time of the analyses at N = 1000 and 10 000 (and the slope of the
//! cost in N): the 10 lowest modes of the peers' stiff chain about its
//! static equilibrium, the chain's static equilibrium from its released
//! state (every segment at 5°), and the static attempt on the falling rod
//! without fluid and contact (a free rod under gravity: no equilibrium,
//! the time to the error).
//!
//! `cargo run --release --example analysis_speed [N …]`; one JSON line per
//! measurement. CPU seconds of the process (`examples/common`).

mod common;

use common::cpu_seconds;
use mbsolve::analysis::{eigenmodes, static_equilibrium, ModeOptions, StaticOptions, Tangent};
use mbsolve::builders::{build_rod, stiff_chain, RodParams};

fn main() {
    let ns: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let ns = if ns.is_empty() {
        vec![1000, 10_000]
    } else {
        ns
    };
    let mut rows = Vec::new();
    for &n in &ns {
        let (sys, q0, _, _) = stiff_chain(n, 5f64.to_radians()).expect("the stiff chain");
        // repeated below N = 10 000 so that each total spans many 10 ms
        // clock ticks; per-call CPU reported
        let reps = (10_000 / n).max(1);
        let c0 = cpu_seconds();
        let mut eq = None;
        for _ in 0..reps {
            eq = Some(
                static_equilibrium(&sys, &q0, StaticOptions::default()).expect("an equilibrium"),
            );
        }
        let eq = eq.expect("at least one repetition");
        let c1 = cpu_seconds();
        let mut tan = Tangent::new(&sys);
        tan.evaluate(0.0, &eq.q, &vec![0.0; eq.q.len()], &eq.lambda)
            .expect("tangent");
        let mut modes = None;
        for _ in 0..reps {
            modes = Some(
                eigenmodes(
                    &tan,
                    ModeOptions {
                        count: 10,
                        ..Default::default()
                    },
                )
                .expect("modes"),
            );
        }
        let modes = modes.expect("at least one repetition");
        let c2 = cpu_seconds();
        let (t_static, t_modes) = ((c1 - c0) / reps as f64, (c2 - c1) / reps as f64);
        let f: Vec<f64> = modes.modes.iter().map(|m| m.frequency_hz).collect();
        println!(
            "{{\"case\":\"stiff_chain\",\"n\":{n},\"reps\":{reps},\"static_cpu_s\":{:.4},\"load_steps\":{},\"newton\":{},\
             \"modes_cpu_s\":{:.4},\"lanczos_steps\":{},\"converged\":{},\"f1_hz\":{:.6},\"f10_hz\":{:.4}}}",
            t_static,
            eq.load_steps,
            eq.iterations,
            t_modes,
            modes.lanczos_steps,
            modes.converged,
            f[0],
            f[f.len() - 1]
        );
        let mut p = RodParams::problem_b(n);
        p.fluid = false;
        p.contact = false;
        let (rod, _) = build_rod(&p).expect("the rod");
        let (rq, _) = rod.initial_state();
        let c3 = cpu_seconds();
        let r = static_equilibrium(&rod, &rq, StaticOptions::default());
        let c4 = cpu_seconds();
        println!(
            "{{\"case\":\"falling_rod_no_fluid_no_contact\",\"n\":{n},\"static_cpu_s\":{:.3},\"result\":{:?}}}",
            c4 - c3,
            match r {
                Ok(_) => "equilibrium".to_string(),
                Err(e) => e.to_string(),
            }
        );
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
