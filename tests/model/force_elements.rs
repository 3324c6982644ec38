//! Force elements on any bodies: laws, forces and
//! Jacobians against central finite differences, potential energy against
//! the work of the force, damper power, law validation, static cases.

use mbsolve::forces::{
    ContactLaw, FdWorkspace, ForceElement, HalfPlaneContact, Law, PointSpringDamper,
    RotationalSpringDamper,
};
use mbsolve::model::{BodyPoint, BodyRef, ModelError, TimeFunction};

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
    e.add_jacobians(
        t,
        q,
        qd,
        mbsolve::forces::ForceJacobians {
            dq: &mut dq,
            dqd: &mut dqd,
            ws: &mut FdWorkspace::default(),
        },
    );
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
        BodyPoint::new(BodyRef::Ground, [0.0, 0.0]),
        BodyPoint::new(BodyRef::Body(0), [0.0, 0.0]),
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
        BodyPoint::new(BodyRef::Body(0), [0.3, -0.1]),
        BodyPoint::new(BodyRef::Body(2), [-0.2, 0.4]),
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
        BodyPoint::new(BodyRef::Body(1), [0.5, 0.2]),
        BodyPoint::new(BodyRef::Ground, [1.0, -2.0]),
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
        BodyPoint::new(BodyRef::Ground, [0.0, 0.0]),
        BodyPoint::new(BodyRef::Body(0), [0.0, 0.0]),
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

