//! Accuracy against work of the adaptive implicit methods on the stiff
//! chain of `../shared/peers/`: for each `METHOD:RTOL` one JSON line with
//! the tip x error at t = 0.1 s against the peers' reference
//! (`stiff_chain_reference_tip`), the error in units of rtol, steps,
//! Newton iterations per step, factorisations, failed steps and CPU
//! seconds.
//!
//! ```text
//! cargo run --release --example stiff_chain_rtol -- N [bdf:RTOL[:MAXORDER] | ndf:RTOL[:MAXORDER] | genalpha:RTOL ...]
//! ```
//!
//! `ndf` is bdf with `integrator.ndf = true` (ode15s's NDF), `MAXORDER`
//! its `integrator.max_order` (default 5); `genalpha:RTOL` is adaptive
//! generalized-α (ρ∞ = 0.9 as the fixed-step runs of
//! `examples/stiff_chain.rs`); `atol = 1e-3 rtol` for all unless env
//! `MBS_ATOL` gives it. Env `MBS_T_END` ends the run earlier (no
//! reference then).

use mbsolve::builders::{stiff_chain, stiff_chain_reference_tip, stiff_chain_tip_x};
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::simulation::{simulate, RunConfig};

mod common;
use common::{cpu_seconds, in_pool};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(n) = args.first().and_then(|a| a.parse::<usize>().ok()) else {
        eprintln!("usage: stiff_chain_rtol N [bdf:RTOL[:MAXORDER] | ndf:RTOL[:MAXORDER] | genalpha:RTOL ...]");
        std::process::exit(2);
    };
    let specs: Vec<String> = if args.len() > 1 {
        args[1..].to_vec()
    } else {
        ["bdf:1e-3", "bdf:1e-5", "bdf:1e-7"]
            .map(String::from)
            .to_vec()
    };
    let (sys, q0, qd0, info) = stiff_chain(n, 5f64.to_radians()).expect("valid chain");
    let t_end: f64 = std::env::var("MBS_T_END")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.1);
    let reference = stiff_chain_reference_tip(n).filter(|_| t_end == 0.1);
    // MBS_ATOL: an absolute tolerance instead of 1e-3 rtol
    let atol_factor: Option<f64> = std::env::var("MBS_ATOL").ok().and_then(|v| v.parse().ok());
    for spec in specs {
        let parts: Vec<&str> = spec.split(':').collect();
        let (name, value) = match parts[..] {
            [name, value] | [name, value, _] => (name, value),
            _ => {
                eprintln!("{spec}: expected METHOD:RTOL[:MAXORDER]");
                std::process::exit(2);
            }
        };
        let ndf = name == "ndf";
        let method: Method = if ndf { "bdf" } else { name }
            .parse()
            .unwrap_or_else(|e| panic!("{spec}: {e}"));
        let rtol: f64 = value.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
        let mut cfg = RunConfig {
            method,
            t_end,
            output_dt: t_end,
            ..Default::default()
        };
        cfg.ode.ndf = ndf;
        if let Some(k) = parts.get(2) {
            cfg.ode.max_order = k.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
        }
        cfg.ode.rtol = rtol;
        cfg.ode.atol = Tolerance::Scalar(atol_factor.map_or(rtol * 1e-3, |a| a));
        cfg.ode.max_steps = 100_000_000;
        cfg.ode.initial_step = std::env::var("H5_H0").ok().and_then(|v| v.parse().ok());
        if method.is_generalized_alpha() {
            cfg.implicit.adaptive = true;
            cfg.implicit.rho_inf = 0.9;
        }
        let cpu0 = cpu_seconds();
        let (traj, s) =
            in_pool(None, || simulate(&sys, &q0, &qd0, &cfg, &mut [])).expect("run starts");
        let cpu = cpu_seconds() - cpu0;
        let tip = traj.q.last().map(|q| stiff_chain_tip_x(&info, q));
        let err = tip.zip(reference).map(|(x, r)| x - r);
        let get = |k: &str| s.extra.get(k).cloned().unwrap_or(serde_json::Value::Null);
        let line = serde_json::json!({
            "n": n,
            "method": name,
            "rtol": rtol,
            "max_order": cfg.ode.max_order,
            "atol": format!("{:?}", cfg.ode.atol),
            "status": s.status,
            "t_reached": s.t_reached,
            "tip_x": tip,
            "tip_error": err,
            "error_over_rtol": err.map(|e| e.abs() / rtol),
            "steps": s.steps,
            "failed_steps": s.failed_steps,
            "newton_failures": get("newton_failures"),
            "error_rejections": get("error_rejections"),
            "newton_iterations": get("newton_iterations"),
            "newton_per_step": get("newton_iterations").as_f64().map(|i| i / s.steps.max(1) as f64),
            "factorizations": s.factorizations,
            "steps_at_order": get("steps_at_order"),
            "cpu_s": cpu,
        });
        println!("{line}");
    }
}
