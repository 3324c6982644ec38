//! Functions of time and space in scenarios: drive motions written as
//! expressions of t or as tabulated splines (against their closed forms),
//! and the documented examples.

use mbsolve::constraints::{spline_motion, Spline};
use mbsolve::scenario;
use mbsolve::simulation::{simulate, simulate_into, Sample, Sink};

use crate::common::setup::{docs_example, parse_error as err, scenario as parse};

/// One output row: (t, q, q̇, q̈, λ).
type Row = (f64, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// The rows of a run.
#[derive(Default)]
struct Rows(Vec<Row>);

impl Sink for Rows {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.0.push((
            s.t,
            s.q.to_vec(),
            s.qd.to_vec(),
            s.qdd.expect("accelerations").to_vec(),
            s.lambda.expect("multipliers").to_vec(),
        ));
        Ok(())
    }
}

/// A free body of mass 2 kg whose x is driven (no gravity, no other load):
/// x = f(t), ẋ = f'(t), ẍ = f''(t), and the drive's force is m f''(t).
fn slider(motion: &str) -> String {
    format!(
        "gravity = [0.0, 0.0]\n\
         [[body]]\nname = \"s\"\nmass = 2.0\ninertia = 0.1\nx = 0.0\n\
         [[joint]]\ntype = \"drive_coordinate\"\nname = \"d\"\nbody = \"s\"\ncoordinate = \"x\"\n\
         motion = {motion}\n\
         [integrator]\nmethod = \"ode45\"\nrtol = 1e-10\natol = 1e-12\n[stabilization]\nprojection = true\n\
         [time]\nend = 1.0\n[output]\ndt = 0.05\nquantities = [\"accelerations\", \"drives\"]\n"
    )
}

fn run(text: &str) -> Rows {
    let sc = parse(text);
    let mut rows = Rows::default();
    let s = simulate_into(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [], &mut rows).unwrap();
    assert_eq!(s.status, "completed", "{s:?}");
    assert!(rows.0.len() > 10);
    rows
}

/// An expression-driven motion against its closed form: positions,
/// velocities, accelerations and the drive's reaction.
#[test]
fn expression_motion_against_its_closed_form() {
    let rows = run(&slider("\"0.1*sin(6*t) + 0.05*t^2\""));
    for (t, q, qd, qdd, lambda) in &rows.0 {
        let x = 0.1 * (6.0 * t).sin() + 0.05 * t * t;
        let v = 0.6 * (6.0 * t).cos() + 0.1 * t;
        let a = -3.6 * (6.0 * t).sin() + 0.1;
        assert!((q[0] - x).abs() < 1e-9, "x at {t}: {} vs {x}", q[0]);
        assert!((qd[0] - v).abs() < 1e-8, "vx at {t}: {} vs {v}", qd[0]);
        assert!((qdd[0] - a).abs() < 1e-8, "ax at {t}: {} vs {a}", qdd[0]);
        // the drive's generalized force −λ is what accelerates the mass
        assert!(
            (-lambda[0] - 2.0 * a).abs() < 1e-8,
            "drive at {t}: {} vs {}",
            -lambda[0],
            2.0 * a
        );
    }
}

/// The same motion as the harmonic table `{ amplitude, omega }` runs the
/// same (to rounding), and with parameters inside the expression exactly as
/// with their values written out.
#[test]
fn expression_motion_equals_the_harmonic_form_and_takes_parameters() {
    let e = run(&slider("\"0.1*sin(6*t)\""));
    let h = run(&slider("{ amplitude = 0.1, omega = 6.0 }"));
    let p = run(&format!(
        "{}[parameters]\nA = 0.1\nw = \"2*3\"\n",
        slider("\"A*sin(w*t)\"")
    ));
    assert_eq!(e.0.len(), h.0.len());
    for ((a, b), c) in e.0.iter().zip(&h.0).zip(&p.0) {
        assert_eq!(a.0, b.0);
        assert!((a.1[0] - b.1[0]).abs() < 1e-14 && (a.2[0] - b.2[0]).abs() < 1e-13);
        assert_eq!((&a.1, &a.2), (&c.1, &c.2), "parameters change nothing");
    }
}

