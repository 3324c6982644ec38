//! The falling rod of problem B (docs/problems.md, the builder behind
//! `[rod]`) at N segments, one JSON line per run (the rod's speed
//! comparisons and CPU slope from N = 1000 to 10 000 of docs/scaling.md):
//! steps, Newton iterations, factorisations, failures, CPU seconds, the time
//! of the first wall contact (a corner against a wall, [`ContactMonitor`])
//! and, with `MBS_TRACE=FILE`, the bottom end, middle joint and tip at every
//! output time written to FILE (one `t x_b y_b x_m y_m x_t y_t` line each),
//! so that two runs can be compared with the `compare` mode.
//!
//! ```text
//! cargo run --release --example falling_rod_speed -- N [genalpha:H | agenalpha:RTOL | bdf:RTOL ...]
//!     radau5:H fixed step, aradau5:RTOL adaptive radau5, auto:RTOL the
//!     method `integrator.method = "auto"` chooses for rtol = RTOL
//! cargo run --release --example falling_rod_speed -- compare RUN.txt REF.txt T_C
//!     max over output times t ≤ T_C of the largest of the three position
//!     differences (run against reference) [m]
//! cargo run --release --example falling_rod_speed -- slope METHOD:H_OR_RTOL N1 N2
//!     both runs, then the log-log slope of CPU per simulated second
//! ```
//!
//! Environment: `MBS_T_END` (s, default 1), `MBS_DT` (output step, default
//! 1e-3 s), `MBS_ATOL` (absolute tolerance of the adaptive runs, default
//! 1e-3·rtol), `MBS_MAX_STEP` (s, the adaptive runs' largest step), `MBS_FLIGHT_STEP` (s,
//! radau's `integrator.flight_step` with a fixed step), `MBS_VX` (m/s, the
//! initial horizontal velocity, default 0.1: a change of 1e-9 gives another
//! path through the contacts, for a sample of paths), `MBS_RHO_INF`, `MBS_EXTRAPOLATE` (1: `integrator.extrapolate`), `MBS_LU` (1: exact Newton with the sparse
//! LU of the full iteration matrix), `MBS_TRACE` (file), `MBS_THREADS` (the rayon
//! pool the run is installed in, default 1; CPU time counts every thread).

use mbsolve::builders::{build_rod, RodInfo, RodParams};
use mbsolve::events::ContactMonitor;
use mbsolve::integrate::{Method, Tolerance};
use mbsolve::simulation::{simulate_into, MethodChoice, Monitor, RunConfig, Sample, Sink};
use std::io::Write;
use std::time::Instant;

mod common;
use common::{cpu_seconds, in_pool};

/// Bottom end of segment 1, the joint at the middle of the rod and the top
/// end of segment N, as `[x_b, y_b, x_m, y_m, x_t, y_t]`.
fn marks(info: &RodInfo, q: &[f64]) -> [f64; 6] {
    let half = 0.5 * info.segment_length;
    // the end of body b at +s·half along its axis (the axis is (−sin φ, cos φ))
    let end = |b: usize, s: f64| {
        let (x, y, phi) = (q[3 * b], q[3 * b + 1], q[3 * b + 2]);
        [x - s * half * phi.sin(), y + s * half * phi.cos()]
    };
    let n = info.bodies.len();
    let b = end(info.bodies[0], -1.0);
    let m = end(info.bodies[n / 2], -1.0);
    let t = end(info.bodies[n - 1], 1.0);
    [b[0], b[1], m[0], m[1], t[0], t[1]]
}

/// Keeps only the three points at each output time.
struct Marks<'a> {
    info: &'a RodInfo,
    rows: Vec<(f64, [f64; 6])>,
}

impl Sink for Marks<'_> {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.rows.push((s.t, marks(self.info, s.q)));
        Ok(())
    }
}

fn read_trace(path: &str) -> Vec<(f64, [f64; 6])> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|x| x.parse().unwrap_or_else(|e| panic!("{path}: '{x}': {e}")))
                .collect();
            assert_eq!(v.len(), 7, "{path}: expected 7 columns in '{l}'");
            (v[0], [v[1], v[2], v[3], v[4], v[5], v[6]])
        })
        .collect()
}

