//! Force elements of the falling rod (docs/problems.md, problem B) and the rod builders:
//! hand-computed values, analytic vs finite-difference Jacobians, power
//! balances, a static Hertz contact equilibrium and builder consistency.

use mbsolve::builders::{add_rod, build_rod, cantilever, n_link_pendulum, RodParams};
use mbsolve::forces::{
    Buoyancy, CornerState, Drag, FdWorkspace, ForceElement, TorsionalSpringDamper, Wall,
    WallContact,
};
use mbsolve::model::{BodyRef, ModelError, System, SystemBuilder};

/// Small deterministic generator (64-bit LCG), uniform in [lo, hi).
struct Rng(u64);
impl Rng {
    fn next(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn forces(e: &dyn ForceElement, q: &[f64], qd: &[f64]) -> Vec<f64> {
    let mut g = vec![0.0; q.len()];
    e.add_forces(0.0, q, qd, &mut g);
    g
}

/// (analytic, finite-difference) Jacobians over the element's block.
fn jacobians<E: ForceElement>(e: &E, q: &[f64], qd: &[f64]) -> [(Vec<f64>, Vec<f64>); 2] {
    let k = e.jacobian_coordinates().len();
    let mut ws = FdWorkspace::default();
    let (mut aq, mut aqd) = (vec![0.0; k * k], vec![0.0; k * k]);
    e.add_jacobians(
        0.0,
        q,
        qd,
        mbsolve::forces::ForceJacobians {
            dq: &mut aq,
            dqd: &mut aqd,
            ws: &mut ws,
        },
    );
    let (mut fq, mut fqd) = (vec![0.0; k * k], vec![0.0; k * k]);
    ws.jacobians(e, 0.0, q, qd, &mut fq, &mut fqd);
    [(aq, fq), (aqd, fqd)]
}

fn assert_jacobians_match<E: ForceElement>(e: &E, q: &[f64], qd: &[f64], rtol: f64) {
    for (which, (a, f)) in ["dg/dq", "dg/dqd"].iter().zip(jacobians(e, q, qd)) {
        let scale = a
            .iter()
            .chain(&f)
            .fold(0.0_f64, |m, v| m.max(v.abs()))
            .max(1e-300);
        for (i, (x, y)) in a.iter().zip(&f).enumerate() {
            assert!(
                (x - y).abs() <= rtol * scale,
                "{}: {which}[{i}] analytic {x} vs FD {y} (scale {scale})",
                e.name()
            );
        }
    }
}

fn assert_close(a: f64, b: f64, rtol: f64, what: &str) {
    assert!(
        (a - b).abs() <= rtol * b.abs().max(1e-300),
        "{what}: {a} vs expected {b}"
    );
}

fn assert_invalid(r: Result<(), ModelError>, field: &str) -> String {
    match r {
        Err(e @ ModelError::InvalidParameter { .. }) => {
            let msg = e.to_string();
            assert!(
                msg.contains(field),
                "message '{msg}' does not name '{field}'"
            );
            msg
        }
        other => panic!("expected an InvalidParameter error naming '{field}', got {other:?}"),
    }
}

// ---------------------------------------------------------------- torsional

#[test]
fn torsional_spring_damper_values_and_energy() {
    let s = TorsionalSpringDamper {
        body_i: BodyRef::Body(0),
        body_j: BodyRef::Body(2),
        k: 100.0,
        c: 2.0,
        rest_angle: 0.05,
    };
    assert_eq!(s.coordinates(), vec![2, 8]);
    let mut q = vec![0.0; 9];
    let mut qd = vec![0.0; 9];
    q[2] = 0.1;
    q[8] = 0.35;
    qd[2] = 0.5;
    qd[8] = -1.0;
    // Δφ = 0.25, Δφ̇ = −1.5: T = −100 (0.25 − 0.05) − 2 (−1.5) = −17
    let g = forces(&s, &q, &qd);
    assert_close(g[8], -17.0, 1e-14, "torque on j");
    assert_close(g[2], 17.0, 1e-14, "torque on i");
    assert!(g
        .iter()
        .enumerate()
        .all(|(k, v)| k == 2 || k == 8 || *v == 0.0));
    assert_close(
        s.potential_energy(&q).unwrap(),
        0.5 * 100.0 * 0.04,
        1e-14,
        "energy",
    );
    assert_jacobians_match(&s, &q, &qd, 1e-7);

    // Reversed numbering (body_i has the larger index) and ground side.
    let r = TorsionalSpringDamper {
        body_i: BodyRef::Body(2),
        body_j: BodyRef::Body(0),
        ..s.clone()
    };
    assert_jacobians_match(&r, &q, &qd, 1e-7);
    assert_close(
        forces(&r, &q, &qd)[2],
        -100.0 * (-0.25 - 0.05) - 2.0 * 1.5,
        1e-14,
        "rev",
    );
    let gr = TorsionalSpringDamper {
        body_i: BodyRef::Ground,
        body_j: BodyRef::Body(1),
        k: 50.0,
        c: 0.0,
        rest_angle: 0.0,
    };
    q[5] = -0.2;
    assert_eq!(gr.coordinates(), vec![5]);
    assert_close(forces(&gr, &q, &qd)[5], 10.0, 1e-14, "ground spring");
    assert_jacobians_match(&gr, &q, &qd, 1e-7);
    let gj = TorsionalSpringDamper {
        body_i: BodyRef::Body(1),
        body_j: BodyRef::Ground,
        ..gr.clone()
    };
    // Δφ = 0 − φ_1 = 0.2: T_j = −10 on the ground, +10 on body 1 (restoring either way).
    assert_close(forces(&gj, &q, &qd)[5], 10.0, 1e-14, "ground as j");
    assert_jacobians_match(&gj, &q, &qd, 1e-7);

    // The elastic part is conservative: g(q, 0) = −∇V.
    let zero = vec![0.0; 9];
    let g0 = forces(&s, &q, &zero);
    for &c in &[2usize, 8] {
        let h = 1e-6;
        let mut qp = q.clone();
        qp[c] += h;
        let mut qm = q.clone();
        qm[c] -= h;
        let dv = (s.potential_energy(&qp).unwrap() - s.potential_energy(&qm).unwrap()) / (2.0 * h);
        assert!(
            (g0[c] + dv).abs() < 1e-6,
            "coordinate {c}: g {} vs −dV {}",
            g0[c],
            -dv
        );
    }
}

#[test]
fn torsional_spring_damper_validation() {
    let ok = TorsionalSpringDamper::new(BodyRef::Body(0), BodyRef::Body(1), 1.0, 0.1);
    assert!(ok.validate(6).is_ok());
    assert!(matches!(
        ok.validate(3),
        Err(ModelError::MissingBody { .. })
    ));
    let e = |f: fn(&mut TorsionalSpringDamper)| {
        let mut s = ok.clone();
        f(&mut s);
        s.validate(6)
    };
    assert_invalid(e(|s| s.k = -1.0), "k");
    assert_invalid(e(|s| s.c = f64::NAN), "c");
    assert_invalid(e(|s| s.rest_angle = f64::INFINITY), "rest_angle");
    assert_invalid(e(|s| s.body_j = BodyRef::Body(0)), "bodies");
    assert_invalid(
        e(|s| {
            s.body_i = BodyRef::Ground;
            s.body_j = BodyRef::Ground
        }),
        "bodies",
    );
}

// ---------------------------------------------------------------- buoyancy

#[test]
fn buoyancy_values_energy_and_validation() {
    let v = 0.03 * 0.03 * 0.1;
    let b = Buoyancy {
        fluid_density: 1000.0,
        gravity: 9.81,
        bodies: vec![(2, v), (0, 2.0 * v)],
    };
    assert_eq!(b.coordinates(), vec![1, 7]);
    assert!(b.jacobian_coordinates().is_empty());
    let q: Vec<f64> = (0..9).map(|k| 0.1 * k as f64 - 0.3).collect();
    let g = forces(&b, &q, &[1.0; 9]);
    let f = 1000.0 * 9.81 * v; // 0.8829 N
    assert_close(g[7], f, 1e-14, "uplift body 2");
    assert_close(g[1], 2.0 * f, 1e-14, "uplift body 0");
    assert_eq!(g.iter().filter(|x| **x != 0.0).count(), 2);
    assert_close(
        b.potential_energy(&q).unwrap(),
        -f * q[7] - 2.0 * f * q[1],
        1e-14,
        "energy",
    );
    assert!(b.validate(9).is_ok());
    assert!(b.validate(6).is_err());
    let mut bad = b.clone();
    bad.bodies[1].1 = 0.0;
    assert_invalid(bad.validate(9), "volume");
    let mut bad = b.clone();
    bad.bodies.push((2, v));
    assert_invalid(bad.validate(9), "bodies");
    let mut bad = b.clone();
    bad.fluid_density = -1.0;
    assert_invalid(bad.validate(9), "fluid_density");
}

// ---------------------------------------------------------------- drag

fn drag(end_face: bool) -> Drag {
    Drag {
        body: 1,
        width: 0.03,
        length: 0.1,
        fluid_density: 1000.0,
        c_transverse: 1.2,
        c_skin: 0.02,
        c_end: 1.0,
        end_face,
    }
}

fn state(body: usize, n_bodies: usize, qb: [f64; 3], vb: [f64; 3]) -> (Vec<f64>, Vec<f64>) {
    let mut q = vec![0.0; 3 * n_bodies];
    let mut qd = vec![0.0; 3 * n_bodies];
    q[3 * body..3 * body + 3].copy_from_slice(&qb);
    qd[3 * body..3 * body + 3].copy_from_slice(&vb);
    (q, qd)
}

#[test]
fn drag_hand_values() {
    // ½ ρ C_t w l = 1.8; ½ ρ C_f 4 w l = 0.12; ½ ρ C_e w² = 0.45;
    // ρ C_t w l⁴ / 64 = 5.625e-5.
    let (q, qd) = state(1, 2, [0.3, -0.2, 0.0], [0.2, -0.5, 3.0]);
    let g = forces(&drag(false), &q, &qd);
    assert_close(g[3], -1.8 * 0.2 * 0.2, 1e-13, "transverse, phi = 0");
    assert_close(g[4], 0.12 * 0.25, 1e-13, "axial, phi = 0");
    assert_close(g[5], -5.625e-5 * 9.0, 1e-13, "rotational");
    assert!(g[..3].iter().all(|v| *v == 0.0));
    let ge = forces(&drag(true), &q, &qd);
    assert_close(ge[4], (0.12 + 0.45) * 0.25, 1e-13, "axial with end face");
    assert_close(ge[3], g[3], 1e-15, "end face is axial only");

    // φ = 90°: the rod lies along −x, e_a = (−1, 0), e_t = (0, 1).
    let (q, qd) = state(
        1,
        2,
        [0.0, 0.0, std::f64::consts::FRAC_PI_2],
        [0.2, -0.5, -1.0],
    );
    let g = forces(&drag(true), &q, &qd);
    // v_t = −0.5 → F_t = +1.8·0.25 along +y; v_a = −0.2 → F_a = +0.57·0.04 along e_a.
    assert_close(g[4], 1.8 * 0.25, 1e-12, "transverse, phi = 90°");
    assert_close(g[3], -(0.12 + 0.45) * 0.04, 1e-12, "axial, phi = 90°");
    assert_close(g[5], 5.625e-5, 1e-13, "rotational, negative rate");
}

#[test]
fn drag_is_frame_invariant_dissipative_and_has_exact_jacobians() {
    let mut rng = Rng(7);
    for trial in 0..200 {
        let d = drag(trial % 2 == 0);
        let phi = rng.next(-3.2, 3.2);
        let v = [
            rng.next(-2.0, 2.0),
            rng.next(-2.0, 2.0),
            rng.next(-20.0, 20.0),
        ];
        let f = d.force(phi, v);
        // Rotating the segment and its velocity by α rotates the force by α.
        let a = rng.next(-3.0, 3.0);
        let (s, c) = a.sin_cos();
        let vr = [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]];
        let fr = d.force(phi + a, vr);
        let expect = [c * f[0] - s * f[1], s * f[0] + c * f[1], f[2]];
        for k in 0..3 {
            assert!(
                (fr[k] - expect[k]).abs() < 1e-12 * (1.0 + f[k].abs()),
                "rotation {k}"
            );
        }
        // Power g·q̇ ≤ 0 (strictly for non-zero velocity).
        let (q, qd) = state(1, 3, [rng.next(-1.0, 1.0), rng.next(-1.0, 1.0), phi], v);
        let g = forces(&d, &q, &qd);
        let p: f64 = g.iter().zip(&qd).map(|(a, b)| a * b).sum();
        assert!(p < 0.0, "drag power {p} at v = {v:?}");
        assert_jacobians_match(&d, &q, &qd, 1e-6);
    }
    assert!(drag(true).validate(6).is_ok());
    let mut bad = drag(true);
    bad.width = 0.0;
    assert_invalid(bad.validate(6), "width");
    let mut bad = drag(true);
    bad.c_skin = -0.1;
    assert_invalid(bad.validate(6), "c_skin");
}

// ---------------------------------------------------------------- contact

fn contact() -> WallContact {
    RodParams::problem_b(10).contact_element(0, 4)
}

#[test]
fn contact_free_inside_the_channel() {
    let c = contact();
    let mut rng = Rng(11);
    let mut states = Vec::new();
    for _ in 0..500 {
        // Random poses whose corners all stay inside |x| < 0.025.
        let phi = rng.next(-0.09, 0.09);
        let half = 0.015 * phi.cos() + 0.05 * phi.sin().abs();
        let x = rng.next(-1.0, 1.0) * (0.025 - half) * 0.999;
        let v = [
            rng.next(-1.0, 1.0),
            rng.next(-1.0, 1.0),
            rng.next(-5.0, 5.0),
        ];
        let (q, qd) = state(0, 1, [x, rng.next(-1.0, 1.0), phi], v);
        assert!(
            forces(&c, &q, &qd).iter().all(|g| *g == 0.0),
            "force at x = {x}, phi = {phi}"
        );
        assert_eq!(c.potential_energy(&q), Some(0.0));
        c.corner_states(&q, &qd, &mut states);
        assert!(states.is_empty());
    }
}

/// The early exit for segments away from the walls never drops a contact:
/// for poses at any angle whose centre lies near the reach `w/2 + l_s/2`
/// from either wall, the element reports a corner state (and a force) exactly
/// when an independently computed corner `r + R(φ) s` penetrates a wall.
#[test]
fn contact_found_exactly_when_a_corner_penetrates() {
    let mut rng = Rng(29);
    let (mut touching, mut clear) = (0, 0);
    for length in [0.1, 1e-4] {
        let c = WallContact {
            length,
            ..contact()
        };
        let reach = 0.5 * (c.width + length);
        let mut states = Vec::new();
        for _ in 0..4000 {
            let phi = rng.next(-std::f64::consts::PI, std::f64::consts::PI);
            let side = if rng.next(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 };
            // centres from just inside the exit bound to past the wall
            let x = side * (0.025 - reach + rng.next(-2e-3, 2e-2) * reach);
            let (q, qd) = state(0, 1, [x, 0.2, phi], [0.0, 0.0, 0.0]);
            let (sn, cs) = (phi.sin(), phi.cos());
            let penetrates = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                .iter()
                .any(|(a, b)| {
                    let px = x + cs * a * 0.5 * c.width - sn * b * 0.5 * length;
                    !(-0.025..=0.025).contains(&px)
                });
            states.clear();
            c.corner_states(&q, &qd, &mut states);
            assert_eq!(
                !states.is_empty(),
                penetrates,
                "x = {x}, phi = {phi}, l_s = {length}: {states:?}"
            );
            assert_eq!(forces(&c, &q, &qd)[0] != 0.0, penetrates);
            if penetrates {
                touching += 1;
            } else {
                clear += 1;
            }
        }
    }
    assert!(
        touching > 1000 && clear > 1000,
        "{touching} touching, {clear} clear"
    );
}

#[test]
fn contact_hand_values_vertical_segment_on_the_right_wall() {
    let c = contact();
    let delta = 1e-5;
    // Vertical segment, right face pushed into the right wall by δ,
    // approaching at 0.02 m/s and sliding down at 1 mm/s (= v_s).
    let (q, qd) = state(0, 1, [0.01 + delta, 0.3, 0.0], [0.02, -1e-3, 0.0]);
    let fnorm = 1e9 * delta.powf(1.5) * (1.0 + 0.75 * 0.02); // ≈ 32.10 N per corner
    let ffric = 0.3 * fnorm * 1f64.tanh(); // upward, per corner
    let g = forces(&c, &q, &qd);
    assert_close(g[0], -2.0 * fnorm, 1e-9, "normal force");
    assert_close(g[1], 2.0 * ffric, 1e-9, "friction force");
    // Normal-force torques of the two corners cancel; friction acts at x = +w/2.
    assert_close(g[2], 0.015 * 2.0 * ffric, 1e-9, "torque");
    let mut states = Vec::new();
    c.corner_states(&q, &qd, &mut states);
    assert_eq!(states.len(), 2);
    assert_eq!(
        states
            .iter()
            .map(|s| (s.corner, s.wall))
            .collect::<Vec<_>>(),
        vec![(1, Wall::Right), (2, Wall::Right)]
    );
    for s in &states {
        assert_eq!((s.body, s.segment), (0, 4));
        assert_close(s.penetration, delta, 1e-9, "penetration");
        assert_close(s.penetration_rate, 0.02, 1e-12, "penetration rate");
        assert_close(s.normal_force, fnorm, 1e-9, "reported normal force");
        assert_close(s.friction_force, ffric, 1e-9, "reported friction");
    }
    assert_close(
        c.potential_energy(&q).unwrap(),
        2.0 * 0.4 * 1e9 * delta.powf(2.5),
        1e-9,
        "elastic energy",
    );

    // Mirror image on the left wall: forces mirror in x, torque flips sign.
    let (qm, qdm) = state(0, 1, [-0.01 - delta, 0.3, 0.0], [-0.02, -1e-3, 0.0]);
    let gm = forces(&c, &qm, &qdm);
    assert_close(gm[0], 2.0 * fnorm, 1e-9, "left normal");
    assert_close(gm[1], 2.0 * ffric, 1e-9, "left friction");
    assert_close(gm[2], -0.015 * 2.0 * ffric, 1e-9, "left torque");
    states.clear(); // corner_states appends
    c.corner_states(&qm, &qdm, &mut states);
    assert_eq!(states.len(), 2);
    assert!(states.iter().all(|s| s.wall == Wall::Left));

    // Separating faster than 1/χ: the Hunt–Crossley force is clamped at 0
    // (no pull, no friction), while the corners still report δ > 0.
    let (qs, qds) = state(0, 1, [0.01 + delta, 0.3, 0.0], [-2.0, -1e-3, 0.0]);
    assert!(forces(&c, &qs, &qds).iter().all(|v| *v == 0.0));
    states.clear();
    c.corner_states(&qs, &qds, &mut states);
    assert_eq!(states.len(), 2);
    assert!(states
        .iter()
        .all(|s| s.normal_force == 0.0 && s.penetration > 0.0));
    // Separating slower than 1/χ: reduced but positive.
    let (qs, qds) = state(0, 1, [0.01 + delta, 0.3, 0.0], [-1.0, 0.0, 0.0]);
    let gs = forces(&c, &qs, &qds);
    assert_close(
        gs[0],
        -2.0 * 1e9 * delta.powf(1.5) * 0.25,
        1e-9,
        "slow separation",
    );
}

/// Random states with at least one corner penetrating a wall.
fn penetrating_states(seed: u64, n: usize) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng = Rng(seed);
    let mut out = Vec::new();
    while out.len() < n {
        let phi = rng.next(-0.05, 0.05);
        let half = 0.015 * phi.cos() + 0.05 * phi.sin().abs();
        let side = if rng.next(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 };
        let x = side * (0.025 - half + rng.next(2e-6, 2e-4));
        let v = [
            rng.next(-0.2, 0.2),
            rng.next(-0.01, 0.01),
            rng.next(-3.0, 3.0),
        ];
        out.push(state(0, 1, [x, rng.next(-0.5, 0.5), phi], v));
    }
    out
}

