//! The stiff chain of `../shared/peers/` with radau5 (and generalized-α)
//! at given fixed steps: tip x at t_end, error against the peers'
//! reference, steps, Newton iterations, factorisations, CPU seconds; one
//! JSON line per run.
//!
//! ```text
//! cargo run --release --example radau_chain -- N [radau5:H[:TOL] | genalpha:H[:TOL] | aradau5:RTOL[:TOL] ...]
//! ```
//! `aradau5:RTOL`: radau5 with adaptive steps at `rtol` (`atol` =
//! 1e-3·rtol, `MBS_ATOL` overrides); `h` in the output line is then rtol;
//! `radau9:H`, `aradau9:RTOL` the same with radau9; `radau59:RTOL`
//! radau59 (always adaptive). The line also gives radau59's steps at
//! order 9 and changes of order.
//! `tip_bits`: the tip's bits in hex, `q_hash`: an FNV-1a hash of the
//! bits of the coordinates q at `t_end`, to compare runs bit for bit.
//! `TOL`: `integrator.newton_tol` (m/s²) of that run; `MBS_NEWTON_TOL`
//! sets it for the runs without one. `MBS_T_END` (s, default 0.1).
//! The stiff-chain comparisons of docs/radau.md run `radau5:4e-4:1`.

use mbsolve::builders::{stiff_chain, stiff_chain_reference_tip, stiff_chain_tip_x};
use mbsolve::integrate::Method;
use mbsolve::simulation::{simulate, RunConfig};

mod common;
use common::{cpu_seconds, in_pool};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(n) = args.first().and_then(|a| a.parse::<usize>().ok()) else {
        eprintln!("usage: radau_chain N [radau5:H | genalpha:H ...]");
        std::process::exit(2);
    };
    let t_end: f64 = std::env::var("MBS_T_END")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.1);
    let (sys, q0, qd0, info) = stiff_chain(n, 5f64.to_radians()).expect("valid chain");
    let reference = if t_end == 0.1 {
        stiff_chain_reference_tip(n)
    } else {
        None
    };
    for spec in &args[1..] {
        let mut parts = spec.split(':');
        let (Some(name), Some(value)) = (parts.next(), parts.next()) else {
            panic!("{spec}: expected METHOD:H[:TOL]");
        };
        let adaptive = name.starts_with("aradau");
        let method: Method = name
            .trim_start_matches('a')
            .parse()
            .unwrap_or_else(|e| panic!("{spec}: {e}"));
        let h: f64 = value.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
        let tol: Option<f64> = parts
            .next()
            .map(|t| t.parse().unwrap_or_else(|e| panic!("{spec}: {e}")));
        let mut cfg = RunConfig {
            method,
            t_end,
            output_dt: t_end,
            ..Default::default()
        };
        if adaptive || method.is_adaptive() {
            cfg.implicit.adaptive = !method.is_adaptive();
            cfg.ode.rtol = h;
            cfg.ode.atol = mbsolve::integrate::Tolerance::Scalar(
                std::env::var("MBS_ATOL")
                    .ok()
                    .and_then(|v| v.parse().ok())
                    .unwrap_or(1e-3 * h),
            );
        } else {
            cfg.ode.fixed_step = Some(h);
        }
        cfg.ode.max_steps = 100_000_000;
        if let Some(t) = tol.or_else(|| {
            std::env::var("MBS_NEWTON_TOL")
                .ok()
                .and_then(|v| v.parse().ok())
        }) {
            cfg.implicit.newton_tol = t;
        }
        let c0 = cpu_seconds();
        let (traj, s) =
            in_pool(None, || simulate(&sys, &q0, &qd0, &cfg, &mut [])).expect("run starts");
        let cpu = cpu_seconds() - c0;
        let q = traj.q.last().expect("an output row");
        let tip = stiff_chain_tip_x(&info, q);
        let err = reference.map(|r| (tip - r).abs());
        let q_hash = q.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, x| {
            (h ^ x.to_bits()).wrapping_mul(0x0000_0100_0000_01b3)
        });
        let get = |k: &str| s.extra.get(k).cloned().unwrap_or_default();
        println!(
            "{{\"n\":{n},\"method\":\"{name}\",\"h\":{h},\"newton_tol\":{},\"status\":{:?},\"tip\":{tip:.10},\"tip_bits\":\"{:016x}\",\"q_hash\":\"{q_hash:016x}\",\"err\":{},\"steps\":{},\"newton_iterations\":{},\"factorizations\":{},\"newton_failures\":{},\"error_rejections\":{},\"steps_order9\":{},\"order_changes\":{},\"max_phi\":{:.3e},\"cpu\":{cpu:.3}}}",
            cfg.implicit.newton_tol,
            s.status,
            tip.to_bits(),
            err.map_or("null".into(), |e| format!("{e:.3e}")),
            s.steps,
            get("newton_iterations"),
            s.factorizations,
            get("newton_failures"),
            get("error_rejections"),
            get("steps_order9"),
            get("order_changes"),
            s.max_constraint_norm,
        );
        if std::env::var("MBS_VERBOSE").is_ok() {
            eprintln!(
                "{:?}\n{:?}",
                s.message,
                &s.warnings[..s.warnings.len().min(50)]
            );
        }
    }
}
