//! The stiff chain's tip x over the whole run against a fine reference
//! run: the largest error over the output rows, where it occurs, and the
//! error at t_end — the error at 0.1 s alone is one sample of an
//! oscillating error (docs/radau.md, "The error over the run").
//!
//! ```text
//! cargo run --release --example stiff_chain_series -- N DT REF SPEC ...
//! ```
//! `DT`: output interval \[s\]; `REF` and each `SPEC`: radau5 as
//! `f:H[:TOL]` (fixed step H, `newton_tol` TOL), `a:RTOL[:TOL]` (adaptive,
//! `atol` = 1e-3·rtol, `MBS_ATOL_RATIO` overrides the 1e-3) or ode45 as `e:RTOL`; `f9:`, `a9:` the same with
//! radau9, `a59:RTOL` radau59. The reference `f:2.5e-5:1e-4`
//! (its agreement with `f:1.25e-5:1e-4`: docs/radau.md). `DUMP_REF=path`
//! writes the reference's tip x per row as a JSON array (for
//! `benches/peers/exudyn_tip_series.py`). `MBS_T_END` (s, default 0.1).
//! `MBS_FROM` (s, default 0): the line also gives the largest error from
//! that time on (after a fixed step's start). With the same step and a
//! tight `TOL` as the reference, the errors are the Newton remainders'.

use mbsolve::builders::{stiff_chain, stiff_chain_tip_x};
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::simulation::{simulate, RunConfig};

/// Tip x per output row and the run's counters of one spec.
fn run(n: usize, spec: &str, dt: f64, t_end: f64) -> (Vec<f64>, String) {
    let (sys, q0, qd0, info) = stiff_chain(n, 5f64.to_radians()).expect("valid chain");
    let mut p = spec.split(':');
    let (Some(kind), Some(value)) = (p.next(), p.next()) else {
        panic!("{spec}: expected f:H[:TOL], a:RTOL[:TOL] or e:RTOL");
    };
    let v: f64 = value.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
    // the kind's letter, then the Radau IIA method: "" radau5, "9" radau9
    let (letter, order) = kind.split_at(kind.len().min(1));
    let method = match (letter, order) {
        ("e", "") => Method::Ode45,
        (_, "") => Method::Radau5,
        (_, o) => format!("radau{o}")
            .parse()
            .unwrap_or_else(|e| panic!("{spec}: {e}")),
    };
    let mut cfg = RunConfig {
        method,
        t_end,
        output_dt: dt,
        ..Default::default()
    };
    cfg.ode.max_steps = 100_000_000;
    match letter {
        "f" => cfg.ode.fixed_step = Some(v),
        "a" | "e" => {
            cfg.implicit.adaptive = letter == "a" && !method.is_adaptive();
            cfg.ode.rtol = v;
            let ratio = match letter {
                "a" => std::env::var("MBS_ATOL_RATIO")
                    .ok()
                    .and_then(|r| r.parse().ok())
                    .unwrap_or(1e-3),
                _ => 1e-3,
            };
            cfg.ode.atol = Tolerance::Scalar(ratio * v);
        }
        _ => panic!("{spec}: kind {kind} is not f, a or e"),
    }
    if let Some(t) = p.next() {
        cfg.implicit.newton_tol = t.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
    }
    let (tr, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).expect("run starts");
    let get = |k: &str| s.extra.get(k).cloned().unwrap_or_default();
    let counts = format!(
        "status {:?}, steps {}, Newton iterations {}, factorizations {}, rejected {}, Newton failures {}, steps at order 9 {}, order changes {}",
        s.status,
        s.steps,
        get("newton_iterations"),
        s.factorizations,
        get("error_rejections"),
        get("newton_failures"),
        get("steps_order9"),
        get("order_changes"),
    );
    let tips = tr.q.iter().map(|q| stiff_chain_tip_x(&info, q)).collect();
    (tips, counts)
}

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() < 3 {
        eprintln!("usage: stiff_chain_series N DT REF SPEC ...");
        std::process::exit(2);
    }
    let n: usize = a[0].parse().expect("N: a number of segments");
    let dt: f64 = a[1].parse().expect("DT: an output interval [s]");
    let t_end: f64 = std::env::var("MBS_T_END")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.1);
    let (r, counts) = run(n, &a[2], dt, t_end);
    println!("reference {}: {counts}", a[2]);
    if let Ok(path) = std::env::var("DUMP_REF") {
        let line: Vec<String> = r.iter().map(|v| format!("{v:.12e}")).collect();
        std::fs::write(&path, format!("[{}]", line.join(","))).expect("DUMP_REF writable");
    }
    for s in &a[3..] {
        let (x, counts) = run(n, s, dt, t_end);
        let e: Vec<f64> = x.iter().zip(&r).map(|(x, r)| x - r).collect();
        let (at, worst) =
            e.iter().enumerate().fold(
                (0, 0.0f64),
                |m, (i, v)| {
                    if v.abs() > m.1 {
                        (i, v.abs())
                    } else {
                        m
                    }
                },
            );
        let from: f64 = std::env::var("MBS_FROM")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(0.0);
        let late = e
            .iter()
            .enumerate()
            .filter(|(i, _)| *i as f64 * dt >= from - 1e-12)
            .fold(0.0f64, |m, (_, v)| m.max(v.abs()));
        println!(
            "{s}: largest tip error {worst:.2e} m at t = {:.3} s, from {from} s {late:.2e} m, at t_end {:.2e} m; {counts}",
            at as f64 * dt,
            e.last().copied().unwrap_or(f64::NAN)
        );
    }
}