#[test]
fn contact_friction_never_adds_energy_and_jacobians_are_exact() {
    let c = contact();
    let mut frictionless = contact();
    frictionless.law.friction = 0.0;
    let (mut n_active, mut n_compared) = (0, 0);
    for (q, qd) in penetrating_states(3, 400) {
        let g = forces(&c, &q, &qd);
        let g0 = forces(&frictionless, &q, &qd);
        let p: f64 = g
            .iter()
            .zip(&g0)
            .zip(&qd)
            .map(|((a, b), v)| (a - b) * v)
            .sum();
        let scale: f64 = g0.iter().map(|x| x.abs()).sum::<f64>() * 1.0;
        assert!(p <= 1e-12 * scale, "friction power {p} > 0");
        if g0[0] != 0.0 {
            n_active += 1;
        }
        // The penalty law is smooth away from δ = 0 and the clamp: compare
        // where every penetrating corner is well inside both regimes.
        let mut states = Vec::new();
        c.corner_states(&q, &qd, &mut states);
        let smooth = states
            .iter()
            .all(|s| s.penetration > 1e-5 && (1.0 + 0.75 * s.penetration_rate) > 1e-3);
        if smooth && !states.is_empty() {
            assert_jacobians_match(&c, &q, &qd, 2e-5);
            n_compared += 1;
        }
    }
    assert!(n_active > 300, "only {n_active} states in contact");
    assert!(n_compared > 100, "only {n_compared} Jacobians compared");
}

