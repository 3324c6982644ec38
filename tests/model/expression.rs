//! Expression loads: forces against independently computed laws, exact
//! Jacobians against finite differences, no allocation, clear errors.

use mbsolve::forces::{
    ExpressionError, ExpressionLoadBuilder, FdWorkspace, ForceElement, LinePoint,
};

use crate::counting::allocations;

const Q: [f64; 9] = [0.1, -0.2, 0.3, 1.2, 0.4, -0.7, 2.0, 2.0, 2.0];
const QD: [f64; 9] = [0.5, -0.3, 0.8, -0.2, 0.6, 1.1, 0.0, 0.0, 0.0];

fn forces(e: &dyn ForceElement, t: f64, q: &[f64], qd: &[f64]) -> Vec<f64> {
    let mut g = vec![0.0; q.len()];
    e.add_forces(t, q, qd, &mut g);
    g
}

/// ∂g/∂q and ∂g/∂q̇ against central differences over the footprint.
fn check_jacobians(e: &dyn ForceElement, t: f64) {
    let jc = e.jacobian_coordinates();
    let k = jc.len();
    let (mut dq, mut dqd) = (vec![0.0; k * k], vec![0.0; k * k]);
    let mut ws = FdWorkspace::default();
    e.add_jacobians(
        t,
        &Q,
        &QD,
        mbsolve::forces::ForceJacobians {
            dq: &mut dq,
            dqd: &mut dqd,
            ws: &mut ws,
        },
    );
    let h = 1e-6;
    for (c, &gc) in jc.iter().enumerate() {
        for (vel, jac) in [(false, &dq), (true, &dqd)] {
            let (mut qp, mut qm, mut vp, mut vm) = (Q, Q, QD, QD);
            if vel {
                vp[gc] += h;
                vm[gc] -= h;
            } else {
                qp[gc] += h;
                qm[gc] -= h;
            }
            let gp = forces(e, t, &qp, &vp);
            let gm = forces(e, t, &qm, &vm);
            for (r, &gr) in jc.iter().enumerate() {
                let fd = (gp[gr] - gm[gr]) / (2.0 * h);
                let an = jac[r * k + c];
                assert!(
                    (an - fd).abs() <= 1e-6 * (1.0 + fd.abs()),
                    "{} d g[{gr}]/d {}[{gc}]: {an} vs fd {fd}",
                    e.name(),
                    if vel { "qd" } else { "q" }
                );
            }
        }
    }
}

