//! The contact report of every `type = "contact"` `[[force]]` (not only the
//! rods'): a ball dropped on a floor against the closed forms of free fall
//! and of Hertz's elastic impact; the note on an angle beyond 2π in a
//! radians field; the falling rod's flight steps after its contacts.

use std::process::Command;

const BALL: &str = r#"
gravity = [0.0, -9.81]

[[body]]
name = "ball"
mass = 1.0
inertia = 0.004
y = 0.3

[[force]]
type = "contact"
name = "floor"
body = "ball"
radius = 0.1
wall_point = [0.0, 0.0]
wall_normal_deg = 90.0
stiffness = 1e6

[[force]]
type = "contact"
name = "ceiling"
body = "ball"
radius = 0.1
wall_point = [0.0, 2.0]
wall_normal_deg = -90.0
stiffness = 1e6

[integrator]
method = "rk4"
step = 1e-4

[time]
end = 0.3
"#;

/// `mbsolve run FILE --out DIR --set S…`: the run's stdout and its
/// summary (`DIR/STEM.summary.json`, STEM the file's); fails the test
/// when the run fails.
fn run(
    file: &std::path::Path,
    dir: &std::path::Path,
    sets: &[&str],
) -> (String, serde_json::Value) {
    let mut args = vec![
        "run".to_string(),
        file.to_str().unwrap().into(),
        "--out".into(),
        dir.to_str().unwrap().into(),
    ];
    for s in sets {
        args.extend(["--set".into(), s.to_string()]);
    }
    let o = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
        .args(&args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stem = file.file_stem().unwrap().to_str().unwrap();
    let summary = std::fs::read_to_string(dir.join(format!("{stem}.summary.json"))).unwrap();
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        serde_json::from_str(&summary).unwrap(),
    )
}

/// The largest compression δ of a body of mass `m` dropped from `h` onto a
/// Hertz contact of stiffness `k` (no damping), from the energy balance
/// ½ m v² + m g δ = (2/5) k δ^{5/2} with v² = 2 g h, by bisection.
fn hertz_compression(g: f64, h: f64, m: f64, k: f64) -> f64 {
    let v2 = 2.0 * g * h;
    let energy = |d: f64| 0.4 * k * d.powf(2.5) - 0.5 * m * v2 - m * g * d;
    let (mut lo, mut hi) = (0.0, 0.1);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if energy(mid) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    lo
}

/// First contact at the free-fall time √(2h/g) (h = 0.2 m: the circle's
/// bottom above the floor) to within a step; the contact starts and ends
/// once; the peak normal force k δ^{3/2} at the largest compression δ of
/// the energy balance ½ m v² + m g δ = (2/5) k δ^{5/2} (no damping) within
/// 1 % (sampled at steps); the ceiling is never touched.
#[test]
fn every_contact_element_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ball.toml");
    std::fs::write(&file, BALL).unwrap();
    let (stdout, s) = run(&file, dir.path(), &[]);
    assert!(stdout.contains("contact floor: first at t = "), "{stdout}");
    assert!(stdout.contains("contact ceiling: none"), "{stdout}");
    let c = s["contacts"].as_array().expect("contacts in the summary");
    assert_eq!(c.len(), 2);
    let (floor, ceiling) = (&c[0], &c[1]);
    assert_eq!(floor["force"], "floor");
    let (g, h, m, k): (f64, f64, f64, f64) = (9.81, 0.2, 1.0, 1e6);
    let t_hit = (2.0 * h / g).sqrt();
    let first = floor["first_contact_time"].as_f64().unwrap();
    assert!(
        first >= t_hit - 1e-9 && first <= t_hit + 1e-4 + 1e-9,
        "{first} against {t_hit}"
    );
    let starts = floor["starts"].as_array().unwrap();
    let ends = floor["ends"].as_array().unwrap();
    assert_eq!((starts.len(), ends.len()), (1, 1), "{floor}");
    assert_eq!(starts[0].as_f64(), Some(first));
    // an elastic Hertz impact lasts ≈ 3.2 δ_max / v: a few milliseconds
    let v2 = 2.0 * g * h;
    let lo = hertz_compression(g, h, m, k);
    let peak = k * lo.powf(1.5);
    let got = floor["peak_normal_force"].as_f64().unwrap();
    assert!((got / peak - 1.0).abs() < 0.01, "{got} N against {peak} N");
    let duration = ends[0].as_f64().unwrap() - first;
    assert!(
        duration > 2.0 * lo / v2.sqrt() && duration < 4.0 * lo / v2.sqrt(),
        "{duration} s"
    );
    assert_eq!(ceiling["force"], "ceiling");
    assert!(ceiling["first_contact_time"].is_null(), "{ceiling}");
    assert_eq!(ceiling["peak_normal_force"].as_f64(), Some(0.0));
}