/// Static Hertz check. A vertical segment pressed against the right wall by a
/// horizontal load F at the body point (0, e) rests on its two right-hand
/// corners. Statics alone give the reactions (force and moment balance),
/// `R_top + R_bot = F`, `R_top − R_bot = (2 e F − w F tan φ)/l_s`, and the
/// Hertz law then predicts the penetrations `δ = (R/k_h)^{2/3}`. The
/// equilibrium (x, φ) is solved by Newton on the element's own forces; the
/// geometric penetrations at the solution must match the prediction.
#[test]
fn contact_static_hertz_equilibrium() {
    let c = contact();
    for (f, e) in [(200.0, 0.02), (50.0, 0.0), (1000.0, -0.03)] {
        let kh = c.law.stiffness;
        let (mut x, mut phi) = (0.01 + (0.5 * f / kh).powf(2.0 / 3.0), 0.0);
        let zero = vec![0.0; 3];
        let mut converged = false;
        for _ in 0..60 {
            let q = vec![x, 0.0, phi];
            let g = forces(&c, &q, &zero);
            // load (F, 0) at R(φ)(0, e): torque −e cos φ · F
            let r = [g[0] + f, g[2] - e * phi.cos() * f];
            if r[0].abs() < 1e-10 * f && r[1].abs() < 1e-10 * f * 0.05 {
                converged = true;
                break;
            }
            let mut ws = FdWorkspace::default();
            let (mut dq, mut dqd) = (vec![0.0; 9], vec![0.0; 9]);
            c.add_jacobians(
                0.0,
                &q,
                &zero,
                mbsolve::forces::ForceJacobians {
                    dq: &mut dq,
                    dqd: &mut dqd,
                    ws: &mut ws,
                },
            );
            let j = [[dq[0], dq[2]], [dq[6], dq[8] + e * phi.sin() * f]];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            x -= (j[1][1] * r[0] - j[0][1] * r[1]) / det;
            phi -= (-j[1][0] * r[0] + j[0][0] * r[1]) / det;
        }
        assert!(converged, "Newton did not converge for F = {f}, e = {e}");
        let q = vec![x, 0.0, phi];
        let mut states: Vec<CornerState> = Vec::new();
        c.corner_states(&q, &zero, &mut states);
        assert_eq!(states.len(), 2, "{states:?}");
        let diff = (2.0 * e * f - 0.03 * f * phi.tan()) / 0.1;
        let (r_top, r_bot) = (0.5 * (f + diff), 0.5 * (f - diff));
        for s in &states {
            let r = if s.corner == 2 { r_top } else { r_bot };
            assert_eq!(s.wall, Wall::Right);
            let predicted = (r / kh).powf(2.0 / 3.0);
            assert_close(s.penetration, predicted, 1e-8, "Hertz penetration");
        }
        println!(
            "F = {f} N at e = {e}: x = {x:.9}, phi = {phi:.3e}, delta = {:.4e} / {:.4e} m",
            states[0].penetration, states[1].penetration
        );
    }
}