/// Largest distance of any of the three points between `run` and `reference`
/// over the common output times up to `t_c`, and the number of times compared.
fn compare(run: &str, reference: &str, t_c: f64) -> (f64, usize) {
    let (a, b) = (read_trace(run), read_trace(reference));
    let mut worst = 0.0_f64;
    let mut count = 0;
    for (ra, rb) in a.iter().zip(&b) {
        if ra.0 > t_c {
            break;
        }
        assert!(
            (ra.0 - rb.0).abs() < 1e-9,
            "output times differ: {} vs {}",
            ra.0,
            rb.0
        );
        for k in 0..3 {
            let d = (ra.1[2 * k] - rb.1[2 * k]).hypot(ra.1[2 * k + 1] - rb.1[2 * k + 1]);
            worst = worst.max(d);
        }
        count += 1;
    }
    (worst, count)
}

fn env<T: std::str::FromStr>(key: &str) -> Option<T> {
    std::env::var(key).ok().and_then(|v| v.parse().ok())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("compare") {
        let (Some(a), Some(b), Some(tc)) = (
            args.get(1),
            args.get(2),
            args.get(3).and_then(|t| t.parse::<f64>().ok()),
        ) else {
            eprintln!("usage: falling_rod_speed compare RUN.txt REF.txt T_C");
            std::process::exit(2);
        };
        let (e, count) = compare(a, b, tc);
        println!(
            "{}",
            serde_json::json!({"run": a, "reference": b, "t_c": tc, "max_error": e, "outputs": count})
        );
        return;
    }
    if args.first().map(String::as_str) == Some("slope") {
        let (Some(spec), Some(n1), Some(n2)) = (
            args.get(1),
            args.get(2).and_then(|a| a.parse::<usize>().ok()),
            args.get(3).and_then(|a| a.parse::<usize>().ok()),
        ) else {
            eprintln!("usage: falling_rod_speed slope METHOD:H_OR_RTOL N1 N2");
            std::process::exit(2);
        };
        let per_s = |line: &serde_json::Value| {
            line["cpu_s"].as_f64().unwrap_or(f64::NAN)
                / line["t_reached"].as_f64().unwrap_or(f64::NAN)
        };
        let a = run(n1, spec);
        println!("{a}");
        let b = run(n2, spec);
        println!("{b}");
        let (ca, cb) = (per_s(&a), per_s(&b));
        println!(
            "{}",
            serde_json::json!({
                "spec": spec,
                "n": [n1, n2],
                "cpu_per_simulated_s": [ca, cb],
                "slope": (cb / ca).ln() / (n2 as f64 / n1 as f64).ln(),
            })
        );
        return;
    }
    let Some(n) = args.first().and_then(|a| a.parse::<usize>().ok()) else {
        eprintln!("usage: falling_rod_speed N [genalpha:H | agenalpha:RTOL | bdf:RTOL ...]");
        std::process::exit(2);
    };
    let specs: Vec<String> = if args.len() > 1 {
        args[1..].to_vec()
    } else {
        vec!["genalpha:5e-5".into()]
    };
    for spec in &specs {
        println!("{}", run(n, spec));
    }
}

