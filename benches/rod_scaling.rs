//! Problem C (the falling rod of problem B (docs/problems.md) with N = 10 … 10 000
//! segments) through generalized-α on the index-3 equations.
//!
//! A plain `main` (harness = false) that times whole runs:
//!
//! ```text
//! cargo bench --bench rod_scaling                    # = slope
//! cargo bench --bench rod_scaling -- slope [h [span [reps]]]
//!     wall time per simulated second vs N at fixed h (best of reps)
//! cargo bench --bench rod_scaling -- full N h [t_end [rho_inf [newton_tol]]]
//!     runs at h and h/4: work, wall time, tip-position error
//! cargo bench --bench rod_scaling -- trace N h [t_end [rho_inf [newton_tol]]]
//!     runs at h, h/4, h/16: tip error over time (convergence study)
//! cargo bench --bench rod_scaling -- perturb N h [t_end [dx]]
//!     sensitivity of the dynamics to a rigid initial shift dx
//! cargo bench --bench rod_scaling -- ode23 [h]
//!     N = 10: genalpha at an accuracy-matched step vs ode23 (MATLAB defaults)
//! cargo bench --bench rod_scaling -- lu [N [h [span]]]
//!     Newton matrix: symmetrised LDLᵀ vs faer's sparse LU
//! ```
//!
//! Not part of CI: the `full` runs take minutes at N = 10 000.

use mbsolve::builders::{build_rod, RodInfo, RodParams};
use mbsolve::events::ContactMonitor;
use mbsolve::integrate::{ImplicitOptions, Method, OdeOptions, Tolerance};
use mbsolve::model::System;
use mbsolve::simulation::{simulate, Monitor, RunConfig, Summary, Trajectory};
use std::time::Instant;

fn rod(n: usize) -> (System, RodInfo) {
    build_rod(&RodParams::problem_b(n)).expect("problem C builds")
}

fn genalpha(h: f64, t_end: f64, dt: f64) -> RunConfig {
    genalpha_with(h, t_end, dt, ImplicitOptions::default())
}

fn genalpha_with(h: f64, t_end: f64, dt: f64, o: ImplicitOptions) -> RunConfig {
    RunConfig {
        method: Method::GenAlpha,
        t_end,
        output_dt: dt,
        ode: OdeOptions {
            fixed_step: Some(h),
            ..Default::default()
        },
        implicit: o,
        ..Default::default()
    }
}

fn run(sys: &System, info: &RodInfo, cfg: &RunConfig) -> (Trajectory, Summary) {
    let (q0, qd0) = sys.initial_state();
    let mut mon = ContactMonitor::new(info.clone());
    let (traj, s) =
        simulate(sys, &q0, &qd0, cfg, &mut [&mut mon as &mut dyn Monitor]).expect("run starts");
    (traj, s)
}

/// Top end of the top segment, at every output time.
fn tip(info: &RodInfo, traj: &Trajectory) -> Vec<[f64; 2]> {
    let b = *info.bodies.last().expect("segments");
    let half = 0.5 * info.segment_length;
    traj.q
        .iter()
        .map(|q| {
            let (x, y, phi) = (q[3 * b], q[3 * b + 1], q[3 * b + 2]);
            [x - half * phi.sin(), y + half * phi.cos()]
        })
        .collect()
}

fn tip_error(info: &RodInfo, a: &Trajectory, b: &Trajectory) -> f64 {
    let (ta, tb) = (tip(info, a), tip(info, b));
    ta.iter()
        .zip(&tb)
        .map(|(p, r)| ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2)).sqrt())
        .fold(0.0, f64::max)
}

fn line(label: &str, s: &Summary) {
    println!(
        "{label}: {} t = {:.4} s, steps {}, failed {}, Newton its {}, factorisations {}, \
         residuals {}, max ‖Φ‖ {:.2e}, contacts {}, wall {:.3} s{}",
        s.status,
        s.t_reached,
        s.steps,
        s.failed_steps,
        s.extra
            .get("newton_iterations")
            .cloned()
            .unwrap_or_default(),
        s.factorizations,
        s.rhs_evals,
        s.max_constraint_norm,
        s.extra.get("contact_starts").cloned().unwrap_or_default(),
        s.wall_s,
        s.message
            .as_ref()
            .map(|m| format!(" ({m})"))
            .unwrap_or_default()
    );
}

fn arg(args: &[String], i: usize, default: f64) -> f64 {
    args.get(i)
        .map(|s| s.parse().expect("a number"))
        .unwrap_or(default)
}