#[test]
fn contact_validation() {
    assert!(contact().validate(3).is_ok());
    assert!(contact().validate(0).is_err());
    let e = |f: fn(&mut WallContact)| {
        let mut c = contact();
        f(&mut c);
        c.validate(3)
    };
    assert_invalid(e(|c| c.law.stiffness = 0.0), "stiffness");
    assert_invalid(e(|c| c.law.slip_velocity = 0.0), "slip_velocity");
    assert_invalid(e(|c| c.law.friction = -0.1), "friction");
    assert_invalid(e(|c| c.law.damping = f64::NAN), "damping");
    assert_invalid(e(|c| c.right_wall = 0.0), "right_wall");
    assert_invalid(e(|c| c.length = -1.0), "length");
}

// ---------------------------------------------------------------- builders

fn constraint_residuals(sys: &System, q: &[f64], qd: &[f64]) -> (f64, f64) {
    let m = sys.n_constraints();
    let mut phi = vec![0.0; m];
    sys.phi(q, 0.0, &mut phi);
    let mut vals = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, 0.0, &mut vals);
    let mut v = vec![0.0; m];
    sys.jacobian_mul(&vals, qd, &mut v);
    let inf = |x: &[f64]| x.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
    (inf(&phi), inf(&v))
}

#[test]
fn rod_builder_problem_b() {
    let p = RodParams::problem_b(10);
    assert_eq!(p, RodParams::default());
    assert_eq!(p.tilt, 0.6 * std::f64::consts::PI / 180.0);
    let (sys, info) = build_rod(&p).unwrap();
    let n = 10;
    assert_eq!(sys.bodies().len(), n);
    assert_eq!(sys.n_constraints(), 2 * (n - 1));
    assert_eq!(info.bodies, (0..n).collect::<Vec<_>>());
    assert_eq!(info.joints, (0..n - 1).collect::<Vec<_>>());
    let ls = 0.1;
    let m = 7850.0 * 0.03 * 0.03 * ls; // 0.7065 kg
    let inertia = m * (ls * ls + 0.03 * 0.03) / 12.0;
    let k = 2.1e11 * 0.03_f64.powi(4) / (12.0 * ls); // 141 750 N m/rad
    assert_close(info.segment_length, ls, 1e-15, "l_s");
    assert_close(info.segment_mass, m, 1e-14, "m");
    assert_close(info.segment_inertia, inertia, 1e-14, "I");
    assert_close(info.spring_stiffness, 141_750.0, 1e-12, "k");
    assert_close(info.spring_stiffness, k, 1e-14, "k formula");
    assert_close(info.spring_damping, 1e-5 * k, 1e-14, "c");
    for (i, b) in sys.bodies().iter().enumerate() {
        assert_eq!(b.name, format!("segment {}", i + 1));
        assert_close(b.mass, m, 1e-14, "body mass");
        assert_close(b.inertia, inertia, 1e-14, "body inertia");
        assert_eq!(b.v0, [0.1, 0.0, 0.0]);
        assert_eq!(b.q0[2], p.tilt);
    }
    // Rod centre at the origin, bottom segment lowest, straight along e_a.
    let (q, qd) = sys.initial_state();
    let cx: f64 = (0..n).map(|i| q[3 * i]).sum::<f64>() / n as f64;
    let cy: f64 = (0..n).map(|i| q[3 * i + 1]).sum::<f64>() / n as f64;
    assert!(cx.abs() < 1e-16 && cy.abs() < 1e-16, "centre ({cx}, {cy})");
    assert_close(q[1], -0.45 * p.tilt.cos(), 1e-14, "bottom segment height");
    assert_close(q[0], 0.45 * p.tilt.sin(), 1e-14, "bottom segment x");
    let (res, vres) = constraint_residuals(&sys, &q, &qd);
    assert!(
        res <= 1e-14 && vres <= 1e-14,
        "Phi = {res:e}, Phi_q qd = {vres:e}"
    );

    // Elements: gravity + 9 springs + buoyancy + 10 drag + 10 contacts.
    assert_eq!(sys.forces().len(), 1 + 9 + 1 + 10 + 10);
    assert_eq!(info.springs.len(), 9);
    assert_eq!(info.drag.len(), 10);
    assert_eq!(info.contact_elements.len(), 10);
    assert_eq!(info.contacts.len(), 10);
    for (&fi, c) in info.contact_elements.iter().zip(&info.contacts) {
        assert_eq!(format!("{:?}", sys.forces()[fi]), format!("{c:?}"));
    }
    assert_eq!(sys.forces()[info.gravity.unwrap()].name(), "gravity");
    assert!(sys.forces()[info.buoyancy.unwrap()]
        .name()
        .starts_with("buoyancy"));
    let drag_end: Vec<bool> = info
        .drag
        .iter()
        .map(|&d| format!("{:?}", sys.forces()[d]).contains("end_face: true"))
        .collect();
    assert_eq!(drag_end, (0..n).map(|i| i == 0).collect::<Vec<_>>());

    // Initial forces: straight rod ⇒ no spring torques; no wall touched; net
    // vertical force −(ρ − ρ_w) g V per segment plus a tiny axial drag.
    let mut g = vec![0.0; 3 * n];
    sys.forces_into(0.0, &q, &qd, &mut g);
    let mut states = vec![];
    info.corner_states(&q, &qd, &mut states);
    assert!(states.is_empty());
    let w_net = (7850.0 - 1000.0) * 9.81 * 0.03 * 0.03 * ls;
    for i in 0..n {
        let d = Drag {
            body: i,
            width: 0.03,
            length: ls,
            fluid_density: 1000.0,
            c_transverse: 1.2,
            c_skin: 0.02,
            c_end: 1.0,
            end_face: i == 0,
        }
        .force(p.tilt, [0.1, 0.0, 0.0]);
        assert!(d[1] < 0.0 && d[1] > -3e-4, "drag {d:?}");
        assert_close(g[3 * i + 1], -w_net + d[1], 1e-12, "net vertical force");
        assert_close(g[3 * i], d[0], 1e-12, "horizontal force");
        assert!(g[3 * i + 2] == 0.0);
    }
    // Potential energy of the straight rod: gravity and buoyancy only.
    let pe: f64 = (0..n).map(|i| w_net * q[3 * i + 1]).sum();
    assert!((sys.potential_energy(&q) - pe).abs() < 1e-12);

    // Bent state: the spring between segments 3 and 4 sees Δφ.
    let mut qb = q.clone();
    for i in 3..n {
        qb[3 * i + 2] += 1e-3;
    }
    sys.forces_into(0.0, &qb, &vec![0.0; 3 * n], &mut g);
    assert_close(g[3 * 3 + 2], -k * 1e-3, 1e-9, "spring torque on segment 4");
    assert_close(g[2 * 3 + 2], k * 1e-3, 1e-9, "spring torque on segment 3");

    // Contact reporting through RodInfo: push the top segment into the left wall.
    let mut qc = q.clone();
    qc[3 * (n - 1)] -= 0.006;
    info.corner_states(&qc, &qd, &mut states);
    assert!(!states.is_empty());
    assert!(states
        .iter()
        .all(|s| s.segment == n - 1 && s.wall == Wall::Left));
}

