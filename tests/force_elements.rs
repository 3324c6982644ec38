//! Force elements on any bodies (issue 11, item 1): laws, forces and
//! Jacobians against central finite differences, potential energy against
//! the work of the force, damper power, law validation, static cases.

use mbsolve::forces::{FdWorkspace, ForceElement, Law, PointSpringDamper};
use mbsolve::model::{BodyRef, ModelError, TimeFunction};

/// Deterministic uniform numbers in [-1, 1) (64-bit LCG).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

fn forces(e: &dyn ForceElement, t: f64, q: &[f64], qd: &[f64]) -> Vec<f64> {
    let mut g = vec![0.0; q.len()];
    e.add_forces(t, q, qd, &mut g);
    g
}

/// Analytic Jacobians of `e` against central differences of its forces.
fn check_jacobians(e: &dyn ForceElement, t: f64, q: &[f64], qd: &[f64], tol: f64) {
    let cols = e.jacobian_coordinates();
    let k = cols.len();
    let (mut dq, mut dqd) = (vec![0.0; k * k], vec![0.0; k * k]);
    e.add_jacobians(t, q, qd, &mut dq, &mut dqd, &mut FdWorkspace::default());
    for velocity in [false, true] {
        for (ci, &c) in cols.iter().enumerate() {
            let h = 1e-6;
            let (mut qp, mut qm, mut vp, mut vm) =
                (q.to_vec(), q.to_vec(), qd.to_vec(), qd.to_vec());
            if velocity {
                vp[c] += h;
                vm[c] -= h;
            } else {
                qp[c] += h;
                qm[c] -= h;
            }
            let gp = forces(e, t, &qp, &vp);
            let gm = forces(e, t, &qm, &vm);
            for (ri, &r) in cols.iter().enumerate() {
                let fd = (gp[r] - gm[r]) / (2.0 * h);
                let an = if velocity {
                    dqd[ri * k + ci]
                } else {
                    dq[ri * k + ci]
                };
                assert!(
                    (fd - an).abs() <= tol * (1.0 + fd.abs()),
                    "{} d g[{r}]/d {}[{c}]: analytic {an} vs fd {fd}",
                    e.name(),
                    if velocity { "qd" } else { "q" }
                );
            }
        }
    }
}

fn table(x: &[f64], f: &[f64]) -> Law {
    Law::Table {
        x: x.to_vec(),
        f: f.to_vec(),
    }
}

#[test]
fn law_value_slope_and_exact_integral() {
    let law = table(&[-1.0, 0.0, 0.5, 2.0], &[-3.0, 0.0, 2.0, 2.5]);
    // interpolation and linear extrapolation
    assert!((law.value(0.25) - 1.0).abs() < 1e-15);
    assert!((law.value(-2.0) + 6.0).abs() < 1e-15);
    assert!((law.value(3.0) - (2.5 + 0.5 / 1.5)).abs() < 1e-14);
    assert!((law.slope(1.0) - 0.5 / 1.5).abs() < 1e-15);
    // integral against a fine midpoint quadrature of the value
    for &x in &[-2.5, -0.7, 0.0, 0.3, 1.7, 3.2] {
        let n = 200_000;
        let h = x / n as f64;
        let quad: f64 = (0..n).map(|i| law.value((i as f64 + 0.5) * h) * h).sum();
        assert!(
            (law.integral(x) - quad).abs() < 1e-8,
            "x = {x}: {} vs {quad}",
            law.integral(x)
        );
    }
    assert_eq!(Law::Linear(4.0).integral(0.5), 0.5);
}

#[test]
fn law_validation_names_field_and_value() {
    let err = |l: Law, monotone: bool| match l.validate("spring", "stiffness", monotone) {
        Err(ModelError::InvalidParameter { field, value, .. }) => (field, value),
        other => panic!("expected an error, got {other:?}"),
    };
    assert_eq!(
        err(table(&[0.0, 1.0, 1.0], &[0.0, 1.0, 2.0]), false),
        ("stiffness.x[2]".to_string(), "1".to_string())
    );
    assert_eq!(
        err(table(&[0.0, 1.0, 2.0], &[0.0, 1.0, 0.5]), true),
        ("stiffness.f[2]".to_string(), "0.5".to_string())
    );
    assert_eq!(
        err(table(&[0.0, f64::NAN], &[0.0, 1.0]), false).0,
        "stiffness.x[1]"
    );
    assert_eq!(
        err(table(&[0.0, 1.0], &[0.0, f64::INFINITY]), false).0,
        "stiffness.f[1]"
    );
    assert_eq!(err(table(&[0.0], &[0.0]), false).0, "stiffness.x");
    assert_eq!(err(table(&[0.0, 1.0], &[0.0]), false).0, "stiffness.f");
    assert_eq!(
        err(Law::Linear(-1.0), true),
        ("stiffness".to_string(), "-1".to_string())
    );
    assert!(table(&[0.0, 1.0, 2.0], &[0.0, 1.0, 0.5])
        .validate("s", "f", false)
        .is_ok());
    // a spring rejects a dissipation-violating damper table
    let mut s = PointSpringDamper::linear(
        BodyRef::Ground,
        [0.0, 0.0],
        BodyRef::Body(0),
        [0.0, 0.0],
        1.0,
        1.0,
        1.0,
    );
    s.damping = table(&[-1.0, 1.0], &[1.0, -1.0]);
    match s.validate(3) {
        Err(ModelError::InvalidParameter { field, .. }) => assert_eq!(field, "damping.f[1]"),
        other => panic!("{other:?}"),
    }
    s.damping = Law::Linear(1.0);
    s.free_length = -1.0;
    assert!(
        matches!(s.validate(3), Err(ModelError::InvalidParameter { field, .. }) if field == "free_length")
    );
}