/// One run of problem B at `n` segments with `spec` = `METHOD:H_OR_RTOL`:
/// its JSON line (and the trace file of `MBS_TRACE`).
fn run(n: usize, spec: &str) -> serde_json::Value {
    let mut params = RodParams::problem_b(n);
    if let Some(vx) = env("MBS_VX") {
        params.initial_velocity[0] = vx;
    }
    let (sys, info) = build_rod(&params).expect("problem B builds");
    let (q0, qd0) = sys.initial_state();
    let t_end = env("MBS_T_END").unwrap_or(1.0);
    let dt = env("MBS_DT").unwrap_or(1e-3);
    let Some((name, value)) = spec.split_once(':') else {
        eprintln!("{spec}: expected METHOD:H_OR_RTOL");
        std::process::exit(2);
    };
    let adaptive_ga = name == "agenalpha";
    let adaptive_radau = name == "aradau5";
    let auto = name == "auto";
    let method: Method = match name {
        "agenalpha" => "genalpha",
        "aradau5" => "radau5",
        // the method is chosen at t0; the index-1 defaults stand until then
        "auto" => "ode45",
        other => other,
    }
    .parse()
    .unwrap_or_else(|e| panic!("{spec}: {e}"));
    let value: f64 = value.parse().unwrap_or_else(|e| panic!("{spec}: {e}"));
    let mut cfg = RunConfig {
        method,
        t_end,
        output_dt: dt,
        ..Default::default()
    };
    cfg.ode.max_steps = 100_000_000;
    if (method.is_generalized_alpha() && !adaptive_ga && method == Method::GenAlpha)
        || method == Method::Rk4
        || (method == Method::Radau5 && !adaptive_radau)
    {
        cfg.ode.fixed_step = Some(value);
    } else {
        cfg.ode.rtol = value;
        cfg.ode.atol = Tolerance::Scalar(env("MBS_ATOL").unwrap_or(value * 1e-3));
        cfg.implicit.adaptive = adaptive_ga || adaptive_radau;
    }
    if auto {
        cfg.choice = MethodChoice::Auto;
    }
    if let Some(lu) = env::<u8>("MBS_LU") {
        cfg.implicit.lu = lu != 0;
    }
    if let Some(r) = env("MBS_RHO_INF") {
        cfg.implicit.rho_inf = r;
    }
    if let Some(x) = env::<u8>("MBS_EXTRAPOLATE") {
        cfg.implicit.extrapolate = x != 0;
    }
    if let Some(h) = env("MBS_MAX_STEP") {
        cfg.ode.max_step = Some(h);
    }
    if let Some(h) = env("MBS_FLIGHT_STEP") {
        cfg.implicit.flight_step = Some(h);
    }
    if let Some(t) = env("MBS_NEWTON_TOL") {
        cfg.implicit.newton_tol = t;
    }
    let mut mon = ContactMonitor::new(info.clone());
    let mut sink = Marks {
        info: &info,
        rows: Vec::new(),
    };
    let (cpu0, wall0) = (cpu_seconds(), Instant::now());
    let s = in_pool(Some(env("MBS_THREADS").unwrap_or(1)), || {
        simulate_into(
            &sys,
            &q0,
            &qd0,
            &cfg,
            &mut [&mut mon as &mut dyn Monitor],
            &mut sink,
        )
    })
    .expect("run starts");
    let (cpu, wall) = (cpu_seconds() - cpu0, wall0.elapsed().as_secs_f64());
    if let Ok(path) = std::env::var("MBS_TRACE") {
        let mut f = std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap_or_else(|e| panic!("{path}: {e}")),
        );
        for (t, m) in &sink.rows {
            writeln!(
                f,
                "{t:.9} {:.15e} {:.15e} {:.15e} {:.15e} {:.15e} {:.15e}",
                m[0], m[1], m[2], m[3], m[4], m[5]
            )
            .expect("trace written");
        }
    }
    let get = |k: &str| s.extra.get(k).cloned().unwrap_or(serde_json::Value::Null);
    let first = mon.events.first();
    serde_json::json!({
        "n": n,
        "method": name,
        "h_or_rtol": value,
        "status": s.status,
        "message": s.message,
        "t_reached": s.t_reached,
        "steps": s.steps,
        "failed_steps": s.failed_steps,
        "newton_iterations": get("newton_iterations"),
        "newton_failures": get("newton_failures"),
        "error_rejections": get("error_rejections"),
        "method_choice": get("method_choice"),
        "min_step_taken": get("min_step_taken"),
        "max_step_taken": get("max_step_taken"),
        "newton_per_step": get("newton_iterations").as_f64().map(|i| i / s.steps.max(1) as f64),
        "factorizations": s.factorizations,
        "first_contact_time": first.map(|e| e.t),
        "first_contact": first.map(|e| format!("segment {} corner {} {} wall", e.segment, e.corner, e.wall)),
        "contact_starts": mon.events.iter().filter(|e| e.kind == "start").count(),
        "tip": sink.rows.last().map(|r| [r.1[4], r.1[5]]),
        "max_constraint_norm": s.max_constraint_norm,
        "wall_s": wall,
        "cpu_s": cpu,
    })
}