#[test]
fn rod_builder_flags_and_offsets() {
    let mut p = RodParams::problem_b(4);
    p.fluid = false;
    p.contact = false;
    let (sys, info) = build_rod(&p).unwrap();
    assert_eq!(sys.forces().len(), 3 + 1);
    assert!(info.drag.is_empty() && info.contacts.is_empty() && info.buoyancy.is_none());
    p.gravity = 0.0;
    let (sys, info) = build_rod(&p).unwrap();
    assert_eq!(sys.forces().len(), 3);
    assert!(info.gravity.is_none());

    // add_rod into a builder that already has a body: indices are offset.
    let mut b = SystemBuilder::new();
    b.add_body(mbsolve::model::Body::new(
        "other",
        1.0,
        1.0,
        [5.0, 5.0, 0.0],
    ));
    let p = RodParams::problem_b(3);
    let info = add_rod(&mut b, &p).unwrap();
    assert_eq!(info.bodies, vec![1, 2, 3]);
    assert_eq!(info.contacts[2].body, 3);
    assert_eq!(info.contacts[2].segment, 2);
    let sys = b.build().unwrap();
    let (q, qd) = sys.initial_state();
    let (res, vres) = constraint_residuals(&sys, &q, &qd);
    assert!(res <= 1e-14 && vres <= 1e-14);

    // Large N stays consistent.
    let (sys, _) = build_rod(&RodParams::problem_b(1000)).unwrap();
    let (q, qd) = sys.initial_state();
    let (res, vres) = constraint_residuals(&sys, &q, &qd);
    assert!(res <= 1e-14 && vres <= 1e-14, "N = 1000: {res:e} {vres:e}");
    // A single segment has no joints.
    let (sys, info) = build_rod(&RodParams::problem_b(1)).unwrap();
    assert_eq!(
        (sys.n_constraints(), info.joints.len(), info.springs.len()),
        (0, 0, 0)
    );
}