fn slope(args: &[String]) {
    let h = arg(args, 1, 1e-4);
    let span = arg(args, 2, 0.02);
    let reps = arg(args, 3, 3.0) as usize;
    println!("# wall time per simulated second, fixed h = {h:e}, t = 0 … {span} s, best of {reps}");
    let mut pts = Vec::new();
    for n in [10usize, 100, 1000, 3000, 10_000] {
        let (sys, info) = rod(n);
        let cfg = genalpha(h, span, span / 4.0);
        let mut best: Option<Summary> = None;
        for _ in 0..reps {
            let (_, s) = run(&sys, &info, &cfg);
            if best.as_ref().is_none_or(|b| s.wall_s < b.wall_s) {
                best = Some(s);
            }
        }
        let s = best.expect("reps ≥ 1");
        let per_s = s.wall_s / span;
        line(&format!("N = {n:5}"), &s);
        println!(
            "    wall per simulated second: {per_s:.3} s ({:.1} µs per step and segment)",
            1e6 * s.wall_s / s.steps as f64 / n as f64
        );
        pts.push((n as f64, per_s));
    }
    let fit = |a: (f64, f64), b: (f64, f64)| (b.1 / a.1).ln() / (b.0 / a.0).ln();
    println!(
        "log-log slope N = 1000 → 10 000: {:.3}   (100 → 1000: {:.3}, 3000 → 10 000: {:.3})",
        fit(pts[2], pts[4]),
        fit(pts[1], pts[2]),
        fit(pts[3], pts[4])
    );
}

fn full(args: &[String]) {
    let n = arg(args, 1, 1000.0) as usize;
    let h = arg(args, 2, 1e-4);
    let t_end = arg(args, 3, 1.0);
    let o = ImplicitOptions {
        rho_inf: arg(args, 4, ImplicitOptions::default().rho_inf),
        newton_tol: arg(args, 5, ImplicitOptions::default().newton_tol),
        ..Default::default()
    };
    let (sys, info) = rod(n);
    println!(
        "# N = {n}, t_end = {t_end} s, outputs every 1 ms, rho_inf = {}, newton_tol = {:e}",
        o.rho_inf, o.newton_tol
    );
    let start = Instant::now();
    let (a, sa) = run(&sys, &info, &genalpha_with(h, t_end, 1e-3, o.clone()));
    line(&format!("h = {h:e}"), &sa);
    let (b, sb) = run(&sys, &info, &genalpha_with(h / 4.0, t_end, 1e-3, o));
    line(&format!("h = {:e}", h / 4.0), &sb);
    if sa.status == "completed" && sb.status == "completed" {
        println!(
            "tip-position error of h against h/4: {:.3e} m (max over output times); total {:.1} s",
            tip_error(&info, &a, &b),
            start.elapsed().as_secs_f64()
        );
    }
}

/// Tip error between runs at h, h/4, h/16 over time (convergence study).
fn trace(args: &[String]) {
    let n = arg(args, 1, 100.0) as usize;
    let h = arg(args, 2, 1e-4);
    let t_end = arg(args, 3, 1.0);
    let o = ImplicitOptions {
        rho_inf: arg(args, 4, ImplicitOptions::default().rho_inf),
        newton_tol: arg(args, 5, ImplicitOptions::default().newton_tol),
        ..Default::default()
    };
    let (sys, info) = rod(n);
    let runs: Vec<(Trajectory, Summary, Vec<f64>)> = [1.0, 4.0, 16.0]
        .iter()
        .map(|d| {
            let (q0, qd0) = sys.initial_state();
            let mut mon = ContactMonitor::new(info.clone());
            let cfg = genalpha_with(h / d, t_end, 1e-3, o.clone());
            let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut [&mut mon as &mut dyn Monitor])
                .expect("run starts");
            line(&format!("h = {:e}", h / d), &s);
            let starts = mon
                .events
                .iter()
                .filter(|e| e.kind == "start")
                .map(|e| e.t)
                .collect();
            (traj, s, starts)
        })
        .collect();
    let (ta, tb, tc) = (
        tip(&info, &runs[0].0),
        tip(&info, &runs[1].0),
        tip(&info, &runs[2].0),
    );
    let d = |p: &[f64; 2], r: &[f64; 2]| ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2)).sqrt();
    let (mut e1, mut e2) = (0.0_f64, 0.0_f64);
    for k in 0..ta.len().min(tb.len()).min(tc.len()) {
        e1 = e1.max(d(&ta[k], &tb[k]));
        e2 = e2.max(d(&tb[k], &tc[k]));
    }
    println!("max tip error: |h − h/4| = {e1:.3e} m, |h/4 − h/16| = {e2:.3e} m");
    for k in (0..ta.len().min(tb.len()).min(tc.len())).step_by(50) {
        println!(
            "t = {:.3}: tip ({:+.5}, {:+.5}); |h − h/4| = {:.2e}, |h/4 − h/16| = {:.2e}; contact starts so far {} {} {}",
            runs[0].0.t[k],
            tc[k][0],
            tc[k][1],
            d(&ta[k], &tb[k]),
            d(&tb[k], &tc[k]),
            runs[0].2.iter().filter(|&&t| t <= runs[0].0.t[k]).count(),
            runs[1].2.iter().filter(|&&t| t <= runs[0].0.t[k]).count(),
            runs[2].2.iter().filter(|&&t| t <= runs[0].0.t[k]).count(),
        );
    }
}