/// `−∫ g·dq` along the straight path q0 → q1 at q̇ = 0 (Simpson, n even).
fn work(e: &dyn ForceElement, q0: &[f64], q1: &[f64], n: usize) -> f64 {
    let zero = vec![0.0; q0.len()];
    let dq: Vec<f64> = q0.iter().zip(q1).map(|(a, b)| b - a).collect();
    let mut w = 0.0;
    for i in 0..=n {
        let c = if i == 0 || i == n {
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
        let g = forces(e, 0.0, &q, &zero);
        w += c * g.iter().zip(&dq).map(|(g, d)| g * d).sum::<f64>();
    }
    w / (3.0 * n as f64)
}

/// Power of the non-conservative part, `(g(q, q̇) − g(q, 0))·q̇`.
fn dissipated_power(e: &dyn ForceElement, q: &[f64], qd: &[f64]) -> f64 {
    let g = forces(e, 0.0, q, qd);
    let g0 = forces(e, 0.0, q, &vec![0.0; q.len()]);
    g.iter()
        .zip(&g0)
        .zip(qd)
        .map(|((a, b), v)| (a - b) * v)
        .sum()
}

fn rotational_springs() -> Vec<RotationalSpringDamper> {
    let a = RotationalSpringDamper::linear(BodyRef::Body(2), BodyRef::Body(0), 0.3, 40.0, 1.5);
    let mut b = RotationalSpringDamper::linear(BodyRef::Ground, BodyRef::Body(1), -0.2, 0.0, 0.0);
    b.stiffness = table(&[-1.0, 0.0, 0.4, 2.0], &[-30.0, 0.0, 8.0, 90.0]);
    b.damping = table(&[-2.0, 0.0, 1.0, 3.0], &[-9.0, 0.0, 0.5, 12.0]);
    let c = RotationalSpringDamper::linear(BodyRef::Body(1), BodyRef::Ground, 0.0, 7.0, 0.2);
    vec![a, b, c]
}

#[test]
fn rotational_spring_torque_jacobians_energy_and_power() {
    let mut rng = Rng(21);
    for s in rotational_springs() {
        s.validate(9).unwrap();
        for _ in 0..20 {
            let q: Vec<f64> = (0..9).map(|_| 2.0 * rng.next()).collect();
            let qd: Vec<f64> = (0..9).map(|_| 3.0 * rng.next()).collect();
            check_jacobians(&s, 0.0, &q, &qd, 2e-5);
            assert!(dissipated_power(&s, &q, &qd) <= 1e-12);
            // torque on j is minus that on i: no net torque from an internal spring
            let g = forces(&s, 0.0, &q, &qd);
            let (gi, gj) = (
                s.body_i.offset().map_or(0.0, |o| g[o + 2]),
                s.body_j.offset().map_or(0.0, |o| g[o + 2]),
            );
            if s.body_i.offset().is_some() && s.body_j.offset().is_some() {
                assert!((gi + gj).abs() < 1e-12);
            }
            assert!((gj - s.body_j.offset().map_or(0.0, |_| s.torque(&q, &qd))).abs() < 1e-12);
        }
        let q0: Vec<f64> = (0..9).map(|_| rng.next()).collect();
        let q1: Vec<f64> = (0..9).map(|_| rng.next()).collect();
        let dv = s.potential_energy(&q1).unwrap() - s.potential_energy(&q0).unwrap();
        let w = work(&s, &q0, &q1, 2000);
        assert!(
            (dv + w).abs() < 1e-6 * (1.0 + dv.abs()),
            "ΔV {dv} vs −W {}",
            -w
        );
    }
    // linear case against the closed form: T = −k (φ_j − φ_i − φ0) − c (φ̇_j − φ̇_i)
    let s = &rotational_springs()[0];
    let q = [0.0, 0.0, 0.7, 0.0, 0.0, 0.0, 0.0, 0.0, -0.4];
    let qd = [0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5];
    let want = -40.0 * (0.7 - (-0.4) - 0.3) - 1.5 * (2.0 - 0.5);
    assert!((s.torque(&q, &qd) - want).abs() < 1e-12);
}

fn contacts() -> Vec<HalfPlaneContact> {
    vec![
        // a point under a floor tilted by 20°
        HalfPlaneContact::new(
            0,
            [0.3, -0.2],
            0.0,
            [0.1, -0.5],
            [-(20f64.to_radians().sin()), 20f64.to_radians().cos()],
            ContactLaw {
                stiffness: 1e5,
                damping: 0.8,
                friction: 0.4,
                slip_velocity: 1e-2,
            },
        ),
        // a circle against a wall at 130°, normal not of unit length
        HalfPlaneContact::new(
            1,
            [-0.1, 0.25],
            0.15,
            [0.4, 0.2],
            [
                2.0 * 130f64.to_radians().cos(),
                2.0 * 130f64.to_radians().sin(),
            ],
            ContactLaw {
                stiffness: 3e4,
                damping: 0.0,
                friction: 0.6,
                slip_velocity: 5e-2,
            },
        ),
    ]
}

/// A state of `c`'s body with penetration in (0.005, 0.05) m.
fn penetrating(c: &HalfPlaneContact, rng: &mut Rng) -> Vec<f64> {
    loop {
        let mut q: Vec<f64> = (0..9).map(|_| rng.next()).collect();
        let d = c.penetration(&q);
        // shift the body along the normal to the target penetration
        let target = 0.005 + 0.045 * (0.5 + 0.5 * rng.next());
        let o = 3 * c.body;
        q[o] -= (target - d) * c.normal[0];
        q[o + 1] -= (target - d) * c.normal[1];
        let d = c.penetration(&q);
        if (d - target).abs() < 1e-12 {
            return q;
        }
    }
}

#[test]
fn half_plane_contact_jacobians_energy_and_power() {
    let mut rng = Rng(5);
    for c in contacts() {
        c.validate(9).unwrap();
        for _ in 0..30 {
            let q = penetrating(&c, &mut rng);
            let qd: Vec<f64> = (0..9).map(|_| 0.05 * rng.next()).collect();
            check_jacobians(&c, 0.0, &q, &qd, 2e-5);
            assert!(dissipated_power(&c, &q, &qd) <= 1e-12);
        }
        // potential against the work, on paths inside the contact and across its edge
        for across in [false, true] {
            let q0 = penetrating(&c, &mut rng);
            let mut q1 = penetrating(&c, &mut rng);
            if across {
                let o = 3 * c.body;
                q1[o] += 0.1 * c.normal[0];
                q1[o + 1] += 0.1 * c.normal[1];
                assert!(c.penetration(&q1) < 0.0);
            }
            let dv = c.potential_energy(&q1).unwrap() - c.potential_energy(&q0).unwrap();
            let w = work(&c, &q0, &q1, 20000);
            assert!(
                (dv + w).abs() < 1e-6 * (1.0 + dv.abs()),
                "ΔV {dv} vs −W {}",
                -w
            );
        }
    }
}

#[test]
fn half_plane_contact_matches_hertz_law_and_rolling_has_no_friction() {
    // a wheel of radius 0.2 on the floor y = 0 (normal up), centre at 0.2 − δ
    let c = HalfPlaneContact::new(
        0,
        [0.0, 0.0],
        0.2,
        [5.0, 0.0],
        [0.0, 3.0],
        ContactLaw {
            stiffness: 2e6,
            damping: 0.5,
            friction: 0.7,
            slip_velocity: 1e-3,
        },
    );
    let delta = 1e-3;
    let q = [1.0, 0.2 - delta, 0.9];
    let g = forces(&c, 0.0, &q, &[0.0; 3]);
    let fn_ = 2e6 * delta.powf(1.5);
    assert!((g[1] - fn_).abs() < 1e-9 * fn_ && g[0].abs() < 1e-12 && g[2].abs() < 1e-12);
    // rolling without slip (v = −ω R) and no approach: friction vanishes
    let g = forces(&c, 0.0, &q, &[-0.4, 0.0, 2.0]);
    assert!(g[0].abs() < 1e-9 * fn_ && (g[1] - fn_).abs() < 1e-9 * fn_);
    // sliding to +x: friction −μ F_n tanh(v/v_s) ≈ −μ F_n, and its moment about the centre
    let g = forces(&c, 0.0, &q, &[0.5, 0.0, 0.0]);
    assert!((g[0] + 0.7 * fn_).abs() < 1e-6 * fn_);
    assert!((g[2] - (-(0.2 - 0.0) * 0.0 - (-0.2) * g[0])).abs() < 1e-9 * fn_);
    // separated: nothing
    let g = forces(&c, 0.0, &[1.0, 0.25, 0.0], &[0.0, -1.0, 0.0]);
    assert_eq!(g, vec![0.0; 3]);
    // bad input names the field
    let mut bad = c.clone();
    bad.radius = -0.1;
    assert!(
        matches!(bad.validate(3), Err(ModelError::InvalidParameter { field, .. }) if field == "radius")
    );
    let bad = HalfPlaneContact::new(
        0,
        [0.0; 2],
        0.0,
        [0.0; 2],
        [0.0, 0.0],
        ContactLaw {
            stiffness: 1.0,
            damping: 0.0,
            friction: 0.0,
            slip_velocity: 1.0,
        },
    );
    assert!(
        matches!(bad.validate(3), Err(ModelError::InvalidParameter { field, .. }) if field == "normal")
    );
}