/// A tabulated motion is followed: the driven coordinate equals the natural
/// cubic spline (computed independently by the library function) with its
/// velocity and acceleration.
#[test]
fn spline_motion_is_followed() {
    let ts = [0.0, 0.2, 0.5, 0.6, 1.0];
    let ys = [0.0, 0.1, -0.05, 0.0, 0.2];
    let rows = run(&slider(
        "{ t = [0.0, 0.2, 0.5, 0.6, 1.0], value = [0.0, 0.1, -0.05, 0.0, 0.2], spline = \"cubic\" }",
    ));
    let f = spline_motion(&ts, &ys, Spline::Cubic).unwrap();
    for (t, q, qd, qdd, _) in &rows.0 {
        let [x, v, a] = f.eval(*t);
        assert!(
            (q[0] - x).abs() < 1e-9 && (qd[0] - v).abs() < 1e-8 && (qdd[0] - a).abs() < 1e-7,
            "at {t}"
        );
    }
    // through the points
    for (t, q, ..) in &rows.0 {
        if let Some(k) = ts.iter().position(|x| (x - t).abs() < 1e-12) {
            assert!((q[0] - ys[k]).abs() < 1e-9);
        }
    }
}

/// Bad motions are errors naming the key.
#[test]
fn bad_motions_name_the_key() {
    let e = err(&slider("\"s.x + t\""));
    assert!(
        e.contains("joint[0].motion") && e.contains("unknown name 's.x'"),
        "{e}"
    );
    let e = err(&slider("{ t = [0.0, 1.0, 1.0], value = [0.0, 1.0, 2.0] }"));
    assert!(
        e.contains("joint[0].motion") && e.contains("increase strictly"),
        "{e}"
    );
    let e = err(&slider(
        "{ t = [0.0, 1.0], value = [0.0, 1.0], spline = \"quintic\" }",
    ));
    assert!(
        e.contains("joint[0].motion.spline") && e.contains("quintic"),
        "{e}"
    );
    let e = err(&slider("{ t = [0.0, 1.0], values = [0.0, 1.0] }"));
    assert!(e.contains("joint[0].motion.values"), "{e}");
    let e = err(&slider("{ t = [0.0, 1.0] }"));
    assert!(
        e.contains("joint[0].motion.value") && e.contains("missing"),
        "{e}"
    );
    let e = err(&slider("{ amplitude = 1.0 }"));
    assert!(e.contains("joint[0].motion") && e.contains("omega"), "{e}");
}

/// A log of a negative number in an expression force stops the run at once
/// with the non-finite force named, never a NaN trajectory.
#[test]
fn a_domain_error_stops_the_run_with_a_message() {
    let text = "gravity = [0.0, -9.81]\n\
         [[body]]\nname = \"b\"\nmass = 1.0\ninertia = 0.1\n\
         [[force]]\ntype = \"expression\"\nbody = \"b\"\nfx = \"log(b.y + 0.01)\"\nfy = \"0\"\n\
         [time]\nend = 1.0\n";
    let sc = parse(text);
    let (traj, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "failed");
    let m = s.message.clone().unwrap_or_default();
    assert!(m.contains("the forces g is not finite"), "{m}");
    assert!(traj.q.iter().flatten().all(|v| v.is_finite()));
    // it fails when b.y + 0.01 first goes below 0: y = −g t²/2, t ≈ 0.045
    let t_end = *traj.t.last().unwrap_or(&0.0);
    assert!(t_end < 0.06, "{t_end}");
}

/// The functions example of docs/scenarios.md parses and runs.
#[test]
fn the_documented_example_runs() {
    let block = &docs_example("functions example");
    let sc = parse(block);
    let (_, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.status, "completed");
}