#[test]
fn rod_params_rejects_bad_input() {
    let base = RodParams::problem_b(10);
    let check = |f: fn(&mut RodParams), field: &str, value: &str| {
        let mut p = base.clone();
        f(&mut p);
        let msg = assert_invalid(p.validate(), field);
        assert!(
            msg.contains(value),
            "message '{msg}' does not show the value '{value}'"
        );
        // add_rod and build_rod refuse the same input.
        assert!(build_rod(&p).is_err());
        assert!(add_rod(&mut SystemBuilder::new(), &p).is_err());
        msg
    };
    check(|p| p.n_segments = 0, "n_segments", "0");
    check(|p| p.length = 0.0, "length", "0");
    check(|p| p.length = -1.0, "length", "-1");
    check(|p| p.width = -0.03, "width", "-0.03");
    check(|p| p.density = 0.0, "density", "0");
    check(
        |p| p.youngs_modulus = -2.1e11,
        "youngs_modulus",
        "-210000000000",
    );
    check(|p| p.youngs_modulus = f64::NAN, "youngs_modulus", "NaN");
    check(|p| p.channel_width = 0.02, "channel_width", "0.02");
    let msg = check(|p| p.tilt = 5f64.to_radians(), "tilt", "0.0872");
    assert!(msg.contains("penetrates"), "{msg}");
    // The extreme corner of the paper's rod clears the wall by ~4.8 mm;
    // a channel 1 cm narrower makes the initial state penetrate.
    let msg = check(|p| p.channel_width = 0.035, "tilt", "0.01047");
    assert!(msg.contains("right") || msg.contains("left"), "{msg}");
    check(|p| p.contact_stiffness = 0.0, "contact_stiffness", "0");
    check(|p| p.friction_velocity = -1.0, "friction_velocity", "-1");
    check(|p| p.water_density = -1.0, "water_density", "-1");
    check(
        |p| p.initial_velocity = [f64::INFINITY, 0.0],
        "initial_velocity",
        "inf",
    );
    // Switched-off parts are not checked.
    let mut p = base.clone();
    p.contact = false;
    p.channel_width = 0.0;
    assert!(p.validate().is_ok());
}

