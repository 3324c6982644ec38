//! Φ_q, Φ_t, γ and (Φ_qᵀλ)_q of every joint kind against finite differences.

use mbsolve::constraints::{DriveCoordinate, DriveRelativeAngle, Revolute, Translational};
use mbsolve::model::{Body, BodyRef, System, SystemBuilder, TimeFunction};

/// Small deterministic generator (xorshift) for reproducible random states.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
    fn vec(&mut self, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| scale * self.next()).collect()
    }
}

/// A system exercising every joint kind, body–body and body–ground.
fn all_joints() -> System {
    let mut b = SystemBuilder::new();
    for i in 0..4 {
        b.add_body(Body::new(format!("b{i}"), 1.0 + i as f64, 0.1, [0.0; 3]));
    }
    let h = TimeFunction::Harmonic {
        amplitude: 0.3,
        omega: 2.0,
        phase: 0.1,
        offset: 0.2,
    };
    b.add_constraint(Revolute::new(
        "g0",
        BodyRef::Ground,
        [0.1, -0.2],
        BodyRef::Body(0),
        [-0.3, 0.05],
    ));
    b.add_constraint(Revolute::new(
        "01",
        BodyRef::Body(0),
        [0.3, 0.1],
        BodyRef::Body(1),
        [-0.2, 0.4],
    ));
    b.add_constraint(Translational::new(
        "12",
        BodyRef::Body(1),
        [0.1, 0.2],
        [1.0, 0.5],
        BodyRef::Body(2),
        [-0.3, 0.1],
        0.4,
    ));
    b.add_constraint(Translational::new(
        "g3",
        BodyRef::Ground,
        [0.0, 1.0],
        [0.3, 1.0],
        BodyRef::Body(3),
        [0.2, 0.0],
        0.1,
    ));
    b.add_constraint(DriveCoordinate::new("x3", 3, 0, h.clone()));
    b.add_constraint(DriveRelativeAngle::new(
        "23",
        BodyRef::Body(2),
        BodyRef::Body(3),
        TimeFunction::Polynomial(vec![0.1, 0.5, -0.3]),
    ));
    b.add_constraint(DriveRelativeAngle::new(
        "g2",
        BodyRef::Ground,
        BodyRef::Body(2),
        h,
    ));
    b.build().unwrap()
}

fn dense_jacobian(sys: &System, q: &[f64], t: f64) -> Vec<Vec<f64>> {
    let mut vals = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, t, &mut vals);
    let mut d = vec![vec![0.0; sys.n_coords()]; sys.n_constraints()];
    for (&(r, c), v) in sys.jacobian_pattern().iter().zip(&vals) {
        d[r][c] += v;
    }
    d
}

#[test]
fn jacobian_matches_central_differences() {
    let sys = all_joints();
    let mut rng = Rng(0x1234_5678_9abc_def1);
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    for _ in 0..20 {
        let q = rng.vec(n, 2.0);
        let t = rng.next();
        let jac = dense_jacobian(&sys, &q, t);
        let h = 1e-6;
        let (mut pp, mut pm) = (vec![0.0; m], vec![0.0; m]);
        for c in 0..n {
            let mut qp = q.clone();
            qp[c] += h;
            sys.phi(&qp, t, &mut pp);
            qp[c] -= 2.0 * h;
            sys.phi(&qp, t, &mut pm);
            for r in 0..m {
                let fd = (pp[r] - pm[r]) / (2.0 * h);
                assert!(
                    (fd - jac[r][c]).abs() < 1e-8,
                    "Φ_q[{r},{c}] = {} vs FD {fd}",
                    jac[r][c]
                );
            }
        }
        // Φ_t
        let mut phit = vec![0.0; m];
        sys.phi_t(&q, t, &mut phit);
        sys.phi(&q, t + h, &mut pp);
        sys.phi(&q, t - h, &mut pm);
        for r in 0..m {
            let fd = (pp[r] - pm[r]) / (2.0 * h);
            assert!(
                (fd - phit[r]).abs() < 1e-8,
                "Φ_t[{r}] = {} vs FD {fd}",
                phit[r]
            );
        }
    }
}

