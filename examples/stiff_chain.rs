//! The cantilevered stiff chain of `../shared/peers/`, run the way the
//! peer scripts run it: one JSON line per method with the tip x at
//! t = 0.1 s, its error against `stiff_chain_reference_tip`, steps,
//! Newton iterations and failures, wall and CPU seconds.
//!
//! ```text
//! cargo run --release --example stiff_chain -- N [genalpha:H | hht:H | radau5:H | rk4:H | bdf:RTOL | ode45:RTOL ...]
//! ```
//!
//! The α family, radau5 and rk4 take the fixed step H; the others RTOL
//! (atol = 1e-3 RTOL).

use mbsolve::builders::{stiff_chain, stiff_chain_reference_tip, stiff_chain_tip_x};
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::simulation::{simulate, RunConfig};
use std::time::Instant;

mod common;
use common::{cpu_seconds, in_pool};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(n) = args.first().and_then(|a| a.parse::<usize>().ok()) else {
        eprintln!("usage: stiff_chain N [genalpha:H | hht:H | ode45:RTOL | ode23:RTOL ...]");
        std::process::exit(2);
    };
    let specs: Vec<String> = if args.len() > 1 {
        args[1..].to_vec()
    } else {
        vec!["genalpha:1e-5".into()]
    };
    let (sys, q0, qd0, info) = stiff_chain(n, 5f64.to_radians()).expect("valid chain");
    let reference = stiff_chain_reference_tip(n);
    for spec in specs {
        let (name, value) = spec.split_once(':').unwrap_or((spec.as_str(), "1e-5"));
        let method: Method = name.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
        let value: f64 = value.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
        let mut cfg = RunConfig {
            method,
            t_end: 0.1,
            output_dt: 0.1,
            ..Default::default()
        };
        if method.is_generalized_alpha() || matches!(method, Method::Rk4 | Method::Radau5) {
            cfg.ode.fixed_step = Some(value);
        } else {
            cfg.ode.rtol = value;
            cfg.ode.atol = Tolerance::Scalar(value * 1e-3);
        }
        cfg.ode.max_steps = 100_000_000;
        // settings to experiment with: MBS_NEWTON_TOL (m/s²), MBS_EXTRAPOLATE (0/1),
        // MBS_RHO_INF, MBS_SPARSE (faer's LDLᵀ instead of the chain solver), MBS_T_END (s),
        // MBS_VERBOSE (the summary's message and warnings on stderr), MBS_NOREUSE (a
        // factorisation at every Newton iteration: exact Newton), MBS_FORMULATION (the
        // scenario key `formulation`, e.g. `augmented_lagrangian` with genalpha)
        if let Some(t) = std::env::var("MBS_NEWTON_TOL")
            .ok()
            .and_then(|v| v.parse().ok())
        {
            cfg.implicit.newton_tol = t;
        }
        if let Ok(v) = std::env::var("MBS_EXTRAPOLATE") {
            cfg.implicit.extrapolate = v != "0";
        }
        if std::env::var("MBS_NOREUSE").is_ok() {
            cfg.implicit.reuse = false;
        }
        if let Ok(v) = std::env::var("MBS_FORMULATION") {
            cfg.formulation.formulation = v.parse().unwrap_or_else(|e| panic!("{v}: {e}"));
        }
        if std::env::var("MBS_SPARSE").is_ok() {
            cfg.formulation.linear_solver = mbsolve::linalg::SolverKind::Sparse;
        }
        if let Some(t) = std::env::var("MBS_T_END").ok().and_then(|v| v.parse().ok()) {
            cfg.t_end = t;
            cfg.output_dt = t;
        }
        let (cpu0, wall0) = (cpu_seconds(), Instant::now());
        let (traj, s) =
            in_pool(None, || simulate(&sys, &q0, &qd0, &cfg, &mut [])).expect("run starts");
        let (cpu, wall) = (cpu_seconds() - cpu0, wall0.elapsed().as_secs_f64());
        let tip = traj.q.last().map(|q| stiff_chain_tip_x(&info, q));
        let get = |k: &str| s.extra.get(k).cloned().unwrap_or(serde_json::Value::Null);
        let line = serde_json::json!({
            "n": n,
            "method": name,
            "h_or_rtol": value,
            "status": s.status,
            "t_reached": s.t_reached,
            "tip_x": tip,
            // the reference is the tip at t = 0.1 s
            "tip_error": tip
                .zip(reference.filter(|_| cfg.t_end == 0.1))
                .map(|(x, r)| x - r),
            "steps": s.steps,
            "factorizations": s.factorizations,
            "failed_steps": s.failed_steps,
            "newton_iterations": get("newton_iterations"),
            "newton_failures": get("newton_failures"),
            "newton_per_step": get("newton_iterations").as_f64().map(|i| i / s.steps.max(1) as f64),
            "max_constraint_norm": s.max_constraint_norm,
            "wall_s": wall,
            "cpu_s": cpu,
        });
        println!("{line}");
        if std::env::var("MBS_VERBOSE").is_ok() {
            eprintln!("{:?}", s.message);
            for w in &s.warnings {
                eprintln!("{w}");
            }
        }
    }
}