/// A linear spring–damper to an anchor, as a point force, and a torque:
/// equal to the law computed by hand.
#[test]
fn linear_spring_damper_reproduces_hand_computed_force() {
    let (k, c, s) = (300.0, 4.0, [0.25, -0.1]);
    let load = ExpressionLoadBuilder::new("sd", &[("A", 0), ("B", 1)])
        .force(
            "B",
            s,
            "-300*(B.x + cos(B.phi)*0.25 + sin(B.phi)*0.1 - 1) - 4*B.vx",
            "-3e2*B.y - 4*B.vy + 2*t",
        )
        .unwrap()
        .torque("A", "-5*(A.phi - B.phi) - 0.5*A.omega")
        .unwrap()
        .build();
    let t = 0.3;
    let g = forces(&load, t, &Q, &QD);
    let phi = Q[5];
    let rs = [
        phi.cos() * s[0] - phi.sin() * s[1],
        phi.sin() * s[0] + phi.cos() * s[1],
    ];
    let fx = -k * (Q[3] + rs[0] - 1.0) - c * QD[3];
    let fy = -k * Q[4] - c * QD[4] + 2.0 * t;
    let want = [
        0.0,
        0.0,
        -5.0 * (Q[2] - Q[5]) - 0.5 * QD[2],
        fx,
        fy,
        rs[0] * fy - rs[1] * fx,
        0.0,
        0.0,
        0.0,
    ];
    for (i, (a, b)) in g.iter().zip(&want).enumerate() {
        assert!(
            (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
            "g[{i}] = {a}, want {b}"
        );
    }
    check_jacobians(&load, t);
}

/// A spring–damper along the line between a body point and a ground point,
/// and between two body points: the force from an independent computation,
/// Jacobians against finite differences (chain rule through the points and
/// the direction).
#[test]
fn line_spring_damper_and_jacobians() {
    let (k, c, l0) = (1e3, 7.0, 0.4);
    let a = LinePoint {
        body: Some("A".into()),
        point: [0.3, 0.05],
    };
    let ground = LinePoint {
        body: None,
        point: [-0.5, 1.0],
    };
    let load = ExpressionLoadBuilder::new("line", &[("A", 0)])
        .line_force(&a, &ground, "1e3*(length - 0.4) + 7*length_rate")
        .unwrap()
        .build();
    let g = forces(&load, 0.0, &Q, &QD);
    // Independent: point position and velocity, then f along the unit vector.
    let (x, y, p, vx, vy, w) = (Q[0], Q[1], Q[2], QD[0], QD[1], QD[2]);
    let rs = [
        p.cos() * 0.3 - p.sin() * 0.05,
        p.sin() * 0.3 + p.cos() * 0.05,
    ];
    let pa = [x + rs[0], y + rs[1]];
    let va = [vx - w * rs[1], vy + w * rs[0]];
    let d = [-0.5 - pa[0], 1.0 - pa[1]];
    let len = d[0].hypot(d[1]);
    let u = [d[0] / len, d[1] / len];
    let rate = -(u[0] * va[0] + u[1] * va[1]);
    let f = k * (len - l0) + c * rate;
    let fa = [f * u[0], f * u[1]];
    let want = [fa[0], fa[1], rs[0] * fa[1] - rs[1] * fa[0]];
    for i in 0..3 {
        assert!(
            (g[i] - want[i]).abs() <= 1e-10 * (1.0 + want[i].abs()),
            "g[{i}] {} vs {}",
            g[i],
            want[i]
        );
    }
    assert!(g[3..].iter().all(|&v| v == 0.0));
    check_jacobians(&load, 0.0);

    // Two bodies, a nonlinear law of relative motion: equal and opposite
    // forces; Jacobians exact.
    let b = LinePoint {
        body: Some("B".into()),
        point: [-0.2, 0.1],
    };
    let load = ExpressionLoadBuilder::new("pair", &[("B", 1), ("A", 0)])
        .line_force(
            &a,
            &b,
            "50*(length - 0.5)^3 + 2*tanh(length_rate/0.1) + sin(t)*abs(A.omega - B.omega)",
        )
        .unwrap()
        .build();
    let g = forces(&load, 0.7, &Q, &QD);
    assert!((g[0] + g[3]).abs() < 1e-12 && (g[1] + g[4]).abs() < 1e-12);
    check_jacobians(&load, 0.7);
}

#[test]
fn evaluation_does_not_allocate() {
    let load = ExpressionLoadBuilder::new("n", &[("A", 0), ("B", 1)])
        .line_force(
            &LinePoint {
                body: Some("A".into()),
                point: [0.1, 0.0],
            },
            &LinePoint {
                body: Some("B".into()),
                point: [0.0, 0.2],
            },
            "10*(length - 1) + max(length_rate, 0)",
        )
        .unwrap()
        .build();
    let k = load.jacobian_coordinates().len();
    let mut g = vec![0.0; 9];
    let (mut dq, mut dqd) = (vec![0.0; k * k], vec![0.0; k * k]);
    let mut ws = FdWorkspace::default();
    load.add_forces(0.0, &Q, &QD, &mut g);
    load.add_jacobians(
        0.0,
        &Q,
        &QD,
        mbsolve::forces::ForceJacobians {
            dq: &mut dq,
            dqd: &mut dqd,
            ws: &mut ws,
        },
    );
    let before = allocations();
    for _ in 0..10 {
        load.add_forces(0.0, &Q, &QD, &mut g);
        load.add_jacobians(
            0.0,
            &Q,
            &QD,
            mbsolve::forces::ForceJacobians {
                dq: &mut dq,
                dqd: &mut dqd,
                ws: &mut ws,
            },
        );
    }
    assert_eq!(allocations() - before, 0);
}

#[test]
fn errors_name_load_field_and_position() {
    let e = ExpressionLoadBuilder::new("L", &[("A", 0)])
        .torque("A", "2 * sinh(A.phi)")
        .unwrap_err();
    assert!(matches!(e, ExpressionError::Parse { .. }));
    assert_eq!(
        e.to_string(),
        "expression load 'L', torque = \"2 * sinh(A.phi)\": unknown function 'sinh' at 4"
    );
    let e = ExpressionLoadBuilder::new("L", &[("A", 0)])
        .torque("A", "C.phi")
        .unwrap_err();
    assert!(e.to_string().ends_with("unknown name 'C.phi' at 0"), "{e}");
    let e = ExpressionLoadBuilder::new("L", &[("A", 0)])
        .torque("B", "1")
        .unwrap_err();
    assert!(matches!(e, ExpressionError::UnknownBody { ref body, .. } if body == "B"));
    let e = ExpressionLoadBuilder::new("L", &[("A", 0)])
        .force("A", [f64::NAN, 0.0], "1", "0")
        .unwrap_err();
    assert!(matches!(e, ExpressionError::BadPoint { .. }));
}
