//! The shipped spring pendulum (scenarios/spring_pendulum.toml)
//! through the library's scenario API, against independent solutions
//! integrated here by a classical RK4: the polar equations of the elastic
//! pendulum (spring at the bob's centre) and, with the spring moved to an
//! off-centre point, the Newton–Euler equations of the bob written by hand.

use mbsolve::{scenario, simulation};
use std::path::PathBuf;

const G: f64 = 9.81;

fn path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenarios/spring_pendulum.toml")
}

/// Classical RK4 of `f` from `y0` over `[0, t_end]` with `n` steps per
/// `dt`; the states at `0, dt, 2 dt, …`.
fn rk4<const N: usize>(
    f: impl Fn(&[f64; N]) -> [f64; N],
    y0: [f64; N],
    dt: f64,
    outputs: usize,
    n: usize,
) -> Vec<[f64; N]> {
    let h = dt / n as f64;
    let mut y = y0;
    let mut out = vec![y];
    let add = |a: &[f64; N], b: &[f64; N], s: f64| {
        let mut r = *a;
        for i in 0..N {
            r[i] += s * b[i];
        }
        r
    };
    for _ in 1..outputs {
        for _ in 0..n {
            let k1 = f(&y);
            let k2 = f(&add(&y, &k1, 0.5 * h));
            let k3 = f(&add(&y, &k2, 0.5 * h));
            let k4 = f(&add(&y, &k3, h));
            for i in 0..N {
                y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        out.push(y);
    }
    out
}

#[test]
fn spring_pendulum_matches_polar_equations_and_conserves_energy() {
    let sc = scenario::load(&path(), &[]).unwrap();
    let (traj, _) = simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    let (m, k, l0) = (1.0, 60.0, 0.5);
    // polar state [r, θ, ṙ, θ̇], θ from the downward vertical
    let y0 = [0.8, 30f64.to_radians(), 0.0, 0.0];
    let f = |y: &[f64; 4]| {
        let [r, th, rd, thd] = *y;
        [
            rd,
            thd,
            r * thd * thd + G * th.cos() - k / m * (r - l0),
            -(G * th.sin() + 2.0 * rd * thd) / r,
        ]
    };
    assert_eq!(traj.t.len(), 501);
    let reference = rk4(f, y0, 0.01, traj.t.len(), 50);
    let mut worst: f64 = 0.0;
    for (i, q) in traj.q.iter().enumerate() {
        assert!((traj.t[i] - 0.01 * i as f64).abs() < 1e-12);
        let [r, th, ..] = reference[i];
        let (x, y) = (r * th.sin(), -r * th.cos());
        worst = worst.max((q[0] - x).abs()).max((q[1] - y).abs());
    }
    eprintln!("polar: largest position error {worst:e} m");
    assert!(worst < 2e-8, "largest position error {worst} m");
    // the motion is not trivial: the radius and the angle both vary a lot
    let rs: Vec<f64> = reference.iter().map(|y| y[0]).collect();
    let span =
        rs.iter().cloned().fold(f64::MIN, f64::max) - rs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(span > 0.1, "radial amplitude {span}");
    // energy: kinetic + gravity + spring, conserved by the undamped system
    let e =
        |i: usize| sc.system.kinetic_energy(&traj.qd[i]) + sc.system.potential_energy(&traj.q[i]);
    let e0 = e(0);
    // against the closed form at t = 0: V = m g y + ½ k (r − L0)²
    let want = m * G * (-0.8 * 30f64.to_radians().cos()) + 0.5 * k * 0.3f64.powi(2);
    assert!((e0 - want).abs() < 1e-12, "E0 {e0} vs {want}");
    let drift = (0..traj.t.len())
        .map(|i| (e(i) - e0).abs())
        .fold(0.0, f64::max);
    eprintln!("energy drift {drift:e} J of E0 = {e0}");
    assert!(drift < 1e-7, "energy drift {drift} J");
}

#[test]
fn off_centre_spring_matches_hand_written_newton_euler() {
    // spring at the bob point s = (0.05, 0.1), inertia 0.02: rotation couples in
    let (s, inertia) = ([0.05, 0.1], 0.02);
    let text = std::fs::read_to_string(path())
        .unwrap()
        .replace(
            "point_j = [0.0, 0.0]",
            &format!("point_j = [{}, {}]", s[0], s[1]),
        )
        .replace("inertia = 0.01", &format!("inertia = {inertia}"))
        .replace("omega = 0.0", "omega = 1.5");
    let sc = scenario::parse(&text, "spring_pendulum.toml", "sp", &["time.end=3".into()]).unwrap();
    let (traj, _) = simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    let (m, k, l0) = (1.0, 60.0, 0.5);
    // Newton–Euler of the bob: m r̈ = F − m g ŷ, I φ̈ = (A s) × F with F the
    // spring force on the bob at its point p = r + A s: F = −k (|p| − L0) p/|p|
    let f = |y: &[f64; 6]| {
        let [x, yy, phi, vx, vy, w] = *y;
        let (sn, cs) = phi.sin_cos();
        let a = [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]];
        let p = [x + a[0], yy + a[1]];
        let len = p[0].hypot(p[1]);
        let t = -k * (len - l0) / len;
        let fs = [t * p[0], t * p[1]];
        [
            vx,
            vy,
            w,
            fs[0] / m,
            fs[1] / m - G,
            (a[0] * fs[1] - a[1] * fs[0]) / inertia,
        ]
    };
    let y0 = [
        sc.q0[0], sc.q0[1], sc.q0[2], sc.qd0[0], sc.qd0[1], sc.qd0[2],
    ];
    assert_eq!(y0[5], 1.5);
    let reference = rk4(f, y0, 0.01, traj.t.len(), 50);
    let mut worst: f64 = 0.0;
    for (q, r) in traj.q.iter().zip(&reference) {
        for c in 0..3 {
            worst = worst.max((q[c] - r[c]).abs());
        }
    }
    eprintln!("newton-euler: largest coordinate error {worst:e}");
    assert!(worst < 2e-8, "largest coordinate error {worst}");
    // the rotation is really driven by the spring (it is not a free spin)
    let phi_end = reference.last().unwrap()[2];
    assert!((phi_end - 1.5 * 3.0).abs() > 0.1, "φ(3) = {phi_end}");
}