/// A disc sliding and bouncing on a floor that moves (`wall_motion`: a
/// conveyor at 0.2 m/s and a vertical shake 0.01 sin 10t) equals the same
/// contact in the wall's own frame: a fixed floor, the initial velocity
/// less the wall's, and the frame's inertial force −m ä = (0, m sin 10t).
#[test]
fn a_moving_wall_is_the_fixed_wall_in_its_own_frame() {
    let disc = |v: [f64; 2], extra: &str| {
        format!(
            "gravity = [0.0, -9.81]\n\
             [[body]]\nname = \"d\"\nmass = 1.0\ninertia = 0.005\ny = 0.099\nvx = {}\nvy = {}\nomega = 1.0\n\
             [[force]]\ntype = \"contact\"\nname = \"floor\"\nbody = \"d\"\nradius = 0.1\n\
             wall_normal_deg = 90.0\nstiffness = 1e5\ndamping = 0.5\nfriction = 0.3\nslip_velocity = 0.01\n{extra}\n\
             [integrator]\nmethod = \"ode45\"\nrtol = 1e-10\natol = 1e-12\n\
             [time]\nend = 1.0\n[output]\ndt = 0.05\n",
            v[0], v[1]
        )
    };
    let moving = parse(&disc(
        [0.5, 0.0],
        "wall_motion = [\"0.2*t\", { amplitude = 0.01, omega = 10.0 }]",
    ));
    let frame = parse(&format!(
        "{}[[force]]\ntype = \"expression\"\nbody = \"d\"\nfx = \"0\"\nfy = \"sin(10*t)\"\n",
        disc([0.3, -0.1], "")
    ));
    let (a, sa) = simulate(
        &moving.system,
        &moving.q0,
        &moving.qd0,
        &moving.run,
        &mut [],
    )
    .unwrap();
    let (b, sb) = simulate(&frame.system, &frame.q0, &frame.qd0, &frame.run, &mut []).unwrap();
    assert_eq!(
        (sa.status.as_str(), sb.status.as_str()),
        ("completed", "completed")
    );
    assert_eq!(a.t, b.t);
    let mut in_contact = 0;
    for k in 0..a.t.len() {
        let t = a.t[k];
        let (dx, dy) = (0.2 * t, 0.01 * (10.0 * t).sin());
        let (vx, vy) = (0.2, 0.1 * (10.0 * t).cos());
        let rel = [a.q[k][0] - dx, a.q[k][1] - dy, a.q[k][2]];
        let vrel = [a.qd[k][0] - vx, a.qd[k][1] - vy, a.qd[k][2]];
        for i in 0..3 {
            assert!(
                (rel[i] - b.q[k][i]).abs() < 1e-7,
                "q{i} at {t}: {} vs {}",
                rel[i],
                b.q[k][i]
            );
            assert!(
                (vrel[i] - b.qd[k][i]).abs() < 1e-6,
                "v{i} at {t}: {} vs {}",
                vrel[i],
                b.qd[k][i]
            );
        }
        if b.q[k][1] < 0.1 {
            in_contact += 1;
        }
    }
    // the comparison covers contact (and the friction that drags the disc)
    assert!(in_contact > 5, "{in_contact}");
    assert!(
        (b.qd.last().unwrap()[0] - 0.3).abs() > 0.01,
        "friction acted"
    );
}