fn springs() -> Vec<PointSpringDamper> {
    let mut a = PointSpringDamper::linear(
        BodyRef::Body(0),
        [0.3, -0.1],
        BodyRef::Body(2),
        [-0.2, 0.4],
        0.7,
        50.0,
        3.0,
    );
    a.preload = 2.0;
    a.actuator = Some(TimeFunction::Harmonic {
        amplitude: 1.5,
        omega: 2.0,
        phase: 0.1,
        offset: 0.3,
    });
    let mut b = PointSpringDamper::linear(
        BodyRef::Body(1),
        [0.5, 0.2],
        BodyRef::Ground,
        [1.0, -2.0],
        0.4,
        0.0,
        0.0,
    );
    b.stiffness = table(&[-1.0, 0.0, 0.3, 2.0], &[-10.0, 0.0, 12.0, 80.0]);
    b.damping = table(&[-3.0, -0.5, 0.0, 1.0, 4.0], &[-40.0, -5.0, 0.0, 2.0, 30.0]);
    vec![a, b]
}

#[test]
fn point_spring_jacobians_match_finite_differences() {
    let mut rng = Rng(7);
    for s in springs() {
        s.validate(9).unwrap();
        for _ in 0..20 {
            let q: Vec<f64> = (0..9).map(|_| 2.0 * rng.next()).collect();
            let qd: Vec<f64> = (0..9).map(|_| 3.0 * rng.next()).collect();
            check_jacobians(&s, 0.4, &q, &qd, 2e-5);
        }
    }
}

#[test]
fn point_spring_potential_is_minus_work_and_damper_dissipates() {
    let mut rng = Rng(11);
    for mut s in springs() {
        s.actuator = None;
        let q0: Vec<f64> = (0..9).map(|_| rng.next()).collect();
        let q1: Vec<f64> = (0..9).map(|_| rng.next()).collect();
        let zero = vec![0.0; 9];
        // work of g along the straight path q0 → q1 (Simpson), at q̇ = 0
        let n = 2000;
        let dq: Vec<f64> = q0.iter().zip(&q1).map(|(a, b)| b - a).collect();
        let mut work = 0.0;
        for i in 0..=n {
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            let q: Vec<f64> = q0
                .iter()
                .zip(&dq)
                .map(|(a, d)| a + d * i as f64 / n as f64)
                .collect();
            let g = forces(&s, 0.0, &q, &zero);
            work += w * g.iter().zip(&dq).map(|(g, d)| g * d).sum::<f64>();
        }
        work /= 3.0 * n as f64;
        let dv = s.potential_energy(&q1).unwrap() - s.potential_energy(&q0).unwrap();
        assert!(
            (dv + work).abs() < 1e-6 * (1.0 + dv.abs()),
            "ΔV {dv} vs −W {}",
            -work
        );
        // damper alone: power g·q̇ ≤ 0
        s.stiffness = Law::Linear(0.0);
        s.preload = 0.0;
        for _ in 0..50 {
            let q: Vec<f64> = (0..9).map(|_| 2.0 * rng.next()).collect();
            let qd: Vec<f64> = (0..9).map(|_| 3.0 * rng.next()).collect();
            let p: f64 = forces(&s, 0.0, &q, &qd)
                .iter()
                .zip(&qd)
                .map(|(g, v)| g * v)
                .sum();
            assert!(p <= 1e-12, "power {p}");
        }
    }
}

#[test]
fn spring_pendulum_static_stretch_is_mg_over_k() {
    // body of mass m hanging at its centre from ground point (0, 0)
    let (m, grav, k, l0) = (2.0, 9.81, 400.0, 0.5);
    let s = PointSpringDamper::linear(
        BodyRef::Ground,
        [0.0, 0.0],
        BodyRef::Body(0),
        [0.0, 0.0],
        l0,
        k,
        10.0,
    );
    let y = -(l0 + m * grav / k);
    let g = forces(&s, 0.0, &[0.0, y, 0.3], &[0.0; 3]);
    assert!((g[1] - m * grav).abs() < 1e-12, "{g:?}");
    assert!(g[0].abs() < 1e-15 && g[2].abs() < 1e-15);
    assert!((s.force(0.0, &[0.0, y, 0.3], &[0.0; 3]) - m * grav).abs() < 1e-12);
    // zero length: no direction, no force, no NaN
    let g0 = forces(&s, 0.0, &[0.0, 0.0, 0.0], &[1.0, 1.0, 0.0]);
    assert_eq!(g0, vec![0.0; 3]);
}