#[test]
fn gamma_is_second_time_derivative_along_trajectories() {
    // Along q(t) = q0 + v (t − t0) + a (t − t0)²/2:  d²Φ/dt² = Φ_q a − γ.
    let sys = all_joints();
    let mut rng = Rng(0x0bad_cafe_dead_beef);
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    for _ in 0..20 {
        let q0 = rng.vec(n, 2.0);
        let v = rng.vec(n, 1.5);
        let a = rng.vec(n, 1.0);
        let t0 = rng.next();
        let qt = |dt: f64| -> Vec<f64> {
            (0..n)
                .map(|i| q0[i] + v[i] * dt + 0.5 * a[i] * dt * dt)
                .collect()
        };
        let h = 1e-4;
        let (mut p0, mut pp, mut pm) = (vec![0.0; m], vec![0.0; m], vec![0.0; m]);
        sys.phi(&qt(0.0), t0, &mut p0);
        sys.phi(&qt(h), t0 + h, &mut pp);
        sys.phi(&qt(-h), t0 - h, &mut pm);
        let jac = dense_jacobian(&sys, &q0, t0);
        let mut gamma = vec![0.0; m];
        sys.gamma(&q0, &v, t0, &mut gamma);
        for r in 0..m {
            let fd = (pp[r] - 2.0 * p0[r] + pm[r]) / (h * h);
            let pred: f64 = (0..n).map(|c| jac[r][c] * a[c]).sum::<f64>() - gamma[r];
            assert!(
                (fd - pred).abs() < 1e-5 * (1.0 + pred.abs()),
                "row {r}: Φ̈ FD {fd} vs Φ_q a − γ = {pred}"
            );
        }
    }
}

#[test]
fn lambda_hessian_matches_finite_differences() {
    let sys = all_joints();
    let mut rng = Rng(0x5eed);
    let n = sys.n_coords();
    for c in sys.constraints() {
        let q = rng.vec(n, 2.0);
        let t = 0.3;
        let lam = rng.vec(c.n_eq(), 1.0);
        let hp = c.hessian_pattern();
        let mut hv = vec![0.0; hp.len()];
        c.add_hessian(
            &q,
            t,
            &lam,
            &mut hv,
            &mut mbsolve::model::FdWorkspace::default(),
        );
        // FD of Φ_qᵀλ (dense over all coordinates)
        let pat = c.jacobian_pattern();
        let grad = |q: &[f64]| {
            let mut vals = vec![0.0; pat.len()];
            c.jacobian(q, t, &mut vals);
            let mut g = vec![0.0; n];
            for (&(r, col), v) in pat.iter().zip(&vals) {
                g[col] += lam[r] * v;
            }
            g
        };
        let h = 1e-6;
        for j in 0..n {
            let mut qp = q.clone();
            qp[j] += h;
            let gp = grad(&qp);
            qp[j] -= 2.0 * h;
            let gm = grad(&qp);
            for i in j..n {
                let fd = (gp[i] - gm[i]) / (2.0 * h);
                let val: f64 = hp
                    .iter()
                    .zip(&hv)
                    .filter(|(&e, _)| e == (i, j))
                    .map(|(_, v)| v)
                    .sum();
                assert!(
                    (fd - val).abs() < 1e-6,
                    "{}: H[{i},{j}] = {val} vs FD {fd}",
                    c.name()
                );
            }
        }
    }
}

#[test]
fn invalid_joints_are_rejected() {
    let mut b = SystemBuilder::new();
    b.add_body(Body::new("a", 1.0, 1.0, [0.0; 3]));
    b.add_constraint(Revolute::new(
        "bad",
        BodyRef::Body(0),
        [0.0; 2],
        BodyRef::Body(3),
        [0.0; 2],
    ));
    let e = b.build().unwrap_err().to_string();
    assert!(
        e.contains("revolute joint 'bad'") && e.contains("index 3"),
        "{e}"
    );

    let mut b = SystemBuilder::new();
    b.add_body(Body::new("a", -1.0, 1.0, [0.0; 3]));
    let e = b.build().unwrap_err().to_string();
    assert!(
        e.contains("'a'") && e.contains("mass") && e.contains("-1"),
        "{e}"
    );
}