/// `phi = 90` (degrees in a radians field) is legal but noted by `check`,
/// naming the key and the `_deg` key; `phi = 1.5` is not.
#[test]
fn an_angle_beyond_two_pi_in_radians_is_noted() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ball.toml");
    for (phi, noted) in [("90", true), ("1.5", false)] {
        std::fs::write(
            &file,
            BALL.replacen("y = 0.3", &format!("y = 0.3\nphi = {phi}"), 1),
        )
        .unwrap();
        let o = Command::new(env!("CARGO_BIN_EXE_mbsolve"))
            .args(["check", file.to_str().unwrap()])
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{e}");
        assert_eq!(
            e.contains("body[0].phi = 90 rad is more than 2π") && e.contains("phi_deg = 90"),
            noted,
            "{e}"
        );
    }
}

/// The ball's run with radau5 at `step` 1e-4, with and without
/// `flight_step` (its summary).
fn radau_ball(flight_step: Option<&str>) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ball.toml");
    std::fs::write(&file, BALL).unwrap();
    let flight = flight_step.map(|h| format!("integrator.flight_step={h}"));
    let mut sets = vec!["integrator.method=\"radau5\"", "integrator.step=1e-4"];
    sets.extend(flight.as_deref());
    run(&file, dir.path(), &sets).1
}

/// radau5 at `step` 1e-4 with `flight_step` 3e-3 on the dropped ball:
/// the free fall takes the flight step (under half the steps), the impact
/// the step — the first contact is seen within one step of 1e-4 after the
/// free-fall time √(2h/g) (the flight step across it, from 0.201 to
/// 0.204 s, would see it 2e-3 late), once — and the peak normal force is
/// that of the energy balance within 1 %, as without the flight step.
#[test]
fn a_flight_step_falls_at_the_larger_step_and_meets_the_floor_at_the_step() {
    let (plain, flight) = (radau_ball(None), radau_ball(Some("3e-3")));
    let steps = |s: &serde_json::Value| s["steps"].as_u64().unwrap();
    assert!(
        2 * steps(&flight) < steps(&plain),
        "{} against {} steps",
        steps(&flight),
        steps(&plain)
    );
    let (g, h, m, k): (f64, f64, f64, f64) = (9.81, 0.2, 1.0, 1e6);
    let t_hit = (2.0 * h / g).sqrt();
    let peak = k * hertz_compression(g, h, m, k).powf(1.5);
    for s in [&plain, &flight] {
        let floor = &s["contacts"][0];
        let first = floor["first_contact_time"].as_f64().unwrap();
        assert!(
            first >= t_hit - 1e-9 && first <= t_hit + 1e-4 + 1e-9,
            "{first} against {t_hit}"
        );
        assert_eq!(floor["starts"].as_array().unwrap().len(), 1, "{floor}");
        let got = floor["peak_normal_force"].as_f64().unwrap();
        assert!((got / peak - 1.0).abs() < 0.01, "{got} N against {peak} N");
    }
}

/// The falling rod (problem B) at N = 100, radau5 at `step` 4e-4 with
/// `flight_step` 8e-3 over 0.3 s: the first flight step after the steps of
/// the first wall contacts starts Newton from the constant predictor, and
/// no attempt fails. Extrapolating the stage polynomials of a step of 4e-4
/// over 8e-3 puts corners into the walls from states with none near them,
/// and flight steps fail (counts: docs/scaling.md, "The falling rod's
/// contact phases"). The rod still touches the walls.
#[test]
fn the_rods_flight_steps_after_its_contacts_do_not_fail() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/falling_rod.toml");
    let sets = [
        "rod.segments=100",
        "integrator.method=\"radau5\"",
        "integrator.step=4e-4",
        "integrator.flight_step=8e-3",
        "integrator.newton_tol=1",
        "time.end=0.3",
        "output.dt=0.01",
    ];
    let (_, s) = run(std::path::Path::new(scenario), dir.path(), &sets);
    assert_eq!(s["newton_failures"].as_u64(), Some(0), "{s}");
    assert!(s["contact_starts"].as_u64().is_some_and(|n| n > 0), "{s}");
}
