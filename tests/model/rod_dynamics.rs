//! Problem B and D dynamics through the whole pipeline: exact free fall
//! with buoyancy, energy of the conservative pendulum, static Hertz contact
//! reached dynamically, contact events, integrator agreement.

use mbsolve::builders::{add_rod, n_link_pendulum, RodParams};
use mbsolve::events::ContactMonitor;
use mbsolve::forces::{AppliedForce, Buoyancy, Gravity};
use mbsolve::formulation::{Baumgarte, Index1Options};
use mbsolve::integrate::{Method, OdeOptions, Tolerance};
use mbsolve::model::{SystemBuilder, TimeFunction};
use mbsolve::scenario;
use mbsolve::scenario::FALLING_ROD_TOML;
use mbsolve::simulation::{simulate, Monitor, RunConfig};

fn config(method: Method, rtol: f64, atol: f64, t_end: f64, dt: f64) -> RunConfig {
    RunConfig {
        method,
        ode: OdeOptions {
            rtol,
            atol: Tolerance::Scalar(atol),
            ..Default::default()
        },
        t0: 0.0,
        t_end,
        output_dt: dt,
        formulation: Index1Options::default(),
        ..Default::default()
    }
}

#[test]
fn buoyant_free_fall_is_exact_and_uniform_in_x() {
    // Contact and drag off, buoyancy on: the centre of mass falls with
    // g (1 − ρ_w/ρ) and moves uniformly in x (docs/problems.md, problem B).
    let mut p = RodParams::problem_b(8);
    p.fluid = false;
    p.contact = false;
    let mut b = SystemBuilder::new();
    let info = add_rod(&mut b, &p).unwrap();
    let vol = p.width * p.width * p.segment_length();
    b.add_force(Buoyancy {
        fluid_density: 1000.0,
        gravity: 9.81,
        bodies: info.bodies.iter().map(|&i| (i, vol)).collect(),
    });
    b.add_force(Gravity {
        g: [0.0, -9.81],
        bodies: info.bodies.iter().map(|&i| (i, p.segment_mass())).collect(),
    });
    let sys = b.build().unwrap();
    let (q0, qd0) = sys.initial_state();
    let cfg = config(Method::Ode45, 1e-10, 1e-12, 0.5, 0.05);
    let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
    assert_eq!(s.status, "completed");
    let a = 9.81 * (1.0 - 1000.0 / 7850.0);
    let com = |q: &[f64], k: usize| info.bodies.iter().map(|&i| q[3 * i + k]).sum::<f64>() / 8.0;
    let (x0, y0) = (com(&traj.q[0], 0), com(&traj.q[0], 1));
    for (k, &t) in traj.t.iter().enumerate() {
        let (x, y) = (com(&traj.q[k], 0), com(&traj.q[k], 1));
        assert!((x - (x0 + 0.1 * t)).abs() < 1e-10, "x at t = {t}: {x}");
        assert!(
            (y - (y0 - 0.5 * a * t * t)).abs() < 1e-10,
            "y at t = {t}: {y} vs {}",
            y0 - 0.5 * a * t * t
        );
    }
}

#[test]
fn conservative_pendulum_keeps_its_energy() {
    let (sys, _) = n_link_pendulum(5, 0.2, 0.3, 0.7, 9.81).unwrap();
    let (q0, qd0) = sys.initial_state();
    let energy = |q: &[f64], qd: &[f64]| sys.kinetic_energy(qd) + sys.potential_energy(q);
    let e0 = energy(&q0, &qd0);
    let scale = 5.0 * 0.3 * 9.81 * 0.2; // a typical potential-energy swing [J]
    let mut drifts = Vec::new();
    for rtol in [1e-6, 1e-9] {
        let mut cfg = config(Method::Ode45, rtol, rtol * 1e-2, 2.0, 0.01);
        cfg.formulation.baumgarte = Baumgarte {
            alpha: 0.0,
            beta: 0.0,
        };
        let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut []).unwrap();
        assert_eq!(s.status, "completed");
        let drift = traj
            .q
            .iter()
            .zip(&traj.qd)
            .map(|(q, qd)| (energy(q, qd) - e0).abs())
            .fold(0.0, f64::max);
        drifts.push(drift / scale);
    }
    assert!(
        drifts[1] < 1e-7,
        "energy drift at rtol 1e-9: {:e}",
        drifts[1]
    );
    assert!(
        drifts[1] < drifts[0] / 50.0,
        "energy drift does not follow the tolerance: {drifts:?}"
    );
}