#[test]
fn cantilever_and_pendulum_builders() {
    let p = RodParams::problem_b(8);
    let (sys, info) = cantilever(&p, [2.0, 0.0]).unwrap();
    assert_eq!(sys.bodies().len(), 8);
    assert_eq!(sys.n_constraints(), 2 * 8);
    assert_eq!(info.springs.len(), 8);
    assert!(info.base_joint.is_some() && info.tip_load.is_some());
    let (q, qd) = sys.initial_state();
    let (res, vres) = constraint_residuals(&sys, &q, &qd);
    assert!(res <= 1e-14 && vres == 0.0);
    // Straight and unloaded springs: only the tip load acts.
    let mut g = vec![0.0; 24];
    sys.forces_into(0.0, &q, &qd, &mut g);
    let ls = 0.125;
    assert_close(g[21], 2.0, 1e-15, "tip load x");
    assert_close(
        g[23],
        -2.0 * ls / 2.0 * p.tilt.cos(),
        1e-12,
        "tip load torque",
    );
    assert!(g[..21].iter().all(|v| v.abs() < 1e-9), "{g:?}");
    assert!(sys.potential_energy(&q).abs() < 1e-20);

    let (sys, info) = n_link_pendulum(5, 0.2, 0.3, 0.4, 9.81).unwrap();
    assert_eq!(sys.n_constraints(), 10);
    let (q, qd) = sys.initial_state();
    let (res, vres) = constraint_residuals(&sys, &q, &qd);
    assert!(res <= 1e-15 && vres == 0.0);
    assert_close(
        sys.bodies()[0].inertia,
        0.3 * 0.04 / 12.0,
        1e-14,
        "link inertia",
    );
    assert_close(q[0], 0.1 * 0.4f64.sin(), 1e-14, "first link x");
    assert_close(q[1], -0.1 * 0.4f64.cos(), 1e-14, "first link y");
    assert_close(q[13], -0.9 * 0.4f64.cos(), 1e-14, "last link y");
    assert!(info.gravity.is_some() && info.springs.is_empty());
    assert!(n_link_pendulum(0, 0.2, 0.3, 0.4, 9.81).is_err());
    assert_invalid(
        n_link_pendulum(2, -0.2, 0.3, 0.0, 9.81).map(|_| ()),
        "link_length",
    );
}