/// Sensitivity of problem C itself: the same step, the initial state
/// shifted rigidly by `dx` (1e-10 m) along x. If the tip moves apart by
/// more than the step-size error, the run-to-run differences are those of
/// the dynamics (impacts of the rod's face on the wall), not of the integrator.
fn perturb(args: &[String]) {
    let n = arg(args, 1, 1000.0) as usize;
    let h = arg(args, 2, 2.5e-5);
    let t_end = arg(args, 3, 1.0);
    let dx = arg(args, 4, 1e-10);
    let (sys, info) = rod(n);
    let (q0, qd0) = sys.initial_state();
    let mut q1 = q0.clone();
    for b in &info.bodies {
        q1[3 * b] += dx;
    }
    let cfg = genalpha(h, t_end, 1e-3);
    let mut out = Vec::new();
    for (label, q) in [("nominal", &q0), ("shifted", &q1)] {
        let mut mon = ContactMonitor::new(info.clone());
        let (traj, s) =
            simulate(&sys, q, &qd0, &cfg, &mut [&mut mon as &mut dyn Monitor]).expect("run starts");
        line(label, &s);
        out.push(traj);
    }
    let (ta, tb) = (tip(&info, &out[0]), tip(&info, &out[1]));
    for k in (0..ta.len()).step_by(100) {
        let e = ((ta[k][0] - tb[k][0]).powi(2) + (ta[k][1] - tb[k][1]).powi(2)).sqrt();
        println!("t = {:.2}: tip difference {e:.3e} m", out[0].t[k]);
    }
    println!(
        "initial shift {dx:e} m → max tip difference {:.3e} m",
        tip_error(&info, &out[0], &out[1])
    );
}

/// Newton predictor: constant vs linearly extrapolated q̈, λ.
fn predictor(args: &[String]) {
    let n = arg(args, 1, 1000.0) as usize;
    let h = arg(args, 2, 2.5e-5);
    let span = arg(args, 3, 0.3);
    let (sys, info) = rod(n);
    println!("# N = {n}, h = {h:e}, t = 0 … {span} s");
    for extrapolate in [false, true] {
        let o = ImplicitOptions {
            extrapolate,
            ..Default::default()
        };
        let (_, s) = run(&sys, &info, &genalpha_with(h, span, span / 10.0, o));
        line(&format!("extrapolate = {extrapolate}"), &s);
    }
}

/// The Newton matrix factorised as its symmetric part with the sparse
/// LDLᵀ (modified Newton) or in full with faer's sparse LU (exact Newton).
fn lu(args: &[String]) {
    let n = arg(args, 1, 1000.0) as usize;
    let h = arg(args, 2, 2.5e-5);
    let span = arg(args, 3, 0.1);
    let (sys, info) = rod(n);
    println!("# N = {n}, h = {h:e}, t = 0 … {span} s");
    let mut out = Vec::new();
    for (label, lu, reuse) in [
        ("LDLT sym., reuse", false, true),
        ("LU full, reuse", true, true),
        ("LDLT sym., fresh every iteration", false, false),
        ("LU full, fresh every iteration", true, false),
    ] {
        let o = ImplicitOptions {
            lu,
            reuse,
            ..Default::default()
        };
        let (traj, s) = run(&sys, &info, &genalpha_with(h, span, span / 10.0, o));
        line(label, &s);
        out.push(traj);
    }
    for k in 1..out.len() {
        println!(
            "tip difference to the first run: {:.3e} m",
            tip_error(&info, &out[0], &out[k])
        );
    }
}

fn ode23(args: &[String]) {
    let h = arg(args, 1, 1e-4);
    let (sys, info) = rod(10);
    let cfg23 = RunConfig {
        method: Method::Ode23,
        ode: OdeOptions::default(),
        t_end: 1.0,
        output_dt: 1e-3,
        ..Default::default()
    };
    let reference = RunConfig {
        method: Method::Ode45,
        ode: OdeOptions {
            rtol: 1e-9,
            atol: Tolerance::Scalar(1e-12),
            ..Default::default()
        },
        ..cfg23.clone()
    };
    let (r, sr) = run(&sys, &info, &reference);
    line("ode45 1e-9 (reference)", &sr);
    let (a, sa) = run(&sys, &info, &cfg23);
    line("ode23 MATLAB defaults", &sa);
    let ea = tip_error(&info, &a, &r);
    println!("    ode23 tip error vs reference: {ea:.3e} m");
    let mut hh = h;
    loop {
        let (g, sg) = run(&sys, &info, &genalpha(hh, 1.0, 1e-3));
        let eg = tip_error(&info, &g, &r);
        line(&format!("genalpha h = {hh:e}"), &sg);
        println!(
            "    genalpha tip error vs reference: {eg:.3e} m; wall ratio genalpha/ode23 = {:.3}",
            sg.wall_s / sa.wall_s
        );
        if eg <= ea || hh < 1e-6 {
            break;
        }
        hh /= 2.0;
    }
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    match args.first().map(String::as_str) {
        None | Some("slope") => slope(&args),
        Some("full") => full(&args),
        Some("ode23") => ode23(&args),
        Some("trace") => trace(&args),
        Some("lu") => lu(&args),
        Some("perturb") => perturb(&args),
        Some("predictor") => predictor(&args),
        Some(other) => eprintln!("unknown mode '{other}' (slope, full, trace, perturb, ode23, lu)"),
    }
}