#[test]
fn segment_pushed_against_a_wall_settles_at_the_hertz_penetration() {
    // One vertical segment, no gravity or fluid, pushed by F towards the
    // right wall: both right corners carry F/2, so δ = (F / (2 k_h))^(2/3).
    // A short segment (0.1 m, 0.7 kg): the contact oscillation (≈ 700 Hz)
    // is damped by Hunt–Crossley at ≈ 100/s, so it settles well within 0.5 s.
    let mut p = RodParams::problem_b(1);
    p.length = 0.1;
    p.fluid = false;
    p.tilt = 0.0;
    p.initial_velocity = [0.0, 0.0];
    let mut b = SystemBuilder::new();
    let info = add_rod(&mut b, &p).unwrap();
    let body = info.bodies[0];
    b.bodies_mut()[body].q0[0] = 0.025 - p.width / 2.0; // touching
    let f = 200.0;
    b.add_force(AppliedForce {
        name: "push".into(),
        body,
        point: [0.0, 0.0],
        fx: TimeFunction::Constant(f),
        fy: TimeFunction::Constant(0.0),
    });
    let sys = b.build().unwrap();
    let (q0, qd0) = sys.initial_state();
    let cfg = config(Method::Ode45, 1e-8, 1e-12, 0.5, 0.01);
    let mut mon = ContactMonitor::new(info.clone());
    let mut mons: [&mut dyn Monitor; 1] = [&mut mon];
    let (traj, s) = simulate(&sys, &q0, &qd0, &cfg, &mut mons).unwrap();
    assert_eq!(s.status, "completed");
    let q = traj.q.last().unwrap();
    let delta = q[3 * body] + p.width / 2.0 - 0.025;
    let expect = (f / (2.0 * p.contact_stiffness)).powf(2.0 / 3.0);
    assert!(
        (delta / expect - 1.0).abs() < 1e-4,
        "δ = {delta:e}, Hertz {expect:e}"
    );
    assert!(
        q[3 * body + 2].abs() < 1e-9,
        "the segment must not tilt: {}",
        q[3 * body + 2]
    );
    // the two right corners came into contact (corners 1 and 2 face +x)
    let starts: Vec<_> = mon.events.iter().filter(|e| e.kind == "start").collect();
    assert!(
        starts.iter().any(|e| e.corner == 1 && e.wall == "right"),
        "{:?}",
        mon.events
    );
    assert!(
        starts.iter().any(|e| e.corner == 2 && e.wall == "right"),
        "{:?}",
        mon.events
    );
}

/// The step ends of a run, for telling its output rows between steps from
/// those at a step.
struct StepTimes(Vec<f64>);

impl Monitor for StepTimes {
    fn step(&mut self, t: f64, _q: &[f64], _qd: &[f64]) {
        self.0.push(t);
    }
    fn report(&self, _extra: &mut serde_json::Map<String, serde_json::Value>) {}
}

/// The output rows of the falling rod (problem B, N = 200) between
/// radau5's steps (`step` 4e-4, `flight_step` 2e-3, rows every 2.5e-4 s to
/// 0.1 s: the fall and the first wall contacts) lie on the joints: every
/// such row's `‖Φ‖∞` is within the output projection's bound
/// `64 ε max(1, ‖q‖∞)` (the step ends only within the Newton tolerance),
/// and no row is left as interpolated (which the run reports as a
/// warning). The rod's mass saddle matrix is ill-conditioned (segments of
/// 7e-3 kg and 6e-7 kg m² against unit joint rows), and the projection's
/// solves have no residual check: its corrections must still reach the
/// bound.
#[test]
fn the_rods_output_rows_between_steps_lie_on_the_joints() {
    let o = vec![
        "rod.segments=200".to_string(),
        "integrator.method=\"radau5\"".to_string(),
        "integrator.step=4e-4".to_string(),
        "integrator.flight_step=2e-3".to_string(),
        "integrator.newton_tol=1".to_string(),
        "time.end=0.1".to_string(),
        "output.dt=2.5e-4".to_string(),
    ];
    let sc = scenario::parse(FALLING_ROD_TOML, "falling_rod.toml", "falling_rod", &o).unwrap();
    let mut steps = StepTimes(Vec::new());
    let (traj, s) = simulate(
        &sc.system,
        &sc.q0,
        &sc.qd0,
        &sc.run,
        &mut [&mut steps as &mut dyn Monitor],
    )
    .unwrap();
    assert_eq!(s.status, "completed", "{:?}", s.message);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    assert_eq!(traj.t.len(), 401);
    let mut phi = vec![0.0; sc.system.n_constraints()];
    let mut between = 0;
    for (t, q) in traj.t.iter().zip(&traj.q) {
        if *t == 0.0 || steps.0.iter().any(|ts| (ts - t).abs() <= 1e-9) {
            continue;
        }
        between += 1;
        sc.system.phi(q, *t, &mut phi);
        let bound = 64.0 * f64::EPSILON * q.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        let worst = phi.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!(worst <= bound, "t = {t}: ‖Φ‖∞ = {worst:e} > {bound:e}");
    }
    assert!(between >= 200, "{between} rows between steps");
}

#[test]
fn ode23_and_ode45_agree_on_problem_b() {
    let run = |method: &str, rtol: f64| {
        let o = vec![
            format!("integrator.method={method}"),
            format!("integrator.rtol={rtol}"),
            format!("integrator.atol={}", rtol * 1e-3),
            "time.end=0.3".to_string(),
            "output.dt=0.01".to_string(),
        ];
        let sc = scenario::parse(FALLING_ROD_TOML, "falling_rod.toml", "falling_rod", &o).unwrap();
        let (traj, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
        assert_eq!(s.status, "completed");
        traj
    };
    let a = run("ode23", 1e-7);
    let b = run("ode45", 1e-9);
    let mut worst: f64 = 0.0;
    for (qa, qb) in a.q.iter().zip(&b.q) {
        for i in 0..10 {
            worst = worst.max((qa[3 * i] - qb[3 * i]).abs());
        }
    }
    assert!(worst < 1e-5, "x of segments differ by {worst:e} m");
}

#[test]
fn bad_rod_input_is_rejected_with_the_field() {
    for (set, needles) in [
        ("rod.segments=0", vec!["rod.segments", "0"]),
        ("rod.width=-0.03", vec!["width", "-0.03"]),
        ("rod.channel_width=0.02", vec!["channel_width", "0.02"]),
        ("rod.tilt_deg=20", vec!["tilt"]),
        ("rod.youngs_modulus=0", vec!["youngs_modulus"]),
    ] {
        let e = scenario::parse(
            FALLING_ROD_TOML,
            "falling_rod.toml",
            "falling_rod",
            &[set.to_string()],
        )
        .unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("falling_rod.toml") && msg.contains("--set"),
            "{set}: {msg}"
        );
        for n in needles {
            assert!(msg.contains(n), "{set}: '{n}' not in: {msg}");
        }
    }
}