/// A disc rolling and bouncing on a road profile equals the same disc on
/// the equivalent wall: a flat road `0` the floor, a straight ramp `0.1*x`
/// the wall with normal (−0.1, 1), a road `0.01*sin(10*t)` the floor moving
/// up and down. Explicit method (no Jacobians involved): the forces agree
/// to rounding (the tangent line's point is `(p_x, h)`, not the wall's),
/// so the runs agree in q within 1e-9 (1e-8 for the tabulated road).
#[test]
fn a_road_profile_equals_the_equivalent_wall() {
    let disc = |contact: &str| {
        parse(&format!(
            "gravity = [0.0, -9.81]\n\
             [[body]]\nname = \"d\"\nmass = 1.0\ninertia = 0.005\nx = 0.2\ny = 0.119\nvx = 0.5\nomega = 1.0\n\
             [[force]]\ntype = \"contact\"\nbody = \"d\"\nradius = 0.1\n\
             stiffness = 1e5\ndamping = 0.5\nfriction = 0.3\nslip_velocity = 0.01\n{contact}\n\
             [integrator]\nmethod = \"ode45\"\nrtol = 1e-9\natol = 1e-12\n\
             [time]\nend = 0.8\n[output]\ndt = 0.05\n"
        ))
    };
    let run = |sc: &scenario::Scenario| {
        let (tr, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
        assert_eq!(s.status, "completed");
        tr
    };
    for (road, wall, tol) in [
        ("road = \"0\"", "wall_normal_deg = 90.0", 1e-9),
        ("road = \"0.1*x\"", "wall_normal = [-0.1, 1.0]", 1e-9),
        (
            "road = \"0.01*sin(10*t)\"",
            "wall_normal_deg = 90.0\nwall_motion = [0.0, \"0.01*sin(10*t)\"]",
            1e-9,
        ),
        (
            "road = \"table(x, [-1, 0, 1], [0.1, 0, 0.1]) + 0.02\"",
            "wall_normal = [-0.1, 1.0]\nwall_point = [0.0, 0.02]",
            // the table's ramp sum rounds differently again: ~4e-9 seen
            1e-8,
        ),
    ] {
        let (a, b) = (run(&disc(road)), run(&disc(wall)));
        let diff =
            a.q.iter()
                .flatten()
                .zip(b.q.iter().flatten())
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
        assert!(diff <= tol, "{road}: max |Δq| = {diff:e}");
        assert!(a.q.iter().any(|q| q[1] < 0.15), "{road}: touched");
    }
    let e = err("[[body]]\nname = \"d\"\nmass = 1.0\ninertia = 0.1\n[[force]]\ntype = \"contact\"\nbody = \"d\"\nstiffness = 1.0\nroad = \"y + x\"\n[time]\nend = 1.0\n");
    assert!(
        e.contains("force[0].road") && e.contains("unknown name 'y'"),
        "{e}"
    );
}

/// The loads of `torque`, `force` and `spring` take the motions' forms: a
/// torque `"0.5*sin(3*t)"` on a free body gives `φ = (0.5/I)(t/3 −
/// sin(3t)/9)`; a force tabulated linearly `fx = 2 t` up to t = 1, then 2,
/// gives `x = t³/(3m)` up to 1 and the parabola after; a spring actuator
/// as an expression equals the same polynomial table.
#[test]
fn loads_take_expressions_and_tables_of_t() {
    /// (t, q) at the output times (these models have no multipliers).
    #[derive(Default)]
    struct Positions(Vec<(f64, Vec<f64>)>);
    impl Sink for Positions {
        fn output(
            &mut self,
            s: &Sample<'_>,
        ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            self.0.push((s.t, s.q.to_vec()));
            Ok(())
        }
    }
    let run = |text: &str| {
        let sc = parse(text);
        let mut rows = Positions::default();
        let s = simulate_into(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [], &mut rows).unwrap();
        assert_eq!(s.status, "completed", "{s:?}");
        assert!(rows.0.len() > 10);
        rows
    };
    let text = "gravity = [0.0, 0.0]\n\
         [[body]]\nname = \"w\"\nmass = 1.0\ninertia = 0.25\n\
         [[body]]\nname = \"p\"\nmass = 2.0\ninertia = 0.1\nx = 1.0\n\
         [[force]]\ntype = \"torque\"\nbody = \"w\"\ntorque = \"0.5*sin(3*t)\"\n\
         [[force]]\ntype = \"force\"\nbody = \"p\"\nfy = 0.0\n\
         fx = { t = [0.0, 1.0, 2.0], value = [0.0, 2.0, 2.0], spline = \"linear\" }\n\
         [integrator]\nmethod = \"ode45\"\nrtol = 1e-11\natol = 1e-13\n[time]\nend = 2.0\n\
         [output]\ndt = 0.05\n";
    let rows = run(text);
    for (t, q) in &rows.0 {
        let phi = 0.5 / 0.25 * (t / 3.0 - (3.0 * t).sin() / 9.0);
        assert!((q[2] - phi).abs() < 1e-8, "t = {t}: φ {} vs {phi}", q[2]);
        let x = if *t <= 1.0 {
            t.powi(3) / 6.0
        } else {
            1.0 / 6.0 + 0.5 * (t - 1.0) + 0.5 * (t - 1.0).powi(2)
        };
        assert!(
            (q[3] - 1.0 - x).abs() < 1e-7,
            "t = {t}: x {} vs {x}",
            q[3] - 1.0
        );
    }
    // a spring actuator: the expression equals the polynomial table
    let spring = |actuator: &str| {
        format!(
            "gravity = [0.0, 0.0]\n[[body]]\nname = \"m\"\nmass = 1.0\ninertia = 0.1\nx = 1.0\n\
             [[force]]\ntype = \"spring\"\nbody_i = \"ground\"\nbody_j = \"m\"\nfree_length = 1.0\n\
             stiffness = 10.0\nactuator = {actuator}\n\
             [integrator]\nmethod = \"rk4\"\nstep = 1e-3\n[time]\nend = 1.0\n\
             [output]\ndt = 0.05\n"
        )
    };
    let (a, b) = (
        run(&spring("\"1 + 2*t - t^2\"")),
        run(&spring("{ polynomial = [1.0, 2.0, -1.0] }")),
    );
    for (r, s) in a.0.iter().zip(&b.0) {
        assert!((r.1[0] - s.1[0]).abs() < 1e-13, "{} vs {}", r.1[0], s.1[0]);
    }
    assert!((a.0.last().unwrap().1[0] - 1.0).abs() > 1e-3);
    // an expression reading coordinates is refused with a pointer
    let e = err(&text.replace("0.5*sin(3*t)", "-w.phi"));
    assert!(
        e.contains("test.toml")
            && e.contains("force[0].torque")
            && e.contains("type = \"expression\""),
        "{e}"
    );
}
