//! The onsets the contact elements foresee (`ForceElement::onset_within`,
//! read by Radau IIA's `flight_step`): the time at which a corner or point
//! moving with its velocity meets its wall, against the time at which the
//! element's own force law switches on along that motion, and the corners'
//! velocities against finite differences of their positions.

use mbsolve::builders::RodParams;
use mbsolve::forces::{ContactLaw, ForceElement, HalfPlaneContact, WallContact};

fn segment() -> WallContact {
    RodParams::problem_b(10).contact_element(0, 0)
}

/// The x-force of `e` at `q` (velocity `qd`).
fn force_x(e: &dyn ForceElement, q: &[f64], qd: &[f64]) -> f64 {
    let mut g = vec![0.0; q.len()];
    e.add_forces(0.0, q, qd, &mut g);
    g[0]
}

/// The global x of corner `c` of the segment at `q`.
fn corner_x(w: &WallContact, q: &[f64], c: usize) -> f64 {
    let s = w.corner_offset(c);
    q[0] + q[2].cos() * s[0] - q[2].sin() * s[1]
}

/// A tilted segment translating towards either wall: the onset is the
/// leading corner's gap over the speed (closed form), the force is zero a
/// nanosecond before it and pushes back a nanosecond after, along the
/// same straight motion; a horizon short of it, or a motion along the
/// walls, foresees none; moving the other way, the trailing corners'
/// gap to the other wall over the speed counts (a corner leaving a wall
/// may come back).
#[test]
fn a_translating_segment_meets_the_wall_when_its_force_switches_on() {
    let w = segment();
    for (x0, vx) in [(0.001, 0.2), (-0.002, -0.35)] {
        let q0 = [x0, 0.3, 0.1];
        let qd = [vx, -1.0, 0.0];
        let lead = (0..4).map(|c| corner_x(&w, &q0, c)).fold(
            if vx > 0.0 { f64::MIN } else { f64::MAX },
            |a, x| {
                if vx > 0.0 {
                    a.max(x)
                } else {
                    a.min(x)
                }
            },
        );
        let wall = if vx > 0.0 { w.right_wall } else { w.left_wall };
        let expect = (wall - lead) / vx;
        let tau = w.onset_within(0.0, &q0, &qd, 1.0).expect("an onset");
        assert!((tau / expect - 1.0).abs() < 1e-12, "{tau} against {expect}");
        let at = |t: f64| [x0 + vx * t, 0.3 - t, 0.1];
        assert_eq!(force_x(&w, &at(tau - 1e-9), &qd), 0.0);
        let push = force_x(&w, &at(tau + 1e-9), &qd);
        assert!(push * vx < 0.0, "force {push} at the onset");
        assert_eq!(w.onset_within(0.0, &q0, &qd, 0.9 * tau), None);
        assert_eq!(w.onset_within(0.0, &q0, &[0.0, -1.0, 0.0], 1.0), None);
        let trail = (0..4).map(|c| corner_x(&w, &q0, c)).fold(
            if vx > 0.0 { f64::MAX } else { f64::MIN },
            |a, x| {
                if vx > 0.0 {
                    a.min(x)
                } else {
                    a.max(x)
                }
            },
        );
        let other = if vx > 0.0 { w.left_wall } else { w.right_wall };
        let back = w
            .onset_within(0.0, &q0, &[-vx, -1.0, 0.0], 1.0)
            .expect("an onset");
        let expect_back = ((trail - other) / vx).min(expect);
        assert!(
            (back / expect_back - 1.0).abs() < 1e-12,
            "{back} against {expect_back}"
        );
        // in contact: an onset now
        assert_eq!(w.onset_within(0.0, &at(tau + 1e-9), &qd, 1e-6), Some(0.0));
    }
    // at rest in the middle: none
    assert_eq!(
        w.onset_within(0.0, &[0.0, 0.0, 0.05], &[0.0; 3], 10.0),
        None
    );
}

/// A rotating segment: the corners' velocities `ẋ − φ̇ (R s)_y` the onset
/// uses match central differences of their positions, and the onset is the
/// smallest gap over speed across the wall among the corners.
#[test]
fn a_rotating_segment_uses_the_corners_velocities() {
    let w = segment();
    let (q, qd) = ([0.004, 0.0, -0.05], [0.05, 0.2, 3.0]);
    let eps = 1e-7;
    let mut expect = f64::INFINITY;
    for c in 0..4 {
        let ahead = [q[0] + qd[0] * eps, q[1], q[2] + qd[2] * eps];
        let back = [q[0] - qd[0] * eps, q[1], q[2] - qd[2] * eps];
        let v = (corner_x(&w, &ahead, c) - corner_x(&w, &back, c)) / (2.0 * eps);
        let x = corner_x(&w, &q, c);
        for gap in [w.right_wall - x, x - w.left_wall] {
            expect = expect.min(gap / v.abs());
        }
    }
    assert!(expect.is_finite());
    let tau = w.onset_within(0.0, &q, &qd, 1.0).expect("an onset");
    assert!((tau / expect - 1.0).abs() < 1e-6, "{tau} against {expect}");
}

/// A ball over a floor and against a wall tilted by 30°: the onset is the
/// gap `−δ` over the closing velocity `−n·ṗ`, where the element's force
/// switches on along the straight motion; in contact, an onset now;
/// moving away, the same gap over the same speed; along the wall, none.
#[test]
fn a_half_plane_contact_foresees_its_onset() {
    let n = [(-30f64).to_radians().sin(), 30f64.to_radians().cos()];
    let c = HalfPlaneContact::new(
        0,
        [0.05, 0.0],
        0.1,
        [0.0, 0.0],
        n,
        ContactLaw {
            stiffness: 1e6,
            damping: 0.0,
            friction: 0.0,
            slip_velocity: 1e-3,
        },
    );
    let q0 = [0.2, 0.6, 0.0];
    let qd = [-0.3, -2.0, 0.0];
    let gap = -c.penetration(&q0);
    let closing = -(n[0] * qd[0] + n[1] * qd[1]);
    let expect = gap / closing;
    let tau = c.onset_within(0.0, &q0, &qd, 1.0).expect("an onset");
    assert!((tau / expect - 1.0).abs() < 1e-12, "{tau} against {expect}");
    let at = |t: f64| [q0[0] + qd[0] * t, q0[1] + qd[1] * t, 0.0];
    let fy = |q: &[f64]| {
        let mut g = vec![0.0; 3];
        c.add_forces(0.0, q, &qd, &mut g);
        g[1]
    };
    assert_eq!(fy(&at(tau - 1e-9)), 0.0);
    assert!(fy(&at(tau + 1e-9)) > 0.0);
    assert_eq!(c.onset_within(0.0, &q0, &qd, 0.9 * tau), None);
    let away = c
        .onset_within(0.0, &q0, &[0.3, 2.0, 0.0], 1.0)
        .expect("an onset");
    assert!(
        (away / expect - 1.0).abs() < 1e-12,
        "{away} against {expect}"
    );
    let along = [n[1], -n[0], 0.0];
    assert_eq!(c.onset_within(0.0, &q0, &along, 1.0), None);
    assert_eq!(c.onset_within(0.0, &at(tau + 1e-9), &qd, 1e-6), Some(0.0));
}
